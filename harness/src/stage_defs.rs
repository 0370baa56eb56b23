//! The stages of issue 27 beyond the first four ([`crate::stage`] re-exports them): `hier_select`,
//! `coalesce`, `command_order`, `refine` and the baselines' `cull` and `primitive`, each with its
//! input and output in the reference's terms and the reference backend; and the judge
//! ([`Judged`]) of every stage of the table, so `tests/tests/parity/every_stage.rs` and
//! [`crate::diagnose`] compare any backend of any stage the same way. The GPU backends, which run
//! one stage alone on the reference's input of it, are [`crate::gpu_stages`].
//!
//! Every input is the reference's input of the stage (the previous stage's reference output,
//! `forestlod_reference::frame::SelectionTrace`), so a difference is the stage's own.

use forestlod_reference::baselines::{
    proxies, render_primitive, tree_spheres, vegetation_commands, visible_trees,
};
use forestlod_reference::coalesce::{coalesce, run_offsets};
use forestlod_reference::command_order::{order, run_keys};
use forestlod_reference::hier_select::{FarCut, HierSelection, hier_select};
use forestlod_reference::hierarchy::Hierarchy;
use forestlod_reference::refine::refine;
use forestlod_reference::select::{SelectUniform, Selection};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{
    Camera, Coalesce as CoalesceMode, CommandOrder as OrderMode, MeshMeta, NodeMeta, Params,
    StageId, ViewUniform,
};

use crate::alternatives::{alpha_test_alternatives, primitive_alternatives};
use crate::diagnose::texel_check;
use crate::image_compare::{Images, MaxDiffs, judge_image};
use crate::judge::{
    AMBIGUITY_REL, CullCase, Culled, RefineCase, Refinement, Thresholds, check_order,
    compare_selections, judge_cull, judge_cut, judge_refine, keys_per_run, primitive_args,
    run_key_bounds, threshold_ambiguity,
};
use crate::stage::{
    Backend, BackendSelection, Bake, BakeInput, Draw, FrameInput, Judged, LevelOut, Mips,
    MipsInput, Reference, Select, SelectInput, Stage, StageCheck, images_of,
};
use crate::texel_compare::TexelTally;

/// `hier_select` (G§3 Fig. 4, C§4.5): the raw cut of a hierarchy, before coalescing, with its
/// per-node codes and states.
pub struct HierSelect;

/// The input of [`HierSelect`].
#[derive(Clone, Copy)]
pub struct HierSelectInput<'a> {
    /// The hierarchy (its mode and nodes).
    pub hierarchy: &'a Hierarchy,
    /// Mesh records with their packed index ranges.
    pub meshes: &'a [MeshMeta],
    /// The billboard quad's record.
    pub billboard: &'a MeshMeta,
    /// The far level under `lod_levels = 3` (issue 32).
    pub far: Option<FarCut<'a>>,
    /// The camera (valid).
    pub camera: &'a Camera,
    /// Parameters (valid).
    pub params: &'a Params,
}

impl Stage for HierSelect {
    type Input<'a> = HierSelectInput<'a>;
    type Output = HierSelection;
}

impl Backend<HierSelect> for Reference {
    fn run(&self, i: HierSelectInput<'_>) -> HierSelection {
        hier_select(
            i.hierarchy,
            i.meshes,
            i.billboard,
            i.far,
            i.camera,
            i.params,
        )
    }
}

impl Judged for HierSelect {
    fn judge(i: HierSelectInput<'_>, want: &HierSelection, got: &HierSelection) -> StageCheck {
        let u = ViewUniform::new(i.camera, i.params);
        let r = judge_cut(i.hierarchy, (i.meshes, i.billboard), i.far, &u, want, got);
        StageCheck::of(
            StageId::HierSelect,
            r.map(|j| {
                (
                    format!(
                        "{} nodes, {} commands, {} ambiguous codes (within {AMBIGUITY_REL}), max \
                         fade float difference {}",
                        want.codes.len(),
                        got.selection.commands.len(),
                        j.ambiguous_nodes,
                        j.max_fade_diff
                    ),
                    f64::from(j.max_fade_diff),
                )
            }),
        )
    }
}

/// `coalesce` (issue 13, G§3's contiguous ranges): the raw cut with its runs merged.
pub struct Coalesce;

/// The input of [`Coalesce`].
#[derive(Clone, Copy)]
pub struct CoalesceInput<'a> {
    /// The raw cut.
    pub raw: &'a Selection,
    /// The mode.
    pub mode: CoalesceMode,
}

