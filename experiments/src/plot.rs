//! The sweeps' plots, drawn with `plotters` (issue 35; they were drawn by hand with tiny-skia and
//! an 8x8 bitmap font before): scatter plots (cost against accuracy), line plots (runtime over a
//! sweep, thesis style, E Fig. 5.1–5.7), points with interval bars, and grouped bar charts (mean
//! time of each pass, E Fig. 5.1c). Real text (DejaVu Sans, [`crate::chart`]), a legend panel
//! naming every series, logarithmic axes when asked and every value is positive.
//!
//! Every plot is written twice: the PNG at the path given, and an SVG twin beside it (same stem).
//! Nothing here knows about forests: it draws what it is given.

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use crate::chart::{FAMILY, font, tick};

/// Plot width in pixels.
pub const WIDTH: u32 = 960;
/// Plot height in pixels.
pub const HEIGHT: u32 = 540;
/// Width of the legend panel at the right.
const RIGHT: u32 = 300;
/// Longest legend label, characters (longer ones end in `…`).
const LABEL_CHARS: usize = 36;

/// A qualitative palette (Okabe–Ito, colour-blind safe), cycled by series index.
pub const PALETTE: [[u8; 3]; 8] = crate::chart::PALETTE;

/// One named series of points.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`; non-finite ones are skipped.
    pub points: Vec<(f64, f64)>,
}

/// How points are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// Markers only.
    Scatter,
    /// Markers joined in x order.
    Lines,
}

/// Axis titles and scales of one plot.
#[derive(Clone, Debug)]
pub struct Axes {
    /// Title above the plot.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Logarithmic x (only if every x is positive).
    pub log_x: bool,
    /// Logarithmic y (only if every y is positive).
    pub log_y: bool,
}

impl Axes {
    /// Linear axes with a title and axis labels.
    pub fn linear(title: String, x_label: &str, y_label: &str) -> Self {
        Self {
            title,
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x: false,
            log_y: false,
        }
    }
}

/// A compact number label: 3 significant digits, scientific beyond 1e5 or below 1e-3.
pub fn format_number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// An axis' range over `values` (finite ones): padded by 5 %; from 0 when linear, all positive
/// and the low end is near 0 compared with the span; logarithmic when asked and all positive
/// (then a factor of 1.3 of room). Returns `(lo, hi, log)`.
fn axis_range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64, bool) {
    let v: Vec<f64> = values.filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 1.0, false);
    }
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if log && lo > 0.0 {
        let (lo, hi) = if hi / lo < 1.01 {
            (lo / 2.0, hi * 2.0)
        } else {
            (lo / 1.3, hi * 1.3)
        };
        return (lo, hi, true);
    }
    let (mut lo, mut hi) = (lo, hi);
    if hi - lo < 1e-12 {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        lo -= pad;
        hi += pad;
    } else {
        let pad = (hi - lo) * 0.05;
        lo -= pad;
        hi += pad;
    }
    if lo > 0.0 && lo < (hi - lo) * 0.5 {
        lo = 0.0;
    }
    (lo, hi, false)
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

fn short(label: &str) -> String {
    if label.chars().count() <= LABEL_CHARS {
        label.to_string()
    } else {
        let mut s: String = label.chars().take(LABEL_CHARS - 1).collect();
        s.push('…');
        s
    }
}

/// How a legend row shows its series.
#[derive(Clone, Copy)]
enum Swatch {
    /// A marker of this shape.
    Marker(usize),
    /// A line.
    Line,
    /// A filled box (a bar).
    Bar,
}

type DrawResult<T, DB> = Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A marker of shape `shape` (circle, square, triangle, diamond, cycled) at `(x, y)` pixels.
fn marker_at<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    c: RGBColor,
    shape: usize,
) -> DrawResult<(), DB> {
    let r = 4;
    match shape % 4 {
        0 => area.draw(&Circle::new((x, y), r, c.filled())),
        1 => area.draw(&Rectangle::new(
            [(x - r, y - r), (x + r, y + r)],
            c.filled(),
        )),
        2 => area.draw(&Polygon::new(
            vec![(x, y - r - 1), (x - r - 1, y + r), (x + r + 1, y + r)],
            c.filled(),
        )),
        _ => area.draw(&Polygon::new(
            vec![
                (x, y - r - 1),
                (x + r + 1, y),
                (x, y + r + 1),
                (x - r - 1, y),
            ],
            c.filled(),
        )),
    }
}

