//! The main job (`forestlod render`, and `cargo run --release` with no arguments): render one frame
//! of a scene with the reference pipeline and write colour, depth, the LOD-id view, the baked
//! billboard atlas, a metrics JSON and a short summary into an output folder.
//!
//! When wgpu finds an adapter (`forestlod_gpu::GpuContext::new`), the same frame is also rendered
//! by the GPU twin (`gpu/src/shaders/select.wgsl` then `draw.wgsl`; `--stage-from-cpu` chooses
//! which GPU stages take their input from the reference instead, as vello's `force_gpu_from`) and
//! judged against the reference with `forestlod_tests::image_compare` (SPEC §8): `gpu_color.png`,
//! `gpu_lod.png` and `diff.png` are written beside the reference's images, and the metrics and the
//! summary gain a `parity` section (adapter, maximum differences per buffer, mismatch and
//! ambiguity counts, FLIP mean). Without an adapter the summary says `GPU: no adapter` and the job
//! still succeeds; a parity failure is reported, not turned into an error.
//!
//! Everything is computed before anything is written, so a failure leaves the output folder as it
//! was.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;
use forestlod_reference::InputError;
use forestlod_reference::bake::contact_sheet;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::output::{depth_preview, lod_id_image, write_depth_exr, write_png};
use forestlod_reference::pipeline::{Frame, Prepared, prepare};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use forestlod_gpu::{GpuContext, GpuDraw};
use forestlod_shared::{Camera, Params};
use forestlod_tests::backend::{StagesFromCpu, alpha_test_alternatives, render_gpu};
use forestlod_tests::image_compare::{
    ClassCounts, ImageReport, Images, class_image, compare_images, difference_image,
};

use crate::options::{ParamArgs, SceneArgs};

/// Options of the main job.
#[derive(Args, Clone, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub params: ParamArgs,
    /// Named camera: far, medium, close (E§5.0.1).
    #[arg(long, default_value = "medium")]
    pub camera: String,
    /// Horizontal rotation of the camera, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw: f32,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// GPU stages that take their input from the reference twin instead of the GPU stage before
    /// them: a comma-separated list of `select` (draw the reference's selection) and `textures`
    /// (sample the reference's mesh mips and billboard bake), or `none` (all on the GPU).
    #[arg(long, default_value = "none")]
    pub stage_from_cpu: String,
    /// Skip the GPU twin even when an adapter exists.
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

