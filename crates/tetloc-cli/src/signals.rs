//! Ending quietly and cleanly: SIGINT, SIGTERM and SIGHUP remove the temporaries of the
//! outputs being written and end the process with the shell's code for the signal (128 + N:
//! 130 for SIGINT, 143 for SIGTERM; `output::remove_temporaries_then_exit`, which no new
//! temporary can slip past); a panic removes them too,
//! and so does SIGABRT (an abort, such as a failed allocation's, or `kill -ABRT`), which then
//! ends the process as SIGABRT does.
//! A closed stdout (`tetloc info m.vtu | head -1`) ends the command quietly with exit code 0,
//! as ripgrep does, instead of a panic message; another failure to write it (a full disk) is
//! an error. (Messages to stderr never panic: `main.rs`'s `eprintln!`.)

use signal_hook::consts::{SIGABRT, SIGHUP, SIGINT, SIGTERM};
use signal_hook::iterator::Signals;
use std::sync::atomic::{AtomicBool, Ordering};
use tetloc_io::output;

/// A server (`tetloc view`) is running: Ctrl-C and SIGTERM are how it stops, with exit code 0.
static SERVING: AtomicBool = AtomicBool::new(false);

/// From now on SIGINT and SIGTERM end the process with exit code 0 (a server's normal stop).
pub fn exit_zero_on_interrupt() {
    SERVING.store(true, Ordering::SeqCst);
}

/// Installs the signal thread and the panic hook; call first thing in `main`.
pub fn install() {
    // Rust ignores SIGPIPE: a write to a closed stdout fails with EPIPE, and `println!`
    // panics on it; the hook below turns that panic into a quiet exit.
    match Signals::new([SIGINT, SIGTERM, SIGHUP]) {
        Ok(mut signals) => {
            std::thread::spawn(move || {
                if let Some(sig) = signals.forever().next() {
                    let stop = sig == SIGINT || sig == SIGTERM;
                    output::remove_temporaries_then_exit(if stop && SERVING.load(Ordering::SeqCst) {
                        0
                    } else {
                        128 + sig
                    });
                }
            });
        }
        Err(e) => eprintln!("warning: no signal handler ({e}): an interrupted run may leave temporary files"),
    }
    // An abort runs nothing after its signal: the handler removes the temporaries in the
    // signal's own thread, then ends the process as SIGABRT's default action does (a handler
    // that returned would let a `kill -ABRT` go unheeded).
    // SAFETY: `register` wants a handler that is safe inside a signal. Ours waits for no lock
    // (`remove_temporaries_on_abort` only tries the list's), so it cannot deadlock on one the
    // aborting thread holds; its file removals allocate small path buffers, which is sound
    // here because an abort for a failed allocation is raised after the allocator returned
    // (its lock free), and the process ends right after. `emulate_default_handler` restores
    // SIG_DFL and raises the signal again.
    let registered = unsafe {
        signal_hook::low_level::register(SIGABRT, || {
            output::remove_temporaries_on_abort();
            let _ = signal_hook::low_level::emulate_default_handler(SIGABRT);
        })
    };
    if let Err(e) = registered {
        eprintln!("warning: no SIGABRT handler ({e}): an aborted run may leave temporary files");
    }
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        output::remove_temporaries();
        match stdout_failure(info.payload()) {
            Some(StdoutFailure::Closed) => std::process::exit(0),
            // Another write error (a full disk, /dev/full): an error, not a panic's report.
            Some(StdoutFailure::Other(text)) => {
                use std::io::Write as _;
                let _ = writeln!(std::io::stderr(), "error: {text}");
                std::process::exit(1);
            }
            None => default(info),
        }
    }));
}

/// How `println!` failed, where a panic (its payload) is its failure to write to stdout.
enum StdoutFailure {
    /// A closed pipe (`| head -1`): the reader has what it wants.
    Closed,
    Other(String),
}

fn stdout_failure(payload: &(dyn std::any::Any + Send)) -> Option<StdoutFailure> {
    let text = payload.downcast_ref::<String>().map(String::as_str).or_else(|| payload.downcast_ref::<&str>().copied());
    let text = text.filter(|t| t.starts_with("failed printing to stdout"))?;
    Some(if text.contains("Broken pipe") { StdoutFailure::Closed } else { StdoutFailure::Other(text.to_string()) })
}
