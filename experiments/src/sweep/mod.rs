//! `forestlod sweep`: measure the speed–accuracy trade (SPEC §1, §10; E§5).
//!
//! A sweep is a small TOML file (format in `experiments/sweeps/README.md`): scenes, cameras (named
//! 360° sweeps or a distance path), which parameters take which values, and which variants run
//! (`ours`, `vegetation`, `primitive`: SPEC §9, [`forestlod_reference::baselines`]). For every
//! frame it records cost (select / draw / frame seconds, work counters, memory, and how many trees
//! batching drew finer or coarser than per-tree selection would: SPEC §6) and accuracy against the ray-traced ground truth
//! ([`forestlod_reference::ground_truth`], [`crate::metrics`]), writes one CSV row per frame, and
//! plots cost against accuracy plus thesis-style runtime plots (E Fig. 5.1–5.7) as PNGs.
//!
//! Built-in sweeps are the files under `experiments/sweeps/`, embedded in the binary
//! ([`BUILTIN_SWEEPS`]). `--quick` applies each file's `[quick]` table (small scene, small images,
//! few steps): `forestlod sweep --quick --out DIR` runs all of them, the CI smoke test of the whole
//! experiment machinery.
//!
//! Every variant runs on the backends the file names (`backends = ["reference", "gpu"]`, or
//! `--backend`): the reference (CPU) rasterizer, or the wgpu twin through
//! [`forestlod_harness::backend::GpuScene`] (GPU selection or per-tree culling, the GPU-baked
//! textures, `draw.wgsl` / `primitive.wgsl`). Timings are wall-clock seconds, the minimum over
//! `repeats` renders of a frame: CPU time on the reference, submit-to-completion on the GPU (plus
//! timestamp-query times where the adapter has them). Ratios are only meaningful between rows of
//! one backend. Ground-truth images are rendered once per scene and camera pose and shared by
//! every variant, backend and parameter set.
//!
//! Layout: [`spec`] (the TOML file, its validation, parameter sets and poses), [`variant`] (the
//! typed variants and backends), [`rows`] (CSV row, saved images, `sweep.json` manifest),
//! [`runner`] (renders every frame of a sweep), [`plots`] (the PNG plots); this file is the CLI
//! glue (`forestlod sweep`: [`SweepArgs`], [`resolve`], [`configure`], [`run`]).

mod io;
mod load;
pub mod paths;
mod plots;
mod rows;
mod runner;
pub mod shard;
mod spec;
mod variant;

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use forestlod_reference::InputError;

use io::io_err;
pub use load::{
    Estimate, MAX_BILLBOARD_BYTES, MAX_FRAME_BYTES, MAX_FRAME_SIDE, MAX_SWEEP_FILE_BYTES,
    MAX_SWEEP_FRAMES, MAX_SWEEP_PIXEL_WORK, MAX_TRUTH_BYTES, check_folder_name, load_sweep_file,
    parse_sweep_toml,
};
pub use plots::write_plots;
pub use rows::{FrameImages, MAX_SWEEP_CSV_BYTES, Manifest, Row, parse_csv, read_csv, write_csv};
pub use runner::Runner;
pub use spec::{
    AxisSpec, CameraSpec, DISTANCE_PATH_BASE_HEIGHT_M, DISTANCE_PATH_CLIMB,
    DISTANCE_PATH_LOOK_AHEAD_M, ParamSet, Pose, QuickSpec, SettingSpec, SweepSpec, distance_camera,
    set_param,
};
pub use variant::{Engine, Pipeline, ReferenceRenderer, Registered};

