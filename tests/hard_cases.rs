//! The hard-case matrix (issue 7): every method on hostile view directions, height fields
//! and coordinates, checked against the exact CPU reference, under validation (core +
//! synchronization) with a leak check at teardown. One row of [`cases`] per case; run
//! with `--nocapture` to see the measured table.
//!
//! # How rays get in
//!
//! Exact view directions (P = 0, exactly along U, ...) cannot come out of a rasterised
//! camera, so most rows *upload* a G-buffer of chosen rays (`common::host::RayHost`) and
//! run the pass through `dispmap::embed`, the path a host engine uses: an orthographic
//! grid of entry points `uv0 = origin + (x, y) * pitch` (one per pixel, so DIG's block
//! corners see a coherent view) with one parallax vector `P` for all. Rows that need the
//! G-buffer shader itself (a camera below the surface, UVs far from the origin)
//! rasterise it with dispmap's `GBufferPass`. The reference traces the same f32 rays in
//! f64.
//!
//! # What every row checks, per method (each method's documented error)
//!
//! * every component of the hit buffer is finite; a hit has `height` in `[0, 1]`;
//! * a hit where the reference hits and a miss where it misses (repeat addressing always
//!   hits; no geometry is a miss). On a clamp-addressed decal `bump` hits wherever there
//!   is geometry, and the fixed-step searches may miss a hit a step skipped before the
//!   ray left the decal (an artifact, like any skipped feature);
//! * `exact`, `dig-guarded`, `cone-exact`: every pixel agrees with the reference within one texel, or
//!   the disagreement is a float-precision tangency (`common::unexplained` with
//!   `TANGENCY`, as in tests/methods.rs); `pyramid`: the same with its documented skim
//!   depth (`PYRAMID_SKIM`);
//! * `linear`, `relief`, `pom`, `secant`, `dig`, `cone`, `relaxed-cone` (fixed-step
//!   searches; the cone methods' within each cell's band, `relaxed-cone`'s bisection over
//!   a whole relaxed step too): never a hit in open
//!   air: within one linear step after the reported hit the ray reaches the surface, up
//!   to the hardware filter's precision (`FILTER_TOLERANCE`). They may report a *later*
//!   hit only past a feature thinner than a step (counted as artifacts and printed):
//!   within one step before such a hit the ray is in open air, up to the filter's
//!   precision; a hit deeper inside the surface (an overshoot: a cone step or a search
//!   that went through the surface) fails;
//! * `bump`: the hit is the entry point (`uv` = `uv0` bit for bit).
//!
//! Rows add what the case is about: the spike found (by `exact` and `dig-guarded`; DIG's
//! count is printed), every method equal to `bump` at depth scale 0, no geometry seen
//! from below, the tile-local rays at a 10^4-tile offset.
//!
//! `HARD_DEBUG=<method>` prints that method's pixels more than a texel off the reference.

mod common;

