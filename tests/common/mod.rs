//! Shared set-up of the GPU tests: a validated context that fails the test on any
//! validation warning or error.

#![allow(dead_code)]

use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::{Convention, HeightField};
use std::path::Path;

/// A context with the Khronos validation layer (and synchronization validation) on.
/// Panics with a setup hint when no Vulkan driver or no validation layer is installed.
pub fn validated_context() -> Context {
    let _ = env_logger::builder().is_test(true).try_init();
    Context::headless(&ContextOptions {
        validation: Some(true),
        device: None,
    })
    .unwrap_or_else(|e| {
        panic!("cannot create a validated Vulkan context: {e}\n(run ./scripts/setup-debian.sh)")
    })
}

/// Asserts that validation reported nothing so far.
pub fn assert_validation_clean(ctx: &Context) {
    let m = ctx.messages();
    assert!(
        ctx.has_messenger(),
        "no debug messenger: validation messages would go unseen"
    );
    assert_eq!(
        (m.errors(), m.warnings()),
        (0, 0),
        "validation reported errors/warnings (see the log)"
    );
}

/// A height map from `assets/heightmaps`.
pub fn asset_map(name: &str, convention: Convention) -> HeightField {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/heightmaps")
        .join(name);
    HeightField::load(&path, convention).expect("bundled map loads")
}
