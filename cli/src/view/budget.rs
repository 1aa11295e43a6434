//! The viewer's memory bound, checked as `render` checks its own: before a window opens,
//! the start (the window's size, its map, methods and assets: a scene's meshes, albedo
//! and normal maps and objects) and each scripted change after it (a resize, a bundled
//! map, a method or split, hard shadows), a refused script line named with its file and
//! line; while it runs, a window the user makes larger than the bound allows is rendered
//! at the largest frame of its shape that fits ([`Bound::fit`]) and scaled to the window.

use super::script::{Action, Script};
use super::state::ViewState;
use anyhow::{Result, anyhow};
use dispmap::method::Method;
use dispmap::passes::shadow::ShadowMode;
use dispmap::renderer::SceneAssets;
use dispmap_cli::memory;

/// The largest bundled map (`mountains`: 1025x1025, 16-bit), what a scripted `map`
/// switch may load.
const BUNDLED_MAP: memory::MapSize = memory::MapSize {
    size: [1025, 1025],
    texel_bytes: 2,
    load_bytes: 0,
};

/// What the viewer's memory is estimated from, but the frame's size.
#[derive(Clone, Debug)]
pub(super) struct Sizing<'a> {
    /// The map shown (a scene of several objects: the objects' maps instead).
    pub map: memory::MapSize,
    /// The methods whose renderers' maps are alive (both sides, and every method the
    /// script switches to: counted together).
    pub methods: Vec<Method>,
    /// Hard self-shadowing (a cell pyramid of its own for methods without one).
    pub hard: bool,
    /// Two sides render (the split view): two frames.
    pub split: bool,
    /// The scene's mesh, material maps and objects.
    pub assets: &'a SceneAssets,
}

impl<'a> Sizing<'a> {
    /// The state's map, methods, split and assets.
    pub fn of(state: &'a ViewState) -> Self {
        Sizing {
            map: memory::MapSize::loaded(&state.maps[state.map].1),
            methods: [Some(state.settings.method), state.right]
                .into_iter()
                .flatten()
                .collect(),
            hard: state.settings.shadows.mode == ShadowMode::Hard,
            split: state.right.is_some(),
            assets: &state.assets,
        }
    }

    /// The estimate of viewing `frame` (the window's size): each side's renderer with
    /// the heat map's read-backs, and (one surface) the error overlay's reference.
    pub fn estimate(&self, frame: [u32; 2]) -> memory::Estimate {
        let mut methods = self.methods.clone();
        methods.sort_by_key(|m| m.name());
        methods.dedup();
        // Two sides render whole frames each (side by side: half of one each).
        let counted = [frame[0].saturating_mul(1 + u32::from(self.split)), frame[1]];
        let mut mesh = memory::MeshSize::default();
        for m in (self.assets.mesh.iter()).chain(self.assets.objects.iter().flat_map(|o| &o.mesh)) {
            mesh.vertices += m.vertices.len() as u64;
            mesh.triangles += (m.indices.len() / 3) as u64;
        }
        let images = memory::MaterialMaps::of_loaded(
            std::iter::once(&self.assets.material).chain(
                (self.assets.objects.iter())
                    .filter_map(|o| o.material.as_ref().map(|(_, _, images)| images)),
            ),
        );
        if self.assets.objects.is_empty() {
            let mut maps = memory::MethodMaps::together(&methods);
            if self.hard {
                maps.pyramids += 1;
            }
            memory::estimate(
                self.map,
                counted,
                memory::Extras {
                    reference: true,
                    heatmap: true,
                    maps,
                    mesh,
                    images,
                    ..memory::Extras::default()
                },
            )
        } else {
            // Every object's material on each side (the error overlay is not available).
            let materials: Vec<memory::MaterialMemory> = (self.assets.objects.iter())
                .filter_map(|o| o.material.as_ref())
                .map(|(field, settings, _)| memory::MaterialMemory {
                    map: memory::MapSize::loaded(field),
                    maps: memory::MethodMaps::of(settings.method, self.hard),
                    dig_block: (settings.method.needs().dig_corners)
                        .then_some(settings.params.block),
                })
                .collect();
            memory::estimate_objects(
                &materials,
                counted,
                memory::Extras {
                    heatmap: true,
                    mesh,
                    images,
                    ..memory::Extras::default()
                },
            )
        }
    }
}

/// The bound a running viewer keeps its frames under: `--max-memory`, or the memory
/// available when it started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Bound {
    /// Bytes; `None`: unknown (nothing is bounded).
    pub limit: Option<u64>,
    /// `--max-memory` gave it.
    pub given: bool,
}

impl Bound {
    /// `--max-memory`, or the memory available now.
    pub fn new(max_memory: Option<u64>) -> Self {
        Bound {
            limit: max_memory.or_else(memory::available),
            given: max_memory.is_some(),
        }
    }