use ash::vk;
use common::host::RayHost;
use common::{finish, unexplained, validated_context};
use dispmap::Context;
use dispmap::abi::{GBufferParams, PixelRayParams};
use dispmap::embed::{DisplacementPass, PassSettings};
use dispmap::heightfield::{Addressing, Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::scene::Scene;
use dispmap_cli::metrics::{self, MapGeometry};
use dispmap_cli::reference::{Hit, Ray, Reference};
use glam::{Mat4, Vec3, Vec4};
use image::{DynamicImage, ImageBuffer, Luma};
use std::collections::HashMap;
use std::sync::Arc;

/// Frame side in pixels: 48x48 = 2304 rays per case.
const FRAME: u32 = 48;
/// The default depth scale (tile units), the scene's.
const DEPTH: f32 = 0.1;
/// Float-precision tangency (in heights, the depth being 1): as tests/methods.rs.
const TANGENCY: f64 = 1e-6;
/// The deepest skim the pyramid method may step over (tests/methods.rs).
const PYRAMID_SKIM: f64 = 1.8e-3;
/// How far a hardware-filtered height may lie from the exact bilinear one: lavapipe (and
/// NVIDIA) filter with 8-bit weights, an error of up to 1/256 of a cell's height range.
const FILTER_TOLERANCE: f64 = 1.0 / 200.0;

/// How a case makes its rays.
#[derive(Clone, Copy)]
enum Rays {
    /// Uploaded: `uv0 = origin + (x, y) * pitch` for pixel `(x, y)`, one `P` for all.
    Ortho {
        origin: [f32; 2],
        pitch: f32,
        p: [f32; 2],
    },
    /// Rasterised by `GBufferPass` from the default scene's camera, `edit` applied to
    /// its parameters.
    Camera(fn(&mut GBufferParams)),
}

/// What a case checks beyond every method's own error (module docs).
#[derive(Clone, Copy, PartialEq)]
enum Extra {
    None,
    /// A one-texel spike above a flat floor at this height: the reference sees it on
    /// some pixels, and `exact` and `dig-guarded` find it on all of them.
    Spike {
        floor: f32,
    },
    /// Depth scale 0: every method returns `bump`'s hit (uv bit for bit, height within
    /// its step and the filter's precision).
    EqualsBump,
    /// No pixel has geometry (seen from below): every method misses everywhere.
    NoGeometry,
    /// Far from the origin: the G-buffer's tile-local `uv0` is within `uv_tolerance`
    /// tiles of the unshifted frame's (wrapped), `P` within `p_tolerance` (relative).
    TileLocal {
        uv_tolerance: f64,
        p_tolerance: f64,
    },
}

/// One row of the matrix.
struct Case {
    name: &'static str,
    /// The height field, given the device's `maxImageDimension2D`.
    map: fn(u32) -> HeightField,
    rays: Rays,
    depth_scale: f32,
    extra: Extra,
    /// `Repeat` (the tiled plane) unless the row is a [`decal`].
    addressing: Addressing,
}

/// `P` for a view `elevation` degrees above the plane at `azimuth` degrees from `+u`.
fn view(elevation_deg: f64, azimuth_deg: f64, depth_scale: f64) -> [f32; 2] {
    let len = depth_scale / elevation_deg.to_radians().tan();
    let a = azimuth_deg.to_radians();
    [(len * a.cos()) as f32, (len * a.sin()) as f32]
}

/// The orthographic grid most rows use: one tile across the frame, off the texel grid.
fn ortho(p: [f32; 2]) -> Rays {
    Rays::Ortho {
        origin: [0.013, 0.029],
        pitch: 1.0 / FRAME as f32,
        p,
    }
}

/// The general direction of the height-field rows: 20 degrees above the plane, 30
/// degrees from the U axis.
fn oblique() -> Rays {
    ortho(oblique_p())
}

fn oblique_p() -> [f32; 2] {
    view(20.0, 30.0, f64::from(DEPTH))
}

fn rocks(_: u32) -> HeightField {
    common::asset_map("rocks_depth.jpg", Convention::Depth)
}

fn flat(value: f32) -> HeightField {
    HeightField::from_heights(64, 64, vec![value; 64 * 64], "flat").unwrap()
}

fn spike(_: u32) -> HeightField {
    let mut v = vec![0.25; 64 * 64];
    v[32 * 64 + 32] = 1.0;
    HeightField::from_heights(64, 64, v, "spike").unwrap()
}

fn wall(_: u32) -> HeightField {
    HeightField::from_fn(64, 64, "wall", |u, _| {
        if (u * 64.0) as u32 == 32 { 1.0 } else { 0.25 }
    })
    .unwrap()
}

fn checker(_: u32) -> HeightField {
    HeightField::from_fn(64, 64, "checker", |u, v| {
        ((u * 64.0) as u32 + (v * 64.0) as u32) as f32 % 2.0
    })
    .unwrap()
}

fn r16(width: u32, height: u32, label: &str, f: impl Fn(u32, u32) -> u16) -> HeightField {
    let img = ImageBuffer::<Luma<u16>, Vec<u16>>::from_fn(width, height, |i, j| Luma([f(i, j)]));
    HeightField::from_image(
        DynamicImage::ImageLuma16(img),
        Convention::Height,
        label.into(),
    )
    .unwrap()
}

/// Every texel a different 16-bit level, consecutive levels side by side.
fn levels_ramp(_: u32) -> HeightField {
    r16(64, 64, "16-bit ramp", |i, j| 30000 + (i + 64 * j) as u16)
}

/// Two 16-bit levels one apart, as a checkerboard: a surface flat within 1.5e-5.
fn levels_checker(_: u32) -> HeightField {
    r16(64, 64, "16-bit checker", |i, j| {
        32768 + ((i + j) % 2) as u16
    })
}

/// A smooth procedural field of any size.
fn bumps(width: u32, height: u32) -> HeightField {
    HeightField::from_fn(width, height, "bumps", |u, v| {
        0.5 + 0.45 * (u * 37.0).sin() * (v * 23.0 + u * 5.0).cos()
    })
    .unwrap()
}

/// One row: `name`, map, rays, depth scale, extra check.
fn row(
    name: &'static str,
    map: fn(u32) -> HeightField,
    rays: Rays,
    depth_scale: f32,
    extra: Extra,
) -> Case {
    Case {
        name,
        map,
        rays,
        depth_scale,
        extra,
        addressing: Addressing::Repeat,
    }
}

/// A row as a clamp-addressed decal: a ray leaving `[0, 1]^2` before it hits is a miss.
fn decal(case: Case) -> Case {
    Case {
        addressing: Addressing::Clamp,
        ..case
    }
}

/// The hard cases, one per row. To add a case (e.g. a macro-geometry scene), add a row;
/// to add a check, add an `Extra` and its arm in `check_extra`.
#[rustfmt::skip]
fn cases() -> Vec<Case> {
    use Extra as E;
    let d = f64::from(DEPTH);
    let corners = Rays::Ortho { origin: [0.0, 0.0], pitch: 1.0 / 256.0, p: [0.25, 0.25] };
    let centres = Rays::Ortho { origin: [0.5 / 1024.0, 0.5 / 1024.0], pitch: 1.0 / 256.0, p: [-0.25, 0.25] };
    // The spike at texel (32, 32) seen by the rays entering upstream of it, at 1 and 4
    // pixels per texel.
    let spike_1px = Rays::Ortho { origin: [0.26, 0.27], pitch: 1.0 / 64.0, p: oblique_p() };
    let spike_4px = Rays::Ortho { origin: [0.325, 0.362], pitch: 1.0 / 256.0, p: oblique_p() };
    // The G-buffer's clamp -V.z >= MIN_COS = 1e-4 bounds |P| by depth_scale / 1e-4.
    let clamp_elevation = 1e-4f64.atan().to_degrees();
    vec![
        // View directions (rocks, 1024x1024 8-bit).
        row("0.5 deg above grazing",           rocks,     ortho(view(0.5, 30.0, d)),   DEPTH, E::None),
        row("0.1 deg above grazing",           rocks,     ortho(view(0.1, 30.0, d)),   DEPTH, E::None),
        row("vertical (P = 0)",                rocks,     ortho([0.0, 0.0]),           DEPTH, E::None),
        row("exactly along U",                 rocks,     ortho([0.3, 0.0]),           DEPTH, E::None),
        row("exactly along -V",                rocks,     ortho([0.0, -0.3]),          DEPTH, E::None),
        row("diagonal through texel corners",  rocks,     corners,                     DEPTH, E::None),
        row("diagonal through texel centres",  rocks,     centres,                     DEPTH, E::None),
        row("from below (back faces)",         rocks,     Rays::Camera(from_below),    DEPTH, E::NoGeometry),
        // Height fields.
        row("all 0",                           |_| flat(0.0), oblique(),               DEPTH, E::None),
        row("all 1",                           |_| flat(1.0), oblique(),               DEPTH, E::None),
        row("one-texel spike, 1 px/texel",     spike,     spike_1px,                   DEPTH, E::Spike { floor: 0.25 }),
        row("one-texel spike, 4 px/texel",     spike,     spike_4px,                   DEPTH, E::Spike { floor: 0.25 }),
        row("one-texel wall",                  wall,      oblique(),                   DEPTH, E::None),
        row("Nyquist checkerboard",            checker,   oblique(),                   DEPTH, E::None),
        row("16-bit consecutive levels",       levels_ramp, oblique(),                 DEPTH, E::None),
        row("16-bit levels, checker",          levels_checker, oblique(),              DEPTH, E::None),
        row("1x1",                             |_| bumps(1, 1), oblique(),             DEPTH, E::None),
        row("1x7",                             |_| bumps(1, 7), oblique(),             DEPTH, E::None),
        row("3x5",                             |_| bumps(3, 5), oblique(),             DEPTH, E::None),
        row("1025x1025 (mountains, 16-bit)",   mountains, oblique(),                   DEPTH, E::None),
        row("4096x4096 (8-bit, the memory budget)", |_| bumps8(4096, 4096), oblique(), DEPTH, E::None),
        row("maxImageDimension2D x 1",         |max| bumps(max, 1), oblique(),         DEPTH, E::None),
        row("1 x maxImageDimension2D",         |max| bumps(1, max), oblique(),         DEPTH, E::None),
        // Coordinates: the surface 1e4 tiles from the origin, two ways. Since the
        // G-buffer takes each pixel's entry from its own centre ray in double-float,
        // relative to the eye (dispmap_plane_pixel_ray, issue 24), neither moves the
        // rays beyond the f32 rounding of uv0 in [0, 1): measured 3.0e-8 tiles (camera)
        // and 6.0e-8 (UVs), P identical. Before, with the interpolated entry: uv0 1.6e-3
        // tiles and P 3.8e-3 relative (the f32 world-space projection at 1e4 moving each
        // pixel's sample point), and a host whose interpolated UVs are 1e4 tiles from the
        // origin lost up to four ulps of 2^-10 tiles before the reduction to [0, 1) (it
        // still does if it interpolates: glsl/include/dispmap_gbuffer.glsl).
        row("camera 1e4 tiles from the origin", rocks,    Rays::Camera(far_camera),    DEPTH, E::TileLocal { uv_tolerance: 2e-7, p_tolerance: 1e-6 }),
        row("host UVs offset by 1e4 tiles",    rocks,     Rays::Camera(offset_uvs),    DEPTH, E::TileLocal { uv_tolerance: 2e-7, p_tolerance: 0.0 }),
        row("|P| = 115 tiles (0.05 deg)",      rocks,     ortho(view(0.05, 30.0, d)),  DEPTH, E::None),
        row("|P| = 1000 tiles (the clamp)",    rocks,     ortho(view(clamp_elevation, 30.0, d)), DEPTH, E::None),
        row("depth scale 0",                   rocks,     ortho([0.0, 0.0]),           0.0,   E::EqualsBump),
        // Clamp addressing: the silhouettes of a decal.
        decal(row("decal, 20 deg (silhouettes)", rocks,   oblique(),                   DEPTH, E::None)),
        decal(row("decal, 1 deg",              rocks,     ortho(view(1.0, 30.0, d)),   DEPTH, E::None)),
        decal(row("decal, 1x1 map",            |_| bumps(1, 1), oblique(),             DEPTH, E::None)),
        // Depth scale 1000 at grazing angles: |P| of 57,000 and 10^7 tiles.
        row("depth scale 1000 at 1 deg",       rocks,     ortho(view(1.0, 30.0, 1000.0)), 1000.0, E::None),
        row("depth scale 1000 at the clamp",   rocks,     ortho(view(clamp_elevation, 30.0, 1000.0)), 1000.0, E::None),
        row("depth scale 1000",                rocks,     ortho(view(30.0, 30.0, 1000.0)), 1000.0, E::None),
    ]
}

/// [`bumps`] as an 8-bit map.
fn bumps8(width: u32, height: u32) -> HeightField {
    let f = bumps(width, height);
    let img = image::GrayImage::from_fn(width, height, |i, j| {
        image::Luma([(f.texel(i, j) * 255.0).round() as u8])
    });
    HeightField::from_image(
        DynamicImage::ImageLuma8(img),
        Convention::Height,
        "bumps8".into(),
    )
    .unwrap()
}

fn mountains(_: u32) -> HeightField {
    common::asset_map("mountains_height16.png", Convention::Height)
}

/// The default camera mirrored below the plane: the G-buffer sees only back faces.
fn from_below(p: &mut GBufferParams) {
    p.view_proj *= Mat4::from_scale(Vec3::new(1.0, -1.0, 1.0));
    p.camera_pos.y = -p.camera_pos.y;
}

/// The tiled plane's UVs offset by 10^4 tiles, as a host's mesh far from the UV origin.
fn offset_uvs(p: &mut GBufferParams) {
    p.uv_rect += Vec4::splat(1e4);
}

/// The eye and the plane moved 10^4 tiles along x and z, as `Scene::gbuffer_params` lays
/// the plane out under an eye there (centred on the eye's tile, UVs centred on 0).
fn far_camera(p: &mut GBufferParams) {
    let offset = Vec3::new(1e4, 0.0, 1e4);
    // `view_proj` is eye-relative: it does not change when the eye moves.
    p.camera_pos += offset.extend(0.0);
    p.world_rect += Vec4::new(offset.x, offset.z, offset.x, offset.z);
}

/// The rays of a case (`None`: no geometry) after they went through the G-buffer.
fn make_rays(host: &mut RayHost, rays: Rays, depth_scale: f32) -> Vec<Option<Ray>> {
    match rays {
        Rays::Ortho { origin, pitch, p } => {
            let chosen: Vec<_> = (0..FRAME)
                .flat_map(|y| (0..FRAME).map(move |x| (x, y)))
                .map(|(x, y)| {
                    let uv = [origin[0] + x as f32 * pitch, origin[1] + y as f32 * pitch];
                    Some((uv, p))
                })
                .collect();
            host.set_rays(&chosen);
        }
        Rays::Camera(edit) => {
            let (params, rays) = camera_params(edit, depth_scale);
            host.rasterise(&params, &rays);
        }
    }
    host.read_rays()
}

/// The G-buffer's push constants and pixel rays of the default scene, `edit`ed. The
/// pixel rays' eye is `camera_pos` (as edited) plus the f64 eye's offset from the
/// unedited `camera_pos`, so a moved frame is the base frame shifted by exactly the f32
/// difference of the two `camera_pos`.
fn camera_params(
    edit: fn(&mut GBufferParams),
    depth_scale: f32,
) -> (GBufferParams, PixelRayParams) {
    let scene = Scene {
        depth_scale,
        ..Scene::default()
    };
    let camera = scene.frame_camera(FRAME, FRAME);
    let mut params = scene.gbuffer_params(&camera);
    let mut rays = camera.pixel_ray_params();
    let base = camera.eye.as_dvec3();
    edit(&mut params);
    for k in 0..3 {
        rays.eye_hi[k] = params.camera_pos[k];
        rays.eye_lo[k] = (camera.rays.eye[k] - base[k]) as f32;
    }
    (params, rays)
}

/// One linear step of the fixed-step searches, in the ray parameter `t` (`None`: the
/// method is checked otherwise).
fn step(method: Method, p: &MethodParams) -> Option<f64> {
    let n = match method {
        Method::Linear | Method::Relief | Method::Dig | Method::Cone | Method::RelaxedCone => {
            p.steps
        }
        Method::Pom => p.min_steps.min(p.steps),
        Method::Secant => p.steps * p.segments,
        Method::Bump | Method::Pyramid | Method::Exact | Method::DigGuarded | Method::ConeExact => {
            return None;
        }
    };
    Some(1.0 / f64::from(n.max(1)))
}

/// The measured outcome of one method on one case.
struct Outcome {
    method: Method,
    artifact_fraction: f64,
    /// Fixed-step searches: hits more than one step in front of the exact first hit
    /// (each must touch the surface within the filter's precision: a skim).
    in_front: usize,
    /// The worst of those touches (the deepest the ray stays above the surface over the
    /// step after such a hit; `-FILTER_TOLERANCE` at worst allowed).
    worst_touch: f64,
    /// Fixed-step searches: hits more than one step behind the exact first hit (each
    /// must have the ray in open air within the step before it: a skipped feature).
    behind: usize,
    /// The worst of those: the least the surface rises above the ray over the step
    /// before such a hit (`FILTER_TOLERANCE` at worst allowed; more is an overshoot).
    worst_overshoot: f64,
    /// Spike rows: pixels whose hit is on the spike.
    spike_found: Option<usize>,
    failures: Vec<String>,
}

struct Frame<'a> {
    reference: &'a Reference,
    rays: &'a [Option<Ray>],
    exact: &'a [Option<Hit>],
    geometry: MapGeometry,
    addressing: Addressing,
}

