//! `forestlod check` (issue 15, part 7): random selection parity cases on the current adapter, for
//! `--cases N` or `--seconds T`, with progress; a failing case is shrunk (fewer trees while it
//! still fails) and written as a scene (`trees.csv`, the bare instance table the CLI's
//! `--instances` reads, built-in species) plus `case.toml` (camera and parameters), with the one
//! command that reproduces it: `forestlod check --replay DIR`.
//!
//! **A case** (deterministic from `--seed` and its index, [`Rng`]): 1..300 trees of the built-in
//! species 0..3 in a square of half-side 10..3000 m, a camera anywhere over 4 km (up to 1.5 km
//! high, pitch -89°..30°, fov 20°..100°, 64..256 px a side), half the time aimed at a random tree
//! from 5..2500 m, one case in eight with the far plane 50..3000 m past the near plane and a
//! 100 km draw distance (the far plane then culls); parameters as `parity::select`'s (grid
//! 1 m..5 km, transition 0..2 km, fade 0..500 m, draw distance 0..6 km, one or two LODs), and the
//! frame's plan (issue 27, [`FramePlan`]): half the cases cut a hierarchy (any mode but the grid,
//! 2..64 children or trees per node, max cull depth 0..8) with a random coalesce mode and command
//! order; the other half select flat over the grid. These draws come last in a case's stream, so
//! the flat part of case `i` is the case `i` of before. `tree_cull` stays `none`: `refine` is
//! judged by `parity::refine`, and a replayed case asking for it is refused. The trees go through
//! the same CSV loader as a replay (`parse_instances_with_builtin_species`, from the text
//! `trees.csv` holds, in memory: no scratch file), so a written case is the case that failed, bit
//! for bit.
//!
//! **The comparison**: the reference frame's selection (`Prepared::select`: every selection stage
//! of the plan before `refine`) against the GPU's (`harness::gpu_frame::SelectionChain`, which runs
//! `select.wgsl` with the stable compaction, or the cut `hier_select.wgsl` then `coalesce.wgsl`
//! and `command_order.wgsl`, as the prepared scene was grouped), commands and per-command data
//! **exactly**, and the per-batch decisions (flat) or the per-node codes and states of the cut
//! (the raw cut's, `Prepared::hier_select`) exactly too (the rule of
//! `harness::diagnose::check_select`). `parity::select` forgives batches within 1e-5 (relative)
//! of a threshold; random cases land there about never (0 of 256 in that test), so an exact
//! comparison here reports such a case as a failure to triage rather than hiding it. The scene is
//! prepared for selection only ([`selection_scene`]: no textures, which no selection stage reads).
//!
//! **Output**: the cases run and their rate, then how many cases each hierarchy mode had
//! (`plans: grid N, ...`, named from what was prepared); a replay names the plan's selection
//! stages beside its verdict.
//!
//! **`case.toml`**: `[camera]` (`eye` in the coordinates of `trees.csv`, the rest as the
//! [`Camera`] fields) and `[params]`, every pipeline parameter under its [`Params`] field name
//! (choices by name). A parameter a case does not give takes its default, so the folders written
//! before the plan was drawn (five numeric parameters) replay as the flat cases they were.
//!
//! **Replays** (issue 28): `--replay DIR` must be a folder (a missing path, a file, a FIFO or a
//! dangling link is one error naming `--replay`); `DIR/case.toml` (at most
//! [`MAX_REPLAY_TOML_BYTES`], parsed by the pure [`parse_replay_toml`]: no lossy casts, unknown,
//! missing or twice-given keys refused, every value checked where it is read) and `DIR/trees.csv`
//! (at most [`MAX_REPLAY_TREES_BYTES`]) are regular files read through
//! `forestlod_reference::files`, before a GPU adapter is looked for. Every error names
//! `DIR/case.toml` or `DIR/trees.csv` with its line; nothing is written (to `$TMPDIR` or
//! elsewhere).
//!
//! Test hook: `FORESTLOD_CHECK_BREAK=drop-last-command` drops the GPU's last command before
//! comparing (a deliberately broken comparison: every case that draws something fails), so the
//! CLI test can see a case being shrunk and written.
//!
//! Exit codes: 0 every case passed, 2 a case failed (written), 1 bad input, 4 no GPU adapter.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use forestlod_gpu::{Compaction, GpuContext};
use forestlod_harness::backend::decode_decision;
use forestlod_harness::gpu_frame::SelectionChain;
use forestlod_reference::error::{InputError, line_col};
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::scene::Scene;
use forestlod_reference::scene::load::parse_instances_with_builtin_species;
use forestlod_reference::select::{Decision, batch_decisions};
use forestlod_shared::{
    Camera, Coalesce, CommandOrder, FramePlan, Hierarchy, PARAMS, ParamKind, Params, StageId,
    TreeCull,
};

use crate::render::exit_code;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// `forestlod check`.
#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// How many random cases (default 1000, or unbounded with --seconds).
    #[arg(long)]
    pub cases: Option<u64>,
    /// Stop after this many seconds (whichever of --cases and --seconds comes first).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// The seed of the case sequence (case i of seed s is always the same case).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where a failing case is written (DIR/case-<seed>-<index>/).
    #[arg(long, default_value = "out/check")]
    pub out: PathBuf,
    /// Re-run the case written in this folder (its trees.csv and case.toml) instead.
    #[arg(long)]
    pub replay: Option<PathBuf>,
}

