//! The report's opening: a verdict per map (the cheapest method at each error level, what
//! the exact family costs, DIG's speed-up beside its paper's claim) and the warnings
//! about statistics the run is too short for.

use super::curves::{
    ARTIFACT_TARGETS, Measure, TimeToError, curve, curve_rows, equal_error_speedup,
    lockstep_ceiling, same_setting_speedup, time_to_reach,
};
use super::materials::{DISJOINT_BOUND, MaterialsBench, TENTH_BOUND};
use super::{BenchResults, RunRow, trim_float};
use dispmap::method::Method;
use std::fmt::Write as _;

/// The DIG paper, cited in full.
pub const DIG_PAPER: &str = "John Judnich and Nam Ling, *Fast Per-Pixel Displacement \
                             Mapping with Screen-Space Depth Interval Grids*, electronic \
                             preprint, Santa Clara University, 2013";

/// The DIG paper's Table 1 (NVIDIA GeForce GTX 580, 2560x1440): DIG-DM's frame rate over
/// POM's per map at 75 and at 150 iterations.
pub const PAPER_SPEEDUPS: [(&str, f64, f64); 3] = [
    ("rocks", 2.17, 2.91),
    ("bricks", 1.64, 2.18),
    ("mountains", 2.90, 4.04),
];

/// Passes over the frames below which a spread says nothing about the noise.
pub const MIN_REPEAT: u32 = 3;

/// The cheapest method at one error level of one map.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    /// The error level (artifact fraction).
    pub target: f64,
    /// The cheapest method and the time it needs (method ms; for a method whose cheapest
    /// setting is already below the target, that setting's time: an upper bound).
    pub best: Option<(Method, f64)>,
    /// The next cheapest, if another method gets there.
    pub next: Option<(Method, f64)>,
}

/// For each of [`ARTIFACT_TARGETS`], the cheapest method of the run on `map` and the
/// next cheapest (read off each method's speed-error curve, [`time_to_reach`]).
pub fn cheapest(results: &BenchResults, map: &str) -> Vec<Pick> {
    ARTIFACT_TARGETS
        .iter()
        .map(|&target| {
            let mut times: Vec<(Method, f64)> = results
                .config
                .methods
                .iter()
                .filter_map(|&m| {
                    let c = curve(&results.rows, map, m, Measure::ArtifactFraction);
                    time_to_reach(&c, target).time().map(|t| (m, t))
                })
                .collect();
            times.sort_by(|a, b| a.1.total_cmp(&b.1));
            Pick {
                target,
                best: times.first().copied(),
                next: times.get(1).copied(),
            }
        })
        .collect()
}

/// A fraction as a percentage for tables: `20%`, `0.1%`.
pub fn percent(fraction: f64) -> String {
    format!("{}%", trim_float(100.0 * fraction))
}

/// The relative spread of a row's method time: highest over lowest per-pass minimum,
/// less one.
fn relative_spread(r: &RunRow) -> f64 {
    if r.method_lo_ms > 0.0 {
        r.method_hi_ms / r.method_lo_ms - 1.0
    } else {
        0.0
    }
}

/// The largest relative spread among `method`'s runs on `map`.
fn method_noise(rows: &[RunRow], map: &str, method: Method) -> f64 {
    curve_rows(rows, map, method)
        .into_iter()
        .map(relative_spread)
        .fold(0.0, f64::max)
}

/// The run's setting nearest `steps` (the paper's 75 and 150), if it has settings.
fn nearest_setting(steps: &[u32], want: u32) -> Option<u32> {
    steps.iter().copied().min_by_key(|s| s.abs_diff(want))
}

