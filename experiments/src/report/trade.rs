//! The speed–accuracy trade as a curve (issue 29): per scene of a sweep, cost against LOD error,
//! one point per group of rows, with 95 % intervals, and the Pareto front named.
//!
//! A **group** is what the report groups rows by, less the camera: variant, backend and setting
//! ([`group_of`]); its point is the mean over the group's frames of that scene whose truth shows
//! a tree (as every mean of the report, [`super::summarize`]), over all its poses. The x value
//! is the mean LOD error (`lod_flip_mean`: FLIP against the same backend's full-detail frame),
//! the y value the mean frame time in milliseconds (one plot) or the mean tree fragments shaded
//! (a second plot; the reference backend counts them, the GPU backend does not, so GPU groups are
//! absent there). Both carry their 95 % Student-t interval over frames ([`super::mean_ci`]) as a
//! bar.
//!
//! The **Pareto front** ([`super::pareto_indices`]) is the groups no other group beats on both
//! LOD error and cost. Times of different backends are not comparable (the report's rule for its
//! text fronts too), so there is one front per backend. Front points are coloured, numbered and
//! joined by a line, and the legend names each by its number; the other groups are grey and
//! unnamed. The caption names the front too, and the report lists it with its intervals
//! (`report.rs`, "Cost against LOD error").
//!
//! The plots are drawn with the sweep's other plots ([`crate::sweep::write_plots`]: by the run,
//! by `sweep merge` and by `report --replot`), as `trade_<scene>_time.png` and
//! `trade_<scene>_fragments.png` in the sweep folder, and listed in `sweep.json` like them.

use std::path::Path;

use forestlod_reference::InputError;

use crate::plot::{Axes, IntervalPoint, IntervalSeries, PALETTE, interval_plot};
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
    /// Frames averaged (those whose truth shows a tree and whose LOD error was measured).
    pub frames: usize,
    /// Mean LOD error and its half-width.
    pub lod: (f64, f64),
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

    /// File-name suffix.
    fn suffix(self) -> &'static str {
        match self {
            Cost::FrameTime => "time",
            Cost::Fragments => "fragments",
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

/// One point per group of `scene`'s rows, first seen first (module docs). Groups none of whose
/// frames has a measured LOD error and shows a tree are left out.
pub fn trade_points(rows: &[Row], scene: &str) -> Vec<TradePoint> {
    let mut order: Vec<(String, String)> = Vec::new();
    for r in rows.iter().filter(|r| r.scene == scene) {
        let key = (group_of(r), r.backend.clone());
        if !order.contains(&key) {
            order.push(key);
        }
    }
    order
        .into_iter()
        .filter_map(|(group, backend)| {
            let rows: Vec<&Row> = rows
                .iter()
                .filter(|r| {
                    r.scene == scene
                        && r.backend == backend
                        && group_of(r) == group
                        && r.accuracy.gt_tree_fraction > 0.0
                        && r.accuracy.lod_flip_mean.is_finite()
                })
                .collect();
            if rows.is_empty() {
                return None;
            }
            let of =
                |f: &dyn Fn(&Row) -> f64| mean_ci(&rows.iter().map(|r| f(r)).collect::<Vec<_>>());
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

/// The Pareto fronts of `points` on `cost` against LOD error, one per backend (in first-seen
/// order; a backend none of whose points has this cost is left out): indices into `points`,
/// each front by increasing LOD error.
pub fn fronts(points: &[TradePoint], cost: Cost) -> Vec<(String, Vec<usize>)> {
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
                    p.backend == b && p.lod.0.is_finite() && cost.of(p).0.is_finite()
                })
                .collect();
            let xy: Vec<(f64, f64)> = mine
                .iter()
                .map(|&i| (points[i].lod.0, cost.of(&points[i]).0))
                .collect();
            let front: Vec<usize> = pareto_indices(&xy).into_iter().map(|j| mine[j]).collect();
            (!front.is_empty()).then(|| (b.to_string(), front))
        })
        .collect()
}

/// `scene` as a file-name part: ASCII letters, digits and `-`, everything else `_`.
fn slug(scene: &str) -> String {
    let s: String = scene
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

/// The trade plots' file-name stems for each scene of `rows`: `(scene, trade_<scene>)`, unique
/// (a second scene with the same [`slug`] gets its index appended); [`plot_name`] adds the cost.
pub fn files(rows: &[Row]) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    for (i, scene) in scenes(rows).into_iter().enumerate() {
        let mut stem = format!("{TRADE_PREFIX}{}", slug(&scene));
        if out.iter().any(|(_, s)| *s == stem) {
            stem = format!("{stem}_{i}");
        }
        out.push((scene, stem));
    }
    out
}

