//! Which stages of a GPU frame the reference computes instead (`forestlod render
//! --stage-from-cpu LIST`; vello's `force_gpu_from` is the model): naming a stage means "the
//! reference computes this stage and every stage of the frame's plan before it; the GPU runs the
//! rest", so a difference that disappears when a stage moves to the CPU is that stage's, or an
//! earlier one's. The frame's stages come in two chains that meet only at the draw:
//! - the textures: `bake` (the billboards' level 0), then `mips` (every chain, the mesh
//!   textures' and the billboards');
//! - the selection: the stages of `FramePlan::selection_stages` (`select`, or `hier_select`,
//!   `coalesce`, `command_order`), then `refine` when the plan has it.
//!
//! A named selection stage that is not in the frame's plan stands for the last plan stage
//! before it in `StageId::ALL` order (`coalesce` on a flat frame is `select`), so one list works
//! for every plan (and `select` in a cut's place is its first stage, `hier_select`). `draw` always runs on the GPU: it is the stage judged. Two names keep their
//! meaning from before the stage table: `textures` is `mips` (every texture from the reference),
//! and `select` is the whole selection, `refine` included (the reference's commands and
//! indirection uploaded as they are drawn).

use forestlod_shared::{FramePart, FramePlan, StageId};

/// The stages a GPU frame takes from the reference (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StagesFromCpu {
    /// The last texture stage the reference computes: `None` (the GPU bakes and mipmaps),
    /// [`StageId::Bake`] (the reference's billboard level 0, the GPU's mips on it and on the mesh
    /// textures) or [`StageId::Mips`] (every chain the reference's).
    pub textures: Option<StageId>,
    /// The last selection stage the reference computes (module docs for a stage not in the
    /// plan); `None`: every selection stage on the GPU.
    pub selection: Option<StageId>,
}

/// The names [`StagesFromCpu::parse`] accepts besides the stages': `none` and the two that keep
/// their meaning from before the stage table (module docs).
const ALIASES: &[(&str, &str)] = &[
    ("none", "nothing"),
    ("textures", "= mips"),
    ("select", "the whole selection, refine included"),
];

impl StagesFromCpu {
    /// Every stage on the GPU.
    pub const NONE: Self = Self {
        textures: None,
        selection: None,
    };
    /// Only the draw stage on the GPU: it alone is judged.
    pub const ALL: Self = Self {
        textures: Some(StageId::Mips),
        selection: Some(StageId::Refine),
    };
    /// The reference's textures, the GPU's selection.
    pub const TEXTURES: Self = Self {
        textures: Some(StageId::Mips),
        selection: None,
    };
    /// The reference's whole selection (refine included), the GPU's textures.
    pub const SELECTION: Self = Self {
        textures: None,
        selection: Some(StageId::Refine),
    };

    /// Parses a comma-separated list of stage names and aliases (module docs); empty or `none`
    /// is nothing. Several names of one chain keep the latest stage.
    pub fn parse(list: &str) -> Result<Self, String> {
        let mut out = Self::NONE;
        let later = |a: Option<StageId>, b: StageId| match a {
            Some(a) if index(a) >= index(b) => Some(a),
            _ => Some(b),
        };
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "none" => {}
                "textures" => out.textures = later(out.textures, StageId::Mips),
                "select" => out.selection = later(out.selection, StageId::Refine),
                other => match StageId::from_name(other) {
                    Some(s) if s.part() == FramePart::Textures => {
                        out.textures = later(out.textures, s)
                    }
                    Some(s) if is_selection_stage(s) => out.selection = later(out.selection, s),
                    Some(s) => {
                        return Err(format!(
                            "stage {:?} in --stage-from-cpu {list:?} cannot come from the reference: {}",
                            s.name(),
                            if s == StageId::Draw {
                                "the draw is the stage a GPU frame judges, it always runs on the GPU"
                            } else if s.part() == FramePart::Occlusion {
                                "occlusion culling runs between the draw's two passes, on the GPU"
                            } else {
                                "it belongs to a baseline's frame, not to ours"
                            }
                        ));
                    }
                    None => {
                        return Err(format!(
                            "unknown stage {other:?} in --stage-from-cpu {list:?}: expected a comma-separated list of {}",
                            Self::expected()
                        ));
                    }
                },
            }
        }
        Ok(out)
    }

    /// What [`StagesFromCpu::parse`] accepts, for messages and `--help`: every stage that can
    /// come from the reference, then the aliases.
    pub fn expected() -> String {
        let stages = StageId::ALL
            .iter()
            .filter(|s| matches!(s.part(), FramePart::Textures | FramePart::Selection))
            .map(|s| s.name().to_string());
        let aliases = ALIASES.iter().map(|(n, m)| format!("{n} ({m})"));
        stages.chain(aliases).collect::<Vec<_>>().join(", ")
    }

    /// The list form [`StagesFromCpu::parse`] reads back to `self`, `none` when empty.
    pub fn name(self) -> String {
        let parts: Vec<&str> = [self.textures, self.selection]
            .into_iter()
            .flatten()
            .map(StageId::name)
            .collect();
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(",")
        }
    }

    /// Whether the reference computes stage `stage` of a frame planned as `plan` (module docs):
    /// `stage` is at or before the named stage of its chain.
    pub fn computes(self, plan: &FramePlan, stage: StageId) -> bool {
        let upto = if stage.part() == FramePart::Textures {
            self.textures
        } else {
            self.selection.map(|s| resolve(plan, s))
        };
        upto.is_some_and(|u| index(stage) <= index(u))
    }

    /// The last stage of `plan`'s selection the reference computes, if any (module docs).
    pub fn last_selection_stage(self, plan: &FramePlan) -> Option<StageId> {
        self.selection.map(|s| resolve(plan, s))
    }
}

