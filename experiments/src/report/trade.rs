//! The speed–accuracy trade as a curve (issues 29 and 35): per scene **and camera** of a sweep
//! (a [`View`]), cost against error, one point per group of rows, with 95 % intervals, and the
//! Pareto front named. The report opens with these plots (`report.rs`, the index page).
//!
//! A **group** is what the report groups rows by, less the camera: variant, backend and setting
//! ([`group_of`]); its point is the mean over the group's frames of that view whose truth shows a
//! tree (as every mean of the report, [`super::summarize`]). Each error and each cost carries its
//! 95 % Student-t interval over frames ([`super::mean_ci`]) as a bar.
//!
//! **Errors** ([`ErrorKind`]): the LOD error (FLIP against the same backend's full-detail frame),
//! the total error (our frame at the truth's sampling rate against the truth, `crate::fair`) and
//! the temporal error of camera paths (`crate::temporal`), each where the sweep measured it; a run
//! written before any of these existed falls back to FLIP against the ray-traced truth at one
//! sample. **Costs** ([`Cost`]): the mean frame time in milliseconds and the mean tree fragments
//! shaded, the machine-independent cost (the reference backend counts them, the GPU backend does
//! not, so GPU groups are absent there). Which pairs are drawn: [`plots`].
//!
//! The **Pareto front** ([`super::pareto_indices`]) is the groups no other group beats on both
//! error and cost. Times of different backends are not comparable (the report's rule for its
//! text fronts too), so there is one front per backend. Front points are numbered and joined by a
//! line, and the legend names every group, the front members by their number
//! ([`crate::chart::trade_chart`]). The caption names the front too, and the report lists it
//! with its intervals.
//!
//! The plots are drawn with the sweep's other plots ([`crate::sweep::write_plots`]: by the run,
//! by `sweep merge` and by `report --replot`), as `trade_<scene>_<camera>_<cost>_vs_<error>.png`
//! and `.svg` in the sweep folder; the PNG is listed in `sweep.json` like the other plots.

use std::path::Path;

use forestlod_reference::InputError;

use crate::chart::{ChartPoint, Geometry, TradeChart, trade_chart};
use crate::sweep::Row;

use super::{mean_ci, pareto_indices, variant_label};

/// The file-name prefix of the trade plots: the report shows them in their own section.
pub const TRADE_PREFIX: &str = "trade_";

/// A group's point: its means and the half-widths of their 95 % intervals.
#[derive(Clone, Debug, PartialEq)]
pub struct TradePoint {
    /// The group ([`group_of`]).
    pub group: String,
    /// The group without its backend (`ours, grid 50`): the plot's legend when every point is of
    /// one backend (legend rows are short).
    pub short: String,
    /// Its backend (a front is per backend).
    pub backend: String,
    /// Frames averaged (those whose truth shows a tree).
    pub frames: usize,
    /// Mean LOD error and its half-width (NaN: not measured).
    pub lod: (f64, f64),
    /// Mean total error and its half-width (NaN: not measured).
    pub total: (f64, f64),
    /// Mean temporal error and its half-width, over the frames that have one (NaN: none).
    pub temporal: (f64, f64),
    /// Mean FLIP against the truth at one sample, and its half-width.
    pub truth: (f64, f64),
    /// Mean frame time, milliseconds, and its half-width.
    pub frame_ms: (f64, f64),
    /// Mean tree fragments shaded and its half-width (NaN where not counted: the GPU backend).
    pub fragments: (f64, f64),
}

/// A cost axis of the trade.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cost {
    /// Mean frame time (select + draw), milliseconds.
    FrameTime,
    /// Mean tree fragments shaded.
    Fragments,
}

impl Cost {
    /// Both, in the report's order.
    pub const ALL: [Cost; 2] = [Cost::FrameTime, Cost::Fragments];

