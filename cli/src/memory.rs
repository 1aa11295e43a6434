//! The memory bound of a run: an estimate of the bytes a render needs from the map's and
//! the frame's size, made before anything large is allocated, and refused when it is
//! above the memory available (or `--max-memory`). See docs/guarantees.md.
//!
//! The estimate is the larger of the two peaks of a run: loading the map (the file's
//! bytes, the decoded image and the height field it becomes, all held at once) and
//! rendering (the height field, the GPU's copy of it with its pyramids, the frame's GPU
//! buffers and read-backs, and with `--metrics` the exact reference: its texels and max
//! pyramid, [`Reference::memory_bytes`], and its per-pixel rays and hits). The per-texel
//! and per-pixel coefficients are the peak resident memory measured on lavapipe (whose
//! "GPU" memory is the process's), rounded up (docs/guarantees.md has the
//! measurements).

use crate::reference::Reference;
use dispmap::error::{Error, Result};
use dispmap::heightfield::ImageHeader;

/// Bytes of the process before any map or frame (Vulkan instance and device, lavapipe,
/// the binary): measured 90-100 MiB with a 2048x2048 map and a 64x64 frame, rounded up.
const BASE_BYTES: u64 = 128 << 20;
/// Bytes per texel of the GPU's copy of the map, per byte of a texel, plus one (the
/// height image, its staging buffer and the pyramids): measured 1.9 (8-bit) and 4.0
/// (16-bit) on 8192x8192 maps.
const GPU_BYTES_PER_TEXEL_BYTE: u64 = 2;
/// Bytes per frame pixel of the GPU's buffers and the colour read-back of any render:
/// measured 62-65.
const FRAME_BYTES_PER_PIXEL: u64 = 72;
/// Bytes per frame pixel `--heatmap` adds (hits and rays read back, the image): measured
/// 69.
const HEATMAP_BYTES_PER_PIXEL: u64 = 72;
/// Bytes per frame pixel `--depth-out` adds (the depth read back, the RGB f32 image):
/// measured 21.
const DEPTH_BYTES_PER_PIXEL: u64 = 32;
/// Bytes per frame pixel the reference adds (`--metrics`): its rays, hits, shaded colour
/// and the compared values: measured 105.
const REFERENCE_BYTES_PER_PIXEL: u64 = 120;

/// What a run keeps per pixel beyond the frame itself.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Extras {
    /// The exact reference (`--metrics`, the demo).
    pub reference: bool,
    /// `--heatmap` (or `--interval-map`: the same read-backs at most).
    pub heatmap: bool,
    /// `--depth-out`.
    pub depth: bool,
}

/// A run's estimated peak memory, with its parts for the message.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The estimated peak in bytes.
    pub bytes: u64,
    /// What it is made of (name, bytes), for messages.
    pub parts: Vec<(&'static str, u64)>,
}

/// The map facts the estimate needs: from a file's header ([`dispmap::HeightField::probe`])
/// or a loaded map (no load peak then).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapSize {
    /// Texels per row and column.
    pub size: [u32; 2],
    /// Bytes per texel of the height field (1, 2 or 4).
    pub texel_bytes: u32,
    /// Bytes held while loading beyond the height field (file + decoded image); 0 for a
    /// map already loaded.
    pub load_bytes: u64,
}

impl MapSize {
    /// From a file's header: the load holds the file and the decoded image.
    pub fn from_header(h: &ImageHeader) -> Self {
        MapSize {
            size: [h.width, h.height],
            texel_bytes: h.texel_bytes,
            load_bytes: h.file_bytes
                + u64::from(h.width) * u64::from(h.height) * u64::from(h.decoded_bytes_per_pixel),
        }
    }

    /// A map already in memory.
    pub fn loaded(field: &dispmap::HeightField) -> Self {
        MapSize {
            size: [field.width(), field.height()],
            texel_bytes: match field.format() {
                ash::vk::Format::R8_UNORM => 1,
                ash::vk::Format::R16_UNORM => 2,
                _ => 4,
            },
            load_bytes: 0,
        }
    }
}

/// The estimate of rendering `frame` pixels on `map` with `extras`.
pub fn estimate(map: MapSize, frame: [u32; 2], extras: Extras) -> Estimate {
    let texels = u64::from(map.size[0]) * u64::from(map.size[1]);
    let pixels = u64::from(frame[0]) * u64::from(frame[1]);
    let field = texels * u64::from(map.texel_bytes);
    let gpu = texels * (GPU_BYTES_PER_TEXEL_BYTE * u64::from(map.texel_bytes) + 1);
    let per_pixel = FRAME_BYTES_PER_PIXEL
        + if extras.heatmap {
            HEATMAP_BYTES_PER_PIXEL
        } else {
            0
        }
        + if extras.depth {
            DEPTH_BYTES_PER_PIXEL
        } else {
            0
        };
    let frame_bytes = pixels * per_pixel;
    let (ref_map, ref_frame) = if extras.reference {
        (
            Reference::memory_bytes(map.size[0], map.size[1]),
            pixels * REFERENCE_BYTES_PER_PIXEL,
        )
    } else {
        (0, 0)
    };
    let load_peak = map.load_bytes + field;
    let render_peak = field + gpu + frame_bytes + ref_map + ref_frame;
    let mut parts = vec![("process", BASE_BYTES)];
    if load_peak > render_peak {
        parts.push(("map file and decoding", map.load_bytes));
        parts.push(("height field", field));
    } else {
        parts.push(("height field", field));
        parts.push(("GPU copy of the map", gpu));
        parts.push(("frame", frame_bytes));
        if extras.reference {
            parts.push(("reference texels and pyramid", ref_map));
            parts.push(("reference rays and hits", ref_frame));
        }
    }
    Estimate {
        bytes: BASE_BYTES + load_peak.max(render_peak),
        parts,
    }
}

