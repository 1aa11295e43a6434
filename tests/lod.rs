//! Level of detail (Tatarchuk 2006; `MethodParams::lod_threshold`, `--lod-threshold`):
//! on a far, minified tiled plane LOD cuts the trace cost of relief, pom and dig at an
//! error cost measured against the exact reference (docs/methods.md lists the numbers),
//! every pixel follows the documented rule (bump beyond the
//! threshold, the method's own hit below the band, the blend in it, a decal's misses
//! kept in the band), and a magnified close-up is bit-identical with LOD on and off.
//! Validation on throughout.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::gpu::owned::Destroy;
use dispmap::heightfield::Convention;
use dispmap::method::{MaxLevel, Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Scene};
use dispmap_cli::measure::Measure as _;
use dispmap_cli::metrics::{self, ErrorMetrics, HitTexel};
use dispmap_cli::reference::{Ray, Reference};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 144;

/// The LOD threshold of the far-plane test: pixels spanning 128 texels or more take bump
/// mapping, 64 to 128 texels blend (on this scene the footprints span levels 5 to 9).
const THRESHOLD: f32 = 7.0;

/// Far plane: the eye 2 tiles above the plane looking 10 degrees down, so the 1024^2
/// rocks map is minified on almost every pixel.
fn far_scene() -> Scene {
    Scene {
        camera: Camera {
            elevation_deg: 10.0,
            height: 2.0,
            ..Camera::default()
        },
        ..Scene::default()
    }
}

/// Close-up: the eye 0.05 tiles above the plane looking 60 degrees down: every pixel
/// spans less than a texel (checked below).
fn close_scene() -> Scene {
    Scene {
        camera: Camera {
            elevation_deg: 60.0,
            height: 0.05,
            ..Camera::default()
        },
        ..Scene::default()
    }
}

fn settings(method: Method, scene: Scene, lod: Option<f32>) -> RenderSettings {
    RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        method,
        params: MethodParams {
            lod_threshold: lod,
            ..MethodParams::for_method(method)
        },
        scene,
        shadows: Default::default(),
    }
}

/// The CPU twin of `footprint_level` in glsl/common/trace.glsl: log2 of the larger uv0
/// step (in texels, tile wraps removed) to the right / lower neighbour (left / upper at
/// the last column / row), 0 when magnified or without neighbours.
fn footprint_levels(rays: &[Option<Ray>], map: [u32; 2]) -> Vec<Option<f64>> {
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    (0..w * h)
        .map(|i| {
            let ray = rays[i].as_ref()?;
            let (x, y) = (i % w, i / w);
            let mut texels: f64 = 0.0;
            for (q, ok) in [
                (if x + 1 < w { i + 1 } else { i.wrapping_sub(1) }, w > 1),
                (if y + 1 < h { i + w } else { i.wrapping_sub(w) }, h > 1),
            ] {
                if !ok {
                    continue;
                }
                if let Some(n) = &rays[q] {
                    let mut d = [n.uv0[0] - ray.uv0[0], n.uv0[1] - ray.uv0[1]];
                    for c in &mut d {
                        *c -= c.round();
                    }
                    let t = (d[0] * map[0] as f64).hypot(d[1] * map[1] as f64);
                    texels = texels.max(t);
                }
            }
            Some(texels.max(1.0).log2())
        })
        .collect()
}

fn bits(t: &HitTexel) -> [u32; 4] {
    t.map(f32::to_bits)
}

/// One method's far-plane numbers with LOD off and on.
struct Row {
    method: Method,
    off: ErrorMetrics,
    on: ErrorMetrics,
    /// Mean hit distance in pixel footprints (texels / texels per pixel), off and on.
    footprints: [f64; 2],
    /// Pixels per LOD region: untouched, blended, bump.
    regions: [usize; 3],
}

