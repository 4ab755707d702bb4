//! The layout every chart shares: one `Frame` puts the title on top, the legend at the bottom,
//! outside the data, and the plot area in between, its margins computed from the extents of the
//! axes' labels so that no label is clipped; and the SVG pieces the charts are drawn with.

use svg::node::element::{Circle, Group, Line, Rectangle, Text};
use svg::{Document, Node};

use super::{AxisSpec, Colour};
use crate::report::axis::{Axis, Direction, FONT_PX, Scale, text_width};

/// Size of every chart \[px\].
const WIDTH: f64 = 560.0;
const HEIGHT: f64 = 320.0;
/// Space between the figure's edge and anything drawn \[px\].
const MARGIN: f64 = 8.0;
/// Font size of the title \[px\].
const TITLE_PX: f64 = 14.0;
/// Length of a tick mark \[px\].
const TICK: f64 = 4.0;
/// From the x axis down to its labels' baseline \[px\]: below the lowest y label, which is
/// centred on the axis, so that the two never touch in the corner.
const LABEL_DROP: f64 = TICK + 5.0 + FONT_PX;
/// Height of one row of the legend \[px\].
const LEGEND_ROW: f64 = 1.7 * FONT_PX;
/// Length of a legend entry's line sample \[px\], and the space after an entry.
const SWATCH: f64 = 18.0;
const ENTRY_GAP: f64 = 16.0;
pub(super) const INK: &str = "#222222";
const GRID: &str = "#dddddd";
const MINOR_GRID: &str = "#f0f0f0";

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
pub(super) enum Mark {
    Line(Colour),
    Dashed(Colour),
    Dot(Colour),
}

/// The horizontal axis of a chart: values, or one slot per named group.
pub(super) enum Horizontal<'a> {
    Values {
        spec: AxisSpec<'a>,
        lo: f64,
        hi: f64,
    },
    Groups(&'a [String]),
}

/// A chart's layout: the plot area `left..right` × `top..bottom` \[px\], its axes and legend.
pub(super) struct Frame<'a> {
    title: &'a str,
    pub(super) left: f64,
    pub(super) right: f64,
    top: f64,
    pub(super) bottom: f64,
    x: Option<(Axis, &'a str)>,
    groups: &'a [String],
    y: Axis,
    y_title: &'a str,
    /// Legend rows: the entries of each with their left edge \[px\].
    legend: Vec<Vec<(f64, String, Mark)>>,
}

/// Rounded to a tenth of a pixel, for short and stable SVG.
pub(super) fn px(v: f64) -> f64 {
    (v * 10.0).round() / 10.0
}

pub(super) fn rgb([r, g, b]: Colour) -> String {
    format!("#{r:02x}{g:02x}{b:02x}")
}

impl<'a> Frame<'a> {
    /// Lays out a chart: legend rows first (their height), then the y axis in the height left,
    /// then the margins from the y labels' width and the x labels' overhang.
    pub(super) fn new(
        title: &'a str,
        horizontal: Horizontal<'a>,
        y: (AxisSpec<'a>, f64, f64),
        legend: Vec<(String, Mark)>,
    ) -> Frame<'a> {
        let legend = legend_rows(legend);
        let top = MARGIN + 1.4 * TITLE_PX;
        let bottom = HEIGHT
            - MARGIN
            - legend.len() as f64 * LEGEND_ROW
            - 1.5 * FONT_PX // the x axis title
            - LABEL_DROP
            - 0.3 * FONT_PX // the tick labels' descent
            - 2.0;
        let (spec, lo, hi) = y;
        let y_axis = Axis::new(
            lo,
            hi,
            spec.scale,
            spec.numbers,
            bottom - top,
            Direction::Vertical,
        );
        let mut left = MARGIN + 1.6 * FONT_PX + y_axis.widest_label() + TICK + 4.0;
        let mut right = WIDTH - MARGIN;
        let (x, groups) = match horizontal {
            Horizontal::Groups(groups) => (None, groups),
            Horizontal::Values { spec, lo, hi } => {
                // the end labels are centred on the ends of the axis: room for their halves
                let mut axis;
                loop {
                    axis = Axis::new(
                        lo,
                        hi,
                        spec.scale,
                        spec.numbers,
                        right - left,
                        Direction::Horizontal,
                    );
                    let half = |t: Option<&crate::report::axis::Tick>| {
                        t.map_or(0.0, |t| text_width(&t.label, FONT_PX) / 2.0)
                    };
                    let need_right = WIDTH - MARGIN - half(axis.ticks.last());
                    let need_left = MARGIN + half(axis.ticks.first());
                    if right <= need_right && left >= need_left {
                        break;
                    }
                    right = right.min(need_right);
                    left = left.max(need_left);
                }
                (Some((axis, spec.title)), &[][..])
            }
        };
        Frame {
            title,
            left,
            right,
            top,
            bottom,
            x,
            groups,
            y: y_axis,
            y_title: spec.title,
            legend,
        }
    }

