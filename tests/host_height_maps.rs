//! Height maps the host owns on the GPU (`DisplacementPass::add_host_material`), under
//! validation (core + synchronization: zero messages, no allocation left):
//!
//! * a `BC4_UNORM` image with a full mip chain, its blocks encoded here from known
//!   texels; the alpha channel of an `R8G8B8A8_UNORM` normal map with mips; an
//!   `R16_UNORM` image: each host map's frame (hits and shaded colour, `exact` and `cone`)
//!   is bit-identical to the same material given as texels decoded the same way, and
//!   `exact`'s hits agree with the CPU reference traced on those texels (0 artifacts);
//! * the preparation (pyramids, cone maps) recorded by the host into its own command
//!   buffer before the first frame: that frame records and times none of it.
//!
//! lavapipe decodes BC4 with llvmpipe's JIT (`lp_build_fetch_rgtc_rgba_aos` ->
//! `s3tc_dxt5_alpha_channel` / `lp_build_lerpdxta`, 8-bit results), not with the
//! `(a0 (8 - c) + a1 (c - 1)) / 7` of Mesa's C fetch (`texcompress_rgtc_tmp.h`):
//! [`bc4_decode`] is that arithmetic, and the test checks it against the GPU through
//! the cell pyramid (its level 0 is the maximum of 4 decoded texels). On another driver
//! the BC4 map's comparisons are skipped (a GPU decodes BC4 at its own precision).

mod common;

use ash::vk;
use common::host::{GBufferTexels, RayHost};
use common::{finish, unexplained, validated_context};
use dispmap::Context;
use dispmap::embed::{
    DisplacementPass, HeightChannel, HostHeightMap, MaterialSettings, PassName, PassSettings,
    Timestamps,
};
use dispmap::gpu::commands::staging_buffer;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Image, OneShot};
use dispmap::heightfield::{Addressing, HeightField, Texels};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::gbuffer::frame;
use dispmap::passes::pyramid::{PyramidKind, cpu_build};
use dispmap::scene::{Camera, Scene};
use dispmap_cli::metrics::{self, MapGeometry};
use dispmap_cli::reference::Reference;

const EXTENT: vk::Extent2D = vk::Extent2D {
    width: 96,
    height: 64,
};
const SLOTS: usize = 2;
const HOST_COLOR: [u8; 4] = [11, 22, 33, 255];
const DEPTH_SCALE: f32 = 0.08;
/// A float-precision tangency, in heights (as tests/methods.rs).
const TANGENCY: f64 = 1e-6;

/// llvmpipe's BC4 (RGTC1 unorm) interpolation of code `c` between endpoints `a0`, `a1`
/// (`lp_build_lerpdxta`): 16-bit integer weights `255 * 64 / 7` or `255 * 64 / 5` times
/// `c - 1`, shifted by 6; the endpoint difference times the weight, its 16-bit two's
/// complement shifted right by 8 (logically), added to `a0` modulo 256. Codes 0 and 1
/// are the endpoints; with `a0 <= a1`, 6 is 0 and 7 is 255.
fn bc4_decode(a0: u8, a1: u8, c: u8) -> u8 {
    let eight = a0 > a1;
    match c {
        0 => a0,
        1 => a1,
        6 if !eight => 0,
        7 if !eight => 255,
        _ => {
            let w: i32 = if eight { 255 * 64 / 7 } else { 255 * 64 / 5 };
            let weight = ((w * i32::from(c - 1)) as u16 >> 6) as i32;
            let product = ((i32::from(a1) - i32::from(a0)) * weight) as u16;
            a0.wrapping_add((product >> 8) as u8)
        }
    }
}

/// Mesa's C fetch of the same code (`texcompress_rgtc_tmp.h`), for the comparison.
fn bc4_decode_c(a0: u8, a1: u8, c: u8) -> u8 {
    let (a0i, a1i, ci) = (u32::from(a0), u32::from(a1), u32::from(c));
    match c {
        0 => a0,
        1 => a1,
        _ if a0 > a1 => ((a0i * (8 - ci) + a1i * (ci - 1)) / 7) as u8,
        2..=5 => ((a0i * (6 - ci) + a1i * (ci - 1)) / 5) as u8,
        6 => 0,
        _ => 255,
    }
}

/// A BC4 encoding of `w x h` texels (rows from row 0) and its decoding (`bc4_decode`):
/// per 4x4 block the endpoints are the block's maximum and minimum (8-value mode) and
/// each texel takes the nearest decoded code. Blocks past the edge repeat the edge.
fn bc4_encode(texels: &[u8], w: u32, h: u32) -> (Vec<u8>, Vec<u8>) {
    let (bw, bh) = (w.div_ceil(4), h.div_ceil(4));
    let mut blocks = Vec::with_capacity((bw * bh * 8) as usize);
    let mut decoded = vec![0u8; (w * h) as usize];
    for by in 0..bh {
        for bx in 0..bw {
            let at = |i: u32, j: u32| {
                let (x, y) = ((bx * 4 + i).min(w - 1), (by * 4 + j).min(h - 1));
                texels[(y * w + x) as usize]
            };
            let values: Vec<u8> = (0..16).map(|k| at(k % 4, k / 4)).collect();
            let (a0, a1) = (
                values.iter().copied().max().unwrap(),
                values.iter().copied().min().unwrap(),
            );
            let palette: Vec<u8> = (0..8).map(|c| bc4_decode(a0, a1, c)).collect();
            let mut bits = 0u64;
            for (k, &v) in values.iter().enumerate() {
                let code = if a0 == a1 {
                    0
                } else {
                    (0..8u8)
                        .min_by_key(|&c| (i32::from(palette[c as usize]) - i32::from(v)).abs())
                        .unwrap()
                };
                bits |= u64::from(code) << (3 * k);
                let (x, y) = (bx * 4 + k as u32 % 4, by * 4 + k as u32 / 4);
                if x < w && y < h {
                    decoded[(y * w + x) as usize] = palette[code as usize];
                }
            }
            blocks.push(a0);
            blocks.push(a1);
            blocks.extend_from_slice(&bits.to_le_bytes()[..6]);
        }
    }
    (blocks, decoded)
}

