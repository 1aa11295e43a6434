//! The cost of silhouettes in the benchmark: the whole frame of `scenes/rocks_sphere.toml`
//! and `scenes/materials.toml` (bundled maps only; the files are compiled in) with what
//! draws carved outlines and what a miss shows, against the same frame without them.
//!
//! * **With**: displaced meshes traced as curved geometry
//!   ([`Renderer::set_curved`]) and the behind layer ([`Renderer::set_behind`]; on by
//!   default for the materials scene, turned on for the rocks sphere as `render --curved`
//!   does for a mesh drawn alone, where it is empty: a convex mesh alone shows nothing
//!   behind its misses, [`Renderer::behind_empty`]).
//! * **Without**: tangent-plane tracing and no behind layer.
//!
//! Four renderers at the benchmark's frame size, each timed like the methods sweep (one
//! untimed warm-up frame, then `R` interleaved passes over `K` frames, frame by frame
//! across the four; the camera does not turn). A frame is every per-frame pass (G-buffer,
//! classify, trace, shade, behind; not the one-off pyramid builds); each time is the
//! **minimum** over the `K R` frames, its spread the lowest and highest of the `R`
//! per-pass minima, and the ratio is also given from the medians over every frame.
//! Beside each ratio: the share of the frame's pixels of materials traced as curved (the
//! displaced meshes of methods with a curved path) and the share whose displaced ray
//! missed (the pixels the behind layer shows something behind; its work is kept to the
//! 8x8 tiles holding them).

use super::materials::Stat;
use crate::scene_file::SceneFile;
use dispmap::abi::NO_HIT_HEIGHT;
use dispmap::context::Context;
use dispmap::error::{Error, Result};
use dispmap::passes::PassName;
use dispmap::renderer::{RenderSettings, Renderer, SceneAssets};
use dispmap::scene::Geometry;
use std::path::Path;
use std::sync::Arc;

/// The scenes, by the name the report gives them, with their text.
const SCENES: [(&str, &str); 2] = [
    (
        "rocks_sphere",
        include_str!("../../../scenes/rocks_sphere.toml"),
    ),
    ("materials", include_str!("../../../scenes/materials.toml")),
];

/// The bound the numbers are read against: the frame with silhouettes over the frame
/// without them, on lavapipe.
pub const SILHOUETTE_BOUND: f64 = 1.3;

/// One scene's numbers.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SceneCost {
    /// The scene's name (`rocks_sphere`, `materials`).
    pub scene: String,
    /// The frame without silhouettes, ms.
    pub without: Stat,
    /// The frame with them, ms.
    pub with: Stat,
    /// `with` over `without`, and the spread of the per-pass ratios.
    pub ratio: Stat,
    /// The same ratio of the medians over every frame.
    pub median_ratio: f64,
    /// The behind layer's own time in the frame with silhouettes (0 without one), ms.
    pub behind: Stat,
    /// Whether the frame with silhouettes has the behind layer on but empty (a convex
    /// mesh alone: nothing drawn, nothing timed).
    pub behind_empty: bool,
    /// Share of the frame's pixels of materials traced as curved.
    pub curved_share: f64,
    /// Share of the frame's pixels whose displaced ray missed (filled by the behind
    /// layer where the scene has one).
    pub missed_share: f64,
}

/// The results of [`run`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SilhouetteBench {
    /// Per scene.
    pub scenes: Vec<SceneCost>,
}

/// A renderer of `text` (a scene file of bundled maps) at `frame`, and the material
/// indices of its displaced meshes whose method has a curved path (what curved tracing
/// traces as curved).
fn renderer(
    ctx: &Arc<Context>,
    name: &str,
    text: &str,
    frame: [u32; 2],
) -> Result<(Renderer, Vec<u32>)> {
    let path = Path::new("scenes").join(format!("{name}.toml"));
    let file = SceneFile::parse(text, &path)?;
    let (field, settings, assets) = if file.has_objects() {
        let specs = crate::scene_objects::specs(&file, &path)?;
        let objects = crate::scene_objects::load(&specs, &path)?;
        let field = objects
            .iter()
            .find_map(|o| Some(o.material.as_ref()?.0.clone()))
            .ok_or_else(|| Error::invalid(name, "no displaced object"))?;
        let assets = SceneAssets {
            objects,
            ..SceneAssets::default()
        };
        let settings = assets.settings(file.settings(&path)?);
        (field, settings, assets)
    } else {
        let loaded = file.resolve(&path)?;
        (loaded.field, loaded.settings, loaded.assets)
    };
    let settings = RenderSettings {
        width: frame[0],
        height: frame[1],
        ..settings
    };
    let renderer = Renderer::with_assets(ctx, &field, settings, &assets)?;
    let plane = |g: Geometry| matches!(g, Geometry::TiledPlane | Geometry::Quad);
    let meshes = if assets.objects.is_empty() {
        renderer
            .object_materials()
            .iter()
            .flatten()
            .filter(|_| {
                !plane(renderer.settings().scene.geometry)
                    && renderer.settings().method.traces_curved()
            })
            .map(|m| m.index())
            .collect()
    } else {
        renderer
            .object_materials()
            .iter()
            .zip(&assets.objects)
            .filter(|(_, o)| {
                !plane(o.geometry)
                    && o.material
                        .as_ref()
                        .is_some_and(|(_, m, _)| m.method.traces_curved())
            })
            .filter_map(|(m, _)| m.map(|m| m.index()))
            .collect()
    };
    Ok((renderer, meshes))
}

