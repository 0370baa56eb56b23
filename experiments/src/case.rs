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
//! ## Bad input (issue 28)
//! `--case` and `--outputs` must be folders (a missing path, a file, a FIFO or a dangling link is
//! one error naming the flag). Every file is read through `forestlod_reference::files` (regular
//! files only, a size limit checked before reading): `case.json` at most [`MAX_CASE_JSON_BYTES`],
//! each `commands.csv` at most [`MAX_COMMANDS_FILE_BYTES`], each image at most
//! `frame_file_limit(width, height)` of the case's size, whose declared size (PNG IHDR, EXR
//! data window) must be the case's before a pixel is decoded. `case.json` is parsed by the pure
//! [`parse_case_json`] (no lossy casts; unknown, missing or twice-given fields refused). The
//! oracle's files (`reference/`, `alternatives/<k>/`) must hold only what `export-case` writes
//! (depths finite in `[0, 1]`, grey LOD ids `0..=4`, 8-bit RGBA PNGs, one `f32` channel `Z`,
//! `case.json`'s command count): anything else is a bad case (exit 1 naming the file and pixel),
//! not blamed on the implementation. NaN or infinite depths in the outputs fail parity (exit 2,
//! their count on the verdict line), whatever the edge rules would forgive.
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
use forestlod_reference::output::{
    read_depth_exr_sized, read_png_sized, write_depth_exr, write_png,
};
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

fn io_at(
    path: &Path,
    position: impl Into<String>,
    value: impl std::fmt::Display,
    reason: impl Into<String>,
) -> InputError {
    InputError::new(path.display().to_string(), position, value, reason)
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

/// Whose frame [`read_frame`] reads: the oracle's (a case's `reference/` or `alternatives/<k>/`,
/// held to exactly what `export-case` writes) or an implementation's (`--outputs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Frame {
    Oracle,
    Implementation,
}

/// Why an oracle file is refused (issue 28: a bad case is not blamed on the implementation).
const NOT_THE_ORACLES: &str = "not what export-case writes: a bad case (the oracle never produces this), not the \
     implementation's fault";

/// Reads a frame written in the case format, its size the case's `(width, height)`; every
/// file a regular file within [`forestlod_reference::output::frame_file_limit`] of that size, its declared size checked before
/// decoding (issue 28). An oracle frame must be exactly what `export-case` writes (8-bit RGBA
/// PNGs, one `f32` channel `Z` of depths in `[0, 1]`, grey LOD ids `0..=4` opaque): anything else
/// is bad input naming the file and the first offending pixel. An implementation's frame may use
/// any PNG colour type and a 16-bit float depth channel; its NaN or infinite depths are counted
/// by [`non_finite_depths`] (a parity failure, not bad input).
fn read_frame(dir: &Path, width: u32, height: u32, whose: Frame) -> Result<Images> {
    let color_path = dir.join("color.png");
    let depth_path = dir.join("depth.exr");
    let ids_path = dir.join("lod_id.png");
    let color = read_png_sized(&color_path, width, height)?;
    let depth = read_depth_exr_sized(&depth_path, width, height)?;
    let ids = read_png_sized(&ids_path, width, height)?;
    if whose == Frame::Oracle {
        for (path, png) in [(&color_path, &color), (&ids_path, &ids)] {
            if !png.is_rgba8 {
                return Err(io_at(path, "colour type", &png.colour_type, NOT_THE_ORACLES).into());
            }
        }
        if !(depth.is_f32 && depth.channel == "Z") {
            let kind = if depth.is_f32 { "f32" } else { "f16" };
            return Err(io_at(
                &depth_path,
                "channel",
                format!("{} ({kind})", depth.channel),
                format!("expected one f32 channel Z: {NOT_THE_ORACLES}"),
            )
            .into());
        }
        let pixel = |i: usize| format!("pixel ({}, {})", i % width as usize, i / width as usize);
        let bad_depths = depth
            .values
            .iter()
            .filter(|d| !(0.0..=1.0).contains(*d))
            .count();
        if let Some(i) = depth.values.iter().position(|d| !(0.0..=1.0).contains(d)) {
            return Err(io_at(
                &depth_path,
                pixel(i),
                depth.values[i],
                format!(
                    "{bad_depths} depths are NaN, infinite or outside [0, 1]: {NOT_THE_ORACLES}"
                ),
            )
            .into());
        }
        let lod_ids = forestlod_shared::LOD_ID_BACKGROUND..=forestlod_shared::LOD_ID_TERRAIN;
        if let Some(i) = ids.image.texels.iter().position(|&[r, g, b, a]| {
            !(r == g && g == b && a == 255 && lod_ids.contains(&u32::from(r)))
        }) {
            return Err(io_at(
                &ids_path,
                pixel(i),
                format!("{:?}", ids.image.texels[i]),
                format!(
                    "expected an opaque grey LOD id in {}..={}: {NOT_THE_ORACLES}",
                    lod_ids.start(),
                    lod_ids.end()
                ),
            )
            .into());
        }
    }
    Ok(Images {
        width,
        height,
        color: color.image.texels,
        depth: depth.values,
        lod_id: ids.image.texels.iter().map(|t| u32::from(t[0])).collect(),
    })
}