/// Mesa's C decode of `blocks` (the comparison only).
fn bc4_decode_blocks_c(blocks: &[u8], w: u32, h: u32) -> Vec<u8> {
    let bw = w.div_ceil(4);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let b = &blocks[((y / 4 * bw + x / 4) * 8) as usize..][..8];
            let mut bits = [0u8; 8];
            bits[..6].copy_from_slice(&b[2..8]);
            let k = (y % 4) * 4 + x % 4;
            let code = ((u64::from_le_bytes(bits) >> (3 * k)) & 7) as u8;
            bc4_decode_c(b[0], b[1], code)
        })
        .collect()
}

/// The known texels: ridges, a crater and steps (8 bits), `w x h`.
fn texels8(w: u32, h: u32, seed: f32) -> Vec<u8> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            let tau = std::f32::consts::TAU;
            let ridges = 0.5 + 0.3 * (tau * (3.0 * u + seed)).sin() * (tau * 2.0 * v).cos();
            let d = ((u - 0.6).powi(2) + (v - 0.4).powi(2)).sqrt();
            let crater = if d < 0.15 {
                -0.35 * (1.0 - d / 0.15)
            } else {
                0.0
            };
            let steps = 0.1 * ((4.0 * u).floor() / 4.0);
            ((ridges + crater + steps).clamp(0.0, 1.0) * 255.0).round() as u8
        })
        .collect()
}

/// The 2x2 box mean of a `w x h` 8-bit level (odd sizes keep the last texel).
fn downsample(texels: &[u8], w: u32, h: u32) -> (Vec<u8>, u32, u32) {
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let at = |x: u32, y: u32| u32::from(texels[(y.min(h - 1) * w + x.min(w - 1)) as usize]);
    let level = (0..nh)
        .flat_map(|y| (0..nw).map(move |x| (x, y)))
        .map(|(x, y)| {
            let s = at(2 * x, 2 * y)
                + at(2 * x + 1, 2 * y)
                + at(2 * x, 2 * y + 1)
                + at(2 * x + 1, 2 * y + 1);
            ((s + 2) / 4) as u8
        })
        .collect();
    (level, nw, nh)
}

/// A host image of `format` with `levels` (bytes of each level, tightly packed), created,
/// filled and left in `SHADER_READ_ONLY_OPTIMAL` visible to compute-shader sampled reads
/// (the host's part of the contract), the way an engine streams its textures.
fn host_image(
    ctx: &Context,
    shot: &OneShot,
    name: &str,
    format: vk::Format,
    extent: vk::Extent2D,
    levels: &[Vec<u8>],
) -> Image {
    let image = Image::new(
        ctx,
        name,
        format,
        extent,
        levels.len() as u32,
        vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
    )
    .unwrap();
    fill(ctx, shot, &image, Access::UNDEFINED, levels);
    image
}

/// Copies `levels` into `image` (last accessed as `before`, e.g. sampled by frames that
/// have completed) and leaves it in `SHADER_READ_ONLY_OPTIMAL` visible to compute-shader
/// sampled reads.
fn fill(ctx: &Context, shot: &OneShot, image: &Image, before: Access, levels: &[Vec<u8>]) {
    let (name, extent) = (image.name(), image.extent);
    let bytes: Vec<u8> = levels.concat();
    let mut staging = staging_buffer(ctx, &format!("{name}.staging"), &bytes).unwrap();
    let mut offset = 0u64;
    let regions: Vec<vk::BufferImageCopy> = levels
        .iter()
        .enumerate()
        .map(|(l, data)| {
            let region = vk::BufferImageCopy::default()
                .buffer_offset(offset)
                .image_subresource(vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: l as u32,
                    base_array_layer: 0,
                    layer_count: 1,
                })
                .image_extent(vk::Extent3D {
                    width: (extent.width >> l).max(1),
                    height: (extent.height >> l).max(1),
                    depth: 1,
                });
            offset += data.len() as u64;
            region
        })
        .collect();
    let cmd = shot.begin(ctx).unwrap();
    // SAFETY: `cmd` was begun by `shot.begin` and is submitted and waited for below, while
    // the image and the staging buffer live; the new image has no earlier access; the
    // regions lie in the image's levels and the buffer (one tightly packed level each).
    unsafe {
        sync::transition(ctx, cmd, image, before, Access::TRANSFER_WRITE);
        ctx.device().cmd_copy_buffer_to_image(
            cmd,
            staging.raw,
            image.raw,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &regions,
        );
        sync::transition(
            ctx,
            cmd,
            image,
            Access::TRANSFER_WRITE,
            Access::COMPUTE_SAMPLED,
        );
    }
    shot.submit_and_wait(ctx).unwrap();
    // SAFETY: the copy that read it was waited for.
    unsafe { staging.destroy(ctx) };
}

