//! The main job (`forestlod render`, and `cargo run --release` with no arguments): render one frame
//! of a scene with the reference pipeline and write colour, depth, the LOD-id view, the baked
//! billboard atlas, a metrics JSON and a short summary into an output folder.
//!
//! When wgpu finds an adapter (`forestlod_gpu::GpuContext::new`), the same frame is also rendered
//! by the GPU twin (`gpu/src/shaders/select.wgsl` then `draw.wgsl`; `--stage-from-cpu` chooses
//! which GPU stages take their input from the reference instead, as vello's `force_gpu_from`) and
//! judged against the reference with `forestlod_harness::image_compare` (SPEC §8): `gpu_color.png`,
//! `gpu_lod.png` and `diff.png` are written beside the reference's images, and the metrics and the
//! summary gain a `parity` section (adapter, maximum differences per buffer, mismatch and
//! ambiguity counts, FLIP mean).
//!
//! The exit code is the verdict ([`exit_code`]): 0 only when every part succeeded and GPU parity
//! passed (or `--no-gpu` asked for no GPU frame); 1 bad input or I/O error, 2 GPU parity failed,
//! 3 GPU error, 4 GPU parity skipped because no suitable adapter exists. The reference outputs,
//! `metrics.json` and `summary.txt` are written in every case but 1, and the last line printed is
//! the verdict.
//!
//! `--out` is checked before any work (an existing folder, or a creatable path, that we can write
//! in). Everything is computed before anything is written, into a staging folder moved into place
//! at the end, so a failure leaves the output folder as it was; after a successful run it holds
//! exactly this run's outputs: the known output files ([`OUTPUT_FILES`]) an earlier run left and
//! this one did not write are removed, other files are never touched.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;
use forestlod_reference::InputError;
use forestlod_reference::bake::contact_sheet;
use forestlod_reference::output::{depth_preview, lod_id_image, write_depth_exr, write_png};
use forestlod_reference::pipeline::{Frame, Prepared, prepare};
use forestlod_reference::texture::Rgba8Image;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde_json::json;

use forestlod_gpu::{GpuContext, GpuDraw};
use forestlod_harness::alternatives::alpha_test_alternatives_at;
use forestlod_harness::gpu_frame::{StagesFromCpu, render_gpu};
use forestlod_harness::image_compare::{
    ClassCounts, ImageReport, Images, alternative_pixels, class_image, compare_images_with_flip,
    flip_mean,
};
use forestlod_shared::{Camera, Params};

use crate::camera::{CameraArgs, no_tree_warning};
use crate::legend::{difference_heatmap, with_class_legend, with_diff_scale, with_lod_legend};
use crate::options::{ParamArgs, SceneArgs};
use crate::resident::Resident;

/// Exit codes of the main job (`forestlod render`, and `forestlod` with no subcommand).
pub mod exit_code {
    /// Every part succeeded and GPU parity passed, or `--no-gpu` asked for no GPU frame.
    pub const SUCCESS: u8 = 0;
    /// Bad input (flags, scene files, `--out`) or an I/O error; command-line usage errors too.
    pub const BAD_INPUT: u8 = 1;
    /// The GPU frame differs from the reference beyond the parity tolerances.
    pub const PARITY_FAILED: u8 = 2;
    /// wgpu failed while rendering the GPU frame.
    pub const GPU_ERROR: u8 = 3;
    /// No suitable GPU adapter: the reference outputs were written, parity was not judged.
    pub const GPU_SKIPPED: u8 = 4;
}

/// The exit-code table as `--help` shows it.
pub const EXIT_CODES_HELP: &str = "Exit codes of the main job (render, or no subcommand):
  0  every part succeeded and GPU parity passed (or --no-gpu)
  1  bad input or I/O error (also command-line usage errors)
  2  GPU parity failed
  3  GPU error (wgpu failed during the GPU frame)
  4  GPU parity skipped: no suitable GPU adapter (scripts/install-deps installs Mesa's lavapipe)
Codes 2-4 still write the reference outputs, metrics.json and summary.txt.";

/// Every file the main job may write into `--out`; an earlier run's copies that this run does not
/// write are removed.
pub const OUTPUT_FILES: [&str; 11] = [
    "color.png",
    "depth.exr",
    "depth_preview.png",
    "lod.png",
    "atlas.png",
    "gpu_color.png",
    "gpu_lod.png",
    "diff.png",
    "parity_classes.png",
    "metrics.json",
    "summary.txt",
];

/// How the summary ends when wgpu finds no suitable adapter.
pub const INSTALL_HINT: &str = "install Mesa's lavapipe with scripts/install-deps (or apt-get install mesa-vulkan-drivers libvulkan1), or pass --no-gpu";

/// Options of the main job.
#[derive(Args, Clone, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub params: ParamArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Output folder (created if missing; checked before any work). After a run it holds exactly
    /// this run's outputs: stale outputs of an earlier run are removed, other files kept.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Stages the reference computes instead of the GPU, by stage name, comma-separated: a named
    /// stage and every stage of the frame's plan before it come from the reference, the GPU runs
    /// the rest (`bake`, `mips`; `select`, `hier_select`, `coalesce`, `command_order`, `refine`).
    /// `textures` is `mips`; `select` is the whole selection, `refine` included; `none`: all on
    /// the GPU (`forestlod_harness::gpu_frame::StagesFromCpu`).
    #[arg(long, default_value = "none")]
    pub stage_from_cpu: String,
    /// Skip the GPU twin even when an adapter exists (exit code 0 without a parity verdict).
    #[arg(long)]
    pub no_gpu: bool,
}

