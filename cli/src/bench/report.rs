//! The benchmark's written outputs: `results.csv` ([`csv_bytes`]), `report.md`
//! ([`markdown`]) and the equal-error reading of the speed-error curves
//! ([`time_to_reach`]).
//!
//! # Speed-up at equal error
//!
//! A method with a step count has one (time, error) point per setting; in order of
//! increasing steps they form its speed-error curve. The time it needs to reach a target
//! error `E` is read off that curve: at the first pair of adjacent settings whose errors
//! bracket `E` (`e_i > E >= e_(i+1)`), time is interpolated linearly in `log(error)`
//! (linearly in the error where an end is 0); if its cheapest setting is already at or
//! below `E`, the time is *at most* that setting's (marked `<=`: fewer steps might do);
//! if no setting reaches `E`, it is *not reached*. A method without a step count has one
//! point: its time if its error is at or below `E`, else not reached.
//!
//! DIG's speed-up over POM (or relief) at equal error is read both ways at each setting
//! `iter`: (a) [`equal_error_speedup`], `POM's time at iter / the time DIG needs for POM's
//! error at iter`; (b) [`equal_error_speedup_at_dig`], `the time POM needs for DIG's error
//! at iter / DIG's time at iter`. When DIG is more accurate at every setting, (a) is only
//! a lower bound (`>=`, DIG's cheapest setting already beats the target) and (b) says
//! whether POM gets there at all. The report also lists the time every method needs for
//! fixed targets ([`ARTIFACT_TARGETS`], [`TEXEL_TARGETS`]).

use super::{BenchResults, RunRow, Sweep, file_stem};
use dispmap::error::{Error, Result};
use dispmap::method::Method;
use std::fmt::Write as _;

/// File name of the map-size plot.
pub const SIZES_PLOT: &str = "sizes.png";

/// File name of a map's Pareto plot.
pub fn pareto_file(map: &str) -> String {
    format!("pareto_{}.png", file_stem(map))
}

/// `rows` as CSV: a header of [`RunRow`]'s field names, one line per row; empty cells
/// for absent values.
pub fn csv_bytes(rows: &[RunRow]) -> Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let err = |e: &dyn std::fmt::Display| Error::invalid("results.csv", e.to_string());
    if rows.is_empty() {
        // serde writes the header with the first row; an empty sweep still gets one.
        writer.write_record(CSV_HEADER).map_err(|e| err(&e))?;
    }
    for row in rows {
        writer.serialize(row).map_err(|e| err(&e))?;
    }
    writer.into_inner().map_err(|e| err(&e))
}

/// The columns of `results.csv`, in order.
pub const CSV_HEADER: [&str; 43] = [
    "sweep",
    "map",
    "map_width",
    "map_height",
    "method",
    "steps",
    "frame_width",
    "frame_height",
    "frames",
    "repeat",
    "error_frames",
    "frame_set",
    "gbuffer_ms",
    "pyramid_build_ms",
    "cpu_pyramid_build_ms",
    "cone_build_ms",
    "dig_corners_ms",
    "trace_ms",
    "shade_ms",
    "shadow_ms",
    "method_ms",
    "method_median_ms",
    "method_lo_ms",
    "method_hi_ms",
    "total_ms",
    "total_median_ms",
    "method_median_lo_ms",
    "method_median_hi_ms",
    "total_median_lo_ms",
    "total_median_hi_ms",
    "iterations_mean",
    "iterations_p99",
    "iterations_simd8",
    "iterations_warp32",
    "iterations_quads8",
    "corner_iterations",
    "mean_texels",
    "p99_texels",
    "max_texels",
    "artifact_fraction",
    "psnr_db",
    "nonfinite_pixels",
    "forward_differing_pixels",
];

/// One point of a speed-error curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint {
    /// Time (method milliseconds).
    pub time_ms: f64,
    /// Error (any measure where lower is better).
    pub error: f64,
}

/// The time a method needs to reach a target error (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeToError {
    /// Reached at this interpolated time.
    Reached(f64),
    /// The cheapest setting already reaches it: at most this time.
    AtMost(f64),
    /// No setting reaches it.
    NotReached,
}

impl TimeToError {
    /// The time, if reached (an upper bound for [`TimeToError::AtMost`]).
    pub fn time(self) -> Option<f64> {
        match self {
            TimeToError::Reached(t) | TimeToError::AtMost(t) => Some(t),
            TimeToError::NotReached => None,
        }
    }
}

