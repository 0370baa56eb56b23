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
//! the same CSV loader as a replay (`load_instances_with_builtin_species`), so a written case is
//! the case that failed, bit for bit.
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
use forestlod_reference::error::InputError;
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::scene::Scene;
use forestlod_reference::scene::load::load_instances_with_builtin_species;
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

    /// Writes `trees.csv` and `case.toml` into `dir`.
    fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        let csv = dir.join("trees.csv");
        std::fs::write(&csv, self.csv()).map_err(|e| io(&csv, e))?;
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
            dir = dir.display(),
        );
        // Every parameter (shortest round-trip decimals; choices by name).
        for spec in PARAMS {
            let v = spec.format(&self.params);
            toml += &match spec.kind {
                ParamKind::Choice(_) => format!("{} = \"{v}\"\n", spec.name),
                _ => format!("{} = {v}\n", spec.name),
            };
        }
        let path = dir.join("case.toml");
        std::fs::write(&path, toml).map_err(|e| io(&path, e))?;
        Ok(())
    }

    /// Reads a case written by [`Case::write`].
    fn read(dir: &Path) -> Result<Case> {
        let path = dir.join("case.toml");
        let text = std::fs::read_to_string(&path).map_err(|e| io(&path, e))?;
        let v: toml::Value = toml::from_str(&text).map_err(|e| io(&path, e))?;
        let num = |table: &str, key: &str| -> Result<f64> {
            v.get(table)
                .and_then(|t| t.get(key))
                .and_then(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                .ok_or_else(|| {
                    io(
                        &path,
                        format!("field {table}.{key}: missing or not a number"),
                    )
                    .into()
                })
        };
        let vec3 = |key: &str| -> Result<[f64; 3]> {
            let a = v
                .get("camera")
                .and_then(|t| t.get(key))
                .and_then(|x| x.as_array())
                .filter(|a| a.len() == 3)
                .ok_or_else(|| io(&path, format!("field camera.{key}: expected 3 numbers")))?;
            let mut out = [0.0; 3];
            for (o, x) in out.iter_mut().zip(a) {
                *o = x
                    .as_float()
                    .or_else(|| x.as_integer().map(|i| i as f64))
                    .ok_or_else(|| io(&path, format!("field camera.{key}: expected numbers")))?;
            }
            Ok(out)
        };
        // The rows as written (shortest round-trip decimals parse back to the same f32s, so the
        // case materializes exactly as it did when it failed).
        let csv = dir.join("trees.csv");
        let text = std::fs::read_to_string(&csv).map_err(|e| io(&csv, e))?;
        let mut rows = Vec::new();
        for (n, line) in text.lines().enumerate().skip(1) {
            let bad = || {
                io(
                    &csv,
                    format!("line {}: expected x,y,z,yaw,scale,species", n + 1),
                )
            };
            let cols: Vec<&str> = line.split(',').collect();
            if cols.len() != 6 {
                return Err(bad().into());
            }
            let mut row = [0.0f32; 5];
            for (r, c) in row.iter_mut().zip(&cols) {
                *r = c.trim().parse().map_err(|_| bad())?;
            }
            rows.push((row, cols[5].trim().parse().map_err(|_| bad())?));
        }
        let f = |x: [f64; 3]| x.map(|c| c as f32);
        let camera = Camera {
            eye: [0.0; 3],
            forward: f(vec3("forward")?),
            up: f(vec3("up")?),
            fov_y: num("camera", "fov_y")? as f32,
            near: num("camera", "near")? as f32,
            far: num("camera", "far")? as f32,
            width: num("camera", "width")? as u32,
            height: num("camera", "height")? as u32,
            tile: [0; 2],
        };
        // Every parameter the case gives, by the parameter table; the others their defaults.
        let table = v
            .get("params")
            .and_then(|t| t.as_table())
            .ok_or_else(|| io(&path, "table [params] missing"))?;
        let mut params = Params::default();
        for (key, value) in table {
            let spec = PARAMS
                .iter()
                .find(|s| s.answers_to(key))
                .ok_or_else(|| io(&path, format!("field params.{key}: not a parameter")))?;
            let parsed = match value {
                toml::Value::String(text) => spec.parse(text).ok(),
                toml::Value::Integer(i) => spec.from_number(*i as f64).ok(),
                toml::Value::Float(x) => spec.from_number(*x).ok(),
                _ => None,
            };
            let parsed = parsed.ok_or_else(|| {
                io(
                    &path,
                    format!("field params.{key} = {value}: {}", spec.expected()),
                )
            })?;
            (spec.set)(&mut params, parsed);
        }
        if let Some(mode) = FramePlan::new(&params).ok().and_then(|p| p.refine) {
            return Err(io(
                &path,
                format!(
                    "field params.tree_cull = {:?}: check compares the selection stages before \
                     refine (parity::refine judges refine); expected {:?}",
                    mode.name(),
                    TreeCull::None.name()
                ),
            )
            .into());
        }
        Ok(Case {
            rows,
            eye: vec3("eye")?,
            camera,
            params,
        })
    }
}

