//! The command line's arguments (clap): every subcommand's options, and how the common
//! ones become render settings (alone or over a scene file's values).

use crate::view;
use anyhow::{Result, bail};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, Parser, Subcommand};
use dispmap::heightfield::Convention;
use dispmap::method::{MaxLevel, Method, MethodParams};
use dispmap::passes::shadow::{DEFAULT_SHADOW_SAMPLES, ShadowMode, ShadowSettings};
use dispmap::renderer::RenderSettings;
use dispmap::scene::{Camera, Geometry, Light, Scene, reduce_degrees};
use dispmap_cli::{bench, memory};
use std::path::PathBuf;

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
pub(crate) struct Cli {
    /// Vulkan device: index in enumeration order or a substring of its name
    /// (default: DISPMAP_DEVICE, else the best GPU, else lavapipe).
    #[arg(long, global = true)]
    pub(crate) device: Option<String>,
    #[command(subcommand)]
    pub(crate) command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub(crate) enum Command {
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
pub(crate) struct BenchArgs {
    /// Output folder (created if missing); every file is written atomically.
    #[arg(long, default_value = "bench-out")]
    pub(crate) out: PathBuf,
    /// Frames per run: the camera turns about the vertical axis by 360/K degrees per
    /// frame.
    #[arg(long, default_value_t = bench::DEFAULT_FRAMES, value_name = "K")]
    pub(crate) frames: u32,
    /// Interleaved passes over the frames: times are the minimum over every frame of
    /// every pass, with the range of the per-pass minima as their spread.
    #[arg(long, default_value_t = bench::DEFAULT_REPEAT, value_name = "R")]
    pub(crate) repeat: u32,
    /// How many of the frames (spread evenly, frame 0 first) are measured against the
    /// exact reference [default: all of them].
    #[arg(long, value_name = "N")]
    pub(crate) error_frames: Option<u32>,
    /// Quality settings: linear steps over the full depth, the same for every method that
    /// has a step count (DIG: eps1 = eps2 = 1/steps).
    #[arg(
        long,
        default_value = "10,15,20,25,35,50,75,100,125,150",
        value_name = "LIST"
    )]
    pub(crate) steps: String,
    /// Methods, comma-separated, `all`, or `default` (every method but cone-exact, which
    /// is slower than exact on every bundled map: docs/cones.md): bump, linear, relief,
    /// pom, secant, dig, dig-guarded, pyramid, exact, cone, cone-exact, relaxed-cone.
    #[arg(long, default_value = "default", value_name = "LIST")]
    pub(crate) methods: String,
    /// Bundled maps (rocks, bricks, mountains), comma-separated, or `none`.
    #[arg(long, default_value = "rocks,bricks,mountains", value_name = "LIST")]
    pub(crate) maps: String,
    /// Add this height map (PNG 8/16-bit, JPEG, OpenEXR) to the maps; needs --convention.
    #[arg(long, requires = "convention", value_name = "FILE")]
    pub(crate) heightmap: Option<PathBuf>,
    /// How --heightmap encodes heights: `height` (white = high) or `depth` (white = low).
    #[arg(long, requires = "heightmap")]
    pub(crate) convention: Option<Convention>,
    /// Frame size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x360", value_parser = parse_size)]
    pub(crate) size: (u32, u32),
    /// Map-size sweep: map sides (the map is resampled to each), comma-separated, or
    /// `none`; pyramid, exact, dig and pom are timed at --size-steps.
    #[arg(long, default_value = "256,512,1024,2048", value_name = "LIST")]
    pub(crate) sizes: String,
    /// The setting of the map-size sweep.
    #[arg(long, default_value_t = bench::DEFAULT_SIZE_STEPS, value_name = "N")]
    pub(crate) size_steps: u32,
    /// The bundled map the map-size sweep resamples.
    #[arg(long, default_value = "rocks", value_name = "NAME")]
    pub(crate) size_map: String,
    /// Self-shadowing of every run: `off`, `hard` or `soft` (see `render --shadows`);
    /// when on, the `shadow` pass's time goes into results.csv (`shadow_ms`) and the report.
    #[arg(long, default_value = "off", value_name = "MODE")]
    pub(crate) shadows: ShadowMode,
    /// Refuse a run whose estimated memory (the largest map or sweep size with the
    /// frame, the reference and the heat maps) is above this (e.g. 8G) [default: the
    /// memory available].
    #[arg(long, value_name = "BYTES", value_parser = memory::parse_bytes)]
    pub(crate) max_memory: Option<u64>,
    /// The material-table numbers (several materials in one frame, a tenth of the
    /// frame displaced): `on` or `off`.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    pub(crate) materials: String,
    /// The cost of silhouettes (the rocks sphere and materials scenes with curved tracing
    /// and the behind layer against without): `on` or `off`.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    pub(crate) silhouettes: String,
    /// The forward path: every relief and pom run again with the march in the G-buffer
    /// pass (what engines do), its whole frame beside the deferred frame: `on` or `off`.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    pub(crate) forward: String,
    /// No progress bar.
    #[arg(long)]
    pub(crate) quiet: bool,
}

