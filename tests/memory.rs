//! What `DisplacementPass` holds ([`DisplacementPass::memory`]) when materials come and go:
//! the tile lists follow the frame's size alone, a batch of 1024 materials at 1920x1080
//! stays within the pass's memory bounds, materials added and removed every frame leave
//! the memory flat, the report counts every allocation the pass made, `destroy` lets go
//! of the context, and the bytes per pixel of the G-buffer contract are the documented 40
//! (the iteration counts only where they are asked for). Validation (core + synchronization) is on throughout: zero messages
//! from the context's creation to the device's destruction, no allocation left.

mod common;

use ash::vk;
use common::host::{GBufferTexels, RayHost};
use common::{finish, validated_context};
use dispmap::Context;
use dispmap::abi::NO_HIT_HEIGHT;
use dispmap::embed::{
    DEPTH_FORMAT, DisplacementPass, FRAME_FORMAT, HIT_HEIGHT_FORMAT, HIT_UV_FORMAT,
    ITERATIONS_FORMAT, MaterialId, MaterialSettings, MemoryReport, PassSettings, RAY_FORMAT,
};
use dispmap::gpu::image::texel_size;
use dispmap::heightfield::{Addressing, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::classify::TileLists;
use dispmap::passes::gbuffer::frame;
use glam::Vec3;
use std::sync::Arc;

const MIB: u64 = 1 << 20;

/// A map of 4x4 texels all of height `h`.
fn flat_map(h: f32) -> HeightField {
    HeightField::from_fn(4, 4, &format!("flat {h}"), |_, _| h).unwrap()
}

/// The height of the 1024 materials' map `i` (1/2048 apart).
fn level(i: usize) -> f32 {
    0.25 + i as f32 / 2048.0
}

/// The height of the churn's map `k` (1/20 apart: the marchers' hits are within 1/100).
fn churn_level(k: usize) -> f32 {
    0.2 + k as f32 / 20.0
}

fn material(method: Method) -> MaterialSettings {
    MaterialSettings {
        method,
        params: MethodParams::for_method(method),
        depth_scale: 0.05,
        addressing: Addressing::Repeat,
    }
}

fn pass_settings(s: MaterialSettings, extent: vk::Extent2D, slots: u32) -> PassSettings {
    PassSettings {
        method: s.method,
        params: s.params,
        depth_scale: s.depth_scale,
        addressing: s.addressing,
        extent,
        frames_in_flight: slots,
    }
}

/// A G-buffer with geometry only in the `block` (x, y, w, h): pixel (x, y) of it has
/// material `assign(x, y)` (a table index) and a ray descending along +u.
fn gbuffer(
    extent: vk::Extent2D,
    block: [u32; 4],
    assign: impl Fn(u32, u32) -> u32,
) -> GBufferTexels {
    let n = (extent.width * extent.height) as usize;
    let mut g = GBufferTexels {
        ray: vec![[0.0; 4]; n],
        depth: vec![0.0; n],
        frame: vec![[0; 2]; n],
    };
    let [bx, by, bw, bh] = block;
    for y in by..by + bh {
        for x in bx..bx + bw {
            let i = (y * extent.width + x) as usize;
            let uv = [x as f32 / 64.0, y as f32 / 64.0];
            g.ray[i] = [uv[0], uv[1], 0.3, 0.2];
            g.depth[i] = 0.5;
            // Normal +y, tangent +x, surface 1, the material's index + 1.
            g.frame[i] = frame::pack(Vec3::Y, Vec3::X, 1.0, assign(x, y) + 1, 1);
        }
    }
    g
}

/// The frame's displaced pixels each hit their own material's flat map at its height
/// (within `tolerance`: `exact` hits it at the height, a marcher near it), and the others
/// have no hit.
fn check_hits(
    hits: &[[f32; 4]],
    extent: vk::Extent2D,
    block: [u32; 4],
    tolerance: f32,
    level_of: impl Fn(u32, u32) -> f32,
) {
    let [bx, by, bw, bh] = block;
    let mut wrong = Vec::new();
    for y in 0..extent.height {
        for x in 0..extent.width {
            let h = hits[(y * extent.width + x) as usize];
            let inside = (bx..bx + bw).contains(&x) && (by..by + bh).contains(&y);
            let want = if inside {
                level_of(x, y)
            } else {
                NO_HIT_HEIGHT
            };
            if !h[2].is_finite() || (h[2] - want).abs() > tolerance {
                wrong.push(((x, y), h, want));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "{} pixels hit another height than their material's (first: {:?})",
        wrong.len(),
        &wrong[..wrong.len().min(5)]
    );
}

/// The report without its per-material list, for the log.
fn kinds(r: &MemoryReport) -> MemoryReport {
    MemoryReport {
        materials: Vec::new(),
        ..r.clone()
    }
}

/// The most alignment padding gpu-allocator's report counts per allocation beyond the
/// bytes asked for (as tests/soak.rs: Vulkan aligns images and buffers to at most 256
/// bytes here).
const PADDING_PER_ALLOCATION: u64 = 256;

/// The report's total is every allocation the pass made (all the context's allocations
/// but the test host's `host.*`), give or take the allocator's alignment padding.
fn check_complete(ctx: &Context, report: &MemoryReport) {
    let r = ctx.allocator().lock().unwrap().generate_report();
    let pass: Vec<_> = (r.allocations.iter())
        .filter(|a| !a.name.starts_with("host."))
        .collect();
    let bytes: u64 = pass.iter().map(|a| a.size).sum();
    let padding = PADDING_PER_ALLOCATION * pass.len() as u64;
    assert!(
        (report.total()..=report.total() + padding).contains(&bytes),
        "the pass's {} allocations hold {bytes} bytes, its report {}: {:?}",
        pass.len(),
        report.total(),
        kinds(report)
    );
}

/// 1024 materials added in one batch before a frame at 1920x1080 with two frames in
/// flight: the tile lists of a slot take at most 8.5 MiB (their size follows the frame
/// alone) and the pass holds less than 64 MiB beside the maps. Two frames whose 8x8 tiles
/// each hold 64 different materials (the most a tile can) trace every pixel with its own
/// material.
#[test]
fn a_thousand_materials_at_1080p_fit_the_memory_bounds() {
    let ctx = validated_context();
    let extent = vk::Extent2D {
        width: 1920,
        height: 1080,
    };
    let exact = material(Method::Exact);
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &flat_map(level(0)),
        pass_settings(exact, extent, 2),
    )
    .unwrap();
    let before = pass.memory();
    for i in 1..1024 {
        pass.add_material(&flat_map(level(i)), exact).unwrap();
    }
    let report = pass.memory();
    eprintln!(
        "one material: {:?}\n1024 materials: {:?}",
        kinds(&before),
        kinds(&report)
    );
    assert_eq!(report.materials.len(), 1024);
    let per_slot = TileLists::bytes_for(extent);
    // 4 * (2048 + 66 * 240 * 135) + 32 * 1025 (docs/embedding.md): 8.20 MiB.
    assert_eq!(per_slot, 8_594_592);
    assert_eq!(report.tile_lists, 2 * per_slot);
    assert_eq!(
        before.tile_lists, report.tile_lists,
        "the lists did not grow"
    );
    assert!(
        per_slot <= 8 * MIB + MIB / 2,
        "tile lists {per_slot} bytes per slot"
    );
    let beside_maps = report.total() - report.maps();
    assert!(
        beside_maps < 64 * MIB,
        "{beside_maps} bytes beside the maps"
    );
    assert_eq!(report.retired, 0, "a batch of adds retires nothing");
    check_complete(&ctx, &report);

    // Tiles of 64 materials: pixel (x, y) of a 128x64 block has material x + 128 y mod
    // 1024, so each 8x8 tile holds 64 and the block all 1024.
    let block = [256, 128, 128, 64];
    let assign = |x: u32, y: u32| ((x - block[0]) + 128 * (y - block[1])) % 1024;
    let mut host = RayHost::new(ctx.clone(), extent, 2);
    host.upload_gbuffer(&gbuffer(extent, block, assign));
    host.submit(&mut pass, 0);
    host.submit(&mut pass, 1);
    for s in 0..2 {
        check_hits(&host.hits(s), extent, block, 1e-4, |x, y| {
            level(assign(x, y) as usize)
        });
    }
    let after = pass.memory();
    assert_eq!(after.uploads, 0, "the first frame recorded every upload");
    assert_eq!(after.tile_lists, report.tile_lists);
    check_complete(&ctx, &after);
    host.destroy();
    // SAFETY: every frame completed (`host.destroy` waited).
    unsafe { pass.destroy() };
    assert_eq!(pass.memory(), MemoryReport::default());
    finish(ctx);
}

/// Materials added and removed every frame for 200 frames with two frames in flight: the
/// tile lists are never rebuilt, what the removed materials held is freed once the slots
/// have been recorded again, and the pass's memory (the report, and the allocator's count
/// of its allocations) is the same after 20 frames and after 200.
#[test]
fn materials_added_and_removed_every_frame_leave_the_memory_flat() {
    let ctx = validated_context();
    let extent = vk::Extent2D {
        width: 48,
        height: 32,
    };
    // Ten maps in turn, eight live at a time; each method builds its own kind of
    // preparation (a pyramid, DIG's corner grids, a cone map, nothing).
    const MAPS: usize = 10;
    const LIVE: usize = 8;
    let methods = [
        Method::Exact,
        Method::Dig,
        Method::ConeExact,
        Method::Relief,
    ];
    let settings = |k: usize| material(methods[k % methods.len()]);
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &flat_map(churn_level(0)),
        pass_settings(settings(0), extent, 2),
    )
    .unwrap();
    let mut live: std::collections::VecDeque<(usize, MaterialId)> =
        std::collections::VecDeque::from([(0, pass.primary())]);
    for k in 1..LIVE {
        let id = pass.add_material(&flat_map(churn_level(k)), settings(k));
        live.push_back((k, id.unwrap()));
    }
    let mut host = RayHost::new(ctx.clone(), extent, 2);
    let tiles = pass.memory().tile_lists;
    let mut samples: Vec<(usize, MemoryReport, usize)> = Vec::new();
    for frame in 0..200 {
        // Pixel x of the block shows the live material x mod 8 (whatever its index).
        let indices: Vec<u32> = live.iter().map(|(_, id)| id.index()).collect();
        let maps: Vec<usize> = live.iter().map(|(k, _)| *k).collect();
        let block = [0, 0, extent.width, extent.height];
        host.upload_gbuffer(&gbuffer(extent, block, |x, _| indices[x as usize % LIVE]));
        let s = frame % 2;
        host.submit(&mut pass, s);
        if frame % 20 == 19 {
            check_hits(&host.hits(s), extent, block, 0.01, |x, _| {
                churn_level(maps[x as usize % LIVE])
            });
        }
        // With the other slot's frame in flight: the oldest material goes, the next map
        // comes.
        let (k, id) = live.pop_front().unwrap();
        pass.remove_material(id).unwrap();
        let next = (k + LIVE) % MAPS;
        let id = pass.add_material(&flat_map(churn_level(next)), settings(next));
        live.push_back((next, id.unwrap()));
        if frame == 19 || frame == 199 {
            host.wait_all();
            let report = pass.memory();
            check_complete(&ctx, &report);
            let count = ctx
                .allocator()
                .lock()
                .unwrap()
                .generate_report()
                .allocations
                .len();
            samples.push((frame, report, count));
        }
        assert_eq!(
            pass.memory().tile_lists,
            tiles,
            "frame {frame}: lists rebuilt"
        );
    }
    let (a, b) = (&samples[0], &samples[1]);
    eprintln!(
        "after frame {}: {:?}\nafter frame {}: {:?}",
        a.0,
        kinds(&a.1),
        b.0,
        kinds(&b.1)
    );
    // Frames 20 and 200 have the same maps in the same places (180 = 18 x 10 frames).
    assert_eq!(a.1.total(), b.1.total(), "the pass's memory grew");
    assert_eq!(a.2, b.2, "the allocation count grew");
    host.destroy();
    // SAFETY: every frame completed (`host.destroy` waited).
    unsafe { pass.destroy() };
    finish(ctx);
}

/// After `destroy` the pass holds no `Arc<Context>`: the host takes its context back
/// with `Arc::into_inner` while the pass value still exists, and any later call is an
/// error, not a use of the device.
#[test]
fn destroy_lets_go_of_the_context() {
    let ctx = validated_context();
    let extent = vk::Extent2D {
        width: 16,
        height: 16,
    };
    let relief = material(Method::Relief);
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &flat_map(0.5),
        pass_settings(relief, extent, 1),
    )
    .unwrap();
    assert_eq!(Arc::strong_count(&ctx), 2);
    // SAFETY: nothing was recorded with the pass.
    unsafe { pass.destroy() };
    assert_eq!(
        Arc::strong_count(&ctx),
        1,
        "the pass still holds the context"
    );
    assert!(pass.context().is_err());
    assert!(pass.add_material(&flat_map(0.25), relief).is_err());
    // `finish` takes the context back with `Arc::into_inner` while `pass` is alive.
    finish(ctx);
    drop(pass);
}