    /// The point's mean and half-width on this axis.
    pub fn of(self, p: &TradePoint) -> (f64, f64) {
        match self {
            Cost::FrameTime => p.frame_ms,
            Cost::Fragments => p.fragments,
        }
    }

    /// Axis label.
    pub fn label(self) -> &'static str {
        match self {
            Cost::FrameTime => "mean frame time [ms]",
            Cost::Fragments => "mean tree fragments shaded",
        }
    }

    /// File-name part.
    fn suffix(self) -> &'static str {
        match self {
            Cost::FrameTime => "time",
            Cost::Fragments => "fragments",
        }
    }
}

/// An error axis of the trade (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// FLIP against the same backend's full-detail frame.
    Lod,
    /// FLIP of our frame at the truth's sampling rate against the truth.
    Total,
    /// FLIP between consecutive frames of a camera path, less the full-detail frames' own.
    Temporal,
    /// FLIP against the truth at one sample (runs without the errors above).
    Truth,
}

impl ErrorKind {
    /// All, in the report's order of preference.
    pub const ALL: [ErrorKind; 4] = [
        ErrorKind::Lod,
        ErrorKind::Total,
        ErrorKind::Temporal,
        ErrorKind::Truth,
    ];

    /// The point's mean and half-width of this error.
    pub fn of(self, p: &TradePoint) -> (f64, f64) {
        match self {
            ErrorKind::Lod => p.lod,
            ErrorKind::Total => p.total,
            ErrorKind::Temporal => p.temporal,
            ErrorKind::Truth => p.truth,
        }
    }

    /// Its name in text.
    pub fn name(self) -> &'static str {
        match self {
            ErrorKind::Lod => "LOD error",
            ErrorKind::Total => "total error",
            ErrorKind::Temporal => "temporal error",
            ErrorKind::Truth => "FLIP against the truth",
        }
    }

    /// Axis label.
    pub fn label(self) -> &'static str {
        match self {
            ErrorKind::Lod => "mean LOD error (FLIP vs full detail)",
            ErrorKind::Total => "mean total error (FLIP vs truth, truth's sampling)",
            ErrorKind::Temporal => "mean temporal error (FLIP between frames)",
            ErrorKind::Truth => "mean FLIP vs ray-traced truth (1 sample)",
        }
    }

    /// File-name part.
    fn suffix(self) -> &'static str {
        match self {
            ErrorKind::Lod => "lod",
            ErrorKind::Total => "total",
            ErrorKind::Temporal => "temporal",
            ErrorKind::Truth => "truth",
        }
    }
}

/// The trade group of a row: variant with backend, and setting (e.g. `ours (reference), grid
/// 50`), as the report's groups less the camera.
pub fn group_of(r: &Row) -> String {
    if r.setting.is_empty() {
        variant_label(r)
    } else {
        format!("{}, {}", variant_label(r), r.setting)
    }
}

/// The scenes of `rows`, first seen first.
pub fn scenes(rows: &[Row]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in rows {
        if !out.contains(&r.scene) {
            out.push(r.scene.clone());
        }
    }
    out
}

/// A scene and camera of a sweep: one trade plot per cost and error.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct View {
    /// The scene.
    pub scene: String,
    /// The camera (`distance` for the distance path).
    pub camera: String,
    /// The plots' file-name stem, `trade_<scene>_<camera>` ([`plot_name`] adds the rest).
    pub stem: String,
}