/// Measured bounds (the measured value plus a small margin; docs/methods.md lists the values).
/// Iterations: LOD-on mean over LOD-off mean (measured 0.517 relief, 0.468 pom, 0.463
/// dig).
const MAX_ITERATION_RATIO: f64 = 0.55;
/// artifact_fraction, mean_texels and the mean distance in pixel footprints with LOD on,
/// per method (measured: 97.23% / 345.89 / 1.172 relief, 97.34% / 346.06 / 1.174 pom,
/// 97.23% / 345.89 / 1.172 dig; off: 8.2% / 323.8 / 0.775, 33.2% / 324.7 / 0.782,
/// 9.6% / 330.6 / 0.797). On a minified plane a pixel spans 32 to 512 texels, so the
/// one-texel artifact criterion counts nearly every pixel that samples the prefiltered
/// mip chain (the reference intersects the full-resolution map); the footprint distance
/// says how far the hit moves on screen. (The blend alone, sampling level 0, measured
/// 76.3% / 343.6 / 1.127 for relief.)
fn error_bound(method: Method) -> (f64, f64, f64) {
    match method {
        Method::Relief | Method::Pom | Method::Dig => (0.98, 349.0, 1.19),
        _ => unreachable!(),
    }
}

/// Checks every pixel of `on` (LOD at `threshold`) against the rule of `trace_lod`
/// (glsl/common/trace.glsl), given the method's hits with the same mip sampling and no
/// blend (`mipped`) and the bump hits with it (`bump`). Returns the pixels per region:
/// untouched, blended, bump. Pixels within 1e-3 of a region boundary are skipped (the
/// GPU's f32 level may fall on either side).
fn check_lod_rule(
    method: Method,
    levels: &[Option<f64>],
    threshold: f32,
    mipped: &[HitTexel],
    on: &[HitTexel],
    bump: &[HitTexel],
) -> [usize; 3] {
    let l = f64::from(threshold);
    let margin = 1e-3;
    let mut regions = [0usize; 3];
    for (i, level) in levels.iter().enumerate() {
        let Some(level) = *level else { continue };
        let (traced, blended, b) = (mipped[i], on[i], bump[i]);
        if level >= l + margin {
            regions[2] += 1;
            assert_eq!(
                bits(&blended),
                bits(&b),
                "{method} pixel {i}: not the bump hit"
            );
        } else if level <= l - 1.0 - margin {
            regions[0] += 1;
            assert_eq!(bits(&blended), bits(&traced), "{method} pixel {i}: changed");
        } else if level > l - 1.0 + margin && level < l - margin {
            regions[1] += 1;
            if traced[2] < 0.0 {
                // A traced miss (a decal's silhouette) stays a miss in the band.
                assert_eq!(bits(&blended), bits(&traced), "{method} pixel {i}: miss");
                continue;
            }
            let w = (level - (l - 1.0)) as f32;
            for c in 0..3 {
                let want = traced[c] + (b[c] - traced[c]) * w;
                let tol = 1e-3 * (b[c] - traced[c]).abs() + 1e-6;
                assert!(
                    (blended[c] - want).abs() <= tol,
                    "{method} pixel {i} channel {c}: {} vs blend {want} (w {w})",
                    blended[c]
                );
            }
            assert_eq!(
                blended[3],
                traced[3] + 1.0,
                "{method} pixel {i}: iterations"
            );
        }
    }
    regions
}

