//! CI smoke test of the temporal measure (`experiments/src/bin/popping.rs`, issue 12) on `tiny`:
//! a short, small dolly through the band for the three fade modes writes its CSV (one row per
//! mode and frame pair, finite scores), plot, worst-pair strips and summary; bad input exits 1.

use std::process::Command;

#[test]
fn a_short_dolly_scores_every_fade_mode() {
    let out = std::env::temp_dir().join(format!("forestlod-popping-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = Command::new(env!("CARGO_BIN_EXE_popping"))
        .args(["--frames", "4", "--width", "128", "--height", "72", "--out"])
        .arg(&out)
        .output()
        .expect("popping runs");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(out.join("popping.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 3 * 3, "3 modes x 3 pairs:\n{csv}");
    for row in &rows {
        for v in row.split(',').skip(2) {
            let v: f64 = v.parse().unwrap();
            assert!(v.is_finite() && v >= 0.0, "{row}");
        }
    }
    use forestlod_shared::FadeMode;
    for mode in [FadeMode::None, FadeMode::DitherSequential, FadeMode::Alpha].map(FadeMode::name) {
        assert!(out.join(format!("worst_{mode}.png")).is_file(), "{mode}");
    }
    assert!(out.join("popping.png").is_file());
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("within the noise") || summary.contains("pops more"));
    std::fs::remove_dir_all(&out).ok();

    let bad = Command::new(env!("CARGO_BIN_EXE_popping"))
        .args(["--modes", "blend", "--out"])
        .arg(std::env::temp_dir())
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--modes") && err.contains("blend"), "{err}");
}