/// The built-in sweeps: `(name, TOML)`, in the order `--quick` runs them.
pub const BUILTIN_SWEEPS: [(&str, &str); 35] = [
    ("camera360", include_str!("../../sweeps/camera360.toml")),
    ("distance", include_str!("../../sweeps/distance.toml")),
    ("grid_size", include_str!("../../sweeps/grid_size.toml")),
    (
        "angles_texture",
        include_str!("../../sweeps/angles_texture.toml"),
    ),
    (
        "lod_settings",
        include_str!("../../sweeps/lod_settings.toml"),
    ),
    ("fade_mode", include_str!("../../sweeps/fade_mode.toml")),
    ("mip_mode", include_str!("../../sweeps/mip_mode.toml")),
    ("angle_index", include_str!("../../sweeps/angle_index.toml")),
    ("compaction", include_str!("../../sweeps/compaction.toml")),
    ("grid_stress", include_str!("../../sweeps/grid_stress.toml")),
    ("tree_cull", include_str!("../../sweeps/tree_cull.toml")),
    ("hierarchy", include_str!("../../sweeps/hierarchy.toml")),
    (
        "hierarchy_paths",
        include_str!("../../sweeps/hierarchy_paths.toml"),
    ),
    (
        "hierarchy_params",
        include_str!("../../sweeps/hierarchy_params.toml"),
    ),
    (
        "command_order",
        include_str!("../../sweeps/command_order.toml"),
    ),
    ("lod_metric", include_str!("../../sweeps/lod_metric.toml")),
    (
        "celba_detail",
        include_str!("../../sweeps/celba_detail.toml"),
    ),
    ("subsets", include_str!("../../sweeps/subsets.toml")),
    ("shading", include_str!("../../sweeps/shading.toml")),
    (
        "shading_shadow",
        include_str!("../../sweeps/shading_shadow.toml"),
    ),
    (
        "blend_temporal",
        include_str!("../../sweeps/blend_temporal.toml"),
    ),
    ("azimuths", include_str!("../../sweeps/azimuths.toml")),
    ("occlusion", include_str!("../../sweeps/occlusion.toml")),
    ("impostors", include_str!("../../sweeps/impostors.toml")),
    ("far_levels", include_str!("../../sweeps/far_levels.toml")),
    (
        "celba_density",
        include_str!("../../sweeps/celba_density.toml"),
    ),
    ("celba_nodes", include_str!("../../sweeps/celba_nodes.toml")),
    ("celba_size", include_str!("../../sweeps/celba_size.toml")),
    (
        "far_levels_temporal",
        include_str!("../../sweeps/far_levels_temporal.toml"),
    ),
    (
        "impostors_temporal",
        include_str!("../../sweeps/impostors_temporal.toml"),
    ),
    ("points", include_str!("../../sweeps/points.toml")),
    (
        "hier_impostors",
        include_str!("../../sweeps/hier_impostors.toml"),
    ),
    (
        "celba_points_detail",
        include_str!("../../sweeps/celba_points_detail.toml"),
    ),
    (
        "celba_points_range",
        include_str!("../../sweeps/celba_points_range.toml"),
    ),
    (
        "celba_points_grid",
        include_str!("../../sweeps/celba_points_grid.toml"),
    ),
];

/// Options of `forestlod sweep` (`Default`: no file, no override, an empty `out`).
#[derive(Args, Clone, Debug, Default)]
pub struct SweepArgs {
    /// A sweep TOML file or a built-in sweep name; all built-in sweeps when omitted. `merge`
    /// followed by shard folders joins `--shard` runs into `--out` (`forestlod sweep merge --out
    /// DIR SHARD_DIR...`).
    pub file: Option<String>,
    /// With `merge`: the `--out` folders of the shard runs to join.
    pub shards: Vec<PathBuf>,
    /// Run shard I of N (`I/N`, 0 <= I < N): a deterministic 1/N of the frames; join the shards
    /// with `forestlod sweep merge`. `auto`: I and N from a Slurm job array
    /// (`SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_COUNT`); `auto/N`: I from a Kubernetes Indexed
    /// Job (`JOB_COMPLETION_INDEX`) of N completions (`experiments/cluster/`).
    #[arg(long)]
    pub shard: Option<shard::Shard>,
    /// Output folder: one sub-folder per sweep.
    #[arg(long)]
    pub out: PathBuf,
    /// Apply each sweep's `[quick]` table: small scene, small images, few steps.
    #[arg(long)]
    pub quick: bool,
    /// Replace the sweep's scene list with this one scene (built-in name or scene file).
    #[arg(long)]
    pub scene: Option<String>,
    /// Replace the image width.
    #[arg(long)]
    pub width: Option<u32>,
    /// Replace the image height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Replace the yaw steps of every 360° camera.
    #[arg(long)]
    pub yaw_steps: Option<u32>,
    /// Replace the frames of every scene-defined camera path (`paths::PATH_NAMES`).
    #[arg(long)]
    pub path_steps: Option<u32>,
    /// Replace the ground truth's samples per pixel side (the total error's too).
    #[arg(long)]
    pub samples: Option<u32>,
    /// Trace the truth on sampled tiles, `SIZE/FRACTION` (e.g. `80/0.125`: an eighth of the
    /// 80x80 tiles), or `full` for the whole frame.
    #[arg(long, value_name = "SIZE/FRACTION|full")]
    pub truth_tiles: Option<String>,
    /// Replace the number of timed renders per frame (the minimum is kept).
    #[arg(long)]
    pub repeats: Option<u32>,
    /// Replace the backends: `reference`, `gpu`, or both comma-separated (`reference,gpu`).
    #[arg(long)]
    pub backend: Option<String>,
}

