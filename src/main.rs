//! The `dispmap` command line: `info`, `render`, and (with no arguments) the default job.

use anyhow::{Context as _, Result, bail};
use clap::{Args, Parser, Subcommand};
use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::metrics::ErrorMetrics;
use dispmap::reference::Reference;
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Light, Scene};
use dispmap::{bundled, output};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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
}

#[derive(Args, Debug)]
struct RenderArgs {
    /// Height map (PNG 8/16-bit, JPEG, OpenEXR).
    #[arg(long)]
    heightmap: PathBuf,
    /// How the file encodes heights: `height` (white = high) or `depth` (white = low).
    #[arg(long)]
    convention: Convention,
    /// Intersection method (bump, linear, relief).
    #[arg(long, default_value = "relief")]
    method: Method,
    #[command(flatten)]
    common: CommonArgs,
    /// Output PNG.
    #[arg(long)]
    out: PathBuf,
    /// Also compute the exact reference and write the metrics JSON here.
    #[arg(long)]
    metrics: Option<PathBuf>,
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
    /// Linear steps over the full depth (the quality setting).
    #[arg(long, default_value_t = 64)]
    steps: u32,
    /// Binary-search steps after the linear march (relief).
    #[arg(long, default_value_t = 5)]
    refine_steps: u32,
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
    #[arg(long, default_value_t = 0.25)]
    camera_height: f32,
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 45.0)]
    fov: f32,
    /// Macro geometry: `plane` (tiled, repeat addressing) or `quad` (one decal, clamp).
    #[arg(long, default_value = "plane")]
    geometry: Geometry,
    /// Frames to render; timings are medians over them.
    #[arg(long, default_value_t = 3)]
    frames: u32,
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

impl CommonArgs {
    fn settings(&self, method: Method) -> RenderSettings {
        RenderSettings {
            width: self.size.0,
            height: self.size.1,
            method,
            params: MethodParams {
                steps: self.steps,
                refine_steps: self.refine_steps,
            },
            scene: Scene {
                geometry: self.geometry,
                depth_scale: self.depth_scale,
                camera: Camera {
                    elevation_deg: self.camera_elevation,
                    azimuth_deg: self.camera_azimuth,
                    fov_y_deg: self.fov,
                    height: self.camera_height,
                },
                light: Light::default(),
            },
        }
    }

    fn check(&self) -> Result<()> {
        if self.frames == 0 || self.frames > 10_000 {
            bail!("invalid --frames: {} is outside 1..=10000", self.frames);
        }
        Ok(())
    }
}

/// The metrics JSON of `render --metrics`.
#[derive(Serialize)]
struct MetricsReport<'a> {
    method: &'a str,
    steps: u32,
    refine_steps: u32,
    width: u32,
    height: u32,
    frames: u32,
    heightmap: String,
    depth_scale: f32,
    camera_elevation: f32,
    device: &'a str,
    driver: &'a str,
    timings_ms: BTreeMap<String, f64>,
    error: ErrorSummary,
    nonfinite_pixels: u64,
    iterations: Iterations,
}

#[derive(Serialize)]
struct ErrorSummary {
    mean_texels: f64,
    p99_texels: f64,
    max_texels: f64,
    artifact_fraction: f64,
    psnr_db: f64,
    compared_pixels: u64,
}

#[derive(Serialize)]
struct Iterations {
    mean: f64,
    p99: f64,
}

impl From<&ErrorMetrics> for ErrorSummary {
    fn from(e: &ErrorMetrics) -> Self {
        ErrorSummary {
            mean_texels: e.mean_texels,
            p99_texels: e.p99_texels,
            max_texels: e.max_texels,
            artifact_fraction: e.artifact_fraction,
            psnr_db: e.psnr_db,
            compared_pixels: e.compared_pixels,
        }
    }
}

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    let options = ContextOptions {
        validation: None,
        device: cli.device.clone(),
    };
    match cli.command {
        Some(Command::Info) => info(&options),
        Some(Command::Render(args)) => render(&options, &args),
        Some(Command::Demo(args)) => demo(&options, &args),
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

fn finish(ctx: &Context) -> Result<()> {
    let m = ctx.messages();
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
    let ctx = Context::headless(options)?;
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
        if ctx.has_messenger() {
            "messenger installed"
        } else {
            "off"
        }
    );
    finish(&ctx)
}

