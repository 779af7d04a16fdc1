//! Several outputs that appear together or not at all.

use crate::cleanup::{Removal, Token, listing, registry, remove};
use crate::file::create_temp;
use crate::{OutError, OutErrorKind};
use std::path::{Path, PathBuf};

/// Files written side by side under temporary names and moved into place together by
/// [`OutputSet::commit`]; the moves hold the clean-up lock, so SIGINT/SIGTERM during them
/// waits until all are done. Dropped without commit (an error) or interrupted, the
/// temporaries are removed, and so is the output directory when this set created it.
#[derive(Debug)]
pub struct OutputSet {
    /// (temporary, target, path as given, registration)
    staged: Vec<(PathBuf, PathBuf, PathBuf, Token)>,
    /// The topmost directory this set created, removed with its contents unless committed.
    created: Option<(PathBuf, Token)>,
}

impl OutputSet {
    /// For outputs in `dir`, created (with its parents) if needed. A directory this call
    /// creates is removed again when the set is dropped without [`OutputSet::commit`] or
    /// the command is interrupted. Checks the directory is writable.
    pub fn in_dir(dir: &Path) -> Result<OutputSet, OutError> {
        let created = create_dir_tracked(dir)?;
        let set = OutputSet { staged: Vec::new(), created };
        let probe = tempfile::Builder::new().prefix(&crate::file::tmp_prefix()).tempfile_in(dir);
        probe.map_err(|e| OutError::new(dir, OutErrorKind::NotWritable(e)))?;
        Ok(set)
    }

    /// For outputs in `dir`, which must exist (nothing is created).
    pub fn in_existing_dir(dir: &Path) -> Result<OutputSet, OutError> {
        if !dir.is_dir() {
            return Err(OutError::new(dir, OutErrorKind::NoDirectory(dir.to_path_buf())));
        }
        Ok(OutputSet { staged: Vec::new(), created: None })
    }

    /// Creates an empty temporary file for `final_path` (same directory, same extension)
    /// and returns its path; write it (e.g. a plotting library given the path), then
    /// [`OutputSet::commit`]. A symlink at `final_path` is followed: its target is replaced.
    /// A device or FIFO cannot be part of a set (it cannot appear "together").
    pub fn stage(&mut self, final_path: &Path) -> Result<PathBuf, OutError> {
        let target = match crate::destination(final_path)? {
            crate::Destination::Staged { final_path } => final_path,
            _ => return Err(OutError::new(final_path, OutErrorKind::NotRegular)),
        };
        let (file, tmp, token) = create_temp(&target)?;
        drop(file);
        self.staged.push((tmp.clone(), target, final_path.to_path_buf(), token));
        Ok(tmp)
    }

    /// Moves every staged file into place, all under the clean-up lock, and returns their
    /// paths as given to [`OutputSet::stage`]. If a move fails, the files already moved
    /// stay (complete) and the rest are removed.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutError> {
        let mut reg = registry();
        if let Some((_, t)) = self.created.take() {
            reg.forget(t);
        }
        let mut done = Vec::new();
        let mut staged = std::mem::take(&mut self.staged).into_iter();
        while let Some((tmp, fin, given, token)) = staged.next() {
            if let Err(e) = std::fs::rename(&tmp, &fin) {
                let _ = std::fs::remove_file(&tmp);
                reg.forget(token);
                for (tmp, _, _, token) in staged {
                    let _ = std::fs::remove_file(&tmp);
                    reg.forget(token);
                }
                return Err(OutError::io(&given, e));
            }
            reg.forget(token);
            done.push(given);
        }
        Ok(done)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let mut reg = registry();
        for (tmp, _, _, token) in self.staged.drain(..) {
            let _ = std::fs::remove_file(&tmp);
            reg.forget(token);
        }
        if let Some((dir, token)) = self.created.take() {
            let _ = std::fs::remove_dir_all(&dir);
            reg.forget(token);
        }
    }
}

/// Creates `dir` and its missing parents; the topmost created one is registered for
/// removal (with its contents) on interruption. `None` when `dir` existed.
fn create_dir_tracked(dir: &Path) -> Result<Option<(PathBuf, Token)>, OutError> {
    if dir.is_dir() {
        return Ok(None);
    }
    if dir.exists() {
        return Err(OutError::new(dir, OutErrorKind::NotADirectory));
    }
    let mut top = dir;
    while let Some(p) = top.parent().filter(|p| !p.as_os_str().is_empty() && !p.exists()) {
        top = p;
    }
    let mut reg = registry();
    let token = reg.add(top, Removal::Tree);
    if let Err(e) = std::fs::create_dir_all(dir) {
        let _ = std::fs::remove_dir_all(top);
        reg.forget(token);
        return Err(OutError::new(dir, OutErrorKind::CannotCreateDir(e)));
    }
    Ok(Some((top.to_path_buf(), token)))
}

/// An output directory filled by several steps (each file written on its own, e.g. by
/// [`crate::write_file`] or [`OutputSet`]) that must end complete or not at all: when the
/// command fails (dropped without [`OutputDir::finish`]) or is interrupted, a directory it
/// created is removed with everything in it, and from a directory that existed every entry
/// it did not have before is removed (a file it had and this command replaced stays, with
/// its new contents).
#[derive(Debug)]
pub struct OutputDir {
    dir: PathBuf,
    /// The registered clean-up: the created directory, or the existing one's new entries.
    cleanup: Option<(PathBuf, Removal, Token)>,
}

impl OutputDir {
    /// Creates `dir` if needed (an existing path that is not a directory is an error) and
    /// checks it is writable.
    pub fn prepare(dir: &Path) -> Result<OutputDir, OutError> {
        let cleanup = match create_dir_tracked(dir)? {
            Some((top, token)) => (top, Removal::Tree, token),
            None => {
                let before = listing(dir).map_err(|e| OutError::io(dir, e))?;
                let removal = Removal::NewIn(before);
                let token = registry().add(dir, removal.clone());
                (dir.to_path_buf(), removal, token)
            }
        };
        let d = OutputDir { dir: dir.to_path_buf(), cleanup: Some(cleanup) };
        let probe = tempfile::Builder::new().prefix(&crate::file::tmp_prefix()).tempfile_in(dir);
        probe.map_err(|e| OutError::new(dir, OutErrorKind::NotWritable(e)))?;
        Ok(d)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// The outputs are complete: keep them.
    pub fn finish(mut self) {
        if let Some((_, _, t)) = self.cleanup.take() {
            registry().forget(t);
        }
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if let Some((path, removal, t)) = self.cleanup.take() {
            let mut reg = registry();
            remove(&path, &removal);
            reg.forget(t);
        }
    }
}
