//! The benchmark on a tiny sweep, through the library and through the binary, with
//! validation on: every output exists and is well formed. No timing is asserted.

#[path = "../../tests/common/mod.rs"]
mod common;

use common::{finish, validated_context};
use dispmap::method::Method;
use dispmap_cli::bench::{self, BenchConfig, MapSpec, Sweep};
use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dispmap-bench-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Reads `results.csv`: checks the header and that every non-empty numeric cell is a
/// finite number; returns the rows.
fn read_csv(path: &Path) -> Vec<bench::RunRow> {
    let bytes = std::fs::read(path).unwrap();
    let mut reader = csv::Reader::from_reader(bytes.as_slice());
    let header: Vec<String> = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    assert_eq!(header, bench::CSV_HEADER);
    let text_columns = ["sweep", "map", "method", "frame_set"];
    for record in csv::Reader::from_reader(bytes.as_slice()).records() {
        let record = record.unwrap();
        assert_eq!(record.len(), header.len());
        for (name, cell) in header.iter().zip(record.iter()) {
            if text_columns.contains(&name.as_str()) || cell.is_empty() {
                continue;
            }
            let v: f64 = cell
                .parse()
                .unwrap_or_else(|_| panic!("{name} = '{cell}' is not a number"));
            assert!(v.is_finite() && v >= 0.0, "{name} = {v}");
        }
    }
    reader.deserialize().map(|r| r.unwrap()).collect()
}

fn png_size(path: &Path) -> (u32, u32) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (img.width(), img.height())
}

fn no_temporary_files(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".tmp"), "left {name}");
    }
}

