//! Issue 24: `exact` on the tiled plane hits where each pixel's own centre ray hits. An
//! f64 tracer written from docs/design.md alone (`pixel_ray/tracer.rs`: its own camera,
//! bilinear field, max quadtree and ray / bilinear-patch solve; no library or CLI ray,
//! camera or reference code) traces the centre ray of every pixel of 192x108 frames of
//! the rocks, bricks and mountains maps at 0.5, 2 and 10 degrees (rocks also at azimuth
//! 37). No pixel's hit may be more than a texel from it (the 3-D hit distance of
//! docs/design.md, "Reference and error metrics"), and coverage (sky or plane) must agree,
//! apart from at most one tangency per frame: a pixel whose hit lies on the f64 ray and
//! where that ray passes within `TANGENCY` of the surface between the two hits. The hit
//! buffer's `u, v` are in the frame of the entry's tile; the corrected depth
//! (`--depth-out`) places the hit along the ray, which fixes the tile.
//! `tracer_is_not_vacuous` checks that the comparison fails on wrong conventions. Run
//! with `--nocapture` for the tables.
//!
//! With the rasterised G-buffer entry (main at a930f3d, before the pixel's own ray), at 2
//! degrees the first covered row's 192 entries were 2 to 88 texels from the centre ray's,
//! which put 1 to 4 hits a frame (where the ray skims a ridge) 20 to 22,223 texels off
//! (rocks, pixel (158, 49): 14,186 texels); 1 to 4 hits a frame at 0.5 and 10 degrees
//! were off by 2 to 4,141 texels where the interpolated ray passed 3e-6 of the depth from
//! the centre ray. With the pixel's own ray (692f387) every entry is within 0.05 texel,
//! p99 is 0.0001 to 0.0038 texel, and 3 of the 12 frames have one tangency (the f64 ray
//! clears the surface by 2e-8 to 3.4e-7 of the depth where `exact` stops, 1.6 to 3.7
//! texels from its hit).

mod common;
#[path = "pixel_ray/tracer.rs"]
mod tracer;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Scene};
use tracer::{Entry, Mistake, PixelRay, Surface, View};

/// The frame of the measurement.
const SIZE: (u32, u32) = (192, 108);
/// The elevations, degrees (azimuth 0, the default camera otherwise).
const ELEVATIONS: [f32; 3] = [0.5, 2.0, 10.0];
/// A second azimuth for rocks, so the rays cross both map axes.
const AZIMUTH: f32 = 37.0;
/// How far (in heights, the depth being 1) the f64 ray may pass above or below the
/// surface between the two hits and still count as a tangency: as tests/methods.rs.
const TANGENCY: f64 = 1e-6;
/// At most this many tangencies per frame (the issue: "apart from at most one").
const MAX_TANGENCIES: usize = 1;
/// More than this many texels off is a wrong hit.
const TEXEL: f64 = 1.0;

/// One rendered frame of `exact`.
struct Rendered {
    scene: Scene,
    hits: Vec<[f32; 4]>,
    depth: Vec<f32>,
    /// The G-buffer's entry `uv0` (tile-local), `None` without geometry.
    entries: Vec<Option<[f64; 2]>>,
}

/// The tiled plane seen from `(elevation, azimuth)`, degrees.
fn scene((elevation_deg, azimuth_deg): (f32, f32)) -> Scene {
    Scene {
        camera: Camera {
            elevation_deg,
            azimuth_deg,
            ..Camera::default()
        },
        ..Scene::default()
    }
}

/// Renders `exact` from each view (validation on, no message allowed).
fn render(field: &HeightField, views: &[(f32, f32)]) -> Vec<Rendered> {
    let ctx = validated_context();
    let frames = {
        let mut renderer = Renderer::new(
            &ctx,
            field,
            RenderSettings {
                width: SIZE.0,
                height: SIZE.1,
                method: Method::Exact,
                params: MethodParams::for_method(Method::Exact),
                scene: scene(views[0]),
                shadows: Default::default(),
            },
        )
        .unwrap();
        renderer.set_depth_output(true).unwrap();
        views
            .iter()
            .map(|&view| {
                renderer.set_scene(scene(view)).unwrap();
                renderer.render().unwrap();
                Rendered {
                    scene: scene(view),
                    hits: renderer.read_hits().unwrap(),
                    depth: renderer.read_depth().unwrap().unwrap(),
                    entries: renderer
                        .read_rays()
                        .unwrap()
                        .iter()
                        .map(|r| r.as_ref().map(|r| r.uv0))
                        .collect(),
                }
            })
            .collect()
    };
    finish(ctx);
    frames
}