/// SplitMix64: a small deterministic generator (no dependency), one stream per case.
pub struct Rng(u64);

impl Rng {
    /// The stream of case `index` of `seed`.
    pub fn new(seed: u64, index: u64) -> Self {
        let mut r = Rng(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        r.next();
        r
    }
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `lo..hi`.
    fn f(&mut self, lo: f32, hi: f32) -> f32 {
        let u = (self.next() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * u
    }
    /// Uniform in `lo..hi` (integers).
    fn u(&mut self, lo: u32, hi: u32) -> u32 {
        lo + (self.next() % u64::from(hi - lo)) as u32
    }
}

/// One tree row of `trees.csv`: x, y, z, yaw, scale, species.
type Row = [f32; 5];

/// A random case: its tree rows (species apart), the camera relative to the rows' coordinates
/// (not yet to the loaded scene's origin) and the parameters.
#[derive(Clone, Debug)]
pub struct Case {
    rows: Vec<(Row, u32)>,
    /// Eye in the rows' (world) coordinates.
    eye: [f64; 3],
    camera: Camera,
    params: Params,
}

/// Case `index` of `seed` (module docs).
pub fn random_case(seed: u64, index: u64) -> Case {
    let mut r = Rng::new(seed, index);
    let n = r.u(1, 301);
    let extent = r.f(10.0, 3000.0);
    let rows: Vec<(Row, u32)> = (0..n)
        .map(|_| {
            (
                [
                    r.f(-extent, extent),
                    r.f(-extent, extent),
                    r.f(-20.0, 60.0),
                    r.f(0.0, 6.3),
                    r.f(0.3, 2.5),
                ],
                r.u(0, 3),
            )
        })
        .collect();
    let (width, height) = (r.u(64, 256), r.u(64, 256));
    let fov = r.f(20.0, 100.0);
    let (eye, forward) = if r.u(0, 2) == 0 {
        let (yaw, pitch) = (r.f(0.0, 360.0).to_radians(), r.f(-89.0, 30.0).to_radians());
        (
            [
                r.f(-4000.0, 4000.0),
                r.f(-4000.0, 4000.0),
                r.f(-10.0, 1500.0),
            ],
            [
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            ],
        )
    } else {
        // Aimed at a tree from 5..2500 m, azimuth any, elevation -10°..60°.
        let t = rows[r.u(0, n) as usize].0;
        let (d, az, el) = (
            r.f(5.0, 2500.0),
            r.f(0.0, 360.0).to_radians(),
            r.f(-10.0, 60.0).to_radians(),
        );
        let dir = [az.cos() * el.cos(), az.sin() * el.cos(), el.sin()];
        (
            [
                t[0] + d * dir[0],
                t[1] + d * dir[1],
                t[2] + 5.0 + d * dir[2],
            ],
            [-dir[0], -dir[1], -dir[2]],
        )
    };
    let mut camera = Camera::look_at(
        [0.0; 3],
        [forward[0], forward[1], forward[2]],
        fov,
        width,
        height,
    );
    camera.forward = forward;
    let mut params = Params {
        grid_size: r.f(1.0, 5000.0),
        lod1_transition: r.f(0.0, 2000.0),
        fade_width: r.f(0.0, 500.0),
        draw_distance: r.f(0.0, 6000.0),
        lod_levels: r.u(1, 3),
        ..Params::default()
    };
    if r.u(0, 8) == 0 {
        camera.far = camera.near + r.f(50.0, 3000.0);
        params.draw_distance = 100_000.0;
    }
    // The frame's plan, drawn last (module docs).
    if r.u(0, 2) == 1 {
        let cuts: Vec<Hierarchy> = Hierarchy::ALL
            .into_iter()
            .filter(|h| h.is_hierarchical())
            .collect();
        params.hierarchy = cuts[r.u(0, cuts.len() as u32) as usize] as u32;
        params.nodes_per_node = r.u(2, 65);
        params.max_cull_depth = r.u(0, 9);
        params.coalesce = r.u(0, Coalesce::ALL.len() as u32);
        params.command_order = r.u(0, CommandOrder::ALL.len() as u32);
    }
    Case {
        rows,
        eye: eye.map(f64::from),
        camera,
        params,
    }
}

impl Case {
    /// `trees.csv`: a header and one row per tree (shortest round-trip decimals).
    fn csv(&self) -> String {
        let mut s = String::from("x,y,z,yaw,scale,species\n");
        for (r, species) in &self.rows {
            s.push_str(&format!(
                "{},{},{},{},{},{species}\n",
                r[0], r[1], r[2], r[3], r[4]
            ));
        }
        s
    }

    /// `case.toml` of the case written into `dir` (what [`parse_replay_toml`] reads back).
    pub fn toml(&self, dir: &Path) -> String {
        let c = &self.camera;
        let mut toml = format!(
            "# forestlod check case: replay with `forestlod check --replay {dir}`\n\
             # The eye is in the coordinates of trees.csv; the rest as the Camera and Params fields.\n\
             [camera]\neye = [{}, {}, {}]\nforward = [{}, {}, {}]\nup = [{}, {}, {}]\n\
             fov_y = {}\nnear = {}\nfar = {}\nwidth = {}\nheight = {}\n\n[params]\n",
            self.eye[0],
            self.eye[1],
            self.eye[2],
            c.forward[0],
            c.forward[1],
            c.forward[2],
            c.up[0],
            c.up[1],
            c.up[2],
            c.fov_y,
            c.near,
            c.far,
            c.width,
            c.height,
            // One comment line whatever the folder's name holds.
            dir = dir.display().to_string().replace(['\n', '\r'], " "),
        );
        // Every parameter (shortest round-trip decimals; choices by name).
        for spec in PARAMS {
            let v = spec.format(&self.params);
            toml += &match spec.kind {
                ParamKind::Choice(_) => format!("{} = \"{v}\"\n", spec.name),
                _ => format!("{} = {v}\n", spec.name),
            };
        }
        toml
    }

    /// Writes `trees.csv` and `case.toml` into `dir`.
    fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        let csv = dir.join("trees.csv");
        std::fs::write(&csv, self.csv()).map_err(|e| io(&csv, e))?;
        let toml = self.toml(dir);
        let path = dir.join("case.toml");
        std::fs::write(&path, toml).map_err(|e| io(&path, e))?;
        Ok(())
    }
}

/// Largest `case.toml` a replay may have (issue 28): `check` writes about 1 KB (a camera and
/// every pipeline parameter); 64 KiB leaves room for comments a person adds, and no more.
pub const MAX_REPLAY_TOML_BYTES: u64 = 64 << 10;

/// Largest `trees.csv` a replay may have (issue 28): `check` writes at most 300 trees (about
/// 20 KB); a hand-made replay may carry an exported case's `instances.csv`. 16 MiB is about
/// 250 000 trees, more than a selection case to triage needs.
pub const MAX_REPLAY_TREES_BYTES: u64 = 16 << 20;

/// A replay's `case.toml` as [`parse_replay_toml`] validated it.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplayToml {
    /// The eye in the coordinates of `trees.csv` (finite, within the world coordinate limit).
    pub eye: [f64; 3],
    /// The camera with its eye at zero (the eye is placed once the trees' origin is known); it
    /// passes [`Camera::validate`] there.
    pub camera: Camera,
    /// Every parameter the file gives, the others their defaults; valid, with a plan
    /// ([`FramePlan::new`]) that does not run `refine` (module docs).
    pub params: Params,
}

