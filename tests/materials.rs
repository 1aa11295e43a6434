//! The material table of `DisplacementPass`: one record for several displaced materials
//! (each its own map, depth scale and method) and flat geometry, under validation (core +
//! synchronization: zero messages from context creation to device destruction, no
//! allocation left after `destroy`).
//!
//! The frame's G-buffer is dispmap's own rasterised plane, read back and split into
//! regions: each region's pixels get a material in the frame's material field and the
//! parallax vector of that material's depth scale, one region is flat (field 0). Each material's
//! hits and colour must be bit-identical to a single-material pass's over the same
//! G-buffer with only that material's pixels displaced (the others flat), and the flat
//! pixels keep the host's colour, a `NOT_DISPLACED_HEIGHT` hit and the G-buffer's own
//! depth as their corrected depth.

mod common;

use ash::vk;
use common::host::{GBufferTexels, RayHost};
use common::{asset_map, validated_context};
use dispmap::Context;
use dispmap::embed::{DisplacementPass, MaterialSettings, NOT_DISPLACED_HEIGHT, PassSettings};
use dispmap::gpu::commands::read_image;
use dispmap::gpu::sync::Access;
use dispmap::heightfield::{Addressing, Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::gbuffer::frame;
use dispmap::scene::{Camera, Scene};
use std::sync::Arc;

const EXTENT: vk::Extent2D = vk::Extent2D {
    width: 96,
    height: 64,
};
const SLOTS: usize = 2;
/// The host's colour where nothing is displaced.
const HOST_COLOR: [u8; 4] = [11, 22, 33, 255];
/// The depth scale the plane is rasterised with (each region's P is rescaled).
const RASTER_DEPTH: f32 = 0.1;

/// One displaced material of the test frame.
struct Mat {
    field: HeightField,
    settings: MaterialSettings,
}

fn materials() -> Vec<Mat> {
    let params = |steps| MethodParams {
        steps,
        ..MethodParams::default()
    };
    let m = |name: &str, conv, method, steps, depth_scale| Mat {
        field: asset_map(name, conv),
        settings: MaterialSettings {
            method,
            params: params(steps),
            depth_scale,
            addressing: Addressing::Repeat,
        },
    };
    vec![
        m(
            "rocks_depth.jpg",
            Convention::Depth,
            Method::Exact,
            32,
            0.08,
        ),
        m(
            "bricks_depth.jpg",
            Convention::Depth,
            Method::Relief,
            24,
            0.05,
        ),
        m(
            "mountains_height16.png",
            Convention::Height,
            Method::Dig,
            32,
            0.12,
        ),
    ]
}

/// The region of pixel (x, y): a material index or `None` (flat). Material 2's region
/// starts at x = 66, inside DIG's 4-pixel blocks, so some of its blocks straddle
/// material 1's pixels; the flat region cuts some of them from below.
fn region(x: u32, y: u32) -> Option<usize> {
    match (x, y) {
        (0..30, _) => Some(0),
        (30..66, _) => Some(1),
        (_, 0..42) => Some(2),
        _ => None,
    }
}

/// The rasterised G-buffer with the materials of `assign` (pixel -> table index or flat)
/// written into the frame's material field and each region's P scaled to its material's depth scale.
fn gbuffer(
    base: &GBufferTexels,
    depths: &[f32],
    assign: impl Fn(u32, u32) -> Option<u32>,
) -> GBufferTexels {
    let mut g = base.clone();
    for y in 0..EXTENT.height {
        for x in 0..EXTENT.width {
            let i = (y * EXTENT.width + x) as usize;
            let region = region(x, y);
            if let Some(r) = region {
                let k = depths[r] / RASTER_DEPTH;
                g.ray[i][2] *= k;
                g.ray[i][3] *= k;
            }
            // The frame's material field (the handedness and the rest kept).
            g.frame[i] = frame::with_material(g.frame[i], assign(x, y).map_or(0, |m| m + 1));
        }
    }
    g
}

fn camera() -> (Scene, (glam::Mat4, glam::Vec3)) {
    let scene = Scene {
        depth_scale: RASTER_DEPTH,
        camera: Camera {
            elevation_deg: 25.0,
            ..Camera::default()
        },
        ..Scene::default()
    };
    let cam = scene.frame_camera(EXTENT.width, EXTENT.height);
    (scene, (cam.view_proj, cam.eye))
}

/// The test's materials, their depth scales, the camera, the host and its rasterised
/// G-buffer.
fn setup(
    ctx: &Arc<Context>,
) -> (
    Vec<Mat>,
    Vec<f32>,
    (glam::Mat4, glam::Vec3),
    RayHost,
    GBufferTexels,
) {
    let mats = materials();
    let depths = mats.iter().map(|m| m.settings.depth_scale).collect();
    let (scene, cam) = camera();
    let mut host = RayHost::new(ctx.clone(), EXTENT, SLOTS);
    let camera = scene.frame_camera(EXTENT.width, EXTENT.height);
    host.rasterise(&scene.gbuffer_params(&camera), &camera.pixel_ray_params());
    let base = host.read_gbuffer();
    (mats, depths, cam, host, base)
}

fn pass_settings(s: &MaterialSettings) -> PassSettings {
    PassSettings {
        method: s.method,
        params: s.params,
        depth_scale: s.depth_scale,
        addressing: s.addressing,
        extent: EXTENT,
        frames_in_flight: SLOTS as u32,
    }
}

/// One shaded frame with the corrected depth on: hits, colour and corrected depth.
fn frame(
    host: &mut RayHost,
    pass: &mut DisplacementPass,
    cam: (glam::Mat4, glam::Vec3),
    s: usize,
) -> (Vec<[f32; 4]>, Vec<[u8; 4]>, Vec<f32>) {
    host.submit_shaded(pass, s, cam, HOST_COLOR);
    let hits = host.hits(s);
    let colors = host.colors(s);
    let image = pass.hit_depth(s as u32).expect("depth output on");
    let depth = read_image(
        pass.context().unwrap(),
        host.shot(),
        image,
        Access::COMPUTE_STORAGE_WRITE,
    )
    .unwrap();
    (hits, colors, bytemuck::cast_slice(&depth).to_vec())
}

fn teardown(ctx: Arc<Context>, passes: Vec<DisplacementPass>, host: RayHost) {
    host.destroy();
    for mut pass in passes {
        // SAFETY: every frame recorded with the pass completed (`destroy` waited).
        unsafe { pass.destroy() };
    }
    common::finish(ctx);
}

#[test]
fn three_materials_and_flat_geometry_in_one_record_match_single_material_frames() {
    let ctx = validated_context();
    let (mats, depths, cam, mut host, base) = setup(&ctx);

    // The frame with every material in one pass.
    let mut all = DisplacementPass::new(
        ctx.clone(),
        &mats[0].field,
        pass_settings(&mats[0].settings),
    )
    .unwrap();
    let ids: Vec<_> = std::iter::once(all.primary())
        .chain(
            mats[1..]
                .iter()
                .map(|m| all.add_material(&m.field, m.settings).unwrap()),
        )
        .collect();
    assert_eq!(ids.iter().map(|i| i.index()).collect::<Vec<_>>(), [0, 1, 2]);
    assert_eq!(all.map_count(), 3);
    all.set_depth_output(true).unwrap();
    host.upload_gbuffer(&gbuffer(&base, &depths, |x, y| {
        region(x, y).map(|r| ids[r].index())
    }));
    let (hits, colors, depth) = frame(&mut host, &mut all, cam, 0);

    // Each material alone (index 0 of its own pass) on its own pixels, the others flat.
    let mut passes = vec![all];
    let mut checked = [0usize; 3];
    for (m, mat) in mats.iter().enumerate() {
        let mut one =
            DisplacementPass::new(ctx.clone(), &mat.field, pass_settings(&mat.settings)).unwrap();
        one.set_depth_output(true).unwrap();
        host.upload_gbuffer(&gbuffer(&base, &depths, |x, y| {
            (region(x, y) == Some(m)).then_some(0)
        }));
        let (h1, c1, d1) = frame(&mut host, &mut one, cam, 1);
        for y in 0..EXTENT.height {
            for x in 0..EXTENT.width {
                let i = (y * EXTENT.width + x) as usize;
                if region(x, y) != Some(m) || base.depth[i] <= 0.0 {
                    continue;
                }
                assert_eq!(
                    hits[i].map(f32::to_bits),
                    h1[i].map(f32::to_bits),
                    "material {m}, pixel ({x}, {y}): {:?} vs {:?}",
                    hits[i],
                    h1[i]
                );
                assert_eq!(colors[i], c1[i], "material {m} colour, pixel ({x}, {y})");
                assert_eq!(
                    depth[i].to_bits(),
                    d1[i].to_bits(),
                    "material {m} depth ({x}, {y})"
                );
                checked[m] += 1;
            }
        }
        passes.push(one);
    }
    for (m, &n) in checked.iter().enumerate() {
        assert!(n > 300, "material {m}: only {n} pixels compared");
    }
    // Material 2 is DIG: count its 4x4 blocks that straddle another material or flat
    // pixels (they fall back to the unconstrained search, as at a surface boundary).
    let straddling = (0..EXTENT.height / 4)
        .flat_map(|by| (0..EXTENT.width / 4).map(move |bx| (bx, by)))
        .filter(|&(bx, by)| {
            let regions: Vec<_> = (0..4)
                .flat_map(|dy| (0..4).map(move |dx| region(bx * 4 + dx, by * 4 + dy)))
                .collect();
            regions.contains(&Some(2)) && regions.iter().any(|r| *r != Some(2))
        })
        .count();
    eprintln!("DIG blocks straddling material 2's boundary: {straddling}");
    assert!(straddling > 0, "the layout must exercise straddling blocks");

    // Flat pixels: the host's colour, not traced, the G-buffer's own depth.
    let mut flat = 0;
    for y in 0..EXTENT.height {
        for x in 0..EXTENT.width {
            let i = (y * EXTENT.width + x) as usize;
            if region(x, y).is_some() || base.depth[i] <= 0.0 {
                continue;
            }
            assert_eq!(colors[i], HOST_COLOR, "flat pixel ({x}, {y}) colour");
            assert_eq!(
                hits[i],
                [0.0, 0.0, NOT_DISPLACED_HEIGHT, 0.0],
                "flat ({x}, {y})"
            );
            assert_eq!(
                depth[i].to_bits(),
                base.depth[i].to_bits(),
                "flat ({x}, {y}) depth"
            );
            flat += 1;
        }
    }
    assert!(flat > 200, "only {flat} flat pixels");
    teardown(ctx, passes, host);
}

/// Materials added, given new settings, given another material's map (shared: the map
/// count drops), removed and re-added (the free index reused, the old handle refused),
/// each followed by a frame in flight, under validation: the frames in between are
/// checked by the validation layer only; the last state (material 2 removed) pixel by
/// pixel: its pixels are left to the host.
#[test]
fn materials_added_replaced_and_removed_with_frames_in_flight() {
    let ctx = validated_context();
    let (mats, depths, cam, mut host, base) = setup(&ctx);
    host.upload_gbuffer(&gbuffer(&base, &depths, |x, y| {
        region(x, y).map(|r| r as u32)
    }));
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &mats[0].field,
        pass_settings(&mats[0].settings),
    )
    .unwrap();
    pass.set_shadows(dispmap::embed::ShadowSettings {
        mode: dispmap::embed::ShadowMode::Hard,
        ..Default::default()
    })
    .unwrap();
    let mut frame_no = 0;
    let mut run = |host: &mut RayHost, pass: &mut DisplacementPass| {
        host.submit_shaded(pass, frame_no % SLOTS, cam, HOST_COLOR);
        frame_no += 1;
    };
    run(&mut host, &mut pass);
    let b = pass.add_material(&mats[1].field, mats[1].settings).unwrap();
    run(&mut host, &mut pass);
    let c = pass.add_material(&mats[2].field, mats[2].settings).unwrap();
    run(&mut host, &mut pass);
    // The same map as material 0: shared, no new texture.
    let shared = MaterialSettings {
        method: Method::Pyramid,
        ..mats[0].settings
    };
    pass.set_material_settings(
        c,
        MaterialSettings {
            method: Method::Cone,
            ..mats[2].settings
        },
    )
    .unwrap();
    run(&mut host, &mut pass);
    pass.set_material_height_map(b, &mats[0].field).unwrap();
    pass.set_material_settings(b, shared).unwrap();
    assert_eq!(pass.map_count(), 2, "b now shares material 0's map");
    run(&mut host, &mut pass);
    // Two materials naming one albedo share its image: c makes it and stages its upload,
    // b shares both; c is removed before any record, and the record still fills the
    // image b samples (validation reports a read of an image never filled, and a
    // second copy into it).
    let albedo =
        dispmap::material::RgbaMap::new(4, 4, [200, 40, 40, 255].repeat(16), "albedo").unwrap();
    let images = dispmap::material::MaterialImages {
        albedo: Some(albedo),
        normal_map: None,
    };
    pass.set_material_maps(c, &images).unwrap();
    pass.set_material_maps(b, &images).unwrap();
    pass.remove_material(c).unwrap();
    assert!(
        pass.set_material_settings(c, mats[2].settings).is_err(),
        "a removed handle"
    );
    run(&mut host, &mut pass);
    let c2 = pass.add_material(&mats[2].field, mats[2].settings).unwrap();
    assert_eq!(c2.index(), c.index(), "the free index is reused");
    assert!(
        pass.remove_material(c).is_err(),
        "the old handle stays refused"
    );
    run(&mut host, &mut pass);
    pass.remove_material(c2).unwrap();
    run(&mut host, &mut pass);
    // Material 2's pixels are no longer displaced.
    let s = (frame_no - 1) % SLOTS;
    let hits = host.hits(s);
    let colors = host.colors(s);
    for y in 0..EXTENT.height {
        for x in 0..EXTENT.width {
            let i = (y * EXTENT.width + x) as usize;
            if region(x, y) == Some(2) && base.depth[i] > 0.0 {
                assert_eq!(hits[i][2], NOT_DISPLACED_HEIGHT, "({x}, {y})");
                assert_eq!(colors[i], HOST_COLOR, "({x}, {y})");
            }
        }
    }
    host.wait_all();
    teardown(ctx, vec![pass], host);
}
