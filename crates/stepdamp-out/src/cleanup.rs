//! What to remove when the command fails or is interrupted.
//!
//! Every temporary file, staging path and directory a command creates is registered here
//! *before* it is created and unregistered when it has been moved into place (or removed).
//! On SIGINT, SIGTERM or SIGHUP a background thread (from `signal-hook`) takes the registry's
//! lock, removes everything still registered, and then lets the signal take its default
//! action (the process ends "killed by SIGINT", as without the handler).
//!
//! Moving outputs into place also holds the lock, so a signal arriving during the moves
//! waits until they are all done: a set of outputs appears complete or not at all.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, Once, PoisonError};

/// How a registered path is removed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Removal {
    /// A file (or a path that may not exist yet).
    File,
    /// A directory and everything in it (a directory this command created).
    Tree,
    /// The entries of an existing directory that are not in this list (those the command
    /// added), each with everything in it.
    NewIn(Vec<std::ffi::OsString>),
}

#[derive(Debug)]
struct Entry {
    id: u64,
    path: PathBuf,
    removal: Removal,
}

#[derive(Debug, Default)]
pub(crate) struct Registry {
    next: u64,
    entries: Vec<Entry>,
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry { next: 0, entries: Vec::new() });
static HANDLER: Once = Once::new();

/// A registered path: removed on interruption until [`Registry::forget`] is called.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Token(u64);

impl Registry {
    /// Registers `path`; it is removed on interruption until forgotten.
    pub(crate) fn add(&mut self, path: &Path, removal: Removal) -> Token {
        self.next += 1;
        self.entries.push(Entry { id: self.next, path: path.to_path_buf(), removal });
        Token(self.next)
    }

    /// Stops tracking a path (it was moved into place or removed).
    pub(crate) fn forget(&mut self, t: Token) {
        self.entries.retain(|e| e.id != t.0);
    }

    /// Removes every registered path, newest first (files inside a created directory go
    /// before the directory).
    fn remove_all(&mut self) {
        for e in self.entries.drain(..).rev() {
            remove(&e.path, &e.removal);
        }
    }
}

/// Removes a path, ignoring a path that is already gone.
pub(crate) fn remove(path: &Path, removal: &Removal) {
    let _ = match removal {
        Removal::File => std::fs::remove_file(path),
        Removal::Tree => std::fs::remove_dir_all(path),
        Removal::NewIn(keep) => {
            for e in std::fs::read_dir(path).into_iter().flatten().flatten() {
                if !keep.contains(&e.file_name()) {
                    let p = e.path();
                    let _ = std::fs::remove_file(&p).or_else(|_| std::fs::remove_dir_all(&p));
                }
            }
            Ok(())
        }
    };
}

/// The names in a directory now (for [`Removal::NewIn`]).
pub(crate) fn listing(dir: &Path) -> std::io::Result<Vec<std::ffi::OsString>> {
    std::fs::read_dir(dir)?.map(|e| e.map(|e| e.file_name())).collect()
}

/// The registry, locked; the signal handler is installed on first use.
pub(crate) fn registry() -> MutexGuard<'static, Registry> {
    install_handler();
    REGISTRY.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Installs the SIGINT/SIGTERM/SIGHUP clean-up (once; does nothing if the signals cannot
/// be hooked, e.g. in a sandbox: then an interruption may leave temporaries, as before).
fn install_handler() {
    HANDLER.call_once(|| {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
            return;
        };
        let spawned = std::thread::Builder::new().name("stepdamp-out-cleanup".into()).spawn(move || {
            if let Some(sig) = signals.forever().next() {
                // Held until the process ends: no new temporary appears after the clean-up.
                let mut reg = REGISTRY.lock().unwrap_or_else(PoisonError::into_inner);
                reg.remove_all();
                let _ = signal_hook::low_level::emulate_default_handler(sig);
                // A signal whose default is not to end the process (none of ours): end anyway.
                std::process::exit(128 + sig);
            }
        });
        drop(spawned);
    });
}