/// The time `curve` (points in order of increasing quality setting) needs to reach
/// `target` (module docs). Non-finite points are skipped.
pub fn time_to_reach(curve: &[CurvePoint], target: f64) -> TimeToError {
    let points: Vec<CurvePoint> = curve
        .iter()
        .copied()
        .filter(|p| p.time_ms.is_finite() && p.error.is_finite())
        .collect();
    let Some(first) = points.first() else {
        return TimeToError::NotReached;
    };
    if !target.is_finite() {
        return TimeToError::NotReached;
    }
    if first.error <= target {
        return if points.len() == 1 {
            TimeToError::Reached(first.time_ms)
        } else {
            TimeToError::AtMost(first.time_ms)
        };
    }
    for pair in points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if a.error > target && target >= b.error {
            let frac = if a.error > 0.0 && b.error > 0.0 && target > 0.0 {
                (a.error.ln() - target.ln()) / (a.error.ln() - b.error.ln())
            } else {
                (a.error - target) / (a.error - b.error)
            };
            return TimeToError::Reached(
                a.time_ms + frac.clamp(0.0, 1.0) * (b.time_ms - a.time_ms),
            );
        }
    }
    TimeToError::NotReached
}

/// The rows of the methods sweep for `map` and `method`, in order of steps.
pub fn curve_rows<'r>(rows: &'r [RunRow], map: &str, method: Method) -> Vec<&'r RunRow> {
    let mut out: Vec<&RunRow> = rows
        .iter()
        .filter(|r| r.sweep == Sweep::Methods && r.map == map && r.method == method.name())
        .collect();
    out.sort_by_key(|r| r.steps);
    out
}

/// An error measure of a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measure {
    /// `artifact_fraction`.
    ArtifactFraction,
    /// `mean_texels`.
    MeanTexels,
}

impl Measure {
    /// The row's value.
    pub fn of(self, row: &RunRow) -> f64 {
        match self {
            Measure::ArtifactFraction => row.artifact_fraction,
            Measure::MeanTexels => row.mean_texels,
        }
    }

    /// The CSV column name.
    pub fn name(self) -> &'static str {
        match self {
            Measure::ArtifactFraction => "artifact_fraction",
            Measure::MeanTexels => "mean_texels",
        }
    }

    /// Words for tables.
    pub fn label(self) -> &'static str {
        match self {
            Measure::ArtifactFraction => "artifact fraction",
            Measure::MeanTexels => "mean hit distance",
        }
    }

    fn format(self, v: f64) -> String {
        match self {
            Measure::ArtifactFraction => format!("{:.3}%", 100.0 * v),
            Measure::MeanTexels => format!("{v:.3} tx"),
        }
    }
}

/// The speed-error curve of `method` on `map` for `measure`.
pub fn curve(rows: &[RunRow], map: &str, method: Method, measure: Measure) -> Vec<CurvePoint> {
    curve_rows(rows, map, method)
        .into_iter()
        .map(|r| CurvePoint {
            time_ms: r.method_ms,
            error: measure.of(r),
        })
        .collect()
}

fn row_at<'r>(rows: &'r [RunRow], map: &str, method: Method, steps: u32) -> Option<&'r RunRow> {
    curve_rows(rows, map, method)
        .into_iter()
        .find(|r| r.steps == Some(steps))
}

/// DIG's speed-ups on `map` at `steps`: method-time and frame-time ratios over `other`
/// at the same setting.
pub fn same_setting_speedup(
    rows: &[RunRow],
    map: &str,
    other: Method,
    steps: u32,
) -> Option<(f64, f64)> {
    let dig = row_at(rows, map, Method::Dig, steps)?;
    let o = row_at(rows, map, other, steps)?;
    Some((o.method_ms / dig.method_ms, o.total_ms / dig.total_ms))
}

/// DIG's lockstep ceiling over `relief` on `map` at `steps`: relief's 8-lane lockstep
/// iterations per pixel over DIG's (trace plus corner-pass fetches per pixel), the
/// speed-up DIG would have if time followed the lockstep count; and DIG's measured
/// speed-up over relief as a fraction of it.
pub fn lockstep_ceiling(rows: &[RunRow], map: &str, steps: u32) -> Option<(f64, f64)> {
    let dig = row_at(rows, map, Method::Dig, steps)?;
    let relief = row_at(rows, map, Method::Relief, steps)?;
    let ceiling =
        relief.iterations_simd8 / (dig.iterations_simd8 + dig.corner_iterations.unwrap_or(0.0));
    let measured = relief.method_ms / dig.method_ms;
    Some((ceiling, measured / ceiling))
}

