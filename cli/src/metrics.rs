//! Error measures of a method's hit buffer against the [reference](crate::reference).
//!
//! # Definitions
//!
//! * **Hit distance** (texels): the GPU hit and the reference hit are compared as 3-D
//!   points in texel units,
//!   `sqrt((du W)² + (dv H)² + (dh depth_scale sqrt(W H))²)`, with `du, dv` the UV
//!   differences (not wrapped: both sides report `uv0 + t P`), `dh` the height difference
//!   and `W x H` the map size. The depth axis is scaled so that a full depth of
//!   `depth_scale` tiles has the same texel units as the surface (`sqrt(W H)` texels per
//!   tile for non-square maps).
//! * **Compared pixels**: pixels with a ray (`Some`, i.e. covered by geometry).
//! * **Artifact**: a compared pixel whose GPU texel has a non-finite component, or where
//!   exactly one of GPU and reference reports a hit (a GPU miss is a height `< 0`), or
//!   whose hit distance exceeds [`ARTIFACT_TEXELS`] (one texel): a missed first
//!   intersection or a wrong layer. `artifact_fraction = artifacts / compared` (0 when
//!   nothing is compared).
//! * **mean / p99 / max texels**: over compared pixels where both sides hit and the GPU
//!   texel is finite. p99 is the nearest-rank percentile (the `ceil(0.99 n)`-th smallest).
//!   All three are 0 when there is no such pixel.
//! * **nonfinite_pixels**: every pixel of the hit buffer with a NaN or infinite component,
//!   covered or not (must be 0).
//! * **mean / p99 iterations**: the hit buffer's iteration count (`w`) over compared
//!   pixels where it is finite.
//! * **PSNR** ([`psnr_rgba8`]): over R, G, B of two RGBA8 images (alpha ignored),
//!   `10 log10(255² / MSE)`, capped at [`PSNR_CAP_DB`] = 100 dB, which is also the value
//!   for identical (or empty) images.

use crate::reference::{Hit, Ray};

pub use dispmap::passes::trace::HitTexel;

/// A hit farther than this (in texels) from the reference is an artifact.
pub const ARTIFACT_TEXELS: f64 = 1.0;

/// The PSNR of identical images, and the upper bound of every PSNR.
pub const PSNR_CAP_DB: f64 = 100.0;

/// Percentile used for `p99_texels` and `p99_iterations`.
const P99: f64 = 0.99;

/// Geometry of the frame needed to convert hit differences to texels.
#[derive(Clone, Copy, Debug)]
pub struct MapGeometry {
    /// Height-map width `W` in texels.
    pub map_width: u32,
    /// Height-map height `H` in texels.
    pub map_height: u32,
    /// Displacement depth in tile (UV) units.
    pub depth_scale: f64,
}

/// Error of one frame's hit buffer against the reference (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorMetrics {
    /// Mean hit distance in texels.
    pub mean_texels: f64,
    /// 99th percentile (nearest rank) of the hit distance in texels.
    pub p99_texels: f64,
    /// Largest hit distance in texels.
    pub max_texels: f64,
    /// Fraction of compared pixels that are artifacts.
    pub artifact_fraction: f64,
    /// PSNR of the shaded image against the shaded reference, in dB; filled by the
    /// caller from [`psnr_rgba8`], 0 until then.
    pub psnr_db: f64,
    /// Covered pixels (rays present).
    pub compared_pixels: u64,
    /// Pixels of the hit buffer with a NaN or infinite component.
    pub nonfinite_pixels: u64,
    /// Mean iteration count over compared pixels.
    pub mean_iterations: f64,
    /// 99th percentile (nearest rank) of the iteration count over compared pixels.
    pub p99_iterations: f64,
}

/// Distance in texels between a GPU hit and the reference hit (module docs).
pub fn hit_distance_texels(gpu: &HitTexel, reference: &Hit, geometry: MapGeometry) -> f64 {
    let w = f64::from(geometry.map_width);
    let h = f64::from(geometry.map_height);
    let du = (f64::from(gpu[0]) - reference.uv[0]) * w;
    let dv = (f64::from(gpu[1]) - reference.uv[1]) * h;
    let dh = (f64::from(gpu[2]) - reference.height) * geometry.depth_scale * (w * h).sqrt();
    (du * du + dv * dv + dh * dh).sqrt()
}

/// Compares a hit buffer with the reference hits of the same rays.
///
/// The three slices are per pixel and should have the same length; extra entries of a
/// longer slice are ignored (except that `nonfinite_pixels` counts all of `gpu`).
pub fn hit_errors(
    gpu: &[HitTexel],
    reference: &[Option<Hit>],
    rays: &[Option<Ray>],
    geometry: MapGeometry,
) -> ErrorMetrics {
    hit_errors_with(gpu, reference, rays, |_| geometry)
}

