//! `forestlod export-case` and `forestlod verify` (issue 15): judge *another* implementation's
//! GPU output against the oracle through files, with the same classified verdict as the
//! in-process parity (`forestlod_harness::image_compare`: classes, budgets, bias gates, FLIP).
//!
//! ## The case folder (`export-case --out CASE`)
//!
//! | file | format |
//! |---|---|
//! | `case.json` | `format` (`"forestlod-case/1"`), `scene` (name, `origin` f64 world metres, tree count), `camera` (`eye`, `forward`, `up` scene-local metres, Z up; `fov_y_degrees` vertical; `near`, `far`; `width`, `height` pixels), `params` (every pipeline parameter under its flag's underscore name), `alpha_cutoff_shifts` of the alternatives |
//! | `instances.csv` | the scene's trees, `x,y,z,yaw,scale,species` (scene-local metres, radians, species index), one a line after a header |
//! | `reference/color.png` | the oracle's colour, 8-bit RGBA, sRGB-encoded RGB, linear alpha, top row first |
//! | `reference/depth.exr` | its depth buffer, one `f32` channel `Z` in `[0, 1]` (wgpu clip depth, 1 = far/background) |
//! | `reference/lod_id.png` | its LOD id per pixel as 8-bit grey (0 background, 1 mesh, 2 billboard, 3 transition band, 4 terrain) |
//! | `reference/commands.csv` | the draw commands the oracle's frame draws (`Prepared::render`'s: the output of the last selection stage of the frame's plan, [`FramePlan`], so `refine`'s when `tree_cull` is not `none`, whose `first_instance` then indexes refine's `3n` indirection), one a line: `index_count,instance_count,first_index,base_vertex,first_instance,mesh,lod,billboard,fading` |
//! | `alternatives/<k>/{color.png,depth.exr,lod_id.png}` | the oracle's frames with the alpha-test cutoff moved by each shift (they classify threshold-ambiguous pixels) |
//!
//! ## What `verify --case CASE --outputs DIR` reads
//! `DIR/color.png`, `DIR/depth.exr`, `DIR/lod_id.png` in the formats above and, when present,
//! `DIR/commands.csv`: the commands the implementation draws, after every selection stage of the
//! case's plan (`FramePlan::new` of the case's `params`: `refine` included when `tree_cull` is not
//! `none`), compared with `reference/commands.csv` as a multiset (an implementation may order
//! atomically, so `base_vertex` is compared without its command index,
//! `base_vertex & (MAX_MESH_VERTICES - 1)`: the index is the command's position, which an atomic
//! order changes); a difference names the plan's last selection stage. It prints
//! the report of `image_compare` (every class with its budget, the signed-difference statistics,
//! FLIP) and the verdict as the last line; exit 0 when parity holds, 2 when it fails (the main
//! job's code for "GPU parity failed"), 1 for bad input (a missing or malformed file, a size that
//! is not the case's), naming the file.
//!
//! `export-case --with-gpu` also writes this project's own GPU frame into `CASE/gpu/` in exactly
//! the format `verify` reads, which is how the round trip is tested
//! (`experiments/tests/cli_verify.rs`).

use std::path::{Path, PathBuf};

use forestlod_harness::alternatives::alpha_test_alternatives;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu};
use forestlod_harness::image_compare::{ALPHA_TEST_SHIFTS, Images, compare_images};
use forestlod_harness::stage::images_of;
use forestlod_reference::error::InputError;
use forestlod_reference::output::{read_depth_exr, read_png, write_depth_exr, write_png};
use forestlod_reference::pipeline::prepare;
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{Camera, CommandData, DrawCommand, FramePlan, ParamKind, Params};
use serde_json::json;

use crate::camera::CameraArgs;
use crate::options::{ParamArgs, SceneArgs};
use crate::render::{exit_code, params_json};

/// `forestlod export-case`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub params: ParamArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Image width, pixels.
    #[arg(long, default_value_t = 128)]
    pub width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 128)]
    pub height: u32,
    /// The case folder (created; files of an earlier case are overwritten).
    #[arg(long)]
    pub out: PathBuf,
    /// Also render this project's GPU frame into OUT/gpu/ in the format `verify` reads.
    #[arg(long)]
    pub with_gpu: bool,
}

