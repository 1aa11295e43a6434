//! The bad-input table (issue 7): one row per bad input to `dispmap render`, each run as
//! a process under validation. Every row must exit non-zero, print an error naming the
//! input and what is wrong (every `expect` string must be in stderr), never panic, and
//! leave nothing behind: neither the output file nor a temporary file next to it. A run
//! still going after [`HANG`] is killed and fails the row: a hang guard, not a timing
//! (rows take 0.3-3 s each; timings are never asserted). To add a row, add one line to
//! [`rows`] and count it in [`ROWS`]; root-only rows that cannot run here are counted as
//! skipped (a failure where `DISPMAP_NO_SKIP=1`, as in CI).

#[path = "../../tests/common/mod.rs"]
mod common;
#[path = "support/hostile.rs"]
mod hostile;
#[path = "support/skip.rs"]
mod skip;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The hang guard: a run still going after this is killed (a hang: every row ends in
/// 0.3-3 s under validation, far below it; not a timing assertion).
const HANG: Duration = Duration::from_secs(120);
/// The rows of the table as root: run, or counted as skipped where a root-only row cannot
/// be made (so a row that silently disappears fails the count).
const ROWS: usize = 113;
/// Every bad-input run peaks below this resident memory (measured: 100-200 MB; an input
/// read without bound grows by gigabytes)...
const ROW_PEAK_BYTES: u64 = 1 << 30;
/// ...and cannot take more than this data segment (`RLIMIT_DATA`), so a regression fails
/// the row instead of exhausting the machine.
const ROW_DATA_LIMIT: u64 = 4 << 30;

/// One bad input: the `render` options it replaces or adds (the others are a valid
/// small render of the rocks map), environment variables, and what stderr must contain.
struct Row {
    name: &'static str,
    options: Vec<(&'static str, String)>,
    env: &'static [(&'static str, &'static str)],
    expect: Vec<String>,
    /// What stderr must not contain (a wrong cause).
    absent: Vec<String>,
    /// A command the run goes through (`setpriv` to run as another user, `sh -c` for a
    /// file size limit); empty: none.
    wrap: Vec<String>,
}

fn row(name: &'static str, options: &[(&'static str, &str)], expect: &[&str]) -> Row {
    Row {
        name,
        options: options.iter().map(|(k, v)| (*k, v.to_string())).collect(),
        env: &[],
        expect: expect.iter().map(|s| s.to_string()).collect(),
        absent: Vec::new(),
        wrap: Vec::new(),
    }
}

/// Whether the tests run as root (device nodes and mounts are made then; permission
/// rows run as `nobody` through setpriv).
fn is_root() -> bool {
    std::process::Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.trim_ascii() == b"0")
}

/// Makes a device node (`mknod NAME c MAJOR MINOR`) in the test's folder, as root only.
fn mknod(path: &Path, major: u32, minor: u32) -> bool {
    is_root()
        && Command::new("mknod")
            .arg(path)
            .args(["c", &major.to_string(), &minor.to_string()])
            .status()
            .is_ok_and(|s| s.success())
}

/// The fixtures: files written into `dir` for the rows that need them.
struct Fixtures {
    dir: PathBuf,
    max_dimension: u32,
    /// The folder the run's outputs go to (must stay empty).
    out_dir: PathBuf,
    /// Device nodes made by the test (root only): `/dev/full`'s and `/dev/zero`'s.
    full: Option<String>,
    zero: Option<String>,
    /// A read-only file system mounted by the test (root only).
    read_only: Option<PathBuf>,
    /// Rows of the table not run on this machine (root-only rows when not root, each
    /// through [`skip::skip`], which fails where `DISPMAP_NO_SKIP=1`).
    skipped: std::cell::Cell<usize>,
}

impl Fixtures {
    fn path(&self, name: &str) -> String {
        self.dir.join(name).to_str().unwrap().to_owned()
    }

    /// `rows` rows named `what` are not run here, because of `why` (a failure where
    /// `DISPMAP_NO_SKIP=1`).
    fn skip(&self, rows: usize, what: &str, why: &str) {
        skip::skip(&format!("bad-input row(s) {what}"), why);
        self.skipped.set(self.skipped.get() + rows);
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
    // Cut, then given back an end-of-image marker (image's decoder loads it grey-filled).
    write(
        "reterminated.jpg",
        &[&rocks[..rocks.len() / 2], &[0xFF, 0xD9][..]].concat(),
    );
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
    // A PNG whose header claims 60000x60000 pixels (the data is one pixel's).
    let mut lying = png(1, 1);
    lying[16..20].copy_from_slice(&60000u32.to_be_bytes());
    lying[20..24].copy_from_slice(&60000u32.to_be_bytes());
    let crc = crc32(&lying[12..29]);
    lying[29..33].copy_from_slice(&crc.to_be_bytes());
    write("lying.png", &lying);
    // A FIFO: no size to check (reading it would block or never end).
    Command::new("mkfifo")
        .arg(dir.join("fifo.png"))
        .status()
        .unwrap();
    // Meshes with no usable triangle.
    write(
        "degenerate.obj",
        b"v 0 0 0\nv 1 0 0\nv 2 0 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n",
    );
    write(
        "overflow.obj",
        b"v -3e38 0 0\nv 3e38 0 0\nv 0 3e38 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n",
    );
    write(
        "degenerate.toml",
        b"geometry = \"mesh\"\nmesh = \"degenerate.obj\"\n",
    );
    write(
        "overflow.toml",
        b"geometry = \"mesh\"\nmesh = \"overflow.obj\"\n",
    );
    std::fs::create_dir_all(dir.join("folder.obj")).unwrap();
    write(
        "folder-mesh.toml",
        b"geometry = \"mesh\"\nmesh = \"folder.obj\"\n",
    );
    write("size3.toml", b"size = [64, 36, 2]\n");
    write("map.png", &png(4, 4));
    write("no-convention.toml", b"[heightmap]\npath = \"map.png\"\n");
    // A normal map (float) with a NaN.
    let mut nan = image::Rgb32FImage::from_pixel(2, 2, image::Rgb([0.5, 0.5, 1.0]));
    nan.put_pixel(1, 0, image::Rgb([f32::NAN, 0.5, 1.0]));
    nan.save(dir.join("nan-normal.exr")).unwrap();
    write(
        "nan-normal.toml",
        b"[material]\nnormal_map = \"nan-normal.exr\"\n",
    );
    // glTF: a node that is its own child; a buffer outside the scene's folder.
    write(
        "self.gltf",
        br#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"children":[0]}]}"#,
    );
    write("cycle.toml", b"geometry = \"mesh\"\nmesh = \"self.gltf\"\n");
    write("outside.gltf", br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"../secret.bin"}],"scenes":[{"nodes":[]}]}"#);
    write(
        "outside.toml",
        b"geometry = \"mesh\"\nmesh = \"outside.gltf\"\n",
    );
    issue_26_fixtures(dir);
    // A read-only output file (kept as it is).
    write("read-only.png", b"old");
    std::fs::set_permissions(
        dir.join("read-only.png"),
        std::os::unix::fs::PermissionsExt::from_mode(0o444),
    )
    .unwrap();
    // Driver manifests: not JSON.
    write("bad-icd.json", b"{ not json");
    let out_dir = dir.parent().unwrap().join("out");
    let full = dir.join("full");
    let zero = dir.join("zero");
    let read_only = dir.join("read-only");
    std::fs::create_dir_all(&read_only).unwrap();
    let mounted = is_root()
        && Command::new("mount")
            .args(["-t", "tmpfs", "-o", "ro,size=64k", "dispmap-test"])
            .arg(&read_only)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
    Fixtures {
        dir: dir.to_owned(),
        max_dimension,
        out_dir,
        full: mknod(&full, 1, 7).then(|| full.to_str().unwrap().to_owned()),
        zero: mknod(&zero, 1, 5).then(|| zero.to_str().unwrap().to_owned()),
        read_only: mounted.then_some(read_only),
        skipped: std::cell::Cell::new(0),
    }
}

