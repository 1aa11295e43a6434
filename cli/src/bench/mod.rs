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
//!   [`Renderer::reference`]) is computed once per map and error frame and shared by
//!   every method. `--error-frames N` picks frames `floor(i K / N)`, `i < N` (frame 0
//!   always; all frames by default). Each error measure of a run is the mean of the
//!   per-frame measures ([`crate::metrics`]) over its error frames, except `max_texels`
//!   (the maximum) and `nonfinite_pixels` (the sum). Iterations are the trace pass's
//!   per-pixel counts (mean and p99 over covered pixels, averaged over the error
//!   frames); for the DIG methods `corner_iterations` adds the corner pass's fetches per
//!   covered pixel.
//! * **Forward path** (`--forward on`, the default): what engines do with relief
//!   mapping and POM, the marcher in the G-buffer pass's fragment shader
//!   ([`dispmap::passes::forward`], [`Renderer::render_forward`]). Every `relief` and
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
pub mod materials;
pub mod plot;
pub mod report;

pub use report::{CurvePoint, TimeToError, time_to_reach};

use crate::heatmap;
use crate::measure::{Compared, FrameReference, Measure as _};
use crate::metrics::{self, ErrorMetrics};
use crate::output::Outputs;
use crate::reference::Reference;
use dispmap::context::Context;
use dispmap::error::{Error, Result};
use dispmap::heightfield::{HeightField, Texels};
use dispmap::method::{MAX_STEPS, Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::renderer::{MAX_FRAME_SIDE, RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Scene};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

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

/// A height map of the sweep and the short name used in tables and file names.
#[derive(Clone, Debug)]
pub struct MapSpec {
    /// Short name (`rocks`; a file's stem), used in file names after [`file_stem`].
    pub name: String,
    /// The map, in the height convention.
    pub field: HeightField,
}

impl MapSpec {
    /// A bundled map by name ([`crate::bundled::NAMES`]); the error names `--maps`.
    pub fn bundled(name: &str) -> Result<Self> {
        Ok(MapSpec {
            name: name.to_owned(),
            field: crate::bundled::by_name(name, "--maps")?,
        })
    }

    /// A map file, named after its stem.
    pub fn load(path: &Path, convention: dispmap::heightfield::Convention) -> Result<Self> {
        let field = HeightField::load(path, convention)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "map".into());
        Ok(MapSpec { name, field })
    }
}

/// The default maps: every bundled map ([`crate::bundled::NAMES`]: rocks, bricks,
/// mountains).
pub fn bundled_maps() -> Result<Vec<MapSpec>> {
    crate::bundled::NAMES
        .iter()
        .map(|name| MapSpec::bundled(name))
        .collect()
}

/// `name` reduced to `[A-Za-z0-9_-]` (other characters become `_`), for file names.
pub fn file_stem(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() { "map".into() } else { s }
}

/// What to sweep. [`BenchConfig::default`] is the protocol's default run.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchConfig {
    /// Frame width and height in pixels (`--size`).
    pub frame: [u32; 2],
    /// Frames (camera azimuths) per run (`--frames`).
    pub frames: u32,
    /// Interleaved passes over the frames (`--repeat`): every run renders its `frames`
    /// frames `repeat` times; the times are the minimum over all of them, with the range
    /// of the per-pass minima as the spread.
    pub repeat: u32,
    /// Frames that get the reference and the error measures (`--error-frames`); `None`:
    /// all of them.
    pub error_frames: Option<u32>,
    /// Quality settings (`--steps`), ascending.
    pub steps: Vec<u32>,
    /// Methods (`--methods`), in [`Method::ALL`] order; by default
    /// [`Method::defaults`].
    pub methods: Vec<Method>,
    /// Map sides of the map-size sweep (`--sizes`), ascending; empty: no sweep.
    pub sizes: Vec<u32>,
    /// Methods of the map-size sweep.
    pub size_methods: Vec<Method>,
    /// The setting of the map-size sweep (`--size-steps`).
    pub size_steps: u32,
    /// The scene of frame 0 (the azimuth is set per frame).
    pub scene: Scene,
    /// Self-shadowing of every run (`--shadows`, default off): when on, the `shadow`
    /// pass is timed (`shadow_ms`) and counted in `total_ms`, not in `method_ms`.
    pub shadows: dispmap::passes::shadow::ShadowMode,
    /// The material-table numbers ([`materials`], `--materials`, default on): six small
    /// renderers over the same `K R` frames.
    pub materials: bool,
    /// The forward path (`--forward`, default on): every run of a method with one
    /// ([`Method::forward_shader`]: `relief`, `pom`) is also run forward (module docs).
    pub forward: bool,
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            frame: DEFAULT_FRAME,
            frames: DEFAULT_FRAMES,
            repeat: DEFAULT_REPEAT,
            error_frames: None,
            steps: DEFAULT_STEPS.to_vec(),
            methods: Method::defaults(),
            sizes: DEFAULT_SIZES.to_vec(),
            size_methods: SIZE_METHODS.to_vec(),
            size_steps: DEFAULT_SIZE_STEPS,
            scene: protocol_scene(),
            shadows: dispmap::passes::shadow::ShadowMode::Off,
            materials: true,
            forward: true,
        }
    }
}

