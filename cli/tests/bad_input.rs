//! The bad-input table (issue 7): one row per bad input to `dispmap render`, each run as
//! a process under validation. Every row must exit non-zero within [`HANG`] (no device
//! hang), print an error naming the input and what is wrong (every `expect` string must
//! be in stderr), never panic, and leave nothing behind: neither the output file nor a
//! temporary file next to it. To add a row, add one line to [`rows`].

#[path = "../../tests/common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A run that takes longer than this is a hang.
const HANG: Duration = Duration::from_secs(120);

/// One bad input: the `render` options it replaces or adds (the others are a valid
/// small render of the rocks map), environment variables, and what stderr must contain.
struct Row {
    name: &'static str,
    options: Vec<(&'static str, String)>,
    env: &'static [(&'static str, &'static str)],
    expect: Vec<String>,
}

fn row(name: &'static str, options: &[(&'static str, &str)], expect: &[&str]) -> Row {
    Row {
        name,
        options: options.iter().map(|(k, v)| (*k, v.to_string())).collect(),
        env: &[],
        expect: expect.iter().map(|s| s.to_string()).collect(),
    }
}

/// The fixtures: files written into `dir` for the rows that need them.
struct Fixtures {
    dir: PathBuf,
    max_dimension: u32,
}

impl Fixtures {
    fn path(&self, name: &str) -> String {
        self.dir.join(name).to_str().unwrap().to_owned()
    }
}

/// An 8-bit grey PNG.
fn png(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    image::GrayImage::from_pixel(width, height, image::Luma([128]))
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
    bytes
}

fn fixtures(dir: &Path, max_dimension: u32) -> Fixtures {
    let asset = |name: &str| {
        std::fs::read(common::repo_root().join("assets/heightmaps").join(name)).unwrap()
    };
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    write("junk.png", b"not a png");
    write("empty.png", b"");
    let mountains = asset("mountains_height16.png");
    write("truncated.png", &mountains[..mountains.len() / 2]);
    let rocks = asset("rocks_depth.jpg");
    write("truncated.jpg", &rocks[..rocks.len() / 2]);
    // A PNG header claiming a 0x4 image (the encoder refuses to write one).
    let mut zero = png(1, 4);
    zero[16..20].copy_from_slice(&0u32.to_be_bytes());
    let crc = crc32(&zero[12..29]);
    zero[29..33].copy_from_slice(&crc.to_be_bytes());
    write("zero.png", &zero);
    write("too-wide.png", &png(max_dimension + 1, 1));
    // Scene files.
    write("unknown-key.toml", b"[camera]\nelevation = 20\nzoom = 2\n");
    write("not-toml.toml", b"this is = = not toml\n");
    write("bad-value.toml", b"[camera]\nelevation = -5\n");
    write(
        "missing-mesh.toml",
        b"geometry = \"mesh\"\nmesh = \"nope.obj\"\n",
    );
    write("bad-geometry.toml", b"geometry = \"teapot\"\n");
    // BMP: a real image in a format dispmap does not read.
    write("map.bmp", &bmp());
    // OpenEXR with a height outside [0, 1].
    let exr = image::Rgb32FImage::from_pixel(2, 2, image::Rgb([2.0, 2.0, 2.0]));
    exr.save(dir.join("too-high.exr")).unwrap();
    Fixtures {
        dir: dir.to_owned(),
        max_dimension,
    }
}

/// A 2x2 24-bit BMP (dispmap's image crate has no BMP codec to write one).
fn bmp() -> Vec<u8> {
    let pixels: Vec<u8> = [[128u8; 6].as_slice(), &[0, 0]].concat().repeat(2);
    let mut out = Vec::new();
    out.extend_from_slice(b"BM");
    for v in [54 + pixels.len() as u32, 0, 54, 40, 2, 2] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&1u16.to_le_bytes());
    out.extend_from_slice(&24u16.to_le_bytes());
    for v in [0u32, pixels.len() as u32, 2835, 2835, 0, 0] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&pixels);
    out
}

