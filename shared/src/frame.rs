//! The frame, described once (issue 27): which stages a frame runs, in which order, decided from
//! the parameters in **one** place ([`FramePlan::new`]) and read by every backend and every tool.
//!
//! A frame is the slow path (E Fig. 3.2: mesh mips and the billboard bake, once per scene and
//! parameters), then per frame a **selection** and the **draw** (E§4.3, §4.4):
//! - the flat selection of the thesis over grid batches (`select`, E§3.5), when `hierarchy` is
//!   `grid`;
//! - or a **cut** of a tree hierarchy (`hier_select`, G§3 Fig. 4, C§4.5) followed by its two
//!   list stages, `coalesce` (merged runs) and `command_order` (E§7 distance-sorted commands),
//!   each with its mode (`off` / `node` make them the identity);
//! - then `refine` (per-tree culling of the commands, beyond the thesis) when `tree_cull` is not
//!   `none`;
//! - then `draw`.
//!
//! The baselines of E§5 (`cull`, then `draw` or `primitive`) are other pipelines over the same
//! scene ([`StageId::Cull`], [`StageId::Primitive`]); they read no selection.
//!
//! [`StageId`] names every stage both twins implement: `reference/src/<name>.rs`,
//! `gpu/src/<name>.rs` and `gpu/src/shaders/<name>.wgsl` share its [`StageId::name`]. The stage
//! table of the harness (`harness/src/stages.rs`) gives each its backend and parity entry, and a
//! test walks it.
//!
//! Rejected design: each consumer asking `params.hierarchy != grid` itself (six places before
//! issue 27, three of which then forgot the cut's coalesce or order, or the hierarchy).

use crate::{Coalesce, CommandOrder, Hierarchy, Occlusion, ParamError, Params, TreeCull};

/// The parts of a frame a stage belongs to (module docs): two chains that meet at the draw, and
/// the baselines' own stages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FramePart {
    /// The slow path: the textures the draw samples (`bake`, `mips`).
    Textures,
    /// The per-frame selection: the stages of [`FramePlan::selection_stages`].
    Selection,
    /// The draw, which reads both chains.
    Draw,
    /// Occlusion culling around the draw (issue 31, `crate::occlusion`): the early split, the
    /// depth pyramid of the early pass and the late test; off unless `params.occlusion` says.
    Occlusion,
    /// The E§5 baselines' stages, in no frame of ours.
    Baseline,
}

/// Declares [`StageId`] with its names, parts and [`StageId::ALL`].
macro_rules! stages {
    ($( $(#[$doc:meta])* $variant:ident => $name:literal, $part:ident, )+) => {
        /// Every stage that has a CPU twin and a GPU twin (module docs), in pipeline order: slow
        /// path, selection, draw, then the baselines' stages.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum StageId {
            $( $(#[$doc])* $variant, )+
        }

        impl StageId {
            /// Every stage, in pipeline order.
            pub const ALL: [StageId; [$($name),+].len()] = [$(StageId::$variant),+];

            /// The stage's file name (`reference/src/<name>.rs`, `gpu/src/shaders/<name>.wgsl`),
            /// and its name on the command line (`--stage-from-cpu`).
            pub fn name(self) -> &'static str {
                match self {
                    $( StageId::$variant => $name, )+
                }
            }
            /// Which part of a frame the stage belongs to.
            pub fn part(self) -> FramePart {
                match self {
                    $( StageId::$variant => FramePart::$part, )+
                }
            }
        }
    };
}

stages! {
    /// Billboard bake (E Alg. 3.1, §4.1): level 0 of every layer.
    Bake => "bake", Textures,
    /// Alpha-aware mip chains (E Alg. 3.2, §4.1) of the mesh textures and the billboards.
    Mips => "mips", Textures,
    /// The far level's octant impostors (issue 32, G§2.2-2.4): every hierarchy node's cells.
    FarBake => "far_bake", Textures,
    /// Flat per-batch selection (E§3.5, §4.3).
    Select => "select", Selection,
    /// The hierarchy's cut (G§3 Fig. 4, C§4.5): one command per emitted node and LOD.
    HierSelect => "hier_select", Selection,
    /// Runs of the cut's commands merged (G§3's contiguous octant ranges).
    Coalesce => "coalesce", Selection,
    /// The cut's commands sorted front to back (E§7).
    CommandOrder => "command_order", Selection,
    /// Per-tree culling of the selected commands (beyond the thesis).
    Refine => "refine", Selection,
    /// Occlusion culling's depth pyramid of the early pass (issue 31, beyond the seeds).
    Pyramid => "pyramid", Occlusion,
    /// Occlusion culling's early split and late test of the commands (issue 31).
    Occlude => "occlude", Occlusion,
    /// Draw execution (E§4.4).
    Draw => "draw", Draw,
    /// The baselines' per-tree culling (E§5).
    Cull => "cull", Baseline,
    /// The Primitive baseline's ray-cast quads (E§5).
    Primitive => "primitive", Baseline,
}

impl StageId {
    /// The stage named `name` ([`StageId::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Every stage name, comma-separated, for messages.
    pub fn names() -> String {
        Self::ALL.map(StageId::name).join(", ")
    }
}

/// How a frame selects (module docs): decided once, by [`FramePlan::new`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SelectionPlan {
    /// `select` over the grid batches.
    Flat,
    /// `hier_select` over the hierarchy built for `hierarchy`, then `coalesce` and
    /// `command_order` with their modes.
    Cut {
        /// The grouping (never [`Hierarchy::Grid`]).
        hierarchy: Hierarchy,
        /// The coalesce stage's mode.
        coalesce: Coalesce,
        /// The command-order stage's mode.
        order: CommandOrder,
    },
}

/// The stages one frame runs (module docs), decided from valid parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FramePlan {
    /// Flat selection or a cut.
    pub selection: SelectionPlan,
    /// The `refine` stage's mode; `None` when it does not run.
    pub refine: Option<TreeCull>,
    /// Occlusion culling (issue 31): `off`, or the draw split in two around `pyramid` and
    /// `occlude` (`crate::occlusion`).
    pub occlusion: Occlusion,
    /// The far level (issue 32, `crate::far`) under `lod_levels = 3`: `far_bake` runs and the
    /// cut selects far nodes.
    pub far: Option<crate::FarLod>,
}