/// Resolves the sweeps `forestlod sweep` runs: a file, a built-in name, or every built-in.
pub fn resolve(file: Option<&str>) -> Result<Vec<SweepSpec>, InputError> {
    match file {
        None => BUILTIN_SWEEPS
            .iter()
            .map(|(name, text)| SweepSpec::parse(text, &format!("<built-in sweep {name}>")))
            .collect(),
        Some(f) => {
            if let Some((name, text)) = BUILTIN_SWEEPS.iter().find(|(n, _)| *n == f) {
                return Ok(vec![SweepSpec::parse(
                    text,
                    &format!("<built-in sweep {name}>"),
                )?]);
            }
            let path = std::path::Path::new(f);
            if std::fs::symlink_metadata(path).is_err() {
                return Err(InputError::new(
                    f,
                    "file",
                    f,
                    format!(
                        "does not exist; expected a sweep TOML file or a built-in sweep name ({})",
                        BUILTIN_SWEEPS.map(|(n, _)| n).join(", ")
                    ),
                ));
            }
            Ok(vec![load_sweep_file(path)?])
        }
    }
}

/// A sweep as `forestlod sweep` runs it: `--quick` and the command-line overrides applied, then
/// validated. `None` when nothing is left to run: `--backend reference` on a sweep of GPU-only
/// variants (the dropped variants are named on stderr).
pub fn configure(spec: SweepSpec, args: &SweepArgs) -> Result<Option<SweepSpec>, InputError> {
    // Zero would be clamped or make an empty sweep: name the flag instead.
    for (flag, value) in [
        ("--repeats", args.repeats),
        ("--yaw-steps", args.yaw_steps),
        ("--width", args.width),
        ("--height", args.height),
        ("--path-steps", args.path_steps),
        ("--samples", args.samples),
    ] {
        if value == Some(0) {
            return Err(InputError::new(
                "<command line>",
                flag,
                0,
                "expected at least 1",
            ));
        }
    }
    let mut spec = if args.quick { spec.quick() } else { spec };
    if let Some(s) = &args.scene {
        spec.scenes = vec![s.clone()];
    }
    spec.width = args.width.unwrap_or(spec.width);
    spec.height = args.height.unwrap_or(spec.height);
    if args.width.is_some() || args.height.is_some() {
        spec.resolutions.clear();
    }
    spec.samples = args.samples.unwrap_or(spec.samples);
    if let Some(t) = &args.truth_tiles {
        spec.truth_tiles = parse_truth_tiles(t)?;
    }
    spec.repeats = args.repeats.unwrap_or(spec.repeats);
    if let Some(b) = &args.backend {
        spec.backends = b.split(',').map(|s| s.trim().to_string()).collect();
        if !spec
            .backends
            .iter()
            .any(|b| Engine::parse(b) == Ok(Engine::Gpu))
        {
            let (gpu_only, keep): (Vec<String>, Vec<String>) = spec
                .variants
                .iter()
                .cloned()
                .partition(|v| Pipeline::parse(v).is_ok_and(Pipeline::gpu_only));
            if !gpu_only.is_empty() {
                eprintln!(
                    "sweep {}: variant(s) {} need the gpu backend; not run with --backend {b}",
                    spec.name,
                    gpu_only.join(", ")
                );
            }
            spec.variants = keep;
            if spec.variants.is_empty() {
                return Ok(None);
            }
        }
    }
    if let Some(n) = args.yaw_steps {
        for c in &mut spec.cameras {
            if c.name != "distance" && !paths::is_path(&c.name) {
                c.yaw_steps = Some(n);
            }
        }
    }
    if let Some(n) = args.path_steps {
        for c in &mut spec.cameras {
            if paths::is_path(&c.name) {
                c.steps = Some(n);
            }
        }
    }
    spec.check().map_err(|b| flag_error(b, &spec.name, args))?;
    Ok(Some(spec))
}

