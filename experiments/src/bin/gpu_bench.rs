//! Per-stage GPU times of the wgpu twin beside the reference's times for the same frames:
//! `synthetic` and `stress` at the named cameras `far`, `medium`, `close` (E§5.0.1).
//!
//! `cargo run --release -p forestlod-experiments --bin gpu_bench -- --out out/gpu_bench`
//!
//! The GPU side is the one GPU frame (`forestlod_harness::gpu_frame::GpuScene`), so every
//! pipeline parameter counts as it does in `render`: the selection stages of the frame's plan
//! (`--hierarchy`, `--coalesce`, `--command-order`) and `refine` (`--tree-cull`), whose time is
//! part of the selection's, as in the sweeps.
//!
//! Each GPU stage is timed two ways, median of `--reps` repetitions after one warm-up: wall time
//! from submit to completion (`device.poll(wait)`), and, where the adapter offers
//! `TIMESTAMP_QUERY`, GPU time between timestamps written by empty compute passes recorded just
//! before and just after the stage in the same command encoder. The reference stages are timed in
//! the same process on the same frames: one frame by default (the reference draw of `stress`
//! takes seconds), or the median of `--ref-reps` frames after one warm-up, as the GPU's. Writes `gpu_bench.csv`, one row per (scene, size, camera), and, when the reference
//! draws, `draw_ratio.png`: the reference draw time over the GPU's per frame (issue 14: the
//! reference at least as fast as lavapipe means every bar at or below 1).
//!
//! Issue 14's runs (`experiments/results/raster_speed/`):
//! `gpu_bench --sizes 320x180,1280x720 --reps 1 --out <folder>` (sessions 7-10), and from
//! session 11 `gpu_bench --sizes 320x180,1280x720 --reps 3 --ref-reps 3 --out <folder>`.

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use forestlod_experiments::metrics::median;
use forestlod_experiments::options::ParamArgs;
use forestlod_gpu::{Compaction, GpuContext, GpuDraw};
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, GpuTimedFrame, StagesFromCpu};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    params: ParamArgs,
    /// Scenes to run.
    #[arg(long, value_delimiter = ',', default_value = "synthetic,stress")]
    scenes: Vec<String>,
    /// Viewport width.
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Viewport height.
    #[arg(long, default_value_t = 180)]
    height: u32,
    /// Viewport sizes `WxH`, comma-separated, every scene run at each; replaces `--width` and
    /// `--height`.
    #[arg(long, value_delimiter = ',', value_parser = parse_size)]
    sizes: Option<Vec<(u32, u32)>>,
    /// Named cameras to run, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "far,medium,close")]
    cameras: Vec<String>,
    /// GPU repetitions per stage (median reported).
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Output folder.
    #[arg(long, default_value = "out/gpu_bench")]
    out: PathBuf,
    /// Reference frames timed per (scene, size, camera), median reported. With more than one,
    /// the timed frames follow one untimed warm-up frame, as the GPU's do; with one (the
    /// default), the first frame is the timed one (runs before session 11, issue 14).
    #[arg(long, default_value_t = 1)]
    ref_reps: usize,
    /// Skip the reference's draw (its selection is still timed): for large frames on a real GPU,
    /// where the reference would take minutes per frame (`scripts/gpu-check`). Its columns are
    /// then empty.
    #[arg(long)]
    no_reference: bool,
}

/// `WxH` as a viewport size, each side in `1..=16384` (the render targets' limit).
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("--sizes: value {s:?}: expected WIDTHxHEIGHT, e.g. 320x180");
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let side = |v: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|n| (1..=forestlod_reference::raster::MAX_TARGET_SIZE).contains(n))
            .ok_or_else(bad)
    };
    Ok((side(w)?, side(h)?))
}