/// `[camera]` of a replay's `case.toml`: every field required, no other.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ReplayCamera {
    // Lists, their length checked here (a fixed-size array would take the first three of four).
    eye: toml::Spanned<Vec<f64>>,
    forward: toml::Spanned<Vec<f64>>,
    up: toml::Spanned<Vec<f64>>,
    fov_y: toml::Spanned<f64>,
    near: toml::Spanned<f64>,
    far: toml::Spanned<f64>,
    width: toml::Spanned<u32>,
    height: toml::Spanned<u32>,
}

/// A replay's `case.toml`: `[camera]` and `[params]`, no other table.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ReplayFile {
    camera: toml::Spanned<ReplayCamera>,
    params: toml::Spanned<toml::Table>,
}

/// Parses and validates a replay's `case.toml` (module docs; what [`Case::write`] writes), `file`
/// naming it in errors. Pure: no file is read (issue 28). Every refusal is one [`InputError`]
/// naming `file`, the line, column and field, and the value: TOML that does not parse, a missing
/// or unknown table or field, a duplicate key (TOML's rule) or a parameter given twice under two
/// of its names, a non-integer or out-of-range `width`/`height` (`128.9` and `-5` are errors,
/// never 128 and 0), a camera number that is not finite or beyond `f32`, an eye beyond
/// [`MAX_WORLD_COORDINATE`], an invalid camera or parameter (named as [`Camera::validate`] and
/// [`Params::validate`] name it), a parameter that is not one, an integer parameter given as a
/// float, and `tree_cull` other than `none`.
///
/// [`MAX_WORLD_COORDINATE`]: forestlod_reference::scene::load::MAX_WORLD_COORDINATE
pub fn parse_replay_toml(text: &str, file: &str) -> std::result::Result<ReplayToml, InputError> {
    let at = |span: std::ops::Range<usize>, field: &str| {
        let (line, col) = line_col(text, span.start);
        format!("line {line}, column {col}, field {field}")
    };
    let parsed: ReplayFile = toml::from_str(text).map_err(|e| {
        let (position, value) = forestlod_reference::error::span_position(text, e.span());
        InputError::new(
            file,
            position,
            value,
            format!(
                "invalid replay case (expected [camera] and [params] as check writes them): {}",
                e.message().replace('\n', " ")
            ),
        )
    })?;
    let c = parsed.camera.get_ref();
    let bad = |span: std::ops::Range<usize>, field: &str, reason: String| {
        let (_, value) = forestlod_reference::error::span_position(text, Some(span.clone()));
        InputError::new(file, at(span, field), value, reason)
    };
    for (v, field) in [
        (&c.eye, "camera.eye"),
        (&c.forward, "camera.forward"),
        (&c.up, "camera.up"),
    ] {
        if v.get_ref().len() != 3 {
            return Err(bad(v.span(), field, "expected three numbers".into()));
        }
    }
    let world = forestlod_reference::scene::load::MAX_WORLD_COORDINATE;
    if c.eye
        .get_ref()
        .iter()
        .any(|x| !x.is_finite() || x.abs() > world)
    {
        return Err(bad(
            c.eye.span(),
            "camera.eye",
            format!("expected finite coordinates within ±{world} m"),
        ));
    }
    let single = |v: &toml::Spanned<f64>, field: &str| {
        let x = *v.get_ref();
        if x.is_finite() && x.abs() <= f64::from(f32::MAX) {
            Ok(x as f32)
        } else {
            Err(bad(
                v.span(),
                field,
                "expected a finite number within the range of f32".into(),
            ))
        }
    };
    let triple = |v: &toml::Spanned<Vec<f64>>, field: &str| {
        let a = v.get_ref();
        let mut out = [0.0f32; 3];
        for (o, &x) in out.iter_mut().zip(a) {
            *o = single(&toml::Spanned::new(v.span(), x), field)?;
        }
        Ok::<_, InputError>(out)
    };
    let camera = Camera {
        eye: [0.0; 3],
        forward: triple(&c.forward, "camera.forward")?,
        up: triple(&c.up, "camera.up")?,
        fov_y: single(&c.fov_y, "camera.fov_y")?,
        near: single(&c.near, "camera.near")?,
        far: single(&c.far, "camera.far")?,
        width: *c.width.get_ref(),
        height: *c.height.get_ref(),
        tile: [0; 2],
    };
    camera.validate().map_err(|e| {
        let span = match e.field {
            "camera.forward" => c.forward.span(),
            "camera.up" => c.up.span(),
            "camera.fov_y" => c.fov_y.span(),
            "camera.near" => c.near.span(),
            "camera.far" => c.far.span(),
            "camera.viewport" if !(1..=16384).contains(c.width.get_ref()) => c.width.span(),
            "camera.viewport" => c.height.span(),
            _ => parsed.camera.span(),
        };
        bad(span, e.field, format!("{}: {}", e.value, e.reason))
    })?;
    // Every parameter the case gives, by the parameter table; the others their defaults.
    let table = parsed.params.get_ref();
    let mut params = Params::default();
    let mut given: Vec<(&str, &str)> = Vec::new();
    // `toml::Table` holds no spans: each key's span is the line after `[params]` that sets it
    // (a bare key, as check writes them; else the table's).
    let params_at = parsed.params.span().start.min(text.len());
    let key_span = |key: &str| {
        let mut at = params_at;
        for line in text[params_at..].split_inclusive('\n') {
            let indent = line.len() - line.trim_start().len();
            let rest = line.trim_start();
            if rest
                .strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with('='))
            {
                // The key and its value: what an error shows.
                return at + indent..at + line.trim_end().len();
            }
            at += line.len();
        }
        parsed.params.span()
    };
    for (key, value) in table {
        let field = format!("params.{key}");
        let spec = PARAMS.iter().find(|s| s.answers_to(key)).ok_or_else(|| {
            bad(
                key_span(key),
                &field,
                format!(
                    "not a parameter: expected one of {}",
                    PARAMS.iter().map(|s| s.name).collect::<Vec<_>>().join(", ")
                ),
            )
        })?;
        if let Some((first, _)) = given.iter().find(|(_, name)| *name == spec.name) {
            return Err(bad(
                key_span(key),
                &field,
                format!(
                    "parameter {} given twice: as {first} and as {key}",
                    spec.name
                ),
            ));
        }
        given.push((key, spec.name));
        let parsed = match (spec.kind, value) {
            (ParamKind::Choice(_), toml::Value::String(text)) => spec.parse(text).ok(),
            (ParamKind::Uint { .. }, toml::Value::Integer(i)) => spec.from_number(*i as f64).ok(),
            (ParamKind::Float { .. }, toml::Value::Integer(i)) => spec.from_number(*i as f64).ok(),
            (ParamKind::Float { .. }, toml::Value::Float(x)) if x.abs() <= f64::from(f32::MAX) => {
                spec.from_number(*x).ok()
            }
            _ => None,
        };
        let parsed = parsed.ok_or_else(|| {
            InputError::new(
                file,
                at(key_span(key), &field),
                value.to_string(),
                spec.expected(),
            )
        })?;
        (spec.set)(&mut params, parsed);
    }
    params.validate().map_err(|e| {
        let key = given
            .iter()
            .find(|(_, name)| *name == e.field)
            .map_or(e.field, |(key, _)| key);
        bad(
            key_span(key),
            &format!("params.{key}"),
            format!("{}: {}", e.value, e.reason),
        )
    })?;
    let plan = FramePlan::new(&params).map_err(|e| {
        bad(
            parsed.params.span(),
            "params",
            format!("no frame plan: {e}"),
        )
    })?;
    if let Some(mode) = plan.refine {
        return Err(bad(
            key_span("tree_cull"),
            "params.tree_cull",
            format!(
                "{} runs refine: check compares the selection stages before refine \
                 (parity::refine judges refine); expected {:?}",
                mode.name(),
                TreeCull::None.name()
            ),
        ));
    }
    let eye = c.eye.get_ref();
    Ok(ReplayToml {
        eye: [eye[0], eye[1], eye[2]],
        camera,
        params,
    })
}

