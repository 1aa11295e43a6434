//! Self-shadowing (the `shadow` pass, Tatarchuk 2006 section 3.2) on lavapipe with
//! validation on: no shadow on a flat map, a ridge that shadows the side away from the
//! light only, `exact` hard shadows against the CPU reference's occlusion query, soft
//! shadows in range and darker with a lower light, and the `shadow` timing only when on.
//! Run with `--nocapture` to see the measured numbers.

#[path = "../../tests/common/mod.rs"]
mod common;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::shadow::{ShadowMode, ShadowSettings};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Light, Scene};
use dispmap_cli::measure::Measure as _;
use dispmap_cli::reference::Reference;

const HARD: ShadowSettings = ShadowSettings {
    mode: ShadowMode::Hard,
    samples: 8,
};
const SOFT: ShadowSettings = ShadowSettings {
    mode: ShadowMode::Soft,
    samples: 8,
};

/// One method of each shadow query and of each marching variant.
const METHODS: [Method; 6] = [
    Method::Exact,
    Method::Pyramid,
    Method::DigGuarded,
    Method::Relief,
    Method::Pom,
    Method::Linear,
];

fn settings(
    method: Method,
    geometry: Geometry,
    light: Light,
    shadows: ShadowSettings,
) -> RenderSettings {
    RenderSettings {
        width: 128,
        height: 96,
        method,
        params: MethodParams::for_method(method),
        scene: Scene {
            geometry,
            camera: Camera {
                elevation_deg: 50.0,
                ..Camera::default()
            },
            light,
            ..Scene::default()
        },
        shadows,
    }
}

fn light(elevation_deg: f32, azimuth_deg: f32) -> Light {
    Light {
        elevation_deg,
        azimuth_deg,
        ..Light::default()
    }
}

/// The light in the plane's tangent frame (T = +x along u, B = +z along v, N = +y), in
/// f64: the scene's direction (cos e sin a, sin e, cos e cos a) as (L.T, L.B, L.N).
fn light_ts(l: Light) -> [f64; 3] {
    let (e, a) = (
        f64::from(l.elevation_deg).to_radians(),
        f64::from(l.azimuth_deg).to_radians(),
    );
    [e.cos() * a.sin(), e.cos() * a.cos(), e.sin()]
}

/// Covered pixels' (hit, visibility).
fn covered(renderer: &Renderer) -> Vec<([f32; 4], f32)> {
    let hits = renderer.read_hits().unwrap();
    let vis = renderer.read_visibility().unwrap().expect("shadows are on");
    assert_eq!(hits.len(), vis.len());
    hits.into_iter()
        .zip(vis)
        .filter(|(h, _)| h[2] >= 0.0)
        .collect()
}

#[test]
fn a_flat_map_casts_no_shadow() {
    let ctx = validated_context();
    let flat = HeightField::from_heights(32, 32, vec![0.5; 1024], "flat").unwrap();
    for geometry in [Geometry::TiledPlane, Geometry::Quad] {
        let base = settings(Method::Exact, geometry, light(12.0, 60.0), HARD);
        let mut renderer = Renderer::new(&ctx, &flat, base).unwrap();
        for method in Method::ALL.iter().copied() {
            renderer
                .set_method(method, MethodParams::for_method(method))
                .unwrap();
            for shadows in [HARD, SOFT] {
                renderer.set_shadows(shadows).unwrap();
                renderer.render().unwrap();
                let px = covered(&renderer);
                assert!(
                    px.len() > 1000,
                    "{geometry:?} {method}: {} pixels",
                    px.len()
                );
                let dark = px.iter().filter(|(_, v)| *v != 1.0).count();
                assert_eq!(
                    dark,
                    0,
                    "{geometry:?} {method} {:?}: {dark} of {} pixels shadowed",
                    shadows.mode,
                    px.len()
                );
            }
        }
    }
    finish(ctx);
}

/// A 64 x 64 decal at height 0.2 with a ridge of height 1 over the texel columns
/// 30..=33; the light comes from +u (azimuth 90 degrees) at 15 degrees: from the low
/// plateau the light ray climbs 0.8 heights over 0.8 * 0.1 / tan 15 = 0.30 uv.
fn ridge() -> HeightField {
    let values = (0..64 * 64)
        .map(|k| {
            if (30..=33).contains(&(k % 64)) {
                1.0
            } else {
                0.2
            }
        })
        .collect();
    HeightField::from_heights(64, 64, values, "ridge").unwrap()
}

