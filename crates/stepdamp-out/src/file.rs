//! One output file: staged beside its target and renamed into place, or written straight
//! through to a device, FIFO or standard output.

use crate::cleanup::{Removal, Token, registry};
use crate::{OutError, OutErrorKind};
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Where the bytes of an [`Output`] go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Destination {
    /// A regular file, or a path that does not exist yet: written to a temporary file in
    /// the same directory and renamed over `final_path` when complete. `final_path` is the
    /// symlink's target when the path given was a symlink (the link stays a link).
    Staged {
        /// The file replaced (or created) on commit.
        final_path: PathBuf,
    },
    /// A device, FIFO, socket, `/dev/std*`, `/dev/fd/*` or `/proc/…`: opened and written in
    /// place, never replaced.
    Direct,
    /// `-`: standard output.
    Stdout,
}

/// Where writing to `path` goes, following symlinks (also dangling ones, whose target is
/// then created). Errors: `path` is a directory, or its directory does not exist.
pub fn destination(path: &Path) -> Result<Destination, OutError> {
    if path.as_os_str() == "-" {
        return Ok(Destination::Stdout);
    }
    // Paths that name an open descriptor or a kernel file are written in place even when
    // they resolve to a regular file (`--log /dev/stdout > run.csv`): renaming over the
    // file would detach it from the descriptor the shell holds.
    if ["/dev/", "/proc/"].iter().any(|p| path.starts_with(p)) {
        return match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => Err(OutError::new(path, OutErrorKind::IsDirectory)),
            _ => Ok(Destination::Direct),
        };
    }
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(OutError::new(path, OutErrorKind::IsDirectory)),
        Ok(m) if m.is_file() => {
            let final_path = std::fs::canonicalize(path).map_err(|e| OutError::io(path, e))?;
            Ok(Destination::Staged { final_path })
        }
        Ok(_) => Ok(Destination::Direct),
        Err(e) if matches!(e.kind(), io::ErrorKind::NotFound | io::ErrorKind::NotADirectory) => {
            let final_path = follow_dangling(path)?;
            let dir = parent_dir(&final_path);
            if !dir.is_dir() {
                return Err(OutError::new(path, OutErrorKind::NoDirectory(dir.to_path_buf())));
            }
            Ok(Destination::Staged { final_path })
        }
        Err(e) => Err(OutError::io(path, e)),
    }
}

/// The path a (possibly dangling) chain of symlinks ends at; `path` itself when it is not
/// a symlink.
fn follow_dangling(path: &Path) -> Result<PathBuf, OutError> {
    let mut p = path.to_path_buf();
    // Linux's own limit on symlinks followed in one lookup.
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&p).map_err(|e| OutError::io(path, e))?;
                p = parent_dir(&p).join(target);
            }
            _ => return Ok(p),
        }
    }
    Err(OutError::new(path, OutErrorKind::SymlinkLoop))
}

/// The directory a file path is in (`.` for a bare name).
pub fn parent_dir(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// The prefix of every temporary name: `.tmp-<pid>-`.
pub(crate) fn tmp_prefix() -> String {
    format!(".tmp-{}-", std::process::id())
}

/// Creates an empty temporary file beside `final_path` (same directory, name
/// `.tmp-<pid>-<random>-<file name>`, so the extension is kept), registered for removal on
/// interruption before it exists. First removes the temporaries for the same target that
/// killed processes left ([`remove_stale_temps`]). Permissions: those of the file it will replace, else
/// 0666 less the umask (as a plain create would give).
pub(crate) fn create_temp(final_path: &Path) -> Result<(File, PathBuf, Token), OutError> {
    let dir = parent_dir(final_path);
    let name = final_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    remove_stale_temps(dir, &name);
    let suffix = format!("-{name}");
    let prefix = tmp_prefix();
    let mut b = tempfile::Builder::new();
    b.prefix(&prefix).suffix(&suffix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        b.permissions(std::fs::Permissions::from_mode(0o666));
    }
    // Created and registered under the registry's lock: a signal cannot fall in between.
    let mut reg = registry();
    let tmp = b.tempfile_in(dir).map_err(|e| OutError::io(final_path, e))?;
    let (file, tmp_path) = tmp.keep().map_err(|e| OutError::io(final_path, e.error))?;
    let token = reg.add(&tmp_path, Removal::File);
    drop(reg);
    if let Ok(m) = std::fs::metadata(final_path)
        && m.is_file()
    {
        let _ = std::fs::set_permissions(&tmp_path, m.permissions());
    }
    Ok((file, tmp_path, token))
}

/// The process id in `file_name` if it is a temporary of ours for the target named
/// `target_name`: `.tmp-<pid>-<random>-<target name>`, with `<random>` alphanumeric.
fn temp_owner(file_name: &str, target_name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix(".tmp-")?;
    let (pid, rest) = rest.split_once('-')?;
    let random = rest.strip_suffix(target_name)?.strip_suffix('-')?;
    let ours = !random.is_empty() && random.bytes().all(|b| b.is_ascii_alphanumeric());
    let digits = !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit());
    if ours && digits { pid.parse().ok() } else { None }
}

