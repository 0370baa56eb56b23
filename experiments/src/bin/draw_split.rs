//! Where the GPU frame's time goes (issue 13): selection, `refine`, and the draw pass split into
//! clear + ground, tree vertex work and tree fragment work, for ours over each hierarchy and for
//! the Vegetation baseline, plus the per-command overhead of the indirect draw.
//!
//! `cargo run --release -p forestlod-experiments --bin draw_split -- --out out/draw_split`
//!
//! `--orders` with every `command_order` value measures each hierarchy in every command order
//! (issue 13, E§7 distance-sorted commands; `experiments/results/hierarchy/command_order.md`): the
//! select time then includes the sort.
//!
//! Every stage is timed three ways, each the minimum of `--reps` repetitions after `--warmups`
//! (1) untimed ones: timestamp queries (`gpu_time::timestamped`), wall time from submit to
//! completion, and this process's CPU seconds (`getrusage`: every thread, lavapipe's included),
//! the one clock other processes on a shared machine barely inflate. The draw
//! pass is split by difference between three recordings of the same frame
//! ([`forestlod_gpu::draw::DrawProbe`]):
//! - `full`: the frame;
//! - `no_trees`: clear and ground only;
//! - `no_tree_fragments`: the frame with the tree draw call under a 1x1 scissor, so every command,
//!   instance and vertex is fetched, shaded, clipped and set up, but no tree triangle is
//!   rasterized or shaded outside pixel (0, 0).
//!
//! `vertex = no_tree_fragments - no_trees`, `fragment = full - no_tree_fragments`. The instrument
//! is checked on every row: the tree pixels (LOD id) of `no_tree_fragments` (at most 1) and
//! `no_trees` (0) are written to the CSV. The per-command series draws Vegetation's visible trees
//! (the same instances, the same triangles) with its commands split into commands of at most `c`
//! instances, for each `c` of `--split-sizes`: time against the number of commands.
//!
//! Writes `draw_split.csv` (one row per scene, camera and variant), `commands.csv` (the series)
//! and the plots `draw_split_<scene>[_cpu].png` and `commands_<scene>_<camera>.png` into `--out`;
//! `--replot` redraws the first from the CSV. Results: `experiments/results/hierarchy_time/`.

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use forestlod_experiments::gpu_time::timestamped;
use forestlod_experiments::options::ParamArgs;
use forestlod_experiments::plot::{Axes, Series, Style, bar_plot, xy_plot};
use forestlod_gpu::draw::{DrawInputs, DrawProbe, DrawScene, DrawTarget};
use forestlod_gpu::{
    Compaction, GpuContext, GpuCull, GpuDraw, GpuError, GpuRefine, GpuSelection, SelectBuffers,
};
use forestlod_harness::bridge::{DrawSceneData, cull_trees, gpu_textures};
use forestlod_harness::gpu_frame::SelectionChain;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::prepare;
use forestlod_reference::scene::builtin;
use forestlod_shared::{
    COMMAND_SHIFT, Camera, CommandOrder, DrawCommand, Hierarchy, LOD_ID_BACKGROUND, LOD_ID_TERRAIN,
    LOD_MESH, Params, TreeCull,
};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    params: ParamArgs,
    /// Scenes to run.
    #[arg(long, value_delimiter = ',', default_value = "stress")]
    scenes: Vec<String>,
    /// Named cameras (yaw 0).
    #[arg(long, value_delimiter = ',', default_value = "close,medium")]
    cameras: Vec<String>,
    /// Hierarchies of ours (`hierarchy` parameter values; default: every conservative one).
    #[arg(long, value_delimiter = ',', default_values_t = conservative_hierarchies())]
    hierarchies: Vec<String>,
    /// Command orders of ours (`command_order` values, issue 13 E§7): each hierarchy is measured
    /// once per order, back to back in the same run (rows `ours <h>` and `ours <h> <order>`).
    #[arg(long, value_delimiter = ',', default_value = "node")]
    orders: Vec<String>,
    /// Also run the grid with `tree_cull = all` (select, then `refine`).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    refine: bool,
    /// Most instances per command of the per-command series over Vegetation's visible trees
    /// (0: Vegetation's own commands, one per mesh).
    #[arg(long, value_delimiter = ',', default_value = "0,64,16,4,1")]
    split_sizes: Vec<u32>,
    /// Cameras of the per-command series.
    #[arg(long, value_delimiter = ',', default_value = "close")]
    split_cameras: Vec<String>,
    /// Viewport width.
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Viewport height.
    #[arg(long, default_value_t = 180)]
    height: u32,
    /// Timed repetitions per measurement (the minimum is reported).
    #[arg(long, default_value_t = 2)]
    reps: usize,
    /// Untimed warm-up runs before them (llvmpipe compiles shader variants on first use).
    #[arg(long, default_value_t = 1)]
    warmups: usize,
    /// Output folder.
    #[arg(long, default_value = "out/draw_split")]
    out: PathBuf,
    /// Only redraw `draw_split_<scene>[_cpu].png` from the `draw_split.csv` in `--out`.
    #[arg(long)]
    replot: bool,
}

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// Plot points `(x, y)`.
type Points = Vec<(f64, f64)>;