/// The verdict section: per map the cheapest method at each error level, the exact
/// family's cost and DIG against its paper.
pub fn markdown(results: &BenchResults) -> String {
    let c = &results.config;
    let rows = &results.rows;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Verdict\n\nOn {} at {}x{} ({} pass(es) over {} frames). **Cheapest** = the method \
         that reaches the error level in the least method time, read off its speed-error \
         curve (`<=`: its cheapest setting already does, so it may need less); times are \
         this run's and this device's: compare within a row, not across devices.",
        results.device, c.frame[0], c.frame[1], c.repeat, c.frames
    );
    for map in &results.maps {
        let name = &map.name;
        let _ = writeln!(
            s,
            "\n### {name}\n\n| artifacts at most | cheapest method | its ms | next cheapest |\n|---:|---|---:|---|"
        );
        for pick in cheapest(results, name) {
            let time = |m: Method, t: f64| {
                let c = curve(rows, name, m, Measure::ArtifactFraction);
                match time_to_reach(&c, pick.target) {
                    TimeToError::AtMost(_) => format!("<= {t:.2}"),
                    _ => format!("{t:.2}"),
                }
            };
            let (best, ms) = match pick.best {
                Some((m, t)) => (format!("`{m}`"), time(m, t)),
                None => (
                    "no method of this run reaches it".to_owned(),
                    "-".to_owned(),
                ),
            };
            let next = match (pick.best, pick.next) {
                (Some((bm, bt)), Some((m, t))) => {
                    let noise = method_noise(rows, name, bm).max(method_noise(rows, name, m));
                    let close = if t / bt - 1.0 <= noise {
                        " (within the spread: a tie)"
                    } else {
                        ""
                    };
                    format!("`{m}` {} ({:.2}x){close}", time(m, t), t / bt)
                }
                _ => "-".to_owned(),
            };
            let _ = writeln!(s, "| {} | {best} | {ms} | {next} |", percent(pick.target));
        }
        exact_family(&mut s, results, name);
        dig_against_paper(&mut s, results, name);
    }
    s
}

/// The exact family's line: each member's cost at its most accurate setting, in `bump`
/// units and against the cheapest method at the same error.
fn exact_family(s: &mut String, results: &BenchResults, map: &str) {
    let rows = &results.rows;
    let bump = curve_rows(rows, map, Method::Bump)
        .first()
        .map(|r| r.method_ms);
    let mut parts = Vec::new();
    for &m in results.config.methods.iter().filter(|m| m.is_exact()) {
        // The most accurate setting (the most steps, for `dig-guarded`).
        let Some(r) = curve_rows(rows, map, m).into_iter().last() else {
            continue;
        };
        let mut part = format!(
            "`{m}`{} {:.2} ms",
            r.steps
                .map_or_else(String::new, |st| format!(" at {st} steps")),
            r.method_ms
        );
        if let Some(b) = bump.filter(|b| *b > 0.0) {
            let _ = write!(part, " ({:.1}x `bump`)", r.method_ms / b);
        }
        let _ = write!(part, ", {:.3}% artifacts", 100.0 * r.artifact_fraction);
        // Who else gets as low, and for how much.
        let others: Vec<(Method, f64)> = results
            .config
            .methods
            .iter()
            .filter(|o| !o.is_exact())
            .filter_map(|&o| {
                let c = curve(rows, map, o, Measure::ArtifactFraction);
                time_to_reach(&c, r.artifact_fraction)
                    .time()
                    .map(|t| (o, t))
            })
            .collect();
        match others.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
            Some((o, t)) => {
                let _ = write!(part, "; `{o}` gets that low in {t:.2} ms");
            }
            None => part.push_str("; no other method run gets that low"),
        }
        parts.push(part);
    }
    if !parts.is_empty() {
        let _ = writeln!(
            s,
            "\n**The exact family** (the reference's first hit up to tangencies): {}.",
            parts.join("; ")
        );
    }
}

