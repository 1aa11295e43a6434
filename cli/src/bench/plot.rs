//! The benchmark's plots, drawn with `plotters` into an RGB buffer and written as PNG
//! (RGB, best compression) as bytes for [`crate::output::Outputs`]. Text uses the
//! bundled DejaVu Sans subset (`assets/fonts`, registered with plotters' `ab_glyph`
//! backend), so no system font is needed.
//!
//! * [`pareto`]: per map, method time (x) against error (y, log) with one curve per
//!   method through its settings; methods without a step count are single larger
//!   markers. Left: artifact fraction; right: mean hit distance. Top: every method, log
//!   time axis; bottom: the marching methods, linear time axis, every point labelled
//!   with its `iter`. Errors of 0 are drawn on the axis floor.
//! * [`with_heat_bar`]: an iteration heat map with its colour bar under it.
//! * [`sizes`]: the map-size sweep: method time per frame against map size (log), the
//!   same relative to the smallest map, and the pyramid's one build (log).

use super::curves::curve_rows;
use super::{RunRow, Sweep, has_steps};
use dispmap::error::{Error, Result};
use dispmap::method::Method;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;
use std::sync::OnceLock;

/// The bundled font (DejaVu Sans, subset to Latin-1, Greek, punctuation and maths;
/// license in `assets/fonts/LICENSE-DejaVu.txt`).
pub const FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans-subset.ttf");

/// The font family name the plots use.
pub(crate) const FAMILY: &str = "sans-serif";

/// Pareto plot size in pixels.
pub const PARETO_SIZE: (u32, u32) = (1280, 1040);

/// Map-size plot size in pixels.
pub const SIZES_SIZE: (u32, u32) = (1500, 460);

pub(crate) fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
                .map_err(|_| "the bundled font does not parse".to_owned())
        })
        .clone()
        .map_err(|m| Error::invalid("font", m))
}

/// The colour of a method (fixed across plots).
pub fn method_color(method: Method) -> RGBColor {
    match method {
        // Tableau 10 (a palette made for categorical data: distinct hues of similar
        // weight), with black for `exact`, grey for the `bump` floor and a dark purple
        // for the twelfth.
        Method::Bump => RGBColor(160, 160, 160),
        Method::Linear => RGBColor(118, 183, 178),
        Method::Relief => RGBColor(78, 121, 167),
        Method::Pom => RGBColor(242, 142, 43),
        Method::Secant => RGBColor(176, 122, 161),
        Method::Dig => RGBColor(225, 87, 89),
        Method::DigGuarded => RGBColor(255, 157, 167),
        Method::Pyramid => RGBColor(89, 161, 79),
        Method::Exact => RGBColor(0, 0, 0),
        Method::Cone => RGBColor(237, 201, 72),
        Method::ConeExact => RGBColor(156, 117, 95),
        Method::RelaxedCone => RGBColor(96, 40, 120),
    }
}

/// Height in pixels of the colour bar under a benchmark heat map ([`with_heat_bar`]).
pub const HEAT_BAR_HEIGHT: u32 = 30;