/// A replay folder (`check --replay DIR`) as read: its case and its trees as the CSV loader
/// builds them, every error naming `DIR/case.toml` or `DIR/trees.csv` (issue 28: never a scratch
/// copy; nothing is written).
pub struct Replay {
    /// The scene of `trees.csv` (built-in species).
    pub scene: Scene,
    /// The camera, its eye in the scene's coordinates (valid).
    pub camera: Camera,
    /// The parameters.
    pub params: Params,
}

/// Reads a replay folder (module docs): `DIR` must be a folder (`--replay` names it otherwise),
/// `case.toml` ([`parse_replay_toml`], at most [`MAX_REPLAY_TOML_BYTES`]) and `trees.csv` (the CSV
/// loader of `--instances`, at most [`MAX_REPLAY_TREES_BYTES`]) regular files.
pub fn read_replay(dir: &Path) -> Result<Replay> {
    crate::case::input_folder(
        "--replay",
        dir,
        "a replay folder holding case.toml and trees.csv",
    )?;
    let path = dir.join("case.toml");
    let file = path.display().to_string();
    let text = forestlod_reference::files::read_text_limited(&path, MAX_REPLAY_TOML_BYTES)?;
    let case = parse_replay_toml(&text, &file)?;
    let csv = dir.join("trees.csv");
    let bytes = forestlod_reference::files::read_limited(&csv, MAX_REPLAY_TREES_BYTES)?;
    let scene = parse_instances_with_builtin_species(
        bytes.as_slice(),
        &csv.display().to_string(),
        "trees".into(),
    )?;
    let camera = placed(&scene, case.eye, case.camera).map_err(|e| {
        InputError::new(
            &file,
            "field camera.eye",
            format!("{:?}", case.eye),
            format!(
                "relative to the origin {:?} of {}: {}: {}",
                scene.origin,
                csv.display(),
                e.value,
                e.reason
            ),
        )
    })?;
    Ok(Replay {
        scene,
        camera,
        params: case.params,
    })
}

