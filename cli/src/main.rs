//! The `dispmap` command line: `info`, `render`, and (with no arguments) the default job.

use anyhow::{Context as _, Result, bail};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{MaxLevel, Method, MethodParams};
use dispmap::passes::shadow::{DEFAULT_SHADOW_SAMPLES, ShadowMode, ShadowSettings};
use dispmap::renderer::{RenderSettings, Renderer, SceneAssets};
use dispmap::scene::{Camera, Geometry, Light, Scene};
use dispmap_cli::heatmap::{self, CornerStats, IterationStats};
use dispmap_cli::measure::Measure as _;
use dispmap_cli::metrics::ErrorMetrics;
use dispmap_cli::reference::Reference;
use dispmap_cli::{bench, bundled, memory, output};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// `println!` of this binary: a line to standard output that records a failed write
/// instead of panicking ([`console`]).
macro_rules! println {
    () => {
        $crate::console::line($crate::console::Stream::Out, format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::console::line($crate::console::Stream::Out, format_args!($($arg)*))
    };
}

/// `eprintln!` of this binary: a line to standard error that records a failed write
/// instead of panicking ([`console`]).
macro_rules! eprintln {
    () => {
        $crate::console::line($crate::console::Stream::Err, format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::console::line($crate::console::Stream::Err, format_args!($($arg)*))
    };
}

mod console;
mod render_objects;
mod view;

#[derive(Parser, Debug)]
#[command(
    name = "dispmap",
    version,
    about = "Per-pixel displacement mapping with Vulkan compute, measured speed against error",
    long_about = "Per-pixel displacement mapping with Vulkan compute shaders. With no \
                  subcommand, renders the bundled rocks map with every method, writes the \
                  images to ./dispmap-out and prints each method's GPU time and error \
                  against the exact CPU reference.\n\nEnvironment: DISPMAP_VALIDATION=1 \
                  enables the Khronos validation layer; DISPMAP_DEVICE selects the device \
                  (index or name substring); RUST_LOG sets the log level."
)]
struct Cli {
    /// Vulkan device: index in enumeration order or a substring of its name
    /// (default: DISPMAP_DEVICE, else the best GPU, else lavapipe).
    #[arg(long, global = true)]
    device: Option<String>,
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Print the chosen device, driver, API version and timestamp facts.
    Info,
    /// Render one height map with one method; optionally measure it against the reference.
    Render(RenderArgs),
    /// The default job: every method on the bundled map (what `dispmap` alone runs).
    Demo(DemoArgs),
    /// The speed-versus-error benchmark: every method on the rocks, bricks and mountains
    /// maps at each quality setting over a turning camera, timed with GPU timestamps and
    /// measured against the exact reference; writes results.csv, report.md, Pareto plots,
    /// heat maps and a map-size sweep into --out.
    Bench(BenchArgs),
    /// An interactive window on the renderer: every method in motion, split view, live
    /// GPU times, the error overlay on demand; `--frames N` runs a scripted, headless
    /// sequence and exits (see docs/viewer.md).
    View(view::ViewArgs),
}

#[derive(Args, Debug)]
struct BenchArgs {
    /// Output folder (created if missing); every file is written atomically.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// Frames per run: the camera turns about the vertical axis by 360/K degrees per
    /// frame.
    #[arg(long, default_value_t = bench::DEFAULT_FRAMES, value_name = "K")]
    frames: u32,
    /// Interleaved passes over the frames: times are the minimum over every frame of
    /// every pass, with the range of the per-pass minima as their spread.
    #[arg(long, default_value_t = bench::DEFAULT_REPEAT, value_name = "R")]
    repeat: u32,
    /// How many of the frames (spread evenly, frame 0 first) are measured against the
    /// exact reference [default: all of them].
    #[arg(long, value_name = "N")]
    error_frames: Option<u32>,
    /// Quality settings: linear steps over the full depth, the same for every method that
    /// has a step count (DIG: eps1 = eps2 = 1/steps).
    #[arg(
        long,
        default_value = "10,15,20,25,35,50,75,100,125,150",
        value_name = "LIST"
    )]
    steps: String,
    /// Methods, comma-separated, `all`, or `default` (every method but cone-exact, which
    /// is slower than exact on every bundled map: docs/cones.md): bump, linear, relief,
    /// pom, secant, dig, dig-guarded, pyramid, exact, cone, cone-exact, relaxed-cone.
    #[arg(long, default_value = "default", value_name = "LIST")]
    methods: String,
    /// Bundled maps (rocks, bricks, mountains), comma-separated, or `none`.
    #[arg(long, default_value = "rocks,bricks,mountains", value_name = "LIST")]
    maps: String,
    /// Add this height map (PNG 8/16-bit, JPEG, OpenEXR) to the maps; needs --convention.
    #[arg(long, requires = "convention", value_name = "FILE")]
    heightmap: Option<PathBuf>,
    /// How --heightmap encodes heights: `height` (white = high) or `depth` (white = low).
    #[arg(long, requires = "heightmap")]
    convention: Option<Convention>,
    /// Frame size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x360", value_parser = parse_size)]
    size: (u32, u32),
    /// Map-size sweep: map sides (the map is resampled to each), comma-separated, or
    /// `none`; pyramid, exact, dig and pom are timed at --size-steps.
    #[arg(long, default_value = "256,512,1024,2048", value_name = "LIST")]
    sizes: String,
    /// The setting of the map-size sweep.
    #[arg(long, default_value_t = bench::DEFAULT_SIZE_STEPS, value_name = "N")]
    size_steps: u32,
    /// The bundled map the map-size sweep resamples.
    #[arg(long, default_value = "rocks", value_name = "NAME")]
    size_map: String,
    /// Self-shadowing of every run: `off`, `hard` or `soft` (see `render --shadows`);
    /// when on, the `shadow` pass's time goes into results.csv (`shadow_ms`) and the report.
    #[arg(long, default_value = "off", value_name = "MODE")]
    shadows: ShadowMode,
    /// Refuse a run whose estimated memory (the largest map or sweep size with the
    /// frame, the reference and the heat maps) is above this (e.g. 8G) [default: the
    /// memory available].
    #[arg(long, value_name = "BYTES", value_parser = memory::parse_bytes)]
    max_memory: Option<u64>,
    /// The material-table numbers (several materials in one frame, a tenth of the
    /// frame displaced): `on` or `off`.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    materials: String,
    /// The forward path: every relief and pom run again with the march in the G-buffer
    /// pass (what engines do), its whole frame beside the deferred frame: `on` or `off`.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    forward: String,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args, Debug)]
