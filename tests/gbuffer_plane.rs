//! The tiled plane's G-buffer against the analytic plane: for every pixel, the ray through
//! the pixel's centre meets `y = 0` (in f64, through the frame's own f32 view-projection)
//! at the expected reverse-Z depth and uv. Every pixel where the plane is visible (below
//! the horizon, with a margin of a pixel) must have geometry, every pixel above it none,
//! and depth and uv0 must be within the stated tolerances, on close-ups, grazing views,
//! high views and several azimuths. Validation on throughout.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::Convention;
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, NEAR, PLANE_HALF_EXTENT, Scene};
use glam::{DMat4, DVec3, DVec4};

/// The rasteriser snaps vertices to its sub-pixel grid (lavapipe: 8 bits, 1/256 pixel;
/// Vulkan guarantees 4): the rasterised plane is the analytic one moved by up to about a
/// sub-pixel step, so depth and uv may differ by that step times their screen gradient.
/// Near the horizon the depth's relative gradient is about 1 / (pixels below the horizon),
/// which bounds the relative depth precision any rasterisation reaches there.
const SNAP_PIXELS: f64 = 1.0 / 256.0;

/// Relative depth error allowed on top of the snap term (f32 vertex positions, f32 clip
/// coordinates and the rasteriser's f32 depth plane). Measured with the grid: see the
/// test's output ("largest error / tolerance").
const DEPTH_REL_TOL: f64 = 1e-5;

/// uv0 error (tiles) allowed on top of the snap term: f32 uvs of up to a few thousand
/// tiles (4096 * 2^-24 = 2.4e-4) and their reduction to [0, 1).
const UV_ABS_TOL: f64 = 5e-4;

/// One view of the plane.
#[derive(Clone, Copy, Debug)]
struct View {
    height: f32,
    elevation: f32,
    azimuth: f32,
    width: u32,
    frame_height: u32,
}

const VIEWS: [View; 8] = [
    // The reported close-up, square and in tests/lod.rs's frame.
    View {
        height: 0.05,
        elevation: 60.0,
        azimuth: 0.0,
        width: 256,
        frame_height: 256,
    },
    View {
        height: 0.05,
        elevation: 60.0,
        azimuth: 0.0,
        width: 256,
        frame_height: 144,
    },
    // The default camera.
    View {
        height: 0.25,
        elevation: 30.0,
        azimuth: 0.0,
        width: 256,
        frame_height: 144,
    },
    // The horizon in view, an odd azimuth.
    View {
        height: 0.25,
        elevation: 15.0,
        azimuth: 37.0,
        width: 256,
        frame_height: 144,
    },
    // Grazing close-up.
    View {
        height: 0.05,
        elevation: 5.0,
        azimuth: 123.0,
        width: 256,
        frame_height: 256,
    },
    // High above the plane, looking back.
    View {
        height: 3.0,
        elevation: 20.0,
        azimuth: 200.0,
        width: 256,
        frame_height: 144,
    },
    // Very close, straight down.
    View {
        height: 0.01,
        elevation: 90.0,
        azimuth: 0.0,
        width: 128,
        frame_height: 128,
    },
    // Almost level.
    View {
        height: 0.1,
        elevation: 1.0,
        azimuth: 300.0,
        width: 256,
        frame_height: 144,
    },
];

struct CpuCamera {
    eye: DVec3,
    view_proj: DMat4,
    inv_view_proj: DMat4,
    width: f64,
    height: f64,
}

impl CpuCamera {
    /// The unit direction through the point (`x`, `y`) of the frame (pixels).
    fn direction(&self, x: f64, y: f64) -> DVec3 {
        let ndc_x = x / self.width * 2.0 - 1.0;
        let ndc_y = y / self.height * 2.0 - 1.0;
        let p = self.inv_view_proj * DVec4::new(ndc_x, ndc_y, 0.5, 1.0);
        ((p.truncate() / p.w) - self.eye).normalize()
    }

