//! The report's ratios of medians, each with the range of its per-pass ratios as the
//! spread (both sides timed in the same interleaved passes, so a load that slows a pass
//! slows both): the deferred frame of `dig` and `exact` against the forward frames of
//! `relief` and `pom` (what engines do, [`super::Sweep::Forward`]), at the largest step
//! setting and at equal error; and the method-time ratios `exact` / `relief` at the
//! largest setting (and at 64 steps when the sweep has them) and `cone-exact` / `exact`.
//!
//! Equal error is read as in [`super::report`] ([`time_to_reach`]), on the artifact
//! fraction, with frame times: the median frame time over the settings' curve, and each
//! pass's median on the same interpolation.

use super::curves::{CurvePoint, TimeToError, time_to_reach};
use super::{BenchResults, RunRow, Sweep};
use dispmap::method::Method;
use std::fmt::Write as _;

/// A time: its median over every frame and its median in each pass of the repeat.
#[derive(Clone, Debug, PartialEq)]
pub struct Timed {
    /// Median over every frame (or a value interpolated from such medians).
    pub median: f64,
    /// The same statistic per pass.
    pub passes: Vec<f64>,
}

/// `a / b` of two [`Timed`]s: the ratio of the medians and the range of the per-pass
/// ratios.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ratio {
    /// Ratio of the medians.
    pub value: f64,
    /// Lowest per-pass ratio.
    pub lo: f64,
    /// Highest per-pass ratio.
    pub hi: f64,
}

impl Timed {
    /// `self / other`.
    pub fn over(&self, other: &Timed) -> Ratio {
        let per_pass: Vec<f64> = self
            .passes
            .iter()
            .zip(&other.passes)
            .map(|(a, b)| a / b)
            .collect();
        Ratio {
            value: self.median / other.median,
            lo: per_pass.iter().copied().fold(f64::INFINITY, f64::min),
            hi: per_pass.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

impl std::fmt::Display for Ratio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.lo.is_finite() && self.hi.is_finite() {
            write!(f, "{:.2}x ({:.2}-{:.2})", self.value, self.lo, self.hi)
        } else {
            write!(f, "{:.2}x", self.value)
        }
    }
}

/// Which time of a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Time {
    /// The method time.
    Method,
    /// The whole frame.
    Frame,
}

fn timed(results: &BenchResults, index: usize, time: Time) -> Timed {
    let row = &results.rows[index];
    let medians = results.pass_medians.get(index);
    match time {
        Time::Method => Timed {
            median: row.method_median_ms,
            passes: medians.map(|m| m.method.clone()).unwrap_or_default(),
        },
        Time::Frame => Timed {
            median: row.total_median_ms,
            passes: medians.map(|m| m.total.clone()).unwrap_or_default(),
        },
    }
}

/// The rows of `sweep` for `map` and `method`, ascending in steps, with their indices.
fn curve(results: &BenchResults, sweep: Sweep, map: &str, method: Method) -> Vec<usize> {
    let mut out: Vec<usize> = (0..results.rows.len())
        .filter(|&i| {
            let r = &results.rows[i];
            r.sweep == sweep && r.map == map && r.method == method.name()
        })
        .collect();
    out.sort_by_key(|&i| results.rows[i].steps);
    out
}

/// The run of `sweep`, `map`, `method` at `steps` (`None`: a method without steps).
pub fn find(
    results: &BenchResults,
    sweep: Sweep,
    map: &str,
    method: Method,
    steps: Option<u32>,
) -> Option<usize> {
    curve(results, sweep, map, method)
        .into_iter()
        .find(|&i| results.rows[i].steps == steps || !super::has_steps(method))
}

