//! `dispmap view`: an interactive window on the renderer, one more host of the same
//! frame as `render` ([`Renderer::render`]), presented through a swapchain
//! ([`present`]), with an on-screen panel drawn over it ([`panel`], through [`ui`]):
//! the methods and their parameters, live GPU times, the error overlay computed on
//! demand off the render thread, and a headless scripted mode (`--frames`, [`script`])
//! for tests and demos.

mod panel;
mod present;
mod script;
mod ui;

use crate::{CommonArgs, RenderArgs, finish, render_inputs};
use anyhow::{Context as _, Result, bail};
use ash::vk;
use clap::parser::ValueSource;
use clap::{ArgMatches, Args};
use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::{Addressing, Convention, HeightField};
use dispmap::method::{MaxLevel, Method};
use dispmap::passes::PassName;
use dispmap::passes::shadow::{ShadowMode, ShadowSettings};
use dispmap::renderer::{RenderSettings, Renderer, SceneAssets};
use dispmap::scene::{Camera, Geometry, Scene};
use dispmap_cli::heatmap;
use dispmap_cli::measure::Measure as _;
use dispmap_cli::metrics::{self, ARTIFACT_TEXELS, ErrorMetrics, HitTexel, MapGeometry};
use dispmap_cli::reference::{Hit, Ray, Reference};
use dispmap_cli::{bundled, output};
use panel::{OverlayState, SideError, SideInfo};
use present::{DIVIDER_PX, DIVIDER_RGBA, Layout, Part, Presenter, Source};
use script::{Action, CameraPath, Script};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, ModifiersState, PhysicalKey};
use winit::window::{Window, WindowId};

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
        heatmap: None,
        heatmap_max: None,
        interval_map: None,
        depth_out: None,
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
    if !given("size") && inputs.scene.is_none() {
        (settings.width, settings.height) = DEFAULT_WINDOW;
    }
    let camera_path = camera_path.as_deref().map(CameraPath::parse).transpose()?;
    let script = script
        .as_deref()
        .map(Script::read)
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
    let state = ViewState {
        maps: vec![(label, Arc::new(field))],
        map: 0,
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

/// What the keys change (and the script).
struct ViewState {
    /// Name and field of each map: the given one first, the bundled ones added when
    /// switched to.
    maps: Vec<(String, Arc<HeightField>)>,
    map: usize,
    assets: SceneAssets,
    /// The left (or only) side's settings; the frame size follows the window.
    settings: RenderSettings,
    /// Steps chosen (`None`: each method's default).
    steps: Option<u32>,
    /// The split view's right method.
    right: Option<Method>,
    /// The divider, a fraction of the width.
    divider: f32,
    /// How the two methods of the split view are compared.
    compare: Compare,
    /// A/B mode shows the right method.
    show_b: bool,
    heatmap: bool,
    /// The camera the reset key returns to.
    home: Camera,
    /// The panel is shown.
    panel: bool,
    /// The help overlay is shown.
    help: bool,
}

/// How the split view puts the two methods on screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Compare {
    /// Left of the divider one method, right of it the other (same camera, same frame).
    Wipe,
    /// The whole frame shows one method at a time, the other one key away: the same
    /// pixels.
    Flip,
    /// Both at half the width side by side, each the whole view of the same camera.
    SideBySide,
}

impl Compare {
    fn next(self) -> Self {
        match self {
            Compare::Wipe => Compare::Flip,
            Compare::Flip => Compare::SideBySide,
            Compare::SideBySide => Compare::Wipe,
        }
    }
}

impl ViewState {
    fn side(&self, method: Method) -> RenderSettings {
        let mut s = self.settings;
        s.method = method;
        s.params.steps = self.steps.unwrap_or(method.default_steps());
        s
    }
}

/// The scripted run.
struct Headless {
    frames: u32,
    camera_path: Option<CameraPath>,
    script: Script,
    screenshot: Option<PathBuf>,
    /// A scripted resize not yet applied by the window system, and when it was asked.
    pending_resize: Option<([u32; 2], Instant)>,
    /// A scripted error overlay not yet shown.
    waiting_error: bool,
    /// The frame whose actions were applied (a frame that waits renders again).
    applied: Option<u32>,
    /// Frames rendered again while waiting (for a resize or the error overlay).
    waited: u32,
}

struct App {
    options: ContextOptions,
    state: ViewState,
    headless: Option<Headless>,
    viewer: Option<Viewer>,
    error: Option<anyhow::Error>,
    /// The scripted frames all ran.
    done: bool,
    /// Draw the panel (not `--no-ui`).
    ui: bool,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.viewer.is_some() {
            return;
        }
        match Viewer::new(
            event_loop,
            &self.options,
            &self.state,
            self.headless.is_some(),
            self.ui,
        ) {
            Ok(v) => self.viewer = Some(v),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(viewer) = self.viewer.as_mut() else {
            return;
        };
        // The panel sees input first; what it uses does not move the camera.
        let mut to_panel = false;
        if self.headless.is_none()
            && let Some(gui) = viewer.gui.as_mut()
        {
            let consumed = gui.on_event(&viewer.window, &event);
            to_panel = match &event {
                WindowEvent::KeyboardInput { .. } => gui.wants_keyboard(),
                WindowEvent::MouseInput {
                    state: ElementState::Released,
                    ..
                } => false,
                WindowEvent::CursorMoved { .. } => false,
                _ => consumed || gui.wants_pointer(),
            };
        }
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::RedrawRequested => {
                match viewer.frame(&mut self.state, self.headless.as_mut()) {
                    Ok(Flow::Continue) => Ok(()),
                    Ok(Flow::Done) => {
                        self.done = true;
                        event_loop.exit();
                        Ok(())
                    }
                    Err(e) => Err(e),
                }
            }
            WindowEvent::ModifiersChanged(m) => {
                viewer.modifiers = m.state();
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } if self.headless.is_none() && !to_panel => {
                match viewer.key(&mut self.state, &event) {
                    Ok(true) => {
                        event_loop.exit();
                        Ok(())
                    }
                    Ok(false) => Ok(()),
                    Err(e) => Err(e),
                }
            }
            WindowEvent::MouseInput { state, button, .. }
                if self.headless.is_none() && !to_panel =>
            {
                viewer.mouse_button(button, state == ElementState::Pressed);
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } if self.headless.is_none() => {
                viewer.cursor(&mut self.state, [position.x as f32, position.y as f32]);
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } if self.headless.is_none() && !to_panel => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                zoom(&mut self.state.settings.scene, lines);
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(v) = &self.viewer {
            v.window.request_redraw();
        }
    }
}

enum Flow {
    Continue,
    Done,
}

/// The error overlay: computed for a frame, shown while the frame's inputs stay.
struct Overlay {
    /// The inputs it was computed for.
    key: FrameKey,
    /// Per side: which pixels are artifacts (1), misses / non-finite (2) or sent to
    /// bump mapping by level of detail (3).
    marks: Vec<Vec<u8>>,
    /// Per side: the measures.
    results: Vec<SideError>,
}

/// A background reference job.
struct ErrorJob {
    key: FrameKey,
    done: Arc<AtomicUsize>,
    total: usize,
    rx: mpsc::Receiver<Vec<Option<Hit>>>,
    rays: Vec<Option<Ray>>,
    /// Per side: name, hits, map geometry.
    sides: Vec<(String, Vec<HitTexel>, MapGeometry)>,
    /// The pixels level of detail sends (wholly or in part) to bump mapping (empty when
    /// it is off).
    lod: Vec<bool>,
}