    pub(super) fn x_px(&self, v: f64) -> f64 {
        let axis = self.x.as_ref().map(|(a, _)| a);
        self.left + axis.map_or(0.0, |a| a.fraction(v)) * (self.right - self.left)
    }

    pub(super) fn y_px(&self, v: f64) -> f64 {
        self.bottom - self.y.fraction(v) * (self.bottom - self.top)
    }

    /// The centre of group `k`'s slot and the slot's width \[px\].
    pub(super) fn slot(&self, k: usize) -> (f64, f64) {
        let width = (self.right - self.left) / self.groups.len().max(1) as f64;
        (self.left + (k as f64 + 0.5) * width, width)
    }

    /// The document with the background, the title and the grid, ready for the data.
    pub(super) fn document(&self) -> Document {
        let mut grid = Group::new().set("class", "grid");
        let mut gridline = |v: f64, colour: &str| {
            let y = px(self.y_px(v));
            grid.append(line((self.left, y), (self.right, y), colour, 1.0));
        };
        for v in &self.y.minor {
            gridline(*v, MINOR_GRID);
        }
        for t in &self.y.ticks {
            gridline(t.value, GRID);
        }
        if let Some((x, _)) = &self.x {
            for (values, colour) in [
                (x.minor.clone(), MINOR_GRID),
                (x.ticks.iter().map(|t| t.value).collect(), GRID),
            ] {
                for v in values {
                    let at = px(self.x_px(v));
                    grid.append(line((at, self.top), (at, self.bottom), colour, 1.0));
                }
            }
        }
        Document::new()
            .set("class", "chart")
            .set("width", WIDTH)
            .set("height", HEIGHT)
            .set("viewBox", (0, 0, WIDTH, HEIGHT))
            .set("font-family", "sans-serif")
            .set("font-size", FONT_PX)
            .add(
                Rectangle::new()
                    .set("width", WIDTH)
                    .set("height", HEIGHT)
                    .set("fill", "#ffffff"),
            )
            .add(
                text(WIDTH / 2.0, MARGIN + TITLE_PX, self.title, "middle")
                    .set("class", "title")
                    .set("font-size", TITLE_PX),
            )
            .add(grid)
    }

    /// The axes, ticks, labels and titles, and the legend, over the data.
    pub(super) fn finish(&self, document: Document) -> String {
        let (l, r, t, b) = (px(self.left), px(self.right), px(self.top), px(self.bottom));
        let mut x_group = Group::new()
            .set("class", "x-axis")
            .add(line((l, b), (r, b), INK, 1.0));
        let label_y = b + LABEL_DROP;
        match &self.x {
            Some((axis, title)) => {
                x_group = x_group
                    .set("data-scale", scale_name(axis.scale))
                    .set("data-numbers", axis.numbers.name());
                for tick in &axis.ticks {
                    let at = px(self.x_px(tick.value));
                    x_group = x_group.add(line((at, b), (at, b + TICK), INK, 1.0)).add(
                        text(at, label_y, &tick.label, "middle")
                            .set("class", "tick-label")
                            .set("data-value", tick.value),
                    );
                }
                x_group = x_group.add(
                    text((l + r) / 2.0, label_y + 1.4 * FONT_PX, title, "middle")
                        .set("class", "axis-title"),
                );
            }
            None => {
                x_group = x_group.set("data-scale", "groups");
                for (k, name) in self.groups.iter().enumerate() {
                    let at = px(self.slot(k).0);
                    x_group =
                        x_group.add(text(at, label_y, name, "middle").set("class", "group-label"));
                }
            }
        }
        let mut y_group = Group::new()
            .set("class", "y-axis")
            .set("data-scale", scale_name(self.y.scale))
            .set("data-numbers", self.y.numbers.name())
            .add(line((l, t), (l, b), INK, 1.0));
        for tick in &self.y.ticks {
            let at = px(self.y_px(tick.value));
            y_group = y_group.add(line((l - TICK, at), (l, at), INK, 1.0)).add(
                text(l - TICK - 3.0, at + 0.35 * FONT_PX, &tick.label, "end")
                    .set("class", "tick-label")
                    .set("data-value", tick.value),
            );
        }
        let (tx, ty) = (px(MARGIN + FONT_PX), px((t + b) / 2.0));
        y_group = y_group.add(
            text(tx, ty, self.y_title, "middle")
                .set("class", "axis-title")
                .set("transform", format!("rotate(-90 {tx} {ty})")),
        );
        let mut document = document.add(x_group).add(y_group);
        if !self.legend.is_empty() {
            document = document.add(self.legend_group());
        }
        document.to_string()
    }