/// The G-buffer contract's bytes per pixel and frame slot, from the formats `record`
/// checks: ray 16 + frame 8 + depth 4 + hit uv 8 + hit height 4 = 40 (the hit images were
/// one `R32G32B32A32_SFLOAT` buffer with the iteration count: 44; before the packed frame,
/// 52), as docs/embedding.md states; the iteration counts (4 more) are the pass's, and only
/// while asked for; the curve image (4 more) only for a frame with a material traced
/// curved.
#[test]
fn the_gbuffer_contract_is_40_bytes_a_pixel() {
    let bytes =
        |formats: &[vk::Format]| -> u32 { formats.iter().map(|&f| texel_size(f).unwrap()).sum() };
    let contract = [
        RAY_FORMAT,
        FRAME_FORMAT,
        DEPTH_FORMAT,
        HIT_UV_FORMAT,
        HIT_HEIGHT_FORMAT,
    ];
    assert_eq!(bytes(&contract), 40);
    assert_eq!(bytes(&[HIT_UV_FORMAT, HIT_HEIGHT_FORMAT]), 12);
    assert_eq!(bytes(&[ITERATIONS_FORMAT]), 4);
    assert_eq!(bytes(&[dispmap::passes::gbuffer::CURVE_FORMAT]), 4);
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/embedding.md")).unwrap();
    for stated in [
        "The G-buffer contract alone (ray, frame, depth, hit uv, hit height) is 40 bytes",
        "44 for a frame with a material traced curved (the curve image)",
    ] {
        assert!(
            doc.replace('\n', " ").contains(stated),
            "docs/embedding.md does not say: {stated}"
        );
    }
}