fn render(options: &ContextOptions, args: &RenderArgs) -> Result<()> {
    args.common.check()?;
    let settings = args.common.settings(args.method);
    settings.validate()?;
    output::check_writable(&args.out)?;
    if let Some(m) = &args.metrics {
        output::check_writable(m)?;
    }
    let field = HeightField::load(&args.heightmap, args.convention)?;
    let ctx = Context::headless(options)?;
    {
        let mut renderer = Renderer::new(&ctx, &field, settings)?;
        let (timings, color, error) = if args.metrics.is_some() {
            let reference = Reference::new(&field, settings.scene.addressing());
            let frame_ref = renderer.reference(&reference)?;
            let m = renderer.measure(&frame_ref, args.common.frames)?;
            (m.timings_ms, m.color, Some(m.error))
        } else {
            let timings = renderer.render_frames(args.common.frames)?;
            (timings, renderer.read_color()?, None)
        };
        output::write_png(&args.out, settings.width, settings.height, &color)?;
        if let (Some(path), Some(error)) = (&args.metrics, error) {
            let report = MetricsReport {
                method: settings.method.name(),
                steps: settings.params.steps,
                refine_steps: settings.params.refine_steps,
                width: settings.width,
                height: settings.height,
                frames: args.common.frames,
                heightmap: args.heightmap.display().to_string(),
                depth_scale: settings.scene.depth_scale,
                camera_elevation: settings.scene.camera.elevation_deg,
                device: &ctx.info().name,
                driver: &ctx.info().driver,
                timings_ms: timings.iter().cloned().collect(),
                error: (&error).into(),
                nonfinite_pixels: error.nonfinite_pixels,
                iterations: Iterations {
                    mean: error.mean_iterations,
                    p99: error.p99_iterations,
                },
            };
            let json = serde_json::to_string_pretty(&report)?;
            output::write_atomic(path, json.as_bytes())?;
        }
        print_timings(&timings);
        if let Some(e) = error {
            println!(
                "error: mean {:.3} texels, p99 {:.3}, max {:.3}, artifacts {:.3}%, PSNR {:.2} dB, non-finite {}",
                e.mean_texels,
                e.p99_texels,
                e.max_texels,
                100.0 * e.artifact_fraction,
                e.psnr_db,
                e.nonfinite_pixels
            );
        }
    }
    finish(&ctx)
}

fn print_timings(timings: &[(String, f64)]) {
    let parts: Vec<String> = timings
        .iter()
        .map(|(name, ms)| format!("{name} {ms:.3} ms"))
        .collect();
    println!("GPU time (median): {}", parts.join(", "));
}

fn demo(options: &ContextOptions, args: &DemoArgs) -> Result<()> {
    args.common.check()?;
    let field = bundled::rocks()?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create {}", args.out_dir.display()))?;
    let ctx = Context::headless(options)?;
    println!(
        "dispmap: {} on {} ({}), {}x{}, camera elevation {} deg, {} steps, median of {} frames",
        field.label(),
        ctx.info().name,
        ctx.info().driver,
        args.common.size.0,
        args.common.size.1,
        args.common.camera_elevation,
        args.common.steps,
        args.common.frames
    );
    {
        let first = args.common.settings(Method::ALL[0]);
        let mut renderer = Renderer::new(&ctx, &field, first)?;
        let reference = Reference::new(&field, first.scene.addressing());
        let frame_ref = renderer.reference(&reference)?;
        let path = args.out_dir.join("reference.png");
        output::write_png(&path, first.width, first.height, &frame_ref.color)?;
        println!(
            "\n{:<8} {:>10} {:>10} {:>10} {:>10} {:>8} {:>10} {:>10} {:>10} {:>9}",
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
        for &method in Method::ALL {
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
                "{:<8} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>8.1} {:>10.3} {:>10.3} {:>10.3} {:>9.2}",
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
            let path: &Path = &args.out_dir.join(format!("{}.png", method.name()));
            output::write_png(path, settings.width, settings.height, &m.color)?;
        }
        println!(
            "\nimages: {} (reference.png is the exact reference, shaded)",
            args.out_dir.display()
        );
    }
    finish(&ctx)
}
