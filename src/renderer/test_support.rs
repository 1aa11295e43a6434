//! What the renderer's GPU tests share: a validated context, a bumpy height field, and
//! the check that validation said nothing.

use super::*;
use crate::context::ContextOptions;

/// A headless context with the Khronos validation layer on.
pub(super) fn validated_context() -> Arc<Context> {
    Arc::new(
        Context::headless(&ContextOptions {
            validation: Some(true),
            device: None,
        })
        .expect("a validated Vulkan context (./scripts/setup-debian.sh)"),
    )
}

/// A 64 x 64 field of `u_cycles` by `v_cycles` sine bumps about 0.5, from 0 to 1.
pub(super) fn bumps(u_cycles: f32, v_cycles: f32) -> HeightField {
    HeightField::from_fn(64, 64, "bumps", |u, v| {
        0.5 + 0.5
            * (u * u_cycles * std::f32::consts::TAU).sin()
            * (v * v_cycles * std::f32::consts::TAU).cos()
    })
    .unwrap()
}

/// Fails on any validation error or warning `ctx` recorded (after the caller dropped
/// everything that used it).
pub(super) fn assert_no_validation_messages(ctx: Arc<Context>) {
    let m = ctx.messages().clone();
    drop(ctx);
    assert_eq!((m.errors(), m.warnings()), (0, 0), "validation messages");
}
