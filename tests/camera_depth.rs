//! The depths and coverage of the tiled plane agree with each pixel's own f64 ray (the
//! camera model of docs/design.md in f64, [`dispmap::pixel_rays::PixelRays`]) on every
//! row, the far rows at grazing angles included, where a ray meets the plane hundreds of
//! tiles away and a depth off by a relative `e` moves the point along the ray by `e`
//! times that distance. For every pixel of 640x360 frames of the shapes map with an
//! `exact` hit, the corrected depth (`--depth-out`) is compared with the reverse-Z depth
//! of the point of the pixel's f64 ray at the hit's height (`h = 1 - t`, the ray
//! descending `depth_scale` over `t` in `[0, 1]`), the G-buffer's depth with that of the
//! ray's entry, and the pixels with geometry with those whose ray meets the plane.
//!
//! Measured (lavapipe): G-buffer depths within 2.5e-7 and corrected depths within 4.5e-7
//! of the f64 rays' at 0.5 to 10 degrees, entries up to 2,400 tiles away (at most 0.19
//! texels along the ray), coverage identical. The camera's parameters are f32 (the one
//! rounding of each given number, shared by every stage): against a camera built in f64
//! from the decimal numbers `2.3`, `37.3`, `0.3` the entries differ by 6.1e-7 of their
//! distance (printed, not asserted). Run with `--nocapture` for the table.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::Convention;
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, MIN_COS, NEAR, Scene};

/// The CLI's default frame: at 2 degrees (eye 0.25 high) its first row below the horizon
/// meets the plane 200 tiles away.
const SIZE: (u32, u32) = (640, 360);

/// Relative error allowed on the G-buffer's depth against the f64 ray's: a few f32 ulps
/// of the stored depth and of the f32 eye-relative positions it is computed from.
const DEPTH_REL_TOL: f64 = 1e-6;

/// Relative error allowed on the corrected depth: it is computed from the world-space
/// view-projection and eye a host passes (`DepthCamera`), whose translation is rounded to
/// f32, by up to the eye's distance from the origin times 2^-24; near an eye close to the
/// plane, where the view distance is smallest, that is up to 1.8e-6 of the depth
/// (measured with the eye 0.01 above the plane at 0.5 and 3 degrees: 0.000 texels).
const CORRECTED_REL_TOL: f64 = 4e-6;

/// The worst relative error of one frame's depths, with its pixel and what it moves the
/// hit along the ray by, in texels.
#[derive(Default, Debug)]
struct Worst {
    rel: f64,
    pixel: (u32, u32),
    texels: f64,
    /// The most texels any pixel's depth moves its point along the ray.
    most_texels: f64,
}

impl Worst {
    fn add(&mut self, rel: f64, pixel: (u32, u32), distance: f64, map_width: f64) {
        let texels = rel * distance * map_width;
        self.most_texels = self.most_texels.max(texels);
        if rel > self.rel {
            *self = Worst {
                rel,
                pixel,
                texels,
                most_texels: self.most_texels,
            };
        }
    }
}

