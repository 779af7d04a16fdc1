//! Shared command-line pieces: motor loading, lists of modes and compensations, atomic
//! output, progress bars.

use anyhow::{Context, Result, anyhow};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use stepdamp_core::Mode;
use stepdamp_sim::{Compensation, Profile, SimError};

/// Loads a preset or a TOML profile, with the reason on failure.
pub fn load_motor(name_or_path: &str) -> Result<Profile> {
    Profile::load(name_or_path).map_err(|e| anyhow!("{e}"))
}

/// How a command prints its result.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// For people (the result type's `Display`).
    #[default]
    Text,
    /// One JSON object (the result type's `Serialize`), for scripts.
    Json,
}

/// How a command that prints a table prints it.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TableFormat {
    /// For people (the result type's `Display`).
    #[default]
    Text,
    /// One JSON object (the result type's `Serialize`), for scripts.
    Json,
    /// CSV with a header row, units in the column names.
    Csv,
}

/// Prints `value` as one line of JSON on standard output.
pub fn print_json(value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string(value).context("cannot serialise the result")?;
    outln!("{text}");
    Ok(())
}

/// A simulation error naming the command-line flag that set the value, where one did:
/// `flags` maps the error's `what` ([`SimError::Option`]) to a flag, after the options every
/// simulating command shares (`--substeps`, `--current-noise`, `--load-torque`).
pub fn sim_error_with_flag(e: SimError, flags: &[(&str, &str)]) -> anyhow::Error {
    const SHARED: [(&str, &str); 3] =
        [("substeps", "--substeps"), ("current noise", "--current-noise"), ("load torque", "--load-torque")];
    match e {
        SimError::Option { what, reason } => match flags.iter().chain(&SHARED).find(|(w, _)| *w == what) {
            Some((_, flag)) => anyhow!("{flag} {reason}"),
            None => SimError::Option { what, reason }.into(),
        },
        e => e.into(),
    }
}

/// A clap value parser for a library's named choice (made with
/// `stepdamp_core::named_choice!`): clap lists the names of `all` as the possible values (in
/// the help, and in the error with the value as written), and the choice's own `FromStr`
/// parses them, so the names have one home, the library's table.
pub fn choice_parser<T>(all: &'static [T], name: fn(T) -> &'static str) -> impl TypedValueParser<Value = T>
where
    T: Copy + FromStr + Send + Sync + 'static,
    T::Err: std::error::Error + Send + Sync + 'static,
{
    PossibleValuesParser::new(all.iter().map(|&c| name(c))).try_map(|s| s.parse::<T>())
}

/// A comma list of choices from the command line (a typed clap value): the choices in the
/// order given, without repeats, and the text as written (for messages).
#[derive(Clone, Debug, PartialEq)]
pub struct ChoiceList<T> {
    /// The choices, aliases expanded.
    pub items: Vec<T>,
    /// The option's value as written.
    pub written: String,
}

impl<T> std::fmt::Display for ChoiceList<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.written)
    }
}

/// `--mode`: a comma list of the core's names (`open-loop`, `servo`; [`Mode::name`]), the
/// aliases `openloop` and `ol`, and `both`. The error names the entry as written and the
/// names allowed.
pub fn parse_modes(s: &str) -> Result<ChoiceList<Mode>, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim) {
        match part {
            "both" => Mode::ALL.iter().for_each(|&m| push_unique(&mut out, m)),
            "openloop" | "ol" => push_unique(&mut out, Mode::OpenLoop),
            name => push_unique(
                &mut out,
                name.parse().map_err(|e| format!("'{part}': {e} or both (a comma list is allowed)"))?,
            ),
        }
    }
    Ok(ChoiceList { items: out, written: s.to_string() })
}

/// `--compensation`: a comma list of the core's names (`off`, `patent`, `estimated`,
/// `angle`, `table`; [`Compensation::name`]), the alias `on` (= `patent`), and `both` (=
/// `off,patent`). The error names the entry as written and the names allowed.
pub fn parse_compensations(s: &str) -> Result<ChoiceList<Compensation>, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim) {
        match part {
            "on" => push_unique(&mut out, Compensation::Patent),
            "both" => {
                push_unique(&mut out, Compensation::Off);
                push_unique(&mut out, Compensation::Patent);
            }
            name => push_unique(
                &mut out,
                name.parse().map_err(|e| {
                    format!("'{part}': {e} (or on = patent, both = off,patent); a comma list is allowed")
                })?,
            ),
        }
    }
    Ok(ChoiceList { items: out, written: s.to_string() })
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

/// Standard output was closed by its reader (`stepdamp … | head -1`): not an error, the
/// command ends quietly with status 0 (see `main`).
#[derive(Debug)]
pub struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("standard output was closed")
    }
}

impl std::error::Error for StdoutClosed {}

/// Writes to `w` (standard output: use the `out!`/`outln!` macros): a closed pipe becomes
/// [`StdoutClosed`], any other failure an error naming standard output.
pub fn write_out(mut w: impl Write, args: std::fmt::Arguments<'_>) -> Result<()> {
    match w.write_fmt(args).and_then(|()| w.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(anyhow::Error::new(e).context("cannot write to standard output")),
    }
}

/// Files written side by side and moved into place only when all are complete, so an
/// error or an interruption (SIGINT/SIGTERM) leaves nothing half-written (see
/// [`stepdamp_out::OutputSet`]).
pub struct AtomicFiles(stepdamp_out::OutputSet);