/// Whether process `pid` is known to be gone: on Linux, `/proc/<pid>` does not exist (with
/// `/proc` mounted). Elsewhere, or without `/proc`, nothing is known to be gone.
fn process_gone(pid: u32) -> bool {
    Path::new("/proc/self").exists() && !Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes the temporaries for the target `target_name` in `dir` that a process left
/// behind when it was killed without a chance to clean up (SIGKILL, a power cut): regular
/// files named by [`temp_owner`]'s pattern whose process is gone. Temporaries of live
/// processes (another run writing the same file), other files, symlinks and directories
/// are left alone; errors are ignored (the write itself reports a real problem).
fn remove_stale_temps(dir: &Path, target_name: &str) {
    if target_name.is_empty() {
        return;
    }
    let own = std::process::id();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| temp_owner(n, target_name)) else { continue };
        let regular = entry.file_type().is_ok_and(|t| t.is_file());
        if regular && pid != own && process_gone(pid) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Renames a registered temporary over its target and unregisters it, under the lock.
pub(crate) fn move_into_place(tmp: &Path, final_path: &Path, token: Token) -> io::Result<()> {
    let mut reg = registry();
    let r = std::fs::rename(tmp, final_path);
    if r.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    reg.forget(token);
    r
}

enum Sink {
    Staged { file: io::BufWriter<File>, tmp: PathBuf, final_path: PathBuf, token: Token },
    Direct(io::BufWriter<File>),
    Stdout(io::Stdout),
    Done,
}

/// An output file being written. Nothing appears at the target until [`Output::commit`]
/// (for a regular file); dropped without commit, or on SIGINT/SIGTERM, the temporary file
/// is removed and the target is as it was.
///
/// ```
/// use std::io::Write;
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("run.csv");
/// let mut out = stepdamp_out::Output::create(&path).unwrap();
/// writeln!(out, "t_s").unwrap();
/// assert!(!path.exists());
/// out.commit().unwrap();
/// assert_eq!(std::fs::read_to_string(&path).unwrap(), "t_s\n");
/// ```
pub struct Output {
    path: PathBuf,
    sink: Sink,
}

impl Output {
    /// Opens `path` for writing (see [`destination`]).
    pub fn create(path: &Path) -> Result<Output, OutError> {
        let sink = match destination(path)? {
            Destination::Stdout => Sink::Stdout(io::stdout()),
            Destination::Direct => {
                let f = File::options().write(true).open(path).map_err(|e| OutError::io(path, e))?;
                Sink::Direct(io::BufWriter::with_capacity(1 << 16, f))
            }
            Destination::Staged { final_path } => {
                let (f, tmp, token) = create_temp(&final_path)?;
                Sink::Staged { file: io::BufWriter::with_capacity(1 << 20, f), tmp, final_path, token }
            }
        };
        Ok(Output { path: path.to_path_buf(), sink })
    }

    /// The path as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes and moves the file into place (renames the temporary over the target, or
    /// flushes a device or standard output). Returns the path as given.
    pub fn commit(mut self) -> Result<PathBuf, OutError> {
        let path = self.path.clone();
        match std::mem::replace(&mut self.sink, Sink::Done) {
            Sink::Staged { file, tmp, final_path, token } => {
                let done = file.into_inner().map_err(|e| e.into_error()).and_then(|f| f.sync_all());
                if let Err(e) = done {
                    let mut reg = registry();
                    let _ = std::fs::remove_file(&tmp);
                    reg.forget(token);
                    return Err(OutError::io(&path, e));
                }
                move_into_place(&tmp, &final_path, token).map_err(|e| OutError::io(&path, e))?;
            }
            Sink::Direct(mut w) => w.flush().map_err(|e| OutError::io(&path, e))?,
            Sink::Stdout(mut s) => s.flush().map_err(|e| OutError::io(&path, e))?,
            Sink::Done => {}
        }
        Ok(path)
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.sink {
            Sink::Staged { file, .. } => file.write(buf),
            Sink::Direct(w) => w.write(buf),
            Sink::Stdout(s) => s.write(buf),
            Sink::Done => Err(io::Error::other("output already committed")),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match &mut self.sink {
            Sink::Staged { file, .. } => file.write_all(buf),
            Sink::Direct(w) => w.write_all(buf),
            Sink::Stdout(s) => s.write_all(buf),
            Sink::Done => Err(io::Error::other("output already committed")),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.sink {
            Sink::Staged { file, .. } => file.flush(),
            Sink::Direct(w) => w.flush(),
            Sink::Stdout(s) => s.flush(),
            Sink::Done => Ok(()),
        }
    }
}

impl Drop for Output {
    fn drop(&mut self) {
        if let Sink::Staged { tmp, token, .. } = std::mem::replace(&mut self.sink, Sink::Done) {
            let mut reg = registry();
            let _ = std::fs::remove_file(&tmp);
            reg.forget(token);
        }
    }
}

/// Writes `bytes` to `path` as one [`Output`]: complete or not at all.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), OutError> {
    let mut out = Output::create(path)?;
    out.write_all(bytes).map_err(|e| OutError::io(path, e))?;
    out.commit()?;
    Ok(())
}
