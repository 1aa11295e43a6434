//! A `DisplacementPass` dropped without `destroy` logs a warning in debug builds; one
//! destroyed first logs nothing on drop.
//!
//! Its own test binary: it installs a capturing `log` logger (before anything can install
//! `env_logger`), and has a single test, so no other test's records mix in.
//!
//! The dropped-without-destroy pass leaks its Vulkan objects. Destroying the device with
//! them alive would be invalid usage (the validation layer's object tracker reports each
//! one at `vkDestroyDevice`), so this test deliberately never destroys its context: it is
//! leaked with `std::mem::forget` and the process exit reclaims it. Validation stays on
//! and must report nothing for everything the test does; every other test keeps the
//! "fail on any validation message, device destruction included" guarantee.

mod common;

use ash::vk;
use common::{asset_map, validated_context};
use dispmap::embed::{DisplacementPass, PassSettings};
use dispmap::heightfield::Convention;
use dispmap::method::{Method, MethodParams};
use dispmap::scene::Scene;
use std::sync::Mutex;

/// Every record logged in this process: level and message.
static RECORDS: Mutex<Vec<(log::Level, String)>> = Mutex::new(Vec::new());

struct Capture;

impl log::Log for Capture {
    fn enabled(&self, _: &log::Metadata<'_>) -> bool {
        true
    }

    fn log(&self, record: &log::Record<'_>) {
        RECORDS
            .lock()
            .unwrap()
            .push((record.level(), record.args().to_string()));
    }

    fn flush(&self) {}
}

/// The pass's drop warnings logged since the last call (and forgets them).
fn drop_warnings() -> Vec<String> {
    RECORDS
        .lock()
        .unwrap()
        .drain(..)
        .filter(|(level, text)| {
            *level == log::Level::Warn && text.contains("DisplacementPass dropped without destroy")
        })
        .map(|(_, text)| text)
        .collect()
}

#[test]
fn dropping_without_destroy_warns_in_debug_builds_and_destroy_then_drop_is_silent() {
    log::set_boxed_logger(Box::new(Capture)).expect("the first logger of this binary");
    log::set_max_level(log::LevelFilter::Trace);

    let ctx = validated_context(); // its env_logger init is refused: ours stays
    let rocks = asset_map("rocks_depth.jpg", Convention::Depth);
    let scene = Scene::default();
    // DIG with the pyramid guard: every optional part (pyramid, per-slot grids) exists.
    let method = Method::DigGuarded;
    let settings = PassSettings {
        method,
        params: MethodParams::for_method(method),
        depth_scale: scene.depth_scale,
        addressing: scene.addressing(),
        extent: vk::Extent2D {
            width: 32,
            height: 16,
        },
        frames_in_flight: 2,
    };
    drop_warnings();

    // destroy, then drop: nothing logged. A second destroy frees nothing twice (every
    // handle was nulled or taken by the first; a second vkDestroy of one would be a
    // validation error below).
    let mut pass = DisplacementPass::new(ctx.clone(), &rocks, settings).unwrap();
    // SAFETY: nothing was recorded with the pass.
    unsafe { pass.destroy() };
    // SAFETY: as above; the pass holds nothing any more.
    unsafe { pass.destroy() };
    drop(pass);
    assert_eq!(drop_warnings(), Vec::<String>::new());

    // The same for the G-buffer, the pipelines and a trace pass of the standalone parts.
    {
        use dispmap::gpu::owned::Destroy;
        use dispmap::passes::gbuffer::{GBuffer, GBufferPass};
        use dispmap::passes::trace::TracePass;
        let extent = settings.extent;
        let mut gbuffer = GBuffer::new_curved(&ctx, extent).unwrap();
        let mut mesh = GBufferPass::new_layer(&ctx, true, false, true, true).unwrap();
        let mut trace = TracePass::new(&ctx, Method::Exact, true, true).unwrap();
        // SAFETY: nothing recorded with them; the second call finds nothing to free.
        unsafe {
            gbuffer.destroy(&ctx);
            gbuffer.destroy(&ctx);
            mesh.destroy(&ctx);
            mesh.destroy(&ctx);
            trace.destroy(&ctx);
            trace.destroy(&ctx);
        }
    }

    // drop without destroy: one warning in debug builds (none in release builds, where
    // the check is compiled out).
    let pass = DisplacementPass::new(ctx.clone(), &rocks, settings).unwrap();
    drop(pass);
    let warnings = drop_warnings();
    if cfg!(debug_assertions) {
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("call destroy()"), "{warnings:?}");
    } else {
        assert!(warnings.is_empty(), "{warnings:?}");
    }

    // Validation saw nothing wrong so far.
    let m = ctx.messages();
    assert!(ctx.has_messenger());
    assert_eq!((m.errors(), m.warnings()), (0, 0), "validation messages");
    // The leaked pass's objects must never meet vkDestroyDevice (see the module docs).
    std::mem::forget(ctx);
}
