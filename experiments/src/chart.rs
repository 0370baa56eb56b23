//! Plots drawn with `plotters` (issue 35): real text (DejaVu Sans, embedded, rendered by
//! `ab_glyph` into the PNG and written as `<text>` into the SVG), a legend that names every
//! series, logarithmic axes where a value spans decades, and 95 % intervals as bars. Every plot is
//! written twice from one drawing routine: `NAME.png` (for pages and READMEs) and `NAME.svg` (for
//! papers; it scales without loss).
//!
//! [`trade_chart`] is the trade plot the report opens with: one point per variant (error against
//! cost, both with their intervals), the Pareto front drawn as a line through its members, which
//! are numbered in the plot and in the legend. It returns the [`Geometry`] it drew with, and
//! [`read_back`] maps the SVG's point markers back to data values, so a test can check that the
//! plotted points are the numbers they were made from.
//!
//! Nothing here knows about forests: it draws what it is given.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

/// Width of a plot in pixels.
pub const WIDTH: u32 = 960;
/// Height of a plot in pixels.
pub const HEIGHT: u32 = 540;
/// Width of the legend panel at the right.
const LEGEND: u32 = 330;
/// The font family every text is set in (registered once: [`font`]).
pub(crate) const FAMILY: &str = "sans-serif";
/// Longest legend label, characters (longer ones end in `…`).
const LABEL_CHARS: usize = 40;
/// A cost axis is logarithmic when its largest value is at least this many times its smallest
/// (and all are positive): below that a linear axis reads better.
pub const LOG_SPAN: f64 = 10.0;

/// A qualitative palette (Okabe–Ito, colour-blind safe), cycled by point index.
pub const PALETTE: [[u8; 3]; 8] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [100, 100, 100],
    [180, 160, 20],
];

/// Registers DejaVu Sans for the bitmap backend (once per process).
pub(crate) fn font() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        // The font is a fixed, valid TrueType file shipped by the `dejavu` crate.
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, dejavu::sans::regular());
    });
}

/// One point of a trade plot.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartPoint {
    /// Legend label (the variant and its setting).
    pub label: String,
    /// x mean and the half-width of its 95 % interval (NaN: no bar).
    pub x: (f64, f64),
    /// y mean and half-width.
    pub y: (f64, f64),
}

/// A trade plot: points, and the Pareto fronts through some of them.
#[derive(Clone, Debug, PartialEq)]
pub struct TradeChart {
    /// Title above the plot.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// The points, drawn in this order (non-finite means are left out).
    pub points: Vec<ChartPoint>,
    /// Each front's name and its members (indices into `points`, in increasing x); members are
    /// numbered 1, 2, ... over all fronts in this order.
    pub fronts: Vec<(String, Vec<usize>)>,
}

/// How data values became pixels: two data values per axis and the pixels they were drawn at
/// (plotters' own mapping), and whether the axis is logarithmic.
#[derive(Clone, Debug, PartialEq)]
pub struct Geometry {
    /// x: `(value a, pixel a, value b, pixel b)`.
    pub x: (f64, f64, f64, f64),
    /// y: `(value a, pixel a, value b, pixel b)`.
    pub y: (f64, f64, f64, f64),
    /// Whether y is logarithmic.
    pub log_y: bool,
    /// The points drawn (indices into the chart's points), in the order of their markers.
    pub drawn: Vec<usize>,
}

impl Geometry {
    /// The data value of pixel `p` on an axis `(a, pa, b, pb)`.
    fn value((a, pa, b, pb): (f64, f64, f64, f64), log: bool, p: f64) -> f64 {
        let t = (p - pa) / (pb - pa);
        if log {
            10f64.powf(a.log10() + t * (b.log10() - a.log10()))
        } else {
            a + t * (b - a)
        }
    }

    /// The data size of one pixel at value `v` of the y axis (for tolerances).
    pub fn y_pixel(&self, v: f64) -> f64 {
        let (a, pa, b, pb) = self.y;
        if self.log_y {
            v * (10f64.powf((b.log10() - a.log10()) / (pb - pa).abs()) - 1.0)
        } else {
            (b - a).abs() / (pb - pa).abs()
        }
    }

