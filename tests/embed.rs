//! `DisplacementPass::resize` and `DisplacementPass::set_method` called while frames are
//! in flight, under validation (core + synchronization): zero messages from context
//! creation to device destruction, no allocation left after `destroy`, and the hits of
//! the frames recorded afterwards are bit-identical to the standalone `Renderer`'s for
//! the same scene, method and size.
//!
//! The "host" here is a minimal frames-in-flight loop: dispmap's own headless context
//! (validated), its `GBuffer` images and `GBufferPass` as the host's G-buffer (so the
//! rays equal the standalone renderer's bit for bit), and per slot a G-buffer and a hit
//! image, with the command buffers and fences of `common::frames` (the slot contract of
//! `dispmap::embed`).

mod common;

use ash::vk;
use common::frames::{FrameSlots, HitPair, record_gbuffer};
use common::{asset_map, validated_context};
use dispmap::Context;
use dispmap::embed::{DisplacementPass, FrameInputs, PassSettings, Timestamps};
use dispmap::gpu::OneShot;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::Access;
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::gbuffer::{GBuffer, GBufferPass};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::Scene;
use std::sync::Arc;

const SLOTS: usize = 2;

/// One frame-in-flight slot's images.
struct Slot {
    gbuffer: GBuffer,
    hit: HitPair,
}

/// The test host: its G-buffer pipeline, slots' images and frame plumbing.
struct Host {
    ctx: Arc<Context>,
    scene: Scene,
    extent: vk::Extent2D,
    gbuffer_pass: GBufferPass,
    slots: Vec<Slot>,
    frames: FrameSlots,
    frame: usize,
}

fn images(ctx: &Context, extent: vk::Extent2D, s: usize) -> (GBuffer, HitPair) {
    let gbuffer = GBuffer::new(ctx, extent).unwrap();
    let hit = HitPair::new(
        ctx,
        &format!("host.hit{s}"),
        extent,
        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
    );
    (gbuffer, hit)
}

impl Host {
    fn new(ctx: Arc<Context>, scene: Scene, extent: vk::Extent2D) -> Host {
        let slots = (0..SLOTS)
            .map(|s| {
                let (gbuffer, hit) = images(&ctx, extent, s);
                Slot { gbuffer, hit }
            })
            .collect();
        let gbuffer_pass = GBufferPass::new(&ctx).unwrap();
        Host {
            frames: FrameSlots::new(ctx.clone(), SLOTS),
            ctx,
            scene,
            extent,
            gbuffer_pass,
            slots,
            frame: 0,
        }
    }

    fn wait_all(&mut self) {
        self.frames.wait_all();
    }

    /// The host's own resize: it changes the size of the frames it records from now on;
    /// each slot's images are replaced when that slot is next recorded (after its fence),
    /// so frames in flight keep theirs.
    fn resize(&mut self, extent: vk::Extent2D) {
        self.extent = extent;
    }

