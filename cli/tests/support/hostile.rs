//! Builders of the hostile inputs of `bad_input.rs` (issue 26), each made in the test:
//! glTF files whose accessors break the specification, damaged and multi-part OpenEXR
//! files, PNGs with a huge header or a short palette, and the bounded wait that measures
//! a run's time and peak memory.

use std::path::Path;
use std::process::Child;
use std::time::{Duration, Instant};

/// glTF component types (the specification's GLenums).
pub const BYTE: u32 = 5120;
pub const UNSIGNED_BYTE: u32 = 5121;
pub const SHORT: u32 = 5122;
pub const UNSIGNED_SHORT: u32 = 5123;
pub const UNSIGNED_INT: u32 = 5125;
pub const FLOAT: u32 = 5126;

/// One triangle as a glTF file `name.gltf` with its buffer `name.bin` in `dir`:
/// POSITION (accessor 0, bufferView 0, `stride` when given), TEXCOORD_0 of `uv_type`
/// (accessor 1, normalized unless FLOAT) and indices of `index_type` (accessor 2). With
/// FLOAT, UNSIGNED_SHORT and UNSIGNED_INT (as the specification allows) it loads.
pub fn gltf_triangle(dir: &Path, name: &str, uv_type: u32, index_type: u32, stride: Option<u32>) {
    let size = |t: u32| match t {
        BYTE | UNSIGNED_BYTE => 1u32,
        SHORT | UNSIGNED_SHORT => 2,
        _ => 4,
    };
    let mut bin = Vec::new();
    for p in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]] {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let uv_at = bin.len();
    for uv in [[0f32, 0.0], [1.0, 0.0], [0.0, 1.0]] {
        for c in uv {
            match uv_type {
                FLOAT => bin.extend_from_slice(&c.to_le_bytes()),
                UNSIGNED_SHORT | SHORT => {
                    bin.extend_from_slice(&((c * 32767.0) as u16).to_le_bytes())
                }
                UNSIGNED_INT => bin.extend_from_slice(&(c as u32).to_le_bytes()),
                _ => bin.push((c * 127.0) as u8),
            }
        }
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let index_at = bin.len();
    for i in 0..3u32 {
        match index_type {
            FLOAT => bin.extend_from_slice(&(i as f32).to_le_bytes()),
            UNSIGNED_INT => bin.extend_from_slice(&i.to_le_bytes()),
            UNSIGNED_SHORT | SHORT => bin.extend_from_slice(&(i as u16).to_le_bytes()),
            _ => bin.push(i as u8),
        }
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    std::fs::write(dir.join(format!("{name}.bin")), &bin).unwrap();
    let stride = stride.map_or(String::new(), |s| format!(",\"byteStride\":{s}"));
    let normalized = if uv_type == FLOAT {
        ""
    } else {
        ",\"normalized\":true"
    };
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2}}]}}],
"buffers":[{{"uri":"{name}.bin","byteLength":{len}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36{stride}}},
{{"buffer":0,"byteOffset":{uv_at},"byteLength":{uv_len}}},
{{"buffer":0,"byteOffset":{index_at},"byteLength":{index_len}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,-1],"max":[1,0,0]}},
{{"bufferView":1,"componentType":{uv_type},"count":3,"type":"VEC2"{normalized}}},
{{"bufferView":2,"componentType":{index_type},"count":3,"type":"SCALAR"}}]}}"#,
        len = bin.len(),
        uv_len = index_at - uv_at,
        index_len = 3 * size(index_type),
    );
    std::fs::write(dir.join(format!("{name}.gltf")), json).unwrap();
}

/// A glTF whose one primitive claims `triangles` triangles (an index accessor of that
/// many indices times 3 over a buffer that does not hold them): refused by its counts
/// before any buffer is read.
pub fn gltf_claiming(dir: &Path, name: &str, triangles: u64) {
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
"buffers":[{{"uri":"{name}.bin","byteLength":4}}],
"bufferViews":[{{"buffer":0,"byteLength":4}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}},
{{"bufferView":0,"componentType":5125,"count":{},"type":"SCALAR"}}]}}"#,
        triangles * 3
    );
    std::fs::write(dir.join(format!("{name}.gltf")), json).unwrap();
    std::fs::write(dir.join(format!("{name}.bin")), [0u8; 4]).unwrap();
}

/// A `side x side` grid of `2 side²` triangles as OBJ text with uvs.
pub fn obj_grid(side: u32) -> String {
    let mut s = String::new();
    for j in 0..=side {
        for i in 0..=side {
            s.push_str(&format!(
                "v {i} 0 {j}\nvt {} {}\n",
                i as f32 / side as f32,
                j as f32 / side as f32
            ));
        }
    }
    let at = |i: u32, j: u32| j * (side + 1) + i + 1;
    for j in 0..side {
        for i in 0..side {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            s.push_str(&format!(
                "f {a}/{a} {d}/{d} {c}/{c}\nf {a}/{a} {c}/{c} {b}/{b}\n"
            ));
        }
    }
    s
}

