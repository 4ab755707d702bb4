//! Charts for the reports, as standalone SVG documents (the `svg` crate writes them): histograms
//! of signed distances, line charts (convergence, transfer function, static pressure) and box
//! plots of a cohort.
//!
//! Every chart is laid out by one `Frame`: the title on top, the legend at the bottom, outside
//! the data, and the plot area in between, its margins computed from the extents of the axes'
//! labels so that no label is clipped. The axes' ticks come from `axis`, the one tick engine.
//! The SVG names what a reader or a checker looks for: the `x-axis` and `y-axis` groups (with
//! `data-scale` and `data-numbers`) and their `tick-label` texts, the `series` polylines, the
//! `point` circles, the `target` lines and the `legend` group.

mod frame;

use svg::node::element::{Group, Polyline, Rectangle};

use super::axis::{Numbers, Scale};
use frame::{Frame, Horizontal, INK, Mark, dot, line, px, rgb};

/// An RGB colour.
pub type Colour = [u8; 3];

/// Box plots of fewer values than this show every value as a point.
pub const SMALL_N: usize = 10;
const BAR: Colour = [70, 110, 190];
const POINT: Colour = [40, 40, 40];
const TARGET: Colour = [200, 40, 40];

/// What an axis shows: its title, scale and kind of numbers.
#[derive(Debug, Clone, Copy)]
pub struct AxisSpec<'a> {
    pub title: &'a str,
    pub scale: Scale,
    pub numbers: Numbers,
}

impl<'a> AxisSpec<'a> {
    /// Real values on a linear scale.
    pub fn linear(title: &'a str) -> Self {
        Self::new(title, Scale::Linear, Numbers::Real)
    }

    /// Positive real values on a log scale.
    pub fn log(title: &'a str) -> Self {
        Self::new(title, Scale::Log, Numbers::Real)
    }

    /// Counts (iterations, rounds) on a linear scale, in whole numbers.
    pub fn counts(title: &'a str) -> Self {
        Self::new(title, Scale::Linear, Numbers::Integer)
    }

    /// Frequencies on a log scale, in Hz.
    pub fn hertz(title: &'a str) -> Self {
        Self::new(title, Scale::Log, Numbers::Hertz)
    }

    fn new(title: &'a str, scale: Scale, numbers: Numbers) -> Self {
        AxisSpec {
            title,
            scale,
            numbers,
        }
    }
}

/// One named curve of (x, y) points.
pub struct Series<'a> {
    pub name: &'a str,
    pub points: &'a [(f64, f64)],
    pub colour: Colour,
}

/// A horizontal target line of a box plot, named in the legend (e.g. "target ≤ 0.2 mm").
pub struct Target {
    pub value: f64,
    pub label: String,
}

/// A histogram of `values` (weighted) over `range` in `bins` bins, as percentages of the
/// total weight; values outside are counted in the end bins so that nothing is silently
/// dropped.
pub fn histogram_svg(
    title: &str,
    x_title: &str,
    values: &[f64],
    weights: Option<&[f64]>,
    range: (f64, f64),
    bins: usize,
) -> String {
    let bins = bins.max(1);
    let width = (range.1 - range.0) / bins as f64;
    let mut counts = vec![0.0f64; bins];
    for (k, v) in values.iter().enumerate() {
        if !v.is_finite() {
            continue;
        }
        let b = (((v - range.0) / width).floor() as isize).clamp(0, bins as isize - 1) as usize;
        counts[b] += weights.map_or(1.0, |w| w[k]);
    }
    let total: f64 = counts.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let percent: Vec<f64> = counts.iter().map(|c| 100.0 * c / total).collect();
    let top = percent.iter().copied().fold(1.0, f64::max);
    let frame = Frame::new(
        title,
        Horizontal::Values {
            spec: AxisSpec::linear(x_title),
            lo: range.0,
            hi: range.1,
        },
        (AxisSpec::linear("% of surface"), 0.0, top),
        Vec::new(),
    );
    let mut bars = Group::new().set("class", "bars");
    for (b, p) in percent.iter().enumerate() {
        let x0 = frame.x_px(range.0 + b as f64 * width);
        let x1 = frame.x_px(range.0 + (b + 1) as f64 * width);
        let y = frame.y_px(*p);
        bars = bars.add(
            Rectangle::new()
                .set("class", "bar")
                .set("x", px(x0))
                .set("y", px(y))
                .set("width", px(x1 - x0))
                .set("height", px(frame.bottom - y))
                .set("fill", rgb(BAR))
                .set("stroke", "#ffffff")
                .set("stroke-width", 0.5),
        );
    }
    frame.finish(frame.document().add(bars))
}