impl BenchConfig {
    /// Checks every value and puts the lists in order (sorted, without duplicates); the
    /// error names the command-line option.
    pub fn validate(&mut self) -> Result<()> {
        let [w, h] = self.frame;
        if w == 0 || h == 0 || w > MAX_FRAME_SIDE || h > MAX_FRAME_SIDE {
            return Err(Error::invalid(
                "--size",
                format!("{w}x{h} is outside 1..={MAX_FRAME_SIDE} per side"),
            ));
        }
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return Err(Error::invalid(
                "--frames",
                format!("{} is outside 1..={MAX_FRAMES}", self.frames),
            ));
        }
        if self.repeat == 0 || self.repeat > MAX_REPEAT {
            return Err(Error::invalid(
                "--repeat",
                format!("{} is outside 1..={MAX_REPEAT}", self.repeat),
            ));
        }
        if let Some(n) = self.error_frames
            && (n == 0 || n > self.frames)
        {
            return Err(Error::invalid(
                "--error-frames",
                format!("{n} is outside 1..={} (--frames)", self.frames),
            ));
        }
        if self.steps.is_empty() {
            return Err(Error::invalid("--steps", "the list is empty"));
        }
        if let Some(bad) = self.steps.iter().find(|&&s| s == 0 || s > MAX_STEPS) {
            return Err(Error::invalid(
                "--steps",
                format!("{bad} is outside 1..={MAX_STEPS}"),
            ));
        }
        self.steps.sort_unstable();
        self.steps.dedup();
        if self.methods.is_empty() {
            return Err(Error::invalid("--methods", "the list is empty"));
        }
        self.methods = in_report_order(&self.methods);
        if let Some(bad) = self
            .sizes
            .iter()
            .find(|&&s| !(2..=MAX_MAP_SIDE).contains(&s))
        {
            return Err(Error::invalid(
                "--sizes",
                format!("{bad} is outside 2..={MAX_MAP_SIDE}"),
            ));
        }
        self.sizes.sort_unstable();
        self.sizes.dedup();
        self.size_methods = in_report_order(&self.size_methods);
        if self.size_steps == 0 || self.size_steps > MAX_STEPS {
            return Err(Error::invalid(
                "--size-steps",
                format!("{} is outside 1..={MAX_STEPS}", self.size_steps),
            ));
        }
        self.scene.validate()
    }

    /// The frames that get the reference (module docs), ascending.
    pub fn error_frame_indices(&self) -> Vec<u32> {
        error_frames(self.frames, self.error_frames.unwrap_or(self.frames))
    }

    /// The scene of frame `f`: the camera turned to azimuth `(f + 0.5) 360 / K`.
    pub fn frame_scene(&self, f: u32) -> Scene {
        let mut scene = self.scene;
        scene.camera.azimuth_deg = azimuth_deg(f, self.frames);
        scene
    }

    /// The frame set as one CSV-safe phrase (azimuths and error frames).
    pub fn frame_set(&self) -> String {
        let k = self.frames;
        let errors: Vec<String> = self
            .error_frame_indices()
            .iter()
            .map(|f| f.to_string())
            .collect();
        format!(
            "azimuth (f+0.5)*{}deg for f<{k}; error frames {}",
            trim_float(360.0 / f64::from(k)),
            errors.join(" ")
        )
    }

    /// The quality settings of `method`: every `--steps` value, or one run without a
    /// step count.
    pub fn settings_of(&self, method: Method) -> Vec<Option<u32>> {
        if has_steps(method) {
            self.steps.iter().copied().map(Some).collect()
        } else {
            vec![None]
        }
    }

    /// The forward runs (module docs): each `relief` and `pom` setting of the methods
    /// sweep, when [`BenchConfig::forward`] is on.
    pub fn forward_methods(&self) -> Vec<Method> {
        self.methods
            .iter()
            .copied()
            .filter(|m| self.forward && m.forward_shader().is_some())
            .collect()
    }

    /// The setting whose heat maps are written: the largest `--steps`.
    pub fn heatmap_steps(&self) -> u32 {
        self.steps
            .iter()
            .copied()
            .max()
            .unwrap_or(DEFAULT_SIZE_STEPS)
    }
}

/// The methods of `list`, once each, in [`Method::ALL`] order.
fn in_report_order(list: &[Method]) -> Vec<Method> {
    Method::ALL
        .iter()
        .copied()
        .filter(|m| list.contains(m))
        .collect()
}

/// Frames `floor(i k / n)` for `i < n` (`n` clamped to `1..=k`).
pub fn error_frames(k: u32, n: u32) -> Vec<u32> {
    let k = k.max(1);
    let n = n.clamp(1, k);
    (0..n)
        .map(|i| (u64::from(i) * u64::from(k) / u64::from(n)) as u32)
        .collect()
}

/// The camera azimuth of frame `f` of `k`, degrees: `(f + 0.5) 360 / k`.
pub fn azimuth_deg(f: u32, k: u32) -> f32 {
    ((f64::from(f) + 0.5) * 360.0 / f64::from(k.max(1))) as f32
}

