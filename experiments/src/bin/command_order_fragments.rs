//! `command_order_fragments`: how many tree fragments does the front-to-back command order
//! (issue 13, E§7 "distance-sorted commands", `command_order = front-to-back`) save from shading?
//! (`experiments/results/hierarchy/command_order.md`).
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin command_order_fragments -- --out out/command_order
//! ```
//!
//! lavapipe exposes no fragment counter here, so the count comes from the reference rasterizer,
//! which runs the depth test before the fragment shader (`reference/src/raster.rs`, step 8) as an
//! early-depth GPU does: `fragments_shaded` is the covered samples that passed the depth test when
//! they were drawn, so it depends on the order, while `fragments_covered` does not. For each
//! hierarchy and named camera (yaw 0) this renders the reference frame in `node` and in
//! `front-to-back` order and writes one CSV row per frame (`command_order_fragments.csv`):
//! commands, covered, shaded and written tree fragments, and the reference draw's seconds.

use std::path::PathBuf;

use clap::Parser;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::{CommandOrder, Hierarchy, Params};

#[derive(Parser, Debug)]
struct Args {
    /// Built-in scene.
    #[arg(long, default_value = "stress")]
    scene: String,
    /// Hierarchies (`hierarchy` values other than `grid`).
    #[arg(long, value_delimiter = ',', default_value = "octree,kmeans")]
    hierarchies: Vec<String>,
    /// Named cameras (yaw 0).
    #[arg(long, value_delimiter = ',', default_value = "close,medium")]
    cameras: Vec<String>,
    /// Frame width.
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 180)]
    height: u32,
    /// Output folder.
    #[arg(long, default_value = "out/command_order")]
    out: PathBuf,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let scene = builtin::by_name(&args.scene)?;
    std::fs::create_dir_all(&args.out)?;
    let mut csv = String::from(
        "scene,camera,hierarchy,command_order,commands,fragments_covered,fragments_shaded,fragments_written,draw_s\n",
    );
    for h_name in &args.hierarchies {
        let h = Hierarchy::from_name(h_name)
            .filter(|h| h.is_hierarchical())
            .ok_or_else(|| format!("--hierarchies: {h_name:?} is not a hierarchy"))?;
        let base = Params {
            hierarchy: h as u32,
            ..Params::default()
        };
        let prepared = prepare(scene.clone(), &base)?;
        for camera_name in &args.cameras {
            let camera = named_camera(camera_name, &prepared.scene, 0.0, args.width, args.height)?;
            for order in [CommandOrder::Node, CommandOrder::FrontToBack] {
                let p = Params {
                    command_order: order as u32,
                    ..base
                };
                let f = prepared.render(&camera, &p)?;
                let s = f.drawn.tree_stats;
                println!(
                    "{} {camera_name} {h_name} {}: {} commands, tree fragments covered {} shaded {} written {}, draw {:.2} s",
                    args.scene,
                    order.name(),
                    f.selection.commands.len(),
                    s.fragments_covered,
                    s.fragments_shaded,
                    s.fragments_written,
                    f.timings.draw
                );
                csv.push_str(&format!(
                    "{},{camera_name},{h_name},{},{},{},{},{},{:.3}\n",
                    args.scene,
                    order.name(),
                    f.selection.commands.len(),
                    s.fragments_covered,
                    s.fragments_shaded,
                    s.fragments_written,
                    f.timings.draw
                ));
            }
        }
    }
    let path = args.out.join("command_order_fragments.csv");
    std::fs::write(&path, csv)?;
    println!("wrote {}", path.display());
    Ok(())
}