fn check_method(method: Method, params: &MethodParams, f: &Frame, hits: &[[f32; 4]]) -> Outcome {
    let mut failures = Vec::new();
    let nonfinite = hits
        .iter()
        .filter(|h| h.iter().any(|c| !c.is_finite()))
        .count();
    if nonfinite > 0 {
        failures.push(format!("{nonfinite} non-finite pixels"));
    }
    let (mut in_front, mut worst_touch): (usize, f64) = (0, 0.0);
    let (mut behind, mut worst_overshoot): (usize, f64) = (0, f64::NEG_INFINITY);
    for (i, ((hit, exact), ray)) in hits.iter().zip(f.exact).zip(f.rays).enumerate() {
        let gpu_hit = hit[2] >= 0.0;
        // On a decal `bump` hits wherever there is geometry, and a fixed-step search
        // misses a hit that a step skipped before the ray left the decal (an artifact, as
        // any skipped feature).
        let clamp = f.addressing == Addressing::Clamp;
        let allowed = clamp
            && ((method == Method::Bump && exact.is_none())
                || (step(method, params).is_some() && !gpu_hit));
        if gpu_hit != exact.is_some() && !allowed {
            failures.push(format!(
                "pixel {i}: hit {hit:?}, reference {exact:?} (ray {ray:?})"
            ));
            continue;
        }
        let (Some(ray), true) = (ray, gpu_hit) else {
            continue;
        };
        if !(0.0..=1.0).contains(&hit[2]) {
            failures.push(format!("pixel {i}: height {} outside [0, 1]", hit[2]));
        }
        if method == Method::Bump
            && [hit[0], hit[1]].map(f32::to_bits) != ray.uv0.map(|c| (c as f32).to_bits())
        {
            failures.push(format!(
                "pixel {i}: bump hit {hit:?} is not at uv0 {:?}",
                ray.uv0
            ));
        }
        if let (Some(dt), Some(exact)) = (step(method, params), exact) {
            // Never in front of the first surface by more than one step, unless the hit
            // touches the surface within the filter's precision (a skim).
            let t = 1.0 - f64::from(hit[2]);
            if exact.height - f64::from(hit[2]) < -(dt + 1e-6) {
                in_front += 1;
                let touch = (0..=64)
                    .map(|k| (t + dt * f64::from(k) / 64.0).min(1.0))
                    .map(|s| f.reference.penetration(ray, s))
                    .fold(f64::NEG_INFINITY, f64::max);
                worst_touch = worst_touch.min(touch);
                if touch < -FILTER_TOLERANCE {
                    failures.push(format!(
                        "pixel {i}: hit {hit:?} more than a step in front of the surface, in open air ({touch:.2e}; ray {ray:?}, exact {exact:?})"
                    ));
                }
            }
            // Never behind the first surface by more than one step, unless the ray is in
            // open air within the step before the hit (a feature thinner than a step
            // skipped, as the method's documentation allows): else an overshoot.
            if f64::from(hit[2]) - exact.height < -(dt + 1e-6) {
                behind += 1;
                let air = (0..=64)
                    .map(|k| (t - dt * f64::from(k) / 64.0).max(0.0))
                    .map(|s| f.reference.penetration(ray, s))
                    .fold(f64::INFINITY, f64::min);
                worst_overshoot = worst_overshoot.max(air);
                if air > FILTER_TOLERANCE {
                    failures.push(format!(
                        "pixel {i}: hit {hit:?} more than a step behind the first surface and under it over the whole step before (an overshoot: {air:.2e} under at least; ray {ray:?}, exact {exact:?})"
                    ));
                }
            }
        }
    }
    let skim = match method {
        Method::Exact | Method::DigGuarded | Method::ConeExact => Some(TANGENCY),
        Method::Pyramid => Some(PYRAMID_SKIM),
        _ => None,
    };
    if let Some(tolerance) = skim {
        let bad = unexplained(f.reference, f.rays, f.exact, hits, f.geometry, tolerance);
        if bad > 0 {
            failures.push(format!("{bad} pixels disagree with the reference"));
        }
    }
    let error = metrics::hit_errors(hits, f.exact, f.rays, f.geometry);
    if std::env::var("HARD_DEBUG").is_ok_and(|m| m == method.name()) {
        for ((h, e), r) in hits.iter().zip(f.exact).zip(f.rays) {
            if let Some(e) = e
                && metrics::hit_distance_texels(h, e, f.geometry) > 1.0
            {
                let r = r.unwrap();
                let (a, b) = (1.0 - f64::from(h[2]), 1.0 - e.height);
                let pens: Vec<f64> = (0..=10)
                    .map(|k| {
                        f.reference
                            .penetration(&r, a + (b - a) * f64::from(k) / 10.0)
                    })
                    .collect();
                eprintln!("DEBUG {h:?} {e:?} {r:?} pens {pens:?}");
            }
        }
    }
    failures.truncate(5);
    Outcome {
        method,
        artifact_fraction: error.artifact_fraction,
        in_front,
        worst_touch,
        behind,
        worst_overshoot,
        spike_found: None,
        failures,
    }
}