struct RenderArgs {
    /// A scene file (TOML: height map, material, geometry, camera, light, method, frame
    /// size; see docs/scenes.md). Flags given on the command line override its values.
    #[arg(long, value_name = "FILE")]
    scene: Option<PathBuf>,
    /// Height map (PNG 8/16-bit, JPEG, OpenEXR); needed unless --scene.
    #[arg(long, required_unless_present = "scene", requires = "convention")]
    heightmap: Option<PathBuf>,
    /// How the file encodes heights: `height` (white = high) or `depth` (white = low).
    #[arg(long, requires = "heightmap")]
    convention: Option<Convention>,
    /// Intersection method: bump, linear, relief, pom, secant, dig, dig-guarded, pyramid,
    /// exact, cone, cone-exact, relaxed-cone.
    #[arg(long, default_value = "relief")]
    method: Method,
    #[command(flatten)]
    common: CommonArgs,
    /// Output PNG (`-`: standard output); may be left out when --metrics is given.
    #[arg(long, required_unless_present = "metrics")]
    out: Option<PathBuf>,
    /// Also compute the exact reference and write the metrics JSON here.
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// Also write the per-pixel iteration count of the trace pass as a colour-mapped PNG
    /// (viridis-like: dark purple = few, yellow = many; black = no geometry; white = a
    /// non-finite count). Scaled to the frame's largest count unless --heatmap-max.
    #[arg(long, value_name = "FILE")]
    heatmap: Option<PathBuf>,
    /// Fixed iteration count at the top of the --heatmap ramp (counts above saturate), so
    /// heat maps of different methods compare by colour.
    #[arg(long, requires = "heatmap", value_name = "N")]
    heatmap_max: Option<f32>,
    /// dig, dig-guarded: also write the depth interval length of each block as a grey PNG
    /// at the frame size (nearest neighbour; darker = longer interval, black = the full
    /// depth; red = no interval: the block's corners are not all on one surface and the
    /// trace falls back to the unconstrained search).
    #[arg(long, value_name = "FILE")]
    interval_map: Option<PathBuf>,
    /// Also write the corrected depth (the reverse-Z clip depth of each pixel's displaced
    /// hit point; 0 where there is none) of the last frame: `.exr` as 32-bit float (the
    /// value in R, G and B) or `.png` as 16-bit grey (depth * 65535, rounded).
    #[arg(long, value_name = "FILE")]
    depth_out: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct DemoArgs {
    /// Folder for the images (created if missing).
    #[arg(long, default_value = "dispmap-out")]
    out_dir: PathBuf,
    #[command(flatten)]
    common: CommonArgs,
}

#[derive(Args, Debug)]
struct CommonArgs {
    /// The quality: linear steps over the full depth (linear, relief, dig's `iter`),
    /// pom's n_max, secant's samples per segment. Default: 15 for secant, 64 otherwise.
    #[arg(long, allow_negative_numbers = true)]
    steps: Option<u32>,
    /// pom: n_min, the sample count at a head-on view; at most --steps (n_max)
    /// [default: 8, or --steps when that is lower].
    #[arg(long, allow_negative_numbers = true)]
    min_steps: Option<u32>,
    /// Binary-search steps after the linear march (relief, dig).
    #[arg(long, default_value_t = 5, allow_negative_numbers = true)]
    refine_steps: u32,
    /// secant: split the ray into this many segments (the paper's multi-pass variant).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    segments: u32,
    /// dig: block size in pixels, N or WxH.
    #[arg(long, default_value = "4x4", value_parser = parse_block)]
    block: (u32, u32),
    /// dig: interval widening eps1 = eps2 (default 1/steps).
    #[arg(long, allow_negative_numbers = true)]
    eps: Option<f32>,
    /// pyramid: coarsest traversal level (0 = full detail) or `auto` (from the pixel's
    /// texel footprint).
    #[arg(long, default_value = "0", allow_negative_numbers = true)]
    max_level: MaxLevel,
    /// Level of detail, every method (off by default): pixels whose texel footprint is at
    /// least 2^L texels take the bump result without tracing; between 2^(L-1) and 2^L
    /// the traced hit is blended toward it.
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    lod_threshold: Option<f32>,
    /// Displacement depth in tile units.
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    depth_scale: f32,
    /// Frame size, WIDTHxHEIGHT.
    #[arg(long, default_value = "256x144", value_parser = parse_size)]
    size: (u32, u32),
    /// Angle in degrees between the central view ray and the plane (90 = straight down).
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    camera_elevation: f32,
    /// Camera rotation about the vertical axis, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    camera_azimuth: f32,
    /// Eye height above the plane in tiles (tiled plane only).
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    camera_height: f32,
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    fov: f32,
    /// Macro geometry: `plane` (tiled, repeat addressing), `quad` (one decal, clamp),
    /// `cube` (six decals), `sphere` or `torus` (tiled); a loaded `mesh` needs --scene.
    #[arg(long, default_value = "plane")]
    geometry: Geometry,
    /// Frames to render; timings are medians over them.
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    frames: u32,
    /// Refuse a run whose estimated memory (from the map and frame size, before
    /// anything large is allocated) is above this (e.g. 8G, 512M) [default: the memory
    /// available].
    #[arg(long, value_name = "BYTES", value_parser = memory::parse_bytes, allow_negative_numbers = true)]
    max_memory: Option<u64>,
    /// Self-shadowing (Tatarchuk 2006, 3.2): `off`, `hard` (first occluder along the
    /// light ray: exact for exact, dig-guarded and pyramid, a linear march with --steps
    /// otherwise) or `soft` (the paper's penumbra estimate); timed as the `shadow` pass.
    #[arg(long, default_value = "off")]
    shadows: ShadowMode,
    /// Soft shadows: height samples along the light ray (the paper's 8).
    #[arg(long, default_value_t = DEFAULT_SHADOW_SAMPLES, value_name = "N", allow_negative_numbers = true)]
    shadow_samples: u32,
}

fn parse_block(s: &str) -> std::result::Result<(u32, u32), String> {
    match s.trim().parse::<u32>() {
        Ok(n) if n > 0 => Ok((n, n)),
        _ => parse_size(s),
    }
}

fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in '{s}'"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in '{s}'"))?;
    if w == 0 || h == 0 {
        return Err(format!("'{s}' has a zero side"));
    }
    Ok((w, h))
}