fn trim_float(x: f64) -> String {
    let s = format!("{x:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// Parses a comma-separated list; empty items are an error naming `option`.
fn parse_list<T>(
    option: &str,
    s: &str,
    parse: impl Fn(&str) -> std::result::Result<T, String>,
) -> Result<Vec<T>> {
    if s.trim().is_empty() {
        return Err(Error::invalid(option, "the list is empty"));
    }
    s.split(',')
        .map(|item| {
            let item = item.trim();
            if item.is_empty() {
                return Err(Error::invalid(option, format!("empty item in '{s}'")));
            }
            parse(item).map_err(|m| Error::invalid(option, m))
        })
        .collect()
}

/// Parses `--steps` (`75,100,125,150`): positive step counts up to [`MAX_STEPS`].
pub fn parse_steps(s: &str) -> Result<Vec<u32>> {
    parse_list("--steps", s, |item| match item.parse::<u32>() {
        Ok(n) if (1..=MAX_STEPS).contains(&n) => Ok(n),
        _ => Err(format!("'{item}' is not a step count in 1..={MAX_STEPS}")),
    })
}

/// Parses `--methods` (`relief,pom,dig`, `all`, or `default`: [`Method::defaults`]).
pub fn parse_methods(s: &str) -> Result<Vec<Method>> {
    match s.trim() {
        "all" => return Ok(Method::ALL.to_vec()),
        "default" => return Ok(Method::defaults()),
        _ => {}
    }
    parse_list("--methods", s, |item| {
        item.parse::<Method>().map_err(|e| match e {
            Error::InvalidInput { message, .. } => message,
            other => other.to_string(),
        })
    })
}

/// Parses `--sizes` (`256,512,1024,2048`, or `none`): map sides in 2..=[`MAX_MAP_SIDE`].
pub fn parse_sizes(s: &str) -> Result<Vec<u32>> {
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    parse_list("--sizes", s, |item| match item.parse::<u32>() {
        Ok(n) if (2..=MAX_MAP_SIDE).contains(&n) => Ok(n),
        _ => Err(format!("'{item}' is not a map side in 2..={MAX_MAP_SIDE}")),
    })
}

/// Parses `--maps` (`rocks,bricks,mountains`, or `none`): bundled map names.
pub fn parse_maps(s: &str) -> Result<Vec<String>> {
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    parse_list("--maps", s, |item| {
        if crate::bundled::NAMES.contains(&item) {
            Ok(item.to_owned())
        } else {
            Err(format!(
                "unknown bundled map '{item}' (known: {}; add a file with --heightmap)",
                crate::bundled::NAMES.join(", ")
            ))
        }
    })
}

/// `field` resampled to `width x height` with a Catmull-Rom filter, at its precision
/// (8-bit stays 8-bit, 16-bit 16-bit, float float clamped to `[0, 1]`).
pub fn resample(field: &HeightField, width: u32, height: u32, label: &str) -> Result<HeightField> {
    use image::imageops::{FilterType, resize};
    use image::{DynamicImage, ImageBuffer, Luma};
    if width == 0 || height == 0 {
        return Err(Error::invalid("--sizes", "a map side is zero"));
    }
    let (w, h) = (field.width(), field.height());
    let bad = || Error::invalid(label, "texel count does not match the map size");
    let filter = FilterType::CatmullRom;
    match field.texels() {
        Texels::R8(v) => {
            let img = ImageBuffer::<Luma<u8>, _>::from_raw(w, h, v.clone()).ok_or_else(bad)?;
            let out = resize(&img, width, height, filter);
            HeightField::from_image(
                DynamicImage::ImageLuma8(out),
                dispmap::heightfield::Convention::Height,
                label.to_owned(),
            )
        }
        Texels::R16(v) => {
            let img = ImageBuffer::<Luma<u16>, _>::from_raw(w, h, v.clone()).ok_or_else(bad)?;
            let out = resize(&img, width, height, filter);
            HeightField::from_image(
                DynamicImage::ImageLuma16(out),
                dispmap::heightfield::Convention::Height,
                label.to_owned(),
            )
        }
        Texels::R32F(v) => {
            let img = ImageBuffer::<Luma<f32>, _>::from_raw(w, h, v.clone()).ok_or_else(bad)?;
            let out = resize(&img, width, height, filter);
            let values = out
                .into_raw()
                .into_iter()
                .map(|x| x.clamp(0.0, 1.0))
                .collect();
            HeightField::from_heights(width, height, values, label)
        }
    }
}

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
}

/// The sweep's progress, reported after each unit of work.
#[derive(Clone, Debug)]
pub struct Progress {
    /// Work done, in [`Progress::total`]'s units.
    pub done: u64,
    /// All the work: a timed frame at `N` steps weighs `N` (methods without steps
    /// [`NO_STEPS_WEIGHT`]), a reference frame [`REFERENCE_WEIGHT`]: roughly
    /// proportional to lavapipe's time.
    pub total: u64,
    /// What runs now, e.g. `rocks dig 100 (frame 3/8)`.
    pub stage: String,
}

/// Progress weight of one frame of a method without a step count.
pub const NO_STEPS_WEIGHT: u64 = 100;

/// Renderers of the material-table numbers ([`materials`]).
const MATERIALS_RENDERERS: u64 = 6;

/// Progress weight of one reference frame (CPU intersection).
pub const REFERENCE_WEIGHT: u64 = 150;

/// The one-off builds of a renderer's maps, GPU milliseconds.
#[derive(Clone, Copy, Debug, Default)]
struct Builds {
    pyramid: Option<f64>,
    cone: Option<f64>,
}

impl Builds {
    fn of(renderer: &Renderer) -> Self {
        Builds {
            pyramid: renderer.build_ms(PassName::Pyramid),
            cone: renderer.build_ms(PassName::Cone),
        }
    }

    /// Each build's faster time.
    fn min(self, other: Self) -> Self {
        let min = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        Builds {
            pyramid: min(self.pyramid, other.pyramid),
            cone: min(self.cone, other.cone),
        }
    }
}

/// The fastest of 3 single-threaded CPU builds of `field`'s pyramid of `kind`, ms.
fn cpu_pyramid_ms(
    field: &HeightField,
    config: &BenchConfig,
    kind: dispmap::method::PyramidKind,
) -> f64 {
    let addressing = config.scene.addressing();
    min_of((0..3).map(|_| {
        let start = Instant::now();
        let levels = dispmap::passes::pyramid::cpu_build(field, addressing, kind);
        std::hint::black_box(levels);
        start.elapsed().as_secs_f64() * 1e3
    }))
}

/// The smallest of `values` (infinity when empty).
fn min_of(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(f64::INFINITY, f64::min)
}

fn run_weight(steps: Option<u32>, frames: u32) -> u64 {
    u64::from(frames) * steps.map_or(NO_STEPS_WEIGHT, u64::from)
}

/// [`run_weight`] of every frame of every pass.
fn frames_rendered(config: &BenchConfig) -> u32 {
    config.frames * config.repeat
}

/// The total progress weight of a sweep over `maps` maps (and the size sweep if
/// `size_sweep`).
fn total_weight(config: &BenchConfig, maps: usize, size_sweep: bool) -> u64 {
    let refs = config.error_frame_indices().len() as u64 * REFERENCE_WEIGHT;
    let per_map: u64 = config
        .methods
        .iter()
        .chain(&config.forward_methods())
        .flat_map(|&m| config.settings_of(m))
        .map(|s| run_weight(s, frames_rendered(config)))
        .sum::<u64>()
        + refs;
    let per_size: u64 = config
        .size_methods
        .iter()
        .map(|&m| {
            run_weight(
                has_steps(m).then_some(config.size_steps),
                frames_rendered(config),
            )
        })
        .sum::<u64>()
        + refs;
    per_map * maps as u64
        + if config.materials {
            MATERIALS_RENDERERS * run_weight(Some(64), frames_rendered(config))
        } else {
            0
        }
        + if size_sweep {
            per_size * config.sizes.len() as u64
        } else {
            0
        }
}

struct Tracker<'p> {
    done: u64,
    total: u64,
    sink: &'p mut dyn FnMut(&Progress),
}

