//! The material-table numbers of the benchmark (issue 22): what a frame of several
//! displaced materials and flat geometry costs against its parts.
//!
//! The scene: a grid of 8 x 4 quads of half a tile (x in [-2, 2], z in [-1, 1]) seen
//! straight down ([`CAMERA_DISTANCE`] frames 2 tiles vertically: at 16:9 the grid fills
//! the frame), drawn with [`Renderer::with_objects`]. Six renderers, each timed like
//! the methods sweep (one untimed warm-up frame, then `R` interleaved passes over `K`
//! frames, frame by frame across the six; every time is the **minimum** over the `K R`
//! frames, its spread the lowest and highest of the `R` per-pass minima):
//!
//! * **(a) disjoint materials.** Columns 0-2 `exact` on bricks (depth 0.05), 3-4
//!   `relief` (64 steps) on rocks (0.1), 5-7 `pom` (64) on mountains (0.08), in one
//!   frame; and three frames where one of them is displaced and the other columns are
//!   flat ("alone on its own pixels"). Ratio: the frame's `trace` over the sum of the
//!   three alone frames' `trace` (bound: [`DISJOINT_BOUND`]).
//! * **(b) a tenth displaced.** All 32 quads one material (`relief` 64 on rocks, 0.1),
//!   against three inner quads of it displaced and the rest flat (about 10.5% of the
//!   pixels; the measured share is reported). Ratio: the pass's time (every pass after
//!   the G-buffer: `classify`, `trace`, `shade`) of the tenth over the full frame's
//!   (bound: [`TENTH_BOUND`]).
//!
//! Each ratio's spread is the range of the ratio of the per-pass minima. Each ratio is
//! also given from the medians over every frame: on a loaded machine a long interval's
//! minimum is inflated more than a short one's (it rarely runs unpreempted), which biases
//! (a)'s ratio of minima up and (b)'s down; the medians scale with the load on both sides.

use dispmap::context::Context;
use dispmap::embed::MaterialSettings;
use dispmap::error::Result;
use dispmap::heightfield::{Addressing, HeightField};
use dispmap::material::MaterialImages;
use dispmap::method::{Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::renderer::{ObjectMaterial, RenderSettings, Renderer, SceneObject};
use dispmap::scene::{Camera, Geometry, Placement, Scene};
use glam::Vec3;
use std::sync::Arc;

/// Orbit distance of the camera: `1 / tan(22.5 deg)`, two tiles across the frame's
/// height with the default 45-degree field of view.
pub const CAMERA_DISTANCE: f32 = 2.414_213_6;

/// Columns and rows of the grid of quads.
const GRID: [usize; 2] = [8, 4];

/// The displaced quads of (b): three inner ones (column, row).
const TENTH: [(usize, usize); 3] = [(3, 1), (4, 1), (3, 2)];

/// A time: the minimum over every frame, and the lowest and highest per-pass minimum.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Stat {
    /// The minimum.
    pub min: f64,
    /// Lowest per-pass minimum (= `min`).
    pub lo: f64,
    /// Highest per-pass minimum.
    pub hi: f64,
}

impl Stat {
    pub(crate) fn of(per_pass: &[f64]) -> Stat {
        let lo = per_pass.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = per_pass.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Stat { min: lo, lo, hi }
    }
}

/// The results of [`run`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MaterialsBench {
    /// (a): each material's `trace` alone on its own pixels (method, map, time).
    pub alone: Vec<(String, Stat)>,
    /// (a): the frame of the three materials, `trace`.
    pub combined_trace: Stat,
    /// (a): `combined_trace` over the sum of `alone`.
    pub disjoint_ratio: Stat,
    /// (a): the same ratio of the medians over every frame (on a loaded machine the
    /// minimum of a long interval is inflated more than a short one's: the median scales
    /// both with the load).
    pub disjoint_median_ratio: f64,
    /// (b): the measured share of displaced pixels of the tenth frame.
    pub tenth_share: f64,
    /// (b): the pass (every pass after the G-buffer) of the fully displaced frame.
    pub full_pass: Stat,
    /// (b): the same of the tenth frame.
    pub tenth_pass: Stat,
    /// (b): `tenth_pass` over `full_pass`.
    pub tenth_ratio: Stat,
    /// (b): the same ratio of the medians over every frame.
    pub tenth_median_ratio: f64,
}

/// One material of the scene.
struct Mat {
    label: String,
    field: HeightField,
    settings: MaterialSettings,
}

fn material(method: Method, field: HeightField, depth_scale: f32, name: &str) -> Mat {
    Mat {
        label: format!("{method} on {name}"),
        field,
        settings: MaterialSettings {
            method,
            params: MethodParams {
                steps: 64,
                refine_steps: super::REFINE_STEPS,
                ..MethodParams::for_method(method)
            },
            depth_scale,
            addressing: Addressing::Clamp,
        },
    }
}