/// Seconds of one measurement, each the minimum over the timed repetitions.
#[derive(Clone, Copy, Debug)]
struct Secs {
    /// Between timestamps.
    gpu: f64,
    /// Wall, submit to completion.
    wall: f64,
    /// CPU seconds of this process (user + system, every thread: lavapipe's included), which
    /// other processes on a shared machine do not inflate as they inflate the other two.
    cpu: f64,
}

impl Secs {
    const NAN: Secs = Secs {
        gpu: f64::NAN,
        wall: f64::NAN,
        cpu: f64::NAN,
    };
    const ZERO: Secs = Secs {
        gpu: 0.0,
        wall: 0.0,
        cpu: 0.0,
    };
    fn minus(self, o: Secs) -> Secs {
        Secs {
            gpu: self.gpu - o.gpu,
            wall: self.wall - o.wall,
            cpu: self.cpu - o.cpu,
        }
    }
    fn plus(self, o: Secs) -> Secs {
        Secs {
            gpu: self.gpu + o.gpu,
            wall: self.wall + o.wall,
            cpu: self.cpu + o.cpu,
        }
    }
}

/// User + system CPU seconds of this process so far.
fn process_cpu_seconds() -> f64 {
    // SAFETY: getrusage writes one `rusage` into the zeroed struct we own.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    tv(u.ru_utime) + tv(u.ru_stime)
}

/// Minimum timestamp, wall and process-CPU seconds of `record`, over `reps` runs after `warmups`
/// untimed ones.
fn time(
    ctx: &GpuContext,
    (warmups, reps): (usize, usize),
    record: &mut dyn FnMut(&mut wgpu::CommandEncoder) -> Result<(), GpuError>,
) -> Res<Secs> {
    let mut best = Secs {
        gpu: f64::INFINITY,
        wall: f64::INFINITY,
        cpu: f64::INFINITY,
    };
    for rep in 0..warmups + reps.max(1) {
        let (t, c) = (Instant::now(), process_cpu_seconds());
        let g = timestamped(ctx, record)?;
        let (w, c) = (t.elapsed().as_secs_f64(), process_cpu_seconds() - c);
        if rep >= warmups {
            best = Secs {
                gpu: best.gpu.min(g.unwrap_or(f64::NAN)),
                wall: best.wall.min(w),
                cpu: best.cpu.min(c),
            };
        }
    }
    Ok(best)
}

/// What one selection asks the draw stage to do.
#[derive(Clone, Copy, Debug, Default)]
struct Work {
    commands: u64,
    mesh_trees: u64,
    billboard_trees: u64,
    /// Indices submitted (index count x instances over every command): the vertex invocations
    /// without a post-transform cache.
    indices: u64,
}

fn work_of(sel: &GpuSelection) -> Work {
    let mut w = Work {
        commands: sel.commands.len() as u64,
        ..Work::default()
    };
    for (c, d) in sel.commands.iter().zip(&sel.data) {
        let n = c.instance_count as u64;
        if d.lod == LOD_MESH {
            w.mesh_trees += n;
        } else {
            w.billboard_trees += n;
        }
        w.indices += n * c.index_count as u64;
    }
    w
}

/// The draw pass's parts for one selection.
#[derive(Clone, Copy, Debug)]
struct Split {
    full: Secs,
    no_trees: Secs,
    no_fragments: Secs,
    /// Tree pixels left by `NoTrees` and by `NoTreeFragments` (instrument check).
    leak: (u64, u64),
}

fn tree_pixels(ctx: &GpuContext, target: &DrawTarget) -> Res<u64> {
    let img = target.read(ctx)?;
    Ok(img
        .lod_id
        .iter()
        .filter(|&&id| id != LOD_ID_BACKGROUND && id != LOD_ID_TERRAIN)
        .count() as u64)
}