impl Tracker<'_> {
    fn advance(&mut self, weight: u64, stage: String) {
        self.done = (self.done + weight).min(self.total);
        (self.sink)(&Progress {
            done: self.done,
            total: self.total,
            stage,
        });
    }
}

/// Runs the sweep: the methods sweep over `maps`, then (if `config.sizes` is not empty
/// and `size_source` is given) the map-size sweep on `size_source`. `progress` is called
/// after every frame. Validates `config` first.
pub fn run(
    ctx: &Arc<Context>,
    config: &BenchConfig,
    maps: &[MapSpec],
    size_source: Option<&MapSpec>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<BenchResults> {
    let mut config = config.clone();
    config.validate()?;
    if maps.is_empty() && (config.sizes.is_empty() || size_source.is_none()) {
        return Err(Error::invalid(
            "--maps",
            "no map to benchmark (give --maps or --heightmap)",
        ));
    }
    let mut names = std::collections::HashSet::new();
    for m in maps {
        if !names.insert(file_stem(&m.name)) {
            return Err(Error::invalid(
                "--maps",
                format!("two maps are named '{}'", m.name),
            ));
        }
    }
    let size_sweep = !config.sizes.is_empty() && size_source.is_some();
    let started = SystemTime::now();
    let clock = Instant::now();
    let mut tracker = Tracker {
        done: 0,
        total: total_weight(&config, maps.len(), size_sweep),
        sink: progress,
    };
    let mut rows = Vec::new();
    let mut pass_medians = Vec::new();
    let mut images = Vec::new();
    let heat_steps = config.heatmap_steps();
    let mut runs: Vec<RunSpec> = config
        .methods
        .iter()
        .flat_map(|&method| {
            config
                .settings_of(method)
                .into_iter()
                .map(move |steps| RunSpec {
                    method,
                    steps,
                    heat: steps.is_none_or(|s| s == heat_steps),
                    forward: false,
                })
        })
        .collect();
    // The forward runs, interleaved with the others in every frame (after them).
    for method in config.forward_methods() {
        for steps in config.settings_of(method) {
            runs.push(RunSpec {
                method,
                steps,
                heat: false,
                forward: true,
            });
        }
    }
    for map in maps {
        let sweep = MapSweep::new(ctx, &config, map, Sweep::Methods, &mut tracker)?;
        let (r, p, imgs) = sweep.run(&runs, &mut tracker)?;
        rows.extend(r);
        pass_medians.extend(p);
        images.extend(imgs);
    }
    let mut size_info = None;
    if let (true, Some(source)) = (size_sweep, size_source) {
        size_info = Some(map_info(&source.name, &source.field));
        for &side in &config.sizes {
            let label = format!("{}@{side}", source.name);
            let field = resample(&source.field, side, side, &label)?;
            let spec = MapSpec { name: label, field };
            let runs: Vec<RunSpec> = config
                .size_methods
                .iter()
                .map(|&method| RunSpec {
                    method,
                    steps: has_steps(method).then_some(config.size_steps),
                    heat: false,
                    forward: false,
                })
                .collect();
            let sweep = MapSweep::new(ctx, &config, &spec, Sweep::MapSize, &mut tracker)?;
            let (r, p, _) = sweep.run(&runs, &mut tracker)?;
            rows.extend(r);
            pass_medians.extend(p);
        }
    }
    let materials = if config.materials {
        let per_pass = MATERIALS_RENDERERS * run_weight(Some(64), frames_rendered(&config))
            / u64::from(config.repeat);
        Some(materials::run(
            ctx,
            config.frame,
            config.frames,
            config.repeat,
            &mut |r| tracker.advance(per_pass, format!("materials (pass {r}/{})", config.repeat)),
        )?)
    } else {
        None
    };
    let info = ctx.info();
    Ok(BenchResults {
        materials,
        maps: maps.iter().map(|m| map_info(&m.name, &m.field)).collect(),
        size_source: size_info,
        device: info.name.clone(),
        driver: info.driver.clone(),
        api_version: info.api_version.clone(),
        config,
        rows,
        pass_medians,
        images,
        started,
        wall: clock.elapsed(),
    })
}

fn map_info(name: &str, field: &HeightField) -> MapInfo {
    MapInfo {
        name: name.to_owned(),
        label: field.label().to_owned(),
        width: field.width(),
        height: field.height(),
        format: format!("{:?}", field.format()),
        mean_height: field.mean(),
    }
}

/// One (method, setting) of a map's sweep.
#[derive(Clone, Copy, Debug)]
struct RunSpec {
    method: Method,
    steps: Option<u32>,
    /// Write the heat map (and DIG's interval map) of frame 0.
    heat: bool,
    /// The forward path ([`Sweep::Forward`]).
    forward: bool,
}

/// What a run has measured so far.
#[derive(Default)]
struct RunAccumulator {
    /// Every frame's time of each pass, over all passes of the repeat.
    passes: Vec<(PassName, Vec<f64>)>,
    /// Every frame's method time (`dig_corners + trace`), with its repeat pass.
    method_ms: Vec<(u32, f64)>,
    /// Every frame's total (without the one-off passes), with its repeat pass.
    total_ms: Vec<(u32, f64)>,
    errors: Vec<ErrorMetrics>,
    /// Forward runs: hit texels differing from the deferred run's, per error frame.
    forward_differing: Vec<u64>,
    corner_iterations: Vec<f64>,
    lockstep: Vec<[f64; 3]>,
}

impl RunAccumulator {
    /// Adds a frame's times; `forward`: the method runs in the G-buffer pass.
    fn add_times(&mut self, times: &[(PassName, f64)], pass: u32, forward: bool) {
        let mut frame_method = 0.0;
        let mut frame_total = 0.0;
        for &(name, ms) in times {
            if name.is_one_off() {
                continue;
            }
            frame_total += ms;
            let method_pass = if forward {
                name == PassName::GBuffer
            } else {
                name == PassName::Trace || name == PassName::DigCorners
            };
            if method_pass {
                frame_method += ms;
            }
            match self.passes.iter_mut().find(|(n, _)| *n == name) {
                Some((_, v)) => v.push(ms),
                None => self.passes.push((name, vec![ms])),
            }
        }
        self.method_ms.push((pass, frame_method));
        self.total_ms.push((pass, frame_total));
    }

    /// The robust time of a pass: its minimum over every frame of every pass.
    fn min_of(&self, name: PassName) -> Option<f64> {
        self.passes
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| min_of(v.iter().copied()))
    }

    /// The method time's minimum over all frames, its median, and the lowest and the
    /// highest per-pass minimum (the spread of the robust statistic over the repeat).
    fn method_stats(&self) -> (f64, f64, f64, f64) {
        let all: Vec<f64> = self.method_ms.iter().map(|&(_, ms)| ms).collect();
        let passes = self
            .method_ms
            .iter()
            .map(|&(p, _)| p)
            .max()
            .map_or(0, |p| p + 1);
        let per_pass: Vec<f64> = (0..passes)
            .map(|p| min_of(self.method_ms.iter().filter(|m| m.0 == p).map(|m| m.1)))
            .collect();
        (
            min_of(all.iter().copied()),
            dispmap::timing::median(&all),
            min_of(per_pass.iter().copied()),
            per_pass.iter().copied().fold(0.0, f64::max),
        )
    }

    /// The per-pass medians of the method time and of the per-frame total.
    fn pass_medians(&self) -> PassMedians {
        let per_pass = |values: &[(u32, f64)]| -> Vec<f64> {
            let passes = values.iter().map(|&(p, _)| p).max().map_or(0, |p| p + 1);
            (0..passes)
                .map(|p| {
                    let v: Vec<f64> = values.iter().filter(|m| m.0 == p).map(|m| m.1).collect();
                    dispmap::timing::median(&v)
                })
                .collect()
        };
        PassMedians {
            method: per_pass(&self.method_ms),
            total: per_pass(&self.total_ms),
        }
    }

    fn mean(&self, get: fn(&ErrorMetrics) -> f64) -> f64 {
        mean_of(self.errors.iter().map(get))
    }
}

