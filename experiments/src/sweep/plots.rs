//! The sweep's PNG plots from its rows ([`write_plots`]): cost against accuracy, the
//! thesis-style runtime plots (E Fig. 5.1–5.7) and, per scene, cost against LOD error with the
//! Pareto front named ([`crate::report::trade`]). Reads only the spec and the rows, so
//! `forestlod report --replot` redraws them from a CSV. Series are variants (or variant–backend
//! pairs when several backends ran), split further by the parameter sets' series labels.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use forestlod_reference::InputError;

use crate::plot::{Axes, Series, Style, bar_plot, xy_plot};

use super::io::io_err;
use super::rows::Row;
use super::spec::SweepSpec;
use super::variant::{Engine, Registered};

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Series label of a row: the variant, plus the parameter set's series label when there is one.
/// Mean select and draw time of rows, milliseconds: the bars of the pass-time plots.
const PASS_MS: [fn(&Row) -> f64; 2] = [|r| r.select_s * 1e3, |r| r.draw_s * 1e3];

/// For each group, the mean of each metric over the group's rows (bar-plot values).
fn group_means<'r>(
    groups: &[String],
    metrics: &[fn(&Row) -> f64],
    rows_of: impl Fn(&String) -> Vec<&'r Row>,
) -> Vec<Vec<f64>> {
    groups
        .iter()
        .map(|g| {
            let rs = rows_of(g);
            metrics
                .iter()
                .map(|m| mean(rs.iter().map(|r| m(r))))
                .collect()
        })
        .collect()
}

fn series_of(row: &Row, sets: &HashMap<String, String>, variants: usize) -> String {
    let series = sets.get(&row.setting).cloned().unwrap_or_default();
    match (variants > 1, series.is_empty()) {
        (true, true) => row.variant.clone(),
        (true, false) => format!("{} {series}", row.variant),
        (false, true) => row.variant.clone(),
        (false, false) => series,
    }
}

