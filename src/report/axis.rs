//! The one tick engine of every chart: where an axis's ticks go, how they read, and how much
//! room their labels take, so that the chart's layout can keep every label inside the figure and
//! clear of its neighbours.
//!
//! Linear axes step by "nice" numbers (1, 2 or 5 × 10^k; whole numbers on counting axes such as
//! iterations). Logarithmic axes tick 1, 2 and 5 × 10^k, or the decades alone when that is too
//! dense; frequency axes tick the octaves 125 Hz × 2^k (or the decades) and read in Hz: 250, 500,
//! 1k, 2k, 4k. The unlabelled 1…9 × 10^k are a log axis's minor ticks. The densest set of ticks
//! whose labels keep a gap between them in the axis's length is chosen, and the range widens to
//! the ticks just outside the data, so both ends of an axis carry a label.

/// Font size of tick labels, axis titles and legends \[px\].
pub const FONT_PX: f64 = 11.0;
/// Least distance between neighbouring ticks along a horizontal axis \[px\], whatever their
/// labels' width: denser ticks make a reader count rather than read.
const MIN_SPACING_X: f64 = 44.0;
/// Least distance between neighbouring ticks along a vertical axis \[px\].
const MIN_SPACING_Y: f64 = 2.4 * FONT_PX;
/// Clear space between two labels side by side \[px\].
const LABEL_GAP: f64 = FONT_PX;
/// The most ticks an axis is ever given (a guard, far above what fits in a report chart).
const MAX_TICKS: usize = 60;

/// How the axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    Linear,
    Log,
}

/// What the values along the axis are, which decides the steps and how labels read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Numbers {
    /// Any real value.
    Real,
    /// Counts (iterations, rounds): whole-number ticks only.
    Integer,
    /// Frequencies: octave or decade ticks labelled in Hz (1k for 1000 Hz).
    Hertz,
}

impl Numbers {
    /// The name written on the axis's SVG group (`data-numbers`).
    pub fn name(self) -> &'static str {
        match self {
            Numbers::Real => "real",
            Numbers::Integer => "integer",
            Numbers::Hertz => "hertz",
        }
    }
}

/// Which way the axis runs on the page: along a horizontal axis labels sit side by side (their
/// widths matter), along a vertical one they are stacked (their height matters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    Horizontal,
    Vertical,
}

/// A labelled tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Tick {
    pub value: f64,
    pub label: String,
}

/// An axis: its range (widened to its outer ticks), scale, labelled ticks and minor ticks.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub lo: f64,
    pub hi: f64,
    pub scale: Scale,
    pub numbers: Numbers,
    pub ticks: Vec<Tick>,
    /// Unlabelled ticks between the labelled ones (a log axis's 1…9 × 10^k).
    pub minor: Vec<f64>,
}

impl Axis {
    /// The axis over the data range `lo..hi` (for a log axis, positive values) given `length`
    /// pixels running in `direction`. A range without extent is widened around its value; a
    /// non-finite or, on a log axis, non-positive range falls back to 0..1 (or 0.1..1).
    pub fn new(
        lo: f64,
        hi: f64,
        scale: Scale,
        numbers: Numbers,
        length: f64,
        direction: Direction,
    ) -> Axis {
        let (lo, hi) = usable_range(lo.min(hi), lo.max(hi), scale);
        let candidates: Vec<Vec<f64>> = match scale {
            Scale::Linear => linear_candidates(lo, hi, numbers),
            Scale::Log => log_candidates(lo, hi, numbers),
        };
        let mut chosen = None;
        for values in candidates {
            let axis = Axis::with_ticks(values, scale, numbers);
            let fits = axis.fits(length, direction);
            chosen = Some(axis);
            if fits {
                break;
            }
        }
        chosen.unwrap_or_else(|| Axis::with_ticks(vec![lo, hi], scale, numbers))
    }