/// Per-pass minima and every frame's time of one renderer.
#[derive(Default)]
struct Times {
    frame: Vec<f64>,
    behind: Vec<f64>,
    all_frame: Vec<f64>,
}

/// Runs the four renderers at `frame` with `frames` x `repeat` timed frames each;
/// `progress` is called after each pass over the frames.
pub fn run(
    ctx: &Arc<Context>,
    frame: [u32; 2],
    frames: u32,
    repeat: u32,
    progress: &mut dyn FnMut(u32),
) -> Result<SilhouetteBench> {
    // Per scene: without, then with.
    let mut renderers = Vec::new();
    let mut shares = Vec::new();
    for (name, text) in SCENES {
        let (mut without, _) = renderer(ctx, name, text, frame)?;
        if without.behind() {
            without.set_behind(false)?;
        }
        without.render()?; // warm-up: pipelines, pyramids
        let (mut with, meshes) = renderer(ctx, name, text, frame)?;
        with.set_curved(true)?;
        // A curved mesh drawn alone shows itself behind a miss, as `render --curved` draws it.
        if !meshes.is_empty() && !with.behind() {
            with.set_behind(true)?;
        }
        with.render()?;
        let materials = with.read_materials()?;
        let hits = with.read_hits()?;
        let pixels = materials.len().max(1) as f64;
        let curved = materials
            .iter()
            .filter(|m| m.is_some_and(|m| meshes.contains(&m)))
            .count();
        let missed = materials
            .iter()
            .zip(&hits)
            .filter(|(m, h)| m.is_some() && h[2] == NO_HIT_HEIGHT)
            .count();
        shares.push((
            curved as f64 / pixels,
            missed as f64 / pixels,
            with.behind_empty(),
        ));
        renderers.push(without);
        renderers.push(with);
    }
    let mut times: Vec<Times> = (0..renderers.len()).map(|_| Times::default()).collect();
    for r in 0..repeat {
        for t in &mut times {
            t.frame.push(f64::INFINITY);
            t.behind.push(f64::INFINITY);
        }
        for _ in 0..frames {
            for (renderer, t) in renderers.iter_mut().zip(&mut times) {
                let passes = renderer.render()?;
                let sum = |keep: &dyn Fn(PassName) -> bool| -> f64 {
                    passes
                        .iter()
                        .filter(|(n, _)| keep(*n))
                        .fold(0.0, |acc, (_, ms)| acc + ms)
                };
                let whole = sum(&|n| !n.is_one_off());
                let behind = sum(&|n| n == PassName::Behind);
                let k = r as usize;
                t.frame[k] = t.frame[k].min(whole);
                t.behind[k] = t.behind[k].min(behind);
                t.all_frame.push(whole);
            }
        }
        progress(r + 1);
    }
    let median = dispmap::timing::median;
    let scenes = SCENES
        .iter()
        .zip(times.chunks(2))
        .zip(&shares)
        .map(
            |(((name, _), pair), &(curved_share, missed_share, behind_empty))| {
                let (without, with) = (&pair[0], &pair[1]);
                let per_pass: Vec<f64> = with
                    .frame
                    .iter()
                    .zip(&without.frame)
                    .map(|(w, o)| w / o)
                    .collect();
                let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
                SceneCost {
                    scene: (*name).to_owned(),
                    without: Stat::of(&without.frame),
                    with: Stat::of(&with.frame),
                    ratio: Stat {
                        min: min(&with.frame) / min(&without.frame),
                        ..Stat::of(&per_pass)
                    },
                    median_ratio: median(&with.all_frame) / median(&without.all_frame),
                    behind: Stat::of(&with.behind),
                    behind_empty,
                    curved_share,
                    missed_share,
                }
            },
        )
        .collect();
    Ok(SilhouetteBench { scenes })
}

/// The report's section.
pub fn markdown(b: &SilhouetteBench, frame: [u32; 2]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let spread = |t: &Stat| format!("{:.3} ({:.3}-{:.3})", t.min, t.lo, t.hi);
    let _ = writeln!(
        s,
        "\n## The cost of silhouettes\n\n\
         {}x{}, the whole frame (every per-frame pass) of `scenes/rocks_sphere.toml` and \
         `scenes/materials.toml` with curved tracing and the behind layer against the \
         same frame traced on tangent planes without the behind layer \
         (`dispmap_cli::bench::silhouettes`). Minimum over the frames (lowest-highest \
         per-pass minimum), ms; the ratio also from the medians. Curved: share of the \
         pixels of materials traced as curved (displaced meshes of `exact`, `relief` and \
         `pom`: each pays the curved setup, a flat face skips the curved march); missed: \
         share whose displaced ray missed (what the behind layer fills; its draws, light and \
         classify are kept to the 8x8 tiles holding them; a convex mesh alone has it \
         empty: nothing of it lies behind its own misses).\n",
        frame[0], frame[1]
    );
    let _ = writeln!(
        s,
        "| scene | without | with | behind layer | with / without | medians | bound | curved | missed |\n\
         |---|---|---|---|---|---|---|---|---|"
    );
    for c in &b.scenes {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.3} | {} | {:.1}% | {:.2}% |",
            c.scene,
            spread(&c.without),
            spread(&c.with),
            if c.behind_empty {
                "empty (convex)".to_owned()
            } else if c.behind.hi > 0.0 {
                spread(&c.behind)
            } else {
                "none".to_owned()
            },
            spread(&c.ratio),
            c.median_ratio,
            super::materials::bound_cell(c.median_ratio, SILHOUETTE_BOUND),
            100.0 * c.curved_share,
            100.0 * c.missed_share,
        );
    }
    s
}