impl Default for RenderArgs {
    fn default() -> Self {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrapper {
            #[command(flatten)]
            args: RenderArgs,
        }
        Wrapper::parse_from(["forestlod"]).args
    }
}

fn spinner(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").expect("static template"),
    );
    bar.set_message(message.to_string());
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// Runs `f` under a spinner and returns its result and wall time.
fn stage<T>(message: &str, f: impl FnOnce() -> T) -> (T, f64) {
    let bar = spinner(message);
    let t = Instant::now();
    let out = f();
    let seconds = t.elapsed().as_secs_f64();
    bar.finish_with_message(format!("{message}: {seconds:.2} s"));
    (out, seconds)
}

/// Every parameter of the parameter table ([`forestlod_shared::registry::PARAMS`]) under its
/// flag's underscore form: numbers as numbers, modes by name.
pub fn params_json(params: &Params) -> serde_json::Value {
    use forestlod_shared::ParamKind;
    forestlod_shared::PARAMS
        .iter()
        .map(|spec| {
            let v = (spec.get)(params);
            let value = match spec.kind {
                ParamKind::Float { .. } => json!(v as f32),
                ParamKind::Uint { .. } => json!(v as u32),
                ParamKind::Choice(_) => json!(spec.format(params)),
            };
            (spec.key(), value)
        })
        .collect::<serde_json::Map<_, _>>()
        .into()
}

/// The metrics JSON of one frame.
pub fn metrics(
    prepared: &Prepared,
    frame: &Frame,
    args: &RenderArgs,
    params: &Params,
    scene_seconds: f64,
) -> serde_json::Value {
    let drawn = &frame.drawn;
    let pixels = (args.width as u64 * args.height as u64).max(1);
    let trees = drawn.tree_stats;
    let c = frame.selection.counters;
    json!({
        "scene": prepared.scene.name,
        "camera": args.camera.label(), "yaw_degrees": args.camera.yaw, "view": args.camera.json(),
        "viewport": [args.width, args.height],
        "params": params_json(params),
        "refine": frame.refined.as_ref().map(|r| json!({
            "trees_tested": r.trees_tested, "trees_kept": r.trees_kept,
        })),
        "times_seconds": {
            "scene": scene_seconds, "prepare": prepared.timings, "frame": frame.timings,
        },
        "selection": {
            "batches_tested": c.batches_tested, "culled_distance": c.culled_distance, "culled_frustum": c.culled_frustum,
            "commands": c.commands, "lod0_commands": c.lod0_commands, "lod1_commands": c.lod1_commands,
            "transition_batches": c.transition_batches, "instances": c.instances,
        },
        "draw": {
            "trees_discarded_by_draw_distance": drawn.trees_discarded,
            "points_drawn": drawn.points_drawn,
            "triangles": trees.triangles_in, "triangles_rasterized": trees.triangles_rasterized,
            "fragments_covered": trees.fragments_covered, "fragments_shaded": trees.fragments_shaded,
            "fragments_written": trees.fragments_written,
            "overdraw": trees.fragments_written as f64 / pixels as f64,
            "terrain_triangles": drawn.terrain_stats.triangles_in,
        },
        "memory_bytes": prepared.memory,
        "trees": prepared.scene.instances.len(), "batches": prepared.batches.metas.len(), "meshes": prepared.scene.meshes.len(),
    })
}

/// What the GPU side of the main job produced.
pub enum GpuOutcome {
    /// `--no-gpu`: no GPU frame was asked for.
    NotRequested,
    /// No suitable adapter: wgpu's reason, on one line.
    Skipped(String),
    /// The GPU ran but failed (a wgpu error): the message.
    Failed {
        /// Adapter description.
        adapter: String,
        /// What went wrong.
        error: String,
    },
    /// The GPU frame and its verdict.
    Rendered(Box<GpuRender>),
}

/// A GPU frame of the main job and its comparison with the reference frame.
pub struct GpuRender {
    /// Adapter description (`GpuContext::describe`).
    pub adapter: String,
    /// The buffers read back.
    pub images: Images,
    /// The comparison with the reference.
    pub report: ImageReport,
    /// The draw calls recorded.
    pub calls: forestlod_gpu::DrawCalls,
    /// Which stages took reference input.
    pub from_cpu: StagesFromCpu,
    /// Wall seconds of the GPU frame (uploads, select, draw, readback).
    pub seconds: f64,
    /// Wall seconds of each GPU-side phase.
    pub phases: GpuPhases,
}