/// A line chart of several series, the legend below the axes. Points that the axes cannot show
/// (non-finite, or not positive on a log axis) are left out.
pub fn line_chart_svg(title: &str, x: AxisSpec, y: AxisSpec, series: &[Series]) -> String {
    let shown = |p: &(f64, f64)| {
        p.0.is_finite()
            && p.1.is_finite()
            && (x.scale == Scale::Linear || p.0 > 0.0)
            && (y.scale == Scale::Linear || p.1 > 0.0)
    };
    let extent = |values: &mut dyn Iterator<Item = f64>| {
        values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
    };
    let points = || {
        series
            .iter()
            .flat_map(|s| s.points.iter().filter(|p| shown(p)))
    };
    let (x0, x1) = extent(&mut points().map(|p| p.0));
    let (mut y0, mut y1) = extent(&mut points().map(|p| p.1));
    if y.scale == Scale::Linear && y1 > y0 {
        let pad = 0.05 * (y1 - y0);
        (y0, y1) = (y0 - pad, y1 + pad);
    }
    // one legend entry per name (a band's two edges share theirs)
    let mut legend: Vec<(String, Mark)> = Vec::new();
    for s in series {
        if !legend.iter().any(|(name, _)| name == s.name) {
            legend.push((s.name.to_string(), Mark::Line(s.colour)));
        }
    }
    let frame = Frame::new(
        title,
        Horizontal::Values {
            spec: x,
            lo: x0,
            hi: x1,
        },
        (y, y0, y1),
        legend,
    );
    let mut curves = Group::new().set("class", "curves");
    for s in series {
        let points: Vec<String> = s
            .points
            .iter()
            .filter(|p| shown(p))
            .map(|p| format!("{},{}", px(frame.x_px(p.0)), px(frame.y_px(p.1))))
            .collect();
        curves = curves.add(
            Polyline::new()
                .set("class", "series")
                .set("data-name", s.name)
                .set("points", points.join(" "))
                .set("fill", "none")
                .set("stroke", rgb(s.colour))
                .set("stroke-width", 2)
                .set("stroke-linejoin", "round"),
        );
    }
    frame.finish(frame.document().add(curves))
}

/// Quartiles by linear interpolation between order statistics (numpy's default) of sorted
/// values.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let at = q * (sorted.len() - 1) as f64;
    let (k, f) = (at.floor() as usize, at.fract());
    match sorted.get(k + 1) {
        Some(next) => sorted[k] + f * (next - sorted[k]),
        None => sorted[k],
    }
}

