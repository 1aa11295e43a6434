//! The `shade` pass against an independent CPU shading of the reference's hits, written
//! from docs/design.md ("Shading") and not from the shader: the normal from central
//! differences of the bilinear height field, Lambert and Blinn-Phong, the stone albedo
//! darkened with depth, the sRGB encoding; without self-shadowing and with hard shadows
//! (the reference's exact visibility, `Reference::occluded`). Every PSNR of the method
//! tests compares two images from the same `shade` pass (hit differences only): this
//! test is what checks the lighting itself. Under validation.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::shadow::{ShadowMode, ShadowSettings};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Scene};
use dispmap_cli::measure::Measure as _;
use dispmap_cli::reference::Reference;
use glam::DVec3;

/// Frame size: small (every pixel is shaded on the CPU too).
const SIZE: [u32; 2] = [160, 90];

/// The tolerance, in 8-bit levels of the sRGB colour: (largest difference of one channel
/// on any pixel, mean absolute difference over every channel of every compared pixel).
/// The GPU samples the height for the normal with the hardware filter and computes in
/// f32; the CPU in f64 with the exact bilinear height.
///
/// A 16-bit map (mountains): measured max 1 level, mean 0.0003 (f32 rounding at a level's
/// edge), at 30 and 5 degrees, with and without hard shadows; allowed 2 and 0.01.
const TOLERANCE_16_BIT: (u8, f64) = (2, 0.01);
/// An 8-bit map (rocks): lavapipe filters 8-bit maps in 8-bit fixed point
/// (docs/methods.md), so each of the four height samples is off by up to 1/255 of the
/// depth and the central differences' slope by up to `depth_scale W / 255` = 0.4 (a
/// 1024 map at depth 0.1): normals tilt by degrees, and the specular highlight
/// (exponent 48) moves. Measured max 37 and 33 levels, mean 3.09 and 2.62 (30 degrees
/// unshadowed, 5 degrees with hard shadows); allowed 48 and 4. A normal in the wrong
/// space or a wrong light term moves the mean by tens of levels.
const TOLERANCE_8_BIT: (u8, f64) = (48, 4.0);

/// sRGB encoding of a linear value (docs/design.md), to 8 bits.
fn srgb8(c: f64) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let e = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (e * 255.0).round() as u8
}

/// The CPU shading of one hit (docs/design.md, "Shading"), on the tiled plane (`T = +x`,
/// `B = +z`, `N = +y`): `view` the pixel's unit view direction, `light` the unit
/// direction towards the light, `vis` the light's visibility.
#[allow(clippy::too_many_arguments)]
fn shade(
    reference: &Reference,
    size: [u32; 2],
    uv: [f64; 2],
    h: f64,
    depth_scale: f64,
    view: DVec3,
    light: DVec3,
    intensity: f64,
    vis: f64,
) -> [u8; 3] {
    let (w, hh) = (f64::from(size[0]), f64::from(size[1]));
    let height = |du: f64, dv: f64| reference.height([uv[0] + du, uv[1] + dv]);
    let g = [
        (height(1.0 / w, 0.0) - height(-1.0 / w, 0.0)) * w / 2.0,
        (height(0.0, 1.0 / hh) - height(0.0, -1.0 / hh)) * hh / 2.0,
    ];
    let n_ts = DVec3::new(-depth_scale * g[0], -depth_scale * g[1], 1.0).normalize();
    let (t, b, n) = (DVec3::X, DVec3::Z, DVec3::Y);
    let normal = (n_ts.x * t + n_ts.y * b + n_ts.z * n).normalize();
    let half = (light - view).normalize();
    let diffuse = normal.dot(light).max(0.0);
    let spec = if diffuse > 0.0 {
        0.25 * normal.dot(half).max(0.0).powf(48.0)
    } else {
        0.0
    };
    let albedo = DVec3::new(0.62, 0.55, 0.47) * (0.35 + 0.65 * h);
    let c = albedo * (0.18 + intensity * vis * diffuse) + DVec3::splat(spec * intensity * vis);
    [srgb8(c.x), srgb8(c.y), srgb8(c.z)]
}