    /// Records and submits one frame (G-buffer, then the pass) without waiting for it.
    /// Returns the passes the displacement pass recorded.
    fn frame(&mut self, pass: &mut DisplacementPass) -> Vec<&'static str> {
        let s = self.frame % SLOTS;
        self.frame += 1;
        let cmd = self.frames.begin(s);
        let ctx = self.ctx.clone();
        if self.slots[s].hit.extent() != self.extent {
            // Slot `s`'s last frame has completed (`begin` waited): its old images are
            // unused.
            let (gbuffer, hit) = images(&ctx, self.extent, s);
            let slot = &mut self.slots[s];
            // SAFETY: slot `s`'s last frame has completed (`begin` waited): nothing reads the old images.
            unsafe {
                std::mem::replace(&mut slot.gbuffer, gbuffer).destroy(&ctx);
                std::mem::replace(&mut slot.hit, hit).destroy(&ctx);
            }
        }
        let slot = &self.slots[s];
        let camera = self
            .scene
            .frame_camera(self.extent.width, self.extent.height);
        let params = self.scene.gbuffer_params(&camera);
        let g = &slot.gbuffer;
        // The pass's entry state (module docs of `dispmap::embed`).
        // SAFETY: `cmd` was begun by `frames.begin` above (outside a render pass, on the
        // context's queue family) and is submitted below; the slot's images are replaced
        // only after its fence, and its last frame completed (`begin` waited), so they
        // may be discarded.
        unsafe {
            record_gbuffer(
                &ctx,
                cmd,
                &self.gbuffer_pass,
                g,
                &params,
                &camera.pixel_ray_params(),
            )
        };
        // SAFETY: as above, for the slot's hit images.
        unsafe { slot.hit.discard(&ctx, cmd) };
        let inputs = FrameInputs {
            frame_slot: s as u32,
            gbuffer: g.views(),
            hit: slot.hit.host(),
            shade: None,
            motion: None,
        };
        // SAFETY: `cmd` is recording outside a render pass on the context's queue family;
        // the views are alive until the frame completes (replaced only after its fence),
        // in the entry layouts above; the slot contract holds (`begin` waited); the buffer
        // is submitted below, in recording order.
        let recorded = unsafe { pass.record(cmd, &inputs, Timestamps::Off) }.unwrap();
        self.frames.submit(s);
        recorded.passes.iter().map(|p| p.as_str()).collect()
    }

    /// The hits of slot `s` with the pass's iteration counts of the slot (its last frame
    /// must have completed: `wait_all`).
    fn hits(&self, s: usize, shot: &OneShot, pass: &DisplacementPass) -> Vec<[f32; 4]> {
        assert!(!self.frames.in_flight(s));
        self.slots[s].hit.read(
            &self.ctx,
            shot,
            Access::COMPUTE_STORAGE_WRITE,
            pass.iterations(s as u32),
        )
    }

    fn destroy(mut self) {
        self.frames.destroy();
        let ctx = self.ctx.clone();
        for slot in &mut self.slots {
            // SAFETY: `frames.destroy()` waited for every frame.
            unsafe {
                slot.gbuffer.destroy(&ctx);
                slot.hit.destroy(&ctx);
            }
        }
        // SAFETY: `frames.destroy()` waited for every frame.
        unsafe { self.gbuffer_pass.destroy(&ctx) };
    }
}

fn settings(method: Method, params: MethodParams, extent: vk::Extent2D) -> PassSettings {
    let scene = Scene::default();
    PassSettings {
        method,
        params,
        depth_scale: scene.depth_scale,
        addressing: scene.addressing(),
        extent,
        frames_in_flight: SLOTS as u32,
    }
}

/// The standalone renderer's hits for the same scene, map, method and size.
fn standalone(
    ctx: &Arc<Context>,
    field: &HeightField,
    method: Method,
    params: MethodParams,
    extent: vk::Extent2D,
) -> Vec<[f32; 4]> {
    let mut r = Renderer::new(
        ctx,
        field,
        RenderSettings {
            shadows: Default::default(),
            width: extent.width,
            height: extent.height,
            method,
            params,
            scene: Scene::default(),
        },
    )
    .unwrap();
    r.render().unwrap();
    r.read_hits().unwrap()
}

fn assert_bit_identical(got: &[[f32; 4]], want: &[[f32; 4]], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: pixel count");
    let mut hits = 0;
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(
            g.map(f32::to_bits),
            w.map(f32::to_bits),
            "{what}, pixel {i}: {g:?} vs {w:?}"
        );
        hits += usize::from(w[3] > 0.0);
    }
    // Not a trivially empty frame: the plane covers most of it.
    assert!(hits > got.len() / 2, "{what}: only {hits} traced pixels");
}