#[allow(clippy::too_many_arguments)]
fn split_draw(
    ctx: &GpuContext,
    draw: &GpuDraw,
    inputs: &DrawInputs,
    camera: &Camera,
    params: &Params,
    target: &DrawTarget,
    reps: (usize, usize),
    probes: &[DrawProbe],
) -> Res<Split> {
    let mut out = Split {
        full: Secs::NAN,
        no_trees: Secs::NAN,
        no_fragments: Secs::NAN,
        leak: (0, 0),
    };
    for &probe in probes {
        let t = time(ctx, reps, &mut |e| {
            draw.encode_probe(ctx, e, inputs, camera, params, target, probe)
                .map(|_| ())
        })?;
        match probe {
            DrawProbe::Full => out.full = t,
            DrawProbe::NoTrees => {
                out.no_trees = t;
                out.leak.0 = tree_pixels(ctx, target)?;
            }
            DrawProbe::NoTreeFragments => {
                out.no_fragments = t;
                out.leak.1 = tree_pixels(ctx, target)?;
            }
        }
    }
    Ok(out)
}

const ALL_PROBES: [DrawProbe; 3] = [
    DrawProbe::Full,
    DrawProbe::NoTrees,
    DrawProbe::NoTreeFragments,
];

/// Vegetation's commands split into commands of at most `c` instances (0: unchanged), each with
/// its own copy of the per-command data; same instances, same order.
fn split_commands(
    sel: &GpuSelection,
    c: u32,
) -> (Vec<DrawCommand>, Vec<forestlod_shared::CommandData>) {
    let (mut cmds, mut data) = (Vec::new(), Vec::new());
    for (cmd, d) in sel.commands.iter().zip(&sel.data) {
        let step = if c == 0 { cmd.instance_count.max(1) } else { c };
        let mut first = 0;
        while first < cmd.instance_count {
            let n = step.min(cmd.instance_count - first);
            cmds.push(DrawCommand {
                instance_count: n,
                first_instance: cmd.first_instance + first,
                base_vertex: ((cmds.len() as u32) << COMMAND_SHIFT) as i32,
                ..*cmd
            });
            data.push(*d);
            first += n;
        }
    }
    (cmds, data)
}

struct Row {
    scene: String,
    camera: String,
    variant: String,
    work: Work,
    select: Secs,
    refine: Secs,
    split: Split,
}

/// Every hierarchy but the seed-faithful, non-conservative `octree-euclidean`.
fn conservative_hierarchies() -> Vec<String> {
    Hierarchy::ALL
        .into_iter()
        .filter(|&h| h != Hierarchy::OctreeEuclidean)
        .map(|h| h.name().to_string())
        .collect()
}

