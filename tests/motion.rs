//! Motion vectors (`DisplacementPass::set_motion_output`, `passes::motion`), validation on
//! throughout:
//!
//! * a camera moving over static geometry: on the method scenes' `exact` frames (rocks,
//!   bricks, mountains on the tiled plane at 30, 5 and 1 degrees, the camera turning by
//!   1.7 degrees), the motion of each displaced pixel of frame N carries it onto the
//!   place where frame N-1 draws the same surface point (the hit's point in f64 from the
//!   documented conventions, projected by frame N-1's camera), wherever frame N-1 sees
//!   that point (the exact reference traces frame N-1's ray to it; hidden points have no
//!   place to go). The flat surface's motion is measured beside it: the check can fail;
//! * a moving object (a displaced patch turning and sliding in front of a still camera,
//!   its G-buffer and macro motion written by the test on the CPU): the error of the
//!   documented approximation (the surface's own move taken as a translation, the
//!   displacement offset unturned) against the exact motion of the displaced point,
//!   reported and checked against its bound.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::gpu::owned::Destroy;
use dispmap::heightfield::{Addressing, Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::gbuffer::Ray;
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Scene};
use dispmap_cli::reference::Reference;
use glam::{DMat4, DQuat, DVec2, DVec3, DVec4};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 144;
const ELEVATIONS: [f32; 3] = [30.0, 5.0, 1.0];
/// The camera's turn between the two frames (degrees of azimuth), about the issue's
/// measured orbit (1.7 degrees per frame).
const TURN_DEG: f32 = 1.7;
/// The largest reprojection error allowed (pixels).
const MOTION_TOL_PX: f64 = 0.05;

fn settings(elevation: f32) -> RenderSettings {
    RenderSettings {
        shadows: Default::default(),
        width: WIDTH,
        height: HEIGHT,
        method: Method::Exact,
        params: MethodParams::for_method(Method::Exact),
        scene: Scene {
            geometry: Geometry::TiledPlane,
            camera: Camera {
                elevation_deg: elevation,
                azimuth_deg: 20.0,
                ..Camera::default()
            },
            ..Scene::default()
        },
    }
}

/// A camera of a `size` frame in f64, from the documented conventions (docs/design.md,
/// "Camera and frame").
struct CpuCamera {
    eye: DVec3,
    view_proj: DMat4,
    inv_view_proj: DMat4,
    /// Frame size in pixels.
    size: DVec2,
    /// Pixels per unit of the image plane at distance 1 (vertical).
    focal_px: f64,
}

impl CpuCamera {
    fn new(scene: &Scene, width: u32, height: u32) -> Self {
        let cam = scene.frame_camera(width, height);
        let view_proj = cam.view_proj.as_dmat4();
        let half_fov = f64::from(scene.camera.fov_y_deg).to_radians() / 2.0;
        CpuCamera {
            eye: cam.eye.as_dvec3(),
            view_proj,
            inv_view_proj: view_proj.inverse(),
            size: DVec2::new(f64::from(width), f64::from(height)),
            focal_px: f64::from(height) / 2.0 / half_fov.tan(),
        }
    }

    /// The centre of pixel `i` (row by row).
    fn centre(&self, i: usize) -> DVec2 {
        let w = self.size.x as usize;
        DVec2::new((i % w) as f64 + 0.5, (i / w) as f64 + 0.5)
    }

    /// The unit direction through the point `px` of the frame (pixels).
    fn direction(&self, px: DVec2) -> DVec3 {
        let ndc = px / self.size * 2.0 - 1.0;
        let p = self.inv_view_proj * DVec4::new(ndc.x, ndc.y, 0.5, 1.0);
        ((p.truncate() / p.w) - self.eye).normalize()
    }

    /// The reverse-Z depth of a world point.
    fn depth(&self, p: DVec3) -> f64 {
        let c = self.view_proj * p.extend(1.0);
        c.z / c.w
    }

    /// Where a world point is drawn (pixels); `None` behind the eye.
    fn project(&self, p: DVec3) -> Option<DVec2> {
        let c = self.view_proj * p.extend(1.0);
        (c.w > 0.0).then(|| (DVec2::new(c.x, c.y) / c.w * 0.5 + 0.5) * self.size)
    }
}