/// One map's references and one renderer per method. The runs are interleaved frame by
/// frame (frame 0 of every run, then frame 1, ...), so a load that comes and goes on
/// the machine spreads over every method's frames instead of skewing the methods that
/// happened to run at that time; the per-pass medians then discard the slow frames.
struct MapSweep<'a> {
    ctx: &'a Arc<Context>,
    config: &'a BenchConfig,
    name: String,
    field: &'a HeightField,
    sweep: Sweep,
    /// (frame index, reference), ascending.
    references: Vec<(u32, FrameReference)>,
}

impl<'a> MapSweep<'a> {
    /// Computes the references of the error frames (with a `bump` renderer).
    fn new(
        ctx: &'a Arc<Context>,
        config: &'a BenchConfig,
        map: &'a MapSpec,
        sweep: Sweep,
        tracker: &mut Tracker<'_>,
    ) -> Result<Self> {
        let mut renderer = Renderer::new(ctx, &map.field, Self::settings(config, Method::Bump))?;
        let reference = Reference::new(&map.field, renderer.settings().scene.addressing());
        let mut references = Vec::new();
        for f in config.error_frame_indices() {
            renderer.set_scene(config.frame_scene(f))?;
            references.push((f, renderer.reference(&reference)?));
            tracker.advance(
                REFERENCE_WEIGHT,
                format!("{} reference (frame {})", map.name, f + 1),
            );
        }
        Ok(MapSweep {
            ctx,
            config,
            name: map.name.clone(),
            field: &map.field,
            sweep,
            references,
        })
    }

    fn settings(config: &BenchConfig, method: Method) -> RenderSettings {
        RenderSettings {
            width: config.frame[0],
            height: config.frame[1],
            method,
            params: protocol_params(None),
            scene: config.frame_scene(0),
            shadows: dispmap::passes::shadow::ShadowSettings {
                mode: config.shadows,
                ..Default::default()
            },
        }
    }