/// The legend panel: one row per entry, then `+N more` when they do not fit.
fn legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, RGBColor, Swatch)],
) -> DrawResult<(), DB> {
    let row = 19;
    let mut y = 44;
    for (i, (label, c, swatch)) in entries.iter().enumerate() {
        if y + row > HEIGHT as i32 - 30 {
            area.draw(&Text::new(
                format!("+{} more", entries.len() - i),
                (28, y),
                (FAMILY, 13).into_font().color(&BLACK),
            ))?;
            break;
        }
        match swatch {
            Swatch::Marker(shape) => marker_at(area, (14, y + 8), *c, *shape)?,
            Swatch::Line => area.draw(&PathElement::new(
                vec![(4, y + 8), (22, y + 8)],
                c.stroke_width(2),
            ))?,
            Swatch::Bar => area.draw(&Rectangle::new([(6, y + 2), (20, y + 14)], c.filled()))?,
        }
        area.draw(&Text::new(
            short(label),
            (28, y + 1),
            (FAMILY, 13).into_font().color(&BLACK),
        ))?;
        y += row;
    }
    Ok(())
}

/// Runs `$body` (a [`DrawResult`]) with `$root` an SVG drawing area (`path` with `.svg`), then
/// with `$root` a PNG one (`path`): one drawing, two files.
macro_rules! both {
    ($path:expr, |$root:ident| $body:block) => {{
        font();
        let path: &Path = $path;
        let io = |e: String| std::io::Error::other(format!("{}: {e}", path.display()));
        let svg = path.with_extension("svg");
        {
            let area = SVGBackend::new(&svg, (WIDTH, HEIGHT)).into_drawing_area();
            let $root = &area;
            (|| $body)().map_err(|e| io(e.to_string()))?;
            area.present().map_err(|e| io(e.to_string()))?;
        }
        let area = BitMapBackend::new(path, (WIDTH, HEIGHT)).into_drawing_area();
        let $root = &area;
        (|| $body)().map_err(|e| io(e.to_string()))?;
        area.present().map_err(|e| io(e.to_string()))
    }};
}

/// Runs `$body` with `$x`, `$y` the linear or logarithmic specs of the `(lo, hi, log)` ranges.
macro_rules! with_axes {
    ($xr:expr, $yr:expr, |$x:ident, $y:ident| $body:block) => {{
        let ((xl, xh, xlog), (yl, yh, ylog)): ((f64, f64, bool), (f64, f64, bool)) = ($xr, $yr);
        match (xlog, ylog) {
            (false, false) => {
                let ($x, $y) = (xl..xh, yl..yh);
                $body
            }
            (true, false) => {
                let ($x, $y) = ((xl..xh).log_scale(), yl..yh);
                $body
            }
            (false, true) => {
                let ($x, $y) = (xl..xh, (yl..yh).log_scale());
                $body
            }
            (true, true) => {
                let ($x, $y) = ((xl..xh).log_scale(), (yl..yh).log_scale());
                $body
            }
        }
    }};
}

/// A chart with its coordinates, and the legend area beside it.
type Framed<'a, DB, X, Y> = (
    ChartContext<
        'a,
        DB,
        Cartesian2d<<X as AsRangedCoord>::CoordDescType, <Y as AsRangedCoord>::CoordDescType>,
    >,
    DrawingArea<DB, Shift>,
);

