//! Report plots: one line/scatter chart type with labelled axes, written as SVG and PNG
//! (plotters with an embedded DejaVu Sans, so no font library is needed).

use std::sync::Once;

use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

static FONT: Once = Once::new();

/// The font shipped in `experiments/assets/` (DejaVu Sans; licence beside it).
fn register() {
    FONT.call_once(|| {
        // The bytes are a valid TrueType font compiled into the binary; a failure here
        // only loses text, which the caller cannot fix either, so it is ignored.
        let _ = register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        );
    });
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mark {
    /// Connected line.
    Line,
    /// Dots.
    Points,
    /// Dots joined by a line.
    LinePoints,
}

/// Palette indices from here on are a sequential colour map (viridis), for series ordered
/// by step: [`step_colour`].
pub const SEQUENTIAL: usize = 1000;

/// The palette index of step `k` of `n` on the sequential colour map: up to 20 steps stay
/// distinguishable and their order shows (dark: first, yellow: last).
pub fn step_colour(k: usize, n: usize) -> usize {
    SEQUENTIAL + (999 * k) / n.saturating_sub(1).max(1)
}

fn colour_of(index: usize) -> RGBColor {
    if index >= SEQUENTIAL {
        use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};
        // The last tenth of viridis is too pale on white.
        let h = 0.9 * (index - SEQUENTIAL).min(999) as f64 / 999.0;
        ViridisRGB.get_color(h)
    } else {
        PALETTE[index % PALETTE.len()]
    }
}

/// A tick label without float noise: as many decimals as the axis's tick spacing needs
/// (`span` / 5), trailing zeros dropped — 0.3, not 0.30000000000000004.
pub fn tick_label(v: f64, span: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    let step = (span.abs() / 5.0).max(1e-12);
    let decimals = (-step.log10().floor()).clamp(0.0, 9.0) as usize;
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" { "0".into() } else { s }
}

/// A tick label on a logarithmic axis: three significant digits, no float noise.
fn log_tick_label(v: f64) -> String {
    if !(v.is_finite() && v > 0.0) {
        return String::new();
    }
    let decimals = (2.0 - v.log10().floor()).clamp(0.0, 12.0) as usize;
    if (1e-3..1e5).contains(&v) {
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.1e}")
    }
}

/// One named series.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text (empty: no legend entry).
    pub name: String,
    /// (x, y) points; non-finite ones are skipped.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub mark: Mark,
    /// Palette index (from [`SEQUENTIAL`] on, the sequential map: [`step_colour`]).
    pub colour: usize,
}

impl Series {
    /// A connected line.
    pub fn line(name: &str, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Self {
            name: name.into(),
            points,
            mark: Mark::Line,
            colour,
        }
    }
}

/// A chart.
#[derive(Debug, Clone, Default)]
pub struct Chart {
    /// Caption.
    pub title: String,
    /// X axis label with unit.
    pub x_label: String,
    /// Y axis label with unit.
    pub y_label: String,
    /// Series.
    pub series: Vec<Series>,
    /// Shaded x intervals (step bands), alternating shades.
    pub bands: Vec<(f64, f64)>,
    /// Vertical marker lines with labels (e.g. the end of the linear range).
    pub markers: Vec<(f64, String)>,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The legend in the upper right corner instead of the upper left.
    pub legend_upper_right: bool,
}

/// Colours of the vertical marker lines, told apart from the series' palette.
const MARKER_PALETTE: [RGBColor; 4] = [
    RGBColor(148, 103, 189),
    RGBColor(40, 40, 40),
    RGBColor(227, 119, 194),
    RGBColor(140, 86, 75),
];

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Plot size in pixels.
pub const SIZE: (u32, u32) = (760, 440);