/// What a frame depends on: the overlay is dropped when any of it changes.
#[derive(Clone, PartialEq)]
struct FrameKey {
    settings: Vec<RenderSettings>,
    map: usize,
}

struct Viewer {
    // Field order is drop order; `shutdown` destroys the GPU objects explicitly first.
    /// The on-screen panel (`None` with `--no-ui`).
    gui: Option<ui::Gui>,
    presenter: Presenter,
    left: Renderer,
    right: Option<Renderer>,
    ctx: Arc<Context>,
    window: Arc<Window>,
    modifiers: ModifiersState,
    /// The cursor position and which buttons are held.
    cursor: Option<[f32; 2]>,
    orbiting: bool,
    dragging_divider: bool,
    frame_index: u32,
    screenshot_next: Option<PathBuf>,
    screenshots_taken: u32,
    stats: Stats,
    overlay: Option<Overlay>,
    job: Option<ErrorJob>,
    /// The map index the renderers were built for.
    built_map: usize,
    /// The window size the swapchain was last made for.
    window_size: [u32; 2],
    /// The error overlay was asked for: its reference starts after the next render.
    error_requested: bool,
    /// The last state the renderers accepted.
    good: Option<Snapshot>,
    /// Each side's GPU milliseconds of the last [`HISTORY`] frames.
    history: [VecDeque<f32>; 2],
    /// The heat map's top count per side, when it is shown.
    heat_scales: [Option<f32>; 2],
    /// The last screenshot's line, shown in the panel for a few seconds.
    notice: Option<(String, Instant)>,
}

/// What the keys change, as last accepted by the renderers.
#[derive(Clone)]
struct Snapshot {
    settings: RenderSettings,
    steps: Option<u32>,
    right: Option<Method>,
    map: usize,
}

impl Snapshot {
    fn of(state: &ViewState) -> Self {
        Snapshot {
            settings: state.settings,
            steps: state.steps,
            right: state.right,
            map: state.map,
        }
    }

    fn restore(&self, state: &mut ViewState) {
        state.settings = self.settings;
        state.steps = self.steps;
        state.right = self.right;
        state.map = self.map;
    }
}

/// Live numbers, accumulated between updates.
struct Stats {
    since: Instant,
    frames: u32,
    /// Per side (left, right) and pass: sum of milliseconds and count, in pass order.
    passes: [Vec<(PassName, f64, u32)>; 2],
    /// Updates since the numbers were last printed.
    updates: u32,
    /// Wall milliseconds of `Renderer::render` (all sides) and of the whole frame.
    render_wall: Vec<f64>,
    frame_wall: Vec<f64>,
    /// Every frame's wall times, for the headless summary.
    all_render: Vec<f64>,
    all_frame: Vec<f64>,
    /// Every frame's GPU milliseconds (the left side's passes, one-off passes left
    /// out), for the headless summary.
    all_gpu: Vec<f64>,
    /// Every frame's panel cost: CPU and GPU milliseconds.
    all_ui_cpu: Vec<f64>,
    all_ui_gpu: Vec<f64>,
    /// What the panel shows, from the last update: per side the mean milliseconds per
    /// pass and the mean iterations per pixel; frames per second; median frame time.
    shown_passes: [Vec<(PassName, f64)>; 2],
    shown_iterations: [Option<f64>; 2],
    shown_fps: f64,
    shown_frame_ms: f64,
    /// The panel's cost in the last frame.
    last_ui: (f64, Option<f64>),
}

impl Stats {
    fn new() -> Self {
        Stats {
            since: Instant::now(),
            frames: 0,
            passes: [Vec::new(), Vec::new()],
            updates: 0,
            render_wall: Vec::new(),
            frame_wall: Vec::new(),
            all_render: Vec::new(),
            all_frame: Vec::new(),
            all_gpu: Vec::new(),
            all_ui_cpu: Vec::new(),
            all_ui_gpu: Vec::new(),
            shown_passes: [Vec::new(), Vec::new()],
            shown_iterations: [None, None],
            shown_fps: 0.0,
            shown_frame_ms: 0.0,
            last_ui: (0.0, None),
        }
    }

    fn add(&mut self, side: usize, times: &[(PassName, f64)]) {
        for &(name, ms) in times {
            if name.is_one_off() {
                continue;
            }
            match self.passes[side].iter_mut().find(|(n, _, _)| *n == name) {
                Some(p) => {
                    p.1 += ms;
                    p.2 += 1;
                }
                None => self.passes[side].push((name, ms, 1)),
            }
        }
    }
}