/// `forestlod verify`.
#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    /// A case folder written by `export-case`.
    #[arg(long)]
    pub case: PathBuf,
    /// The implementation's outputs: color.png, depth.exr, lod_id.png, optionally commands.csv.
    #[arg(long)]
    pub outputs: PathBuf,
}

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn io(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::new(path.display().to_string(), "", "", e.to_string())
}

/// The LOD ids as 8-bit grey.
fn id_png(images: &Images) -> Rgba8Image {
    Rgba8Image {
        width: images.width,
        height: images.height,
        texels: images
            .lod_id
            .iter()
            .map(|&id| {
                let v = id.min(255) as u8;
                [v, v, v, 255]
            })
            .collect(),
    }
}

/// Writes `images` as `color.png`, `depth.exr`, `lod_id.png` into `dir`.
fn write_frame(dir: &Path, images: &Images) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    write_png(&dir.join("color.png"), &images.color_image())?;
    write_depth_exr(
        &dir.join("depth.exr"),
        images.width,
        images.height,
        &images.depth,
    )?;
    write_png(&dir.join("lod_id.png"), &id_png(images))?;
    Ok(())
}

/// Reads a frame written in the case format, checking its size against `(width, height)`.
fn read_frame(dir: &Path, width: u32, height: u32) -> Result<Images> {
    let color_path = dir.join("color.png");
    let color = read_png(&color_path)?;
    let (dw, dh, depth) = read_depth_exr(&dir.join("depth.exr"))?;
    let ids = read_png(&dir.join("lod_id.png"))?;
    for (path, size) in [
        (color_path, (color.width, color.height)),
        (dir.join("depth.exr"), (dw, dh)),
        (dir.join("lod_id.png"), (ids.width, ids.height)),
    ] {
        if size != (width, height) {
            return Err(io(
                &path,
                format!(
                    "size {}x{}: expected the case's {width}x{height}",
                    size.0, size.1
                ),
            )
            .into());
        }
    }
    if depth.len() != (width * height) as usize {
        return Err(io(&dir.join("depth.exr"), "wrong sample count").into());
    }
    Ok(Images {
        width,
        height,
        color: color.texels,
        depth,
        lod_id: ids.texels.iter().map(|t| u32::from(t[0])).collect(),
    })
}

const COMMANDS_HEADER: &str =
    "index_count,instance_count,first_index,base_vertex,first_instance,mesh,lod,billboard,fading";

/// Commands in the `commands.csv` format.
pub fn commands_csv(commands: &[DrawCommand], data: &[CommandData]) -> String {
    let mut csv = String::from(COMMANDS_HEADER);
    csv.push('\n');
    for (c, d) in commands.iter().zip(data) {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{},{}\n",
            c.index_count,
            c.instance_count,
            c.first_index,
            c.base_vertex,
            c.first_instance,
            d.mesh,
            d.lod,
            d.billboard,
            d.fading
        ));
    }
    csv
}

/// Reads `commands.csv` as sorted rows (a multiset), each `base_vertex` (column 3) without the
/// command index above [`forestlod_shared::COMMAND_SHIFT`]: the index is the command's position in
/// the list, which an atomic compaction orders differently from run to run (module docs).
fn read_commands(path: &Path) -> Result<Vec<Vec<i64>>> {
    let text = std::fs::read_to_string(path).map_err(|e| io(path, e))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if i == 0 || line.trim().is_empty() {
            continue;
        }
        let row: std::result::Result<Vec<i64>, _> =
            line.split(',').map(|v| v.trim().parse::<i64>()).collect();
        match row {
            Ok(mut r) if r.len() == 9 => {
                r[3] &= i64::from(forestlod_shared::MAX_MESH_VERTICES - 1);
                rows.push(r)
            }
            _ => {
                return Err(io(
                    path,
                    format!(
                        "line {}: {:?}: expected 9 integers ({COMMANDS_HEADER})",
                        i + 1,
                        line.chars().take(40).collect::<String>()
                    ),
                )
                .into());
            }
        }
    }
    rows.sort();
    Ok(rows)
}

