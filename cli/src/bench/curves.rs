//! Speed-error curves and what is read off them: the time a method needs for a target
//! error ([`time_to_reach`]) and DIG's speed-ups over another method at the same setting
//! and at equal error.
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

use super::{RunRow, Sweep};
use dispmap::method::Method;

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

    /// The value as the report writes it.
    pub(super) fn format(self, v: f64) -> String {
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

/// The run of `method` on `map` at `steps`.
pub(super) fn row_at<'r>(
    rows: &'r [RunRow],
    map: &str,
    method: Method,
    steps: u32,
) -> Option<&'r RunRow> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::results::sample_row as row;

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
}