/// One point per group of the rows of `scene` seen from `camera`, first seen first (module
/// docs). Groups none of whose frames shows a tree are left out.
pub fn trade_points(rows: &[Row], scene: &str, camera: &str) -> Vec<TradePoint> {
    let mine: Vec<&Row> = rows
        .iter()
        .filter(|r| r.scene == scene && r.camera == camera)
        .collect();
    let mut order: Vec<(String, String)> = Vec::new();
    for r in &mine {
        let key = (group_of(r), r.backend.clone());
        if !order.contains(&key) {
            order.push(key);
        }
    }
    order
        .into_iter()
        .filter_map(|(group, backend)| {
            let rows: Vec<&Row> = mine
                .iter()
                .copied()
                .filter(|r| {
                    r.backend == backend
                        && group_of(r) == group
                        && r.accuracy.gt_tree_fraction > 0.0
                })
                .collect();
            if rows.is_empty() {
                return None;
            }
            // Each mean over the frames that measured it.
            let of = |f: &dyn Fn(&Row) -> f64| {
                mean_ci(
                    &rows
                        .iter()
                        .map(|r| f(r))
                        .filter(|v| v.is_finite())
                        .collect::<Vec<_>>(),
                )
            };
            let counted: Vec<f64> = rows
                .iter()
                .filter_map(|r| r.fragments.map(|f| f as f64))
                .collect();
            let short = match rows[0].setting.as_str() {
                "" => rows[0].variant.clone(),
                setting => format!("{}, {setting}", rows[0].variant),
            };
            Some(TradePoint {
                group,
                short,
                backend,
                frames: rows.len(),
                lod: of(&|r| r.accuracy.lod_flip_mean),
                total: of(&|r| r.accuracy.total_flip_mean),
                temporal: of(&|r| r.temporal_mean.unwrap_or(f64::NAN)),
                truth: of(&|r| r.accuracy.flip_mean),
                frame_ms: of(&|r| r.frame_s * 1e3),
                fragments: if counted.len() == rows.len() {
                    mean_ci(&counted)
                } else {
                    (f64::NAN, f64::NAN)
                },
            })
        })
        .collect()
}

/// The errors measured for some point of `points`, in [`ErrorKind::ALL`]'s order; FLIP against
/// the truth only when neither the LOD error nor the total error was measured (module docs).
pub fn errors(points: &[TradePoint]) -> Vec<ErrorKind> {
    let measured = |e: ErrorKind| points.iter().any(|p| e.of(p).0.is_finite());
    let mut out: Vec<ErrorKind> = [ErrorKind::Lod, ErrorKind::Total, ErrorKind::Temporal]
        .into_iter()
        .filter(|&e| measured(e))
        .collect();
    if !out.contains(&ErrorKind::Lod) && !out.contains(&ErrorKind::Total) {
        out.insert(0, ErrorKind::Truth);
    }
    out
}

/// The trade plots of `points`, the first one the headline (the index page shows it): frame time
/// against every error measured ([`errors`]), and fragments against the first error; only pairs
/// with a front (some point has both values).
pub fn plots(points: &[TradePoint]) -> Vec<(Cost, ErrorKind)> {
    let errors = errors(points);
    errors
        .iter()
        .map(|&e| (Cost::FrameTime, e))
        .chain(errors.first().map(|&e| (Cost::Fragments, e)))
        .filter(|&(c, e)| !fronts(points, c, e).is_empty())
        .collect()
}

/// The Pareto fronts of `points` on `cost` against `error`, one per backend (in first-seen
/// order; a backend none of whose points has both values is left out): indices into `points`,
/// each front by increasing error.
pub fn fronts(points: &[TradePoint], cost: Cost, error: ErrorKind) -> Vec<(String, Vec<usize>)> {
    let mut backends: Vec<&str> = Vec::new();
    for p in points {
        if !backends.contains(&p.backend.as_str()) {
            backends.push(&p.backend);
        }
    }
    backends
        .into_iter()
        .filter_map(|b| {
            let mine: Vec<usize> = (0..points.len())
                .filter(|&i| {
                    let p = &points[i];
                    p.backend == b && error.of(p).0.is_finite() && cost.of(p).0.is_finite()
                })
                .collect();
            let xy: Vec<(f64, f64)> = mine
                .iter()
                .map(|&i| (error.of(&points[i]).0, cost.of(&points[i]).0))
                .collect();
            let front: Vec<usize> = pareto_indices(&xy).into_iter().map(|j| mine[j]).collect();
            (!front.is_empty()).then(|| (b.to_string(), front))
        })
        .collect()
}

