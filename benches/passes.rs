//! `cargo bench`: per-pass GPU time (timestamp medians) of every method on the bundled
//! rocks map, with its error against the exact reference. Not wall-clock: the numbers
//! come from timestamp queries, so compare ratios within one run (on lavapipe they are
//! CPU times).

use dispmap::context::{Context, ContextOptions};
use dispmap::method::{Method, MethodParams};
use dispmap::reference::Reference;
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Scene};

fn main() -> anyhow::Result<()> {
    // `cargo bench` passes `--bench`; any other argument filters methods by name.
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let ctx = Context::headless(&ContextOptions::default())?;
    let field = dispmap::bundled::rocks()?;
    let frames = 9;
    let base = RenderSettings {
        width: 480,
        height: 270,
        method: Method::Bump,
        params: MethodParams::default(),
        scene: Scene {
            camera: Camera {
                elevation_deg: 20.0,
                ..Camera::default()
            },
            ..Scene::default()
        },
    };
    println!(
        "dispmap bench: {} on {} ({}), {}x{}, median of {frames} frames",
        field.label(),
        ctx.info().name,
        ctx.info().driver,
        base.width,
        base.height
    );
    let mut renderer = Renderer::new(&ctx, &field, base)?;
    let reference = Reference::new(&field, base.scene.addressing());
    let frame_ref = renderer.reference(&reference)?;
    println!(
        "{:<12} {:>6} {:>10} {:>10} {:>10} {:>8} {:>10}",
        "method", "steps", "trace ms", "total ms", "vs bump", "iters", "artifact%"
    );
    let mut bump_trace = None;
    for &method in Method::ALL {
        if !filter.is_empty() && !filter.iter().any(|f| method.name().contains(f.as_str())) {
            continue;
        }
        // Methods without a step count (bump, pyramid, exact) run once.
        let steps_list: &[u32] = match method {
            Method::Bump | Method::Pyramid | Method::Exact => &[1],
            Method::Secant => &[15, 30],
            _ => &[32, 64, 128],
        };
        for &steps in steps_list {
            renderer.set_method(method, MethodParams::with_steps(steps))?;
            let m = renderer.measure(&frame_ref, frames)?;
            let get = |n: &str| {
                m.timings_ms
                    .iter()
                    .find(|(k, _)| k == n)
                    .map_or(0.0, |(_, v)| *v)
            };
            let trace = get("trace");
            if method == Method::Bump {
                bump_trace = Some(trace);
            }
            let ratio = bump_trace.map_or(f64::NAN, |b| trace / b);
            println!(
                "{:<12} {:>6} {:>10.3} {:>10.3} {:>9.1}x {:>8.1} {:>10.3}",
                method.name(),
                steps,
                trace,
                get("total"),
                ratio,
                m.error.mean_iterations,
                100.0 * m.error.artifact_fraction
            );
        }
    }
    Ok(())
}