/// The chart area of a plot: the frame, title, axes, grid and labels; the legend area beside.
fn frame<'a, DB, X, Y>(
    root: &'a DrawingArea<DB, Shift>,
    axes: &Axes,
    x: X,
    y: Y,
) -> DrawResult<Framed<'a, DB, X, Y>, DB>
where
    DB: DrawingBackend + 'a,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    root.fill(&WHITE)?;
    let (plot, legend_area) = root.split_horizontally(WIDTH - RIGHT);
    let mut c = ChartBuilder::on(&plot)
        .caption(&axes.title, (FAMILY, 17))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(78)
        .build_cartesian_2d(x, y)?;
    c.configure_mesh()
        .x_desc(axes.x_label.as_str())
        .y_desc(axes.y_label.as_str())
        .label_style((FAMILY, 13))
        .axis_desc_style((FAMILY, 14))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()?;
    Ok((c, legend_area))
}

/// A scatter or line plot of `series`, written as PNG (and its SVG twin).
pub fn xy_plot(path: &Path, axes: &Axes, series: &[Series], style: Style) -> std::io::Result<()> {
    let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().filter(finite).copied())
        .collect();
    let xr = axis_range(all.iter().map(|p| p.0), axes.log_x);
    let yr = axis_range(all.iter().map(|p| p.1), axes.log_y);
    both!(path, |root| {
        with_axes!(xr, yr, |x, y| {
            let (mut c, legend_area) = frame(root, axes, x, y)?;
            for (i, s) in series.iter().enumerate() {
                let colour = rgb(PALETTE[i % PALETTE.len()]);
                let mut pts: Vec<(f64, f64)> = s.points.iter().filter(finite).copied().collect();
                if style == Style::Lines {
                    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                    c.draw_series(std::iter::once(PathElement::new(
                        pts.clone(),
                        colour.stroke_width(2),
                    )))?;
                }
                let area = c.plotting_area().strip_coord_spec();
                for p in &pts {
                    let px = c.backend_coord(p);
                    let (ox, oy) = area.get_base_pixel();
                    marker_at(&area, (px.0 - ox, px.1 - oy), colour, i)?;
                }
            }
            let entries: Vec<(String, RGBColor, Swatch)> = series
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    (
                        s.label.clone(),
                        rgb(PALETTE[i % PALETTE.len()]),
                        Swatch::Marker(i),
                    )
                })
                .collect();
            legend(&legend_area, &entries)
        })
    })
}

/// A point with the half-widths of its intervals (e.g. 95 % intervals of two means); a
/// half-width that is NaN or not positive draws no bar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntervalPoint {
    /// X value.
    pub x: f64,
    /// Half-width of the horizontal interval around `x`.
    pub x_half: f64,
    /// Y value.
    pub y: f64,
    /// Half-width of the vertical interval around `y`.
    pub y_half: f64,
}

/// A series of an [`interval_plot`]: points with interval bars, optionally joined by a line.
#[derive(Clone, Debug)]
pub struct IntervalSeries {
    /// Legend label; an empty label gets no legend row.
    pub label: String,
    /// Points; non-finite ones are skipped.
    pub points: Vec<IntervalPoint>,
    /// Join the points with a line, in x order.
    pub line: bool,
    /// Draw a marker (and the interval bars) at each point.
    pub markers: bool,
    /// Colour.
    pub colour: [u8; 3],
    /// Marker shape (circle, square, triangle, diamond, cycled).
    pub shape: usize,
    /// Text drawn beside each point (e.g. its number in the legend); empty for none.
    pub tag: String,
}

