//! `forestlod`: the command line of the forestlod research codebase.
//!
//! - `forestlod scene info --scene stress`: trees, batches, meshes, memory beside E Eq. 4.1.
//! - `forestlod select --scene synthetic --camera medium`: what selection emits for one frame, and
//!   how long grouped and per-tree selection take.
//! - `forestlod export-case --scene tiny --out CASE` / `forestlod verify --case CASE --outputs
//!   DIR`: judge another implementation's frame through files (`case.rs`).
//! - `forestlod sweep [FILE] --out DIR [--quick]`: the speed–accuracy sweeps
//!   (`experiments/sweeps/README.md`); `forestlod report --run DIR` summarizes them.
//!
//! Every error is one line naming the field and the value, with exit code 1; command-line usage
//! errors exit with 1 too, so that the main job's codes 2-4 keep their meaning
//! ([`forestlod_experiments::render::exit_code`]: 2 GPU parity failed, 3 GPU error, 4 GPU parity
//! skipped for want of an adapter).

use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use forestlod_experiments::camera::{CameraArgs, no_tree_warning};
use forestlod_experiments::options::{ParamArgs, SceneArgs};
use forestlod_experiments::render::{EXIT_CODES_HELP, exit_code};
use forestlod_reference::frame::{SelectScene, select_stages};
use forestlod_reference::geometry::pack_geometry;
use forestlod_reference::pipeline::{group_trees, scene_memory};
use forestlod_reference::scene::tree_sphere;
use forestlod_reference::select::{count_per_tree, select_per_tree};

#[derive(Parser, Debug)]
#[command(
    name = "forestlod",
    version,
    about = "Grouped-LOD forest rendering: CPU reference, experiments and tools",
    after_help = EXIT_CODES_HELP
)]
struct Cli {
    /// With no subcommand: the main job, `render` with its defaults.
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The main job: render one frame with the reference and write images, metrics and a summary.
    #[command(after_help = EXIT_CODES_HELP)]
    Render(forestlod_experiments::render::RenderArgs),
    /// Facts about a scene.
    Scene {
        #[command(subcommand)]
        what: SceneCommand,
    },
    /// Print the GPU adapter wgpu finds (the one the parity tests use).
    GpuInfo,
    /// Measure the speed–accuracy trade: run sweep TOML files (all built-ins when no file is
    /// given) against the ray-traced ground truth, writing CSVs and plots.
    Sweep(forestlod_experiments::sweep::SweepArgs),
    /// Write DIR/report.md over the sweeps in DIR.
    Report(forestlod_experiments::report::ReportArgs),
    /// Write a parity case (scene, camera, parameters, the oracle's buffers and images) that
    /// another implementation can be verified against (`forestlod verify`).
    ExportCase(forestlod_experiments::case::ExportArgs),
    /// Judge another implementation's outputs for a case with the in-process parity's classes;
    /// exit 0 pass, 2 fail, 1 bad input.
    Verify(forestlod_experiments::case::VerifyArgs),
    /// Random selection parity cases on the current adapter (`--cases N` or `--seconds T`); a
    /// failing case is shrunk and written with the command that replays it. Exit 0 all passed,
    /// 2 a case failed, 1 bad input, 4 no adapter.
    Check(forestlod_experiments::check::CheckArgs),
    /// Run selection for one frame and print what it emitted.
    Select {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        params: ParamArgs,
        #[command(flatten)]
        camera: CameraArgs,
        /// How many commands to list.
        #[arg(long, default_value_t = 10)]
        list: usize,
    },
}