    /// The frame to render for a window of `window` pixels: the window's own size when
    /// its estimate fits the bound, else the largest frame of the same shape (each side
    /// scaled by one factor, at least 1 pixel) whose estimate does.
    pub fn fit(&self, sizing: &Sizing<'_>, window: [u32; 2]) -> [u32; 2] {
        let Some(limit) = self.limit else {
            return window;
        };
        let fits = |f: [u32; 2]| sizing.estimate(f).bytes <= limit;
        if fits(window) {
            return window;
        }
        let [w, h] = window.map(|s| s.max(1));
        let at = |x: u32| {
            let y = (u64::from(h) * u64::from(x) / u64::from(w)).max(1) as u32;
            [x, y]
        };
        // The largest width (the height follows) that fits: estimates grow with the
        // frame, so a bisection finds it.
        let (mut lo, mut hi) = (1u32, w);
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            if fits(at(mid)) {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        at(lo)
    }

    /// The source of the limit, for messages.
    pub fn source(&self) -> &'static str {
        if self.given {
            "--max-memory"
        } else {
            "the memory available at the start"
        }
    }
}

/// Refuses a run whose start, or a scripted change, needs more than `max_memory` (or
/// the memory available): `state` is the start (its window size in `state.settings`),
/// `script` the scripted changes, `script_name` the script's file. A refused change
/// names its file and line.
pub(super) fn check(
    state: &ViewState,
    script: &Script,
    script_name: &str,
    max_memory: Option<u64>,
) -> Result<()> {
    let mut sizing = Sizing::of(state);
    let mut frame = [state.settings.width, state.settings.height];
    let mut map_label = state.maps[state.map].0.clone();
    let what = |frame: [u32; 2], sizing: &Sizing<'_>, map: &str| {
        format!(
            "viewing {}x{}{} on the map {map}{}",
            frame[0],
            frame[1],
            if sizing.split {
                ", both sides of the split view"
            } else {
                ""
            },
            if sizing.assets.objects.is_empty() {
                " with the error overlay's reference"
            } else {
                ""
            }
        )
    };
    memory::check(
        &sizing.estimate(frame),
        max_memory,
        &what(frame, &sizing, &map_label),
    )?;
    for (k, (_, action)) in script.events.iter().enumerate() {
        let changed = match action {
            Action::Resize(w, h) => {
                frame = [*w, *h];
                true
            }
            Action::Map(name) => {
                if bytes(BUNDLED_MAP) > bytes(sizing.map) {
                    sizing.map = BUNDLED_MAP;
                    map_label = name.clone();
                }
                true
            }
            Action::Method(m) => {
                sizing.methods.push(*m);
                true
            }
            Action::Split(Some(m)) => {
                sizing.methods.push(*m);
                sizing.split = true;
                true
            }
            Action::Shadows(ShadowMode::Hard) => {
                sizing.hard = true;
                true
            }
            _ => false,
        };
        if changed {
            memory::check(
                &sizing.estimate(frame),
                max_memory,
                &what(frame, &sizing, &map_label),
            )
            .map_err(|e| {
                anyhow!(
                    "invalid --script: {script_name}:{}: {e}",
                    script.lines.get(k).copied().unwrap_or(0)
                )
            })?;
        }
    }
    Ok(())
}

fn bytes(map: memory::MapSize) -> u64 {
    u64::from(map.size[0]) * u64::from(map.size[1]) * u64::from(map.texel_bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assets() -> SceneAssets {
        SceneAssets::default()
    }

    fn sizing(assets: &SceneAssets) -> Sizing<'_> {
        Sizing {
            map: memory::MapSize {
                size: [1024, 1024],
                texel_bytes: 1,
                load_bytes: 0,
            },
            methods: vec![Method::Relief],
            hard: false,
            split: false,
            assets,
        }
    }

    #[test]
    fn a_window_above_the_bound_renders_the_largest_frame_of_its_shape_that_fits() {
        let assets = assets();
        let s = sizing(&assets);
        let limit = s.estimate([1000, 500]).bytes;
        let bound = Bound {
            limit: Some(limit),
            given: true,
        };
        // Within the bound: the window's size.
        assert_eq!(bound.fit(&s, [1000, 500]), [1000, 500]);
        assert_eq!(bound.fit(&s, [640, 360]), [640, 360]);
        // Above it: the largest frame of the same shape at or under the bound.
        let fitted = bound.fit(&s, [2000, 1000]);
        assert_eq!(fitted, [1000, 500]);
        let fitted = bound.fit(&s, [3000, 1000]);
        assert!(s.estimate(fitted).bytes <= limit, "{fitted:?}");
        assert!(
            s.estimate([fitted[0] + 1, (fitted[0] + 1) / 3]).bytes > limit,
            "{fitted:?}"
        );
        assert_eq!(fitted[1], fitted[0] / 3);
        // Two sides count twice: half the pixels.
        let split = Sizing {
            split: true,
            ..s.clone()
        };
        let fitted = bound.fit(&split, [1000, 500]);
        assert!(fitted[0] < 1000 && split.estimate(fitted).bytes <= limit);
        // A bound below the process itself: one pixel, never zero.
        let tiny = Bound {
            limit: Some(1),
            given: true,
        };
        assert_eq!(tiny.fit(&s, [800, 600]), [1, 1]);
        // No bound: the window.
        let none = Bound {
            limit: None,
            given: false,
        };
        assert_eq!(none.fit(&s, [8192, 8192]), [8192, 8192]);
    }
}
