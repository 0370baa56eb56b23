//! Small PNG plots for the sweeps (tiny-skia for shapes, the public-domain `font8x8` bitmap font for
//! labels): scatter plots (cost against accuracy), line plots (runtime over a sweep, thesis style,
//! E Fig. 5.1–5.7) and grouped bar charts (mean time of each pass, E Fig. 5.1c).
//!
//! Axes are linear, or logarithmic when asked and every value is positive; ticks are "nice"
//! numbers. Nothing here knows about forests: it draws what it is given.

use std::path::Path;

use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Rect, Stroke, Transform};

/// Plot width in pixels.
pub const WIDTH: u32 = 880;
/// Plot height in pixels.
pub const HEIGHT: u32 = 520;
const LEFT: f32 = 90.0;
const RIGHT: f32 = 300.0;
const TOP: f32 = 40.0;
const BOTTOM: f32 = 60.0;

/// A qualitative palette (Okabe–Ito, colour-blind safe), cycled by series index.
pub const PALETTE: [[u8; 3]; 8] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [100, 100, 100],
    [240, 228, 66],
];

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

fn color(c: [u8; 3]) -> Color {
    Color::from_rgba8(c[0], c[1], c[2], 255)
}

fn paint(c: [u8; 3]) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color(color(c));
    p.anti_alias = true;
    p
}

/// Draws `text` with the 8x8 font at pixel `(x, y)` (top-left), `scale` pixels per font pixel.
pub fn draw_text(pixmap: &mut Pixmap, text: &str, x: f32, y: f32, scale: u32, c: [u8; 3]) {
    let p = paint(c);
    let mut pen = x;
    for ch in text.chars() {
        let code = ch as usize;
        let glyph = if code < 128 {
            font8x8::legacy::BASIC_LEGACY[code]
        } else {
            font8x8::legacy::BASIC_LEGACY[b'?' as usize]
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0
                    && let Some(r) = Rect::from_xywh(
                        pen + (col * scale) as f32,
                        y + (row as u32 * scale) as f32,
                        scale as f32,
                        scale as f32,
                    )
                {
                    pixmap.fill_rect(r, &p, Transform::identity(), None);
                }
            }
        }
        pen += (8 * scale) as f32;
    }
}

/// Width in pixels of `text` at `scale`.
pub fn text_width(text: &str, scale: u32) -> f32 {
    (text.chars().count() as u32 * 8 * scale) as f32
}

/// Draws `text` rotated a quarter turn (reading bottom to top), its baseline at `x`, ending at `y`.
fn draw_text_vertical(pixmap: &mut Pixmap, text: &str, x: f32, y: f32, c: [u8; 3]) {
    let p = paint(c);
    let mut pen = y;
    for ch in text.chars() {
        let code = (ch as usize).min(127);
        let glyph = font8x8::legacy::BASIC_LEGACY[code];
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0
                    && let Some(r) = Rect::from_xywh(x + row as f32, pen - col as f32, 1.0, 1.0)
                {
                    pixmap.fill_rect(r, &p, Transform::identity(), None);
                }
            }
        }
        pen -= 8.0;
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

/// "Nice" tick values covering `[lo, hi]` (about five).
fn nice_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).max(1e-12);
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= 6.0)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() * step;
    let mut t = Vec::new();
    let mut v = first;
    while v <= hi + step * 1e-9 && t.len() < 20 {
        t.push(if v.abs() < step * 1e-9 { 0.0 } else { v });
        v += step;
    }
    t
}

/// A mapping from data to pixels along one axis.
struct Scale {
    lo: f64,
    hi: f64,
    log: bool,
    p0: f32,
    p1: f32,
}