/// The world point of a hit `(u, v, h)` of the tiled plane (u along +x, v along +z, the
/// surface `(1 - h) * depth` below y = 0) seen through pixel centre `px` of `camera`: the
/// hit's uv holds the point modulo a tile, the pixel's ray gives the tile.
fn hit_point(camera: &CpuCamera, px: DVec2, hit: [f32; 4], depth: f64) -> DVec3 {
    let d = camera.direction(px);
    let y = -(1.0 - f64::from(hit[2])) * depth;
    let on_ray = camera.eye + d * ((camera.eye.y - y) / -d.y);
    let (u, v) = (f64::from(hit[0]), f64::from(hit[1]));
    DVec3::new(u + (on_ray.x - u).round(), y, v + (on_ray.z - v).round())
}

/// Whether camera `a` sees the world point `p` (no surface in front of it): the exact
/// reference traces a's ray towards `p` from where it enters the macro plane, and its
/// first hit must be `p` (within a hundredth of a texel).
fn visible(a: &CpuCamera, reference: &Reference, p: DVec3, depth: f64, texels: f64) -> bool {
    let d = (p - a.eye).normalize();
    if d.y >= 0.0 {
        return false;
    }
    let entry = a.eye + d * (a.eye.y / -d.y);
    // Tangent space of the tiled plane: T = +x, B = +z, N = +y.
    let parallax = [depth * d.x / -d.y, depth * d.z / -d.y];
    let uv0 = [entry.x - entry.x.floor(), entry.z - entry.z.floor()];
    let ray = Ray { uv0, parallax };
    let Some(hit) = reference.intersect(&ray) else {
        return false;
    };
    let t = 1.0 - hit.height;
    let seen = DVec2::new(entry.x, entry.z) + DVec2::new(d.x, d.z) * (t * depth / -d.y);
    (seen - DVec2::new(p.x, p.z)).length() * texels <= 1e-2
}

/// Reprojection errors (pixels) of frame B's displaced pixels under `motion`: the
/// distance from where the motion sends each pixel to where camera `a` draws the pixel's
/// hit point, for the points `a` sees (the others were hidden in the previous frame).
fn reprojection_errors(
    a: &CpuCamera,
    b: &CpuCamera,
    reference: &Reference,
    (depth, texels): (f64, f64),
    hits: &[[f32; 4]],
    motion: &[[f64; 2]],
) -> Vec<f64> {
    let mut errors = Vec::new();
    for (i, (hit, m)) in hits.iter().zip(motion).enumerate() {
        if hit[2] < 0.0 || !hit[2].is_finite() {
            continue;
        }
        let centre = b.centre(i);
        let p = hit_point(b, centre, *hit, depth);
        if !visible(a, reference, p, depth, texels) {
            continue;
        }
        let Some(seen) = a.project(p) else { continue };
        errors.push((centre + DVec2::new(m[0], m[1]) - seen).length());
    }
    errors
}

/// The flat surface's motion (what a host without the pass's motion would use): the
/// macro entry point under each pixel centre, from the G-buffer depth, projected by the
/// previous camera; in f64.
fn macro_motion(depth: &[f32], camera: &CpuCamera, previous: &CpuCamera) -> Vec<[f64; 2]> {
    depth
        .iter()
        .enumerate()
        .map(|(i, &z)| {
            let centre = camera.centre(i);
            let ndc = centre / camera.size * 2.0 - 1.0;
            let x = camera.inv_view_proj * DVec4::new(ndc.x, ndc.y, f64::from(z), 1.0);
            let c = previous.view_proj * x;
            let m = (DVec2::new(c.x, c.y) / c.w * 0.5 + 0.5) * previous.size - centre;
            [m.x, m.y]
        })
        .collect()
}

struct Stats {
    checked: usize,
    displaced: usize,
    mean: f64,
    p99: f64,
    max: f64,
}

fn stats(mut errors: Vec<f64>, displaced: usize) -> Stats {
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    Stats {
        checked: n,
        displaced,
        mean: errors.iter().sum::<f64>() / n.max(1) as f64,
        p99: errors
            .get((n * 99 / 100).min(n.saturating_sub(1)))
            .copied()
            .unwrap_or(0.0),
        max: errors.last().copied().unwrap_or(0.0),
    }
}