/// The comparison of one frame.
#[derive(Default)]
struct Outcome {
    /// Pixels where both hit.
    compared: usize,
    /// Hit distances (texels) of the compared pixels.
    errors: Vec<f64>,
    /// The largest, with its pixel.
    worst: (f64, u32, u32),
    /// Pixels more than a texel off that are not tangencies, with what was found.
    wrong: Vec<String>,
    /// Pixels where one side hits the plane and the other does not.
    coverage: Vec<String>,
    /// Hits the corrected depth does not place on the ray (within a quarter tile).
    unplaced: Vec<String>,
    /// The tangencies, described.
    tangencies: Vec<String>,
    /// Pixels within a tile of the plane's edge (not compared).
    edge: usize,
    /// Rays whose parallax `MIN_COS` clamps.
    clamped: usize,
    /// Pixels whose G-buffer entry is more than a texel from the centre ray's (reported,
    /// not a failure: the hits are what must agree), and the largest such distance.
    entries_off: usize,
    entry_max: f64,
}

impl Outcome {
    fn failures(&self) -> usize {
        self.wrong.len() + self.coverage.len() + self.unplaced.len()
    }

    fn over_texel(&self) -> usize {
        self.wrong.len() + self.tangencies.len()
    }

    /// Nearest-rank percentile of the errors.
    fn percentile(&self, p: f64) -> f64 {
        let mut e = self.errors.clone();
        e.sort_by(|a, b| a.total_cmp(b));
        match e.len() {
            0 => 0.0,
            n => e[((p * n as f64).ceil() as usize).clamp(1, n) - 1],
        }
    }

    fn row(&self, label: &str) -> String {
        format!(
            "| {label} | {} | {} | {} | {} | {} | {:.4} | {:.2} at ({}, {}) | {} | {} ({:.1}) | {} |",
            self.compared,
            self.over_texel(),
            self.tangencies.len(),
            self.coverage.len(),
            self.unplaced.len(),
            self.percentile(0.99),
            self.worst.0,
            self.worst.1,
            self.worst.2,
            self.clamped,
            self.entries_off,
            self.entry_max,
            self.edge,
        )
    }
}

const HEADER: &str = "| frame | compared | > 1 texel | tangencies | coverage | unplaced | \
     p99 texels | max texels (pixel) | clamped P | entries > 1 texel (max) | edge |\n\
     |---|---|---|---|---|---|---|---|---|---|---|";

/// The hit distance of docs/design.md: `sqrt((du W)² + (dv H)² + (dh depth_scale
/// sqrt(W H))²)`, in texels.
fn texels(surface: &Surface, depth_scale: f64, a: ([f64; 2], f64), b: ([f64; 2], f64)) -> f64 {
    let [w, h] = surface.size();
    let du = (a.0[0] - b.0[0]) * w;
    let dv = (a.0[1] - b.0[1]) * h;
    let dh = (a.1 - b.1) * depth_scale * (w * h).sqrt();
    (du * du + dv * dv + dh * dh).sqrt()
}

fn along(ray: &PixelRay, t: f64) -> [f64; 2] {
    [0, 1].map(|k| ray.entry[k] + t * ray.parallax[k])
}