    /// Times every run over the frames (interleaved, see the type's docs) and measures
    /// their errors; returns one row per run, in order, their per-pass medians, and the
    /// heat and interval maps. A forward run uses the renderer of its method.
    fn run(
        &self,
        runs: &[RunSpec],
        tracker: &mut Tracker<'_>,
    ) -> Result<(Vec<RunRow>, Vec<PassMedians>, Vec<NamedImage>)> {
        let config = self.config;
        // One renderer per method; each gets one untimed warm-up frame (first use of its
        // pipelines; it builds the pyramid, whose time is kept).
        let mut renderers: Vec<(Method, Renderer, Builds)> = Vec::new();
        for run in runs {
            if renderers.iter().any(|(m, _, _)| *m == run.method) {
                continue;
            }
            let mut settings = Self::settings(config, run.method);
            settings.params = protocol_params(run.steps);
            let mut renderer = Renderer::new(self.ctx, self.field, settings)?;
            renderer.render()?;
            if runs.iter().any(|r| r.forward && r.method == run.method) {
                renderer.enable_forward(self.field)?;
                // The forward pipeline's first use, untimed like the deferred one's.
                renderer.render_forward()?;
            }
            let mut builds = Builds::of(&renderer);
            // The builds run once per renderer: `repeat` renderers give `repeat` builds,
            // of which the fastest is kept (the same statistic as every other time).
            if builds.pyramid.is_some() || builds.cone.is_some() {
                for _ in 1..config.repeat {
                    let mut again = Renderer::new(self.ctx, self.field, settings)?;
                    again.render()?;
                    builds = builds.min(Builds::of(&again));
                }
            }
            renderers.push((run.method, renderer, builds));
        }
        let mut acc: Vec<RunAccumulator> = runs.iter().map(|_| RunAccumulator::default()).collect();
        let mut images = Vec::new();
        // The deferred hits of the current error frame, for the forward runs' comparison.
        let mut deferred_hits: std::collections::HashMap<
            (Method, Option<u32>),
            Vec<metrics::HitTexel>,
        > = std::collections::HashMap::new();
        let mut next_ref = 0;
        for (pass, f) in (0..config.repeat).flat_map(|p| (0..config.frames).map(move |f| (p, f))) {
            // The references are measured in the first pass only.
            let reference = match self.references.get(next_ref) {
                Some((rf, r)) if *rf == f && pass == 0 => {
                    next_ref += 1;
                    Some(r)
                }
                _ => None,
            };
            for (run, acc) in runs.iter().zip(acc.iter_mut()) {
                let (_, renderer, _) = renderers
                    .iter_mut()
                    .find(|(m, _, _)| *m == run.method)
                    .expect("a renderer per method was made above");
                renderer.set_method(run.method, protocol_params(run.steps))?;
                renderer.set_scene(config.frame_scene(f))?;
                let times = if run.forward {
                    renderer.render_forward()?
                } else {
                    renderer.render()?
                };
                acc.add_times(&times, pass, run.forward);
                if let Some(reference) = reference {
                    let img = self.measure(renderer, run, f, reference, acc, &mut deferred_hits)?;
                    images.extend(img);
                }
                tracker.advance(
                    run.steps.map_or(NO_STEPS_WEIGHT, u64::from),
                    format!(
                        "{} {}{} {} (frame {}/{}, pass {}/{})",
                        self.name,
                        run.method,
                        if run.forward { " forward" } else { "" },
                        run.steps.map_or("-".to_owned(), |s| s.to_string()),
                        f + 1,
                        config.frames,
                        pass + 1,
                        config.repeat
                    ),
                );
            }
        }
        let rows = runs
            .iter()
            .zip(&acc)
            .map(|(run, acc)| {
                let builds = renderers
                    .iter()
                    .find(|(m, _, _)| *m == run.method)
                    .map_or_else(Builds::default, |r| r.2);
                self.row(run, acc, builds)
            })
            .collect();
        let medians = acc.iter().map(RunAccumulator::pass_medians).collect();
        Ok((rows, medians, images))
    }

    /// Measures the last frame of `renderer` against `reference` into `acc`; returns the
    /// heat and interval maps when the run wants them and `f` is frame 0. A deferred
    /// run's hits are kept in `deferred` when a forward run of its method and setting
    /// follows; a forward run's are compared with them.
    fn measure(
        &self,
        renderer: &Renderer,
        run: &RunSpec,
        f: u32,
        reference: &FrameReference,
        acc: &mut RunAccumulator,
        deferred: &mut std::collections::HashMap<(Method, Option<u32>), Vec<metrics::HitTexel>>,
    ) -> Result<Vec<NamedImage>> {
        let frame = self.config.frame;
        let Compared {
            error: e,
            hits,
            color: _,
        } = renderer.compare_last(reference)?;
        let key = (run.method, run.steps);
        if run.forward {
            let bits = |t: &metrics::HitTexel| t.map(f32::to_bits);
            let differing = match deferred.get(&key) {
                Some(d) if d.len() == hits.len() => hits
                    .iter()
                    .zip(d)
                    .filter(|(a, b)| bits(a) != bits(b))
                    .count(),
                _ => hits.len(),
            };
            acc.forward_differing.push(differing as u64);
        } else if self.config.forward_methods().contains(&run.method) {
            deferred.insert(key, hits.clone());
        }
        let covered = heatmap::coverage(&hits, Some(&reference.rays));
        acc.lockstep.push([
            lockstep_iterations(&hits, &covered, frame[0], [8, 1]),
            lockstep_iterations(&hits, &covered, frame[0], [8, 4]),
            lockstep_iterations(&hits, &covered, frame[0], [4, 2]),
        ]);
        let corners = if run.method.needs().dig_corners {
            renderer.read_corners()?
        } else {
            None
        };
        if let Some((_, c)) = &corners {
            let stats = heatmap::corner_stats(c);
            acc.corner_iterations.push(if e.compared_pixels == 0 {
                0.0
            } else {
                stats.total / e.compared_pixels as f64
            });
        }
        acc.errors.push(e);
        if run.heat && f == 0 {
            self.images(renderer, run.method, &hits, &reference.rays, corners)
        } else {
            Ok(Vec::new())
        }
    }