/// How many of an implementation's depths are NaN or infinite: each fails `verify` (issue 28;
/// a NaN compares unequal to nothing, and the edge-ambiguity rules must not forgive it).
pub fn non_finite_depths(depth: &[f32]) -> usize {
    depth.iter().filter(|d| !d.is_finite()).count()
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

/// Largest `commands.csv` accepted (reference or implementation), bytes (issue 28): a row is at
/// most 9 numbers of 10 digits and their commas (under 110 bytes); 128 MiB holds over a million
/// commands at the widest, far more than a frame's batches, LODs and billboards give (the cases
/// of the tests draw tens to thousands).
pub const MAX_COMMANDS_FILE_BYTES: u64 = 128 << 20;

/// The columns of `commands.csv` that hold an `i32` (`base_vertex`); the others hold a `u32`.
const SIGNED_COLUMN: usize = 3;

/// One row of `commands.csv`, its `base_vertex` without the command index (see [`read_commands`]).
type CommandRow = [i64; 9];

/// Parses `commands.csv` text (`file` names it in errors) as sorted rows (a multiset), each
/// `base_vertex` (column 3) without the command index above [`forestlod_shared::COMMAND_SHIFT`]:
/// the index is the command's position in the list, which an atomic compaction orders
/// differently from run to run (module docs). The header must be the format's; every value an
/// integer in its column's type (`i32` for `base_vertex`, `u32` else), at most
/// [`forestlod_shared::MAX_COMMANDS`] rows; an error names the line, the column and the value.
pub fn parse_commands_csv(
    text: &str,
    file: &str,
) -> std::result::Result<Vec<CommandRow>, InputError> {
    let columns: Vec<&str> = COMMANDS_HEADER.split(',').collect();
    let mut lines = text.lines().enumerate();
    let header = lines
        .next()
        .map_or("", |(_, l)| l.trim_start_matches('\u{feff}').trim());
    if header != COMMANDS_HEADER {
        return Err(InputError::new(
            file,
            "line 1",
            header,
            format!("expected the header {COMMANDS_HEADER}"),
        ));
    }
    let mut rows = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        if rows.len() >= forestlod_shared::MAX_COMMANDS as usize {
            return Err(InputError::new(
                file,
                format!("line {}", i + 1),
                rows.len() + 1,
                format!("more than {} commands", forestlod_shared::MAX_COMMANDS),
            ));
        }
        let values: Vec<&str> = line.split(',').collect();
        if values.len() != 9 {
            return Err(InputError::new(
                file,
                format!("line {}", i + 1),
                line,
                format!("{} values: expected 9 ({COMMANDS_HEADER})", values.len()),
            ));
        }
        let mut row = [0i64; 9];
        for (c, (v, r)) in values.iter().zip(&mut row).enumerate() {
            let range = if c == SIGNED_COLUMN {
                i64::from(i32::MIN)..=i64::from(i32::MAX)
            } else {
                0..=i64::from(u32::MAX)
            };
            *r = v
                .trim()
                .parse::<i64>()
                .ok()
                .filter(|x| range.contains(x))
                .ok_or_else(|| {
                    InputError::new(
                        file,
                        format!("line {}, column {}", i + 1, columns[c]),
                        v.trim(),
                        format!(
                            "expected an integer in {}..={} ({})",
                            range.start(),
                            range.end(),
                            if c == SIGNED_COLUMN { "i32" } else { "u32" }
                        ),
                    )
                })?;
        }
        row[SIGNED_COLUMN] &= i64::from(forestlod_shared::MAX_MESH_VERTICES - 1);
        rows.push(row);
    }
    rows.sort_unstable();
    Ok(rows)
}