impl FramePlan {
    /// The plan of `params` (the one place the selection strategy is decided). Fails on an
    /// unknown mode id.
    pub fn new(params: &Params) -> Result<Self, ParamError> {
        // Only the cut decides far nodes: a far level selects the grid batches by the cut of
        // their depth-1 hierarchy.
        let far = if params.lod_levels >= 3 {
            Some(params.far_level()?)
        } else {
            None
        };
        let selection = match params.hierarchy_mode()? {
            Hierarchy::Grid if far.is_none() => SelectionPlan::Flat,
            hierarchy => SelectionPlan::Cut {
                hierarchy,
                coalesce: params.coalescing()?,
                order: params.command_ordering()?,
            },
        };
        let refine = match params.tree_culling()? {
            TreeCull::None => None,
            mode => Some(mode),
        };
        let occlusion = params.occlusion_mode()?;
        Ok(Self {
            selection,
            refine,
            occlusion,
            far,
        })
    }

    /// Whether the frame selects by a hierarchy's cut.
    pub fn is_cut(&self) -> bool {
        matches!(self.selection, SelectionPlan::Cut { .. })
    }

    /// The selection stages of the frame, in order: `[select]` or
    /// `[hier_select, coalesce, command_order]`, then `refine` when it runs.
    pub fn selection_stages(&self) -> Vec<StageId> {
        let mut out = match self.selection {
            SelectionPlan::Flat => vec![StageId::Select],
            SelectionPlan::Cut { .. } => {
                vec![
                    StageId::HierSelect,
                    StageId::Coalesce,
                    StageId::CommandOrder,
                ]
            }
        };
        if self.refine.is_some() {
            out.push(StageId::Refine);
        }
        out
    }

    /// Every stage of the frame, in order: the slow path (`bake`, `mips`, and `far_bake` under a
    /// far level), the selection stages,
    /// under occlusion culling `pyramid` and `occlude` (which run interleaved with the draw's two
    /// passes: early split, early draw, pyramid, late test, late draw), then `draw`.
    pub fn stages(&self) -> Vec<StageId> {
        let mut out = vec![StageId::Bake, StageId::Mips];
        if self.far.is_some() {
            out.push(StageId::FarBake);
        }
        out.extend(self.selection_stages());
        if self.occlusion != Occlusion::Off {
            out.extend([StageId::Pyramid, StageId::Occlude]);
        }
        out.push(StageId::Draw);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_are_unique() {
        let mut names: Vec<_> = StageId::ALL.iter().map(|s| s.name()).collect();
        for s in StageId::ALL {
            assert_eq!(StageId::from_name(s.name()), Some(s));
        }
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), StageId::ALL.len());
    }

    #[test]
    fn the_plan_follows_the_parameters() {
        let flat = FramePlan::new(&Params::default()).unwrap();
        assert_eq!(
            flat.stages(),
            [StageId::Bake, StageId::Mips, StageId::Select, StageId::Draw]
        );
        // A far level (issue 32) bakes its cells after the mips, over a cut.
        let far = FramePlan::new(&Params {
            lod_levels: 3,
            ..Params::default()
        })
        .unwrap();
        assert_eq!(
            far.stages()[..4],
            [
                StageId::Bake,
                StageId::Mips,
                StageId::FarBake,
                StageId::HierSelect
            ]
        );
        let p = Params {
            hierarchy: Hierarchy::Octree as u32,
            tree_cull: TreeCull::Lod0 as u32,
            ..Params::default()
        };
        let cut = FramePlan::new(&p).unwrap();
        assert!(cut.is_cut());
        assert_eq!(
            cut.selection_stages(),
            [
                StageId::HierSelect,
                StageId::Coalesce,
                StageId::CommandOrder,
                StageId::Refine
            ]
        );
        let bad = Params {
            hierarchy: 99,
            ..Params::default()
        };
        assert!(FramePlan::new(&bad).is_err());
        let occluded = FramePlan::new(&Params {
            occlusion: Occlusion::TwoPhase as u32,
            ..Params::default()
        })
        .unwrap();
        assert_eq!(occluded.occlusion, Occlusion::TwoPhase);
        assert_eq!(
            occluded.stages(),
            [
                StageId::Bake,
                StageId::Mips,
                StageId::Select,
                StageId::Pyramid,
                StageId::Occlude,
                StageId::Draw
            ]
        );
    }
}