    /// Where the ray through (`x`, `y`) meets `y = 0` (`None`: at or above the horizon).
    fn entry(&self, x: f64, y: f64) -> Option<DVec3> {
        let d = self.direction(x, y);
        (d.y < 0.0).then(|| self.eye + d * (-self.eye.y / d.y))
    }

    /// The reverse-Z depth of a world point.
    fn depth(&self, p: DVec3) -> f64 {
        let c = self.view_proj * p.extend(1.0);
        c.z / c.w
    }
}

/// Distance between two uvs reduced to [0, 1) (on the torus of one tile).
fn wrapped_distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = |x: f64, y: f64| {
        let t = (x - y).rem_euclid(1.0);
        t.min(1.0 - t)
    };
    d(a[0], b[0]).hypot(d(a[1], b[1]))
}

#[test]
fn the_plane_covers_every_pixel_below_the_horizon_at_the_analytic_depth_and_uv() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let mut failures = Vec::new();
    for view in VIEWS {
        let scene = Scene {
            geometry: Geometry::TiledPlane,
            camera: Camera {
                height: view.height,
                elevation_deg: view.elevation,
                azimuth_deg: view.azimuth,
                ..Camera::default()
            },
            ..Scene::default()
        };
        let settings = RenderSettings {
            width: view.width,
            height: view.frame_height,
            method: Method::Bump,
            params: MethodParams::for_method(Method::Bump),
            scene,
            shadows: Default::default(),
        };
        let mut renderer = Renderer::new(&ctx, &field, settings).unwrap();
        renderer.render().unwrap();
        let depth = renderer.read_macro_depth().unwrap();
        let rays = renderer.read_rays().unwrap();
        drop(renderer);

        let frame = scene.frame_camera(view.width, view.frame_height);
        let view_proj = frame.view_proj.as_dmat4();
        let cam = CpuCamera {
            eye: frame.eye.as_dvec3(),
            view_proj,
            inv_view_proj: view_proj.inverse(),
            width: f64::from(view.width),
            height: f64::from(view.frame_height),
        };
        // The plane's uv at a world point: the tile grid is anchored at integer world
        // coordinates (one tile = one world unit).
        let uv_of = |p: DVec3| [p.x.rem_euclid(1.0), p.z.rem_euclid(1.0)];
        // Well inside the plane's square (it is laid out around the eye's tile).
        let inside = |p: DVec3| {
            (p.x - cam.eye.x).abs().max((p.z - cam.eye.z).abs())
                < f64::from(PLANE_HALF_EXTENT) - 2.0
        };
        let (mut covered, mut missing, mut sky, mut stray) = (0usize, 0usize, 0usize, 0usize);
        // Largest relative depth errors (within 10 eye heights and beyond) and largest
        // error / tolerance ratio of depth or uv.
        let (mut near_err, mut far_err, mut excess): (f64, f64, f64) = (0.0, 0.0, 0.0);
        let mut first_missing = Vec::new();
        let w = view.width as usize;
        for (i, (&d, ray)) in depth.iter().zip(&rays).enumerate() {
            assert!(d.is_finite(), "{view:?} pixel {i}: depth {d}");
            let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            // The pixel's neighbourhood (a pixel each way).
            let around: Vec<_> = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|(dx, dy)| cam.entry(x + dx, y + dy))
                .collect();
            if around.iter().all(|e| e.is_none()) {
                sky += 1;
                if d != 0.0 {
                    stray += 1;
                }
                continue;
            }
            if !around.iter().all(|e| e.is_some_and(inside)) {
                continue; // at the horizon or the plane's edge: either is right
            }
            let entry = cam.entry(x, y).expect("below the horizon");
            let Some(ray) = ray else {
                missing += 1;
                if first_missing.len() < 8 {
                    first_missing.push((i % w, i / w));
                }
                continue;
            };
            covered += 1;
            let want = cam.depth(entry);
            // Analytic screen gradients (largest step to a neighbouring pixel centre).
            let neighbours: Vec<DVec3> = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
                .iter()
                .filter_map(|(dx, dy)| cam.entry(x + dx, y + dy))
                .collect();
            let depth_step = neighbours
                .iter()
                .map(|&p| (cam.depth(p) - want).abs())
                .fold(0.0f64, f64::max);
            let footprint = neighbours
                .iter()
                .map(|&p| (p - entry).length())
                .fold(0.0f64, f64::max);
            let rel = (f64::from(d) - want).abs() / want;
            let depth_tol = DEPTH_REL_TOL * want + SNAP_PIXELS * depth_step;
            let du = wrapped_distance(ray.uv0, uv_of(entry));
            let uv_tol = UV_ABS_TOL + SNAP_PIXELS * footprint;
            let distance = (entry - cam.eye).length();
            let max_rel = if distance < 10.0 * f64::from(view.height) {
                &mut near_err
            } else {
                &mut far_err
            };
            *max_rel = max_rel.max(rel);
            excess = excess
                .max((f64::from(d) - want).abs() / depth_tol)
                .max(du / uv_tol);
            if (f64::from(d) - want).abs() > depth_tol || du > uv_tol {
                failures.push(format!(
                    "{view:?} pixel ({}, {}): depth {d} vs {want} (rel {rel:.2e}, step to a \
                     neighbour {depth_step:.2e}), uv0 {:?} vs {:?} ({du:.2e} tiles, footprint \
                     {footprint:.2e})",
                    i % w,
                    i / w,
                    ray.uv0,
                    uv_of(entry)
                ));
            }
        }
        println!(
            "{view:?}: {covered} covered, {missing} missing {first_missing:?}, {sky} sky \
             ({stray} with geometry); depth rel error near {near_err:.2e}, far {far_err:.2e}; \
             largest error / tolerance (depth or uv) {excess:.2e}"
        );
        if missing > 0 || stray > 0 {
            failures.push(format!(
                "{view:?}: {missing} pixels below the horizon without geometry \
                 (first {first_missing:?}), {stray} above it with geometry"
            ));
        }
        assert!(covered > 1000, "{view:?}: {covered} pixels compared");
    }
    finish(ctx);
    let shown: Vec<_> = failures.iter().take(20).collect();
    assert!(
        failures.is_empty(),
        "{} failures: {shown:#?}",
        failures.len()
    );
}