fn describe(image: &Image, channel: HeightChannel) -> HostHeightMap {
    HostHeightMap {
        image: image.raw,
        format: image.format,
        extent: image.extent,
        mip_levels: image.mip_levels,
        usage: image.usage,
        channel,
    }
}

/// The three host maps and the texel fields they must equal (decoded the same way).
struct Maps {
    images: Vec<Image>,
    hosts: Vec<HostHeightMap>,
    fields: Vec<HeightField>,
}

fn maps(ctx: &Context, shot: &OneShot) -> Maps {
    // BC4 with every mip level, each encoded from the box-filtered texels of the level
    // above.
    let (w, h) = (64u32, 64u32);
    let mut level = texels8(w, h, 0.0);
    let (mut lw, mut lh) = (w, h);
    let mut bc4_levels = Vec::new();
    let mut decoded0 = Vec::new();
    let mut c_mismatch = 0;
    loop {
        let (blocks, decoded) = bc4_encode(&level, lw, lh);
        if bc4_levels.is_empty() {
            decoded0 = decoded.clone();
            let c = bc4_decode_blocks_c(&blocks, lw, lh);
            c_mismatch = c.iter().zip(&decoded).filter(|(a, b)| a != b).count();
        }
        bc4_levels.push(blocks);
        if lw == 1 && lh == 1 {
            break;
        }
        (level, lw, lh) = downsample(&level, lw, lh);
    }
    eprintln!(
        "BC4 level 0: {c_mismatch} of {} texels decode differently with Mesa's C fetch",
        w * h
    );
    let extent = |w, h| vk::Extent2D {
        width: w,
        height: h,
    };
    let bc4 = host_image(
        ctx,
        shot,
        "host.bc4",
        vk::Format::BC4_UNORM_BLOCK,
        extent(w, h),
        &bc4_levels,
    );
    let bc4_field = HeightField::from_texels(w, h, Texels::R8(decoded0), "bc4 decoded").unwrap();

    // The alpha of an RGBA8 normal map (a tilted normal in rgb), with mips.
    let (nw, nh) = (64u32, 32u32);
    let mut alpha = texels8(nw, nh, 0.37);
    let alpha0 = alpha.clone();
    let (mut lw, mut lh) = (nw, nh);
    let mut rgba_levels = Vec::new();
    loop {
        rgba_levels.push(
            alpha
                .iter()
                .flat_map(|&a| [160, 110, 230, a])
                .collect::<Vec<u8>>(),
        );
        if lw == 1 && lh == 1 {
            break;
        }
        (alpha, lw, lh) = downsample(&alpha, lw, lh);
    }
    let rgba = host_image(
        ctx,
        shot,
        "host.normal_map",
        vk::Format::R8G8B8A8_UNORM,
        extent(nw, nh),
        &rgba_levels,
    );
    let alpha_field = HeightField::from_texels(nw, nh, Texels::R8(alpha0), "normal alpha").unwrap();

    // R16, one level, not a power of two.
    let (rw, rh) = (48u32, 40u32);
    let r16: Vec<u16> = (0..rh)
        .flat_map(|y| (0..rw).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (u, v) = (x as f32 / rw as f32, y as f32 / rh as f32);
            let t = 0.5 + 0.25 * (9.0 * u).sin() + 0.2 * (7.0 * v + 3.0 * u).cos();
            (t.clamp(0.0, 1.0) * 65535.0).round() as u16
        })
        .collect();
    let r16_image = host_image(
        ctx,
        shot,
        "host.r16",
        vk::Format::R16_UNORM,
        extent(rw, rh),
        &[bytemuck::cast_slice(&r16).to_vec()],
    );
    let r16_field = HeightField::from_texels(rw, rh, Texels::R16(r16), "r16").unwrap();

    Maps {
        hosts: vec![
            describe(&bc4, HeightChannel::R),
            describe(&rgba, HeightChannel::A),
            describe(&r16_image, HeightChannel::R),
        ],
        images: vec![bc4, rgba, r16_image],
        fields: vec![bc4_field, alpha_field, r16_field],
    }
}

fn settings(method: Method) -> MaterialSettings {
    MaterialSettings {
        method,
        params: MethodParams::for_method(method),
        depth_scale: DEPTH_SCALE,
        addressing: Addressing::Repeat,
    }
}

/// The band of pixel column `x`: map 0, 1 or 2.
fn band(x: u32) -> usize {
    (x * 3 / EXTENT.width) as usize
}

/// The G-buffer with band `b`'s pixels given material `ids[b]`.
fn assign(base: &GBufferTexels, ids: [u32; 3]) -> GBufferTexels {
    let mut g = base.clone();
    for y in 0..EXTENT.height {
        for x in 0..EXTENT.width {
            let i = (y * EXTENT.width + x) as usize;
            if frame::material_plus_one(g.frame[i]) != 0 {
                g.frame[i] = frame::with_material(g.frame[i], ids[band(x)] + 1);
            }
        }
    }
    g
}

