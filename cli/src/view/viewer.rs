//! The viewer's GPU objects (renderers, presenter, panel) and one frame, from the
//! script and camera to the presented image.

use super::app::Flow;
use super::compose::frame_layout;
use super::headless::Headless;
use super::input::{next_screenshot_path, set_object_map, switch_map};
use super::overlay::{ErrorJob, Overlay};
use super::present::{Presenter, Source};
use super::script::{Action, CameraPath};
use super::state::{
    MaterialEdit, Snapshot, ViewState, build_renderer, material_lines, side_of, title,
};
use super::stats::{Stats, push_history};
use super::{RESIZE_TIMEOUT, STATS_PERIOD};
use super::{budget, panel, present, ui};
use crate::finish;
use anyhow::{Context as _, Result, bail};
use dispmap::context::{Context, ContextOptions};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap_cli::{memory, output};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::dpi::PhysicalSize;
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::ModifiersState;
use winit::window::Window;

/// What a frame depends on: the overlay is dropped when any of it changes.
#[derive(Clone, PartialEq)]
pub(super) struct FrameKey {
    pub(super) settings: Vec<RenderSettings>,
    pub(super) map: usize,
}

pub(super) struct Viewer {
    // Field order is drop order; `shutdown` destroys the GPU objects explicitly first.
    /// The on-screen panel (`None` with `--no-ui`).
    pub(super) gui: Option<ui::Gui>,
    pub(super) presenter: Presenter,
    pub(super) left: Renderer,
    pub(super) right: Option<Renderer>,
    pub(super) ctx: Arc<Context>,
    pub(super) window: Arc<Window>,
    pub(super) modifiers: ModifiersState,
    /// The cursor position and which buttons are held.
    pub(super) cursor: Option<[f32; 2]>,
    pub(super) orbiting: bool,
    pub(super) dragging_divider: bool,
    pub(super) frame_index: u32,
    pub(super) screenshot_next: Option<PathBuf>,
    pub(super) screenshots_taken: u32,
    pub(super) stats: Stats,
    pub(super) overlay: Option<Overlay>,
    pub(super) job: Option<ErrorJob>,
    /// The map index the renderers were built for.
    pub(super) built_map: usize,
    /// The objects' materials the renderers were built with (a scene of several objects).
    pub(super) built_materials: Vec<Option<MaterialEdit>>,
    /// Columns at the right of the window the panel takes in split view (0: it floats
    /// over the frame, or is hidden).
    pub(super) dock_px: u32,
    /// The material lines the panel showed last (for the headless summary).
    pub(super) panel_listed: Vec<String>,
    /// The window size the swapchain was last made for.
    pub(super) window_size: [u32; 2],
    /// A window above the memory bound and the smaller frame rendered for it
    /// ([`super::budget::Bound::fit`]), once said.
    pub(super) fitted: Option<([u32; 2], [u32; 2])>,
    /// The error overlay was asked for: its reference starts after the next render.
    pub(super) error_requested: bool,
    /// The last state the renderers accepted.
    pub(super) good: Option<Snapshot>,
    /// Each side's GPU milliseconds of the last [`HISTORY`] frames.
    pub(super) history: [VecDeque<f32>; 2],
    /// The heat map's top count per side, when it is shown.
    pub(super) heat_scales: [Option<f32>; 2],
    /// The last screenshot's line, shown in the panel for a few seconds.
    pub(super) notice: Option<(String, Instant)>,
}

