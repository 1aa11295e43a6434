//! The speed-versus-error benchmark behind `dispmap bench` and `cargo bench`: every
//! method on several height maps at several quality settings, timed with GPU timestamps
//! and measured against the exact reference, written as a CSV, a Markdown report and
//! plots.
//!
//! # Protocol (after the DIG paper, section 8)
//!
//! * **Scene.** The effectively infinite tiled plane ([`Geometry::TiledPlane`]), the eye
//!   0.25 tiles above it, depth scale 0.1. The camera's central ray is
//!   [`CAMERA_ELEVATION_DEG`] below the horizon and the vertical field of view is
//!   [`FOV_Y_DEG`], so the bottom row of the frame looks 40 degrees down and the top row
//!   0.5 degrees down (the paper: "from 40 degrees at the bottom of the screen to less
//!   than 1 degree near the horizon"). Over the `K` frames of a run the camera turns
//!   about the vertical axis: frame `f` has azimuth `(f + 0.5) 360 / K` degrees (the
//!   half step keeps the views off the map's axes).
//! * **Settings.** Each `--steps` value `iter` is the number of linear steps over the
//!   full depth, the same step size for every method that has one: `linear`, `relief`,
//!   `dig` and `dig-guarded` march `iter` steps, `pom` gets `n_max = iter` (and its
//!   default `n_min`), `secant` `N = iter` samples. DIG uses `eps1 = eps2 = 1 / iter`,
//!   4x4 blocks; every binary search has 5 steps. Methods without a step count
//!   (`bump`, `pyramid`, `exact`) run once per map (their `steps` is empty).
//! * **Time.** One renderer per method and map, each with one untimed warm-up frame (the
//!   first use of its pipelines; it also builds the pyramid and the cone map, whose one
//!   builds are reported as `pyramid_build_ms` and `cone_build_ms`, each the fastest of
//!   `R` renderers' builds). Then the runs are interleaved frame by frame: frame 0 of
//!   every (method, setting), then frame 1, and so on, so that load from other processes
//!   spreads over all methods instead of skewing the ones that ran while it lasted; the
//!   whole pass over the `K` frames is repeated `R` times (`--repeat`). Every pass's time
//!   is the **minimum** over the `K R` frames of its timestamp interval: on a shared
//!   machine a frame median swung 2x between runs where the minimum repeated to about
//!   10%. The *method time* (`method_ms`) is the minimum per-frame sum of the method's
//!   own passes (`trace`, plus `dig_corners` for DIG): what the speed-ups and plots
//!   compare; `method_median_ms` is its median, and `method_lo_ms` / `method_hi_ms` the
//!   lowest and highest of the `R` per-pass minima (the spread of the statistic).
//!   `total_ms` is the minimum whole frame (G-buffer, corner pass, trace, shade; without
//!   the one-off pyramid build), `total_median_ms` its median.
//! * **Error.** The reference of a frame (the exact CPU intersection of its rays,
//!   [`Measure::reference`](crate::measure::Measure::reference)) is computed once per map and error frame and shared by
//!   every method. `--error-frames N` picks frames `floor(i K / N)`, `i < N` (frame 0
//!   always; all frames by default). Each error measure of a run is the mean of the
//!   per-frame measures ([`crate::metrics`]) over its error frames, except `max_texels`
//!   (the maximum) and `nonfinite_pixels` (the sum). Iterations are the trace pass's
//!   per-pixel counts (mean and p99 over covered pixels, averaged over the error
//!   frames); for the DIG methods `corner_iterations` adds the corner pass's fetches per
//!   covered pixel.
//! * **Forward path** (`--forward on`, the default): what engines do with relief
//!   mapping and POM, the marcher in the G-buffer pass's fragment shader
//!   ([`dispmap::passes::forward`], [`Renderer::render_forward`](dispmap::renderer::Renderer::render_forward)). Every `relief` and
//!   `pom` run of the methods sweep is run a second time that way, by the same renderer,
//!   interleaved with the others frame by frame (rows of [`Sweep::Forward`]). A forward
//!   frame is `gbuffer` (the raster pass with the march), `classify` and `shade`; its
//!   *method time* is that `gbuffer` pass. Its hits are compared with the deferred run's
//!   of the same frame (`forward_differing_pixels`), and the report compares whole frames:
//!   the deferred frame of `dig` and `exact` against the forward frames of `relief` and
//!   `pom` at 150 steps and at equal error ([`compare`]).
//! * **Map-size sweep.** One map (rocks by default) resampled to each `--sizes` side
//!   (Catmull-Rom, keeping the map's precision), and `pyramid`, `exact`, `cone-exact`,
//!   `dig` and `pom` run at one setting (`size_steps`) with the same frames, the pyramid
//!   and cone-map builds reported apart from the trace.
//!
//! Beside the minima every time has its **median** over every frame, and the lowest and
//! highest per-pass median (`*_median_lo_ms`, `*_median_hi_ms`); the report's ratios of
//! medians carry the range of their per-pass ratios ([`PassMedians`]).
//!
//! [`run`] does the sweep and returns [`BenchResults`]; [`write_outputs`] writes
//! `results.csv`, `report.md`, `pareto_<map>.png`, `sizes.png` and the heat maps.
//! Timings on lavapipe are CPU timings: compare ratios within one run, never absolute
//! numbers across runs.

