//! Long Rust calls that Ctrl-C can stop (docs/python.md#interrupting-a-long-call).
//!
//! The work runs on a thread of its own with the GIL released, while the calling thread
//! (Python's main thread, the only one that sees signals) waits for it and, every
//! [`POLL`], takes the GIL briefly to run Python's signal handlers. A handler that raises
//! (Ctrl-C: `KeyboardInterrupt`) sets the stop flag the work polls through the library's
//! cancellation hook (`stepdamp_sim::run_while`, `sweep_until`, `Study::run_range_until`);
//! once the work has stopped, the handler's exception is returned. A panic in the work is
//! returned as a `StepdampError`, never as a `PanicException`.

use crate::err;
use pyo3::prelude::*;
use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

/// How often the waiting thread runs Python's signal handlers.
const POLL: Duration = Duration::from_millis(50);

/// Runs `work` (given the stop check it must poll) off the GIL; see the module's doc.
/// Returns `work`'s result, its error as a `StepdampError`, or the exception a signal
/// handler raised while it ran (then `work`'s own result is dropped).
pub(crate) fn interruptible<T, E>(
    py: Python<'_>,
    work: impl FnOnce(&(dyn Fn() -> bool + Sync)) -> Result<T, E> + Send,
) -> PyResult<T>
where
    T: Send,
    E: std::fmt::Display + Send,
{
    let stop = AtomicBool::new(false);
    let (result, signal) = py.allow_threads(|| {
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel();
            let stop = &stop;
            s.spawn(move || {
                let stopped = || stop.load(Ordering::Relaxed);
                let r = catch_unwind(AssertUnwindSafe(|| work(&stopped)));
                // The receiver waits until this is sent: it cannot be gone.
                let _ = tx.send(r);
            });
            let mut signal: Option<PyErr> = None;
            loop {
                match rx.recv_timeout(POLL) {
                    Ok(r) => return (r, signal),
                    Err(mpsc::RecvTimeoutError::Timeout) => {
                        if signal.is_none() {
                            if let Err(e) = Python::with_gil(|py| py.check_signals()) {
                                signal = Some(e);
                                stop.store(true, Ordering::Relaxed);
                            }
                        }
                    }
                    // Only if the worker thread died without sending, which catch_unwind
                    // prevents; reported, not panicked on.
                    Err(mpsc::RecvTimeoutError::Disconnected) => {
                        let e: Box<dyn Any + Send> = Box::new("the worker thread ended without a result");
                        return (Err(e), signal);
                    }
                }
            }
        })
    });
    if let Some(e) = signal {
        return Err(e);
    }
    // A signal that came after the last poll is raised now, before any Python object is made.
    py.check_signals()?;
    match result {
        Ok(r) => r.map_err(err),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(err(format!("internal error (please report it): {what}")))
        }
    }
}