#[test]
fn a_ridge_shadows_the_side_away_from_the_light() {
    let ctx = validated_context();
    let field = ridge();
    let sun = light(15.0, 90.0);
    // The ridge's foot on the low side is at texel-space x = 29, u = 29.5 / 64.
    let foot = 29.5 / 64.0;
    let reach = 0.8 * 0.1 / 15f64.to_radians().tan();
    let mut renderer = Renderer::new(
        &ctx,
        &field,
        settings(Method::Exact, Geometry::Quad, sun, HARD),
    )
    .unwrap();
    for method in METHODS {
        renderer
            .set_method(method, MethodParams::for_method(method))
            .unwrap();
        let mut soft_means = [0.0; 2];
        for shadows in [HARD, SOFT] {
            renderer.set_shadows(shadows).unwrap();
            renderer.render().unwrap();
            let px = covered(&renderer);
            let low = |u: f32, h: f32| (h - 0.2).abs() < 0.02 && u.is_finite();
            // Behind: on the low plateau, well within the ray's reach of the foot.
            let behind: Vec<f32> = px
                .iter()
                .filter(|(h, _)| {
                    let u = f64::from(h[0]);
                    low(h[0], h[2]) && u < foot - 0.02 && u > foot - 0.6 * reach
                })
                .map(|(_, v)| *v)
                .collect();
            // In front: the low plateau on the light's side of the ridge.
            let front: Vec<f32> = px
                .iter()
                .filter(|(h, _)| low(h[0], h[2]) && f64::from(h[0]) > 34.5 / 64.0 + 0.02)
                .map(|(_, v)| *v)
                .collect();
            assert!(
                behind.len() > 200 && front.len() > 200,
                "{method}: {} behind, {} in front",
                behind.len(),
                front.len()
            );
            let mean = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
            eprintln!(
                "{method:<11} {:<4} behind {:>5} px mean visibility {:.3}, front {:>5} px mean {:.3}",
                shadows.mode,
                behind.len(),
                mean(&behind),
                front.len(),
                mean(&front)
            );
            assert!(
                front.iter().all(|&v| v == 1.0),
                "{method}: a lit pixel is dark"
            );
            match shadows.mode {
                ShadowMode::Hard => assert!(
                    behind.iter().all(|&v| v == 0.0),
                    "{method}: {} of {} pixels behind the ridge are lit",
                    behind.iter().filter(|&&v| v != 0.0).count(),
                    behind.len()
                ),
                _ => {
                    assert!(behind.iter().all(|&v| (0.0..1.0).contains(&v)), "{method}");
                    soft_means[0] = mean(&behind);
                    soft_means[1] = mean(&front);
                }
            }
        }
        assert!(
            soft_means[0] < 0.5 && soft_means[1] == 1.0,
            "{method}: {soft_means:?}"
        );
    }
    drop(renderer);
    finish(ctx);
}

/// How far (heights) the receiver may move up or down before the reference's answer
/// counts as decided: f32 rounding of the GPU's light ray (the hit is stored in f32 and
/// the traversal runs in f32) is far below it.
const TANGENCY: f64 = 1e-5;