    fn row(&self, run: &RunSpec, acc: &RunAccumulator, builds: Builds) -> RunRow {
        let config = self.config;
        let (method_ms, method_median_ms, method_lo_ms, method_hi_ms) = acc.method_stats();
        let medians = acc.pass_medians();
        let range = |v: &[f64]| {
            (
                min_of(v.iter().copied()),
                v.iter().copied().fold(0.0, f64::max),
            )
        };
        let (method_median_lo_ms, method_median_hi_ms) = range(&medians.method);
        let (total_median_lo_ms, total_median_hi_ms) = range(&medians.total);
        let totals: Vec<f64> = acc.total_ms.iter().map(|&(_, ms)| ms).collect();
        RunRow {
            sweep: if run.forward {
                Sweep::Forward
            } else {
                self.sweep
            },
            map: self.name.clone(),
            map_width: self.field.width(),
            map_height: self.field.height(),
            method: run.method.name().to_owned(),
            steps: run.steps,
            frame_width: config.frame[0],
            frame_height: config.frame[1],
            frames: config.frames,
            repeat: config.repeat,
            error_frames: acc.errors.len() as u32,
            frame_set: config.frame_set(),
            gbuffer_ms: acc.min_of(PassName::GBuffer).unwrap_or(0.0),
            pyramid_build_ms: run.method.needs().pyramid.and(builds.pyramid),
            cpu_pyramid_build_ms: match (self.sweep, run.method.needs().pyramid) {
                (Sweep::MapSize, Some(kind)) => Some(cpu_pyramid_ms(self.field, config, kind)),
                _ => None,
            },
            cone_build_ms: if run.method.needs().cone.is_some() {
                builds.cone
            } else {
                None
            },
            dig_corners_ms: acc.min_of(PassName::DigCorners),
            trace_ms: acc.min_of(PassName::Trace).unwrap_or(0.0),
            shade_ms: acc.min_of(PassName::Shade).unwrap_or(0.0),
            shadow_ms: acc.min_of(PassName::Shadow),
            method_ms,
            method_median_ms,
            method_lo_ms,
            method_hi_ms,
            total_ms: min_of(totals.iter().copied()),
            total_median_ms: dispmap::timing::median(&totals),
            method_median_lo_ms,
            method_median_hi_ms,
            total_median_lo_ms,
            total_median_hi_ms,
            iterations_mean: acc.mean(|e| e.mean_iterations),
            iterations_p99: acc.mean(|e| e.p99_iterations),
            iterations_simd8: mean_of(acc.lockstep.iter().map(|l| l[0])),
            iterations_warp32: mean_of(acc.lockstep.iter().map(|l| l[1])),
            iterations_quads8: mean_of(acc.lockstep.iter().map(|l| l[2])),
            corner_iterations: (!acc.corner_iterations.is_empty())
                .then(|| mean_of(acc.corner_iterations.iter().copied())),
            mean_texels: acc.mean(|e| e.mean_texels),
            p99_texels: acc.mean(|e| e.p99_texels),
            max_texels: acc.errors.iter().map(|e| e.max_texels).fold(0.0, f64::max),
            artifact_fraction: acc.mean(|e| e.artifact_fraction),
            psnr_db: acc.mean(|e| e.psnr_db),
            nonfinite_pixels: acc.errors.iter().map(|e| e.nonfinite_pixels).sum(),
            forward_differing_pixels: run.forward.then(|| acc.forward_differing.iter().sum()),
        }
    }

    /// The heat map of `hits` (fixed scale: the largest setting plus the binary search)
    /// and, for `dig`, the interval map of the same frame.
    fn images(
        &self,
        renderer: &Renderer,
        method: Method,
        hits: &[metrics::HitTexel],
        rays: &[Option<crate::reference::Ray>],
        corners: Option<([u32; 2], Vec<dispmap::passes::dig::Corner>)>,
    ) -> Result<Vec<NamedImage>> {
        let config = self.config;
        let [w, h] = config.frame;
        let stem = file_stem(&self.name);
        let scale = (config.heatmap_steps() + REFINE_STEPS) as f32;
        let covered = heatmap::coverage(hits, Some(rays));
        let mut out = vec![NamedImage {
            file_name: format!("heatmap_{stem}_{}.png", method.name()),
            caption: format!(
                "{} on {}: trace iterations per pixel, frame 0 (0 to {scale}, saturating)",
                method.name(),
                self.name
            ),
            width: w,
            height: h,
            rgba: heatmap::iteration_heatmap(hits, &covered, Some(scale))?,
        }];
        if method == Method::Dig
            && let Some((grid, corners)) = corners
        {
            let params = renderer.settings().params;
            let intervals = heatmap::block_intervals(grid, &corners, params.dig_eps())?;
            out.push(NamedImage {
                file_name: format!("intervals_{stem}.png"),
                caption: format!(
                    "dig on {}: depth interval length per block, frame 0 (darker = longer; \
                     red = no interval)",
                    self.name
                ),
                width: w,
                height: h,
                rgba: heatmap::interval_map(
                    &intervals,
                    heatmap::block_count(grid),
                    params.block,
                    [w, h],
                )?,
            });
        }
        Ok(out)
    }
}