#[test]
fn lod_on_a_far_plane_trades_error_for_iterations() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = far_scene();
    let reference = Reference::new(&field, scene.addressing());
    let mut renderer = Renderer::new(&ctx, &field, settings(Method::Bump, scene, None)).unwrap();
    let frame_ref = renderer.reference(&reference).unwrap();
    let map = [field.width(), field.height()];
    let levels = footprint_levels(&frame_ref.rays, map);
    let covered = levels.iter().flatten().count();
    let minified = levels.iter().flatten().filter(|&&l| l >= 1.0).count();
    println!("far plane: {covered} covered pixels, {minified} minified (> 2 texels per pixel)");
    let mut histogram = [0usize; 12];
    for l in levels.iter().flatten() {
        histogram[(l.floor() as usize).min(11)] += 1;
    }
    println!("pixels per footprint level (floor, 0..=11+): {histogram:?}");
    assert!(
        minified * 10 >= covered * 9,
        "the far plane is not minified enough"
    );

    // With LOD on every height_at samples the mip chain at the footprint level; a
    // threshold beyond every level isolates that sampling (no blend, no bump) for the
    // per-pixel rule below.
    let mip_only = |method: Method| settings(method, scene, Some(31.0)).params;
    renderer
        .set_method(Method::Bump, mip_only(Method::Bump))
        .unwrap();
    renderer.render().unwrap();
    let bump = renderer.read_hits().unwrap();
    let mut rows = Vec::new();
    for method in [Method::Relief, Method::Pom, Method::Dig] {
        let s = settings(method, scene, None);
        renderer.set_method(method, s.params).unwrap();
        let off = renderer.measure(&frame_ref, 1).unwrap();
        renderer.set_method(method, mip_only(method)).unwrap();
        renderer.render().unwrap();
        let mipped = renderer.read_hits().unwrap();
        let s = settings(method, scene, Some(THRESHOLD));
        renderer.set_method(method, s.params).unwrap();
        let on = renderer.measure(&frame_ref, 1).unwrap();
        assert_eq!(on.error.nonfinite_pixels, 0, "{method}");

        // Every pixel follows the rule of trace_lod (glsl/common/trace.glsl).
        let regions = check_lod_rule(method, &levels, THRESHOLD, &mipped, &on.hits, &bump);
        let geo = renderer.map_geometry();
        let footprints = [&off.hits, &on.hits].map(|hits| {
            let d: Vec<f64> = (0..hits.len())
                .filter_map(|i| {
                    let (Some(level), Some(want)) = (levels[i], frame_ref.hits[i]) else {
                        return None;
                    };
                    (hits[i][2] >= 0.0)
                        .then(|| metrics::hit_distance_texels(&hits[i], &want, geo) / level.exp2())
                })
                .collect();
            d.iter().sum::<f64>() / d.len().max(1) as f64
        });
        rows.push(Row {
            method,
            off: off.error,
            on: on.error,
            footprints,
            regions,
        });
    }
    println!(
        "threshold {THRESHOLD}: method | iterations off -> on | artifact% off -> on | \
         mean texels off -> on | mean pixel footprints off -> on | PSNR off -> on | \
         pixels untouched / blended / bump"
    );
    for r in &rows {
        println!(
            "{:7} | {:6.2} -> {:5.2} ({:.3}x) | {:6.2} -> {:6.2} | {:7.3} -> {:7.3} | {:5.3} -> {:5.3} | {:5.2} -> {:5.2} | {:?}",
            r.method.name(),
            r.off.mean_iterations,
            r.on.mean_iterations,
            r.on.mean_iterations / r.off.mean_iterations,
            100.0 * r.off.artifact_fraction,
            100.0 * r.on.artifact_fraction,
            r.off.mean_texels,
            r.on.mean_texels,
            r.footprints[0],
            r.footprints[1],
            r.off.psnr_db,
            r.on.psnr_db,
            r.regions
        );
    }
    for r in &rows {
        let ratio = r.on.mean_iterations / r.off.mean_iterations;
        assert!(
            ratio <= MAX_ITERATION_RATIO,
            "{}: LOD keeps {ratio:.3} of the iterations",
            r.method
        );
        let (artifacts, texels, footprints) = error_bound(r.method);
        assert!(
            r.on.artifact_fraction <= artifacts
                && r.on.mean_texels <= texels
                && r.footprints[1] <= footprints,
            "{}: LOD error {} artifacts, {} mean texels, {} footprints over the bound",
            r.method,
            r.on.artifact_fraction,
            r.on.mean_texels,
            r.footprints[1]
        );
        assert!(
            r.regions.iter().all(|&n| n > 0),
            "{}: {:?}",
            r.method,
            r.regions
        );
    }
    drop(renderer);
    finish(ctx);
}

