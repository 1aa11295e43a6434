//! The live numbers: GPU times per pass, frame rate, the rolling graph and the headless
//! run's timing summary.

use super::HISTORY;
use super::headless::Headless;
use super::state::{ViewState, title};
use super::viewer::Viewer;
use anyhow::Result;
use dispmap::passes::PassName;
use dispmap_cli::heatmap;
use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Live numbers, accumulated between updates.
pub(super) struct Stats {
    pub(super) since: Instant,
    pub(super) frames: u32,
    /// Per side (left, right) and pass: sum of milliseconds and count, in pass order.
    pub(super) passes: [Vec<(PassName, f64, u32)>; 2],
    /// Updates since the numbers were last printed.
    pub(super) updates: u32,
    /// Wall milliseconds of `Renderer::render` (all sides) and of the whole frame.
    pub(super) render_wall: Vec<f64>,
    pub(super) frame_wall: Vec<f64>,
    /// Every frame's wall times, for the headless summary.
    pub(super) all_render: Vec<f64>,
    pub(super) all_frame: Vec<f64>,
    /// Every frame's GPU milliseconds (the left side's passes, one-off passes left
    /// out), for the headless summary.
    pub(super) all_gpu: Vec<f64>,
    /// Every frame's panel cost: CPU and GPU milliseconds.
    pub(super) all_ui_cpu: Vec<f64>,
    pub(super) all_ui_gpu: Vec<f64>,
    /// What the panel shows, from the last update: per side the mean milliseconds per
    /// pass and the mean iterations per pixel; frames per second; median frame time.
    pub(super) shown_passes: [Vec<(PassName, f64)>; 2],
    pub(super) shown_iterations: [Option<f64>; 2],
    pub(super) shown_fps: f64,
    pub(super) shown_frame_ms: f64,
    /// The panel's cost in the last frame.
    pub(super) last_ui: (f64, Option<f64>),
}

impl Stats {
    pub(super) fn new() -> Self {
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

    pub(super) fn add(&mut self, side: usize, times: &[(PassName, f64)]) {
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
    /// Updates the live numbers (the panel's, the window title, and standard error
    /// when interactive).
    pub(super) fn report(&mut self, state: &ViewState, print: bool) -> Result<()> {
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
    pub(super) fn summary(&self, headless: Option<&Headless>) {
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
            if self.dock_px > 0 {
                eprintln!(
                    "panel: docked at the right edge, {} px wide (the sides share the {} \
                     columns left of it)",
                    self.dock_px,
                    self.presenter.extent().width.saturating_sub(self.dock_px)
                );
            }
            if !self.panel_listed.is_empty() {
                eprintln!("panel: {} objects listed:", self.panel_listed.len());
                for line in &self.panel_listed {
                    eprintln!("  {line}");
                }
            }
        }
    }
}

/// Appends a frame's milliseconds to a rolling graph of [`HISTORY`] frames.
pub(super) fn push_history(history: &mut VecDeque<f32>, ms: f64) {
    if history.len() == HISTORY {
        history.pop_front();
    }
    history.push_back(ms as f32);
}