/// Wall seconds of the main job's GPU-side phases (issue 14: every second accounted for).
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuPhases {
    /// Adapter, device and pipelines (`GpuContext::new`, `GpuDraw::new`).
    pub init: f64,
    /// The GPU frame: uploads, select, draw, readback (`render_gpu`).
    pub frame: f64,
    /// The reference's alternative frames (cutoff moved), drawn only where the frames disagree.
    pub alternatives: f64,
    /// The classified comparison after the alternatives; FLIP, which needs no alternative,
    /// runs beside them and counts here only for what it takes after them.
    pub comparison: f64,
    /// How many pixels the alternatives were drawn at.
    pub alternative_pixels: usize,
    /// How many alternative frames were drawn (0 when no pixel needed one).
    pub alternative_frames: usize,
    /// Resident memory at the end of `init`, `frame`, `alternatives` and `comparison`.
    pub resident: [Option<Resident>; 4],
}

/// Renders the frame on the GPU, when an adapter exists, and compares it with the reference's.
pub fn gpu_frame(
    prepared: &Prepared,
    frame: &Frame,
    camera: &Camera,
    params: &Params,
    from_cpu: StagesFromCpu,
    name: &str,
) -> GpuOutcome {
    let mut phases = GpuPhases::default();
    let t = Instant::now();
    let ctx = match GpuContext::new() {
        Ok(ctx) => {
            // Adapters that cannot run the pipeline (wgpu's GL backend, say), one line each.
            for line in &ctx.passed_over {
                eprintln!("{}", one_line(line));
            }
            ctx
        }
        // The tests' hint (install, or FORESTLOD_ALLOW_NO_GPU) is not the main job's.
        Err(forestlod_gpu::GpuError::NoAdapter(why)) => {
            return GpuOutcome::Skipped(one_line(&format!("no suitable GPU adapter ({why})")));
        }
        Err(e) => return GpuOutcome::Skipped(one_line(&e.to_string())),
    };
    let adapter = one_line(&ctx.describe());
    let failed = |e: String| GpuOutcome::Failed {
        adapter: adapter.clone(),
        error: one_line(&e),
    };
    let t_draw = Instant::now();
    let draw = match GpuDraw::new(&ctx) {
        Ok(d) => d,
        Err(e) => return failed(e.to_string()),
    };
    phases.init = t.elapsed().as_secs_f64();
    phases.resident[0] = Resident::sample();
    let t = Instant::now();
    let gpu = match render_gpu(&ctx, &draw, prepared, camera, params, from_cpu) {
        Ok(g) => g,
        Err(e) => return failed(e.to_string()),
    };
    phases.frame = t.elapsed().as_secs_f64();
    phases.resident[1] = Resident::sample();
    let seconds = t_draw.elapsed().as_secs_f64();
    // The device goes before the reference draws its alternatives: peak memory is the larger of
    // the two sides, not their sum (issue 14; lavapipe keeps every buffer in host memory).
    drop(draw);
    drop(ctx);
    crate::resident::release_free_heap();
    let target = &frame.drawn.target;
    let reference = Images {
        width: target.width(),
        height: target.height(),
        color: target.color().to_vec(),
        depth: target.depth().to_vec(),
        lod_id: target.aux().to_vec(),
    };
    // FLIP runs beside the alternatives (issue 14: neither fills both cores alone); the
    // comparison phase is what follows the alternatives (the classification, and FLIP's rest).
    let t = Instant::now();
    let ((pixels, alternatives, alternatives_seconds), flip) = rayon::join(
        || {
            let pixels = alternative_pixels(&gpu.images, &reference);
            let alternatives = alpha_test_alternatives_at(prepared, camera, params, &pixels);
            (pixels, alternatives, t.elapsed().as_secs_f64())
        },
        || {
            flip_mean(
                &reference.color,
                &gpu.images.color,
                reference.width,
                reference.height,
            )
        },
    );
    phases.alternatives = alternatives_seconds;
    phases.resident[2] = Resident::sample();
    phases.alternative_pixels = pixels.iter().filter(|&&p| p).count();
    phases.alternative_frames = alternatives.len();
    let report =
        compare_images_with_flip(name, &gpu.images, &reference, &alternatives, camera, flip);
    phases.comparison = t.elapsed().as_secs_f64() - alternatives_seconds;
    phases.resident[3] = Resident::sample();
    GpuOutcome::Rendered(Box::new(GpuRender {
        adapter,
        images: gpu.images,
        report,
        calls: gpu.calls,
        from_cpu,
        seconds,
        phases,
    }))
}

fn counts_json(c: &ClassCounts) -> serde_json::Value {
    json!({
        "exact": c.exact, "within_tolerance": c.within_tolerance, "window": c.window,
        "threshold_ambiguous": c.threshold_ambiguous, "depth_tie": c.depth_tie,
        "translucent": c.translucent, "edge_ambiguous": c.edge_ambiguous, "mismatches": c.mismatches,
    })
}