/// Two exact frames of `field` with the camera turned by [`TURN_DEG`] between them; the
/// motion of the second checked against where the first camera draws each hit point,
/// beside the flat surface's motion. Returns (pass, flat) statistics per elevation.
fn camera_turn(name: &str, field: &HeightField) -> Vec<(f32, Stats, Stats)> {
    let ctx = validated_context();
    let reference = Reference::new(field, Addressing::Repeat);
    let texels = f64::from(field.width());
    let mut out = Vec::new();
    {
        let mut renderer = Renderer::new(&ctx, field, settings(ELEVATIONS[0])).unwrap();
        renderer.set_motion_output(true).unwrap();
        for &elevation in &ELEVATIONS {
            let mut scene = settings(elevation).scene;
            let depth = f64::from(scene.depth_scale);
            renderer.set_scene(scene).unwrap();
            renderer.render().unwrap();
            let a = CpuCamera::new(&scene, WIDTH, HEIGHT);
            scene.camera.azimuth_deg += TURN_DEG;
            renderer.set_scene(scene).unwrap();
            renderer.render().unwrap();
            let b = CpuCamera::new(&scene, WIDTH, HEIGHT);
            let hits = renderer.read_hits().unwrap();
            let motion: Vec<[f64; 2]> = renderer
                .read_motion()
                .unwrap()
                .expect("motion output on")
                .iter()
                .map(|m| [f64::from(m[0]), f64::from(m[1])])
                .collect();
            assert!(
                motion.iter().flatten().all(|v| v.is_finite()),
                "{name} at {elevation}: a non-finite motion vector"
            );
            let flat = macro_motion(&renderer.read_macro_depth().unwrap(), &b, &a);
            let displaced = hits.iter().filter(|h| h[2] >= 0.0).count();
            let scale = (depth, texels);
            let pass = stats(
                reprojection_errors(&a, &b, &reference, scale, &hits, &motion),
                displaced,
            );
            let flat = stats(
                reprojection_errors(&a, &b, &reference, scale, &hits, &flat),
                displaced,
            );
            println!(
                "{name} {elevation:>4} deg: checked {}/{} displaced pixels (the others hidden \
                 in frame N-1); pass motion mean {:.4} p99 {:.4} max {:.4} px; flat motion \
                 mean {:.4} p99 {:.4} max {:.4} px",
                pass.checked,
                pass.displaced,
                pass.mean,
                pass.p99,
                pass.max,
                flat.mean,
                flat.p99,
                flat.max,
            );
            out.push((elevation, pass, flat));
        }
    }
    finish(ctx);
    out
}

fn check_camera_turn(name: &str, field: &HeightField) {
    for (elevation, pass, flat) in camera_turn(name, field) {
        assert!(
            pass.max <= MOTION_TOL_PX,
            "{name} at {elevation}: reprojection error {:.4} px > {MOTION_TOL_PX}",
            pass.max
        );
        // The check sees most of the frame and can fail: the flat surface's motion, which
        // ignores the displacement, misses by more than the tolerance.
        assert!(
            pass.checked * 2 >= pass.displaced,
            "{name} at {elevation}: only {} of {} displaced pixels checked",
            pass.checked,
            pass.displaced
        );
        assert!(
            flat.max > MOTION_TOL_PX,
            "{name} at {elevation}: the flat motion is within tolerance too ({:.4} px): the \
             check cannot tell",
            flat.max
        );
    }
}

#[test]
fn camera_turn_rocks() {
    check_camera_turn("rocks", &asset_map("rocks_depth.jpg", Convention::Depth));
}

#[test]
fn camera_turn_bricks() {
    check_camera_turn("bricks", &asset_map("bricks_depth.jpg", Convention::Depth));
}

#[test]
fn camera_turn_mountains() {
    check_camera_turn(
        "mountains",
        &asset_map("mountains_height16.png", Convention::Height),
    );
}

// ---------------------------------------------------------------------------------------
// A moving object.

const OBJ_W: u32 = 192;
const OBJ_H: u32 = 108;
/// The object's depth scale (tiles).
const OBJ_DEPTH: f64 = 0.1;
/// The object's half size (tiles): a square patch of the plane.
const OBJ_HALF: f64 = 1.5;

/// A rigid placement of the displaced patch: object space (the plane y = 0, u along +x,
/// v along +z) to world.
#[derive(Clone, Copy)]
struct Placement {
    rotation: DQuat,
    origin: DVec3,
}

impl Placement {
    fn to_world(self, l: DVec3) -> DVec3 {
        self.origin + self.rotation * l
    }

    fn to_local(self, w: DVec3) -> DVec3 {
        self.rotation.inverse() * (w - self.origin)
    }
}

/// f32 -> IEEE half bits.
fn half(x: f64) -> u16 {
    half::f16::from_f64(x).to_bits()
}