/// Points with horizontal and vertical interval bars (whiskers with caps), series joined by
/// lines where asked, tags beside points and a legend of the labelled series: e.g. cost against
/// error with their 95 % intervals and a Pareto front. The axes cover the intervals.
pub fn interval_plot(path: &Path, axes: &Axes, series: &[IntervalSeries]) -> std::io::Result<()> {
    let finite = |p: &&IntervalPoint| p.x.is_finite() && p.y.is_finite();
    let half = |h: f64| if h.is_finite() && h > 0.0 { h } else { 0.0 };
    let all: Vec<IntervalPoint> = series
        .iter()
        .flat_map(|s| s.points.iter().filter(finite).copied())
        .collect();
    // A log axis cannot show an interval reaching 0 or below: such ends are left out of the
    // range and cut at the axis' end.
    let ends = |log: bool, v: f64, h: f64| {
        [v - half(h), v, v + half(h)]
            .into_iter()
            .filter(move |e| !log || *e > 0.0)
    };
    let xr = axis_range(
        all.iter().flat_map(|p| ends(axes.log_x, p.x, p.x_half)),
        axes.log_x,
    );
    let yr = axis_range(
        all.iter().flat_map(|p| ends(axes.log_y, p.y, p.y_half)),
        axes.log_y,
    );
    both!(path, |root| {
        with_axes!(xr, yr, |x, y| {
            let (mut c, legend_area) = frame(root, axes, x, y)?;
            let cx = |v: f64| v.clamp(xr.0, xr.1);
            let cy = |v: f64| v.clamp(yr.0, yr.1);
            for s in series {
                let colour = rgb(s.colour);
                let mut pts: Vec<IntervalPoint> = s.points.iter().filter(finite).copied().collect();
                pts.sort_by(|a, b| a.x.total_cmp(&b.x));
                if s.line {
                    c.draw_series(std::iter::once(PathElement::new(
                        pts.iter().map(|p| (p.x, p.y)).collect::<Vec<_>>(),
                        colour.stroke_width(2),
                    )))?;
                }
                if !s.markers {
                    continue;
                }
                let area = c.plotting_area().strip_coord_spec();
                let (ox, oy) = area.get_base_pixel();
                for p in &pts {
                    let at = |v: (f64, f64)| {
                        let b = c.backend_coord(&v);
                        (b.0 - ox, b.1 - oy)
                    };
                    let cap = 3;
                    if half(p.x_half) > 0.0 {
                        let (a, b) = (at((cx(p.x - p.x_half), p.y)), at((cx(p.x + p.x_half), p.y)));
                        area.draw(&PathElement::new(vec![a, b], colour.stroke_width(1)))?;
                        for e in [a, b] {
                            area.draw(&PathElement::new(
                                vec![(e.0, e.1 - cap), (e.0, e.1 + cap)],
                                colour.stroke_width(1),
                            ))?;
                        }
                    }
                    if half(p.y_half) > 0.0 {
                        let (a, b) = (at((p.x, cy(p.y - p.y_half))), at((p.x, cy(p.y + p.y_half))));
                        area.draw(&PathElement::new(vec![a, b], colour.stroke_width(1)))?;
                        for e in [a, b] {
                            area.draw(&PathElement::new(
                                vec![(e.0 - cap, e.1), (e.0 + cap, e.1)],
                                colour.stroke_width(1),
                            ))?;
                        }
                    }
                    let m = at((p.x, p.y));
                    marker_at(&area, m, colour, s.shape)?;
                    if !s.tag.is_empty() {
                        area.draw(&Text::new(
                            s.tag.clone(),
                            (m.0 + 7, m.1 - 18),
                            (FAMILY, 14).into_font().color(&BLACK),
                        ))?;
                    }
                }
            }
            let entries: Vec<(String, RGBColor, Swatch)> = series
                .iter()
                .filter(|s| !s.label.is_empty())
                .map(|s| {
                    let swatch = if s.markers {
                        Swatch::Marker(s.shape)
                    } else {
                        Swatch::Line
                    };
                    (s.label.clone(), rgb(s.colour), swatch)
                })
                .collect();
            legend(&legend_area, &entries)
        })
    })
}