/// Reads `commands.csv` ([`parse_commands_csv`]): a regular file of at most
/// [`MAX_COMMANDS_FILE_BYTES`].
fn read_commands(path: &Path) -> Result<Vec<CommandRow>> {
    let text = forestlod_reference::files::read_text_limited(path, MAX_COMMANDS_FILE_BYTES)?;
    Ok(parse_commands_csv(&text, &path.display().to_string())?)
}

/// `forestlod export-case`.
pub fn export(args: &ExportArgs) -> Result<u8> {
    // `--out` checked before any work, and created only once the scene is prepared (issue 28).
    crate::render::check_out(&args.out)?;
    crate::render::check_viewport(args.width, args.height)?;
    let params = args.params.params()?;
    let scene = args.scene.load()?;
    let camera = args.camera.camera(&scene, args.width, args.height)?;
    let prepared = prepare(scene, &params)?;
    std::fs::create_dir_all(&args.out).map_err(|e| io(&args.out, e))?;
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

/// Largest `case.json` accepted, bytes (issue 28): `export-case` writes about 2 KB (a camera,
/// every pipeline parameter and a few shifts); 1 MiB is room for any hand edit and no more.
pub const MAX_CASE_JSON_BYTES: u64 = 1 << 20;

/// Most alternative frames a case may name (`alpha_cutoff_shifts`; `export-case` writes
/// `2 * ALPHA_TEST_SHIFTS.len()` = 6): each is three images read in full.
pub const MAX_ALTERNATIVES: usize = 64;

/// The case format [`parse_case_json`] reads.
pub const CASE_FORMAT: &str = "forestlod-case/1";

/// A case's `case.json` as [`parse_case_json`] validated it.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseJson {
    /// The camera (valid: [`Camera::validate`]); its `width`x`height` is every image's size.
    pub camera: Camera,
    /// The pipeline parameters (valid, with a [`FramePlan`]).
    pub params: Params,
    /// How many alternative frames `alternatives/<k>/` the case holds (`alpha_cutoff_shifts`).
    pub alternatives: usize,
    /// How many commands `reference/commands.csv` holds.
    pub commands: u64,
}

/// A JSON value parsed with duplicate keys refused (serde_json keeps the last silently).
struct NoDuplicates(serde_json::Value);

impl<'de> serde::Deserialize<'de> for NoDuplicates {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use serde::de::{Error, MapAccess, SeqAccess, Visitor};
        use serde_json::Value;
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = NoDuplicates;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a JSON value")
            }
            fn visit_bool<E: Error>(self, v: bool) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::Bool(v)))
            }
            fn visit_i64<E: Error>(self, v: i64) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::from(v)))
            }
            fn visit_u64<E: Error>(self, v: u64) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::from(v)))
            }
            fn visit_f64<E: Error>(self, v: f64) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::from(v)))
            }
            fn visit_str<E: Error>(self, v: &str) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::String(v.to_string())))
            }
            fn visit_string<E: Error>(self, v: String) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::String(v)))
            }
            fn visit_unit<E: Error>(self) -> std::result::Result<Self::Value, E> {
                Ok(NoDuplicates(Value::Null))
            }
            fn visit_seq<A: SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let mut out = Vec::new();
                while let Some(NoDuplicates(v)) = seq.next_element()? {
                    out.push(v);
                }
                Ok(NoDuplicates(Value::Array(out)))
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                mut map: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let mut out = serde_json::Map::new();
                while let Some(key) = map.next_key::<String>()? {
                    let NoDuplicates(v) = map.next_value()?;
                    if out.contains_key(&key) {
                        return Err(A::Error::custom(format!("key {key:?} given twice")));
                    }
                    out.insert(key, v);
                }
                Ok(NoDuplicates(Value::Object(out)))
            }
        }
        d.deserialize_any(V)
    }
}

/// Reads fields of `case.json` by path, every refusal naming the file, the field and its value.
struct Fields<'a> {
    file: &'a str,
}