/// The inputs of issue 26's rows: glTF accessors the specification does not allow,
/// inputs that never end (FIFOs, `/dev/zero` behind symlinks, sparse giants), meshes
/// above the memory bound, damaged and multi-part OpenEXR files, odd PNG headers.
fn issue_26_fixtures(dir: &Path) {
    use hostile::*;
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    let scene = |name: &str, mesh: &str| {
        write(
            name,
            format!("geometry = \"mesh\"\nmesh = \"{mesh}\"\n").as_bytes(),
        )
    };
    let fifo = |name: &str| {
        assert!(
            Command::new("mkfifo")
                .arg(dir.join(name))
                .status()
                .unwrap()
                .success()
        );
    };
    let zero = |name: &str| std::os::unix::fs::symlink("/dev/zero", dir.join(name)).unwrap();
    // 1. glTF accessors.
    for (name, uv, index, stride) in [
        ("index-byte", FLOAT, BYTE, None),
        ("index-short", FLOAT, SHORT, None),
        ("index-float", FLOAT, FLOAT, None),
        ("uv-byte", BYTE, UNSIGNED_SHORT, None),
        ("uv-short", SHORT, UNSIGNED_SHORT, None),
        ("uv-uint", UNSIGNED_INT, UNSIGNED_SHORT, None),
        ("stride-4", FLOAT, UNSIGNED_SHORT, Some(4)),
    ] {
        gltf_triangle(dir, name, uv, index, stride);
        scene(&format!("{name}.toml"), &format!("{name}.gltf"));
    }
    // 3. Inputs that never end.
    fifo("fifo-scene.toml");
    fifo("fifo.obj");
    scene("fifo-obj.toml", "fifo.obj");
    fifo("fifo.gltf");
    scene("fifo-gltf.toml", "fifo.gltf");
    gltf_triangle(dir, "fifo-buffer", FLOAT, UNSIGNED_SHORT, None);
    std::fs::remove_file(dir.join("fifo-buffer.bin")).unwrap();
    fifo("fifo-buffer.bin");
    scene("fifo-buffer.toml", "fifo-buffer.gltf");
    zero("zero-scene.toml");
    zero("zero-link.obj");
    scene("zero-obj.toml", "zero-link.obj");
    write(
        "zero-mtl.obj",
        b"mtllib zero-link.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n",
    );
    zero("zero-link.mtl");
    scene("zero-mtl.toml", "zero-mtl.obj");
    gltf_triangle(dir, "zero-buffer", FLOAT, UNSIGNED_SHORT, None);
    std::fs::remove_file(dir.join("zero-buffer.bin")).unwrap();
    zero("zero-buffer.bin");
    scene("zero-buffer.toml", "zero-buffer.gltf");
    // Sparse giants: a 2 GB scene file, a 5 GB OBJ (no disk space taken).
    std::fs::File::create(dir.join("sparse.toml"))
        .unwrap()
        .set_len(2 << 30)
        .unwrap();
    std::fs::File::create(dir.join("sparse.obj"))
        .unwrap()
        .set_len(5 << 30)
        .unwrap();
    scene("sparse-obj.toml", "sparse.obj");
    // 4. Meshes in the memory bound: 180,000 triangles (8.6 MB of OBJ); a glTF claiming
    // 17 million.
    write("grid.obj", obj_grid(300).as_bytes());
    scene("grid.toml", "grid.obj");
    gltf_claiming(dir, "huge", 17_000_000);
    scene("huge-gltf.toml", "huge.gltf");
    // 7. Damaged single-channel OpenEXR (Y only, 8x40: three ZIP16 chunks).
    let zip = exr(
        &[("height", "Y", 1.0)],
        8,
        40,
        exr::compression::Compression::ZIP16,
    );
    let rle = exr(
        &[("height", "Y", 1.0)],
        8,
        40,
        exr::compression::Compression::RLE,
    );
    write("exr-cut.exr", &zip[..zip.len() * 6 / 10]);
    let table = exr_header_end(&zip);
    let mut offsets = zip.clone();
    offsets[table..table + 8].copy_from_slice(&(1u64 << 40).to_le_bytes());
    write("exr-offsets.exr", &offsets);
    let mut corrupt = zip.clone();
    let first = u64::from_le_bytes(zip[table..table + 8].try_into().unwrap()) as usize;
    // The chunk: y (4 bytes), size (4), then the compressed bytes.
    for b in &mut corrupt[first + 8..first + 24] {
        *b ^= 0x5A;
    }
    write("exr-zip.exr", &corrupt);
    let table = exr_header_end(&rle);
    let first = u64::from_le_bytes(rle[table..table + 8].try_into().unwrap()) as usize;
    let mut corrupt = rle.clone();
    corrupt[first + 4..first + 8].copy_from_slice(&7u32.to_le_bytes());
    write("exr-rle.exr", &corrupt);
    let mut window = zip.clone();
    let at = exr_attribute(&zip, "dataWindow");
    window[at + 12..at + 16].copy_from_slice(&4000i32.to_le_bytes());
    write("exr-window.exr", &window);
    // 8. Multi-part: a colour part, then the height part (Y, up to 3: out of range).
    write(
        "multi-high.exr",
        &exr(
            &[("color", "R", 0.5), ("height", "Y", 3.0)],
            4,
            4,
            exr::compression::Compression::Uncompressed,
        ),
    );
    // 13. A PNG header claiming 2147483647x1; also seen: a palette index past the palette.
    write("huge.png", &png(2147483647, 1, 0, None, &[0, 0]));
    write(
        "palette.png",
        &png(2, 1, 3, Some(&[0, 0, 0, 255, 255, 255]), &[0, 1, 5]),
    );
}