/// What [`Coalesce`] gives: the merged runs, and the exclusive scan of the head flags (one entry
/// per raw command) that `command_order` reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coalesced {
    /// The merged runs.
    pub selection: Selection,
    /// `run_offsets[j]`: the runs that start before raw command `j`.
    pub run_offsets: Vec<u32>,
}

impl Stage for Coalesce {
    type Input<'a> = CoalesceInput<'a>;
    type Output = Coalesced;
}

impl Backend<Coalesce> for Reference {
    fn run(&self, i: CoalesceInput<'_>) -> Coalesced {
        Coalesced {
            selection: coalesce(i.raw, i.mode),
            run_offsets: run_offsets(i.raw, i.mode),
        }
    }
}

impl Judged for Coalesce {
    /// Exact: coalescing is integer work (head flags, a scan, copies).
    fn judge(i: CoalesceInput<'_>, want: &Coalesced, got: &Coalesced) -> StageCheck {
        let r = compare_selections("runs", &want.selection, &got.selection).and_then(|()| {
            let differing = want
                .run_offsets
                .iter()
                .zip(&got.run_offsets)
                .filter(|(a, b)| a != b)
                .count();
            if differing > 0 || want.run_offsets.len() != got.run_offsets.len() {
                return Err(format!(
                    "run offsets: {differing} of {} differ ({} read)",
                    want.run_offsets.len(),
                    got.run_offsets.len()
                ));
            }
            Ok((
                format!(
                    "{} raw commands -> {} runs ({}), run offsets equal, max difference 0",
                    i.raw.commands.len(),
                    got.selection.commands.len(),
                    i.mode.name()
                ),
                0.0,
            ))
        });
        StageCheck::of(StageId::Coalesce, r)
    }
}

/// `command_order` (E§7): the coalesced runs reordered by their nearest view depth.
pub struct CommandOrder;

/// The input of [`CommandOrder`].
#[derive(Clone, Copy)]
pub struct CommandOrderInput<'a> {
    /// The hierarchy's nodes (the keys' depths).
    pub nodes: &'a [NodeMeta],
    /// The raw cut.
    pub raw: &'a Selection,
    /// Its coalescing under `coalesce`.
    pub coalesced: &'a Selection,
    /// The coalescing's mode (which raw commands belong to which run).
    pub coalesce: CoalesceMode,
    /// The camera (valid).
    pub camera: &'a Camera,
    /// Parameters (valid; `command_order` is the stage's mode).
    pub params: &'a Params,
}

/// What [`CommandOrder`] gives: the ordered commands and, for `front-to-back`, the sort's
/// `(key, run)` pairs in output order (empty for `node`, which computes nothing).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Ordered {
    /// The ordered commands.
    pub selection: Selection,
    /// `(key, run)` in output order.
    pub pairs: Vec<(u32, u32)>,
}

impl Stage for CommandOrder {
    type Input<'a> = CommandOrderInput<'a>;
    type Output = Ordered;
}

impl Backend<CommandOrder> for Reference {
    fn run(&self, i: CommandOrderInput<'_>) -> Ordered {
        let mode = i.params.command_ordering().expect("valid parameters");
        if mode == OrderMode::Node {
            return Ordered {
                selection: i.coalesced.clone(),
                pairs: Vec::new(),
            };
        }
        let u = ViewUniform::new(i.camera, i.params);
        let keys = run_keys(i.nodes, i.raw, i.coalesced, &u, i.coalesce);
        let mut pairs: Vec<(u32, u32)> = keys.iter().zip(0u32..).map(|(&k, r)| (k, r)).collect();
        pairs.sort_unstable();
        let (selection, _) = order(i.coalesced.clone(), keys, mode);
        Ordered { selection, pairs }
    }
}

impl Judged for CommandOrder {
    /// `node`: exact. `front-to-back`: every key within its run's
    /// [`crate::judge::near_depth_bound`] of the reference's, and the order the reference's sort
    /// under the backend's keys.
    fn judge(i: CommandOrderInput<'_>, want: &Ordered, got: &Ordered) -> StageCheck {
        let mode = i.params.command_ordering().expect("valid parameters");
        let n = i.coalesced.commands.len();
        let r = if mode == OrderMode::Node {
            compare_selections("commands (node order)", &want.selection, &got.selection)
                .map(|()| (format!("{n} commands in node order, exact"), 0.0))
        } else {
            let u = ViewUniform::new(i.camera, i.params);
            let bounds = run_key_bounds(i.nodes, i.raw, n, &u, i.coalesce);
            keys_per_run(&want.pairs, n)
                .and_then(|ref_keys| {
                    check_order(&got.selection, &got.pairs, i.coalesced, &ref_keys, &bounds)
                })
                .map(|o| {
                    (
                        format!(
                            "{n} runs sorted front to back, {} keys within their contraction \
                             bound, max key difference {} ulp ({:.3} of its bound)",
                            o.ambiguous, o.max_steps, o.max_of_bound
                        ),
                        f64::from(o.max_steps),
                    )
                })
        };
        StageCheck::of(StageId::CommandOrder, r)
    }
}

