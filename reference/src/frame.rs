//! The reference's frame (issue 27): the selection stages of a [`FramePlan`] run in order, one
//! stage after the other, each on the previous one's output (pbrt-v4's wavefront `Render()` is
//! the model: one function calling named stages in order). The plan is decided once, from the
//! parameters ([`FramePlan::new`]); [`crate::pipeline::Prepared::select`], `render` and every tool
//! run the selection through [`select_stages`], so no consumer decides grid or hierarchy itself.
//!
//! | stage | module | input | output |
//! |---|---|---|---|
//! | `select` | [`crate::select`] | batches | [`Selection`] |
//! | `hier_select` | [`crate::hier_select`] | hierarchy nodes | the raw cut ([`HierSelection`]) |
//! | `coalesce` | [`crate::coalesce`] | the raw cut | merged runs |
//! | `command_order` | [`crate::command_order`] | the raw cut and its runs | the runs sorted |
//! | `refine` | [`crate::refine`] | the selection so far | refined commands, `3n` indirection |
//!
//! A [`SelectionTrace`] keeps every stage's output when asked (`keep`), for the harness's stage
//! parity and first-differing-stage diagnosis; without it each stage consumes its input.

use std::time::Instant;

use forestlod_shared::{
    Camera, Coalesce, CommandOrder, FramePlan, Params, SelectionPlan, StageId, ViewUniform,
};

use crate::batches::Batches;
use crate::coalesce::coalesce;
use crate::command_order::{order, run_keys};
use crate::geometry::PackedGeometry;
use crate::hier_select::{FarCut, HierSelection, hier_select};
use crate::hierarchy::Hierarchy;
use crate::refine::{Refined, refine};
use crate::select::{Selection, select};

/// What the cut's stages produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CutTrace {
    /// `hier_select`'s raw cut, with its per-node codes and states.
    pub cut: HierSelection,
    /// `coalesce`'s runs (kept only when asked).
    pub coalesced: Option<Selection>,
    /// `command_order`'s key of every output command, in output order (computed whatever the
    /// order mode).
    pub keys: Vec<u32>,
}

/// What one frame's selection stages produced (module docs).
#[derive(Clone, Debug)]
pub struct SelectionTrace {
    /// The plan that ran.
    pub plan: FramePlan,
    /// Whether the intermediate outputs were kept.
    pub kept: bool,
    /// The cut's stages' outputs, for a cut.
    pub cut: Option<CutTrace>,
    /// The selection before `refine` (kept only when asked and `refine` ran).
    pub unrefined: Option<Selection>,
    /// What the draw reads: the last selection stage's commands.
    pub selection: Selection,
    /// `refine`'s output, when it ran.
    pub refined: Option<Refined>,
    /// Wall seconds of each stage that ran.
    pub seconds: StageSeconds,
}

/// Wall seconds per stage, in the order they ran.
#[derive(Clone, Debug, Default)]
pub struct StageSeconds(pub Vec<(StageId, f64)>);

impl StageSeconds {
    /// Runs `f` as stage `stage`, timed.
    fn time<T>(&mut self, stage: StageId, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.0.push((stage, t.elapsed().as_secs_f64()));
        out
    }

    /// Seconds of `stage` (0 when it did not run).
    pub fn get(&self, stage: StageId) -> f64 {
        self.0
            .iter()
            .filter(|(s, _)| *s == stage)
            .map(|(_, t)| t)
            .sum()
    }

    /// Seconds of the selection stages but `refine` (E§5's selection time).
    pub fn selection(&self) -> f64 {
        self.0
            .iter()
            .filter(|(s, _)| *s != StageId::Refine)
            .map(|(_, t)| t)
            .sum()
    }
}

impl SelectionTrace {
    /// The output of selection stage `stage` (`None` for a stage the plan did not run or whose
    /// output was not kept; for `refine`, its commands).
    pub fn output(&self, stage: StageId) -> Option<&Selection> {
        let before_refine = match &self.refined {
            Some(_) => self.unrefined.as_ref(),
            None => Some(&self.selection),
        };
        let cut = self.cut.as_ref();
        match stage {
            StageId::Select => before_refine.filter(|_| !self.plan.is_cut()),
            StageId::HierSelect => cut.filter(|_| self.kept).map(|c| &c.cut.selection),
            StageId::Coalesce => cut.and_then(|c| c.coalesced.as_ref()),
            StageId::CommandOrder => before_refine.filter(|_| self.plan.is_cut()),
            StageId::Refine => self.refined.as_ref().map(|_| &self.selection),
            _ => None,
        }
    }

