//! Keys and mouse, and the camera, method, map and screenshot controls they drive.

use super::MIN_ELEVATION;
use super::state::{Compare, ViewState};
use super::viewer::Viewer;
use anyhow::Result;
use dispmap::method::{MaxLevel, Method};
use dispmap::passes::shadow::{ShadowMode, ShadowSettings};
use dispmap::scene::{Camera, Geometry, Scene};
use dispmap_cli::bundled;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use winit::event::{ElementState, KeyEvent, MouseButton};
use winit::keyboard::{KeyCode, PhysicalKey};

impl Viewer {
    pub(super) fn key(&mut self, state: &mut ViewState, event: &KeyEvent) -> Result<bool> {
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

    pub(super) fn mouse_button(&mut self, button: MouseButton, pressed: bool) {
        match button {
            MouseButton::Left => self.orbiting = pressed,
            MouseButton::Right => self.dragging_divider = pressed,
            _ => {}
        }
    }

    pub(super) fn cursor(&mut self, state: &mut ViewState, at: [f32; 2]) {
        if let Some(prev) = self.cursor {
            let (dx, dy) = (at[0] - prev[0], at[1] - prev[1]);
            if self.orbiting {
                let c = &mut state.settings.scene.camera;
                c.azimuth_deg -= dx * 0.3;
                tilt(c, dy * 0.2);
            }
        }
        if self.dragging_divider {
            // The sides share the columns left of the docked panel.
            let w = self
                .window
                .inner_size()
                .width
                .saturating_sub(self.dock_px)
                .max(1) as f32;
            state.divider = (at[0] / w).clamp(0.0, 1.0);
        }
        self.cursor = Some(at);
    }
}

/// The next (or, `back`, previous) method in [`Method::ALL`].
pub(super) fn cycle(m: Method, back: bool) -> Method {
    let all = Method::ALL;
    let i = all.iter().position(|x| *x == m).unwrap_or(0);
    let n = all.len();
    all[if back { (i + n - 1) % n } else { (i + 1) % n }]
}

/// Moves the eye toward (`lines > 0`) or away from the target: on the tiled plane the
/// eye height, on the quad and the meshes the orbit distance, by 10% a line.
pub(super) fn zoom(scene: &mut Scene, lines: f32) {
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
    keep_beyond_near_plane(scene);
}

/// Sets the orbit distance: on the tiled plane through the eye height (at the current
/// elevation), elsewhere directly; within the zoom's limits.
pub(super) fn set_distance(scene: &mut Scene, distance: f32) {
    let camera = &mut scene.camera;
    match scene.geometry {
        Geometry::TiledPlane => {
            let sin = camera.elevation_deg.to_radians().sin().max(1e-6);
            camera.height = (distance * sin).clamp(0.01, 100.0);
        }
        _ => camera.distance = Some(distance.clamp(0.05, 1000.0)),
    }
    keep_beyond_near_plane(scene);
}

/// Changes the elevation within `[MIN_ELEVATION, 90]` degrees.
pub(super) fn tilt(camera: &mut Camera, degrees: f32) {
    camera.elevation_deg = (camera.elevation_deg + degrees).clamp(MIN_ELEVATION, 90.0);
    // The tiled plane's eye stays high enough for the new elevation.
    camera.height = camera.height.max(least_height(camera));
}

/// The least eye height above a flat surface that `render` accepts with `camera`
/// ([`dispmap::scene::min_plane_height`]), rounded up to f32.
fn least_height(camera: &Camera) -> f32 {
    (dispmap::scene::min_plane_height(camera) * (1.0 + 1e-6)) as f32
}

/// Keeps a zoom's eye beyond the near plane as `render` requires (the tiled plane's
/// height, the quad's distance); meshes keep their distance.
fn keep_beyond_near_plane(scene: &mut Scene) {
    let least = least_height(&scene.camera);
    let camera = &mut scene.camera;
    match scene.geometry {
        Geometry::TiledPlane => camera.height = camera.height.max(least),
        Geometry::Quad => {
            let sin = camera.elevation_deg.to_radians().sin().max(1e-6);
            camera.distance = camera.distance.map(|d| d.max(least / sin * (1.0 + 1e-6)));
        }
        _ => {}
    }
}

/// Switches to the named bundled map, or (`None`) to the next map in turn: the given
/// map first, then the bundled ones.
pub(super) fn switch_map(state: &mut ViewState, name: Option<&str>) -> Result<()> {
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

/// Object `object`'s material switched to the map `name` (a map already loaded, or a
/// bundled one, loaded here).
pub(super) fn set_object_map(state: &mut ViewState, object: usize, name: &str) -> Result<()> {
    let index = match state.maps.iter().position(|(n, _)| n == name) {
        Some(i) => i,
        None => {
            let field = bundled::by_name(name, "map")?;
            state.maps.push((name.to_owned(), Arc::new(field)));
            state.maps.len() - 1
        }
    };
    if let Some(Some(edit)) = state.materials.get_mut(object) {
        edit.map = Some(index);
    }
    Ok(())
}

/// `dispmap-view-N.png` in the current folder, the first N not taken.
pub(super) fn next_screenshot_path(from: u32) -> PathBuf {
    (from..)
        .map(|n| PathBuf::from(format!("dispmap-view-{n}.png")))
        .find(|p| !Path::new(p).exists())
        .unwrap_or_else(|| PathBuf::from("dispmap-view.png"))
}