/// `refine` (beyond the thesis): per-tree culling of the selected commands.
pub struct Refine;

/// The input of [`Refine`].
#[derive(Clone, Copy)]
pub struct RefineInput<'a> {
    /// The selection, indirection, spheres, camera and parameters (what the judge reads too).
    pub case: RefineCase<'a>,
    /// The trees as the GPU takes them (`crate::bridge::cull_trees`).
    pub trees: &'a [forestlod_gpu::CullTree],
}

impl Stage for Refine {
    type Input<'a> = RefineInput<'a>;
    type Output = Refinement;
}

impl Backend<Refine> for Reference {
    fn run(&self, i: RefineInput<'_>) -> Refinement {
        let c = i.case;
        let mut selection = c.selection.clone();
        let refined = refine(
            &mut selection,
            c.batch_indirection,
            c.spheres,
            c.scales,
            c.camera,
            c.params,
        );
        Refinement { selection, refined }
    }
}

impl Judged for Refine {
    /// [`judge_refine`] without the per-tree oracle (the input may be a cut's commands).
    fn judge(i: RefineInput<'_>, want: &Refinement, got: &Refinement) -> StageCheck {
        let r = judge_refine(i.case, want, got, false).map(|j| {
            (
                format!(
                    "{} commands ({} refined), {} trees tested, {} kept, {} ambiguous trees \
                     (within {AMBIGUITY_REL}), max difference {} trees",
                    got.selection.commands.len(),
                    j.refined_commands,
                    want.refined.trees_tested,
                    j.kept,
                    j.ambiguous.len(),
                    j.ambiguous.len()
                ),
                j.ambiguous.len() as f64,
            )
        });
        StageCheck::of(StageId::Refine, r)
    }
}

/// `cull` (E§5, the baselines): per-tree visibility, compacted mesh by mesh into Vegetation's
/// commands and the Primitive's indirect arguments.
pub struct Cull;

impl Stage for Cull {
    type Input<'a> = CullCase<'a>;
    type Output = Culled;
}

impl Backend<Cull> for Reference {
    fn run(&self, i: CullCase<'_>) -> Culled {
        let visible = visible_trees(i.spheres, i.camera, i.params);
        let (selection, indirection) =
            vegetation_commands(i.scene, i.meshes, &visible, i.camera, i.params);
        Culled {
            selection,
            draw_args: primitive_args(indirection.len()),
            indirection,
        }
    }
}

impl Judged for Cull {
    fn judge(i: CullCase<'_>, want: &Culled, got: &Culled) -> StageCheck {
        let r = judge_cull(i, want, got).map(|j| {
            (
                format!(
                    "{} trees, {} visible, {} commands, {} ambiguous trees (within \
                     {AMBIGUITY_REL}), max difference {} trees",
                    i.spheres.len(),
                    j.visible,
                    got.selection.commands.len(),
                    j.ambiguous,
                    j.ambiguous
                ),
                j.ambiguous as f64,
            )
        });
        StageCheck::of(StageId::Cull, r)
    }
}

/// `primitive` (E§5): the Primitive baseline's frame, one ray-cast proxy quad per visible tree
/// (the reference's visible set: `cull`'s output).
pub struct Primitive;

impl Stage for Primitive {
    type Input<'a> = FrameInput<'a>;
    type Output = Images;
}

impl Backend<Primitive> for Reference {
    fn run(&self, i: FrameInput<'_>) -> Images {
        let p = i.prepared;
        let spheres = tree_spheres(&p.scene, &p.geometry.meshes);
        let proxy_list = proxies(p, i.params.alpha_cutoff);
        images_of(&render_primitive(p, &spheres, &proxy_list, i.camera, i.params).target)
    }
}

