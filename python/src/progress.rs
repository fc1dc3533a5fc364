//! Running a render off the Python thread: progress reported to a Python callable on the
//! caller's thread, and Ctrl-C (or an exception from the callable) cancelling the render
//! through the library's cancel flag.

use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

/// How often the caller's thread wakes while a render runs: it reports progress and checks
/// for Ctrl-C this often. Short enough that Ctrl-C feels immediate, long enough that the
/// waking costs nothing measurable (a few microseconds each).
const POLL: Duration = Duration::from_millis(50);

/// Runs `work` (which must honour the cancel flag and call the progress function it is given,
/// as [`meshtracer::render::render`] does) on a thread of its own while this thread, without the
/// GIL between polls, calls `progress(done, total)` when the count moved and checks for signals.
/// A callable that raises, or a signal handler that raises (Ctrl-C: `KeyboardInterrupt`),
/// sets the cancel flag, waits for `work` to stop, and returns that exception. When `work`
/// finishes, `progress` is called a last time with its final count, so the counts a callable
/// sees increase and end at the total.
pub fn run_cancellable<T: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&AtomicBool, &(dyn Fn(u64, u64) + Sync)) -> T + Send,
) -> PyResult<T> {
    let cancel = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let total = AtomicU64::new(0);
    let finished = (Mutex::new(false), Condvar::new());
    let report = |d: u64, t: u64| {
        done.fetch_max(d, Ordering::Relaxed);
        total.store(t, Ordering::Relaxed);
    };
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let result = work(&cancel, &report);
            if let Ok(mut flag) = finished.0.lock() {
                *flag = true;
            }
            finished.1.notify_all();
            result
        });
        let mut reported = 0;
        let mut failure = None;
        loop {
            let over = py.detach(|| {
                let Ok(flag) = finished.0.lock() else {
                    return true;
                };
                match finished.1.wait_timeout_while(flag, POLL, |f| !*f) {
                    Ok((flag, _)) => *flag,
                    Err(_) => true,
                }
            });
            let now = done.load(Ordering::Relaxed);
            if let Some(callable) = progress.filter(|_| now > reported) {
                reported = now;
                if let Err(error) = callable.call1((now, total.load(Ordering::Relaxed))) {
                    failure = Some(error);
                }
            }
            if failure.is_none() && !over {
                failure = py.check_signals().err();
            }
            if failure.is_some() {
                // The worker stops at its next tile.
                cancel.store(true, Ordering::Relaxed);
                break;
            }
            if over {
                break;
            }
        }
        let joined = worker.join();
        match (failure, joined) {
            (Some(error), _) => Err(error),
            (None, Ok(result)) => Ok(result),
            (None, Err(panic)) => std::panic::resume_unwind(panic),
        }
    })
}
