//! The benchmark's `report.md` ([`markdown`]): the set-up, per map the run table, DIG's
//! speed-ups and the time each method needs for fixed errors, the shadow and map-size
//! sweeps; and the file names of the plots it links.

use super::curves::{
    ARTIFACT_TARGETS, Measure, Speedup, TEXEL_TARGETS, TimeToError, curve, curve_rows,
    equal_error_speedup, equal_error_speedup_at_dig, lockstep_ceiling, row_at,
    same_setting_speedup, time_to_reach,
};
use super::{BenchResults, RunRow, Sweep, file_stem};
use dispmap::method::Method;
use std::fmt::Write as _;

/// File name of the map-size plot.
pub const SIZES_PLOT: &str = "sizes.png";

/// File name of a map's Pareto plot.
pub fn pareto_file(map: &str) -> String {
    format!("pareto_{}.png", file_stem(map))
}

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
        "- date: {}\n- command: `{command}`\n- device: {} (driver {}, Vulkan {}; traversal step rules {})\n- wall time of the sweep: {:.1} s",
        utc_timestamp(results.started),
        results.device,
        results.driver,
        results.api_version,
        if results.traversal_rules { "on" } else { "off" },
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
    if let Some(b) = &results.silhouettes {
        s.push_str(&super::silhouettes::markdown(b, c.frame));
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
             saturating, the colour bar under each; black = no geometry): {}.",
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