/// [`hit_errors`] where each pixel (by its index) has its own map geometry: a frame of
/// several materials, each with its own map size and depth scale.
pub fn hit_errors_with(
    gpu: &[HitTexel],
    reference: &[Option<Hit>],
    rays: &[Option<Ray>],
    geometry: impl Fn(usize) -> MapGeometry,
) -> ErrorMetrics {
    debug_assert_eq!(gpu.len(), reference.len(), "hit buffer vs reference");
    debug_assert_eq!(gpu.len(), rays.len(), "hit buffer vs rays");
    let finite = |t: &HitTexel| t.iter().all(|c| c.is_finite());

    let mut compared = 0u64;
    let mut artifacts = 0u64;
    let mut distances = Vec::new();
    let mut iterations = Vec::new();
    for (i, ((texel, reference), ray)) in gpu.iter().zip(reference).zip(rays).enumerate() {
        if ray.is_none() {
            continue;
        }
        compared += 1;
        if texel[3].is_finite() {
            iterations.push(f64::from(texel[3]));
        }
        if !finite(texel) {
            artifacts += 1;
            continue;
        }
        let gpu_hit = texel[2] >= 0.0;
        match (gpu_hit, reference) {
            (true, Some(hit)) => {
                let d = hit_distance_texels(texel, hit, geometry(i));
                if d > ARTIFACT_TEXELS {
                    artifacts += 1;
                }
                distances.push(d);
            }
            (false, None) => {}
            _ => artifacts += 1,
        }
    }

    let (mean_texels, p99_texels, max_texels) = summary(&mut distances);
    let (mean_iterations, p99_iterations, _) = summary(&mut iterations);
    ErrorMetrics {
        mean_texels,
        p99_texels,
        max_texels,
        artifact_fraction: if compared == 0 {
            0.0
        } else {
            artifacts as f64 / compared as f64
        },
        psnr_db: 0.0,
        compared_pixels: compared,
        nonfinite_pixels: gpu.iter().filter(|t| !finite(t)).count() as u64,
        mean_iterations,
        p99_iterations,
    }
}

/// Mean, nearest-rank p99 and maximum of finite values; zeros for an empty slice.
pub(crate) fn summary(values: &mut [f64]) -> (f64, f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    let max = values.iter().copied().fold(f64::MIN, f64::max);
    let rank = ((P99 * n as f64).ceil() as usize).clamp(1, n);
    let (_, p99, _) = values.select_nth_unstable_by(rank - 1, f64::total_cmp);
    (mean, *p99, max)
}