/// A refusal of a sweep as configured: named by the flag that set the value when one did
/// (`--width 9000`: `<command line>: --width`), else by the sweep and key.
fn flag_error(b: load::Bad, name: &str, args: &SweepArgs) -> InputError {
    let root = match b.path.0.first() {
        Some(load::Seg::Key(k)) => k.as_str(),
        _ => "",
    };
    let leaf = match b.path.0.last() {
        Some(load::Seg::Key(k)) => k.as_str(),
        _ => "",
    };
    let given = [
        ("--width", args.width.is_some()),
        ("--height", args.height.is_some()),
        ("--samples", args.samples.is_some()),
        ("--repeats", args.repeats.is_some()),
        ("--yaw-steps", args.yaw_steps.is_some()),
        ("--path-steps", args.path_steps.is_some()),
        ("--truth-tiles", args.truth_tiles.is_some()),
        ("--scene", args.scene.is_some()),
        ("--backend", args.backend.is_some()),
    ];
    let named: Vec<&str> = given
        .iter()
        .filter(|(flag, on)| {
            *on && match root {
                "" => !matches!(*flag, "--scene" | "--truth-tiles"),
                "width" | "height" | "resolutions" => {
                    matches!(*flag, "--width" | "--height" | "--samples")
                }
                "samples" => *flag == "--samples",
                "repeats" => *flag == "--repeats",
                "cameras" => {
                    (leaf == "yaw_steps" && *flag == "--yaw-steps")
                        || (leaf == "steps" && *flag == "--path-steps")
                }
                "truth_tiles" => *flag == "--truth-tiles",
                "scenes" => *flag == "--scene",
                "variants" | "backends" => *flag == "--backend",
                _ => false,
            }
        })
        .map(|(flag, _)| *flag)
        .collect();
    let file = format!("<sweep {name}>");
    if named.is_empty() {
        let quick = if args.quick { " (with --quick)" } else { "" };
        let mut e = b.without_text(&file);
        e.reason.push_str(quick);
        return e;
    }
    let what = if b.path.0.is_empty() {
        "the sweep's size".to_string()
    } else {
        format!("key {}", b.path)
    };
    InputError::new(
        forestlod_reference::error::COMMAND_LINE,
        named.join(" "),
        b.value,
        format!("{} ({file}, {what})", b.reason),
    )
}

/// Checks `--out` before anything is read or written: absent (it is created), or a folder (or a
/// link to one). A file or a dangling link is refused, naming `--out`. Returns whether it exists.
pub fn check_out(out: &std::path::Path) -> Result<bool, InputError> {
    let bad = |reason: &str| {
        InputError::new(
            forestlod_reference::error::COMMAND_LINE,
            "--out",
            out.display(),
            reason,
        )
    };
    match std::fs::symlink_metadata(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(bad(&format!("cannot be read: {e}"))),
        Ok(link) => match std::fs::metadata(out) {
            Ok(m) if m.is_dir() => Ok(true),
            Ok(_) => Err(bad(
                "is not a folder: expected a folder or a path to create",
            )),
            Err(_) if link.file_type().is_symlink() => Err(bad(
                "is a dangling link: expected a folder or a path to create",
            )),
            Err(e) => Err(bad(&format!("cannot be read: {e}"))),
        },
    }
}