/// An image judged by [`judge_image`] against `want` and `alternatives`: the check of `stage`,
/// the largest interior colour difference its maximum.
fn image_check(
    stage: StageId,
    got: &Images,
    want: &Images,
    alternatives: &[Images],
    camera: &Camera,
) -> StageCheck {
    let mut max: MaxDiffs = (0, 0, 0.0);
    let failure = judge_image(stage.name(), got, want, alternatives, camera, &mut max);
    let summary = format!(
        "image parity classes of image_compare: max interior colour difference {}, depth {} ulp \
         ({} absolute)",
        max.0, max.1, max.2
    );
    StageCheck::of(
        stage,
        match failure {
            None => Ok((summary, f64::from(max.0))),
            Some(f) => Err(format!("{f}; {summary}")),
        },
    )
}

impl Judged for Primitive {
    /// The image classes of [`crate::image_compare`], with the ray cast's root tests moved
    /// (`PRIMITIVE_DISC_SHIFTS`) as alternatives.
    fn judge(i: FrameInput<'_>, want: &Images, got: &Images) -> StageCheck {
        let p = i.prepared;
        let spheres = tree_spheres(&p.scene, &p.geometry.meshes);
        let proxy_list = proxies(p, i.params.alpha_cutoff);
        let alternatives = primitive_alternatives(p, &spheres, &proxy_list, i.camera, i.params);
        image_check(StageId::Primitive, got, want, &alternatives, i.camera)
    }
}

impl Judged for Draw {
    /// The image classes of [`crate::image_compare`], with the alpha-test cutoff moved
    /// (`ALPHA_TEST_SHIFTS`) as alternatives.
    fn judge(i: FrameInput<'_>, want: &Images, got: &Images) -> StageCheck {
        let alternatives = alpha_test_alternatives(i.prepared, i.camera, i.params);
        image_check(StageId::Draw, got, want, &alternatives, i.camera)
    }
}

impl Judged for Select {
    /// Per-batch decisions equal up to batches within [`AMBIGUITY_REL`] of a threshold
    /// ([`Thresholds::BATCH`]); the commands exactly the reference's when none is ambiguous
    /// (stable order; `parity::select` judges the rest).
    fn judge(i: SelectInput<'_>, want: &BackendSelection, got: &BackendSelection) -> StageCheck {
        let u = SelectUniform::new(i.camera, i.params);
        let r = (|| {
            if want.decisions.len() != got.decisions.len() {
                return Err(format!(
                    "{} decisions for {} batches",
                    got.decisions.len(),
                    want.decisions.len()
                ));
            }
            let mut ambiguous = 0u64;
            for (b, (w, g)) in want.decisions.iter().zip(&got.decisions).enumerate() {
                if w == g {
                    continue;
                }
                let m = &i.batches[b];
                match threshold_ambiguity(m.center, m.radius, &u, AMBIGUITY_REL, Thresholds::BATCH)
                {
                    Some(why) => {
                        eprintln!("batch {b} ambiguous ({why}): reference {w:?}, GPU {g:?}");
                        ambiguous += 1;
                    }
                    None => {
                        return Err(format!(
                            "batch {b}: {g:?}, the reference's {w:?}, not near a threshold"
                        ));
                    }
                }
            }
            if ambiguous == 0 {
                compare_selections("commands", &want.selection, &got.selection)?;
            }
            Ok((
                format!(
                    "{} batches, {} commands, {ambiguous} ambiguous decisions (within \
                     {AMBIGUITY_REL}), max difference {ambiguous} batches",
                    want.decisions.len(),
                    got.selection.commands.len()
                ),
                ambiguous as f64,
            ))
        })();
        StageCheck::of(StageId::Select, r)
    }
}

/// The texel tally of `got` against `want`, image by image (±1 per channel).
fn tally_images<'a>(
    pairs: impl Iterator<Item = (String, &'a Rgba8Image, &'a Rgba8Image)>,
) -> TexelTally {
    let mut tally = TexelTally::default();
    for (what, g, w) in pairs {
        tally.compare(&what, &g.texels, &w.texels, 1);
    }
    tally
}

/// A texture stage's check: [`texel_check`]'s thresholds, the stage named by its id.
fn texture_stage_check(stage: StageId, shapes_agree: bool, tally: &TexelTally) -> StageCheck {
    if !shapes_agree {
        return StageCheck::of(stage, Err("layer or level counts differ".into()));
    }
    let c = texel_check(stage.name(), tally);
    StageCheck {
        max_difference: f64::from(tally.max_diff),
        ..c
    }
}