#[derive(Args, Debug)]
pub(crate) struct RenderArgs {
    /// A scene file (TOML: height map, material, geometry, camera, light, method, frame
    /// size; see docs/scenes.md). Flags given on the command line override its values.
    #[arg(long, value_name = "FILE")]
    pub(crate) scene: Option<PathBuf>,
    /// Height map (PNG 8/16-bit, JPEG, OpenEXR); needed unless --scene.
    #[arg(long, required_unless_present = "scene", requires = "convention")]
    pub(crate) heightmap: Option<PathBuf>,
    /// How the file encodes heights: `height` (white = high) or `depth` (white = low).
    #[arg(long, requires = "heightmap")]
    pub(crate) convention: Option<Convention>,
    /// Intersection method: bump, linear, relief, pom, secant, dig, dig-guarded, pyramid,
    /// exact, cone, cone-exact, relaxed-cone.
    #[arg(long, default_value = "relief")]
    pub(crate) method: Method,
    #[command(flatten)]
    pub(crate) common: CommonArgs,
    /// Output PNG (`-`: standard output); may be left out when --metrics is given.
    #[arg(long, required_unless_present = "metrics")]
    pub(crate) out: Option<PathBuf>,
    /// Also compute the exact reference and write the metrics JSON here.
    #[arg(long)]
    pub(crate) metrics: Option<PathBuf>,
    /// Trace displaced meshes as curved geometry: each pixel's ray follows the curvature of
    /// the mesh under it and misses when it leaves the relief's shell, so carved outlines
    /// show (methods exact, relief and pom; the others and the plane trace tangent planes).
    #[arg(long)]
    pub(crate) curved: bool,
    /// Leave out the behind layer, so a displaced ray that misses (leaves a decal or, with
    /// --curved, its shell) shows the sky instead of the next surface behind it (the layer
    /// is on by default in scenes of several objects where an object can miss, and for a
    /// mesh drawn alone with --curved, which can show itself behind a miss).
    #[arg(long)]
    pub(crate) no_behind: bool,
    /// Also write the per-pixel iteration count of the trace pass as a colour-mapped PNG
    /// (viridis-like: dark purple = few, yellow = many; black = no geometry; white = a
    /// non-finite count). Scaled to the frame's largest count unless --heatmap-max.
    #[arg(long, value_name = "FILE")]
    pub(crate) heatmap: Option<PathBuf>,
    /// Fixed iteration count at the top of the --heatmap ramp (counts above saturate), so
    /// heat maps of different methods compare by colour.
    #[arg(long, requires = "heatmap", value_name = "N")]
    pub(crate) heatmap_max: Option<f32>,
    /// dig, dig-guarded: also write the depth interval length of each block as a grey PNG
    /// at the frame size (nearest neighbour; darker = longer interval, black = the full
    /// depth; red = no interval: the block's corners are not all on one surface and the
    /// trace falls back to the unconstrained search).
    #[arg(long, value_name = "FILE")]
    pub(crate) interval_map: Option<PathBuf>,
    /// Also write the corrected depth (the reverse-Z clip depth of each pixel's displaced
    /// hit point; 0 where there is none) of the last frame: `.exr` as 32-bit float (the
    /// value in R, G and B) or `.png` as 16-bit grey (depth * 65535, rounded).
    #[arg(long, value_name = "FILE")]
    pub(crate) depth_out: Option<PathBuf>,
    /// Samples per pixel of the --out image: 1, 4, 9 or 16 (the frame rendered again at 2,
    /// 3 or 4 times the size in each direction and averaged in linear light: anti-aliased
    /// edges). The metrics, heat map, interval map and depth stay one ray per pixel
    /// centre, as with 1.
    #[arg(long, default_value_t = 1, value_parser = parse_samples, value_name = "N")]
    pub(crate) samples: u32,
}

/// `--samples`: a square number of samples per pixel, 1 to 16.
fn parse_samples(s: &str) -> std::result::Result<u32, String> {
    match s.parse::<u32>() {
        Ok(n @ (1 | 4 | 9 | 16)) => Ok(n),
        _ => Err(format!("'{s}' is not 1, 4, 9 or 16")),
    }
}

#[derive(Args, Debug)]
pub(crate) struct DemoArgs {
    /// Folder for the images (created if missing).
    #[arg(long, default_value = "dispmap-out")]
    pub(crate) out_dir: PathBuf,
    #[command(flatten)]
    pub(crate) common: CommonArgs,
}

