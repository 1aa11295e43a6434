//! `dispmap bench`: the benchmark's configuration from the command line, its run with a
//! progress bar, its outputs, and the summary printed at the end.

use crate::args::BenchArgs;
use crate::finish_with;
use anyhow::{Context as _, Result, bail};
use dispmap::context::{Context, ContextOptions};
use dispmap::method::Method;
use dispmap_cli::{bench, bundled, memory, output};
use std::sync::Arc;

pub(crate) fn bench_command(options: &ContextOptions, args: &BenchArgs) -> Result<()> {
    // Everything that can be wrong with the input fails here, before any GPU work.
    let mut config = bench::BenchConfig {
        frame: [args.size.0, args.size.1],
        frames: args.frames,
        repeat: args.repeat,
        error_frames: args.error_frames,
        steps: bench::parse_steps(&args.steps)?,
        methods: bench::parse_methods(&args.methods)?,
        sizes: bench::parse_sizes(&args.sizes)?,
        size_steps: args.size_steps,
        shadows: args.shadows,
        materials: args.materials == "on",
        silhouettes: args.silhouettes == "on",
        forward: args.forward == "on",
        ..bench::BenchConfig::default()
    };
    config.validate()?;
    let mut maps = Vec::new();
    for name in bench::parse_maps(&args.maps)? {
        maps.push(bench::MapSpec::bundled(&name)?);
    }
    if let (Some(path), Some(convention)) = (&args.heightmap, args.convention) {
        maps.push(bench::MapSpec::load(path, convention)?);
    }
    let size_source = if config.sizes.is_empty() {
        None
    } else {
        Some(bench::MapSpec {
            name: args.size_map.clone(),
            field: bundled::by_name(&args.size_map, "--size-map")?,
        })
    };
    if maps.is_empty() && size_source.is_none() {
        bail!("invalid --maps: no map to benchmark (give --maps or --heightmap)");
    }
    // The largest map (or sweep size) with the frame, the reference and the heat maps.
    // One renderer per method is alive at once (runs interleaved frame by frame).
    let extras = memory::Extras {
        reference: true,
        heatmap: true,
        depth: false,
        maps: memory::MethodMaps::together(&config.methods),
        mesh: memory::MeshSize::default(),
        images: memory::MaterialMaps::default(),
        // The silhouettes' scenes: generated meshes (a sphere at most) traced curved.
        curved: memory::Curved {
            on: config.silhouettes,
            walked_triangles: memory::Curved::object_triangles(
                config.silhouettes,
                dispmap::scene::Geometry::Sphere,
                Some(Method::Exact),
                &memory::MeshSize::default(),
            ),
        },
    };
    let sweep_extras = memory::Extras {
        maps: memory::MethodMaps::together(&config.size_methods),
        ..extras
    };
    let mut candidates: Vec<(memory::MapSize, String, memory::Extras)> = maps
        .iter()
        .map(|m| (memory::MapSize::loaded(&m.field), m.name.clone(), extras))
        .collect();
    if let Some(source) = &size_source {
        let bytes = memory::MapSize::loaded(&source.field).texel_bytes;
        for &side in &config.sizes {
            let map = memory::MapSize {
                size: [side, side],
                texel_bytes: bytes,
                load_bytes: 0,
            };
            candidates.push((
                map,
                format!("{} resampled to {side}x{side}", source.name),
                sweep_extras,
            ));
        }
    }
    if let Some((estimate, name)) = candidates
        .into_iter()
        .map(|(map, name, extras)| (memory::estimate(map, config.frame, extras), name))
        .max_by_key(|(e, _)| e.bytes)
    {
        let what = format!(
            "benchmarking {}x{} frames on {name} with the reference",
            config.frame[0], config.frame[1]
        );
        memory::check(&estimate, args.max_memory, &what)?;
    }
    // The folder is created and filled only when every result is in (all files at once).
    // Each file it will hold is checked now too (a read-only results.csv, a folder
    // named report.md), not after the run.
    let mut names = vec!["results.csv".to_owned(), "report.md".to_owned()];
    for map in maps.iter().map(|m| &m.name) {
        names.push(bench::report::pareto_file(map));
        let stem = bench::file_stem(map);
        for method in &config.methods {
            names.push(format!("heatmap_{stem}_{}.png", method.name()));
        }
        if config.methods.contains(&Method::Dig) {
            names.push(format!("intervals_{stem}.png"));
        }
    }
    if size_source.is_some() {
        names.push(bench::report::SIZES_PLOT.to_owned());
    }
    output::check_folder_files(&args.out, &names).context("invalid --out")?;

    let ctx = Arc::new(Context::headless(options)?);
    // Everything that uses the device, then `finish_with` checks validation whether it
    // succeeded or was refused.
    let result = (|| -> Result<_> {
        dispmap_cli::frame_limit::check(&ctx, config.frame[0], config.frame[1], "--size")?;
        let bar = if args.quiet {
            indicatif::ProgressBar::hidden()
        } else {
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(1),
                indicatif::ProgressDrawTarget::stderr(),
            );
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "[{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta:>4} {msg}",
                )
                .expect("the template is valid")
                .progress_chars("=> "),
            );
            bar
        };
        eprintln!(
            "dispmap bench: {} map(s), {} method(s), steps {}, {}x{}, {} frames, on {} ({})",
            maps.len(),
            config.methods.len(),
            args.steps,
            config.frame[0],
            config.frame[1],
            config.frames,
            ctx.info().name,
            ctx.info().driver
        );
        let results = bench::run(&ctx, &config, &maps, size_source.as_ref(), &mut |p| {
            bar.set_length(p.total);
            bar.set_position(p.done);
            bar.set_message(p.stage.clone());
        });
        bar.finish_and_clear();
        let results = results?;
        let command = command_line();
        let outputs = bench::stage_outputs(&args.out, &results, &command)?;
        let written = outputs.paths();
        print_bench_summary(&results);
        // What the run is too short or too noisy for: after the tables, where it is read.
        for warning in bench::verdict::warnings(&results) {
            eprintln!("warning: {warning}");
        }
        println!(
            "\nwrote {} files to {} in {:.0} s (report.md, results.csv, plots, heat maps)",
            written.len(),
            args.out.display(),
            results.wall.as_secs_f64()
        );
        Ok(outputs)
    })();
    let outputs = finish_with(ctx, result)?;
    outputs.commit()?;
    Ok(())
}