fn io(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::new(path.display().to_string(), "", "", e.to_string())
}

/// The case's scene through the CSV loader (as a replay reads it) and its camera in that scene's
/// coordinates. `scratch` is a file the CSV is written to.
fn materialize(case: &Case, scratch: &Path) -> Result<(Scene, Camera)> {
    std::fs::write(scratch, case.csv()).map_err(|e| io(scratch, e))?;
    let scene = load_instances_with_builtin_species(scratch)?;
    let o = scene.origin;
    let camera = Camera {
        eye: [
            (case.eye[0] - o[0]) as f32,
            (case.eye[1] - o[1]) as f32,
            (case.eye[2] - o[2]) as f32,
        ],
        ..case.camera
    };
    Ok((scene, camera))
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
        texture_size: 1,
        layers: Vec::new(),
        chains: Vec::new(),
        texture: Texture::new(vec![placeholder]).map_err(|e| e.to_string())?,
        extents: Vec::new(),
    };
    Ok(Prepared {
        scene,
        geometry,
        batches,
        hierarchy,
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

/// Runs one case (module docs). `Err` for a case no stage can run (an invalid camera or
/// parameters).
fn run_case(ctx: &'static GpuContext, case: &Case, scratch: &Path) -> Result<Outcome> {
    let (scene, camera) = materialize(case, scratch)?;
    camera.validate().map_err(|e| io(scratch, e))?;
    case.params.validate().map_err(|e| io(scratch, e))?;
    let params = &case.params;
    let plan = FramePlan::new(params).map_err(|e| io(scratch, e))?;
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
    scratch: &Path,
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
            match run_case(ctx, &candidate, scratch).map(|o| o.failure) {
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
    let Some(ctx) = forestlod_harness::context::gpu_context() else {
        eprintln!(
            "check skipped: no suitable GPU adapter; install Mesa's lavapipe with scripts/install-deps"
        );
        return Ok(exit_code::GPU_SKIPPED);
    };
    // Each case's trees go through this file and the CSV loader (module docs).
    let scratch = std::env::temp_dir().join(format!("forestlod-check-{}.csv", std::process::id()));
    if let Some(dir) = &args.replay {
        let case = Case::read(dir)?;
        let result = run_case(ctx, &case, &scratch);
        let _ = std::fs::remove_file(&scratch);
        let outcome = result?;
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
        match run_case(ctx, &case, &scratch) {
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
            let (small, why) = shrink(ctx, case, why, &scratch, 400);
            let dir = args.out.join(format!("case-{}-{i}", args.seed));
            small.write(&dir)?;
            println!("shrunk to {} trees: {why}", small.rows.len());
            println!("written: {}", dir.display());
            println!("reproduce: forestlod check --replay {}", dir.display());
            exit_code::PARITY_FAILED
        }
    };
    let _ = std::fs::remove_file(&scratch);
    Ok(code)
}