/// Whether `s` is one of the selection chain's stages (module docs).
fn is_selection_stage(s: StageId) -> bool {
    s.part() == FramePart::Selection
}

/// `s`'s place in [`StageId::ALL`].
fn index(s: StageId) -> usize {
    StageId::ALL
        .iter()
        .position(|&t| t == s)
        .expect("StageId::ALL holds every stage")
}

/// The last stage of `plan`'s selection chain at or before `s` (module docs); `select` on a cut
/// (before every cut stage) is the cut's first stage, `hier_select`.
fn resolve(plan: &FramePlan, s: StageId) -> StageId {
    let stages = plan.selection_stages();
    stages
        .iter()
        .copied()
        .rfind(|&t| index(t) <= index(s))
        .unwrap_or(stages[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use forestlod_shared::{CommandOrder, Hierarchy, Params, TreeCull};

    fn plan(hierarchy: Option<Hierarchy>, tree_cull: TreeCull) -> FramePlan {
        let mut p = Params::default();
        if let Some(h) = hierarchy {
            p.hierarchy = h as u32;
        }
        p.command_order = CommandOrder::FrontToBack as u32;
        p.tree_cull = tree_cull as u32;
        FramePlan::new(&p).unwrap()
    }

    #[test]
    fn parse_reads_back_its_name_and_keeps_the_old_meanings() {
        for list in [
            "none",
            "textures",
            "select",
            "select,textures",
            "bake",
            "coalesce,mips",
        ] {
            let s = StagesFromCpu::parse(list).unwrap();
            assert_eq!(StagesFromCpu::parse(&s.name()).unwrap(), s, "{list}");
        }
        assert_eq!(StagesFromCpu::parse("").unwrap(), StagesFromCpu::NONE);
        assert_eq!(
            StagesFromCpu::parse("select,textures").unwrap(),
            StagesFromCpu::ALL
        );
        assert_eq!(
            StagesFromCpu::parse("select").unwrap(),
            StagesFromCpu::SELECTION
        );
        // The later stage of a chain wins, whatever the order of the list.
        assert_eq!(
            StagesFromCpu::parse("mips,bake").unwrap().textures,
            Some(StageId::Mips)
        );
        assert_eq!(
            StagesFromCpu::parse("refine,hier_select")
                .unwrap()
                .selection,
            Some(StageId::Refine)
        );
    }

    #[test]
    fn parse_refuses_the_draw_the_baselines_and_unknown_names() {
        for bad in ["draw", "cull", "primitive", "selectt", "select;textures"] {
            let e = StagesFromCpu::parse(bad).unwrap_err();
            assert!(e.contains("--stage-from-cpu"), "{bad}: {e}");
        }
        let e = StagesFromCpu::parse("nope").unwrap_err();
        for name in [
            "bake",
            "mips",
            "select",
            "hier_select",
            "coalesce",
            "command_order",
            "refine",
        ] {
            assert!(e.contains(name), "{e}");
        }
    }

    #[test]
    fn a_stage_covers_every_plan_stage_before_it() {
        let cut = plan(Some(Hierarchy::Octree), TreeCull::Lod0);
        let s = StagesFromCpu::parse("coalesce").unwrap();
        assert!(s.computes(&cut, StageId::HierSelect));
        assert!(s.computes(&cut, StageId::Coalesce));
        assert!(!s.computes(&cut, StageId::CommandOrder));
        assert!(!s.computes(&cut, StageId::Refine));
        assert!(!s.computes(&cut, StageId::Mips));
        // On a flat frame a cut stage stands for the last plan stage before it: select.
        let flat = plan(None, TreeCull::Lod0);
        assert_eq!(s.last_selection_stage(&flat), Some(StageId::Select));
        assert!(s.computes(&flat, StageId::Select));
        assert!(!s.computes(&flat, StageId::Refine));
        // `select` is the whole selection, refine included, on both.
        let all = StagesFromCpu::parse("select").unwrap();
        for p in [&cut, &flat] {
            assert!(all.computes(p, StageId::Refine));
        }
        // Without refine in the plan, `refine` is the plan's last selection stage.
        let no_refine = plan(Some(Hierarchy::Octree), TreeCull::None);
        assert_eq!(
            all.last_selection_stage(&no_refine),
            Some(StageId::CommandOrder)
        );
        let bake = StagesFromCpu::parse("bake").unwrap();
        assert!(bake.computes(&cut, StageId::Bake) && !bake.computes(&cut, StageId::Mips));
    }
}