impl Scale {
    fn new(values: impl Iterator<Item = f64> + Clone, log: bool, p0: f32, p1: f32) -> Self {
        let log = log && values.clone().all(|v| v > 0.0);
        let f = |v: f64| if log { v.log10() } else { v };
        let (mut lo, mut hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(f(v)), b.max(f(v)))
        });
        if !lo.is_finite() || !hi.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        if hi - lo < 1e-12 {
            let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
            lo -= pad;
            hi += pad;
        } else {
            let pad = (hi - lo) * 0.05;
            lo -= pad;
            hi += pad;
        }
        if !log && lo > 0.0 && lo < (hi - lo) * 0.5 {
            lo = 0.0;
        }
        Self {
            lo,
            hi,
            log,
            p0,
            p1,
        }
    }

    fn map(&self, v: f64) -> f32 {
        let v = if self.log { v.log10() } else { v };
        self.p0 + ((v - self.lo) / (self.hi - self.lo)) as f32 * (self.p1 - self.p0)
    }

    fn ticks(&self) -> Vec<(f64, String)> {
        if self.log {
            let (a, b) = (self.lo.floor() as i32, self.hi.ceil() as i32);
            let mut t: Vec<(f64, String)> = (a..=b)
                .map(|e| 10f64.powi(e))
                .filter(|v| (self.lo..=self.hi).contains(&v.log10()))
                .map(|v| (v, format_number(v)))
                .collect();
            if t.len() < 2 {
                t = nice_ticks(10f64.powf(self.lo), 10f64.powf(self.hi))
                    .into_iter()
                    .filter(|v| *v > 0.0)
                    .map(|v| (v, format_number(v)))
                    .collect();
            }
            t
        } else {
            nice_ticks(self.lo, self.hi)
                .into_iter()
                .map(|v| (v, format_number(v)))
                .collect()
        }
    }
}

fn frame(pixmap: &mut Pixmap, axes: &Axes) {
    pixmap.fill(Color::WHITE);
    let (w, h) = (pixmap.width() as f32, pixmap.height() as f32);
    draw_text(pixmap, &axes.title, LEFT, 12.0, 2, [20, 20, 20]);
    let xl = &axes.x_label;
    draw_text(
        pixmap,
        xl,
        LEFT + (w - LEFT - RIGHT - text_width(xl, 1)) * 0.5,
        h - 18.0,
        1,
        [20, 20, 20],
    );
    let yl = &axes.y_label;
    draw_text_vertical(
        pixmap,
        yl,
        14.0,
        TOP + (h - TOP - BOTTOM + text_width(yl, 1)) * 0.5,
        [20, 20, 20],
    );
}

fn stroke_line(pixmap: &mut Pixmap, pts: &[(f32, f32)], c: [u8; 3], width: f32) {
    if pts.len() < 2 {
        return;
    }
    let mut pb = PathBuilder::new();
    pb.move_to(pts[0].0, pts[0].1);
    for p in &pts[1..] {
        pb.line_to(p.0, p.1);
    }
    if let Some(path) = pb.finish() {
        let stroke = Stroke {
            width,
            ..Stroke::default()
        };
        pixmap.stroke_path(&path, &paint(c), &stroke, Transform::identity(), None);
    }
}

fn marker(pixmap: &mut Pixmap, x: f32, y: f32, c: [u8; 3], shape: usize) {
    let r = 4.0;
    let mut pb = PathBuilder::new();
    match shape % 3 {
        0 => pb.push_circle(x, y, r),
        1 => {
            if let Some(rect) = Rect::from_xywh(x - r, y - r, 2.0 * r, 2.0 * r) {
                pb.push_rect(rect);
            }
        }
        _ => {
            pb.move_to(x, y - r - 1.0);
            pb.line_to(x + r + 1.0, y + r);
            pb.line_to(x - r - 1.0, y + r);
            pb.close();
        }
    }
    if let Some(path) = pb.finish() {
        pixmap.fill_path(
            &path,
            &paint(c),
            FillRule::Winding,
            Transform::identity(),
            None,
        );
    }
}