/// Tears down pass, host and context in the documented order and checks: no allocation
/// left after `destroy`, and no validation message up to and including the device's
/// destruction (the object tracker reports any object still alive there).
fn teardown(ctx: Arc<Context>, mut pass: DisplacementPass, host: Host, shot: OneShot) {
    let mut shot = shot;
    host.destroy();
    // SAFETY: every submission of the shot was waited for.
    unsafe { shot.destroy(&ctx) };
    // SAFETY: every frame recorded with the pass completed (`Host::destroy` waited).
    unsafe { pass.destroy() };
    let leaked = ctx
        .allocator()
        .lock()
        .unwrap()
        .generate_report()
        .allocations
        .len();
    assert_eq!(leaked, 0, "allocations left after destroy");
    assert!(ctx.has_messenger(), "validation messages would go unseen");
    let messages = ctx.messages().clone();
    let ctx = Arc::into_inner(ctx).expect("nothing else holds the context");
    drop(ctx); // destroys the device, then the messenger
    assert_eq!(
        (messages.errors(), messages.warnings()),
        (0, 0),
        "validation reported errors/warnings (see the log)"
    );
}

#[test]
fn resize_with_frames_in_flight_matches_standalone_at_the_new_size() {
    let ctx = validated_context();
    let rocks = asset_map("rocks_depth.jpg", Convention::Depth);
    // DIG with the pyramid guard: a per-slot corner grid (which resize replaces) and a
    // shared pyramid (which it keeps).
    let method = Method::DigGuarded;
    let params = MethodParams::for_method(method);
    let small = vk::Extent2D {
        width: 96,
        height: 64,
    };
    let large = vk::Extent2D {
        width: 128,
        height: 72,
    };
    let shot = OneShot::new(&ctx, "test.readback").unwrap();
    let mut host = Host::new(ctx.clone(), Scene::default(), small);
    let mut pass =
        DisplacementPass::new(ctx.clone(), &rocks, settings(method, params, small)).unwrap();
    // The standalone renderer's hits carry iteration counts: the host asks for them.
    assert!(!pass.iterations_output() && pass.iterations(0).is_none());
    pass.set_iterations_output(true).unwrap();
    assert!(pass.iterations_output());

    // Frames at the first size; the first uploads the map and builds the pyramid.
    assert_eq!(
        host.frame(&mut pass),
        ["upload", "pyramid", "classify", "dig_corners", "trace"]
    );
    for _ in 0..3 {
        assert_eq!(host.frame(&mut pass), ["classify", "dig_corners", "trace"]);
    }
    // Resize while both slots' frames are in flight (no wait): the pass retires its
    // old grids, the host replaces each slot's images once that slot's fence signals.
    assert!(host.frames.all_in_flight());
    pass.resize(large).unwrap();
    host.resize(large);
    assert_eq!(pass.settings().extent, large);
    for _ in 0..4 {
        // The pyramid does not depend on the frame size: not rebuilt.
        assert_eq!(host.frame(&mut pass), ["classify", "dig_corners", "trace"]);
    }
    host.wait_all();

    let expected = standalone(&ctx, &rocks, method, params, large);
    for s in 0..SLOTS {
        assert_eq!(host.slots[s].hit.extent(), large);
        let got = host.hits(s, &shot, &pass);
        assert_bit_identical(&got, &expected, &format!("slot {s} after resize"));
    }

    // And back down, again with frames in flight (the frames after it record at the new
    // size and match a standalone frame of it); a refused resize changes nothing.
    host.frame(&mut pass);
    host.frame(&mut pass);
    pass.resize(small).unwrap();
    host.resize(small);
    for _ in 0..2 {
        host.frame(&mut pass);
    }
    host.wait_all();
    let expected = standalone(&ctx, &rocks, method, params, small);
    for s in 0..SLOTS {
        let got = host.hits(s, &shot, &pass);
        assert_bit_identical(&got, &expected, &format!("slot {s} after resizing back"));
    }
    assert!(
        pass.resize(vk::Extent2D {
            width: 0,
            height: 64
        })
        .is_err()
    );
    assert_eq!(
        pass.settings().extent,
        small,
        "a refused resize changes nothing"
    );
    teardown(ctx, pass, host, shot);
}

