//! `forestlod export-case` and `forestlod verify` through the binary (issue 15): this project's
//! own GPU frame, written in the case format by `export-case --with-gpu`, passes `verify`; the
//! same frame deliberately broken fails it with exit code 2 naming the class that caught it
//! (a wrong block: the depth-tie gate; a two-step shift of every green value, invisible to the
//! per-pixel tolerance: the bias gate); a missing file is bad input (1) naming the file.
//!
//! Needs a GPU adapter (lavapipe in CI), like the parity tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use forestlod_reference::output::{read_png, write_png};

#[path = "../../reference/tests/common/mod.rs"]
mod common;

fn forestlod(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run forestlod")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn last_line(o: &Output) -> String {
    text(&o.stdout).lines().last().unwrap_or("").to_string()
}

/// Copies the three image files (and the commands) of `from` into a fresh `to`.
fn copy_outputs(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for f in ["color.png", "depth.exr", "lod_id.png", "commands.csv"] {
        std::fs::copy(from.join(f), to.join(f)).unwrap();
    }
}

/// Exports the `tiny` case from `medium` at 96² with this project's GPU frame, once.
fn case() -> PathBuf {
    let dir = common::fresh_dir("cli-verify", "case");
    let o = forestlod(&[
        "export-case",
        "--scene",
        "tiny",
        "--camera",
        "medium",
        "--grid-size",
        "50",
        "--angles",
        "8",
        "--texture-size",
        "32",
        "--transition",
        "400",
        "--fade-width",
        "80",
        "--width",
        "96",
        "--height",
        "96",
        "--with-gpu",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        o.status.success(),
        "export-case failed: {}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    for f in [
        "case.json",
        "instances.csv",
        "reference/color.png",
        "reference/depth.exr",
        "reference/lod_id.png",
        "reference/commands.csv",
        "alternatives/0/color.png",
        "gpu/color.png",
        "gpu/commands.csv",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    dir
}

fn verify(case: &Path, outputs: &Path) -> Output {
    forestlod(&[
        "verify",
        "--case",
        case.to_str().unwrap(),
        "--outputs",
        outputs.to_str().unwrap(),
    ])
}

#[test]
fn own_gpu_output_passes_and_broken_outputs_fail_naming_the_class() {
    let case = case();
    // 1. This project's GPU frame (whole GPU pipeline, atomic selection order) passes.
    let o = verify(&case, &case.join("gpu"));
    let out = text(&o.stdout);
    eprintln!("{out}");
    assert_eq!(o.status.code(), Some(0), "{out}{}", text(&o.stderr));
    assert_eq!(last_line(&o), "parity passed");
    assert!(out.contains("class budgets (count/budget)"), "{out}");
    assert!(out.contains("0 missing, 0 extra"), "{out}");

    // 2. A 10x10 block of the wrong colour in the middle of the frame. Its depth and LOD id are
    //    right, so every pixel looks like a depth tie (a second surface at the same depth); the
    //    depth-tie gate names it: 100 pixels, over 1 % of the 96² frame.
    let broken = case.join("broken-block");
    copy_outputs(&case.join("gpu"), &broken);
    let mut img = read_png(&broken.join("color.png")).unwrap();
    for y in 40..50 {
        for x in 40..50 {
            img.texels[y * 96 + x] = [255, 0, 255, 255];
        }
    }
    write_png(&broken.join("color.png"), &img).unwrap();
    let o = verify(&case, &broken);
    let last = last_line(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stdout));
    assert!(
        last.starts_with("parity FAILED: colour: 100 depth-tie pixels"),
        "{last}"
    );

    // 3. Every green value two steps up: within the per-pixel tolerance everywhere, caught by
    //    the bias gate only.
    let shifted = case.join("broken-shift");
    copy_outputs(&case.join("gpu"), &shifted);
    let reference = read_png(&case.join("reference/color.png")).unwrap();
    let mut img = reference.clone();
    for t in &mut img.texels {
        t[1] = t[1].saturating_add(2);
    }
    write_png(&shifted.join("color.png"), &img).unwrap();
    let o = verify(&case, &shifted);
    let last = last_line(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stdout));
    assert!(
        last.contains("colour channel G: bias per reference value") && !last.contains("colour:"),
        "{last}"
    );

    // 4. A command missing from the implementation's selection: the select stage is named.
    let fewer = case.join("broken-commands");
    copy_outputs(&case.join("gpu"), &fewer);
    let csv = std::fs::read_to_string(fewer.join("commands.csv")).unwrap();
    let kept: Vec<&str> = csv.lines().take(csv.lines().count() - 1).collect();
    std::fs::write(fewer.join("commands.csv"), kept.join("\n") + "\n").unwrap();
    let o = verify(&case, &fewer);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stdout));
    assert!(
        last_line(&o).contains("stage select: the command multisets differ (1 missing, 0 extra)"),
        "{}",
        last_line(&o)
    );

    // 4b. The same commands in another order, as an atomic compaction emits them on a busy
    //     machine: each command's index (`base_vertex >> COMMAND_SHIFT`) is its new position.
    //     Still the same multiset, so parity passes (a comparison that kept the index failed
    //     this: every command missing and extra).
    let reordered = case.join("reordered-commands");
    copy_outputs(&case.join("gpu"), &reordered);
    let csv = std::fs::read_to_string(reordered.join("commands.csv")).unwrap();
    let mut lines = csv.lines();
    let mut out = vec![lines.next().unwrap().to_string()];
    let rows: Vec<&str> = lines.filter(|l| !l.trim().is_empty()).collect();
    assert!(
        rows.len() > 2,
        "too few commands to reorder: {}",
        rows.len()
    );
    for (i, row) in rows.iter().rev().enumerate() {
        let mut f: Vec<i64> = row.split(',').map(|v| v.parse().unwrap()).collect();
        f[3] = ((i as i64) << forestlod_shared::COMMAND_SHIFT)
            | (f[3] & i64::from(forestlod_shared::MAX_MESH_VERTICES - 1));
        out.push(
            f.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(","),
        );
    }
    std::fs::write(reordered.join("commands.csv"), out.join("\n") + "\n").unwrap();
    let o = verify(&case, &reordered);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stdout));
    assert!(
        text(&o.stdout).contains("0 missing, 0 extra"),
        "{}",
        text(&o.stdout)
    );

    // 5. Bad input: a missing file is exit 1 naming it.
    let missing = case.join("missing-depth");
    copy_outputs(&case.join("gpu"), &missing);
    std::fs::remove_file(missing.join("depth.exr")).unwrap();
    let o = verify(&case, &missing);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
    assert!(text(&o.stderr).contains("depth.exr"), "{}", text(&o.stderr));
}