fn grid_and_ticks(pixmap: &mut Pixmap, xs: &Scale, ys: &Scale) {
    let (w, h) = (pixmap.width() as f32, pixmap.height() as f32);
    let (x0, x1, y0, y1) = (LEFT, w - RIGHT, h - BOTTOM, TOP);
    for (v, label) in xs.ticks() {
        let x = xs.map(v);
        stroke_line(pixmap, &[(x, y0), (x, y1)], [225, 225, 225], 1.0);
        draw_text(
            pixmap,
            &label,
            x - text_width(&label, 1) * 0.5,
            y0 + 8.0,
            1,
            [60, 60, 60],
        );
    }
    for (v, label) in ys.ticks() {
        let y = ys.map(v);
        stroke_line(pixmap, &[(x0, y), (x1, y)], [225, 225, 225], 1.0);
        draw_text(
            pixmap,
            &label,
            x0 - 6.0 - text_width(&label, 1),
            y - 4.0,
            1,
            [60, 60, 60],
        );
    }
    stroke_line(
        pixmap,
        &[(x0, y1), (x0, y0), (x1, y0), (x1, y1), (x0, y1)],
        [40, 40, 40],
        1.5,
    );
}

fn legend(pixmap: &mut Pixmap, labels: &[String], markers: bool) {
    let swatch = if markers { Swatch::Marker } else { Swatch::Box };
    let entries: Vec<(String, [u8; 3], Swatch, usize)> = labels
        .iter()
        .enumerate()
        .map(|(i, l)| (l.clone(), PALETTE[i % PALETTE.len()], swatch, i))
        .collect();
    legend_entries(pixmap, &entries);
}

/// How a legend entry shows its series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Swatch {
    /// The series' marker (its shape index is the entry's).
    Marker,
    /// A filled box (bars).
    Box,
    /// A short line (a series drawn as a line only).
    Line,
}

/// Legend rows `(label, colour, swatch, marker shape)` right of the plot; rows that do not fit
/// the plot's height are replaced by one `+N more` row.
fn legend_entries(pixmap: &mut Pixmap, entries: &[(String, [u8; 3], Swatch, usize)]) {
    let x = pixmap.width() as f32 - RIGHT + 16.0;
    let rows = (((pixmap.height() as f32 - BOTTOM) - (TOP + 10.0)) / 18.0).max(1.0) as usize;
    let shown = if entries.len() > rows {
        rows - 1
    } else {
        entries.len()
    };
    for (i, (label, c, swatch, shape)) in entries[..shown].iter().enumerate() {
        let y = TOP + 10.0 + i as f32 * 18.0;
        let c = *c;
        match swatch {
            Swatch::Marker => marker(pixmap, x + 6.0, y + 4.0, c, *shape),
            Swatch::Box => {
                if let Some(r) = Rect::from_xywh(x, y, 12.0, 9.0) {
                    pixmap.fill_rect(r, &paint(c), Transform::identity(), None);
                }
            }
            Swatch::Line => stroke_line(pixmap, &[(x, y + 4.0), (x + 12.0, y + 4.0)], c, 2.0),
        }
        // Cut long labels (e.g. `select vegetation (reference)`) to the legend's width, marking
        // the cut with `~`, so that no label runs off the image.
        let room = pixmap.width() as f32 - (x + 18.0) - 4.0;
        let mut short = label.clone();
        while text_width(&short, 1) > room && short.chars().count() > 1 {
            short.pop();
            short.pop();
            short.push('~');
        }
        draw_text(pixmap, &short, x + 18.0, y, 1, [20, 20, 20]);
    }
    if shown < entries.len() {
        let y = TOP + 10.0 + shown as f32 * 18.0;
        let more = format!("+{} more", entries.len() - shown);
        draw_text(pixmap, &more, x + 18.0, y, 1, [20, 20, 20]);
    }
}