/// pom's default n_min (`--min-steps`), lowered to `--steps` when that is lower.
const DEFAULT_MIN_STEPS: u32 = 8;

/// [`RenderSettings::validate`], and pom's n_min at most its n_max (`--min-steps` above
/// `--steps` would take more samples head-on than at grazing angles).
fn validate_settings(settings: &RenderSettings) -> Result<()> {
    settings.validate()?;
    let p = &settings.params;
    if settings.method == Method::Pom && p.min_steps > p.steps {
        bail!(
            "invalid --min-steps: {} is above --steps {} (pom's head-on sample count n_min \
             must not exceed n_max)",
            p.min_steps,
            p.steps
        );
    }
    Ok(())
}

impl CommonArgs {
    fn settings(&self, method: Method) -> RenderSettings {
        RenderSettings {
            width: self.size.0,
            height: self.size.1,
            method,
            params: MethodParams {
                steps: self.steps.unwrap_or(method.default_steps()),
                min_steps: self
                    .min_steps
                    .unwrap_or(DEFAULT_MIN_STEPS.min(self.steps.unwrap_or(method.default_steps()))),
                refine_steps: self.refine_steps,
                segments: self.segments,
                block: [self.block.0, self.block.1],
                eps: self.eps,
                max_level: self.max_level,
                lod_threshold: self.lod_threshold,
            },
            scene: Scene {
                geometry: self.geometry,
                depth_scale: self.depth_scale,
                camera: Camera {
                    elevation_deg: self.camera_elevation,
                    azimuth_deg: self.camera_azimuth,
                    fov_y_deg: self.fov,
                    height: self.camera_height,
                    distance: None,
                },
                light: Light::default(),
                addressing: None,
            },
            shadows: ShadowSettings {
                mode: self.shadows,
                samples: self.shadow_samples,
            },
        }
    }

    /// Overrides the values of a scene file's `settings` with the flags given on the
    /// command line (`matches`: the subcommand's); `method` is --method when given.
    fn override_scene(
        &self,
        settings: &mut RenderSettings,
        file: &dispmap_cli::scene_file::SceneFile,
        method: Option<Method>,
        matches: &ArgMatches,
    ) {
        let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
        if let Some(method) = method {
            settings.method = method;
            if file.method.steps.is_none() {
                settings.params.steps = method.default_steps();
            }
        }
        let p = &mut settings.params;
        if let Some(steps) = self.steps {
            p.steps = steps;
        }
        if let Some(min_steps) = self.min_steps {
            p.min_steps = min_steps;
        } else if file.method.min_steps.is_none() {
            // Neither the scene nor the command line set n_min: the default, at most n_max.
            p.min_steps = p.min_steps.min(p.steps);
        }
        if given("refine_steps") {
            p.refine_steps = self.refine_steps;
        }
        if given("segments") {
            p.segments = self.segments;
        }
        if given("block") {
            p.block = [self.block.0, self.block.1];
        }
        if self.eps.is_some() {
            p.eps = self.eps;
        }
        if given("max_level") {
            p.max_level = self.max_level;
        }
        if self.lod_threshold.is_some() {
            p.lod_threshold = self.lod_threshold;
        }
        if given("shadows") {
            settings.shadows.mode = self.shadows;
        }
        if given("shadow_samples") {
            settings.shadows.samples = self.shadow_samples;
        }
        let scene = &mut settings.scene;
        if given("depth_scale") {
            scene.depth_scale = self.depth_scale;
        }
        if given("size") {
            (settings.width, settings.height) = self.size;
        }
        if given("camera_elevation") {
            scene.camera.elevation_deg = self.camera_elevation;
        }
        if given("camera_azimuth") {
            scene.camera.azimuth_deg = self.camera_azimuth;
        }
        if given("camera_height") {
            scene.camera.height = self.camera_height;
        }
        if given("fov") {
            scene.camera.fov_y_deg = self.fov;
        }
        if given("geometry") {
            scene.geometry = self.geometry;
        }
    }

    fn check(&self) -> Result<()> {
        if self.frames == 0 || self.frames > 10_000 {
            bail!("invalid --frames: {} is outside 1..=10000", self.frames);
        }
        Ok(())
    }
}

/// The largest depth scale at which `exact`, `dig-guarded` and `cone-exact` are measured
/// to agree with the reference as the accuracy tests require (at most 0.04% of pixels
/// more than a texel off on the mountains map at 1-60 degrees, docs/guarantees.md); above
/// it a warning is printed.
const EXACT_DEPTH_SCALE: f32 = 10.0;

/// The warning of a measured frame with no compared pixel.
const NO_PIXELS: &str = "no pixel of the frame shows the displaced surface (0 compared \
                         pixels): the error metrics are null, not a perfect score";

/// The metrics JSON of `render --metrics`.
#[derive(Serialize)]
struct MetricsReport<'a> {
    method: &'a str,
    steps: u32,
    refine_steps: u32,
    /// `--lod-threshold` when level of detail is on.
    #[serde(skip_serializing_if = "Option::is_none")]
    lod_threshold: Option<f32>,
    width: u32,
    height: u32,
    frames: u32,
    heightmap: String,
    depth_scale: f32,
    camera_elevation: f32,
    shadows: &'a str,
    device: &'a str,
    driver: &'a str,
    timings_ms: BTreeMap<String, f64>,
    error: ErrorSummary,
    /// Set when the metrics mean nothing (no pixel compared).
    #[serde(skip_serializing_if = "Option::is_none")]
    warning: Option<String>,
    nonfinite_pixels: u64,
    /// The reference traces each pixel's own centre ray on the tiled plane and the quad:
    /// pixels where the G-buffer's coverage and the f64 centre ray disagree
    /// (`Renderer::reference_rays`).
    coverage: CoverageReport,
    iterations: Iterations,
    /// DIG methods only: the corner pass's iterations.
    #[serde(skip_serializing_if = "Option::is_none")]
    corner_pass: Option<CornerPass>,
}