/// The case-specific checks of `extra`, on every method's hits (`all`, in `Method::ALL`
/// order).
fn check_extra(
    case: &Case,
    f: &Frame,
    all: &[Vec<[f32; 4]>],
    outcomes: &mut [Outcome],
    host: &mut RayHost,
) {
    match case.extra {
        Extra::None => {}
        Extra::Spike { floor } => {
            let on_spike = |h: f32| f64::from(h) > f64::from(floor) + 1e-3;
            let spike_pixels: Vec<usize> = f
                .exact
                .iter()
                .enumerate()
                .filter(|(_, h)| h.is_some_and(|h| on_spike(h.height as f32)))
                .map(|(i, _)| i)
                .collect();
            assert!(
                spike_pixels.len() >= 5,
                "{}: only {} rays meet the spike",
                case.name,
                spike_pixels.len()
            );
            for (o, hits) in outcomes.iter_mut().zip(all) {
                let found = spike_pixels
                    .iter()
                    .filter(|&&i| on_spike(hits[i][2]))
                    .count();
                o.spike_found = Some(found);
                if matches!(
                    o.method,
                    Method::Exact | Method::DigGuarded | Method::ConeExact
                ) && found != spike_pixels.len()
                {
                    o.failures.push(format!(
                        "found the spike on {found} of {} pixels",
                        spike_pixels.len()
                    ));
                }
            }
        }
        Extra::EqualsBump => {
            let bump = &all[Method::ALL.iter().position(|&m| m == Method::Bump).unwrap()];
            for (o, hits) in outcomes.iter_mut().zip(all) {
                let tolerance = step(o.method, &MethodParams::for_method(o.method)).unwrap_or(0.0)
                    + FILTER_TOLERANCE;
                for (i, (h, b)) in hits.iter().zip(bump).enumerate() {
                    let same_uv = [h[0], h[1]].map(f32::to_bits) == [b[0], b[1]].map(f32::to_bits);
                    if !same_uv || f64::from((h[2] - b[2]).abs()) > tolerance {
                        o.failures.push(format!("pixel {i}: {h:?} vs bump {b:?}"));
                        break;
                    }
                }
            }
        }
        Extra::NoGeometry => {
            assert!(
                f.rays.iter().all(Option::is_none),
                "{}: a back face has geometry",
                case.name
            );
            // The route itself draws the plane when the camera is above it.
            let (params, rays) = camera_params(|_| {}, case.depth_scale);
            host.rasterise(&params, &rays);
            let upright = host.read_rays().iter().filter(|r| r.is_some()).count();
            assert!(
                upright > host.pixels() / 2,
                "the upright camera covers only {upright} pixels"
            );
        }
        Extra::TileLocal {
            uv_tolerance,
            p_tolerance,
        } => {
            let (base_params, base_rays) = camera_params(|_| {}, case.depth_scale);
            host.rasterise(&base_params, &base_rays);
            let base = host.read_rays();
            // A moved eye is rounded to f32 (an ulp is 1e-3 tiles at 1e4): the frame is
            // then the exact frame of that rounded eye, shifted by the rounding. The
            // expected tile-local shift of uv0 is that rounding (the plane's uv is its
            // world x, z), computed in f64 from the two eyes.
            let eye_shift = match case.rays {
                Rays::Camera(edit) => {
                    let moved = camera_params(edit, case.depth_scale).0.camera_pos;
                    [0, 2].map(|k| f64::from(moved[k]) - f64::from(base_params.camera_pos[k]))
                }
                Rays::Ortho { .. } => [0.0; 2],
            };
            let (mut uv_worst, mut p_worst, mut compared): (f64, f64, usize) = (0.0, 0.0, 0);
            for (a, b) in f.rays.iter().zip(&base) {
                let (Some(a), Some(b)) = (a, b) else {
                    continue;
                };
                compared += 1;
                assert!(
                    (0..2).all(|k| (0.0..1.0).contains(&a.uv0[k])),
                    "uv0 {:?} is not tile-local",
                    a.uv0
                );
                for (k, shift) in eye_shift.iter().enumerate() {
                    let d = a.uv0[k] - b.uv0[k] - shift;
                    uv_worst = uv_worst.max((d - d.round()).abs());
                    let dp = (a.parallax[k] - b.parallax[k]).abs()
                        / b.parallax[0].hypot(b.parallax[1]).max(1e-9);
                    p_worst = p_worst.max(dp);
                }
            }
            eprintln!(
                "{}: {compared} pixels; tile-local uv0 within {uv_worst:.3e} tiles of the unshifted frame's (after the eye's f32 rounding, {eye_shift:?} tiles), P within {p_worst:.3e} (relative)",
                case.name
            );
            assert!(
                compared > host.pixels() / 2,
                "{}: only {compared} pixels covered in both",
                case.name
            );
            assert!(
                uv_worst <= uv_tolerance,
                "{}: uv0 moved by {uv_worst} tiles",
                case.name
            );
            assert!(
                p_worst <= p_tolerance,
                "{}: P moved by {p_worst} (relative)",
                case.name
            );
        }
    }
}

