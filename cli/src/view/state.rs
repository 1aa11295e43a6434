//! What the keys, the panel and the script change ([`ViewState`]), the last state the
//! renderers accepted (the undo [`Snapshot`]), and the window title and side settings
//! derived from it.

use anyhow::Result;
use dispmap::context::Context;
use dispmap::embed::MaterialSettings;
use dispmap::heightfield::HeightField;
use dispmap::method::Method;
use dispmap::renderer::{RenderSettings, Renderer, SceneAssets};
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
    /// A scene of several objects: each object's material as the panel left it (`None`:
    /// flat), in the objects' order; empty for one geometry.
    pub(super) materials: Vec<Option<MaterialEdit>>,
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

/// One displaced object's material as edited in the panel. The first displaced object's
/// material is the renderer's primary one: its method, parameters and depth scale are
/// [`ViewState::settings`]' (the side's), and only its `map` is read from here.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct MaterialEdit {
    /// The height map: an index into [`ViewState::maps`], or `None` for the object's own.
    pub(super) map: Option<usize>,
    /// Method, parameters, depth scale and addressing.
    pub(super) settings: MaterialSettings,
}

/// The materials of `assets`' objects as loaded (nothing edited yet).
pub(super) fn initial_materials(assets: &SceneAssets) -> Vec<Option<MaterialEdit>> {
    assets
        .objects
        .iter()
        .map(|o| {
            o.material.as_ref().map(|(_, settings, _)| MaterialEdit {
                map: None,
                settings: *settings,
            })
        })
        .collect()
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
    /// The index of the first displaced object (the primary material), if any.
    pub(super) fn primary(&self) -> Option<usize> {
        self.materials.iter().position(Option::is_some)
    }

    /// Object `i`'s material as shown and rendered on the left side: the name of its map
    /// and its settings (the primary's method, parameters and depth scale are the
    /// side's). `None` for a flat object.
    pub(super) fn material(&self, i: usize) -> Option<(String, MaterialSettings)> {
        let edit = self.materials.get(i).copied().flatten()?;
        let map = match edit.map {
            Some(m) => self
                .maps
                .get(m)
                .map_or_else(String::new, |(n, _)| n.clone()),
            None => self.assets.objects[i]
                .material
                .as_ref()
                .map_or_else(String::new, |(field, _, _)| field.label().to_owned()),
        };
        let mut settings = edit.settings;
        if self.primary() == Some(i) {
            settings.method = self.settings.method;
            settings.params = self.settings.params;
            settings.depth_scale = self.settings.scene.depth_scale;
        }
        Some((map, settings))
    }

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
    pub(super) materials: Vec<Option<MaterialEdit>>,
}

impl Snapshot {
    pub(super) fn of(state: &ViewState) -> Self {
        Snapshot {
            settings: state.settings,
            steps: state.steps,
            right: state.right,
            map: state.map,
            materials: state.materials.clone(),
        }
    }

    pub(super) fn restore(&self, state: &mut ViewState) {
        state.settings = self.settings;
        state.steps = self.steps;
        state.right = self.right;
        state.map = self.map;
        state.materials = self.materials.clone();
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
        .map(|(i, o)| match state.material(i) {
            Some((map, m)) => format!(
                "{}. {}: {} on {}, depth {}",
                i + 1,
                o.geometry.name(),
                m.method.name(),
                map,
                m.depth_scale
            ),
            None => format!("{}. {}: flat", i + 1, o.geometry.name()),
        })
        .collect()
}

/// A renderer of the current map with `settings`; for a scene of several objects, of
/// its objects with their materials as edited (the primary one with `settings`' method,
/// parameters and depth scale).
pub(super) fn build_renderer(
    ctx: &Arc<Context>,
    state: &ViewState,
    settings: RenderSettings,
) -> Result<Renderer> {
    let field = &state.maps[state.map].1;
    if state.assets.objects.is_empty() {
        return Ok(Renderer::with_assets(ctx, field, settings, &state.assets)?);
    }
    let primary = state.primary();
    let objects: Vec<_> = state
        .assets
        .objects
        .iter()
        .zip(&state.materials)
        .enumerate()
        .map(|(i, (o, edit))| {
            let mut object = o.as_object();
            if let (Some(material), Some(edit)) = (object.material.as_mut(), edit) {
                if let Some((_, f)) = edit.map.and_then(|m| state.maps.get(m)) {
                    material.field = f.as_ref();
                }
                material.settings = if primary == Some(i) {
                    MaterialSettings {
                        method: settings.method,
                        params: settings.params,
                        depth_scale: settings.scene.depth_scale,
                        addressing: material.settings.addressing,
                    }
                } else {
                    edit.settings
                };
            }
            object
        })
        .collect();
    Ok(Renderer::with_objects(ctx, settings, &objects)?)
}
