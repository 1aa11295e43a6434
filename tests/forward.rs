//! The forward path (`Renderer::render_forward`: relief mapping and POM marched in the
//! G-buffer's fragment shader, as engines do) against the deferred frame (the same method
//! in the trace pass), validation on: the same hits, bit for bit on lavapipe (the same
//! marcher code on the same rays: `src/passes/forward.rs` says why another driver may
//! differ in a few pixels), and therefore the same colour; and what it refuses.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::passes::shadow::{ShadowMode, ShadowSettings};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Scene};

fn settings(method: Method, steps: u32, geometry: Geometry, elevation: f32) -> RenderSettings {
    RenderSettings {
        width: 160,
        height: 96,
        method,
        params: MethodParams {
            steps,
            min_steps: 6,
            refine_steps: 5,
            ..MethodParams::default()
        },
        scene: Scene {
            geometry,
            camera: Camera {
                elevation_deg: elevation,
                azimuth_deg: 37.0,
                ..Camera::default()
            },
            ..Scene::default()
        },
        shadows: ShadowSettings::default(),
    }
}

/// Renders the deferred frame then the forward frame and compares them. Returns the hits
/// and the misses on geometry (rays that left a clamp-addressed decal).
fn compare(renderer: &mut Renderer, lavapipe: bool, label: &str) -> (usize, usize) {
    let deferred_times = renderer.render().unwrap();
    assert!(deferred_times.iter().any(|(n, _)| *n == PassName::Trace));
    let deferred = renderer.read_hits().unwrap();
    let deferred_color = renderer.read_color().unwrap();
    let times = renderer.render_forward().unwrap();
    let passes: Vec<PassName> = times.iter().map(|&(n, _)| n).collect();
    for pass in [PassName::GBuffer, PassName::Classify, PassName::Shade] {
        assert!(passes.contains(&pass), "{label}: {passes:?}");
    }
    assert!(!passes.contains(&PassName::Trace), "{label}: {passes:?}");
    let forward = renderer.read_hits().unwrap();
    let color = renderer.read_color().unwrap();
    assert_eq!(forward.len(), deferred.len());
    let bits = |t: &[f32; 4]| t.map(f32::to_bits);
    let differing = forward
        .iter()
        .zip(&deferred)
        .filter(|(f, d)| bits(f) != bits(d))
        .count();
    let hits = deferred.iter().filter(|t| t[2] >= 0.0).count();
    let depth = renderer.read_macro_depth().unwrap();
    let misses = deferred
        .iter()
        .zip(&depth)
        .filter(|(t, d)| t[2] < 0.0 && **d > 0.0)
        .count();
    assert!(forward.iter().flatten().all(|v| v.is_finite()), "{label}");
    eprintln!(
        "{label}: {differing} of {} hit texels differ ({hits} hits, {misses} rays left the map)",
        deferred.len()
    );
    if lavapipe {
        assert_eq!(differing, 0, "{label}: forward and deferred hits differ");
    } else {
        assert!(
            differing * 1000 <= deferred.len(),
            "{label}: {differing} hit texels differ"
        );
    }
    if differing == 0 {
        assert!(
            color == deferred_color,
            "{label}: equal hits shaded differently"
        );
    }
    (hits, misses)
}