/// Box plots of one value per case, per group: the box from the first to the third quartile
/// with the median, whiskers to the furthest values within 1.5 interquartile ranges of the box
/// (Tukey); the values beyond as points, and every value as a point (spread sideways so that
/// equal values stay visible) when a group has fewer than `SMALL_N`. `target`, when given, is a
/// dashed line named in the legend; the value axis starts at 0 and reaches above it.
pub fn box_plot_svg(
    title: &str,
    y_title: &str,
    groups: &[(String, Vec<f64>)],
    target: Option<&Target>,
) -> String {
    let finite: Vec<Vec<f64>> = groups
        .iter()
        .map(|(_, values)| {
            let mut v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
            v.sort_by(f64::total_cmp);
            v
        })
        .collect();
    let top = finite
        .iter()
        .flatten()
        .copied()
        .chain(target.map(|t| t.value))
        .fold(0.0f64, f64::max)
        * 1.1;
    let names: Vec<String> = groups.iter().map(|(n, _)| n.clone()).collect();
    let any_points = finite.iter().any(|v| !v.is_empty() && v.len() < SMALL_N);
    let mut legend = Vec::new();
    if any_points {
        legend.push(("one case".to_string(), Mark::Dot(POINT)));
    }
    if let Some(t) = target {
        legend.push((t.label.clone(), Mark::Dashed(TARGET)));
    }
    let frame = Frame::new(
        title,
        Horizontal::Groups(&names),
        (AxisSpec::linear(y_title), 0.0, top),
        legend,
    );
    let mut boxes = Group::new().set("class", "boxes");
    for (k, values) in finite.iter().enumerate() {
        if values.is_empty() {
            continue;
        }
        let (centre, slot) = frame.slot(k);
        let half = (0.2 * slot).min(30.0);
        let (q1, median, q3) = (
            quantile(values, 0.25),
            quantile(values, 0.5),
            quantile(values, 0.75),
        );
        let fence = 1.5 * (q3 - q1);
        let low = values
            .iter()
            .copied()
            .find(|v| *v >= q1 - fence)
            .unwrap_or(q1);
        let high = values
            .iter()
            .rev()
            .copied()
            .find(|v| *v <= q3 + fence)
            .unwrap_or(q3);
        let y = |v: f64| px(frame.y_px(v));
        let mut group = Group::new()
            .set("class", "box")
            .set("data-group", names[k].as_str())
            .add(line((centre, y(low)), (centre, y(q1)), INK, 1.0))
            .add(line((centre, y(q3)), (centre, y(high)), INK, 1.0))
            .add(line(
                (centre - half / 2.0, y(low)),
                (centre + half / 2.0, y(low)),
                INK,
                1.0,
            ))
            .add(line(
                (centre - half / 2.0, y(high)),
                (centre + half / 2.0, y(high)),
                INK,
                1.0,
            ))
            .add(
                Rectangle::new()
                    .set("x", px(centre - half))
                    .set("y", y(q3))
                    .set("width", px(2.0 * half))
                    .set("height", px(y(q1) - y(q3)))
                    .set("fill", "#dfe7f5")
                    .set("stroke", INK),
            )
            .add(line(
                (centre - half, y(median)),
                (centre + half, y(median)),
                INK,
                2.0,
            ));
        let every = values.len() < SMALL_N;
        // spread sideways by the golden ratio's fractions: deterministic, and no two alike
        for (i, v) in values.iter().enumerate() {
            if every || *v < low || *v > high {
                let spread = ((i as f64 * 0.618_034).fract() - 0.5) * 1.6 * half;
                group = group.add(dot(centre + spread, frame.y_px(*v), POINT));
            }
        }
        boxes = boxes.add(group);
    }
    let mut document = frame.document().add(boxes);
    if let Some(t) = target {
        let at = px(frame.y_px(t.value));
        document = document.add(
            line((frame.left, at), (frame.right, at), &rgb(TARGET), 1.5)
                .set("class", "target")
                .set("data-value", t.value)
                .set("stroke-dasharray", "5 3"),
        );
    }
    frame.finish(document)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::axis::FONT_PX;

    fn count(svg: &str, needle: &str) -> usize {
        svg.matches(needle).count()
    }

    /// The `data-value`s and texts of the tick labels of the axis group `class`.
    fn tick_labels(svg: &str, class: &str) -> Vec<String> {
        let start = svg.find(&format!("class=\"{class}\"")).unwrap();
        let end = svg[start..].find("</g>").unwrap() + start;
        svg[start..end]
            .split("class=\"tick-label\"")
            .skip(1)
            .map(|s| {
                let from = s.find('>').unwrap() + 1;
                let to = s.find("</text>").unwrap();
                s[from..to].trim().to_string()
            })
            .collect()
    }

    #[test]
    fn histogram_draws_one_bar_per_bin() {
        // 3 values in bin 0, 1 in bin 2 of 4 bins: bars of 75 %, 0, 25 % and 0
        let svg = histogram_svg("h", "mm", &[-0.45, -0.4, -0.3, 0.1], None, (-0.5, 0.5), 4);
        assert!(svg.starts_with("<svg"));
        assert_eq!(count(&svg, "class=\"bar\""), 4, "{svg}");
        assert!(svg.contains("mm") && svg.contains("% of surface"));
        assert_eq!(
            tick_labels(&svg, "x-axis"),
            [
                "-0.5", "-0.4", "-0.3", "-0.2", "-0.1", "0.0", "0.1", "0.2", "0.3", "0.4", "0.5"
            ]
        );
    }

    #[test]
    fn a_frequency_axis_is_logarithmic_and_reads_in_hz() {
        let pts: Vec<(f64, f64)> = [250.0, 500.0, 1000.0, 2000.0, 7943.0]
            .iter()
            .map(|f| (*f, 100.0 / (1.0 + f / 1000.0)))
            .collect();
        let svg = line_chart_svg(
            "tf",
            AxisSpec::hertz("frequency (Hz)"),
            AxisSpec::log("|H_V|"),
            &[Series {
                name: "model",
                points: &pts,
                colour: [200, 30, 30],
            }],
        );
        let x_axis = &svg[svg.find("class=\"x-axis\"").unwrap()..];
        let x_axis = &x_axis[..x_axis.find('>').unwrap()];
        assert!(
            x_axis.contains("data-numbers=\"hertz\"") && x_axis.contains("data-scale=\"log\""),
            "{x_axis}"
        );
        assert_eq!(
            tick_labels(&svg, "x-axis"),
            ["250", "500", "1k", "2k", "4k", "8k"]
        );
        assert!(!svg.contains("log10"));
    }

    #[test]
    fn every_legend_entry_lies_below_the_plot_area() {
        let a = [(1.0, 1.0), (2.0, 0.1), (3.0, 0.01)];
        let svg = line_chart_svg(
            "c",
            AxisSpec::counts("iteration"),
            AxisSpec::log("mm"),
            &[
                Series {
                    name: "band",
                    points: &a,
                    colour: [150, 150, 150],
                },
                Series {
                    name: "band",
                    points: &a,
                    colour: [150, 150, 150],
                },
            ],
        );
        assert_eq!(tick_labels(&svg, "x-axis"), ["1", "2", "3"]);
        let legend = &svg[svg.find("class=\"legend\"").unwrap()..];
        assert_eq!(count(legend, "band"), 1, "one entry per name");
        // the legend's texts sit below the x axis line (y of the plot area's bottom)
        let frame_bottom: f64 = {
            let axis = &svg[svg.find("class=\"x-axis\"").unwrap()..];
            let y1 = &axis[axis.find("y1=\"").unwrap() + 4..];
            y1[..y1.find('"').unwrap()].parse().unwrap()
        };
        let text_y: f64 = {
            let t = &legend[legend.find("<text").unwrap()..];
            let y = &t[t.find(" y=\"").unwrap() + 4..];
            y[..y.find('"').unwrap()].parse().unwrap()
        };
        assert!(
            text_y > frame_bottom + 2.0 * FONT_PX,
            "{text_y} vs {frame_bottom}"
        );
    }

    #[test]
    fn small_box_plots_show_every_value_and_the_target() {
        let groups = vec![
            ("malleus".to_string(), vec![0.02, 0.03, 0.025]),
            ("incus".to_string(), vec![0.01, 0.02, 0.015]),
        ];
        let target = Target {
            value: 0.2,
            label: "target ≤ 0.2 mm".into(),
        };
        let svg = box_plot_svg("MASD", "MASD (mm)", &groups, Some(&target));
        assert_eq!(
            count(&svg, "class=\"point\""),
            6 + 1,
            "six cases and the legend's dot"
        );
        assert_eq!(count(&svg, "class=\"target\""), 1);
        assert!(svg.contains("target ≤ 0.2 mm"));
        // the value axis reaches above the target
        let labels = tick_labels(&svg, "y-axis");
        let top: f64 = labels.last().unwrap().parse().unwrap();
        assert!(top > 0.2, "{labels:?}");
        assert!(
            svg.contains(">\nmalleus\n<") || svg.contains(">malleus<"),
            "{svg}"
        );
    }

    #[test]
    fn tukey_whiskers_end_at_data_and_outliers_are_points() {
        // 12 values: 11 between 1 and 2, one outlier at 10; no whisker reaches beyond the data
        let mut values: Vec<f64> = (0..11).map(|k| 1.0 + k as f64 / 10.0).collect();
        values.push(10.0);
        let svg = box_plot_svg("b", "mm", &[("g".into(), values)], None);
        assert_eq!(count(&svg, "class=\"point\""), 1, "only the outlier");
        let sorted: Vec<f64> = (0..11).map(|k| 1.0 + k as f64 / 10.0).collect();
        assert_eq!(quantile(&sorted, 0.5), 1.5);
        assert!((quantile(&sorted, 0.25) - 1.25).abs() < 1e-12);
    }
}
