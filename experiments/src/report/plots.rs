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
            include_bytes!("../../assets/DejaVuSans.ttf"),
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

/// One named series.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) points; non-finite ones are skipped.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub mark: Mark,
    /// Palette index.
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
    ((x0, x1), (y0, y1))
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
            ctx.configure_mesh()
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
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
                let c = PALETTE[s.colour % PALETTE.len()];
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| p.0.is_finite() && p.1.is_finite() && (!chart.log_y || p.1 > 0.0))
                    .collect();
                if matches!(s.mark, Mark::Line | Mark::LinePoints) {
                    ctx.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                        .map_err(e)?
                        .label(s.name.as_str())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                        });
                }
                if matches!(s.mark, Mark::Points | Mark::LinePoints) {
                    let a = ctx
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                        .map_err(e)?;
                    if s.mark == Mark::Points {
                        a.label(s.name.as_str())
                            .legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled()));
                    }
                }
            }
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