/// What a run created in `--out`, removed again when it fails (issue 28: a refused or failed run
/// leaves nothing behind): `--out` itself when it did not exist, else each sweep folder that did
/// not exist before. Folders of earlier runs are left as they were.
pub(crate) struct OutGuard {
    created: Vec<std::path::PathBuf>,
    pub(crate) done: bool,
}

impl OutGuard {
    pub(crate) fn new(out: &std::path::Path, existed: bool, names: &[String]) -> Self {
        let created = if existed {
            names
                .iter()
                .map(|n| out.join(n))
                .filter(|p| std::fs::symlink_metadata(p).is_err())
                .collect()
        } else {
            vec![out.to_path_buf()]
        };
        Self {
            created,
            done: false,
        }
    }
}

impl Drop for OutGuard {
    fn drop(&mut self) {
        if !self.done {
            for p in &self.created {
                let _ = std::fs::remove_dir_all(p);
            }
        }
    }
}

/// Checks that every scene a sweep names can be loaded, before anything is written: a built-in
/// name, or a scene file (loaded here and dropped: its loader's checks and limits, issue 28).
fn check_scenes(specs: &[SweepSpec]) -> Result<(), InputError> {
    let mut done: Vec<&str> = Vec::new();
    for spec in specs {
        for (i, scene) in spec.scenes.iter().enumerate() {
            if done.contains(&scene.as_str())
                || forestlod_reference::scene::builtin::is_builtin(scene)
            {
                continue;
            }
            let path = std::path::Path::new(scene);
            if std::fs::symlink_metadata(path).is_err() {
                // A Celba name that is not one (`celba-30-4`): its own error, naming the value.
                forestlod_reference::scene::celba::parse_celba_name(scene)
                    .map_err(|e| e.within(format!("<sweep {}>: key scenes[{i}]", spec.name)))?;
            }
            if !scene.ends_with(".toml") && std::fs::symlink_metadata(path).is_err() {
                return Err(InputError::new(
                    format!("<sweep {}>", spec.name),
                    format!("key scenes[{i}]"),
                    scene,
                    format!(
                        "expected a built-in scene ({}, or {}) or a scene file",
                        forestlod_reference::scene::builtin::BUILTIN_NAMES.join(", "),
                        forestlod_reference::scene::celba::celba_name_hint()
                    ),
                ));
            }
            forestlod_reference::scene::load::load_scene_file(path)?;
            done.push(scene);
        }
    }
    Ok(())
}

/// `--truth-tiles SIZE/FRACTION` or `full`.
fn parse_truth_tiles(text: &str) -> Result<Option<crate::fair::TileSpec>, InputError> {
    if text == "full" {
        return Ok(None);
    }
    let bad = |reason: String| InputError::new("<command line>", "--truth-tiles", text, reason);
    let (size, fraction) = text
        .split_once('/')
        .ok_or_else(|| bad("expected SIZE/FRACTION (e.g. 80/0.125) or full".into()))?;
    let spec = crate::fair::TileSpec {
        size: size
            .trim()
            .parse()
            .map_err(|_| bad("the tile size must be a whole number of pixels".into()))?,
        fraction: fraction
            .trim()
            .parse()
            .map_err(|_| bad("the fraction must be a number in (0, 1]".into()))?,
    };
    spec.check().map_err(bad)?;
    Ok(Some(spec))
}