/// The `parity` object of the metrics JSON.
pub fn parity_json(outcome: &GpuOutcome) -> serde_json::Value {
    use forestlod_harness::image_compare as ic;
    match outcome {
        GpuOutcome::NotRequested => json!({ "gpu": "not requested (--no-gpu)" }),
        GpuOutcome::Skipped(why) => json!({ "gpu": "skipped", "reason": why }),
        GpuOutcome::Failed { adapter, error } => json!({ "adapter": adapter, "error": error }),
        GpuOutcome::Rendered(g) => {
            let r = &g.report;
            json!({
                "adapter": g.adapter,
                "stages_from_cpu": g.from_cpu.name(),
                "indirect_call": g.calls.mode.name(),
                "cpu_draw_calls": { "terrain": g.calls.terrain, "trees": g.calls.trees, "max_commands": g.calls.max_commands },
                "gpu_frame_seconds": g.seconds,
                "passed": r.passed(),
                "mismatch_budget_per_buffer": r.compound_budget(),
                "failures": r.failures(),
                "mismatch_examples": r.examples,
                "flip_mean": r.flip_mean,
                "edge_pixels": r.edge_pixels,
                "color": {
                    "max_diff": r.color_max_diff, "max_diff_after_window": r.color_max_window_diff,
                    "max_interior_diff": r.color_max_interior_diff, "counts": counts_json(&r.color),
                },
                "depth": {
                    "max_diff": r.depth_max_diff, "max_interior_ulps": r.depth_max_interior_ulps,
                    "counts": counts_json(&r.depth),
                },
                "lod_id": { "counts": counts_json(&r.lod_id) },
                "class_budgets": r.class_budgets().iter().map(|(buffer, class, count, budget)| {
                    json!({ "buffer": buffer, "class": class, "count": count, "budget": budget })
                }).collect::<Vec<_>>(),
                "signed_differences": {
                    "color": r.color_signed.iter().zip(["r", "g", "b", "a"]).map(|(h, c)| {
                        let (per_value, up, down) = h.value_bias();
                        (c.to_string(), json!({ "bias": h.mean(), "bias_per_value": per_value,
                            "values_up": up, "values_down": down, "edge_fraction": h.edge_fraction(),
                            "histogram": h.histogram() }))
                    }).collect::<serde_json::Map<_, _>>(),
                    "depth_ulps": { "bias": r.depth_signed.mean(), "edge_fraction": r.depth_signed.edge_fraction(),
                        "histogram": r.depth_signed.histogram() },
                },
                "tolerances": {
                    "color": ic::COLOR_TOLERANCE, "edge_color_margin": ic::EDGE_COLOR_MARGIN,
                    "depth_ulps": ic::DEPTH_MAX_ULPS, "depth_edge_rel": ic::DEPTH_EDGE_REL,
                    "alpha_test_shifts": ic::ALPHA_TEST_SHIFTS, "depth_tie_max_fraction": ic::DEPTH_TIE_MAX_FRACTION,
                    "compound_max_fraction": ic::MAX_COMPOUND_FRACTION,
                    "flip_mean_max": ic::FLIP_MEAN_MAX,
                    "color_bias_max": ic::COLOR_BIAS_MAX, "depth_bias_max_ulps": ic::DEPTH_BIAS_MAX_ULPS,
                },
            })
        }
    }
}

/// The summary lines of the GPU side.
pub fn parity_text(outcome: &GpuOutcome) -> String {
    match outcome {
        GpuOutcome::NotRequested | GpuOutcome::Skipped(_) => String::new(),
        GpuOutcome::Failed { adapter, .. } => format!("GPU: {adapter}\n"),
        GpuOutcome::Rendered(g) => {
            let r = &g.report;
            format!(
                "GPU: {} ({} s, stages from the reference: {}, {} CPU draw call(s) for all trees via {})\n\
                 parity: FLIP mean {:.4}; colour max diff {} ({} after the ±1 px window, {} on interior pixels), \
                 {} mismatches, {} ambiguous; depth max diff {:.2e} ({} ulp interior), {} mismatches; \
                 LOD id {} mismatches, {} ambiguous (mismatch budget {} per buffer)\n",
                g.adapter,
                format_args!("{:.2}", g.seconds),
                g.from_cpu.name(),
                g.calls.trees,
                g.calls.mode.name(),
                r.flip_mean,
                r.color_max_diff,
                r.color_max_window_diff,
                r.color_max_interior_diff,
                r.color.mismatches,
                r.color.threshold_ambiguous + r.color.depth_tie + r.color.edge_ambiguous,
                r.depth_max_diff,
                r.depth_max_interior_ulps,
                r.depth.mismatches,
                r.lod_id.mismatches,
                r.lod_id.threshold_ambiguous + r.lod_id.edge_ambiguous,
                r.compound_budget(),
            )
        }
    }
}

/// `s` on one line: every run of whitespace (newlines included) becomes one space.
pub fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

impl GpuOutcome {
    /// The main job's exit code for this outcome ([`exit_code`]).
    pub fn exit_code(&self) -> u8 {
        match self {
            GpuOutcome::NotRequested => exit_code::SUCCESS,
            GpuOutcome::Skipped(_) => exit_code::GPU_SKIPPED,
            GpuOutcome::Failed { .. } => exit_code::GPU_ERROR,
            GpuOutcome::Rendered(g) if g.report.passed() => exit_code::SUCCESS,
            GpuOutcome::Rendered(_) => exit_code::PARITY_FAILED,
        }
    }