/// The command line as typed (arguments with spaces or quotes are single-quoted).
pub(crate) fn command_line() -> String {
    let mut parts = vec!["dispmap".to_owned()];
    for a in std::env::args().skip(1) {
        if a.is_empty() || a.contains(|c: char| c.is_whitespace() || c == '\'' || c == '"') {
            parts.push(format!("'{}'", a.replace('\'', r"'\''")));
        } else {
            parts.push(a);
        }
    }
    parts.join(" ")
}

pub(crate) fn print_bench_summary(results: &bench::BenchResults) {
    use bench::curves::{
        Measure, Speedup, equal_error_speedup, equal_error_speedup_at_dig, same_setting_speedup,
    };
    let cell = |s: Option<Speedup>| match s {
        Some(Speedup::Ratio(x)) => format!("{x:.2}x"),
        Some(Speedup::AtLeast(x)) => format!(">={x:.2}x"),
        Some(Speedup::AtMost(x)) => format!("<={x:.2}x"),
        Some(Speedup::OtherNeverReaches) => "never".into(),
        Some(Speedup::DigNeverReaches) => "dig never".into(),
        None => "-".into(),
    };
    println!(
        "\nDIG's speed-up (method time: dig_corners + trace) over pom / relief: at the same \
         setting; at equal artifact fraction (a) on DIG's curve at the other's error, (b) on \
         the other's curve at DIG's error (never: the other never gets that low):"
    );
    println!(
        "{:<10} {:>5} {:>8} {:>10} {:>10} {:>8} {:>10} {:>10}",
        "map", "iter", "pom", "pom (a)", "pom (b)", "relief", "relief (a)", "relief (b)"
    );
    for map in &results.maps {
        for &steps in &results.config.steps {
            let rows = &results.rows;
            let same = |m| {
                same_setting_speedup(rows, &map.name, m, steps)
                    .map_or_else(|| "-".into(), |(x, _)| format!("{x:.2}x"))
            };
            let a = |m| {
                cell(equal_error_speedup(
                    rows,
                    &map.name,
                    m,
                    steps,
                    Measure::ArtifactFraction,
                ))
            };
            let b = |m| {
                cell(equal_error_speedup_at_dig(
                    rows,
                    &map.name,
                    m,
                    steps,
                    Measure::ArtifactFraction,
                ))
            };
            println!(
                "{:<10} {:>5} {:>8} {:>10} {:>10} {:>8} {:>10} {:>10}",
                map.name,
                steps,
                same(Method::Pom),
                a(Method::Pom),
                b(Method::Pom),
                same(Method::Relief),
                a(Method::Relief),
                b(Method::Relief)
            );
        }
    }
    if let Some(b) = &results.silhouettes {
        for c in &b.scenes {
            println!(
                "silhouettes, {}: with / without {:.3} ({:.3}-{:.3}; medians {:.3}; bound {}), \
                 {:.1}% curved, {:.2}% missed",
                c.scene,
                c.ratio.min,
                c.ratio.lo,
                c.ratio.hi,
                c.median_ratio,
                bench::silhouettes::SILHOUETTE_BOUND,
                100.0 * c.curved_share,
                100.0 * c.missed_share,
            );
        }
    }
    if let Some(m) = &results.materials {
        use bench::materials::{DISJOINT_BOUND, TENTH_BOUND};
        let verdict = |v: f64, bound: f64| if v <= bound { "met" } else { "MISSED" };
        println!(
            "materials: (a) together / alone trace {:.3} ({:.3}-{:.3}; medians {:.3}; bound \
             {DISJOINT_BOUND}: {}); (b) {:.1}% displaced / fully displaced pass {:.3} \
             ({:.3}-{:.3}; medians {:.3}; bound {TENTH_BOUND}: {})",
            m.disjoint_ratio.min,
            m.disjoint_ratio.lo,
            m.disjoint_ratio.hi,
            m.disjoint_median_ratio,
            verdict(m.disjoint_ratio.min, DISJOINT_BOUND),
            100.0 * m.tenth_share,
            m.tenth_ratio.min,
            m.tenth_ratio.lo,
            m.tenth_ratio.hi,
            m.tenth_median_ratio,
            verdict(m.tenth_ratio.min, TENTH_BOUND),
        );
    }
    // The verdict: the cheapest method at each error level, per map.
    println!("\ncheapest method (method time) at each artifact level:");
    for map in &results.maps {
        let picks: Vec<String> = bench::verdict::cheapest(results, &map.name)
            .iter()
            .map(|p| {
                let level = bench::verdict::percent(p.target);
                match p.best {
                    Some((m, t)) => format!("{level} {m} {t:.2} ms"),
                    None => format!("{level} none"),
                }
            })
            .collect();
        println!("{:<10} {}", map.name, picks.join(", "));
    }
}