/// A host and an `exact` pass whose only material is a small flat map, after the first
/// frame that built that map's preparation (the baseline of the memory measurements).
fn small_pass_after_one_frame(
    ctx: &std::sync::Arc<dispmap::Context>,
) -> (
    RayHost,
    DisplacementPass,
    GBufferTexels,
    (glam::Mat4, glam::Vec3),
) {
    let (scene, cam) = camera();
    let mut host = RayHost::new(ctx.clone(), EXTENT, SLOTS);
    let camera = scene.frame_camera(EXTENT.width, EXTENT.height);
    host.rasterise(&scene.gbuffer_params(&camera), &camera.pixel_ray_params());
    let base = host.read_gbuffer();
    let small = HeightField::from_texels(4, 4, Texels::R8(vec![128; 16]), "small").unwrap();
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &small,
        PassSettings {
            method: Method::Exact,
            params: MethodParams::for_method(Method::Exact),
            depth_scale: DEPTH_SCALE,
            addressing: Addressing::Repeat,
            extent: EXTENT,
            frames_in_flight: SLOTS as u32,
        },
    )
    .unwrap();
    // A first frame builds the small map's preparation.
    host.upload_gbuffer(&assign(&base, [0, 0, 0]));
    host.submit_shaded(&mut pass, 0, cam, HOST_COLOR);
    host.wait_all();
    (host, pass, base, cam)
}

fn camera() -> (Scene, (glam::Mat4, glam::Vec3)) {
    let scene = Scene {
        depth_scale: DEPTH_SCALE,
        camera: Camera {
            elevation_deg: 20.0,
            ..Camera::default()
        },
        ..Scene::default()
    };
    let cam = scene.frame_camera(EXTENT.width, EXTENT.height);
    (scene, (cam.view_proj, cam.eye))
}

/// The pass's passes that prepare maps.
const PREPARATION: [PassName; 3] = [PassName::Upload, PassName::Pyramid, PassName::Cone];

