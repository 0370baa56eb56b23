//! CI smoke test of the whole experiment machinery (SPEC §10): every built-in sweep in quick mode
//! (`forestlod sweep --quick`: the `tiny` scene, small images, few steps), then the report. Each
//! CSV must hold, for every variant the sweep lists, frames with a finite cost figure (frame time
//! and work counters) and a finite accuracy figure (FLIP against the ray-traced ground truth,
//! coverage error), the LOD error and the total error (our frame at the truth's sampling rate),
//! with the truth's cost. The quick tables exercise every measure of issue 12 on `tiny`: sampled
//! truth tiles (`angles_texture`), two resolutions (`mip_mode`) and the four scene-defined camera
//! paths (orbit, dolly, flyover, pan), each of whose frames must show trees, and whose frames
//! after the first carry the temporal error (`temporal_mean`, `temporal_p99`: finite; empty on a
//! path's first pose and on other cameras, never NaN). The report shows, per sweep and scene, the
//! trade plots (cost against LOD error), linked, embedded and with their Pareto front named. No
//! timing is asserted; the quick run's wall time is printed.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use forestlod_experiments::report::{read_rows, replot, write_report};
use forestlod_experiments::sweep::{
    BUILTIN_SWEEPS, Manifest, SweepArgs, SweepSpec, configure, run,
};