/// `exact`, `pyramid` and `dig-guarded` answer hard shadows with the exact traversal:
/// each pixel against `Reference::occluded` of the same receiver.
#[test]
fn exact_hard_shadows_match_the_reference() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    for (method, geometry, elevation, azimuth) in [
        (Method::Exact, Geometry::TiledPlane, 20.0, 60.0),
        (Method::Exact, Geometry::TiledPlane, 8.0, 200.0),
        (Method::Exact, Geometry::Quad, 25.0, 300.0),
        (Method::Pyramid, Geometry::TiledPlane, 20.0, 60.0),
        (Method::DigGuarded, Geometry::Quad, 25.0, 300.0),
    ] {
        let sun = light(elevation, azimuth);
        let s = settings(method, geometry, sun, HARD);
        let reference = Reference::new(&field, s.scene.addressing());
        let mut renderer = Renderer::new(&ctx, &field, s).unwrap();
        renderer.render().unwrap();
        let l = light_ts(sun);
        let depth = f64::from(s.scene.depth_scale);
        let (mut shadowed, mut total, mut tangent, mut tangent_disagree) = (0, 0, 0, 0);
        let mut disagree = Vec::new();
        for (hit, vis) in covered(&renderer) {
            let uv = [f64::from(hit[0]), f64::from(hit[1])];
            // The receiver as the pass takes it: the surface under the hit's uv.
            let h = reference.height(uv);
            let gpu = vis == 0.0;
            assert!(vis == 0.0 || vis == 1.0, "hard visibility {vis}");
            let cpu = reference.occluded(uv, h, l, depth);
            let decided = reference.occluded(uv, h + TANGENCY, l, depth)
                == reference.occluded(uv, h - TANGENCY, l, depth);
            total += 1;
            shadowed += usize::from(gpu);
            if !decided {
                tangent += 1;
                tangent_disagree += usize::from(gpu != cpu);
            } else if gpu != cpu {
                disagree.push((uv, h, gpu));
            }
        }
        eprintln!(
            "{method} hard {geometry:?} light {elevation}/{azimuth} deg: {total} px, shadowed {:.2}%, \
             tangency cases {tangent} ({tangent_disagree} disagree), decided disagreements {}",
            100.0 * shadowed as f64 / total as f64,
            disagree.len()
        );
        assert!(total > 5000);
        assert!(
            shadowed * 20 > total,
            "too few shadowed pixels to test: {shadowed}"
        );
        assert!(
            disagree.is_empty(),
            "{} decided pixels disagree, e.g. {:?}",
            disagree.len(),
            &disagree[..disagree.len().min(5)]
        );
        // Tangency (the answer flips within TANGENCY): under 1% of the pixels (measured
        // 0.22%, 0.83%, 0.26%), and the GPU may go either way there (measured: 1, 0, 0
        // pixels disagree).
        assert!(
            tangent * 100 <= total,
            "{tangent} tangency cases of {total}"
        );
        assert!(
            tangent_disagree <= 2,
            "{tangent_disagree} tangency disagreements of {total}"
        );
    }
    finish(ctx);
}

/// The marching methods' hard shadows (a linear march with the method's step, from the
/// surface height under the hit) against the reference's occlusion of the same start
/// point (`Reference::height` at the hit's uv). The march samples the exact bilinear
/// surface, so it can only miss shadows (a thin occluder between two samples, or one
/// within the first step of the receiver), never invent one, and misses fewer with more
/// steps. Measured on rocks, tiled plane, light 20 degrees, share of covered pixels the
/// march leaves lit where the reference shadows them: relief 6.17% (64 steps), 2.30%
/// (256), 0.62% (1024); linear 6.46% and pom 6.69% (64); secant 14.88% (15); falsely
/// shadowed: 0 in every run.
#[test]
fn marching_hard_shadows_against_the_reference() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let sun = light(20.0, 60.0);
    let base = settings(Method::Relief, Geometry::TiledPlane, sun, HARD);
    let reference = Reference::new(&field, base.scene.addressing());
    let mut renderer = Renderer::new(&ctx, &field, base).unwrap();
    let l = light_ts(sun);
    let depth = f64::from(base.scene.depth_scale);
    let mut relief_missed = Vec::new();
    for (method, steps, missed_bound) in [
        (Method::Relief, 64, 0.07),
        (Method::Relief, 256, 0.03),
        (Method::Relief, 1024, 0.01),
        (Method::Linear, 64, 0.07),
        (Method::Pom, 64, 0.075),
        (Method::Secant, 15, 0.16),
    ] {
        renderer
            .set_method(
                method,
                MethodParams {
                    steps,
                    ..MethodParams::for_method(method)
                },
            )
            .unwrap();
        renderer.render().unwrap();
        let px = covered(&renderer);
        let (mut shadowed, mut missed, mut extra) = (0, 0, 0);
        for (hit, vis) in &px {
            let uv = [f64::from(hit[0]), f64::from(hit[1])];
            let cpu = reference.occluded(uv, reference.height(uv), l, depth);
            let gpu = *vis == 0.0;
            shadowed += usize::from(gpu);
            missed += usize::from(cpu && !gpu);
            extra += usize::from(gpu && !cpu);
        }
        let n = px.len() as f64;
        let missed = missed as f64 / n;
        eprintln!(
            "{method:<7} hard (march, {steps} steps): shadowed {:.2}%, missed (reference \
             shadowed, march lit) {:.2}%, falsely shadowed {extra} px",
            100.0 * shadowed as f64 / n,
            100.0 * missed
        );
        // Ties (a sample exactly on a plateau) may go either way in f32: 0 measured.
        assert!(
            extra as f64 <= 5e-4 * n,
            "{method} {steps}: {extra} falsely shadowed"
        );
        assert!(
            missed <= missed_bound,
            "{method} {steps}: {:.2}% missed",
            100.0 * missed
        );
        if method == Method::Relief {
            relief_missed.push(missed);
        }
    }
    assert!(
        relief_missed.windows(2).all(|w| w[1] < w[0]),
        "more steps must miss fewer shadows: {relief_missed:?}"
    );
    drop(renderer);
    finish(ctx);
}