pub mod compare;
mod config;
pub mod curves;
mod maps;
pub mod materials;
pub mod plot;
pub mod report;
mod results;
mod run;
pub mod silhouettes;
mod sweep;
pub mod verdict;

pub use curves::{CurvePoint, TimeToError, time_to_reach};

use crate::output::Outputs;
use config::trim_float;
pub use config::{
    BenchConfig, azimuth_deg, error_frames, parse_maps, parse_methods, parse_sizes, parse_steps,
};
use dispmap::error::Result;
use dispmap::method::{Method, MethodParams};
use dispmap::scene::{Camera, Geometry, Scene};
pub use maps::{MapSpec, bundled_maps, file_stem, resample};
pub use results::{
    BenchResults, CSV_HEADER, MapInfo, NamedImage, PassMedians, RunRow, Sweep, csv_bytes,
};
use run::{Builds, Tracker, cpu_pyramid_ms, min_of};
pub use run::{NO_STEPS_WEIGHT, Progress, REFERENCE_WEIGHT, run};
use std::path::{Path, PathBuf};
pub use sweep::lockstep_iterations;
use sweep::{MapSweep, RunSpec};

/// The central view ray's angle below the horizon, degrees: with [`FOV_Y_DEG`] the
/// frame spans 40 degrees (bottom row) to 0.5 degrees (top row) below the horizon.
pub const CAMERA_ELEVATION_DEG: f32 = 20.25;

/// Vertical field of view of the benchmark camera, degrees.
pub const FOV_Y_DEG: f32 = 39.5;

/// The quality settings (iterations): the DIG paper's 75 to 150, and 10 to 50 so that the
/// setting where DIG reaches `pom`-150's error is read off measured points (DIG at 25
/// already beats `pom` at 150 on every bundled map).
pub const DEFAULT_STEPS: [u32; 10] = [10, 15, 20, 25, 35, 50, 75, 100, 125, 150];

/// Map sides of the map-size sweep (the pyramid paper's Fig. 21).
pub const DEFAULT_SIZES: [u32; 4] = [256, 512, 1024, 2048];

/// Methods timed in the map-size sweep (default methods only, [`Method::in_defaults`]).
pub const SIZE_METHODS: [Method; 4] = [Method::Pyramid, Method::Exact, Method::Dig, Method::Pom];

/// The setting of the map-size sweep.
pub const DEFAULT_SIZE_STEPS: u32 = 100;