/// The file name of the trade plot of stem `stem` ([`files`]) on `cost`.
pub fn plot_name(stem: &str, cost: Cost) -> String {
    format!("{stem}_{}.png", cost.suffix())
}

/// The trade plot of `scene`'s `points` on `cost`, written to `path`.
fn draw(
    path: &Path,
    sweep: &str,
    scene: &str,
    points: &[TradePoint],
    cost: Cost,
) -> std::io::Result<()> {
    let point = |p: &TradePoint| {
        let (y, y_half) = cost.of(p);
        IntervalPoint {
            x: p.lod.0,
            x_half: p.lod.1,
            y,
            y_half,
        }
    };
    let fronts = fronts(points, cost);
    let on_front: Vec<usize> = fronts.iter().flat_map(|(_, f)| f.clone()).collect();
    let mut series = vec![IntervalSeries {
        label: "other groups".into(),
        points: (0..points.len())
            .filter(|i| !on_front.contains(i))
            .map(|i| point(&points[i]))
            .collect(),
        line: false,
        markers: true,
        colour: [170, 170, 170],
        shape: 0,
        tag: String::new(),
    }];
    if series[0].points.is_empty() {
        series.clear();
    }
    let several = fronts.len() > 1;
    let one_backend = points.iter().all(|p| p.backend == points[0].backend);
    let mut number = 0;
    for (k, (backend, front)) in fronts.iter().enumerate() {
        series.push(IntervalSeries {
            label: if several {
                format!("Pareto front ({backend})")
            } else {
                "Pareto front".into()
            },
            points: front.iter().map(|&i| point(&points[i])).collect(),
            line: true,
            markers: false,
            colour: [40, 40, 40],
            shape: k,
            tag: String::new(),
        });
        for &i in front {
            number += 1;
            series.push(IntervalSeries {
                label: format!(
                    "{number} {}",
                    if one_backend {
                        &points[i].short
                    } else {
                        &points[i].group
                    }
                ),
                points: vec![point(&points[i])],
                line: false,
                markers: true,
                colour: PALETTE[(number - 1) % PALETTE.len()],
                shape: number - 1,
                tag: number.to_string(),
            });
        }
    }
    let axes = Axes::linear(
        format!("{sweep}, {scene}: cost vs LOD error"),
        "mean LOD error (FLIP vs full detail), 95% interval",
        cost.label(),
    );
    interval_plot(path, &axes, &series)
}

/// The front of `points` on `cost`, named: `Pareto front (backend): 1 a; 2 b` per backend,
/// numbered as the plot's legend.
pub fn front_text(points: &[TradePoint], cost: Cost) -> String {
    let fronts = fronts(points, cost);
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

/// Draws the trade plots of every scene of `rows` into `dir` (module docs); returns
/// `(file name, caption)` pairs. A scene without a measured LOD error gets none.
pub fn write_trade_plots(
    sweep: &str,
    rows: &[Row],
    dir: &Path,
) -> Result<Vec<(String, String)>, InputError> {
    let mut out = Vec::new();
    for (scene, stem) in files(rows) {
        let points = trade_points(rows, &scene);
        for cost in Cost::ALL {
            if fronts(&points, cost).is_empty() {
                continue;
            }
            let name = plot_name(&stem, cost);
            let path = dir.join(&name);
            draw(&path, sweep, &scene, &points, cost).map_err(|e| {
                InputError::new(path.display().to_string(), "write", "", e.to_string())
            })?;
            out.push((
                name,
                format!(
                    "Scene `{scene}`: {} against LOD error, one point per variant / backend / setting (mean over its frames that show trees, 95% intervals as bars). {}.",
                    cost.label(),
                    front_text(&points, cost)
                ),
            ));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(group: &str, backend: &str, lod: f64, ms: f64, fragments: f64) -> TradePoint {
        TradePoint {
            group: group.into(),
            short: group.into(),
            backend: backend.into(),
            frames: 3,
            lod: (lod, 0.001),
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
            fronts(&points, Cost::FrameTime),
            vec![
                ("reference".to_string(), vec![0, 1]),
                ("gpu".into(), vec![4])
            ]
        );
        assert_eq!(
            fronts(&points, Cost::Fragments),
            vec![("reference".to_string(), vec![0, 1, 2])]
        );
        assert_eq!(
            front_text(&points, Cost::FrameTime),
            "Pareto front (reference): 1 vegetation (reference); 2 ours (reference), a. Pareto front (gpu): 3 vegetation (gpu)"
        );
    }

    #[test]
    fn scene_names_become_distinct_file_names() {
        assert_eq!(slug("tiny"), "tiny");
        assert_eq!(slug("../a b"), "___a_b");
        assert_eq!(slug(""), "scene");
    }
}
