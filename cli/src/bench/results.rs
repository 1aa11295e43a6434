//! What a run returns ([`BenchResults`]): one row per run, the medians, the heat maps
//! and the maps' facts; the rows as `results.csv` ([`csv_bytes`]).

use super::*;
use dispmap::error::{Error, Result};
use dispmap::method::Method;
use std::time::{Duration, SystemTime};

/// Which part of the benchmark a row belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sweep {
    /// Every method and setting on every map.
    Methods,
    /// One map resampled to several sizes.
    MapSize,
    /// The methods sweep's `relief` and `pom` runs again, forward: the march in the
    /// G-buffer pass (module docs).
    Forward,
}

/// One run: a (map, method, setting, frame set), as one row of `results.csv`. Times are
/// milliseconds; empty optional cells mean "no such pass" (module docs for every value).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunRow {
    /// Which sweep.
    pub sweep: Sweep,
    /// The map's short name.
    pub map: String,
    /// Map width in texels.
    pub map_width: u32,
    /// Map height in texels.
    pub map_height: u32,
    /// The method's CLI name.
    pub method: String,
    /// Linear steps (`iter`); empty for methods without a step count.
    pub steps: Option<u32>,
    /// Frame width in pixels.
    pub frame_width: u32,
    /// Frame height in pixels.
    pub frame_height: u32,
    /// Frames (camera azimuths) per pass.
    pub frames: u32,
    /// Interleaved passes over the frames (`--repeat`).
    pub repeat: u32,
    /// Frames measured against the reference.
    pub error_frames: u32,
    /// The frames (azimuths and error frames) in words.
    pub frame_set: String,
    /// G-buffer pass (every `*_ms` time below is the minimum over the `frames` frames of
    /// the `repeat` passes unless it says median); forward rows: the raster pass with the
    /// march.
    pub gbuffer_ms: f64,
    /// The pyramid's build (once per map and pyramid kind; the fastest of `repeat`
    /// builds by as many renderers), if the method uses one.
    pub pyramid_build_ms: Option<f64>,
    /// Map-size sweep: the same pyramid built on the CPU by one thread
    /// (`dispmap::passes::pyramid::cpu_build`, the minimum of 3 builds), the yardstick
    /// of the GPU build.
    pub cpu_pyramid_build_ms: Option<f64>,
    /// The cone map's build (once per map; the fastest of `repeat` builds), cone
    /// methods only. It follows the pyramid build, which it reads.
    pub cone_build_ms: Option<f64>,
    /// DIG corner pass, DIG methods only.
    pub dig_corners_ms: Option<f64>,
    /// Trace pass (0 in forward rows: none).
    pub trace_ms: f64,
    /// Shade pass.
    pub shade_ms: f64,
    /// Self-shadowing pass (`--shadows` on only).
    pub shadow_ms: Option<f64>,
    /// The method's time, per-frame `dig_corners + trace` (forward rows: the `gbuffer`
    /// pass, which runs the march): the minimum over every frame of every pass, the
    /// statistic the speed-ups and plots use.
    pub method_ms: f64,
    /// Its median over every frame of every pass.
    pub method_median_ms: f64,
    /// The lowest per-pass minimum of the method time.
    pub method_lo_ms: f64,
    /// The highest per-pass minimum of the method time (with `method_lo_ms`: the spread
    /// of `method_ms` over the repeat).
    pub method_hi_ms: f64,
    /// Per-frame total (without the one-off passes), minimum.
    pub total_ms: f64,
    /// Per-frame total, median.
    pub total_median_ms: f64,
    /// The lowest per-pass median of the method time.
    pub method_median_lo_ms: f64,
    /// The highest per-pass median of the method time.
    pub method_median_hi_ms: f64,
    /// The lowest per-pass median of the per-frame total.
    pub total_median_lo_ms: f64,
    /// The highest per-pass median of the per-frame total.
    pub total_median_hi_ms: f64,
    /// Mean per-pixel iterations of the trace pass.
    pub iterations_mean: f64,
    /// p99 per-pixel iterations of the trace pass.
    pub iterations_p99: f64,
    /// Lockstep cost of 8x1 pixel groups (lavapipe's 8-lane SIMD subgroups): the mean
    /// over groups with a covered pixel of the group's largest iteration count
    /// ([`lockstep_iterations`]).
    pub iterations_simd8: f64,
    /// The same for 8x4 groups (a 32-lane GPU warp in an 8x8 workgroup).
    pub iterations_warp32: f64,
    /// The same for 4x2 groups: 8 lanes of two 2x2 quads side by side, how an 8-wide
    /// fragment shader (llvmpipe's on 256-bit vectors) runs, where a compute shader's
    /// 8 lanes are an 8x1 row (`iterations_simd8`): the forward path's lockstep yardstick.
    pub iterations_quads8: f64,
    /// DIG: corner-pass fetches per covered pixel.
    pub corner_iterations: Option<f64>,
    /// Mean hit distance, texels.
    pub mean_texels: f64,
    /// p99 hit distance, texels.
    pub p99_texels: f64,
    /// Largest hit distance over the error frames, texels.
    pub max_texels: f64,
    /// Fraction of covered pixels more than one texel off (or hit/miss mismatched).
    pub artifact_fraction: f64,
    /// PSNR of the shaded frame against the shaded reference, dB.
    pub psnr_db: f64,
    /// Non-finite hit texels summed over the error frames (must be 0).
    pub nonfinite_pixels: u64,
    /// Forward rows: hit texels that differ (bit for bit) from the deferred run's of the
    /// same method and setting on the same frame, summed over the error frames.
    pub forward_differing_pixels: Option<u64>,
}