/// The G-buffer of the patch at `place` seen by `camera`, written on the CPU in f64 from
/// the G-buffer contract (glsl/include/dispmap_gbuffer.glsl), and each covered pixel's
/// macro entry point (world).
fn object_gbuffer(
    camera: &CpuCamera,
    place: &Placement,
) -> (common::host::GBufferTexels, Vec<Option<DVec3>>) {
    let n = (OBJ_W * OBJ_H) as usize;
    let mut g = common::host::GBufferTexels {
        ray: vec![[0.0; 4]; n],
        depth: vec![0.0; n],
        frame: vec![[0; 2]; n],
    };
    let mut entries = vec![None; n];
    let normal = place.rotation * DVec3::Y;
    let tangent = place.rotation * DVec3::X;
    let bitangent = place.rotation * DVec3::Z;
    // The frame: material 0, B = handedness * cross(N, T).
    let handedness = normal.cross(tangent).dot(bitangent).signum();
    for (i, entry) in entries.iter_mut().enumerate() {
        let px = camera.centre(i);
        let d = camera.direction(px);
        let denom = d.dot(normal);
        if denom >= 0.0 {
            continue;
        }
        let t = (place.origin - camera.eye).dot(normal) / denom;
        if t <= 0.0 {
            continue;
        }
        let p = camera.eye + d * t;
        let l = place.to_local(p);
        if l.x.abs() > OBJ_HALF || l.z.abs() > OBJ_HALF {
            continue;
        }
        let v_ts = DVec3::new(d.dot(tangent), d.dot(bitangent), denom);
        let parallax = DVec2::new(v_ts.x, v_ts.y) * OBJ_DEPTH / (-v_ts.z).max(1e-4);
        let uv0 = DVec2::new(l.x - l.x.floor(), l.z - l.z.floor());
        g.ray[i] = [
            uv0.x as f32,
            uv0.y as f32,
            parallax.x as f32,
            parallax.y as f32,
        ];
        g.depth[i] = camera.depth(p) as f32;
        g.frame[i] = dispmap::passes::gbuffer::frame::pack(
            normal.as_vec3(),
            tangent.as_vec3(),
            handedness as f32,
            1,
            1,
        );
        *entry = Some(p);
    }
    (g, entries)
}