    /// The verdict: the last line the main job prints and the last line of `summary.txt`.
    pub fn verdict(&self) -> String {
        let line = match self {
            GpuOutcome::NotRequested => "GPU parity not judged: --no-gpu".to_string(),
            GpuOutcome::Skipped(why) => format!("GPU parity skipped: {why}; {INSTALL_HINT}"),
            GpuOutcome::Failed { error, .. } => format!("GPU error: {error}"),
            GpuOutcome::Rendered(g) => {
                let r = &g.report;
                let counts = format!(
                    "FLIP mean {:.4}; mismatches colour {}, depth {}, LOD id {} (budget {} per buffer)",
                    r.flip_mean,
                    r.color.mismatches,
                    r.depth.mismatches,
                    r.lod_id.mismatches,
                    r.compound_budget()
                );
                if r.passed() {
                    format!("GPU parity PASSED: {counts}")
                } else {
                    format!("GPU parity FAILED: {}; {counts}", r.failures().join("; "))
                }
            }
        };
        format!("{} [exit {}]", one_line(&line), self.exit_code())
    }
}

/// Checks `--out` before any work: an existing folder must be a folder we can create files in;
/// a missing one must be creatable (its nearest existing ancestor a folder we can write in).
/// Nothing is left behind (a probe file is created and removed). The error names `--out`, the
/// path and the operating system's reason.
pub fn check_out(out: &Path) -> Result<(), InputError> {
    let fail = |at: &Path, e: std::io::Error| {
        let at = if at == out {
            String::new()
        } else {
            format!("{}: ", at.display())
        };
        InputError::new(
            "<command line>",
            "--out",
            out.display(),
            format!("cannot be used as the output folder: {at}{e}"),
        )
    };
    let mut dir = out;
    loop {
        match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => break,
            Ok(_) => {
                // A file: reading it as a folder gives the operating system's reason.
                let e = std::fs::read_dir(dir).err().unwrap_or_else(|| {
                    std::io::Error::new(std::io::ErrorKind::NotADirectory, "not a directory")
                });
                return Err(fail(dir, e));
            }
            // A dangling link (the folder or one above it): `metadata` says "not found", yet
            // creating the folder would fail after the work (issue 28).
            Err(e) if std::fs::symlink_metadata(dir).is_ok_and(|m| m.file_type().is_symlink()) => {
                let target = std::fs::read_link(dir)
                    .map(|t| t.display().to_string())
                    .unwrap_or_default();
                return Err(fail(
                    dir,
                    std::io::Error::new(
                        e.kind(),
                        format!("a link to {target} that does not resolve ({e})"),
                    ),
                ));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                dir = match dir.parent() {
                    Some(p) if !p.as_os_str().is_empty() => p,
                    _ => Path::new("."),
                };
            }
            Err(e) => return Err(fail(dir, e)),
        }
    }
    let probe = dir.join(format!(".forestlod-write-probe-{}", std::process::id()));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(fail(dir, e)),
    }
}

/// Checks `--width` and `--height` before any work, naming the flag (issue 28; the camera's own
/// check names `camera.viewport`, which the user did not type).
pub fn check_viewport(width: u32, height: u32) -> Result<(), InputError> {
    use forestlod_reference::raster::MAX_TARGET_SIZE;
    for (flag, v) in [("--width", width), ("--height", height)] {
        if !(1..=MAX_TARGET_SIZE).contains(&v) {
            return Err(InputError::new(
                "<command line>",
                flag,
                v,
                format!("expected 1..={MAX_TARGET_SIZE} pixels"),
            ));
        }
    }
    Ok(())
}

