//! The soak (issue 7): many frames through the embeddable pass with two frames in
//! flight, the height map swapped (`set_height_map`, frames in flight) every `swap_every`
//! frames, cycling through maps of different sizes and formats. Resident memory (VmRSS
//! from /proc/self/status) and gpu-allocator's report are sampled at the end of every
//! swap period (slots idle) and must be flat after warm-up:
//!
//! * device allocations: after the first cycle through the maps, every sample taken with
//!   map `k` bound has exactly the allocation count of the first sample with map `k`, and
//!   its bytes within [`PADDING_PER_ALLOCATION`] per allocation (gpu-allocator counts a
//!   chunk's alignment padding, which depends on where the chunk lands: small images of
//!   odd sizes, such as an 8-bit map's compact pyramid, move it by tens of bytes); the
//!   allocator's block capacity never grows again;
//! * resident memory: grows by at most [`RSS_TOLERANCE_KIB`] from the first sample after
//!   warm-up to the last (allocator and driver caches settle in the first cycle).
//!
//! Validation (core + synchronization) is on throughout and the teardown checks no
//! allocation and no Vulkan object is left. CI runs the short soak (100 frames, a swap
//! every 10); the full one is ignored by default:
//!
//! ```sh
//! cargo test --release --test soak -- --ignored --nocapture   # 1,000 frames, a swap every 100
//! ```

mod common;

/// The most alignment padding gpu-allocator may count per allocation beyond the bytes
/// asked for (Vulkan images and buffers align to at most 256 bytes here).
const PADDING_PER_ALLOCATION: u64 = 256;

use ash::vk;
use common::host::RayHost;
use common::{asset_map, finish, validated_context};
use dispmap::embed::{DisplacementPass, PassSettings};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::scene::Scene;

/// Allowed growth of resident memory after warm-up, KiB. Measured on lavapipe: 1.9 MiB
/// during the second cycle through the maps (allocator and driver caches), then none.
const RSS_TOLERANCE_KIB: u64 = 4096;

/// Resident set size of this process, KiB.
fn rss_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmRSS in /proc/self/status")
}

/// One sample at the end of a swap period.
#[derive(Clone, Debug, PartialEq)]
struct Sample {
    map: usize,
    rss_kib: u64,
    allocations: usize,
    allocated_bytes: u64,
    capacity_bytes: u64,
}

fn soak(frames: usize, swap_every: usize) {
    let ctx = validated_context();
    // Three maps of different sizes and texel formats (R8, R32F, R16).
    let maps: Vec<HeightField> = vec![
        asset_map("rocks_depth.jpg", Convention::Depth),
        HeightField::from_fn(300, 200, "bumps", |u, v| {
            0.5 + 0.45 * (u * 37.0).sin() * (v * 23.0).cos()
        })
        .unwrap(),
        asset_map("mountains_height16.png", Convention::Height),
    ];
    let extent = vk::Extent2D {
        width: 64,
        height: 48,
    };
    let mut host = RayHost::new(ctx.clone(), extent, 2);
    let scene = Scene::default();
    let camera = scene.frame_camera(extent.width, extent.height);
    host.rasterise(&scene.gbuffer_params(&camera), &camera.pixel_ray_params());
    // DIG with the pyramid guard: height texture, pyramid, corner grids per slot.
    let method = Method::DigGuarded;
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &maps[0],
        PassSettings {
            method,
            params: MethodParams::for_method(method),
            depth_scale: scene.depth_scale,
            addressing: scene.addressing(),
            extent,
            frames_in_flight: 2,
        },
    )
    .unwrap();
    let mut samples: Vec<Sample> = Vec::new();
    let mut map = 0;
    for frame in 0..frames {
        if frame > 0 && frame % swap_every == 0 {
            host.wait_all();
            let report = ctx.allocator().lock().unwrap().generate_report();
            samples.push(Sample {
                map,
                rss_kib: rss_kib(),
                allocations: report.allocations.len(),
                allocated_bytes: report.total_allocated_bytes,
                capacity_bytes: report.total_capacity_bytes,
            });
            map = (map + 1) % maps.len();
            // With the other slot's frame still in flight on the next record.
            pass.set_height_map(&maps[map]).unwrap();
        }
        host.submit(&mut pass, frame % 2);
    }
    let hits = host.hits(frames % 2);
    host.wait_all();
    assert!(
        hits.iter().all(|h| h.iter().all(|c| c.is_finite())),
        "non-finite hits"
    );
    assert!(hits.iter().filter(|h| h[2] >= 0.0).count() > hits.len() / 2);
    // SAFETY: every frame completed (`wait_all`).
    unsafe { pass.destroy() };
    host.destroy();
    finish(ctx);

    for s in &samples {
        eprintln!("{s:?}");
    }
    let warm = maps.len();
    assert!(
        samples.len() > warm,
        "{} samples: too short to see past warm-up",
        samples.len()
    );
    let (first, rest) = samples.split_at(warm);
    for s in rest {
        let base = &first[s.map];
        assert!(
            s.allocations == base.allocations
                && s.allocated_bytes.abs_diff(base.allocated_bytes)
                    <= PADDING_PER_ALLOCATION * s.allocations as u64,
            "device allocations with map {} changed: {base:?} -> {s:?}",
            s.map
        );
        let capacity = first.iter().map(|f| f.capacity_bytes).max().unwrap();
        assert!(
            s.capacity_bytes <= capacity,
            "allocator blocks grew after warm-up: {capacity} -> {}",
            s.capacity_bytes
        );
    }
    let (rss0, rss1) = (rest[0].rss_kib, rest.last().unwrap().rss_kib);
    eprintln!(
        "resident memory after warm-up: {rss0} KiB -> {rss1} KiB over {} swaps",
        rest.len() - 1
    );
    assert!(
        rss1 <= rss0 + RSS_TOLERANCE_KIB,
        "resident memory grew by {} KiB after warm-up",
        rss1.saturating_sub(rss0)
    );
}

/// The CI soak: 100 frames, the map swapped every 10.
#[test]
fn soak_short() {
    soak(100, 10);
}

/// The full soak: 1,000 frames, the map swapped every 100 (see the module docs).
#[test]
#[ignore = "the full soak (about 10 s on lavapipe); run with --ignored"]
fn soak_1000_frames() {
    soak(1000, 100);
}
