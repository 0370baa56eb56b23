//! Popping: how much a frame changes, from one frame to the next along a camera path, that the
//! motion itself does not explain (issue 12's temporal error), for each fade mode (E§4.4, G§4).
//!
//! The camera dollies towards the forest (`distance_camera`, the sweeps' distance path) so that
//! trees cross the fade band `[transition - fade width, transition]`. For each consecutive pair
//! of frames `(t, t + 1)` it renders, on the reference backend:
//! - the frame with LOD, `v_t`, and
//! - the full-detail frame `f_t` (the Vegetation baseline: every visible tree at full mesh,
//!   same camera, same one-sample rasterization),
//!
//! and scores the pair with `excess = mean over pixels of max(0, FLIP(v_t, v_t+1) − FLIP(f_t,
//! f_t+1))`: the change between the two LOD frames beyond the change between the two
//! full-detail frames at the same pixel. Motion and aliasing change both sequences alike and
//! cancel; what remains is change the LOD made, which is what a user sees as a pop (a hard
//! switch) or as shimmer (a dither moving its pixel sets). Its 99th percentile over pixels is
//! reported beside the mean because a single popping tree is a few hundred pixels of a frame.
//!
//! Why not against the ray-traced truth, as the issue suggests as one option: the truth has no
//! aliasing, the rasterized frames do, so `FLIP(v_t, v_t+1) − FLIP(truth_t, truth_t+1)` would
//! measure the foliage's temporal aliasing (the same for every fade mode) on top of the LOD's
//! change. The full-detail frame shares the aliasing, as the LOD error of the sweeps does.
//!
//! `cargo run --release -p forestlod-experiments --bin popping -- --out out/popping` writes
//! `popping.csv` (one row per mode and frame pair), `popping.png` (excess against the camera's
//! distance, one line per mode), `worst_<mode>.png` (the worst pair of each mode: LOD frames and
//! their change map on top, full-detail frames and theirs below) and `summary.md` (per mode:
//! mean excess with a 95% interval over pairs, the worst pair, and whether the modes differ
//! beyond the noise). `experiments/popping/README.md` reads the committed result.

use std::fmt::Write as _;
use std::path::PathBuf;

use clap::Parser;
use forestlod_experiments::metrics::{error_image, flip_map, percentile};
use forestlod_experiments::plot::{Axes, Series, Style, xy_plot};
use forestlod_experiments::report::{mean_ci, within_noise};
use forestlod_experiments::sweep::distance_camera;
use forestlod_reference::InputError;
use forestlod_reference::baselines::{render_vegetation, tree_spheres};
use forestlod_reference::error::COMMAND_LINE;
use forestlod_reference::output::write_png;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{FadeMode, Params};

#[derive(Parser, Debug)]
struct Args {
    /// Built-in scene.
    #[arg(long, default_value = "tiny")]
    scene: String,
    /// Fade modes to compare, comma-separated (none, alpha, dither, dither-sequential).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "none,dither-sequential,alpha"
    )]
    modes: Vec<String>,
    /// LOD1 transition distance, metres (the end of the fade band).
    #[arg(long, default_value_t = 150.0)]
    transition: f32,
    /// Fade band width, metres.
    #[arg(long, default_value_t = 50.0)]
    fade_width: f32,
    /// Batch grid cell, metres: small enough (50 m in a 200 m scene, as the quick sweeps) that
    /// batches, not the whole forest, cross the band.
    #[arg(long, default_value_t = 50.0)]
    grid_size: f32,
    /// Camera distance from the scene's centre at the first frame, metres.
    #[arg(long, default_value_t = 320.0)]
    from: f32,
    /// Camera distance at the last frame, metres.
    #[arg(long, default_value_t = 80.0)]
    to: f32,
    /// Frames along the path (pairs = frames - 1).
    #[arg(long, default_value_t = 61)]
    frames: u32,
    /// Viewport width.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Viewport height.
    #[arg(long, default_value_t = 360)]
    height: u32,
    /// Output folder.
    #[arg(long, default_value = "out/popping")]
    out: PathBuf,
}