impl Judged for Mips {
    /// [`crate::diagnose::STAGE_TEXEL_MAX_FRACTION`] of the texels beyond ±1 and the bias limit
    /// of the diagnosis, over every level of every layer.
    fn judge(_: MipsInput<'_>, want: &Vec<Vec<LevelOut>>, got: &Vec<Vec<LevelOut>>) -> StageCheck {
        let shapes =
            want.len() == got.len() && want.iter().zip(got).all(|(a, b)| a.len() == b.len());
        let tally = tally_images(want.iter().zip(got).enumerate().flat_map(|(l, (w, g))| {
            w.iter()
                .zip(g)
                .enumerate()
                .map(move |(k, (w, g))| (format!("layer {l} level {k}"), &g.image, &w.image))
        }));
        texture_stage_check(StageId::Mips, shapes, &tally)
    }
}

impl Judged for Bake {
    /// As [`Mips`], on level 0 of every layer.
    fn judge(_: BakeInput<'_>, want: &Vec<Rgba8Image>, got: &Vec<Rgba8Image>) -> StageCheck {
        let tally = tally_images(
            want.iter()
                .zip(got)
                .enumerate()
                .map(|(l, (w, g))| (format!("layer {l}"), g, w)),
        );
        texture_stage_check(StageId::Bake, want.len() == got.len(), &tally)
    }
}

/// `pyramid` (issue 31): the depth pyramid of the early pass (`forestlod_shared::occlusion`).
pub struct Pyramid;

/// The input of [`Pyramid`]: a depth buffer.
#[derive(Clone, Copy)]
pub struct PyramidInput<'a> {
    /// `width · height` depths, row-major from the top-left pixel.
    pub depth: &'a [f32],
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Stage for Pyramid {
    type Input<'a> = PyramidInput<'a>;
    /// Every level's texels (`forestlod_shared::pyramid_levels` layout).
    type Output = Vec<f32>;
}

impl Backend<Pyramid> for Reference {
    fn run(&self, i: PyramidInput<'_>) -> Vec<f32> {
        forestlod_reference::pyramid::Pyramid::build(i.depth, i.width, i.height).texels
    }
}

impl Judged for Pyramid {
    /// Bit for bit: the reduction is a maximum, which rounds nothing.
    fn judge(i: PyramidInput<'_>, want: &Vec<f32>, got: &Vec<f32>) -> StageCheck {
        let differing = want
            .iter()
            .zip(got)
            .filter(|(w, g)| w.to_bits() != g.to_bits())
            .count();
        let max = want
            .iter()
            .zip(got)
            .map(|(w, g)| f64::from((w - g).abs()))
            .fold(0.0, f64::max);
        let r = if want.len() != got.len() || differing > 0 {
            Err(format!(
                "{}x{}: {differing} of {} texels differ in bits ({} vs {} texels), max |difference| {max}",
                i.width,
                i.height,
                want.len(),
                got.len(),
                want.len()
            ))
        } else {
            Ok((
                format!(
                    "{}x{}: {} texels equal bit for bit",
                    i.width,
                    i.height,
                    want.len()
                ),
                max,
            ))
        };
        StageCheck::of(StageId::Pyramid, r)
    }
}

/// `occlude` (issue 31): the early split and the late test of the commands, on a path's first
/// frame (no history).
pub struct Occlude;

/// The input of [`Occlude`].
#[derive(Clone, Copy)]
pub struct OccludeInput<'a> {
    /// The frame's commands, after every selection stage.
    pub selection: &'a Selection,
    /// The indirection they index (`m` entries).
    pub indirection: &'a [u32],
    /// Every tree's footprint sphere (`Prepared::footprints`).
    pub footprints: &'a [forestlod_reference::occlude::Footprint],
    /// The camera (valid).
    pub camera: &'a Camera,
    /// Parameters (valid, occlusion culling on).
    pub params: &'a Params,
    /// The early pass's depth (`camera.width · camera.height`): the pyramid's level 0.
    pub early_depth: &'a [f32],
}

/// What [`Occlude`] gives.
#[derive(Clone, Debug, PartialEq)]
pub struct Occluded {
    /// The early commands over [`Occluded::indirection`].
    pub early: Selection,
    /// The late commands over [`Occluded::indirection`].
    pub late: Selection,
    /// The `4m` lists (entries outside the commands' ranges are not compared).
    pub indirection: Vec<u32>,
    /// The stage's counters.
    pub counters: forestlod_shared::OcclusionCounters,
    /// Per tree, 1 when it passed the test.
    pub visible: Vec<u32>,
}

