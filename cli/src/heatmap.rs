//! Diagnostic images and counts of where a method spends its work: the per-pixel
//! iteration heat map (like Fig. 9 of Judnich & Ling's DIG paper) and the DIG interval
//! map (like their Fig. 5), both as RGBA8 buffers for [`output::write_png`], plus the
//! iteration statistics of the metrics JSON. Everything here is pure CPU code over
//! read-back buffers, so it is testable without a GPU.
//!
//! # Iteration heat map ([`iteration_heatmap`])
//!
//! Each covered pixel's iteration count (the hit buffer's `w`: height-field or pyramid
//! fetches of the trace pass, without the DIG corner pass) divided by a scale is mapped
//! through [`ramp`], a viridis-like perceptual ramp (dark purple = few, yellow = many;
//! luminance increases monotonically). The scale is by default the largest count over
//! the frame's covered pixels (so every frame uses the full ramp and frames are not
//! comparable by colour); a fixed scale can be given instead (counts above it saturate).
//! Pixels without geometry are black ([`NO_GEOMETRY_RGB`]); covered pixels with a
//! non-finite count (always a bug) are white ([`NONFINITE_RGB`]).
//!
//! # DIG interval map ([`block_intervals`], [`interval_map`])
//!
//! Block `(i, j)` of the corner grid uses corners `(i, j)`, `(i + 1, j)`, `(i, j + 1)`
//! and `(i + 1, j + 1)`; its interval is `[min(h) - eps, max(h) + eps]` clamped to
//! `[0, 1]` (as `glsl/common/dig.glsl` computes it). A block whose four corners are not
//! all on the same surface (surface id nonzero and equal) has no interval: the trace
//! falls back to the unconstrained search there. The map is grey per block,
//! `255 (1 - length)` (darker = longer interval: black is the whole depth, white an
//! empty interval), and [`FALLBACK_RGB`] (red) for blocks without an interval. It is
//! upscaled to the frame size with nearest neighbour (pixel `(x, y)` shows block
//! `(x / bx, y / by)`), so it overlays the rendered frame.
//!
//! [`output::write_png`]: crate::output::write_png

use crate::metrics::HitTexel;
use crate::reference::Ray;
use dispmap::error::{Error, Result};
use dispmap::passes::dig::Corner;

/// The ramp's control points: viridis (matplotlib) sampled at `k / 8`; [`ramp`]
/// interpolates linearly between them.
pub const RAMP: [[u8; 3]; 9] = [
    [68, 1, 84],
    [72, 40, 120],
    [62, 73, 137],
    [49, 104, 142],
    [38, 130, 142],
    [31, 158, 137],
    [53, 183, 121],
    [110, 206, 88],
    [253, 231, 37],
];

/// Colour of pixels without geometry in the heat map.
pub const NO_GEOMETRY_RGB: [u8; 3] = [0, 0, 0];

/// Colour of covered pixels whose iteration count is NaN or infinite in the heat map.
pub const NONFINITE_RGB: [u8; 3] = [255, 255, 255];

/// Colour of blocks without a DIG interval (the corners are not all on one surface).
pub const FALLBACK_RGB: [u8; 3] = [255, 0, 0];

/// The ramp colour of `t` in `[0, 1]` (clamped; NaN is 0): linear interpolation between
/// the [`RAMP`] control points.
pub fn ramp(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (RAMP.len() - 1) as f32;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f32;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    std::array::from_fn(|c| {
        let v = f32::from(a[c]) + (f32::from(b[c]) - f32::from(a[c])) * f;
        v.round().clamp(0.0, 255.0) as u8
    })
}

/// Which pixels have geometry. With `rays` (from the G-buffer), the pixels that have a
/// ray; without, the pixels whose hit texel is not the trace pass's "no geometry" value
/// (a height `< 0` with 0 iterations; a covered miss has spent at least one iteration).
pub fn coverage(hits: &[HitTexel], rays: Option<&[Option<Ray>]>) -> Vec<bool> {
    match rays {
        Some(rays) => rays.iter().map(Option::is_some).collect(),
        None => hits.iter().map(|t| !(t[2] < 0.0 && t[3] == 0.0)).collect(),
    }
}

