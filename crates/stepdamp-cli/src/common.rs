//! Shared command-line pieces: motor loading, lists of modes and compensations, atomic
//! output, progress bars.

use anyhow::{Context, Result, anyhow, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use stepdamp_core::Mode;
use stepdamp_sim::{Compensation, Profile};

/// Loads a preset or a TOML profile, with the reason on failure.
pub fn load_motor(name_or_path: &str) -> Result<Profile> {
    Profile::load(name_or_path).map_err(|e| anyhow!("{e}"))
}

/// Parses `open-loop`, `servo` or `both`.
pub fn parse_modes(s: &str) -> Result<Vec<Mode>> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim) {
        match part {
            "open-loop" | "openloop" | "ol" => push_unique(&mut out, Mode::OpenLoop),
            "servo" => push_unique(&mut out, Mode::Servo),
            "both" => {
                push_unique(&mut out, Mode::OpenLoop);
                push_unique(&mut out, Mode::Servo);
            }
            _ => bail!("--mode '{part}': expected open-loop, servo or both (a comma list is allowed)"),
        }
    }
    Ok(out)
}

/// Parses a comma list of `off`, `patent` (alias `on`), `estimated`, or `both` (= `off,patent`).
pub fn parse_compensations(s: &str) -> Result<Vec<Compensation>> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim) {
        match part {
            "off" => push_unique(&mut out, Compensation::Off),
            "patent" | "on" => push_unique(&mut out, Compensation::Patent),
            "estimated" => push_unique(&mut out, Compensation::Estimated),
            "both" => {
                push_unique(&mut out, Compensation::Off);
                push_unique(&mut out, Compensation::Patent);
            }
            _ => bail!(
                "--compensation '{part}': expected off, patent (or on), estimated, or both (= off,patent); a comma list is allowed"
            ),
        }
    }
    Ok(out)
}

fn push_unique<T: PartialEq>(v: &mut Vec<T>, x: T) {
    if !v.contains(&x) {
        v.push(x);
    }
}

/// A progress bar on stderr, hidden when quiet or when stderr is not a terminal.
pub fn progress(len: u64, quiet: bool, what: &str) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} runs [{elapsed_precise} < {eta_precise}]")
            .expect("valid template"),
    );
    pb.set_message(what.to_string());
    pb
}

/// Files written side by side and moved into place only when all are complete, so an
/// error leaves nothing half-written.
pub struct AtomicFiles {
    staged: Vec<(PathBuf, PathBuf)>,
}

impl AtomicFiles {
    /// Creates `dir` (and parents) and checks it is writable.
    pub fn in_dir(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the output directory", dir.display()))?;
        let probe = dir.join(".stepdamp-write-test");
        std::fs::write(&probe, b"").with_context(|| format!("{}: output directory is not writable", dir.display()))?;
        let _ = std::fs::remove_file(&probe);
        Ok(AtomicFiles { staged: Vec::new() })
    }

    /// A temporary path to write `final_path` to (same directory, same extension).
    pub fn stage(&mut self, final_path: &Path) -> PathBuf {
        let name = final_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let tmp = final_path.with_file_name(format!(".tmp-{}-{name}", std::process::id()));
        self.staged.push((tmp.clone(), final_path.to_path_buf()));
        tmp
    }

    /// Moves every staged file into place. If a move fails, the temporary files not yet
    /// moved are removed (by `Drop`), so no `.tmp-*` file is left behind.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let mut done = Vec::new();
        while !self.staged.is_empty() {
            let (tmp, fin) = self.staged.remove(0);
            if let Err(e) = std::fs::rename(&tmp, &fin) {
                let _ = std::fs::remove_file(&tmp);
                return Err(anyhow::Error::new(e).context(format!("{}: cannot write", fin.display())));
            }
            done.push(fin);
        }
        Ok(done)
    }
}

impl Drop for AtomicFiles {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Writes a single file atomically (temporary file in the same directory, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!("{}: directory {} does not exist", path.display(), dir.display());
    }
    let mut files = AtomicFiles { staged: Vec::new() };
    let tmp = files.stage(path);
    std::fs::write(&tmp, bytes).with_context(|| format!("{}: cannot write", path.display()))?;
    files.commit()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compensation_lists_accept_aliases_and_reject_nonsense() {
        assert_eq!(parse_compensations("both").unwrap(), vec![Compensation::Off, Compensation::Patent]);
        assert_eq!(parse_compensations("on").unwrap(), vec![Compensation::Patent]);
        assert_eq!(parse_compensations("off, patent,on").unwrap(), vec![Compensation::Off, Compensation::Patent]);
        let e = parse_compensations("maybe").unwrap_err().to_string();
        assert!(e.contains("maybe"), "{e}");
        assert_eq!(parse_modes("both").unwrap(), vec![Mode::OpenLoop, Mode::Servo]);
        assert!(parse_modes("closed").is_err());
    }

    #[test]
    fn failed_atomic_writes_leave_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.csv");
        {
            let mut f = AtomicFiles::in_dir(dir.path()).unwrap();
            let tmp = f.stage(&target);
            std::fs::write(&tmp, b"x").unwrap();
            // Dropped without commit.
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_failed_move_leaves_no_temporary_file_behind() {
        let dir = tempfile::tempdir().unwrap();
        // The second target is an existing non-empty directory: renaming a file onto it fails.
        let blocker = dir.path().join("b.csv");
        std::fs::create_dir(&blocker).unwrap();
        std::fs::write(blocker.join("keep"), b"").unwrap();
        let mut f = AtomicFiles::in_dir(dir.path()).unwrap();
        for name in ["a.csv", "b.csv", "c.csv"] {
            let tmp = f.stage(&dir.path().join(name));
            std::fs::write(&tmp, b"x").unwrap();
        }
        let e = f.commit().unwrap_err().to_string();
        assert!(e.contains("b.csv") && e.contains("cannot write"), "{e}");
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, vec!["a.csv".to_string(), "b.csv".to_string()]);
    }
}