/// The patch turns by `turn_deg` about a tilted axis and slides between two frames of a
/// still camera; the host's macro motion is exact (f64) and the pass adds the
/// displacement's parallax. Returns, per displaced pixel, the pass's error against the
/// exact motion of the displaced point, the documented bound of the approximation, and
/// the flat surface's error (the macro motion alone).
fn moving_object(turn_deg: f64, slide: DVec3) -> Vec<(f64, f64, f64)> {
    use dispmap::embed::{
        DepthCamera, DisplacementPass, FrameMotion, MotionSettings, PassSettings,
    };
    use dispmap::gpu::Image;
    use dispmap::gpu::commands::{read_image, upload_image};
    use dispmap::gpu::sync::Access;

    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = Scene {
        camera: Camera {
            elevation_deg: 35.0,
            azimuth_deg: 20.0,
            height: 1.2,
            ..Camera::default()
        },
        ..Scene::default()
    };
    let camera = CpuCamera::new(&scene, OBJ_W, OBJ_H);
    let frame = scene.frame_camera(OBJ_W, OBJ_H);
    let tilt = DQuat::from_rotation_x(0.25);
    let axis = DVec3::new(0.4, 1.0, 0.3).normalize();
    let prev = Placement {
        rotation: tilt,
        origin: DVec3::new(0.2, 0.0, -0.1),
    };
    let cur = Placement {
        rotation: DQuat::from_axis_angle(axis, turn_deg.to_radians()) * tilt,
        origin: prev.origin + slide,
    };
    let extent = ash::vk::Extent2D {
        width: OBJ_W,
        height: OBJ_H,
    };
    let mut host = common::host::RayHost::new(ctx.clone(), extent, 1);
    let (gbuffer, entries) = object_gbuffer(&camera, &cur);
    host.upload_gbuffer(&gbuffer);
    // The host's macro motion: where each entry point was in the previous frame.
    let macro_motion: Vec<[u16; 2]> = entries
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let Some(e) = e else { return [0; 2] };
            let px = camera.centre(i);
            let m = camera
                .project(prev.to_world(cur.to_local(*e)))
                .expect("in front")
                - px;
            [half(m.x), half(m.y)]
        })
        .collect();
    let mut motion_image = Image::new(
        &ctx,
        "test.motion",
        ash::vk::Format::R16G16_SFLOAT,
        extent,
        1,
        ash::vk::ImageUsageFlags::STORAGE
            | ash::vk::ImageUsageFlags::TRANSFER_SRC
            | ash::vk::ImageUsageFlags::TRANSFER_DST,
    )
    .unwrap();
    upload_image(
        &ctx,
        host.shot(),
        &motion_image,
        bytemuck::cast_slice(&macro_motion),
        Access::COMPUTE_STORAGE_READ_WRITE,
    )
    .unwrap();
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &field,
        PassSettings {
            method: Method::Exact,
            params: MethodParams::for_method(Method::Exact),
            depth_scale: OBJ_DEPTH as f32,
            addressing: Addressing::Repeat,
            extent,
            frames_in_flight: 1,
        },
    )
    .unwrap();
    pass.set_motion_output(Some(MotionSettings::default()))
        .unwrap();
    let now = DepthCamera {
        view_proj: frame.view_proj,
        eye: frame.eye,
    };
    host.submit_with_motion(
        &mut pass,
        0,
        now,
        FrameMotion {
            image: motion_image.host_view(),
            previous: now,
        },
    );
    let hits = host.hits(0);
    let written: Vec<[u16; 2]> = bytemuck::cast_slice(
        &read_image(
            &ctx,
            host.shot(),
            &motion_image,
            Access::COMPUTE_STORAGE_WRITE,
        )
        .unwrap(),
    )
    .to_vec();
    let mut out = Vec::new();
    let turn = turn_deg.to_radians();
    for (i, (hit, e)) in hits.iter().zip(&entries).enumerate() {
        let Some(e) = e else { continue };
        if hit[2] < 0.0 {
            continue;
        }
        let px = camera.centre(i);
        let l = cur.to_local(*e);
        let local_hit = DVec3::new(
            f64::from(hit[0]) + l.x.floor(),
            -(1.0 - f64::from(hit[2])) * OBJ_DEPTH,
            f64::from(hit[1]) + l.z.floor(),
        );
        let exact = camera.project(prev.to_world(local_hit)).expect("in front") - px;
        let m = written[i].map(|b| f64::from(half::f16::from_bits(b).to_f32()));
        let error = (DVec2::new(m[0], m[1]) - exact).length();
        // The bound: the offset d = p_hit - p_entry turns by the object's rotation, and
        // the parallax of d changes with the entry point's move; both projected at the
        // entry's distance; plus the half floats' rounding of the motion read and written.
        let d = (cur.to_world(local_hit) - *e).length();
        let dist = (*e - camera.eye).length();
        let moved = (prev.to_world(l) - *e).length();
        let geometric = camera.focal_px / dist * (turn * d + 2.0 * d * moved / dist);
        let rounding = 2.0 * exact.length() * 2f64.powi(-11) + 1e-3;
        let flat = (camera.project(prev.to_world(l)).expect("in front") - px - exact).length();
        out.push((error, 1.5 * geometric + rounding, flat));
    }
    assert!(
        written
            .iter()
            .flatten()
            .all(|b| half::f16::from_bits(*b).is_finite()),
        "a non-finite motion vector"
    );
    // SAFETY: `hits` and `read_image` waited for the frame: nothing is pending.
    unsafe { pass.destroy() };
    // SAFETY: `hits` and `read_image` waited for the frame: nothing is pending.
    unsafe { motion_image.destroy(&ctx) };
    host.destroy();
    finish(ctx);
    out
}

#[test]
fn moving_object_error_is_within_the_documented_bound() {
    for (turn, slide) in [
        (0.0, DVec3::new(0.02, 0.0, -0.015)),
        (2.0, DVec3::ZERO),
        (2.0, DVec3::new(0.02, 0.01, -0.015)),
    ] {
        let rows = moving_object(turn, slide);
        let n = rows.len();
        assert!(n > 1000, "only {n} displaced pixels");
        let summary = |mut e: Vec<f64>| {
            e.sort_by(f64::total_cmp);
            let mean = e.iter().sum::<f64>() / n as f64;
            format!(
                "mean {mean:.4} p99 {:.4} max {:.4} px",
                e[n * 99 / 100],
                e[n - 1]
            )
        };
        println!(
            "moving object, turn {turn} deg, slide {:.3} tiles: {n} displaced pixels; pass \
             motion error {}; flat motion error {}",
            slide.length(),
            summary(rows.iter().map(|r| r.0).collect()),
            summary(rows.iter().map(|r| r.2).collect()),
        );
        if turn == 0.0 {
            // A slide (mostly parallel to the image plane): the translation model holds.
            let worst = rows.iter().map(|r| r.0).fold(0.0, f64::max);
            assert!(worst <= 0.01, "slide: error {worst:.4} px");
        }
        for (error, bound, _) in rows {
            assert!(
                error <= bound,
                "error {error:.4} px over its bound {bound:.4}"
            );
        }
    }
}