#[test]
fn every_builtin_sweep_runs_in_quick_mode_and_reports_cost_and_accuracy() {
    let out = std::env::temp_dir().join(format!("forestlod-sweep-quick-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    // The GPU backend needs an adapter: without one this fails with the install hint, unless the
    // user opted out (FORESTLOD_ALLOW_NO_GPU=1), in which case only the reference backend runs.
    let backend = match forestlod_gpu::gpu_or_explain() {
        Some(_) => None,
        None => Some("reference".to_string()),
    };
    let args = SweepArgs {
        out: out.clone(),
        quick: true,
        backend: backend.clone(),
        ..SweepArgs::default()
    };
    let start = Instant::now();
    run(&args).expect("the quick sweeps run");
    eprintln!(
        "quick sweeps: {:.1} s wall time",
        start.elapsed().as_secs_f64()
    );
    let mut cameras: BTreeMap<String, usize> = BTreeMap::new();
    let mut temporal_rows = 0;
    let mut sizes: BTreeMap<(&str, u32, u32), usize> = BTreeMap::new();
    for (name, text) in BUILTIN_SWEEPS {
        let Some(spec) = configure(SweepSpec::parse(text, name).unwrap(), &args).unwrap() else {
            continue;
        };
        let dir: PathBuf = out.join(name);
        let manifest: Manifest =
            serde_json::from_str(&std::fs::read_to_string(dir.join("sweep.json")).unwrap())
                .unwrap();
        assert!(manifest.quick);
        // The truth's cost is reported per run.
        assert!(
            manifest
                .ground_truth_seconds
                .is_some_and(|s| s.is_finite() && s >= 0.0)
                && manifest.ground_truth_memory_bytes.is_some_and(|b| b > 0)
                && !manifest.ground_truth_layout.is_empty(),
            "{name}: truth cost {:?} {:?} {:?}",
            manifest.ground_truth_seconds,
            manifest.ground_truth_memory_bytes,
            manifest.ground_truth_layout
        );
        for (plot, _) in &manifest.plots {
            assert!(dir.join(plot).is_file(), "{name}: plot {plot} missing");
        }
        for im in &manifest.images {
            for p in [&im.color, &im.lod, &im.flip, &im.lod_flip, &im.ground_truth] {
                assert!(dir.join(p).is_file(), "{name}: image {p} missing");
            }
            // Ours splits both error maps by LOD class, with the same classes.
            assert_eq!(
                im.per_lod.len(),
                im.per_lod_lod_error.len(),
                "{name}: per-LOD maps of {}",
                im.variant
            );
            for (_, p, mean, _) in &im.per_lod_lod_error {
                assert!(dir.join(p).is_file() && mean.is_finite(), "{name}: {p}");
            }
            // The total error's map, and ours split by LOD class too (where the sweep measures
            // it: `total_error = false` skips it, and then no map is written).
            if spec.total_error {
                assert!(dir.join(&im.total_flip).is_file(), "{name}: total map");
                assert_eq!(
                    im.per_lod_total.is_empty(),
                    im.per_lod.is_empty(),
                    "{name}: per-LOD total maps of {}",
                    im.variant
                );
            } else {
                assert!(im.per_lod_total.is_empty(), "{name}: total maps written");
            }
            for (_, p, mean, _) in &im.per_lod_total {
                assert!(dir.join(p).is_file() && mean.is_finite(), "{name}: {p}");
            }
        }
        if name == "angles_texture" {
            assert!(
                spec.truth_tiles.is_some(),
                "the quick run samples truth tiles"
            );
        }
        let rows = read_rows(&dir.join(&manifest.csv)).unwrap();
        temporal_rows += check_temporal_columns(name, &dir.join(&manifest.csv), &rows);
        let mut per_variant: BTreeMap<(&str, &str), usize> = BTreeMap::new();
        for r in &rows {
            let cost = [r.select_s, r.draw_s, r.frame_s];
            let total = [
                r.accuracy.total_flip_mean,
                r.accuracy.total_flip_p99,
                r.accuracy.total_coverage_error,
            ];
            let mut acc = vec![
                r.accuracy.flip_mean,
                r.accuracy.flip_p95,
                r.accuracy.flip_p99,
                r.accuracy.coverage_error,
                r.accuracy.lod_flip_mean,
                r.accuracy.lod_flip_p99,
                r.accuracy.lod_changed,
            ];
            if spec.total_error {
                acc.extend(total);
            } else {
                // Not measured: NaN in the CSV (and `null` in sweep.json), never a made-up 0.
                assert!(
                    total.iter().all(|v| v.is_nan()),
                    "{name}: total error {total:?} with total_error = false"
                );
            }
            assert!(
                cost.iter().all(|v| v.is_finite() && *v >= 0.0) && r.frame_s > 0.0,
                "{name}: cost figures of {} {} {}: {cost:?}",
                r.variant,
                r.camera,
                r.setting
            );
            assert!(
                acc.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
                "{name}: accuracy figures of {} {} {}: {acc:?}",
                r.variant,
                r.camera,
                r.setting
            );
            // The reference counts fragments; the GPU backend does not.
            assert_eq!(
                r.overdraw.is_some(),
                r.backend == "reference",
                "{name}: overdraw of {} on {}",
                r.variant,
                r.backend
            );
            assert!(r.overdraw.is_none_or(|o| o.is_finite() && o >= 0.0));
            // Points drawn (issue 33): ours on the reference only; the GPU and the baselines
            // leave the cell empty.
            assert_eq!(
                r.points_drawn.is_some(),
                r.backend == "reference" && r.variant == "ours",
                "{name}: points_drawn of {} on {}",
                r.variant,
                r.backend
            );
            if r.params.lod1 == forestlod_shared::points::Lod1::Billboard as u32 {
                assert_eq!(
                    r.points_drawn.unwrap_or(0),
                    0,
                    "{name}: points under billboards"
                );
            }
            // The LOD error's reference is the full-detail frame, which the Vegetation baseline
            // is: its LOD error is exactly zero, on either backend.
            if r.variant == "vegetation" {
                assert_eq!(
                    (r.accuracy.lod_flip_mean, r.accuracy.lod_changed),
                    (0.0, 0.0),
                    "{name}: Vegetation's LOD error on {}",
                    r.backend
                );
            }
            // The truth: its time, and where it was traced: a quarter of the 16x16 tiles in
            // angles_texture's quick run (3 of 12); the full frame elsewhere (the files' 80x80
            // tiles do not fit a 64x48 frame, which is then traced whole).
            assert!(
                r.truth_s.is_some_and(|s| s.is_finite() && s >= 0.0),
                "{name}"
            );
            let want = if name == "angles_texture" { 0.25 } else { 1.0 };
            assert_eq!(r.truth_fraction, Some(want), "{name}: truth fraction");
            // Scene-defined paths look at trees in every frame.
            if forestlod_experiments::sweep::paths::is_path(&r.camera) {
                assert!(
                    r.accuracy.gt_tree_fraction > 0.0,
                    "{name}: {} frame at yaw {} / {} m shows no tree",
                    r.camera,
                    r.yaw_deg,
                    r.distance_m
                );
                *cameras.entry(r.camera.clone()).or_default() += 1;
            }
            *sizes.entry((name, r.width, r.height)).or_default() += 1;
            // Conservative selection: no tree misses a LOD the per-tree oracle gives it. Except
            // under hierarchical impostors (issue 33 item 2, C§4.6.3): an impostor replaces its
            // node's trees whatever their LOD, so a tree that would be a mesh may be drawn inside
            // one (the row counts such trees there).
            let impostors = r.params.lod_levels >= 3
                && r.params.far_lod == forestlod_shared::FarLod::Impostor as u32;
            if !impostors {
                assert_eq!(r.trees_missing_lod, 0, "{name}: {} {}", r.variant, r.camera);
            }
            *per_variant
                .entry((r.variant.as_str(), r.backend.as_str()))
                .or_default() += 1;
        }
        // A point sweep's reference rows count the points they drew.
        if name == "points" {
            assert!(
                rows.iter().any(|r| r.points_drawn.is_some_and(|p| p > 0)),
                "{name}: no row drew a point"
            );
        }
        // Ours on the GPU reports the work counters of the reference's selection of the same
        // frame (`render_gpu_variant`, computed once per frame): they must equal the reference
        // row's, where the sweep runs ours on both backends.
        let mut gpu_checked = 0;
        for g in rows
            .iter()
            .filter(|r| r.backend == "gpu" && r.variant == "ours")
        {
            let same = |r: &&forestlod_experiments::sweep::Row| {
                r.backend == "reference"
                    && (&r.camera, r.yaw_deg, r.distance_m, &r.variant, &r.setting)
                        == (&g.camera, g.yaw_deg, g.distance_m, &g.variant, &g.setting)
            };
            let Some(r) = rows.iter().find(same) else {
                continue;
            };
            let counters = |r: &forestlod_experiments::sweep::Row| {
                (
                    r.batches_tested,
                    r.trees_drawn,
                    r.trees_finer,
                    r.trees_coarser,
                    r.trees_outside_view,
                    r.memory_bytes,
                )
            };
            assert_eq!(
                counters(g),
                counters(r),
                "{name}: GPU counters at {}",
                g.camera
            );
            gpu_checked += 1;
        }
        if backend.is_none() && spec.backends.len() == 2 && spec.variants.contains(&"ours".into()) {
            assert!(gpu_checked > 0, "{name}: no GPU row of ours compared");
        }
        for b in &spec.backends {
            for v in &spec.variants {
                assert!(
                    per_variant
                        .get(&(v.as_str(), b.as_str()))
                        .copied()
                        .unwrap_or(0)
                        > 0,
                    "{name}: no frame of variant {v} on backend {b}"
                );
            }
        }
    }
    assert!(temporal_rows > 0, "no quick sweep scored a temporal error");
    for path in ["orbit", "dolly", "flyover", "pan"] {
        assert!(
            cameras.contains_key(path),
            "no quick sweep ran the {path} path"
        );
    }
    // Resolution is an axis: mip_mode's quick run has two frame sizes.
    assert!(sizes.contains_key(&("mip_mode", 64, 48)) && sizes.contains_key(&("mip_mode", 48, 32)));
    // Plots can be redrawn from the CSVs alone (`forestlod report --replot`).
    let sweeps = std::fs::read_dir(&out)
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().join("sweep.json").is_file())
        .count();
    assert_eq!(replot(&out).expect("the plots are redrawn"), sweeps);
    let report = write_report(&out).expect("the report is written");
    let text = std::fs::read_to_string(&report).unwrap();
    // The HTML twin embeds every image: nothing points outside the page.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        html.contains("src=\"data:image/png;base64,"),
        "report.html embeds images"
    );
    assert!(!html.contains("missing image"), "report.html lost an image");
    for (name, _) in BUILTIN_SWEEPS {
        if !out.join(name).join("sweep.json").is_file() {
            continue; // GPU-only sweep with the GPU opted out
        }
        assert!(text.contains(&format!("`{name}`")), "report lacks {name}");
        check_trade_plots(name, &out, &text, &html);
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// The temporal error (issue 29) of sweep `name`: the CSV has the `temporal_mean` and
/// `temporal_p99` columns, whose cells are empty or finite (never `NaN`); in the rows, a camera
/// path's frames after its first have both, finite and in `[0, 1]` (Vegetation's exactly 0: its
/// frames are the full-detail frames), and its first frame and every other camera's have neither.
/// Returns how many rows have one.
fn check_temporal_columns(
    name: &str,
    csv_path: &std::path::Path,
    rows: &[forestlod_experiments::sweep::Row],
) -> usize {
    let mut reader = csv::Reader::from_path(csv_path).unwrap();
    let headers = reader.headers().unwrap().clone();
    let column = |c: &str| {
        headers
            .iter()
            .position(|h| h == c)
            .unwrap_or_else(|| panic!("{name}: no column {c} in {headers:?}"))
    };
    let columns = [column("temporal_mean"), column("temporal_p99")];
    for record in reader.records() {
        let record = record.unwrap();
        for &c in &columns {
            let cell = &record[c];
            assert!(
                cell.is_empty() || cell.parse::<f64>().is_ok_and(f64::is_finite),
                "{name}: temporal cell {cell:?} is neither empty nor finite"
            );
        }
    }
    // Frames of one path, setting, variant and backend, in the CSV's (pose) order.
    let mut seen: BTreeMap<(&str, &str, &str, &str, &str), usize> = BTreeMap::new();
    let mut scored = 0;
    for r in rows {
        let key = (
            r.scene.as_str(),
            r.camera.as_str(),
            r.setting.as_str(),
            r.variant.as_str(),
            r.backend.as_str(),
        );
        let step = seen.entry(key).or_default();
        let pair = (r.temporal_mean, r.temporal_p99);
        let at = format!(
            "{name}: {} {} {} {} step {step}",
            r.camera, r.setting, r.variant, r.backend
        );
        if forestlod_experiments::sweep::paths::is_path(&r.camera) && *step > 0 {
            let (Some(mean), Some(p99)) = pair else {
                panic!("{at}: no temporal error {pair:?}");
            };
            assert!(
                [mean, p99]
                    .iter()
                    .all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
                "{at}: {pair:?}"
            );
            if r.variant == "vegetation" {
                assert_eq!((mean, p99), (0.0, 0.0), "{at}");
            }
            scored += 1;
        } else {
            assert_eq!(pair, (None, None), "{at}: a first pose or no path");
        }
        *step += 1;
    }
    scored
}

/// The trade as a curve (issues 29, 35) in the report of sweep `name`: its manifest lists a
/// `trade_*` plot (PNG, with its SVG twin) per scene, camera, cost and error, each linked from
/// `report.md` (`text`) and embedded in `report.html` (`html`, as its SVG), and the report names every group
/// of its Pareto front; the index links each view's headline plot and the sweep's page.
fn check_trade_plots(name: &str, out: &std::path::Path, text: &str, html: &str) {
    use forestlod_experiments::html::escape_markdown;
    use forestlod_experiments::report::trade::{fronts, plot_name, plots, trade_points, views};
    let dir = out.join(name);
    let manifest: Manifest =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sweep.json")).unwrap()).unwrap();
    let rows = read_rows(&dir.join(&manifest.csv)).unwrap();
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(
        text.contains("### The trade: cost against error"),
        "{name}: no trade section"
    );
    assert!(
        index.contains(&format!("href=\"sweep-{name}.html\"")),
        "{name}: the index does not link its page"
    );
    assert!(out.join(format!("sweep-{name}.html")).is_file());
    let mut count = 0;
    for view in views(&rows) {
        let points = trade_points(&rows, &view.scene, &view.camera);
        for (k, (cost, error)) in plots(&points).into_iter().enumerate() {
            let fronts = fronts(&points, cost, error);
            assert!(!fronts.is_empty());
            let plot = plot_name(&view.stem, cost, error);
            let listed = manifest.plots.iter().find(|(p, _)| *p == plot);
            let (_, caption) = listed.unwrap_or_else(|| panic!("{name}: {plot} not listed"));
            assert!(dir.join(&plot).is_file(), "{name}: {plot} missing");
            assert!(
                dir.join(&plot).with_extension("svg").is_file(),
                "{name}: {plot}'s SVG missing"
            );
            let path = format!("{name}/{plot}");
            assert!(
                text.contains(&format!("]({path})")),
                "{name}: {plot} not linked"
            );
            // The self-contained page embeds the SVG twin (issue 35).
            let svg = format!(
                "{name}/{}",
                std::path::Path::new(&plot).with_extension("svg").display()
            );
            assert!(
                html.contains(&format!(
                    "title=\"{svg}\" loading=\"lazy\" src=\"data:image/svg+xml;base64,"
                )),
                "{name}: {plot} not embedded"
            );
            if k == 0 {
                assert!(
                    index.contains(&format!("src=\"{path}\"")),
                    "{name}: headline plot {plot} not on the index"
                );
            }
            for (backend, front) in &fronts {
                assert!(
                    caption.contains(&format!("Pareto front ({backend}): ")),
                    "{name}: {caption}"
                );
                for &i in front {
                    let group = &points[i].group;
                    assert!(
                        caption.contains(group.as_str()),
                        "{name}: {group} not in {caption}"
                    );
                    assert!(
                        text.contains(&format!("| **{}** | {} |", escape_markdown(group), backend)),
                        "{name}: front group {group} not named in the report"
                    );
                }
            }
            count += 1;
        }
    }
    assert!(count > 0, "{name}: no trade plot");
}