/// DIG's speed-up over another method at equal error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Speedup {
    /// This ratio.
    Ratio(f64),
    /// At least this ratio (DIG's cheapest setting already reaches the target).
    AtLeast(f64),
    /// At most this ratio (the other method's cheapest setting already reaches it).
    AtMost(f64),
    /// The other method reaches DIG's error at no setting.
    OtherNeverReaches,
    /// DIG reaches the other method's error at no setting.
    DigNeverReaches,
}

impl Speedup {
    /// The ratio, if there is one (a bound for `AtLeast` / `AtMost`).
    pub fn ratio(self) -> Option<f64> {
        match self {
            Speedup::Ratio(x) | Speedup::AtLeast(x) | Speedup::AtMost(x) => Some(x),
            _ => None,
        }
    }

    /// Short text for tables: `2.10x`, `>= 2.10x`, `<= 2.10x`, or who never reaches the
    /// target.
    pub fn cell(self, other: Method) -> String {
        match self {
            Speedup::Ratio(x) => format!("{x:.2}x"),
            Speedup::AtLeast(x) => format!(">= {x:.2}x"),
            Speedup::AtMost(x) => format!("<= {x:.2}x"),
            Speedup::OtherNeverReaches => format!("`{other}` never reaches it"),
            Speedup::DigNeverReaches => "`dig` never reaches it".into(),
        }
    }
}

/// DIG's speed-up over `other` on `map` at equal error, reading DIG's curve: `other`'s
/// time at `steps` over the time DIG needs to reach `other`'s error there
/// ([`time_to_reach`]). `None` if either has no such run.
pub fn equal_error_speedup(
    rows: &[RunRow],
    map: &str,
    other: Method,
    steps: u32,
    measure: Measure,
) -> Option<Speedup> {
    let o = row_at(rows, map, other, steps)?;
    let dig = curve(rows, map, Method::Dig, measure);
    if dig.is_empty() {
        return None;
    }
    Some(match time_to_reach(&dig, measure.of(o)) {
        TimeToError::Reached(t) => Speedup::Ratio(o.method_ms / t),
        // DIG needs at most t: the speed-up is at least the ratio.
        TimeToError::AtMost(t) => Speedup::AtLeast(o.method_ms / t),
        TimeToError::NotReached => Speedup::DigNeverReaches,
    })
}

/// The other reading: the time `other` needs to reach DIG's error at `steps` (read off
/// `other`'s curve) over DIG's time at `steps`. `None` if either has no such run.
pub fn equal_error_speedup_at_dig(
    rows: &[RunRow],
    map: &str,
    other: Method,
    steps: u32,
    measure: Measure,
) -> Option<Speedup> {
    let dig = row_at(rows, map, Method::Dig, steps)?;
    let o = curve(rows, map, other, measure);
    if o.is_empty() {
        return None;
    }
    Some(match time_to_reach(&o, measure.of(dig)) {
        TimeToError::Reached(t) => Speedup::Ratio(t / dig.method_ms),
        // The other needs at most t: the speed-up is at most the ratio.
        TimeToError::AtMost(t) => Speedup::AtMost(t / dig.method_ms),
        TimeToError::NotReached => Speedup::OtherNeverReaches,
    })
}

/// The fixed error targets of the report's time-to-error table.
pub const ARTIFACT_TARGETS: [f64; 6] = [0.2, 0.1, 0.05, 0.02, 0.01, 0.001];

/// The fixed mean-texel targets of the report's time-to-error table.
pub const TEXEL_TARGETS: [f64; 6] = [20.0, 10.0, 5.0, 2.0, 1.0, 0.1];

fn time_cell(t: TimeToError) -> String {
    match t {
        TimeToError::Reached(x) => format!("{x:.2}"),
        TimeToError::AtMost(x) => format!("<= {x:.2}"),
        TimeToError::NotReached => "-".into(),
    }
}

fn steps_cell(r: &RunRow) -> String {
    r.steps
        .map_or_else(|| "- (one run)".into(), |s| s.to_string())
}

fn opt_ms(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |x| format!("{x:.2}"))
}

/// `YYYY-MM-DD HH:MM UTC` of a time (the proleptic Gregorian calendar).
pub fn utc_timestamp(t: std::time::SystemTime) -> String {
    let secs = t
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        rem / 3600,
        (rem % 3600) / 60
    )
}

