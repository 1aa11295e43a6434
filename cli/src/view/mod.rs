//! `dispmap view`: an interactive window on the renderer, one more host of the same
//! frame as `render` ([`Renderer::render`]), presented through a swapchain
//! ([`present`]), with an on-screen panel drawn over it ([`panel`], through [`ui`]):
//! the methods and their parameters, live GPU times, the error overlay computed on
//! demand off the render thread, and a headless scripted mode (`--frames`, [`script`])
//! for tests and demos.

mod app;
mod budget;
mod compose;
mod headless;
mod input;
mod overlay;
mod panel;
mod present;
mod script;
mod state;
mod stats;
mod ui;
mod viewer;

use crate::{CommonArgs, RenderArgs, render_inputs};
use anyhow::{Context as _, Result, bail};
use app::App;
use clap::parser::ValueSource;
use clap::{ArgMatches, Args};
use dispmap::context::ContextOptions;
use dispmap::heightfield::Convention;
use dispmap::method::Method;
use dispmap::renderer::SceneAssets;
use dispmap_cli::{bundled, output};
use headless::Headless;
use input::{cycle, set_distance};
use script::{Action, CameraPath, Script};
use state::{Compare, ViewState};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use viewer::Viewer;
use winit::event_loop::{ControlFlow, EventLoop};

/// The interactive window's size when `--size` is not given.
const DEFAULT_WINDOW: (u32, u32) = (960, 540);
/// Lowest camera elevation the controls reach, degrees.
const MIN_ELEVATION: f32 = 0.5;
/// How often the live numbers are updated.
const STATS_PERIOD: Duration = Duration::from_millis(500);
/// Artifact pixels of the error overlay (more than one texel off).
const ARTIFACT_RGBA: [u8; 4] = [255, 0, 0, 255];
/// Miss pixels of the error overlay (exactly one of method and reference hits) and
/// non-finite hits.
const MISS_RGBA: [u8; 4] = [0, 255, 255, 255];
/// Pixels of the error overlay that level of detail sent (wholly or in part) to bump
/// mapping: not compared with the reference.
const LOD_RGBA: [u8; 4] = [255, 0, 255, 255];
/// Frames in the panel's rolling graph.
const HISTORY: usize = 120;
/// How long the panel shows the last screenshot's file name.
const NOTICE_TIME: Duration = Duration::from_secs(5);
/// How long a scripted resize may take before the run fails.
const RESIZE_TIMEOUT: Duration = Duration::from_secs(10);

/// `dispmap view`'s arguments: `render`'s inputs, plus the viewer's.
#[derive(Args, Debug)]
#[command(
    mut_arg("size", |a| a
        .default_value("960x540")
        .help("The window's first size, WIDTHxHEIGHT (the frame follows the window)")),
    mut_arg("frames", |a| a
        .hide_default_value(true)
        .help("Headless use: run N frames, write --screenshot, print the timings and exit \
               [default: interactive, until the window closes]")
        .value_name("N")),
)]
pub struct ViewArgs {
    /// A scene file (as `render --scene`); flags given override its values.
    #[arg(long, value_name = "FILE")]
    scene: Option<PathBuf>,
    /// Height map (PNG 8/16-bit, JPEG, OpenEXR) [default: the bundled rocks map].
    #[arg(long, requires = "convention")]
    heightmap: Option<PathBuf>,
    /// How the file encodes heights: `height` (white = high) or `depth` (white = low).
    #[arg(long, requires = "heightmap")]
    convention: Option<Convention>,
    /// Intersection method (of the left side in split view).
    #[arg(long, default_value = "relief")]
    method: Method,
    /// Split view from the start: this method right of the divider.
    #[arg(long, value_name = "METHOD")]
    split: Option<Method>,
    /// Start in the iteration heat-map view.
    #[arg(long)]
    heatmap: bool,
    #[command(flatten)]
    common: CommonArgs,
    /// Headless use: the camera of each frame, `orbit` (one turn about the vertical
    /// axis over --frames) or a file of `ELEVATION AZIMUTH [HEIGHT]` lines, one a frame.
    /// Only with --frames.
    #[arg(long, value_name = "FILE|orbit", requires = "frames")]
    camera_path: Option<String>,
    /// Headless use: changes at given frames (`FRAME ACTION [ARG]` lines: method,
    /// split, divider, resize, steps, depth-scale, shadows, lod, map, heatmap, error,
    /// screenshot; see docs/viewer.md). Only with --frames.
    #[arg(long, value_name = "FILE", requires = "frames")]
    script: Option<PathBuf>,
    /// Headless use: write the last frame, as presented, to this PNG. Only with
    /// --frames.
    #[arg(long, value_name = "FILE", requires = "frames")]
    screenshot: Option<PathBuf>,
    /// No on-screen panel, labels or help: the window shows `render`'s frame alone.
    #[arg(long)]
    no_ui: bool,
}