#[test]
fn forward_hits_are_the_deferred_hits() {
    let ctx = validated_context();
    let lavapipe = ctx.info().driver.contains("llvmpipe");
    {
        let rocks = asset_map("rocks_depth.jpg", Convention::Depth);
        let mountains = asset_map("mountains_height16.png", Convention::Height);
        let cases: [(&str, &HeightField, Geometry, f32, ShadowMode); 4] = [
            (
                "rocks, tiled plane",
                &rocks,
                Geometry::TiledPlane,
                12.0,
                ShadowMode::Off,
            ),
            (
                "rocks, quad",
                &rocks,
                Geometry::Quad,
                35.0,
                ShadowMode::Hard,
            ),
            (
                "mountains, tiled plane",
                &mountains,
                Geometry::TiledPlane,
                6.0,
                ShadowMode::Soft,
            ),
            (
                "mountains, quad",
                &mountains,
                Geometry::Quad,
                20.0,
                ShadowMode::Off,
            ),
        ];
        for (name, field, geometry, elevation, shadows) in cases {
            let mut s = settings(Method::Relief, 24, geometry, elevation);
            s.shadows.mode = shadows;
            let mut renderer = Renderer::new(&ctx, field, s).unwrap();
            renderer.enable_forward(field).unwrap();
            let mut misses = 0;
            for (method, steps) in [(Method::Relief, 24), (Method::Pom, 40), (Method::Relief, 7)] {
                renderer
                    .set_method(method, MethodParams { steps, ..s.params })
                    .unwrap();
                let label = format!("{name}, {method} {steps}");
                let (h, m) = compare(&mut renderer, lavapipe, &label);
                assert!(h > 1000, "{label}: {h} hits");
                misses += m;
            }
            if geometry == Geometry::Quad {
                // The decal's silhouette: rays that leave it are misses in both frames.
                assert!(misses > 0, "{name}: no ray left the quad");
            }
        }
    }
    finish(ctx);
}

#[test]
fn forward_refuses_what_it_cannot_draw() {
    let ctx = validated_context();
    {
        let rocks = asset_map("rocks_depth.jpg", Convention::Depth);
        let small = HeightField::from_fn(8, 8, "small", |u, v| 0.5 + 0.25 * (u - v)).unwrap();
        let mut renderer = Renderer::new(
            &ctx,
            &rocks,
            settings(Method::Relief, 16, Geometry::TiledPlane, 10.0),
        )
        .unwrap();
        let err = renderer.render_forward().unwrap_err().to_string();
        assert!(err.contains("enable_forward"), "{err}");
        let err = renderer.read_rays().unwrap_err().to_string();
        assert!(err.contains("no rays"), "{err}");
        let err = renderer.enable_forward(&small).unwrap_err().to_string();
        assert!(err.contains("small") && err.contains("8x8"), "{err}");
        renderer.enable_forward(&rocks).unwrap();
        renderer.render_forward().unwrap();
        let err = renderer.read_rays().unwrap_err().to_string();
        assert!(err.contains("forward frame"), "{err}");
        renderer.render().unwrap();
        assert!(renderer.read_rays().unwrap().iter().any(Option::is_some));
        renderer
            .set_method(Method::Exact, MethodParams::default())
            .unwrap();
        let err = renderer.render_forward().unwrap_err().to_string();
        assert!(
            err.contains("exact") && err.contains("relief or pom"),
            "{err}"
        );
        renderer
            .set_method(
                Method::Pom,
                MethodParams {
                    lod_threshold: Some(2.0),
                    ..MethodParams::default()
                },
            )
            .unwrap();
        let err = renderer.render_forward().unwrap_err().to_string();
        assert!(err.contains("lod-threshold"), "{err}");
        renderer
            .set_method(Method::Pom, MethodParams::default())
            .unwrap();
        renderer.set_depth_output(true).unwrap();
        let err = renderer.render_forward().unwrap_err().to_string();
        assert!(err.contains("depth output"), "{err}");
        renderer.set_depth_output(false).unwrap();
        renderer.set_motion_output(true).unwrap();
        let err = renderer.render_forward().unwrap_err().to_string();
        assert!(err.contains("motion output"), "{err}");
        renderer.set_motion_output(false).unwrap();
        renderer.render_forward().unwrap();
        drop(renderer);
        let mut cube = Renderer::new(
            &ctx,
            &rocks,
            settings(Method::Relief, 16, Geometry::Cube, 10.0),
        )
        .unwrap();
        let err = cube.enable_forward(&rocks).unwrap_err().to_string();
        assert!(err.contains("mesh"), "{err}");
    }
    finish(ctx);
}