/// DIG's measured speed-up over POM at the paper's settings beside the paper's.
fn dig_against_paper(s: &mut String, results: &BenchResults, map: &str) {
    let c = &results.config;
    let rows = &results.rows;
    if !c.methods.contains(&Method::Dig) || !c.methods.contains(&Method::Pom) {
        return;
    }
    let paper = PAPER_SPEEDUPS.iter().find(|(n, _, _)| *n == map);
    let mut settings: Vec<u32> = [75, 150]
        .iter()
        .filter_map(|&want| nearest_setting(&c.steps, want))
        .collect();
    settings.dedup();
    let mut cells = Vec::new();
    for st in settings {
        let Some((method, frame)) = same_setting_speedup(rows, map, Method::Pom, st) else {
            continue;
        };
        let equal = equal_error_speedup(rows, map, Method::Pom, st, Measure::ArtifactFraction)
            .map_or_else(|| "-".to_owned(), |x| x.cell(Method::Pom));
        cells.push(format!(
            "at {st} steps {method:.2}x method time, {frame:.2}x whole frame, {equal} at \
             `pom`'s artifact fraction"
        ));
    }
    if cells.is_empty() {
        return;
    }
    let claim = paper.map_or_else(
        || "the paper has no figure for this map".to_owned(),
        |(_, at75, at150)| {
            format!(
                "the paper reports {at75:.2}x at 75 iterations and {at150:.2}x at 150 on this \
                 map (frame rate at the same iteration count; {DIG_PAPER}, Table 1, NVIDIA \
                 GeForce GTX 580 at 2560x1440)"
            )
        },
    );
    let _ = writeln!(
        s,
        "\n**DIG over POM**: measured {}; {claim}.",
        cells.join("; ")
    );
}

/// What the run is too short or too noisy for, one sentence each (empty: nothing).
pub fn warnings(results: &BenchResults) -> Vec<String> {
    let c = &results.config;
    let rows = &results.rows;
    let mut out = Vec::new();
    if c.repeat < MIN_REPEAT {
        out.push(format!(
            "only {} pass(es) over the frames (--repeat {}): a spread needs at least \
             {MIN_REPEAT} to show the noise, so every time and ratio of this run is unconfirmed",
            c.repeat, c.repeat
        ));
    }
    for map in &results.maps {
        let name = &map.name;
        let mut overlap = Vec::new();
        let mut over_ceiling = Vec::new();
        for &st in &c.steps {
            let Some(dig) = curve_rows(rows, name, Method::Dig)
                .into_iter()
                .find(|r| r.steps == Some(st))
            else {
                continue;
            };
            for other in [Method::Pom, Method::Relief] {
                let Some(o) = curve_rows(rows, name, other)
                    .into_iter()
                    .find(|r| r.steps == Some(st))
                else {
                    continue;
                };
                if dig.method_lo_ms <= o.method_hi_ms && o.method_lo_ms <= dig.method_hi_ms {
                    overlap.push(format!("`{other}` at {st}"));
                }
            }
            if let Some((_, share)) = lockstep_ceiling(rows, name, st)
                && share > 1.0
            {
                over_ceiling.push(format!("{:.0}% at {st}", 100.0 * share));
            }
        }
        if !overlap.is_empty() {
            out.push(format!(
                "{name}: the spreads of `dig` and {} overlap: those speed-ups are within noise",
                overlap.join(", ")
            ));
        }
        if !over_ceiling.is_empty() {
            out.push(format!(
                "{name}: DIG's speed-up over `relief` exceeds its lockstep ceiling ({}): more \
                 than the iteration counts allow, so those times are noise",
                over_ceiling.join(", ")
            ));
        }
        for &m in &c.methods {
            let curve = curve_rows(rows, name, m);
            for pair in curve.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                let (Some(sa), Some(sb)) = (a.steps, b.steps) else {
                    continue;
                };
                // The time follows the work: iterations per pixel (corner fetches
                // included).
                let work = |r: &RunRow| r.iterations_mean + r.corner_iterations.unwrap_or(0.0);
                if work(a) <= 0.0 || a.method_ms <= 0.0 {
                    continue;
                }
                let iters = work(b) / work(a);
                let ratio = b.method_ms / a.method_ms;
                // A fixed cost per pixel makes the time grow slower than the work, never
                // fall while it grows, nor grow much faster.
                if ratio < 0.9 * iters.min(1.0) || ratio > 1.5 * iters.max(1.0) {
                    out.push(format!(
                        "{name}: `{m}` takes {:.2} ms at {sa} steps and {:.2} ms at {sb}: a \
                         {ratio:.2}x change where its iterations per pixel change {iters:.2}x, \
                         so at least one of the two times is noise",
                        a.method_ms, b.method_ms
                    ));
                }
            }
        }
    }
    if let Some(m) = &results.materials {
        out.extend(materials_missed(m));
    }
    out
}