/// Where the G-buffer's coverage and the reference's f64 centre rays disagree.
#[derive(Serialize)]
struct CoverageReport {
    /// Whether the reference traced the f64 centre rays (the tiled plane or the quad
    /// alone) rather than the G-buffer's rays.
    centre_rays: bool,
    /// Pixels drawn whose f64 centre ray misses the surface: not compared.
    drawn_without_ray: usize,
    /// Pixels with an f64 centre ray that the G-buffer left empty: compared (a method
    /// has no ray there: an artifact where the reference hits).
    ray_without_draw: usize,
}

/// The error against the reference; every measure `null` when no pixel was compared
/// (the frame shows no geometry: nothing was measured, which is not a perfect score).
#[derive(Serialize)]
struct ErrorSummary {
    mean_texels: Option<f64>,
    p99_texels: Option<f64>,
    max_texels: Option<f64>,
    artifact_fraction: Option<f64>,
    psnr_db: Option<f64>,
    compared_pixels: u64,
}

/// The trace pass's per-pixel iteration counts over covered pixels (see
/// `dispmap_cli::heatmap::iteration_stats`).
#[derive(Serialize)]
struct Iterations {
    mean: f64,
    p99: f64,
    max: f64,
    /// Sum over covered pixels.
    total: f64,
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
struct CornerPass {
    corners: u64,
    total: f64,
    mean: f64,
    total_with_corners: f64,
}

impl CornerPass {
    fn new(corners: CornerStats, trace: &IterationStats) -> Self {
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

fn main() {
    // A file size limit (`ulimit -f`) makes a write fail with EFBIG instead of killing the
    // process with SIGXFSZ, so the temporary file of an output is removed, not left.
    // SAFETY: setting a signal's disposition to SIG_IGN installs no handler code; it is
    // done before any other thread exists.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    // SIGINT, SIGTERM, SIGHUP during a commit remove its temporary files first.
    output::clean_up_on_signals();
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let matches = Cli::command().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    if let Err(e) = run(cli, &matches) {
        eprintln!("error: {}", error_chain(&e));
        std::process::exit(1);
    }
    // A console that could not be written fails the run, after its outputs were
    // committed.
    if let Some(failure) = console::failure() {
        eprintln!("error: {failure} (the run finished: its outputs, if any, were written)");
        std::process::exit(1);
    }
}

/// The error and its causes, `outer: inner`, skipping a cause whose text the message
/// already ends with (dispmap's errors print their source in their own message).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = e.to_string();
    for cause in e.chain().skip(1) {
        let cause = cause.to_string();
        if !out.ends_with(&cause) {
            out = format!("{out}: {cause}");
        }
    }
    out
}

fn run(cli: Cli, matches: &ArgMatches) -> Result<()> {
    let options = ContextOptions {
        validation: None,
        device: cli.device.clone(),
    };
    match cli.command {
        Some(Command::Info) => info(&options),
        Some(Command::Render(args)) => {
            let sub = matches
                .subcommand_matches("render")
                .context("clap parsed `render` without its matches")?;
            render(&options, &args, sub)
        }
        Some(Command::Demo(args)) => demo(&options, &args),
        Some(Command::Bench(args)) => bench_command(&options, &args),
        Some(Command::View(args)) => {
            let sub = matches
                .subcommand_matches("view")
                .context("clap parsed `view` without its matches")?;
            view::run(&options, args, sub)
        }
        None => {
            let args = DemoArgs::parse_defaults();
            demo(&options, &args)
        }
    }
}

impl DemoArgs {
    fn parse_defaults() -> Self {
        #[derive(Parser)]
        struct Defaults {
            #[command(flatten)]
            demo: DemoArgs,
        }
        Defaults::parse_from(["dispmap"]).demo
    }
}

/// Destroys the context, then fails if validation reported anything up to and including
/// the device's destruction (where the object tracker reports leaked objects).
fn finish(ctx: Arc<Context>) -> Result<()> {
    let m = ctx.messages().clone();
    // The last holder: dropping it destroys the device (every renderer is gone).
    drop(ctx);
    if m.total() > 0 {
        bail!(
            "Vulkan validation reported {} error(s) and {} warning(s) (see the log above)",
            m.errors(),
            m.warnings()
        );
    }
    Ok(())
}

fn info(options: &ContextOptions) -> Result<()> {
    let ctx = Arc::new(Context::headless(options)?);
    let i = ctx.info();
    println!("device:               {}", i.name);
    println!("type:                 {}", i.device_type);
    println!("driver:               {}", i.driver);
    println!("api version:          {}", i.api_version);
    println!("queue family:         {}", i.queue_family_index);
    println!("timestamp period:     {} ns", i.timestamp_period_ns);
    println!("timestamp valid bits: {}", i.timestamp_valid_bits);
    println!("max image 2D:         {}", i.max_image_dimension_2d);
    println!(
        "validation:           {}",
        match (ctx.validation_enabled(), ctx.has_messenger()) {
            (true, true) => "on (Khronos validation layer, messages counted)",
            (true, false) => "on (Khronos validation layer, no debug messenger)",
            (false, _) => "off (DISPMAP_VALIDATION=1 turns it on)",
        }
    );
    finish(ctx)
}

/// The height map, settings and scene assets of `render`: from --scene (its values,
/// overridden by the flags given) or from the flags alone. What the command line
/// overrides is not loaded (--heightmap: the scene's map; --geometry: its mesh); the
/// run's memory is estimated and checked before the map is read (a file's header gives
/// its size).
fn render_inputs(
    args: &RenderArgs,
    matches: &ArgMatches,
) -> Result<(HeightField, String, RenderSettings, SceneAssets)> {
    use dispmap_cli::scene_file::{MapSource, SceneFile};
    let method_given = matches.value_source("method") == Some(ValueSource::CommandLine);
    let given_map = match (&args.heightmap, args.convention) {
        (Some(path), Some(convention)) => Some(MapSource::File {
            path: path.clone(),
            convention,
        }),
        _ => None,
    };
    let (settings, source, scene) = match &args.scene {
        None => {
            let Some(source) = given_map else {
                bail!("--heightmap and --convention are needed without --scene");
            };
            let settings = args.common.settings(args.method);
            validate_settings(&settings)?;
            (settings, source, None)
        }
        Some(scene_path) => {
            let file = SceneFile::read(scene_path)?;
            if file.has_objects() {
                let (field, label, settings, assets, _) =
                    render_objects::inputs(args, matches, &file, scene_path)?;
                return Ok((field, label, settings, assets));
            }
            let mut settings = file.settings(scene_path)?;
            args.common.override_scene(
                &mut settings,
                &file,
                method_given.then_some(args.method),
                matches,
            );
            validate_settings(&settings)?;
            let source = given_map.unwrap_or_else(|| file.heightmap_source(scene_path));
            (settings, source, Some((file, scene_path)))
        }
    };
    // The map's header, then a scene's mesh (not loaded when --geometry overrides it):
    // both measured before either is read, counted in the estimate.
    let header = match &source {
        MapSource::File { path, .. } => Some(HeightField::probe(path)?),
        MapSource::Bundled { .. } => None,
    };
    let mesh_path = match &scene {
        Some((file, path)) if settings.scene.geometry == Geometry::Mesh => file
            .mesh
            .as_ref()
            .map(|m| path.parent().unwrap_or(Path::new(".")).join(m)),
        _ => None,
    };
    let mesh = match &mesh_path {
        Some(m) => dispmap_cli::mesh_file::measure(m)?,
        None => memory::MeshSize::default(),
    };
    let check_memory = |map: memory::MapSize, mesh: memory::MeshSize| {
        let frame = [settings.width, settings.height];
        let what = format!(
            "rendering {}x{} on the {}x{} map {}{}{}",
            frame[0],
            frame[1],
            map.size[0],
            map.size[1],
            source.label(),
            match &mesh_path {
                Some(m) => format!(
                    " with the mesh {} ({} vertices, {} triangles)",
                    m.display(),
                    mesh.vertices,
                    mesh.triangles
                ),
                None => String::new(),
            },
            if args.metrics.is_some() {
                " with the reference (--metrics)"
            } else {
                ""
            }
        );
        let extras = memory::Extras {
            reference: args.metrics.is_some(),
            heatmap: args.heatmap.is_some() || args.interval_map.is_some(),
            depth: args.depth_out.is_some(),
            maps: memory::MethodMaps::of(
                settings.method,
                settings.shadows.mode == ShadowMode::Hard,
            ),
            mesh,
        };
        let estimate = memory::estimate(map, frame, extras);
        memory::check(&estimate, args.common.max_memory, &what)
    };
    if let Some(header) = &header {
        check_memory(memory::MapSize::from_header(header), mesh)?;
    }
    let field = source.load()?;
    if let Some(part) = field.part() {
        eprintln!(
            "note: {} has several parts: the height is read from {part} (the first part \
             with a Y channel, else with R, G and B, else with R; docs/scenes.md)",
            source.label()
        );
    }
    if let MapSource::Bundled { .. } = &source {
        check_memory(memory::MapSize::loaded(&field), mesh)?;
    }
    let assets = match scene {
        Some((file, path)) => file.assets(path, settings.scene.geometry == Geometry::Mesh)?,
        None => SceneAssets::default(),
    };
    // The mesh as parsed (an OBJ's vertex count was an estimate): its memory while
    // rendering, before anything is uploaded.
    if let Some(m) = &assets.mesh {
        let parsed = memory::MeshSize {
            file_bytes: 0,
            vertices: m.vertices.len() as u64,
            triangles: m.indices.len() as u64 / 3,
        };
        check_memory(memory::MapSize::loaded(&field), parsed)?;
    }
    Ok((field, source.label(), settings, assets))
}

fn render(options: &ContextOptions, args: &RenderArgs, matches: &ArgMatches) -> Result<()> {
    args.common.check()?;
    // Every output is checked before any work (before the inputs are read), its bytes
    // kept until all are made, and all are written together at the end (nothing is
    // written if any fails).
    let mut outputs = output::Outputs::new();
    let checks = [
        ("--out", args.out.as_ref(), output::Format::Png),
        ("--metrics", args.metrics.as_ref(), output::Format::Json),
        ("--heatmap", args.heatmap.as_ref(), output::Format::Png),
        (
            "--interval-map",
            args.interval_map.as_ref(),
            output::Format::Png,
        ),
        (
            "--depth-out",
            args.depth_out.as_ref(),
            output::Format::Depth,
        ),
    ];
    for (option, path, format) in checks {
        if let Some(path) = path {
            outputs
                .check(option, path, format)
                .with_context(|| format!("invalid {option}"))?;
        }
    }
    if let Some(path) = &args.scene {
        let file = dispmap_cli::scene_file::SceneFile::read(path)?;
        if file.has_objects() {
            return render_objects::render(options, args, matches, outputs, &file, path);
        }
    }
    let (field, heightmap_label, settings, assets) = render_inputs(args, matches)?;
    if matches!(
        settings.method,
        Method::Exact | Method::DigGuarded | Method::ConeExact | Method::Pyramid
    ) && settings.scene.depth_scale > EXACT_DEPTH_SCALE
    {
        eprintln!(
            "warning: --depth-scale {} is above {EXACT_DEPTH_SCALE}: {}'s agreement with the \
             exact reference is not guaranteed there (rays near the horizon whose hits lie \
             thousands of tiles away, beyond the f32 hit buffer's texel precision, or that \
             reach the traversal's step cap; measured on the mountains map, 1-60 degrees: \
             up to 0.55% of pixels more than a texel off at 30, 0.13% at 100, 0.97% at \
             300, 3.7% at 1000; docs/guarantees.md)",
            settings.scene.depth_scale, settings.method
        );
    }
    let dig = settings.method.needs().dig_corners;
    if args.interval_map.is_some() && !dig {
        bail!(
            "invalid --interval-map: method {} has no depth interval grid (only dig and \
             dig-guarded have one)",
            settings.method
        );
    }
    if let Some(max) = args.heatmap_max
        && !(max.is_finite() && max > 0.0)
    {
        bail!("invalid --heatmap-max: {max} is not a positive finite number");
    }
    let ctx = Arc::new(Context::headless(options)?);
    dispmap_cli::frame_limit::check(&ctx, settings.width, settings.height, "--size")?;
    {
        let mut renderer = Renderer::with_assets(&ctx, &field, settings, &assets)?;
        renderer.set_depth_output(args.depth_out.is_some())?;
        let mut coverage = None;
        let (timings, color, error, hits, rays) = if args.metrics.is_some() {
            let reference = Reference::new(&field, settings.scene.addressing());
            let frame_ref = renderer.reference(&reference)?;
            coverage = Some(CoverageReport {
                centre_rays: renderer.reference_rays()?.analytic,
                drawn_without_ray: frame_ref.drawn_only,
                ray_without_draw: frame_ref.ray_only,
            });
            let m = renderer.measure(&frame_ref, args.common.frames)?;
            (m.timings_ms, m.color, Some(m.error), m.hits, frame_ref.rays)
        } else {
            let timings = renderer.render_frames(args.common.frames)?;
            let (hits, rays) = if args.heatmap.is_some() {
                (renderer.read_hits()?, renderer.read_rays()?)
            } else {
                (Vec::new(), Vec::new())
            };
            (timings, renderer.read_color()?, None, hits, rays)
        };
        let covered = heatmap::coverage(&hits, Some(&rays));
        let trace_iterations = heatmap::iteration_stats(&hits, &covered);
        let corners = if dig && (args.metrics.is_some() || args.interval_map.is_some()) {
            renderer.read_corners()?
        } else {
            None
        };
        if let Some(out) = &args.out {
            let png = output::png_bytes(out, settings.width, settings.height, &color)?;
            outputs.stage(out, png)?;
        }
        if let Some(path) = &args.heatmap {
            let rgba = heatmap::iteration_heatmap(&hits, &covered, args.heatmap_max)?;
            let png = output::png_bytes(path, settings.width, settings.height, &rgba)?;
            outputs.stage(path, png)?;
        }
        if let Some(path) = &args.depth_out {
            let depth = renderer
                .read_depth()?
                .context("the renderer kept no corrected depth")?;
            let bytes = output::depth_bytes(path, settings.width, settings.height, &depth)?;
            outputs.stage(path, bytes)?;
        }
        if let Some(path) = &args.interval_map {
            let (grid, corners) = corners
                .as_ref()
                .context("the renderer kept no DIG corner grid")?;
            let intervals = heatmap::block_intervals(*grid, corners, settings.params.dig_eps())?;
            let rgba = heatmap::interval_map(
                &intervals,
                heatmap::block_count(*grid),
                settings.params.block,
                [settings.width, settings.height],
            )?;
            let png = output::png_bytes(path, settings.width, settings.height, &rgba)?;
            outputs.stage(path, png)?;
        }
        if let Some(c) = coverage
            .as_ref()
            .filter(|c| c.drawn_without_ray + c.ray_without_draw > 0)
        {
            eprintln!(
                "note: coverage: {} pixels drawn whose centre ray misses the surface (not \
                 compared), {} centre-ray hits not drawn (compared)",
                c.drawn_without_ray, c.ray_without_draw
            );
        }
        if let (Some(path), Some(error), Some(coverage)) = (&args.metrics, error, coverage) {
            let report = MetricsReport {
                method: settings.method.name(),
                steps: settings.params.steps,
                refine_steps: settings.params.refine_steps,
                lod_threshold: settings.params.lod_threshold,
                width: settings.width,
                height: settings.height,
                frames: args.common.frames,
                heightmap: heightmap_label.clone(),
                depth_scale: settings.scene.depth_scale,
                camera_elevation: settings.scene.camera.elevation_deg,
                shadows: settings.shadows.mode.name(),
                device: &ctx.info().name,
                driver: &ctx.info().driver,
                timings_ms: timings.iter().cloned().collect(),
                error: (&error).into(),
                warning: (error.compared_pixels == 0).then(|| NO_PIXELS.to_owned()),
                nonfinite_pixels: error.nonfinite_pixels,
                coverage,
                iterations: trace_iterations.into(),
                corner_pass: corners
                    .as_ref()
                    .map(|(_, c)| CornerPass::new(heatmap::corner_stats(c), &trace_iterations)),
            };
            let json = serde_json::to_string_pretty(&report)?;
            outputs.stage(path, json.into_bytes())?;
        }
        // With `--out -` (or `--metrics -`) standard output carries the file: the
        // summary goes to standard error instead.
        let to_stdout = [&args.out, &args.metrics]
            .iter()
            .any(|p| p.as_deref() == Some(Path::new("-")));
        let summary = timings_line(&timings);
        let mut lines = vec![summary];
        if let Some(e) = error.as_ref().filter(|e| e.compared_pixels == 0) {
            eprintln!("warning: {NO_PIXELS} (non-finite {})", e.nonfinite_pixels);
        } else if let Some(e) = error {
            lines.push(format!(
                "error: mean {:.3} texels, p99 {:.3}, max {:.3}, artifacts {:.3}%, PSNR {:.2} dB, non-finite {}",
                e.mean_texels,
                e.p99_texels,
                e.max_texels,
                100.0 * e.artifact_fraction,
                e.psnr_db,
                e.nonfinite_pixels
            ));
        }
        for line in lines {
            if to_stdout {
                eprintln!("{line}");
            } else {
                println!("{line}");
            }
        }
    }
    // Validation clean, then every output at once.
    finish(ctx)?;
    outputs.commit()?;
    Ok(())
}

/// The per-pass times as one line.
fn timings_line(timings: &[(String, f64)]) -> String {
    let parts: Vec<String> = timings
        .iter()
        .map(|(name, ms)| format!("{name} {ms:.3} ms"))
        .collect();
    format!("GPU time (median): {}", parts.join(", "))
}

fn demo(options: &ContextOptions, args: &DemoArgs) -> Result<()> {
    args.common.check()?;
    // The default methods ([`Method::in_defaults`]: cone-exact is available by name only).
    let methods = Method::defaults();
    // Every method's settings are checked before anything is printed or created.
    for &method in &methods {
        validate_settings(&args.common.settings(method))?;
    }
    let field = bundled::rocks()?;
    let first = args.common.settings(methods[0]);
    memory::check(
        &memory::estimate(
            memory::MapSize::loaded(&field),
            [first.width, first.height],
            memory::Extras {
                reference: true,
                // One method at a time, the previous one's maps retired: at most all.
                maps: memory::MethodMaps::together(&methods),
                ..memory::Extras::default()
            },
        ),
        args.common.max_memory,
        &format!(
            "rendering {}x{} on the bundled rocks map with the reference",
            first.width, first.height
        ),
    )?;
    // The folder is checked now, created and filled at the end, all files together.
    output::check_folder_writable(&args.out_dir).context("invalid --out-dir")?;
    let mut outputs = output::Outputs::new();
    let ctx = Arc::new(Context::headless(options)?);
    dispmap_cli::frame_limit::check(&ctx, first.width, first.height, "--size")?;
    println!(
        "dispmap: {} on {} ({}), {}x{}, camera elevation {} deg, steps {}, median of {} frames",
        field.label(),
        ctx.info().name,
        ctx.info().driver,
        args.common.size.0,
        args.common.size.1,
        args.common.camera_elevation,
        args.common
            .steps
            .map_or("per method (secant 15, others 64)".into(), |s| s
                .to_string()),
        args.common.frames
    );
    {
        let first = args.common.settings(methods[0]);
        let mut renderer = Renderer::new(&ctx, &field, first)?;
        let reference = Reference::new(&field, first.scene.addressing());
        let frame_ref = renderer.reference(&reference)?;
        let path = args.out_dir.join("reference.png");
        let png = output::png_bytes(&path, first.width, first.height, &frame_ref.color)?;
        outputs.stage_in(&args.out_dir, "reference.png", png)?;
        let mut tiles = vec![dispmap_cli::contact_sheet::Tile {
            label: "reference (CPU, exact)".into(),
            rgba: frame_ref.color.clone(),
        }];
        // The method column as wide as the longest name.
        let w = methods.iter().map(|m| m.name().len()).max().unwrap_or(6);
        println!(
            "\n{:<w$} {:>10} {:>10} {:>10} {:>10} {:>8} {:>10} {:>10} {:>10} {:>9}",
            "method",
            "gbuffer",
            "trace ms",
            "shade ms",
            "total ms",
            "iters",
            "mean tx",
            "p99 tx",
            "artifact%",
            "PSNR dB"
        );
        for &method in &methods {
            let settings = args.common.settings(method);
            renderer.set_method(method, settings.params)?;
            let m = renderer.measure(&frame_ref, args.common.frames)?;
            let t = |name: &str| {
                m.timings_ms
                    .iter()
                    .find(|(n, _)| n == name)
                    .map(|(_, ms)| *ms)
                    .unwrap_or(0.0)
            };
            let e = &m.error;
            println!(
                "{:<w$} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>8.1} {:>10.3} {:>10.3} {:>10.3} {:>9.2}",
                method.name(),
                t("gbuffer"),
                t("trace"),
                t("shade"),
                t("total"),
                e.mean_iterations,
                e.mean_texels,
                e.p99_texels,
                100.0 * e.artifact_fraction,
                e.psnr_db
            );
            if e.nonfinite_pixels > 0 {
                bail!("{method}: {} non-finite hit texels", e.nonfinite_pixels);
            }
            let name = format!("{}.png", method.name());
            let png = output::png_bytes(
                &args.out_dir.join(&name),
                settings.width,
                settings.height,
                &m.color,
            )?;
            outputs.stage_in(&args.out_dir, &name, png)?;
            tiles.push(dispmap_cli::contact_sheet::Tile {
                label: format!(
                    "{}  {:.2}% artifacts",
                    method.name(),
                    100.0 * e.artifact_fraction
                ),
                rgba: m.color,
            });
        }
        let sheet = dispmap_cli::contact_sheet::compose(&tiles, first.width, first.height, 5)?;
        let png = output::png_bytes(
            &args.out_dir.join("contact_sheet.png"),
            sheet.width,
            sheet.height,
            &sheet.rgba,
        )?;
        outputs.stage_in(&args.out_dir, "contact_sheet.png", png)?;
        println!(
            "\nimages: {} (reference.png is the exact reference, shaded; contact_sheet.png \
             shows every method beside it)",
            args.out_dir.display()
        );
    }
    finish(ctx)?;
    outputs.commit()?;
    Ok(())
}

fn bench_command(options: &ContextOptions, args: &BenchArgs) -> Result<()> {
    // Everything that can be wrong with the input fails here, before any GPU work.
    let mut config = bench::BenchConfig {
        frame: [args.size.0, args.size.1],
        frames: args.frames,
        repeat: args.repeat,
        error_frames: args.error_frames,
        steps: bench::parse_steps(&args.steps)?,
        methods: bench::parse_methods(&args.methods)?,
        sizes: bench::parse_sizes(&args.sizes)?,
        size_steps: args.size_steps,
        shadows: args.shadows,
        materials: args.materials == "on",
        forward: args.forward == "on",
        ..bench::BenchConfig::default()
    };
    config.validate()?;
    let mut maps = Vec::new();
    for name in bench::parse_maps(&args.maps)? {
        maps.push(bench::MapSpec::bundled(&name)?);
    }
    if let (Some(path), Some(convention)) = (&args.heightmap, args.convention) {
        maps.push(bench::MapSpec::load(path, convention)?);
    }
    let size_source = if config.sizes.is_empty() {
        None
    } else {
        Some(bench::MapSpec {
            name: args.size_map.clone(),
            field: bundled::by_name(&args.size_map, "--size-map")?,
        })
    };
    if maps.is_empty() && size_source.is_none() {
        bail!("invalid --maps: no map to benchmark (give --maps or --heightmap)");
    }
    // The largest map (or sweep size) with the frame, the reference and the heat maps.
    // One renderer per method is alive at once (runs interleaved frame by frame).
    let extras = memory::Extras {
        reference: true,
        heatmap: true,
        depth: false,
        maps: memory::MethodMaps::together(&config.methods),
        mesh: memory::MeshSize::default(),
    };
    let sweep_extras = memory::Extras {
        maps: memory::MethodMaps::together(&config.size_methods),
        ..extras
    };
    let mut candidates: Vec<(memory::MapSize, String, memory::Extras)> = maps
        .iter()
        .map(|m| (memory::MapSize::loaded(&m.field), m.name.clone(), extras))
        .collect();
    if let Some(source) = &size_source {
        let bytes = memory::MapSize::loaded(&source.field).texel_bytes;
        for &side in &config.sizes {
            let map = memory::MapSize {
                size: [side, side],
                texel_bytes: bytes,
                load_bytes: 0,
            };
            candidates.push((
                map,
                format!("{} resampled to {side}x{side}", source.name),
                sweep_extras,
            ));
        }
    }
    if let Some((estimate, name)) = candidates
        .into_iter()
        .map(|(map, name, extras)| (memory::estimate(map, config.frame, extras), name))
        .max_by_key(|(e, _)| e.bytes)
    {
        let what = format!(
            "benchmarking {}x{} frames on {name} with the reference",
            config.frame[0], config.frame[1]
        );
        memory::check(&estimate, args.max_memory, &what)?;
    }
    // The folder is created and filled only when every result is in (all files at once).
    output::check_folder_writable(&args.out).context("invalid --out")?;

    let ctx = Arc::new(Context::headless(options)?);
    dispmap_cli::frame_limit::check(&ctx, config.frame[0], config.frame[1], "--size")?;
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        let bar = indicatif::ProgressBar::with_draw_target(
            Some(1),
            indicatif::ProgressDrawTarget::stderr(),
        );
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "[{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta:>4} {msg}",
            )
            .expect("the template is valid")
            .progress_chars("=> "),
        );
        bar
    };
    eprintln!(
        "dispmap bench: {} map(s), {} method(s), steps {}, {}x{}, {} frames, on {} ({})",
        maps.len(),
        config.methods.len(),
        args.steps,
        config.frame[0],
        config.frame[1],
        config.frames,
        ctx.info().name,
        ctx.info().driver
    );
    let results = bench::run(&ctx, &config, &maps, size_source.as_ref(), &mut |p| {
        bar.set_length(p.total);
        bar.set_position(p.done);
        bar.set_message(p.stage.clone());
    });
    bar.finish_and_clear();
    let results = results?;
    let command = command_line();
    let outputs = bench::stage_outputs(&args.out, &results, &command)?;
    let written = outputs.paths();
    print_bench_summary(&results);
    println!(
        "\nwrote {} files to {} in {:.0} s (report.md, results.csv, plots, heat maps)",
        written.len(),
        args.out.display(),
        results.wall.as_secs_f64()
    );
    finish(ctx)?;
    outputs.commit()?;
    Ok(())
}