impl Fields<'_> {
    fn error(
        &self,
        field: &str,
        value: &serde_json::Value,
        reason: impl Into<String>,
    ) -> InputError {
        InputError::new(self.file, format!("field {field}"), value, reason)
    }

    /// The object at `field`, with exactly the keys `keys` (issue 28: a field this version does not
    /// know is an error, not dropped; a missing one too).
    fn object<'v>(
        &self,
        v: &'v serde_json::Value,
        field: &str,
        keys: &[&str],
    ) -> std::result::Result<&'v serde_json::Map<String, serde_json::Value>, InputError> {
        let o = v
            .as_object()
            .ok_or_else(|| self.error(field, v, "expected an object"))?;
        let inner = |k: &str| {
            if field.is_empty() {
                k.to_string()
            } else {
                format!("{field}.{k}")
            }
        };
        if let Some(k) = o.keys().find(|k| !keys.contains(&k.as_str())) {
            return Err(self.error(
                &inner(k),
                &o[k],
                format!(
                    "not a field of the case format {CASE_FORMAT}: expected {}",
                    keys.join(", ")
                ),
            ));
        }
        if let Some(k) = keys.iter().find(|k| !o.contains_key(**k)) {
            return Err(InputError::new(
                self.file,
                format!("field {}", inner(k)),
                "",
                "missing",
            ));
        }
        Ok(o)
    }

    /// A finite number within the range of `f32` (no silent infinity).
    fn single(&self, v: &serde_json::Value, field: &str) -> std::result::Result<f32, InputError> {
        match v.as_f64() {
            Some(x) if x.is_finite() && x.abs() <= f64::from(f32::MAX) => Ok(x as f32),
            _ => Err(self.error(field, v, "expected a finite number within the range of f32")),
        }
    }

    fn triple(
        &self,
        v: &serde_json::Value,
        field: &str,
    ) -> std::result::Result<[f32; 3], InputError> {
        match v.as_array() {
            Some(a) if a.len() == 3 => Ok([
                self.single(&a[0], field)?,
                self.single(&a[1], field)?,
                self.single(&a[2], field)?,
            ]),
            _ => Err(self.error(field, v, "expected three numbers")),
        }
    }

    /// An integer (never a float: `128.9` and `-5` are errors, not 128 and 0) in `range`.
    fn integer(
        &self,
        v: &serde_json::Value,
        field: &str,
        range: std::ops::RangeInclusive<u64>,
    ) -> std::result::Result<u64, InputError> {
        v.as_u64().filter(|x| range.contains(x)).ok_or_else(|| {
            self.error(
                field,
                v,
                format!("expected an integer in {}..={}", range.start(), range.end()),
            )
        })
    }
}