#[test]
fn depths_follow_each_pixels_f64_ray_on_every_row() {
    let ctx = validated_context();
    let field = asset_map("shapes_depth.png", Convention::Depth);
    let map_width = f64::from(field.width());
    let views: [(f32, f32, f32); 11] = [
        (2.3, 37.3, 0.3),
        // Far edges of the rectangle near the horizon, whose rasterised edge left out 1
        // to 3 pixels of a row whose rays meet it, and near eyes.
        (20.0, 200.0, 5.0),
        (1.0, 200.0, 100.0),
        (3.0, 13.0, 100.0),
        (20.0, 200.0, 100.0),
        (0.5, 200.0, 0.01),
        (2.0, 0.0, 0.25),
        (0.5, 0.0, 0.25),
        (2.0, 37.0, 0.25),
        (10.0, 123.0, 0.25),
        (2.0, 0.0, 3.0),
    ];
    let mut failures = Vec::new();
    {
        let scene = |(elevation_deg, azimuth_deg, height): (f32, f32, f32)| Scene {
            camera: Camera {
                elevation_deg,
                azimuth_deg,
                height,
                ..Camera::default()
            },
            ..Scene::default()
        };
        let mut renderer = Renderer::new(
            &ctx,
            &field,
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
        println!(
            "view (elevation, azimuth, height) | pixels | G-buffer depth worst | corrected depth worst"
        );
        for view in views {
            let scene = scene(view);
            renderer.set_scene(scene).unwrap();
            renderer.render().unwrap();
            let hits = renderer.read_hits().unwrap();
            let depth = renderer.read_depth().unwrap().unwrap();
            let macro_depth = renderer.read_macro_depth().unwrap();
            let camera = scene.frame_camera(SIZE.0, SIZE.1);
            let rect = scene.analytic_rect(&camera).unwrap();
            let rays = &camera.rays;
            // The camera as the decimal numbers given say it, in f64 (not rounded to f32
            // first): how far rounding the parameters moves the entries (printed only).
            let decimal = |v: f32| format!("{v}").parse::<f64>().unwrap();
            let given = orbit_f64(decimal(view.0), decimal(view.1), decimal(view.2));
            let mut given_worst = 0.0f64;
            for y in 0..SIZE.1 {
                for x in 0..SIZE.0 {
                    if let (Some((a, _)), Some((b, _))) = (
                        rays.plane_entry(x, y, &rect),
                        given.plane_entry(x, y, &rect),
                    ) {
                        let rel = (a - b).length() / (b - given.eye).length();
                        given_worst = given_worst.max(rel);
                    }
                }
            }
            println!("    entries against the decimal camera's: {given_worst:.2e} relative");
            let ds = f64::from(scene.depth_scale);
            let (mut entry_worst, mut hit_worst, mut compared) =
                (Worst::default(), Worst::default(), 0usize);
            let mut farthest = 0.0f64;
            // Pixels whose f64 ray meets the plane without geometry in the G-buffer, and
            // the reverse.
            let mut coverage = Vec::new();
            for y in 0..SIZE.1 {
                for x in 0..SIZE.0 {
                    let i = (y * SIZE.0 + x) as usize;
                    let Some((entry, d)) = rays.plane_entry(x, y, &rect) else {
                        if macro_depth[i] > 0.0 {
                            coverage.push((x, y, true));
                        }
                        continue;
                    };
                    if macro_depth[i] <= 0.0 {
                        coverage.push((x, y, false));
                    }
                    let v = d.normalize();
                    let forward = |p: glam::DVec3| (p - rays.eye).dot(rays.forward);
                    let want = f64::from(NEAR) / forward(entry);
                    let distance = (entry - rays.eye).length();
                    farthest = farthest.max(distance);
                    if macro_depth[i] > 0.0 {
                        let rel = (f64::from(macro_depth[i]) - want).abs() / want;
                        entry_worst.add(rel, (x, y), distance, map_width);
                    }
                    let hit = hits[i];
                    // A hit on the view ray (not where P is clamped to MIN_COS).
                    if hit[2] < 0.0 || -v.y < f64::from(MIN_COS) || depth[i] <= 0.0 {
                        continue;
                    }
                    compared += 1;
                    let t = 1.0 - f64::from(hit[2]);
                    let p = entry + v * (t * ds / -v.y);
                    let want = f64::from(NEAR) / forward(p);
                    let rel = (f64::from(depth[i]) - want).abs() / want;
                    hit_worst.add(rel, (x, y), (p - rays.eye).length(), map_width);
                }
            }
            println!(
                "{view:?} | {compared} (to {farthest:.0} tiles) | {:.2e} at {:?} ({:.3} texels; at most {:.3}) | {:.2e} at {:?} ({:.3} texels; at most {:.3})",
                entry_worst.rel,
                entry_worst.pixel,
                entry_worst.texels,
                entry_worst.most_texels,
                hit_worst.rel,
                hit_worst.pixel,
                hit_worst.texels,
                hit_worst.most_texels
            );
            assert!(compared > 1000, "{view:?}: {compared} pixels compared");
            if !coverage.is_empty() {
                println!(
                    "    coverage differs at {} pixels (x, y, drawn): {:?}",
                    coverage.len(),
                    &coverage[..coverage.len().min(8)]
                );
                failures.push(format!(
                    "{view:?}: coverage differs from the f64 rays at {} pixels (x, y, drawn): {:?}",
                    coverage.len(),
                    &coverage[..coverage.len().min(8)]
                ));
            }
            for (what, w, tol) in [
                ("G-buffer", &entry_worst, DEPTH_REL_TOL),
                ("corrected", &hit_worst, CORRECTED_REL_TOL),
            ] {
                if w.rel > tol {
                    failures.push(format!(
                        "{view:?}: {what} depth {:.2e} relative off the f64 ray at {:?} ({:.3} \
                         texels along it)",
                        w.rel, w.pixel, w.texels
                    ));
                }
            }
        }
    }
    finish(ctx);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// docs/design.md's orbit camera about the origin from f64 parameters (the tiled plane's:
/// the eye `height` above it), 45 degrees of field, for [`SIZE`].
fn orbit_f64(elevation_deg: f64, azimuth_deg: f64, height: f64) -> dispmap::pixel_rays::PixelRays {
    use glam::DVec3;
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    let to_eye = DVec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos());
    let eye = to_eye * (height / e.sin());
    let forward = -to_eye;
    let right = forward.cross(DVec3::Y).normalize();
    dispmap::pixel_rays::PixelRays {
        eye,
        forward,
        right,
        up: right.cross(forward),
        tan_half_fov_y: (45f64.to_radians() / 2.0).tan(),
        width: SIZE.0,
        height: SIZE.1,
    }
}