    /// The indirection the selection's commands index: the refined `3n` one when `refine` ran,
    /// else `batches` (the prepared scene's).
    pub fn indirection<'a>(&'a self, batches: &'a [u32]) -> &'a [u32] {
        self.refined.as_ref().map_or(batches, |r| &r.indirection)
    }
}

/// What the selection stages read of a prepared scene (`Prepared::select_scene`).
#[derive(Clone, Copy)]
pub struct SelectScene<'a> {
    /// Packed geometry (the meshes' index ranges, the billboard quad).
    pub geometry: &'a PackedGeometry,
    /// The batches: the grid's, or the hierarchy's leaves.
    pub batches: &'a Batches,
    /// The hierarchy, for a cut.
    pub hierarchy: Option<&'a Hierarchy>,
    /// The hierarchy's far level under `lod_levels = 3` (issue 32).
    pub far: Option<&'a forestlod_shared::FarLevel>,
    /// Every tree's bounding sphere (`refine`'s input).
    pub tree_spheres: &'a [([f32; 3], f32)],
    /// Every tree's scale (`refine`'s per-tree band, issue 29).
    pub tree_scales: &'a [f32],
}

/// Runs the selection stages of `params`' plan on `prepared` (grouped as `params` says,
/// `crate::pipeline::group_trees`) in order. `keep` keeps the intermediate outputs. `params`
/// must be valid.
pub fn select_stages(
    prepared: &SelectScene<'_>,
    camera: &Camera,
    params: &Params,
    keep: bool,
) -> SelectionTrace {
    let plan = FramePlan::new(params).expect("parameters are validated before selection");
    let g = &prepared.geometry;
    let mut seconds = StageSeconds::default();
    let (mut selection, cut) = match plan.selection {
        SelectionPlan::Flat => {
            let s = seconds.time(StageId::Select, || {
                select(
                    &prepared.batches.metas,
                    &prepared.batches.scales,
                    &g.meshes,
                    &g.billboard,
                    camera,
                    params,
                )
            });
            (s, None)
        }
        SelectionPlan::Cut {
            coalesce: mode,
            order: order_mode,
            ..
        } => {
            let h = prepared
                .hierarchy
                .expect("a scene prepared with a hierarchy mode has its hierarchy");
            let far = FarCut::new(prepared.far, g.far.first_index, camera, params);
            let (ordered, trace) = cut_stages(
                h,
                &g.meshes,
                &g.billboard,
                far,
                camera,
                params,
                (mode, order_mode),
                keep,
                &mut seconds,
            );
            (ordered, Some(trace))
        }
    };
    let (unrefined, refined) = match plan.refine {
        None => (None, None),
        Some(_) => {
            let unrefined = keep.then(|| selection.clone());
            let r = seconds.time(StageId::Refine, || {
                refine(
                    &mut selection,
                    &prepared.batches.indirection,
                    prepared.tree_spheres,
                    prepared.tree_scales,
                    camera,
                    params,
                )
            });
            (unrefined, Some(r))
        }
    };
    SelectionTrace {
        plan,
        kept: keep,
        cut,
        unrefined,
        selection,
        refined,
        seconds,
    }
}