    fn legend_group(&self) -> Group {
        let mut group = Group::new().set("class", "legend");
        let first_row = HEIGHT - MARGIN - self.legend.len() as f64 * LEGEND_ROW;
        for (row, entries) in self.legend.iter().enumerate() {
            let mid = px(first_row + (row as f64 + 0.5) * LEGEND_ROW);
            for (x, label, mark) in entries {
                let x = px(*x);
                let sample: Box<dyn Node> = match *mark {
                    Mark::Line(c) => Box::new(line((x, mid), (x + SWATCH, mid), &rgb(c), 2.0)),
                    Mark::Dashed(c) => Box::new(
                        line((x, mid), (x + SWATCH, mid), &rgb(c), 1.5)
                            .set("stroke-dasharray", "5 3"),
                    ),
                    Mark::Dot(c) => Box::new(dot(x + SWATCH / 2.0, mid, c)),
                };
                group = group.add(sample).add(text(
                    x + SWATCH + 5.0,
                    mid + 0.35 * FONT_PX,
                    label,
                    "start",
                ));
            }
        }
        group
    }
}

/// Lays the legend out in rows, each centred in the figure's width: (left edge, label, mark).
fn legend_rows(entries: Vec<(String, Mark)>) -> Vec<Vec<(f64, String, Mark)>> {
    let width = |label: &str| SWATCH + 5.0 + text_width(label, FONT_PX);
    let mut rows: Vec<Vec<(String, Mark)>> = Vec::new();
    let mut used = f64::MAX;
    for (label, mark) in entries {
        let w = width(&label);
        if used + ENTRY_GAP + w > WIDTH - 2.0 * MARGIN {
            rows.push(Vec::new());
            used = -ENTRY_GAP;
        }
        used += ENTRY_GAP + w;
        if let Some(row) = rows.last_mut() {
            row.push((label, mark));
        }
    }
    rows.into_iter()
        .map(|row| {
            let total: f64 = row.iter().map(|(l, _)| width(l)).sum::<f64>()
                + ENTRY_GAP * (row.len().saturating_sub(1)) as f64;
            let mut x = (WIDTH - total) / 2.0;
            row.into_iter()
                .map(|(label, mark)| {
                    let at = x;
                    x += width(&label) + ENTRY_GAP;
                    (at, label, mark)
                })
                .collect()
        })
        .collect()
}

fn scale_name(scale: Scale) -> &'static str {
    match scale {
        Scale::Linear => "linear",
        Scale::Log => "log",
    }
}

pub(super) fn line(a: (f64, f64), b: (f64, f64), colour: &str, width: f64) -> Line {
    Line::new()
        .set("x1", px(a.0))
        .set("y1", px(a.1))
        .set("x2", px(b.0))
        .set("y2", px(b.1))
        .set("stroke", colour)
        .set("stroke-width", width)
}

fn text(x: f64, y: f64, content: &str, anchor: &str) -> Text {
    Text::new(content)
        .set("x", px(x))
        .set("y", px(y))
        .set("text-anchor", anchor)
        .set("fill", INK)
}

pub(super) fn dot(x: f64, y: f64, colour: Colour) -> Circle {
    Circle::new()
        .set("class", "point")
        .set("cx", px(x))
        .set("cy", px(y))
        .set("r", 3)
        .set("fill", rgb(colour))
        .set("fill-opacity", 0.6)
        .set("stroke", rgb(colour))
}