impl Stage for Occlude {
    type Input<'a> = OccludeInput<'a>;
    type Output = Occluded;
}

impl Backend<Occlude> for Reference {
    fn run(&self, i: OccludeInput<'_>) -> Occluded {
        use forestlod_reference::occlude::{occlude_early, occlude_late};
        let (early, mut indirection) = occlude_early(
            i.selection,
            i.indirection,
            i.footprints,
            i.camera,
            i.params,
            &[],
        );
        let pyramid = forestlod_reference::pyramid::Pyramid::build(
            i.early_depth,
            i.camera.width,
            i.camera.height,
        );
        let late = occlude_late(
            i.selection,
            i.indirection,
            i.footprints,
            i.camera,
            i.params,
            &[],
            &pyramid,
            &mut indirection,
        );
        Occluded {
            early,
            late: late.selection,
            indirection,
            counters: late.counters,
            visible: late.visible,
        }
    }
}

/// Decisions of the GPU's late test that may differ from the reference's, per thousand trees
/// tested: a tree whose nearest corner depth or rectangle edge lies within a few ulps of a
/// threshold may round either way on a GPU (the projection's division, a fused multiply-add;
/// `tests/tests/parity/occlusion.rs` measured none on lavapipe over 593,010 tests). One per
/// thousand still catches a wrong rule, which flips whole groups of trees.
pub const OCCLUDE_DECISIONS_PER_MILLE: u64 = 1;

/// How many trees two lists differ by (as multisets).
pub fn list_difference(a: &[u32], b: &[u32]) -> u64 {
    let (mut a, mut b) = (a.to_vec(), b.to_vec());
    a.sort_unstable();
    b.sort_unstable();
    let (mut i, mut j, mut d) = (0, 0, 0u64);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Equal => (i, j) = (i + 1, j + 1),
            std::cmp::Ordering::Less => (i, d) = (i + 1, d + 1),
            std::cmp::Ordering::Greater => (j, d) = (j + 1, d + 1),
        }
    }
    d + (a.len() - i + b.len() - j) as u64
}

impl Judged for Occlude {
    /// The early and late commands (slots, ranges), their lists in order, the counters and the
    /// history equal the reference's, but for at most [`OCCLUDE_DECISIONS_PER_MILLE`] differing
    /// decisions (a list that differs only in order is a failure: the compaction is stable).
    fn judge(_: OccludeInput<'_>, want: &Occluded, got: &Occluded) -> StageCheck {
        let mut differing = 0u64;
        let mut why = Vec::new();
        for (what, w, g) in [
            ("early", &want.early, &got.early),
            ("late", &want.late, &got.late),
        ] {
            if w.commands.len() != g.commands.len() {
                why.push(format!(
                    "{what}: {} commands, the reference's {}",
                    g.commands.len(),
                    w.commands.len()
                ));
                continue;
            }
            for (k, (wc, gc)) in w.commands.iter().zip(&g.commands).enumerate() {
                let list = |c: &forestlod_shared::DrawCommand, ind: &[u32]| {
                    ind[c.first_instance as usize..(c.first_instance + c.instance_count) as usize]
                        .to_vec()
                };
                if wc.first_instance != gc.first_instance {
                    why.push(format!("{what}: command {k} at slot {}", gc.first_instance));
                    continue;
                }
                let (wl, gl) = (list(wc, &want.indirection), list(gc, &got.indirection));
                if wl != gl {
                    let d = list_difference(&wl, &gl);
                    if d == 0 {
                        why.push(format!("{what}: command {k}'s trees in another order"));
                    }
                    differing += d;
                }
            }
        }
        let history = want
            .visible
            .iter()
            .zip(&got.visible)
            .filter(|(w, g)| w != g)
            .count() as u64;
        let tested = u64::from(want.counters.tested);
        let budget = (tested * OCCLUDE_DECISIONS_PER_MILLE).div_ceil(1000);
        if differing == 0 && history == 0 && want.counters != got.counters {
            why.push(format!(
                "counters {:?}, the reference's {:?}",
                got.counters, want.counters
            ));
        }
        if differing + history > budget {
            why.push(format!(
                "{differing} list decisions and {history} history entries differ (budget {budget})"
            ));
        }
        let r = if why.is_empty() {
            Ok((
                format!(
                    "{} early, {} tested, {} occluded, {} late; {} differing decisions, max \
                     difference {} trees",
                    want.counters.early,
                    tested,
                    want.counters.occluded,
                    want.counters.late,
                    differing + history,
                    differing + history
                ),
                (differing + history) as f64,
            ))
        } else {
            Err(why.join("; "))
        };
        StageCheck::of(StageId::Occlude, r)
    }
}