/// Compares `exact`'s frame with the f64 trace of every pixel's centre ray.
fn compare(frame: &Rendered, surface: &Surface, mistake: Mistake) -> Outcome {
    let view = View::new(&frame.scene, SIZE, mistake);
    let ds = f64::from(frame.scene.depth_scale);
    let mut out = Outcome::default();
    for y in 0..SIZE.1 {
        for x in 0..SIZE.0 {
            let i = (y * SIZE.0 + x) as usize;
            let hit = frame.hits[i];
            let gpu_hits = hit[2] >= 0.0;
            let ray = match (view.entry(x, y), gpu_hits) {
                (Entry::Edge, _) => {
                    out.edge += 1;
                    continue;
                }
                (Entry::Sky, false) => continue,
                (Entry::Sky, true) => {
                    out.coverage.push(format!(
                        "({x}, {y}): the centre ray misses the plane, exact hits {hit:?}"
                    ));
                    continue;
                }
                (Entry::Plane(ray), false) => {
                    out.coverage.push(format!(
                        "({x}, {y}): the centre ray enters the plane at {:?}, exact has no hit",
                        ray.entry
                    ));
                    continue;
                }
                (Entry::Plane(ray), true) => ray,
            };
            out.clamped += usize::from(ray.clamped);
            out.compared += 1;
            if let Some(uv0) = frame.entries[i] {
                let [w, h] = surface.size();
                let d = [0, 1].map(|k| {
                    let d = uv0[k] - ray.entry[k];
                    d - d.round()
                });
                let off = (d[0] * w).hypot(d[1] * h);
                out.entries_off += usize::from(off > TEXEL);
                out.entry_max = out.entry_max.max(off);
            }
            let t = surface.trace(&ray);
            let mine = (along(&ray, t), 1.0 - t);
            // The hit's u, v are in the frame of the entry's tile: the corrected depth
            // (a forward distance) says how far along the ray it is, which fixes the tile.
            let depth = f64::from(frame.depth[i]);
            let gpu_h = f64::from(hit[2]);
            let gpu_uv = [f64::from(hit[0]), f64::from(hit[1])];
            if !(depth.is_finite() && depth > 0.0) {
                out.unplaced
                    .push(format!("({x}, {y}): a hit {hit:?} with depth {depth}"));
                continue;
            }
            let distance = tracer::NEAR / depth;
            let fd = |t: f64| view.forward_distance(view.world(along(&ray, t), 1.0 - t));
            let (f0, f1) = (fd(0.0), fd(1.0));
            let t_depth = (distance - f0) / (f1 - f0);
            let near = along(&ray, t_depth);
            let gpu_uv = [0, 1].map(|k| gpu_uv[k] + (near[k] - gpu_uv[k]).round());
            let gpu = (gpu_uv, gpu_h);
            let residual = (view.forward_distance(view.world(gpu_uv, gpu_h)) - distance).abs();
            if residual > 0.25 {
                out.unplaced.push(format!(
                    "({x}, {y}): exact's hit {hit:?} at depth {depth:e} is {residual} tiles \
                     off the forward distance of any tile's copy"
                ));
                continue;
            }
            let error = texels(surface, ds, mine, gpu);
            out.errors.push(error);
            if error > out.worst.0 {
                out.worst = (error, x, y);
            }
            if error <= TEXEL {
                continue;
            }
            // A tangency: exact's hit lies on this ray, and between the two hits the ray
            // stays within TANGENCY of the surface (it touches at the earlier one).
            let p = ray.parallax;
            let t_gpu = ((gpu_uv[0] - ray.entry[0]) * p[0] + (gpu_uv[1] - ray.entry[1]) * p[1])
                / (p[0] * p[0] + p[1] * p[1]);
            let off_ray = texels(surface, ds, gpu, (along(&ray, t_gpu), 1.0 - t_gpu));
            // In heights (the depth being 1): a G-buffer ray offset along itself moves
            // the hit off this ray vertically, by little in texels at grazing angles.
            let above = gpu_h - (1.0 - t_gpu);
            let (a, b) = (t.min(t_gpu).clamp(0.0, 1.0), t.max(t_gpu).clamp(0.0, 1.0));
            // Where exact's hit can be along the ray: two f32 ulps of its height and of
            // its u, v.
            let eps = f64::from(f32::EPSILON);
            let stored = f64::from(hit[0].abs().max(hit[1].abs()));
            let reach = 2.0 * eps * stored.max(1.0) / p[0].abs().max(p[1].abs());
            let window = 2.0 * eps + reach;
            let clearance = (-64..=64)
                .map(|k| (a + window * f64::from(k) / 64.0).clamp(0.0, 1.0))
                .map(|s| -surface.penetration(&ray, s))
                .fold(f64::INFINITY, f64::min);
            let deepest = surface.deepest(&ray, a, b);
            let text = format!(
                "({x}, {y}): {error:.2} texels; f64 ray: uv ({:.6}, {:.6}) h {:.8} (t {t:.8}); \
                 exact: uv ({:.6}, {:.6}) h {gpu_h:.8} (t {t_gpu:.8} on the f64 ray, \
                 {off_ray:.2} texels off it, {above:.2e} above it); the f64 ray's clearance at the earlier hit \
                 {clearance:.2e}, deepest between {deepest:.2e}; entry ({:.4}, {:.4}), \
                 |P| {:.3}{}",
                mine.0[0],
                mine.0[1],
                mine.1,
                gpu_uv[0],
                gpu_uv[1],
                ray.entry[0],
                ray.entry[1],
                p[0].hypot(p[1]),
                if ray.clamped { " (clamped)" } else { "" },
            );
            if off_ray <= TEXEL && clearance <= TANGENCY && deepest <= TANGENCY {
                out.tangencies.push(text);
            } else {
                out.wrong.push(text);
            }
        }
    }
    out
}