/// The cut's three stages in order (`hier_select`, `coalesce`, `command_order`) with the given
/// modes, timed into `seconds`: the ordered commands and the stages' outputs (the raw cut's
/// commands and the runs kept only when `keep`).
#[allow(clippy::too_many_arguments)]
pub fn cut_stages(
    h: &Hierarchy,
    meshes: &[forestlod_shared::MeshMeta],
    billboard: &forestlod_shared::MeshMeta,
    far: Option<FarCut<'_>>,
    camera: &Camera,
    params: &Params,
    (mode, order_mode): (Coalesce, CommandOrder),
    keep: bool,
    seconds: &mut StageSeconds,
) -> (Selection, CutTrace) {
    let mut raw = seconds.time(StageId::HierSelect, || {
        hier_select(h, meshes, billboard, far, camera, params)
    });
    let merged = seconds.time(StageId::Coalesce, || coalesce(&raw.selection, mode));
    let coalesced = keep.then(|| merged.clone());
    let (ordered, keys) = seconds.time(StageId::CommandOrder, || {
        let u = ViewUniform::new(camera, params);
        let keys = run_keys(&h.nodes, &raw.selection, &merged, &u, mode);
        order(merged, keys, order_mode)
    });
    if !keep {
        raw.selection = Selection::default();
    }
    let trace = CutTrace {
        cut: raw,
        coalesced,
        keys,
    };
    (ordered, trace)
}

/// [`cut_stages`] with the modes of `params` (valid), every output kept: the whole cut of one
/// frame, for tests and experiments that judge the cut on its own hierarchy (with its far level
/// when `far` is given).
pub fn cut(
    h: &Hierarchy,
    meshes: &[forestlod_shared::MeshMeta],
    billboard: &forestlod_shared::MeshMeta,
    far: Option<FarCut<'_>>,
    camera: &Camera,
    params: &Params,
) -> (Selection, CutTrace) {
    let modes = (
        params.coalescing().expect("valid parameters"),
        params.command_ordering().expect("valid parameters"),
    );
    cut_stages(
        h,
        meshes,
        billboard,
        far,
        camera,
        params,
        modes,
        true,
        &mut StageSeconds::default(),
    )
}

#[cfg(test)]
mod tests {
    use forestlod_shared::{Coalesce, CommandOrder, Hierarchy, Params, StageId, TreeCull};

    use crate::cameras::named_camera;
    use crate::coalesce::coalesce;
    use crate::hier_select::hier_select;
    use crate::pipeline::prepare;
    use crate::scene::builtin;

    /// Each stage's output is the stage applied to the one before it, the plan's stages run in
    /// the plan's order, and a trace that keeps nothing ends with the same commands.
    #[test]
    fn each_stage_reads_the_one_before_it() {
        let params = Params {
            hierarchy: Hierarchy::Octree as u32,
            command_order: CommandOrder::FrontToBack as u32,
            tree_cull: TreeCull::Lod0 as u32,
            coalesce: Coalesce::On as u32,
            ..Params::default()
        };
        let prepared = prepare(builtin::by_name("tiny").unwrap(), &params).unwrap();
        let camera = named_camera("close", &prepared.scene, 0.0, 160, 90).unwrap();
        let trace = prepared.select_stages(&camera, &params, true);
        let ran: Vec<StageId> = trace.seconds.0.iter().map(|(s, _)| *s).collect();
        assert_eq!(ran, trace.plan.selection_stages());
        let g = &prepared.geometry;
        let h = prepared.hierarchy.as_ref().unwrap();
        let raw = hier_select(h, &g.meshes, &g.billboard, None, &camera, &params).selection;
        assert!(!raw.commands.is_empty(), "the case draws something");
        assert_eq!(trace.output(StageId::HierSelect), Some(&raw));
        let merged = coalesce(&raw, Coalesce::On);
        assert_eq!(trace.output(StageId::Coalesce), Some(&merged));
        let ordered = trace.output(StageId::CommandOrder).unwrap();
        assert_eq!(ordered.commands.len(), merged.commands.len());
        assert_eq!(trace.output(StageId::Refine), Some(&trace.selection));
        assert!(trace.refined.is_some());
        assert_eq!(
            trace.output(StageId::Select),
            None,
            "a cut has no flat select"
        );
        let plain = prepared.select_stages(&camera, &params, false);
        assert_eq!(plain.selection, trace.selection);
        assert_eq!(plain.output(StageId::HierSelect), None, "nothing kept");
        let (selection, _) = prepared.select_refined(&camera, &params);
        assert_eq!(selection, trace.selection);
        let unrefined = prepared.select(&camera, &params);
        assert_eq!(Some(&unrefined), trace.output(StageId::CommandOrder));
    }
}
