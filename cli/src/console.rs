//! The console (standard output and standard error) as a place a run may fail to write
//! without losing its work. `println!` and `eprintln!` in this binary are this module's
//! (`main.rs` shadows the standard macros): a failed write (a closed pipe, `/dev/full`)
//! is recorded, later lines to that stream are dropped, and the run goes on to commit
//! its outputs; `main` then reports the failure and exits with 1. The standard macros
//! would panic instead, after the work and before the commit.

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

/// Writes one line (`args` and a newline) to `stream`; a failure is recorded, never
/// raised.
pub fn line(stream: Stream, args: std::fmt::Arguments) {
    let broken = &BROKEN[stream as usize];
    if broken.load(Ordering::Relaxed) {
        return;
    }
    let written = match stream {
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
