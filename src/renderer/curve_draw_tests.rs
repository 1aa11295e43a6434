//! Which of the renderer's G-buffer draws compute the curve output: only those of a
//! material traced curved (the pipeline with `CURVE_COMPUTED`); the others write 0.

use super::test_support::{assert_no_validation_messages, bumps, validated_context};
use super::*;
use crate::embed::MaterialSettings;
use crate::gpu::commands::read_image;
use crate::heightfield::Addressing;
use crate::material::MaterialImages;
use crate::scene::{Geometry, Placement};
use glam::Vec3;

/// A relief sphere (traced curved), a secant sphere (its method traces tangent planes)
/// and a flat torus in one frame traced curved: the curve image is not zero on most of the
/// relief sphere's pixels (a sphere bends everywhere) and exactly zero on every pixel of
/// the other two (before the draws chose their pipeline, the secant sphere's pixels held
/// their curvature too).
#[test]
fn only_the_draws_of_curved_materials_compute_the_curve() {
    let ctx = validated_context();
    let field = bumps(4.0, 3.0);
    let images = MaterialImages::default();
    let material = |method: Method| ObjectMaterial {
        field: &field,
        settings: MaterialSettings {
            method,
            params: MethodParams::for_method(method),
            depth_scale: 0.05,
            addressing: Addressing::Repeat,
        },
        images: &images,
    };
    let at = |x: f32, z: f32| Placement {
        position: Vec3::new(x, 0.0, z),
        scale: 0.5,
        ..Placement::default()
    };
    let objects = [
        SceneObject {
            geometry: Geometry::Sphere,
            placement: at(-0.6, 0.0),
            mesh: None,
            material: Some(material(Method::Relief)),
        },
        SceneObject {
            geometry: Geometry::Sphere,
            placement: at(0.6, 0.0),
            mesh: None,
            material: Some(material(Method::Secant)),
        },
        SceneObject {
            geometry: Geometry::Torus,
            placement: at(0.0, 0.7),
            mesh: None,
            material: None,
        },
    ];
    let settings = RenderSettings {
        width: 96,
        height: 64,
        method: Method::Relief,
        params: MethodParams::for_method(Method::Relief),
        scene: Scene::default(),
        shadows: ShadowSettings::default(),
    };
    let mut r = Renderer::with_objects(&ctx, settings, &objects).unwrap();
    r.set_curved(true).unwrap();
    r.render().unwrap();
    let materials = r.read_materials().unwrap();
    let depth = r.read_macro_depth().unwrap();
    let curve = read_image(
        &r.ctx,
        &r.shot,
        r.gbuffer.curve.as_ref().expect("the curve image"),
        Access::COMPUTE_SAMPLED,
    )
    .unwrap();
    // R16G16_SFLOAT: a pixel's curve is zero when both halves are +0 or -0.
    let zero = |i: usize| {
        curve[4 * i..4 * i + 4]
            .chunks_exact(2)
            .all(|h| u16::from_le_bytes([h[0], h[1]]) & 0x7fff == 0)
    };
    let (mut relief, mut relief_bent, mut others, mut others_bent) = (0, 0, 0, 0);
    for (i, (m, &d)) in materials.iter().zip(&depth).enumerate() {
        match m {
            Some(0) => {
                relief += 1;
                relief_bent += usize::from(!zero(i));
            }
            _ if d > 0.0 => {
                others += 1;
                others_bent += usize::from(!zero(i));
            }
            _ => {}
        }
    }
    assert!(relief > 100 && others > 100, "{relief} and {others} pixels");
    assert!(
        relief_bent * 2 > relief,
        "{relief_bent} of the relief sphere's {relief} pixels have a curve"
    );
    assert_eq!(
        others_bent, 0,
        "the secant sphere's and the torus's pixels ({others}) have no curve"
    );
    drop(r);
    assert_no_validation_messages(ctx);
}