    /// The axis whose range runs from the first to the last of `values` (ascending), all
    /// labelled.
    fn with_ticks(values: Vec<f64>, scale: Scale, numbers: Numbers) -> Axis {
        let step = values
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::MAX, f64::min);
        let ticks: Vec<Tick> = values
            .iter()
            .map(|&value| Tick {
                value,
                label: label(value, scale, numbers, step),
            })
            .collect();
        let (lo, hi) = (values[0], values[values.len() - 1]);
        let minor = match scale {
            Scale::Linear => Vec::new(),
            Scale::Log => decade_multiples(lo, hi)
                .into_iter()
                .filter(|v| !values.iter().any(|t| (v / t - 1.0).abs() < 1e-9))
                .collect(),
        };
        Axis {
            lo,
            hi,
            scale,
            numbers,
            ticks,
            minor,
        }
    }

    /// Where `value` lies along the axis, 0 at `lo` and 1 at `hi` (outside for values beyond).
    pub fn fraction(&self, value: f64) -> f64 {
        match self.scale {
            Scale::Linear => (value - self.lo) / (self.hi - self.lo),
            Scale::Log => (value.ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln()),
        }
    }

    /// The widest tick label \[px\].
    pub fn widest_label(&self) -> f64 {
        self.ticks
            .iter()
            .map(|t| text_width(&t.label, FONT_PX))
            .fold(0.0, f64::max)
    }

    /// Whether every pair of neighbouring labels keeps clear of each other along `length`.
    fn fits(&self, length: f64, direction: Direction) -> bool {
        self.ticks.windows(2).all(|pair| {
            let spacing = length * (self.fraction(pair[1].value) - self.fraction(pair[0].value));
            match direction {
                Direction::Horizontal => {
                    let half = (text_width(&pair[0].label, FONT_PX)
                        + text_width(&pair[1].label, FONT_PX))
                        / 2.0;
                    spacing >= (half + LABEL_GAP).max(MIN_SPACING_X)
                }
                Direction::Vertical => spacing >= MIN_SPACING_Y,
            }
        })
    }
}

/// A finite range with extent, positive on a log axis.
fn usable_range(lo: f64, hi: f64, scale: Scale) -> (f64, f64) {
    match scale {
        Scale::Linear if !(lo.is_finite() && hi.is_finite()) => (0.0, 1.0),
        Scale::Linear if hi - lo <= 1e-12 * lo.abs().max(1.0) => (lo - 1.0, hi + 1.0),
        Scale::Log if !(lo.is_finite() && hi.is_finite() && lo > 0.0) => (0.1, 1.0),
        Scale::Log if hi / lo <= 1.0 + 1e-9 => (lo / 2.0, hi * 2.0),
        _ => (lo, hi),
    }
}

/// Tick sets of a linear axis from the densest to the sparsest: for each step 1, 2, 5 × 10^k
/// (whole steps only on an integer axis), the multiples from the one at or below `lo` to the
/// one at or above `hi`. The last set's step spans the range (two or three ticks).
fn linear_candidates(lo: f64, hi: f64, numbers: Numbers) -> Vec<Vec<f64>> {
    let span = hi - lo;
    let mut exponent = (span / MAX_TICKS as f64).log10().floor() as i32;
    let mut out = Vec::new();
    loop {
        for mantissa in [1.0, 2.0, 5.0] {
            let step = mantissa * 10f64.powi(exponent);
            if numbers == Numbers::Integer && step < 1.0 {
                continue;
            }
            // a little slack so that 0.30000000000000004 counts as 0.3
            let first = (lo / step + 1e-9).floor() as i64;
            let last = (hi / step - 1e-9).ceil() as i64;
            if last - first > MAX_TICKS as i64 {
                continue;
            }
            out.push((first..=last).map(|k| k as f64 * step).collect());
            if step >= span {
                return out;
            }
        }
        exponent += 1;
    }
}

/// Tick sets of a log axis from the densest to the sparsest. Frequencies: the octaves
/// 125 × 2^k Hz, then the decades; other values: 1, 2 and 5 × 10^k, then the decades, then
/// every second, third… decade until two ticks remain. Each set runs from the tick at or below
/// `lo` to the one at or above `hi`.
fn log_candidates(lo: f64, hi: f64, numbers: Numbers) -> Vec<Vec<f64>> {
    let (e0, e1) = (lo.log10().floor() as i32 - 1, hi.log10().ceil() as i32 + 1);
    let decades = |every: i32, mantissas: &[f64]| -> Vec<f64> {
        (e0.div_euclid(every)..=e1.div_euclid(every) + 1)
            .flat_map(|k| mantissas.iter().map(move |m| m * 10f64.powi(k * every)))
            .collect()
    };
    let mut sets = Vec::new();
    if numbers == Numbers::Hertz {
        let (k0, k1) = (
            (lo / 125.0).log2().floor() as i32 - 1,
            (hi / 125.0).log2().ceil() as i32 + 1,
        );
        sets.push((k0..=k1).map(|k| 125.0 * 2f64.powi(k)).collect());
    } else {
        sets.push(decades(1, &[1.0, 2.0, 5.0]));
    }
    for every in 1..=(e1 - e0).max(1) {
        sets.push(decades(every, &[1.0]));
    }
    sets.into_iter()
        .map(|candidates| bracket(&candidates, lo, hi))
        .filter(|ticks| ticks.len() >= 2 && ticks.len() <= MAX_TICKS)
        .collect()
}