/// The Markdown report (see the module docs of [`crate::bench`] for the protocol): the
/// warnings about what the run is too short for and the verdict per map
/// ([`super::verdict`]), the set-up, then per map the run table, DIG's speed-ups at the same setting and at equal
/// error, the time every method needs for the reference errors and the plots; then the
/// map-size sweep.
pub fn markdown(results: &BenchResults, command: &str) -> String {
    let c = &results.config;
    let mut s = String::new();
    let _ = writeln!(s, "# dispmap speed-versus-error benchmark\n");
    s.push_str(&super::verdict::warnings_markdown(
        &super::verdict::warnings(results),
    ));
    s.push_str(&super::verdict::markdown(results));
    let _ = writeln!(s, "\n## Set-up\n");
    let _ = writeln!(
        s,
        "- date: {}\n- command: `{command}`\n- device: {} (driver {}, Vulkan {})\n- wall time of the sweep: {:.1} s",
        utc_timestamp(results.started),
        results.device,
        results.driver,
        results.api_version,
        results.wall.as_secs_f64()
    );
    let _ = writeln!(
        s,
        "- frame {}x{}, {} frames per run (camera azimuth (f + 0.5) x {} deg), error on {} of them; \
         tiled plane seen from {:.1} deg below the horizon (bottom row) to {:.1} deg (top row), \
         eye height {} tiles, depth scale {}",
        c.frame[0],
        c.frame[1],
        c.frames,
        super::trim_float(360.0 / f64::from(c.frames)),
        c.error_frame_indices().len(),
        c.scene.camera.elevation_deg + c.scene.camera.fov_y_deg / 2.0,
        c.scene.camera.elevation_deg - c.scene.camera.fov_y_deg / 2.0,
        c.scene.camera.height,
        c.scene.depth_scale
    );
    let steps: Vec<String> = c.steps.iter().map(|s| s.to_string()).collect();
    let _ = writeln!(
        s,
        "- settings (`iter`, linear steps over the full depth, the same for every method): {}; \
         DIG eps1 = eps2 = 1/iter, 4x4 blocks; 5 binary steps; {} have no step count and run \
         once per map",
        steps.join(", "),
        Method::ALL
            .iter()
            .filter(|&&m| !super::has_steps(m))
            .map(|m| format!("`{m}`"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "\nTimes are milliseconds of GPU timestamps, the **minimum** over every frame of {} \
         interleaved passes over the {} frames (the runs are interleaved frame by frame, and \
         the passes one after the other, so a passing load spreads over every method; on a \
         shared machine the minimum repeats far better than the median, which is listed as \
         **method med.**). **spread** = the lowest and the highest of the per-pass minima of \
         the method time: a ratio whose two sides' spreads overlap is within noise. **method** \
         = `dig_corners` + `trace` (what the speed-ups compare, all from the minimum), \
         **frame** = the whole frame \
         (G-buffer, corner pass, trace, shade; without the one-off pyramid and cone-map builds, listed as \
         **pyr. build** and **cone build**). Errors are means over the error frames against the exact CPU \
         reference: **artifacts** = covered pixels more than one texel off, **mean tx** = mean \
         hit distance in texels. **iters** = the trace pass's iterations per pixel (mean, p99); \
         **SIMD-8** / **warp-32** = the mean over 8x1 / 8x4 pixel groups of the group's largest \
         count (a SIMD group runs until its slowest lane is done: lavapipe's subgroups have 8 \
         lanes, a GPU warp 32); **corner it./px** = DIG's corner-pass fetches per pixel. \
         **x bump** = method time over `bump`'s (the cost floor: one fetch). On lavapipe the times are CPU times: read ratios within this run only.",
        c.repeat, c.frames
    );
    for map in &results.maps {
        map_section(&mut s, results, &map.name, map);
    }
    s.push_str(&super::compare::markdown(results));
    shadow_section(&mut s, results);
    size_section(&mut s, results);
    if let Some(m) = &results.materials {
        s.push_str(&super::materials::markdown(m, c.frame));
    }
    let _ = writeln!(
        s,
        "\n## How to read the equal-error tables\n\n\
         Each method's (time, error) points over its settings form its speed-error curve. The \
         time a method needs for a target error is interpolated between the two adjacent \
         settings that bracket it, linearly in log(error); `<= t` means its cheapest setting \
         already reaches the target (fewer steps might do, so a speed-up computed from it is a \
         lower bound, `>=`); *not reached* means no setting gets that low. Targets are the \
         errors of `pom` and `relief` at each setting. Methods without a step count are single \
         points."
    );
    s
}

fn map_section(s: &mut String, results: &BenchResults, name: &str, info: &super::MapInfo) {
    let c = &results.config;
    let rows = &results.rows;
    let _ = writeln!(
        s,
        "\n## {name}\n\n`{}`: {}x{}, {}, mean height {:.3}.\n",
        info.label, info.width, info.height, info.format, info.mean_height
    );
    let bump = curve_rows(rows, name, Method::Bump)
        .first()
        .map(|r| r.method_ms);
    let _ = writeln!(
        s,
        "| method | steps | pyr. build | cone build | corners | trace | method | spread | method med. | frame | x bump | iters mean | iters p99 | SIMD-8 | warp-32 | corner it./px | artifacts | mean tx | p99 tx | PSNR dB |"
    );
    let _ = writeln!(
        s,
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for &method in &c.methods {
        for r in curve_rows(rows, name, method) {
            let _ = writeln!(
                s,
                "| `{}` | {} | {} | {} | {} | {:.2} | {:.2} | {:.2}-{:.2} | {:.2} | {:.2} | {} | {:.1} | {:.0} | {:.1} | {:.1} | {} | {:.3}% | {:.3} | {:.3} | {:.2} |",
                r.method,
                steps_cell(r),
                opt_ms(r.pyramid_build_ms),
                opt_ms(r.cone_build_ms),
                opt_ms(r.dig_corners_ms),
                r.trace_ms,
                r.method_ms,
                r.method_lo_ms,
                r.method_hi_ms,
                r.method_median_ms,
                r.total_ms,
                bump.map_or_else(|| "-".into(), |b| format!("{:.1}", r.method_ms / b)),
                r.iterations_mean,
                r.iterations_p99,
                r.iterations_simd8,
                r.iterations_warp32,
                r.corner_iterations
                    .map_or_else(|| "-".into(), |v| format!("{v:.2}")),
                100.0 * r.artifact_fraction,
                r.mean_texels,
                r.p99_texels,
                r.psnr_db
            );
        }
    }
    let has = |m: Method| c.methods.contains(&m);
    if has(Method::Dig) && (has(Method::Pom) || has(Method::Relief)) {
        let _ = writeln!(
            s,
            "\n**DIG's speed-up at the same setting** (method time; whole frame in brackets):\n"
        );
        let _ = writeln!(
            s,
            "| iter | over `pom` | over `relief` | lockstep ceiling over `relief` | of the ceiling |\n|---:|---:|---:|---:|---:|"
        );
        for &st in &c.steps {
            let cell = |m: Method| {
                same_setting_speedup(rows, name, m, st)
                    .map_or_else(|| "-".into(), |(a, b)| format!("{a:.2}x ({b:.2}x)"))
            };
            let (ceiling, share) = lockstep_ceiling(rows, name, st).map_or_else(
                || ("-".to_owned(), "-".to_owned()),
                |(c, f)| (format!("{c:.2}x"), format!("{:.0}%", 100.0 * f)),
            );
            let _ = writeln!(
                s,
                "| {st} | {} | {} | {ceiling} | {share} |",
                cell(Method::Pom),
                cell(Method::Relief)
            );
        }
        let _ = writeln!(
            s,
            "\nThe lockstep ceiling is relief's SIMD-8 count over DIG's (its corner-pass fetches \
             per pixel added): the speed-up DIG would show if a group of 8 lanes cost what its \
             slowest lane's fetches cost."
        );
        let _ = writeln!(
            s,
            "\n**DIG's speed-up at equal error**, two readings: (a) the other method's error at \
             `iter` is the target and DIG's time for it is read off DIG's curve, speed-up = \
             other's time at `iter` / that; (b) DIG's error at `iter` is the target and the \
             other's time for it is read off the other's curve, speed-up = that / DIG's time \
             at `iter`.\n"
        );
        let _ = writeln!(
            s,
            "| iter | vs | measure | its error | (a) speed-up | `dig`'s error | (b) speed-up |\n|---:|---|---|---:|---:|---:|---:|"
        );
        for &st in &c.steps {
            for other in [Method::Pom, Method::Relief] {
                if !has(other) {
                    continue;
                }
                for measure in [Measure::ArtifactFraction, Measure::MeanTexels] {
                    let err = |m: Method| {
                        row_at(rows, name, m, st)
                            .map_or_else(|| "-".into(), |r| measure.format(measure.of(r)))
                    };
                    let cell = |x: Option<Speedup>| x.map_or_else(|| "-".into(), |x| x.cell(other));
                    let _ = writeln!(
                        s,
                        "| {st} | `{other}` | {} | {} | {} | {} | {} |",
                        measure.label(),
                        err(other),
                        cell(equal_error_speedup(rows, name, other, st, measure)),
                        err(Method::Dig),
                        cell(equal_error_speedup_at_dig(rows, name, other, st, measure)),
                    );
                }
            }
        }
    }
    for (measure, targets) in [
        (Measure::ArtifactFraction, &ARTIFACT_TARGETS[..]),
        (Measure::MeanTexels, &TEXEL_TARGETS[..]),
    ] {
        let _ = writeln!(
            s,
            "\n**Time each method needs to reach a given {}** (method ms, read off its \
             speed-error curve; `-`: no setting gets there):\n",
            measure.label()
        );
        let mut header = "| target |".to_owned();
        let mut rule = "|---|".to_owned();
        for &m in &c.methods {
            let _ = write!(header, " `{m}` |");
            rule.push_str("---:|");
        }
        let _ = writeln!(s, "{header}\n{rule}");
        for &target in targets {
            let target_text = match measure {
                Measure::ArtifactFraction => format!("{}%", super::trim_float(100.0 * target)),
                Measure::MeanTexels => format!("{} tx", super::trim_float(target)),
            };
            let mut line = format!("| {target_text} |");
            for &m in &c.methods {
                let t = time_to_reach(&curve(rows, name, m, measure), target);
                let _ = write!(line, " {} |", time_cell(t));
            }
            let _ = writeln!(s, "{line}");
        }
    }
    let _ = writeln!(
        s,
        "\n![speed against error on {name}]({})\n",
        pareto_file(name)
    );
    let heat: Vec<&super::NamedImage> = results
        .images
        .iter()
        .filter(|i| {
            i.file_name
                .starts_with(&format!("heatmap_{}_", file_stem(name)))
        })
        .collect();
    if !heat.is_empty() {
        let links: Vec<String> = heat
            .iter()
            .map(|i| {
                let method = i
                    .file_name
                    .trim_start_matches(&format!("heatmap_{}_", file_stem(name)))
                    .trim_end_matches(".png");
                format!("[{method}]({})", i.file_name)
            })
            .collect();
        let _ = writeln!(
            s,
            "Iteration heat maps of frame 0 (trace pass, viridis from 0 to {} iterations, \
             saturating; black = no geometry): {}.",
            c.heatmap_steps() + super::REFINE_STEPS,
            links.join(", ")
        );
    }
    let intervals = format!("intervals_{}.png", file_stem(name));
    if results.images.iter().any(|i| i.file_name == intervals) {
        let _ = writeln!(
            s,
            "DIG interval map of frame 0 (grey per 4x4 block, darker = longer interval; red = no \
             interval): [{intervals}]({intervals})."
        );
    }
}

/// With `--shadows` on: the `shadow` pass's median time per run, and over `trace`.
fn shadow_section(s: &mut String, results: &BenchResults) {
    let mode = results.config.shadows;
    let rows: Vec<&RunRow> = results
        .rows
        .iter()
        .filter(|r| r.shadow_ms.is_some())
        .collect();
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Self-shadowing (`--shadows {mode}`)\n\nThe `shadow` pass (after `trace`, before \
         `shade`) per run: median milliseconds and its time over the trace pass's. It is part \
         of **frame**, not of **method**.\n\n| map | method | steps | trace | shadow | shadow / trace |\n|---|---|---|---:|---:|---:|"
    );
    for r in rows {
        let shadow = r.shadow_ms.unwrap_or(0.0);
        let _ = writeln!(
            s,
            "| {} | `{}` | {} | {:.2} | {:.2} | {} |",
            r.map,
            r.method,
            steps_cell(r),
            r.trace_ms,
            shadow,
            if r.trace_ms > 0.0 {
                format!("{:.2}", shadow / r.trace_ms)
            } else {
                "-".into()
            }
        );
    }
}

fn size_section(s: &mut String, results: &BenchResults) {
    let c = &results.config;
    let rows: Vec<&RunRow> = results
        .rows
        .iter()
        .filter(|r| r.sweep == Sweep::MapSize)
        .collect();
    let Some(source) = &results.size_source else {
        return;
    };
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Map-size sweep\n\n`{}` resampled (Catmull-Rom, {}) to each size; the methods \
         at iter = {} (where they have a step count), the same frames. **build** = the \
         pyramid's one GPU build per map (not in the per-frame time); **CPU build** = the \
         same pyramid built by one CPU thread (`cpu_build`, fastest of 3), the yardstick; \
         **cone build** = the cone map's one GPU build (after the pyramid, which it reads).\n",
        source.label, source.format, c.size_steps
    );
    let mut header = "| map size |".to_owned();
    let mut rule = "|---:|".to_owned();
    for &m in &c.size_methods {
        if m.needs().pyramid.is_some() {
            let _ = write!(header, " `{m}` build | `{m}` CPU build |");
            rule.push_str("---:|---:|");
        }
        if m.needs().cone.is_some() {
            let _ = write!(header, " `{m}` cone build |");
            rule.push_str("---:|");
        }
        let _ = write!(header, " `{m}` method | `{m}` artifacts |");
        rule.push_str("---:|---:|");
    }
    let _ = writeln!(s, "{header}\n{rule}");
    for &side in &c.sizes {
        let mut line = format!("| {side}x{side} |");
        for &m in &c.size_methods {
            let r = rows
                .iter()
                .find(|r| r.map_width == side && r.method == m.name());
            if m.needs().pyramid.is_some() {
                let _ = write!(
                    line,
                    " {} | {} |",
                    opt_ms(r.and_then(|r| r.pyramid_build_ms)),
                    opt_ms(r.and_then(|r| r.cpu_pyramid_build_ms))
                );
            }
            if m.needs().cone.is_some() {
                let _ = write!(line, " {} |", opt_ms(r.and_then(|r| r.cone_build_ms)));
            }
            match r {
                Some(r) => {
                    let _ = write!(
                        line,
                        " {:.2} | {:.3}% |",
                        r.method_ms,
                        100.0 * r.artifact_fraction
                    );
                }
                None => line.push_str(" - | - |"),
            }
        }
        let _ = writeln!(s, "{line}");
    }
    if let (Some(&first), Some(&last)) = (c.sizes.first(), c.sizes.last())
        && first != last
    {
        let _ = writeln!(
            s,
            "\nMethod time at {last}x{last} over {first}x{first} (the pyramid paper's Fig. 21: \
             480 -> 375.5 fps from 256x256 to 2048x2048, i.e. 1.28x the frame time):\n"
        );
        let _ = writeln!(s, "| method | ratio |\n|---|---:|");
        for &m in &c.size_methods {
            let t = |side: u32| {
                rows.iter()
                    .find(|r| r.map_width == side && r.method == m.name())
                    .map(|r| r.method_ms)
            };
            if let (Some(a), Some(b)) = (t(first), t(last)) {
                let _ = writeln!(s, "| `{m}` | {:.2}x |", b / a);
            }
        }
    }
    let _ = writeln!(s, "\n![method time against map size]({SIZES_PLOT})");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(time_ms: f64, error: f64) -> CurvePoint {
        CurvePoint { time_ms, error }
    }

    #[test]
    fn equal_error_interpolates_in_log_error() {
        let curve = [p(10.0, 0.1), p(20.0, 0.01), p(30.0, 0.001)];
        // Halfway in log between 0.1 and 0.01.
        let t = time_to_reach(&curve, 0.1f64.sqrt() * 0.1f64.sqrt() * 0.1f64.sqrt());
        let TimeToError::Reached(t) = t else {
            panic!("{t:?}")
        };
        assert!((t - 15.0).abs() < 1e-9, "{t}");
        assert_eq!(time_to_reach(&curve, 0.01), TimeToError::Reached(20.0));
        assert_eq!(time_to_reach(&curve, 0.5), TimeToError::AtMost(10.0));
        assert_eq!(time_to_reach(&curve, 0.0001), TimeToError::NotReached);
        assert_eq!(time_to_reach(&[], 0.1), TimeToError::NotReached);
        assert_eq!(time_to_reach(&curve, f64::NAN), TimeToError::NotReached);
    }

    #[test]
    fn equal_error_handles_zero_single_points_and_bumps() {
        // A zero end falls back to linear interpolation in the error.
        let curve = [p(10.0, 0.2), p(20.0, 0.0)];
        assert_eq!(time_to_reach(&curve, 0.1), TimeToError::Reached(15.0));
        // One point: its time if it is good enough, never "at most".
        assert_eq!(
            time_to_reach(&[p(7.0, 0.0)], 0.0),
            TimeToError::Reached(7.0)
        );
        assert_eq!(time_to_reach(&[p(7.0, 0.2)], 0.1), TimeToError::NotReached);
        // Non-monotone curve: the first crossing counts.
        let bumpy = [p(10.0, 0.3), p(20.0, 0.1), p(30.0, 0.2), p(40.0, 0.05)];
        assert_eq!(time_to_reach(&bumpy, 0.1), TimeToError::Reached(20.0));
        // Non-finite points are skipped.
        let with_nan = [p(f64::NAN, 0.3), p(20.0, 0.1), p(30.0, 0.05)];
        assert_eq!(time_to_reach(&with_nan, 0.2), TimeToError::AtMost(20.0));
    }

    fn row(method: &str, steps: Option<u32>, method_ms: f64, artifacts: f64) -> RunRow {
        RunRow {
            sweep: Sweep::Methods,
            map: "rocks".into(),
            map_width: 1024,
            map_height: 1024,
            method: method.into(),
            steps,
            frame_width: 64,
            frame_height: 36,
            frames: 2,
            repeat: 1,
            error_frames: 1,
            frame_set: "azimuth (f+0.5)*180deg for f<2; error frames 0".into(),
            gbuffer_ms: 0.5,
            pyramid_build_ms: None,
            cpu_pyramid_build_ms: None,
            cone_build_ms: None,
            dig_corners_ms: (method == "dig").then_some(0.25),
            trace_ms: method_ms,
            shade_ms: 0.75,
            shadow_ms: None,
            method_ms,
            method_median_ms: method_ms,
            method_lo_ms: method_ms,
            method_hi_ms: method_ms,
            total_ms: method_ms + 1.25,
            total_median_ms: method_ms + 1.25,
            method_median_lo_ms: method_ms,
            method_median_hi_ms: method_ms,
            total_median_lo_ms: method_ms + 1.25,
            total_median_hi_ms: method_ms + 1.25,
            iterations_mean: 12.5,
            iterations_p99: 40.0,
            iterations_simd8: 20.0,
            iterations_warp32: 30.0,
            iterations_quads8: 18.0,
            corner_iterations: None,
            mean_texels: 10.0 * artifacts,
            p99_texels: 3.0,
            max_texels: 9.0,
            artifact_fraction: artifacts,
            psnr_db: 30.0,
            nonfinite_pixels: 0,
            forward_differing_pixels: None,
        }
    }

    #[test]
    fn csv_has_the_header_and_blank_absent_values() {
        let rows = [
            row("pom", Some(75), 4.0, 0.125),
            row("bump", None, 1.0, 0.5),
        ];
        let bytes = csv_bytes(&rows).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(header, CSV_HEADER);
        assert_eq!(
            lines.next().unwrap(),
            "methods,rocks,1024,1024,pom,75,64,36,2,1,1,azimuth (f+0.5)*180deg for f<2; error frames 0,\
             0.5,,,,,4.0,0.75,,4.0,4.0,4.0,4.0,5.25,5.25,4.0,4.0,5.25,5.25,12.5,40.0,20.0,30.0,18.0,,1.25,3.0,9.0,0.125,30.0,0,"
        );
        let bump = lines.next().unwrap();
        assert!(
            bump.starts_with("methods,rocks,1024,1024,bump,,64"),
            "{bump}"
        );
        assert!(lines.next().is_none());
        // Round trip through the csv reader.
        let mut reader = csv::Reader::from_reader(bytes.as_slice());
        let back: Vec<RunRow> = reader.deserialize().map(|r| r.unwrap()).collect();
        assert_eq!(back, rows);
        // An empty sweep still has the header.
        let empty = String::from_utf8(csv_bytes(&[]).unwrap()).unwrap();
        assert!(empty.starts_with("sweep,map,"), "{empty}");
    }

    #[test]
    fn speedups_from_rows() {
        let rows = vec![
            row("pom", Some(75), 40.0, 0.10),
            row("pom", Some(150), 80.0, 0.05),
            row("dig", Some(75), 10.0, 0.20),
            row("dig", Some(150), 20.0, 0.05),
        ];
        let (m, _) = same_setting_speedup(&rows, "rocks", Method::Pom, 150).unwrap();
        assert_eq!(m, 4.0);
        // POM at 75 has 10% artifacts; DIG reaches 10% halfway in log between 20% and 5%.
        let s = equal_error_speedup(&rows, "rocks", Method::Pom, 75, Measure::ArtifactFraction)
            .unwrap();
        let Speedup::Ratio(x) = s else {
            panic!("{s:?}")
        };
        let frac = (0.2f64.ln() - 0.1f64.ln()) / (0.2f64.ln() - 0.05f64.ln());
        assert!((x - 40.0 / (10.0 + frac * 10.0)).abs() < 1e-9, "{x}");
        assert!(
            equal_error_speedup(&rows, "rocks", Method::Relief, 75, Measure::MeanTexels).is_none()
        );
    }

    #[test]
    fn utc_dates() {
        use std::time::{Duration, UNIX_EPOCH};
        assert_eq!(utc_timestamp(UNIX_EPOCH), "1970-01-01 00:00 UTC");
        // 2000-02-29 12:34 UTC (a leap day).
        let t = UNIX_EPOCH + Duration::from_secs(951_827_640);
        assert_eq!(utc_timestamp(t), "2000-02-29 12:34 UTC");
        let t = UNIX_EPOCH + Duration::from_secs(1_798_761_599);
        assert_eq!(utc_timestamp(t), "2026-12-31 23:59 UTC");
    }
}