#[derive(Args, Debug)]
pub(crate) struct CommonArgs {
    /// The quality: linear steps over the full depth (linear, relief, dig's `iter`),
    /// pom's n_max, secant's samples per segment. Default: 15 for secant, 64 otherwise.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) steps: Option<u32>,
    /// pom: n_min, the sample count at a head-on view; at most --steps (n_max)
    /// [default: 8, or --steps when that is lower].
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) min_steps: Option<u32>,
    /// Binary-search steps after the linear march (relief, dig).
    #[arg(long, default_value_t = 5, allow_negative_numbers = true)]
    pub(crate) refine_steps: u32,
    /// secant: split the ray into this many segments (the paper's multi-pass variant).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub(crate) segments: u32,
    /// dig: block size in pixels, N or WxH.
    #[arg(long, default_value = "4x4", value_parser = parse_block)]
    pub(crate) block: (u32, u32),
    /// dig: interval widening eps1 = eps2 (default 1/steps).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) eps: Option<f32>,
    /// pyramid: coarsest traversal level (0 = full detail) or `auto` (from the pixel's
    /// texel footprint).
    #[arg(long, default_value = "0", allow_negative_numbers = true)]
    pub(crate) max_level: MaxLevel,
    /// Level of detail, every method (off by default): pixels whose texel footprint is at
    /// least 2^L texels take the bump result without tracing; between 2^(L-1) and 2^L
    /// the traced hit is blended toward it.
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    pub(crate) lod_threshold: Option<f32>,
    /// Displacement depth in tile units.
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    pub(crate) depth_scale: f32,
    /// Frame size, WIDTHxHEIGHT.
    #[arg(long, default_value = "256x144", value_parser = parse_size)]
    pub(crate) size: (u32, u32),
    /// Angle in degrees between the central view ray and the plane (90 = straight down).
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub(crate) camera_elevation: f32,
    /// Camera rotation about the vertical axis, degrees.
    /// (Read in f64 and reduced modulo 360 before it is rounded to f32, so any finite
    /// angle turns the camera by what it says.)
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub(crate) camera_azimuth: f64,
    /// Eye height above the plane in tiles (tiled plane only).
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub(crate) camera_height: f32,
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    pub(crate) fov: f32,
    /// Macro geometry: `plane` (tiled, repeat addressing), `quad` (one decal, clamp),
    /// `cube` (six decals), `sphere` or `torus` (tiled); a loaded `mesh` needs --scene.
    #[arg(long, default_value = "plane")]
    pub(crate) geometry: Geometry,
    /// Frames to render; timings are medians over them.
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    pub(crate) frames: u32,
    /// Refuse a run whose estimated memory (from the map and frame size, before
    /// anything large is allocated) is above this (e.g. 8G, 512M) [default: the memory
    /// available].
    #[arg(long, value_name = "BYTES", value_parser = memory::parse_bytes, allow_negative_numbers = true)]
    pub(crate) max_memory: Option<u64>,
    /// Self-shadowing (Tatarchuk 2006, 3.2): `off`, `hard` (first occluder along the
    /// light ray: exact for exact, dig-guarded and pyramid, a linear march with --steps
    /// otherwise) or `soft` (the paper's penumbra estimate); timed as the `shadow` pass.
    #[arg(long, default_value = "off")]
    pub(crate) shadows: ShadowMode,
    /// Soft shadows: height samples along the light ray (the paper's 8).
    #[arg(long, default_value_t = DEFAULT_SHADOW_SAMPLES, value_name = "N", allow_negative_numbers = true)]
    pub(crate) shadow_samples: u32,
}

pub(crate) fn parse_block(s: &str) -> std::result::Result<(u32, u32), String> {
    match s.trim().parse::<u32>() {
        Ok(n) if n > 0 => Ok((n, n)),
        _ => parse_size(s),
    }
}

pub(crate) fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
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
pub(crate) const DEFAULT_MIN_STEPS: u32 = 8;

/// [`RenderSettings::validate`] and the method's own checks of its values
/// ([`Method::check_params`]: pom's n_min at most its n_max), which a scene's objects
/// get too.
pub(crate) fn validate_settings(settings: &RenderSettings) -> Result<()> {
    settings.validate()?;
    settings.method.check_params(&settings.params)?;
    Ok(())
}

impl CommonArgs {
    pub(crate) fn settings(&self, method: Method) -> RenderSettings {
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
                    azimuth_deg: reduce_degrees(self.camera_azimuth),
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
    pub(crate) fn override_scene(
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
            scene.camera.azimuth_deg = reduce_degrees(self.camera_azimuth);
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

    pub(crate) fn check(&self) -> Result<()> {
        if self.frames == 0 || self.frames > 10_000 {
            bail!("invalid --frames: {} is outside 1..=10000", self.frames);
        }
        Ok(())
    }
}

impl DemoArgs {
    pub(crate) fn parse_defaults() -> Self {
        #[derive(Parser)]
        struct Defaults {
            #[command(flatten)]
            demo: DemoArgs,
        }
        Defaults::parse_from(["dispmap"]).demo
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