/// The command line as typed (arguments with spaces or quotes are single-quoted).
fn command_line() -> String {
    let mut parts = vec!["dispmap".to_owned()];
    for a in std::env::args().skip(1) {
        if a.is_empty() || a.contains(|c: char| c.is_whitespace() || c == '\'' || c == '"') {
            parts.push(format!("'{}'", a.replace('\'', r"'\''")));
        } else {
            parts.push(a);
        }
    }
    parts.join(" ")
}

fn print_bench_summary(results: &bench::BenchResults) {
    use bench::report::{
        Measure, Speedup, equal_error_speedup, equal_error_speedup_at_dig, same_setting_speedup,
    };
    let cell = |s: Option<Speedup>| match s {
        Some(Speedup::Ratio(x)) => format!("{x:.2}x"),
        Some(Speedup::AtLeast(x)) => format!(">={x:.2}x"),
        Some(Speedup::AtMost(x)) => format!("<={x:.2}x"),
        Some(Speedup::OtherNeverReaches) => "never".into(),
        Some(Speedup::DigNeverReaches) => "dig never".into(),
        None => "-".into(),
    };
    println!(
        "\nDIG's speed-up (method time: dig_corners + trace) over pom / relief: at the same \
         setting; at equal artifact fraction (a) on DIG's curve at the other's error, (b) on \
         the other's curve at DIG's error (never: the other never gets that low):"
    );
    println!(
        "{:<10} {:>5} {:>8} {:>10} {:>10} {:>8} {:>10} {:>10}",
        "map", "iter", "pom", "pom (a)", "pom (b)", "relief", "relief (a)", "relief (b)"
    );
    for map in &results.maps {
        for &steps in &results.config.steps {
            let rows = &results.rows;
            let same = |m| {
                same_setting_speedup(rows, &map.name, m, steps)
                    .map_or_else(|| "-".into(), |(x, _)| format!("{x:.2}x"))
            };
            let a = |m| {
                cell(equal_error_speedup(
                    rows,
                    &map.name,
                    m,
                    steps,
                    Measure::ArtifactFraction,
                ))
            };
            let b = |m| {
                cell(equal_error_speedup_at_dig(
                    rows,
                    &map.name,
                    m,
                    steps,
                    Measure::ArtifactFraction,
                ))
            };
            println!(
                "{:<10} {:>5} {:>8} {:>10} {:>10} {:>8} {:>10} {:>10}",
                map.name,
                steps,
                same(Method::Pom),
                a(Method::Pom),
                b(Method::Pom),
                same(Method::Relief),
                a(Method::Relief),
                b(Method::Relief)
            );
        }
    }
    if let Some(m) = &results.materials {
        println!(
            "materials: (a) together / alone trace {:.3} ({:.3}-{:.3}; medians {:.3}; bound \
             1.1); (b) {:.1}% displaced / fully displaced pass {:.3} ({:.3}-{:.3}; medians \
             {:.3}; bound 0.2)",
            m.disjoint_ratio.min,
            m.disjoint_ratio.lo,
            m.disjoint_ratio.hi,
            m.disjoint_median_ratio,
            100.0 * m.tenth_share,
            m.tenth_ratio.min,
            m.tenth_ratio.lo,
            m.tenth_ratio.hi,
            m.tenth_median_ratio
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// The option texts list the methods by hand: every method is named.
    #[test]
    fn method_options_name_every_method() {
        let mut cli = Cli::command();
        for sub in ["render", "bench"] {
            let help = cli
                .find_subcommand_mut(sub)
                .expect("subcommand")
                .render_long_help()
                .to_string();
            for m in Method::ALL {
                assert!(help.contains(m.name()), "`{sub} --help` does not name {m}");
            }
        }
    }
}