/// Default frame size: keeps the default run under 15 minutes on 2 CPU cores of lavapipe.
pub const DEFAULT_FRAME: [u32; 2] = [640, 360];

/// Default number of frames (camera azimuths) per run.
pub const DEFAULT_FRAMES: u32 = 8;

/// Default `--repeat`: interleaved passes over the frames.
pub const DEFAULT_REPEAT: u32 = 3;

/// Largest `--repeat`.
pub const MAX_REPEAT: u32 = 100;

/// Largest `--frames`.
pub const MAX_FRAMES: u32 = 10_000;

/// Largest side of the map-size sweep (the device's limit applies too).
pub const MAX_MAP_SIDE: u32 = 16384;

/// Binary-search steps of every method that has them (the paper's 5).
pub const REFINE_STEPS: u32 = 5;

/// Does `method` read a step count (`--steps`, [`Method::reads`])? `bump`, `pyramid`,
/// `exact` and `cone-exact` do not: they run once per map.
pub fn has_steps(method: Method) -> bool {
    method.reads().steps
}

/// The parameters of `method` at `steps` under the protocol (module docs).
pub fn protocol_params(steps: Option<u32>) -> MethodParams {
    MethodParams {
        steps: steps.unwrap_or(MethodParams::default().steps),
        refine_steps: REFINE_STEPS,
        eps: None,
        ..MethodParams::default()
    }
}

/// The benchmark scene (module docs), camera at azimuth 0.
pub fn protocol_scene() -> Scene {
    Scene {
        geometry: Geometry::TiledPlane,
        camera: Camera {
            elevation_deg: CAMERA_ELEVATION_DEG,
            azimuth_deg: 0.0,
            fov_y_deg: FOV_Y_DEG,
            height: Camera::default().height,
            distance: None,
        },
        ..Scene::default()
    }
}

/// The benchmark's files (results.csv, the Pareto and map-size plots, heat maps,
/// report.md), encoded and checked for the folder `dir`, to be written together by
/// [`crate::output::Outputs::commit`] (which creates `dir`).
pub fn stage_outputs(dir: &Path, results: &BenchResults, command: &str) -> Result<Outputs> {
    let mut out = Outputs::new();
    out.stage_in(dir, "results.csv", csv_bytes(&results.rows)?)?;
    for map in &results.maps {
        let name = report::pareto_file(&map.name);
        let png = plot::pareto(&dir.join(&name), &map.name, &results.rows)?;
        out.stage_in(dir, &name, png)?;
    }
    if results.rows.iter().any(|r| r.sweep == Sweep::MapSize) {
        let png = plot::sizes(&dir.join(report::SIZES_PLOT), &results.rows)?;
        out.stage_in(dir, report::SIZES_PLOT, png)?;
    }
    for image in &results.images {
        let png = crate::output::png_bytes(
            &dir.join(&image.file_name),
            image.width,
            image.height,
            &image.rgba,
        )?;
        out.stage_in(dir, &image.file_name, png)?;
    }
    out.stage_in(
        dir,
        "report.md",
        report::markdown(results, command).into_bytes(),
    )?;
    Ok(out)
}

/// Writes the benchmark's files into `dir` (created if missing), all together: a
/// failure leaves none of them (see [`stage_outputs`]); returns their paths.
pub fn write_outputs(dir: &Path, results: &BenchResults, command: &str) -> Result<Vec<PathBuf>> {
    let out = stage_outputs(dir, results, command)?;
    let written = out.paths();
    out.commit()?;
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_protocol_scene_spans_40_to_half_a_degree() {
        let s = protocol_scene();
        let bottom = s.camera.elevation_deg + s.camera.fov_y_deg / 2.0;
        let top = s.camera.elevation_deg - s.camera.fov_y_deg / 2.0;
        assert_eq!((bottom, top), (40.0, 0.5));
        assert!(s.validate().is_ok());
    }
}
