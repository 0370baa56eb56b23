//! `truth_bench`: what the ground truth's BVH costs to build, hold and trace, per layout
//! ([`TruthLayout::Trees`], one primitive per tree, the default; [`TruthLayout::Triangles`], one
//! per triangle, the first design), side by side in one run (issue 14).
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin truth_bench -- \
//!     --scenes tiny,synthetic,patchy,stress --out experiments/results/truth_bvh
//! ```
//!
//! For each scene and layout: build seconds, the truth's own bytes
//! ([`GroundTruthScene::memory_bytes`]), the process's peak resident memory during the build and
//! the render (Linux `VmHWM`, reset before each layout through `/proc/self/clear_refs`), and the
//! seconds to trace the `medium` and `close` frames at `--width` x `--height` with `--samples`²
//! rays per pixel; the images of the two layouts must be bit-identical (the run fails otherwise).
//! Writes `truth_bench.csv` and `truth_bench_{peak_mb,build_s,trace_s}.png` (peak memory, build and trace seconds against the
//! cluster size, one line per scene). See `experiments/truth_bvh/README.md`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use forestlod_experiments::plot::{Axes, Series, Style, xy_plot};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::ground_truth::{GroundTruthImage, GroundTruthScene, TruthLayout};
use forestlod_reference::scene::builtin;

#[derive(Parser, Debug)]
struct Args {
    /// Scenes to run.
    #[arg(long, value_delimiter = ',', default_value = "tiny,synthetic")]
    scenes: Vec<String>,
    /// Layouts to run, in this order: `trees`, `triangles`, or a cluster size (triangles of one
    /// tree per BVH primitive at most).
    #[arg(long, value_delimiter = ',', default_value = "trees,4,triangles")]
    layouts: Vec<String>,
    /// Frame width.
    #[arg(long, default_value_t = 160)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 90)]
    height: u32,
    /// Samples per pixel side.
    #[arg(long, default_value_t = 2)]
    samples: u32,
    /// Output folder.
    #[arg(long, default_value = "out/truth_bench")]
    out: PathBuf,
    /// Only draw the plots again from the `truth_bench.csv` in `--out` (no scene is built).
    #[arg(long)]
    plot_only: bool,
}