/// The grid's objects, each quad with the material `which(column, row)` picks.
fn grid<'a>(
    images: &'a MaterialImages,
    which: impl Fn(usize, usize) -> Option<&'a Mat>,
) -> Vec<SceneObject<'a>> {
    let mut objects = Vec::new();
    for row in 0..GRID[1] {
        for col in 0..GRID[0] {
            objects.push(SceneObject {
                geometry: Geometry::Quad,
                placement: Placement {
                    position: Vec3::new(-2.0 + 0.5 * col as f32, 0.0, -1.0 + 0.5 * row as f32),
                    scale: 0.5,
                    rotation_deg: Vec3::ZERO,
                },
                mesh: None,
                material: which(col, row).map(|m| ObjectMaterial {
                    field: &m.field,
                    settings: m.settings,
                    images,
                }),
            });
        }
    }
    objects
}

/// Per pass over the frames, the minimum of each renderer's `trace` and of its pass.
struct Minima {
    trace: Vec<f64>,
    pass: Vec<f64>,
    /// Every frame's `trace` and pass, for the medians.
    all_trace: Vec<f64>,
    all_pass: Vec<f64>,
}

/// Runs the six renderers at `frame` with `frames` x `repeat` timed frames each;
/// `progress` is called after each pass over the frames.
pub fn run(
    ctx: &Arc<Context>,
    frame: [u32; 2],
    frames: u32,
    repeat: u32,
    progress: &mut dyn FnMut(u32),
) -> Result<MaterialsBench> {
    let bricks = material(Method::Exact, crate::bundled::bricks()?, 0.05, "bricks");
    let rocks = material(Method::Relief, crate::bundled::rocks()?, 0.1, "rocks");
    let mountains = material(
        Method::Pom,
        crate::bundled::by_name("mountains", "--maps")?,
        0.08,
        "mountains",
    );
    let images = MaterialImages::default();
    let column = |col: usize| -> &Mat {
        match col {
            0..=2 => &bricks,
            3..=4 => &rocks,
            _ => &mountains,
        }
    };
    let settings = RenderSettings {
        width: frame[0],
        height: frame[1],
        method: Method::Relief,
        params: MethodParams::default(),
        scene: Scene {
            camera: Camera {
                elevation_deg: 90.0,
                distance: Some(CAMERA_DISTANCE),
                ..Camera::default()
            },
            ..Scene::default()
        },
        shadows: Default::default(),
    };
    let mats = [&bricks, &rocks, &mountains];
    let mut scenes: Vec<Vec<SceneObject<'_>>> = vec![grid(&images, |c, _| Some(column(c)))];
    for m in mats {
        scenes.push(grid(&images, |c, _| {
            Some(column(c)).filter(|k| std::ptr::eq(*k, m))
        }));
    }
    scenes.push(grid(&images, |_, _| Some(&rocks)));
    scenes.push(grid(&images, |c, r| {
        TENTH.contains(&(c, r)).then_some(&rocks)
    }));
    let mut renderers = Vec::new();
    for objects in &scenes {
        let mut r = Renderer::with_objects(ctx, settings, objects)?;
        // What (a) and (b) measure is the per-material passes following the displaced
        // pixels; the behind layer (a second raster where a quad's rays leave it, on by
        // default in a scene of several objects) would add a raster of the whole grid to
        // every frame's "pass" sum. It is measured on its own by `render` ("behind").
        r.set_behind(false)?;
        r.render()?; // warm-up: pipelines, pyramids
        renderers.push(r);
    }
    let tenth = &renderers[5];
    let shown = tenth.read_materials()?;
    let tenth_share = shown.iter().filter(|m| m.is_some()).count() as f64 / shown.len() as f64;
    let mut minima: Vec<Minima> = (0..renderers.len())
        .map(|_| Minima {
            trace: Vec::new(),
            pass: Vec::new(),
            all_trace: Vec::new(),
            all_pass: Vec::new(),
        })
        .collect();
    for r in 0..repeat {
        for m in &mut minima {
            m.trace.push(f64::INFINITY);
            m.pass.push(f64::INFINITY);
        }
        for _ in 0..frames {
            for (renderer, m) in renderers.iter_mut().zip(&mut minima) {
                let times = renderer.render()?;
                let trace: f64 = times
                    .iter()
                    .filter(|(n, _)| *n == PassName::Trace)
                    .map(|(_, ms)| ms)
                    .sum();
                let pass: f64 = times
                    .iter()
                    .filter(|(n, _)| *n != PassName::GBuffer && !n.is_one_off())
                    .map(|(_, ms)| ms)
                    .sum();
                let k = r as usize;
                m.trace[k] = m.trace[k].min(trace);
                m.pass[k] = m.pass[k].min(pass);
                m.all_trace.push(trace);
                m.all_pass.push(pass);
            }
        }
        progress(r + 1);
    }
    let ratio = |f: &dyn Fn(usize) -> f64| -> Stat {
        let per_pass: Vec<f64> = (0..repeat as usize).map(f).collect();
        let all = Stat::of(&per_pass);
        Stat {
            min: f(usize::MAX),
            ..all
        }
    };
    // `usize::MAX` stands for "the minimum over every pass".
    let at = |v: &[f64], k: usize| {
        if k == usize::MAX {
            v.iter().copied().fold(f64::INFINITY, f64::min)
        } else {
            v[k]
        }
    };
    let disjoint_ratio =
        ratio(&|k| at(&minima[0].trace, k) / (1..=3).map(|i| at(&minima[i].trace, k)).sum::<f64>());
    let tenth_ratio = ratio(&|k| at(&minima[5].pass, k) / at(&minima[4].pass, k));
    let median = dispmap::timing::median;
    let disjoint_median_ratio =
        median(&minima[0].all_trace) / (1..=3).map(|i| median(&minima[i].all_trace)).sum::<f64>();
    let tenth_median_ratio = median(&minima[5].all_pass) / median(&minima[4].all_pass);
    Ok(MaterialsBench {
        alone: mats
            .iter()
            .zip(&minima[1..=3])
            .map(|(m, t)| (m.label.clone(), Stat::of(&t.trace)))
            .collect(),
        combined_trace: Stat::of(&minima[0].trace),
        disjoint_ratio,
        disjoint_median_ratio,
        tenth_share,
        full_pass: Stat::of(&minima[4].pass),
        tenth_pass: Stat::of(&minima[5].pass),
        tenth_ratio,
        tenth_median_ratio,
    })
}