#[test]
fn set_method_with_frames_in_flight_matches_standalone_for_each_method() {
    let ctx = validated_context();
    let rocks = asset_map("rocks_depth.jpg", Convention::Depth);
    let extent = vk::Extent2D {
        width: 96,
        height: 64,
    };
    let dig8 = MethodParams {
        block: [8, 8],
        ..MethodParams::for_method(Method::DigGuarded)
    };
    let relief16 = MethodParams {
        steps: 16,
        ..MethodParams::for_method(Method::Relief)
    };
    // Each step: the method, its parameters, and the passes its first and later frames
    // record (what the switch had to build: a pyramid only when its kind changed, grids
    // only when absent or of another block size).
    #[allow(clippy::type_complexity)]
    let steps: [(Method, MethodParams, &[&str], &[&str]); 9] = [
        (
            Method::Relief,
            MethodParams::for_method(Method::Relief),
            &["upload", "classify", "trace"],
            &["classify", "trace"],
        ),
        (
            Method::Exact,
            MethodParams::for_method(Method::Exact),
            &["pyramid", "classify", "trace"],
            &["classify", "trace"],
        ),
        (
            Method::Dig,
            MethodParams::for_method(Method::Dig),
            &["classify", "dig_corners", "trace"],
            &["classify", "dig_corners", "trace"],
        ),
        (
            Method::DigGuarded,
            dig8,
            &["pyramid", "classify", "dig_corners", "trace"],
            &["classify", "dig_corners", "trace"],
        ),
        (
            Method::Pyramid,
            MethodParams::for_method(Method::Pyramid),
            &["pyramid", "classify", "trace"],
            &["classify", "trace"],
        ),
        // The cone maps follow their kind: a relaxed map replaces the conservative one
        // and back (the cell pyramid stays).
        (
            Method::Cone,
            MethodParams::for_method(Method::Cone),
            &["pyramid", "cone", "classify", "trace"],
            &["classify", "trace"],
        ),
        (
            Method::RelaxedCone,
            MethodParams::for_method(Method::RelaxedCone),
            &["cone", "classify", "trace"],
            &["classify", "trace"],
        ),
        (
            Method::ConeExact,
            MethodParams::for_method(Method::ConeExact),
            &["cone", "classify", "trace"],
            &["classify", "trace"],
        ),
        (
            Method::Relief,
            relief16,
            &["classify", "trace"],
            &["classify", "trace"],
        ),
    ];
    let shot = OneShot::new(&ctx, "test.readback").unwrap();
    let mut host = Host::new(ctx.clone(), Scene::default(), extent);
    let (m0, p0, _, _) = steps[0];
    let mut pass =
        DisplacementPass::with_iterations(ctx.clone(), &rocks, settings(m0, p0, extent), true)
            .unwrap();
    for (i, &(method, params, first, later)) in steps.iter().enumerate() {
        assert_eq!(
            host.frame(&mut pass),
            first,
            "{} first frame",
            method.name()
        );
        for _ in 0..2 {
            assert_eq!(
                host.frame(&mut pass),
                later,
                "{} later frame",
                method.name()
            );
        }
        // Switch while this method's frames are in flight (both slots submitted); a
        // refused switch changes nothing.
        assert!(host.frames.all_in_flight());
        let bad = MethodParams {
            steps: 0,
            ..MethodParams::default()
        };
        assert!(pass.set_method(Method::Dig, bad).is_err());
        assert_eq!(
            (pass.settings().method, pass.settings().params),
            (method, params)
        );
        if let Some(&(next, next_params, _, _)) = steps.get(i + 1) {
            pass.set_method(next, next_params).unwrap();
            assert_eq!(pass.settings().method, next);
        }
        // The frames recorded before the switch finish with the old method (whose
        // retired resources are still alive) and match the standalone renderer.
        host.wait_all();
        let expected = standalone(&ctx, &rocks, method, params, extent);
        for s in 0..SLOTS {
            let got = host.hits(s, &shot, &pass);
            assert_bit_identical(&got, &expected, &format!("{} slot {s}", method.name()));
        }
    }
    teardown(ctx, pass, host, shot);
}