#[test]
fn lod_on_a_decal_keeps_its_silhouette_in_the_band() {
    // The quad (clamp addressing) 1.4 units away: footprints of 4 to 64 texels. A traced
    // miss (a ray leaving the decal) stays a miss in the blend band; beyond the threshold
    // the pixel is bump mapped like any other.
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = Scene {
        geometry: dispmap::scene::Geometry::Quad,
        camera: Camera {
            elevation_deg: 20.0,
            ..Camera::default()
        },
        ..Scene::default()
    };
    let threshold = 4.5;
    let mut renderer = Renderer::new(&ctx, &field, settings(Method::Bump, scene, None)).unwrap();
    renderer.render().unwrap();
    let rays = renderer.read_rays().unwrap();
    let levels = footprint_levels(&rays, [field.width(), field.height()]);
    let mut histogram = [0usize; 6];
    for l in levels.iter().flatten() {
        histogram[(l.floor() as usize).min(5)] += 1;
    }
    println!("quad: pixels per footprint level (floor, 0..=5+): {histogram:?}");
    let mip_only = |method: Method| settings(method, scene, Some(31.0)).params;
    renderer
        .set_method(Method::Bump, mip_only(Method::Bump))
        .unwrap();
    renderer.render().unwrap();
    let bump = renderer.read_hits().unwrap();
    for method in [Method::Relief, Method::Exact] {
        renderer.set_method(method, mip_only(method)).unwrap();
        renderer.render().unwrap();
        let mipped = renderer.read_hits().unwrap();
        renderer
            .set_method(method, settings(method, scene, Some(threshold)).params)
            .unwrap();
        renderer.render().unwrap();
        let on = renderer.read_hits().unwrap();
        let regions = check_lod_rule(method, &levels, threshold, &mipped, &on, &bump);
        let band_misses = levels
            .iter()
            .zip(&mipped)
            .filter(|(l, h)| {
                l.is_some_and(|l| l > f64::from(threshold) - 1.0 && l < f64::from(threshold))
                    && h[2] < 0.0
            })
            .count();
        println!(
            "quad {method}: pixels untouched / blended / bump {regions:?}, {band_misses} misses kept in the band"
        );
        assert!(regions.iter().all(|&n| n > 0), "{method}: {regions:?}");
        assert!(band_misses > 0, "{method}: no silhouette in the band");
    }
    drop(renderer);
    finish(ctx);
}

#[test]
fn lod_leaves_a_magnified_close_up_bit_identical() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = close_scene();
    let mut renderer = Renderer::new(&ctx, &field, settings(Method::Relief, scene, None)).unwrap();
    renderer.render().unwrap();
    let rays = renderer.read_rays().unwrap();
    let levels = footprint_levels(&rays, [field.width(), field.height()]);
    // The plane covers the whole close-up (tests/gbuffer_plane.rs checks its coverage).
    let covered = levels.iter().flatten().count();
    assert_eq!(
        covered,
        levels.len(),
        "the close-up has pixels without geometry"
    );
    let max_level = levels.iter().flatten().copied().fold(0.0, f64::max);
    assert_eq!(max_level, 0.0, "the close-up is not magnified everywhere");
    for method in [Method::Relief, Method::Pom, Method::Dig, Method::Pyramid] {
        let mut frames = Vec::new();
        for lod in [None, Some(1.0)] {
            let mut s = settings(method, scene, lod);
            if method == Method::Pyramid {
                s.params.max_level = MaxLevel::Auto;
            }
            renderer.set_method(method, s.params).unwrap();
            renderer.render().unwrap();
            frames.push((
                renderer.read_hits().unwrap(),
                renderer.read_color().unwrap(),
            ));
        }
        let (off, on) = (&frames[0], &frames[1]);
        let differing = off
            .0
            .iter()
            .zip(&on.0)
            .filter(|(a, b)| bits(a) != bits(b))
            .count();
        assert_eq!(
            differing, 0,
            "{method}: {differing} hits differ with LOD on"
        );
        assert!(off.1 == on.1, "{method}: the shaded frames differ");
    }
    drop(renderer);
    finish(ctx);
}