fn main() -> Res<()> {
    let args = Args::parse();
    if args.replot {
        return plot_parts(&args.out);
    }
    let base = args.params.params()?;
    let ctx = GpuContext::new()?;
    println!("adapter: {}", ctx.describe());
    let draw = GpuDraw::new(&ctx)?;
    let target = DrawTarget::new(&ctx, args.width, args.height)?;
    let mut rows: Vec<Row> = Vec::new();
    let mut series = String::from(
        "scene,camera,max_instances_per_command,commands,trees,no_trees_gpu_s,no_tree_fragments_gpu_s,full_gpu_s,no_trees_cpu_s,no_tree_fragments_cpu_s,full_cpu_s\n",
    );
    let mut series_points: Vec<(String, Points, Points)> = Vec::new();
    for scene_name in &args.scenes {
        let scene = builtin::by_name(scene_name)?;
        for (hi, h_name) in args.hierarchies.iter().enumerate() {
            let h = Hierarchy::from_name(h_name).ok_or_else(|| {
                format!(
                    "--hierarchies: unknown hierarchy {h_name:?} (expected one of {})",
                    Hierarchy::ALL.map(Hierarchy::name).join(", ")
                )
            })?;
            let params = Params {
                hierarchy: h as u32,
                ..base
            };
            let t = Instant::now();
            let prepared = prepare(scene.clone(), &params)?;
            let data = DrawSceneData::new(&prepared);
            let gpu_scene = DrawScene::new(&ctx, &data.desc(&prepared))?;
            let textures = gpu_textures(&ctx, &prepared, &params)?.draw_textures()?;
            let mut select = SelectionChain::gpu(&ctx, &prepared)?;
            let first = hi == 0;
            let trees = cull_trees(&prepared);
            // Vegetation and refine run on the first hierarchy's prepared scene (the grid by
            // default): they read the trees, not the hierarchy.
            let mut cull = if first {
                Some(GpuCull::new(&ctx, &trees, &prepared.geometry.meshes)?)
            } else {
                None
            };
            let mut refine = if first && args.refine {
                Some(GpuRefine::new(&ctx, &trees, &prepared.batches.indirection)?)
            } else {
                None
            };
            println!(
                "{scene_name} {h_name}: prepared and uploaded in {:.1} s",
                t.elapsed().as_secs_f64()
            );
            for camera_name in &args.cameras {
                let camera =
                    named_camera(camera_name, &prepared.scene, 0.0, args.width, args.height)?;
                // Every variant's draw, split into its parts, over the same scene, textures,
                // camera and target: only the selection, its indirection and the parameters vary.
                let split_of = |selection: &SelectBuffers,
                                indirection: Option<&wgpu::Buffer>,
                                params: &Params|
                 -> Res<Split> {
                    let inputs = DrawInputs {
                        scene: &gpu_scene,
                        textures: &textures,
                        selection,
                        indirection,
                    };
                    split_draw(
                        &ctx,
                        &draw,
                        &inputs,
                        &camera,
                        params,
                        &target,
                        (args.warmups, args.reps),
                        &ALL_PROBES,
                    )
                };
                let mut push = |row: Row| {
                    report(&row);
                    rows.push(row);
                };
                // Ours, once per command order (the last one's selection stays for refine).
                let mut sel_t = Secs::NAN;
                for order_name in &args.orders {
                    let order = CommandOrder::from_name(order_name).ok_or_else(|| {
                        format!("--orders: unknown command order {order_name:?} (expected node or front-to-back)")
                    })?;
                    let params = Params {
                        command_order: order as u32,
                        ..params
                    };
                    sel_t = time(&ctx, (args.warmups, args.reps), &mut |e| {
                        select.encode(e, &camera, &params, Compaction::Stable);
                        Ok(())
                    })?;
                    let sel = select.buffers().read(&ctx)?;
                    let split = split_of(select.buffers(), None, &params)?;
                    push(Row {
                        scene: scene_name.clone(),
                        camera: camera_name.clone(),
                        variant: if order == CommandOrder::Node {
                            format!("ours {h_name}")
                        } else {
                            format!("ours {h_name} {order_name}")
                        },
                        work: work_of(&sel),
                        select: sel_t,
                        refine: Secs::ZERO,
                        split,
                    });
                }
                // Ours with refine (select, then refine.wgsl, timed apart).
                if let Some(refine) = refine.as_mut() {
                    let rparams = Params {
                        tree_cull: TreeCull::All as u32,
                        ..params
                    };
                    let mut ts = Secs {
                        gpu: f64::INFINITY,
                        wall: f64::INFINITY,
                        cpu: f64::INFINITY,
                    };
                    let runs = args.warmups + args.reps.max(1);
                    for rep in 0..runs {
                        let (t, c) = (Instant::now(), process_cpu_seconds());
                        let g = timestamped(&ctx, &mut |e| {
                            refine.encode(e, select.buffers_mut(), &camera, &rparams);
                            Ok(())
                        });
                        let (w, c) = (t.elapsed().as_secs_f64(), process_cpu_seconds() - c);
                        let g = g?;
                        if rep >= args.warmups {
                            ts = Secs {
                                gpu: ts.gpu.min(g.unwrap_or(f64::NAN)),
                                wall: ts.wall.min(w),
                                cpu: ts.cpu.min(c),
                            };
                        }
                        // `refine` rewrites the selection in place: select again before the next
                        // refine (untimed; the selection's own time is the row above).
                        if rep + 1 < runs {
                            select.dispatch(&camera, &rparams, Compaction::Stable)?;
                            ctx.wait()?;
                        }
                    }
                    let rsel = select.buffers().read(&ctx)?;
                    let split = split_of(select.buffers(), Some(refine.indirection()), &rparams)?;
                    push(Row {
                        scene: scene_name.clone(),
                        camera: camera_name.clone(),
                        variant: format!("ours {h_name} + refine all"),
                        work: work_of(&rsel),
                        select: sel_t,
                        refine: ts,
                        split,
                    });
                }
                // Vegetation.
                if let Some(cull) = cull.as_mut() {
                    let cull_t = time(&ctx, (args.warmups, args.reps), &mut |e| {
                        cull.encode(e, &camera, &params);
                        Ok(())
                    })?;
                    let vsel = cull.buffers().read(&ctx)?;
                    let split = split_of(cull.buffers(), Some(cull.indirection()), &params)?;
                    push(Row {
                        scene: scene_name.clone(),
                        camera: camera_name.clone(),
                        variant: "vegetation".into(),
                        work: work_of(&vsel),
                        select: cull_t,
                        refine: Secs::ZERO,
                        split,
                    });
                    if args.split_cameras.contains(camera_name) {
                        let (mut nofrag, mut full) = (Vec::new(), Vec::new());
                        for &c in &args.split_sizes {
                            let (cmds, cdata) = split_commands(&vsel, c);
                            let counters = forestlod_shared::SelectCounters {
                                commands: cmds.len() as u32,
                                ..vsel.counters
                            };
                            let buffers = SelectBuffers::from_cpu(&ctx, &cmds, &cdata, &counters)?;
                            let s = split_of(&buffers, Some(cull.indirection()), &params)?;
                            let trees: u64 = cmds.iter().map(|c| c.instance_count as u64).sum();
                            let (v, f) =
                                (s.no_fragments.minus(s.no_trees), s.full.minus(s.no_trees));
                            println!(
                                "  split {c}: {} commands, {trees} trees: tree part without fragments {:.1} ms ({:.1} ms CPU), with {:.1} ms ({:.1} ms CPU)",
                                cmds.len(),
                                v.gpu * 1e3,
                                v.cpu * 1e3,
                                f.gpu * 1e3,
                                f.cpu * 1e3
                            );
                            series.push_str(&format!(
                                "{scene_name},{camera_name},{c},{},{trees},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}\n",
                                cmds.len(),
                                s.no_trees.gpu,
                                s.no_fragments.gpu,
                                s.full.gpu,
                                s.no_trees.cpu,
                                s.no_fragments.cpu,
                                s.full.cpu
                            ));
                            nofrag.push((cmds.len() as f64, v.gpu * 1e3));
                            full.push((cmds.len() as f64, v.cpu * 1e3));
                        }
                        series_points.push((format!("{scene_name} {camera_name}"), nofrag, full));
                    }
                }
            }
        }
    }
    std::fs::create_dir_all(&args.out)?;
    let mut csv = String::from(
        "adapter,scene,camera,variant,width,height,commands,mesh_trees,billboard_trees,indices",
    );
    const CLOCKS: [&str; 3] = ["gpu", "wall", "cpu"];
    for clock in CLOCKS {
        for part in [
            "select", "refine", "draw", "ground", "vertex", "fragment", "frame",
        ] {
            csv.push_str(&format!(",{part}_{clock}_s"));
        }
    }
    csv.push_str(",no_trees_tree_pixels,no_tree_fragments_tree_pixels\n");
    for r in &rows {
        let s = &r.split;
        csv.push_str(&format!(
            "\"{}\",{},{},{},{},{},{},{},{},{}",
            ctx.info.name.replace(',', ";"),
            r.scene,
            r.camera,
            r.variant,
            args.width,
            args.height,
            r.work.commands,
            r.work.mesh_trees,
            r.work.billboard_trees,
            r.work.indices
        ));
        let vertex = s.no_fragments.minus(s.no_trees);
        let fragment = s.full.minus(s.no_fragments);
        let frame = r.select.plus(r.refine).plus(s.full);
        for pick in [
            (|t: Secs| t.gpu) as fn(Secs) -> f64,
            |t: Secs| t.wall,
            |t: Secs| t.cpu,
        ] {
            for t in [
                r.select, r.refine, s.full, s.no_trees, vertex, fragment, frame,
            ] {
                csv.push_str(&format!(",{:.6}", pick(t)));
            }
        }
        csv.push_str(&format!(",{},{}\n", s.leak.0, s.leak.1));
    }
    std::fs::write(args.out.join("draw_split.csv"), csv)?;
    std::fs::write(args.out.join("commands.csv"), series)?;
    plot_parts(&args.out)?;
    for (label, nofrag, full) in &series_points {
        let mut axes = Axes::linear(
            format!("Vegetation's trees in N commands, {label}: tree vertex part (no fragments)"),
            "commands",
            "ms",
        );
        axes.log_x = true;
        xy_plot(
            &args
                .out
                .join(format!("commands_{}.png", label.replace(' ', "_"))),
            &axes,
            &[
                Series {
                    label: "timestamps".into(),
                    points: nofrag.clone(),
                },
                Series {
                    label: "process CPU".into(),
                    points: full.clone(),
                },
            ],
            Style::Lines,
        )?;
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Per scene, grouped bars (camera / variant) of the frame's parts, in timestamps
/// (`draw_split_<scene>.png`) and in process CPU seconds (`draw_split_<scene>_cpu.png`), from the
/// `draw_split.csv` in `out`.
fn plot_parts(out: &std::path::Path) -> Res<()> {
    let path = out.join("draw_split.csv");
    // A CSV this program wrote (`--replot`): regular file, 64 MiB at most (issue 28).
    let bytes = forestlod_reference::files::read_limited(&path, 64 << 20)?;
    let mut reader = csv::Reader::from_reader(&bytes[..]);
    let headers = reader.headers()?.clone();
    let records: Vec<csv::StringRecord> = reader.records().collect::<Result<_, _>>()?;
    let col = |r: &csv::StringRecord, name: &str| -> Res<String> {
        let i = headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no column {name}", path.display()))?;
        Ok(r[i].to_string())
    };
    let num = |r: &csv::StringRecord, name: &str| -> Res<f64> {
        let v = col(r, name)?;
        v.parse().map_err(|_| {
            format!(
                "{}: column {name}: value {v:?} is no number",
                path.display()
            )
            .into()
        })
    };
    let mut scenes: Vec<String> = Vec::new();
    for r in &records {
        let s = col(r, "scene")?;
        if !scenes.contains(&s) {
            scenes.push(s);
        }
    }
    let bars: Vec<String> = [
        "select+refine",
        "clear+ground",
        "tree vertex",
        "tree fragment",
    ]
    .map(String::from)
    .to_vec();
    for scene in &scenes {
        let mine: Vec<&csv::StringRecord> = records
            .iter()
            .filter(|r| col(r, "scene").is_ok_and(|s| &s == scene))
            .collect();
        // Short labels: the plot's group labels have room for about 8 characters.
        let mut groups = Vec::new();
        for r in &mine {
            let variant = col(r, "variant")?
                .replace("ours ", "")
                .replace(" + refine all", "+ref")
                .replace("vegetation", "Veg")
                .replace("quadtree", "quad")
                .replace("octree", "oct");
            let camera = col(r, "camera")?;
            groups.push(format!("{} {variant}", &camera[..1].to_uppercase()));
        }
        let (w, h) = (col(mine[0], "width")?, col(mine[0], "height")?);
        for (clock, suffix) in [("gpu", ""), ("cpu", "_cpu")] {
            let mut values = Vec::new();
            for r in &mine {
                values.push(vec![
                    num(r, &format!("select_{clock}_s"))? + num(r, &format!("refine_{clock}_s"))?,
                    num(r, &format!("ground_{clock}_s"))?,
                    num(r, &format!("vertex_{clock}_s"))?,
                    num(r, &format!("fragment_{clock}_s"))?,
                ]);
            }
            let name = if clock == "gpu" {
                "timestamps"
            } else {
                "process CPU"
            };
            bar_plot(
                &out.join(format!("draw_split_{scene}{suffix}.png")),
                &Axes::linear(
                    format!("Frame parts, {scene}, {w}x{h} ({name}, s); C close, M medium"),
                    "camera / variant",
                    "seconds",
                ),
                &groups,
                &bars,
                &values,
            )?;
        }
    }
    Ok(())
}

fn report(r: &Row) {
    let s = &r.split;
    let (v, f) = (
        s.no_fragments.minus(s.no_trees),
        s.full.minus(s.no_fragments),
    );
    println!(
        "{} {} {}: {} commands, {} mesh + {} billboard trees, {} indices | select {:.1} ms, refine {:.1} ms | draw {:.1} ms = ground {:.1} + vertex {:.1} + fragment {:.1} | CPU: draw {:.1} ms = ground {:.1} + vertex {:.1} + fragment {:.1} | leaks {:?}",
        r.scene,
        r.camera,
        r.variant,
        r.work.commands,
        r.work.mesh_trees,
        r.work.billboard_trees,
        r.work.indices,
        r.select.gpu * 1e3,
        r.refine.gpu * 1e3,
        s.full.gpu * 1e3,
        s.no_trees.gpu * 1e3,
        v.gpu * 1e3,
        f.gpu * 1e3,
        s.full.cpu * 1e3,
        s.no_trees.cpu * 1e3,
        v.cpu * 1e3,
        f.cpu * 1e3,
        s.leak
    );
}