/// Prints a frame's row and what went wrong in it.
fn report(label: &str, out: &Outcome) {
    println!("{}", out.row(label));
    for t in &out.tangencies {
        println!("    tangency {t}");
    }
    for list in [&out.wrong, &out.coverage, &out.unplaced] {
        for w in list.iter().take(4) {
            println!("    {w}");
        }
        if list.len() > 4 {
            println!("    ... {} more", list.len() - 4);
        }
    }
}

/// The check on one map: every view, every pixel.
fn check_map(name: &str, convention: Convention, views: &[(f32, f32)]) {
    // The tracer's documented constants are still the library's.
    assert_eq!(dispmap::scene::NEAR, tracer::NEAR as f32);
    assert_eq!(dispmap::scene::MIN_COS, tracer::MIN_COS as f32);
    assert_eq!(
        dispmap::scene::PLANE_HALF_EXTENT,
        tracer::PLANE_HALF_EXTENT as f32
    );
    let field = asset_map(name, convention);
    let surface = Surface::new(&field, Mistake::None);
    let frames = render(&field, views);
    println!("{HEADER}");
    let mut failed = Vec::new();
    for frame in &frames {
        let c = &frame.scene.camera;
        let label = format!("{name} {}° az {}°", c.elevation_deg, c.azimuth_deg);
        let out = compare(frame, &surface, Mistake::None);
        report(&label, &out);
        assert!(
            out.compared > (SIZE.0 * SIZE.1 / 4) as usize,
            "{label}: only {} pixels compared",
            out.compared
        );
        if out.failures() > 0 || out.tangencies.len() > MAX_TANGENCIES {
            failed.push(format!(
                "{label}: {} pixels more than a texel off, {} coverage disagreements, {} \
                 unplaced, {} tangencies (worst {:.2} texels at ({}, {}))",
                out.wrong.len(),
                out.coverage.len(),
                out.unplaced.len(),
                out.tangencies.len(),
                out.worst.0,
                out.worst.1,
                out.worst.2
            ));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// The elevations at azimuth 0, then at `azimuth` when given.
fn views(azimuth: Option<f32>) -> Vec<(f32, f32)> {
    let mut v: Vec<_> = ELEVATIONS.iter().map(|&e| (e, 0.0)).collect();
    v.extend(azimuth.into_iter().flat_map(|a| ELEVATIONS.map(|e| (e, a))));
    v
}

#[test]
fn rocks_follows_pixel_rays() {
    check_map("rocks_depth.jpg", Convention::Depth, &views(Some(AZIMUTH)));
}

#[test]
fn bricks_follows_pixel_rays() {
    check_map("bricks_depth.jpg", Convention::Depth, &views(None));
}

#[test]
fn mountains_follows_pixel_rays() {
    check_map("mountains_height16.png", Convention::Height, &views(None));
}

/// The tracer read with a wrong convention disagrees with `exact` on many pixels of rocks
/// at 10 degrees (frames the documented conventions match), so agreement is not vacuous:
/// at least 1% of the pixels, where the check allows one.
#[test]
fn tracer_is_not_vacuous() {
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let frames = render(&field, &[(10.0, 0.0), (10.0, AZIMUTH)]);
    println!("{HEADER}");
    for (mistake, frame) in [
        (Mistake::PixelCorners, 0),
        (Mistake::HalfTexelShift, 0),
        (Mistake::FlippedRows, 0),
        (Mistake::FlippedConvention, 0),
        (Mistake::MirroredAzimuth, 1),
    ] {
        let frame = &frames[frame];
        let out = compare(frame, &Surface::new(&field, mistake), mistake);
        let c = &frame.scene.camera;
        println!(
            "{}",
            out.row(&format!(
                "rocks {}° az {}° {mistake:?}",
                c.elevation_deg, c.azimuth_deg
            ))
        );
        let off = out.over_texel() + out.coverage.len() + out.unplaced.len();
        assert!(
            off * 100 > out.compared,
            "{mistake:?}: only {off} of {} pixels disagree",
            out.compared
        );
    }
}
