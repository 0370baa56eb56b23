//! `hierarchy_ties`: are the pixels where a hierarchy's frame differs from the grid's all depth
//! ties? (issue 13; `experiments/results/hierarchy_paths/README.md`, "Accuracy").
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin hierarchy_ties -- --scene stress --distance 1000
//! ```
//!
//! The hierarchies draw the same (tree, LOD) fragments as the grid (the fade is per fragment;
//! `tests/tests/properties/hierarchy_properties.rs`), but in another order: node by node,
//! depth-first, where the grid goes batch by batch. With the depth test `LESS`, the first of two
//! fragments at *equal* depth wins, so exactly there the order can change the pixel. This renders
//! the reference frame of the distance path's pose (E§5.0.2, the sweeps' `distance` camera) with
//! the grid, the quadtree and the octree, lists every pixel whose colour, depth or LOD id differs
//! from the grid's, and exits 2 if one of them is **not** at equal depth (a difference the draw
//! order cannot explain).

use clap::Parser;
use forestlod_experiments::sweep::distance_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::Params;
use forestlod_shared::params::Hierarchy;

#[derive(Parser, Debug)]
struct Args {
    /// Built-in scene.
    #[arg(long, default_value = "stress")]
    scene: String,
    /// Distance-path pose: metres before the footprint.
    #[arg(long, default_value_t = 1000.0)]
    distance: f32,
    /// Frame width.
    #[arg(long, default_value_t = 160)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 90)]
    height: u32,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let mut frames = Vec::new();
    for h in [Hierarchy::Grid, Hierarchy::Quadtree, Hierarchy::Octree] {
        let scene = builtin::by_name(&args.scene)?;
        let params = Params {
            hierarchy: h as u32,
            ..Params::default()
        };
        let camera = distance_camera(&scene, args.distance, args.width, args.height);
        let prepared = prepare(scene, &params)?;
        let frame = prepared.render(&camera, &params)?;
        let t = frame.drawn.target;
        println!("{h:?}: {} commands", frame.selection.counters.commands);
        frames.push((h, t.color().to_vec(), t.depth().to_vec(), t.aux().to_vec()));
    }
    let (_, c0, d0, a0) = &frames[0];
    let mut unexplained = 0;
    for (h, c, d, a) in &frames[1..] {
        let (mut differ, mut ties) = (0, 0);
        for i in 0..c0.len() {
            if c[i] == c0[i] && a[i] == a0[i] && d[i].to_bits() == d0[i].to_bits() {
                continue;
            }
            differ += 1;
            let tie = d[i].to_bits() == d0[i].to_bits();
            ties += tie as u32;
            unexplained += !tie as u32;
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
        println!(
            "{h:?} vs grid: {differ} of {} pixels differ, {ties} of them at equal depth",
            c0.len()
        );
    }
    if unexplained > 0 {
        eprintln!("{unexplained} differing pixel(s) not at equal depth");
        std::process::exit(2);
    }
    Ok(())
}