#[test]
fn library_sweep_writes_every_output() {
    let ctx = validated_context();
    let config = BenchConfig {
        frame: [96, 54],
        frames: 1,
        error_frames: None,
        steps: vec![32, 16],
        methods: vec![Method::Dig, Method::Relief, Method::Exact],
        sizes: vec![64, 32],
        size_methods: vec![Method::Pyramid, Method::ConeExact, Method::Pom],
        size_steps: 16,
        ..BenchConfig::default()
    };
    let rocks = MapSpec::bundled("rocks").unwrap();
    let mut events = Vec::new();
    let results = bench::run(
        &ctx,
        &config,
        std::slice::from_ref(&rocks),
        Some(&rocks),
        &mut |p| events.push((p.done, p.total)),
    )
    .unwrap();
    let device = ctx.info().name.clone();
    finish(ctx);

    // Progress: monotone, ends complete.
    assert!(events.windows(2).all(|w| w[0].0 <= w[1].0), "{events:?}");
    let (done, total) = *events.last().unwrap();
    assert_eq!(done, total);

    // Lists are put in order; 2 methods x 2 settings and exact once, then 2 sizes x 3
    // methods.
    assert_eq!(results.config.steps, [16, 32]);
    assert_eq!(results.config.sizes, [32, 64]);
    let main: Vec<_> = results
        .rows
        .iter()
        .filter(|r| r.sweep == Sweep::Methods)
        .collect();
    let sizes: Vec<_> = results
        .rows
        .iter()
        .filter(|r| r.sweep == Sweep::MapSize)
        .collect();
    assert_eq!(main.len(), 5);
    assert_eq!(sizes.len(), 6);
    // The forward path (on by default): relief's two settings again, forward.
    let forward: Vec<_> = results
        .rows
        .iter()
        .filter(|r| r.sweep == Sweep::Forward)
        .collect();
    let settings: Vec<(&str, Option<u32>)> = forward
        .iter()
        .map(|r| (r.method.as_str(), r.steps))
        .collect();
    assert_eq!(settings, [("relief", Some(16)), ("relief", Some(32))]);
    for f in &forward {
        // No trace pass; the method time is the G-buffer pass with the march.
        assert_eq!(f.trace_ms, 0.0, "{f:?}");
        assert!(
            f.method_ms > 0.0 && f.method_ms >= f.gbuffer_ms * 0.999,
            "{f:?}"
        );
        let deferred = main
            .iter()
            .find(|r| r.method == f.method && r.steps == f.steps)
            .unwrap();
        // The same hits (bit for bit on lavapipe: tests/forward.rs), so the same errors.
        if device.contains("llvmpipe") {
            assert_eq!(f.forward_differing_pixels, Some(0), "{f:?}");
            assert_eq!(f.artifact_fraction, deferred.artifact_fraction);
            assert_eq!(f.iterations_mean, deferred.iterations_mean);
        }
    }
    assert_eq!(results.pass_medians.len(), results.rows.len());
    for r in &results.rows {
        assert!(
            r.total_median_lo_ms <= r.total_median_ms && r.total_median_ms <= r.total_median_hi_ms,
            "{r:?}"
        );
        assert_eq!(
            r.forward_differing_pixels.is_some(),
            r.sweep == Sweep::Forward,
            "{r:?}"
        );
        if r.sweep == Sweep::Forward {
            continue;
        }
        assert!(r.trace_ms > 0.0 && r.method_ms >= r.trace_ms, "{r:?}");
        assert!(r.total_ms >= r.method_ms, "{r:?}");
        assert_eq!(r.nonfinite_pixels, 0, "{r:?}");
        assert_eq!(r.error_frames, 1);
        assert!(r.iterations_mean > 0.0 && r.iterations_simd8 >= r.iterations_mean * 0.5);
        // The documented accuracy of the near-exact methods (docs/methods.md: `pyramid`
        // at most 0.1% of pixels off by a texel; `cone-exact` exact's, a tangency a frame
        // at most: 1 of these frames' 5184 pixels); the others' error is the method tests'.
        match r.method.as_str() {
            "pyramid" => assert!(r.artifact_fraction <= 0.001, "{r:?}"),
            "cone-exact" => assert!(r.artifact_fraction <= 1.0 / 5184.0, "{r:?}"),
            _ => {}
        }
        let dig = r.method == "dig";
        assert_eq!(r.dig_corners_ms.is_some(), dig, "{r:?}");
        assert_eq!(r.corner_iterations.is_some(), dig, "{r:?}");
        let needs = r.method().unwrap().needs();
        assert_eq!(
            r.pyramid_build_ms.is_some(),
            needs.pyramid.is_some(),
            "{r:?}"
        );
        assert_eq!(
            r.cone_build_ms.is_some(),
            r.method.starts_with("cone"),
            "{r:?}"
        );
    }
    let side: Vec<u32> = sizes.iter().map(|r| r.map_width).collect();
    assert_eq!(side, [32, 32, 32, 64, 64, 64]);

    let dir = scratch("lib");
    let written = bench::write_outputs(&dir, &results, "dispmap bench (test)").unwrap();
    for path in &written {
        assert!(path.is_file(), "{}", path.display());
    }
    let rows = read_csv(&dir.join("results.csv"));
    assert_eq!(rows, results.rows);

    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    for needle in [
        "## rocks",
        "| method | steps |",
        "DIG's speed-up at the same setting",
        "DIG's speed-up at equal error",
        "## Map-size sweep",
        "(pareto_rocks.png)",
        "(sizes.png)",
        "dispmap bench (test)",
        "## Several materials in one pass",
        "## The deferred frame against what engines do (the forward path)",
        "`dig` at equal error",
        "At DIG's equal-error point",
        "| (a) together / sum alone |",
        "## The cost of silhouettes",
        "| materials | ",
        &device,
    ] {
        assert!(md.contains(needle), "report.md lacks '{needle}'");
    }
    // The report opens with the verdict: per map, a method named at each error level
    // (exact reaches every level here).
    let first = md
        .split("\n## ")
        .nth(1)
        .expect("report.md has a first section");
    assert!(first.starts_with("Verdict"), "{first}");
    for map in &results.maps {
        let section = first
            .split(&format!("### {}\n", map.name))
            .nth(1)
            .unwrap_or_else(|| panic!("the verdict has no {} part: {first}", map.name));
        for target in bench::curves::ARTIFACT_TARGETS {
            let level = format!("| {} |", bench::verdict::percent(target));
            let line = section
                .lines()
                .find(|l| l.starts_with(&level))
                .unwrap_or_else(|| panic!("no {level} line in {section}"));
            let named = Method::ALL
                .iter()
                .any(|m| line.contains(&format!("| `{m}` |")));
            assert!(named, "no method named for {level}: {line}");
        }
    }
    // The material-table numbers: finite, positive, the tenth's share measured.
    let m = results.materials.as_ref().unwrap();
    assert_eq!(m.alone.len(), 3);
    for t in [
        m.disjoint_ratio,
        m.tenth_ratio,
        m.full_pass,
        m.combined_trace,
    ] {
        assert!(t.min.is_finite() && t.min > 0.0 && t.lo <= t.hi, "{t:?}");
    }
    assert!((0.05..0.2).contains(&m.tenth_share), "{}", m.tenth_share);
    // The cost of silhouettes: both scenes, finite positive times, the curved share of
    // the rocks sphere (every displaced pixel) and the materials scene's missed pixels.
    let b = results.silhouettes.as_ref().unwrap();
    let names: Vec<_> = b.scenes.iter().map(|c| c.scene.as_str()).collect();
    assert_eq!(names, ["rocks_sphere", "materials"]);
    for c in &b.scenes {
        for t in [c.without, c.with, c.ratio] {
            assert!(t.min.is_finite() && t.min > 0.0 && t.lo <= t.hi, "{c:?}");
        }
        assert!(c.curved_share > 0.05 && c.curved_share < 1.0, "{c:?}");
    }
    assert!(b.scenes[1].missed_share > 0.0, "{:?}", b.scenes[1]);
    assert!(b.scenes[1].behind.min > 0.0, "{:?}", b.scenes[1]);
    // One table line per run of the map.
    let run_lines = md
        .lines()
        .filter(|l| l.starts_with("| `relief` | "))
        .count();
    assert_eq!(run_lines, 2);

    assert_eq!(
        png_size(&dir.join("pareto_rocks.png")),
        bench::plot::PARETO_SIZE
    );
    assert_eq!(png_size(&dir.join("sizes.png")), bench::plot::SIZES_SIZE);
    assert_eq!(png_size(&dir.join("intervals_rocks.png")), (96, 54));
    // The heat maps carry their colour bar under the frame: the ramp from its first
    // colour at the left to its last at the right.
    let bar = bench::plot::HEAT_BAR_HEIGHT;
    for name in ["heatmap_rocks_relief.png", "heatmap_rocks_dig.png"] {
        assert_eq!(png_size(&dir.join(name)), (96, 54 + bar), "{name}");
        let img = image::open(dir.join(name)).unwrap().to_rgb8();
        let row = 54 + 8;
        assert_eq!(
            img.get_pixel(4, row).0,
            dispmap_cli::heatmap::ramp(0.0),
            "{name}"
        );
        assert_eq!(
            img.get_pixel(91, row).0,
            dispmap_cli::heatmap::ramp(1.0),
            "{name}"
        );
    }
    no_temporary_files(&dir);
}