/// Peak resident memory of this process since the last reset, bytes (Linux; 0 elsewhere).
fn peak_rss() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// Resets the peak resident memory to the current one (Linux `clear_refs` value 5).
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    if args.plot_only {
        let points = points_from_csv(&args.out.join("truth_bench.csv"))?;
        plot(&args.out, &points)?;
        return Ok(());
    }
    let layouts = args
        .layouts
        .iter()
        .map(|l| match l.as_str() {
            "trees" => Ok(TruthLayout::TREES),
            "triangles" => Ok(TruthLayout::TRIANGLES),
            n => match n.parse::<u32>() {
                Ok(k) if k >= 1 => Ok(TruthLayout { max_triangles: k }),
                _ => Err(format!(
                    "--layouts: {n:?} is not a layout (trees, triangles, or a cluster size >= 1)"
                )),
            },
        })
        .collect::<Result<Vec<_>, _>>()?;
    std::fs::create_dir_all(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let csv_path = args.out.join("truth_bench.csv");
    let mut csv =
        std::fs::File::create(&csv_path).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    writeln!(
        csv,
        "scene,cluster_triangles,trees,triangles,primitives,build_s,truth_bytes,peak_rss_bytes,\
         width,height,samples,medium_s,close_s,rays"
    )?;
    let mut mismatches = 0;
    // Per scene: (cluster size, peak MB, build s, trace s) of each layout.
    let mut points: Vec<ScenePoints> = Vec::new();
    for name in &args.scenes {
        let scene = builtin::by_name(name)?;
        let mut first: Option<Vec<GroundTruthImage>> = None;
        points.push((name.clone(), Vec::new()));
        for &layout in &layouts {
            reset_peak_rss();
            let gt = GroundTruthScene::build_with(&scene, 0.5, layout)?;
            let mut images = Vec::new();
            let mut seconds = Vec::new();
            let mut rays = 0;
            for camera_name in ["medium", "close"] {
                let camera = named_camera(camera_name, &scene, 0.0, args.width, args.height)?;
                let start = Instant::now();
                let image = gt.render(&camera, args.samples);
                seconds.push(start.elapsed().as_secs_f64());
                rays += image.rays;
                images.push(image);
            }
            let peak = peak_rss();
            let line = format!(
                "{name},{},{},{},{},{:.3},{},{},{},{},{},{:.3},{:.3},{rays}",
                layout.max_triangles,
                scene.instances.len(),
                gt.triangle_count(),
                gt.primitive_count(),
                gt.build_seconds(),
                gt.memory_bytes(),
                peak,
                args.width,
                args.height,
                args.samples,
                seconds[0],
                seconds[1],
            );
            println!("{line}");
            points.last_mut().expect("pushed").1.push([
                layout.max_triangles as f64,
                peak as f64 / 1e6,
                gt.build_seconds(),
                seconds[0] + seconds[1],
            ]);
            writeln!(csv, "{line}")?;
            drop(gt);
            match &first {
                None => first = Some(images),
                Some(reference) if *reference != images => {
                    eprintln!("{name}: the {layout:?} layout's images differ from the first's");
                    mismatches += 1;
                }
                Some(_) => {}
            }
        }
    }
    plot(&args.out, &points)?;
    println!("wrote {}", csv_path.display());
    if mismatches > 0 {
        return Err(format!("{mismatches} scene(s) whose layouts gave different images").into());
    }
    Ok(())
}

/// A scene and its rows of (cluster size, peak MB, build s, trace s), one per layout.
type ScenePoints = (String, Vec<[f64; 4]>);

/// Draws `truth_bench_*.png` in `out`: per scene, rows of (cluster size, peak MB, build s, trace s).
fn plot(out: &std::path::Path, points: &[ScenePoints]) -> Result<(), String> {
    for (k, what, file) in [
        (1, "peak resident memory, MB", "peak_mb"),
        (2, "BVH build, s", "build_s"),
        (3, "medium + close trace, s", "trace_s"),
    ] {
        let series: Vec<Series> = points
            .iter()
            .map(|(scene, rows)| Series {
                label: scene.clone(),
                points: rows.iter().map(|r| (r[0], r[k])).collect(),
            })
            .collect();
        let mut axes = Axes::linear(
            format!("truth BVH: {what}"),
            "triangles per BVH primitive (1 = one per triangle)",
            what,
        );
        axes.log_x = true;
        axes.log_y = true;
        let path = out.join(format!("truth_bench_{file}.png"));
        xy_plot(&path, &axes, &series, Style::Lines)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// The plot points of a `truth_bench.csv`, by scene in file order.
fn points_from_csv(path: &std::path::Path) -> Result<Vec<ScenePoints>, String> {
    // A CSV this program wrote (`--replot`): regular file, 64 MiB at most (issue 28).
    let text =
        forestlod_reference::files::read_text_limited(path, 64 << 20).map_err(|e| e.to_string())?;
    let mut points: Vec<ScenePoints> = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let num = |k: usize| -> Result<f64, String> {
            f.get(k).and_then(|v| v.parse::<f64>().ok()).ok_or_else(|| {
                format!(
                    "{}: line {}: column {k} is not a number",
                    path.display(),
                    i + 1
                )
            })
        };
        let row = [num(1)?, num(7)? / 1e6, num(5)?, num(11)? + num(12)?];
        match points.last_mut() {
            Some((scene, rows)) if scene == f[0] => rows.push(row),
            _ => points.push((f[0].to_string(), vec![row])),
        }
    }
    Ok(points)
}