/// `rgba`, an iteration heat map of `width` x `height` (RGBA8, the ramp from 0 to `top`
/// iterations), with its colour bar under it: the ramp across the width, `0` under its
/// left end, `top` under its right end and, where there is room, what it counts. RGBA8
/// of `width` x `height + HEAT_BAR_HEIGHT`.
pub fn with_heat_bar(rgba: &[u8], width: u32, height: u32, top: f32) -> Result<Vec<u8>> {
    register_font()?;
    let (w, h) = (width as usize, height as usize);
    if rgba.len() != 4 * w * h || w == 0 {
        return Err(Error::invalid(
            "heat map",
            format!("{} bytes are not {width}x{height} RGBA8", rgba.len()),
        ));
    }
    let total = height + HEAT_BAR_HEIGHT;
    let mut rgb = vec![255u8; w * total as usize * 3];
    for (dst, src) in rgb.chunks_exact_mut(3).zip(rgba.chunks_exact(4)) {
        dst.copy_from_slice(&src[..3]);
    }
    let drawn = (|| -> std::result::Result<(), String> {
        let e = |e: &dyn std::fmt::Display| e.to_string();
        let root = BitMapBackend::with_buffer(&mut rgb, (width, total)).into_drawing_area();
        let margin = if width >= 24 { 4 } else { 0 };
        let (x0, x1) = (margin, width as i32 - margin);
        let (y0, y1) = (height as i32 + 3, height as i32 + 13);
        for x in x0..x1 {
            let t = (x - x0) as f32 / (x1 - x0 - 1).max(1) as f32;
            let [r, g, b] = crate::heatmap::ramp(t);
            for y in y0..y1 {
                root.draw_pixel((x, y), &RGBColor(r, g, b))
                    .map_err(|x| e(&x))?;
            }
        }
        let font = |h: HPos| {
            (FAMILY, 12)
                .into_font()
                .color(&BLACK)
                .pos(Pos::new(h, VPos::Top))
        };
        let label_y = y1 + 2;
        root.draw(&Text::new("0", (x0, label_y), font(HPos::Left)))
            .map_err(|x| e(&x))?;
        root.draw(&Text::new(
            format!("{top:.0}"),
            (x1 - 1, label_y),
            font(HPos::Right),
        ))
        .map_err(|x| e(&x))?;
        if width >= 200 {
            root.draw(&Text::new(
                "iterations per pixel",
                (width as i32 / 2, label_y),
                font(HPos::Center),
            ))
            .map_err(|x| e(&x))?;
        }
        root.present().map_err(|x| e(&x))
    })();
    drawn.map_err(|message| {
        Error::invalid("heat map", format!("cannot draw its colour bar: {message}"))
    })?;
    Ok(rgb
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect())
}

/// Draws into an RGB buffer with `draw` and encodes it as PNG (`path` names it in errors).
fn render_png(
    path: &Path,
    (w, h): (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> std::result::Result<(), String>,
) -> Result<Vec<u8>> {
    register_font()?;
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| e.to_string())
            .and_then(|_| draw(&root))
            .and_then(|_| root.present().map_err(|e| e.to_string()))
            .map_err(|message| Error::Image {
                path: path.to_owned(),
                message: format!("cannot draw the plot: {message}"),
            })?;
    }
    // RGB, best compression: plots are mostly flat colour, so this keeps them small.
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        &mut png,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    image::ImageEncoder::write_image(encoder, &rgb, w, h, image::ExtendedColorType::Rgb8).map_err(
        |e| Error::Image {
            path: path.to_owned(),
            message: format!("cannot encode PNG: {e}"),
        },
    )?;
    Ok(png)
}

/// Lower and upper bound for a log axis over `values` (positive ones, at least `floor`;
/// `floor` to `10 floor` if none), widened to whole decades so that every decade gets
/// tick labels.
fn log_range(values: impl Iterator<Item = f64>, floor: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (floor, floor * 10.0);
    }
    let lo = lo.max(floor);
    let hi = hi.max(lo);
    let lo = 10f64.powf((lo / 1.05).log10().floor());
    let hi = 10f64.powf((hi * 1.05).log10().ceil());
    // A hair below the decade, so rounding cannot drop the first tick label.
    (lo * (1.0 - 1e-9), hi.max(lo * 10.0))
}

/// Where a Pareto panel draws zeros and values under its floor: this factor above the
/// axis' lowest value (a fifth of a decade), so that their markers are whole.
const ZERO_LIFT: f64 = 1.6;

/// What a Pareto panel shows.
struct Panel<'a> {
    title: String,
    y_desc: &'a str,
    value: fn(&RunRow) -> f64,
    /// Smallest value drawn (zeros are drawn on it).
    floor: f64,
    /// Largest upper bound of the y axis.
    cap: f64,
    /// Linear time axis over the data, with each point labelled by its steps (the zoom
    /// on the marching methods); otherwise a log time axis and only the curves' ends
    /// labelled.
    zoom: bool,
}