/// The main job: returns its exit code ([`exit_code`]); `Err` is bad input or an I/O error.
pub fn run(args: &RenderArgs) -> Result<u8, Box<dyn std::error::Error>> {
    check_out(&args.out)?;
    let params = args.params.params()?;
    let from_cpu = StagesFromCpu::parse(&args.stage_from_cpu).map_err(|e| {
        InputError::new(
            "<command line>",
            "--stage-from-cpu",
            &args.stage_from_cpu,
            e,
        )
    })?;
    args.camera.free()?;
    check_viewport(args.width, args.height)?;
    let wall = Instant::now();
    let (scene, scene_seconds) = stage("loading scene", || args.scene.load());
    let scene = scene?;
    let mut resident = vec![("scene", Resident::sample())];
    let camera = args.camera.camera(&scene, args.width, args.height)?;
    let (prepared, prepare_seconds) = stage("batches, mips and billboard bake", || {
        prepare(scene, &params)
    });
    let prepared = prepared?;
    resident.push(("prepare", Resident::sample()));
    let (frame, frame_seconds) = stage("selection and reference draw", || {
        prepared.render(&camera, &params)
    });
    let frame = frame?;
    resident.push(("reference_frame", Resident::sample()));
    // The reference frame's vertex stage and setup freed over 200 MB that the allocator keeps
    // resident; handing it back first keeps it from stacking under the GPU twin's memory (issue 14).
    crate::resident::release_free_heap();
    resident.push(("heap_trim", Resident::sample()));
    if let Some(warning) = no_tree_warning(
        &prepared.scene,
        frame.selection.counters.commands,
        Some(frame.drawn.tree_stats.fragments_written),
    ) {
        eprintln!("{warning}");
    }

    let gpu = if args.no_gpu {
        GpuOutcome::NotRequested
    } else {
        let name = format!("{}-{}", prepared.scene.name, args.camera.label());
        let (outcome, _) = stage("GPU twin (select + draw) and parity", || {
            gpu_frame(&prepared, &frame, &camera, &params, from_cpu, &name)
        });
        outcome
    };
    let verdict = gpu.verdict();
    let code = gpu.exit_code();

    let mut metrics = metrics(&prepared, &frame, args, &params, scene_seconds);
    metrics["parity"] = parity_json(&gpu);
    metrics["verdict"] = json!({ "line": verdict, "exit_code": code });
    let mut phases = vec![
        ("scene", scene_seconds),
        ("prepare", prepare_seconds),
        ("reference_frame", frame_seconds),
    ];
    if let GpuOutcome::Rendered(g) = &gpu {
        phases.extend([
            ("gpu_init", g.phases.init),
            ("gpu_frame", g.phases.frame),
            ("alternatives", g.phases.alternatives),
            ("comparison", g.phases.comparison),
        ]);
        resident.extend(
            ["gpu_init", "gpu_frame", "alternatives", "comparison"]
                .into_iter()
                .zip(g.phases.resident),
        );
    }
    let target = &frame.drawn.target;
    let (w, h) = (target.width(), target.height());
    let mut written: Vec<&str> = Vec::new();
    let mut details = String::new();
    write_outputs(
        &args.out,
        |dir, written| {
            let encoding = Instant::now();
            // Every image is made and encoded on its own (in parallel, issue 14); the files are
            // the same bytes whatever the order.
            let png = png_job;
            let mut jobs: Vec<(&'static str, Encode<'_>)> = vec![
                png("color.png", Box::new(|| target.color_image())),
                png(
                    "depth_preview.png",
                    Box::new(|| depth_preview(w, h, target.depth())),
                ),
                png(
                    "lod.png",
                    Box::new(|| with_lod_legend(&lod_id_image(w, h, target.aux()))),
                ),
                png(
                    "atlas.png",
                    Box::new(|| contact_sheet(&prepared.billboards, prepared.scene.meshes.len())),
                ),
            ];
            if let GpuOutcome::Rendered(g) = &gpu {
                jobs.extend([
                    png("gpu_color.png", Box::new(|| g.images.color_image())),
                    png(
                        "gpu_lod.png",
                        Box::new(|| with_lod_legend(&g.images.lod_image())),
                    ),
                    png(
                        "parity_classes.png",
                        Box::new(|| with_class_legend(&class_image(&g.report))),
                    ),
                    png(
                        "diff.png",
                        Box::new(|| {
                            with_diff_scale(&difference_heatmap(
                                w,
                                h,
                                &g.images.color,
                                target.color(),
                            ))
                        }),
                    ),
                ]);
            }
            let exr: Encode<'_> = Box::new(|dir: &Path| {
                write_depth_exr(&dir.join("depth.exr"), w, h, target.depth())
            });
            jobs.push(("depth.exr", exr));
            written.extend(jobs.iter().map(|(name, _)| *name));
            let results: Vec<Result<(), InputError>> =
                jobs.into_par_iter().map(|(_, job)| job(dir)).collect();
            results.into_iter().collect::<Result<Vec<()>, _>>()?;
            // The summary and metrics are written last, so that they can account for the image
            // encoding and for the whole run's wall time up to here.
            phases.push(("image_encoding", encoding.elapsed().as_secs_f64()));
            resident.push(("image_encoding", Resident::sample()));
            metrics["resident_memory_mb"] = resident
                .iter()
                .filter_map(|&(name, r)| Some((name.to_string(), r?.json())))
                .collect::<serde_json::Map<_, _>>()
                .into();
            let accounted: f64 = phases.iter().map(|p| p.1).sum();
            let wall_seconds = wall.elapsed().as_secs_f64();
            metrics["times_seconds"]["phases"] = phases
                .iter()
                .map(|&(name, t)| (name.to_string(), json!(t)))
                .collect::<serde_json::Map<_, _>>()
                .into();
            metrics["times_seconds"]["wall"] = json!(wall_seconds);
            if let GpuOutcome::Rendered(g) = &gpu {
                metrics["parity"]["alternative_pixels"] = json!(g.phases.alternative_pixels);
                metrics["parity"]["alternative_frames"] = json!(g.phases.alternative_frames);
            }
            details = format!(
                "{}{}{}{}",
                summary_text(&metrics),
                parity_text(&gpu),
                phases_text(&phases, accounted, wall_seconds, &gpu),
                resident_text(&resident)
            );
            for (name, text) in [
                (
                    "metrics.json",
                    serde_json::to_string_pretty(&metrics).unwrap_or_default(),
                ),
                ("summary.txt", format!("{details}{verdict}\n")),
            ] {
                written.push(name);
                std::fs::write(dir.join(name), text).map_err(|e| {
                    InputError::new(
                        dir.join(name).display().to_string(),
                        "write",
                        "",
                        e.to_string(),
                    )
                })?;
            }
            Ok(())
        },
        &mut written,
    )?;
    print!("{details}");
    println!("wrote {} to {}", written.join(", "), args.out.display());
    println!("{verdict}");
    Ok(code)
}

