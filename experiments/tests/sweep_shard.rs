//! `forestlod sweep --shard I/N` and `forestlod sweep merge` (issue 12): every built-in sweep in
//! quick mode on the reference backend, unsharded and as 3 shards, then merged. The merged CSV
//! must equal the unsharded one row for row in everything but wall-clock times (frame and truth
//! times, which differ between any two runs), the temporal error included (a shard that lacks a
//! path's previous pose renders it again), and the merge must refuse an incomplete set of
//! shards. Beside it, the runner's reuse of a timed Vegetation frame as the pose's full-detail
//! frame must give the same rows and images as rendering that frame on its own.

use std::path::{Path, PathBuf};

use forestlod_experiments::report::read_rows;
use forestlod_experiments::sweep::shard::Shard;
use forestlod_experiments::sweep::{
    BUILTIN_SWEEPS, Manifest, Row, Runner, SweepArgs, SweepSpec, configure, run,
};

fn args(out: &Path, shard: Option<Shard>) -> SweepArgs {
    SweepArgs {
        shard,
        out: out.to_path_buf(),
        quick: true,
        backend: Some("reference".into()),
        ..SweepArgs::default()
    }
}

/// Everything of a row a second run must reproduce (all but the times).
fn deterministic(r: &Row) -> String {
    format!(
        "{} {} {} {} {} {} {} {} {} {:?} {}x{} {:?} | {} {} {} {} {} {} {} {:?} {:?} {:?} {:?} {} | {:?} {:?} | {:?}",
        r.frame,
        r.sweep,
        r.scene,
        r.camera,
        r.yaw_deg,
        r.distance_m,
        r.variant,
        r.backend,
        r.setting,
        r.params,
        r.width,
        r.height,
        r.truth_fraction,
        r.batches_tested,
        r.commands,
        r.trees_drawn,
        r.trees_finer,
        r.trees_coarser,
        r.trees_outside_view,
        r.trees_missing_lod,
        r.triangles,
        r.fragments,
        r.fragments_written,
        r.overdraw,
        r.memory_bytes,
        r.temporal_mean,
        r.temporal_p99,
        r.accuracy
    )
}

fn manifest(dir: &Path) -> Manifest {
    serde_json::from_str(&std::fs::read_to_string(dir.join("sweep.json")).unwrap()).unwrap()
}