/// An OpenEXR file of `layers` (name, channel, value per pixel), each `w x h`, f32,
/// compressed with `compression`.
pub fn exr(
    layers: &[(&str, &str, f32)],
    w: usize,
    h: usize,
    compression: exr::compression::Compression,
) -> Vec<u8> {
    use exr::prelude::*;
    let layers: Vec<Layer<AnyChannels<FlatSamples>>> = layers
        .iter()
        .map(|&(name, channel, value)| {
            let values: Vec<f32> = (0..w * h)
                .map(|k| value * (k as f32 + 1.0) / (w * h) as f32)
                .collect();
            let channels =
                AnyChannels::sort(vec![AnyChannel::new(channel, FlatSamples::F32(values))].into());
            Layer::new(
                (w, h),
                LayerAttributes::named(name),
                Encoding {
                    compression,
                    blocks: Blocks::ScanLines,
                    line_order: LineOrder::Increasing,
                },
                channels,
            )
        })
        .collect();
    let image = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((w, h))),
        layers,
    );
    let mut out = std::io::Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).unwrap();
    out.into_inner()
}

/// The byte offset where a single-part OpenEXR file's header ends (its offset table
/// starts): after the magic number, the version and the attributes up to the empty name.
pub fn exr_header_end(bytes: &[u8]) -> usize {
    let mut at = 8;
    loop {
        let name_end = at + bytes[at..].iter().position(|&b| b == 0).unwrap();
        if name_end == at {
            return at + 1;
        }
        let type_end = name_end + 1 + bytes[name_end + 1..].iter().position(|&b| b == 0).unwrap();
        let size =
            i32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap()) as usize;
        at = type_end + 5 + size;
    }
}

/// The byte offset of an attribute's value in a single-part OpenEXR header.
pub fn exr_attribute(bytes: &[u8], name: &str) -> usize {
    let mut at = 8;
    loop {
        let name_end = at + bytes[at..].iter().position(|&b| b == 0).unwrap();
        assert!(name_end > at, "no attribute {name}");
        let type_end = name_end + 1 + bytes[name_end + 1..].iter().position(|&b| b == 0).unwrap();
        let size =
            i32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap()) as usize;
        if &bytes[at..name_end] == name.as_bytes() {
            return type_end + 5;
        }
        at = type_end + 5 + size;
    }
}

/// The PNG chunk `kind` with `data` and its CRC.
pub fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut body = kind.to_vec();
    body.extend_from_slice(data);
    let mut crc = !0u32;
    for &b in &body {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    let mut out = (data.len() as u32).to_be_bytes().to_vec();
    out.extend_from_slice(&body);
    out.extend_from_slice(&(!crc).to_be_bytes());
    out
}

/// A PNG of `width x height` 8-bit pixels of color type `color` whose image data is
/// `rows` (each row with its filter byte), with `palette` entries (RGB) when given.
pub fn png(width: u32, height: u32, color: u8, palette: Option<&[u8]>, rows: &[u8]) -> Vec<u8> {
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, color, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(png_chunk(b"IHDR", &ihdr));
    if let Some(p) = palette {
        out.extend(png_chunk(b"PLTE", p));
    }
    // Stored (uncompressed) deflate blocks in a zlib stream.
    let mut z = vec![0x78, 0x01];
    let mut chunks = rows.chunks(65535).peekable();
    while let Some(c) = chunks.next() {
        z.push(u8::from(chunks.peek().is_none()));
        z.extend_from_slice(&(c.len() as u16).to_le_bytes());
        z.extend_from_slice(&(!(c.len() as u16)).to_le_bytes());
        z.extend_from_slice(c);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in rows {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    z.extend_from_slice(&((b << 16) | a).to_be_bytes());
    out.extend(png_chunk(b"IDAT", &z));
    out.extend(png_chunk(b"IEND", &[]));
    out
}

/// How a bounded run ended.
pub struct Ended {
    /// The exit code (`None`: a signal).
    pub code: Option<i32>,
    /// The signal that ended it.
    pub signal: Option<i32>,
    /// Peak resident memory in bytes.
    pub peak_bytes: u64,
}

/// Waits for `child`, killing it after `limit`, and returns how it ended with its peak
/// resident memory (`wait4`'s `ru_maxrss`).
pub fn wait_bounded(child: &mut Child, limit: Duration, what: &str) -> Ended {
    let pid = child.id() as libc::pid_t;
    let start = Instant::now();
    loop {
        let mut status = 0;
        // SAFETY: a zeroed rusage is valid for wait4 to fill; `pid` is our child, not yet
        // reaped (Child::wait is never called on it).
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if r == pid {
            let exited = libc::WIFEXITED(status);
            return Ended {
                code: exited.then(|| libc::WEXITSTATUS(status)),
                signal: libc::WIFSIGNALED(status).then(|| libc::WTERMSIG(status)),
                peak_bytes: usage.ru_maxrss as u64 * 1024,
            };
        }
        assert!(r == 0, "{what}: wait4 failed");
        if start.elapsed() > limit {
            child.kill().ok();
            panic!("{what}: still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Limits the data segment (heap and private mappings) of commands run by `cmd` to
/// `bytes`, so a run that reads without bound fails instead of taking the machine.
pub fn limit_memory(cmd: &mut std::process::Command, bytes: u64) {
    use std::os::unix::process::CommandExt as _;
    // SAFETY: the closure runs in the forked child before exec and only calls
    // setrlimit(2), which is async-signal-safe.
    unsafe {
        cmd.pre_exec(move || {
            let limit = libc::rlimit {
                rlim_cur: bytes,
                rlim_max: bytes,
            };
            libc::setrlimit(libc::RLIMIT_DATA, &limit);
            Ok(())
        });
    }
}