#[test]
fn soft_shadows_are_in_range_and_darken_with_a_lower_light() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    for method in [Method::Exact, Method::Relief] {
        let mut renderer = Renderer::new(
            &ctx,
            &field,
            settings(method, Geometry::TiledPlane, light(60.0, 60.0), SOFT),
        )
        .unwrap();
        let mut means = Vec::new();
        for elevation in [60.0, 35.0, 15.0, 5.0] {
            let mut scene = renderer.settings().scene;
            scene.light = light(elevation, 60.0);
            renderer.set_scene(scene).unwrap();
            renderer.render().unwrap();
            let px = covered(&renderer);
            assert!(
                px.iter()
                    .all(|(_, v)| v.is_finite() && (0.0..=1.0).contains(v)),
                "{method} {elevation}: visibility out of [0, 1]"
            );
            let mean = px.iter().map(|(_, v)| f64::from(*v)).sum::<f64>() / px.len() as f64;
            let dark = px.iter().filter(|(_, v)| *v < 1.0).count() as f64 / px.len() as f64;
            // For comparison: the hard shadows' fraction under the same light.
            renderer.set_shadows(HARD).unwrap();
            renderer.render().unwrap();
            let hard = covered(&renderer);
            let hard_dark =
                hard.iter().filter(|(_, v)| *v == 0.0).count() as f64 / hard.len() as f64;
            renderer.set_shadows(SOFT).unwrap();
            eprintln!(
                "{method} soft, light {elevation} deg: mean visibility {mean:.4}, {:.2}% below 1 \
                 (hard: {:.2}% shadowed)",
                100.0 * dark,
                100.0 * hard_dark
            );
            means.push(mean);
        }
        assert!(
            means.windows(2).all(|w| w[1] < w[0]),
            "{method}: not darker with a lower light: {means:?}"
        );
        // Colour stays finite with shadows on.
        let color = renderer.read_color().unwrap();
        assert!(color.chunks(4).all(|c| c[3] == 255));
    }
    finish(ctx);
}

#[test]
fn the_shadow_pass_is_timed_only_when_on() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let mut renderer = Renderer::new(
        &ctx,
        &field,
        settings(
            Method::Pyramid,
            Geometry::TiledPlane,
            light(30.0, 60.0),
            ShadowSettings::default(),
        ),
    )
    .unwrap();
    let names = |t: &[(String, f64)]| t.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    let off = renderer.render_frames(1).unwrap();
    assert!(!names(&off).contains(&"shadow".to_string()), "{off:?}");
    assert!(renderer.read_visibility().unwrap().is_none());
    for shadows in [HARD, SOFT] {
        renderer.set_shadows(shadows).unwrap();
        let on = renderer.render_frames(2).unwrap();
        let n = names(&on);
        let (shade, shadow) = (
            n.iter().position(|x| x == "shade").unwrap(),
            n.iter().position(|x| x == "shadow").expect("shadow timed"),
        );
        assert!(n.iter().position(|x| x == "trace").unwrap() < shadow && shadow < shade);
        let ms = on[shadow].1;
        let trace = on.iter().find(|(x, _)| x == "trace").unwrap().1;
        eprintln!(
            "pyramid + {:?} shadows, rocks 128x96: shadow {ms:.3} ms, trace {trace:.3} ms ({:.2}x)",
            shadows.mode,
            ms / trace
        );
        assert!(ms.is_finite() && ms >= 0.0);
    }
    renderer.set_shadows(ShadowSettings::default()).unwrap();
    let off = renderer.render_frames(1).unwrap();
    assert!(!names(&off).contains(&"shadow".to_string()), "{off:?}");
    // A bad sample count is refused by name.
    let err = renderer
        .set_shadows(ShadowSettings {
            mode: ShadowMode::Soft,
            samples: 0,
        })
        .unwrap_err()
        .to_string();
    assert!(err.contains("shadow-samples"), "{err}");
    drop(renderer);
    finish(ctx);
}