/// Writes the sweep's plots; returns `(relative path, caption)` pairs.
pub fn write_plots(
    spec: &SweepSpec,
    rows: &[Row],
    dir: &Path,
) -> Result<Vec<(String, String)>, InputError> {
    let file = format!("<sweep {}>", spec.name);
    let sets = spec.param_sets(&file)?;
    // Cost against LOD error per scene, the Pareto front named (`crate::report::trade`): from the
    // rows as written (its groups keep variant and backend apart themselves).
    let trade = crate::report::trade::write_trade_plots(&spec.name, rows, dir)?;
    let series_by_label: HashMap<String, String> = sets
        .iter()
        .map(|s| (s.label.clone(), s.series.clone()))
        .collect();
    let x_by_label: HashMap<String, Option<f64>> =
        sets.iter().map(|s| (s.label.clone(), s.x)).collect();
    // With several backends a series is a (variant, backend) pair: relabel the variant.
    let (rows, variants): (Vec<Row>, Vec<String>) = if spec.backends.len() > 1 {
        // Short backend names keep legends readable: `ours ref`, `vegetation gpu`.
        let label = |v: &str, b: &str| {
            let b = Engine::parse(b).map_or(b, |b| b.short_name());
            format!("{v} {b}")
        };
        (
            rows.iter()
                .map(|r| Row {
                    variant: label(&r.variant, &r.backend),
                    ..r.clone()
                })
                .collect(),
            spec.backends
                .iter()
                .flat_map(|b| spec.variants.iter().map(move |v| label(v, b)))
                .collect(),
        )
    } else {
        (rows.to_vec(), spec.variants.clone())
    };
    let rows = &rows[..];
    let nv = variants.len();
    let backend_label = if spec.backends.len() > 1 {
        "reference CPU and GPU backends".to_string()
    } else if spec.backend_list(&file)?.contains(&Engine::Gpu) {
        "GPU backend".to_string()
    } else {
        "reference CPU backend".to_string()
    };
    let mut out = Vec::new();
    let mut plot = |name: &str,
                    caption: String,
                    f: &dyn Fn(&Path) -> std::io::Result<()>|
     -> Result<(), InputError> {
        let path = dir.join(name);
        f(&path).map_err(|e| io_err(&path, e))?;
        out.push((name.to_string(), caption));
        Ok(())
    };
    // Group rows into series, keeping first-seen order.
    let group = |rows: &[&Row],
                 y: &dyn Fn(&Row) -> f64,
                 x: &dyn Fn(&Row) -> f64,
                 avg: bool|
     -> Vec<Series> {
        let mut order: Vec<String> = Vec::new();
        let mut pts: HashMap<String, Vec<(f64, f64)>> = HashMap::new();
        for r in rows {
            let s = series_of(r, &series_by_label, nv);
            if !pts.contains_key(&s) {
                order.push(s.clone());
            }
            pts.entry(s).or_default().push((x(r), y(r)));
        }
        order
            .into_iter()
            .map(|label| {
                let mut points = pts.remove(&label).unwrap_or_default();
                if avg {
                    let mut by_x: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
                    for (x, y) in &points {
                        by_x.entry(x.to_bits()).or_default().push(*y);
                    }
                    points = by_x
                        .into_iter()
                        .map(|(x, ys)| (f64::from_bits(x), mean(ys.into_iter())))
                        .collect();
                }
                Series { label, points }
            })
            .collect()
    };
    let all: Vec<&Row> = rows.iter().collect();
    // 1. Cost against accuracy, every frame.
    for (name, ylabel, y) in [
        (
            "cost_vs_flip.png",
            "FLIP mean vs ground truth",
            (|r: &Row| r.accuracy.flip_mean) as fn(&Row) -> f64,
        ),
        (
            "cost_vs_coverage.png",
            "coverage error (fraction of pixels)",
            |r: &Row| r.accuracy.coverage_error,
        ),
    ] {
        let series = group(&all, &y, &|r: &Row| r.frame_s, false);
        let axes = Axes {
            title: format!("{}: cost vs accuracy", spec.name),
            x_label: format!("frame time [s] ({backend_label}, log)"),
            y_label: ylabel.into(),
            log_x: true,
            log_y: false,
        };
        plot(
            name,
            format!("Every frame: frame time against {ylabel}, one colour per variant / setting."),
            &|p| xy_plot(p, &axes, &series, Style::Scatter),
        )?;
    }
    // 2. Thesis-style runtime plots.
    match spec.x_axis.as_str() {
        "yaw" => {
            let cameras: Vec<String> = {
                let mut c: Vec<String> = rows.iter().map(|r| r.camera.clone()).collect();
                c.dedup();
                let mut seen = Vec::new();
                for x in c {
                    if !seen.contains(&x) {
                        seen.push(x);
                    }
                }
                seen
            };
            for cam in &cameras {
                let rs: Vec<&Row> = rows.iter().filter(|r| &r.camera == cam).collect();
                let series = group(&rs, &|r| r.frame_s * 1e3, &|r| r.yaw_deg as f64, true);
                let axes = Axes::linear(
                    format!("{}: {cam} benchmark runtime over 360 deg", spec.name),
                    "camera yaw [deg]",
                    "frame time [ms]",
                );
                plot(
                    &format!("runtime_{cam}.png"),
                    format!("Runtime over the 360° sweep of camera `{cam}` (E Fig. 5.1–5.3 b)."),
                    &|p| xy_plot(p, &axes, &series, Style::Lines),
                )?;
                // Mean time of each pass per variant (E Fig. 5.1c).
                let values = group_means(&variants, &PASS_MS, |v| {
                    rs.iter().copied().filter(|r| &r.variant == v).collect()
                });
                let axes = Axes::linear(
                    format!("{}: {cam} mean pass times", spec.name),
                    "variant",
                    "mean time [ms]",
                );
                plot(
                    &format!("passes_{cam}.png"),
                    format!(
                        "Mean time of each pass for camera `{cam}` (E Fig. 5.1–5.3 c): select = selection or per-tree culling, draw = rasterization."
                    ),
                    &|p| {
                        bar_plot(
                            p,
                            &axes,
                            &variants,
                            &["select".into(), "draw".into()],
                            &values,
                        )
                    },
                )?;
            }
        }
        "distance" => {
            for (name, ylabel, y, cap) in [
                (
                    "runtime_distance.png",
                    "frame time [ms]",
                    (|r: &Row| r.frame_s * 1e3) as fn(&Row) -> f64,
                    "Runtime along the distance path (E Fig. 5.4).",
                ),
                (
                    "accuracy_distance.png",
                    "FLIP mean",
                    |r: &Row| r.accuracy.flip_mean,
                    "FLIP mean along the distance path.",
                ),
                (
                    "coverage_distance.png",
                    "coverage error",
                    |r: &Row| r.accuracy.coverage_error,
                    "Coverage error along the distance path.",
                ),
            ] {
                let series = group(&all, &y, &|r| r.distance_m as f64, true);
                let axes = Axes::linear(
                    format!("{}: {ylabel} vs distance", spec.name),
                    "camera distance from the forest centre [m]",
                    ylabel,
                );
                plot(name, cap.into(), &|p| {
                    xy_plot(p, &axes, &series, Style::Lines)
                })?;
            }
        }
        param => {
            let numeric = sets.iter().all(|s| s.x.is_some());
            if numeric {
                let x = |r: &Row| {
                    x_by_label
                        .get(&r.setting)
                        .copied()
                        .flatten()
                        .unwrap_or(f64::NAN)
                };
                let log_x = {
                    let xs: Vec<f64> = sets.iter().filter_map(|s| s.x).collect();
                    let (lo, hi) = xs
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
                    lo > 0.0 && hi / lo > 20.0
                };
                // Select and draw time, then the errors, against the parameter (E Fig. 5.5a / 5.6).
                type Metric = (&'static str, fn(&Row) -> f64);
                let times: [Metric; 3] = [
                    ("select", |r| r.select_s * 1e3),
                    ("draw", |r| r.draw_s * 1e3),
                    ("frame", |r| r.frame_s * 1e3),
                ];
                let errors: [Metric; 3] = [
                    ("FLIP mean", |r| r.accuracy.flip_mean),
                    ("FLIP p95", |r| r.accuracy.flip_p95),
                    ("coverage err", |r| r.accuracy.coverage_error),
                ];
                for (file, title, y_label, caption, metrics) in [
                    (
                        "runtime.png",
                        "mean pass times",
                        "mean time [ms]",
                        format!(
                            "Mean select, draw and frame time against `{param}` (thesis-style, E Fig. 5.5–5.6)."
                        ),
                        times,
                    ),
                    (
                        "accuracy.png",
                        "accuracy",
                        "error vs ground truth",
                        format!("Mean FLIP, FLIP p95 and coverage error against `{param}`."),
                        errors,
                    ),
                ] {
                    let mut series = Vec::new();
                    for (what, y) in metrics {
                        for mut s in group(&all, &y, &x, true) {
                            s.label = format!("{what} {}", s.label);
                            series.push(s);
                        }
                    }
                    let axes = Axes {
                        title: format!("{}: {title} vs {param}", spec.name),
                        x_label: format!("{param}{}", if log_x { " (log)" } else { "" }),
                        y_label: y_label.into(),
                        log_x,
                        log_y: false,
                    };
                    plot(file, caption, &|p| xy_plot(p, &axes, &series, Style::Lines))?;
                }
            } else {
                // Categorical settings: grouped bars (E Fig. 5.7).
                let labels: Vec<String> = sets.iter().map(|s| s.label.clone()).collect();
                let by_setting =
                    |l: &String| -> Vec<&Row> { rows.iter().filter(|r| &r.setting == l).collect() };
                let passes = group_means(&labels, &PASS_MS, by_setting);
                let axes = Axes::linear(
                    format!("{}: mean pass times", spec.name),
                    "setting",
                    "mean time [ms]",
                );
                plot(
                    "runtime.png",
                    "Mean select and draw time per setting (thesis-style, E Fig. 5.7).".into(),
                    &|p| {
                        bar_plot(
                            p,
                            &axes,
                            &labels,
                            &["select".into(), "draw".into()],
                            &passes,
                        )
                    },
                )?;
                let acc = group_means(
                    &labels,
                    &[
                        |r| r.accuracy.flip_mean,
                        |r| r.accuracy.flip_p95,
                        |r| r.accuracy.coverage_error,
                    ],
                    by_setting,
                );
                let axes = Axes::linear(
                    format!("{}: accuracy per setting", spec.name),
                    "setting",
                    "error vs ground truth",
                );
                plot(
                    "accuracy.png",
                    "Mean FLIP, FLIP p95 and coverage error per setting.".into(),
                    &|p| {
                        bar_plot(
                            p,
                            &axes,
                            &labels,
                            &["FLIP mean".into(), "FLIP p95".into(), "coverage err".into()],
                            &acc,
                        )
                    },
                )?;
                // The temporal error per setting, one bar per camera path that scored one
                // (issue 30: the blends differ in motion, not in a still frame).
                let mut paths: Vec<String> = Vec::new();
                for r in rows.iter().filter(|r| r.temporal_mean.is_some()) {
                    if !paths.contains(&r.camera) {
                        paths.push(r.camera.clone());
                    }
                }
                if !paths.is_empty() {
                    let temporal: Vec<Vec<f64>> = labels
                        .iter()
                        .map(|l| {
                            paths
                                .iter()
                                .map(|c| {
                                    mean(
                                        rows.iter()
                                            .filter(|r| &r.setting == l && &r.camera == c)
                                            .filter_map(|r| r.temporal_mean),
                                    )
                                })
                                .collect()
                        })
                        .collect();
                    let axes = Axes::linear(
                        format!("{}: temporal error per setting", spec.name),
                        "setting",
                        "mean temporal error",
                    );
                    plot(
                        "temporal.png",
                        "Mean temporal error per setting, one bar per camera path (the report \
                         gives its 95% intervals and the paired differences)."
                            .into(),
                        &|p| bar_plot(p, &axes, &labels, &paths, &temporal),
                    )?;
                }
            }
        }
    }
    // 3. Issue 30: the billboards' own LOD error against billboard memory, where the sweep varies
    // the billboard views (azimuths J or elevations K).
    if let Some((name, caption, series)) = billboard_memory_series(rows) {
        let axes = Axes {
            title: format!("{}: billboard LOD error vs memory", spec.name),
            x_label: "memory beside E Eq. 4.1 [MB] (billboards: K x J or N^2 layers x r^2 x 5.3 B a mesh)".into(),
            y_label: "LOD error in the billboard region".into(),
            log_x: true,
            log_y: false,
        };
        plot(name, caption, &|p| {
            crate::plot::interval_plot(p, &axes, &series)
        })?;
    }
    out.extend(trade);
    Ok(out)
}

/// The series of the billboard-memory plot (issue 30), when the rows' parameter sets differ in
/// their billboard views (`azimuth_count` or `angle_count`) and some frame shows billboards: one
/// series per camera, backend, azimuth count and azimuth rule, its points the elevation counts,
/// each at its mean memory and its mean LOD error over the billboard region
/// (`lod_flip_billboard`) with a 95 % interval over the frames that have one.
fn billboard_memory_series(
    rows: &[Row],
) -> Option<(&'static str, String, Vec<crate::plot::IntervalSeries>)> {
    use crate::plot::{IntervalPoint, IntervalSeries, PALETTE};
    let views = |r: &Row| {
        let p = &r.params;
        (
            p.angle_count,
            p.azimuth_count,
            p.billboard_views,
            p.octahedral_grid,
            p.texture_size,
            p.octahedral_depth,
        )
    };
    let first = rows.first().map(views)?;
    if rows.iter().all(|r| views(r) == first)
        || !rows
            .iter()
            .any(|r| r.accuracy.lod_flip_billboard.is_finite())
    {
        return None;
    }
    let mut order: Vec<String> = Vec::new();
    let mut points: BTreeMap<(String, u32), Vec<&Row>> = BTreeMap::new();
    for r in rows {
        let p = &r.params;
        let name = |id: u32| forestlod_shared::AzimuthMode::from_id(id).map_or("?", |m| m.name());
        // Octahedral impostors (issue 32): one line per map, rule and texture side, its points
        // the grid sides N; elevation views: one line per J, rule and side, its points K.
        let (label, point) = match forestlod_shared::ViewSphere::from_id(p.billboard_views) {
            Some(v) if v.is_octahedral() => (
                format!(
                    "{} {} {} {}{} r{}",
                    r.camera,
                    r.backend,
                    // Short, so the legend does not cut the rule and the side.
                    if v == forestlod_shared::ViewSphere::HemiOctahedral {
                        "hemi"
                    } else {
                        "octa"
                    },
                    name(p.octahedral_blend),
                    // The depth channel (issue 32).
                    if forestlod_shared::depth_channel(p) {
                        "+depth"
                    } else {
                        ""
                    },
                    p.texture_size
                ),
                p.octahedral_grid,
            ),
            _ => (
                format!(
                    "{} {} J{} {} r{}",
                    r.camera,
                    r.backend,
                    p.azimuth_count,
                    name(p.azimuth_mode),
                    p.texture_size
                ),
                p.angle_count,
            ),
        };
        if !order.contains(&label) {
            order.push(label.clone());
        }
        points.entry((label, point)).or_default().push(r);
    }
    let series = order
        .iter()
        .enumerate()
        .map(|(i, label)| IntervalSeries {
            label: label.clone(),
            points: points
                .iter()
                .filter(|((l, _), _)| l == label)
                .map(|(_, rs)| {
                    let errors: Vec<f64> = rs
                        .iter()
                        .map(|r| r.accuracy.lod_flip_billboard)
                        .filter(|e| e.is_finite())
                        .collect();
                    let (y, y_half) = crate::report::mean_ci(&errors);
                    IntervalPoint {
                        x: mean(rs.iter().map(|r| r.memory_bytes as f64 / 1e6)),
                        x_half: 0.0,
                        y,
                        y_half,
                    }
                })
                .collect(),
            line: true,
            markers: true,
            colour: PALETTE[i % PALETTE.len()],
            shape: i / PALETTE.len(),
            tag: String::new(),
        })
        .collect();
    Some((
        "billboard_memory.png",
        "The billboards' own LOD error (mean FLIP against the full-detail frame over the pixels \
         drawn as billboards, 95 % intervals over frames) against memory beside E Eq. 4.1, one \
         line per camera, backend, azimuth count J, rule and texture side, its points the \
         elevation counts K (issue 30); octahedral impostors one line per map, rule and side, \
         their points the grid sides N (issue 32)."
            .into(),
        series,
    ))
}