/// CRC-32 of PNG chunks (ISO 3309).
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// The table. Options replace the valid defaults of [`run`] or add to them.
#[rustfmt::skip]
fn rows(f: &Fixtures) -> Vec<Row> {
    let max = f.max_dimension;
    let no_driver: &[(&str, &str)] = &[("VK_ICD_FILENAMES", "/nonexistent/icd.json"), ("VK_DRIVER_FILES", "/nonexistent/icd.json")];
    vec![
        // Height-map files.
        row("missing file",            &[("--heightmap", "/no/such/map.png")],       &["/no/such/map.png", "No such file"]),
        row("not an image",            &[("--heightmap", &f.path("junk.png"))],      &["junk.png", "not a PNG, JPEG or OpenEXR image"]),
        row("empty file",              &[("--heightmap", &f.path("empty.png"))],     &["empty.png", "not a PNG, JPEG or OpenEXR image"]),
        row("truncated PNG",           &[("--heightmap", &f.path("truncated.png"))], &["truncated.png", "cannot decode"]),
        row("truncated JPEG",          &[("--heightmap", &f.path("truncated.jpg"))], &["truncated.jpg", "truncated JPEG"]),
        row("zero-sized image",        &[("--heightmap", &f.path("zero.png"))],      &["zero.png", "dimensions"]),
        row("larger than maxImageDimension2D", &[("--heightmap", &f.path("too-wide.png"))], &["too-wide.png", &format!("{}x1", max + 1), "maxImageDimension2D"]),
        row("unsupported format (BMP)", &[("--heightmap", &f.path("map.bmp"))],     &["map.bmp", "Bmp is not supported"]),
        row("float heights outside [0, 1]", &[("--heightmap", &f.path("too-high.exr"))], &["too-high.exr", "outside [0, 1]"]),
        row("unknown convention",      &[("--convention", "sideways")],             &["sideways", "height, depth"]),
        // Numbers.
        row("NaN depth scale",         &[("--depth-scale", "NaN")],                 &["depth-scale", "NaN"]),
        row("negative depth scale",    &[("--depth-scale", "-1")],                  &["depth-scale", "-1 is outside [0, 1000]"]),
        row("huge depth scale",        &[("--depth-scale", "1e9")],                 &["depth-scale", "outside [0, 1000]"]),
        row("infinite camera height",  &[("--camera-height", "inf")],               &["camera-height", "inf"]),
        row("negative elevation",      &[("--camera-elevation", "-3")],             &["camera-elevation", "-3 is outside"]),
        row("zero steps",              &[("--steps", "0")],                         &["steps", "0 is outside 1..=65536"]),
        row("absurd steps",            &[("--steps", "4294967295")],                &["steps", "4294967295 is outside 1..=65536"]),
        row("steps beyond u32",        &[("--steps", "99999999999")],               &["--steps", "99999999999"]),
        row("negative steps",          &[("--steps", "-3")],                        &["-3"]),
        row("zero frames",             &[("--frames", "0")],                        &["frames", "0 is outside"]),
        row("absurd frames",           &[("--frames", "1000000000")],               &["frames", "1000000000 is outside"]),
        row("zero-sized frame",        &[("--size", "0x10")],                       &["0x10"]),
        row("huge frame",              &[("--size", "100000x10")],                  &["100000x10"]),
        row("zero DIG block",          &[("--block", "0x4")],                       &["--block", "zero side"]),
        row("eps above 1",             &[("--eps", "2")],                           &["eps", "2 is outside 0..=1"]),
        row("absurd refine steps",     &[("--refine-steps", "99")],                 &["refine-steps", "99 is outside"]),
        row("absurd max level",        &[("--max-level", "99")],                    &["max-level", "99"]),
        row("zero secant segments",    &[("--segments", "0")],                      &["segments", "0 is outside"]),
        row("unknown method",          &[("--method", "magic")],                    &["magic", "known: bump"]),
        row("unknown shadow mode",     &[("--shadows", "magic")],                   &["magic"]),
        row("zero shadow samples",     &[("--shadows", "soft"), ("--shadow-samples", "0")], &["shadow-samples", "0"]),
        row("NaN LOD threshold",       &[("--lod-threshold", "NaN")],               &["lod-threshold", "NaN"]),
        // Scene files.
        row("missing scene file",      &[("--scene", "/no/such/scene.toml")],       &["/no/such/scene.toml", "No such file"]),
        row("unknown scene key",       &[("--scene", &f.path("unknown-key.toml"))], &["unknown-key.toml", "zoom"]),
        row("scene not TOML",          &[("--scene", &f.path("not-toml.toml"))],    &["not-toml.toml"]),
        row("scene value out of range", &[("--scene", &f.path("bad-value.toml"))],  &["bad-value.toml", "camera-elevation", "-5"]),
        row("scene mesh missing",      &[("--scene", &f.path("missing-mesh.toml"))], &["nope.obj"]),
        row("unknown scene geometry",  &[("--scene", &f.path("bad-geometry.toml"))], &["bad-geometry.toml", "teapot"]),
        // Outputs.
        row("output folder missing",   &[("--out", &f.path("missing-folder/out.png"))], &["--out", "missing-folder", "does not exist"]),
        row("output is a folder",      &[("--out", f.dir.to_str().unwrap())],       &["--out", "is a folder"]),
        row("depth output not EXR/PNG", &[("--depth-out", &f.path("depth.bmp"))],  &["--depth-out", "depth.bmp", ".exr"]),
        row("metrics folder missing",  &[("--metrics", &f.path("missing-folder/m.json"))], &["--metrics", "missing-folder", "does not exist"]),
        // Devices.
        Row { env: no_driver, ..row("no Vulkan driver", &[], &["vkCreateInstance", "Vulkan driver"]) },
        row("no such device (name)",   &[("--device", "no-such-gpu")],              &["no-such-gpu", "no suitable Vulkan device"]),
        row("no such device (index)",  &[("--device", "7")],                        &["device index 7 out of range"]),
    ]
}