impl Viewer {
    fn new(
        event_loop: &ActiveEventLoop,
        options: &ContextOptions,
        state: &ViewState,
        headless: bool,
        ui: bool,
    ) -> Result<Self> {
        let s = &state.settings;
        let attributes = Window::default_attributes()
            .with_title(title(state))
            .with_inner_size(PhysicalSize::new(s.width, s.height))
            .with_resizable(true);
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .context("cannot open a window")?,
        );
        let instance_exts = present::instance_extensions(&*window)?;
        let ctx = Arc::new(Context::with_extensions(
            options,
            &instance_exts,
            &[ash::khr::swapchain::NAME],
        )?);
        dispmap_cli::frame_limit::check(&ctx, s.width, s.height, "--size")?;
        let size = window.inner_size();
        let presenter = Presenter::new(&ctx, &*window, [size.width, size.height])?;
        let extent = presenter.extent();
        let mut settings = state.settings;
        if extent.width > 0 && extent.height > 0 {
            (settings.width, settings.height) = (extent.width, extent.height);
        }
        let field = &state.maps[state.map].1;
        let build = |s: RenderSettings| Renderer::with_assets(&ctx, field, s, &state.assets);
        let left = match build(settings) {
            Ok(r) => r,
            Err(e) => {
                let mut presenter = presenter;
                presenter.destroy(&ctx);
                return Err(e.into());
            }
        };
        let right = match state.right.map(|m| build(side_of(&settings, state, m))) {
            Some(Err(e)) => {
                let mut presenter = presenter;
                presenter.destroy(&ctx);
                drop(left);
                return Err(e.into());
            }
            Some(Ok(r)) => Some(r),
            None => None,
        };
        let gui = match ui.then(|| ui::Gui::new(&ctx, &window, presenter.format())) {
            Some(Err(e)) => {
                let mut presenter = presenter;
                presenter.destroy(&ctx);
                drop((left, right));
                return Err(e);
            }
            Some(Ok(g)) => Some(g),
            None => None,
        };
        eprintln!(
            "dispmap view: {} on {} ({}), {}x{}, {:?}{}",
            state.maps[state.map].0,
            ctx.info().name,
            ctx.info().driver,
            extent.width,
            extent.height,
            presenter.present_mode(),
            match (headless, ui) {
                (true, _) => "",
                (false, true) => "; F1 lists the keys, Tab hides the panel, Esc quits",
                (false, false) => "; keys: see docs/viewer.md (Esc quits)",
            }
        );
        Ok(Viewer {
            gui,
            presenter,
            left,
            right,
            ctx,
            window,
            modifiers: ModifiersState::empty(),
            cursor: None,
            orbiting: false,
            dragging_divider: false,
            frame_index: 0,
            screenshot_next: None,
            screenshots_taken: 0,
            stats: Stats::new(),
            overlay: None,
            job: None,
            built_map: state.map,
            window_size: [size.width, size.height],
            error_requested: false,
            good: None,
            history: [VecDeque::new(), VecDeque::new()],
            heat_scales: [None, None],
            notice: None,
        })
    }

    /// Waits for the device, destroys the swapchain and surface, drops the renderers,
    /// then the context (failing on any validation message, as every command does).
    fn shutdown(self) -> Result<()> {
        let Viewer {
            gui,
            mut presenter,
            left,
            right,
            ctx,
            window,
            ..
        } = self;
        if let Some(mut gui) = gui {
            gui.destroy(&ctx);
        }
        presenter.destroy(&ctx);
        drop(right);
        drop(left);
        let result = finish(ctx);
        drop(window);
        result
    }

    /// Brings the renderers in line with `state` (map, methods, settings, size); errors
    /// of a change the user asked for are printed and the change undone where possible.
    fn sync(&mut self, state: &mut ViewState, size: [u32; 2]) -> Result<()> {
        let mut want = state.settings;
        (want.width, want.height) = (size[0], size[1]);
        if self.built_map != state.map {
            // A new map: new renderers (the pass keeps its map for its lifetime here).
            let field = state.maps[state.map].1.clone();
            let left = Renderer::with_assets(&self.ctx, &field, want, &state.assets)?;
            let right = state
                .right
                .map(|m| {
                    Renderer::with_assets(
                        &self.ctx,
                        &field,
                        side_of(&want, state, m),
                        &state.assets,
                    )
                })
                .transpose()?;
            self.left = left;
            self.right = right;
            self.built_map = state.map;
        }
        apply(&mut self.left, &want)?;
        match (state.right, self.right.as_mut()) {
            (None, _) => self.right = None,
            (Some(m), Some(r)) => apply(r, &side_of(&want, state, m))?,
            (Some(m), None) => {
                let field = state.maps[state.map].1.clone();
                self.right = Some(Renderer::with_assets(
                    &self.ctx,
                    &field,
                    side_of(&want, state, m),
                    &state.assets,
                )?);
            }
        }
        Ok(())
    }

    fn frame_key(&self, state: &ViewState) -> FrameKey {
        let mut settings = vec![*self.left.settings()];
        if let Some(r) = &self.right {
            settings.push(*r.settings());
        }
        FrameKey {
            settings,
            map: state.map,
        }
    }

    fn frame(
        &mut self,
        state: &mut ViewState,
        mut headless: Option<&mut Headless>,
    ) -> Result<Flow> {
        let frame_start = Instant::now();
        // Scripted changes and the camera of this frame.
        if let Some(h) = headless.as_deref_mut() {
            if h.applied != Some(self.frame_index) {
                h.applied = Some(self.frame_index);
                let now: Vec<Action> = h
                    .script
                    .events
                    .iter()
                    .filter(|(f, _)| *f == self.frame_index)
                    .map(|(_, a)| a.clone())
                    .collect();
                for action in now {
                    self.scripted(state, h, action)?;
                }
            }
            if let Some(path) = &h.camera_path {
                let c = &mut state.settings.scene.camera;
                match path {
                    CameraPath::Orbit => {
                        c.azimuth_deg = state.home.azimuth_deg
                            + 360.0 * self.frame_index as f32 / h.frames as f32;
                    }
                    CameraPath::Points(points) => {
                        let i = (self.frame_index as usize).min(points.len() - 1);
                        c.elevation_deg = points[i].elevation;
                        c.azimuth_deg = points[i].azimuth;
                        if let Some(height) = points[..=i].iter().rev().find_map(|p| p.height) {
                            c.height = height;
                        }
                    }
                }
            }
            if let Some((size, asked)) = h.pending_resize {
                let now = self.window.inner_size();
                if [now.width, now.height] == size && {
                    let e = self.presenter.extent();
                    [e.width, e.height] == size
                } {
                    h.pending_resize = None;
                } else if asked.elapsed() > RESIZE_TIMEOUT {
                    bail!(
                        "the window system did not resize the window to {}x{} within {} s",
                        size[0],
                        size[1],
                        RESIZE_TIMEOUT.as_secs()
                    );
                }
            }
        }
        // The swapchain follows the window.
        let inner = self.window.inner_size();
        let size = [inner.width, inner.height];
        let e = self.presenter.extent();
        if size != self.window_size || e.width == 0 || e.height == 0 {
            self.window_size = size;
            if !self.presenter.recreate(&self.ctx, size)? {
                // Minimised: nothing to draw until it is shown again.
                std::thread::sleep(Duration::from_millis(50));
                return Ok(Flow::Continue);
            }
        }
        let e = self.presenter.extent();
        let frame = [e.width, e.height];
        if let Err(err) = self.sync(state, frame_layout(state, frame).0) {
            if headless.is_some() {
                return Err(err);
            }
            // An interactive change the renderer refused (e.g. a step count past the
            // driver's loop budget): say why and go back to the last state that rendered.
            eprintln!("error: {err:#}");
            let good = self
                .good
                .clone()
                .context("no earlier state to go back to")?;
            good.restore(state);
            self.sync(state, frame_layout(state, frame).0)?;
        }
        self.good = Some(Snapshot::of(state));
        let layout = frame_layout(state, frame).1;

        let render_start = Instant::now();
        let times = self.left.render()?;
        self.stats.add(0, &times);
        let gpu_ms: f64 = times
            .iter()
            .filter(|(n, _)| !n.is_one_off())
            .map(|(_, ms)| ms)
            .sum();
        push_history(&mut self.history[0], gpu_ms);
        if let Some(r) = self.right.as_mut() {
            let times = r.render()?;
            self.stats.add(1, &times);
            let right_ms: f64 = times
                .iter()
                .filter(|(n, _)| !n.is_one_off())
                .map(|(_, ms)| ms)
                .sum();
            push_history(&mut self.history[1], right_ms);
        } else {
            self.history[1].clear();
        }
        let render_ms = render_start.elapsed().as_secs_f64() * 1e3;
        if std::mem::take(&mut self.error_requested) {
            self.start_error_job(state)?;
        }

        let key = self.frame_key(state);
        if self.overlay.as_ref().is_some_and(|o| o.key != key) {
            self.overlay = None;
            eprintln!("error overlay: cleared (the frame changed)");
        }
        self.poll_job(&key, headless.as_deref_mut())?;
        // A scripted run moves on once a resize reached the frame and an asked-for
        // overlay is shown.
        let advance = headless
            .as_deref()
            .is_none_or(|h| h.pending_resize.is_none() && !h.waiting_error);
        // The panel's numbers: at the first frame, then twice a second.
        if self.stats.updates == 0 || self.stats.since.elapsed() >= STATS_PERIOD {
            self.report(state, headless.is_none())?;
        }

        // The frame: the renderers' images as they are, or composed on the CPU.
        let composed = if state.heatmap || self.overlay.is_some() {
            Some(self.compose(state, &layout)?)
        } else {
            self.heat_scales = [None, None];
            None
        };
        let source = match &composed {
            Some(rgba) => Source::Cpu {
                rgba,
                extent: layout.frame,
            },
            None => Source::Gpu {
                images: [
                    Some(self.left.color_image()),
                    self.right.as_ref().map(|r| r.color_image()),
                ],
                layout: &layout,
            },
        };
        let last = headless
            .as_deref()
            .is_some_and(|h| advance && self.frame_index + 1 >= h.frames);
        // The panel, drawn over the frame.
        if self.gui.is_some() {
            let info = self.panel_info(state, &layout);
            let mut requests = panel::Requests::default();
            if let Some(gui) = self.gui.as_mut() {
                gui.run(&self.ctx, &self.window, |ctx| {
                    let r = panel::draw(ctx, state, &info);
                    requests.error |= r.error;
                    requests.screenshot |= r.screenshot;
                    if r.map.is_some() {
                        requests.map = r.map;
                    }
                })?;
            }
            if requests.error {
                self.error_requested = true;
            }
            if requests.screenshot {
                self.screenshots_taken += 1;
                self.screenshot_next = Some(next_screenshot_path(self.screenshots_taken));
            }
            if let Some(name) = requests.map {
                switch_map(state, Some(&name))?;
            }
        }
        let final_shot = if last {
            headless.as_deref().and_then(|h| h.screenshot.clone())
        } else {
            None
        };
        let shot_path = final_shot.or_else(|| self.screenshot_next.take());
        let presented = self.presenter.present(
            &self.ctx,
            source,
            self.gui.as_mut().map(|g| g as &mut dyn present::Overlay),
            shot_path.is_some(),
            size,
        )?;
        if let Some(gui) = self.gui.as_mut() {
            gui.after_frame()?;
        }
        if !presented.shown {
            if let Some(p) = shot_path {
                self.screenshot_next = Some(p);
            }
            return Ok(Flow::Continue);
        }
        if let (Some(path), Some((extent, rgba))) = (&shot_path, &presented.screenshot) {
            output::write_png(path, extent.width, extent.height, rgba)?;
            let line = format!(
                "screenshot: {} ({}x{})",
                path.display(),
                extent.width,
                extent.height
            );
            eprintln!("{line}");
            self.notice = Some((line, Instant::now()));
        }
        let frame_ms = frame_start.elapsed().as_secs_f64() * 1e3;
        self.stats.render_wall.push(render_ms);
        self.stats.frame_wall.push(frame_ms);
        self.stats.all_render.push(render_ms);
        self.stats.all_frame.push(frame_ms);
        self.stats.all_gpu.push(gpu_ms);
        if let Some(gui) = &self.gui {
            self.stats.last_ui = (gui.cpu_ms, presented.overlay_gpu_ms);
            self.stats.all_ui_cpu.push(gui.cpu_ms);
            if let Some(g) = presented.overlay_gpu_ms {
                self.stats.all_ui_gpu.push(g);
            }
        }
        self.stats.frames += 1;
        if advance {
            self.frame_index += 1;
        } else if let Some(h) = headless.as_deref_mut() {
            h.waited += 1;
        }
        if last {
            self.summary(headless.as_deref());
            return Ok(Flow::Done);
        }
        Ok(Flow::Continue)
    }

    /// What the panel shows.
    fn panel_info(&self, state: &ViewState, layout: &Layout) -> panel::Info {
        let renderers = std::iter::once(&self.left).chain(self.right.as_ref());
        let sides = renderers
            .enumerate()
            .map(|(i, r)| SideInfo {
                method: r.settings().method,
                passes: self.stats.shown_passes[i].clone(),
                iterations: self.stats.shown_iterations[i],
                heat_scale: self.heat_scales[i],
                error: self
                    .overlay
                    .as_ref()
                    .and_then(|o| o.results.get(i).copied()),
            })
            .collect();
        let overlay = match (&self.job, &self.overlay) {
            (Some(j), _) => OverlayState::Computing(
                j.done.load(Ordering::Relaxed) as f32 / j.total.max(1) as f32,
            ),
            (None, Some(_)) => OverlayState::Shown,
            (None, None) => OverlayState::Off,
        };
        // Each side's label at the middle of its widest part on screen.
        let scale = self.presenter.extent().width as f32 / layout.frame.width.max(1) as f32;
        let mut label_columns: Vec<(usize, f32)> = Vec::new();
        for part in &layout.parts {
            let w = part.src_x1.saturating_sub(part.src_x0);
            if w == 0 {
                continue;
            }
            label_columns.push((part.side, (part.dst_x as f32 + w as f32 / 2.0) * scale));
        }
        let s = self.left.settings();
        panel::Info {
            sides,
            fps: self.stats.shown_fps,
            frame_ms: self.stats.shown_frame_ms,
            history: [
                self.history[0].iter().copied().collect(),
                self.history[1].iter().copied().collect(),
            ],
            overlay,
            panel_ms: self.stats.last_ui,
            frame: [layout.frame.width, layout.frame.height],
            label_columns,
            maps: state.maps.iter().map(|(n, _)| n.clone()).collect(),
            geometry: format!("{:?}", s.scene.geometry).to_lowercase(),
            notice: self
                .notice
                .as_ref()
                .filter(|(_, at)| at.elapsed() < NOTICE_TIME)
                .map(|(line, _)| line.clone()),
        }
    }

    fn scripted(&mut self, state: &mut ViewState, h: &mut Headless, action: Action) -> Result<()> {
        match action {
            Action::Method(m) => state.settings.method = m,
            Action::Split(m) => state.right = m,
            Action::Divider(f) => state.divider = f,
            Action::Compare(c) => state.compare = c,
            Action::Flip => {
                state.compare = Compare::Flip;
                state.show_b = !state.show_b;
            }
            Action::Zoom(lines) => zoom(&mut state.settings.scene, lines),
            Action::Panel(on) => state.panel = on,
            Action::Help(on) => state.help = on,
            Action::Resize(w, hgt) => {
                let _ = self.window.request_inner_size(PhysicalSize::new(w, hgt));
                h.pending_resize = Some(([w, hgt], Instant::now()));
            }
            Action::Steps(s) => state.steps = Some(s),
            Action::DepthScale(d) => state.settings.scene.depth_scale = d,
            Action::Shadows(mode) => state.settings.shadows.mode = mode,
            Action::Lod(l) => state.settings.params.lod_threshold = l,
            Action::Map(name) => switch_map(state, Some(&name))?,
            Action::Heatmap(on) => state.heatmap = on,
            Action::Error => {
                h.waiting_error = true;
                self.error_requested = true;
            }
            Action::Screenshot(path) => self.screenshot_next = Some(path),
        }
        state.settings.params.steps = state.steps.unwrap_or(state.settings.method.default_steps());
        Ok(())
    }

    /// The frame composed on the CPU: each side's colour (or heat map) with the
    /// overlay's marks, put together by `layout` over the divider's colour. Also keeps
    /// the heat map's scale per side.
    fn compose(&mut self, state: &ViewState, layout: &Layout) -> Result<Vec<u8>> {
        let mut sides = Vec::new();
        let mut scales = [None, None];
        for (i, r) in std::iter::once(&self.left)
            .chain(self.right.as_ref())
            .enumerate()
        {
            let mut rgba = if state.heatmap {
                let hits = r.read_hits()?;
                let covered = heatmap::coverage(&hits, None);
                scales[i] = Some(heatmap::iteration_stats(&hits, &covered).max as f32);
                heatmap::iteration_heatmap(&hits, &covered, None)?
            } else {
                r.read_color()?
            };
            if let Some(marks) = self.overlay.as_ref().and_then(|o| o.marks.get(i)) {
                for (px, &m) in rgba.chunks_exact_mut(4).zip(marks) {
                    match m {
                        1 => px.copy_from_slice(&ARTIFACT_RGBA),
                        2 => px.copy_from_slice(&MISS_RGBA),
                        3 => px.copy_from_slice(&LOD_RGBA),
                        _ => {}
                    }
                }
            }
            sides.push((rgba, r.settings().width as usize));
        }
        self.heat_scales = scales;
        let (w, h) = (layout.frame.width as usize, layout.frame.height as usize);
        let mut out = DIVIDER_RGBA.repeat(w * h);
        for part in &layout.parts {
            let Some((rgba, side_w)) = sides.get(part.side) else {
                continue;
            };
            let (x0, x1) = (part.src_x0 as usize, (part.src_x1 as usize).min(*side_w));
            let dst = part.dst_x as usize;
            if x0 >= x1 || dst + (x1 - x0) > w {
                continue;
            }
            for (row_out, row_in) in out
                .chunks_exact_mut(4 * w)
                .zip(rgba.chunks_exact(4 * side_w))
            {
                row_out[4 * dst..4 * (dst + x1 - x0)].copy_from_slice(&row_in[4 * x0..4 * x1]);
            }
        }
        Ok(out)
    }

    /// Starts the exact reference of the current frame in a background thread.
    fn start_error_job(&mut self, state: &ViewState) -> Result<()> {
        if self.job.is_some() {
            eprintln!("error overlay: already computing");
            return Ok(());
        }
        if !state.assets.objects.is_empty() {
            // One reference map here; `render --metrics` traces each material's own.
            eprintln!(
                "error overlay: not available for a scene of several objects (use render \
                 --metrics: one entry per material)"
            );
            return Ok(());
        }
        // The rays and hits of the last rendered frame (the current inputs); the
        // reference traces each pixel's own f64 centre ray on the plane and the quad
        // (`Renderer::reference_rays`), so entry errors show too.
        let rays = self.left.reference_rays()?.rays;
        let mut sides = vec![(
            self.left.settings().method.name().to_owned(),
            self.left.read_hits()?,
            self.left.map_geometry(),
        )];
        if let Some(r) = &self.right {
            sides.push((
                r.settings().method.name().to_owned(),
                r.read_hits()?,
                r.map_geometry(),
            ));
        }
        let settings = *self.left.settings();
        let lod = match settings.params.lod_threshold {
            Some(threshold) => {
                let (normals, _) = self.left.read_frames()?;
                let g = self.left.map_geometry();
                lod_pixels(
                    &rays,
                    &normals,
                    settings.width as usize,
                    [g.map_width, g.map_height],
                    settings.scene.addressing() == Addressing::Repeat,
                    threshold,
                )
            }
            None => Vec::new(),
        };
        let field = state.maps[state.map].1.clone();
        let addressing = settings.scene.addressing();
        let done = Arc::new(AtomicUsize::new(0));
        let (tx, rx) = mpsc::channel();
        let total = rays.len();
        let thread_rays = rays.clone();
        let thread_done = done.clone();
        std::thread::Builder::new()
            .name("dispmap-reference".into())
            .spawn(move || {
                let reference = Reference::new(&field, addressing);
                let mut hits = Vec::with_capacity(thread_rays.len());
                for chunk in thread_rays.chunks(4096) {
                    hits.extend(reference.trace(chunk));
                    thread_done.fetch_add(chunk.len(), Ordering::Relaxed);
                }
                // The viewer may have quit meanwhile: nothing to tell then.
                let _ = tx.send(hits);
            })
            .context("cannot start the reference thread")?;
        eprintln!("error overlay: computing the exact reference of {total} pixels...");
        self.job = Some(ErrorJob {
            key: self.frame_key(state),
            done,
            total,
            rx,
            rays,
            sides,
            lod,
        });
        Ok(())
    }

    /// Picks up a finished reference: the overlay when the frame is still the same.
    fn poll_job(&mut self, key: &FrameKey, headless: Option<&mut Headless>) -> Result<()> {
        let Some(job) = &self.job else {
            return Ok(());
        };
        let hits = match job.rx.try_recv() {
            Ok(hits) => hits,
            Err(mpsc::TryRecvError::Empty) => return Ok(()),
            Err(mpsc::TryRecvError::Disconnected) => {
                self.job = None;
                bail!("the reference thread ended without a result");
            }
        };
        let job = self.job.take().context("the job vanished")?;
        if &job.key != key {
            eprintln!(
                "error overlay: the frame changed while the reference was computed; press C again"
            );
            if let Some(h) = headless {
                h.waiting_error = false;
            }
            return Ok(());
        }
        // Pixels level of detail sent to bump mapping are not compared: no ray.
        let compared: Vec<Option<Ray>> = job
            .rays
            .iter()
            .enumerate()
            .map(|(i, r)| r.filter(|_| !job.lod.get(i).copied().unwrap_or(false)))
            .collect();
        let covered = job.rays.iter().filter(|r| r.is_some()).count();
        let lod_count = job
            .rays
            .iter()
            .zip(&job.lod)
            .filter(|(r, l)| r.is_some() && **l)
            .count();
        let mut marks = Vec::new();
        let mut results = Vec::new();
        for (name, gpu, geometry) in &job.sides {
            let e = metrics::hit_errors(gpu, &hits, &compared, *geometry);
            print_error(name, &e, lod_count);
            let mut m = mark_pixels(gpu, &hits, &compared, *geometry);
            for ((mark, ray), lod) in m.iter_mut().zip(&job.rays).zip(&job.lod) {
                if ray.is_some() && *lod {
                    *mark = 3;
                }
            }
            marks.push(m);
            results.push(SideError {
                metrics: e,
                lod_pixels: lod_count,
                covered,
            });
        }
        self.overlay = Some(Overlay {
            key: job.key,
            marks,
            results,
        });
        if let Some(h) = headless {
            h.waiting_error = false;
        }
        Ok(())
    }

    /// Updates the live numbers (the panel's, the window title, and standard error
    /// when interactive).
    fn report(&mut self, state: &ViewState, print: bool) -> Result<()> {
        let secs = self.stats.since.elapsed().as_secs_f64();
        let fps = f64::from(self.stats.frames) / secs.max(1e-9);
        let mut iterations = [None, None];
        for (i, r) in std::iter::once(&self.left)
            .chain(self.right.as_ref())
            .enumerate()
        {
            let hits = r.read_hits()?;
            let covered = heatmap::coverage(&hits, None);
            iterations[i] = Some(heatmap::iteration_stats(&hits, &covered).mean);
        }
        let mean = |side: &[(PassName, f64, u32)]| -> Vec<(PassName, f64)> {
            side.iter()
                .map(|(n, sum, count)| (*n, sum / f64::from((*count).max(1))))
                .collect()
        };
        let passes = |side: &[(PassName, f64)]| {
            side.iter()
                .map(|(n, ms)| format!("{n} {ms:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let shown = [mean(&self.stats.passes[0]), mean(&self.stats.passes[1])];
        let mut gpu = passes(&shown[0]);
        if self.right.is_some() {
            gpu = format!("{gpu} / right: {}", passes(&shown[1]));
        }
        let frame_ms = dispmap::timing::median(&self.stats.frame_wall);
        let s = self.left.settings();
        let mut what = format!("{} {} steps", s.method.name(), s.params.steps);
        if let Some(r) = &self.right {
            what.push_str(&format!(
                " | {} {} steps",
                r.settings().method.name(),
                r.settings().params.steps
            ));
        }
        let progress = self.job.as_ref().map(|j| {
            format!(
                " | reference {:.0}%",
                100.0 * j.done.load(Ordering::Relaxed) as f64 / j.total.max(1) as f64
            )
        });
        let line = format!(
            "{what} | GPU ms: {gpu} | {:.1} iter/px | {:.1} fps, frame {:.1} ms | {}x{} {}{}",
            iterations[0].unwrap_or(0.0),
            fps,
            frame_ms,
            s.width,
            s.height,
            state.maps[state.map].0,
            progress.unwrap_or_default()
        );
        self.window.set_title(&title(state));
        // Standard error one update in four (every 2 s).
        if print && self.stats.updates.is_multiple_of(4) {
            eprintln!("{line}");
        }
        if self.stats.frames > 0 {
            self.stats.shown_passes = shown;
            self.stats.shown_fps = fps;
            self.stats.shown_frame_ms = frame_ms;
        }
        self.stats.shown_iterations = iterations;
        self.stats.updates += 1;
        self.stats.since = Instant::now();
        self.stats.frames = 0;
        self.stats.passes = [Vec::new(), Vec::new()];
        self.stats.render_wall.clear();
        self.stats.frame_wall.clear();
        Ok(())
    }

    /// The headless run's timing summary.
    fn summary(&self, headless: Option<&Headless>) {
        // The first frames build pipelines and upload the map: left out when there are
        // enough frames.
        let skip = if self.stats.all_frame.len() > 4 { 2 } else { 0 };
        let render = dispmap::timing::median(&self.stats.all_render[skip..]);
        let frame = dispmap::timing::median(&self.stats.all_frame[skip..]);
        let gpu = dispmap::timing::median(&self.stats.all_gpu[skip..]);
        let (asked, waited) = headless.map_or((self.frame_index, 0), |h| (h.frames, h.waited));
        let waited = if waited > 0 {
            format!(" (and {waited} rendered again while waiting for a resize or the overlay)")
        } else {
            String::new()
        };
        eprintln!(
            "frames: {asked}{waited}, median ms per frame: GPU (left side's passes) {gpu:.2}, \
             wall: render {render:.2}, render + present {frame:.2} (first {skip} left out)",
        );
        if self.gui.is_some() {
            let cpu_skip = skip.min(self.stats.all_ui_cpu.len());
            let gpu_skip = skip.min(self.stats.all_ui_gpu.len());
            eprintln!(
                "panel: median ms per frame: CPU {:.3} (egui, tessellation, uploads, \
                 recording), GPU {:.3} (its draw)",
                dispmap::timing::median(&self.stats.all_ui_cpu[cpu_skip..]),
                dispmap::timing::median(&self.stats.all_ui_gpu[gpu_skip..]),
            );
        }
    }

    fn key(&mut self, state: &mut ViewState, event: &KeyEvent) -> Result<bool> {
        if event.state != ElementState::Pressed {
            return Ok(false);
        }
        let PhysicalKey::Code(code) = event.physical_key else {
            return Ok(false);
        };
        let shift = self.modifiers.shift_key();
        if let KeyCode::KeyW | KeyCode::KeyS = code {
            let lines = if code == KeyCode::KeyW { 1.0 } else { -1.0 };
            zoom(&mut state.settings.scene, lines);
            return Ok(false);
        }
        let camera = &mut state.settings.scene.camera;
        match code {
            KeyCode::Escape => return Ok(true),
            KeyCode::Tab => state.panel = !state.panel,
            KeyCode::F1 => state.help = !state.help,
            KeyCode::KeyX => {
                if state.right.is_none() {
                    state.right = Some(cycle(state.settings.method, false));
                }
                state.compare = state.compare.next();
            }
            KeyCode::Space => {
                if state.right.is_none() {
                    state.right = Some(cycle(state.settings.method, false));
                }
                if state.compare == Compare::Flip {
                    state.show_b = !state.show_b;
                } else {
                    state.compare = Compare::Flip;
                }
            }
            KeyCode::KeyA => camera.azimuth_deg -= 5.0,
            KeyCode::KeyD => camera.azimuth_deg += 5.0,
            KeyCode::KeyQ => tilt(camera, -if shift { 0.5 } else { 2.0 }),
            KeyCode::KeyE => tilt(camera, if shift { 0.5 } else { 2.0 }),
            KeyCode::KeyR => *camera = state.home,
            KeyCode::KeyM => {
                state.settings.method = cycle(state.settings.method, shift);
                state.settings.params.steps =
                    state.steps.unwrap_or(state.settings.method.default_steps());
            }
            KeyCode::KeyN => {
                let from = state.right.unwrap_or(state.settings.method);
                state.right = Some(cycle(from, shift));
            }
            KeyCode::KeyV => {
                state.right = match state.right {
                    Some(_) => None,
                    None => Some(cycle(state.settings.method, false)),
                }
            }
            KeyCode::BracketLeft => state.divider = (state.divider - 0.05).max(0.0),
            KeyCode::BracketRight => state.divider = (state.divider + 0.05).min(1.0),
            KeyCode::Equal | KeyCode::NumpadAdd | KeyCode::Minus | KeyCode::NumpadSubtract => {
                let up = matches!(code, KeyCode::Equal | KeyCode::NumpadAdd);
                let now = state.settings.params.steps.max(1);
                let delta = (now / 8).max(1);
                let steps = if up {
                    now + delta
                } else {
                    now.saturating_sub(delta).max(1)
                };
                state.steps = Some(steps);
                state.settings.params.steps = steps;
            }
            KeyCode::PageUp => state.settings.scene.depth_scale *= 1.25,
            KeyCode::PageDown => state.settings.scene.depth_scale /= 1.25,
            KeyCode::KeyH => {
                state.settings.shadows = ShadowSettings {
                    mode: match state.settings.shadows.mode {
                        ShadowMode::Off => ShadowMode::Hard,
                        ShadowMode::Hard => ShadowMode::Soft,
                        ShadowMode::Soft => ShadowMode::Off,
                    },
                    ..state.settings.shadows
                }
            }
            KeyCode::KeyL => {
                const LEVELS: [Option<f32>; 5] = [None, Some(0.0), Some(1.0), Some(2.0), Some(3.0)];
                let i = LEVELS
                    .iter()
                    .position(|l| *l == state.settings.params.lod_threshold)
                    .map_or(0, |i| (i + 1) % LEVELS.len());
                state.settings.params.lod_threshold = LEVELS[i];
            }
            KeyCode::KeyF => {
                let p = &mut state.settings.params;
                p.refine_steps = if shift {
                    p.refine_steps.saturating_sub(1)
                } else {
                    p.refine_steps + 1
                };
            }
            KeyCode::KeyO => {
                let p = &mut state.settings.params;
                p.min_steps = if shift {
                    p.min_steps.saturating_sub(4).max(1)
                } else {
                    p.min_steps + 4
                };
            }
            KeyCode::KeyJ => {
                let p = &mut state.settings.params;
                p.segments = if shift {
                    p.segments.saturating_sub(1).max(1)
                } else {
                    p.segments + 1
                };
            }
            KeyCode::KeyB => {
                let p = &mut state.settings.params;
                let side = match p.block[0] {
                    2 => 4,
                    4 => 8,
                    _ => 2,
                };
                p.block = [side, side];
            }
            KeyCode::KeyK => {
                let p = &mut state.settings.params;
                p.max_level = match p.max_level {
                    MaxLevel::Fixed(l) if l < 3 => MaxLevel::Fixed(l + 1),
                    MaxLevel::Fixed(_) => MaxLevel::Auto,
                    MaxLevel::Auto => MaxLevel::Fixed(0),
                };
            }
            KeyCode::KeyG => {
                let shadows = &mut state.settings.shadows;
                shadows.samples = if shift {
                    (shadows.samples / 2).max(1)
                } else {
                    shadows.samples.saturating_mul(2)
                };
            }
            KeyCode::KeyT => switch_map(state, None)?,
            KeyCode::KeyI => state.heatmap = !state.heatmap,
            KeyCode::KeyC => self.error_requested = true,
            KeyCode::KeyP | KeyCode::F12 => {
                self.screenshots_taken += 1;
                let path = next_screenshot_path(self.screenshots_taken);
                self.screenshot_next = Some(path);
            }
            _ => return Ok(false),
        }
        Ok(false)
    }

    fn mouse_button(&mut self, button: MouseButton, pressed: bool) {
        match button {
            MouseButton::Left => self.orbiting = pressed,
            MouseButton::Right => self.dragging_divider = pressed,
            _ => {}
        }
    }

    fn cursor(&mut self, state: &mut ViewState, at: [f32; 2]) {
        if let Some(prev) = self.cursor {
            let (dx, dy) = (at[0] - prev[0], at[1] - prev[1]);
            if self.orbiting {
                let c = &mut state.settings.scene.camera;
                c.azimuth_deg -= dx * 0.3;
                tilt(c, dy * 0.2);
            }
        }
        if self.dragging_divider {
            let w = self.window.inner_size().width.max(1) as f32;
            state.divider = (at[0] / w).clamp(0.0, 1.0);
        }
        self.cursor = Some(at);
    }
}

/// The settings of a side showing `method`, with the frame size of `want`.
fn side_of(want: &RenderSettings, state: &ViewState, method: Method) -> RenderSettings {
    let mut s = state.side(method);
    (s.width, s.height) = (want.width, want.height);
    s
}

/// Brings one renderer to `want` with the cheapest calls (size, method, shadows, scene).
fn apply(r: &mut Renderer, want: &RenderSettings) -> Result<()> {
    let have = *r.settings();
    if (have.width, have.height) != (want.width, want.height) {
        r.resize(want.width, want.height)?;
    }
    if (have.method, have.params) != (want.method, want.params) {
        r.set_method(want.method, want.params)?;
    }
    if have.shadows != want.shadows {
        r.set_shadows(want.shadows)?;
    }
    if have.scene != want.scene {
        r.set_scene(want.scene)?;
    }
    Ok(())
}

/// The next (or, `back`, previous) method in [`Method::ALL`].
fn cycle(m: Method, back: bool) -> Method {
    let all = Method::ALL;
    let i = all.iter().position(|x| *x == m).unwrap_or(0);
    let n = all.len();
    all[if back { (i + n - 1) % n } else { (i + 1) % n }]
}

/// Moves the eye toward (`lines > 0`) or away from the target: on the tiled plane the
/// eye height, on the quad and the meshes the orbit distance, by 10% a line.
fn zoom(scene: &mut Scene, lines: f32) {
    let camera = &mut scene.camera;
    match scene.geometry {
        Geometry::TiledPlane => {
            camera.height = (camera.height * 0.9f32.powf(lines)).clamp(0.01, 100.0);
        }
        _ => {
            let d = scene.orbit_distance() * 0.9f32.powf(lines);
            set_distance(scene, d);
        }
    }
}

/// Sets the orbit distance: on the tiled plane through the eye height (at the current
/// elevation), elsewhere directly; within the zoom's limits.
fn set_distance(scene: &mut Scene, distance: f32) {
    let camera = &mut scene.camera;
    match scene.geometry {
        Geometry::TiledPlane => {
            let sin = camera.elevation_deg.to_radians().sin().max(1e-6);
            camera.height = (distance * sin).clamp(0.01, 100.0);
        }
        _ => camera.distance = Some(distance.clamp(0.05, 1000.0)),
    }
}

/// The window's title: the methods shown.
fn title(state: &ViewState) -> String {
    match state.right {
        Some(r) => format!(
            "dispmap view: {} | {}",
            state.settings.method.name(),
            r.name()
        ),
        None => format!("dispmap view: {}", state.settings.method.name()),
    }
}

/// Appends a frame's milliseconds to a rolling graph of [`HISTORY`] frames.
fn push_history(history: &mut VecDeque<f32>, ms: f64) {
    if history.len() == HISTORY {
        history.pop_front();
    }
    history.push_back(ms as f32);
}

/// Each side's frame size and where the sides' columns go in a frame of `frame`
/// pixels, for the compare mode of `state`.
fn frame_layout(state: &ViewState, frame: [u32; 2]) -> ([u32; 2], Layout) {
    let [w, h] = frame;
    let extent = vk::Extent2D {
        width: w,
        height: h,
    };
    let part = |side, src_x0, src_x1, dst_x| Part {
        side,
        src_x0,
        src_x1,
        dst_x,
    };
    let (size, parts) = match (state.right, state.compare) {
        (None, _) => (frame, vec![part(0, 0, w, 0)]),
        (Some(_), Compare::Flip) => (frame, vec![part(usize::from(state.show_b), 0, w, 0)]),
        (Some(_), Compare::Wipe) => {
            let d = ((state.divider * w as f32).round() as u32).min(w);
            let d_end = (d + DIVIDER_PX).min(w);
            (frame, vec![part(0, 0, d, 0), part(1, d_end, w, d_end)])
        }
        (Some(_), Compare::SideBySide) => {
            let half = (w.saturating_sub(DIVIDER_PX) / 2).max(1);
            (
                [half, h],
                vec![
                    part(0, 0, half, 0),
                    part(1, 0, half, w.saturating_sub(half)),
                ],
            )
        }
    };
    (
        size,
        Layout {
            frame: extent,
            parts,
        },
    )
}

/// The pixels level of detail sends (wholly or in part) to bump mapping at
/// `threshold`: those whose footprint level exceeds `threshold - 1` (`trace_lod` in
/// glsl/common/trace.glsl blends from there). The level is the CPU twin of
/// `footprint_level` there: log2 of the larger uv step in texels to the right / lower
/// neighbour (left / upper at the last column / row) on the same surface (`normals`'
/// w), tile wraps removed under repeat addressing; pixels within 1e-3 of the boundary
/// count as sent (the GPU's f32 level may fall on either side), except a magnified
/// pixel (at most one texel: level exactly 0), which only a threshold below 1 sends.
fn lod_pixels(
    rays: &[Option<Ray>],
    normals: &[[f32; 4]],
    width: usize,
    map: [u32; 2],
    repeat: bool,
    threshold: f32,
) -> Vec<bool> {
    let height = rays.len() / width.max(1);
    let from = f64::from(threshold) - 1.0 - 1e-3;
    (0..rays.len())
        .map(|i| {
            let Some(ray) = &rays[i] else {
                return false;
            };
            let (x, y) = (i % width, i / width);
            let mut texels: f64 = 0.0;
            for (q, inside) in [
                (
                    if x + 1 < width {
                        i + 1
                    } else {
                        i.wrapping_sub(1)
                    },
                    width > 1,
                ),
                (
                    if y + 1 < height {
                        i + width
                    } else {
                        i.wrapping_sub(width)
                    },
                    height > 1,
                ),
            ] {
                if !inside || normals.get(q).map(|n| n[3]) != normals.get(i).map(|n| n[3]) {
                    continue;
                }
                let Some(n) = rays.get(q).and_then(Option::as_ref) else {
                    continue;
                };
                let mut d = [n.uv0[0] - ray.uv0[0], n.uv0[1] - ray.uv0[1]];
                if repeat {
                    for c in &mut d {
                        *c -= c.round();
                    }
                }
                texels = texels.max((d[0] * f64::from(map[0])).hypot(d[1] * f64::from(map[1])));
            }
            if texels <= 1.0 {
                threshold < 1.0
            } else {
                texels.log2() > from
            }
        })
        .collect()
}

/// Changes the elevation within `[MIN_ELEVATION, 90]` degrees.
fn tilt(camera: &mut Camera, degrees: f32) {
    camera.elevation_deg = (camera.elevation_deg + degrees).clamp(MIN_ELEVATION, 90.0);
}

/// Switches to the named bundled map, or (`None`) to the next map in turn: the given
/// map first, then the bundled ones.
fn switch_map(state: &mut ViewState, name: Option<&str>) -> Result<()> {
    let target = match name {
        Some(n) => n.to_owned(),
        None => {
            let given = state.maps[0].0.clone();
            let mut order = vec![given.clone()];
            order.extend(
                bundled::NAMES
                    .iter()
                    .filter(|n| **n != given)
                    .map(|n| (*n).to_owned()),
            );
            let current = &state.maps[state.map].0;
            let i = order.iter().position(|o| o == current).unwrap_or(0);
            order[(i + 1) % order.len()].clone()
        }
    };
    if let Some(i) = state.maps.iter().position(|(n, _)| *n == target) {
        state.map = i;
        return Ok(());
    }
    let field = bundled::by_name(&target, "map")?;
    state.maps.push((target, Arc::new(field)));
    state.map = state.maps.len() - 1;
    Ok(())
}

/// Per pixel: 0 fine (or no geometry), 1 an artifact (more than [`ARTIFACT_TEXELS`]
/// off), 2 a miss (exactly one of method and reference hits) or a non-finite hit: the
/// classes of [`metrics::hit_errors`].
fn mark_pixels(
    gpu: &[HitTexel],
    reference: &[Option<Hit>],
    rays: &[Option<Ray>],
    geometry: MapGeometry,
) -> Vec<u8> {
    gpu.iter()
        .zip(reference)
        .zip(rays)
        .map(|((t, r), ray)| {
            if ray.is_none() {
                return 0;
            }
            if !t.iter().all(|c| c.is_finite()) {
                return 2;
            }
            match (t[2] >= 0.0, r) {
                (true, Some(hit)) => {
                    u8::from(metrics::hit_distance_texels(t, hit, geometry) > ARTIFACT_TEXELS)
                }
                (false, None) => 0,
                _ => 2,
            }
        })
        .collect()
}

fn print_error(name: &str, e: &ErrorMetrics, lod: usize) {
    let lod = if lod > 0 {
        format!(", {lod} more sent to bump mapping by level of detail (magenta, not compared)")
    } else {
        String::new()
    };
    eprintln!(
        "error overlay: {name}: mean {:.3} texels, p99 {:.3}, max {:.3}, artifacts {:.3}% \
         (red: more than {ARTIFACT_TEXELS} texel off; cyan: misses), {} pixels, non-finite \
         {}{lod}",
        e.mean_texels,
        e.p99_texels,
        e.max_texels,
        100.0 * e.artifact_fraction,
        e.compared_pixels,
        e.nonfinite_pixels
    );
}

/// `dispmap-view-N.png` in the current folder, the first N not taken.
fn next_screenshot_path(from: u32) -> PathBuf {
    (from..)
        .map(|n| PathBuf::from(format!("dispmap-view-{n}.png")))
        .find(|p| !Path::new(p).exists())
        .unwrap_or_else(|| PathBuf::from("dispmap-view.png"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dispmap::method::MethodParams;

    fn state(right: Option<Method>, compare: Compare) -> ViewState {
        let settings = RenderSettings {
            width: 100,
            height: 40,
            method: Method::Relief,
            params: MethodParams::default(),
            scene: Scene::default(),
            shadows: ShadowSettings::default(),
        };
        ViewState {
            maps: Vec::new(),
            map: 0,
            assets: SceneAssets::default(),
            settings,
            steps: None,
            right,
            divider: 0.5,
            compare,
            show_b: true,
            heatmap: false,
            home: settings.scene.camera,
            panel: true,
            help: false,
        }
    }

    fn part(side: usize, src_x0: u32, src_x1: u32, dst_x: u32) -> Part {
        Part {
            side,
            src_x0,
            src_x1,
            dst_x,
        }
    }

    #[test]
    fn each_compare_mode_lays_out_its_sides() {
        let frame = [100, 40];
        let (size, l) = frame_layout(&state(None, Compare::Wipe), frame);
        assert!(!l.has_gaps());
        assert_eq!((size, l.parts), (frame, vec![part(0, 0, 100, 0)]));
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::Wipe), frame);
        assert_eq!(size, frame);
        assert_eq!(l.parts, vec![part(0, 0, 50, 0), part(1, 52, 100, 52)]);
        assert!(l.has_gaps());
        // A/B: the shown side fills the frame, the same pixels as a frame of its own.
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::Flip), frame);
        assert_eq!((size, l.parts), (frame, vec![part(1, 0, 100, 0)]));
        // Side by side: each renderer at half the width less the divider.
        let (size, l) = frame_layout(&state(Some(Method::Pom), Compare::SideBySide), frame);
        assert_eq!(size, [49, 40]);
        assert_eq!(l.parts, vec![part(0, 0, 49, 0), part(1, 0, 49, 51)]);
    }

    #[test]
    fn level_of_detail_sends_minified_pixels_past_the_band() {
        // One row of four pixels over a 64-texel map: uv steps of 0.5, 3, 12 texels.
        let ray = |u: f64| {
            Some(Ray {
                uv0: [u, 0.0],
                parallax: [0.0, 0.0],
            })
        };
        let t = 1.0 / 64.0;
        let rays = [ray(0.0), ray(0.5 * t), ray(3.5 * t), ray(15.5 * t)];
        let normals = [[0.0, 1.0, 0.0, 0.0]; 4];
        let sent = |threshold| lod_pixels(&rays, &normals, 4, [64, 64], true, threshold);
        // Levels: 0 (magnified), 1.58, 3.58, 3.58 (the last pixel looks left); a pixel
        // is sent above threshold - 1.
        assert_eq!(sent(1.0), vec![false, true, true, true]);
        assert_eq!(sent(3.0), vec![false, false, true, true]);
        assert_eq!(sent(5.0), vec![false, false, false, false]);
        // Below 1 every pixel blends toward bump mapping.
        assert_eq!(sent(0.5), vec![true; 4]);
        // Another surface's neighbour is not a neighbour.
        let mut split = normals;
        split[2][3] = 1.0;
        let sent = lod_pixels(&rays, &split, 4, [64, 64], true, 3.0);
        assert_eq!(sent, vec![false, false, false, false]);
    }
}