#[test]
fn host_bc4_alpha_and_r16_maps_match_their_decoded_texels() {
    let ctx = validated_context();
    let shot = OneShot::new(&ctx, "test.shot").unwrap();
    let mut maps = maps(&ctx, &shot);
    // The BC4 map's texels are decoded as llvmpipe decodes them: on another driver (a
    // GPU decodes BC4 at its own precision) its band is not compared.
    let llvmpipe = ctx.info().name.contains("llvmpipe");
    if !llvmpipe {
        eprintln!(
            "{}: not llvmpipe, the BC4 map is not compared",
            ctx.info().name
        );
    }
    let checked = |b: usize| b != 0 || llvmpipe;
    let (scene, cam) = camera();
    let mut host = RayHost::new(ctx.clone(), EXTENT, SLOTS);
    let camera = scene.frame_camera(EXTENT.width, EXTENT.height);
    host.rasterise(&scene.gbuffer_params(&camera), &camera.pixel_ray_params());
    let base = host.read_gbuffer();
    let rays = host.read_rays();

    // Materials 0, 2, 4: the texels; 1, 3, 5: the host's images.
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &maps.fields[0],
        PassSettings {
            method: Method::Exact,
            params: MethodParams::for_method(Method::Exact),
            depth_scale: DEPTH_SCALE,
            addressing: Addressing::Repeat,
            extent: EXTENT,
            frames_in_flight: SLOTS as u32,
        },
    )
    .unwrap();
    let mut texel_ids = vec![pass.primary()];
    let mut host_ids = Vec::new();
    for (k, (field, map)) in maps.fields.iter().zip(&maps.hosts).enumerate() {
        if k > 0 {
            texel_ids.push(pass.add_material(field, settings(Method::Exact)).unwrap());
        }
        host_ids.push(
            pass.add_host_material(map, settings(Method::Exact))
                .unwrap(),
        );
    }
    assert_eq!(pass.map_count(), 6);
    // A second material on the same host image and channel shares its map.
    let shared = pass
        .add_host_material(&maps.hosts[0], settings(Method::Exact))
        .unwrap();
    assert_eq!(pass.map_count(), 6);
    pass.remove_material(shared).unwrap();

    for method in [Method::Exact, Method::Cone] {
        for &id in texel_ids.iter().chain(&host_ids) {
            pass.set_material_settings(id, settings(method)).unwrap();
        }
        // The host prepares the maps in its own command buffer before the frames.
        assert!(pass.preparation_pending());
        let cmd = shot.begin(&ctx).unwrap();
        // SAFETY: `cmd` was begun above and is submitted (and waited for) before the
        // next record; the host images are SHADER_READ_ONLY_OPTIMAL, visible to compute
        // sampled reads (`host_image` waited for their fill).
        let prepared = unsafe { pass.record_preparation(cmd, Timestamps::Off) }.unwrap();
        shot.submit_and_wait(&ctx).unwrap();
        // Exact's cell pyramids first, then (the pyramids kept) cone's cone maps.
        let built = match method {
            Method::Exact => PassName::Pyramid,
            _ => PassName::Cone,
        };
        assert!(
            prepared.passes.contains(&built),
            "{method}: {:?}",
            prepared.passes
        );
        assert!(!pass.preparation_pending());

        let mut frames = Vec::new();
        for (s, ids) in [&texel_ids, &host_ids].into_iter().enumerate() {
            let ids = [ids[0].index(), ids[1].index(), ids[2].index()];
            host.upload_gbuffer(&assign(&base, ids));
            let recorded = host.submit_shaded_timed(&mut pass, s, cam, HOST_COLOR);
            assert!(
                !recorded.passes.iter().any(|p| PREPARATION.contains(p)),
                "{method}: the frame prepared again: {:?}",
                recorded.passes
            );
            let hits = host.hits(s);
            let colors = host.colors(s);
            let timed = pass.timings(s as u32).unwrap();
            assert!(
                !timed.iter().any(|(p, _)| PREPARATION.contains(p)),
                "{method}: {timed:?}"
            );
            frames.push((hits, colors));
        }
        let [(texel_hits, texel_colors), (host_hits, host_colors)] = &frames[..] else {
            unreachable!()
        };
        let mut compared = [0usize; 3];
        for y in 0..EXTENT.height {
            for x in 0..EXTENT.width {
                let i = (y * EXTENT.width + x) as usize;
                if !checked(band(x)) {
                    continue;
                }
                assert_eq!(
                    texel_hits[i].map(f32::to_bits),
                    host_hits[i].map(f32::to_bits),
                    "{method}, map {} pixel ({x}, {y})",
                    band(x)
                );
                assert_eq!(
                    texel_colors[i], host_colors[i],
                    "{method} colour ({x}, {y})"
                );
                if rays[i].is_some() {
                    compared[band(x)] += 1;
                }
            }
        }
        assert!(
            (0..3).all(|b| !checked(b) || compared[b] > 500),
            "{compared:?}"
        );

        if method == Method::Exact {
            for (b, field) in maps.fields.iter().enumerate().filter(|(b, _)| checked(*b)) {
                let reference = Reference::new(field, Addressing::Repeat);
                let band_rays: Vec<_> = (0..rays.len())
                    .map(|i| rays[i].filter(|_| band(i as u32 % EXTENT.width) == b))
                    .collect();
                let exact = reference.trace(&band_rays);
                let geometry = MapGeometry {
                    map_width: field.width(),
                    map_height: field.height(),
                    depth_scale: f64::from(DEPTH_SCALE),
                };
                let m = metrics::hit_errors(host_hits, &exact, &band_rays, geometry);
                let artifacts = (m.artifact_fraction * m.compared_pixels as f64).round() as usize;
                let left = unexplained(
                    &reference, &band_rays, &exact, host_hits, geometry, TANGENCY,
                );
                eprintln!(
                    "exact on host map {b}: {} pixels, {artifacts} artifacts, {left} unexplained",
                    m.compared_pixels
                );
                assert_eq!(m.nonfinite_pixels, 0);
                assert!(m.compared_pixels > 500);
                assert_eq!(artifacts, 0, "host map {b}");
            }
            // The GPU's decoding of each host map is the texels': the cell pyramids
            // (level 0: the maximum of a cell's 4 texels, as the shaders sample them)
            // equal the CPU build on the decoded texels, in the texels' own precision
            // (8 or 16 bits: the alpha map's `R8_UNORM` and the R16 map's `R16_UNORM`
            // pyramids hold the texels' codes; the BC4 map's `R32_SFLOAT` one, levels 1
            // and up, the sampled floats, and lavapipe converts an 8-bit unorm `c` as
            // `c * (1 / 255)` in f32, which is one ulp above `c / 255` for some `c`:
            // counted below).
            for (b, field) in maps.fields.iter().enumerate().filter(|(b, _)| checked(*b)) {
                let pyramid = pass
                    .material_pyramid(host_ids[b])
                    .expect("exact's cell pyramid is built");
                let levels = pyramid.read_levels(&ctx, &shot).unwrap();
                let first = pyramid.first_stored_level() as usize;
                assert_eq!(first, usize::from(b == 0), "host map {b}");
                let want = &cpu_build(field, Addressing::Repeat, PyramidKind::Cell)[first..];
                let scale = if b == 2 { 65535.0 } else { 255.0 };
                let quantised = |v: &[f32]| {
                    v.iter()
                        .map(|x| (x * scale).round() as u32)
                        .collect::<Vec<_>>()
                };
                assert_eq!(levels.len(), want.len());
                for (l, (got, want)) in levels.iter().zip(want).enumerate() {
                    assert_eq!(
                        quantised(got),
                        quantised(want),
                        "host map {b} pyramid level {l}"
                    );
                }
                if b == 0 {
                    assert_eq!(pyramid.image.format, vk::Format::R32_SFLOAT);
                    let texels: Vec<f32> = (0..field.height())
                        .flat_map(|j| (0..field.width()).map(move |i| (i, j)))
                        .map(|(i, j)| (field.texel(i, j) * 255.0).round() * (1.0f32 / 255.0))
                        .collect();
                    let as_gpu = HeightField::from_texels(
                        field.width(),
                        field.height(),
                        Texels::R32F(texels),
                        "c * (1 / 255)",
                    )
                    .unwrap();
                    let gpu_way = &cpu_build(&as_gpu, Addressing::Repeat, PyramidKind::Cell)[1..];
                    let same = |a: &[f32], b: &[f32]| {
                        a.iter()
                            .zip(b)
                            .filter(|(x, y)| x.to_bits() == y.to_bits())
                            .count()
                    };
                    eprintln!(
                        "BC4 pyramid level 1: {} of {} values bit-equal to c / 255, {} to c * (1 / 255)",
                        same(&levels[0], &want[0]),
                        want[0].len(),
                        same(&levels[0], &gpu_way[0])
                    );
                }
            }
        }
    }

    host.destroy();
    // SAFETY: `host.destroy()` waited for every frame; the one-shots were waited for.
    unsafe {
        pass.destroy();
        for image in &mut maps.images {
            image.destroy(&ctx);
        }
        let mut shot = shot;
        shot.destroy(&ctx);
    }
    finish(ctx);
}

/// The bytes of every live allocation of the context, by name.
fn allocations(ctx: &Context) -> Vec<(String, u64)> {
    let report = ctx.allocator().lock().unwrap().generate_report();
    report
        .allocations
        .iter()
        .map(|a| (a.name.clone(), a.size))
        .collect()
}