fn range(chart: &Chart) -> ((f64, f64), (f64, f64)) {
    let pts = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite() && (!chart.log_y || p.1 > 0.0));
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    for &(a, b) in &chart.bands {
        x0 = x0.min(a);
        x1 = x1.max(b);
    }
    if !x0.is_finite() {
        return ((0.0, 1.0), (0.0, 1.0));
    }
    let pad = |a: f64, b: f64| {
        let d = (b - a).abs().max(1e-9 * a.abs().max(1.0));
        (a - 0.04 * d, b + 0.04 * d)
    };
    let ((x0, x1), (y0, y1)) = (
        pad(x0, x1),
        if chart.log_y {
            (y0 / 1.5, y1 * 1.5)
        } else {
            pad(y0, y1)
        },
    );
    // Room above the data for the legend (it sits in an upper corner): about 17 px per
    // entry of the plot's ~330 px, so no entry covers a point.
    let entries = legend_entries(chart);
    if entries == 0 {
        return ((x0, x1), (y0, y1));
    }
    let share = ((17.0 * entries as f64 + 14.0) / 330.0).min(0.6);
    let y1 = if chart.log_y {
        let (l0, l1) = (y0.ln(), y1.ln());
        (l0 + (l1 - l0) / (1.0 - share)).exp()
    } else {
        y0 + (y1 - y0) / (1.0 - share)
    };
    ((x0, x1), (y0, y1))
}

/// Legend entries of `chart`: named series and marker lines.
fn legend_entries(chart: &Chart) -> usize {
    chart.series.iter().filter(|s| !s.name.is_empty()).count() + chart.markers.len()
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let ((x0, x1), (y0, y1)) = range(chart);
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&chart.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(64);
    macro_rules! body {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            let (xspan, yspan) = (x1 - x0, y1 - y0);
            let xfmt = move |v: &f64| tick_label(*v, xspan);
            let log_y = chart.log_y;
            let yfmt = move |v: &f64| {
                if log_y {
                    log_tick_label(*v)
                } else {
                    tick_label(*v, yspan)
                }
            };
            ctx.configure_mesh()
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .x_label_formatter(&xfmt)
                .y_label_formatter(&yfmt)
                .label_style(("sans-serif", 13))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(e)?;
            for (k, &(a, b)) in chart.bands.iter().enumerate() {
                let shade = if k % 2 == 0 {
                    RGBColor(240, 244, 250)
                } else {
                    RGBColor(250, 250, 250)
                };
                let (lo, hi) = if chart.log_y { (y0, y1) } else { (y0, y1) };
                ctx.draw_series(std::iter::once(Rectangle::new(
                    [(a, lo), (b, hi)],
                    shade.filled(),
                )))
                .map_err(e)?;
            }
            for (k, (x, label)) in chart.markers.iter().enumerate() {
                let c = MARKER_PALETTE[k % MARKER_PALETTE.len()];
                ctx.draw_series(std::iter::once(PathElement::new(
                    vec![(*x, y0), (*x, y1)],
                    c.stroke_width(2),
                )))
                .map_err(e)?
                .label(label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                });
            }
            for s in &chart.series {
                let c = colour_of(s.colour);
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| p.0.is_finite() && p.1.is_finite() && (!chart.log_y || p.1 > 0.0))
                    .collect();
                let named = !s.name.is_empty();
                if matches!(s.mark, Mark::Line | Mark::LinePoints) {
                    // A non-finite point breaks the line (a pause in the record, such as
                    // the time between a run's interruption and its resumption).
                    let mut pieces: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
                    for p in &s.points {
                        if p.0.is_finite() && p.1.is_finite() && (!chart.log_y || p.1 > 0.0) {
                            if let Some(last) = pieces.last_mut() {
                                last.push(*p);
                            }
                        } else if pieces.last().is_some_and(|l| !l.is_empty()) {
                            pieces.push(Vec::new());
                        }
                    }
                    for piece in pieces.iter().skip(1).filter(|p| !p.is_empty()) {
                        ctx.draw_series(LineSeries::new(piece.clone(), c.stroke_width(2)))
                            .map_err(e)?;
                    }
                    let first = pieces.into_iter().next().unwrap_or_default();
                    let a = ctx
                        .draw_series(LineSeries::new(first, c.stroke_width(2)))
                        .map_err(e)?;
                    if named {
                        a.label(s.name.as_str()).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                        });
                    }
                }
                if matches!(s.mark, Mark::Points | Mark::LinePoints) {
                    let a = ctx
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                        .map_err(e)?;
                    if s.mark == Mark::Points && named {
                        a.label(s.name.as_str())
                            .legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled()));
                    }
                }
            }
            if legend_entries(chart) > 0 {
                ctx.configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(RGBColor(200, 200, 200))
                    .label_font(("sans-serif", 12))
                    .position(if chart.legend_upper_right {
                        SeriesLabelPosition::UpperRight
                    } else {
                        SeriesLabelPosition::UpperLeft
                    })
                    .draw()
                    .map_err(e)?;
            }
        }};
    }
    if chart.log_y {
        body!(
            builder
                .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
                .map_err(e)?
        );
    } else {
        body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(e)?);
    }
    root.present().map_err(e)?;
    Ok(())
}

