//! Outputs that are never half-written and never destroy what they replace, and inputs
//! read with a bound.
//!
//! * [`Output`] / [`write_file`]: one file. A regular file (or a path that does not exist
//!   yet) is written to a temporary file beside it (`.tmp-<pid>-…`) and renamed over it when
//!   complete; a symlink is followed and its target replaced (the link stays); a device, FIFO,
//!   `/dev/std*`, `/proc/…` or `-` (standard output) is written straight through, never replaced.
//! * [`OutputSet`]: several files moved into place together; [`OutputDir`]: a directory
//!   filled step by step that is removed again if the command fails.
//! * On SIGINT, SIGTERM or SIGHUP every temporary file and every directory the command
//!   created is removed before the process ends (see `cleanup`). SIGKILL cannot be
//!   caught: its temporary stays until the next write to the same target, which removes
//!   the temporaries of that target whose process is gone (Linux: no `/proc/<pid>`).
//! * [`input`]: reading with a byte bound, a line-length bound, and messages that never
//!   echo non-printable bytes.

mod cleanup;
mod file;
pub mod input;
mod set;

pub use file::{Destination, Output, destination, parent_dir, write_file};
pub use set::{OutputDir, OutputSet};

use std::path::{Path, PathBuf};

/// Why an output could not be written; the message names the path.
#[derive(Debug)]
pub struct OutError {
    /// The path as given.
    pub path: PathBuf,
    /// What went wrong.
    pub kind: OutErrorKind,
}

/// What went wrong with an output.
#[derive(Debug)]
pub enum OutErrorKind {
    /// The path is a directory.
    IsDirectory,
    /// The path exists and is not a directory (where one is needed).
    NotADirectory,
    /// The directory the file would go in does not exist.
    NoDirectory(PathBuf),
    /// The directory could not be created.
    CannotCreateDir(std::io::Error),
    /// The directory is not writable.
    NotWritable(std::io::Error),
    /// A device or FIFO given where files must appear together.
    NotRegular,
    /// Too many levels of symlinks.
    SymlinkLoop,
    /// Reading or writing failed.
    Io(std::io::Error),
}

impl OutError {
    pub(crate) fn new(path: &Path, kind: OutErrorKind) -> OutError {
        OutError { path: path.to_path_buf(), kind }
    }

    pub(crate) fn io(path: &Path, e: std::io::Error) -> OutError {
        OutError::new(path, OutErrorKind::Io(e))
    }

    /// Whether the reader of a pipe or FIFO went away (`--log /dev/stdout | head`): not a
    /// failure of the command.
    pub fn is_broken_pipe(&self) -> bool {
        matches!(&self.kind, OutErrorKind::Io(e) if e.kind() == std::io::ErrorKind::BrokenPipe)
    }
}

impl std::fmt::Display for OutError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = self.path.display();
        match &self.kind {
            OutErrorKind::IsDirectory => write!(f, "{p}: is a directory (expected a file)"),
            OutErrorKind::NotADirectory => write!(f, "{p}: exists and is not a directory"),
            OutErrorKind::NoDirectory(d) => write!(f, "{p}: directory {} does not exist", d.display()),
            OutErrorKind::CannotCreateDir(e) => write!(f, "{p}: cannot create the output directory: {e}"),
            OutErrorKind::NotWritable(e) => write!(f, "{p}: output directory is not writable: {e}"),
            OutErrorKind::NotRegular => {
                write!(f, "{p}: is a device or FIFO; this output is a set of files, give a directory of files")
            }
            OutErrorKind::SymlinkLoop => write!(f, "{p}: too many levels of symbolic links"),
            OutErrorKind::Io(e) => write!(f, "{p}: cannot write: {e}"),
        }
    }
}

/// The message is complete in itself (it includes the system's reason), so there is no
/// separate source: printing the chain would say it twice.
impl std::error::Error for OutError {}