/// Grouped bars: one group per `groups` entry, one bar per `bars` label within it;
/// `values[group][bar]`.
pub fn bar_plot(
    path: &Path,
    axes: &Axes,
    groups: &[String],
    bars: &[String],
    values: &[Vec<f64>],
) -> std::io::Result<()> {
    let all: Vec<f64> = values
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .chain((!axes.log_y).then_some(0.0))
        .collect();
    let yr = axis_range(all.iter().copied(), axes.log_y);
    let n = groups.len().max(1);
    both!(path, |root| {
        with_axes!((0.0, n as f64, false), yr, |x, y| {
            root.fill(&WHITE)?;
            let (plot, legend_area) = root.split_horizontally(WIDTH - RIGHT);
            let mut c = ChartBuilder::on(&plot)
                .caption(&axes.title, (FAMILY, 17))
                .margin(12)
                .x_label_area_size(48)
                .y_label_area_size(78)
                .build_cartesian_2d(x, y)?;
            // Group names under the groups' centres.
            let name = |v: &f64| {
                let g = v.floor() as usize;
                if (v - g as f64 - 0.5).abs() < 1e-6 && g < groups.len() {
                    let max = (((WIDTH - RIGHT - 100) as usize / n) / 7).max(3);
                    groups[g].chars().take(max).collect()
                } else {
                    String::new()
                }
            };
            c.configure_mesh()
                .disable_x_mesh()
                .x_desc(axes.x_label.as_str())
                .y_desc(axes.y_label.as_str())
                .label_style((FAMILY, 13))
                .axis_desc_style((FAMILY, 14))
                .x_labels(2 * n + 1)
                .x_label_formatter(&name)
                .y_label_formatter(&|v| tick(*v))
                .light_line_style(RGBColor(238, 238, 238))
                .bold_line_style(RGBColor(215, 215, 215))
                .draw()?;
            let base = if yr.2 { yr.0 } else { 0.0 };
            let width = 0.8 / bars.len().max(1) as f64;
            for (g, row) in values.iter().enumerate().take(groups.len()) {
                for (b, v) in row.iter().enumerate() {
                    if !v.is_finite() {
                        continue;
                    }
                    let x0 = g as f64 + 0.1 + b as f64 * width;
                    c.draw_series(std::iter::once(Rectangle::new(
                        [(x0, base), (x0 + width * 0.9, v.clamp(yr.0, yr.1))],
                        rgb(PALETTE[b % PALETTE.len()]).filled(),
                    )))?;
                }
            }
            let entries: Vec<(String, RGBColor, Swatch)> = bars
                .iter()
                .enumerate()
                .map(|(b, l)| (l.clone(), rgb(PALETTE[b % PALETTE.len()]), Swatch::Bar))
                .collect();
            legend(&legend_area, &entries)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_ranges_are_readable() {
        assert_eq!(format_number(0.0), "0");
        assert_eq!(format_number(250.0), "250");
        assert_eq!(format_number(1.5), "1.5");
        assert_eq!(format_number(0.0125), "0.0125");
        assert_eq!(axis_range([1.0, 3.0].into_iter(), false).0, 0.0);
        assert!(axis_range([1.0, 1000.0].into_iter(), true).2);
        assert!(
            !axis_range([0.0, 1000.0].into_iter(), true).2,
            "no log with 0"
        );
    }

    #[test]
    fn plots_are_written_as_png_and_svg() {
        let dir = std::env::temp_dir().join(format!("forestlod-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let axes = Axes {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: false,
        };
        let s = vec![Series {
            label: "series a".into(),
            points: vec![(1.0, 2.0), (10.0, 3.0), (f64::NAN, 1.0)],
        }];
        xy_plot(&dir.join("a.png"), &axes, &s, Style::Lines).unwrap();
        bar_plot(
            &dir.join("b.png"),
            &axes,
            &["g".into()],
            &["b1".into(), "b2".into()],
            &[vec![1.0, 2.0]],
        )
        .unwrap();
        let p = |x, y| IntervalPoint {
            x,
            x_half: 0.1,
            y,
            y_half: f64::NAN,
        };
        let front = IntervalSeries {
            label: "front".into(),
            points: vec![p(0.5, 2.0), p(1.0, 1.0), p(f64::NAN, 1.0)],
            line: true,
            markers: true,
            colour: PALETTE[0],
            shape: 0,
            tag: "1".into(),
        };
        interval_plot(&dir.join("c.png"), &axes, &[front]).unwrap();
        for f in ["a", "b", "c"] {
            let png = image::open(dir.join(f).with_extension("png")).unwrap();
            assert_eq!((png.width(), png.height()), (WIDTH, HEIGHT));
            let svg = std::fs::read_to_string(dir.join(f).with_extension("svg")).unwrap();
            assert!(svg.contains("<text"), "{f}: real text");
        }
        let svg = std::fs::read_to_string(dir.join("a.svg")).unwrap();
        assert!(svg.contains("series a"), "the legend names the series");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
