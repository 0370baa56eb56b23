//! `hierarchy_ties`: are the pixels where a hierarchy's frame differs from the grid's all depth
//! ties? (issue 13; `experiments/results/hierarchy_paths/README.md`, "Accuracy").
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin hierarchy_ties -- --scene stress --distance 1000
//! cargo run --release -p forestlod-experiments --bin hierarchy_ties -- --scene patchy --dolly 1
//! cargo run --release -p forestlod-experiments --bin hierarchy_ties -- --scene stress --distance 0 --backend gpu
//! cargo run --release -p forestlod-experiments --bin hierarchy_ties -- --scene stress --camera medium --command-order front-to-back
//! ```
//!
//! The conservative hierarchies (every one but `octree-euclidean`) draw the same (tree, LOD)
//! fragments as the grid (the fade is per fragment; `tests/tests/properties/hierarchy_properties.rs`),
//! but in another order: node by node, depth-first, where the grid goes batch by batch. With the
//! depth test `LESS`, the first of two fragments at *equal* depth wins, so exactly there the order
//! can change the pixel. This renders one reference frame (the distance path's pose, E§5.0.2, or
//! the dolly's, as the sweeps' `distance` and `dolly` cameras place them) with the grid and each
//! hierarchy, lists every pixel whose colour, depth or LOD id differs from the grid's, and exits 2
//! if one of a conservative hierarchy's is **not** at equal depth (a difference the draw order
//! cannot explain). With `--command-order front-to-back` the hierarchies draw their commands
//! sorted front to back (E§7), a second change of draw order with the same rule: only ties may
//! differ in `dither-sequential` (the default fade mode, opaque fragments only). With `--backend gpu` every frame is the GPU's (selection, cut, coalescing,
//! textures and draw on the adapter, lavapipe in CI), compared with the GPU's grid frame: the
//! same classification for the GPU's own ties. `octree-euclidean` decides on G§3's Euclidean distance, which is not
//! conservative: its other differences are counted as such and expected.

use clap::Parser;
use forestlod_experiments::sweep::distance_camera;
use forestlod_experiments::sweep::paths::path_camera;
use forestlod_gpu::GpuContext;
use forestlod_gpu::draw::GpuDraw;
use forestlod_harness::gpu_frame::{StagesFromCpu, render_gpu};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::Params;
use forestlod_shared::params::{CommandOrder, Hierarchy};

/// `--command-order`'s help, the orders' names from [`CommandOrder`].
fn command_order_help() -> String {
    let names: Vec<String> = CommandOrder::ALL
        .iter()
        .map(|o| format!("`{}`", o.name()))
        .collect();
    format!(
        "The hierarchies' command order ({}: E§7 distance-sorted commands); the grid's flat \
         selection does not read it",
        names.join(", or ")
    )
}

/// `--hierarchies`' default: every hierarchical [`Hierarchy`], comma-separated, in id order.
fn hierarchical_names() -> &'static str {
    static NAMES: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    NAMES.get_or_init(|| {
        let names: Vec<&str> = Hierarchy::ALL
            .iter()
            .filter(|h| h.is_hierarchical())
            .map(|h| h.name())
            .collect();
        names.join(",")
    })
}

/// Differing pixels listed one per line, per hierarchy (the rest are counted).
const MAX_LISTED: u32 = 12;

