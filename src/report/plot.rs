//! Charts for the reports, as standalone SVG strings (plotters' SVG backend, no fonts or
//! system libraries needed): signed-distance histograms, convergence curves, box plots.

use plotters::prelude::*;

/// A chart could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw the chart {chart:?}: {message}")]
pub struct PlotError {
    pub chart: String,
    pub message: String,
}

fn plot_err(chart: &str) -> impl Fn(String) -> PlotError + '_ {
    move |message| PlotError {
        chart: chart.to_string(),
        message,
    }
}

const SIZE: (u32, u32) = (560, 320);

/// A histogram of `values` (weighted) over `range` in `bins` bins; values outside are counted
/// in the end bins so that nothing is silently dropped.
pub fn histogram_svg(
    title: &str,
    x_label: &str,
    values: &[f64],
    weights: Option<&[f64]>,
    range: (f64, f64),
    bins: usize,
) -> Result<String, PlotError> {
    let err = plot_err(title);
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
    let top = percent.iter().copied().fold(1.0, f64::max) * 1.1;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(range.0..range.1, 0.0..top)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc("% of surface")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        chart
            .draw_series(percent.iter().enumerate().map(|(b, p)| {
                let x0 = range.0 + b as f64 * width;
                Rectangle::new(
                    [(x0, 0.0), (x0 + width, *p)],
                    RGBColor(70, 110, 190).filled(),
                )
            }))
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(svg)
}

/// An axis label with three significant digits and no trailing zeros (a log axis's ticks are
/// products like 0.30000000000000004).
fn significant(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

/// One named curve of (x, y) points.
pub struct Series<'a> {
    pub name: &'a str,
    pub points: &'a [(f64, f64)],
    pub color: RGBColor,
}

/// Line chart of several series; `log_y` for convergence histories.
pub fn line_chart_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_y: bool,
) -> Result<String, PlotError> {
    let err = plot_err(title);
    let pts = || {
        series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in pts() {
        if log_y && *y <= 0.0 {
            continue;
        }
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.1, 1.0);
    }
    if x1 - x0 < 1e-12 {
        x1 = x0 + 1.0;
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56);
        macro_rules! draw {
            ($chart:expr, $map:expr) => {{
                let mut chart = $chart.map_err(|e| err(e.to_string()))?;
                chart
                    .configure_mesh()
                    .x_desc(x_label)
                    .y_desc(y_label)
                    .y_label_formatter(&|v| significant(*v))
                    .draw()
                    .map_err(|e| err(e.to_string()))?;
                for s in series {
                    let points: Vec<(f64, f64)> = s.points.iter().copied().filter($map).collect();
                    let color = s.color;
                    chart
                        .draw_series(LineSeries::new(points, color.stroke_width(2)))
                        .map_err(|e| err(e.to_string()))?
                        .label(s.name)
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
                        });
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .draw()
                    .map_err(|e| err(e.to_string()))?;
            }};
        }
        if log_y {
            let (lo, hi) = (y0 * 0.8, y1 * 1.25);
            draw!(
                builder.build_cartesian_2d(x0..x1, (lo..hi).log_scale()),
                |p: &(f64, f64)| p.1 > 0.0
            );
        } else {
            let pad = ((y1 - y0) * 0.05).max(1e-9);
            draw!(
                builder.build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad)),
                |_: &(f64, f64)| true
            );
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(svg)
}

/// Box plots (median, quartiles, whiskers at 1.5 IQR) of one value per case, per group.
pub fn box_plot_svg(
    title: &str,
    y_label: &str,
    groups: &[(String, Vec<f64>)],
) -> Result<String, PlotError> {
    let err = plot_err(title);
    let names: Vec<String> = groups.iter().map(|(n, _)| n.clone()).collect();
    let top = groups
        .iter()
        .flat_map(|(_, v)| v.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-6)
        * 1.15;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(names.as_slice().into_segmented(), 0.0f32..top as f32)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .y_desc(y_label)
            .x_label_formatter(&|v| match v {
                SegmentValue::Exact(n) | SegmentValue::CenterOf(n) => n.to_string(),
                SegmentValue::Last => String::new(),
            })
            .draw()
            .map_err(|e| err(e.to_string()))?;
        chart
            .draw_series(
                groups
                    .iter()
                    .zip(&names)
                    .filter(|((_, v), _)| !v.is_empty())
                    .map(|((_, v), name)| {
                        let q = Quartiles::new(v);
                        Boxplot::new_vertical(SegmentValue::CenterOf(name), &q)
                    }),
            )
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(svg: &str, needle: &str) -> usize {
        svg.matches(needle).count()
    }

    #[test]
    fn histogram_draws_one_bar_per_non_empty_bin() {
        // 3 values in bin 0, 1 in bin 2 of 4 bins: two filled bars of 75 % and 25 %
        let svg =
            histogram_svg("h", "mm", &[-0.45, -0.4, -0.3, 0.1], None, (-0.5, 0.5), 4).unwrap();
        assert!(svg.starts_with("<svg"));
        let bars = count(&svg, "fill=\"#466EBE\"");
        assert_eq!(bars, 4, "{svg}"); // zero-height bars are drawn too
        assert!(
            svg.contains("mm") && svg.contains("% of surface"),
            "axis labels"
        );
    }

    #[test]
    fn axis_labels_keep_three_significant_digits() {
        assert_eq!(significant(0.30000000000000004), "0.3");
        assert_eq!(significant(0.000123456), "0.000123");
        assert_eq!(significant(12.5), "12.5");
        assert_eq!(significant(1500.0), "1500");
        assert_eq!(significant(-0.25), "-0.25");
    }

    #[test]
    fn line_chart_and_box_plot_render() {
        let pts = [(1.0, 1.0), (2.0, 0.1), (3.0, 0.01)];
        let svg = line_chart_svg(
            "c",
            "iteration",
            "max update (mm)",
            &[Series {
                name: "update",
                points: &pts,
                color: RGBColor(200, 30, 30),
            }],
            true,
        )
        .unwrap();
        assert!(svg.contains("polyline") || svg.contains("<path"), "{svg}");
        let svg = box_plot_svg(
            "b",
            "MASD (mm)",
            &[("malleus".into(), vec![0.1, 0.12, 0.2, 0.15])],
        )
        .unwrap();
        assert!(
            svg.contains("\nmalleus\n") && !svg.contains("\"malleus\""),
            "the group name without quotes: {svg}"
        );
    }
}