/// The passes of one run, one per (method, depth scale); the height map is swapped in.
struct Passes {
    ctx: Arc<Context>,
    passes: HashMap<(Method, u32, bool), DisplacementPass>,
}

impl Passes {
    fn get(
        &mut self,
        method: Method,
        depth_scale: f32,
        addressing: Addressing,
        field: &HeightField,
    ) -> &mut DisplacementPass {
        let ctx = self.ctx.clone();
        let pass = self
            .passes
            .entry((
                method,
                depth_scale.to_bits(),
                addressing == Addressing::Clamp,
            ))
            .or_insert_with(|| {
                DisplacementPass::new(
                    ctx,
                    field,
                    PassSettings {
                        method,
                        params: MethodParams::for_method(method),
                        depth_scale,
                        addressing,
                        extent: vk::Extent2D {
                            width: FRAME,
                            height: FRAME,
                        },
                        frames_in_flight: 1,
                    },
                )
                .unwrap()
            });
        pass.set_height_map(field).unwrap();
        pass
    }

    fn destroy(self) {
        for (_, mut pass) in self.passes {
            // SAFETY: every frame was waited for (`RayHost::trace`).
            unsafe { pass.destroy() };
        }
    }
}

fn run_case(case: &Case, host: &mut RayHost, passes: &mut Passes, max_dim: u32) -> Vec<Outcome> {
    let field = (case.map)(max_dim);
    let reference = Reference::new(&field, case.addressing);
    let rays = make_rays(host, case.rays, case.depth_scale);
    let exact = reference.trace(&rays);
    let frame = Frame {
        reference: &reference,
        rays: &rays,
        exact: &exact,
        geometry: MapGeometry {
            map_width: field.width(),
            map_height: field.height(),
            depth_scale: f64::from(case.depth_scale),
        },
        addressing: case.addressing,
    };
    let mut all = Vec::new();
    let mut outcomes = Vec::new();
    for &method in Method::ALL {
        let pass = passes.get(method, case.depth_scale, case.addressing, &field);
        let hits = host.trace(pass);
        outcomes.push(check_method(
            method,
            &MethodParams::for_method(method),
            &frame,
            &hits,
        ));
        all.push(hits);
    }
    check_extra(case, &frame, &all, &mut outcomes, host);
    outcomes
}