/// uv0 error (tiles) allowed against the f64 centre ray: the G-buffer's double-float
/// entry keeps about 48 bits, and uv0 is an f32 in [0, 1) (an ulp is at most 2^-24 =
/// 6e-8 tiles), so a few ulps: 2e-4 texels of a 1024-texel map (measured: at most 6.2e-8
/// tiles, every case below).
const CENTRE_RAY_UV_TOL: f64 = 2e-7;

/// Relative error allowed on the parallax vector P (f32 from the f32 eye-relative entry;
/// measured: at most 1.9e-7).
const CENTRE_RAY_P_REL_TOL: f64 = 1e-6;

/// Relative error allowed on the G-buffer depth against the centre ray's entry:
/// `gl_FragDepth` from the entry through the f32 eye-relative view-projection (measured:
/// at most 2.0e-7; the rasteriser's interpolated depth was up to 7.4e-5 off at 2 degrees).
const CENTRE_RAY_DEPTH_REL_TOL: f64 = 1e-6;

/// The G-buffer's entry on the analytic surfaces is each pixel's own centre ray
/// (`dispmap_plane_pixel_ray`): on the tiled plane at grazing angles (where one pixel row
/// spans hundreds of tiles and the rasteriser's interpolation was tens to thousands of
/// texels off) and on the quad, every pixel's uv0 and P agree with the library's f64
/// centre ray (`Scene::analytic_rays`), and the two agree on which pixels have geometry.
#[test]
fn uv0_is_the_entry_of_the_pixel_centre_ray() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let mut failures = Vec::new();
    let cases = [
        (Geometry::TiledPlane, 0.5, 0.0),
        (Geometry::TiledPlane, 2.0, 0.0),
        (Geometry::TiledPlane, 10.0, 0.0),
        (Geometry::TiledPlane, 2.0, 37.0),
        (Geometry::Quad, 30.0, 20.0),
        (Geometry::Quad, 8.0, 0.0),
    ];
    for (geometry, elevation, azimuth) in cases {
        let scene = Scene {
            geometry,
            camera: Camera {
                elevation_deg: elevation,
                azimuth_deg: azimuth,
                ..Camera::default()
            },
            ..Scene::default()
        };
        let (w, h) = (192, 108);
        let settings = RenderSettings {
            width: w,
            height: h,
            method: Method::Bump,
            params: MethodParams::for_method(Method::Bump),
            scene,
            shadows: Default::default(),
        };
        let mut renderer = Renderer::new(&ctx, &field, settings).unwrap();
        renderer.render().unwrap();
        let rays = renderer.read_rays().unwrap();
        let depth = renderer.read_macro_depth().unwrap();
        let reference = renderer.reference_rays().unwrap();
        drop(renderer);
        let frame = scene.frame_camera(w, h);
        let want = scene.analytic_rays(&frame).expect("analytic geometry");
        let rect = scene.analytic_rect(&frame).expect("analytic geometry");
        let mut depth_worst = 0.0f64;
        assert!(
            reference.analytic,
            "{geometry:?}: the reference traces centre rays"
        );
        assert_eq!(
            reference.rays, want,
            "{geometry:?}: reference_rays are analytic_rays"
        );
        let (mut compared, mut uv_worst, mut p_worst) = (0usize, 0.0f64, 0.0f64);
        let mut coverage = Vec::new();
        for (i, (got, want)) in rays.iter().zip(&want).enumerate() {
            let (x, y) = (i % w as usize, i / w as usize);
            let (got, want) = match (got, want) {
                (Some(g), Some(r)) => (g, r),
                (None, None) => continue,
                _ => {
                    coverage.push((x, y, got.is_some()));
                    continue;
                }
            };
            compared += 1;
            let du = if scene.addressing() == dispmap::heightfield::Addressing::Repeat {
                wrapped_distance(got.uv0, want.uv0)
            } else {
                (got.uv0[0] - want.uv0[0]).hypot(got.uv0[1] - want.uv0[1])
            };
            let dp = (got.parallax[0] - want.parallax[0]).hypot(got.parallax[1] - want.parallax[1])
                / want.parallax[0].hypot(want.parallax[1]).max(1e-12);
            uv_worst = uv_worst.max(du);
            p_worst = p_worst.max(dp);
            // The entry's reverse-Z depth: NEAR / its distance along the view direction.
            let (entry, _) = frame
                .rays
                .plane_entry(x as u32, y as u32, &rect)
                .expect("a ray");
            let want_depth = f64::from(NEAR) / (entry - frame.rays.eye).dot(frame.rays.forward);
            let dd = (f64::from(depth[i]) - want_depth).abs() / want_depth;
            depth_worst = depth_worst.max(dd);
            if du > CENTRE_RAY_UV_TOL || dp > CENTRE_RAY_P_REL_TOL || dd > CENTRE_RAY_DEPTH_REL_TOL
            {
                failures.push(format!(
                    "{geometry:?} {elevation} deg az {azimuth}: pixel ({x}, {y}) uv0 {:?} vs \
                     {:?} ({du:.2e} tiles), P {:?} vs {:?} (rel {dp:.2e}), depth {} vs \
                     {want_depth} (rel {dd:.2e})",
                    got.uv0, want.uv0, got.parallax, want.parallax, depth[i]
                ));
            }
        }
        println!(
            "{geometry:?} {elevation} deg az {azimuth}: {compared} pixels, uv0 worst \
             {uv_worst:.2e} tiles, P worst rel {p_worst:.2e}, depth worst rel \
             {depth_worst:.2e}, coverage differs at {coverage:?}"
        );
        if !coverage.is_empty() {
            failures.push(format!(
                "{geometry:?} {elevation} deg az {azimuth}: coverage differs at (x, y, drawn) \
                 {coverage:?}"
            ));
        }
        assert!(compared > 1000, "{geometry:?}: {compared} pixels compared");
    }
    finish(ctx);
    let shown: Vec<_> = failures.iter().take(20).collect();
    assert!(
        failures.is_empty(),
        "{} failures: {shown:#?}",
        failures.len()
    );
}