/// `far_bake` (issue 32 item 2, G§2.2-2.4): the far level's cells of a prepared scene's
/// hierarchy (`forestlod_shared::far_bake`).
pub struct FarBake;

/// The input of [`FarBake`].
#[derive(Clone, Copy)]
pub struct FarBakeInput<'a> {
    /// The prepared scene (its hierarchy, scene, geometry and mesh textures).
    pub prepared: &'a forestlod_reference::pipeline::Prepared,
    /// Parameters (valid).
    pub params: &'a Params,
}

impl Stage for FarBake {
    type Input<'a> = FarBakeInput<'a>;
    type Output = forestlod_shared::FarLevel;
}

impl Backend<FarBake> for Reference {
    fn run(&self, i: FarBakeInput<'_>) -> forestlod_shared::FarLevel {
        let p = i.prepared;
        let h = p
            .hierarchy
            .as_ref()
            .expect("a far level is baked over a hierarchy");
        forestlod_reference::far_bake::far_bake(
            h,
            &p.scene,
            &p.geometry,
            &p.mesh_textures,
            i.params,
        )
        .unwrap_or_else(|e| panic!("reference far bake: {e}"))
    }
}

/// Largest sRGB byte difference of a far cell's side whose coverage (alpha byte) both twins
/// agree on, for all but [`FAR_COLOUR_SHARE`] of the sides: the issue's ±1 (the sRGB encodes and
/// `f32` sums round apart).
pub const FAR_CHANNEL_TOLERANCE: i32 = 1;

/// Largest share of equally covered sides beyond [`FAR_CHANNEL_TOLERANCE`]: lavapipe quantizes
/// bilinear weights to 8 bits and interpolates uv from unsnapped vertices (`gpu/src/bake.rs`
/// module docs), so a few texels of a block move by a few bytes. Measured on `tiny`'s octree
/// (`tests/tests/parity/far_bake.rs`, printed): 3.1 % at cluster size 1, 1.6 % at 2, 0.24 % at 4.
pub const FAR_COLOUR_SHARE: f64 = 0.05;

// No bound on the largest sRGB difference of an equally covered side: a block with one covered
// pixel whose winner swaps where two leaves meet at nearly one depth (the bake's depth-ambiguous
// class) moves by that pixel's whole difference. Measured (printed): 42 on `tiny`'s leaves at
// cluster size 2, 137 on its whole level at 12. The share above is what is judged.

/// Largest share of sides whose coverage differs (a pixel kept by one twin only: an edge within
/// the 8-bit subpixel ambiguity, a filtered alpha at the cutoff, the bake's classes). Their colour
/// is not judged (a flipped pixel moves the mean by its own difference over the covered count).
/// Measured on `tiny`: 12 % of the sides at cluster size 1 (8² pixels over a whole leaf: most
/// pixels lie on a leaf's alpha edge at the mip level an 8-pixel view samples), 7.8 % at 2, 1.7 %
/// at 4.
pub const FAR_COVERAGE_SHARE: f64 = 0.15;

/// Largest alpha byte difference of a leaf's side: 8 pixels of the block's 64 (`255/64` each).
/// Measured: 28 (7 pixels). Not applied to whole levels ([`judge_far_level`]): an interior cell
/// averages its gathered cells, and a cell kept for one pixel on one twin only changes how many
/// `average` divides by.
pub const FAR_ALPHA_MAX: i32 = 32;

/// Largest share of kept cells in one twin's level only (a cell kept for one covered pixel on one
/// twin). Measured: 0.6 %.
pub const FAR_KEPT_SHARE: f64 = 0.02;

/// The tally of far cell sides compared ([`far_tally`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FarTally {
    /// Sides compared.
    pub sides: usize,
    /// Sides whose alpha bytes differ by more than [`FAR_CHANNEL_TOLERANCE`].
    pub coverage_differs: usize,
    /// Largest alpha byte difference.
    pub max_alpha: i32,
    /// Equally covered sides beyond [`FAR_CHANNEL_TOLERANCE`].
    pub colour_beyond: usize,
    /// Largest sRGB byte difference of an equally covered side (0 for uncovered ones).
    pub max_colour: i32,
}