/// `forestlod sweep`.
pub fn run(args: &SweepArgs) -> Result<(), Box<dyn std::error::Error>> {
    let out_existed = check_out(&args.out)?;
    if args.file.as_deref() == Some("merge") {
        for m in shard::merge(&args.shards, &args.out, out_existed)? {
            println!(
                "sweep {}: {} frames merged -> {}",
                m.name,
                m.frames,
                args.out.join(&m.name).join(&m.csv).display()
            );
        }
        return Ok(());
    }
    if !args.shards.is_empty() {
        return Err(InputError::new(
            "<command line>",
            "sweep",
            args.shards[0].display(),
            "extra folders are for `forestlod sweep merge`",
        )
        .into());
    }
    // Every sweep is configured (and so validated) before anything runs or is written.
    let mut specs = Vec::new();
    for spec in resolve(args.file.as_deref())? {
        let name = spec.name.clone();
        match configure(spec, args)? {
            Some(spec) => specs.push(spec),
            None => eprintln!("sweep {name}: nothing to run on the chosen backends"),
        }
    }
    check_scenes(&specs)?;
    let names: Vec<String> = specs.iter().map(|s| s.name.clone()).collect();
    let mut guard = OutGuard::new(&args.out, out_existed, &names);
    std::fs::create_dir_all(&args.out).map_err(|e| io_err(&args.out, e))?;
    let mut runner = Runner::default();
    let start = Instant::now();
    for spec in specs {
        let m = runner.run_sweep(&spec, args.quick, args.shard, &args.out)?;
        println!(
            "sweep {}: {} frames in {:.1} s -> {}",
            m.name,
            m.frames,
            m.wall_seconds,
            args.out.join(&m.name).join(&m.csv).display()
        );
    }
    println!(
        "all sweeps: {:.1} s; `forestlod report --run {}` writes the report",
        start.elapsed().as_secs_f64(),
        args.out.display()
    );
    guard.done = true;
    Ok(())
}

#[cfg(test)]
mod tests {
    use forestlod_shared::FadeMode;

    use super::*;

    #[test]
    fn every_builtin_sweep_parses_in_both_modes() {
        for (name, text) in BUILTIN_SWEEPS {
            let spec = SweepSpec::parse(text, name).unwrap();
            assert_eq!(spec.name, name);
            assert!(!spec.param_sets(name).unwrap().is_empty());
            let quick = spec.quick();
            quick.validate(name).unwrap();
            assert!(!quick.poses().is_empty());
        }
    }

    #[test]
    fn bad_sweeps_are_named() {
        // (file body after the common head, the text the error must name)
        let head = "name = 'x'\ntitle = 't'\nscenes = ['tiny']\n";
        let far = "[[cameras]]\nname = 'far'\n";
        for (body, named) in [
            ("[[cameras]]\nname = 'sideways'\n".to_string(), "sideways"),
            (
                format!("{far}[[axes]]\nparam = 'grid_size'\nvalues = [-1]\n"),
                "grid_size",
            ),
            (format!("variants = ['fast']\n{far}"), "fast"),
            (format!("backends = ['cuda']\n{far}"), "cuda"),
            (format!("backends = []\n{far}"), "backends"),
            (format!("variants = ['ours-atomic']\n{far}"), "ours-atomic"),
            (
                format!("{far}[[axes]]\nparam = 'tree_cull'\nvalues = ['some']\n"),
                "tree_cull",
            ),
            (
                "[[cameras]]\nname = 'far'\nyaw_steps = 0\n".to_string(),
                "cameras[0].yaw_steps",
            ),
        ] {
            let e = SweepSpec::parse(&format!("{head}{body}"), "f.toml").unwrap_err();
            assert!(e.to_string().contains(named), "{named}: {e}");
        }
    }

    #[test]
    fn axes_multiply_and_settings_apply() {
        let spec = SweepSpec::parse(
            "name = 'x'\ntitle = 't'\nscenes = ['tiny']\nx_axis = 'angle_count'\n[[cameras]]\nname = 'far'\nyaw_steps = 4\n\
             [[axes]]\nparam = 'angle_count'\nvalues = [2, 10]\n[[axes]]\nparam = 'texture_size'\nvalues = [32, 64, 128]\n\
             [[settings]]\nlabel = 'a'\n[[settings]]\nlabel = 'b'\nfade_mode = 'alpha'\n",
            "f.toml",
        )
        .unwrap();
        let sets = spec.param_sets("f").unwrap();
        assert_eq!(sets.len(), 2 * 2 * 3);
        assert!(
            sets.iter().any(
                |s| s.params.fade_mode == FadeMode::Alpha as u32 && s.params.texture_size == 64
            )
        );
        assert_eq!(sets[0].x, Some(2.0));
        assert_eq!(sets[0].series, "a texture_size=32");
        let yaws: Vec<f32> = spec.poses().iter().map(|p| p.yaw_deg).collect();
        assert_eq!(yaws, [0.0, 90.0, 180.0, 270.0]);
    }
}