/// One output file's work: make it and write it into the given folder.
type Encode<'e> = Box<dyn FnOnce(&Path) -> Result<(), InputError> + Send + 'e>;

/// The job that makes the image `image` returns and writes it as the PNG `name`.
fn png_job<'e>(
    name: &'static str,
    image: Box<dyn FnOnce() -> Rgba8Image + Send + 'e>,
) -> (&'static str, Encode<'e>) {
    (
        name,
        Box::new(move |dir: &Path| write_png(&dir.join(name), &image())),
    )
}

/// Writes into a fresh sibling temp folder, then moves the files into `out`: a failure midway
/// leaves `out` untouched. `write` records the names it wrote (each one of [`OUTPUT_FILES`]);
/// afterwards the outputs of [`OUTPUT_FILES`] it did not write are removed from `out` (stale files
/// of an earlier run), and nothing else is touched.
fn write_outputs<'a>(
    out: &Path,
    write: impl FnOnce(&Path, &mut Vec<&'a str>) -> Result<(), InputError>,
    written: &mut Vec<&'a str>,
) -> Result<(), InputError> {
    let err = |p: &Path, e: std::io::Error| {
        InputError::new(p.display().to_string(), "output folder", "", e.to_string())
    };
    std::fs::create_dir_all(out).map_err(|e| err(out, e))?;
    let staging = out.join(format!(".staging-{}", std::process::id()));
    std::fs::create_dir_all(&staging).map_err(|e| err(&staging, e))?;
    let result = write(&staging, written);
    let moved = result.and_then(|()| {
        for name in written.iter() {
            debug_assert!(OUTPUT_FILES.contains(name), "{name} not in OUTPUT_FILES");
            std::fs::rename(staging.join(name), out.join(name)).map_err(|e| err(out, e))?;
        }
        for stale in OUTPUT_FILES.iter().filter(|n| !written.contains(n)) {
            let path = out.join(stale);
            if path.symlink_metadata().is_ok_and(|m| m.is_file()) {
                std::fs::remove_file(&path).map_err(|e| err(&path, e))?;
            }
        }
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&staging);
    moved
}

/// The phase line of the summary: every phase's wall seconds, their sum and the run's wall time
/// so far (the rest is argument parsing and the output folder's set-up).
fn phases_text(phases: &[(&str, f64)], accounted: f64, wall: f64, gpu: &GpuOutcome) -> String {
    let list: Vec<String> = phases
        .iter()
        .map(|(name, t)| format!("{} {t:.2} s", name.replace('_', " ")))
        .collect();
    let alternatives = match gpu {
        GpuOutcome::Rendered(g) => format!(
            "; alternatives: {} reference frame(s) drawn at {} pixel(s) only",
            g.phases.alternative_frames, g.phases.alternative_pixels
        ),
        _ => String::new(),
    };
    format!(
        "phases: {}; sum {accounted:.2} s of {wall:.2} s wall{alternatives}\n",
        list.join(", ")
    )
}

/// The resident-memory line of the summary: the process's peak and the first phase at whose end
/// it had been reached (empty where memory cannot be sampled).
fn resident_text(resident: &[(&str, Option<Resident>)]) -> String {
    let Some(peak) = resident
        .iter()
        .filter_map(|(_, r)| r.map(|r| r.peak_mb))
        .reduce(f64::max)
    else {
        return String::new();
    };
    let phase = resident
        .iter()
        .find(|(_, r)| r.is_some_and(|r| r.peak_mb >= peak))
        .map_or("", |(name, _)| name);
    let list: Vec<String> = resident
        .iter()
        .filter_map(|&(name, r)| Some(format!("{} {:.0}", name.replace('_', " "), r?.rss_mb)))
        .collect();
    let mut cpu = Vec::new();
    let mut last = 0.0;
    for &(name, r) in resident {
        if let Some(r) = r {
            cpu.push(format!("{} {:.2}", name.replace('_', " "), r.cpu_s - last));
            last = r.cpu_s;
        }
    }
    format!(
        "resident memory: peak {peak:.0} MB, reached by the end of {}; MB resident after each phase: {}\ncpu seconds (user + system, all threads) per phase: {}; total {last:.2}\n",
        phase.replace('_', " "),
        list.join(", "),
        cpu.join(", ")
    )
}

/// A few human-readable lines from the metrics.
pub fn summary_text(m: &serde_json::Value) -> String {
    let f = |path: &str| m.pointer(path).cloned().unwrap_or_default();
    let refine = match m.pointer("/refine").filter(|r| !r.is_null()) {
        Some(r) => format!(
            "refine (--tree-cull {}): {} trees tested one by one, {} kept, {:.4} s\n",
            f("/params/tree_cull").as_str().unwrap_or("?"),
            r["trees_tested"],
            r["trees_kept"],
            f("/times_seconds/frame/refine").as_f64().unwrap_or(0.0),
        ),
        None => String::new(),
    };
    let text = format!(
        "forestlod reference render: scene {} ({} trees, {} batches), camera {} at {}x{}\n\
         selection: {} commands ({} LOD0, {} LOD1, {} far), {} batches in the fade band, {} culled by distance, {} by frustum\n\
         draw: {} triangles, {} fragments written (overdraw {:.2}), {} trees beyond the draw distance, {} points\n\
         time: prepare {:.3} s (bake {:.3} s), select {:.4} s, draw {:.3} s\n\
         memory: {} bytes (E Eq. 4.1 gives {} bytes)\n",
        f("/scene"),
        f("/trees"),
        f("/batches"),
        f("/camera"),
        f("/viewport/0"),
        f("/viewport/1"),
        f("/selection/commands"),
        f("/selection/lod0_commands"),
        f("/selection/lod1_commands"),
        f("/selection/commands").as_u64().unwrap_or(0)
            - f("/selection/lod0_commands").as_u64().unwrap_or(0)
            - f("/selection/lod1_commands").as_u64().unwrap_or(0),
        f("/selection/transition_batches"),
        f("/selection/culled_distance"),
        f("/selection/culled_frustum"),
        f("/draw/triangles"),
        f("/draw/fragments_written"),
        f("/draw/overdraw").as_f64().unwrap_or(0.0),
        f("/draw/trees_discarded_by_draw_distance"),
        f("/draw/points_drawn"),
        f("/times_seconds/prepare/bake").as_f64().unwrap_or(0.0)
            + f("/times_seconds/prepare/batches").as_f64().unwrap_or(0.0)
            + f("/times_seconds/prepare/mesh_mips")
                .as_f64()
                .unwrap_or(0.0),
        f("/times_seconds/prepare/bake").as_f64().unwrap_or(0.0),
        f("/times_seconds/frame/select").as_f64().unwrap_or(0.0),
        f("/times_seconds/frame/draw").as_f64().unwrap_or(0.0),
        f("/memory_bytes/total"),
        f("/memory_bytes/eq41"),
    );
    text + &refine
}

#[cfg(test)]
mod tests {
    use super::*;
    use forestlod_harness::image_compare::compare_images;
    use forestlod_reference::draw::LOD_ID_TERRAIN;

    /// A GPU outcome whose colour differs from the reference's in `bad` of 16x16 pixels.
    fn rendered(bad: usize) -> GpuOutcome {
        let (w, h) = (16u32, 16u32);
        let n = (w * h) as usize;
        let reference = Images {
            width: w,
            height: h,
            color: vec![[90, 90, 90, 255]; n],
            depth: vec![0.5; n],
            lod_id: vec![LOD_ID_TERRAIN; n],
        };
        let mut gpu = reference.clone();
        for i in 0..bad {
            gpu.color[(i * 37) % n] = [255, 0, 255, 255];
        }
        let camera = Camera::look_at([0.0, 0.0, 10.0], [100.0, 0.0, 0.0], 60.0, w, h);
        let report = compare_images("unit", &gpu, &reference, &[], &camera);
        GpuOutcome::Rendered(Box::new(GpuRender {
            adapter: "test".into(),
            images: gpu,
            report,
            calls: forestlod_gpu::DrawCalls {
                terrain: 1,
                trees: 1,
                mode: forestlod_gpu::IndirectMode::Count,
                max_commands: 0,
            },
            from_cpu: StagesFromCpu::default(),
            seconds: 0.0,
            phases: GpuPhases::default(),
        }))
    }

    #[test]
    fn exit_codes_follow_the_outcome() {
        let passed = rendered(0);
        let failed = rendered(200);
        for (outcome, code, start) in [
            (&GpuOutcome::NotRequested, 0, "GPU parity not judged"),
            (
                &GpuOutcome::Skipped("no adapter\n  (wgpu: none)".into()),
                4,
                "GPU parity skipped: ",
            ),
            (
                &GpuOutcome::Failed {
                    adapter: "a".into(),
                    error: "Validation Error\n\nCaused by:\n  bad".into(),
                },
                3,
                "GPU error: ",
            ),
            (&passed, 0, "GPU parity PASSED"),
            (&failed, 2, "GPU parity FAILED"),
        ] {
            assert_eq!(outcome.exit_code(), code);
            let v = outcome.verdict();
            assert!(v.starts_with(start), "{v}");
            assert!(v.ends_with(&format!("[exit {code}]")), "{v}");
            assert!(!v.contains('\n'), "{v:?}");
            assert!(!parity_text(outcome).contains("skipped"));
        }
        assert_eq!(
            exit_code::GPU_SKIPPED,
            GpuOutcome::Skipped(String::new()).exit_code()
        );
    }

    #[test]
    fn one_line_collapses_newlines() {
        assert_eq!(one_line("a\n\n  b\r\nc "), "a b c");
    }
}