#[test]
fn pyramid_auto_level_uses_the_footprint_level() {
    // Oh et al. 3.4 through the shared footprint function: on the far plane the automatic
    // coarsest level must cut the traversal, and stay finite.
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = far_scene();
    let reference = Reference::new(&field, scene.addressing());
    let mut renderer = Renderer::new(&ctx, &field, settings(Method::Pyramid, scene, None)).unwrap();
    let frame_ref = renderer.reference(&reference).unwrap();
    let full = renderer.measure(&frame_ref, 1).unwrap();
    let mut s = settings(Method::Pyramid, scene, None);
    s.params.max_level = MaxLevel::Auto;
    renderer.set_method(Method::Pyramid, s.params).unwrap();
    let auto = renderer.measure(&frame_ref, 1).unwrap();
    println!(
        "pyramid far plane: iterations {:.2} -> {:.2} (auto), artifacts {:.2}% -> {:.2}%, mean texels {:.3} -> {:.3}",
        full.error.mean_iterations,
        auto.error.mean_iterations,
        100.0 * full.error.artifact_fraction,
        100.0 * auto.error.artifact_fraction,
        full.error.mean_texels,
        auto.error.mean_texels
    );
    assert_eq!(auto.error.nonfinite_pixels, 0);
    assert!(auto.error.mean_iterations < full.error.mean_iterations);
    drop(renderer);
    finish(ctx);
}

#[test]
fn the_height_mip_chain_is_the_box_average_and_level_0_is_the_map() {
    // The level-of-detail sampling reads this chain (src/gpu/height_texture.rs). It exists
    // only while level of detail is on: uploaded with it, or derived on the GPU from a
    // texture without it, and dropped again when level of detail goes off.
    let ctx = validated_context();
    let (w, h) = (16u32, 8u32);
    let values: Vec<f32> = (0..w * h)
        .map(|i| ((i * 37 % 101) as f32) / 100.0)
        .collect();
    let field = dispmap::HeightField::from_heights(w, h, values.clone(), "mips").unwrap();
    let mut shot = dispmap::gpu::OneShot::new(&ctx, "test.mips").unwrap();
    let upload = |chain: bool| {
        dispmap::gpu::HeightTexture::upload(
            &ctx,
            &shot,
            &field,
            dispmap::heightfield::Addressing::Repeat,
            chain,
        )
        .unwrap()
    };
    let derive = |from: &dispmap::gpu::HeightTexture, chain: bool| {
        let texture = from.create_like(&ctx, chain).unwrap();
        let cmd = shot.begin(&ctx).unwrap();
        // SAFETY: `cmd` was just begun by `shot.begin` (outside a render pass, on the
        // context's queue family) and is submitted and waited for below, while both
        // textures live; `texture` is `from`'s new twin (`create_like`), never accessed,
        // and `from` was left sampled-readable by its upload or derivation.
        unsafe { texture.record_copy_from(&ctx, cmd, from).unwrap() };
        shot.submit_and_wait(&ctx).unwrap();
        texture
    };
    let mut plain = upload(false);
    assert!(!plain.has_chain(), "uploaded without level of detail");
    check_levels(&ctx, &shot, &plain, &values, (w, h), 1);
    let mut chained = upload(true);
    check_levels(&ctx, &shot, &chained, &values, (w, h), 5);
    let mut derived = derive(&plain, true);
    check_levels(&ctx, &shot, &derived, &values, (w, h), 5);
    let mut dropped = derive(&derived, false);
    check_levels(&ctx, &shot, &dropped, &values, (w, h), 1);
    for t in [&mut plain, &mut chained, &mut derived, &mut dropped] {
        // SAFETY: every one-shot submission was waited for.
        unsafe { t.destroy(&ctx) };
    }
    // SAFETY: every one-shot submission was waited for.
    unsafe { shot.destroy(&ctx) };
    finish(ctx);
}