#[test]
fn hard_case_matrix() {
    let ctx = validated_context();
    let max_dim = ctx.info().max_image_dimension_2d;
    let extent = vk::Extent2D {
        width: FRAME,
        height: FRAME,
    };
    let mut host = RayHost::new(ctx.clone(), extent, 1);
    let mut passes = Passes {
        ctx: ctx.clone(),
        passes: HashMap::new(),
    };
    let mut failures = Vec::new();
    eprintln!(
        "{:<32} {}",
        "case",
        Method::ALL
            .iter()
            .map(|m| format!("{:>12}", m.name()))
            .collect::<String>()
    );
    for case in cases() {
        let outcomes = run_case(&case, &mut host, &mut passes, max_dim);
        let row: String = outcomes
            .iter()
            .map(|o| match o.spike_found {
                Some(n) => format!("{:>7.2}%/{n:>3}", 100.0 * o.artifact_fraction),
                None => format!("{:>11.2}%", 100.0 * o.artifact_fraction),
            })
            .collect();
        eprintln!("{:<32} {row}", case.name);
        for o in outcomes {
            if o.in_front > 0 {
                eprintln!(
                    "    {}: {} hits in front of the surface by more than a step (skims within {:.1e})",
                    o.method.name(),
                    o.in_front,
                    -o.worst_touch
                );
            }
            if o.behind > 0 {
                eprintln!(
                    "    {}: {} hits behind the first surface by more than a step (in open air within the step before, up to {:.1e} under)",
                    o.method.name(),
                    o.behind,
                    o.worst_overshoot
                );
            }
            for f in o.failures {
                failures.push(format!("{} / {}: {f}", case.name, o.method.name()));
            }
        }
    }
    passes.destroy();
    host.destroy();
    assert!(
        failures.is_empty(),
        "hard-case failures:\n{}",
        failures.join("\n")
    );
    finish(ctx);
}