#[test]
fn three_merged_shards_equal_the_unsharded_run_row_for_row() {
    let root = std::env::temp_dir().join(format!("forestlod-sweep-shard-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let whole = root.join("whole");
    run(&args(&whole, None)).expect("unsharded run");
    let shard_dirs: Vec<PathBuf> = (0..3).map(|i| root.join(format!("shard-{i}"))).collect();
    for (i, dir) in shard_dirs.iter().enumerate() {
        run(&args(dir, Some(Shard { index: i, count: 3 }))).expect("shard run");
    }
    // An incomplete set is refused, naming the missing shard.
    let mut merge = args(&root.join("partial"), None);
    merge.file = Some("merge".into());
    merge.shards = shard_dirs[..2].to_vec();
    let e = run(&merge).unwrap_err().to_string();
    assert!(e.contains("2/3") && e.contains("missing"), "{e}");
    // Issue 34: every missing index is named.
    merge.shards = shard_dirs[..1].to_vec();
    let e = run(&merge).unwrap_err().to_string();
    assert!(
        e.contains("1/3 2/3") && e.contains("2 shards are missing"),
        "{e}"
    );
    // Issue 34: shards of another build are refused, naming the field.
    let other = root.join("other-build");
    copy_tree(&shard_dirs[2], &other);
    for entry in std::fs::read_dir(&other).unwrap() {
        let m = entry.unwrap().path().join("sweep.json");
        if m.is_file() {
            let mut v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
            v["build"] = serde_json::json!("forestlod 0.0.0 0000000000000000");
            std::fs::write(&m, serde_json::to_string(&v).unwrap()).unwrap();
        }
    }
    merge.shards = vec![shard_dirs[0].clone(), shard_dirs[1].clone(), other];
    let e = run(&merge).unwrap_err().to_string();
    assert!(e.contains("build") && e.contains("one build"), "{e}");
    // Issue 34: `--shard auto` under a Slurm array's variables (task 2 of an array 1-3, so
    // index 1 of 3) runs the frames of the explicit `--shard 1/3`, through the binary.
    let sweep = BUILTIN_SWEEPS
        .iter()
        .map(|(n, _)| *n)
        .find(|n| shard_dirs[1].join(n).join("sweep.json").is_file())
        .unwrap();
    let auto = root.join("auto");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args([
            "sweep",
            sweep,
            "--shard",
            "auto",
            "--quick",
            "--backend",
            "reference",
            "--out",
        ])
        .arg(&auto)
        .env("SLURM_ARRAY_TASK_ID", "2")
        .env("SLURM_ARRAY_TASK_MIN", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ma, me) = (
        manifest(&auto.join(sweep)),
        manifest(&shard_dirs[1].join(sweep)),
    );
    assert_eq!(ma.shard.as_deref(), Some("1/3"));
    let frames = |dir: &Path, m: &Manifest| -> Vec<u64> {
        read_rows(&dir.join(&m.csv))
            .unwrap()
            .iter()
            .map(|r| r.frame)
            .collect()
    };
    assert_eq!(
        frames(&auto.join(sweep), &ma),
        frames(&shard_dirs[1].join(sweep), &me),
        "{sweep}: --shard auto picks the frames of --shard 1/3"
    );

    let merged = root.join("merged");
    merge.out = merged.clone();
    merge.shards = shard_dirs.clone();
    run(&merge).expect("merge");
    let mut compared = 0;
    let mut temporal = 0;
    for (name, _) in BUILTIN_SWEEPS {
        let w = whole.join(name);
        if !w.join("sweep.json").is_file() {
            continue; // GPU-only sweep: nothing to run on the reference backend
        }
        let (mw, mm) = (manifest(&w), manifest(&merged.join(name)));
        let want = read_rows(&w.join(&mw.csv)).unwrap();
        let got = read_rows(&merged.join(name).join(&mm.csv)).unwrap();
        assert_eq!(got.len(), want.len(), "{name}: rows");
        for (i, (g, r)) in got.iter().zip(&want).enumerate() {
            assert_eq!(r.frame, i as u64, "{name}: unsharded frames in order");
            assert_eq!(deterministic(g), deterministic(r), "{name}: row {i}");
        }
        assert_eq!(mm.frames, mw.frames, "{name}");
        assert_eq!(mm.images.len(), mw.images.len(), "{name}: saved frames");
        assert_eq!(mm.plots.len(), mw.plots.len(), "{name}: plots");
        for im in &mm.images {
            assert!(
                merged.join(name).join(&im.color).is_file(),
                "{name}: {}",
                im.color
            );
        }
        // Each shard did a part, not the whole.
        for dir in &shard_dirs {
            let m = manifest(&dir.join(name));
            assert!(
                m.frames < mw.frames || mw.frames <= 1,
                "{name}: shard ran everything"
            );
        }
        compared += want.len();
        temporal += want.iter().filter(|r| r.temporal_mean.is_some()).count();
    }
    assert!(compared > 50, "only {compared} rows compared");
    // Path sweeps' later poses compared their temporal error too (with 3 shards, consecutive
    // units lie in different shards: every one in a shard that does not own the previous pose).
    assert!(temporal > 0, "no temporal error compared");
    std::fs::remove_dir_all(&root).ok();
}

/// Copies the folder `from` to `to`, recursively.
fn copy_tree(from: &Path, to: &Path) {
    for rel in files_under(from) {
        let dst = to.join(&rel);
        std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
        std::fs::copy(from.join(&rel), dst).unwrap();
    }
}

/// Every file under `dir` (recursively), as paths relative to it, sorted.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// The sweeps that time the Vegetation variant on the reference backend, where the runner takes
/// the LOD error's full-detail frame from that timed frame instead of rendering it again: the
/// rows (all but the times) and every saved image must be the same as with a render of its own.
#[test]
fn reusing_the_timed_vegetation_frame_changes_no_row_and_no_image() {
    let root = std::env::temp_dir().join(format!("forestlod-sweep-reuse-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let a = args(&root, None);
    let mut compared = 0;
    for name in ["distance", "camera360"] {
        let (_, text) = BUILTIN_SWEEPS.iter().find(|(n, _)| *n == name).unwrap();
        let spec = configure(SweepSpec::parse(text, name).unwrap(), &a)
            .unwrap()
            .unwrap();
        assert!(
            spec.variants.iter().any(|v| v == "vegetation") && spec.variants.len() > 1,
            "{name}: the reuse needs Vegetation among other variants"
        );
        let (reused, own) = (root.join("reused"), root.join("own"));
        Runner::default()
            .run_sweep(&spec, true, None, &reused)
            .expect("reused");
        Runner::without_full_frame_reuse()
            .run_sweep(&spec, true, None, &own)
            .expect("own renders");
        let (mr, mo) = (manifest(&reused.join(name)), manifest(&own.join(name)));
        let got = read_rows(&reused.join(name).join(&mr.csv)).unwrap();
        let want = read_rows(&own.join(name).join(&mo.csv)).unwrap();
        assert_eq!(got.len(), want.len(), "{name}: rows");
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(deterministic(g), deterministic(w), "{name}: row {i}");
        }
        // Some row has an LOD error to compare (ours differs from the full-detail frame).
        assert!(
            want.iter().any(|r| r.accuracy.lod_flip_mean > 0.0),
            "{name}: no LOD error anywhere"
        );
        let files = files_under(&own.join(name).join("img"));
        assert_eq!(files, files_under(&reused.join(name).join("img")), "{name}");
        assert!(
            files
                .iter()
                .any(|f| f.to_string_lossy().ends_with("_lod_flip.png"))
        );
        for f in &files {
            let (g, w) = (
                std::fs::read(reused.join(name).join("img").join(f)).unwrap(),
                std::fs::read(own.join(name).join("img").join(f)).unwrap(),
            );
            assert!(g == w, "{name}: {} differs", f.display());
        }
        compared += want.len();
    }
    assert!(compared > 10, "only {compared} rows compared");
    std::fs::remove_dir_all(&root).ok();
}