/// `forestlod export-case`.
pub fn export(args: &ExportArgs) -> Result<u8> {
    let params = args.params.params()?;
    let scene = args.scene.load()?;
    let camera = args.camera.camera(&scene, args.width, args.height)?;
    std::fs::create_dir_all(&args.out).map_err(|e| io(&args.out, e))?;
    let prepared = prepare(scene, &params)?;
    // The oracle's frame, and the commands it draws: every selection stage of the frame's plan,
    // `refine` included when `tree_cull` runs it (module docs).
    let frame = prepared.render(&camera, &params)?;
    let out = &args.out;
    write_frame(&out.join("reference"), &images_of(&frame.drawn.target))?;
    let selection = &frame.selection;
    let path = out.join("reference/commands.csv");
    std::fs::write(&path, commands_csv(&selection.commands, &selection.data))
        .map_err(|e| io(&path, e))?;
    for (k, alt) in alpha_test_alternatives(&prepared, &camera, &params)
        .iter()
        .enumerate()
    {
        write_frame(&out.join(format!("alternatives/{k}")), alt)?;
    }
    let scene = &prepared.scene;
    let mut trees = String::from("x,y,z,yaw,scale,species\n");
    for t in &scene.instances {
        trees.push_str(&format!(
            "{},{},{},{},{},{}\n",
            t.position[0], t.position[1], t.position[2], t.yaw, t.scale, t.mesh
        ));
    }
    let path = out.join("instances.csv");
    std::fs::write(&path, trees).map_err(|e| io(&path, e))?;
    let shifts: Vec<f32> = ALPHA_TEST_SHIFTS.iter().flat_map(|&d| [-d, d]).collect();
    let case = json!({
        "format": "forestlod-case/1",
        "scene": {"name": scene.name, "origin": scene.origin, "trees": scene.instances.len()},
        "camera": {
            "eye": camera.eye, "forward": camera.forward, "up": camera.up,
            "fov_y_degrees": camera.fov_y.to_degrees(), "near": camera.near, "far": camera.far,
            "width": camera.width, "height": camera.height,
        },
        "params": params_json(&params),
        "alpha_cutoff_shifts": shifts,
        "commands": selection.commands.len(),
    });
    let path = out.join("case.json");
    std::fs::write(&path, serde_json::to_string_pretty(&case)? + "\n").map_err(|e| io(&path, e))?;
    println!(
        "case written to {} ({}x{}, {} commands)",
        out.display(),
        camera.width,
        camera.height,
        selection.commands.len()
    );
    if args.with_gpu {
        let ctx = forestlod_gpu::GpuContext::new().map_err(|e| format!("GPU: {e}"))?;
        let draw = forestlod_gpu::GpuDraw::new(&ctx).map_err(|e| format!("GPU: {e}"))?;
        let gpu_err = |e: forestlod_gpu::GpuError| format!("GPU: {e}");
        let mut scene =
            GpuScene::with_pipelines(&ctx, &draw, &prepared, &params, StagesFromCpu::NONE)
                .map_err(gpu_err)?;
        let stable = GpuPipeline::Ours(forestlod_gpu::Compaction::Stable);
        let gpu = scene
            .render(&prepared, stable, &camera, &params)
            .map_err(gpu_err)?;
        write_frame(&out.join("gpu"), &gpu.images)?;
        // The GPU frame's commands as its draw reads them (the plan's selection stages and
        // `refine` when planned), with the flat selection's atomic compaction: another order
        // than the reference's (a cut has one order).
        let atomic = GpuPipeline::Ours(forestlod_gpu::Compaction::Atomic);
        scene
            .render(&prepared, atomic, &camera, &params)
            .map_err(gpu_err)?;
        let s = scene
            .chain()
            .expect("a frame of ours ran the GPU selection chain")
            .buffers()
            .read(&ctx)
            .map_err(gpu_err)?;
        let path = out.join("gpu/commands.csv");
        std::fs::write(&path, commands_csv(&s.commands, &s.data)).map_err(|e| io(&path, e))?;
        println!(
            "this project's GPU frame written to {}",
            out.join("gpu").display()
        );
    }
    Ok(exit_code::SUCCESS)
}

fn field<'a>(case: &'a serde_json::Value, path: &Path, key: &str) -> Result<&'a serde_json::Value> {
    case.pointer(key)
        .ok_or_else(|| io(path, format!("field {key} missing")).into())
}

fn vec3(case: &serde_json::Value, path: &Path, key: &str) -> Result<[f32; 3]> {
    let v = field(case, path, key)?;
    let a: Option<Vec<f32>> = v.as_array().map(|a| {
        a.iter()
            .filter_map(|x| x.as_f64().map(|x| x as f32))
            .collect()
    });
    match a {
        Some(a) if a.len() == 3 => Ok([a[0], a[1], a[2]]),
        _ => Err(io(path, format!("field {key} = {v}: expected three numbers")).into()),
    }
}