/// Per-pixel iteration counts over the covered pixels with a finite count.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct IterationStats {
    /// Pixels counted.
    pub pixels: u64,
    /// Mean count.
    pub mean: f64,
    /// 99th percentile (nearest rank: the `ceil(0.99 n)`-th smallest), as in
    /// [`metrics`](crate::metrics).
    pub p99: f64,
    /// Largest count.
    pub max: f64,
    /// Sum of the counts.
    pub total: f64,
}

/// The iteration statistics of `hits` over the pixels where `covered` is true (all zero
/// when there are none). Non-finite counts are skipped.
pub fn iteration_stats(hits: &[HitTexel], covered: &[bool]) -> IterationStats {
    let mut values: Vec<f64> = hits
        .iter()
        .zip(covered)
        .filter(|(t, c)| **c && t[3].is_finite())
        .map(|(t, _)| f64::from(t[3]))
        .collect();
    if values.is_empty() {
        return IterationStats::default();
    }
    let total: f64 = values.iter().sum();
    let (mean, p99, max) = crate::metrics::summary(&mut values);
    IterationStats {
        pixels: values.len() as u64,
        mean,
        p99,
        max,
        total,
    }
}

/// The heat map of `hits` as RGBA8 (one pixel per hit texel, same order): covered
/// pixels get `ramp(iterations / scale)`, others [`NO_GEOMETRY_RGB`] (module docs).
/// `scale` is the count at the top of the ramp; `None` uses the largest finite count
/// over the covered pixels. A scale of 0 (nothing covered, or no iterations anywhere)
/// maps every covered pixel to the ramp's start. Errors if `scale` is given and not
/// positive and finite, or if the slices differ in length.
pub fn iteration_heatmap(
    hits: &[HitTexel],
    covered: &[bool],
    scale: Option<f32>,
) -> Result<Vec<u8>> {
    if hits.len() != covered.len() {
        return Err(Error::invalid(
            "heat map",
            format!(
                "{} hit texels but {} coverage flags",
                hits.len(),
                covered.len()
            ),
        ));
    }
    let scale = match scale {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return Err(Error::invalid(
                "heatmap-max",
                format!("{s} is not a positive finite number"),
            ));
        }
        None => iteration_stats(hits, covered).max as f32,
    };
    let mut rgba = Vec::with_capacity(hits.len() * 4);
    for (t, &c) in hits.iter().zip(covered) {
        let rgb = if !c {
            NO_GEOMETRY_RGB
        } else if !t[3].is_finite() {
            NONFINITE_RGB
        } else if scale > 0.0 {
            ramp(t[3] / scale)
        } else {
            ramp(0.0)
        };
        rgba.extend_from_slice(&[rgb[0], rgb[1], rgb[2], 255]);
    }
    Ok(rgba)
}

/// One block's DIG interval of ray heights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockInterval {
    /// Lower end, `min(corner heights) - eps` clamped to `[0, 1]`.
    pub bottom: f32,
    /// Upper end, `max(corner heights) + eps` clamped to `[0, 1]`.
    pub top: f32,
}

impl BlockInterval {
    /// `top - bottom` (in `[0, 1]`).
    pub fn length(&self) -> f32 {
        (self.top - self.bottom).max(0.0)
    }
}

/// Blocks per axis of a corner grid of `grid` corners (one fewer per axis).
pub fn block_count(grid: [u32; 2]) -> [u32; 2] {
    [grid[0].saturating_sub(1), grid[1].saturating_sub(1)]
}

