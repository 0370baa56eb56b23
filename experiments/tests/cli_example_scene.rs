//! The example scene from real public data (issue 34, item 3) through the main job, on a cut
//! small enough for CI: the Barro Colorado Island census `bei` and its elevation model from
//! Debian's `r-cran-spatstat.data` 3.0-0-1 (`forestlod_experiments::example_data`).
//!
//! The data are GPL-2+ and not committed: the test runs `scripts/fetch-example-data
//! --package-only` (the fetch, the sha256 check and the unpacking; cached under
//! `target/example-data`), and a failed fetch fails the test with the script's message, never a
//! skip. It then pins what the package holds (a misread stream cannot pass), writes the
//! 250 m × 250 m south-western cut of the plot (544 trees, 52 × 52 DEM samples, 23.75 m of relief)
//! and renders it with `forestlod render --scene` on the reference and, where an adapter exists
//! (lavapipe in CI), on the GPU, with a camera and LOD settings whose frame holds meshes, the
//! fade band and billboards; the last line must be the `PASSED` verdict.

use std::path::{Path, PathBuf};
use std::process::Command;

use forestlod_experiments::example_data::{
    DATA_DIR_IN_PACKAGE, PACKAGE_SHA256, SPECIES_NAME, Window, read_bei, write_scene,
};

#[path = "../../reference/tests/common/mod.rs"]
mod common;

/// The CI cut: the plot's south-western 250 m × 250 m.
const CUT: Window = Window([0.0, 0.0, 250.0, 250.0]);

/// Runs the fetch script (fetch, check, unpack; cached) and returns the unpacked package root.
fn fetched_package() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let o = Command::new(root.join("scripts/fetch-example-data"))
        .arg("--package-only")
        .output()
        .expect("run scripts/fetch-example-data");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(
        o.status.success(),
        "the example scene's data could not be fetched (scripts/fetch-example-data, exit {:?}):\n{stderr}",
        o.status.code()
    );
    PathBuf::from(stdout.lines().last().unwrap_or_default().trim())
}

#[test]
fn the_real_example_scene_renders_on_both_backends_with_a_verdict() {
    let package = fetched_package();
    // The script's pinned checksum is the module's (one package, one sha256).
    let stamp = std::fs::read_to_string(package.join(".sha256-ok")).unwrap();
    assert_eq!(stamp.trim(), PACKAGE_SHA256);
    let (census, elev) = read_bei(&package.join(DATA_DIR_IN_PACKAGE)).unwrap();
    // What the package holds (its documentation: 1000 m x 500 m, elevation on a 5 m grid).
    assert_eq!(census.x.len(), 3604);
    assert_eq!(census.window, [0.0, 0.0, 1000.0, 500.0]);
    assert_eq!((census.x[0], census.y[0]), (11.7, 151.1));
    assert_eq!(
        (elev.xcol.len(), elev.yrow.len(), elev.step),
        (201, 101, 5.0)
    );
    assert_eq!(elev.range(), [119.81, 159.48]);
    assert_eq!(elev.at(0, 0), 120.63);

    let dir = common::fresh_dir("cli-example", "bci-cut");
    let w = write_scene(&census, &elev, Some(CUT), &dir).unwrap();
    println!("cut: {w:?}");
    assert_eq!((w.trees, w.dem_size), (544, [52, 52]));
    let csv = std::fs::read_to_string(dir.join("trees.csv")).unwrap();
    assert!(csv.lines().skip(1).all(|l| l.ends_with(SPECIES_NAME)));

    let out = dir.join("out");
    let gpu = forestlod_gpu::GpuContext::new().is_ok();
    let mut args: Vec<String> = [
        "render",
        "--scene",
        &dir.join("bei.toml").display().to_string(),
        "--width",
        "192",
        "--height",
        "108",
        // Scene-local metres: the origin is the trees' bounding-box centre at about 132 m.
        "--eye=-70,-90,60",
        "--look-at=40,40,-10",
        "--fov",
        "50",
        // Batches of 50 m and a near transition: meshes, the fade band and billboards in view.
        "--grid-size",
        "50",
        "--transition",
        "170",
        "--fade-width",
        "50",
        "--out",
        &out.display().to_string(),
    ]
    .map(String::from)
    .to_vec();
    if !gpu {
        args.push("--no-gpu".into());
    }
    let o = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args(&args)
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    );
    println!("{stdout}{stderr}");
    assert_eq!(o.status.code(), Some(0), "{stdout}{stderr}");
    assert!(
        stderr.contains("52x52 samples at 5 x 5 m") && stderr.contains("544 trees on it"),
        "{stderr}"
    );
    let selection = stdout
        .lines()
        .chain(stderr.lines())
        .find(|l| l.starts_with("selection: "))
        .unwrap_or_default();
    assert!(
        !selection.contains("(0 LOD0") && !selection.contains(", 0 LOD1"),
        "the frame should hold both levels: {selection}"
    );
    let last = stdout.lines().last().unwrap_or("");
    if gpu {
        assert!(last.starts_with("GPU parity PASSED: "), "{stdout}");
    } else {
        assert!(
            std::env::var_os(forestlod_gpu::ALLOW_NO_GPU_ENV).is_some(),
            "{}",
            forestlod_gpu::NO_GPU_HINT
        );
    }
}