/// The differences of one frame: (compared pixels, mean level difference, largest).
fn compare(field: &HeightField, elevation: f32, shadows: ShadowMode) -> (usize, f64, u8) {
    let ctx = validated_context();
    let settings = RenderSettings {
        width: SIZE[0],
        height: SIZE[1],
        method: Method::Exact,
        params: MethodParams::for_method(Method::Exact),
        scene: Scene {
            geometry: Geometry::TiledPlane,
            camera: Camera {
                elevation_deg: elevation,
                ..Camera::default()
            },
            ..Scene::default()
        },
        shadows: ShadowSettings {
            mode: shadows,
            ..ShadowSettings::default()
        },
    };
    let scene = settings.scene;
    let reference = Reference::new(field, scene.addressing());
    let result = {
        let mut renderer = Renderer::new(&ctx, field, settings).unwrap();
        let frame = renderer.reference(&reference).unwrap();
        let camera = scene.frame_camera(SIZE[0], SIZE[1]);
        let light = scene.light_direction().as_dvec3().normalize();
        // The plane's tangent frame (T, B, N) = (+x, +z, +y): the light in it.
        let light_ts = [light.x, light.z, light.y];
        let depth_scale = f64::from(scene.depth_scale);
        let intensity = f64::from(scene.light.intensity);
        let (mut compared, mut sum, mut worst) = (0usize, 0u64, 0u8);
        for (i, (hit, ray)) in frame.hits.iter().zip(&frame.rays).enumerate() {
            let (Some(hit), Some(_)) = (hit, ray) else {
                continue;
            };
            let (x, y) = (i as u32 % SIZE[0], i as u32 / SIZE[0]);
            let view = camera.rays.direction(x, y).normalize();
            let vis = match shadows {
                ShadowMode::Off => 1.0,
                ShadowMode::Hard => {
                    let occluded = reference.occluded(hit.uv, hit.height, light_ts, depth_scale);
                    if occluded { 0.0 } else { 1.0 }
                }
                ShadowMode::Soft => unreachable!("soft shadows are an estimate, not checked here"),
            };
            let cpu = shade(
                &reference,
                [field.width(), field.height()],
                hit.uv,
                hit.height,
                depth_scale,
                view,
                light,
                intensity,
                vis,
            );
            let gpu = &frame.color[4 * i..4 * i + 3];
            compared += 1;
            for (a, b) in cpu.iter().zip(gpu) {
                let d = a.abs_diff(*b);
                sum += u64::from(d);
                worst = worst.max(d);
            }
        }
        (compared, sum as f64 / (3 * compared.max(1)) as f64, worst)
    };
    finish(ctx);
    result
}

#[test]
fn shade_matches_a_cpu_shading_of_the_reference_hits() {
    let rocks = asset_map("rocks_depth.jpg", Convention::Depth);
    let mountains = asset_map("mountains_height16.png", Convention::Height);
    let mut failures = Vec::new();
    for (field, elevation, shadows, (max_levels, mean_levels)) in [
        (&rocks, 30.0, ShadowMode::Off, TOLERANCE_8_BIT),
        (&rocks, 5.0, ShadowMode::Hard, TOLERANCE_8_BIT),
        (&mountains, 30.0, ShadowMode::Hard, TOLERANCE_16_BIT),
        (&mountains, 5.0, ShadowMode::Off, TOLERANCE_16_BIT),
    ] {
        let (compared, mean, worst) = compare(field, elevation, shadows);
        eprintln!(
            "{} {elevation} deg, shadows {shadows:?}: {compared} pixels, mean {mean:.4} levels, max {worst}",
            field.label()
        );
        assert!(
            compared > (SIZE[0] * SIZE[1] / 3) as usize,
            "{compared} pixels"
        );
        if mean > mean_levels || worst > max_levels {
            failures.push(format!(
                "{} {elevation} deg {shadows:?}: mean {mean:.4} (bound {mean_levels}), max {worst} (bound {max_levels})",
                field.label()
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