/// Determinism: the same input gives a bit-identical hit buffer from two fresh passes,
/// and from a two-slot pass whatever the order its frames are recorded and in flight
/// (slot 1 first, so the first frame, which uploads the map and builds the pyramid, is
/// still running when slot 0's frame is submitted to read them; then slot 0 first).
#[test]
fn hits_are_bit_identical_across_runs_and_frame_orderings() {
    let ctx = validated_context();
    let field = rocks(0);
    let extent = vk::Extent2D {
        width: FRAME,
        height: FRAME,
    };
    let mut host = RayHost::new(ctx.clone(), extent, 2);
    make_rays(&mut host, ortho(view(5.0, 30.0, f64::from(DEPTH))), DEPTH);
    let settings = |method, frames_in_flight| PassSettings {
        method,
        params: MethodParams::for_method(method),
        depth_scale: DEPTH,
        addressing: Addressing::Repeat,
        extent,
        frames_in_flight,
    };
    for &method in Method::ALL {
        let bits = |hits: Vec<[f32; 4]>| -> Vec<[u32; 4]> {
            hits.iter().map(|h| h.map(f32::to_bits)).collect()
        };
        let mut runs = Vec::new();
        for _ in 0..2 {
            let mut pass = DisplacementPass::new(ctx.clone(), &field, settings(method, 1)).unwrap();
            runs.push(bits(host.trace(&mut pass)));
            // SAFETY: the frame was waited for (`trace`).
            unsafe { pass.destroy() };
        }
        let mut pass = DisplacementPass::new(ctx.clone(), &field, settings(method, 2)).unwrap();
        for order in [[1, 0], [0, 1]] {
            for s in order {
                host.submit(&mut pass, s);
            }
            for s in order {
                runs.push(bits(host.hits(s)));
            }
        }
        host.wait_all();
        // SAFETY: every frame was waited for.
        unsafe { pass.destroy() };
        let covered = runs[0]
            .iter()
            .filter(|h| f32::from_bits(h[2]) >= 0.0)
            .count();
        assert!(covered > host.pixels() / 2, "{method}: {covered} hits");
        for (k, run) in runs.iter().enumerate().skip(1) {
            let first = run.iter().zip(&runs[0]).position(|(a, b)| a != b);
            assert_eq!(
                first, None,
                "{method}: run {k} differs from run 0 at pixel {first:?}"
            );
        }
    }
    host.destroy();
    finish(ctx);
}