    /// The data size of one pixel on the x axis.
    pub fn x_pixel(&self) -> f64 {
        let (a, pa, b, pb) = self.x;
        (b - a).abs() / (pb - pa).abs()
    }
}

/// The point markers of a trade plot's SVG (`<circle>` elements, in drawing order), mapped back
/// to data values with `geometry`.
pub fn read_back(svg: &str, geometry: &Geometry) -> Vec<(f64, f64)> {
    let attr = |tag: &str, name: &str| -> Option<f64> {
        let key = format!(" {name}=\"");
        let start = tag.find(&key)? + key.len();
        let end = tag[start..].find('"')? + start;
        tag[start..end].parse().ok()
    };
    svg.split("<circle")
        .skip(1)
        .filter_map(|tag| {
            let tag = &tag[..tag.find('>').unwrap_or(tag.len())];
            Some((attr(tag, "cx")?, attr(tag, "cy")?))
        })
        .map(|(cx, cy)| {
            (
                Geometry::value(geometry.x, false, cx),
                Geometry::value(geometry.y, geometry.log_y, cy),
            )
        })
        .collect()
}

/// `label` cut to [`LABEL_CHARS`].
fn short(label: &str) -> String {
    if label.chars().count() <= LABEL_CHARS {
        label.to_string()
    } else {
        let mut s: String = label.chars().take(LABEL_CHARS - 1).collect();
        s.push('…');
        s
    }
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// The range of `values` (finite ones), padded by 5 %, from 0 when all are non-negative (an
/// error or a cost read from 0); `(0, 1)` when there are none.
fn linear_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let v: Vec<f64> = values.filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    let mut lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let mut hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if lo >= 0.0 {
        lo = 0.0;
    }
    if hi <= lo {
        hi = lo + if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
    }
    let pad = (hi - lo) * 0.05;
    (if lo == 0.0 { 0.0 } else { lo - pad }, hi + pad)
}

/// The logarithmic range of `values` when they are all positive and span at least
/// [`LOG_SPAN`]: a factor of 1.3 of room at both ends.
fn log_range(values: &[f64]) -> Option<(f64, f64)> {
    let v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() || v.iter().any(|&v| v <= 0.0) {
        return None;
    }
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (hi / lo >= LOG_SPAN).then_some((lo / 1.3, hi * 1.3))
}

/// A number as an axis label: short, without trailing zeros.
pub fn tick(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if a >= 1e6 {
        format!("{}M", trim(format!("{:.3}", v / 1e6)))
    } else if a >= 1e4 {
        format!("{:.0}k", v / 1e3)
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        trim(format!("{v:.2}"))
    } else {
        trim(format!("{v:.4}"))
    }
}