/// The ascending `candidates` from the last at or below `lo` to the first at or above `hi`.
fn bracket(candidates: &[f64], lo: f64, hi: f64) -> Vec<f64> {
    let tolerance = 1e-9;
    let first = candidates
        .iter()
        .rposition(|&c| c <= lo * (1.0 + tolerance))
        .unwrap_or(0);
    let last = candidates
        .iter()
        .position(|&c| c >= hi * (1.0 - tolerance))
        .unwrap_or(candidates.len() - 1);
    candidates[first..=last.max(first)].to_vec()
}

/// 1…9 × 10^k within `lo..=hi`.
fn decade_multiples(lo: f64, hi: f64) -> Vec<f64> {
    let (e0, e1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    (e0..=e1)
        .flat_map(|e| (1..10).map(move |m| m as f64 * 10f64.powi(e)))
        .filter(|v| *v >= lo * (1.0 - 1e-9) && *v <= hi * (1.0 + 1e-9))
        .collect()
}

/// A tick's label: a linear axis's labels share the decimals of its step; a log axis's read
/// with three significant digits; counts as whole numbers; frequencies in Hz with "k" for
/// thousands.
fn label(value: f64, scale: Scale, numbers: Numbers, step: f64) -> String {
    let text = match (numbers, scale) {
        (Numbers::Integer, _) => format!("{}", value.round() as i64),
        (Numbers::Hertz, _) if value.abs() >= 1000.0 => format!("{}k", significant(value / 1000.0)),
        (Numbers::Hertz, _) | (Numbers::Real, Scale::Log) => significant(value),
        (Numbers::Real, Scale::Linear) => {
            let decimals = (-(step.log10() + 1e-9).floor()).max(0.0) as usize;
            format!("{value:.decimals$}")
        }
    };
    // no "-0" or "-0.0" for a zero reached from below
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => text,
    }
}