impl RunRow {
    /// The parsed method (rows written by this module always parse).
    pub fn method(&self) -> Option<Method> {
        self.method.parse().ok()
    }
}

/// The medians of one run's times, one per pass of the repeat (pass order): what the
/// spread of a ratio of medians is read from (the ratio per pass, both sides measured in
/// the same interleaved pass).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PassMedians {
    /// The method time's median per pass.
    pub method: Vec<f64>,
    /// The per-frame total's median per pass.
    pub total: Vec<f64>,
}

/// An RGBA8 image produced by the sweep (heat maps, interval maps).
#[derive(Clone, Debug)]
pub struct NamedImage {
    /// File name inside the output folder.
    pub file_name: String,
    /// What it shows.
    pub caption: String,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8 pixels, row by row.
    pub rgba: Vec<u8>,
}

/// A map of the sweep as the report describes it.
#[derive(Clone, Debug, PartialEq)]
pub struct MapInfo {
    /// Short name.
    pub name: String,
    /// The field's label (file name).
    pub label: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Storage format (`R8_UNORM`, ...).
    pub format: String,
    /// Mean height.
    pub mean_height: f64,
}

/// Everything a sweep measured.
#[derive(Clone, Debug)]
pub struct BenchResults {
    /// The (validated) configuration.
    pub config: BenchConfig,
    /// Device name.
    pub device: String,
    /// Driver name and version.
    pub driver: String,
    /// Vulkan API version.
    pub api_version: String,
    /// Whether the cell-pyramid traversals ran with their step rules
    /// (`Context::traversal_rules`: on for CPU devices, off for GPUs).
    pub traversal_rules: bool,
    /// The maps of the methods sweep.
    pub maps: Vec<MapInfo>,
    /// The map resampled by the map-size sweep, if it ran.
    pub size_source: Option<MapInfo>,
    /// One row per run, methods sweep first.
    pub rows: Vec<RunRow>,
    /// Per row (same order), the per-pass medians of its times.
    pub pass_medians: Vec<PassMedians>,
    /// Heat maps and interval maps.
    pub images: Vec<NamedImage>,
    /// When the sweep started.
    pub started: SystemTime,
    /// Wall-clock duration of the sweep.
    pub wall: Duration,
    /// The material-table numbers, when they ran ([`BenchConfig::materials`]).
    pub materials: Option<materials::MaterialsBench>,
    /// The cost of silhouettes, when it ran ([`BenchConfig::silhouettes`]).
    pub silhouettes: Option<super::silhouettes::SilhouetteBench>,
}

/// `rows` as CSV: a header of [`RunRow`]'s field names, one line per row; empty cells
/// for absent values.
pub fn csv_bytes(rows: &[RunRow]) -> Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let err = |e: &dyn std::fmt::Display| Error::invalid("results.csv", e.to_string());
    if rows.is_empty() {
        // serde writes the header with the first row; an empty sweep still gets one.
        writer.write_record(CSV_HEADER).map_err(|e| err(&e))?;
    }
    for row in rows {
        writer.serialize(row).map_err(|e| err(&e))?;
    }
    writer.into_inner().map_err(|e| err(&e))
}