fn trim(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Draws `chart` to `stem.png` and `stem.svg`; returns the geometry of the SVG (the PNG is the
/// same drawing on a bitmap).
pub fn trade_chart(stem: &Path, chart: &TradeChart) -> std::io::Result<Geometry> {
    font();
    let io = |e: &dyn std::fmt::Display| std::io::Error::other(e.to_string());
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    let ys: Vec<f64> = chart
        .points
        .iter()
        .flat_map(|p| {
            let h = if p.y.1.is_finite() { p.y.1 } else { 0.0 };
            [p.y.0, p.y.0 - h, p.y.0 + h]
        })
        .collect();
    let centres: Vec<f64> = chart.points.iter().map(|p| p.y.0).collect();
    // Errors and costs are never negative: when no mean is, an interval reaching below 0 is cut
    // at 0 (its bar ends at the axis).
    let floor = |means: &[f64], r: (f64, f64)| {
        if means.iter().all(|v| !v.is_finite() || *v >= 0.0) {
            (r.0.max(0.0), r.1)
        } else {
            r
        }
    };
    let x = floor(
        &chart.points.iter().map(|p| p.x.0).collect::<Vec<_>>(),
        linear_range(chart.points.iter().flat_map(|p| {
            let h = if p.x.1.is_finite() { p.x.1 } else { 0.0 };
            [p.x.0 - h, p.x.0 + h]
        })),
    );
    // Log when the means span decades; interval ends at or below 0 are clipped then.
    let log = log_range(&centres).map(|_| {
        let positive: Vec<f64> = ys.iter().copied().filter(|v| *v > 0.0).collect();
        log_range(&positive).unwrap_or_else(|| log_range(&centres).expect("checked"))
    });
    let geometry;
    {
        let root = SVGBackend::new(&svg, (WIDTH, HEIGHT)).into_drawing_area();
        let g = match log {
            Some((lo, hi)) => draw(&root, chart, x, (lo..hi).log_scale(), true),
            None => {
                let (lo, hi) = floor(&centres, linear_range(ys.iter().copied()));
                draw(&root, chart, x, lo..hi, false)
            }
        }
        .map_err(|e| io(&e))?;
        root.present().map_err(|e| io(&e))?;
        geometry = g;
    }
    {
        let root = BitMapBackend::new(&png, (WIDTH, HEIGHT)).into_drawing_area();
        match log {
            Some((lo, hi)) => draw(&root, chart, x, (lo..hi).log_scale(), true),
            None => {
                let (lo, hi) = floor(&centres, linear_range(ys.iter().copied()));
                draw(&root, chart, x, lo..hi, false)
            }
        }
        .map_err(|e| io(&e))?;
        root.present().map_err(|e| io(&e))?;
    }
    Ok(geometry)
}

type DrawResult<T, DB> = Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// The one drawing routine of [`trade_chart`], for either backend and either y axis.
fn draw<DB, Y>(
    root: &DrawingArea<DB, Shift>,
    chart: &TradeChart,
    (x_lo, x_hi): (f64, f64),
    y_spec: Y,
    log_y: bool,
) -> DrawResult<Geometry, DB>
where
    DB: DrawingBackend,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    root.fill(&WHITE)?;
    let (plot_area, legend_area) = root.split_horizontally(WIDTH - LEGEND);
    let mut c = ChartBuilder::on(&plot_area)
        .caption(&chart.title, (FAMILY, 17))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(78)
        .build_cartesian_2d(x_lo..x_hi, y_spec)?;
    c.configure_mesh()
        .x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .label_style((FAMILY, 13))
        .axis_desc_style((FAMILY, 14))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .light_line_style(RGBColor(246, 246, 246))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()?;
    let (y_lo, y_hi) = {
        let r = c.y_range();
        (r.start, r.end)
    };
    let clamp = |v: f64| v.clamp(y_lo, y_hi);
    let colour = |i: usize| rgb(PALETTE[i % PALETTE.len()]);
    let finite = |p: &ChartPoint| p.x.0.is_finite() && p.y.0.is_finite();
    // Intervals first (under the markers): y bars and x bars with end caps.
    for (i, p) in chart.points.iter().enumerate().filter(|(_, p)| finite(p)) {
        let style = colour(i).mix(0.8).stroke_width(2);
        if p.y.1.is_finite() && p.y.1 > 0.0 {
            let (a, b) = (clamp(p.y.0 - p.y.1), clamp(p.y.0 + p.y.1));
            let (a, b) = (a.max(y_lo), b.min(y_hi));
            c.draw_series(std::iter::once(PathElement::new(
                vec![(p.x.0, a), (p.x.0, b)],
                style,
            )))?;
        }
        if p.x.1.is_finite() && p.x.1 > 0.0 {
            c.draw_series(std::iter::once(PathElement::new(
                vec![
                    ((p.x.0 - p.x.1).max(x_lo), p.y.0),
                    ((p.x.0 + p.x.1).min(x_hi), p.y.0),
                ],
                style,
            )))?;
        }
    }
    // The fronts: a line through their members.
    for (k, (_, front)) in chart.fronts.iter().enumerate() {
        let line: Vec<(f64, f64)> = front
            .iter()
            .map(|&i| &chart.points[i])
            .filter(|p| finite(p))
            .map(|p| (p.x.0, p.y.0))
            .collect();
        let style = if k == 0 {
            BLACK.stroke_width(2)
        } else {
            RGBColor(90, 90, 90).stroke_width(2)
        };
        c.draw_series(std::iter::once(PathElement::new(line, style)))?;
    }
    // Markers: one circle per point, in point order (what [`read_back`] reads), then the front
    // members' numbers beside them.
    let number_of = |i: usize| {
        chart
            .fronts
            .iter()
            .flat_map(|(_, f)| f.iter())
            .position(|&j| j == i)
            .map(|n| n + 1)
    };
    let mut drawn = Vec::new();
    for (i, p) in chart.points.iter().enumerate().filter(|(_, p)| finite(p)) {
        let on_front = number_of(i).is_some();
        c.draw_series(std::iter::once(Circle::new(
            (p.x.0, p.y.0),
            if on_front { 6 } else { 4 },
            colour(i).filled(),
        )))?;
        drawn.push(i);
    }
    for (i, p) in chart.points.iter().enumerate().filter(|(_, p)| finite(p)) {
        if let Some(n) = number_of(i) {
            c.draw_series(std::iter::once(
                EmptyElement::at((p.x.0, p.y.0))
                    + Text::new(
                        n.to_string(),
                        (7, -18),
                        (FAMILY, 15).into_font().color(&BLACK),
                    ),
            ))?;
        }
    }
    // The mapping plotters used: two values per axis and their pixels.
    let (px_lo, _) = c.backend_coord(&(x_lo, y_lo));
    let (px_hi, py_hi) = c.backend_coord(&(x_hi, y_hi));
    let (_, py_lo) = c.backend_coord(&(x_lo, y_lo));
    let geometry = Geometry {
        x: (x_lo, f64::from(px_lo), x_hi, f64::from(px_hi)),
        y: (y_lo, f64::from(py_lo), y_hi, f64::from(py_hi)),
        log_y,
        drawn,
    };
    // The legend panel: every point named, front members by their number; then the fronts.
    let row = 19;
    let mut y = 40;
    legend_area.draw(&Text::new(
        "variants (mean, 95% interval)",
        (6, y - 24),
        (FAMILY, 14).into_font().color(&BLACK),
    ))?;
    for (i, p) in chart.points.iter().enumerate() {
        if y + row > HEIGHT as i32 - 50 {
            legend_area.draw(&Text::new(
                format!("… {} more", chart.points.len() - i),
                (6, y),
                (FAMILY, 13).into_font().color(&BLACK),
            ))?;
            y += row;
            break;
        }
        legend_area.draw(&Rectangle::new(
            [(8, y + 2), (20, y + 14)],
            colour(i).filled(),
        ))?;
        let label = match number_of(i) {
            Some(n) => format!("{n}  {}", short(&p.label)),
            None => format!("    {}", short(&p.label)),
        };
        let style = if finite(p) {
            (FAMILY, 13).into_font().color(&BLACK)
        } else {
            (FAMILY, 13).into_font().color(&RGBColor(150, 150, 150))
        };
        legend_area.draw(&Text::new(label, (26, y + 1), style))?;
        y += row;
    }
    y += 6;
    for (k, (name, _)) in chart.fronts.iter().enumerate() {
        let colour = if k == 0 { BLACK } else { RGBColor(90, 90, 90) };
        legend_area.draw(&PathElement::new(
            vec![(6, y + 8), (22, y + 8)],
            colour.stroke_width(2),
        ))?;
        legend_area.draw(&Text::new(
            short(name),
            (26, y + 1),
            (FAMILY, 13).into_font().color(&BLACK),
        ))?;
        y += row;
    }
    Ok(geometry)
}

/// A colour scale from 0 to 1 (`colour` of each value), titled, with ticks at every 0.1: the
/// legend of an error map, written to `stem.png` and `stem.svg`.
pub fn colour_scale(
    stem: &Path,
    title: &str,
    colour: &dyn Fn(f64) -> [u8; 3],
) -> std::io::Result<()> {
    font();
    let io = |e: &dyn std::fmt::Display| std::io::Error::other(e.to_string());
    let size = (480, 80);
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    fn draw_scale<DB: DrawingBackend>(
        root: &DrawingArea<DB, Shift>,
        title: &str,
        colour: &dyn Fn(f64) -> [u8; 3],
    ) -> DrawResult<(), DB> {
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(root)
            .caption(title, (FAMILY, 14))
            .margin_left(14)
            .margin_right(14)
            .x_label_area_size(22)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)?;
        c.configure_mesh()
            .disable_y_axis()
            .disable_mesh()
            .x_labels(11)
            .label_style((FAMILY, 12))
            .x_label_formatter(&|v| tick(*v))
            .draw()?;
        let steps = 256;
        c.draw_series((0..steps).map(|i| {
            let (a, b) = (i as f64 / steps as f64, (i + 1) as f64 / steps as f64);
            Rectangle::new([(a, 0.0), (b, 1.0)], rgb(colour((a + b) / 2.0)).filled())
        }))?;
        Ok(())
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_scale(&root, title, colour).map_err(|e| io(&e))?;
        root.present().map_err(|e| io(&e))?;
    }
    let root = BitMapBackend::new(&png, size).into_drawing_area();
    draw_scale(&root, title, colour).map_err(|e| io(&e))?;
    root.present().map_err(|e| io(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_start_at_zero_and_log_only_across_decades() {
        assert_eq!(linear_range([1.0, 3.0].into_iter()).0, 0.0);
        assert!(linear_range([1.0, 3.0].into_iter()).1 > 3.0);
        assert_eq!(log_range(&[1.0, 5.0]), None);
        assert_eq!(log_range(&[0.0, 500.0]), None);
        let (lo, hi) = log_range(&[2.0, 9000.0]).unwrap();
        assert!(lo < 2.0 && hi > 9000.0);
        assert_eq!(tick(0.0125), "0.0125");
        assert_eq!(tick(2500.0), "2500");
        assert_eq!(tick(2_500_000.0), "2.5M");
    }

    /// The markers of a drawn chart read back as the values they were drawn from, within a pixel,
    /// on a linear and on a logarithmic axis.
    #[test]
    fn markers_read_back_as_their_values() {
        let dir = std::env::temp_dir().join(format!("forestlod-chart-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for ys in [[3.0, 4.0, 9.0], [3.0, 400.0, 9000.0]] {
            let chart = TradeChart {
                title: "t".into(),
                x_label: "x".into(),
                y_label: "y".into(),
                points: ys
                    .iter()
                    .enumerate()
                    .map(|(i, &y)| ChartPoint {
                        label: format!("p{i}"),
                        x: (0.01 * (i + 1) as f64, 0.002),
                        y: (y, 0.5),
                    })
                    .collect(),
                fronts: vec![("front".into(), vec![0, 1])],
            };
            let stem = dir.join("c");
            let g = trade_chart(&stem, &chart).unwrap();
            assert_eq!(g.log_y, ys[2] / ys[0] >= LOG_SPAN);
            let png = image::open(stem.with_extension("png")).unwrap();
            assert_eq!((png.width(), png.height()), (WIDTH, HEIGHT));
            let svg = std::fs::read_to_string(stem.with_extension("svg")).unwrap();
            assert!(svg.contains("p1") && svg.contains("front"), "legend");
            let back = read_back(&svg, &g);
            assert_eq!(back.len(), 3);
            // Pixels are truncated, the marker's and the calibration's: 1.5 px covers both.
            const PIXELS: f64 = 1.5;
            for (p, (x, y)) in chart.points.iter().zip(back) {
                let (dx, dy) = ((x - p.x.0).abs(), (y - p.y.0).abs());
                eprintln!("read back {dx:e} in x, {dy:e} in y");
                assert!(dx <= PIXELS * g.x_pixel(), "{x} vs {:?}", p.x);
                assert!(dy <= PIXELS * g.y_pixel(p.y.0), "{y} vs {:?}", p.y);
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