/// The mean of `values` (0 for none).
fn mean_of(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// The lockstep cost of a hit buffer: pixels are grouped in aligned `group[0] x
/// group[1]` tiles of a frame `width` pixels wide (row by row), and each tile with a
/// covered pixel costs the largest iteration count among its covered pixels (a SIMD
/// group runs until its slowest lane is done). Returns the mean cost per such tile (0
/// if none). Non-finite counts are skipped.
pub fn lockstep_iterations(
    hits: &[metrics::HitTexel],
    covered: &[bool],
    width: u32,
    group: [u32; 2],
) -> f64 {
    let w = width.max(1) as usize;
    let [gx, gy] = group.map(|g| g.max(1) as usize);
    let tiles_x = w.div_ceil(gx);
    let mut max: std::collections::HashMap<usize, f32> = std::collections::HashMap::new();
    for (i, (t, &c)) in hits.iter().zip(covered).enumerate() {
        if !c || !t[3].is_finite() {
            continue;
        }
        let (x, y) = (i % w, i / w);
        let tile = (y / gy) * tiles_x + x / gx;
        let m = max.entry(tile).or_insert(0.0);
        *m = m.max(t[3]);
    }
    mean_of(max.values().map(|&m| f64::from(m)))
}

/// The benchmark's files (results.csv, the Pareto and map-size plots, heat maps,
/// report.md), encoded and checked for the folder `dir`, to be written together by
/// [`crate::output::Outputs::commit`] (which creates `dir`).
pub fn stage_outputs(dir: &Path, results: &BenchResults, command: &str) -> Result<Outputs> {
    let mut out = Outputs::new();
    out.stage_in(dir, "results.csv", report::csv_bytes(&results.rows)?)?;
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
    fn error_frames_are_spread_and_start_at_zero() {
        assert_eq!(error_frames(8, 8), (0..8).collect::<Vec<_>>());
        assert_eq!(error_frames(8, 2), [0, 4]);
        assert_eq!(error_frames(8, 3), [0, 2, 5]);
        assert_eq!(error_frames(1, 5), [0]);
        assert_eq!(error_frames(5, 0), [0]);
        assert_eq!(azimuth_deg(0, 8), 22.5);
        assert_eq!(azimuth_deg(7, 8), 337.5);
    }

    #[test]
    fn the_protocol_scene_spans_40_to_half_a_degree() {
        let s = protocol_scene();
        let bottom = s.camera.elevation_deg + s.camera.fov_y_deg / 2.0;
        let top = s.camera.elevation_deg - s.camera.fov_y_deg / 2.0;
        assert_eq!((bottom, top), (40.0, 0.5));
        assert!(s.validate().is_ok());
    }

    #[test]
    fn lists_parse_and_bad_items_name_the_option() {
        assert_eq!(parse_steps("75, 100,125,150").unwrap(), [75, 100, 125, 150]);
        assert_eq!(
            parse_methods("pom,dig").unwrap(),
            [Method::Pom, Method::Dig]
        );
        assert_eq!(parse_methods("all").unwrap(), Method::ALL);
        // The default lists leave cone-exact out; it stays available by name.
        assert_eq!(parse_methods("default").unwrap(), Method::defaults());
        assert!(!BenchConfig::default().methods.contains(&Method::ConeExact));
        assert!(!SIZE_METHODS.contains(&Method::ConeExact));
        assert_eq!(parse_methods("cone-exact").unwrap(), [Method::ConeExact]);
        assert_eq!(parse_sizes("256,2048").unwrap(), [256, 2048]);
        assert!(parse_sizes("none").unwrap().is_empty());
        assert_eq!(parse_maps("rocks").unwrap(), ["rocks"]);
        for (result, option, needle) in [
            (parse_steps("").map(|_| ()), "--steps", "empty"),
            (parse_steps("0").map(|_| ()), "--steps", "'0'"),
            (parse_steps("10,,20").map(|_| ()), "--steps", "empty"),
            (parse_steps("x").map(|_| ()), "--steps", "'x'"),
            (parse_methods("pom,magic").map(|_| ()), "--methods", "magic"),
            (parse_sizes("1").map(|_| ()), "--sizes", "'1'"),
            (parse_sizes("256,abc").map(|_| ()), "--sizes", "abc"),
            (parse_maps("moon").map(|_| ()), "--maps", "moon"),
        ] {
            let err = result.unwrap_err().to_string();
            assert!(err.contains(option) && err.contains(needle), "{err}");
        }
    }

    #[test]
    fn config_validation_names_options_and_orders_lists() {
        let mut c = BenchConfig {
            steps: vec![150, 75, 75],
            methods: vec![Method::Pom, Method::Bump, Method::Pom],
            sizes: vec![512, 256],
            ..BenchConfig::default()
        };
        c.validate().unwrap();
        assert_eq!(c.steps, [75, 150]);
        assert_eq!(c.methods, [Method::Bump, Method::Pom]);
        assert_eq!(c.sizes, [256, 512]);
        type Spoil = fn(&mut BenchConfig);
        let cases: [(&str, Spoil); 7] = [
            ("--steps", |c| c.steps.clear()),
            ("--steps", |c| c.steps = vec![0]),
            ("--methods", |c| c.methods.clear()),
            ("--frames", |c| c.frames = 0),
            ("--error-frames", |c| c.error_frames = Some(99)),
            ("--sizes", |c| c.sizes = vec![1]),
            ("--size", |c| c.frame = [0, 10]),
        ];
        for (option, spoil) in cases {
            let mut c = BenchConfig::default();
            spoil(&mut c);
            let err = c.validate().unwrap_err().to_string();
            assert!(err.contains(option), "{option}: {err}");
        }
    }

    #[test]
    fn lockstep_cost_is_the_group_maximum() {
        let t = |n: f32| [0.0, 0.0, 0.5, n];
        // A 4x2 frame: groups of 2x1 -> (1, 5), (2, 2), (7, -), (3, 4 uncovered).
        let hits = [
            t(1.0),
            t(5.0),
            t(2.0),
            t(2.0),
            t(7.0),
            t(0.0),
            t(3.0),
            t(9.0),
        ];
        let covered = [true, true, true, true, true, false, true, false];
        let cost = lockstep_iterations(&hits, &covered, 4, [2, 1]);
        assert_eq!(cost, (5.0 + 2.0 + 7.0 + 3.0) / 4.0);
        // One 4x2 group: the largest covered count.
        assert_eq!(lockstep_iterations(&hits, &covered, 4, [4, 2]), 7.0);
        assert_eq!(lockstep_iterations(&hits, &[false; 8], 4, [2, 1]), 0.0);
    }

    #[test]
    fn settings_and_weights() {
        let c = BenchConfig {
            steps: vec![10, 20],
            frames: 2,
            ..BenchConfig::default()
        };
        assert_eq!(c.settings_of(Method::Bump), [None]);
        assert_eq!(c.settings_of(Method::Dig), [Some(10), Some(20)]);
        assert_eq!(run_weight(Some(10), 2), 20);
        assert_eq!(run_weight(None, 2), 2 * NO_STEPS_WEIGHT);
        assert!(c.frame_set().contains("error frames 0 1"));
        assert!(!c.frame_set().contains(','));
    }

    #[test]
    fn resampling_keeps_the_precision_and_the_range() {
        let rocks = crate::bundled::rocks().unwrap();
        let small = resample(&rocks, 64, 32, "rocks@64").unwrap();
        assert_eq!((small.width(), small.height()), (64, 32));
        assert_eq!(small.format(), rocks.format());
        assert!((small.mean() - rocks.mean()).abs() < 0.02);
        let f = HeightField::from_fn(8, 8, "f", |u, _| u).unwrap();
        let big = resample(&f, 16, 16, "f@16").unwrap();
        assert_eq!(big.format(), f.format());
        let (lo, hi) = (0..16).fold((1.0f32, 0.0f32), |(lo, hi), i| {
            let v = big.texel(i, 3);
            (lo.min(v), hi.max(v))
        });
        assert!(lo >= 0.0 && hi <= 1.0 && hi > lo);
        assert_eq!(file_stem("rocks@256 x/y"), "rocks_256_x_y");
    }
}