/// Tallies pairs of packed far side colours (`(reference, other)`).
pub fn far_tally(pairs: impl IntoIterator<Item = (u32, u32)>) -> FarTally {
    let b = |w: u32, k: u32| ((w >> (8 * k)) & 255) as i32;
    let mut t = FarTally::default();
    for (x, y) in pairs {
        t.sides += 1;
        let alpha = (b(x, 3) - b(y, 3)).abs();
        if alpha > FAR_CHANNEL_TOLERANCE {
            t.coverage_differs += 1;
            t.max_alpha = t.max_alpha.max(alpha);
            continue;
        }
        t.max_alpha = t.max_alpha.max(alpha);
        if b(x, 3) == 0 && b(y, 3) == 0 {
            continue;
        }
        let d = (0..3).map(|k| (b(x, k) - b(y, k)).abs()).max().unwrap_or(0);
        t.max_colour = t.max_colour.max(d);
        if d > FAR_CHANNEL_TOLERANCE {
            t.colour_beyond += 1;
        }
    }
    t
}

impl FarTally {
    /// Whether the tally of leaf sides is within the named tolerances; the summary either way.
    pub fn verdict(&self) -> Result<String, String> {
        self.verdict_with(true)
    }

    /// [`FarTally::verdict`], with [`FAR_ALPHA_MAX`] applied or not (whole levels).
    pub fn verdict_with(&self, alpha_max: bool) -> Result<String, String> {
        let n = self.sides.max(1) as f64;
        let summary = format!(
            "{} sides: {} equally covered beyond ±{FAR_CHANNEL_TOLERANCE} (largest {}), coverage \
             differs on {} (largest alpha difference {})",
            self.sides, self.colour_beyond, self.max_colour, self.coverage_differs, self.max_alpha
        );
        if self.colour_beyond as f64 > FAR_COLOUR_SHARE * n
            || self.coverage_differs as f64 > FAR_COVERAGE_SHARE * n
            || (alpha_max && self.max_alpha > FAR_ALPHA_MAX)
        {
            Err(summary)
        } else {
            Ok(summary)
        }
    }
}

/// Judges a far level against the reference's: node by node, the kept cells (by their boxes'
/// bits) in one level only (at most [`FAR_KEPT_SHARE`]), and the common cells' sides
/// ([`far_tally`], [`FarTally::verdict`]). The summary and the largest byte difference.
pub fn judge_far_level(
    want: &forestlod_shared::FarLevel,
    got: &forestlod_shared::FarLevel,
) -> Result<(String, f64), String> {
    if want.nodes.len() != got.nodes.len() {
        return Err(format!(
            "{} nodes, reference {}",
            got.nodes.len(),
            want.nodes.len()
        ));
    }
    let cells = |l: &forestlod_shared::FarLevel, i: usize| {
        let f = l.nodes[i];
        l.cells
            .get(f.cell_offset as usize..(f.cell_offset + f.cell_count) as usize)
            .unwrap_or(&[])
            .to_vec()
    };
    let key =
        |c: &forestlod_shared::FarCell| (c.center.map(f32::to_bits), c.extent.map(f32::to_bits));
    let (mut pairs, mut one_only) = (Vec::new(), 0usize);
    for i in 0..want.nodes.len() {
        let (w, g) = (cells(want, i), cells(got, i));
        for c in &w {
            match g.iter().find(|x| key(x) == key(c)) {
                None => one_only += 1,
                Some(x) => pairs.extend(c.colours.iter().copied().zip(x.colours)),
            }
        }
        one_only += g
            .iter()
            .filter(|x| !w.iter().any(|c| key(c) == key(x)))
            .count();
    }
    let tally = far_tally(pairs);
    let kept = format!(
        "{} kept cells, {one_only} in one level only",
        want.cells.len()
    );
    let largest = f64::from(tally.max_colour.max(tally.max_alpha));
    match tally.verdict_with(false) {
        Ok(s) if one_only as f64 <= FAR_KEPT_SHARE * want.cells.len().max(1) as f64 => {
            Ok((format!("{kept}; {s}"), largest))
        }
        Ok(s) | Err(s) => Err(format!("{kept}; {s}")),
    }
}

impl Judged for FarBake {
    /// [`judge_far_level`].
    fn judge(
        _: FarBakeInput<'_>,
        want: &forestlod_shared::FarLevel,
        got: &forestlod_shared::FarLevel,
    ) -> StageCheck {
        StageCheck::of(StageId::FarBake, judge_far_level(want, got))
    }
}
