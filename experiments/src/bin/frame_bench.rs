//! Frame time and throughput of the reference renderer for the main job's frame (`synthetic`,
//! camera `medium`, 1280x720), at 1 and 2 rayon threads, side by side in one run.
//!
//! `cargo run --release -p forestlod-experiments --bin frame_bench -- --out out/frame_bench`
//! writes `frame_bench.csv` (one row per repetition) and prints the medians. Mpixel/s counts the
//! viewport's pixels per second of the per-frame path (selection plus draw).

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use forestlod_experiments::metrics::median;
use forestlod_experiments::options::{ParamArgs, SceneArgs};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    params: ParamArgs,
    /// Named camera.
    #[arg(long, default_value = "medium")]
    camera: String,
    /// Viewport width.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Viewport height.
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Repetitions per thread count (after one warm-up frame).
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Thread counts to compare.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Output folder.
    #[arg(long, default_value = "out/frame_bench")]
    out: PathBuf,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let params = args.params.params()?;
    let scene = args.scene.load()?;
    let camera = named_camera(&args.camera, &scene, 0.0, args.width, args.height)?;
    let prepared = prepare(scene, &params)?;
    let mut csv =
        String::from("threads,rep,select_s,draw_s,frame_s,mpixel_per_s,fragments_written\n");
    let pixels = args.width as f64 * args.height as f64;
    let mut medians = Vec::new();
    for &threads in &args.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        let mut frames = Vec::new();
        for rep in 0..=args.reps {
            let t = Instant::now();
            let frame = pool.install(|| prepared.render(&camera, &params))?;
            let seconds = t.elapsed().as_secs_f64();
            if rep == 0 {
                continue; // warm-up
            }
            frames.push(seconds);
            csv.push_str(&format!(
                "{threads},{rep},{:.6},{:.6},{seconds:.6},{:.3},{}\n",
                frame.timings.select,
                frame.timings.draw,
                pixels / seconds / 1e6,
                frame.drawn.tree_stats.fragments_written
            ));
        }
        let m = median(frames);
        println!(
            "{threads} thread(s): median frame {m:.3} s, {:.3} Mpixel/s",
            pixels / m / 1e6
        );
        medians.push((threads, m));
    }
    if let (Some(first), Some(last)) = (medians.first(), medians.last()) {
        println!(
            "speed-up {} -> {} threads: {:.2}x",
            first.0,
            last.0,
            first.1 / last.1
        );
    }
    std::fs::create_dir_all(&args.out)?;
    std::fs::write(args.out.join("frame_bench.csv"), csv)?;
    println!("wrote {}", args.out.join("frame_bench.csv").display());
    Ok(())
}