fn io(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::new(path.display().to_string(), "", "", e.to_string())
}

/// What names a random case's trees in its errors (its trees are never written to a file while
/// it runs: module docs).
const RANDOM_TREES: &str = "<random case>/trees.csv";

/// The case's scene through the CSV loader (as a replay reads it, from the text [`Case::write`]
/// writes, in memory) and its camera in that scene's coordinates.
fn materialize(case: &Case) -> std::result::Result<(Scene, Camera), InputError> {
    let scene =
        parse_instances_with_builtin_species(case.csv().as_bytes(), RANDOM_TREES, "trees".into())?;
    let camera = placed(&scene, case.eye, case.camera)
        .map_err(|e| InputError::new(RANDOM_TREES, "camera", e.value, e.reason))?;
    Ok((scene, camera))
}

/// `camera` with its eye at `eye` (world coordinates) in `scene`'s coordinates, validated.
fn placed(
    scene: &Scene,
    eye: [f64; 3],
    camera: Camera,
) -> std::result::Result<Camera, forestlod_shared::ParamError> {
    let o = scene.origin;
    let camera = Camera {
        eye: [0, 1, 2].map(|k| (eye[k] - o[k]) as f32),
        ..camera
    };
    camera.validate()?;
    Ok(camera)
}

/// The case's scene prepared for selection only (module docs): grouped as the frame's plan says
/// (`group_trees`, the grid's batches or the hierarchy with its leaves) with its memory and tree
/// spheres, as `prepare` builds them; no mesh textures and a 1x1 placeholder billboard texture,
/// which no selection stage reads (the bake is most of `prepare`'s time, and a case is run
/// hundreds of times while it shrinks).
pub fn selection_scene(scene: Scene, params: &Params) -> Result<Prepared> {
    use forestlod_reference::bake::BakedBillboards;
    use forestlod_reference::pipeline::{group_trees, scene_memory};
    use forestlod_reference::sampler::Texture;
    use forestlod_reference::texture::Rgba8Image;
    let geometry = forestlod_reference::geometry::pack_geometry(&scene);
    let (hierarchy, batches) = group_trees(&scene, &geometry.meshes, params)?;
    let memory = scene_memory(&scene, &batches, hierarchy.as_ref(), params);
    let tree_spheres = scene
        .instances
        .iter()
        .map(|t| forestlod_reference::scene::tree_sphere(t, &geometry.meshes[t.mesh as usize]))
        .collect();
    let placeholder = Rgba8Image {
        width: 1,
        height: 1,
        texels: vec![[0; 4]],
    };
    let billboards = BakedBillboards {
        angle_count: params.angle_count,
        azimuth_count: params.azimuth_count,
        sphere: params.billboard_views,
        grid: params.octahedral_grid,
        texture_size: 1,
        layers: Vec::new(),
        chains: Vec::new(),
        texture: Texture::new(vec![placeholder]).map_err(|e| e.to_string())?,
        extents: Vec::new(),
        depth: None,
    };
    Ok(Prepared {
        tree_scales: scene.instances.iter().map(|t| t.scale).collect(),
        footprints: forestlod_reference::pipeline::tree_footprints(
            &scene,
            &geometry.meshes,
            params,
        ),
        scene,
        geometry,
        batches,
        hierarchy,
        far: None,
        points: None,
        mesh_textures: Vec::new(),
        billboards,
        memory,
        tree_spheres,
        timings: Default::default(),
    })
}

