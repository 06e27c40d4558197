//! Ending quietly and cleanly: SIGINT, SIGTERM and SIGHUP remove the temporaries of the
//! outputs being written (`output::remove_temporaries`) and end the process with the shell's
//! code for the signal (128 + N: 130 for SIGINT, 143 for SIGTERM); a panic removes them too.
//! A closed stdout (`tetloc info m.vtu | head -1`) ends the command quietly with exit code 0,
//! as ripgrep does, instead of a panic message.

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
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
                    output::remove_temporaries();
                    let stop = sig == SIGINT || sig == SIGTERM;
                    std::process::exit(if stop && SERVING.load(Ordering::SeqCst) { 0 } else { 128 + sig });
                }
            });
        }
        Err(e) => eprintln!("warning: no signal handler ({e}): an interrupted run may leave temporary files"),
    }
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        output::remove_temporaries();
        if is_closed_stdout(info.payload()) {
            std::process::exit(0);
        }
        default(info);
    }));
}

/// Whether a panic (its payload) is `println!`'s on a closed stdout.
fn is_closed_stdout(payload: &(dyn std::any::Any + Send)) -> bool {
    let text = payload.downcast_ref::<String>().map(String::as_str).or_else(|| payload.downcast_ref::<&str>().copied());
    text.is_some_and(|t| t.starts_with("failed printing to stdout") && t.contains("Broken pipe"))
}