/// `dispmap render --shadows MODE`: the metrics JSON lists the `shadow` pass only when
/// shadows are on; bad values are refused by option name, before any file is written.
#[test]
fn cli_render_shadows() {
    let dir = std::env::temp_dir().join(format!("dispmap-shadows-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let map = common::repo_root().join("assets/heightmaps/rocks_depth.jpg");
    let run = |extra: &[&str], png: &std::path::Path, json: &std::path::Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_dispmap"))
            .env("DISPMAP_VALIDATION", "1")
            .args(["render", "--heightmap"])
            .arg(&map)
            .args(["--convention", "depth", "--size", "64x48", "--frames", "1"])
            .args(extra)
            .arg("--out")
            .arg(png)
            .arg("--metrics")
            .arg(json)
            .output()
            .unwrap()
    };
    for (mode, method, timed) in [
        ("off", "exact", false),
        ("hard", "exact", true),
        ("hard", "relief", true),
        ("soft", "pom", true),
    ] {
        let (png, json) = (
            dir.join(format!("{mode}-{method}.png")),
            dir.join(format!("{mode}-{method}.json")),
        );
        let out = run(&["--shadows", mode, "--method", method], &png, &json);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{mode} {method}: {stderr}");
        assert!(!stderr.contains("Validation"), "{stderr}");
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(v["shadows"], mode);
        let shadow = v["timings_ms"].get("shadow");
        assert_eq!(shadow.is_some(), timed, "{mode} {method}: {v}");
        if let Some(ms) = shadow {
            assert!(ms.as_f64().unwrap() >= 0.0);
        }
        assert!(image::open(&png).is_ok());
    }
    for (args, named) in [
        (&["--shadows", "maybe"][..], "--shadows"),
        (
            &["--shadows", "soft", "--shadow-samples", "0"][..],
            "shadow-samples",
        ),
        (&["--shadow-samples", "many"][..], "--shadow-samples"),
    ] {
        let (png, json) = (dir.join("bad.png"), dir.join("bad.json"));
        let out = run(args, &png, &json);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} was accepted");
        assert!(stderr.contains(named), "{args:?}: {stderr}");
        assert!(!png.exists() && !json.exists(), "{args:?} wrote a file");
    }
}

/// With hard shadows the reference colour (what PSNR compares against) is shaded with
/// the exact visibility of the exact hits, so it is the same image whichever method's
/// renderer builds it; the exact methods reproduce it.
#[test]
fn the_hard_shadow_reference_is_the_same_for_every_method() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let sun = light(20.0, 60.0);
    let mut colors = Vec::new();
    for method in [Method::Relief, Method::Exact, Method::Pyramid] {
        let s = settings(method, Geometry::TiledPlane, sun, HARD);
        let reference = Reference::new(&field, s.scene.addressing());
        let mut renderer = Renderer::new(&ctx, &field, s).unwrap();
        let frame = renderer.reference(&reference).unwrap();
        let m = renderer.measure(&frame, 1).unwrap();
        eprintln!(
            "{method} hard shadows: PSNR {:.2} dB against the shadowed reference, artifacts {:.3}%",
            m.error.psnr_db,
            100.0 * m.error.artifact_fraction
        );
        if method == Method::Exact {
            assert!(m.error.psnr_db >= 60.0, "exact: {} dB", m.error.psnr_db);
        }
        colors.push(frame.color);
    }
    assert!(colors.windows(2).all(|w| w[0] == w[1]));
    finish(ctx);
}