/// A 4096² BC4 map with its full mip chain, prepared by the host in its own command
/// buffer before the first frame that uses it: that frame (96x64) records and times no
/// preparation, and traces the map. Prints (`--nocapture`) the preparation's
/// milliseconds (lavapipe's cell pyramid of the map: about 0.9 s) and what the pass
/// allocated for the map, by allocation: at most 48 MiB (its `R32_SFLOAT` cell pyramid
/// of levels 1 and up, 21.33 MiB; with level 0 it was 85.33 MiB).
#[test]
fn a_4096_bc4_map_prepared_by_the_host_before_its_first_frame() {
    let ctx = validated_context();
    let shot = OneShot::new(&ctx, "test.shot").unwrap();
    let side = 4096u32;
    let started = std::time::Instant::now();
    let mut level = texels8(side, side, 0.2);
    let (mut lw, mut lh) = (side, side);
    let mut levels = Vec::new();
    loop {
        levels.push(bc4_encode(&level, lw, lh).0);
        if lw == 1 && lh == 1 {
            break;
        }
        (level, lw, lh) = downsample(&level, lw, lh);
    }
    let extent = vk::Extent2D {
        width: side,
        height: side,
    };
    let mut image = host_image(
        &ctx,
        &shot,
        "host.bc4",
        vk::Format::BC4_UNORM_BLOCK,
        extent,
        &levels,
    );
    eprintln!(
        "host image: {} levels, {:.2} MiB of blocks, encoded and uploaded in {:.1} s",
        levels.len(),
        levels.iter().map(Vec::len).sum::<usize>() as f64 / 1048576.0,
        started.elapsed().as_secs_f64()
    );
    let (mut host, mut pass, base, cam) = small_pass_after_one_frame(&ctx);
    let before = allocations(&ctx);
    let id = pass
        .add_host_material(&describe(&image, HeightChannel::R), settings(Method::Exact))
        .unwrap();
    assert!(pass.preparation_pending());

    // SAFETY: a timestamp pool of the device, destroyed below after its queries are read.
    let pool = unsafe {
        ctx.device().create_query_pool(
            &vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(dispmap::embed::MAX_QUERIES),
            None,
        )
    }
    .unwrap();
    let cmd = shot.begin(&ctx).unwrap();
    // SAFETY: `cmd` is submitted and waited for before the next record; the host image is
    // SHADER_READ_ONLY_OPTIMAL, visible to compute sampled reads (`host_image`); the pool
    // has MAX_QUERIES queries, used by nothing else.
    let prepared = unsafe {
        pass.record_preparation(
            cmd,
            Timestamps::Host {
                pool,
                first_query: 0,
            },
        )
    }
    .unwrap();
    let started = std::time::Instant::now();
    shot.submit_and_wait(&ctx).unwrap();
    let wall = started.elapsed().as_secs_f64();
    // SAFETY: the queries' command buffer completed (waited above).
    let timed = unsafe { dispmap::embed::read_timestamps(&ctx, &prepared.timestamps) }.unwrap();
    eprintln!("preparation (host command buffer): {timed:?}, submit to idle {wall:.2} s");
    assert!(prepared.passes.contains(&PassName::Pyramid));
    let after = allocations(&ctx);
    let added: Vec<&(String, u64)> = after.iter().filter(|a| !before.contains(a)).collect();
    let total: u64 = added.iter().map(|a| a.1).sum();
    for (name, size) in &added {
        eprintln!("  {name}: {:.2} MiB", *size as f64 / 1048576.0);
    }
    eprintln!(
        "the pass allocated {:.2} MiB for the host's 4096² BC4 map (exact)",
        total as f64 / 1048576.0
    );
    assert!(total <= 48 << 20, "{total} bytes for the host's BC4 map");

    // The first frame with it: no preparation recorded or timed.
    host.upload_gbuffer(&assign(&base, [id.index(); 3]));
    let recorded = host.submit_shaded_timed(&mut pass, 1, cam, HOST_COLOR);
    host.wait(1);
    let frame = pass.timings(1).unwrap();
    eprintln!("first frame with it: {frame:?}");
    assert!(!recorded.passes.iter().any(|p| PREPARATION.contains(p)));
    assert!(!frame.iter().any(|(p, _)| PREPARATION.contains(p)));
    let hits = host.hits(1);
    assert!(hits.iter().any(|h| h[2] >= 0.0), "the map is traced");

    host.destroy();
    // SAFETY: every frame and one-shot completed (waited above).
    unsafe {
        ctx.device().destroy_query_pool(pool, None);
        pass.destroy();
        image.destroy(&ctx);
        let mut shot = shot;
        shot.destroy(&ctx);
    }
    finish(ctx);
}