fn median_opt(v: Vec<Option<f64>>) -> Option<f64> {
    let v: Vec<f64> = v.into_iter().flatten().collect();
    (!v.is_empty()).then(|| median(v))
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or_else(String::new, |s| format!("{s:.6}"))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let params = args.params.params()?;
    let ctx = GpuContext::new()?;
    println!("adapter: {}", ctx.describe());
    let draw = GpuDraw::new(&ctx)?;
    let mut csv = String::from(
        "adapter,scene,camera,width,height,commands,ref_select_s,gpu_select_stable_s,gpu_select_atomic_s,ref_draw_s,gpu_draw_s,gpu_select_stable_timestamp_s,gpu_draw_timestamp_s,select_ratio_ref_over_gpu,draw_ratio_ref_over_gpu\n",
    );
    let sizes = args
        .sizes
        .clone()
        .unwrap_or(vec![(args.width, args.height)]);
    let (mut groups, mut ratios) = (Vec::new(), Vec::new());
    for name in &args.scenes {
        let scene = builtin::by_name(name)?;
        let prepared = prepare(scene, &params)?;
        // The GPU frame (`forestlod_harness::gpu_frame`): the plan's selection stages (flat, or
        // the cut with its coalesce and order; the cut has the stable order only, so its
        // "atomic" column times it again), `refine` when `--tree-cull` asks, then the draw.
        let mut frame =
            GpuScene::with_pipelines(&ctx, &draw, &prepared, &params, StagesFromCpu::NONE)?;
        for &(width, height) in &sizes {
            for camera_name in &args.cameras {
                let camera_name = camera_name.as_str();
                let camera = named_camera(camera_name, &prepared.scene, 0.0, width, height)?;
                // `reps` frames after one warm-up, each stage timed from submit to completion
                // and, where offered, between timestamps.
                let mut timed =
                    |compaction| -> Result<Vec<GpuTimedFrame>, Box<dyn std::error::Error>> {
                        let mut frames = Vec::new();
                        for rep in 0..=args.reps {
                            let f = frame.render(
                                &prepared,
                                GpuPipeline::Ours(compaction),
                                &camera,
                                &params,
                            )?;
                            if rep > 0 {
                                frames.push(f);
                            }
                        }
                        Ok(frames)
                    };
                let atomic = timed(Compaction::Atomic)?;
                let stable = timed(Compaction::Stable)?;
                let select_atomic = median(atomic.iter().map(|f| f.select_s).collect());
                let select_stable = median(stable.iter().map(|f| f.select_s).collect());
                let gpu_draw = median(stable.iter().map(|f| f.draw_s).collect());
                let ts_select = median_opt(stable.iter().map(|f| f.gpu_select_s).collect());
                let ts_draw = median_opt(stable.iter().map(|f| f.gpu_draw_s).collect());
                let (commands, ref_select, ref_draw) = if args.no_reference {
                    let start = Instant::now();
                    let (selection, _) = prepared.select_refined(&camera, &params);
                    let seconds = start.elapsed().as_secs_f64();
                    (selection.counters.commands, seconds, None)
                } else {
                    // Untimed warm-up frame first when several are timed (`--ref-reps`).
                    let warm_up = usize::from(args.ref_reps > 1);
                    let (mut selects, mut draws, mut commands) = (Vec::new(), Vec::new(), 0);
                    for rep in 0..warm_up + args.ref_reps.max(1) {
                        let frame = prepared.render(&camera, &params)?;
                        commands = frame.selection.counters.commands;
                        if rep >= warm_up {
                            selects.push(frame.timings.select);
                            draws.push(frame.timings.draw);
                        }
                    }
                    (commands, median(selects), Some(median(draws)))
                };
                println!(
                    "{name} {width}x{height} {camera_name}: {commands} commands | select ref {:.3} ms, gpu stable {:.3} ms (timestamps {:?} ms), atomic {:.3} ms | draw ref {:?} ms, gpu {:.1} ms (timestamps {:?} ms)",
                    ref_select * 1e3,
                    select_stable * 1e3,
                    ts_select.map(|s| s * 1e3),
                    select_atomic * 1e3,
                    ref_draw.map(|s| s * 1e3),
                    gpu_draw * 1e3,
                    ts_draw.map(|s| s * 1e3)
                );
                csv.push_str(&format!(
                "\"{}\",{name},{camera_name},{},{},{commands},{ref_select:.6},{select_stable:.6},{select_atomic:.6},{},{gpu_draw:.6},{},{},{:.3},{}\n",
                ctx.info.name.replace(',', ";"),
                width,
                height,
                fmt_opt(ref_draw),
                fmt_opt(ts_select),
                fmt_opt(ts_draw),
                ref_select / select_stable,
                ref_draw.map_or_else(String::new, |d| format!("{:.3}", d / gpu_draw))
            ));
                if let Some(d) = ref_draw {
                    // Short labels ("syn 320 med") so that the bars' names fit under them.
                    let short = |s: &str| s.chars().take(3).collect::<String>();
                    groups.push(format!("{} {width} {}", short(name), short(camera_name)));
                    ratios.push(vec![d / gpu_draw]);
                }
            }
        }
    }
    std::fs::create_dir_all(&args.out)?;
    std::fs::write(args.out.join("gpu_bench.csv"), csv)?;
    println!("wrote {}", args.out.join("gpu_bench.csv").display());
    if !ratios.is_empty() {
        // One bar per frame, in CSV row order (the frames' names are too long for the x axis).
        let plot = args.out.join("draw_ratio.png");
        forestlod_experiments::plot::bar_plot(
            &plot,
            &forestlod_experiments::plot::Axes::linear(
                "reference draw / GPU draw (wall)".into(),
                "scene, width, camera (CSV row order)",
                "ratio",
            ),
            &groups,
            &["ref / gpu".to_string()],
            &ratios,
        )?;
        println!("wrote {}", plot.display());
    }
    Ok(())
}