/// `texture` has `levels` levels ("16x8 has levels 16, 8, 4, 2, 1 wide"), level 0 is
/// `values` bit for bit and every further level the 2x2 box average of the one above.
fn check_levels(
    ctx: &dispmap::Context,
    shot: &dispmap::gpu::OneShot,
    texture: &dispmap::gpu::HeightTexture,
    values: &[f32],
    (w, h): (u32, u32),
    levels: u32,
) {
    assert_eq!(texture.image.mip_levels, levels);
    assert_eq!(texture.has_chain(), levels > 1);
    let mut expect = values.to_vec();
    let (mut lw, mut lh) = (w as usize, h as usize);
    for level in 0..levels {
        let bytes = dispmap::gpu::commands::read_image_level(
            ctx,
            shot,
            &texture.image,
            level,
            dispmap::gpu::sync::Access::COMPUTE_SAMPLED,
        )
        .unwrap();
        let got: &[f32] = bytemuck::cast_slice(&bytes);
        assert_eq!(got.len(), lw * lh, "level {level}");
        for (i, (g, e)) in got.iter().zip(&expect).enumerate() {
            if level == 0 {
                assert_eq!(g, e, "level 0 texel {i} is not the map's");
            } else {
                assert!((g - e).abs() <= 1e-5, "level {level} texel {i}: {g} vs {e}");
            }
        }
        // The next level: the mean of each 2x2 block (a side of 1 stays 1).
        let (nw, nh) = ((lw / 2).max(1), (lh / 2).max(1));
        expect = (0..nw * nh)
            .map(|k| {
                let (x, y) = (k % nw, k / nw);
                let xs = if lw > 1 { [2 * x, 2 * x + 1] } else { [0, 0] };
                let ys = if lh > 1 { [2 * y, 2 * y + 1] } else { [0, 0] };
                let mut sum = 0.0;
                for yy in ys {
                    for xx in xs {
                        sum += expect[yy * lw + xx];
                    }
                }
                sum / 4.0
            })
            .collect();
        (lw, lh) = (nw, nh);
    }
}

#[test]
fn switching_lod_on_later_matches_a_renderer_built_with_it() {
    // The renderer uploads the map without its mip chain while level of detail is off and
    // derives the chain when `set_method` turns it on: the far plane (every pixel
    // minified) then renders bit for bit as with the chain from the start, and not as
    // without it.
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = far_scene();
    let on = settings(Method::Relief, scene, Some(THRESHOLD));
    let hits = |r: &mut Renderer| {
        r.render().unwrap();
        r.read_hits()
            .unwrap()
            .iter()
            .map(|h| h.map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    let mut built_on = Renderer::new(&ctx, &field, on).unwrap();
    let want = hits(&mut built_on);
    drop(built_on);
    let mut switched = Renderer::new(&ctx, &field, settings(Method::Relief, scene, None)).unwrap();
    let off = hits(&mut switched);
    for round in 0..2 {
        switched.set_method(Method::Relief, on.params).unwrap();
        assert_eq!(hits(&mut switched), want, "round {round}: LOD switched on");
        switched
            .set_method(Method::Relief, settings(Method::Relief, scene, None).params)
            .unwrap();
        assert_eq!(hits(&mut switched), off, "round {round}: LOD switched off");
    }
    assert_ne!(want, off, "LOD changes no hit on the far plane");
    drop(switched);
    finish(ctx);
}
