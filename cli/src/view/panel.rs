//! What the on-screen panel shows and lets the user change: the methods and their
//! parameters, the scene, the camera, the timings with their rolling graph, the error
//! overlay's results with its legend, the heat map's colour bar; the labels of the split
//! sides and the help overlay of the keys.

use super::{ARTIFACT_RGBA, Compare, LOD_RGBA, MIN_ELEVATION, MISS_RGBA, ViewState};
use dispmap::method::{MaxLevel, Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::passes::shadow::ShadowMode;
use dispmap_cli::heatmap;
use dispmap_cli::metrics::{ARTIFACT_TEXELS, ErrorMetrics};
use egui::{Align2, Color32, FontId, Pos2, Rect, Sense, Stroke, Vec2};

/// Every key and mouse control, as the help overlay lists them (docs/viewer.md has the
/// same table).
pub const KEYS: &[(&str, &str)] = &[
    ("left drag", "orbit: azimuth, elevation"),
    (
        "wheel, W / S",
        "zoom: the eye moves toward / away from the target",
    ),
    ("A / D", "orbit left / right by 5 degrees"),
    ("Q / E", "elevation down / up by 2 degrees (Shift: 0.5)"),
    ("R", "reset the camera"),
    ("M / Shift+M", "next / previous method (left side)"),
    ("V", "split view on / off"),
    ("N / Shift+N", "next / previous method on the right side"),
    ("X", "compare: wipe, A/B flip, side by side"),
    ("Space", "A/B: show the other method on the same pixels"),
    ("right drag, [ / ]", "move the divider (wipe)"),
    ("+ / -", "more / fewer steps"),
    ("PageUp / PageDown", "depth scale up / down by 25%"),
    ("F / Shift+F", "refine steps +1 / -1"),
    ("O / Shift+O", "pom's minimum steps +4 / -4"),
    ("J / Shift+J", "secant's segments +1 / -1"),
    ("B", "DIG block size: 2, 4, 8"),
    ("K", "pyramid's coarsest level: 0, 1, 2, 3, auto"),
    ("H", "shadows: off, hard, soft"),
    ("G / Shift+G", "soft-shadow samples x2 / /2"),
    ("L", "level of detail: off, 0, 1, 2, 3"),
    ("T", "next map"),
    ("I", "iteration heat map"),
    ("C", "error overlay (exact CPU reference)"),
    ("P, F12", "screenshot (dispmap-view-N.png)"),
    ("Tab", "hide / show the panel"),
    ("F1", "this help"),
    ("Esc", "quit"),
];

/// Height in points of the band at the bottom of the window where the side labels go.
const LABEL_BAND: f32 = 28.0;

/// One side's numbers.
pub struct SideInfo {
    /// Its method.
    pub method: Method,
    /// Mean GPU milliseconds per pass over the last update period, in pass order.
    pub passes: Vec<(PassName, f64)>,
    /// Mean iterations per covered pixel of the last frame read.
    pub iterations: Option<f64>,
    /// The heat map's top count when the heat map is shown.
    pub heat_scale: Option<f32>,
    /// The error overlay's results for this side.
    pub error: Option<SideError>,
}

impl SideInfo {
    /// Sum of the pass means.
    pub fn gpu_ms(&self) -> f64 {
        self.passes.iter().map(|(_, ms)| ms).sum()
    }
}

/// The error overlay's measures for a side.
#[derive(Clone, Copy)]
pub struct SideError {
    /// The metrics of `render --metrics` (over the pixels level of detail leaves to the
    /// method).
    pub metrics: ErrorMetrics,
    /// Pixels level of detail sent (wholly or in part) to bump mapping.
    pub lod_pixels: usize,
    /// Pixels with geometry.
    pub covered: usize,
}

/// The error overlay's state.
pub enum OverlayState {
    /// Not asked for, or cleared.
    Off,
    /// The reference is being computed: the fraction done.
    Computing(f32),
    /// Shown.
    Shown,
}

/// What the panel shows besides the state it edits.
pub struct Info {
    /// Left, and right in split view.
    pub sides: Vec<SideInfo>,
    /// Frames per second over the last update period (`None` until the first one).
    pub fps: Option<f64>,
    /// Median wall milliseconds of a frame (`None` until the first update).
    pub frame_ms: Option<f64>,
    /// Each side's total GPU milliseconds of the recent frames, oldest first.
    pub history: [Vec<f32>; 2],
    /// The error overlay.
    pub overlay: OverlayState,
    /// The panel's own cost in the last frame: CPU and GPU milliseconds.
    pub panel_ms: (f64, Option<f64>),
    /// The frame's size.
    pub frame: [u32; 2],
    /// Where each side's label goes: the centre column of the side on screen (pixels).
    pub label_columns: Vec<(usize, f32)>,
    /// The map names to choose from.
    pub maps: Vec<String>,
    /// The geometry's name.
    pub geometry: String,
    /// In split view: the width in points of the column at the right edge the panel
    /// takes (the sides share the rest); `None`: it floats over the frame.
    pub docked: Option<f32>,
    /// A recent message (the last screenshot's file).
    pub notice: Option<String>,
}

/// What the user asked for through the panel (besides direct changes of the state).
#[derive(Default)]
pub struct Requests {
    /// Compute the error overlay.
    pub error: bool,
    /// Take a screenshot.
    pub screenshot: bool,
    /// Switch to this map.
    pub map: Option<String>,
    /// Switch this object's material to this map.
    pub object_map: Option<(usize, String)>,
    /// The objects' lines as the panel listed them (a scene of several objects).
    pub listed: Vec<String>,
}

fn rgb(c: [u8; 4]) -> Color32 {
    Color32::from_rgb(c[0], c[1], c[2])
}

/// Draws the panel (unless hidden), the side labels and the help; changes `state` as
/// the controls are used.
pub fn draw(ctx: &egui::Context, state: &mut ViewState, info: &Info) -> Requests {
    let mut req = Requests::default();
    labels(ctx, info);
    if state.help {
        let mut open = true;
        let height = ctx.content_rect().height() - 24.0 - LABEL_BAND;
        egui::Window::new("Keys (F1 closes)")
            .open(&mut open)
            .collapsible(false)
            .resizable(false)
            .vscroll(true)
            .max_height(height.max(60.0))
            .anchor(Align2::CENTER_TOP, Vec2::new(0.0, 8.0))
            .show(ctx, |ui| {
                egui::Grid::new("keys").striped(true).show(ui, |ui| {
                    for (key, what) in KEYS {
                        ui.monospace(*key);
                        ui.label(*what);
                        ui.end_row();
                    }
                });
            });
        state.help = open;
    }
    if !state.panel {
        return req;
    }
    let mut contents = |ui: &mut egui::Ui, req: &mut Requests| {
        ui.weak("Tab hides this panel, F1 lists the keys");
        methods(ui, state);
        overlay(ui, state, info, req);
        if state.heatmap {
            heat_bar(ui, info);
        }
        timings(ui, info);
        objects(ui, state, req);
        scene(ui, state, info, req);
        camera(ui, state);
        ui.horizontal(|ui| {
            if ui.button("Screenshot (P)").clicked() {
                req.screenshot = true;
            }
            if let Some(n) = &info.notice {
                ui.label(n);
            }
        });
    };
    match info.docked {
        // Split view: a column of its own at the right edge, so that it hides neither
        // side (the sides share the columns left of it).
        Some(width) => {
            let screen = ctx.content_rect();
            egui::Area::new(egui::Id::new("dispmap-view-docked"))
                .fixed_pos(Pos2::new(screen.right() - width, screen.top()))
                // Never pushed left over the sides: what is wider than the column is
                // cut at the window's edge.
                .constrain(false)
                .show(ctx, |ui| {
                    egui::Frame::new()
                        .fill(ui.style().visuals.panel_fill)
                        .inner_margin(egui::Margin::same(6))
                        .show(ui, |ui| {
                            ui.set_width(width - 12.0);
                            ui.set_height(screen.height() - 12.0);
                            egui::ScrollArea::vertical()
                                .max_height(screen.height() - 12.0)
                                .show(ui, |ui| contents(ui, &mut req));
                        });
                });
        }
        None => {
            // The panel leaves the bottom band to the side labels.
            let max_height = ctx.content_rect().height() - 16.0 - LABEL_BAND;
            egui::Window::new("dispmap view")
                .default_pos([8.0, 8.0])
                .default_width(300.0)
                .default_height(max_height.max(60.0))
                .resizable(false)
                .collapsible(true)
                .vscroll(true)
                .max_height(max_height.max(60.0))
                .show(ctx, |ui| contents(ui, &mut req));
        }
    }
    req
}

/// The method, time and iterations of each side, at the bottom of its part of the frame.
fn labels(ctx: &egui::Context, info: &Info) {
    let ppp = ctx.pixels_per_point();
    let bottom = ctx.content_rect().bottom() - 4.0;
    for (side, column) in &info.label_columns {
        let Some(s) = info.sides.get(*side) else {
            continue;
        };
        let which = match (info.sides.len(), side) {
            (1, _) => "",
            (_, 0) => "A: ",
            _ => "B: ",
        };
        // No time until the first measurement (not a zero).
        let ms = if s.passes.is_empty() {
            "measuring".to_owned()
        } else {
            format!("{:.2} ms", s.gpu_ms())
        };
        let mut text = format!("{which}{}  {ms}", s.method.name());
        if let Some(it) = s.iterations {
            text.push_str(&format!("  {it:.1} it/px"));
        }
        let pos = Pos2::new(column / ppp, bottom);
        egui::Area::new(egui::Id::new(("side-label", *side)))
            .fixed_pos(pos)
            .pivot(Align2::CENTER_BOTTOM)
            .order(egui::Order::Foreground)
            .interactable(false)
            .show(ctx, |ui| {
                egui::Frame::popup(ui.style())
                    .fill(Color32::from_black_alpha(190))
                    .inner_margin(egui::Margin::symmetric(6, 2))
                    .show(ui, |ui| {
                        ui.add(
                            egui::Label::new(
                                egui::RichText::new(text).strong().color(Color32::WHITE),
                            )
                            .extend(),
                        );
                    });
            });
    }
}

fn method_combo(ui: &mut egui::Ui, id: &str, method: &mut Method) {
    egui::ComboBox::from_id_salt(id)
        .selected_text(method.name())
        .show_ui(ui, |ui| {
            for m in Method::ALL {
                ui.selectable_value(method, *m, m.name());
            }
        });
}

/// The parameters `m` reads, as sliders and lists; returns the steps when changed.
fn params(ui: &mut egui::Ui, m: Method, p: &mut MethodParams, steps: &mut u32) -> bool {
    let u = m.reads();
    let mut steps_changed = false;
    if !(u.steps || u.refine_steps || u.min_steps || u.segments || u.block || u.max_level) {
        ui.weak("no parameters");
    }
    if u.steps {
        steps_changed |= ui
            .add(
                egui::Slider::new(steps, 1..=1024)
                    .logarithmic(true)
                    .text("steps"),
            )
            .changed();
    }
    if u.refine_steps {
        ui.add(egui::Slider::new(&mut p.refine_steps, 0..=16).text("refine steps"));
    }
    if u.min_steps {
        ui.add(egui::Slider::new(&mut p.min_steps, 1..=256).text("min steps"));
    }
    if u.segments {
        ui.add(
            egui::Slider::new(&mut p.segments, 1..=dispmap::method::MAX_SEGMENTS).text("segments"),
        );
    }
    if u.block {
        let mut side = p.block[0];
        egui::ComboBox::from_id_salt(("block", m.name()))
            .selected_text(format!("block {side}x{side}"))
            .show_ui(ui, |ui| {
                for b in [2, 4, 8] {
                    ui.selectable_value(&mut side, b, format!("{b}x{b}"));
                }
            });
        p.block = [side, side];
    }
    if u.max_level {
        let text = |l: MaxLevel| match l {
            MaxLevel::Fixed(l) => format!("coarsest level {l}"),
            MaxLevel::Auto => "coarsest level auto".to_owned(),
        };
        egui::ComboBox::from_id_salt(("max-level", m.name()))
            .selected_text(text(p.max_level))
            .show_ui(ui, |ui| {
                for l in [
                    MaxLevel::Fixed(0),
                    MaxLevel::Fixed(1),
                    MaxLevel::Fixed(2),
                    MaxLevel::Fixed(3),
                    MaxLevel::Auto,
                ] {
                    ui.selectable_value(&mut p.max_level, l, text(l));
                }
            });
    }
    steps_changed
}

fn methods(ui: &mut egui::Ui, state: &mut ViewState) {
    egui::CollapsingHeader::new("Methods")
        .default_open(true)
        .show(ui, |ui| {
            ui.horizontal(|ui| {
                let mut split = state.right.is_some();
                ui.checkbox(&mut split, "split");
                match (split, state.right) {
                    (true, None) => state.right = Some(super::cycle(state.settings.method, false)),
                    (false, Some(_)) => state.right = None,
                    _ => {}
                }
                if state.right.is_some() {
                    ui.selectable_value(&mut state.compare, Compare::Wipe, "wipe");
                    ui.selectable_value(&mut state.compare, Compare::Flip, "A/B");
                    ui.selectable_value(&mut state.compare, Compare::SideBySide, "side by side");
                }
            });
            // One column per side: its method and the parameters it reads.
            let side = |ui: &mut egui::Ui, state: &mut ViewState, b: bool| {
                ui.spacing_mut().slider_width = 70.0;
                let before = if b {
                    state.right.unwrap_or(state.settings.method)
                } else {
                    state.settings.method
                };
                let mut m = before;
                ui.horizontal(|ui| {
                    if state.right.is_some() {
                        ui.strong(if b { "B" } else { "A" });
                    }
                    method_combo(ui, if b { "method-b" } else { "method-a" }, &mut m);
                });
                if b {
                    state.right = Some(m);
                } else if m != before {
                    state.settings.method = m;
                    state.settings.params.steps = state.steps.unwrap_or(m.default_steps());
                }
                let mut steps = state.steps.unwrap_or(m.default_steps());
                if params(ui, m, &mut state.settings.params, &mut steps) {
                    state.steps = Some(steps);
                    state.settings.params.steps = steps;
                }
            };
            if state.right.is_some() {
                ui.columns(2, |cols| {
                    side(&mut cols[0], state, false);
                    side(&mut cols[1], state, true);
                });
                match state.compare {
                    Compare::Wipe => {
                        ui.add(egui::Slider::new(&mut state.divider, 0.0..=1.0).text("divider"));
                    }
                    Compare::Flip => {
                        ui.horizontal(|ui| {
                            ui.label("showing (Space)");
                            ui.selectable_value(&mut state.show_b, false, "A");
                            ui.selectable_value(&mut state.show_b, true, "B");
                        });
                    }
                    Compare::SideBySide => {}
                }
                ui.weak("A and B share a parameter both read");
            } else {
                side(ui, state, false);
            }
        });
}

/// A scene of several objects: each object's material (method, map, depth scale), each
/// one editable; the first displaced object's method and depth are side A's.
fn objects(ui: &mut egui::Ui, state: &mut ViewState, req: &mut Requests) {
    let n = state.assets.objects.len();
    if n == 0 {
        return;
    }
    egui::CollapsingHeader::new(format!("Objects ({n})"))
        .default_open(true)
        .show(ui, |ui| {
            let primary = state.primary();
            for i in 0..n {
                let geometry = state.assets.objects[i].geometry.name();
                let Some((map, current)) = state.material(i) else {
                    ui.label(format!("{}. {geometry}: flat", i + 1));
                    continue;
                };
                ui.horizontal(|ui| {
                    ui.strong(format!("{}. {geometry}", i + 1));
                    if primary == Some(i) {
                        ui.weak("(side A's method and depth)");
                    }
                });
                let mut method = current.method;
                let mut depth = current.depth_scale;
                ui.horizontal(|ui| {
                    egui::ComboBox::from_id_salt(("object-method", i))
                        .width(80.0)
                        .selected_text(method.name())
                        .show_ui(ui, |ui| {
                            for m in Method::ALL {
                                ui.selectable_value(&mut method, *m, m.name());
                            }
                        });
                    ui.add(
                        egui::DragValue::new(&mut depth)
                            .speed(0.002)
                            .range(0.001..=1.0)
                            .prefix("depth "),
                    );
                });
                ui.horizontal(|ui| {
                    let own = state.assets.objects[i]
                        .material
                        .as_ref()
                        .map_or_else(String::new, |(f, _, _)| f.label().to_owned());
                    egui::ComboBox::from_id_salt(("object-map", i))
                        .width(200.0)
                        .selected_text(&map)
                        .show_ui(ui, |ui| {
                            let mut names = vec![own.clone()];
                            names.extend(
                                dispmap_cli::bundled::NAMES.iter().map(|n| (*n).to_owned()),
                            );
                            for name in names {
                                if ui.selectable_label(name == map, &name).clicked() && name != map
                                {
                                    if name == own {
                                        if let Some(Some(edit)) = state.materials.get_mut(i) {
                                            edit.map = None;
                                        }
                                    } else {
                                        req.object_map = Some((i, name));
                                    }
                                }
                            }
                        });
                });
                if primary == Some(i) {
                    if method != current.method {
                        state.settings.method = method;
                        state.settings.params.steps = state.steps.unwrap_or(method.default_steps());
                    }
                    state.settings.scene.depth_scale = depth;
                } else if let Some(Some(edit)) = state.materials.get_mut(i) {
                    if method != edit.settings.method {
                        edit.settings.method = method;
                        edit.settings.params.steps = state.steps.unwrap_or(method.default_steps());
                    }
                    edit.settings.depth_scale = depth;
                }
            }
        });
    req.listed = super::state::material_lines(state);
}

fn scene(ui: &mut egui::Ui, state: &mut ViewState, info: &Info, req: &mut Requests) {
    egui::CollapsingHeader::new("Scene")
        .default_open(true)
        .show(ui, |ui| {
            let mut depth = state.settings.scene.depth_scale;
            if ui
                .add(
                    egui::Slider::new(&mut depth, 0.0..=1.0)
                        .logarithmic(true)
                        .text("depth scale"),
                )
                .changed()
            {
                state.settings.scene.depth_scale = depth;
            }
            let shadows = &mut state.settings.shadows;
            ui.horizontal(|ui| {
                ui.label("shadows");
                for mode in [ShadowMode::Off, ShadowMode::Hard, ShadowMode::Soft] {
                    ui.selectable_value(&mut shadows.mode, mode, mode.name());
                }
            });
            if shadows.mode == ShadowMode::Soft {
                ui.add(
                    egui::Slider::new(&mut shadows.samples, 1..=256)
                        .logarithmic(true)
                        .text("samples"),
                );
            }
            let lod = &mut state.settings.params.lod_threshold;
            let mut on = lod.is_some();
            ui.horizontal(|ui| {
                ui.checkbox(&mut on, "level of detail");
                let mut l = lod.unwrap_or(1.0);
                ui.add_enabled(on, egui::Slider::new(&mut l, 0.0..=8.0).text("threshold"));
                if on {
                    *lod = Some(l);
                } else {
                    *lod = None;
                }
            });
            let current = info.maps.get(state.map).cloned().unwrap_or_default();
            // A scene of several objects: each material has its own map (Objects).
            if state.assets.objects.is_empty() {
                egui::ComboBox::from_label("map")
                    .selected_text(&current)
                    .show_ui(ui, |ui| {
                        let mut names: Vec<String> = info.maps.clone();
                        for n in dispmap_cli::bundled::NAMES {
                            if !names.iter().any(|x| x == n) {
                                names.push((*n).to_owned());
                            }
                        }
                        for n in names {
                            if ui.selectable_label(n == current, &n).clicked() && n != current {
                                req.map = Some(n);
                            }
                        }
                    });
            }
            ui.label(format!(
                "{}, {}x{}",
                info.geometry, info.frame[0], info.frame[1]
            ));
            ui.checkbox(&mut state.heatmap, "iteration heat map");
        });
}

fn camera(ui: &mut egui::Ui, state: &mut ViewState) {
    egui::CollapsingHeader::new("Camera")
        .default_open(true)
        .show(ui, |ui| {
            let c = &mut state.settings.scene.camera;
            ui.add(
                egui::Slider::new(&mut c.elevation_deg, MIN_ELEVATION..=90.0)
                    .text("elevation")
                    .suffix("°"),
            );
            let mut azimuth = c.azimuth_deg.rem_euclid(360.0);
            if ui
                .add(
                    egui::Slider::new(&mut azimuth, 0.0..=360.0)
                        .text("azimuth")
                        .suffix("°"),
                )
                .changed()
            {
                c.azimuth_deg = azimuth;
            }
            let mut d = state.settings.scene.orbit_distance();
            if ui
                .add(
                    egui::Slider::new(&mut d, 0.05..=50.0)
                        .logarithmic(true)
                        .text("distance"),
                )
                .changed()
            {
                super::set_distance(&mut state.settings.scene, d);
            }
            if ui.button("Reset camera").clicked() {
                state.settings.scene.camera = state.home;
            }
        });
}

fn timings(ui: &mut egui::Ui, info: &Info) {
    egui::CollapsingHeader::new("Timings")
        .default_open(true)
        .show(ui, |ui| {
            ui.label(match (info.fps, info.frame_ms) {
                (Some(fps), Some(ms)) => format!("{fps:.1} fps, frame {ms:.1} ms"),
                _ => "fps, frame: measuring (after the first update)".to_owned(),
            });
            let colours = [
                Color32::from_rgb(255, 200, 60),
                Color32::from_rgb(90, 200, 255),
            ];
            for (i, s) in info.sides.iter().enumerate() {
                let name = if info.sides.len() > 1 {
                    format!("{}: {}", if i == 0 { "A" } else { "B" }, s.method.name())
                } else {
                    s.method.name().to_owned()
                };
                let iterations = s
                    .iterations
                    .map_or(String::new(), |it| format!(", {it:.1} iterations / pixel"));
                let gpu = if s.passes.is_empty() {
                    "measuring".to_owned()
                } else {
                    format!("{:.2} ms", s.gpu_ms())
                };
                ui.colored_label(colours[i], format!("{name}: GPU {gpu}{iterations}"));
                let passes: Vec<String> = s
                    .passes
                    .iter()
                    .map(|(pass, ms)| format!("{pass} {ms:.2}"))
                    .collect();
                ui.weak(format!("  {}", passes.join(" · ")));
            }
            graph(ui, info, colours);
            ui.weak(format!(
                "panel: CPU {:.2} ms, GPU {}",
                info.panel_ms.0,
                info.panel_ms
                    .1
                    .map_or("-".to_owned(), |g| format!("{g:.2} ms"))
            ));
        });
}

/// The rolling graph of each side's GPU milliseconds per frame.
fn graph(ui: &mut egui::Ui, info: &Info, colours: [Color32; 2]) {
    let (rect, _) = ui.allocate_exact_size(Vec2::new(230.0, 56.0), Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_black_alpha(120));
    let top = info
        .history
        .iter()
        .flat_map(|h| h.iter())
        .fold(0.0f32, |a, &b| a.max(b))
        .max(1e-3);
    for (h, colour) in info.history.iter().zip(colours) {
        if h.len() < 2 {
            continue;
        }
        let n = super::HISTORY - 1;
        let points: Vec<Pos2> = h
            .iter()
            .enumerate()
            .map(|(i, &ms)| {
                let x =
                    rect.left() + rect.width() * (i + super::HISTORY - h.len()) as f32 / n as f32;
                let y = rect.bottom() - (rect.height() - 12.0) * ms / top;
                Pos2::new(x, y)
            })
            .collect();
        painter.add(egui::Shape::line(points, Stroke::new(1.5, colour)));
    }
    painter.text(
        rect.left_top() + Vec2::new(3.0, 1.0),
        Align2::LEFT_TOP,
        format!("GPU ms / frame, top {top:.1}"),
        FontId::proportional(10.0),
        Color32::LIGHT_GRAY,
    );
}

fn swatch(ui: &mut egui::Ui, colour: Color32, text: String) {
    ui.horizontal(|ui| {
        let (rect, _) = ui.allocate_exact_size(Vec2::splat(12.0), Sense::hover());
        ui.painter().rect_filled(rect, 2.0, colour);
        ui.label(text);
    });
}

fn overlay(ui: &mut egui::Ui, state: &ViewState, info: &Info, req: &mut Requests) {
    egui::CollapsingHeader::new("Error overlay")
        .default_open(true)
        .show(ui, |ui| {
            match info.overlay {
                OverlayState::Off => {
                    if ui.button("Compute (C)").clicked() {
                        req.error = true;
                    }
                    return;
                }
                OverlayState::Computing(f) => {
                    ui.add(egui::ProgressBar::new(f).text("exact reference"));
                }
                OverlayState::Shown => {
                    ui.weak("against the exact reference, until the frame changes");
                }
            }
            for (i, s) in info.sides.iter().enumerate() {
                let Some(e) = &s.error else { continue };
                let m = &e.metrics;
                let which = match (info.sides.len(), i) {
                    (1, _) => "",
                    (_, 0) => "A ",
                    _ => "B ",
                };
                ui.label(format!("{which}{}:", s.method.name()));
                ui.strong(format!(
                    "  {:.3} % artifacts, mean {:.2}, p99 {:.2} texels",
                    100.0 * m.artifact_fraction,
                    m.mean_texels,
                    m.p99_texels
                ));
                if state.settings.params.lod_threshold.is_some() || e.lod_pixels > 0 {
                    ui.label(format!(
                        "  to bump mapping by LOD {:.3} % (not compared)",
                        100.0 * e.lod_pixels as f64 / e.covered.max(1) as f64
                    ));
                }
            }
            swatch(
                ui,
                rgb(ARTIFACT_RGBA),
                format!("artifact: hit more than {ARTIFACT_TEXELS} texel off"),
            );
            swatch(
                ui,
                rgb(MISS_RGBA),
                "miss: only one of method, reference hits".into(),
            );
            if state.settings.params.lod_threshold.is_some() {
                swatch(ui, rgb(LOD_RGBA), "sent to bump mapping by LOD".into());
            }
        });
}

/// The heat map's colour bar for each side (its scale is that side's largest count).
fn heat_bar(ui: &mut egui::Ui, info: &Info) {
    egui::CollapsingHeader::new("Heat map")
        .default_open(true)
        .show(ui, |ui| {
            ui.label("iterations per pixel");
            let (rect, _) = ui.allocate_exact_size(Vec2::new(230.0, 14.0), Sense::hover());
            let painter = ui.painter_at(rect);
            let n = 64;
            for i in 0..n {
                let t0 = i as f32 / n as f32;
                let c = heatmap::ramp(t0 + 0.5 / n as f32);
                let r = Rect::from_min_max(
                    Pos2::new(rect.left() + rect.width() * t0, rect.top()),
                    Pos2::new(
                        rect.left() + rect.width() * (i + 1) as f32 / n as f32 + 0.5,
                        rect.bottom(),
                    ),
                );
                painter.rect_filled(r, 0.0, Color32::from_rgb(c[0], c[1], c[2]));
            }
            for (i, s) in info.sides.iter().enumerate() {
                let top = s.heat_scale.unwrap_or(0.0);
                ui.horizontal(|ui| {
                    if info.sides.len() > 1 {
                        ui.label(if i == 0 { "A:" } else { "B:" });
                    }
                    ui.label(format!("0 … {top:.0}"));
                });
            }
            swatch(ui, Color32::BLACK, "no geometry".into());
        });
}