impl Viewer {
    pub(super) fn new(
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
            // The window system may give more than was asked: kept under the bound.
            let window = [extent.width, extent.height];
            [settings.width, settings.height] = state.bound.fit(&budget::Sizing::of(state), window);
        }
        let build = |s: RenderSettings| build_renderer(&ctx, state, s);
        let left = match build(settings) {
            Ok(r) => r,
            Err(e) => {
                let mut presenter = presenter;
                // SAFETY: this thread alone submits with the presenter; the window lives.
                unsafe { presenter.destroy(&ctx) };
                return Err(e);
            }
        };
        let right = match state.right.map(|m| build(side_of(&settings, state, m))) {
            Some(Err(e)) => {
                let mut presenter = presenter;
                // SAFETY: this thread alone submits with the presenter; the window lives.
                unsafe { presenter.destroy(&ctx) };
                drop(left);
                return Err(e);
            }
            Some(Ok(r)) => Some(r),
            None => None,
        };
        let gui = match ui.then(|| ui::Gui::new(&ctx, &window, presenter.format())) {
            Some(Err(e)) => {
                let mut presenter = presenter;
                // SAFETY: this thread alone submits with the presenter; the window lives.
                unsafe { presenter.destroy(&ctx) };
                drop((left, right));
                return Err(e);
            }
            Some(Ok(g)) => Some(g),
            None => None,
        };
        let objects = material_lines(state);
        let shown = if objects.is_empty() {
            state.maps[state.map].0.clone()
        } else {
            format!("a scene of {} objects", objects.len())
        };
        eprintln!(
            "dispmap view: {} on {} ({}), {}x{}, {:?}{}",
            shown,
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
        for line in &objects {
            eprintln!("  {line}");
        }
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
            built_materials: state.materials.clone(),
            dock_px: 0,
            panel_listed: Vec::new(),
            window_size: [size.width, size.height],
            fitted: None,
            error_requested: false,
            good: None,
            history: [VecDeque::new(), VecDeque::new()],
            heat_scales: [None, None],
            notice: None,
        })
    }

    /// Waits for the device, destroys the swapchain and surface, drops the renderers,
    /// then the context (failing on any validation message, as every command does).
    pub(super) fn shutdown(self) -> Result<()> {
        let Viewer {
            gui,
            mut presenter,
            left,
            right,
            ctx,
            window,
            ..
        } = self;
        // SAFETY: a plain wait on the context's live device.
        let _ = unsafe { ctx.device().device_wait_idle() };
        if let Some(mut gui) = gui {
            // SAFETY: the device is idle (waited above): no frame uses the panel's objects.
            unsafe { gui.destroy(&ctx) };
        }
        // SAFETY: the device is idle (waited above) and this thread alone submits; the
        // window is dropped after.
        unsafe { presenter.destroy(&ctx) };
        drop(right);
        drop(left);
        let result = finish(ctx);
        drop(window);
        result
    }

    /// Brings the renderers in line with `state` (map, methods, settings, size); errors
    /// of a change the user asked for are printed and the change undone where possible.
    pub(super) fn sync(&mut self, state: &mut ViewState, size: [u32; 2]) -> Result<()> {
        let mut want = state.settings;
        (want.width, want.height) = (size[0], size[1]);
        if self.built_map != state.map || self.built_materials != state.materials {
            // A new map, or an object's material edited: new renderers (the pass keeps
            // its maps for its lifetime here, and each object's depth scale is the
            // G-buffer's).
            let left = build_renderer(&self.ctx, state, want)?;
            let right = state
                .right
                .map(|m| build_renderer(&self.ctx, state, side_of(&want, state, m)))
                .transpose()?;
            self.left = left;
            self.right = right;
            self.built_map = state.map;
            self.built_materials = state.materials.clone();
        }
        apply(&mut self.left, &want)?;
        match (state.right, self.right.as_mut()) {
            (None, _) => self.right = None,
            (Some(m), Some(r)) => apply(r, &side_of(&want, state, m))?,
            (Some(m), None) => {
                self.right = Some(build_renderer(&self.ctx, state, side_of(&want, state, m))?);
            }
        }
        Ok(())
    }

    /// The frame rendered for a window of `window` pixels: the window's size, or under
    /// the memory bound the largest frame of its shape that fits (scaled to the window
    /// when presented), said on the console and in the panel when it starts.
    fn fit(&mut self, state: &ViewState, window: [u32; 2]) -> [u32; 2] {
        let frame = state.bound.fit(&budget::Sizing::of(state), window);
        let fitted = (frame != window).then_some((window, frame));
        if fitted.is_some() && fitted != self.fitted {
            let limit = state.bound.limit.unwrap_or(0);
            let line = format!(
                "the {}x{} window needs more than the {} of {}: rendering {}x{}, scaled \
                 to the window",
                window[0],
                window[1],
                memory::human(limit),
                state.bound.source(),
                frame[0],
                frame[1]
            );
            eprintln!("view: {line}");
            self.notice = Some((line, Instant::now()));
        }
        self.fitted = fitted;
        frame
    }

    pub(super) fn frame_key(&self, state: &ViewState) -> FrameKey {
        let mut settings = vec![*self.left.settings()];
        if let Some(r) = &self.right {
            settings.push(*r.settings());
        }
        FrameKey {
            settings,
            map: state.map,
        }
    }

    pub(super) fn frame(
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
        let window = [e.width, e.height];
        let frame = self.fit(state, window);
        // In split view the panel takes a column at the right instead of covering a side:
        // its width in the window's pixels, and the same columns of the frame (which the
        // memory bound may render smaller, scaled to the window).
        self.dock_px = match &self.gui {
            Some(gui) if state.panel && state.right.is_some() => {
                dock_width(window[0], gui.egui.pixels_per_point())
            }
            _ => 0,
        };
        let dock = (u64::from(self.dock_px) * u64::from(frame[0]))
            .div_ceil(u64::from(window[0].max(1))) as u32;
        if let Err(err) = self.sync(state, frame_layout(state, frame, dock).0) {
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
            self.sync(state, frame_layout(state, frame, dock).0)?;
        }
        self.good = Some(Snapshot::of(state));
        let layout = frame_layout(state, frame, dock).1;

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
                    if r.object_map.is_some() {
                        requests.object_map = r.object_map;
                    }
                    requests.listed = r.listed;
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
            if let Some((object, name)) = requests.object_map {
                set_object_map(state, object, &name)?;
            }
            self.panel_listed = requests.listed;
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
}

/// Widest the docked panel gets, in points.
const DOCK_POINTS: f32 = 300.0;

/// Columns the docked panel takes on a window `width` pixels wide: [`DOCK_POINTS`], but
/// at most 40% of the window (the panel narrows on a narrow window).
pub(super) fn dock_width(width: u32, pixels_per_point: f32) -> u32 {
    let want = (DOCK_POINTS * pixels_per_point).ceil() as u32;
    want.min(width * 2 / 5)
}

/// Brings one renderer to `want` with the cheapest calls (size, method, shadows, scene).
pub(super) fn apply(r: &mut Renderer, want: &RenderSettings) -> Result<()> {
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