impl AtomicFiles {
    /// Creates `dir` (and parents) and checks it is writable. A directory created here is
    /// removed again if the files are not committed (an error or an interruption).
    pub fn in_dir(dir: &Path) -> Result<Self> {
        Ok(AtomicFiles(stepdamp_out::OutputSet::in_dir(dir)?))
    }

    /// The same as [`AtomicFiles::in_dir`] (kept for its callers' clarity).
    pub fn in_dir_removed_on_failure(dir: &Path) -> Result<Self> {
        Self::in_dir(dir)
    }

    /// A temporary path to write `final_path` to (same directory, same extension).
    pub fn stage(&mut self, final_path: &Path) -> Result<PathBuf> {
        Ok(self.0.stage(final_path)?)
    }

    /// Moves every staged file into place (a signal waits until all are moved).
    pub fn commit(self) -> Result<Vec<PathBuf>> {
        Ok(self.0.commit()?)
    }
}

/// Writes a single file completely or not at all (see [`stepdamp_out::Output`]: a device,
/// FIFO or `-` is written straight through, a symlink keeps its link).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Ok(stepdamp_out::write_file(path, bytes)?)
}

/// Whether an error is (caused by) the reader closing standard output or the pipe an
/// output was written to (`--log /dev/stdout | head`).
pub fn is_stdout_closed(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.is::<StdoutClosed>() || c.downcast_ref::<stepdamp_out::OutError>().is_some_and(|o| o.is_broken_pipe())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compensation_lists_accept_aliases_and_reject_nonsense() {
        let comps = |s| parse_compensations(s).map(|l| l.items);
        let modes = |s| parse_modes(s).map(|l| l.items);
        assert_eq!(comps("both").unwrap(), vec![Compensation::Off, Compensation::Patent]);
        assert_eq!(comps("on").unwrap(), vec![Compensation::Patent]);
        assert_eq!(comps("off, patent,on").unwrap(), vec![Compensation::Off, Compensation::Patent]);
        assert_eq!(parse_compensations("off, patent,on").unwrap().to_string(), "off, patent,on");
        let e = comps("off,maybe").unwrap_err();
        assert!(e.contains("'maybe'") && e.contains("expected off, patent, estimated, angle, table"), "{e}");
        assert_eq!(modes("both").unwrap(), vec![Mode::OpenLoop, Mode::Servo]);
        let e = modes("closed").unwrap_err();
        assert!(e.contains("'closed'") && e.contains("expected open-loop, servo or both"), "{e}");
        // The core's names are the CLI's.
        for &m in Mode::ALL {
            assert_eq!(modes(m.name()).unwrap(), vec![m]);
        }
        for &c in Compensation::ALL {
            assert_eq!(comps(c.name()).unwrap(), vec![c]);
        }
    }

    #[test]
    fn a_closed_pipe_is_a_quiet_stop_and_other_write_errors_are_errors() {
        struct Fails(std::io::ErrorKind);
        impl Write for Fails {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(self.0.into())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let e = write_out(Fails(std::io::ErrorKind::BrokenPipe), format_args!("x {}", 1)).unwrap_err();
        assert!(is_stdout_closed(&e), "{e:#}");
        assert!(is_stdout_closed(&e.context("while printing")));
        let e = write_out(Fails(std::io::ErrorKind::StorageFull), format_args!("x")).unwrap_err();
        assert!(!is_stdout_closed(&e) && format!("{e:#}").contains("standard output"), "{e:#}");
        let mut buf = Vec::new();
        write_out(&mut buf, format_args!("a {}\n", 2)).unwrap();
        assert_eq!(buf, b"a 2\n");
    }

    #[test]
    fn an_output_directory_created_for_a_failed_command_is_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new/deeper");
        {
            let mut f = AtomicFiles::in_dir_removed_on_failure(&out).unwrap();
            let tmp = f.stage(&out.join("a.csv")).unwrap();
            std::fs::write(&tmp, b"x").unwrap();
            // Dropped without commit.
        }
        assert!(files(dir.path()).is_empty(), "{:?}", files(dir.path()));
        // Nothing staged and nothing committed: the new directory goes too.
        drop(AtomicFiles::in_dir(&out).unwrap());
        assert!(files(dir.path()).is_empty(), "{:?}", files(dir.path()));
        // A committed directory stays, and so does an existing one.
        let mut f = AtomicFiles::in_dir_removed_on_failure(&out).unwrap();
        let tmp = f.stage(&out.join("a.csv")).unwrap();
        std::fs::write(&tmp, b"x").unwrap();
        f.commit().unwrap();
        drop(AtomicFiles::in_dir_removed_on_failure(&out).unwrap());
        assert_eq!(files(&out), ["a.csv"]);
    }

    fn files(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn failed_atomic_writes_leave_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.csv");
        {
            let mut f = AtomicFiles::in_dir(dir.path()).unwrap();
            let tmp = f.stage(&target).unwrap();
            std::fs::write(&tmp, b"x").unwrap();
            // Dropped without commit.
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_failed_move_leaves_no_temporary_file_behind() {
        let dir = tempfile::tempdir().unwrap();
        let mut f = AtomicFiles::in_dir(dir.path()).unwrap();
        for name in ["a.csv", "b.csv", "c.csv"] {
            let tmp = f.stage(&dir.path().join(name)).unwrap();
            std::fs::write(&tmp, b"x").unwrap();
        }
        // The second target becomes a non-empty directory after staging: renaming a file
        // onto it fails.
        let blocker = dir.path().join("b.csv");
        std::fs::create_dir(&blocker).unwrap();
        std::fs::write(blocker.join("keep"), b"").unwrap();
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