/// A value with three significant digits and no trailing zeros (products such as
/// 0.30000000000000004 read 0.3).
pub fn significant(v: f64) -> String {
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

/// The width of `text` in a sans-serif font of `font_px` \[px\], from advance widths at least as
/// wide as those of the common sans-serif fonts (DejaVu Sans, the widest, Liberation Sans,
/// Arial), so that room reserved by it is enough whichever the browser picks.
pub fn text_width(text: &str, font_px: f64) -> f64 {
    let em: f64 = text
        .chars()
        .map(|c| match c {
            '0'..='9' => 0.64,
            '.' | ',' | ':' | ';' | '\'' | '!' | '|' | 'i' | 'j' | 'l' | ' ' => 0.33,
            '-' | '(' | ')' | '[' | ']' | '/' | 'f' | 'r' | 't' => 0.42,
            'm' | 'w' | 'M' | 'W' | '%' | '@' => 1.0,
            'A'..='Z' => 0.78,
            _ => 0.66,
        })
        .sum();
    em * font_px
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(axis: &Axis) -> Vec<&str> {
        axis.ticks.iter().map(|t| t.label.as_str()).collect()
    }

    #[test]
    fn a_frequency_axis_reads_in_hz_on_octaves() {
        // the transfer function's 250 Hz to about 8 kHz on a 480 px axis
        let axis = Axis::new(
            250.0,
            7943.0,
            Scale::Log,
            Numbers::Hertz,
            480.0,
            Direction::Horizontal,
        );
        assert_eq!(labels(&axis), ["250", "500", "1k", "2k", "4k", "8k"]);
        assert_eq!((axis.lo, axis.hi), (250.0, 8000.0));
        assert!(
            (axis.fraction(1000.0) - 2.0 / 5.0).abs() < 1e-12,
            "log spacing"
        );
        // the 300…900 and 2000…7000 minor ticks, none on a labelled tick
        assert!(axis.minor.contains(&300.0) && axis.minor.contains(&3000.0));
        assert!(!axis.minor.contains(&1000.0) && !axis.minor.contains(&2000.0));
        // too short for octaves: the decades
        let short = Axis::new(
            20.0,
            20000.0,
            Scale::Log,
            Numbers::Hertz,
            300.0,
            Direction::Horizontal,
        );
        assert_eq!(labels(&short), ["10", "100", "1k", "10k", "100k"]);
    }

    #[test]
    fn counting_axes_take_whole_steps() {
        let axis = Axis::new(
            1.0,
            4.0,
            Scale::Linear,
            Numbers::Integer,
            480.0,
            Direction::Horizontal,
        );
        assert_eq!(labels(&axis), ["1", "2", "3", "4"]);
        let long = Axis::new(
            1.0,
            37.0,
            Scale::Linear,
            Numbers::Integer,
            480.0,
            Direction::Horizontal,
        );
        assert_eq!(
            labels(&long),
            ["0", "5", "10", "15", "20", "25", "30", "35", "40"]
        );
    }

    #[test]
    fn linear_ticks_are_nice_and_keep_clear_of_each_other() {
        // the static-pressure axis whose "4000.0" used to be clipped
        let x = Axis::new(
            -4000.0,
            4000.0,
            Scale::Linear,
            Numbers::Real,
            480.0,
            Direction::Horizontal,
        );
        assert_eq!(
            labels(&x),
            [
                "-4000", "-3000", "-2000", "-1000", "0", "1000", "2000", "3000", "4000"
            ]
        );
        // a vertical axis of 200 px: ticks at least 2.4 font sizes apart
        let y = Axis::new(
            0.0,
            0.072,
            Scale::Linear,
            Numbers::Real,
            200.0,
            Direction::Vertical,
        );
        assert_eq!(labels(&y), ["0.00", "0.02", "0.04", "0.06", "0.08"]);
        let gaps: Vec<f64> = y
            .ticks
            .windows(2)
            .map(|p| 200.0 * (y.fraction(p[1].value) - y.fraction(p[0].value)))
            .collect();
        assert!(gaps.iter().all(|g| *g >= MIN_SPACING_Y), "{gaps:?}");
        // a zero reached from below reads "0"
        let z = Axis::new(
            -0.5,
            0.5,
            Scale::Linear,
            Numbers::Real,
            480.0,
            Direction::Horizontal,
        );
        assert!(labels(&z).contains(&"0.0"), "{:?}", labels(&z));
        assert!(!labels(&z).iter().any(|l| l.starts_with("-0.0")));
    }

    #[test]
    fn log_axes_label_1_2_5_and_mark_the_rest_of_each_decade() {
        // the convergence curve: 0.005 mm to 0.19 mm on 220 px
        let axis = Axis::new(
            0.005,
            0.19,
            Scale::Log,
            Numbers::Real,
            220.0,
            Direction::Vertical,
        );
        assert_eq!(
            labels(&axis),
            ["0.005", "0.01", "0.02", "0.05", "0.1", "0.2"]
        );
        // squeezed: decades only
        let squeezed = Axis::new(
            0.005,
            0.19,
            Scale::Log,
            Numbers::Real,
            90.0,
            Direction::Vertical,
        );
        assert_eq!(labels(&squeezed), ["0.001", "0.01", "0.1", "1"]);
        assert!(squeezed.minor.iter().any(|v| (v - 0.05).abs() < 1e-12));
    }

    #[test]
    fn degenerate_ranges_still_give_two_ticks() {
        for (lo, hi, scale) in [
            (3.0, 3.0, Scale::Linear),
            (f64::NAN, 1.0, Scale::Linear),
            (0.0, 5.0, Scale::Log),
            (2.0, 2.0, Scale::Log),
        ] {
            let axis = Axis::new(lo, hi, scale, Numbers::Real, 300.0, Direction::Vertical);
            assert!(axis.ticks.len() >= 2, "{lo}..{hi}: {:?}", axis.ticks);
            assert!(axis.hi > axis.lo);
        }
    }

    #[test]
    fn labels_keep_three_significant_digits() {
        assert_eq!(significant(0.30000000000000004), "0.3");
        assert_eq!(significant(0.000123456), "0.000123");
        assert_eq!(significant(12.5), "12.5");
        assert_eq!(significant(1500.0), "1500");
        assert_eq!(significant(-0.25), "-0.25");
    }

    #[test]
    fn text_width_is_at_least_dejavu_sans() {
        // DejaVu Sans advances: digits 0.636 em, "." 0.318 em, "k" 0.579 em
        assert!(text_width("4000", 10.0) >= 4.0 * 6.36);
        assert!(text_width("0.05", 10.0) >= 3.0 * 6.36 + 3.18);
        assert!(text_width("1k", 10.0) >= 6.36 + 5.79);
    }
}