/// Runs `dispmap view`; `matches` are the subcommand's.
pub fn run(options: &ContextOptions, args: ViewArgs, matches: &ArgMatches) -> Result<()> {
    let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
    let headless = given("frames");
    let ViewArgs {
        scene,
        heightmap,
        convention,
        method,
        split,
        heatmap: start_heatmap,
        common,
        camera_path,
        script,
        screenshot,
        no_ui,
    } = args;
    // `render`'s inputs, read by `render`'s code (with its memory check).
    let inputs = RenderArgs {
        scene,
        heightmap,
        convention,
        method,
        common,
        out: None,
        metrics: None,
        curved: false,
        no_behind: false,
        heatmap: None,
        heatmap_max: None,
        interval_map: None,
        depth_out: None,
        samples: 1,
    };
    let common = &inputs.common;
    common.check()?;
    // Everything about the input is checked before a window opens.
    let (field, label, mut settings, assets) =
        if inputs.scene.is_some() || inputs.heightmap.is_some() {
            render_inputs(&inputs, matches)?
        } else {
            let settings = common.settings(method);
            crate::validate_settings(&settings)?;
            let field = bundled::rocks()?;
            (field, "rocks".to_owned(), settings, SceneAssets::default())
        };
    // The documented first size, unless --size or the scene file gives one.
    let scene_size = match &inputs.scene {
        Some(path) => dispmap_cli::scene_file::SceneFile::read(path)?.size,
        None => None,
    };
    if !given("size") && scene_size.is_none() {
        (settings.width, settings.height) = DEFAULT_WINDOW;
    }
    // The camera path and the script checked completely, against this run.
    let camera_path = camera_path
        .as_deref()
        .map(|p| CameraPath::parse(p, &settings.scene))
        .transpose()?;
    let run = script::Run {
        frames: common.frames,
        objects: !assets.objects.is_empty(),
        displaced: assets
            .objects
            .iter()
            .map(|o| o.material.is_some())
            .collect(),
    };
    let script_name = script
        .as_deref()
        .map_or(String::new(), |p| p.display().to_string());
    let script = script
        .as_deref()
        .map(|p| Script::read(p, &run))
        .transpose()?
        .unwrap_or_default();
    if let Some(path) = &screenshot {
        output::check_writable_as(path, output::Format::Png).context("invalid --screenshot")?;
    }
    for (_, action) in &script.events {
        if let Action::Screenshot(path) = action {
            output::check_writable_as(path, output::Format::Png)
                .context("invalid --script screenshot")?;
        }
    }
    if let Some(right) = split {
        let mut s = settings;
        s.method = right;
        s.params.steps = common.steps.unwrap_or(right.default_steps());
        s.validate()?;
    }
    let state = ViewState {
        bound: budget::Bound::new(common.max_memory),
        maps: vec![(label, Arc::new(field))],
        map: 0,
        materials: state::initial_materials(&assets),
        assets,
        settings,
        steps: common.steps,
        right: split,
        divider: 0.5,
        compare: Compare::Wipe,
        show_b: false,
        heatmap: start_heatmap,
        home: settings.scene.camera,
        panel: true,
        help: false,
    };
    // The memory bound of the start and of every scripted change.
    budget::check(&state, &script, &script_name, common.max_memory)?;
    let headless = headless.then(|| Headless {
        frames: common.frames,
        camera_path,
        script,
        screenshot: screenshot.clone(),
        pending_resize: None,
        waiting_error: false,
        applied: None,
        waited: 0,
    });
    let event_loop = EventLoop::new().context(
        "cannot open a window: no display server (set DISPLAY or WAYLAND_DISPLAY, or run \
         under Xvfb)",
    )?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App {
        options: options.clone(),
        state,
        headless,
        viewer: None,
        error: None,
        done: false,
        ui: !no_ui,
    };
    event_loop
        .run_app(&mut app)
        .context("the window system's event loop failed")?;
    let viewer = app.viewer.take();
    let shutdown = viewer.map(Viewer::shutdown).transpose();
    if let Some(e) = app.error {
        return Err(e);
    }
    shutdown?;
    if app.headless.is_some() && !app.done {
        bail!("the window closed before the scripted frames ran");
    }
    Ok(())
}