/// Parses and validates a case's `case.json` (module docs; what `export-case` writes), `file`
/// naming it in errors. Pure: no file is read (issue 28). Refused, each with one [`InputError`]
/// naming `file`, the field and its value: text that is not JSON (with its line and column), a
/// key given twice, a format other than [`CASE_FORMAT`], a missing field or one the format does
/// not have (at every level, `params` included: a parameter this version does not know is an
/// error, not dropped; a parameter given twice under two of its names too), a number that is not
/// finite or beyond `f32`, a `width`, `height`, `trees` or `commands` that is not an integer in
/// range, an integer parameter given as a float, an invalid camera or parameter
/// ([`Camera::validate`], [`Params::validate`], [`FramePlan::new`]), more than
/// [`MAX_ALTERNATIVES`] shifts. A parameter the case does not give takes its default (cases of
/// before a parameter existed replay as they were).
pub fn parse_case_json(text: &str, file: &str) -> std::result::Result<CaseJson, InputError> {
    let NoDuplicates(case) = serde_json::from_str(text).map_err(|e| {
        InputError::new(
            file,
            format!("line {}, column {}", e.line(), e.column()),
            "",
            format!("not a case file (JSON): {e}"),
        )
    })?;
    let f = Fields { file };
    let top = f.object(
        &case,
        "",
        &[
            "format",
            "scene",
            "camera",
            "params",
            "alpha_cutoff_shifts",
            "commands",
        ],
    )?;
    if top["format"].as_str() != Some(CASE_FORMAT) {
        return Err(f.error(
            "format",
            &top["format"],
            format!("expected {CASE_FORMAT:?}"),
        ));
    }
    // The scene is documentation for `verify` (it judges images), but it is checked all the same.
    let scene = f.object(&top["scene"], "scene", &["name", "origin", "trees"])?;
    if !scene["name"].is_string() {
        return Err(f.error("scene.name", &scene["name"], "expected a string"));
    }
    let world = forestlod_reference::scene::load::MAX_WORLD_COORDINATE;
    match scene["origin"].as_array() {
        Some(a)
            if a.len() == 3
                && a.iter()
                    .all(|x| x.as_f64().is_some_and(|x| x.abs() <= world)) => {}
        _ => {
            return Err(f.error(
                "scene.origin",
                &scene["origin"],
                format!("expected three finite coordinates within ±{world} m"),
            ));
        }
    }
    let max_trees = forestlod_reference::scene::load::MAX_INSTANCES as u64;
    f.integer(&scene["trees"], "scene.trees", 1..=max_trees)?;
    let c = f.object(
        &top["camera"],
        "camera",
        &[
            "eye",
            "forward",
            "up",
            "fov_y_degrees",
            "near",
            "far",
            "width",
            "height",
        ],
    )?;
    let side = 1..=u64::from(forestlod_reference::output::MAX_FRAME_SIDE);
    let camera = Camera {
        eye: f.triple(&c["eye"], "camera.eye")?,
        forward: f.triple(&c["forward"], "camera.forward")?,
        up: f.triple(&c["up"], "camera.up")?,
        fov_y: f
            .single(&c["fov_y_degrees"], "camera.fov_y_degrees")?
            .to_radians(),
        near: f.single(&c["near"], "camera.near")?,
        far: f.single(&c["far"], "camera.far")?,
        width: f.integer(&c["width"], "camera.width", side.clone())? as u32,
        height: f.integer(&c["height"], "camera.height", side)? as u32,
        tile: [0; 2],
    };
    camera.validate().map_err(|e| {
        let key = match e.field {
            "camera.fov_y" => "fov_y_degrees",
            "camera.viewport" => "width",
            other => other.trim_start_matches("camera."),
        };
        let value = c.get(key).cloned().unwrap_or_default();
        f.error(
            &format!("camera.{key}"),
            &value,
            format!("{} ({}): {}", e.field, e.value, e.reason),
        )
    })?;
    let params = case_params(&f, &top["params"])?;
    FramePlan::new(&params)
        .map_err(|e| f.error("params", &top["params"], format!("no frame plan: {e}")))?;
    let shifts = &top["alpha_cutoff_shifts"];
    let alternatives = match shifts.as_array() {
        Some(a) if a.len() <= MAX_ALTERNATIVES => {
            for x in a {
                f.single(x, "alpha_cutoff_shifts")?;
            }
            a.len()
        }
        _ => {
            return Err(f.error(
                "alpha_cutoff_shifts",
                shifts,
                format!("expected a list of at most {MAX_ALTERNATIVES} numbers"),
            ));
        }
    };
    let commands = f.integer(
        &top["commands"],
        "commands",
        0..=u64::from(forestlod_shared::MAX_COMMANDS),
    )?;
    Ok(CaseJson {
        camera,
        params,
        alternatives,
        commands,
    })
}