/// The materials benchmark's bounds the run missed.
fn materials_missed(m: &MaterialsBench) -> Vec<String> {
    let mut out = Vec::new();
    if m.disjoint_ratio.min > DISJOINT_BOUND {
        out.push(format!(
            "several materials: together / sum alone is {:.3}, over its bound of {DISJOINT_BOUND} \
             (missed)",
            m.disjoint_ratio.min
        ));
    }
    if m.tenth_ratio.min > TENTH_BOUND {
        out.push(format!(
            "several materials: {} displaced / fully displaced is {:.3}, over its bound of \
             {TENTH_BOUND} (missed)",
            percent(m.tenth_share),
            m.tenth_ratio.min
        ));
    }
    out
}

/// The warnings as the report's opening block (empty: none).
pub fn warnings_markdown(warnings: &[String]) -> String {
    if warnings.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "> **Warning: this run is too short or too noisy for some of its statistics.**\n>\n",
    );
    for w in warnings {
        let _ = writeln!(s, "> - {w}");
    }
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::{BenchConfig, MapInfo, Sweep};
    use std::time::{Duration, SystemTime};

    fn row(method: Method, steps: Option<u32>, ms: f64, artifacts: f64) -> RunRow {
        RunRow {
            sweep: Sweep::Methods,
            map: "rocks".into(),
            map_width: 64,
            map_height: 64,
            method: method.name().into(),
            steps,
            frame_width: 64,
            frame_height: 36,
            frames: 2,
            repeat: 1,
            error_frames: 1,
            frame_set: String::new(),
            gbuffer_ms: 0.5,
            pyramid_build_ms: None,
            cpu_pyramid_build_ms: None,
            cone_build_ms: None,
            dig_corners_ms: None,
            trace_ms: ms,
            shade_ms: 0.5,
            shadow_ms: None,
            method_ms: ms,
            method_median_ms: ms,
            method_lo_ms: ms,
            method_hi_ms: ms,
            total_ms: ms + 1.0,
            total_median_ms: ms + 1.0,
            method_median_lo_ms: ms,
            method_median_hi_ms: ms,
            total_median_lo_ms: ms + 1.0,
            total_median_hi_ms: ms + 1.0,
            iterations_mean: steps.map_or(10.0, f64::from),
            iterations_p99: 20.0,
            iterations_simd8: if method == Method::Relief { 30.0 } else { 12.0 },
            iterations_warp32: 14.0,
            iterations_quads8: 12.0,
            corner_iterations: (method == Method::Dig).then_some(1.0),
            mean_texels: 10.0 * artifacts,
            p99_texels: 1.0,
            max_texels: 2.0,
            artifact_fraction: artifacts,
            psnr_db: 30.0,
            nonfinite_pixels: 0,
            forward_differing_pixels: None,
        }
    }

    /// A run of `repeat` passes: `dig` cheapest down to 5% artifacts, `exact` alone
    /// below 3%.
    fn results(repeat: u32) -> BenchResults {
        let config = BenchConfig {
            steps: vec![10, 20],
            methods: vec![Method::Bump, Method::Relief, Method::Dig, Method::Exact],
            repeat,
            ..BenchConfig::default()
        };
        let rows = vec![
            row(Method::Bump, None, 1.0, 0.99),
            row(Method::Relief, Some(10), 2.0, 0.10),
            row(Method::Relief, Some(20), 3.0, 0.04),
            row(Method::Dig, Some(10), 1.5, 0.15),
            row(Method::Dig, Some(20), 2.5, 0.03),
            row(Method::Exact, None, 8.0, 0.0),
        ];
        BenchResults {
            config,
            device: "test device".into(),
            driver: "test".into(),
            api_version: "1.3".into(),
            traversal_rules: true,
            maps: vec![MapInfo {
                name: "rocks".into(),
                label: "rocks".into(),
                width: 64,
                height: 64,
                format: "R8_UNORM".into(),
                mean_height: 0.5,
            }],
            size_source: None,
            rows,
            pass_medians: Vec::new(),
            images: Vec::new(),
            started: SystemTime::UNIX_EPOCH,
            wall: Duration::from_secs(1),
            materials: None,
            silhouettes: None,
        }
    }

    #[test]
    fn the_cheapest_method_at_each_level() {
        let r = results(3);
        let picks = cheapest(&r, "rocks");
        let best: Vec<Option<Method>> = picks.iter().map(|p| p.best.map(|b| b.0)).collect();
        let d = Some(Method::Dig);
        let e = Some(Method::Exact);
        // 20%, 10%, 5%: dig (at most 1.5 ms, then read off its curve); 2% and below only
        // exact reaches.
        assert_eq!(best, [d, d, d, e, e, e]);
        assert_eq!(picks[0].best, Some((Method::Dig, 1.5)));
        assert_eq!(picks[0].next, Some((Method::Relief, 2.0)));
        assert_eq!(picks[3].next, None);
        let md = markdown(&r);
        assert!(md.starts_with("## Verdict"), "{md}");
        assert!(md.contains("### rocks"), "{md}");
        assert!(
            md.contains("| 20% | `dig` | <= 1.50 | `relief` <= 2.00 (1.33x) |"),
            "{md}"
        );
        assert!(md.contains("| 2% | `exact` | 8.00 | - |"), "{md}");
        // The exact family's cost in bump units; DIG over POM needs a pom run.
        assert!(md.contains("`exact` 8.00 ms (8.0x `bump`)"), "{md}");
        assert!(!md.contains("DIG over POM"), "{md}");
        // Three passes and separated spreads: nothing to warn about.
        assert_eq!(warnings(&r), Vec::<String>::new());
    }

    #[test]
    fn a_short_or_noisy_run_is_flagged() {
        let mut r = results(1);
        let w = warnings(&r);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("--repeat 1"), "{w:?}");
        assert!(warnings_markdown(&w).starts_with("> **Warning"));
        // Overlapping spreads, a share of the lockstep ceiling above 100% and a curve
        // that falls with more steps.
        r.config.repeat = 3;
        for x in &mut r.rows {
            if x.method == "relief" && x.steps == Some(10) {
                (x.method_lo_ms, x.method_hi_ms) = (1.4, 2.2);
            }
            if x.method == "dig" && x.steps == Some(20) {
                x.method_ms = 1.2;
                x.method_lo_ms = 1.2;
                x.method_hi_ms = 1.2;
            }
        }
        let w = warnings(&r).join("\n");
        assert!(w.contains("`relief` at 10 overlap"), "{w}");
        assert!(w.contains("lockstep ceiling"), "{w}");
        assert!(
            w.contains("`dig` takes 1.50 ms at 10 steps and 1.20 ms at 20"),
            "{w}"
        );
    }

    #[test]
    fn dig_is_set_beside_the_paper() {
        let mut r = results(3);
        r.config.steps = vec![75, 150];
        r.config.methods = vec![Method::Pom, Method::Dig];
        r.rows = vec![
            row(Method::Pom, Some(75), 3.0, 0.10),
            row(Method::Pom, Some(150), 5.0, 0.05),
            row(Method::Dig, Some(75), 2.0, 0.08),
            row(Method::Dig, Some(150), 2.5, 0.04),
        ];
        let md = markdown(&r);
        assert!(md.contains("at 150 steps 2.00x method time"), "{md}");
        assert!(
            md.contains("2.17x at 75 iterations and 2.91x at 150"),
            "{md}"
        );
        assert!(md.contains("Depth Interval Grids*"), "{md}");
    }
}
