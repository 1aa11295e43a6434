//! `cargo bench`: a reduced run of `dispmap bench` (the same protocol through
//! `dispmap_cli::bench`): 480x270 frames, 3 frames per run (error on the first), settings 75
//! and 150, every default method (`Method::defaults`) on the rocks, bricks and mountains
//! maps, and a 256/2048 map-size sweep. Times are GPU timestamp medians, not wall-clock: compare ratios within one run
//! (on lavapipe they are CPU times). Prints the report's tables and writes the full
//! outputs to `target/dispmap-bench/`.
//!
//! Arguments other than cargo's `--bench` select methods by name substring among all of
//! them (`cargo bench -- dig pom`, `cargo bench -- cone-exact`).

use dispmap::context::{Context, ContextOptions};
use dispmap::method::Method;
use dispmap_cli::bench::{self, BenchConfig, MapSpec};
use std::path::Path;

fn main() -> anyhow::Result<()> {
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let methods: Vec<Method> = if filter.is_empty() {
        Method::defaults()
    } else {
        Method::ALL
            .iter()
            .copied()
            .filter(|m| filter.iter().any(|f| m.name().contains(f.as_str())))
            .collect()
    };
    anyhow::ensure!(!methods.is_empty(), "no method matches {filter:?}");
    let config = BenchConfig {
        frame: [480, 270],
        frames: 3,
        error_frames: Some(1),
        steps: vec![75, 150],
        methods,
        sizes: vec![256, 2048],
        ..BenchConfig::default()
    };
    let ctx = std::sync::Arc::new(Context::headless(&ContextOptions::default())?);
    let maps = bench::bundled_maps()?;
    let rocks = MapSpec::bundled("rocks")?;
    eprintln!(
        "cargo bench: reduced dispmap bench on {} ({}), {}x{}, {} frames, steps 75/150",
        ctx.info().name,
        ctx.info().driver,
        config.frame[0],
        config.frame[1],
        config.frames
    );
    let mut last = 0;
    let results = bench::run(&ctx, &config, &maps, Some(&rocks), &mut |p| {
        let percent = p.done * 100 / p.total.max(1);
        if percent >= last + 10 {
            last = percent - percent % 10;
            eprintln!("{percent:>3}% {}", p.stage);
        }
    })?;
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/dispmap-bench");
    bench::write_outputs(&out, &results, "cargo bench (benches/passes.rs)")?;
    println!(
        "{}",
        bench::report::markdown(&results, "cargo bench (benches/passes.rs)")
    );
    println!("outputs: {}", out.display());
    Ok(())
}