fn dispmap() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dispmap"));
    c.env("DISPMAP_VALIDATION", "1");
    c
}

#[test]
fn cli_bench_writes_every_output() {
    let dir = scratch("cli");
    let out = dispmap()
        .args(["bench", "--out"])
        .arg(&dir)
        .args(["--size", "64x36", "--frames", "1", "--steps", "8,16"])
        .args([
            "--methods",
            "bump,pom",
            "--maps",
            "rocks",
            "--sizes",
            "32,64",
        ])
        .args(["--size-steps", "8", "--repeat", "1", "--quiet"])
        // The cost of silhouettes runs in library_sweep_writes_every_output.
        .args(["--silhouettes", "off"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("Validation"), "{stderr}");
    // One pass is too few for a spread: the console says so, and so does the report.
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("warning: only 1 pass(es)") && l.contains("--repeat 1")),
        "{stderr}"
    );
    let rows = read_csv(&dir.join("results.csv"));
    // bump once, pom twice (and twice forward); 2 sizes x (pyramid, exact, dig, pom): the
    // default size methods leave cone-exact out.
    let methods: Vec<(&str, Option<u32>)> = rows
        .iter()
        .filter(|r| r.sweep == Sweep::Methods)
        .map(|r| (r.method.as_str(), r.steps))
        .collect();
    assert_eq!(
        methods,
        [("bump", None), ("pom", Some(8)), ("pom", Some(16))]
    );
    assert_eq!(rows.iter().filter(|r| r.sweep == Sweep::MapSize).count(), 8);
    assert!(rows.iter().all(|r| r.method != "cone-exact"));
    assert_eq!(rows.iter().filter(|r| r.sweep == Sweep::Forward).count(), 2);
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("## rocks") && md.contains("## Map-size sweep"));
    let warning = md.find("> **Warning").expect("report.md warns");
    assert!(warning < md.find("## Verdict").unwrap() && md[warning..].contains("--repeat 1"));
    assert!(
        md.contains("--methods bump,pom"),
        "the command line is quoted"
    );
    assert_eq!(
        png_size(&dir.join("pareto_rocks.png")),
        bench::plot::PARETO_SIZE
    );
    assert_eq!(png_size(&dir.join("sizes.png")), bench::plot::SIZES_SIZE);
    for name in ["heatmap_rocks_bump.png", "heatmap_rocks_pom.png"] {
        assert_eq!(
            png_size(&dir.join(name)),
            (64, 36 + bench::plot::HEAT_BAR_HEIGHT),
            "{name}"
        );
    }
    no_temporary_files(&dir);
}

/// Each bad option fails before any work, names the option and writes nothing.
#[test]
fn cli_bench_rejects_bad_options_by_name() {
    let dir = scratch("bad");
    let cases: [(&[&str], &str); 11] = [
        (
            &["--size", "4096x4096", "--max-memory", "64M"],
            "--max-memory",
        ),
        (&["--methods", "pom,magic"], "--methods"),
        (&["--methods", ""], "--methods"),
        (&["--steps", "0"], "--steps"),
        (&["--steps", ""], "--steps"),
        (&["--steps", "75,,100"], "--steps"),
        (&["--sizes", "256,1"], "--sizes"),
        (&["--frames", "0"], "--frames"),
        (&["--frames", "2", "--error-frames", "3"], "--error-frames"),
        (&["--maps", "moon"], "--maps"),
        (&["--heightmap", "/no/such/map.png"], "--convention"),
    ];
    for (args, needle) in cases {
        let out = dispmap()
            .args(["bench", "--quiet", "--out"])
            .arg(&dir)
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(
            stderr.contains(needle),
            "{args:?}: '{needle}' not in: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(!dir.exists(), "{args:?} created {}", dir.display());
    }
    let out = dispmap()
        .args(["bench", "--quiet", "--out"])
        .arg(&dir)
        .args(["--heightmap", "/no/such/map.png", "--convention", "height"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/no/such/map.png"));
    assert!(!dir.exists());
}