/// One panel of the Pareto plot: `panel.value` of each row against its method time.
fn pareto_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    panel: &Panel<'_>,
    curves: &[(Method, Vec<&RunRow>)],
) -> std::result::Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let value = panel.value;
    let all = || curves.iter().flat_map(|(_, rows)| rows.iter());
    let (y0, y1) = log_range(all().map(|r| value(r)), panel.floor);
    let y1 = y1.min(panel.cap).max(y0 * 10.0);
    let x_desc = if panel.zoom {
        "method time per frame (ms; dig_corners + trace)"
    } else {
        "method time per frame (ms, log; dig_corners + trace)"
    };
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&panel.title, (FAMILY, 19))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(72);
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(x_desc)
                .y_desc(panel.y_desc)
                .label_style((FAMILY, 14))
                .axis_desc_style((FAMILY, 15))
                .x_label_formatter(&|x| format_tick(*x))
                .y_label_formatter(&|y| format_tick(*y))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(|x| e(&x))?;
            // Step labels placed so far (pixel boxes): a label that would overlap one is
            // left out.
            let mut placed: Vec<(i32, i32, i32, i32)> = Vec::new();
            for (method, rows) in curves {
                let color = method_color(*method);
                // Zeros (and values under the floor) sit a little above the bottom edge,
                // whole, not cut by it.
                let points: Vec<(f64, f64)> = rows
                    .iter()
                    .map(|r| {
                        let v = value(r);
                        let v = if v <= panel.floor {
                            y0 * ZERO_LIFT
                        } else {
                            v.clamp(y0, y1)
                        };
                        (r.method_ms, v)
                    })
                    .collect();
                let name = method.name();
                if has_steps(*method) {
                    chart
                        .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
                        .map_err(|x| e(&x))?
                        .label(name)
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(2))
                        });
                    chart
                        .draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))
                        .map_err(|x| e(&x))?;
                    let last = rows.len().saturating_sub(1);
                    for (i, (r, &p)) in rows.iter().zip(&points).enumerate() {
                        let labelled = panel.zoom || i == 0 || i == last;
                        if let (true, Some(steps)) = (labelled, r.steps) {
                            let (px, py) = chart.backend_coord(&p);
                            let text = steps.to_string();
                            let w = 7 * text.len() as i32;
                            let rect = (px + 5, py - 16, px + 5 + w, py - 3);
                            let overlaps = placed.iter().any(|q| {
                                rect.0 < q.2 && q.0 < rect.2 && rect.1 < q.3 && q.1 < rect.3
                            });
                            if overlaps {
                                continue;
                            }
                            placed.push(rect);
                            chart
                                .draw_series(std::iter::once(
                                    EmptyElement::at(p)
                                        + Text::new(
                                            text,
                                            (5, -16),
                                            (FAMILY, 12).into_font().color(&color),
                                        ),
                                ))
                                .map_err(|x| e(&x))?;
                        }
                    }
                } else {
                    chart
                        .draw_series(
                            points
                                .iter()
                                .map(|&p| TriangleMarker::new(p, 8, color.filled())),
                        )
                        .map_err(|x| e(&x))?
                        .label(format!("{name} (one run)"))
                        .legend(move |(x, y)| TriangleMarker::new((x + 11, y), 6, color.filled()));
                }
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .label_font((FAMILY, 13))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(160, 160, 160))
                .draw()
                .map_err(|x| e(&x))?;
        }};
    }
    if panel.zoom {
        let (lo, hi) = all()
            .map(|r| r.method_ms)
            .filter(|t| t.is_finite())
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), t| {
                (lo.min(t), hi.max(t))
            });
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
        let pad = ((hi - lo) * 0.08).max(hi * 0.02).max(1e-3);
        // The legend sits in the lower left: leave room for it there.
        draw!(
            builder
                .build_cartesian_2d((lo - 4.0 * pad).max(0.0)..hi + pad, (y0..y1).log_scale())
                .map_err(|x| e(&x))?
        );
    } else {
        let (x0, x1) = log_range(all().map(|r| r.method_ms), 1e-3);
        draw!(
            builder
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(|x| e(&x))?
        );
    }
    Ok(())
}