/// The chart as an SVG document.
pub fn svg(chart: &Chart) -> Result<String, String> {
    register();
    let mut out = String::new();
    draw(
        SVGBackend::with_string(&mut out, SIZE).into_drawing_area(),
        chart,
    )?;
    Ok(out)
}

/// The chart as RGB8 pixels (`SIZE`), for PNG encoding by the caller.
pub fn rgb(chart: &Chart) -> Result<Vec<u8>, String> {
    register();
    let mut buf = vec![255u8; (SIZE.0 * SIZE.1 * 3) as usize];
    draw(
        BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area(),
        chart,
    )?;
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_carry_no_float_noise() {
        assert_eq!(tick_label(0.1 + 0.2, 1.0), "0.3");
        assert_eq!(tick_label(120.0, 600.0), "120");
        assert_eq!(tick_label(-0.0001, 1.0), "0");
        assert_eq!(tick_label(2.6, 10.0), "3");
        assert_eq!(tick_label(0.014, 0.005), "0.014");
        assert_eq!(tick_label(0.014, 0.05), "0.01");
        assert_eq!(log_tick_label(0.30000000000000004), "0.3");
        assert_eq!(log_tick_label(1e-6), "1.0e-6");
    }

    #[test]
    fn the_legend_gets_room_above_the_data() {
        let chart = Chart {
            series: (0..4)
                .map(|k| Series::line(&format!("step {k}"), vec![(0.0, 0.0), (1.0, 1.0)], k))
                .collect(),
            ..Default::default()
        };
        let (_, (y0, y1)) = range(&chart);
        // The data's top (1.04 after padding) sits below the legend's four entries.
        let legend_bottom = y1 - (y1 - y0) * (17.0 * 4.0 + 14.0) / 330.0;
        assert!(legend_bottom >= 1.04 - 1e-9, "{y0} {y1} {legend_bottom}");
    }

    #[test]
    fn steps_get_distinct_ordered_colours() {
        let c: Vec<RGBColor> = (0..20).map(|k| colour_of(step_colour(k, 20))).collect();
        for w in c.windows(2) {
            assert_ne!(w[0], w[1]);
        }
        assert_eq!(step_colour(0, 1), SEQUENTIAL);
    }

    #[test]
    fn a_non_finite_point_breaks_the_line() {
        let chart = |points: Vec<(f64, f64)>| Chart {
            series: vec![Series::line("Fz", points, 0)],
            ..Default::default()
        };
        let whole = vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.0), (3.0, 1.0)];
        let mut broken = whole.clone();
        broken.insert(2, (f64::NAN, f64::NAN));
        let lines = |c: &Chart| svg(c).expect("svg").matches("<polyline").count();
        assert_eq!(lines(&chart(broken)), lines(&chart(whole)) + 1);
    }
}
