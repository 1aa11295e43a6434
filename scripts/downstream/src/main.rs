//! A crate outside dispmap's repository, depending on it by path: it must
//! build with no `.cargo/config.toml`, then render one small frame with the validation
//! layer on. Exits non-zero on any validation message or any non-finite hit texel.
//!
//! Built and run by `scripts/downstream-check.sh`.

use dispmap::{
    Context, ContextOptions, HeightField, Method, MethodParams, RenderSettings, Renderer, Scene,
};
use std::error::Error;
use std::sync::Arc;

const SIDE: u32 = 64;

/// dispmap's G-buffer include as the build script found it (DEP_DISPMAP_INCLUDE).
const GBUFFER_GLSL: &str = include_str!(concat!(env!("OUT_DIR"), "/dispmap_gbuffer.glsl"));

fn main() -> Result<(), Box<dyn Error>> {
    if !GBUFFER_GLSL.contains("dispmap_gbuffer_encode_material") {
        return Err("DEP_DISPMAP_INCLUDE did not lead to dispmap's G-buffer include".into());
    }
    let field = HeightField::from_fn(SIDE, SIDE, "downstream bumps", |u, v| {
        let tau = std::f32::consts::TAU;
        0.5 + 0.25 * (3.0 * tau * u).sin() * (2.0 * tau * v).cos()
    })?;
    let settings = RenderSettings {
        width: SIDE,
        height: SIDE,
        method: Method::Relief,
        params: MethodParams::default(),
        scene: Scene::default(),
        shadows: Default::default(),
    };

    // The only calls that depend on how the context is shared: a validated headless
    // context (the device: DISPMAP_DEVICE, else the best one; lavapipe on CI), one frame,
    // its hit buffer. `&ctx` is a `&Arc<Context>`, which also coerces to `&Context`.
    let ctx = Arc::new(Context::headless(&ContextOptions {
        validation: Some(true),
        device: None,
    })?);
    if !ctx.has_messenger() {
        return Err("no debug messenger: validation messages would go unseen".into());
    }
    let device = ctx.info().name.clone();
    let messages = ctx.messages().clone();
    let hits = {
        let mut renderer = Renderer::new(&ctx, &field, settings)?;
        renderer.render()?;
        renderer.read_hits()?
    };
    // Destroy the device too: the validation layer reports leaked objects there.
    let ctx = Arc::into_inner(ctx).ok_or("the renderer left a holder of the context")?;
    drop(ctx);

    let non_finite = hits
        .iter()
        .filter(|t| !t.iter().all(|x| x.is_finite()))
        .count();
    let hit = hits.iter().filter(|t| t[2] >= 0.0).count();
    println!(
        "downstream: {SIDE}x{SIDE} frame on {device}: {hit} of {} pixels hit, {non_finite} \
         non-finite; validation: {} errors, {} warnings",
        hits.len(),
        messages.errors(),
        messages.warnings()
    );
    if hits.len() != (SIDE * SIDE) as usize {
        return Err(format!("{} hit texels, expected {}", hits.len(), SIDE * SIDE).into());
    }
    if non_finite > 0 {
        return Err(format!("{non_finite} hit texels are not finite").into());
    }
    if hit == 0 {
        return Err("no pixel hit the surface".into());
    }
    if messages.errors() > 0 || messages.warnings() > 0 {
        // dispmap logs each message through the `log` crate; this crate (dispmap only)
        // installs no logger, so only the counts are known here.
        return Err(
            "validation reported errors or warnings: reproduce in the checkout \
                    with a logger (e.g. RUST_LOG=warn cargo test) to read them"
                .into(),
        );
    }
    Ok(())
}
