//! The metrics JSON of `render --metrics`: the error summary (null when no pixel was
//! compared), the coverage, and the iteration counts.

use dispmap_cli::heatmap::{CornerStats, IterationStats};
use dispmap_cli::metrics::ErrorMetrics;
use serde::Serialize;
use std::collections::BTreeMap;

/// The warning of a measured frame with no compared pixel.
pub(crate) const NO_PIXELS: &str = "no pixel of the frame shows the displaced surface (0 compared \
                         pixels): the error metrics are null, not a perfect score";

/// The metrics JSON of `render --metrics`.
#[derive(Serialize)]
pub(crate) struct MetricsReport<'a> {
    pub(crate) method: &'a str,
    pub(crate) steps: u32,
    pub(crate) refine_steps: u32,
    /// `--lod-threshold` when level of detail is on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) lod_threshold: Option<f32>,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) frames: u32,
    pub(crate) heightmap: String,
    pub(crate) depth_scale: f32,
    pub(crate) camera_elevation: f32,
    pub(crate) shadows: &'a str,
    pub(crate) device: &'a str,
    pub(crate) driver: &'a str,
    pub(crate) timings_ms: BTreeMap<String, f64>,
    pub(crate) error: ErrorSummary,
    /// Set when the metrics mean nothing (no pixel compared).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) warning: Option<String>,
    pub(crate) nonfinite_pixels: u64,
    /// The reference traces each pixel's own centre ray on the tiled plane and the quad:
    /// pixels where the G-buffer's coverage and the f64 centre ray disagree
    /// (`Renderer::reference_rays`).
    pub(crate) coverage: CoverageReport,
    pub(crate) iterations: Iterations,
    /// DIG methods only: the corner pass's iterations.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) corner_pass: Option<CornerPass>,
    /// Meshes only: hit or miss near the outlines against the tessellated reference
    /// (`dispmap_cli::silhouette`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) silhouette: Option<SilhouetteReport>,
}

/// How the frame's hit-or-miss agrees with the tessellated mesh's within
/// `dispmap_cli::silhouette::OUTLINE_BAND` pixels of an outline.
#[derive(Serialize)]
pub(crate) struct SilhouetteReport {
    /// Pixels in the band.
    pub(crate) band_pixels: usize,
    /// Of those, the pixels where the frame hits exactly where the reference does.
    pub(crate) agreeing_pixels: usize,
    /// `agreeing_pixels / band_pixels` (1 for an empty band).
    pub(crate) agreement: f64,
}

impl From<dispmap_cli::silhouette::OutlineAgreement> for SilhouetteReport {
    fn from(a: dispmap_cli::silhouette::OutlineAgreement) -> Self {
        SilhouetteReport {
            band_pixels: a.band,
            agreeing_pixels: a.agreeing,
            agreement: a.share(),
        }
    }
}

/// Where the G-buffer's coverage and the reference's f64 centre rays disagree.
#[derive(Serialize)]
pub(crate) struct CoverageReport {
    /// Whether the reference traced the f64 centre rays (the tiled plane or the quad
    /// alone) rather than the G-buffer's rays.
    pub(crate) centre_rays: bool,
    /// Pixels drawn whose f64 centre ray misses the surface: not compared.
    pub(crate) drawn_without_ray: usize,
    /// Pixels with an f64 centre ray that the G-buffer left empty: compared (a method
    /// has no ray there: an artifact where the reference hits).
    pub(crate) ray_without_draw: usize,
}

/// The error against the reference; every measure `null` when no pixel was compared
/// (the frame shows no geometry: nothing was measured, which is not a perfect score).
#[derive(Serialize)]
pub(crate) struct ErrorSummary {
    pub(crate) mean_texels: Option<f64>,
    p99_texels: Option<f64>,
    pub(crate) max_texels: Option<f64>,
    pub(crate) artifact_fraction: Option<f64>,
    pub(crate) psnr_db: Option<f64>,
    pub(crate) compared_pixels: u64,
}

/// The trace pass's per-pixel iteration counts over covered pixels (see
/// `dispmap_cli::heatmap::iteration_stats`).
#[derive(Serialize)]
pub(crate) struct Iterations {
    pub(crate) mean: f64,
    p99: f64,
    pub(crate) max: f64,
    /// Sum over covered pixels.
    pub(crate) total: f64,
}

impl From<IterationStats> for Iterations {
    fn from(s: IterationStats) -> Self {
        Iterations {
            mean: s.mean,
            p99: s.p99,
            max: s.max,
            total: s.total,
        }
    }
}

/// The DIG corner pass: `corners` in the grid, the `total` and `mean` of their iteration
/// counts, and `total_with_corners` = the trace pass's per-pixel total + `total`.
#[derive(Serialize)]
pub(crate) struct CornerPass {
    pub(crate) corners: u64,
    pub(crate) total: f64,
    pub(crate) mean: f64,
    pub(crate) total_with_corners: f64,
}

impl CornerPass {
    pub(crate) fn new(corners: CornerStats, trace: &IterationStats) -> Self {
        CornerPass {
            corners: corners.corners,
            total: corners.total,
            mean: corners.mean,
            total_with_corners: trace.total + corners.total,
        }
    }
}

impl From<&ErrorMetrics> for ErrorSummary {
    fn from(e: &ErrorMetrics) -> Self {
        let some = |v: f64| (e.compared_pixels > 0).then_some(v);
        ErrorSummary {
            mean_texels: some(e.mean_texels),
            p99_texels: some(e.p99_texels),
            max_texels: some(e.max_texels),
            artifact_fraction: some(e.artifact_fraction),
            psnr_db: some(e.psnr_db),
            compared_pixels: e.compared_pixels,
        }
    }
}
