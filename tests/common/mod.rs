//! Shared set-up of the GPU tests: a validated context (core and synchronization
//! validation), [`finish`] (the teardown check every GPU test ends with), the reference
//! agreement check [`unexplained`], [`frames`], the frames-in-flight plumbing of the test
//! hosts, and [`host`], a test host that feeds chosen or rasterised rays to the
//! embeddable pass.

#![allow(dead_code)]

pub mod frames;
pub mod host;

use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::{Convention, HeightField};
use dispmap_cli::metrics::{MapGeometry, hit_distance_texels};
use dispmap_cli::reference::{Hit, Ray, Reference};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A context with the Khronos validation layer (and synchronization validation) on.
/// Panics with a setup hint when no Vulkan driver or no validation layer is installed.
pub fn validated_context() -> Arc<Context> {
    let _ = env_logger::builder().is_test(true).try_init();
    Arc::new(
        Context::headless(&ContextOptions {
            validation: Some(true),
            device: None,
        })
        .unwrap_or_else(|e| {
            panic!("cannot create a validated Vulkan context: {e}\n(run ./scripts/setup-debian.sh)")
        }),
    )
}

/// The end of every GPU test: checks that no `gpu-allocator` allocation is left (its
/// report), destroys the device (the validation layer's object tracker reports every
/// Vulkan object still alive there as an error) and asserts that validation reported
/// no warning or error from the context's creation to its destruction. Every other
/// holder of the context (renderers, passes) must be gone.
pub fn finish(ctx: Arc<Context>) {
    let ctx = Arc::into_inner(ctx).expect("nothing else holds the context");
    let report = ctx.allocator().lock().unwrap().generate_report();
    let names: Vec<&str> = report.allocations.iter().map(|a| a.name.as_str()).collect();
    assert!(names.is_empty(), "allocations left at teardown: {names:?}");
    assert!(
        ctx.has_messenger(),
        "no debug messenger: validation messages would go unseen"
    );
    let messages = ctx.messages().clone();
    drop(ctx); // waits for idle, destroys the allocator, the device, then the messenger
    assert_eq!(
        (messages.errors(), messages.warnings()),
        (0, 0),
        "validation reported errors/warnings up to the device's destruction (see the log)"
    );
}

/// The repository's root (the tests of both crates include this module).
pub fn repo_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    match manifest.join("assets").is_dir() {
        true => manifest.to_path_buf(),
        false => manifest.join(".."),
    }
}

/// A height map from `assets/heightmaps`.
pub fn asset_map(name: &str, convention: Convention) -> HeightField {
    let path = repo_root().join("assets/heightmaps").join(name);
    HeightField::load(&path, convention).expect("bundled map loads")
}

/// The pixels of `hits` that disagree with the reference (`exact`, for `rays`) by more
/// than one texel, or on hit versus miss, and that a skim of depth `tolerance` does not
/// explain. An exact method and the f64 reference may disagree on a ray that skims the
/// surface within f32 rounding (one reports the touch, the other the next crossing); the
/// pyramid method's refinement samples the surface half a texel apart and steps over
/// shallow skims. Such a pixel is explained when the earlier of the two hits is a touch
/// (the surface within `tolerance` of the ray) and the ray between the two never goes
/// deeper than `tolerance` under the surface. The touch is looked for within two f32
/// ulps of the stored hit height, and within two ulps of the stored uv of the hit's own
/// point along the ray (the exact family places it from `t`, not from the height): a height
/// cannot place a hit more finely along the ray (at `|P|` = 1732 tiles one ulp of a
/// height near 1 is a tenth of a texel of a 1024 map, and a steep flank moves the surface
/// by 1e-4 of the depth over it; on a grazing row at depth scale 100 an ulp is 4 texels).
pub fn unexplained(
    reference: &Reference,
    rays: &[Option<Ray>],
    exact: &[Option<Hit>],
    hits: &[[f32; 4]],
    geometry: MapGeometry,
    tolerance: f64,
) -> usize {
    let mut count = 0;
    for ((hit, exact), ray) in hits.iter().zip(exact).zip(rays) {
        let Some(ray) = ray else { continue };
        // On the ray itself, or on the ray as the G-buffer stores it (uv0 and P rounded to
        // f32, `R32G32B32A32_SFLOAT`): the reference traces each pixel's f64 centre ray,
        // and a ray that skims a steep ridge can touch it or clear it depending on that
        // rounding alone (mountains at 1 degree: the f64 ray clears a ridge by 4.6e-6 of
        // the depth, its f32 rounding touches it), which f32 cannot decide.
        let stored = Ray {
            uv0: ray.uv0.map(|x| f64::from(x as f32)),
            parallax: ray.parallax.map(|x| f64::from(x as f32)),
        };
        let explained = explained_pixel(reference, ray, exact.as_ref(), hit, geometry, tolerance)
            || explained_pixel(
                reference,
                &stored,
                reference.intersect(&stored).as_ref(),
                hit,
                geometry,
                tolerance,
            );
        if !explained {
            count += 1;
        }
    }
    count
}

/// Whether `hit` agrees with `exact`, the exact hit of `ray`, or the two are a skim of
/// depth `tolerance` along `ray` (see [`unexplained`]).
fn explained_pixel(
    reference: &Reference,
    ray: &Ray,
    exact: Option<&Hit>,
    hit: &[f32; 4],
    geometry: MapGeometry,
    tolerance: f64,
) -> bool {
    match (hit[2] >= 0.0, exact) {
        (false, None) => true,
        (true, Some(exact)) => {
            if hit_distance_texels(hit, exact, geometry) <= 1.0 {
                true
            } else {
                let (t_gpu, t_ref) = (1.0 - f64::from(hit[2]), 1.0 - exact.height);
                let (a, b) = (t_gpu.min(t_ref), t_gpu.max(t_ref));
                // One ulp of a height in [0.5, 1): 2^-24.
                let ulp = f64::from(f32::EPSILON) / 2.0;
                // The hit's own point along the ray, from its uv (the exact family
                // places it from t, not from the rounded height): the touch is
                // looked for there too.
                let axis = usize::from(ray.parallax[1].abs() > ray.parallax[0].abs());
                let t_uv = (f64::from(hit[axis]) - ray.uv0[axis]) / ray.parallax[axis];
                let t_uv = if t_uv.is_finite() {
                    t_uv.clamp(0.0, 1.0)
                } else {
                    t_gpu
                };
                // Two ulps of the stored uv, in t: where along the ray the hit can be.
                let uv_ulp = f64::from(hit[axis]).abs().max(1.0) * f64::from(f32::EPSILON);
                let dt = 2.0 * uv_ulp / ray.parallax[axis].abs();
                let near_uv = (-64..=64).map(|k| t_uv + dt * f64::from(k) / 64.0);
                let touch = (-2..=2)
                    .map(|k| a + f64::from(k) * ulp)
                    .chain(near_uv)
                    .map(|t| reference.penetration(ray, t.clamp(0.0, 1.0)))
                    .fold(f64::NEG_INFINITY, f64::max)
                    >= -tolerance;
                let (a, b) = (a.min(t_uv), b.max(t_uv));
                let shallow = (0..=1000)
                    .map(|k| reference.penetration(ray, a + (b - a) * f64::from(k) / 1000.0))
                    .all(|p| p <= tolerance);
                touch && shallow
            }
        }
        _ => false,
    }
}
