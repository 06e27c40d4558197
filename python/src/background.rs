//! Long single calls of the core (reading a file, building a locator) run on a worker thread
//! while the calling thread waits without the GIL and checks for Ctrl-C every 100 ms: the core
//! has no cancellation points inside a build, so on Ctrl-C the caller gets `KeyboardInterrupt`
//! at once and the abandoned worker finishes in the background, its result dropped.

use crate::errors::internal_error;
use pyo3::prelude::*;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

/// How often the waiting thread checks for signals and ticks the progress callback.
const POLL: Duration = Duration::from_millis(100);

enum Message<T> {
    /// The worker entered its next stage (a short name for the progress bar).
    Stage(&'static str),
    Done(PyResult<T>),
}

/// What a job uses to name its stages.
pub struct Stages<'a, T>(&'a mpsc::Sender<Message<T>>);

impl<T> Stages<'_, T> {
    pub fn enter(&self, name: &'static str) {
        let _ = self.0.send(Message::Stage(name)); // the caller may be gone (Ctrl-C)
    }
}

/// Runs `job` on a worker thread. `progress`, when given, is called with the GIL as
/// `progress(stage, None, elapsed_seconds)` when a stage starts and on every poll, and as
/// `progress("done", 1.0, elapsed_seconds)` at the end.
pub fn run<T: Send + 'static>(
    py: Python<'_>,
    what: &'static str,
    progress: Option<&Bound<'_, PyAny>>,
    job: impl FnOnce(&Stages<T>) -> PyResult<T> + Send + 'static,
) -> PyResult<T> {
    let (tx, mut rx) = mpsc::channel();
    let worker = std::thread::Builder::new()
        .name(format!("tetloc {what}"))
        .spawn(move || {
            let result = crate::errors::guarded(what, || job(&Stages(&tx)));
            let _ = tx.send(Message::Done(result));
        })
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(format!("cannot start a thread for {what}: {e}")))?;
    let t0 = std::time::Instant::now();
    let mut stage = "starting";
    loop {
        // The receiver moves into the detached closure and back (a `&Receiver` is not `Send`).
        let msg;
        (rx, msg) = py.detach(move || {
            let msg = rx.recv_timeout(POLL);
            (rx, msg)
        });
        let tick = |stage: &str| {
            let fraction = (stage == "done").then_some(1.0);
            progress.map(|p| p.call1((stage, fraction, t0.elapsed().as_secs_f64()))).transpose()
        };
        match msg {
            Ok(Message::Stage(s)) => {
                stage = s;
                tick(stage)?;
            }
            Ok(Message::Done(result)) => {
                let _ = py.detach(|| worker.join());
                tick("done")?;
                return result;
            }
            Err(RecvTimeoutError::Timeout) => {
                py.check_signals()?;
                tick(stage)?;
            }
            // The worker ended without a result: only a panic outside `guarded` gets here.
            Err(RecvTimeoutError::Disconnected) => {
                let payload = py.detach(|| worker.join()).err();
                return Err(internal_error(
                    what,
                    payload.as_deref().unwrap_or(&"the worker thread ended without a result"),
                ));
            }
        }
    }
}