/// PSNR in dB over R, G, B (alpha ignored) of two RGBA8 images of the same size.
///
/// Identical images give [`PSNR_CAP_DB`] (100 dB), which also caps the result. Equal
/// length is the caller's precondition (checked in debug builds); otherwise only the
/// whole pixels of the shorter buffer are compared.
pub fn psnr_rgba8(a: &[u8], b: &[u8]) -> f64 {
    debug_assert_eq!(a.len(), b.len(), "images of different sizes");
    let mut sum = 0u64;
    let mut samples = 0u64;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for c in 0..3 {
            let d = u64::from(pa[c].abs_diff(pb[c]));
            sum += d * d;
        }
        samples += 3;
    }
    if sum == 0 {
        return PSNR_CAP_DB;
    }
    let mse = sum as f64 / samples as f64;
    (10.0 * (255.0 * 255.0 / mse).log10()).min(PSNR_CAP_DB)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GEOMETRY: MapGeometry = MapGeometry {
        map_width: 256,
        map_height: 128,
        depth_scale: 0.1,
    };

    fn ray() -> Option<Ray> {
        Some(Ray {
            uv0: [0.5, 0.5],
            parallax: [0.1, 0.0],
        })
    }

    fn texel(hit: &Hit, iterations: f32) -> HitTexel {
        [
            hit.uv[0] as f32,
            hit.uv[1] as f32,
            hit.height as f32,
            iterations,
        ]
    }

    /// Exactly representable in f32, so texels reproduce the reference exactly.
    fn hit(k: usize) -> Hit {
        Hit {
            uv: [0.25 + k as f64 / 64.0, 0.5],
            height: 0.5,
        }
    }

    #[test]
    fn identical_hits_have_no_error() {
        let reference: Vec<Option<Hit>> = (0..8).map(|k| Some(hit(k))).collect();
        let gpu: Vec<HitTexel> = reference
            .iter()
            .map(|h| h.as_ref().map_or([0.0, 0.0, -1.0, 0.0], |h| texel(h, 10.0)))
            .collect();
        let rays = vec![ray(); 8];
        let m = hit_errors(&gpu, &reference, &rays, GEOMETRY);
        assert_eq!(
            m,
            ErrorMetrics {
                compared_pixels: 8,
                mean_iterations: 10.0,
                p99_iterations: 10.0,
                ..ErrorMetrics::default()
            }
        );
        let image: Vec<u8> = (0..64u8).collect();
        assert_eq!(psnr_rgba8(&image, &image), 100.0);
        assert_eq!(psnr_rgba8(&[], &[]), 100.0);
    }

    #[test]
    fn a_known_shift_gives_the_known_distance() {
        let r = hit(0);
        // 3 texels in u, 4 in v: 5 texels.
        let mut t = texel(&r, 1.0);
        t[0] += 3.0 / 256.0;
        t[1] += 4.0 / 128.0;
        assert!((hit_distance_texels(&t, &r, GEOMETRY) - 5.0).abs() < 1e-9);
        // Depth: dh * 0.1 * sqrt(256 * 128) texels.
        let mut t = texel(&r, 1.0);
        t[2] -= 0.125;
        let expected = 0.125 * 0.1 * (256.0f64 * 128.0).sqrt();
        let m = hit_errors(&[t], &[Some(r)], &[ray()], GEOMETRY);
        assert!((m.mean_texels - expected).abs() < 1e-9, "{m:?}");
        assert_eq!(m.max_texels, m.mean_texels);
        assert_eq!(m.p99_texels, m.mean_texels);
        assert_eq!(m.artifact_fraction, 1.0, "{expected} texels is an artifact");
    }

    #[test]
    fn non_finite_texels_are_counted_and_artifacts() {
        let r = hit(1);
        let mut bad = texel(&r, 3.0);
        bad[0] = f32::NAN;
        let mut uncovered = texel(&r, 3.0);
        uncovered[2] = f32::INFINITY;
        let gpu = [bad, texel(&r, 5.0), uncovered];
        let m = hit_errors(&gpu, &[Some(r); 3], &[ray(), ray(), None], GEOMETRY);
        assert_eq!(m.nonfinite_pixels, 2);
        assert_eq!(m.compared_pixels, 2);
        assert_eq!(m.artifact_fraction, 0.5);
        assert_eq!((m.mean_texels, m.max_texels), (0.0, 0.0));
        assert_eq!(m.mean_iterations, 4.0);
        assert_eq!(m.p99_iterations, 5.0);
    }

    #[test]
    fn hit_miss_mismatches_are_artifacts() {
        let r = hit(2);
        let miss = [0.0, 0.0, -1.0, 7.0];
        let gpu = [miss, texel(&r, 7.0), miss, texel(&r, 7.0)];
        let reference = [Some(r), None, None, Some(r)];
        let m = hit_errors(&gpu, &reference, &[ray(); 4], GEOMETRY);
        assert_eq!(m.compared_pixels, 4);
        assert_eq!(m.artifact_fraction, 0.5);
        assert_eq!(m.nonfinite_pixels, 0);
        assert_eq!(m.max_texels, 0.0);
    }

    #[test]
    fn one_far_pixel_in_four_is_a_quarter() {
        let reference: Vec<Option<Hit>> = (0..4).map(|k| Some(hit(k))).collect();
        let mut gpu: Vec<HitTexel> = reference.iter().flatten().map(|h| texel(h, 1.0)).collect();
        gpu[2][0] += 1.5 / 256.0;
        let m = hit_errors(&gpu, &reference, &[ray(); 4], GEOMETRY);
        assert_eq!(m.artifact_fraction, 0.25);
        assert!((m.max_texels - 1.5).abs() < 1e-6, "{m:?}");
        assert!((m.mean_texels - 1.5 / 4.0).abs() < 1e-6, "{m:?}");
        assert!((m.p99_texels - 1.5).abs() < 1e-6, "{m:?}");
        // Exactly one texel is not an artifact.
        gpu[2][0] = gpu[1][0] + 1.0 / 256.0;
        let shifted = [Some(Hit {
            uv: [gpu[1][0] as f64, 0.5],
            height: 0.5,
        })];
        let m = hit_errors(&gpu[2..3], &shifted, &[ray()], GEOMETRY);
        assert_eq!(m.artifact_fraction, 0.0, "{m:?}");
    }

    #[test]
    fn p99_is_the_nearest_rank() {
        let mut values: Vec<f64> = (1..=200).rev().map(f64::from).collect();
        let (mean, p99, max) = summary(&mut values);
        assert_eq!((mean, p99, max), (100.5, 198.0, 200.0));
        assert_eq!(summary(&mut []), (0.0, 0.0, 0.0));
        assert_eq!(summary(&mut [4.0]), (4.0, 4.0, 4.0));
    }

    #[test]
    fn psnr_of_a_known_mse() {
        // Two pixels; every colour channel differs by 10: MSE = 100. Alpha is ignored.
        let a = [10, 20, 30, 255, 0, 0, 0, 0];
        let b = [20, 10, 40, 0, 10, 10, 10, 99];
        let expected = 10.0 * (255.0f64 * 255.0 / 100.0).log10();
        assert!((psnr_rgba8(&a, &b) - expected).abs() < 1e-12);
        // Channel differences 0, 0, 3 on one pixel: MSE = 9 / 3 = 3.
        let expected = 10.0 * (255.0f64 * 255.0 / 3.0).log10();
        assert!((psnr_rgba8(&[1, 2, 3, 4], &[1, 2, 6, 4]) - expected).abs() < 1e-12);
    }
}