/// The time of `method`'s runs of `sweep` on `map` to reach the artifact fraction
/// `target` ([`time_to_reach`] on the median and on every pass's median), and whether it
/// is an upper bound (its cheapest setting already reaches it). `None`: not reached.
pub fn time_to_error(
    results: &BenchResults,
    sweep: Sweep,
    map: &str,
    method: Method,
    target: f64,
    time: Time,
) -> Option<(Timed, bool)> {
    let rows = curve(results, sweep, map, method);
    let points = |value: &dyn Fn(usize) -> Option<f64>| -> Option<Vec<CurvePoint>> {
        rows.iter()
            .map(|&i| {
                Some(CurvePoint {
                    time_ms: value(i)?,
                    error: results.rows[i].artifact_fraction,
                })
            })
            .collect()
    };
    let median = points(&|i| Some(timed(results, i, time).median))?;
    let (median, at_most) = match time_to_reach(&median, target) {
        TimeToError::Reached(t) => (t, false),
        TimeToError::AtMost(t) => (t, true),
        TimeToError::NotReached => return None,
    };
    let passes = rows
        .first()
        .map_or(0, |&i| timed(results, i, time).passes.len());
    let passes = (0..passes)
        .filter_map(|p| {
            let curve = points(&|i| timed(results, i, time).passes.get(p).copied())?;
            time_to_reach(&curve, target).time()
        })
        .collect();
    Some((Timed { median, passes }, at_most))
}

fn pct(row: &RunRow) -> String {
    format!("{:.3}%", 100.0 * row.artifact_fraction)
}

/// The report's section (empty when the sweep has no forward rows and neither ratio can
/// be formed): see the module docs.
pub fn markdown(results: &BenchResults) -> String {
    let mut s = String::new();
    let c = &results.config;
    let Some(top) = c.steps.iter().copied().max() else {
        return s;
    };
    let maps: Vec<&str> = results.maps.iter().map(|m| m.name.as_str()).collect();
    let forward = results.rows.iter().any(|r| r.sweep == Sweep::Forward);
    if forward {
        forward_section(&mut s, results, &maps, top);
    }
    method_ratios(&mut s, results, &maps, top);
    s
}