#[derive(Subcommand, Debug)]
enum SceneCommand {
    /// Trees n, batches t, meshes m, memory beside E Eq. 4.1, batch statistics.
    Info {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        params: ParamArgs,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn scene_info(scene: &SceneArgs, params: &ParamArgs, json: bool) -> Result<()> {
    let params = params.params()?;
    let scene = scene.load()?;
    let geometry = pack_geometry(&scene);
    let start = Instant::now();
    // Grouped as the frame's plan says (`prepare`'s own grouping and memory count).
    let (hierarchy, batches) = group_trees(&scene, &geometry.meshes, &params)?;
    let batch_seconds = start.elapsed().as_secs_f64();
    let memory = scene_memory(&scene, &batches, hierarchy.as_ref(), &params);
    let stats = batches.stats();
    if json {
        let value = serde_json::json!({
            "scene": scene.name, "n": memory.n, "t": memory.t, "m": memory.m,
            "area_km2": scene.area_km2(), "origin": scene.origin, "mesh_triangles": scene.mesh_triangles(),
            "memory": memory, "batches": stats, "batch_build_seconds": batch_seconds,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    let mb = |b: u64| b as f64 / 1.0e6;
    println!(
        "scene {}: {:.3} km² at origin {:?}",
        scene.name,
        scene.area_km2(),
        scene.origin
    );
    println!(
        "  n = {} trees ({:.0} per km²)",
        memory.n,
        memory.n as f64 / scene.area_km2().max(1e-12)
    );
    println!(
        "  m = {} meshes, {} triangles in all",
        memory.m,
        scene.mesh_triangles()
    );
    println!(
        "  t = {} batches over {} occupied cells (grid {} m{}), built in {:.3} s",
        memory.t,
        stats.cells,
        params.grid_size,
        match &hierarchy {
            Some(h) => format!(
                "; hierarchy {}: {} leaves, {} nodes",
                h.mode.name(),
                memory.t,
                h.nodes.len()
            ),
            None => String::new(),
        },
        batch_seconds
    );
    println!(
        "  trees per batch: min {} / mean {:.1} / max {}; sphere radius mean {:.1} m, max {:.1} m",
        stats.min_trees, stats.mean_trees, stats.max_trees, stats.mean_radius, stats.max_radius
    );
    println!(
        "memory (a = {}, J = {}, r = {}, l = {}): ours beside E Eq. 4.1 (extended by J azimuths)",
        memory.a, memory.j, memory.r, memory.l
    );
    println!("  {:<22} {:>12} {:>12}", "term", "ours [B]", "Eq. 4.1 [B]");
    let rows = [
        ("indirection (4n)", memory.indirection, 4 * memory.n),
        ("batch meta (64t)", memory.batch_meta, 64 * memory.t),
        ("mesh meta (24m)", memory.mesh_meta, 24 * memory.m),
        (
            "billboards (16aJmr²)",
            memory.billboards,
            16 * memory.a * memory.j * memory.m * memory.r * memory.r,
        ),
        ("commands (52lt)", memory.commands, 52 * memory.l * memory.t),
        ("counters (4lm)", memory.counters, 4 * memory.l * memory.m),
        ("interior nodes", memory.hierarchy_nodes, 0),
        ("far level (issue 32)", memory.far_level, 0),
    ];
    for (name, ours, eq) in rows {
        println!("  {name:<22} {ours:>12} {eq:>12}");
    }
    println!(
        "  {:<22} {:>12} {:>12}   ({:.2} MB vs {:.2} MB)",
        "total",
        memory.total,
        memory.eq41,
        mb(memory.total),
        mb(memory.eq41)
    );
    Ok(())
}

fn select_frame(
    scene: &SceneArgs,
    params: &ParamArgs,
    camera: &CameraArgs,
    list: usize,
) -> Result<()> {
    let params = params.params()?;
    camera.free()?;
    let scene = scene.load()?;
    let camera = camera.camera(&scene, 1280, 720)?;
    let geometry = pack_geometry(&scene);
    // Grouped as the frame's plan says, and selected by the frame's selection stages (`refine`
    // included when `--tree-cull` asks for it), as `render` does.
    let (hierarchy, batches) = group_trees(&scene, &geometry.meshes, &params)?;
    let spheres: Vec<_> = scene
        .instances
        .iter()
        .map(|t| tree_sphere(t, &geometry.meshes[t.mesh as usize]))
        .collect();
    let scales: Vec<f32> = scene.instances.iter().map(|t| t.scale).collect();
    let frame_scene = SelectScene {
        geometry: &geometry,
        batches: &batches,
        hierarchy: hierarchy.as_ref(),
        far: None,
        tree_spheres: &spheres,
        tree_scales: &scales,
    };
    let trace = select_stages(&frame_scene, &camera, &params, false);
    let selection = &trace.selection;
    if let Some(h) = &hierarchy {
        println!(
            "hierarchy {}: {} nodes, {} leaves, {} levels (batches below are its leaves; \"batches tested\" counts the nodes the cut visits)",
            h.mode.name(),
            h.nodes.len(),
            h.leaf_count(),
            h.levels()
        );
    }
    let grouped_seconds = trace.seconds.0.iter().map(|(_, t)| t).sum::<f64>();
    let start = Instant::now();
    let per_tree = select_per_tree(&spheres, &camera, &params);
    let per_tree_seconds = start.elapsed().as_secs_f64();
    let [lod0_trees, lod1_trees] = count_per_tree(&per_tree);
    let c = selection.counters;
    println!(
        "scene {} ({} trees, {} batches), camera eye {:?} forward {:?}",
        scene.name,
        scene.instances.len(),
        batches.metas.len(),
        camera.eye,
        camera.forward
    );
    println!(
        "  batches tested {}, culled by distance {}, by frustum {}, in the fade band {}",
        c.batches_tested, c.culled_distance, c.culled_frustum, c.transition_batches
    );
    println!(
        "  commands {} (LOD0 {}, LOD1 {}), tree instances drawn {}",
        c.commands, c.lod0_commands, c.lod1_commands, c.instances
    );
    println!("  per-tree oracle: {lod0_trees} trees need LOD0, {lod1_trees} need LOD1");
    println!(
        "  one-shot timings (use `cargo bench` for figures): grouped {:.3} ms, per-tree {:.3} ms",
        grouped_seconds * 1e3,
        per_tree_seconds * 1e3
    );
    for (i, (cmd, data)) in selection
        .commands
        .iter()
        .zip(&selection.data)
        .take(list)
        .enumerate()
    {
        println!(
            "  [{i}] batch {} mesh {} lod {} fading {} | index_count {} instances {} first_index {} base_vertex {} first_instance {}",
            data.batch,
            data.mesh,
            data.lod,
            data.fading,
            cmd.index_count,
            cmd.instance_count,
            cmd.first_index,
            cmd.base_vertex,
            cmd.first_instance
        );
    }
    if selection.commands.len() > list {
        println!("  ... {} more (--list N)", selection.commands.len() - list);
    }
    if let Some(warning) = no_tree_warning(&scene, c.commands, None) {
        eprintln!("{warning}");
    }
    Ok(())
}

/// `forestlod gpu-info`: the adapter the GPU twin and the parity tests use, its backend, device
/// type and the optional features enabled; exit code 0 with or without an adapter.
fn gpu_info() -> Result<()> {
    match forestlod_gpu::GpuContext::new() {
        Ok(ctx) => {
            for line in &ctx.passed_over {
                println!("{line}");
            }
            let info = &ctx.info;
            println!("adapter: {}", info.name);
            println!("backend: {:?}", info.backend);
            println!("device type: {:?}", info.device_type);
            println!("driver: {} {}", info.driver, info.driver_info);
            let names: Vec<String> = ctx
                .features
                .iter_names()
                .map(|(name, _)| name.to_string())
                .collect();
            println!("features enabled: {}", names.join(", "));
            let draw = match forestlod_gpu::GpuDraw::new(&ctx) {
                Ok(d) => format!("one {} call per frame", d.indirect_mode().name()),
                Err(e) => format!("unavailable: {e}"),
            };
            println!("draw stage: {draw}");
            println!(
                "limits: max 2D texture {}, max array layers {}",
                ctx.limits.max_texture_dimension_2d, ctx.limits.max_texture_array_layers
            );
        }
        Err(e) => println!("GPU: no adapter ({e})"),
    }
    Ok(())
}

/// Restores the default action of SIGPIPE (Rust ignores it, so a closed pipe turns every print
/// into a panic): `forestlod ... | head` then ends quietly, as other command-line tools do.
fn quiet_broken_pipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any thread exists; SIG_DFL is a valid action.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Mesa's Vulkan drivers warn on every start when `XDG_RUNTIME_DIR` is unset; give them a private
/// folder (removed at exit) before any wgpu instance exists. Returns the folder to remove.
fn private_runtime_dir() -> Option<std::path::PathBuf> {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("forestlod-runtime-{}", std::process::id()));
    let mut builder = std::fs::DirBuilder::new();
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder.create(&dir).ok()?;
    // SAFETY: called at the start of `main`, before any other thread exists.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    Some(dir)
}

fn main() -> ExitCode {
    quiet_broken_pipe();
    let runtime_dir = private_runtime_dir();
    let code = run();
    if let Some(dir) = runtime_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    ExitCode::from(code)
}

fn run() -> u8 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            // --help and --version print to stdout and succeed; usage errors are bad input (1),
            // not clap's 2, which is the main job's "GPU parity failed".
            return if e.use_stderr() {
                exit_code::BAD_INPUT
            } else {
                exit_code::SUCCESS
            };
        }
    };
    let result = match &cli.command {
        None => forestlod_experiments::render::run(&Default::default()),
        Some(Command::Render(args)) => forestlod_experiments::render::run(args),
        Some(Command::Scene {
            what:
                SceneCommand::Info {
                    scene,
                    params,
                    json,
                },
        }) => scene_info(scene, params, *json).map(|()| exit_code::SUCCESS),
        Some(Command::Select {
            scene,
            params,
            camera,
            list,
        }) => select_frame(scene, params, camera, *list).map(|()| exit_code::SUCCESS),
        Some(Command::GpuInfo) => gpu_info().map(|()| exit_code::SUCCESS),
        Some(Command::ExportCase(args)) => forestlod_experiments::case::export(args),
        Some(Command::Verify(args)) => forestlod_experiments::case::verify(args),
        Some(Command::Check(args)) => forestlod_experiments::check::run(args),
        Some(Command::Sweep(args)) => {
            forestlod_experiments::sweep::run(args).map(|()| exit_code::SUCCESS)
        }
        Some(Command::Report(args)) => {
            forestlod_experiments::report::run(args).map(|()| exit_code::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!(
                "error: {}",
                forestlod_experiments::render::one_line(&e.to_string())
            );
            exit_code::BAD_INPUT
        }
    }
}