fn number(case: &serde_json::Value, path: &Path, key: &str) -> Result<f64> {
    let v = field(case, path, key)?;
    v.as_f64()
        .ok_or_else(|| io(path, format!("field {key} = {v}: expected a number")).into())
}

/// The case's pipeline parameters (`params`, every parameter under its flag's underscore name as
/// `export-case` writes them, [`params_json`]; one missing takes its default), validated.
fn case_params(case: &serde_json::Value, path: &Path) -> Result<Params> {
    let table = field(case, path, "/params")?
        .as_object()
        .ok_or_else(|| io(path, "field /params: expected an object"))?;
    let mut params = Params::default();
    for spec in forestlod_shared::PARAMS {
        let Some(v) = table.get(&spec.key()) else {
            continue;
        };
        let parsed = match (spec.kind, v) {
            (ParamKind::Choice(_), serde_json::Value::String(name)) => spec.parse(name).ok(),
            (ParamKind::Choice(_), _) => None,
            (_, v) => v.as_f64().and_then(|x| spec.from_number(x).ok()),
        };
        let value = parsed.ok_or_else(|| {
            io(
                path,
                format!("field /params/{} = {v}: {}", spec.key(), spec.expected()),
            )
        })?;
        (spec.set)(&mut params, value);
    }
    params
        .validate()
        .map_err(|e| io(path, format!("params: {e}")))?;
    Ok(params)
}

/// `forestlod verify`.
pub fn verify(args: &VerifyArgs) -> Result<u8> {
    let path = args.case.join("case.json");
    let text = std::fs::read_to_string(&path).map_err(|e| io(&path, e))?;
    let case: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| io(&path, format!("not JSON: {e}")))?;
    if case.get("format").and_then(|f| f.as_str()) != Some("forestlod-case/1") {
        return Err(io(&path, "field format: expected \"forestlod-case/1\"").into());
    }
    let (width, height) = (
        number(&case, &path, "/camera/width")? as u32,
        number(&case, &path, "/camera/height")? as u32,
    );
    let camera = Camera {
        eye: vec3(&case, &path, "/camera/eye")?,
        forward: vec3(&case, &path, "/camera/forward")?,
        up: vec3(&case, &path, "/camera/up")?,
        fov_y: (number(&case, &path, "/camera/fov_y_degrees")? as f32).to_radians(),
        near: number(&case, &path, "/camera/near")? as f32,
        far: number(&case, &path, "/camera/far")? as f32,
        width,
        height,
        tile: [0; 2],
    };
    camera
        .validate()
        .map_err(|e| io(&path, format!("camera: {e}")))?;
    // The stage whose output the commands are: the last selection stage of the case's plan.
    let plan = FramePlan::new(&case_params(&case, &path)?)
        .map_err(|e| io(&path, format!("params: {e}")))?;
    let last_stage = plan
        .selection_stages()
        .last()
        .map_or("select", |s| s.name());
    let want = read_frame(&args.case.join("reference"), width, height)?;
    let shifts = field(&case, &path, "/alpha_cutoff_shifts")?
        .as_array()
        .map_or(0, |a| a.len());
    let alternatives: Vec<Images> = (0..shifts)
        .map(|k| read_frame(&args.case.join(format!("alternatives/{k}")), width, height))
        .collect::<Result<_>>()?;
    let got = read_frame(&args.outputs, width, height)?;
    let mut failures = Vec::new();
    let commands = args.outputs.join("commands.csv");
    if commands.exists() {
        let a = read_commands(&args.case.join("reference/commands.csv"))?;
        let b = read_commands(&commands)?;
        let missing = a.iter().filter(|r| !b.contains(r)).count();
        let extra = b.iter().filter(|r| !a.contains(r)).count();
        println!(
            "commands: {} reference, {} yours, {missing} missing, {extra} extra (compared as a multiset)",
            a.len(),
            b.len()
        );
        if a != b {
            failures.push(format!(
                "stage {last_stage}: the command multisets differ ({missing} missing, {extra} extra)"
            ));
        }
    }
    let report = compare_images(
        &args.outputs.display().to_string(),
        &got,
        &want,
        &alternatives,
        &camera,
    );
    println!("{report}");
    failures.extend(report.failures());
    if failures.is_empty() {
        println!("parity passed");
        Ok(exit_code::SUCCESS)
    } else {
        println!("parity FAILED: {}", failures.join("; "));
        Ok(exit_code::PARITY_FAILED)
    }
}