/// A 4096² 16-bit map the pass owns (`add_material`): the texture and its `exact`
/// preparation (the `R16_UNORM` cell pyramid) resident after the frames that first use it
/// are at most 80 MiB, read from the allocator (32 MiB of texels and 42.67 MiB of
/// pyramid; an `R32_SFLOAT` chain kept beside its `R16_UNORM` copy made 160 MiB).
#[test]
fn a_4096_r16_map_the_pass_owns_holds_at_most_80_mib() {
    let ctx = validated_context();
    let side = 4096u32;
    let texels: Vec<u16> = (0..side * side)
        .map(|k| {
            let (x, y) = (
                (k % side) as f32 / side as f32,
                (k / side) as f32 / side as f32,
            );
            let tau = std::f32::consts::TAU;
            let v = 0.5 + 0.3 * (tau * 5.0 * x).sin() * (tau * 3.0 * y).cos();
            (v * 65535.0).round() as u16
        })
        .collect();
    let field = HeightField::from_texels(side, side, Texels::R16(texels), "r16 4096").unwrap();
    let (mut host, mut pass, base, cam) = small_pass_after_one_frame(&ctx);
    let before = allocations(&ctx);
    let id = pass.add_material(&field, settings(Method::Exact)).unwrap();
    // Its first frame uploads and builds; the next ones (every slot) find it resident.
    let mut last = 0;
    for frame in 0..=SLOTS {
        let slot = frame % SLOTS;
        last = slot;
        host.upload_gbuffer(&assign(&base, [id.index(); 3]));
        host.submit_shaded(&mut pass, slot, cam, HOST_COLOR);
        host.wait(slot);
    }
    let hits = host.hits(last);
    assert!(hits.iter().any(|h| h[2] >= 0.0), "the map is traced");
    let after = allocations(&ctx);
    let added: Vec<&(String, u64)> = after.iter().filter(|a| !before.contains(a)).collect();
    let total: u64 = added.iter().map(|a| a.1).sum();
    for (name, size) in &added {
        eprintln!("  {name}: {:.2} MiB", *size as f64 / 1048576.0);
    }
    eprintln!(
        "resident for the owned 4096² R16 map (exact): {:.2} MiB",
        total as f64 / 1048576.0
    );
    let pyramid = pass.material_pyramid(id).expect("exact's cell pyramid");
    assert_eq!(pyramid.image.format, vk::Format::R16_UNORM);
    assert!(total <= 80 << 20, "{total} bytes for the owned R16 map");

    host.destroy();
    // SAFETY: every frame completed (waited above).
    unsafe { pass.destroy() };
    drop(pass);
    finish(ctx);
}

/// The host rewrites its image's contents and says so (`host_height_map_changed`): the
/// next preparation rebuilds the map's pyramid, and frames match the new texels; the old
/// preparation is retired (the map count does not grow). Then another image for the
/// material (`set_material_host_height_map`), built by the next record: frames match its
/// texels. Descriptions dispmap can check
/// are refused naming the host height map; a preparation cannot use the pass's own
/// timestamp pool.
#[test]
fn host_map_changed_in_place_and_bad_descriptions_refused() {
    let ctx = validated_context();
    let shot = OneShot::new(&ctx, "test.shot").unwrap();
    let (w, h) = (40u32, 36u32);
    let texels = |seed: f32| -> Vec<u16> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
                let t = 0.5 + 0.3 * (6.0 * u + seed).sin() * (5.0 * v - seed).cos();
                (t.clamp(0.0, 1.0) * 65535.0).round() as u16
            })
            .collect()
    };
    let extent = vk::Extent2D {
        width: w,
        height: h,
    };
    let bytes = |t: &[u16]| vec![bytemuck::cast_slice(t).to_vec()];
    let first = texels(0.0);
    let mut image = host_image(
        &ctx,
        &shot,
        "host.r16",
        vk::Format::R16_UNORM,
        extent,
        &bytes(&first),
    );
    let field = |t: Vec<u16>| HeightField::from_texels(w, h, Texels::R16(t), "r16").unwrap();
    let (scene, cam) = camera();
    let mut host = RayHost::new(ctx.clone(), EXTENT, SLOTS);
    let camera = scene.frame_camera(EXTENT.width, EXTENT.height);
    host.rasterise(&scene.gbuffer_params(&camera), &camera.pixel_ray_params());
    let base = host.read_gbuffer();
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &field(first),
        PassSettings {
            method: Method::Exact,
            params: MethodParams::for_method(Method::Exact),
            depth_scale: DEPTH_SCALE,
            addressing: Addressing::Repeat,
            extent: EXTENT,
            frames_in_flight: SLOTS as u32,
        },
    )
    .unwrap();
    let map = describe(&image, HeightChannel::R);
    let id = pass
        .add_host_material(&map, settings(Method::Exact))
        .unwrap();
    let frame = |pass: &mut DisplacementPass, host: &mut RayHost, m: u32, s: usize| {
        host.upload_gbuffer(&assign(&base, [m; 3]));
        host.submit_shaded(pass, s, cam, HOST_COLOR);
        (host.hits(s), host.colors(s))
    };
    let mut other = None;
    for round in 0..3 {
        let texel_frame = frame(&mut pass, &mut host, 0, 0);
        let host_frame = frame(&mut pass, &mut host, id.index(), 1);
        let bits = |f: &(Vec<[f32; 4]>, Vec<[u8; 4]>)| {
            f.0.iter().map(|h| h.map(f32::to_bits)).collect::<Vec<_>>()
        };
        assert_eq!(bits(&texel_frame), bits(&host_frame), "round {round} hits");
        assert_eq!(texel_frame.1, host_frame.1, "round {round} colours");
        assert!(texel_frame.0.iter().filter(|h| h[2] >= 0.0).count() > 1000);
        assert_eq!(pass.map_count(), 2);
        if round == 2 {
            break;
        }
        if round == 1 {
            // Another host image for the material (the default path: the next record
            // builds its pyramid); the old image's map is retired.
            let third = texels(2.1);
            let image2 = host_image(
                &ctx,
                &shot,
                "host.r16b",
                vk::Format::R16_UNORM,
                extent,
                &bytes(&third),
            );
            pass.set_material_host_height_map(id, &describe(&image2, HeightChannel::R))
                .unwrap();
            pass.set_height_map(&field(third)).unwrap();
            other = Some(image2);
            continue;
        }
        // New contents: the host waits for the frames that sample the image, writes it,
        // says so, and prepares the map again before the next frame.
        let second = texels(1.3);
        host.wait_all();
        fill(
            &ctx,
            &shot,
            &image,
            Access::COMPUTE_SAMPLED,
            &bytes(&second),
        );
        pass.host_height_map_changed(image.raw).unwrap();
        pass.set_height_map(&field(second)).unwrap();
        assert!(pass.preparation_pending());
        let cmd = shot.begin(&ctx).unwrap();
        // SAFETY: `cmd` is submitted and waited for before the next record; the image was
        // refilled and left sampled-readable (`fill`, waited for).
        let refused = unsafe { pass.record_preparation(cmd, Timestamps::Owned) };
        assert!(
            matches!(refused, Err(dispmap::Error::InvalidInput { ref name, .. }) if name == "timestamps")
        );
        // SAFETY: as above.
        let prepared = unsafe { pass.record_preparation(cmd, Timestamps::Off) }.unwrap();
        shot.submit_and_wait(&ctx).unwrap();
        assert!(
            prepared.passes.contains(&PassName::Pyramid),
            "{:?}",
            prepared.passes
        );
        assert!(
            prepared.passes.contains(&PassName::Upload),
            "{:?}",
            prepared.passes
        );
    }
    // An image no material uses changes nothing.
    pass.host_height_map_changed(vk::Image::null()).unwrap();
    assert!(!pass.preparation_pending());

    let bad = [
        HostHeightMap {
            image: vk::Image::null(),
            ..map
        },
        HostHeightMap {
            format: vk::Format::R8G8B8A8_SRGB,
            ..map
        },
        HostHeightMap {
            channel: HeightChannel::A,
            ..map
        },
        HostHeightMap {
            usage: vk::ImageUsageFlags::TRANSFER_DST,
            ..map
        },
        HostHeightMap {
            mip_levels: 7,
            ..map
        },
        HostHeightMap {
            extent: vk::Extent2D {
                width: 0,
                height: h,
            },
            ..map
        },
    ];
    for b in bad {
        match pass.add_host_material(&b, settings(Method::Exact)) {
            Err(dispmap::Error::InvalidInput { name, message }) => {
                assert_eq!(name, "host height map", "{message}");
                eprintln!("refused: {message}");
            }
            other => panic!("{b:?} not refused: {other:?}"),
        }
    }
    assert_eq!(pass.materials().len(), 2);

    host.destroy();
    // SAFETY: every frame and one-shot completed (`host.destroy` waited).
    unsafe {
        pass.destroy();
        image.destroy(&ctx);
        if let Some(mut image2) = other {
            image2.destroy(&ctx);
        }
        let mut shot = shot;
        shot.destroy(&ctx);
    }
    finish(ctx);
}