/// The columns of `results.csv`, in order.
pub const CSV_HEADER: [&str; 43] = [
    "sweep",
    "map",
    "map_width",
    "map_height",
    "method",
    "steps",
    "frame_width",
    "frame_height",
    "frames",
    "repeat",
    "error_frames",
    "frame_set",
    "gbuffer_ms",
    "pyramid_build_ms",
    "cpu_pyramid_build_ms",
    "cone_build_ms",
    "dig_corners_ms",
    "trace_ms",
    "shade_ms",
    "shadow_ms",
    "method_ms",
    "method_median_ms",
    "method_lo_ms",
    "method_hi_ms",
    "total_ms",
    "total_median_ms",
    "method_median_lo_ms",
    "method_median_hi_ms",
    "total_median_lo_ms",
    "total_median_hi_ms",
    "iterations_mean",
    "iterations_p99",
    "iterations_simd8",
    "iterations_warp32",
    "iterations_quads8",
    "corner_iterations",
    "mean_texels",
    "p99_texels",
    "max_texels",
    "artifact_fraction",
    "psnr_db",
    "nonfinite_pixels",
    "forward_differing_pixels",
];

/// A row of the methods sweep on `rocks` with these values (the unit tests').
#[cfg(test)]
pub(super) fn sample_row(
    method: &str,
    steps: Option<u32>,
    method_ms: f64,
    artifacts: f64,
) -> RunRow {
    RunRow {
        sweep: Sweep::Methods,
        map: "rocks".into(),
        map_width: 1024,
        map_height: 1024,
        method: method.into(),
        steps,
        frame_width: 64,
        frame_height: 36,
        frames: 2,
        repeat: 1,
        error_frames: 1,
        frame_set: "azimuth (f+0.5)*180deg for f<2; error frames 0".into(),
        gbuffer_ms: 0.5,
        pyramid_build_ms: None,
        cpu_pyramid_build_ms: None,
        cone_build_ms: None,
        dig_corners_ms: (method == "dig").then_some(0.25),
        trace_ms: method_ms,
        shade_ms: 0.75,
        shadow_ms: None,
        method_ms,
        method_median_ms: method_ms,
        method_lo_ms: method_ms,
        method_hi_ms: method_ms,
        total_ms: method_ms + 1.25,
        total_median_ms: method_ms + 1.25,
        method_median_lo_ms: method_ms,
        method_median_hi_ms: method_ms,
        total_median_lo_ms: method_ms + 1.25,
        total_median_hi_ms: method_ms + 1.25,
        iterations_mean: 12.5,
        iterations_p99: 40.0,
        iterations_simd8: 20.0,
        iterations_warp32: 30.0,
        iterations_quads8: 18.0,
        corner_iterations: None,
        mean_texels: 10.0 * artifacts,
        p99_texels: 3.0,
        max_texels: 9.0,
        artifact_fraction: artifacts,
        psnr_db: 30.0,
        nonfinite_pixels: 0,
        forward_differing_pixels: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &str, steps: Option<u32>, method_ms: f64, artifacts: f64) -> RunRow {
        sample_row(method, steps, method_ms, artifacts)
    }

    #[test]
    fn csv_has_the_header_and_blank_absent_values() {
        let rows = [
            row("pom", Some(75), 4.0, 0.125),
            row("bump", None, 1.0, 0.5),
        ];
        let bytes = csv_bytes(&rows).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(header, CSV_HEADER);
        assert_eq!(
            lines.next().unwrap(),
            "methods,rocks,1024,1024,pom,75,64,36,2,1,1,azimuth (f+0.5)*180deg for f<2; error frames 0,\
             0.5,,,,,4.0,0.75,,4.0,4.0,4.0,4.0,5.25,5.25,4.0,4.0,5.25,5.25,12.5,40.0,20.0,30.0,18.0,,1.25,3.0,9.0,0.125,30.0,0,"
        );
        let bump = lines.next().unwrap();
        assert!(
            bump.starts_with("methods,rocks,1024,1024,bump,,64"),
            "{bump}"
        );
        assert!(lines.next().is_none());
        // Round trip through the csv reader.
        let mut reader = csv::Reader::from_reader(bytes.as_slice());
        let back: Vec<RunRow> = reader.deserialize().map(|r| r.unwrap()).collect();
        assert_eq!(back, rows);
        // An empty sweep still has the header.
        let empty = String::from_utf8(csv_bytes(&[]).unwrap()).unwrap();
        assert!(empty.starts_with("sweep,map,"), "{empty}");
    }
}
