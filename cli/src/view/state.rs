//! What the keys, the panel and the script change ([`ViewState`]), the last state the
//! renderers accepted (the undo [`Snapshot`]), and the window title and side settings
//! derived from it.

use dispmap::heightfield::HeightField;
use dispmap::method::Method;
use dispmap::renderer::{RenderSettings, SceneAssets};
use dispmap::scene::Camera;
use std::sync::Arc;

/// What the keys change (and the script).
pub(super) struct ViewState {
    /// The memory bound frames are kept under (a larger window renders a smaller frame,
    /// scaled to it).
    pub(super) bound: super::budget::Bound,
    /// Name and field of each map: the given one first, the bundled ones added when
    /// switched to.
    pub(super) maps: Vec<(String, Arc<HeightField>)>,
    pub(super) map: usize,
    pub(super) assets: SceneAssets,
    /// The left (or only) side's settings; the frame size follows the window.
    pub(super) settings: RenderSettings,
    /// Steps chosen (`None`: each method's default).
    pub(super) steps: Option<u32>,
    /// The split view's right method.
    pub(super) right: Option<Method>,
    /// The divider, a fraction of the width.
    pub(super) divider: f32,
    /// How the two methods of the split view are compared.
    pub(super) compare: Compare,
    /// A/B mode shows the right method.
    pub(super) show_b: bool,
    pub(super) heatmap: bool,
    /// The camera the reset key returns to.
    pub(super) home: Camera,
    /// The panel is shown.
    pub(super) panel: bool,
    /// The help overlay is shown.
    pub(super) help: bool,
}

/// How the split view puts the two methods on screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Compare {
    /// Left of the divider one method, right of it the other (same camera, same frame).
    Wipe,
    /// The whole frame shows one method at a time, the other one key away: the same
    /// pixels.
    Flip,
    /// Both at half the width side by side, each the whole view of the same camera.
    SideBySide,
}

impl Compare {
    pub(super) fn next(self) -> Self {
        match self {
            Compare::Wipe => Compare::Flip,
            Compare::Flip => Compare::SideBySide,
            Compare::SideBySide => Compare::Wipe,
        }
    }
}

impl ViewState {
    pub(super) fn side(&self, method: Method) -> RenderSettings {
        let mut s = self.settings;
        s.method = method;
        s.params.steps = self.steps.unwrap_or(method.default_steps());
        s
    }
}

/// What the keys change, as last accepted by the renderers.
#[derive(Clone)]
pub(super) struct Snapshot {
    pub(super) settings: RenderSettings,
    pub(super) steps: Option<u32>,
    pub(super) right: Option<Method>,
    pub(super) map: usize,
}

impl Snapshot {
    pub(super) fn of(state: &ViewState) -> Self {
        Snapshot {
            settings: state.settings,
            steps: state.steps,
            right: state.right,
            map: state.map,
        }
    }

    pub(super) fn restore(&self, state: &mut ViewState) {
        state.settings = self.settings;
        state.steps = self.steps;
        state.right = self.right;
        state.map = self.map;
    }
}

/// The settings of a side showing `method`, with the frame size of `want`.
pub(super) fn side_of(want: &RenderSettings, state: &ViewState, method: Method) -> RenderSettings {
    let mut s = state.side(method);
    (s.width, s.height) = (want.width, want.height);
    s
}

/// The window's title: the methods shown.
pub(super) fn title(state: &ViewState) -> String {
    match state.right {
        Some(r) => format!(
            "dispmap view: {} | {}",
            state.settings.method.name(),
            r.name()
        ),
        None => format!("dispmap view: {}", state.settings.method.name()),
    }
}

/// One line per object of a scene of several objects: its geometry, and its method, map
/// and depth scale, or `flat` (empty for one geometry).
pub(super) fn material_lines(state: &ViewState) -> Vec<String> {
    state
        .assets
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| match &o.material {
            Some((field, m, _)) => format!(
                "{}. {}: {} on {}, depth {}",
                i + 1,
                o.geometry.name(),
                m.method.name(),
                field.label(),
                m.depth_scale
            ),
            None => format!("{}. {}: flat", i + 1, o.geometry.name()),
        })
        .collect()
}
