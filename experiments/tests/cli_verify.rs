//! `forestlod export-case` and `forestlod verify` through the binary (issue 15): this project's
//! own GPU frame, written in the case format by `export-case --with-gpu`, passes `verify`; the
//! same frame deliberately broken fails it with exit code 2 naming the class that caught it
//! (a wrong block: the depth-tie gate; a two-step shift of every green value, invisible to the
//! per-pixel tolerance: the bias gate); a missing file is bad input (1) naming the file.
//!
//! Needs a GPU adapter (lavapipe in CI), like the parity tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use forestlod_experiments::case::commands_csv;
use forestlod_reference::output::{read_png, write_png};
use forestlod_shared::{Camera, FramePlan, Hierarchy, Params, TreeCull};

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
/// reached every path). With `--tree-cull` too, the reference commands are the ones `render`
/// draws (refined: not the selection before `refine`), `verify` names `refine` when they differ,
/// and `check` replays the cut of these flags, naming its stages; `check`'s random cases include
/// hierarchies.
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

    let mut refined_flags = flags.to_vec();
    refined_flags.extend(["--tree-cull", "lod0"]);
    tree_cull_reaches_export_case_and_verify(&refined_flags);
    check_covers_the_plan(&flags, &dir);
}

/// The scene, parameters and 96² camera `export-case` builds from `flags`, parsed by the same
/// argument structs.
fn frame_of(flags: &[&str]) -> (forestlod_reference::pipeline::Prepared, Camera, Params) {
    #[derive(clap::Parser)]
    struct Args {
        #[command(flatten)]
        scene: forestlod_experiments::options::SceneArgs,
        #[command(flatten)]
        params: forestlod_experiments::options::ParamArgs,
        #[command(flatten)]
        camera: forestlod_experiments::camera::CameraArgs,
    }
    let args = <Args as clap::Parser>::try_parse_from(std::iter::once("x").chain(flags.to_vec()))
        .expect("the test's flags parse");
    let params = args.params.params().unwrap();
    let scene = args.scene.load().unwrap();
    let camera = args.camera.camera(&scene, 96, 96).unwrap();
    let prepared = forestlod_reference::pipeline::prepare(scene, &params).unwrap();
    (prepared, camera, params)
}

/// `export-case` with `--tree-cull` (not `none`): `reference/commands.csv` is what `render` draws
/// (the frame's commands after `refine`), which differ from the selection before `refine` (so the
/// flag changed the commands); `verify` passes the reference's own outputs and the GPU frame's
/// (`--with-gpu`: refined by `refine.wgsl`), and names `refine` for the unrefined commands.
fn tree_cull_reaches_export_case_and_verify(flags: &[&str]) {
    let dir = common::fresh_dir("cli-verify", "octree-tree-cull");
    let mut args = vec!["export-case"];
    args.extend(flags);
    args.extend(["--width", "96", "--height", "96", "--with-gpu", "--out"]);
    args.push(dir.to_str().unwrap());
    let o = forestlod(&args);
    assert!(
        o.status.success(),
        "export-case --tree-cull: {}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    let reference = std::fs::read_to_string(dir.join("reference/commands.csv")).unwrap();
    let (prepared, camera, params) = frame_of(flags);
    assert_ne!(params.tree_cull, TreeCull::None as u32, "{flags:?}");
    let frame = prepared.render(&camera, &params).unwrap();
    assert!(frame.refined.is_some(), "render ran refine");
    let drawn = commands_csv(&frame.selection.commands, &frame.selection.data);
    let first_difference = reference
        .lines()
        .zip(drawn.lines())
        .position(|(a, b)| a != b);
    assert!(
        reference == drawn,
        "export-case's reference commands are not the ones render draws: {} lines against {}, \
         first difference at line {first_difference:?}",
        reference.lines().count(),
        drawn.lines().count()
    );
    let unrefined = prepared.select(&camera, &params);
    let unrefined = commands_csv(&unrefined.commands, &unrefined.data);
    assert_ne!(
        unrefined, drawn,
        "refine changed no command: the case cannot tell the refined commands from the selection's"
    );
    // The reference's own outputs pass, and so does this project's GPU frame (its commands the
    // frame's after `refine.wgsl`); with the unrefined commands, `refine` is named.
    for outputs in ["reference", "gpu"] {
        let o = verify(&dir, &dir.join(outputs));
        assert_eq!(
            o.status.code(),
            Some(0),
            "{outputs}: {}{}",
            text(&o.stdout),
            text(&o.stderr)
        );
    }
    let before = dir.join("unrefined");
    copy_outputs(&dir.join("reference"), &before);
    std::fs::write(before.join("commands.csv"), unrefined).unwrap();
    let o = verify(&dir, &before);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stdout));
    assert!(
        last_line(&o).contains("stage refine: the command multisets differ"),
        "{}",
        last_line(&o)
    );
}