/// The metrics JSON of one frame.
pub fn metrics(
    prepared: &Prepared,
    frame: &Frame,
    args: &RenderArgs,
    scene_seconds: f64,
) -> serde_json::Value {
    let drawn = &frame.drawn;
    let pixels = (args.width as u64 * args.height as u64).max(1);
    let trees = drawn.tree_stats;
    let c = frame.selection.counters;
    json!({
        "scene": prepared.scene.name,
        "camera": args.camera, "yaw_degrees": args.yaw,
        "viewport": [args.width, args.height],
        "params": {
            "grid_size": args.params.grid_size, "angles": args.params.angles, "texture_size": args.params.texture_size,
            "lod_levels": args.params.lod_levels, "transition": args.params.transition, "fade_width": args.params.fade_width,
            "draw_distance": args.params.draw_distance, "fade_mode": args.params.fade_mode, "mip_mode": args.params.mip_mode,
            "angle_index": args.params.angle_index, "tree_cull": args.params.tree_cull,
        },
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
    /// No adapter (or `--no-gpu`): the reason, for the summary.
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
    let ctx = match GpuContext::new() {
        Ok(ctx) => ctx,
        Err(e) => return GpuOutcome::Skipped(format!("no adapter ({e})")),
    };
    let adapter = ctx.describe();
    let failed = |e: String| GpuOutcome::Failed {
        adapter: adapter.clone(),
        error: e,
    };
    let t = Instant::now();
    let draw = match GpuDraw::new(&ctx) {
        Ok(d) => d,
        Err(e) => return failed(e.to_string()),
    };
    let gpu = match render_gpu(&ctx, &draw, prepared, camera, params, from_cpu) {
        Ok(g) => g,
        Err(e) => return failed(e.to_string()),
    };
    let seconds = t.elapsed().as_secs_f64();
    let target = &frame.drawn.target;
    let reference = Images {
        width: target.width(),
        height: target.height(),
        color: target.color().to_vec(),
        depth: target.depth().to_vec(),
        lod_id: target.aux().to_vec(),
    };
    let alternatives = alpha_test_alternatives(prepared, camera, params);
    let report = compare_images(name, &gpu.images, &reference, &alternatives, camera);
    GpuOutcome::Rendered(Box::new(GpuRender {
        adapter,
        images: gpu.images,
        report,
        calls: gpu.calls,
        from_cpu,
        seconds,
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
    use forestlod_tests::image_compare as ic;
    match outcome {
        GpuOutcome::Skipped(why) => json!({ "gpu": why }),
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
                "tolerances": {
                    "color": ic::COLOR_TOLERANCE, "edge_color_margin": ic::EDGE_COLOR_MARGIN,
                    "depth_ulps": ic::DEPTH_MAX_ULPS, "depth_edge_rel": ic::DEPTH_EDGE_REL,
                    "alpha_test_shifts": ic::ALPHA_TEST_SHIFTS, "depth_tie_max_fraction": ic::DEPTH_TIE_MAX_FRACTION,
                    "compound_max_fraction": ic::MAX_COMPOUND_FRACTION,
                    "flip_mean_max": ic::FLIP_MEAN_MAX,
                },
            })
        }
    }
}

/// The summary lines of the GPU side.
pub fn parity_text(outcome: &GpuOutcome) -> String {
    match outcome {
        GpuOutcome::Skipped(why) => format!("GPU: {why}\n"),
        GpuOutcome::Failed { adapter, error } => format!("GPU ({adapter}): failed: {error}\n"),
        GpuOutcome::Rendered(g) => {
            let r = &g.report;
            let verdict = if r.passed() {
                "PASSED".to_string()
            } else {
                format!("FAILED ({})", r.failures().join("; "))
            };
            format!(
                "GPU: {} ({} s, stages from the reference: {}, {} CPU draw call(s) for all trees via {})\n\
                 parity {verdict}: FLIP mean {:.4}; colour max diff {} ({} after the ±1 px window, {} on interior pixels), \
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

/// The main job.
pub fn run(args: &RenderArgs) -> Result<(), Box<dyn std::error::Error>> {
    let params = args.params.params()?;
    let from_cpu = StagesFromCpu::parse(&args.stage_from_cpu).map_err(|e| {
        InputError::new(
            "<command line>",
            "--stage-from-cpu",
            &args.stage_from_cpu,
            e,
        )
    })?;
    let (scene, scene_seconds) = stage("loading scene", || args.scene.load());
    let scene = scene?;
    let camera = named_camera(&args.camera, &scene, args.yaw, args.width, args.height)?;
    camera.validate()?;
    let (prepared, _) = stage("batches, mips and billboard bake", || {
        prepare(scene, &params)
    });
    let prepared = prepared?;
    let (frame, _) = stage("selection and reference draw", || {
        prepared.render(&camera, &params)
    });
    let frame = frame?;

    let gpu = if args.no_gpu {
        GpuOutcome::Skipped("skipped (--no-gpu)".into())
    } else {
        let name = format!("{}-{}", prepared.scene.name, args.camera);
        let (outcome, _) = stage("GPU twin (select + draw) and parity", || {
            gpu_frame(&prepared, &frame, &camera, &params, from_cpu, &name)
        });
        outcome
    };

    let mut metrics = metrics(&prepared, &frame, args, scene_seconds);
    metrics["parity"] = parity_json(&gpu);
    let target = &frame.drawn.target;
    let (w, h) = (target.width(), target.height());
    let summary = format!("{}{}", summary_text(&metrics), parity_text(&gpu));
    write_outputs(&args.out, |dir| {
        write_png(&dir.join("color.png"), &target.color_image())?;
        write_depth_exr(&dir.join("depth.exr"), w, h, target.depth())?;
        write_png(
            &dir.join("depth_preview.png"),
            &depth_preview(w, h, target.depth()),
        )?;
        write_png(&dir.join("lod.png"), &lod_id_image(w, h, target.aux()))?;
        write_png(
            &dir.join("atlas.png"),
            &contact_sheet(&prepared.billboards, prepared.scene.meshes.len()),
        )?;
        if let GpuOutcome::Rendered(g) = &gpu {
            let reference = Images {
                width: w,
                height: h,
                color: target.color().to_vec(),
                depth: Vec::new(),
                lod_id: Vec::new(),
            };
            write_png(&dir.join("gpu_color.png"), &g.images.color_image())?;
            write_png(&dir.join("gpu_lod.png"), &g.images.lod_image())?;
            write_png(&dir.join("parity_classes.png"), &class_image(&g.report))?;
            write_png(
                &dir.join("diff.png"),
                &difference_image(&g.images, &reference),
            )?;
        }
        std::fs::write(
            dir.join("metrics.json"),
            serde_json::to_string_pretty(&metrics).unwrap_or_default(),
        )
        .map_err(|e| {
            InputError::new(
                dir.join("metrics.json").display().to_string(),
                "write",
                "",
                e.to_string(),
            )
        })?;
        std::fs::write(dir.join("summary.txt"), &summary).map_err(|e| {
            InputError::new(
                dir.join("summary.txt").display().to_string(),
                "write",
                "",
                e.to_string(),
            )
        })?;
        Ok(())
    })?;
    print!("{summary}");
    let gpu_files = if matches!(gpu, GpuOutcome::Rendered(_)) {
        "gpu_color.png, gpu_lod.png, diff.png, parity_classes.png, "
    } else {
        ""
    };
    println!(
        "wrote color.png, depth.exr, depth_preview.png, lod.png, atlas.png, {gpu_files}metrics.json, summary.txt to {}",
        args.out.display()
    );
    Ok(())
}

/// Writes into a fresh sibling temp folder, then moves the files into `out`: a failure midway
/// leaves `out` untouched.
fn write_outputs(
    out: &Path,
    write: impl FnOnce(&Path) -> Result<(), InputError>,
) -> Result<(), InputError> {
    let err = |p: &Path, e: std::io::Error| {
        InputError::new(p.display().to_string(), "output folder", "", e.to_string())
    };
    std::fs::create_dir_all(out).map_err(|e| err(out, e))?;
    let staging = out.join(format!(".staging-{}", std::process::id()));
    std::fs::create_dir_all(&staging).map_err(|e| err(&staging, e))?;
    let result = write(&staging);
    if result.is_ok() {
        for entry in std::fs::read_dir(&staging).map_err(|e| err(&staging, e))? {
            let entry = entry.map_err(|e| err(&staging, e))?;
            std::fs::rename(entry.path(), out.join(entry.file_name())).map_err(|e| err(out, e))?;
        }
    }
    let _ = std::fs::remove_dir_all(&staging);
    result
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
         selection: {} commands ({} LOD0, {} LOD1), {} batches in the fade band, {} culled by distance, {} by frustum\n\
         draw: {} triangles, {} fragments written (overdraw {:.2}), {} trees beyond the draw distance\n\
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
        f("/selection/transition_batches"),
        f("/selection/culled_distance"),
        f("/selection/culled_frustum"),
        f("/draw/triangles"),
        f("/draw/fragments_written"),
        f("/draw/overdraw").as_f64().unwrap_or(0.0),
        f("/draw/trees_discarded_by_draw_distance"),
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