/// The interval of every block of a corner grid (`grid` corners per axis, `corners` row
/// by row), blocks row by row; `None` for a block whose four corners are not all on one
/// nonzero surface (module docs). Errors if the grid has fewer than 2 corners on a side
/// or `corners` does not hold `grid[0] * grid[1]` corners.
pub fn block_intervals(
    grid: [u32; 2],
    corners: &[Corner],
    eps: f32,
) -> Result<Vec<Option<BlockInterval>>> {
    let [cw, ch] = grid.map(|n| n as usize);
    if cw < 2 || ch < 2 || corners.len() != cw * ch {
        return Err(Error::invalid(
            "corner grid",
            format!(
                "{} corners for a {}x{} grid (at least 2x2 needed)",
                corners.len(),
                grid[0],
                grid[1]
            ),
        ));
    }
    let mut out = Vec::with_capacity((cw - 1) * (ch - 1));
    for j in 0..ch - 1 {
        for i in 0..cw - 1 {
            let quad = [
                corners[j * cw + i],
                corners[j * cw + i + 1],
                corners[(j + 1) * cw + i],
                corners[(j + 1) * cw + i + 1],
            ];
            let surface = quad[0].surface;
            // NaN ids are never on a surface.
            let one_surface = surface > 0.0 && quad.iter().all(|c| c.surface == surface);
            if !one_surface {
                out.push(None);
                continue;
            }
            let lo = quad.iter().fold(1.0f32, |m, c| m.min(c.height));
            let hi = quad.iter().fold(0.0f32, |m, c| m.max(c.height));
            out.push(Some(BlockInterval {
                bottom: (lo - eps).clamp(0.0, 1.0),
                top: (hi + eps).clamp(0.0, 1.0),
            }));
        }
    }
    Ok(out)
}

/// The grey of an interval length: `255 (1 - length)`, darker = longer.
pub fn interval_grey(length: f32) -> u8 {
    (255.0 * (1.0 - length.clamp(0.0, 1.0))).round() as u8
}

/// The interval map as RGBA8 at the frame size: pixel `(x, y)` shows block
/// `(x / block[0], y / block[1])` of `intervals` (`blocks` per axis, row by row) as
/// [`interval_grey`] or [`FALLBACK_RGB`]. Errors if the blocks do not cover the frame.
pub fn interval_map(
    intervals: &[Option<BlockInterval>],
    blocks: [u32; 2],
    block: [u32; 2],
    frame: [u32; 2],
) -> Result<Vec<u8>> {
    let [bw, bh] = blocks.map(|n| n as usize);
    let [bx, by] = block.map(|n| n.max(1) as usize);
    let [w, h] = frame.map(|n| n as usize);
    if intervals.len() != bw * bh || w.div_ceil(bx) > bw || h.div_ceil(by) > bh {
        return Err(Error::invalid(
            "interval map",
            format!(
                "{} intervals in {}x{} blocks of {}x{} do not cover a {}x{} frame",
                intervals.len(),
                blocks[0],
                blocks[1],
                block[0],
                block[1],
                frame[0],
                frame[1]
            ),
        ));
    }
    let mut rgba = Vec::with_capacity(w * h * 4);
    for y in 0..h {
        for x in 0..w {
            let rgb = match intervals[(y / by) * bw + x / bx] {
                Some(i) => [interval_grey(i.length()); 3],
                None => FALLBACK_RGB,
            };
            rgba.extend_from_slice(&[rgb[0], rgb[1], rgb[2], 255]);
        }
    }
    Ok(rgba)
}

/// The DIG corner pass's work.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CornerStats {
    /// Corners in the grid (with or without geometry).
    pub corners: u64,
    /// Sum of the corners' iteration counts (non-finite ones skipped).
    pub total: f64,
    /// `total / corners` (0 for an empty grid).
    pub mean: f64,
}