/// What one case ran and found.
struct Outcome {
    /// The hierarchy the scene was prepared with (the grid for a flat selection).
    hierarchy: Hierarchy,
    /// The selection stages of the case's plan.
    stages: Vec<StageId>,
    /// `None` when the GPU's selection equals the reference's, else why not.
    failure: Option<String>,
}

/// Runs one random case (module docs). `Err` for a case no stage can run (an invalid camera or
/// parameters).
fn run_case(ctx: &'static GpuContext, case: &Case) -> Result<Outcome> {
    let (scene, camera) = materialize(case)?;
    run_selection(ctx, scene, &camera, &case.params)
}

/// Runs the selection parity of `scene` seen by `camera` (valid, in the scene's coordinates).
fn run_selection(
    ctx: &'static GpuContext,
    scene: Scene,
    camera: &Camera,
    params: &Params,
) -> Result<Outcome> {
    let camera = *camera;
    params.validate().map_err(InputError::from)?;
    let plan = FramePlan::new(params).map_err(|e| io(Path::new("<params>"), e))?;
    let prepared = selection_scene(scene, params)?;
    let hierarchy = prepared
        .hierarchy
        .as_ref()
        .map_or(Hierarchy::Grid, |h| h.mode);
    let outcome = |failure| Outcome {
        hierarchy,
        stages: plan.selection_stages(),
        failure,
    };
    // The reference frame's selection, and the per-item decisions of its first stage.
    let want = prepared.select(&camera, params);
    let (items, want_decisions) = match prepared.hier_select(&camera, params) {
        Some(cut) => {
            let n = cut.codes.len();
            (
                format!("{n} nodes of the {} hierarchy", hierarchy.name()),
                DecisionList::Nodes(cut.codes, cut.states),
            )
        }
        None => (
            format!("{} batches", prepared.batches.metas.len()),
            DecisionList::Batches(batch_decisions(&prepared.batches.metas, &camera, params)),
        ),
    };
    // The GPU selection chain itself (not the harness backend, which panics on a GPU error): an error is a
    // failing case with its message.
    let gpu = (|| {
        let mut gpu = SelectionChain::gpu(ctx, &prepared)?;
        let out = gpu
            .dispatch(&camera, params, Compaction::Stable)?
            .read(ctx)?;
        let decisions = match gpu.flat() {
            Some(s) => DecisionList::Batches(
                s.read_decisions()?
                    .into_iter()
                    .map(decode_decision)
                    .collect(),
            ),
            None => {
                let (codes, states) = gpu.read_codes_and_states()?;
                DecisionList::Nodes(codes, states)
            }
        };
        Ok::<_, Box<dyn std::error::Error>>((out, decisions))
    })();
    let (mut got, got_decisions) = match gpu {
        Ok(g) => g,
        Err(e) => return Ok(outcome(Some(format!("GPU error: {e}")))),
    };
    if std::env::var("FORESTLOD_CHECK_BREAK").as_deref() == Ok("drop-last-command") {
        got.commands.pop();
        got.data.pop();
    }
    let decisions = want_decisions.differing(&got_decisions);
    let (w, g) = (&want, &got);
    let n = w.commands.len().max(g.commands.len());
    let commands = (0..n)
        .filter(|&i| w.commands.get(i) != g.commands.get(i) || w.data.get(i) != g.data.get(i))
        .count();
    Ok(outcome((decisions > 0 || commands > 0).then(|| {
        format!(
            "{items}: {decisions} {} differ; {} reference commands, {} GPU commands, \
             {commands} differing",
            want_decisions.what(),
            w.commands.len(),
            g.commands.len()
        )
    })))
}

/// The per-item decisions of a selection's first stage.
#[derive(PartialEq)]
enum DecisionList {
    /// `select`'s per-batch decisions.
    Batches(Vec<Decision>),
    /// The cut's per-node codes and states.
    Nodes(Vec<u32>, Vec<u32>),
}

impl DecisionList {
    /// What the items' decisions are called in a failure.
    fn what(&self) -> &'static str {
        match self {
            DecisionList::Batches(_) => "decisions",
            DecisionList::Nodes(..) => "node codes or states",
        }
    }

    /// How many items differ (a length difference counting each missing item; lists of
    /// different kinds differ everywhere).
    fn differing(&self, other: &DecisionList) -> usize {
        fn count<T: PartialEq>(a: &[T], b: &[T]) -> usize {
            a.len().abs_diff(b.len()) + a.iter().zip(b).filter(|(x, y)| x != y).count()
        }
        match (self, other) {
            (DecisionList::Batches(a), DecisionList::Batches(b)) => count(a, b),
            (DecisionList::Nodes(ca, sa), DecisionList::Nodes(cb, sb)) => {
                let pairs = |c: &[u32], s: &[u32]| -> Vec<(u32, u32)> {
                    c.iter().copied().zip(s.iter().copied()).collect()
                };
                count(&pairs(ca, sa), &pairs(cb, sb))
            }
            (DecisionList::Batches(a), DecisionList::Nodes(b, _))
            | (DecisionList::Nodes(b, _), DecisionList::Batches(a)) => a.len().max(b.len()).max(1),
        }
    }
}

