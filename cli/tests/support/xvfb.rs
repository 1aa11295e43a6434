//! An Xvfb server for the tests that open a window (`view`, `doc_commands`).
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

/// An Xvfb server, killed when dropped.
pub struct Xvfb {
    child: Child,
    /// The X display name (`:N`).
    pub display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts Xvfb on a display number the server picks itself; `Err` says why it could not.
///
/// The server chooses the number (`-displayfd`: it takes the first display whose lock
/// file it can create, atomically) and writes it to its standard output once clients can
/// connect. Choosing the number here instead raced: two tests of one process started
/// servers on the same number, the second server exited, and its test used (and lost,
/// when the first test ended) the first test's server.
pub fn start_xvfb() -> Result<Xvfb, String> {
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "640x480x24",
            "-nolisten",
            "tcp",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot run Xvfb ({e}); install the xvfb package"))?;
    let stdout = child.stdout.take().expect("stdout is piped");
    let (send, receive) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let read = BufReader::new(stdout).read_line(&mut line);
        let _ = send.send(read.map(|_| line));
    });
    let mut xvfb = Xvfb {
        child,
        display: String::new(),
    };
    match receive.recv_timeout(Duration::from_secs(20)) {
        Ok(Ok(line)) if line.trim().parse::<u32>().is_ok() => {
            xvfb.display = format!(":{}", line.trim());
            Ok(xvfb)
        }
        Ok(Ok(line)) if line.is_empty() => Err("Xvfb exited without opening a display".into()),
        Ok(Ok(line)) => Err(format!("Xvfb printed {line:?}, not a display number")),
        Ok(Err(e)) => Err(format!("reading Xvfb's display number: {e}")),
        Err(_) => Err("Xvfb did not open a display within 20 s".into()),
    }
}