/// A scatter or line plot of `series`, written as PNG.
pub fn xy_plot(path: &Path, axes: &Axes, series: &[Series], style: Style) -> std::io::Result<()> {
    let mut pixmap = Pixmap::new(WIDTH, HEIGHT).expect("non-zero plot size");
    frame(&mut pixmap, axes);
    let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().filter(finite).copied())
        .collect();
    let (w, h) = (WIDTH as f32, HEIGHT as f32);
    let xs = Scale::new(all.iter().map(|p| p.0), axes.log_x, LEFT, w - RIGHT);
    let ys = Scale::new(all.iter().map(|p| p.1), axes.log_y, h - BOTTOM, TOP);
    grid_and_ticks(&mut pixmap, &xs, &ys);
    for (i, s) in series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let mut pts: Vec<(f64, f64)> = s.points.iter().filter(finite).copied().collect();
        if style == Style::Lines {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let px: Vec<(f32, f32)> = pts.iter().map(|p| (xs.map(p.0), ys.map(p.1))).collect();
            stroke_line(&mut pixmap, &px, c, 2.0);
        }
        for p in &pts {
            marker(&mut pixmap, xs.map(p.0), ys.map(p.1), c, i);
        }
    }
    legend(
        &mut pixmap,
        &series.iter().map(|s| s.label.clone()).collect::<Vec<_>>(),
        true,
    );
    save(&pixmap, path)
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
    /// Marker shape (circle, square, triangle, cycled).
    pub shape: usize,
    /// Text drawn beside each point (e.g. its number in the legend); empty for none.
    pub tag: String,
}