/// The bound of (a): the three materials together over the sum of each alone.
pub const DISJOINT_BOUND: f64 = 1.1;
/// The bound of (b): a tenth of the frame displaced over the frame fully displaced.
pub const TENTH_BOUND: f64 = 0.2;

/// `<= bound`, with `met` or `**missed**` by `value`.
pub(crate) fn bound_cell(value: f64, bound: f64) -> String {
    if value <= bound {
        format!("<= {bound} (met)")
    } else {
        format!("<= {bound} (**missed**)")
    }
}

/// The report's section.
pub fn markdown(b: &MaterialsBench, frame: [u32; 2]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let spread = |t: &Stat| format!("{:.3} ({:.3}-{:.3})", t.min, t.lo, t.hi);
    let _ = writeln!(
        s,
        "\n## Several materials in one pass\n\n\
         {}x{}, a grid of 8 x 4 quads seen straight down (`dispmap_cli::bench::materials`): \
         **(a)** three materials side by side against each alone on its own pixels (the other \
         columns flat), `trace` ms; **(b)** {:.1}% of the pixels displaced against the same \
         frame fully displaced, every pass after the G-buffer (`classify`, `trace`, `shade`; \
         the behind layer off) ms. Minimum over the frames (lowest-highest per-pass minimum).\n",
        frame[0],
        frame[1],
        100.0 * b.tenth_share
    );
    let _ = writeln!(s, "| frame | ms | bound |\n|---|---|---|");
    for (label, t) in &b.alone {
        let _ = writeln!(s, "| (a) {label} alone, trace | {} | |", spread(t));
    }
    let _ = writeln!(
        s,
        "| (a) the three together, trace | {} | |\n\
         | (a) together / sum alone | {} | {} |\n\
         | (a) together / sum alone, medians | {:.3} | {} |\n\
         | (b) fully displaced, pass | {} | |\n\
         | (b) {:.1}% displaced, pass | {} | |\n\
         | (b) {:.1}% / fully displaced | {} | {} |\n\
         | (b) {:.1}% / fully displaced, medians | {:.3} | {} |",
        spread(&b.combined_trace),
        spread(&b.disjoint_ratio),
        bound_cell(b.disjoint_ratio.min, DISJOINT_BOUND),
        b.disjoint_median_ratio,
        bound_cell(b.disjoint_median_ratio, DISJOINT_BOUND),
        spread(&b.full_pass),
        100.0 * b.tenth_share,
        spread(&b.tenth_pass),
        100.0 * b.tenth_share,
        spread(&b.tenth_ratio),
        bound_cell(b.tenth_ratio.min, TENTH_BOUND),
        100.0 * b.tenth_share,
        b.tenth_median_ratio,
        bound_cell(b.tenth_median_ratio, TENTH_BOUND),
    );
    s
}