/// Runs `dispmap render` with the valid defaults overridden by `row` and returns the
/// exit status's success and stderr; fails on a hang.
fn run(row: &Row, out: &Path) -> (bool, String) {
    let rocks = common::repo_root().join("assets/heightmaps/rocks_depth.jpg");
    let mut options: Vec<(&str, String)> = vec![
        ("--heightmap", rocks.to_str().unwrap().to_owned()),
        ("--convention", "depth".into()),
        ("--size", "16x16".into()),
        ("--frames", "1".into()),
        ("--out", out.to_str().unwrap().to_owned()),
    ];
    let mut global = Vec::new();
    for (k, v) in &row.options {
        if *k == "--device" {
            global.push((*k, v.clone()));
        } else if let Some(o) = options.iter_mut().find(|(name, _)| name == k) {
            o.1 = v.clone();
        } else {
            options.push((k, v.clone()));
        }
    }
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_dispmap"));
    cmd.env("DISPMAP_VALIDATION", "1")
        .env_remove("DISPMAP_DEVICE")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for (k, v) in row.env {
        cmd.env(k, v);
    }
    for (k, v) in global {
        cmd.arg(k).arg(v);
    }
    cmd.arg("render");
    for (k, v) in options {
        // `=` so a value starting with '-' is not read as an option.
        cmd.arg(format!("{k}={v}"));
    }
    let mut child = cmd.spawn().unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > HANG {
            child.kill().ok();
            panic!("{}: still running after {HANG:?}", row.name);
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    (status.success(), stderr)
}

#[test]
fn every_bad_input_is_named_and_leaves_nothing() {
    let max_dimension = {
        let ctx = common::validated_context();
        let max = ctx.info().max_image_dimension_2d;
        common::finish(ctx);
        max
    };
    let root = std::env::temp_dir().join(format!("dispmap-bad-input-{}", std::process::id()));
    let fixtures_dir = root.join("fixtures");
    let out_dir = root.join("out");
    std::fs::create_dir_all(&fixtures_dir).unwrap();
    std::fs::create_dir_all(&out_dir).unwrap();
    let f = fixtures(&fixtures_dir, max_dimension);
    let out = out_dir.join("out.png");
    let mut failures = Vec::new();
    for row in rows(&f) {
        let (success, stderr) = run(&row, &out);
        let last = stderr
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("");
        eprintln!("{:<32} {last}", row.name);
        let mut problems = Vec::new();
        if success {
            problems.push("exited with success".to_owned());
        }
        if stderr.contains("panicked") {
            problems.push("panicked".to_owned());
        }
        for want in &row.expect {
            if !stderr.contains(want.as_str()) {
                problems.push(format!("'{want}' not in stderr"));
            }
        }
        let left: Vec<_> = std::fs::read_dir(&out_dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        if !left.is_empty() {
            problems.push(format!("left {left:?}"));
            for name in left {
                std::fs::remove_file(out_dir.join(name)).ok();
            }
        }
        if !problems.is_empty() {
            failures.push(format!("{}: {}\n{stderr}", row.name, problems.join("; ")));
        }
    }
    std::fs::remove_dir_all(&root).ok();
    assert!(
        failures.is_empty(),
        "bad inputs handled badly:\n{}",
        failures.join("\n")
    );
}

/// The defaults of [`run`] are valid: the same process succeeds and writes the PNG (so
/// each row fails because of its own input).
#[test]
fn the_defaults_render() {
    let dir = std::env::temp_dir().join(format!("dispmap-bad-input-ok-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out.png");
    let ok = Row {
        name: "valid",
        options: Vec::new(),
        env: &[],
        expect: Vec::new(),
    };
    let (success, stderr) = run(&ok, &out);
    assert!(success, "{stderr}");
    assert!(out.exists());
    std::fs::remove_dir_all(&dir).ok();
}