/// The pass allocates the iteration counts (one `R32_UINT` image per frame slot) only
/// while the output is on: none after `new`, 4 bytes a pixel per slot when turned on, and
/// retired (not freed under frames in flight) when turned off.
#[test]
fn the_iteration_counts_exist_only_when_asked_for() {
    let ctx = validated_context();
    let extent = vk::Extent2D {
        width: 64,
        height: 32,
    };
    let relief = material(Method::Relief);
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &flat_map(0.5),
        pass_settings(relief, extent, 2),
    )
    .unwrap();
    assert!(!pass.iterations_output());
    assert_eq!(pass.memory().iterations, 0);
    assert!(pass.iterations(0).is_none() && pass.iterations(1).is_none());
    pass.set_iterations_output(true).unwrap();
    let on = pass.memory();
    let pixels = u64::from(extent.width * extent.height);
    assert!(
        (2 * 4 * pixels..=2 * (4 * pixels + PADDING_PER_ALLOCATION)).contains(&on.iterations),
        "{} bytes of iteration counts for two slots of {pixels} pixels",
        on.iterations
    );
    for s in 0..2 {
        let image = pass.iterations(s).unwrap();
        assert_eq!((image.format, image.extent), (ITERATIONS_FORMAT, extent));
    }
    check_complete(&ctx, &on);
    pass.set_iterations_output(false).unwrap();
    let off = pass.memory();
    assert_eq!(off.iterations, 0);
    assert!(off.retired >= 2 * 4 * pixels, "the images are retired");
    assert!(pass.iterations(0).is_none());
    // SAFETY: nothing was recorded with the pass.
    unsafe { pass.destroy() };
    finish(ctx);
}