/// Tick label: up to 3 significant digits without trailing zeros.
fn format_tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return "0".into();
    }
    let digits = (2 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

/// The marching methods the zoomed panels of the Pareto plot show (the DIG paper's
/// comparison plus `linear` and `secant`).
pub const ZOOM_METHODS: [Method; 5] = [
    Method::Linear,
    Method::Relief,
    Method::Pom,
    Method::Secant,
    Method::Dig,
];

/// The Pareto plot of `map` (methods sweep rows) as PNG (`path` names it in errors): top, every method
/// (log-log); bottom, the marching methods ([`ZOOM_METHODS`]) with a linear time axis
/// and every point labelled with its steps.
pub fn pareto(path: &Path, map: &str, rows: &[RunRow]) -> Result<Vec<u8>> {
    let curves: Vec<(Method, Vec<&RunRow>)> = Method::ALL
        .iter()
        .map(|&m| (m, curve_rows(rows, map, m)))
        .filter(|(_, r)| !r.is_empty())
        .collect();
    let zoomed: Vec<(Method, Vec<&RunRow>)> = curves
        .iter()
        .filter(|(m, _)| ZOOM_METHODS.contains(m))
        .cloned()
        .collect();
    let artifacts = |zoom: bool| Panel {
        title: format!(
            "{map}: artifacts against time{}",
            if zoom { " (marching methods)" } else { "" }
        ),
        y_desc: "artifacts (% of covered pixels, log; 0 at the bottom)",
        value: |r| 100.0 * r.artifact_fraction,
        floor: 1e-3,
        cap: 100.0,
        zoom,
    };
    let texels = |zoom: bool| Panel {
        title: format!(
            "{map}: mean hit distance against time{}",
            if zoom { " (marching methods)" } else { "" }
        ),
        y_desc: "mean hit distance (texels, log; 0 at the bottom)",
        value: |r| r.mean_texels,
        floor: 1e-4,
        cap: f64::INFINITY,
        zoom,
    };
    render_png(path, PARETO_SIZE, |root| {
        let areas = root.split_evenly((2, 2));
        pareto_panel(&areas[0], &artifacts(false), &curves)?;
        pareto_panel(&areas[1], &texels(false), &curves)?;
        if !zoomed.is_empty() {
            pareto_panel(&areas[2], &artifacts(true), &zoomed)?;
            pareto_panel(&areas[3], &texels(true), &zoomed)?;
        }
        Ok(())
    })
}

/// The map-size plot (map-size sweep rows) as PNG (`path` names it in errors): method time per frame
/// (log), the same relative to the smallest map, and the one-off builds (log): the
/// pyramid, plus the cone map for a cone method.
pub fn sizes(path: &Path, rows: &[RunRow]) -> Result<Vec<u8>> {
    let rows: Vec<&RunRow> = rows.iter().filter(|r| r.sweep == Sweep::MapSize).collect();
    let mut sides: Vec<u32> = rows.iter().map(|r| r.map_width).collect();
    sides.sort_unstable();
    sides.dedup();
    let methods: Vec<Method> = Method::ALL
        .iter()
        .copied()
        .filter(|m| rows.iter().any(|r| r.method == m.name()))
        .collect();
    let value_at = |m: Method, side: u32, value: fn(&RunRow) -> Option<f64>| {
        rows.iter()
            .find(|r| r.map_width == side && r.method == m.name())
            .and_then(|r| value(r))
            .filter(|v| v.is_finite() && *v > 0.0)
    };
    let series = |value: fn(&RunRow) -> Option<f64>, relative: bool| {
        methods
            .iter()
            .map(|&m| {
                let base = sides.first().and_then(|&s| value_at(m, s, value));
                let points: Vec<(usize, f64)> = sides
                    .iter()
                    .enumerate()
                    .filter_map(|(i, &side)| {
                        let v = value_at(m, side, value)?;
                        if relative {
                            base.map(|b| (i, v / b))
                        } else {
                            Some((i, v))
                        }
                    })
                    .collect();
                (m, points)
            })
            .filter(|(_, p)| !p.is_empty())
            .collect::<Vec<_>>()
    };
    let method_ms: fn(&RunRow) -> Option<f64> = |r| Some(r.method_ms);
    // A cone method's one-off cost is its pyramid and its cone map.
    let build_ms: fn(&RunRow) -> Option<f64> = |r| {
        r.pyramid_build_ms
            .map(|p| p + r.cone_build_ms.unwrap_or(0.0))
    };
    // Legends where the lines are not: under the (flat) time curves, above the rising
    // ratio and build curves.
    let panels = [
        (
            "method time per frame",
            "method time (ms, log)",
            series(method_ms, false),
            true,
            SeriesLabelPosition::LowerRight,
        ),
        (
            "relative to the smallest map",
            "method time / time at the smallest map",
            series(method_ms, true),
            false,
            SeriesLabelPosition::UpperLeft,
        ),
        (
            "pyramid (+ cone map) build, once per map",
            "build time (ms, log)",
            series(build_ms, false),
            true,
            SeriesLabelPosition::UpperLeft,
        ),
    ];
    render_png(path, SIZES_SIZE, |root| {
        let areas = root.split_evenly((1, 3));
        for (area, (title, y_desc, series, log, legend)) in areas.iter().zip(panels) {
            size_panel(area, &sides, title, y_desc, &series, log, legend)?;
        }
        Ok(())
    })
}

/// One panel of the map-size plot: `series` (index into `sides`, value) per method.
fn size_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    sides: &[u32],
    title: &str,
    y_desc: &str,
    series: &[(Method, Vec<(usize, f64)>)],
    log: bool,
    legend: SeriesLabelPosition,
) -> std::result::Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let n = sides.len().max(1);
    let label = |i: &SegmentValue<usize>| match i {
        SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => {
            sides.get(*i).map_or_else(String::new, |s| s.to_string())
        }
        SegmentValue::Last => String::new(),
    };
    let values = || series.iter().flat_map(|(_, s)| s.iter().map(|p| p.1));
    let x_desc = "height-map side (texels)";
    // Segmented ranges include their end: 0..n-1 gives n segments.
    let x = (0..n - 1).into_segmented();
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(x_desc)
                .y_desc(y_desc)
                .label_style((FAMILY, 13))
                .axis_desc_style((FAMILY, 14))
                .x_label_formatter(&label)
                .y_label_formatter(&|y| format_tick(*y))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(|x| e(&x))?;
            for (m, s) in series {
                let color = method_color(*m);
                let points: Vec<(SegmentValue<usize>, f64)> = s
                    .iter()
                    .map(|&(i, v)| (SegmentValue::CenterOf(i), v))
                    .collect();
                chart
                    .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
                    .map_err(|x| e(&x))?
                    .label(m.name())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(2))
                    });
                chart
                    .draw_series(
                        points
                            .into_iter()
                            .map(|p| Circle::new(p, 4, color.filled())),
                    )
                    .map_err(|x| e(&x))?;
            }
            chart
                .configure_series_labels()
                .position(legend.clone())
                .label_font((FAMILY, 13))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(160, 160, 160))
                .draw()
                .map_err(|x| e(&x))?;
        }};
    }
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(title, (FAMILY, 18))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(60);
    if log {
        let (y0, y1) = log_range(values(), 1e-3);
        draw!(
            builder
                .build_cartesian_2d(x, (y0..y1).log_scale())
                .map_err(|x| e(&x))?
        );
    } else {
        let hi = values().fold(1.0f64, f64::max) * 1.15;
        let lo = values().fold(1.0f64, f64::min).min(1.0) * 0.9;
        draw!(
            builder
                .build_cartesian_2d(x, lo.min(0.9)..hi.max(1.1))
                .map_err(|x| e(&x))?
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_and_ranges() {
        assert_eq!(format_tick(1.0), "1");
        assert_eq!(format_tick(0.0125), "0.0125");
        assert_eq!(format_tick(250.0), "250");
        assert_eq!(format_tick(12.34), "12.3");
        let close = |(a, b): (f64, f64), (c, d): (f64, f64)| {
            assert!(
                (a - c).abs() < 1e-6 * c && (b - d).abs() < 1e-6 * d,
                "{a} {b}"
            )
        };
        close(log_range([0.0, 2.0, 8.0].into_iter(), 1e-3), (1.0, 10.0));
        close(log_range([1.1, 50.0].into_iter(), 1e-3), (1.0, 100.0));
        assert_eq!(log_range(std::iter::empty(), 0.5), (0.5, 5.0));
    }

    #[test]
    fn the_font_registers() {
        register_font().unwrap();
    }
}