fn forward_section(s: &mut String, results: &BenchResults, maps: &[&str], top: u32) {
    let c = &results.config;
    let _ = writeln!(
        s,
        "\n## The deferred frame against what engines do (the forward path)\n\n\
         Engines evaluate relief mapping and POM in the fragment shader that writes their \
         G-buffer. The forward rows run that: the same marcher on the same rays, in the \
         G-buffer pass (`gbuffer` below is that raster pass with the march), then the same \
         classification and shading as the deferred frame (G-buffer, classify, [corner \
         pass], trace, shade). Times are **whole frames**: the median over every frame of \
         the {} interleaved passes, in brackets the lowest and highest per-pass median; \
         ratios are ratios of medians, in brackets the range of the per-pass ratios. \
         **gbuffer** / **trace**: the forward raster pass with the march / the deferred \
         trace (medians); **lockstep 4x2 / 8x1**: the mean over 4x2 / 8x1 pixel groups of \
         the group's largest iteration count (8 lanes of two 2x2 quads, how an 8-wide \
         fragment shader runs, against a compute shader's 8x1 rows). **hits differ** = hit \
         texels of the forward frame that differ bit for bit from the deferred frame's of the \
         same method, setting and camera, over the error frames.\n",
        c.repeat
    );
    let methods: Vec<Method> = c.forward_methods();
    for &map in maps {
        let _ = writeln!(s, "**{map}**, frame time by setting (ms):\n");
        let mut head = String::from("| steps |");
        let mut rule = String::from("|---:|");
        for m in &methods {
            let _ = write!(
                head,
                " `{m}` forward | `{m}` deferred | `{m}` forward gbuffer | `{m}` deferred trace | lockstep 4x2 / 8x1 | artifacts | hits differ |"
            );
            rule.push_str("---:|---:|---:|---:|---:|---:|---:|");
        }
        let _ = writeln!(s, "{head}\n{rule}");
        for &steps in &c.steps {
            let mut line = format!("| {steps} |");
            for &m in &methods {
                let f = find(results, Sweep::Forward, map, m, Some(steps));
                let d = find(results, Sweep::Methods, map, m, Some(steps));
                let frame = |i: Option<usize>| {
                    i.map_or_else(
                        || "-".to_owned(),
                        |i| {
                            let r = &results.rows[i];
                            format!(
                                "{:.2} ({:.2}-{:.2})",
                                r.total_median_ms, r.total_median_lo_ms, r.total_median_hi_ms
                            )
                        },
                    )
                };
                let gbuffer = f.map_or_else(
                    || "-".to_owned(),
                    |i| format!("{:.2}", results.rows[i].method_median_ms),
                );
                let trace = d.map_or_else(
                    || "-".to_owned(),
                    |i| format!("{:.2}", results.rows[i].method_median_ms),
                );
                let lockstep = d.or(f).map_or_else(
                    || "-".to_owned(),
                    |i| {
                        let r = &results.rows[i];
                        format!("{:.1} / {:.1}", r.iterations_quads8, r.iterations_simd8)
                    },
                );
                let err = d
                    .or(f)
                    .map_or_else(|| "-".to_owned(), |i| pct(&results.rows[i]));
                let differ = f
                    .and_then(|i| results.rows[i].forward_differing_pixels)
                    .map_or_else(|| "-".to_owned(), |n| n.to_string());
                let _ = write!(
                    line,
                    " {} | {} | {gbuffer} | {trace} | {lockstep} | {err} | {differ} |",
                    frame(f),
                    frame(d)
                );
            }
            let _ = writeln!(s, "{line}");
        }
        let _ = writeln!(s);
    }

    // The speed-ups of the deferred frames over the forward frames at `top` steps.
    let _ = writeln!(
        s,
        "**The deferred frame's speed-up over the forward frame at {top} steps** (forward \
         frame / deferred frame; > 1: the deferred frame is faster). `dig` at equal error: \
         DIG's frame time for the forward method's artifact fraction at {top} steps, read \
         off DIG's curve (`>=`: DIG's cheapest setting is already below it). `exact` is more \
         accurate than either (its artifacts in brackets).\n"
    );
    let mut head = String::from("| map | deferred frame |");
    let mut rule = String::from("|---|---|");
    for m in &methods {
        let _ = write!(head, " over forward `{m}`-{top} |");
        rule.push_str("---:|");
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for &map in maps {
        let fwd: Vec<Option<(Timed, &RunRow)>> = methods
            .iter()
            .map(|&m| {
                find(results, Sweep::Forward, map, m, Some(top))
                    .map(|i| (timed(results, i, Time::Frame), &results.rows[i]))
            })
            .collect();
        let mut line_of = |label: String, deferred: &dyn Fn(Method, &RunRow) -> Option<String>| {
            let mut line = format!("| {map} | {label} |");
            for (&m, f) in methods.iter().zip(&fwd) {
                let cell = f
                    .as_ref()
                    .and_then(|(_, row)| deferred(m, row))
                    .unwrap_or_else(|| "-".into());
                let _ = write!(line, " {cell} |");
            }
            let _ = writeln!(s, "{line}");
        };
        let ratio_to = |other: Option<usize>, m: Method| -> Option<String> {
            let k = methods.iter().position(|&x| x == m)?;
            let (f, _) = fwd[k].as_ref()?;
            Some(f.over(&timed(results, other?, Time::Frame)).to_string())
        };
        // The same method deferred.
        line_of(
            format!("the same method deferred, {top} steps (same hits)"),
            &|m, _| ratio_to(find(results, Sweep::Methods, map, m, Some(top)), m),
        );
        line_of("`dig` at equal error".into(), &|m, row| {
            let k = methods.iter().position(|&x| x == m)?;
            let (f, _) = fwd[k].as_ref()?;
            find(results, Sweep::Methods, map, Method::Dig, Some(top))?;
            Some(
                match time_to_error(
                    results,
                    Sweep::Methods,
                    map,
                    Method::Dig,
                    row.artifact_fraction,
                    Time::Frame,
                ) {
                    Some((t, at_most)) => format!(
                        "{}{} (at {})",
                        if at_most { ">= " } else { "" },
                        f.over(&t),
                        pct(row)
                    ),
                    None => format!("`dig` never reaches {}", pct(row)),
                },
            )
        });
        line_of(format!("`dig`, {top} steps"), &|m, _| {
            let i = find(results, Sweep::Methods, map, Method::Dig, Some(top))?;
            Some(format!(
                "{} ({})",
                ratio_to(Some(i), m)?,
                pct(&results.rows[i])
            ))
        });
        line_of("`exact`".into(), &|m, _| {
            let i = find(results, Sweep::Methods, map, Method::Exact, None)?;
            Some(format!(
                "{} ({})",
                ratio_to(Some(i), m)?,
                pct(&results.rows[i])
            ))
        });
    }

    // The other reading: the forward frame at DIG's error.
    let _ = writeln!(
        s,
        "\n**At DIG's equal-error point**: the forward frame's time for DIG's artifact \
         fraction at each setting (read off the forward curve; `<=`: its cheapest setting \
         is already below it; *never*: no setting reaches it), over DIG's deferred frame at \
         that setting.\n"
    );
    let mut head = String::from("| map | `dig` steps | `dig` artifacts |");
    let mut rule = String::from("|---|---:|---:|");
    for m in &methods {
        let _ = write!(head, " forward `{m}` / `dig` |");
        rule.push_str("---:|");
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for &map in maps {
        for &steps in &c.steps {
            let Some(d) = find(results, Sweep::Methods, map, Method::Dig, Some(steps)) else {
                continue;
            };
            let dig = timed(results, d, Time::Frame);
            let target = results.rows[d].artifact_fraction;
            let mut line = format!("| {map} | {steps} | {} |", pct(&results.rows[d]));
            for &m in &methods {
                let cell = match time_to_error(results, Sweep::Forward, map, m, target, Time::Frame)
                {
                    Some((t, at_most)) => {
                        format!("{}{}", if at_most { "<= " } else { "" }, t.over(&dig))
                    }
                    None => "never".into(),
                };
                let _ = write!(line, " {cell} |");
            }
            let _ = writeln!(s, "{line}");
        }
    }
}

fn method_ratios(s: &mut String, results: &BenchResults, maps: &[&str], top: u32) {
    let mut pairs = vec![(Method::Exact, None, Method::Relief, Some(top))];
    // Issue 25's moonshot: `exact` at `relief`-64's time.
    if top != 64 && results.config.steps.contains(&64) {
        pairs.push((Method::Exact, None, Method::Relief, Some(64)));
    }
    pairs.push((Method::ConeExact, None, Method::Exact, None));
    let mut lines = Vec::new();
    for (a, sa, b, sb) in pairs {
        for &map in maps {
            let (Some(i), Some(j)) = (
                find(results, Sweep::Methods, map, a, sa),
                find(results, Sweep::Methods, map, b, sb),
            ) else {
                continue;
            };
            let (ra, rb) = (&results.rows[i], &results.rows[j]);
            let name = |m: Method, st: Option<u32>| match st {
                Some(st) => format!("`{m}`-{st}"),
                None => format!("`{m}`"),
            };
            lines.push(format!(
                "| {} / {} | {map} | {} | {:.2}x | {:.2} / {:.2} | {:.1} / {:.1} | {:.1} / {:.1} | {} / {} |",
                name(a, sa),
                name(b, sb),
                timed(results, i, Time::Method).over(&timed(results, j, Time::Method)),
                ra.method_ms / rb.method_ms,
                ra.method_median_ms,
                rb.method_median_ms,
                ra.iterations_simd8,
                rb.iterations_simd8,
                ra.iterations_warp32,
                rb.iterations_warp32,
                pct(ra),
                pct(rb)
            ));
        }
    }
    if lines.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Method-time ratios\n\n\
         Method time (`trace`, with DIG's corner pass): the ratio of the medians with the \
         range of the per-pass ratios, and the ratio of the minima (the per-map tables' \
         statistic).\n\n\
         | ratio | map | of medians (per pass) | of minima | medians, ms | SIMD-8 | warp-32 | artifacts |\n\
         |---|---|---:|---:|---:|---:|---:|---:|"
    );
    for l in lines {
        let _ = writeln!(s, "{l}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratios_of_medians_carry_the_per_pass_range() {
        let a = Timed {
            median: 30.0,
            passes: vec![28.0, 33.0, 30.0],
        };
        let b = Timed {
            median: 10.0,
            passes: vec![10.0, 10.0, 12.0],
        };
        let r = a.over(&b);
        assert_eq!(r.value, 3.0);
        assert_eq!((r.lo, r.hi), (2.5, 3.3));
        assert_eq!(r.to_string(), "3.00x (2.50-3.30)");
        let none = Timed {
            median: 1.0,
            passes: Vec::new(),
        };
        assert_eq!(a.over(&none).to_string(), "30.00x");
    }
}
