//! The main job (`forestlod render`, and `cargo run --release` with no arguments): render one frame
//! of a scene with the reference pipeline and write colour, depth, the LOD-id view, the baked
//! billboard atlas, a metrics JSON and a short summary into an output folder.
//!
//! Everything is computed before anything is written, so a failure leaves the output folder as it
//! was.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;
use forestlod_reference::bake::contact_sheet;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::output::{depth_preview, lod_id_image, write_depth_exr, write_png};
use forestlod_reference::pipeline::{Frame, Prepared, prepare};
use forestlod_reference::{InputError, draw};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

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
            "angle_index": args.params.angle_index,
        },
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

/// The main job.
pub fn run(args: &RenderArgs) -> Result<(), Box<dyn std::error::Error>> {
    let params = args.params.params()?;
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

    let metrics = metrics(&prepared, &frame, args, scene_seconds);
    let target = &frame.drawn.target;
    let (w, h) = (target.width(), target.height());
    let summary = summary_text(&metrics);
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
    println!(
        "wrote color.png, depth.exr, depth_preview.png, lod.png, atlas.png, metrics.json, summary.txt to {}",
        args.out.display()
    );
    let _ = draw::LOD_ID_MESH;
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
    format!(
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
    )
}