/// One frame pair's scores.
struct Pair {
    /// Camera distance at the pair's first frame.
    distance: f32,
    /// Mean over pixels of the LOD's excess change.
    excess_mean: f64,
    /// 99th percentile over pixels of it.
    excess_p99: f64,
    /// Mean FLIP between the two LOD frames.
    lod_change: f64,
    /// Mean FLIP between the two full-detail frames.
    full_change: f64,
    /// LOD error of the pair's first frame: mean FLIP against its full-detail frame.
    lod_error: f64,
}

fn main() {
    if let Err(e) = run(&Args::parse()) {
        eprintln!("popping: {e}");
        std::process::exit(1);
    }
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    if args.frames < 2 {
        return Err(
            InputError::new(COMMAND_LINE, "--frames", args.frames, "expected at least 2").into(),
        );
    }
    let modes: Vec<FadeMode> = args
        .modes
        .iter()
        .map(|m| {
            FadeMode::from_name(m).ok_or_else(|| {
                InputError::new(
                    COMMAND_LINE,
                    "--modes",
                    m,
                    "expected none, alpha, dither or dither-sequential",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    let scene = builtin::by_name(&args.scene)?;
    let base = Params {
        lod1_transition: args.transition,
        fade_width: args.fade_width,
        grid_size: args.grid_size,
        ..Params::default()
    };
    base.validate().map_err(InputError::from)?;
    std::fs::create_dir_all(&args.out)?;
    let distances: Vec<f32> = (0..args.frames)
        .map(|i| args.from + (args.to - args.from) * i as f32 / (args.frames - 1) as f32)
        .collect();
    let cameras: Vec<_> = distances
        .iter()
        .map(|&d| distance_camera(&scene, d, args.width, args.height))
        .collect();
    for c in &cameras {
        c.validate().map_err(InputError::from)?;
    }

    // The full-detail sequence does not depend on the fade mode: render it once.
    let prepared = prepare(scene.clone(), &base)?;
    let spheres = tree_spheres(&prepared.scene, &prepared.geometry.meshes);
    let full: Vec<Rgba8Image> = cameras
        .iter()
        .map(|c| {
            render_vegetation(&prepared, &spheres, c, &base)
                .target
                .color_image()
        })
        .collect();
    let full_maps: Vec<Vec<f32>> = full.windows(2).map(|w| flip_map(&w[0], &w[1])).collect();

    let mut csv = String::from(
        "mode,pair,distance_m,excess_mean,excess_p99,lod_change,full_change,lod_error\n",
    );
    let mut summary = String::new();
    let mut series = Vec::new();
    let mut stats: Vec<(FadeMode, (f64, f64))> = Vec::new();
    let _ = writeln!(
        summary,
        "| fade mode | pairs | excess mean ±95% | excess p99 (mean) | worst pair (distance) | worst excess | LOD error ±95% |\n|---|--:|--:|--:|--:|--:|--:|"
    );
    for &mode in &modes {
        let params = Params {
            fade_mode: mode as u32,
            ..base
        };
        let prepared = prepare(scene.clone(), &params)?;
        let frames: Vec<Rgba8Image> = cameras
            .iter()
            .map(|c| {
                prepared
                    .render(c, &params)
                    .map(|f| f.drawn.target.color_image())
            })
            .collect::<Result<_, _>>()?;
        let mut pairs = Vec::new();
        let mut excess_maps = Vec::new();
        for t in 0..frames.len() - 1 {
            let lod_map = flip_map(&frames[t], &frames[t + 1]);
            let excess: Vec<f32> = lod_map
                .iter()
                .zip(&full_maps[t])
                .map(|(v, f)| (v - f).max(0.0))
                .collect();
            let n = excess.len().max(1) as f64;
            let mean = |m: &[f32]| m.iter().map(|&e| e as f64).sum::<f64>() / n;
            pairs.push(Pair {
                distance: distances[t],
                excess_mean: mean(&excess),
                excess_p99: percentile(&excess, 99.0),
                lod_change: mean(&lod_map),
                full_change: mean(&full_maps[t]),
                lod_error: mean(&flip_map(&full[t], &frames[t])),
            });
            excess_maps.push((lod_map, excess));
        }
        for (i, p) in pairs.iter().enumerate() {
            let _ = writeln!(
                csv,
                "{},{i},{},{},{},{},{},{}",
                mode.name(),
                p.distance,
                p.excess_mean,
                p.excess_p99,
                p.lod_change,
                p.full_change,
                p.lod_error
            );
        }
        let means: Vec<f64> = pairs.iter().map(|p| p.excess_mean).collect();
        let (mean, ci) = mean_ci(&means);
        let p99 = pairs.iter().map(|p| p.excess_p99).sum::<f64>() / pairs.len() as f64;
        let lod_errors: Vec<f64> = pairs.iter().map(|p| p.lod_error).collect();
        let (lod_mean, lod_ci) = mean_ci(&lod_errors);
        let worst = (0..pairs.len())
            .max_by(|&a, &b| pairs[a].excess_mean.total_cmp(&pairs[b].excess_mean))
            .expect("at least one pair");
        let _ = writeln!(
            summary,
            "| {} | {} | {mean:.5} ± {ci:.5} | {p99:.4} | {worst} ({:.1} m) | {:.5} | {lod_mean:.5} ± {lod_ci:.5} |",
            mode.name(),
            pairs.len(),
            pairs[worst].distance,
            pairs[worst].excess_mean
        );
        stats.push((mode, (mean, ci)));
        series.push(Series {
            label: mode.name().into(),
            points: pairs
                .iter()
                .map(|p| (p.distance as f64, p.excess_mean))
                .collect(),
        });
        let (w, h) = (args.width, args.height);
        let strip = tile(
            &[
                &frames[worst],
                &frames[worst + 1],
                &error_image(&excess_maps[worst].1, w, h),
                &full[worst],
                &full[worst + 1],
                &error_image(&full_maps[worst], w, h),
            ],
            3,
        );
        write_png(&args.out.join(format!("worst_{}.png", mode.name())), &strip)?;
    }
    let _ = writeln!(
        summary,
        "\nDifferences of mean excess beyond the noise (95% intervals do not overlap):\n"
    );
    for (i, (a, sa)) in stats.iter().enumerate() {
        for (b, sb) in &stats[i + 1..] {
            let verdict = if within_noise(*sa, *sb) {
                "within the noise"
            } else if sa.0 > sb.0 {
                "first pops more"
            } else {
                "second pops more"
            };
            let _ = writeln!(
                summary,
                "- {} vs {}: {verdict} ({:.2}x)",
                a.name(),
                b.name(),
                sa.0 / sb.0
            );
        }
    }
    std::fs::write(args.out.join("popping.csv"), csv)?;
    std::fs::write(args.out.join("summary.md"), &summary)?;
    xy_plot(
        &args.out.join("popping.png"),
        &Axes::linear(
            format!(
                "{}: LOD change beyond motion, band {}-{} m",
                args.scene,
                args.transition - args.fade_width,
                args.transition
            ),
            "camera distance from the forest centre [m]",
            "excess FLIP per frame pair (mean over pixels)",
        ),
        &series,
        Style::Lines,
    )?;
    print!("{summary}");
    println!(
        "wrote popping.csv, popping.png, worst_<mode>.png, summary.md to {}",
        args.out.display()
    );
    Ok(())
}

/// Images of one size laid out `columns` to a row.
fn tile(images: &[&Rgba8Image], columns: usize) -> Rgba8Image {
    let (w, h) = (images[0].width as usize, images[0].height as usize);
    let rows = images.len().div_ceil(columns);
    let mut texels = vec![[0u8, 0, 0, 255]; w * columns * h * rows];
    for (i, img) in images.iter().enumerate() {
        let (ox, oy) = ((i % columns) * w, (i / columns) * h);
        for y in 0..h {
            let dst = (oy + y) * w * columns + ox;
            texels[dst..dst + w].copy_from_slice(&img.texels[y * w..(y + 1) * w]);
        }
    }
    Rgba8Image {
        width: (w * columns) as u32,
        height: (h * rows) as u32,
        texels,
    }
}
