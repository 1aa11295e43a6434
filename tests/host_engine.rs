//! The host-engine example (`examples/host_engine.rs`: its own instance, device,
//! allocator, G-buffer pass and shaders, two frames in flight, height-map swaps) runs
//! under validation (core + synchronization) with zero messages and no leaked object or
//! allocation, and its hit buffer equals the standalone renderer's for the same scene.
//!
//! Comparison: the engine's floor is the standalone renderer's plane (same vertices, same
//! triangle order, same camera), so on every pixel where the floor is visible the rays,
//! and so the hits, are bit-identical. The cube covers pixels that the standalone frame
//! shows as floor, so with the cube those pixels are left out (they are identified by the
//! engine's G-buffer surface id); without the cube the whole frame must match.

#[path = "../examples/host_engine.rs"]
#[allow(dead_code)]
mod host_engine;

mod common;

use common::{finish, validated_context};
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use host_engine::{Options, run};

const W: u32 = 128;
const H: u32 = 72;

fn standalone_hits(method: Method) -> Vec<[f32; 4]> {
    let ctx = validated_context();
    let hits = {
        let mut r = Renderer::new(
            &ctx,
            &host_engine::rocks().unwrap(),
            RenderSettings {
                shadows: Default::default(),
                width: W,
                height: H,
                method,
                params: MethodParams::for_method(method),
                scene: host_engine::scene(),
            },
        )
        .unwrap();
        r.render().unwrap();
        r.read_hits().unwrap()
    };
    finish(ctx);
    hits
}

fn bits(h: &[f32; 4]) -> [u32; 4] {
    h.map(f32::to_bits)
}

fn engine(method: Method, cube: bool, out: Option<std::path::PathBuf>) -> host_engine::Output {
    let _ = env_logger::builder().is_test(true).try_init();
    let out = run(&Options {
        width: W,
        height: H,
        frames: 6,
        method,
        cube,
        validation: true,
        out,
    })
    .unwrap();
    assert!(out.validated);
    assert_eq!(
        out.validation_messages, 0,
        "validation messages (see stderr)"
    );
    assert_eq!(out.leaked_allocations, 0, "allocations left after destroy");
    // Every frame was timed (host pool on slot 0, the pass's own on slot 1), and the
    // height-map swaps in frames 1 and 3 re-ran the upload (and the pyramid) only there.
    assert_eq!(out.timings.len(), 6);
    for (i, t) in out.timings.iter().enumerate() {
        let names: Vec<_> = t.iter().map(|(n, _)| *n).collect();
        assert!(
            names.contains(&"trace") && names.contains(&"shade"),
            "{names:?}"
        );
        assert_eq!(
            names.contains(&"height_upload"),
            [0, 1, 3].contains(&i),
            "frame {i}: {names:?}"
        );
        assert!(t.iter().all(|(_, ms)| ms.is_finite() && *ms >= 0.0));
    }
    out
}

#[test]
fn host_engine_with_cube_matches_standalone_on_the_floor() {
    let dir = std::env::temp_dir().join(format!("dispmap-host-engine-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("host.png");
    let out = engine(Method::Exact, true, Some(png.clone()));
    let expected = standalone_hits(Method::Exact);
    let (mut floor, mut cube) = (0, 0);
    for (i, (got, want)) in out.hits.iter().zip(&expected).enumerate() {
        if out.is_floor(i) {
            floor += 1;
            assert_eq!(bits(got), bits(want), "pixel {i}: {got:?} vs {want:?}");
        } else if out.surface_ids[i] >= 2.0 {
            cube += 1;
            assert!(got.iter().all(|v| v.is_finite()), "pixel {i}: {got:?}");
        }
    }
    let n = (W * H) as usize;
    assert!(floor > n / 2, "floor pixels: {floor} of {n}");
    assert!(cube > 50, "cube pixels: {cube}");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (W, H));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn host_engine_floor_only_equals_standalone_everywhere() {
    let out = engine(Method::Dig, false, None);
    let expected = standalone_hits(Method::Dig);
    assert_eq!(out.hits.len(), expected.len());
    for (i, (got, want)) in out.hits.iter().zip(&expected).enumerate() {
        assert_eq!(bits(got), bits(want), "pixel {i}: {got:?} vs {want:?}");
    }
}