impl Drop for Fixtures {
    fn drop(&mut self) {
        if let Some(ro) = &self.read_only {
            let _ = Command::new("umount").arg(ro).status();
        }
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
    let out = |name: &str| f.out_dir.join(name).to_str().unwrap().to_owned();
    let mut rows = vec![
        // Height-map files.
        row("missing file",            &[("--heightmap", "/no/such/map.png")],       &["/no/such/map.png", "No such file"]),
        row("not an image",            &[("--heightmap", &f.path("junk.png"))],      &["junk.png", "not a PNG, JPEG or OpenEXR image"]),
        row("empty file",              &[("--heightmap", &f.path("empty.png"))],     &["empty.png", "not a PNG, JPEG or OpenEXR image"]),
        row("truncated PNG",           &[("--heightmap", &f.path("truncated.png"))], &["truncated.png", "cannot decode"]),
        row("truncated JPEG",          &[("--heightmap", &f.path("truncated.jpg"))], &["truncated.jpg", "truncated JPEG"]),
        row("truncated JPEG, end marker appended", &[("--heightmap", &f.path("reterminated.jpg"))], &["reterminated.jpg", "truncated JPEG", "data that was cut"]),
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
        row("output name ends in /",   &[("--out", &format!("{}/", out("o.png")))], &["--out", "o.png/", "ends in '/'"]),
        row("same output twice",       &[("--heatmap", &out("out.png"))],           &["--heatmap", "same file as --out"]),
        row("same output via ./",      &[("--metrics", &format!("{}/./m", f.out_dir.display())), ("--heatmap", &format!("{}/m", f.out_dir.display()))], &["same file as --metrics"]),
        row("--out extension not PNG", &[("--out", &out("o.jpg"))],                 &["--out", "o.jpg", ".jpg does not match the format written (PNG)"]),
        row("--metrics extension not JSON", &[("--metrics", &out("m.png"))],        &["--metrics", "m.png", "(JSON)"]),
        row("--heatmap extension not PNG", &[("--heatmap", &out("h.exr"))],         &["--heatmap", "h.exr", "(PNG)"]),
        row("stdout twice",            &[("--out", "-"), ("--metrics", "-")],       &["--metrics", "same file as --out"]),
        row("memory above --max-memory", &[("--size", "4096x4096"), ("--max-memory", "64M")], &["4096x4096", "needs about", "--max-memory"]),
        row("bad --max-memory",        &[("--max-memory", "lots")],                 &["--max-memory", "lots"]),
        row("lying PNG header",        &[("--heightmap", &f.path("lying.png")), ("--max-memory", "8G")], &["lying.png", "60000x60000", "needs about"]),
        row("lying PNG header, no bound", &[("--heightmap", &f.path("lying.png")), ("--max-memory", "1T")], &["lying.png", "60000x60000"]),
        row("height map is a FIFO",    &[("--heightmap", &f.path("fifo.png"))],     &["fifo.png", "not a regular file"]),
        row("height map is a folder",  &[("--heightmap", f.dir.to_str().unwrap())], &["is a folder"]),
        row("degenerate mesh",         &[("--scene", &f.path("degenerate.toml"))],  &["degenerate.obj", "no usable triangle"]),
        row("mesh overflowing f32",    &[("--scene", &f.path("overflow.toml"))],    &["overflow.obj", "overflows f32"]),
        row("mesh is a folder",        &[("--scene", &f.path("folder-mesh.toml"))], &["folder.obj", "is a folder"]),
        row("scene size of 3 numbers", &[("--scene", &f.path("size3.toml"))],       &["size3.toml", "two numbers"]),
        row("scene map without convention", &[("--scene", &f.path("no-convention.toml"))], &["no-convention.toml", "heightmap.convention"]),
        row("negative --fov",          &[("--fov", "-1")],                          &["fov", "-1"]),
        row("negative --camera-height", &[("--camera-height", "-1")],               &["camera-height", "-1"]),
        row("negative --frames",       &[("--frames", "-1")],                       &["--frames", "-1"]),
        row("negative --eps",          &[("--eps", "-1")],                          &["eps", "-1"]),
        row("negative --max-level",    &[("--max-level", "-1")],                    &["max-level", "-1"]),
        row("glTF node cycle",         &[("--scene", &f.path("cycle.toml"))],       &["self.gltf", "node 0 is reached twice"]),
        row("glTF buffer outside",     &[("--scene", &f.path("outside.toml"))],     &["outside.gltf", "points outside the file's folder"]),
        row("read-only output file",   &[("--out", &f.path("read-only.png"))],      &["--out", "read-only.png", "is read-only"]),
        row("NaN in a normal map",     &[("--scene", &f.path("nan-normal.toml"))],  &["nan-normal.exr", "non-finite value NaN at pixel (1, 0)"]),
        // Devices.
        Row { env: no_driver, ..row("no Vulkan driver", &[], &["vkCreateInstance", "Vulkan driver"]) },
        row("no such device (name)",   &[("--device", "no-such-gpu")],              &["no-such-gpu", "no suitable Vulkan device"]),
        row("no such device (index)",  &[("--device", "7")],                        &["device index 7 out of range"]),
    ];
    rows.extend(issue_26_rows(f));
    // A driver manifest that is not JSON: the variable is named (leaked so the row can
    // borrow it for the test's life).
    let icd: &'static str = Box::leak(f.path("bad-icd.json").into_boxed_str());
    let bad_icd: &'static [(&str, &str)] = Box::leak(Box::new([("VK_ICD_FILENAMES", icd), ("VK_DRIVER_FILES", icd)]));
    rows.push(Row { env: bad_icd, ..row("malformed driver manifest", &[], &["bad-icd.json", "VK_DRIVER_FILES", "valid JSON"]) });
    // DISPMAP_VALIDATION neither on nor off: refused by name.
    rows.push(Row { env: &[("DISPMAP_VALIDATION", "2")], ..row("DISPMAP_VALIDATION=2", &[], &["DISPMAP_VALIDATION", "2"]) });
    // Validation requested while the loader disables the layer: said so.
    rows.push(Row { env: &[("VK_LOADER_LAYERS_DISABLE", "VK_LAYER_KHRONOS_validation")], ..row("validation layer disabled", &[], &["VK_LOADER_LAYERS_DISABLE", "disables it"]) });
    // A later output failing (a full device) writes none of them: --out stays absent.
    if let Some(full) = &f.full {
        rows.push(row("metrics on a full device", &[("--metrics", full)], &["full", "No space left"]));
        rows.push(row("heatmap on a full device", &[("--heatmap", full)], &["full", "No space left"]));
    } else {
        f.skip(2, "metrics/heatmap on a full device", "no device node (mknod needs root)");
    }
    if let Some(zero) = &f.zero {
        rows.push(row("height map is /dev/zero's node", &[("--heightmap", zero)], &["zero", "not a regular file"]));
    } else {
        f.skip(1, "height map is /dev/zero's node", "no device node (mknod needs root)");
    }
    if let Some(ro) = &f.read_only {
        let path = ro.join("o.png");
        rows.push(Row {
            options: vec![("--heatmap", path.to_str().unwrap().to_owned())],
            ..row("output on a read-only file system", &[], &["--heatmap", "read-only file system"])
        });
    } else {
        f.skip(1, "output on a read-only file system", "no tmpfs mounted (mount needs root)");
    }
    // A folder this user cannot write (as root: the run drops to nobody, for whom the
    // test's folders are read-only; otherwise a folder made read-only).
    let locked = f.dir.join("locked");
    std::fs::create_dir_all(&locked).unwrap();
    let locked_out = locked.join("o.png").to_str().unwrap().to_owned();
    let nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "--"];
    // As root: only where nobody can run the binary (a checkout under a private home
    // folder cannot be).
    let nobody_runs = || {
        Command::new(nobody[0])
            .args(&nobody[1..])
            .arg(env!("CARGO_BIN_EXE_dispmap"))
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if is_root() && nobody_runs() {
        rows.push(Row {
            wrap: nobody.iter().map(|s| s.to_string()).collect(),
            ..row("output folder not writable", &[("--out", &locked_out)], &["--out", "permission denied", "locked"])
        });
    } else if !is_root() {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
        rows.push(row("output folder not writable", &[("--out", &locked_out)], &["--out", "permission denied", "locked"]));
    } else {
        f.skip(1, "output folder not writable", "root, and nobody cannot run the binary through setpriv (a checkout under a private folder?)");
    }
    // A file size limit: the write fails with EFBIG (SIGXFSZ is ignored), the temporary
    // file is removed and nothing is left.
    rows.push(Row {
        wrap: vec!["sh".into(), "-c".into(), "ulimit -f 1 && exec \"$@\"".into(), "sh".into()],
        ..row("file size limit (SIGXFSZ)", &[("--size", "128x128")], &["out.png", "File too large"])
    });
    rows
}

/// Issue 26's rows (the inputs of [`issue_26_fixtures`]); numbered as the issue's
/// defects.
#[rustfmt::skip]
fn issue_26_rows(f: &Fixtures) -> Vec<Row> {
    let p = |name: &str| f.path(name);
    let rgb = &["rgb channels"][..];
    let without = |r: Row, absent: &[&str]| Row { absent: absent.iter().map(|s| s.to_string()).collect(), ..r };
    let long_name = f.out_dir.join(format!("{}.png", "n".repeat(252)));
    vec![
        // 1. glTF accessors the specification does not allow, named with the file, mesh,
        // primitive and accessor.
        row("glTF indices of BYTE",    &[("--scene", &p("index-byte.toml"))],  &["index-byte.gltf", "mesh 0, primitive 0, accessor 2 (indices)", "SCALAR of BYTE"]),
        row("glTF indices of SHORT",   &[("--scene", &p("index-short.toml"))], &["index-short.gltf", "accessor 2 (indices)", "SCALAR of SHORT"]),
        row("glTF indices of FLOAT",   &[("--scene", &p("index-float.toml"))], &["index-float.gltf", "accessor 2 (indices)", "SCALAR of FLOAT"]),
        row("glTF TEXCOORD_0 of BYTE", &[("--scene", &p("uv-byte.toml"))],     &["uv-byte.gltf", "mesh 0, primitive 0, accessor 1 (TEXCOORD_0)", "VEC2 of BYTE"]),
        row("glTF TEXCOORD_0 of SHORT", &[("--scene", &p("uv-short.toml"))],   &["uv-short.gltf", "accessor 1 (TEXCOORD_0)", "VEC2 of SHORT"]),
        row("glTF TEXCOORD_0 of UNSIGNED_INT", &[("--scene", &p("uv-uint.toml"))], &["uv-uint.gltf", "accessor 1 (TEXCOORD_0)", "VEC2 of UNSIGNED_INT"]),
        row("glTF byteStride below the element", &[("--scene", &p("stride-4.toml"))], &["stride-4.gltf", "accessor 0 (POSITION)", "byteStride 4, smaller than the accessor's 12-byte element"]),
        // 3. Inputs that never end: refused before reading.
        row("scene file is a FIFO",    &[("--scene", &p("fifo-scene.toml"))],  &["fifo-scene.toml", "not a regular file"]),
        row("OBJ mesh is a FIFO",      &[("--scene", &p("fifo-obj.toml"))],    &["fifo.obj", "not a regular file"]),
        row("glTF mesh is a FIFO",     &[("--scene", &p("fifo-gltf.toml"))],   &["fifo.gltf", "not a regular file"]),
        row("glTF .bin is a FIFO",     &[("--scene", &p("fifo-buffer.toml"))], &["fifo-buffer.bin", "not a regular file"]),
        row("scene file is /dev/zero (symlink)", &[("--scene", &p("zero-scene.toml"))], &["zero-scene.toml", "not a regular file"]),
        row("OBJ is /dev/zero (symlink)", &[("--scene", &p("zero-obj.toml"))], &["zero-link.obj", "not a regular file"]),
        row("OBJ mtllib is /dev/zero", &[("--scene", &p("zero-mtl.toml"))],    &["zero-mtl.obj", "mtllib", "zero-link.mtl", "not a regular file"]),
        row("glTF .bin is /dev/zero",  &[("--scene", &p("zero-buffer.toml"))], &["zero-buffer.bin", "not a regular file"]),
        row("2 GB sparse scene file",  &[("--scene", &p("sparse.toml"))],      &["sparse.toml", "2147483648 bytes, more than the 1048576"]),
        row("5 GB sparse OBJ",         &[("--scene", &p("sparse-obj.toml"))],  &["sparse.obj", "5368709120 bytes, more than the 4294967296"]),
        // 4. Meshes count in the memory bound.
        row("mesh above --max-memory", &[("--scene", &p("grid.toml")), ("--max-memory", "150M")], &["grid.obj (90601 vertices, 180000 triangles)", "needs about", "mesh file and parsing", "smaller map, mesh or frame"]),
        row("mesh above 16M triangles", &[("--scene", &p("huge-gltf.toml"))],  &["huge.gltf", "17000000 triangles, more than the 16777216"]),
        // 5. A frame past the device's resource limits, refused before any allocation.
        row("frame past maxResourceSize", &[("--size", "16384x16384"), ("--max-memory", "1T")], &["--size", "16384x16384", "bytes per image", "at most"]),
        // 6. An output name longer than NAME_MAX, refused before any work.
        row("output name past NAME_MAX", &[("--out", long_name.to_str().unwrap())], &["--out", "256 bytes, more than the 255", "NAME_MAX"]),
        // 7. Damaged single-channel OpenEXR: the real cause, not "no rgb channels".
        without(row("EXR cut",          &[("--heightmap", &p("exr-cut.exr"))],     &["exr-cut.exr", "cannot decode part 0 'height' of 1 (channel Y)"]), rgb),
        without(row("EXR offset table past the end", &[("--heightmap", &p("exr-offsets.exr"))], &["exr-offsets.exr", "cannot decode part 0"]), rgb),
        without(row("EXR corrupt ZIP block", &[("--heightmap", &p("exr-zip.exr"))], &["exr-zip.exr", "cannot decode part 0"]), rgb),
        without(row("EXR corrupt RLE block", &[("--heightmap", &p("exr-rle.exr"))], &["exr-rle.exr", "cannot decode part 0"]), rgb),
        without(row("EXR data window lies", &[("--heightmap", &p("exr-window.exr"))], &["exr-window.exr", "cannot decode part 0"]), rgb),
        // 8. Multi-part OpenEXR: the part is named in the range error.
        row("multi-part EXR out of range", &[("--heightmap", &p("multi-high.exr"))], &["multi-high.exr", "part 1 'height' of 2 (channel Y)", "outside [0, 1]"]),
        // 13. A PNG header of 2147483647x1 names its size.
        row("PNG header 2147483647x1", &[("--heightmap", &p("huge.png"))],     &["huge.png", "2147483647x1", "maxImageDimension2D"]),
        // Also seen.
        row("empty --device",          &[("--device", "")],                     &["--device", "is empty"]),
        row("pom --min-steps above --steps", &[("--method", "pom"), ("--min-steps", "64"), ("--steps", "8")], &["min-steps", "64 is above steps 8"]),
        row("PNG palette index past the palette", &[("--heightmap", &p("palette.png"))], &["palette.png", "palette index 5, past the palette's 2 entries"]),
    ]
}

/// Runs `dispmap render` with the valid defaults overridden by `row` and returns the
/// exit code (`None`: killed by a signal) and stderr; fails on a hang.
fn run(row: &Row, out: &Path) -> (Option<i32>, String) {
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
    let mut cmd = match row.wrap.split_first() {
        Some((program, args)) => {
            let mut c = Command::new(program);
            c.args(args).arg(env!("CARGO_BIN_EXE_dispmap"));
            c
        }
        None => Command::new(env!("CARGO_BIN_EXE_dispmap")),
    };
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
    hostile::limit_memory(&mut cmd, ROW_DATA_LIMIT);
    let mut child = cmd.spawn().unwrap();
    let ended = hostile::wait_bounded(&mut child, HANG, row.name);
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    if ended.peak_bytes > ROW_PEAK_BYTES {
        stderr.push_str(&format!(
            "\n[test] peaked at {} MB, more than {} MB",
            ended.peak_bytes >> 20,
            ROW_PEAK_BYTES >> 20
        ));
    }
    if let Some(signal) = ended.signal {
        stderr.push_str(&format!("\n[test] ended by signal {signal}"));
    }
    (ended.code, stderr)
}

/// The first validation message in `stderr` (as the command line logs them: `[vulkan
/// VALIDATION] ...`, or their count), or the allocator's report of a leaked allocation,
/// if any; the loader's notices (`[vulkan notice`) are not messages of the layer.
fn validation_message(stderr: &str) -> Option<&str> {
    stderr.lines().find(|l| {
        (l.contains("[vulkan ") && !l.contains("[vulkan notice"))
            || l.contains("Vulkan validation reported")
            || l.contains("leak detected")
    })
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
    let mut ran = 0;
    for row in rows(&f) {
        ran += 1;
        let (code, stderr) = run(&row, &out);
        let last = stderr
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("");
        eprintln!("{:<32} {last}", row.name);
        let mut problems = Vec::new();
        // 1: a run's error; 2: clap's usage error. Never success, never a signal.
        if !matches!(code, Some(1 | 2)) {
            problems.push(format!("exit code {code:?}, not 1 or 2"));
        }
        if stderr.contains("panicked") {
            problems.push("panicked".to_owned());
        }
        // A refused run that created a device still ends under validation: no message
        // (a leaked object is reported when the device is destroyed), no count of them.
        if let Some(message) = validation_message(&stderr) {
            problems.push(format!("a validation message: {message}"));
        }
        for want in &row.expect {
            if !stderr.contains(want.as_str()) {
                problems.push(format!("'{want}' not in stderr"));
            }
        }
        for unwanted in &row.absent {
            if stderr.contains(unwanted.as_str()) {
                problems.push(format!("'{unwanted}' in stderr (the wrong cause)"));
            }
        }
        if stderr.contains("[test]") {
            problems.push("over its memory bound, or killed".to_owned());
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
    let skipped = f.skipped.get();
    drop(f);
    std::fs::remove_dir_all(&root).ok();
    assert!(
        failures.is_empty(),
        "bad inputs handled badly:\n{}",
        failures.join("\n")
    );
    eprintln!("{ran} rows ran, {skipped} skipped (root only)");
    assert_eq!(
        ran + skipped,
        ROWS,
        "rows ran ({ran}) and skipped ({skipped}): a row was dropped or added without counting it"
    );
}

/// The defaults of [`run`] are valid: the same process succeeds and writes the PNG (so
/// each row fails because of its own input).
#[test]
fn the_defaults_render() {
    let dir = std::env::temp_dir().join(format!("dispmap-bad-input-ok-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out.png");
    let ok = row("valid", &[], &[]);
    let (code, stderr) = run(&ok, &out);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(out.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// The dispmap binary under validation.
fn dispmap() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dispmap"));
    c.env("DISPMAP_VALIDATION", "1")
        .env_remove("DISPMAP_DEVICE")
        .stdin(Stdio::null());
    c
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dispmap-bad-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A render of the rocks map at 16x16, one frame.
fn render_args(c: &mut Command) -> &mut Command {
    c.arg("render")
        .arg("--heightmap")
        .arg(common::repo_root().join("assets/heightmaps/rocks_depth.jpg"))
        .args(["--convention", "depth", "--size", "16x16", "--frames", "1"])
}

/// Outputs are committed together: when a later one fails (a full device), an earlier
/// one's old file is neither replaced nor joined by a temporary file; when all succeed,
/// every one is replaced, keeping its permissions. The first half is root only (the
/// device node is made with mknod in the test's folder): skipped otherwise, a failure
/// where `DISPMAP_NO_SKIP=1`.
#[test]
fn a_failing_output_replaces_no_other() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("commit");
    let full = dir.join("full");
    let png = dir.join("old.png");
    let json = dir.join("old.json");
    std::fs::write(&png, b"old image").unwrap();
    std::fs::set_permissions(&png, std::fs::Permissions::from_mode(0o640)).unwrap();
    std::fs::write(&json, b"old metrics").unwrap();
    if mknod(&full, 1, 7) {
        let out = render_args(&mut dispmap())
            .arg("--out")
            .arg(&png)
            .arg("--metrics")
            .arg(&json)
            .arg("--heatmap")
            .arg(&full)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("--heatmap") || stderr.contains("full"),
            "{stderr}"
        );
        assert!(stderr.contains("No space left"), "{stderr}");
        assert_eq!(std::fs::read(&png).unwrap(), b"old image");
        assert_eq!(std::fs::read(&json).unwrap(), b"old metrics");
        std::fs::remove_file(&full).unwrap();
        assert_eq!(names(&dir), ["old.json", "old.png"]);
    } else {
        skip::skip(
            "a_failing_output_replaces_no_other, the full-device half",
            "no device node (mknod needs root)",
        );
    }
    let out = render_args(&mut dispmap())
        .arg("--out")
        .arg(&png)
        .arg("--metrics")
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(image::open(&png).is_ok());
    assert!(std::fs::read(&json).unwrap().starts_with(b"{"));
    let mode = std::fs::metadata(&png).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640);
    assert_eq!(names(&dir), ["old.json", "old.png"]);
    std::fs::remove_dir_all(&dir).ok();
}

/// `bench` creates and fills its folder only at the end, all files at once: a run that
/// fails while writing them (a file size limit: EFBIG, as SIGXFSZ is ignored) leaves no
/// folder and no temporary file.
#[test]
fn bench_leaves_no_partial_folder() {
    let dir = scratch("bench");
    let out_dir = dir.join("bench-out");
    let out = Command::new("sh")
        .args(["-c", "ulimit -f 8 && exec \"$@\"", "sh"])
        .arg(env!("CARGO_BIN_EXE_dispmap"))
        .env("DISPMAP_VALIDATION", "1")
        .args(["bench", "--quiet", "--out"])
        .arg(&out_dir)
        .args([
            "--size", "16x16", "--frames", "1", "--repeat", "1", "--steps", "8",
        ])
        .args(["--methods", "bump", "--maps", "rocks", "--sizes", "none"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("File too large"), "{stderr}");
    assert!(!out_dir.exists(), "left {:?}", names(&out_dir));
    assert!(names(&dir).is_empty(), "left {:?}", names(&dir));
    std::fs::remove_dir_all(&dir).ok();
}

/// What the command line overrides is not loaded: a scene whose own map or mesh is
/// missing renders with --heightmap or --geometry instead.
#[test]
fn overrides_do_not_load_what_they_override() {
    let dir = scratch("override");
    let scene = dir.join("s.toml");
    std::fs::write(
        &scene,
        "geometry = \"mesh\"\nmesh = \"missing.obj\"\n[heightmap]\npath = \"missing.png\"\nconvention = \"height\"\n",
    )
    .unwrap();
    let png = dir.join("o.png");
    let out = render_args(&mut dispmap())
        .arg("--scene")
        .arg(&scene)
        .args(["--geometry", "plane", "--out"])
        .arg(&png)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(image::open(&png).is_ok());
    // Without the overrides the scene's missing files are named.
    let out = dispmap()
        .args(["render", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.join("p.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("missing.png"), "{stderr}");
    assert!(!dir.join("p.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// A frame with no pixel of the displaced surface (a mesh whose one triangle faces away
/// from the camera) is measured as nothing: a warning, `compared_pixels: 0` and `null`
/// metrics, not PSNR 100 and 0% artifacts.
#[test]
fn an_empty_frame_has_null_metrics_and_a_warning() {
    let dir = scratch("empty");
    // One triangle facing down (-y), seen from above: culled.
    std::fs::write(
        dir.join("down.obj"),
        "v -1 0 -1\nv 1 0 -1\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0.5 1\nf 1/1 2/2 3/3\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("s.toml"),
        "geometry = \"mesh\"\nmesh = \"down.obj\"\nsize = [16, 16]\n",
    )
    .unwrap();
    let json = dir.join("m.json");
    let out = dispmap()
        .args(["render", "--frames", "1", "--scene"])
        .arg(dir.join("s.toml"))
        .arg("--metrics")
        .arg(&json)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("warning: no pixel"), "{stderr}");
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(m["error"]["compared_pixels"], 0, "{m}");
    for key in [
        "mean_texels",
        "p99_texels",
        "max_texels",
        "artifact_fraction",
        "psnr_db",
    ] {
        assert!(m["error"][key].is_null(), "{key}: {m}");
    }
    assert!(
        m["warning"]
            .as_str()
            .unwrap()
            .contains("not a perfect score"),
        "{m}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Above the depth scale where the exact methods are measured to agree with the
/// reference (10), `render` warns, naming the depth scale and the method; at 10 it does not.
#[test]
fn exact_methods_warn_beyond_the_guaranteed_depth_scale() {
    let dir = scratch("depth-scale");
    for (scale, warns) in [("10", false), ("30", true)] {
        let png = dir.join(format!("{scale}.png"));
        let out = render_args(&mut dispmap())
            .args(["--method", "exact", "--depth-scale", scale, "--out"])
            .arg(&png)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert_eq!(
            stderr.contains("warning: --depth-scale 30 is above 10: exact's agreement"),
            warns,
            "{stderr}"
        );
        assert!(png.exists());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A run killed while committing its outputs leaves no temporary file, whichever signal
/// that ends a process by default kills it (issue 26, 11: SIGQUIT and SIGUSR2 too): the
/// commit writes `--out`'s temporary file, then blocks opening a FIFO given as
/// `--heatmap` (no reader), and is killed there.
#[test]
fn a_kill_during_the_commit_leaves_no_temporary_file() {
    for signal in ["TERM", "QUIT", "USR2"] {
        kill_during_the_commit(signal);
    }
}

fn kill_during_the_commit(signal: &str) {
    let dir = scratch(&format!("kill-{signal}"));
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    let fifo = dir.join("heat");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let mut child = render_args(&mut dispmap())
        .arg("--out")
        .arg(out_dir.join("o.png"))
        .arg("--heatmap")
        .arg(&fifo)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while names(&out_dir).is_empty() {
        assert!(start.elapsed() < HANG, "no temporary file appeared");
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before the commit"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let tmp = names(&out_dir);
    assert!(
        tmp[0].starts_with(".o.png.") && tmp[0].ends_with(".tmp"),
        "{tmp:?}"
    );
    assert!(
        Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap()
            .success()
    );
    let status = child.wait().unwrap();
    assert!(
        status.code().is_none(),
        "SIG{signal}: not ended by the signal: {status}"
    );
    assert!(
        names(&out_dir).is_empty(),
        "SIG{signal}: left {:?}",
        names(&out_dir)
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 26, 2: a console that cannot be written (a closed pipe, `/dev/full`) is an
/// ordinary error reported after the run's outputs are committed: `render`, `demo` and
/// `bench` write every output, exit with 1 and say why; `info` too; nothing panics.
#[test]
fn a_console_that_cannot_be_written_loses_no_output() {
    use std::fs::File;
    let dir = scratch("console");
    let full = || Stdio::from(File::options().write(true).open("/dev/full").unwrap());
    // How a run's standard output fails: a pipe whose reader is gone, or a full device.
    let closed_pipe = |c: &mut Command| {
        c.stdout(Stdio::piped()).stderr(Stdio::piped());
        let mut child = c.spawn().unwrap();
        drop(child.stdout.take());
        child
    };
    let on_full = |c: &mut Command| {
        c.stdout(full()).stderr(Stdio::piped());
        c.spawn().unwrap()
    };
    let check = |child: &mut std::process::Child, what: &str| {
        let ended = hostile::wait_bounded(child, HANG, what);
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert_eq!(ended.code, Some(1), "{what}: {stderr}");
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        assert!(
            stderr.contains("error: cannot write to standard output")
                && stderr.contains("its outputs, if any, were written"),
            "{what}: {stderr}"
        );
    };
    let png = dir.join("piped.png");
    let mut child = closed_pipe(
        render_args(&mut dispmap())
            .arg("--out")
            .arg(&png)
            .arg("--metrics")
            .arg(dir.join("piped.json")),
    );
    check(&mut child, "render | (closed)");
    assert!(image::open(&png).is_ok());
    assert!(
        std::fs::read(dir.join("piped.json"))
            .unwrap()
            .starts_with(b"{")
    );
    let png = dir.join("full.png");
    let mut child = on_full(render_args(&mut dispmap()).arg("--out").arg(&png));
    check(&mut child, "render > /dev/full");
    assert!(image::open(&png).is_ok());
    let demo = dir.join("demo");
    let mut child = on_full(
        dispmap()
            .args(["demo", "--size", "16x16", "--frames", "1", "--out-dir"])
            .arg(&demo),
    );
    check(&mut child, "demo > /dev/full");
    assert!(image::open(demo.join("contact_sheet.png")).is_ok());
    assert!(image::open(demo.join("reference.png")).is_ok());
    let bench = dir.join("bench");
    let mut child = closed_pipe(
        dispmap()
            .args([
                "bench", "--quiet", "--size", "16x16", "--frames", "1", "--repeat", "1",
            ])
            .args([
                "--steps",
                "8",
                "--methods",
                "bump",
                "--maps",
                "rocks",
                "--sizes",
                "none",
                "--out",
            ])
            .arg(&bench),
    );
    check(&mut child, "bench | (closed)");
    assert!(bench.join("report.md").exists() && bench.join("results.csv").exists());
    let mut child = on_full(dispmap().arg("info"));
    check(&mut child, "info > /dev/full");
    let leftovers: Vec<String> = names(&dir)
        .into_iter()
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 26, 12: `info` says whether validation is on.
#[test]
fn info_says_whether_validation_is_on() {
    for (env, want) in [
        ("0", "validation:           off"),
        ("1", "validation:           on"),
    ] {
        let out = dispmap()
            .env("DISPMAP_VALIDATION", env)
            .arg("info")
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains(want), "DISPMAP_VALIDATION={env}:\n{stdout}");
    }
}

/// Issue 26, 6: a legal 250-byte output name (the limit is 255) is written: the
/// temporary file's name is cut to fit, and nothing is left beside it.
#[test]
fn a_250_byte_output_name_is_written() {
    let dir = scratch("long-name");
    let name = format!("{}.png", "n".repeat(246));
    assert_eq!(name.len(), 250);
    let out = render_args(&mut dispmap())
        .arg("--out")
        .arg(dir.join(&name))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(image::open(dir.join(&name)).is_ok());
    assert_eq!(names(&dir), [name]);
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 26, 3, 4, 9 and 10: the viewer's file inputs are bounded regular files, its
/// mesh counts in `--max-memory`, a screenshot's name must be a PNG's, and a script's
/// values are checked when it is parsed, naming `file:line`; all before a window opens
/// (no display is needed), fast, in bounded memory, without a panic.
#[test]
fn view_inputs_are_checked_before_a_window() {
    let dir = scratch("view-inputs");
    let fifo = dir.join("fifo.txt");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let zero = dir.join("zero.txt");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let script = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let (fifo, zero) = (fifo.to_str().unwrap(), zero.to_str().unwrap());
    let depth = script("depth.txt", "0 method pom\n1 depth-scale 1001\n");
    let lod = script("lod.txt", "# comment\n\n2 lod 99\n");
    let steps = script("steps.txt", "0 steps 70000\n");
    let shot = script("shot.txt", "0 screenshot x.jpg\n");
    let jpg = dir.join("s.jpg");
    std::fs::write(dir.join("grid.obj"), hostile::obj_grid(300)).unwrap();
    let mesh = script("grid.toml", "geometry = \"mesh\"\nmesh = \"grid.obj\"\n");
    let cases: Vec<(&str, Vec<&str>, Vec<String>)> = vec![
        (
            "mesh above --max-memory",
            vec!["--scene", &mesh, "--max-memory", "150M"],
            vec![
                "grid.obj (90601 vertices, 180000 triangles)".into(),
                "needs about".into(),
            ],
        ),
        (
            "camera path FIFO",
            vec!["--camera-path", fifo],
            vec![fifo.into(), "not a regular file".into()],
        ),
        (
            "script FIFO",
            vec!["--script", fifo],
            vec![fifo.into(), "not a regular file".into()],
        ),
        (
            "camera path /dev/zero",
            vec!["--camera-path", zero],
            vec![zero.into(), "not a regular file".into()],
        ),
        (
            "script /dev/zero",
            vec!["--script", zero],
            vec![zero.into(), "not a regular file".into()],
        ),
        (
            "depth-scale 1001",
            vec!["--script", &depth],
            vec![format!("{depth}:2"), "1001 is outside [0, 1000]".into()],
        ),
        (
            "lod 99",
            vec!["--script", &lod],
            vec![format!("{lod}:3"), "99 is outside 0..=31".into()],
        ),
        (
            "steps 70000",
            vec!["--script", &steps],
            vec![format!("{steps}:1"), "70000 is outside 1..=65536".into()],
        ),
        (
            "script screenshot x.jpg",
            vec!["--script", &shot],
            vec![
                format!("{shot}:1"),
                ".jpg does not match the format written (PNG)".into(),
            ],
        ),
        (
            "--screenshot s.jpg",
            vec!["--screenshot", jpg.to_str().unwrap()],
            vec![
                "s.jpg".into(),
                ".jpg does not match the format written (PNG)".into(),
            ],
        ),
    ];
    for (what, args, want) in cases {
        let mut cmd = dispmap();
        cmd.args(["view", "--frames", "2", "--size", "16x16"])
            .args(&args)
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        hostile::limit_memory(&mut cmd, ROW_DATA_LIMIT);
        let mut child = cmd.spawn().unwrap();
        let ended = hostile::wait_bounded(&mut child, HANG, what);
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert_eq!(ended.code, Some(1), "{what}: {stderr}");
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        for w in &want {
            assert!(stderr.contains(w.as_str()), "{what}: '{w}' not in {stderr}");
        }
        assert!(
            ended.peak_bytes < ROW_PEAK_BYTES,
            "{what}: {} MB",
            ended.peak_bytes >> 20
        );
    }
    assert!(!jpg.exists() && !dir.join("x.jpg").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// The inputs issue 26 keeps working: a multi-part OpenEXR whose height is in its second
/// part renders from that part and says so; glTF files with the accessor types the
/// specification allows (normalized UNSIGNED_SHORT texture coordinates, UNSIGNED_INT
/// indices) render; a palette PNG whose indices are all in its palette renders.
#[test]
fn allowed_inputs_render() {
    let dir = scratch("allowed");
    let palette = dir.join("palette.png");
    std::fs::write(
        &palette,
        hostile::png(
            2,
            2,
            3,
            Some(&[0, 0, 0, 255, 255, 255]),
            &[0, 0, 1, 0, 1, 0],
        ),
    )
    .unwrap();
    let out = dispmap()
        .args([
            "render",
            "--convention",
            "height",
            "--size",
            "16x16",
            "--frames",
            "1",
            "--heightmap",
        ])
        .arg(&palette)
        .arg("--out")
        .arg(dir.join("palette-out.png"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let multi = dir.join("multi.exr");
    std::fs::write(
        &multi,
        hostile::exr(
            &[("color", "R", 1.0), ("height", "Y", 1.0)],
            4,
            4,
            exr::compression::Compression::ZIP16,
        ),
    )
    .unwrap();
    let out = dispmap()
        .args([
            "render",
            "--convention",
            "height",
            "--size",
            "16x16",
            "--frames",
            "1",
            "--heightmap",
        ])
        .arg(&multi)
        .arg("--out")
        .arg(dir.join("multi.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("note:") && stderr.contains("part 1 'height' of 2 (channel Y)"),
        "{stderr}"
    );
    for (name, uv, index) in [
        ("float", hostile::FLOAT, hostile::UNSIGNED_INT),
        ("ushort", hostile::UNSIGNED_SHORT, hostile::UNSIGNED_SHORT),
        ("ubyte", hostile::UNSIGNED_BYTE, hostile::UNSIGNED_BYTE),
    ] {
        hostile::gltf_triangle(&dir, name, uv, index, Some(12));
        let scene = dir.join(format!("{name}.toml"));
        std::fs::write(
            &scene,
            format!("geometry = \"mesh\"\nmesh = \"{name}.gltf\"\nsize = [16, 16]\n"),
        )
        .unwrap();
        let png = dir.join(format!("{name}.png"));
        let out = dispmap()
            .args(["render", "--frames", "1", "--scene"])
            .arg(&scene)
            .arg("--out")
            .arg(&png)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        assert!(image::open(&png).is_ok());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 26, 4: what a mesh adds to a render's peak resident memory stays within what
/// it adds to the estimate `--max-memory` is checked against (an 80,000-triangle OBJ
/// grid against the same scene on the plane; both under validation, whose own memory
/// is in neither difference).
#[test]
fn a_mesh_render_stays_within_its_estimate() {
    let dir = scratch("mesh-memory");
    std::fs::write(dir.join("grid.obj"), hostile::obj_grid(200)).unwrap();
    let mesh = dir.join("grid.toml");
    std::fs::write(
        &mesh,
        "geometry = \"mesh\"\nmesh = \"grid.obj\"\nsize = [16, 16]\n",
    )
    .unwrap();
    let plane = dir.join("plane.toml");
    std::fs::write(&plane, "size = [16, 16]\n").unwrap();
    let measure = |scene: &Path| {
        let refused = dispmap()
            .args(["render", "--frames", "1", "--max-memory", "1", "--scene"])
            .arg(scene)
            .arg("--out")
            .arg(dir.join("refused.png"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&refused.stderr);
        let mib: f64 = stderr
            .split("needs about ")
            .nth(1)
            .and_then(|rest| rest.split(" MiB").next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no estimate in: {stderr}"));
        let mut cmd = dispmap();
        cmd.args(["render", "--frames", "1", "--scene"])
            .arg(scene)
            .arg("--out")
            .arg(dir.join("out.png"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().unwrap();
        let ended = hostile::wait_bounded(&mut child, HANG, "render");
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert_eq!(ended.code, Some(0), "{stderr}");
        assert!(image::open(dir.join("out.png")).is_ok());
        (
            (mib * f64::from(1u32 << 20)) as i64,
            ended.peak_bytes as i64,
        )
    };
    let (mesh_estimate, mesh_peak) = measure(&mesh);
    let (plane_estimate, plane_peak) = measure(&plane);
    let (added, estimated) = (mesh_peak - plane_peak, mesh_estimate - plane_estimate);
    eprintln!(
        "the mesh adds {} MiB, estimated {} MiB",
        added >> 20,
        estimated >> 20
    );
    assert!(
        added <= estimated,
        "the mesh adds {} MiB, more than its estimate {} MiB",
        added >> 20,
        estimated >> 20
    );
    std::fs::remove_dir_all(&dir).ok();
}

// ---------------------------------------------------------------------------------------
// Issue 37 (reliability, fourth round): inputs refused naming the object, key and file,
// checked before work; the albedo and normal maps in the memory bound. Kept apart from
// the table above: these rows need their own command lines (scenes of several objects
// refuse the table's --heightmap, bench and demo are other commands).
// ---------------------------------------------------------------------------------------

/// One refused input of issue 37: the whole command line after `dispmap`, the
/// environment, a command it runs through, and what stderr must and must not contain.
struct Refusal {
    name: &'static str,
    args: Vec<String>,
    env: &'static [(&'static str, &'static str)],
    wrap: &'static [&'static str],
    expect: &'static [&'static str],
    absent: &'static [&'static str],
}

/// The scenes and files of [`issue_37_refusals`], written into `dir`.
fn issue_37_fixtures(dir: &Path) {
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    let cube = "[[object]]\ngeometry = \"cube\"\n[object.heightmap]\n";
    // 7. pom's n_min above n_max in an object's [method] and in the scene's [method] that
    // the objects take.
    write(
        "objects-pom.toml",
        &format!("{cube}[object.method]\nname = \"pom\"\nsteps = 8\nmin_steps = 64\n"),
    );
    write(
        "scene-pom.toml",
        &format!("[method]\nname = \"pom\"\nsteps = 8\nmin_steps = 64\n{cube}"),
    );
    // 8. Loop budgets of an object, and an empty mesh name.
    write(
        "objects-eps.toml",
        &format!("{cube}[object.method]\nname = \"dig\"\neps = 0.0\n"),
    );
    write(
        "objects-secant.toml",
        &format!("{cube}[object.method]\nname = \"secant\"\nsteps = 4096\nsegments = 64\n"),
    );
    write(
        "objects-mesh.toml",
        "[[object]]\ngeometry = \"mesh\"\nmesh = \"\"\n[object.heightmap]\n",
    );
    write("mesh-empty.toml", "geometry = \"mesh\"\nmesh = \"\"\n");
    write(
        "objects-albedo-empty.toml",
        &format!("{cube}[object.material]\nalbedo = \"\"\n"),
    );
    // 9. A scene of several objects (its --heatmap-max is checked before the device).
    write("objects.toml", &format!("size = [16, 16]\n{cube}"));
    // 4. A quad seen from nearer than the near plane; the plane's eye inside a cube at
    // the origin.
    write(
        "quad-near.toml",
        "geometry = \"quad\"\nsize = [16, 16]\n[camera]\ndistance = 0.001\n",
    );
    write(
        "eye-cube.toml",
        "size = [16, 16]\n[[object]]\ngeometry = \"plane\"\n[object.heightmap]\n\
         [[object]]\ngeometry = \"cube\"\n",
    );
    // 2. A 4096x4096 albedo (a small file, 64 MiB of texels) under --max-memory.
    let mut png = Vec::new();
    image::RgbImage::from_pixel(4096, 4096, image::Rgb([90, 120, 60]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(dir.join("albedo.png"), png).unwrap();
    write(
        "albedo.toml",
        "size = [16, 16]\n[material]\nalbedo = \"albedo.png\"\n",
    );
    // 9. bench's and demo's files in the way: a read-only results.csv, a folder named
    // report.md, a read-only contact_sheet.png.
    use std::os::unix::fs::PermissionsExt;
    for (folder, file) in [
        ("bench-csv", "results.csv"),
        ("demo-sheet", "contact_sheet.png"),
    ] {
        std::fs::create_dir_all(dir.join(folder)).unwrap();
        let path = dir.join(folder).join(file);
        std::fs::write(&path, b"old").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o444)).unwrap();
    }
    std::fs::create_dir_all(dir.join("bench-md/report.md")).unwrap();
    // The viewer's script and camera path, checked when read.
    write("script-error.txt", "1 error\n");
    write("script-late.txt", "0 method pom\n99 screenshot late.png\n");
    write("script-two.txt", "1 screenshot a.png\n1 screenshot b.png\n");
    write(
        "script-same.txt",
        "0 screenshot a.png\n1 screenshot a.png\n",
    );
    write("script-resize.txt", "1 resize 2048x2048\n");
    write(
        "script-resize-1024.txt",
        "# the albedo counts too\n1 resize 1024x1024\n",
    );
    write("path-high.txt", "30 0\n30 10 20000\n");
    write("path-low.txt", "30 0 0.001\n");
}

/// Issue 37's refused inputs (the files of [`issue_37_fixtures`] in `dir`, outputs into
/// `out`), numbered as the issue's defects.
#[rustfmt::skip]
fn issue_37_refusals(dir: &Path, out: &Path) -> Vec<Refusal> {
    let p = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    let o = |name: &str| out.join(name).to_str().unwrap().to_owned();
    let rocks = common::repo_root().join("assets/heightmaps/rocks_depth.jpg").to_str().unwrap().to_owned();
    let scene = |file: &str, more: &[&str]| {
        let mut v: Vec<String> = ["render", "--frames", "1", "--scene"].iter().map(|s| s.to_string()).collect();
        v.push(p(file));
        v.extend(["--out".to_owned(), o("o.png")]);
        v.extend(more.iter().map(|s| s.to_string()));
        v
    };
    let flags = |more: &[&str]| {
        let mut v: Vec<String> = ["render", "--frames", "1", "--size", "16x16", "--convention", "depth", "--heightmap"].iter().map(|s| s.to_string()).collect();
        v.push(rocks.clone());
        v.extend(more.iter().map(|s| s.to_string()));
        v
    };
    let no_driver: &'static [(&str, &str)] = &[("VK_ICD_FILENAMES", "/nonexistent/icd.json"), ("VK_DRIVER_FILES", "/nonexistent/icd.json")];
    let view = |more: &[&str]| {
        let mut v: Vec<String> = ["view", "--frames", "3", "--no-ui"].iter().map(|s| s.to_string()).collect();
        v.extend(more.iter().map(|s| s.to_string()));
        v
    };
    let r = |name, args, expect| Refusal { name, args, env: &[], wrap: &[], expect, absent: &[] };
    vec![
        // 2. The albedo counts in the memory bound.
        r("2: albedo above --max-memory", scene("albedo.toml", &["--max-memory", "250M"]), &["albedo.toml", "needs about", "albedo and normal maps"]),
        // 4. Cameras that would render garbage are refused, naming the option or key.
        r("4: eye below the near plane", flags(&["--camera-height", "0.001", "--out", &o("o.png")]), &["camera-height", "0.001", "near plane (0.005)", "at least"]),
        r("4: quad nearer than the near plane", scene("quad-near.toml", &[]), &["camera-distance in", "quad-near.toml", "near plane"]),
        r("4: eye inside a cube", scene("eye-cube.toml", &[]), &["camera in", "eye-cube.toml", "inside object 2"]),
        // 7. An object's method values checked as the command line's.
        r("7: object pom min_steps above steps", scene("objects-pom.toml", &[]), &["object 1 min-steps in", "objects-pom.toml", "64 is above steps 8"]),
        r("7: scene [method] pom min_steps above steps", scene("scene-pom.toml", &[]), &["object 1 min-steps in", "scene-pom.toml", "64 is above steps 8"]),
        // 8. Errors name the object and the file, and no flag the user did not give.
        Refusal { absent: &["--eps"], ..r("8: object dig eps 0", scene("objects-eps.toml", &[]), &["object 1 eps in", "objects-eps.toml", "raise eps"]) },
        Refusal { absent: &["--steps", "--segments"], ..r("8: object secant steps x segments", scene("objects-secant.toml", &[]), &["object 1 steps and segments in", "objects-secant.toml", "lower steps or segments"]) },
        r("8: object mesh \"\"", scene("objects-mesh.toml", &[]), &["object 1 mesh in", "objects-mesh.toml", "is empty"]),
        r("8: scene mesh \"\"", scene("mesh-empty.toml", &[]), &["mesh in", "mesh-empty.toml", "is empty"]),
        r("8: object albedo \"\"", scene("objects-albedo-empty.toml", &[]), &["object 1 material.albedo in", "objects-albedo-empty.toml", "is empty"]),
        // 9. Outputs checked before any work (without a Vulkan driver, any work fails).
        Refusal { env: no_driver, ..r("9: objects --heatmap-max 0", scene("objects.toml", &["--heatmap", &o("h.png"), "--heatmap-max", "0"]), &["--heatmap-max", "0 is not a positive"]) },
        Refusal { env: no_driver, ..r("9: bench read-only results.csv", vec!["bench".into(), "--out".into(), p("bench-csv"), "--quiet".into()], &["--out", "results.csv", "read-only"]) },
        Refusal { env: no_driver, ..r("9: bench report.md a folder", vec!["bench".into(), "--out".into(), p("bench-md"), "--quiet".into()], &["--out", "report.md", "is a folder"]) },
        Refusal { env: no_driver, ..r("9: demo read-only contact_sheet.png", vec!["demo".into(), "--out-dir".into(), p("demo-sheet")], &["--out-dir", "contact_sheet.png", "read-only"]) },
        // 1, 6, 10. The viewer's script and camera path, checked completely when read
        // (no display is needed to be refused: nothing opens a window first).
        r("1: view script `error` on objects", view(&["--scene", &p("objects.toml"), "--script", &p("script-error.txt")]), &["script-error.txt:1", "error overlay is not available"]),
        r("6: view screenshot past --frames", view(&["--script", &p("script-late.txt")]), &["script-late.txt:2", "frame 99 is past the last frame", "--frames 3"]),
        r("6: view two screenshots at a frame", view(&["--script", &p("script-two.txt")]), &["script-two.txt:2", "second screenshot at frame 1"]),
        r("6: view one file for two screenshots", view(&["--script", &p("script-same.txt")]), &["script-same.txt:2", "a.png is also the screenshot of line 1"]),
        r("10: view camera path height 20000", view(&["--camera-path", &p("path-high.txt")]), &["path-high.txt:2", "camera-height", "20000"]),
        r("10: view camera path below the near plane", view(&["--camera-path", &p("path-low.txt")]), &["path-low.txt:1", "camera-height", "near plane"]),
        // 3. The viewer's memory bound, its scripted resizes included.
        r("3: view 2048x2048 under --max-memory", view(&["--size", "2048x2048", "--max-memory", "150M"]), &["viewing 2048x2048", "needs about", "--max-memory"]),
        r("3: view scripted resize under --max-memory", view(&["--size", "64x64", "--max-memory", "150M", "--script", &p("script-resize.txt")]), &["script-resize.txt:1", "viewing 2048x2048", "needs about", "--max-memory"]),
        // 2, 3. The viewer's bound counts the scene's albedo (at 1024x1024 the frame
        // alone fits 500M: 405 MiB; with the 4096x4096 albedo 661 MiB).
        r("2, 3: view albedo scene resized above --max-memory", view(&["--scene", &p("albedo.toml"), "--max-memory", "500M", "--script", &p("script-resize-1024.txt")]), &["script-resize-1024.txt:2", "viewing 1024x1024", "albedo and normal maps", "needs about"]),
        // 12. A closed standard output takes no file.
        Refusal { wrap: &["sh", "-c", "exec \"$@\" >&-", "sh"], ..r("12: --out - with stdout closed", flags(&["--out", "-"]), &["--out", "standard output is closed"]) },
    ]
}

/// Every input of [`issue_37_refusals`] is refused (exit 1 or 2) within [`HANG`], naming
/// what the row expects, never panicking, and leaving nothing in the output folder.
#[test]
fn issue_37_inputs_are_refused_naming_them() {
    let dir = scratch("issue37");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    issue_37_fixtures(&dir);
    let mut failures = Vec::new();
    for row in issue_37_refusals(&dir, &out) {
        let mut cmd = match row.wrap.split_first() {
            Some((program, args)) => {
                let mut c = Command::new(program);
                c.args(args).arg(env!("CARGO_BIN_EXE_dispmap"));
                c
            }
            None => Command::new(env!("CARGO_BIN_EXE_dispmap")),
        };
        cmd.env("DISPMAP_VALIDATION", "1")
            .env_remove("DISPMAP_DEVICE")
            .envs(row.env.iter().copied())
            .args(&row.args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        hostile::limit_memory(&mut cmd, ROW_DATA_LIMIT);
        let mut child = cmd.spawn().unwrap();
        let ended = hostile::wait_bounded(&mut child, HANG, row.name);
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        eprintln!("{:<40} {}", row.name, stderr.lines().last().unwrap_or(""));
        let mut problems = Vec::new();
        if !matches!(ended.code, Some(1 | 2)) {
            problems.push(format!("exit code {:?}, not 1 or 2", ended.code));
        }
        if stderr.contains("panicked") {
            problems.push("panicked".to_owned());
        }
        for want in row.expect {
            if !stderr.contains(want) {
                problems.push(format!("'{want}' not in stderr"));
            }
        }
        for unwanted in row.absent {
            if stderr.contains(unwanted) {
                problems.push(format!("'{unwanted}' in stderr"));
            }
        }
        let left = names(&out);
        if !left.is_empty() {
            problems.push(format!("left {left:?}"));
            for name in left {
                std::fs::remove_file(out.join(name)).ok();
            }
        }
        if !problems.is_empty() {
            failures.push(format!("{}: {}\n{stderr}", row.name, problems.join("; ")));
        }
    }
    // The files in the way are untouched.
    for file in ["bench-csv/results.csv", "demo-sheet/contact_sheet.png"] {
        assert_eq!(std::fs::read(dir.join(file)).unwrap(), b"old", "{file}");
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        failures.is_empty(),
        "issue 37 inputs handled badly:\n{}",
        failures.join("\n")
    );
}

/// The albedo and normal maps are in the memory estimate, and objects naming one file
/// share one copy of it, on the CPU and on the GPU: four cubes naming one 4096x4096
/// albedo add to the estimate what one cube naming it adds (one copy), a `--max-memory`
/// between that estimate and what four GPU copies would need accepts the run, and its
/// measured peak stays under the bound (with a GPU image per material it measured
/// above it: four images, staging buffers and upload copies).
#[test]
fn issue_37_albedo_maps_are_in_the_estimate_and_shared() {
    let dir = scratch("albedo-memory");
    const SIDE: u32 = 4096;
    let mut png = Vec::new();
    image::RgbImage::from_pixel(SIDE, SIDE, image::Rgb([90, 120, 60]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(dir.join("albedo.png"), png).unwrap();
    let scene = |name: &str, objects: i32, albedo: bool| {
        let mut text = String::from("size = [16, 16]\n");
        for k in 0..objects {
            text.push_str(&format!(
                "[[object]]\ngeometry = \"cube\"\nposition = [{}, 0, 0]\nscale = 0.5\n\
                 [object.heightmap]\n",
                2 * k - 3
            ));
            if albedo {
                text.push_str("[object.material]\nalbedo = \"albedo.png\"\n");
            }
        }
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    // The estimate `render` checks --max-memory against, in bytes (from its refusal).
    let estimate = |scene: &Path| {
        let refused = dispmap()
            .args(["render", "--frames", "1", "--max-memory", "1", "--scene"])
            .arg(scene)
            .arg("--out")
            .arg(dir.join("refused.png"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&refused.stderr);
        let mib: f64 = stderr
            .split("needs about ")
            .nth(1)
            .and_then(|rest| rest.split(" MiB").next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no estimate in: {stderr}"));
        (mib * f64::from(1u32 << 20)) as i64
    };
    // The run's exit code and peak resident memory, with --max-memory `bound`.
    let run = |scene: &Path, bound: i64| {
        let mut cmd = dispmap();
        cmd.args(["render", "--frames", "1", "--scene"])
            .arg(scene)
            .arg("--max-memory")
            .arg(bound.to_string())
            .arg("--out")
            .arg(dir.join("out.png"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().unwrap();
        let ended = hostile::wait_bounded(&mut child, HANG, "render");
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert_eq!(ended.code, Some(0), "under --max-memory {bound}: {stderr}");
        ended.peak_bytes as i64
    };
    let four = scene("four.toml", 4, true);
    let four_plain = scene("four-plain.toml", 4, false);
    let (one, one_plain) = (
        scene("one.toml", 1, true),
        scene("one-plain.toml", 1, false),
    );
    let added_four = estimate(&four) - estimate(&four_plain);
    let added_one = estimate(&one) - estimate(&one_plain);
    let texels = i64::from(SIDE) * i64::from(SIDE);
    eprintln!(
        "one {SIDE}x{SIDE} albedo adds {} MiB to the estimate of one cube and {} MiB to that \
         of four cubes naming it",
        added_one >> 20,
        added_four >> 20
    );
    // One copy: four objects add what one adds (the estimates are printed to 0.1 MiB).
    assert!(
        (added_four - added_one).abs() <= 1 << 18,
        "four objects naming one albedo add {added_four} bytes, one adds {added_one}"
    );
    assert!(added_one >= 12 * texels, "{added_one}");
    // A bound that one copy fits and four GPU copies (12 bytes per texel each) would not.
    let bound = estimate(&four) + (1 << 20);
    assert!(bound < estimate(&four_plain) + 4 * 12 * texels);
    let peak = run(&four, bound);
    let peak_plain = run(&four_plain, bound);
    eprintln!(
        "four objects naming one {SIDE}x{SIDE} albedo: peak {} MiB under --max-memory {} MiB \
         (the albedo adds {} MiB, estimated {} MiB)",
        peak >> 20,
        bound >> 20,
        (peak - peak_plain) >> 20,
        added_four >> 20
    );
    assert!(
        peak <= bound,
        "peaked at {} MiB, above the --max-memory {} MiB the run was accepted under",
        peak >> 20,
        bound >> 20
    );
    assert!(
        peak - peak_plain <= added_four,
        "the albedo adds {} MiB to the peak, more than its estimate {} MiB",
        (peak - peak_plain) >> 20,
        added_four >> 20
    );
    std::fs::remove_dir_all(&dir).ok();
}
