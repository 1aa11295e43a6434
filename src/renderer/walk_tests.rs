//! The mesh walk seen through the renderer's own pass: its fallback (the pixels of a walked
//! material on none of the walked triangles take the per-pixel circle model, the hits of
//! the curved trace without a walk) and its overlap step per flat region against the
//! triage's per-triangle test.

use super::test_support::{assert_no_validation_messages, bumps, validated_context};
use super::*;
use crate::mesh::Mesh;
use crate::scene::Geometry;

/// How many pixels' hits (uv and height) of `a` and `b` differ by more than `tolerance`.
fn differ(a: &[HitTexel], b: &[HitTexel], tolerance: f32) -> usize {
    a.iter()
        .zip(b)
        .filter(|(p, q)| (0..3).any(|k| (p[k] - q[k]).abs() > tolerance))
        .count()
}

/// A 96 x 64 renderer of `geometry` with `exact`, a depth of 0.15 and the bumpy field.
fn exact_renderer(ctx: &Arc<Context>, geometry: Geometry) -> Renderer {
    let settings = RenderSettings {
        width: 96,
        height: 64,
        method: Method::Exact,
        params: MethodParams::for_method(Method::Exact),
        scene: Scene {
            geometry,
            depth_scale: 0.15,
            ..Scene::default()
        },
        shadows: ShadowSettings::default(),
    };
    Renderer::new(ctx, &bumps(6.0, 5.0), settings).unwrap()
}

#[test]
fn pixels_off_the_walked_meshes_take_the_circle_model() {
    let ctx = validated_context();
    let mut r = exact_renderer(&ctx, Geometry::Sphere);
    r.set_curved(true).unwrap();
    assert!(r.pass.curved_mesh_triangles() > 0, "the sphere is walked");
    r.render().unwrap();
    let walked = r.read_hits().unwrap();
    // The walk buffer of a cube far from the sphere: no pixel is on its triangles.
    let mut away = Mesh::cube();
    for v in &mut away.vertices {
        v.position[0] += 100.0;
    }
    r.pass.set_curved_meshes(&[&away]).unwrap();
    r.render().unwrap();
    let off = r.read_hits().unwrap();
    // No meshes: the curved trace alone (its circle model everywhere).
    r.pass.set_curved_meshes(&[]).unwrap();
    r.render().unwrap();
    let circle = r.read_hits().unwrap();
    assert_eq!(
        differ(&off, &circle, 1e-6),
        0,
        "off the meshes: the circle model"
    );
    // The walk changes hits where the circle model drifts from the mesh (so the first
    // check can fail: a first trace's flat hit kept off the meshes would differ too).
    let changed = differ(&walked, &circle, 1e-4);
    assert!(changed > 20, "the walk changed {changed} hits");
    drop(r);
    assert_no_validation_messages(ctx);
}

/// The overlap step (each overlapping flat region's relief along a cube face's straight
/// path, clipped and intersected once per region, no solve) gives the hits of the
/// triage's per-triangle test of the same model (the walk buffer without its flat regions
/// sends every pixel the first trace cannot keep there), to f32; and the paths it takes
/// are many and change hits, so that the comparison can fail.
#[test]
fn the_overlap_step_meets_the_per_triangle_model() {
    let ctx = validated_context();
    let mut r = exact_renderer(&ctx, Geometry::Cube);
    r.render().unwrap();
    let flat = r.read_hits().unwrap();
    r.set_curved(true).unwrap();
    assert!(r.pass.curved_mesh_triangles() > 0, "the cube is walked");
    r.render().unwrap();
    let regions = r.read_hits().unwrap();
    let meshes: Vec<Mesh> = r.curved_meshes.clone();
    let meshes: Vec<&Mesh> = meshes.iter().collect();
    r.pass.set_curved_meshes_without_regions(&meshes).unwrap();
    r.render().unwrap();
    let per_triangle = r.read_hits().unwrap();
    // Where the overlapping faces' relief is met before the face's own (and where paths
    // leave a face), the curved hits are not the flat trace's.
    let curved = differ(&per_triangle, &flat, 1e-3);
    assert!(curved > 40, "the walk changed {curved} hits");
    let apart = differ(&regions, &per_triangle, 1e-3);
    assert!(
        apart <= 2,
        "{apart} hits of the overlap step differ from the per-triangle test's ({curved} \
         curved hits)"
    );
    drop(r);
    assert_no_validation_messages(ctx);
}
