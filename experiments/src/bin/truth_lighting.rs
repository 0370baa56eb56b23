//! `truth_lighting`: how far the sun-depth model (G§5) is from real shadowing, and what each lit
//! truth costs (issue 30). For each scene, named camera, yaw and sun elevation it traces the
//! unlit truth, the **model** truth (the sun-depth model at each hit) and the **shadow** truth
//! (one shadow ray per tree hit towards the sun through the alpha-tested trees), on the sampled
//! tiles the sweeps use (`crate::fair::TruthLayout`), and writes per pose the model error
//! (FLIP mean of the model truth against the shadow truth, tree pixels and all pixels) and the
//! seconds and rays of each truth.
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin truth_lighting -- \
//!     --scenes synthetic --out experiments/results/shading
//! ```
//!
//! Writes `truth_lighting.csv` and prints the mean model error per sun elevation with its 95 %
//! interval over the poses, and the cost ratios shadow/model/unlit. See
//! `experiments/results/shading/README.md`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use forestlod_experiments::fair::{TileSpec, TruthLayout};
use forestlod_experiments::metrics::flip_map;
use forestlod_experiments::report::mean_ci;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::ground_truth::{GroundTruthScene, PixelClass, TruthLighting};
use forestlod_reference::scene::builtin;
use forestlod_shared::Params;

#[derive(Parser, Debug)]
struct Args {
    /// Scenes to run.
    #[arg(long, value_delimiter = ',', default_value = "synthetic")]
    scenes: Vec<String>,
    /// Named cameras.
    #[arg(long, value_delimiter = ',', default_value = "medium,close")]
    cameras: Vec<String>,
    /// Yaws per camera (equal steps over 360°).
    #[arg(long, default_value_t = 4)]
    yaw_steps: u32,
    /// Sun elevations, degrees.
    #[arg(long, value_delimiter = ',', default_value = "15,45")]
    sun_elevations: Vec<f32>,
    /// Frame width.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Truth samples per pixel side.
    #[arg(long, default_value_t = 2)]
    samples: u32,
    /// Fraction of 80x80 tiles traced (the sweeps' sampled truth); 1 traces the whole frame.
    #[arg(long, default_value_t = 0.125)]
    tile_fraction: f64,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("truth_lighting: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Box<dyn std::error::Error>> {
    if !(args.tile_fraction > 0.0 && args.tile_fraction <= 1.0) {
        return Err(format!(
            "--tile-fraction {}: expected a fraction in (0, 1]",
            args.tile_fraction
        )
        .into());
    }
    if args.yaw_steps == 0 || args.samples == 0 {
        return Err("--yaw-steps and --samples must be at least 1".into());
    }
    for &e in &args.sun_elevations {
        let p = Params {
            sun_elevation: e,
            ..Params::default()
        };
        p.validate()
            .map_err(|err| format!("--sun-elevations {e}: {err}"))?;
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("{}: cannot create: {e}", args.out.display()))?;
    let csv_path = args.out.join("truth_lighting.csv");
    let mut csv = std::fs::File::create(&csv_path)
        .map_err(|e| format!("{}: cannot create: {e}", csv_path.display()))?;
    writeln!(
        csv,
        "scene,camera,yaw_deg,sun_elevation,width,height,samples,tile_fraction,tree_pixels,\
         model_error_tree,model_error_all,shadowed_fraction,unlit_s,model_s,shadow_s,unlit_rays,\
         model_rays,shadow_rays"
    )?;
    let tiles = (args.tile_fraction < 1.0).then_some(TileSpec {
        size: 80,
        fraction: args.tile_fraction,
    });
    let layout = TruthLayout::new(args.width, args.height, tiles);
    let mut by_sun: Vec<(f32, Vec<f64>, [f64; 3])> = args
        .sun_elevations
        .iter()
        .map(|&e| (e, Vec::new(), [0.0; 3]))
        .collect();
    for name in &args.scenes {
        let scene = builtin::by_name(name)?;
        let gt = GroundTruthScene::build(&scene, Params::default().alpha_cutoff)?;
        for cam in &args.cameras {
            for step in 0..args.yaw_steps {
                let yaw = 360.0 * step as f32 / args.yaw_steps as f32;
                let camera = named_camera(cam, &scene, yaw, args.width, args.height)?;
                let timed = |lighting: Option<TruthLighting>| {
                    let t0 = Instant::now();
                    let img = layout.render_truth(&gt, &camera, args.samples, lighting);
                    (img, t0.elapsed().as_secs_f64())
                };
                let (unlit, unlit_s) = timed(None);
                for (elevation, errors, seconds) in &mut by_sun {
                    let params = Params {
                        sun_elevation: *elevation,
                        shading: forestlod_shared::Shading::SunDepthPlane as u32,
                        ..Params::default()
                    };
                    let light = |mode| TruthLighting::of(&params, mode);
                    let (model, model_s) = timed(light(forestlod_shared::TruthLight::Model));
                    let (shadow, shadow_s) = timed(light(forestlod_shared::TruthLight::Shadow));
                    let map = flip_map(&shadow.srgb, &model.srgb);
                    let trees: Vec<usize> = (0..map.len())
                        .filter(|&i| model.class[i] == PixelClass::Tree)
                        .collect();
                    let mean = |v: &mut dyn Iterator<Item = f32>, n: usize| {
                        v.map(f64::from).sum::<f64>() / n.max(1) as f64
                    };
                    let tree_err = mean(&mut trees.iter().map(|&i| map[i]), trees.len());
                    let all_err = mean(&mut map.iter().copied(), map.len());
                    // Pixels the shadow truth darkened against the unlit truth by more than the
                    // model could: lit by less than the model's darkest (the ambient level) plus
                    // a margin would be rounding; count tree pixels below 0.9 of unlit instead.
                    let shadowed = trees
                        .iter()
                        .filter(|&&i| {
                            let (s, u) = (shadow.linear[i][1], unlit.linear[i][1]);
                            u > 0.0 && s < 0.9 * u
                        })
                        .count() as f64
                        / trees.len().max(1) as f64;
                    writeln!(
                        csv,
                        "{name},{cam},{yaw},{elevation},{},{},{},{},{},{tree_err},{all_err},\
                         {shadowed},{unlit_s},{model_s},{shadow_s},{},{},{}",
                        args.width,
                        args.height,
                        args.samples,
                        args.tile_fraction,
                        trees.len(),
                        unlit.rays,
                        model.rays,
                        shadow.rays
                    )?;
                    // A pose without trees (medium yaw 180° looks away from the forest) has no
                    // model error to speak of: it is written but kept out of the mean.
                    if !trees.is_empty() {
                        errors.push(tree_err);
                    }
                    seconds[0] += unlit_s;
                    seconds[1] += model_s;
                    seconds[2] += shadow_s;
                    println!(
                        "{name} {cam} yaw {yaw} sun {elevation}°: model error (tree pixels) \
                         {tree_err:.4}, all {all_err:.4}, {:.0} % of tree pixels in shadow; \
                         truth seconds unlit {unlit_s:.2} model {model_s:.2} shadow {shadow_s:.2}",
                        shadowed * 100.0
                    );
                }
            }
        }
    }
    for (elevation, errors, s) in &by_sun {
        let (mean, half) = mean_ci(errors);
        println!(
            "sun {elevation}°: model error {mean:.4} ± {half:.4} (95 %, {} poses with trees); truth seconds \
             model/unlit {:.2}x, shadow/unlit {:.2}x",
            errors.len(),
            s[1] / s[0],
            s[2] / s[0]
        );
    }
    println!("wrote {}", csv_path.display());
    Ok(())
}