/// A preparation submitted on its own (its own command buffer and fence, not waited
/// for), then the map it prepared replaced before the next frame, with one frame in
/// flight: what the preparation reads and writes (the staging buffer, the texture, the
/// pyramid) must outlive the next frame, whose fence is the first that covers the
/// preparation. Synchronization and object-lifetime validation report any of them
/// destroyed while the preparation may still run.
#[test]
fn a_preparation_submitted_apart_keeps_what_it_uses_past_the_next_frame() {
    let ctx = validated_context();
    let (scene, _) = camera();
    let mut host = RayHost::new(ctx.clone(), EXTENT, 1);
    let camera = scene.frame_camera(EXTENT.width, EXTENT.height);
    host.rasterise(&scene.gbuffer_params(&camera), &camera.pixel_ray_params());
    let base = host.read_gbuffer();
    host.upload_gbuffer(&assign(&base, [0; 3]));
    let field =
        |seed| HeightField::from_texels(64, 64, Texels::R8(texels8(64, 64, seed)), "r8").unwrap();
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &field(0.0),
        PassSettings {
            method: Method::Exact,
            params: MethodParams::for_method(Method::Exact),
            depth_scale: DEPTH_SCALE,
            addressing: Addressing::Repeat,
            extent: EXTENT,
            frames_in_flight: 1,
        },
    )
    .unwrap();
    host.submit(&mut pass, 0);
    host.wait(0);
    pass.set_height_map(&field(0.5)).unwrap();
    let mut prep = common::frames::FrameSlots::new(ctx.clone(), 1);
    let cmd = prep.begin(0);
    // SAFETY: `cmd` (begun above, outside a render pass, on the context's queue family)
    // is submitted below, before the next record.
    let prepared = unsafe { pass.record_preparation(cmd, Timestamps::Off) }.unwrap();
    assert_eq!(
        prepared.passes,
        [PassName::Upload, PassName::Pyramid],
        "the new map's upload and pyramid"
    );
    prep.submit(0);
    // Replaced before any frame used it: the prepared texture and pyramid are retired.
    pass.set_height_map(&field(0.9)).unwrap();
    for _ in 0..3 {
        host.submit(&mut pass, 0);
    }
    let hits = host.hits(0);
    assert!(hits.iter().filter(|h| h[2] >= 0.0).count() > 1000);
    assert!(hits.iter().flatten().all(|v| v.is_finite()));
    prep.destroy();
    host.destroy();
    // SAFETY: every frame completed (`host.destroy` waited).
    unsafe { pass.destroy() };
    finish(ctx);
}