/// The case's pipeline parameters (`params`, every parameter under its flag's underscore name as
/// `export-case` writes them, [`params_json`]; one missing takes its default, one unknown or given
/// twice is an error), validated.
fn case_params(f: &Fields, v: &serde_json::Value) -> std::result::Result<Params, InputError> {
    let table = v
        .as_object()
        .ok_or_else(|| f.error("params", v, "expected an object"))?;
    let mut params = Params::default();
    let mut given: Vec<(&str, &str)> = Vec::new();
    for (key, v) in table {
        let field = format!("params.{key}");
        let spec = forestlod_shared::PARAMS
            .iter()
            .find(|s| s.answers_to(key))
            .ok_or_else(|| {
                f.error(
                    &field,
                    v,
                    format!(
                        "not a parameter of this version: expected one of {}",
                        forestlod_shared::PARAMS
                            .iter()
                            .map(|s| s.key())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })?;
        if let Some((first, _)) = given.iter().find(|(_, name)| *name == spec.name) {
            return Err(f.error(
                &field,
                v,
                format!(
                    "parameter {} given twice: as {first} and as {key}",
                    spec.name
                ),
            ));
        }
        given.push((key, spec.name));
        let parsed = match (spec.kind, v) {
            (ParamKind::Choice(_), serde_json::Value::String(name)) => spec.parse(name).ok(),
            (ParamKind::Uint { .. }, v) => v.as_u64().and_then(|x| spec.from_number(x as f64).ok()),
            (ParamKind::Float { .. }, v) => v
                .as_f64()
                .filter(|x| x.abs() <= f64::from(f32::MAX))
                .and_then(|x| spec.from_number(x).ok()),
            _ => None,
        };
        let value = parsed.ok_or_else(|| f.error(&field, v, spec.expected()))?;
        (spec.set)(&mut params, value);
    }
    params.validate().map_err(|e| {
        let key = given
            .iter()
            .find(|(_, name)| *name == e.field)
            .map_or(e.field, |(key, _)| key);
        let value = table.get(key).cloned().unwrap_or_default();
        f.error(
            &format!("params.{key}"),
            &value,
            format!("{}: {}", e.value, e.reason),
        )
    })?;
    Ok(params)
}

/// Checks that `path`, given as `flag`, is a folder (after resolving links), before anything in it
/// is read (issue 28): a missing path, a dangling link, a file or a special file (a FIFO, socket
/// or device) is one error naming the flag and the path; `what` says what the folder should hold.
pub fn input_folder(flag: &str, path: &Path, what: &str) -> std::result::Result<(), InputError> {
    let refuse = |why: String| {
        Err(InputError::new(
            forestlod_reference::error::COMMAND_LINE,
            flag,
            path.display(),
            format!("expected {what}: {why}"),
        ))
    };
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(m) if m.is_file() => refuse("it is a file, not a folder".into()),
        Ok(_) => refuse("it is a special file (a FIFO, socket or device), not a folder".into()),
        Err(e) if std::fs::symlink_metadata(path).is_ok() => {
            refuse(format!("it is a link that does not resolve ({e})"))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => refuse("no such folder".into()),
        Err(e) => refuse(format!("it cannot be read ({e})")),
    }
}

/// Whether `path` exists as a directory entry (a dangling link included, so that it is read and
/// refused rather than taken as absent).
fn entry_exists(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok()
}

/// `(missing, extra)`: the rows of sorted multiset `want` not in `got`, and of `got` not in
/// `want`, counted with multiplicity, in one merge (linear: a list of a million commands is not a
/// quadratic hang).
fn multiset_difference(want: &[CommandRow], got: &[CommandRow]) -> (usize, usize) {
    let (mut i, mut j, mut missing, mut extra) = (0, 0, 0, 0);
    while i < want.len() && j < got.len() {
        match want[i].cmp(&got[j]) {
            std::cmp::Ordering::Less => {
                missing += 1;
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                extra += 1;
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
        }
    }
    (missing + want.len() - i, extra + got.len() - j)
}

/// `forestlod verify`.
pub fn verify(args: &VerifyArgs) -> Result<u8> {
    input_folder("--case", &args.case, "a case folder written by export-case")?;
    input_folder(
        "--outputs",
        &args.outputs,
        "a folder of color.png, depth.exr, lod_id.png (and optionally commands.csv)",
    )?;
    let path = args.case.join("case.json");
    let text = forestlod_reference::files::read_text_limited(&path, MAX_CASE_JSON_BYTES)?;
    let case = parse_case_json(&text, &path.display().to_string())?;
    let camera = case.camera;
    let (width, height) = (camera.width, camera.height);
    // The stage whose output the commands are: the last selection stage of the case's plan.
    let plan = FramePlan::new(&case.params).map_err(|e| io(&path, format!("params: {e}")))?;
    let last_stage = plan
        .selection_stages()
        .last()
        .map_or("select", |s| s.name());
    let want = read_frame(&args.case.join("reference"), width, height, Frame::Oracle)?;
    let alternatives: Vec<Images> = (0..case.alternatives)
        .map(|k| {
            read_frame(
                &args.case.join(format!("alternatives/{k}")),
                width,
                height,
                Frame::Oracle,
            )
        })
        .collect::<Result<_>>()?;
    let got = read_frame(&args.outputs, width, height, Frame::Implementation)?;
    let mut failures = Vec::new();
    let commands = args.outputs.join("commands.csv");
    if entry_exists(&commands) {
        let reference = args.case.join("reference/commands.csv");
        let a = read_commands(&reference)?;
        if a.len() as u64 != case.commands {
            return Err(io_at(
                &reference,
                "rows",
                a.len(),
                format!(
                    "expected the {} commands case.json names: {NOT_THE_ORACLES}",
                    case.commands
                ),
            )
            .into());
        }
        let b = read_commands(&commands)?;
        let (missing, extra) = multiset_difference(&a, &b);
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
    // NaN or infinite depths fail whatever the comparison's edge rules forgive (issue 28).
    let non_finite = non_finite_depths(&got.depth);
    if non_finite > 0 {
        println!(
            "depth: {non_finite} NaN or infinite pixels in {}",
            args.outputs.join("depth.exr").display()
        );
        failures.push(format!(
            "depth: {non_finite} NaN or infinite pixels (expected depths in [0, 1])"
        ));
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const FILE: &str = "c/case.json";

    fn named(e: &InputError) -> bool {
        let s = e.to_string();
        s.starts_with("c/case.json: ") && !s.contains('\n')
    }

    /// A `case.json` as `export-case` writes it (its `json!`), for a default frame.
    fn valid_case() -> serde_json::Value {
        let camera = Camera::look_at([0.0, -50.0, 10.0], [0.0, 0.0, 5.0], 60.0, 64, 48);
        json!({
            "format": CASE_FORMAT,
            "scene": {"name": "tiny", "origin": [500000.0, 5300000.0, 200.0], "trees": 12},
            "camera": {
                "eye": camera.eye, "forward": camera.forward, "up": camera.up,
                "fov_y_degrees": camera.fov_y.to_degrees(), "near": camera.near, "far": camera.far,
                "width": camera.width, "height": camera.height,
            },
            "params": params_json(&Params::default()),
            "alpha_cutoff_shifts": [-0.01, 0.01, -0.03, 0.03],
            "commands": 17,
        })
    }

    #[test]
    fn an_exported_case_reads_back() {
        let case = parse_case_json(&valid_case().to_string(), FILE).unwrap();
        assert_eq!((case.camera.width, case.camera.height), (64, 48));
        assert_eq!(case.params, Params::default());
        assert_eq!((case.alternatives, case.commands), (4, 17));
    }

    #[test]
    fn lossy_unknown_missing_and_twice_are_refused_naming_field_and_value() {
        let with = |edit: &dyn Fn(&mut serde_json::Value)| {
            let mut v = valid_case();
            edit(&mut v);
            parse_case_json(&v.to_string(), FILE)
                .unwrap_err()
                .to_string()
        };
        for (e, want) in [
            (
                with(&|v| v["camera"]["width"] = json!(128.9)),
                "field camera.width: value \"128.9\": expected an integer",
            ),
            (
                with(&|v| v["camera"]["width"] = json!(-5)),
                "field camera.width: value \"-5\"",
            ),
            (
                with(&|v| v["camera"]["width"] = json!(0)),
                "field camera.width: value \"0\"",
            ),
            (
                with(&|v| v["camera"]["near"] = json!(1e300)),
                "field camera.near: value \"1e+300\"",
            ),
            (
                with(&|v| v["params"]["bogus"] = json!(1)),
                "field params.bogus",
            ),
            (
                with(&|v| v["params"]["angle_count"] = json!(8)),
                "given twice",
            ),
            (
                with(&|v| v["params"]["angles"] = json!(8.5)),
                "field params.angles: value \"8.5\"",
            ),
            (with(&|v| v["extra"] = json!(1)), "field extra"),
            (
                with(&|v| {
                    v["camera"].as_object_mut().unwrap().remove("far");
                }),
                "field camera.far: value \"\": missing",
            ),
            (
                with(&|v| v["commands"] = json!(1.5)),
                "field commands: value \"1.5\"",
            ),
            (
                with(&|v| v["alpha_cutoff_shifts"] = json!([0.1, "x"])),
                "field alpha_cutoff_shifts: value \"\\\"x\\\"\"",
            ),
        ] {
            assert!(
                e.starts_with("c/case.json: ") && e.contains(want),
                "{want}: {e}"
            );
        }
        let twice = valid_case().to_string().replacen(
            "\"commands\":17",
            "\"commands\":17,\"commands\":18",
            1,
        );
        let e = parse_case_json(&twice, FILE).unwrap_err().to_string();
        assert!(
            e.contains("given twice") && e.contains("line 1, column"),
            "{e}"
        );
    }

    #[test]
    fn commands_are_typed_per_column_and_compared_as_a_multiset() {
        let h = COMMANDS_HEADER;
        let rows = parse_commands_csv(
            &format!("{h}\n1,2,3,260,5,6,7,0,1\n1,2,3,4,5,6,7,0,1\n"),
            "x.csv",
        )
        .unwrap();
        assert_eq!(rows[0], rows[1], "base_vertex without its command index");
        let e =
            parse_commands_csv(&format!("{h}\n1,2,3,4,5,6,7,0,4294967296\n"), "x.csv").unwrap_err();
        assert!(
            e.to_string()
                .contains("line 2, column fading: value \"4294967296\""),
            "{e}"
        );
        let e = parse_commands_csv("1,2,3,4,5,6,7,0,1\n", "x.csv").unwrap_err();
        assert!(e.to_string().contains("line 1"), "{e}");
        let r = |x: i64| [x; 9];
        assert_eq!(
            multiset_difference(&[r(1), r(1), r(2)], &[r(1), r(3)]),
            (2, 1)
        );
    }

    /// JSON-ish tokens, so that soups reach the field checks.
    fn token() -> impl Strategy<Value = &'static str> {
        prop::sample::select(vec![
            "{",
            "}",
            "[",
            "]",
            ",",
            ":",
            "\"format\"",
            "\"forestlod-case/1\"",
            "\"camera\"",
            "\"params\"",
            "\"scene\"",
            "\"width\"",
            "\"height\"",
            "\"eye\"",
            "\"near\"",
            "\"grid_size\"",
            "\"angles\"",
            "\"alpha_cutoff_shifts\"",
            "\"commands\"",
            "0",
            "1",
            "-1",
            "1.5",
            "1e39",
            "64",
            "null",
            "true",
            "\"x\"",
        ])
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn arbitrary_text_is_parsed_or_refused_naming_the_file(text in ".{0,400}") {
            if let Err(e) = parse_case_json(&text, FILE) {
                prop_assert!(named(&e), "{e}");
            }
        }

        #[test]
        fn token_soups_are_refused_naming_the_file(tokens in prop::collection::vec(token(), 0..80)) {
            if let Err(e) = parse_case_json(&tokens.concat(), FILE) {
                prop_assert!(named(&e), "{e}");
            }
        }

        #[test]
        fn a_case_with_one_value_replaced_is_valid_or_names_it(
            field in prop::sample::select(vec![
                "/camera/width", "/camera/height", "/camera/near", "/camera/far",
                "/camera/fov_y_degrees", "/camera/eye/0", "/params/grid_size", "/params/angles",
                "/params/lod_levels", "/params/hierarchy", "/scene/trees", "/commands",
            ]),
            value in prop::sample::select(vec![
                json!(0), json!(-1), json!(1.5), json!(64), json!(64.0), json!(1e39),
                json!(4294967296u64), json!("grid"), json!([1, 2]), json!(null),
            ])
        ) {
            let mut v = valid_case();
            *v.pointer_mut(field).unwrap() = value.clone();
            match parse_case_json(&v.to_string(), FILE) {
                Ok(case) => {
                    prop_assert!(case.camera.validate().is_ok());
                    prop_assert!(case.params.validate().is_ok());
                    // Integers stay integers: nothing was cast.
                    if field == "/camera/width" {
                        prop_assert_eq!(Some(u64::from(case.camera.width)), value.as_u64());
                    }
                }
                Err(e) => {
                    // The field, or (for a value valid alone) the camera or parameter it breaks.
                    let top = field[1..].split('/').next().unwrap();
                    prop_assert!(named(&e), "{e}");
                    prop_assert!(e.to_string().contains(&format!("field {top}")), "{field}: {e}");
                }
            }
        }
    }
}