#[derive(Parser, Debug)]
struct Args {
    /// Built-in scene.
    #[arg(long, default_value = "stress")]
    scene: String,
    /// Distance-path pose: metres before the footprint.
    #[arg(long, default_value_t = 1000.0, conflicts_with = "dolly")]
    distance: f32,
    /// Dolly pose instead: the fraction of the path, in [0, 1] (the sweeps' 2 steps are 0 and 1).
    #[arg(long, conflicts_with = "camera")]
    dolly: Option<f32>,
    /// A named camera instead (`far`, `medium`, `close`, E§5.0.1), at yaw 0.
    #[arg(long, conflicts_with = "distance")]
    camera: Option<String>,
    // The hierarchies' command order: its help names the orders (`command_order_help`).
    #[arg(long, default_value = "node", help = command_order_help())]
    command_order: String,
    /// Hierarchies compared with the grid, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = hierarchical_names())]
    hierarchies: Vec<String>,
    /// `reference` or `gpu` (every stage on the adapter).
    #[arg(long, default_value = "reference", value_parser = ["reference", "gpu"])]
    backend: String,
    /// Frame width.
    #[arg(long, default_value_t = 160)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 90)]
    height: u32,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let mut hierarchies = vec![Hierarchy::Grid];
    for name in &args.hierarchies {
        let h = Hierarchy::from_name(name).ok_or_else(|| {
            format!(
                "--hierarchies: unknown hierarchy {name:?} (expected one of {:?})",
                Hierarchy::choices().iter().map(|c| c.0).collect::<Vec<_>>()
            )
        })?;
        hierarchies.push(h);
    }
    if let Some(t) = args.dolly
        && !(0.0..=1.0).contains(&t)
    {
        return Err(format!("--dolly: {t} is not in [0, 1]").into());
    }
    let order = CommandOrder::from_name(&args.command_order).ok_or_else(|| {
        format!(
            "--command-order: unknown order {:?} (expected one of {:?})",
            args.command_order,
            CommandOrder::choices()
                .iter()
                .map(|c| c.0)
                .collect::<Vec<_>>()
        )
    })?;
    let gpu = if args.backend == "gpu" {
        let ctx = GpuContext::new()?;
        let draw = GpuDraw::new(&ctx)?;
        println!("adapter: {}", ctx.describe());
        Some((ctx, draw))
    } else {
        None
    };
    let mut frames = Vec::new();
    for h in hierarchies {
        let scene = builtin::by_name(&args.scene)?;
        let params = Params {
            hierarchy: h as u32,
            command_order: order as u32,
            ..Params::default()
        };
        let camera = match (args.dolly, &args.camera) {
            (None, Some(name)) => named_camera(name, &scene, 0.0, args.width, args.height)?,
            (None, None) => distance_camera(&scene, args.distance, args.width, args.height),
            (Some(t), _) => {
                path_camera("dolly", &scene, &params, t, args.width, args.height)
                    .ok_or("the dolly path is not defined")?
                    .0
            }
        };
        let prepared = prepare(scene, &params)?;
        if let Some((ctx, draw)) = &gpu {
            let g = render_gpu(ctx, draw, &prepared, &camera, &params, StagesFromCpu::NONE)?;
            println!("{h:?}: GPU frame");
            frames.push((h, g.images.color, g.images.depth, g.images.lod_id));
        } else {
            let frame = prepared.render(&camera, &params)?;
            let t = frame.drawn.target;
            println!("{h:?}: {} commands", frame.selection.counters.commands);
            frames.push((h, t.color().to_vec(), t.depth().to_vec(), t.aux().to_vec()));
        }
    }
    let (_, c0, d0, a0) = &frames[0];
    let mut unexplained = 0;
    for (h, c, d, a) in &frames[1..] {
        let conservative = *h != Hierarchy::OctreeEuclidean;
        let (mut differ, mut ties) = (0, 0);
        for i in 0..c0.len() {
            if c[i] == c0[i] && a[i] == a0[i] && d[i].to_bits() == d0[i].to_bits() {
                continue;
            }
            differ += 1;
            let tie = d[i].to_bits() == d0[i].to_bits();
            ties += tie as u32;
            unexplained += (!tie && conservative) as u32;
            if differ > MAX_LISTED {
                continue;
            }
            println!(
                "  {h:?} pixel ({}, {}): depth {} vs grid {}{}, colour {:?} vs {:?}, LOD id {} vs {}",
                i as u32 % args.width,
                i as u32 / args.width,
                d[i],
                d0[i],
                if tie { " (tie)" } else { "" },
                c[i],
                c0[i],
                a[i],
                a0[i]
            );
        }
        if differ > MAX_LISTED {
            println!("  ... {} more", differ - MAX_LISTED);
        }
        println!(
            "{h:?} vs grid: {differ} of {} pixels differ, {ties} of them at equal depth{}",
            c0.len(),
            if conservative || differ == ties {
                ""
            } else {
                " (the rest: G§3's Euclidean distance is not conservative)"
            }
        );
    }
    if unexplained > 0 {
        eprintln!("{unexplained} differing pixel(s) not at equal depth");
        std::process::exit(2);
    }
    Ok(())
}