/// `name` as a file-name part: ASCII letters, digits and `-`, everything else `_`.
fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() { "scene".into() } else { s }
}

/// The views of `rows`: every scene and camera, first seen first, each with a unique file-name
/// stem (a second view with the same [`slug`]s gets its index appended).
pub fn views(rows: &[Row]) -> Vec<View> {
    let mut pairs: Vec<(String, String)> = Vec::new();
    for r in rows {
        let key = (r.scene.clone(), r.camera.clone());
        if !pairs.contains(&key) {
            pairs.push(key);
        }
    }
    let mut out: Vec<View> = Vec::new();
    for (i, (scene, camera)) in pairs.into_iter().enumerate() {
        let mut stem = format!("{TRADE_PREFIX}{}_{}", slug(&scene), slug(&camera));
        if out.iter().any(|v| v.stem == stem) {
            stem = format!("{stem}_{i}");
        }
        out.push(View {
            scene,
            camera,
            stem,
        });
    }
    out
}

/// The file name of the PNG trade plot of stem `stem` ([`views`]) on `cost` against `error`;
/// its SVG twin has the same stem.
pub fn plot_name(stem: &str, cost: Cost, error: ErrorKind) -> String {
    format!("{stem}_{}_vs_{}.png", cost.suffix(), error.suffix())
}

/// The chart of `view`'s `points` on `cost` against `error` (module docs).
pub fn chart(
    sweep: &str,
    view: &View,
    points: &[TradePoint],
    cost: Cost,
    error: ErrorKind,
) -> TradeChart {
    let fronts = fronts(points, cost, error);
    let one_backend = points.iter().all(|p| p.backend == points[0].backend);
    let several = fronts.len() > 1;
    TradeChart {
        title: format!("{sweep}: {}, camera {}", view.scene, view.camera),
        x_label: format!("{}, 95% interval", error.label()),
        y_label: cost.label().to_string(),
        points: points
            .iter()
            .map(|p| ChartPoint {
                label: if one_backend {
                    p.short.clone()
                } else {
                    p.group.clone()
                },
                x: error.of(p),
                y: cost.of(p),
            })
            .collect(),
        fronts: fronts
            .into_iter()
            .map(|(backend, front)| {
                let name = if several {
                    format!("Pareto front ({backend})")
                } else {
                    "Pareto front".to_string()
                };
                (name, front)
            })
            .collect(),
    }
}

/// Draws the trade plot of `view`'s `points` on `cost` against `error` to `dir` (PNG and SVG);
/// returns the PNG's path and the geometry of the drawing ([`crate::chart::read_back`]).
pub fn draw(
    dir: &Path,
    sweep: &str,
    view: &View,
    points: &[TradePoint],
    cost: Cost,
    error: ErrorKind,
) -> std::io::Result<(std::path::PathBuf, Geometry)> {
    let path = dir.join(plot_name(&view.stem, cost, error));
    let geometry = trade_chart(&path, &chart(sweep, view, points, cost, error))?;
    Ok((path, geometry))
}

/// The front of `points` on `cost` against `error`, named: `Pareto front (backend): 1 a; 2 b`
/// per backend, numbered as the plot's legend.
pub fn front_text(points: &[TradePoint], cost: Cost, error: ErrorKind) -> String {
    let fronts = fronts(points, cost, error);
    let mut number = 0;
    fronts
        .iter()
        .map(|(backend, front)| {
            let names: Vec<String> = front
                .iter()
                .map(|&i| {
                    number += 1;
                    format!("{number} {}", points[i].group)
                })
                .collect();
            format!("Pareto front ({backend}): {}", names.join("; "))
        })
        .collect::<Vec<_>>()
        .join(". ")
}

