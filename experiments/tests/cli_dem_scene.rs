//! A user scene with a GeoTIFF elevation model and a named-column CSV inventory through the main
//! job (issue 34, "must be true on main"): `forestlod render --scene forest.toml` renders it on
//! the reference and, where an adapter exists (lavapipe in CI), on the GPU, and ends with the
//! parity verdict (`GPU parity PASSED`, exit 0); the DEM's report (a tree whose z disagrees with
//! it) goes to stderr.

use std::path::{Path, PathBuf};
use std::process::Command;

use forestlod_reference::scene::load::geotiff_writer::{GeoTiffSpec, SampleKind, write_geotiff};

#[path = "../../reference/tests/common/mod.rs"]
mod common;

/// A 200 m x 160 m DEM at 4 m (a ridge of 30 m relief) over UTM coordinates, 12 trees of an
/// inventory with its own column names, one of them 8 m above the DEM.
fn write_scene(dir: &Path) -> PathBuf {
    let (w, h, d) = (51u32, 41u32, 4.0);
    let corner = [512_000.0, 5_402_000.0];
    let samples: Vec<f64> = (0..h)
        .flat_map(|r| {
            (0..w).map(move |c| {
                let (x, y) = (f64::from(c) / f64::from(w), f64::from(r) / f64::from(h));
                420.0 + 30.0 * (x * 3.1).sin() * (1.0 - y) + 5.0 * y
            })
        })
        .collect();
    let spec = GeoTiffSpec::new(w, h, samples, SampleKind::F32, corner, d);
    common::write(dir, "dem.tif", write_geotiff(&spec, 1, &|b| b.to_vec()));
    let mut csv = String::from("id,East,North,Elev,Height_m,Baumart\n");
    for k in 0..12 {
        let (e, n) = (
            corner[0] + 40.0 + f64::from(k % 4) * 30.0,
            corner[1] - 40.0 - f64::from(k / 4) * 30.0,
        );
        let z = if k == 5 {
            "470".to_string()
        } else {
            String::new()
        };
        let sp = ["Fichte", "Kiefer", "Buche"][k as usize % 3];
        csv += &format!("{k},{e},{n},{z},{},{sp}\n", 14.0 + f64::from(k));
    }
    common::write(dir, "plot.csv", csv);
    common::write(
        dir,
        "forest.toml",
        r#"instances = "plot.csv"
[terrain]
kind = "dem"
file = "dem.tif"
[columns]
x = "East"
y = "North"
z = "Elev"
height = "Height_m"
species = "Baumart"
[species_names]
Fichte = "spruce"
Kiefer = "pine"
Buche = "oak"
"#,
    )
}

#[test]
fn a_dem_scene_renders_on_both_backends_with_a_verdict() {
    let dir = common::fresh_dir("cli-dem", "render");
    let scene = write_scene(&dir);
    let out = dir.join("out");
    let gpu = forestlod_gpu::GpuContext::new().is_ok();
    let mut args = vec![
        "render".to_string(),
        "--scene".into(),
        scene.display().to_string(),
        "--width".into(),
        "96".into(),
        "--height".into(),
        "64".into(),
        // Scene-local metres: the origin is the trees' bounding-box centre (x ±45 m, y ±30 m).
        "--eye=-100,-80,40".into(),
        "--look-at=0,0,-5".into(),
        "--out".into(),
        out.display().to_string(),
    ];
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
        stderr.contains("terrain ") && stderr.contains("1 differ from the DEM"),
        "{stderr}"
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