/// No tool ignores the frame's pipeline parameters (issue 27): with a hierarchy's cut, its command
/// order and a non-default fade, `export-case`'s reference commands, its GPU commands (the GPU's
/// own selection stages: the cut, coalesce and front-to-back order) and `select`'s commands are
/// one list, the GPU frame passes `verify`, and the cut differs from the grid's (so the flags
/// reached every path).
#[test]
fn every_tool_path_sees_the_frames_pipeline_parameters() {
    let flags = [
        "--scene",
        "tiny",
        "--camera",
        "medium",
        "--hierarchy",
        "octree",
        "--command-order",
        "front-to-back",
        "--fade-mode",
        "dither",
        "--angles",
        "8",
        "--texture-size",
        "32",
        "--transition",
        "400",
        "--fade-width",
        "80",
    ];
    let dir = common::fresh_dir("cli-verify", "octree-front-to-back");
    let mut args = vec!["export-case"];
    args.extend(flags);
    args.extend(["--width", "96", "--height", "96", "--with-gpu", "--out"]);
    args.push(dir.to_str().unwrap());
    let o = forestlod(&args);
    assert!(
        o.status.success(),
        "export-case: {}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    let reference = std::fs::read_to_string(dir.join("reference/commands.csv")).unwrap();
    let gpu = std::fs::read_to_string(dir.join("gpu/commands.csv")).unwrap();
    assert_eq!(
        gpu, reference,
        "the GPU's selection stages are not the reference's"
    );
    let o = verify(&dir, &dir.join("gpu"));
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    // `select` runs the same stages: the same number of commands.
    let commands = reference.lines().skip(1).filter(|l| !l.is_empty()).count();
    let mut args = vec!["select"];
    args.extend(flags);
    args.extend(["--list", "0"]);
    let o = forestlod(&args);
    assert!(o.status.success(), "select: {}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(
        out.contains(&format!("  commands {commands} (")),
        "select: {out}\nreference {commands} commands"
    );
    // The grid's list differs: the flags changed what every path saw.
    let grid = common::fresh_dir("cli-verify", "grid-same-flags");
    let mut args = vec!["export-case"];
    let flat: Vec<&str> = flags
        .iter()
        .map(|&f| if f == "octree" { "grid" } else { f })
        .collect();
    args.extend(flat);
    args.extend(["--width", "96", "--height", "96", "--out"]);
    args.push(grid.to_str().unwrap());
    let o = forestlod(&args);
    assert!(
        o.status.success(),
        "export-case (grid): {}",
        text(&o.stderr)
    );
    let flat_commands = std::fs::read_to_string(grid.join("reference/commands.csv")).unwrap();
    assert_ne!(
        flat_commands, reference,
        "the hierarchy flag changed nothing"
    );
}