/// The iteration counts of a corner grid.
pub fn corner_stats(corners: &[Corner]) -> CornerStats {
    let total: f64 = corners
        .iter()
        .filter(|c| c.iterations.is_finite())
        .map(|c| f64::from(c.iterations))
        .sum();
    let n = corners.len() as u64;
    CornerStats {
        corners: n,
        total,
        mean: if n == 0 { 0.0 } else { total / n as f64 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn luminance(c: [u8; 3]) -> f32 {
        0.2126 * f32::from(c[0]) + 0.7152 * f32::from(c[1]) + 0.0722 * f32::from(c[2])
    }

    #[test]
    fn ramp_ends_and_monotone_luminance() {
        assert_eq!(ramp(0.0), RAMP[0]);
        assert_eq!(ramp(1.0), RAMP[RAMP.len() - 1]);
        assert_eq!(ramp(-3.0), RAMP[0]);
        assert_eq!(ramp(7.0), RAMP[RAMP.len() - 1]);
        assert_eq!(ramp(f32::NAN), RAMP[0]);
        assert_eq!(ramp(0.5), RAMP[4]);
        assert_ne!(ramp(0.0), NO_GEOMETRY_RGB);
        // Between control points luminance may dip by less than one 8-bit step of
        // rounding; the control points themselves strictly increase.
        let mut last = -1.0;
        for k in 0..=256 {
            let l = luminance(ramp(k as f32 / 256.0));
            assert!(l >= last - 1.0, "luminance falls at {k}/256: {l} < {last}");
            last = l;
        }
        assert!(luminance(ramp(1.0)) > luminance(ramp(0.0)) + 150.0);
        for pair in RAMP.windows(2) {
            assert!(luminance(pair[1]) > luminance(pair[0]), "{pair:?}");
        }
    }

    #[test]
    fn heatmap_scales_to_the_frame_max_and_blacks_out_empty_pixels() {
        let miss = [0.0, 0.0, dispmap::abi::NO_HIT_HEIGHT, 0.0];
        let hits = [
            [0.1, 0.2, 0.5, 4.0],
            [0.1, 0.2, 0.5, 8.0],
            miss,
            [0.0, 0.0, -1.0, 3.0],
            [0.0, 0.0, 0.5, f32::NAN],
        ];
        let covered = coverage(&hits, None);
        assert_eq!(covered, [true, true, false, true, true]);
        let rgba = iteration_heatmap(&hits, &covered, None).unwrap();
        let px = |i: usize| [rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2]];
        assert_eq!(rgba.len(), 4 * hits.len());
        assert_eq!(px(0), ramp(0.5));
        assert_eq!(px(1), ramp(1.0));
        assert_eq!(px(2), NO_GEOMETRY_RGB);
        assert_eq!(px(3), ramp(3.0 / 8.0));
        assert_eq!(px(4), NONFINITE_RGB);
        assert!(rgba.chunks(4).all(|p| p[3] == 255));
        // A fixed scale saturates; rays decide coverage when given.
        let ray = Ray {
            uv0: [0.5, 0.5],
            parallax: [0.1, 0.0],
        };
        let rays = [None, Some(ray), None, None, None];
        let covered = coverage(&hits, Some(&rays));
        let fixed = iteration_heatmap(&hits, &covered, Some(4.0)).unwrap();
        assert_eq!(&fixed[..3], &NO_GEOMETRY_RGB);
        assert_eq!(&fixed[4..7], &ramp(1.0));
        assert!(iteration_heatmap(&hits, &covered, Some(0.0)).is_err());
        assert!(iteration_heatmap(&hits, &covered[..2], None).is_err());
        // Nothing covered: all black, no division by zero.
        let none = iteration_heatmap(&hits, &[false; 5], None).unwrap();
        assert!(none.chunks(4).all(|p| p[..3] == NO_GEOMETRY_RGB));
    }

    #[test]
    fn iteration_stats_over_covered_pixels() {
        let hits: Vec<HitTexel> = (1..=100).map(|k| [0.0, 0.0, 0.5, k as f32]).collect();
        let mut covered = vec![true; 100];
        covered[99] = false;
        let s = iteration_stats(&hits, &covered);
        assert_eq!(s.pixels, 99);
        assert_eq!(s.max, 99.0);
        assert_eq!(s.total, (1..=99).sum::<u32>() as f64);
        assert!((s.mean - 50.0).abs() < 1e-12);
        assert_eq!(s.p99, 99.0);
        assert_eq!(
            iteration_stats(&hits, &[false; 100]),
            IterationStats::default()
        );
    }

    fn corner(height: f32, surface: f32, iterations: f32) -> Corner {
        Corner {
            height,
            surface,
            iterations,
        }
    }

    #[test]
    fn intervals_from_corners() {
        // 3x2 corners: 2x1 blocks. Block 0 all on surface 1, block 1 touches surface 2.
        let corners = [
            corner(0.8, 1.0, 5.0),
            corner(0.6, 1.0, 7.0),
            corner(0.3, 2.0, 9.0),
            corner(0.7, 1.0, 6.0),
            corner(0.9, 1.0, 4.0),
            corner(0.5, 1.0, 8.0),
        ];
        let eps = 0.05;
        let iv = block_intervals([3, 2], &corners, eps).unwrap();
        assert_eq!(iv.len(), 2);
        let b = iv[0].unwrap();
        assert!((b.bottom - 0.55).abs() < 1e-6, "{b:?}");
        assert!((b.top - 0.95).abs() < 1e-6, "{b:?}");
        assert!((b.length() - 0.4).abs() < 1e-6);
        assert_eq!(iv[1], None);
        // Clamping to [0, 1].
        let flat = [corner(1.0, 3.0, 1.0), corner(0.02, 3.0, 1.0)];
        let flat = [flat[0], flat[1], flat[0], flat[1]];
        let b = block_intervals([2, 2], &flat, 0.1).unwrap()[0].unwrap();
        assert_eq!((b.bottom, b.top), (0.0, 1.0));
        assert_eq!(b.length(), 1.0);
        // No geometry (surface 0) has no interval even if all four agree.
        let sky = [corner(1.0, 0.0, 0.0); 4];
        assert_eq!(block_intervals([2, 2], &sky, 0.1).unwrap(), [None]);
        // Bad grids.
        assert!(block_intervals([1, 2], &corners[..2], eps).is_err());
        assert!(block_intervals([3, 3], &corners, eps).is_err());

        let stats = corner_stats(&corners);
        assert_eq!(stats.corners, 6);
        assert_eq!(stats.total, 39.0);
        assert_eq!(stats.mean, 6.5);
        assert_eq!(corner_stats(&[]), CornerStats::default());
    }

    #[test]
    fn interval_map_is_upscaled_with_nearest_neighbour() {
        let long = BlockInterval {
            bottom: 0.0,
            top: 1.0,
        };
        let short = BlockInterval {
            bottom: 0.5,
            top: 0.75,
        };
        assert_eq!(interval_grey(1.0), 0);
        assert_eq!(interval_grey(0.0), 255);
        assert!(interval_grey(short.length()) > interval_grey(long.length()));
        // 2x1 blocks of 4x4 over a 6x3 frame (partial blocks at the edges).
        let iv = [Some(short), None];
        let rgba = interval_map(&iv, [2, 1], [4, 4], [6, 3]).unwrap();
        assert_eq!(rgba.len(), 6 * 3 * 4);
        let px = |x: usize, y: usize| {
            let i = 4 * (y * 6 + x);
            [rgba[i], rgba[i + 1], rgba[i + 2]]
        };
        let grey = interval_grey(0.25);
        assert_eq!(grey, 191);
        for y in 0..3 {
            for x in 0..4 {
                assert_eq!(px(x, y), [grey; 3]);
            }
            for x in 4..6 {
                assert_eq!(px(x, y), FALLBACK_RGB);
            }
        }
        assert!(interval_map(&iv, [2, 1], [4, 4], [9, 3]).is_err());
        assert!(interval_map(&iv[..1], [2, 1], [4, 4], [6, 3]).is_err());
        // The grid of the corner pass covers any frame.
        let frame = [67, 45];
        let grid = dispmap::passes::dig::corner_size(frame, [4, 4]);
        let blocks = block_count(grid);
        let all = vec![Some(long); (blocks[0] * blocks[1]) as usize];
        assert!(interval_map(&all, blocks, [4, 4], frame).is_ok());
    }
}