/// Bytes as GiB or MiB with one decimal.
pub fn human(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", bytes as f64 / f64::from(1u32 << 30))
    } else {
        format!("{:.1} MiB", bytes as f64 / f64::from(1u32 << 20))
    }
}

/// The memory this process may still take: `MemAvailable` of /proc/meminfo, lowered to
/// the cgroup's limit less its usage where one is set (cgroup v2); `None` where neither
/// can be read.
pub fn available() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find_map(|l| l.strip_prefix("MemAvailable:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
                .map(|kib| kib * 1024)
        });
    let read = |name: &str| {
        std::fs::read_to_string(format!("/sys/fs/cgroup/{name}"))
            .ok()
            .and_then(|t| t.trim().parse::<u64>().ok())
    };
    let cgroup = match (read("memory.max"), read("memory.current")) {
        (Some(max), Some(current)) => Some(max.saturating_sub(current)),
        _ => None,
    };
    match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Parses a memory size: bytes, or a number with `K`, `M`, `G` or `T` (powers of 1024;
/// an optional `iB`/`B` after it), e.g. `8G`, `512MiB`, `1.5G`.
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let lower = t.to_ascii_lowercase();
    let number = lower.trim_end_matches("ib").trim_end_matches('b');
    let (digits, shift) = match number.chars().last() {
        Some('k') => (&number[..number.len() - 1], 10),
        Some('m') => (&number[..number.len() - 1], 20),
        Some('g') => (&number[..number.len() - 1], 30),
        Some('t') => (&number[..number.len() - 1], 40),
        _ => (number, 0),
    };
    let value: f64 = digits
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a memory size (e.g. 8G, 512M, 1073741824)"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !bytes.is_finite() || bytes < 1.0 || bytes > u64::MAX as f64 {
        return Err(format!("'{s}' is not a positive memory size"));
    }
    Ok(bytes as u64)
}

/// Refuses `estimate` when it is above `max` (from `option`, e.g. `--max-memory`) or,
/// without one, above the memory available; the message gives the estimate, its parts
/// and the limit. `what` names the run (the map and frame).
pub fn check(estimate: &Estimate, max: Option<u64>, what: &str) -> Result<()> {
    let (limit, source) = match max {
        Some(m) => (m, "--max-memory".to_owned()),
        None => match available() {
            Some(a) => (
                a,
                "available memory (MemAvailable, cgroup limit)".to_owned(),
            ),
            None => return Ok(()),
        },
    };
    if estimate.bytes <= limit {
        return Ok(());
    }
    let parts: Vec<String> = estimate
        .parts
        .iter()
        .map(|(name, b)| format!("{name} {}", human(*b)))
        .collect();
    Err(Error::invalid(
        "memory",
        format!(
            "{what} needs about {} ({}), more than the {} of {source}; use a smaller map \
             or frame{}",
            human(estimate.bytes),
            parts.join(", "),
            human(limit),
            if max.is_some() {
                " or raise --max-memory"
            } else {
                " or pass --max-memory to override"
            }
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_bytes("8G"), Ok(8 << 30));
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5g"), Ok(3 << 29));
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert!(parse_bytes("-1G").is_err());
        assert!(parse_bytes("lots").is_err());
        assert!(parse_bytes("0").is_err());
    }

    #[test]
    fn estimate_grows_with_map_frame_and_reference_and_is_refused_above_the_limit() {
        let map = MapSize {
            size: [16384, 16384],
            texel_bytes: 1,
            load_bytes: 0,
        };
        let plain = Extras::default();
        let with_reference = Extras {
            reference: true,
            ..plain
        };
        let small = estimate(map, [256, 144], plain);
        let metrics = estimate(map, [256, 144], with_reference);
        let frame = estimate(map, [16384, 16384], plain);
        assert!(small.bytes < metrics.bytes && small.bytes < frame.bytes);
        // The reference's texels and pyramid in f32: 4 (1 + 4/3) bytes per texel.
        let r = Reference::memory_bytes(16384, 16384);
        assert!(r > 9 * (16384 * 16384) && r < 10 * (16384 * 16384), "{r}");
        let err = check(&frame, Some(1 << 30), "the 16384x16384 frame")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("16384x16384") && err.contains("GiB") && err.contains("--max-memory"),
            "{err}"
        );
        assert!(check(&small, Some(u64::MAX), "x").is_ok());
    }
}