/// Points with horizontal and vertical interval bars (whiskers with caps), series joined by
/// lines where asked, tags beside points and a legend of the labelled series: e.g. cost against
/// error with their 95 % intervals and a Pareto front. The axes cover the intervals.
pub fn interval_plot(path: &Path, axes: &Axes, series: &[IntervalSeries]) -> std::io::Result<()> {
    let mut pixmap = Pixmap::new(WIDTH, HEIGHT).expect("non-zero plot size");
    frame(&mut pixmap, axes);
    let finite = |p: &&IntervalPoint| p.x.is_finite() && p.y.is_finite();
    let half = |h: f64| if h.is_finite() && h > 0.0 { h } else { 0.0 };
    let all: Vec<IntervalPoint> = series
        .iter()
        .flat_map(|s| s.points.iter().filter(finite).copied())
        .collect();
    let (w, h) = (WIDTH as f32, HEIGHT as f32);
    let xs = Scale::new(
        all.iter()
            .flat_map(|p| [p.x - half(p.x_half), p.x + half(p.x_half)]),
        axes.log_x,
        LEFT,
        w - RIGHT,
    );
    let ys = Scale::new(
        all.iter()
            .flat_map(|p| [p.y - half(p.y_half), p.y + half(p.y_half)]),
        axes.log_y,
        h - BOTTOM,
        TOP,
    );
    grid_and_ticks(&mut pixmap, &xs, &ys);
    // A log axis cannot show an interval reaching 0 or below: it is cut at the axis' end.
    let map_x = |v: f64| xs.map(if xs.log { v.max(10f64.powf(xs.lo)) } else { v });
    let map_y = |v: f64| ys.map(if ys.log { v.max(10f64.powf(ys.lo)) } else { v });
    for s in series {
        let mut pts: Vec<IntervalPoint> = s.points.iter().filter(finite).copied().collect();
        pts.sort_by(|a, b| a.x.total_cmp(&b.x));
        if s.line {
            let px: Vec<(f32, f32)> = pts.iter().map(|p| (map_x(p.x), map_y(p.y))).collect();
            stroke_line(&mut pixmap, &px, s.colour, 2.0);
        }
        if !s.markers {
            continue;
        }
        for p in &pts {
            let (x, y) = (map_x(p.x), map_y(p.y));
            let cap = 3.0;
            if half(p.x_half) > 0.0 {
                let (a, b) = (map_x(p.x - p.x_half), map_x(p.x + p.x_half));
                stroke_line(&mut pixmap, &[(a, y), (b, y)], s.colour, 1.0);
                for e in [a, b] {
                    stroke_line(&mut pixmap, &[(e, y - cap), (e, y + cap)], s.colour, 1.0);
                }
            }
            if half(p.y_half) > 0.0 {
                let (a, b) = (map_y(p.y - p.y_half), map_y(p.y + p.y_half));
                stroke_line(&mut pixmap, &[(x, a), (x, b)], s.colour, 1.0);
                for e in [a, b] {
                    stroke_line(&mut pixmap, &[(x - cap, e), (x + cap, e)], s.colour, 1.0);
                }
            }
            marker(&mut pixmap, x, y, s.colour, s.shape);
            if !s.tag.is_empty() {
                draw_text(&mut pixmap, &s.tag, x + 6.0, y - 12.0, 1, [20, 20, 20]);
            }
        }
    }
    let entries: Vec<(String, [u8; 3], Swatch, usize)> = series
        .iter()
        .filter(|s| !s.label.is_empty())
        .map(|s| {
            let swatch = if s.markers {
                Swatch::Marker
            } else {
                Swatch::Line
            };
            (s.label.clone(), s.colour, swatch, s.shape)
        })
        .collect();
    legend_entries(&mut pixmap, &entries);
    save(&pixmap, path)
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
    let mut pixmap = Pixmap::new(WIDTH, HEIGHT).expect("non-zero plot size");
    frame(&mut pixmap, axes);
    let (w, h) = (WIDTH as f32, HEIGHT as f32);
    let all: Vec<f64> = values
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .chain([0.0])
        .collect();
    let ys = Scale::new(all.iter().copied(), axes.log_y, h - BOTTOM, TOP);
    let xs = Scale {
        lo: 0.0,
        hi: 1.0,
        log: false,
        p0: LEFT,
        p1: w - RIGHT,
    };
    // Y grid and labels only.
    for (v, label) in ys.ticks() {
        let y = ys.map(v);
        stroke_line(
            &mut pixmap,
            &[(LEFT, y), (w - RIGHT, y)],
            [225, 225, 225],
            1.0,
        );
        draw_text(
            &mut pixmap,
            &label,
            LEFT - 6.0 - text_width(&label, 1),
            y - 4.0,
            1,
            [60, 60, 60],
        );
    }
    let group_w = (xs.p1 - xs.p0) / groups.len().max(1) as f32;
    let bar_w = group_w * 0.8 / bars.len().max(1) as f32;
    let base = ys.map(if ys.log { 10f64.powf(ys.lo) } else { 0.0 });
    for (g, name) in groups.iter().enumerate() {
        let gx = xs.p0 + g as f32 * group_w + group_w * 0.1;
        for (b, v) in values.get(g).into_iter().flatten().enumerate() {
            if !v.is_finite() {
                continue;
            }
            let top = ys.map(*v);
            let (y, hgt) = if top < base {
                (top, base - top)
            } else {
                (base, top - base)
            };
            if let Some(r) = Rect::from_xywh(gx + b as f32 * bar_w, y, bar_w * 0.9, hgt.max(1.0)) {
                pixmap.fill_rect(
                    r,
                    &paint(PALETTE[b % PALETTE.len()]),
                    Transform::identity(),
                    None,
                );
            }
        }
        let short: String = name
            .chars()
            .take(((group_w / 8.0) as usize).max(3))
            .collect();
        draw_text(
            &mut pixmap,
            &short,
            gx + (group_w * 0.8 - text_width(&short, 1)) * 0.5,
            h - BOTTOM + 8.0,
            1,
            [60, 60, 60],
        );
    }
    stroke_line(
        &mut pixmap,
        &[
            (LEFT, TOP),
            (LEFT, h - BOTTOM),
            (w - RIGHT, h - BOTTOM),
            (w - RIGHT, TOP),
            (LEFT, TOP),
        ],
        [40, 40, 40],
        1.5,
    );
    legend(&mut pixmap, bars, false);
    save(&pixmap, path)
}

fn save(pixmap: &Pixmap, path: &Path) -> std::io::Result<()> {
    pixmap
        .save_png(path)
        .map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_ticks_are_readable() {
        assert_eq!(format_number(0.0), "0");
        assert_eq!(format_number(250.0), "250");
        assert_eq!(format_number(1.5), "1.5");
        assert_eq!(format_number(0.0125), "0.0125");
        let t = nice_ticks(0.0, 1.0);
        assert!(t.len() >= 3 && t.len() <= 7, "{t:?}");
        assert_eq!(t[0], 0.0);
    }

    #[test]
    fn plots_are_written() {
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
            label: "a".into(),
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
        assert!(dir.join("a.png").is_file() && dir.join("b.png").is_file());
        assert!(dir.join("c.png").is_file());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
