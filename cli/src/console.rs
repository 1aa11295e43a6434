//! The console (standard output and standard error) as a place a run may fail to write
//! without losing its work. `println!` and `eprintln!` in this binary are this module's
//! (`main.rs` shadows the standard macros): a failed write (a closed pipe, `/dev/full`)
//! is recorded, later lines to that stream are dropped, and the run goes on to commit
//! its outputs; `main` then reports the failure and exits with 1. The standard macros
//! would panic instead, after the work and before the commit.
//!
//! A standard output that was closed when the process started (`>&-`) counts as one
//! that cannot be written: the Rust runtime reopens a closed standard descriptor on
//! `/dev/null` before `main`, so it is recorded earlier, while the C runtime runs the
//! program's initialisers ([`stdout_closed_at_start`]).

use std::io::Write as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// Which stream a line goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stream {
    /// Standard output.
    Out,
    /// Standard error.
    Err,
}

/// Whether a write to the stream failed (later lines are dropped).
static BROKEN: [AtomicBool; 2] = [AtomicBool::new(false), AtomicBool::new(false)];
/// The first failure: the stream and the error.
static FAILURE: Mutex<Option<(Stream, std::io::Error)>> = Mutex::new(None);

/// Whether descriptor 1 was closed when the process started.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Records whether descriptor 1 is closed; run by the C runtime before `main` (and
/// before the Rust runtime reopens a closed descriptor on `/dev/null`).
#[cfg(target_os = "linux")]
extern "C" fn record_closed_stdout() {
    // SAFETY: fcntl(F_GETFD) only reads the flags of a descriptor number (-1 with EBADF
    // when none is open); it touches no memory of this process.
    if unsafe { libc::fcntl(libc::STDOUT_FILENO, libc::F_GETFD) } == -1 {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
    }
}

/// The initialiser that runs [`record_closed_stdout`] before `main`.
// SAFETY: an `.init_array` entry is a function pointer the C runtime calls once, before
// `main`, with (argc, argv, envp), which a function of no arguments ignores under the C
// calling convention; the function only makes a system call and stores an atomic, which
// needs nothing the Rust runtime sets up.
#[cfg(target_os = "linux")]
#[used]
#[unsafe(link_section = ".init_array")]
static RECORD_CLOSED_STDOUT: extern "C" fn() = record_closed_stdout;

/// Whether standard output was closed when the process started (`>&-`): nothing
/// receives what is written there.
pub fn stdout_closed_at_start() -> bool {
    STDOUT_CLOSED.load(Ordering::Relaxed)
}

/// Writes one line (`args` and a newline) to `stream`; a failure is recorded, never
/// raised.
pub fn line(stream: Stream, args: std::fmt::Arguments) {
    let broken = &BROKEN[stream as usize];
    if broken.load(Ordering::Relaxed) {
        return;
    }
    let written = match stream {
        Stream::Out if stdout_closed_at_start() => {
            Err(std::io::Error::from_raw_os_error(libc::EBADF))
        }
        Stream::Out => {
            let mut out = std::io::stdout().lock();
            writeln!(out, "{args}").and_then(|()| out.flush())
        }
        Stream::Err => writeln!(std::io::stderr().lock(), "{args}"),
    };
    if let Err(e) = written {
        broken.store(true, Ordering::Relaxed);
        let mut first = FAILURE.lock().unwrap_or_else(|p| p.into_inner());
        first.get_or_insert((stream, e));
    }
}

/// The first failed console write, as a sentence, if any.
pub fn failure() -> Option<String> {
    let first = FAILURE.lock().unwrap_or_else(|p| p.into_inner());
    first.as_ref().map(|(stream, e)| {
        let name = match stream {
            Stream::Out => "standard output",
            Stream::Err => "standard error",
        };
        format!("cannot write to {name}: {e}")
    })
}