/// Draws the trade plots of every view of `rows` into `dir` (module docs); returns the PNGs'
/// `(file name, caption)` pairs, each view's headline plot first.
pub fn write_trade_plots(
    sweep: &str,
    rows: &[Row],
    dir: &Path,
) -> Result<Vec<(String, String)>, InputError> {
    let mut out = Vec::new();
    for view in views(rows) {
        let points = trade_points(rows, &view.scene, &view.camera);
        for (cost, error) in plots(&points) {
            let (path, _) = draw(dir, sweep, &view, &points, cost, error).map_err(|e| {
                InputError::new(
                    dir.join(plot_name(&view.stem, cost, error))
                        .display()
                        .to_string(),
                    "write",
                    "",
                    e.to_string(),
                )
            })?;
            let name = path
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_default();
            out.push((
                name,
                format!(
                    "Scene `{}`, camera `{}`: {} against {}, one point per variant / backend / setting (mean over its frames that show trees, 95% intervals as bars). {}.",
                    view.scene,
                    view.camera,
                    cost.label(),
                    error.name(),
                    front_text(&points, cost, error)
                ),
            ));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn point(group: &str, backend: &str, lod: f64, ms: f64, fragments: f64) -> TradePoint {
        TradePoint {
            group: group.into(),
            short: group.into(),
            backend: backend.into(),
            frames: 3,
            lod: (lod, 0.001),
            total: (f64::NAN, f64::NAN),
            temporal: (f64::NAN, f64::NAN),
            truth: (lod * 2.0, 0.001),
            frame_ms: (ms, 0.1),
            fragments: (fragments, 10.0),
        }
    }

    /// One front per backend, undominated points only, by increasing LOD error; a point without
    /// the cost (GPU fragments) is on no front.
    #[test]
    fn fronts_are_per_backend_and_keep_only_undominated_groups() {
        let points = vec![
            point("vegetation (reference)", "reference", 0.0, 9.0, 900.0),
            point("ours (reference), a", "reference", 0.02, 3.0, 300.0),
            point("ours (reference), b", "reference", 0.03, 4.0, 200.0),
            point("ours (gpu), a", "gpu", 0.02, 0.5, f64::NAN),
            point("vegetation (gpu)", "gpu", 0.0, 0.4, f64::NAN),
        ];
        assert_eq!(
            fronts(&points, Cost::FrameTime, ErrorKind::Lod),
            vec![
                ("reference".to_string(), vec![0, 1]),
                ("gpu".into(), vec![4])
            ]
        );
        assert_eq!(
            fronts(&points, Cost::Fragments, ErrorKind::Lod),
            vec![("reference".to_string(), vec![0, 1, 2])]
        );
        assert_eq!(
            front_text(&points, Cost::FrameTime, ErrorKind::Lod),
            "Pareto front (reference): 1 vegetation (reference); 2 ours (reference), a. Pareto front (gpu): 3 vegetation (gpu)"
        );
    }

    #[test]
    fn scene_names_become_distinct_file_names() {
        assert_eq!(slug("tiny"), "tiny");
        assert_eq!(slug("../a b"), "___a_b");
        assert_eq!(slug(""), "scene");
    }

    /// The plots' numbers are the CSV's (issue 35): for committed sweeps (one with the LOD error
    /// on one backend, one with FLIP against the truth on two, one with frames that show no
    /// tree), every view's plots are drawn, the
    /// point markers are read back from the SVG ([`crate::chart::read_back`]) and compared with
    /// the means computed here straight from the CSV's cells (not through [`Row`] or
    /// [`trade_points`]): the mean of `frame_s` × 1000 or `fragments`, and of the error's column,
    /// over the group's rows whose `gt_tree_fraction` is positive. They must agree within one
    /// pixel of the axis ([`READ_BACK_PIXELS`]).
    #[test]
    fn plotted_points_read_back_as_the_csv_means() {
        /// Markers are drawn at whole pixels (SVG `cx`, `cy` are integers; plotters truncates,
        /// so up to one pixel off), and the two calibration pixels of [`Geometry`] are truncated
        /// the same way: 1.5 pixels covers both (0.99 px seen on the committed sweeps).
        const READ_BACK_PIXELS: f64 = 1.5;
        let results = Path::new(env!("CARGO_MANIFEST_DIR")).join("results");
        let dir = std::env::temp_dir().join(format!("forestlod-trade-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut checked = 0;
        let mut worst: f64 = 0.0;
        for sweep in ["hierarchy", "grid_size", "angles_texture"] {
            let csv_path = results.join(sweep).join(format!("{sweep}.csv"));
            let rows = crate::report::read_rows(&csv_path).unwrap();
            let mut reader = csv::Reader::from_path(&csv_path).unwrap();
            let headers = reader.headers().unwrap().clone();
            let records: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
            let cell = |r: &csv::StringRecord, c: &str| -> String {
                let i = headers.iter().position(|h| h == c).unwrap_or(usize::MAX);
                r.get(i).unwrap_or("").to_string()
            };
            let num =
                |r: &csv::StringRecord, c: &str| cell(r, c).parse::<f64>().unwrap_or(f64::NAN);
            for view in views(&rows) {
                let points = trade_points(&rows, &view.scene, &view.camera);
                for (cost, error) in plots(&points) {
                    let (_, g) = draw(&dir, sweep, &view, &points, cost, error).unwrap();
                    let svg = std::fs::read_to_string(
                        dir.join(plot_name(&view.stem, cost, error))
                            .with_extension("svg"),
                    )
                    .unwrap();
                    let back = crate::chart::read_back(&svg, &g);
                    assert_eq!(back.len(), g.drawn.len(), "{sweep} {view:?}");
                    for (&i, &(x, y)) in g.drawn.iter().zip(&back) {
                        let p = &points[i];
                        // The group's rows, straight from the CSV.
                        let mine: Vec<&csv::StringRecord> = records
                            .iter()
                            .filter(|r| {
                                cell(r, "scene") == view.scene
                                    && cell(r, "camera") == view.camera
                                    && cell(r, "backend") == p.backend
                                    && format!("{} ({})", cell(r, "variant"), cell(r, "backend"))
                                        + &match cell(r, "setting").as_str() {
                                            "" => String::new(),
                                            s => format!(", {s}"),
                                        }
                                        == p.group
                                    && num(r, "gt_tree_fraction") > 0.0
                            })
                            .collect();
                        let mean = |c: &str, scale: f64| {
                            let v: Vec<f64> = mine
                                .iter()
                                .map(|r| num(r, c) * scale)
                                .filter(|v| v.is_finite())
                                .collect();
                            v.iter().sum::<f64>() / v.len() as f64
                        };
                        let want_y = match cost {
                            Cost::FrameTime => mean("frame_s", 1e3),
                            Cost::Fragments => mean("fragments", 1.0),
                        };
                        let want_x = mean(
                            match error {
                                ErrorKind::Lod => "lod_flip_mean",
                                ErrorKind::Total => "total_flip_mean",
                                ErrorKind::Temporal => "temporal_mean",
                                ErrorKind::Truth => "flip_mean",
                            },
                            1.0,
                        );
                        let (dx, dy) = ((x - want_x).abs(), (y - want_y).abs());
                        worst = worst.max(dx / g.x_pixel()).max(dy / g.y_pixel(want_y));
                        assert!(
                            dx <= READ_BACK_PIXELS * g.x_pixel()
                                && dy <= READ_BACK_PIXELS * g.y_pixel(want_y),
                            "{sweep} {} {:?} {:?}: plotted ({x}, {y}), CSV ({want_x}, {want_y})",
                            p.group,
                            cost,
                            error
                        );
                        checked += 1;
                    }
                }
            }
        }
        std::fs::remove_dir_all(&dir).ok();
        eprintln!("{checked} points read back; largest difference {worst:.3} px");
        assert!(checked > 10, "{checked}");
    }
}