/// Fewer trees while the case still fails: drops chunks of half, a quarter, ... one tree
/// (at most `budget` tries). Returns the smallest failing case and its failure.
fn shrink(
    ctx: &'static GpuContext,
    mut case: Case,
    mut why: String,
    budget: u32,
) -> (Case, String) {
    let mut tries = 0;
    let mut chunk = case.rows.len().div_ceil(2);
    while chunk >= 1 && case.rows.len() > 1 && tries < budget {
        let mut start = 0;
        let mut progressed = false;
        while start < case.rows.len() && case.rows.len() > 1 && tries < budget {
            let mut candidate = case.clone();
            let end = (start + chunk).min(candidate.rows.len());
            candidate.rows.drain(start..end);
            tries += 1;
            if candidate.rows.is_empty() {
                start = end;
                continue;
            }
            match run_case(ctx, &candidate).map(|o| o.failure) {
                Ok(Some(w)) => {
                    case = candidate;
                    why = w;
                    progressed = true;
                }
                _ => start = end,
            }
        }
        if !progressed {
            chunk /= 2;
        }
    }
    (case, why)
}

/// `forestlod check` (module docs): the exit code.
pub fn run(args: &CheckArgs) -> Result<u8> {
    if args.seconds.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        return Err(format!(
            "--seconds {}: expected a finite number of seconds > 0",
            args.seconds.unwrap()
        )
        .into());
    }
    if args.cases == Some(0) {
        return Err("--cases 0: expected at least one case".into());
    }
    // A replay is read (and refused, naming its files) before an adapter is looked for.
    let replay = match &args.replay {
        Some(dir) => Some((dir, read_replay(dir)?)),
        None => None,
    };
    if replay.is_none() {
        // Where failing cases would be written: checked before any work (issue 28).
        crate::render::check_out(&args.out)?;
    }
    let Some(ctx) = forestlod_harness::context::gpu_context() else {
        eprintln!(
            "check skipped: no suitable GPU adapter; install Mesa's lavapipe with scripts/install-deps"
        );
        return Ok(exit_code::GPU_SKIPPED);
    };
    if let Some((dir, replay)) = replay {
        let outcome = run_selection(ctx, replay.scene, &replay.camera, &replay.params)?;
        let stages = outcome.stages.iter().map(|s| s.name()).collect::<Vec<_>>();
        let ran = format!("{} over {}", stages.join(", "), outcome.hierarchy.name());
        return Ok(match outcome.failure {
            None => {
                println!("case {} ({ran}): passed", dir.display());
                exit_code::SUCCESS
            }
            Some(why) => {
                println!("case {} ({ran}): FAILED: {why}", dir.display());
                exit_code::PARITY_FAILED
            }
        });
    }
    std::fs::create_dir_all(&args.out).map_err(|e| io(&args.out, e))?;
    let limit = args.cases.unwrap_or(if args.seconds.is_some() {
        u64::MAX
    } else {
        1000
    });
    let started = Instant::now();
    let mut done = 0u64;
    let mut skipped = 0u64;
    let mut index = 0u64;
    let mut last_progress = Instant::now();
    let mut failure = None;
    // Cases run per hierarchy mode (what was prepared), in id order.
    let mut plans = [0u64; Hierarchy::ALL.len()];
    while done < limit
        && args
            .seconds
            .is_none_or(|s| started.elapsed().as_secs_f64() < s)
    {
        let case = random_case(args.seed, index);
        index += 1;
        match run_case(ctx, &case) {
            // A random case the loader or validation refuses (none expected): counted apart.
            Err(_) => skipped += 1,
            Ok(outcome) => {
                done += 1;
                plans[outcome.hierarchy as usize] += 1;
                if let Some(why) = outcome.failure {
                    failure = Some((index - 1, case, why));
                    break;
                }
            }
        }
        if last_progress.elapsed().as_secs_f64() >= 2.0 {
            last_progress = Instant::now();
            eprint!(
                "\rcheck: {done} cases passed, {:.0} cases/min",
                done as f64 / started.elapsed().as_secs_f64() * 60.0
            );
            let _ = std::io::stderr().flush();
        }
    }
    let secs = started.elapsed().as_secs_f64();
    eprintln!();
    println!(
        "check (select, seed {}): {done} cases in {secs:.1} s, {:.0} cases/min on {}{}",
        args.seed,
        done as f64 / secs * 60.0,
        ctx.info.name,
        if skipped > 0 {
            format!(", {skipped} invalid cases skipped")
        } else {
            String::new()
        }
    );
    let plans: Vec<String> = Hierarchy::ALL
        .into_iter()
        .zip(plans)
        .filter(|&(_, n)| n > 0)
        .map(|(h, n)| format!("{} {n}", h.name()))
        .collect();
    println!("plans: {}", plans.join(", "));
    let code = match failure {
        None => {
            println!("every case passed");
            exit_code::SUCCESS
        }
        Some((i, case, why)) => {
            println!("case {i} FAILED ({} trees): {why}", case.rows.len());
            let (small, why) = shrink(ctx, case, why, 400);
            let dir = args.out.join(format!("case-{}-{i}", args.seed));
            small.write(&dir)?;
            println!("shrunk to {} trees: {why}", small.rows.len());
            println!("written: {}", dir.display());
            println!("reproduce: forestlod check --replay {}", dir.display());
            exit_code::PARITY_FAILED
        }
    };
    Ok(code)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const FILE: &str = "r/case.toml";

    /// Every refusal is one line naming the file first.
    fn named(e: &InputError) -> bool {
        let s = e.to_string();
        s.starts_with("r/case.toml: ") && !s.contains('\n')
    }

    #[test]
    fn written_cases_read_back_exactly() {
        for i in 0..64 {
            let case = random_case(7, i);
            let r = parse_replay_toml(&case.toml(Path::new("out/x")), FILE)
                .unwrap_or_else(|e| panic!("case {i}: {e}"));
            assert_eq!(r.eye, case.eye, "case {i}");
            assert_eq!(
                r.camera,
                Camera {
                    eye: [0.0; 3],
                    ..case.camera
                },
                "case {i}"
            );
            assert_eq!(r.params, case.params, "case {i}");
        }
    }

    #[test]
    fn lossy_and_unknown_values_are_refused_naming_line_field_and_value() {
        let good = random_case(1, 3).toml(Path::new("d"));
        let with = |from: &str, to: &str| {
            let text = good.replacen(from, to, 1);
            assert_ne!(text, good, "{from}");
            parse_replay_toml(&text, FILE).unwrap_err().to_string()
        };
        let width = format!("width = {}", random_case(1, 3).camera.width);
        for (from, to, want) in [
            (width.as_str(), "width = 128.9", "value \"128.9\""),
            (width.as_str(), "width = -5", "value \"-5\""),
            (
                width.as_str(),
                "width = 99999999999",
                "value \"99999999999\"",
            ),
            ("[params]", "[params]\nbogus = 1", "field params.bogus"),
            ("[params]", "[params]\ngrid-size = 3", "given twice"),
            (
                "tree_cull = \"none\"",
                "tree_cull = \"lod0\"",
                "field params.tree_cull",
            ),
            ("[params]", "[other]\n[params]", "unknown field `other`"),
            (
                "fov_y = ",
                "fov_y = inf\n#",
                "field camera.fov_y: value \"inf\"",
            ),
            ("near = ", "near = 1e300\n#", "field camera.near"),
            ("eye = [", "eye = [1, ", "field camera.eye: value \"[1, "),
        ] {
            let e = with(from, to);
            assert!(
                e.starts_with("r/case.toml: line ") && e.contains(want),
                "{to}: {e}"
            );
        }
        let e = parse_replay_toml("[camera]\n", FILE).unwrap_err();
        assert!(named(&e) && e.to_string().contains("missing field"), "{e}");
    }

    /// TOML-ish tokens, so that arbitrary soups reach the field checks.
    fn token() -> impl Strategy<Value = &'static str> {
        prop::sample::select(vec![
            "[camera]",
            "[params]",
            "\n",
            " = ",
            "eye",
            "forward",
            "up",
            "fov_y",
            "near",
            "far",
            "width",
            "height",
            "[0, 0, 1]",
            "[1, 0, 0]",
            "[1e40, 0, 0]",
            "1",
            "0",
            "-1",
            "64",
            "1.5",
            "nan",
            "inf",
            "\"grid\"",
            "grid_size",
            "grid-size",
            "tree_cull",
            "\"lod0\"",
            "hierarchy",
            "lod_levels",
            "\"x\"",
            "#",
            "[",
            "]",
            ",",
            "=",
        ])
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn arbitrary_text_is_parsed_or_refused_naming_the_file(text in ".{0,400}") {
            if let Err(e) = parse_replay_toml(&text, FILE) {
                prop_assert!(named(&e), "{e}");
            }
        }

        #[test]
        fn token_soups_are_parsed_or_refused_naming_the_file(
            tokens in prop::collection::vec(token(), 0..80)
        ) {
            let text = tokens.concat();
            match parse_replay_toml(&text, FILE) {
                Ok(r) => {
                    prop_assert!(r.camera.validate().is_ok());
                    prop_assert!(r.params.validate().is_ok());
                }
                Err(e) => prop_assert!(named(&e), "{e}"),
            }
        }

        #[test]
        fn a_written_case_with_one_value_replaced_is_valid_or_named(
            i in 0u64..32, line in 0usize..40, value in prop::sample::select(vec![
                "0", "-1", "1.5", "nan", "-inf", "1e39", "4294967296", "\"grid\"", "[1, 2]", "true",
            ])
        ) {
            let good = random_case(3, i).toml(Path::new("d"));
            let lines: Vec<String> = good.lines().map(|l| match l.split_once(" = ") {
                Some((k, _)) if !l.is_empty() => k.to_string() + " = " + value,
                _ => l.to_string(),
            }).collect();
            let mut edited: Vec<&str> = good.lines().collect();
            let n = line % edited.len();
            edited[n] = &lines[n];
            match parse_replay_toml(&edited.join("\n"), FILE) {
                Ok(r) => {
                    prop_assert!(r.camera.validate().is_ok());
                    prop_assert!(r.params.validate().is_ok());
                    prop_assert!(r.camera.width >= 1 && r.camera.width <= 16384);
                }
                Err(e) => {
                    // The edited line is named (or the plan its parameters make).
                    let s = e.to_string();
                    prop_assert!(named(&e), "{e}");
                    prop_assert!(
                        s.starts_with(&format!("r/case.toml: line {}, ", n + 1))
                            || s.contains(", field params: ")
                            || (edited[n].starts_with("near") && s.contains("field camera.far")),
                        "line {}: {e}", n + 1
                    );
                }
            }
        }
    }
}
