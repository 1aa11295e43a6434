//! The viewer's memory bound: the estimate of its largest frame (the window's size and
//! every scripted resize) on its largest map (the given one and every scripted bundled
//! map), with both sides of a split view, the heat map's read-backs and the error
//! overlay's reference, checked as `render` checks its own before a window opens.

use super::script::{Action, Script};
use anyhow::Result;
use dispmap::heightfield::HeightField;
use dispmap::method::Method;
use dispmap::passes::shadow::ShadowMode;
use dispmap::renderer::RenderSettings;
use dispmap_cli::memory;

/// The largest bundled map (`mountains`: 1025x1025, 16-bit), what a scripted `map`
/// switch may load.
const BUNDLED_MAP: memory::MapSize = memory::MapSize {
    size: [1025, 1025],
    texel_bytes: 2,
    load_bytes: 0,
};

/// Refuses a run whose largest frame and map need more than `max_memory` (or the memory
/// available): `field` and `settings` are the start's, `right` the split view's method,
/// `script` the scripted changes. A scene of several objects was checked by `render`'s
/// code at its size; its scripted resizes are counted here per pixel on its first map.
pub(super) fn check(
    field: &HeightField,
    label: &str,
    settings: &RenderSettings,
    right: Option<Method>,
    script: &Script,
    max_memory: Option<u64>,
) -> Result<()> {
    let mut frame = [settings.width, settings.height];
    let mut map = memory::MapSize::loaded(field);
    let mut map_label = label.to_owned();
    let mut methods = vec![settings.method];
    methods.extend(right);
    let mut split = right.is_some();
    for (_, action) in &script.events {
        match action {
            Action::Resize(w, h) if u64::from(*w) * u64::from(*h) > pixels(frame) => {
                frame = [*w, *h];
            }
            Action::Map(name) if texel_bytes(BUNDLED_MAP) > texel_bytes(map) => {
                map = BUNDLED_MAP;
                map_label = name.clone();
            }
            Action::Method(m) => methods.push(*m),
            Action::Split(Some(m)) => {
                methods.push(*m);
                split = true;
            }
            _ => {}
        }
    }
    methods.sort_by_key(|m| m.name());
    methods.dedup();
    let hard = settings.shadows.mode == ShadowMode::Hard
        || script
            .events
            .iter()
            .any(|(_, a)| *a == Action::Shadows(ShadowMode::Hard));
    let mut maps = memory::MethodMaps::together(&methods);
    if hard {
        maps.pyramids += 1;
    }
    // Two sides render whole frames each (side by side: half of one each).
    let counted = [frame[0] * if split { 2 } else { 1 }, frame[1]];
    let estimate = memory::estimate(
        map,
        counted,
        memory::Extras {
            reference: true,
            heatmap: true,
            maps,
            ..memory::Extras::default()
        },
    );
    memory::check(
        &estimate,
        max_memory,
        &format!(
            "viewing {}x{} (the window and the script's resizes){} on the map {map_label} \
             with the error overlay's reference",
            frame[0],
            frame[1],
            if split {
                ", both sides of the split view"
            } else {
                ""
            }
        ),
    )?;
    Ok(())
}

fn pixels(frame: [u32; 2]) -> u64 {
    u64::from(frame[0]) * u64::from(frame[1])
}

fn texel_bytes(map: memory::MapSize) -> u64 {
    u64::from(map.size[0]) * u64::from(map.size[1]) * u64::from(map.texel_bytes)
}