/// `forestlod check` sees the plan: a case of `flags`' trees, camera and hierarchy replays through
/// the cut's stages (named in its verdict), passing, and failing with the broken-comparison hook
/// (so the cut's commands are compared); its random cases include hierarchies.
fn check_covers_the_plan(flags: &[&str], case: &Path) {
    let (_, camera, params) = frame_of(flags);
    let hierarchy = params.hierarchy_mode().unwrap();
    assert!(hierarchy.is_hierarchical(), "{flags:?}");
    let dir = common::fresh_dir("cli-verify", "check-replay");
    std::fs::copy(case.join("instances.csv"), dir.join("trees.csv")).unwrap();
    let v3 = |v: [f32; 3]| format!("[{}, {}, {}]", v[0], v[1], v[2]);
    let mut toml = format!(
        "[camera]\neye = {}\nforward = {}\nup = {}\nfov_y = {}\nnear = {}\nfar = {}\n\
         width = {}\nheight = {}\n\n[params]\n",
        v3(camera.eye),
        v3(camera.forward),
        v3(camera.up),
        camera.fov_y,
        camera.near,
        camera.far,
        camera.width,
        camera.height
    );
    for spec in forestlod_shared::PARAMS {
        let v = spec.format(&params);
        toml += &match spec.kind {
            forestlod_shared::ParamKind::Choice(_) => format!("{} = \"{v}\"\n", spec.name),
            _ => format!("{} = {v}\n", spec.name),
        };
    }
    std::fs::write(dir.join("case.toml"), toml).unwrap();
    let replay = |broken: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_forestlod"));
        c.args(["check", "--replay", dir.to_str().unwrap()])
            .env("RUST_BACKTRACE", "0");
        if broken {
            c.env("FORESTLOD_CHECK_BREAK", "drop-last-command");
        } else {
            c.env_remove("FORESTLOD_CHECK_BREAK");
        }
        c.output().expect("run forestlod")
    };
    let plan = FramePlan::new(&params).unwrap();
    let stages: Vec<&str> = plan.selection_stages().iter().map(|s| s.name()).collect();
    let ran = format!("({} over {})", stages.join(", "), hierarchy.name());
    let o = replay(false);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    assert!(
        text(&o.stdout).contains(&format!("{ran}: passed")),
        "check --replay did not run the cut {ran}: {}",
        text(&o.stdout)
    );
    let o = replay(true);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stdout));
    assert!(
        text(&o.stdout).contains(&format!("{ran}: FAILED")),
        "{}",
        text(&o.stdout)
    );
    // Random cases: some cut a hierarchy.
    let out = common::fresh_dir("cli-verify", "check-cases");
    let o = forestlod(&["check", "--cases", "8", "--out", out.to_str().unwrap()]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    let stdout = text(&o.stdout);
    let plans = stdout
        .lines()
        .find_map(|l| l.strip_prefix("plans: "))
        .unwrap_or_else(|| panic!("no plans line: {stdout}"));
    let cuts: u64 = plans
        .split(", ")
        .filter_map(|p| p.split_once(' '))
        .filter(|(name, _)| Hierarchy::from_name(name).is_some_and(|h| h.is_hierarchical()))
        .map(|(_, n)| n.parse::<u64>().unwrap())
        .sum();
    assert!(cuts > 0, "no random case cut a hierarchy: plans {plans}");
}