/// The mesh walk's lists exist only while a material walks given meshes: an `exact`
/// material traced curved holds none until the pass is given meshes, then one per slot
/// (32 + 8 bytes a pixel: the first trace's list and the triage's, `walk_lists`) beside the meshes' buffer (`curved_meshes`),
/// counted in the report's total; giving no meshes again retires them.
#[test]
fn the_walk_lists_exist_only_with_meshes_to_walk() {
    let ctx = validated_context();
    let extent = vk::Extent2D {
        width: 64,
        height: 32,
    };
    let exact = material(Method::Exact);
    let mut pass =
        DisplacementPass::new(ctx.clone(), &flat_map(0.5), pass_settings(exact, extent, 2))
            .unwrap();
    let m = pass.primary();
    pass.set_material_curved(m, true).unwrap();
    assert_eq!(pass.memory().walk_lists, 0, "no meshes: no lists");
    let cube = dispmap::mesh::Mesh::cube();
    pass.set_curved_meshes(&[&cube]).unwrap();
    assert!(pass.curved_mesh_triangles() > 0);
    let on = pass.memory();
    let list = 32 + 8 * u64::from(extent.width * extent.height);
    assert!(
        (2 * list..=2 * (list + PADDING_PER_ALLOCATION)).contains(&on.walk_lists),
        "{} bytes of walk lists for two slots of {list} bytes",
        on.walk_lists
    );
    // The cube's triangles at 36 words each, at least.
    let triangles = u64::from(pass.curved_mesh_triangles());
    assert!(on.curved_meshes >= 4 * 36 * triangles, "{on:?}");
    assert!(on.frame() >= on.walk_lists && on.maps() >= on.curved_meshes);
    check_complete(&ctx, &on);
    // Not traced curved: nothing walks.
    pass.set_material_curved(m, false).unwrap();
    assert_eq!(pass.memory().walk_lists, 0);
    pass.set_material_curved(m, true).unwrap();
    assert_eq!(pass.memory().walk_lists, on.walk_lists);
    pass.set_curved_meshes(&[]).unwrap();
    let off = pass.memory();
    assert_eq!((off.walk_lists, pass.curved_mesh_triangles()), (0, 0));
    assert!(off.retired >= 2 * list, "the lists are retired");
    check_complete(&ctx, &off);
    // SAFETY: nothing was recorded with the pass.
    unsafe { pass.destroy() };
    finish(ctx);
}
