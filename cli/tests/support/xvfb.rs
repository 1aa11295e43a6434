//! An Xvfb server for the tests that open a window (`view`, `doc_commands`).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

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

/// Starts Xvfb on a free display number; `Err` says why it could not.
pub fn start_xvfb() -> Result<Xvfb, String> {
    // Display numbers from the process id, so parallel runs of this test pick different
    // ones; a display whose lock file exists is taken.
    let base = 100 + (std::process::id() % 400);
    for n in base..base + 20 {
        if Path::new(&format!("/tmp/.X{n}-lock")).exists() {
            continue;
        }
        let display = format!(":{n}");
        let child = Command::new("Xvfb")
            .args([&display, "-screen", "0", "640x480x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot run Xvfb ({e}); install the xvfb package"))?;
        let mut xvfb = Xvfb { child, display };
        let socket = PathBuf::from(format!("/tmp/.X11-unix/X{n}"));
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(10) {
            if let Ok(Some(_)) = xvfb.child.try_wait() {
                break; // it exited: the display was taken after all, try the next one
            }
            if socket.exists() {
                return Ok(xvfb);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = xvfb.child.kill();
    }
    Err("Xvfb did not start on any of 20 display numbers".into())
}
