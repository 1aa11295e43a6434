//! The library's barriers are derived in one place: no file under `src/` but the tracker
//! (`src/gpu/track.rs`) and the host-facing helpers (`src/gpu/sync.rs`) builds a
//! `vk::*MemoryBarrier*`, records a pipeline barrier or writes a barrier's "before"
//! state; everything else declares its accesses to a `Tracker` (resources enter it once,
//! with their documented state). A scan of the sources, so that the rule cannot regress
//! silently.

use std::path::{Path, PathBuf};

/// The files allowed to build barriers, relative to the crate root.
const ALLOWED: [&str; 2] = ["src/gpu/sync.rs", "src/gpu/track.rs"];

/// What builds a barrier or states its "before" side by hand.
const FORBIDDEN: [&str; 10] = [
    "MemoryBarrier",
    "pipeline_barrier",
    "image_barrier",
    "memory_barrier",
    "sync::transition",
    "sync::record",
    "src_stage_mask",
    "src_access_mask",
    "old_layout",
    "DependencyInfo",
];

/// The `(line number, pattern)` of each forbidden pattern in `source`'s code (comment
/// lines and the text after `//` are not code).
fn offences(source: &str) -> Vec<(usize, &'static str)> {
    let mut out = Vec::new();
    for (i, line) in source.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        for pattern in FORBIDDEN {
            if code.contains(pattern) {
                out.push((i + 1, pattern));
            }
        }
        // `use crate::gpu::sync::{self, transition}` and the like.
        if code.contains("sync::{") && (code.contains("transition") || code.contains("record")) {
            out.push((i + 1, "an import of sync's barrier helpers"));
        }
    }
    out
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn only_the_tracker_and_the_host_helpers_build_barriers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    assert!(files.len() > 50, "the scan found the sources");
    let mut found = Vec::new();
    for path in &files {
        let relative = path
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        if ALLOWED.contains(&relative.as_str()) {
            continue;
        }
        let source = std::fs::read_to_string(path).unwrap();
        for (line, pattern) in offences(&source) {
            found.push(format!("{relative}:{line}: {pattern}"));
        }
    }
    assert!(
        found.is_empty(),
        "barriers written outside the tracker (declare the accesses to a \
         dispmap::gpu::track::Tracker instead):\n{}",
        found.join("\n")
    );
}

/// The scan sees what it looks for (so the test above can fail).
#[test]
fn the_scan_finds_hand_written_barriers() {
    let hand_written = "let b = sync::image_barrier(i.raw, i.range(), DISCARD, WRITE);\n\
                        unsafe { sync::transition(ctx, cmd, &image, before, after) };\n\
                        // a comment naming vk::ImageMemoryBarrier2 is fine\n\
                        let m = vk::MemoryBarrier2::default().src_stage_mask(s);\n\
                        use crate::gpu::sync::{self, transition};";
    let found: Vec<usize> = offences(hand_written).iter().map(|(l, _)| *l).collect();
    assert_eq!(found, vec![1, 2, 4, 4, 5]);
    assert!(offences("t.declare(hit, Access::COMPUTE_STORAGE_READ)?;").is_empty());
}
