//! The scripted (headless) run: its state and how one script action changes the view.

use super::input::{set_object_map, switch_map, zoom};
use super::script::{Action, CameraPath, ObjectChange, Script};
use super::state::{Compare, ViewState};
use super::viewer::Viewer;
use anyhow::Result;
use std::path::PathBuf;
use std::time::Instant;
use winit::dpi::PhysicalSize;

/// The scripted run.
pub(super) struct Headless {
    pub(super) frames: u32,
    pub(super) camera_path: Option<CameraPath>,
    pub(super) script: Script,
    pub(super) screenshot: Option<PathBuf>,
    /// A scripted resize not yet applied by the window system, and when it was asked.
    pub(super) pending_resize: Option<([u32; 2], Instant)>,
    /// A scripted error overlay not yet shown.
    pub(super) waiting_error: bool,
    /// The frame whose actions were applied (a frame that waits renders again).
    pub(super) applied: Option<u32>,
    /// Frames rendered again while waiting (for a resize or the error overlay).
    pub(super) waited: u32,
}

impl Viewer {
    pub(super) fn scripted(
        &mut self,
        state: &mut ViewState,
        h: &mut Headless,
        action: Action,
    ) -> Result<()> {
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
            // The panel's controls of the object's row (the first displaced object's
            // method and depth are the left side's).
            Action::Object(i, change) => {
                let primary = state.primary() == Some(i);
                match change {
                    ObjectChange::Method(m) if primary => state.settings.method = m,
                    ObjectChange::Depth(d) if primary => state.settings.scene.depth_scale = d,
                    ObjectChange::Map(Some(name)) => set_object_map(state, i, &name)?,
                    change => {
                        if let Some(Some(edit)) = state.materials.get_mut(i) {
                            match change {
                                ObjectChange::Method(m) => {
                                    edit.settings.method = m;
                                    edit.settings.params.steps =
                                        state.steps.unwrap_or(m.default_steps());
                                }
                                ObjectChange::Depth(d) => edit.settings.depth_scale = d,
                                ObjectChange::Map(_) => edit.map = None,
                            }
                        }
                    }
                }
            }
        }
        state.settings.params.steps = state.steps.unwrap_or(state.settings.method.default_steps());
        Ok(())
    }
}
