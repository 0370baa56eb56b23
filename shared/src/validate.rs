//! The validated accessors of [`Params`] and [`Params::validate`]: every check is the parameter
//! table's ([`crate::registry`]), so the words of a refusal are the table's. Kept apart from
//! `params.rs` so that the table may import the parameters and their limits without the
//! parameters importing the table back.

use crate::params::{
    AngleIndexMode, Coalesce, CommandOrder, Hierarchy, MipMode, ParamError, Params, TreeCull,
};
use crate::registry::{PARAMS, param};

/// The error the parameter table gives for field `name` of `p` (its reason, the stored value).
fn rejected(name: &str, p: &Params) -> ParamError {
    let spec = param(name).expect("every Params field is in the table");
    spec.check(p)
        .expect_err("only called for a value the typed accessor refused")
}

impl Params {
    /// Fade mode, validated.
    pub fn fade(&self) -> Result<crate::FadeMode, ParamError> {
        crate::FadeMode::from_id(self.fade_mode).ok_or_else(|| rejected("fade_mode", self))
    }
    /// Mip mode, validated.
    pub fn mips(&self) -> Result<MipMode, ParamError> {
        MipMode::from_id(self.mip_mode).ok_or_else(|| rejected("mip_mode", self))
    }
    /// Angle index mode, validated.
    pub fn angle_mode(&self) -> Result<AngleIndexMode, ParamError> {
        AngleIndexMode::from_id(self.angle_index_mode)
            .ok_or_else(|| rejected("angle_index_mode", self))
    }

    /// Per-tree culling mode, validated.
    pub fn tree_culling(&self) -> Result<TreeCull, ParamError> {
        TreeCull::from_id(self.tree_cull).ok_or_else(|| rejected("tree_cull", self))
    }

    /// Tree grouping, validated.
    pub fn hierarchy_mode(&self) -> Result<Hierarchy, ParamError> {
        Hierarchy::from_id(self.hierarchy).ok_or_else(|| rejected("hierarchy", self))
    }

    /// Command coalescing of the hierarchical cut, validated.
    pub fn coalescing(&self) -> Result<Coalesce, ParamError> {
        Coalesce::from_id(self.coalesce).ok_or_else(|| rejected("coalesce", self))
    }

    /// Command order of the hierarchical cut, validated.
    pub fn command_ordering(&self) -> Result<CommandOrder, ParamError> {
        CommandOrder::from_id(self.command_order).ok_or_else(|| rejected("command_order", self))
    }

    /// The LOD metric (issue 29), validated.
    pub fn lod_metric_mode(&self) -> Result<crate::LodMetric, ParamError> {
        crate::LodMetric::from_id(self.lod_metric).ok_or_else(|| rejected("lod_metric", self))
    }

    /// The far-field subset mode (issue 29), validated.
    pub fn subset(&self) -> Result<crate::SubsetMode, ParamError> {
        crate::SubsetMode::from_id(self.subset_mode).ok_or_else(|| rejected("subset_mode", self))
    }

    /// Tree shading (issue 30), validated.
    pub fn shading_mode(&self) -> Result<crate::Shading, ParamError> {
        crate::Shading::from_id(self.shading).ok_or_else(|| rejected("shading", self))
    }

    /// Where the dithered fades' threshold comes from (issue 30), validated.
    pub fn dither(&self) -> Result<crate::DitherSpace, ParamError> {
        crate::DitherSpace::from_id(self.dither_space).ok_or_else(|| rejected("dither_space", self))
    }

    /// What a fade's progress is taken from (issue 30), validated.
    pub fn granularity(&self) -> Result<crate::FadeGranularity, ParamError> {
        crate::FadeGranularity::from_id(self.fade_granularity)
            .ok_or_else(|| rejected("fade_granularity", self))
    }

    /// The occlusion culling mode (issue 31), validated.
    pub fn occlusion_mode(&self) -> Result<crate::Occlusion, ParamError> {
        crate::Occlusion::from_id(self.occlusion).ok_or_else(|| rejected("occlusion", self))
    }

    /// The occlusion pass order (issue 31), validated.
    pub fn occlusion_ordering(&self) -> Result<crate::OcclusionOrder, ParamError> {
        crate::OcclusionOrder::from_id(self.occlusion_order)
            .ok_or_else(|| rejected("occlusion_order", self))
    }

    /// The billboard views (issue 32), validated.
    pub fn views(&self) -> Result<crate::ViewSphere, ParamError> {
        crate::ViewSphere::from_id(self.billboard_views)
            .ok_or_else(|| rejected("billboard_views", self))
    }

    /// The far level's primitive (issue 32), validated.
    pub fn far_level(&self) -> Result<crate::FarLod, ParamError> {
        crate::FarLod::from_id(self.far_lod).ok_or_else(|| rejected("far_lod", self))
    }

    /// The far level's parent rule (issue 32), validated.
    pub fn far_parent_rule(&self) -> Result<crate::ParentRule, ParamError> {
        crate::ParentRule::from_id(self.parent_rule).ok_or_else(|| rejected("parent_rule", self))
    }

    /// The azimuth view rule (issue 30), validated.
    pub fn azimuth(&self) -> Result<crate::AzimuthMode, ParamError> {
        crate::AzimuthMode::from_id(self.azimuth_mode).ok_or_else(|| rejected("azimuth_mode", self))
    }

    /// Checks every field against the parameter table ([`crate::registry::PARAMS`], in its
    /// order), returning the first impossible one. Nothing downstream runs on invalid parameters,
    /// so no stage needs to guard against NaN or zero divisors (SPEC §7).
    pub fn validate(&self) -> Result<(), ParamError> {
        PARAMS.iter().try_for_each(|spec| spec.check(self))?;
        // Far-field subsets (issue 29) rank a tree by its place in its grid batch's range: a
        // hierarchy's node ranges and refine's compacted ranges carry no such rank.
        let subset = self.subset()?;
        if subset != crate::SubsetMode::Off
            && (self.hierarchy_mode()? != Hierarchy::Grid || self.tree_culling()? != TreeCull::None)
        {
            return Err(ParamError {
                field: "subset_mode",
                value: subset.name().to_string(),
                reason: "far-field subsets need hierarchy = grid and tree_cull = none (a subset \
                         ranks trees within a grid batch's range)"
                    .into(),
            });
        }
        // Occlusion culling (issue 31) rewrites instance lists, which then carry no subset rank.
        let occlusion = self.occlusion_mode()?;
        if subset != crate::SubsetMode::Off && occlusion != crate::Occlusion::Off {
            return Err(ParamError {
                field: "occlusion",
                value: occlusion.name().to_string(),
                reason: "occlusion culling needs subset_mode = off (it compacts the instance \
                         lists, which then carry no subset rank)"
                    .into(),
            });
        }
        // The chain mesh -> billboard -> far is conservative per tree only if the far level starts
        // where billboards have fully replaced meshes (issue 32, `shared/src/far.rs`).
        if self.lod_levels >= 3
            && (self.far_start.is_nan() || self.far_start < self.lod1_transition)
        {
            return Err(ParamError {
                field: "far_start",
                value: self.far_start.to_string(),
                reason: format!(
                    "under lod_levels = 3 the far level must start at or beyond lod1_transition = {} \
                     (a node goes far only where every tree would be a billboard)",
                    self.lod1_transition
                )
                .into(),
            });
        }
        // The far level's commands (issue 32) index cells, not trees: the stages that rewrite
        // instance lists (refine, occlusion) and the grid's subsets (which rank trees within a
        // flat selection's batches) do not apply to them.
        if self.lod_levels >= 3 {
            let conflict = if self.tree_culling()? != TreeCull::None {
                Some(("tree_cull", self.tree_culling()?.name()))
            } else if occlusion != crate::Occlusion::Off {
                Some(("occlusion", occlusion.name()))
            } else if subset != crate::SubsetMode::Off {
                Some(("subset_mode", subset.name()))
            } else {
                None
            };
            if let Some((field, value)) = conflict {
                return Err(ParamError {
                    field,
                    value: value.to_string(),
                    reason:
                        "lod_levels = 3 (the far level) needs tree_cull = none, occlusion = off \
                             and subset_mode = off (far commands index cells, not trees)"
                            .into(),
                });
            }
        }
        // The point LOD (issue 33) replaces the billboard as the second level; the far level's
        // chain (mesh -> billboard -> far) is not defined over points.
        if self.lod1 == crate::points::Lod1::Points as u32 && self.lod_levels >= 3 {
            return Err(ParamError {
                field: "lod1",
                value: crate::points::Lod1::Points.name().to_string(),
                reason: format!(
                    "lod1 = points needs lod_levels 1 or 2 (got {}): the far level follows \
                     billboards only",
                    self.lod_levels
                )
                .into(),
            });
        }
        // The impostor atlas (issue 33 item 2, `crate::impostor`) is bounded.
        if self.lod_levels >= 3 && self.far_level()? == crate::FarLod::Impostor {
            let texels = self.impostor_tiles as u64 * (self.impostor_pixels as u64).pow(2);
            if texels > crate::impostor::MAX_IMPOSTOR_TEXELS {
                return Err(ParamError {
                    field: "impostor_tiles",
                    value: self.impostor_tiles.to_string(),
                    reason: format!(
                        "the impostor atlas of impostor_tiles x impostor_pixels² = {texels} texels \
                         exceeds {} (64 MiB)",
                        crate::impostor::MAX_IMPOSTOR_TEXELS
                    )
                    .into(),
                });
            }
        }
        // One mesh's `K·J` views must fit the billboard array (issue 30); the scene's `m·K·J` is
        // checked where the mesh count is known (`crate::check_billboard_layers`).
        crate::check_billboard_layers(1, self)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registry::{ParamKind, ParamSpec};

    #[test]
    fn defaults_are_the_thesis_values_and_valid() {
        let p = Params::default();
        assert_eq!(
            (p.grid_size, p.angle_count, p.texture_size, p.lod_levels),
            (500.0, 10, 128, 2)
        );
        assert_eq!((p.lod1_transition, p.fade_width), (1000.0, 250.0));
        assert_eq!(p.mip_level_count(), 8);
        p.validate().unwrap();
    }

    /// Values each table entry must refuse: non-finite and out-of-range floats, integers just
    /// outside their range and non-powers of two, unknown choice codes.
    fn impossible(spec: &ParamSpec) -> Vec<f64> {
        match spec.kind {
            ParamKind::Float { min, max } => vec![
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::from(min) - 1.0,
                f64::from(max) * 2.0,
            ],
            ParamKind::Uint {
                min,
                max,
                power_of_two,
            } => {
                let mut v = vec![f64::from(max) + 1.0, f64::from(max) * 2.0];
                if min > 0 {
                    v.push(f64::from(min - 1));
                }
                if power_of_two {
                    v.extend([3.0, 100.0, f64::from(max - 1)]);
                }
                v
            }
            ParamKind::Choice(choices) => vec![choices().len() as f64, 9.0],
        }
    }

    /// The extremes each entry must accept (SPEC §7 asks the pipeline to run at them).
    fn extremes(spec: &ParamSpec) -> Vec<f64> {
        match spec.kind {
            ParamKind::Float { min, max } => vec![f64::from(min), f64::from(max)],
            ParamKind::Uint { min, max, .. } => vec![f64::from(min), f64::from(max)],
            ParamKind::Choice(choices) => choices().iter().map(|(_, c)| f64::from(*c)).collect(),
        }
    }

    #[test]
    fn each_impossible_value_is_named() {
        let mut checked = 0;
        for spec in &PARAMS {
            for v in impossible(spec) {
                let mut p = Params::default();
                (spec.set)(&mut p, v);
                let e = p.validate().expect_err(spec.name);
                assert_eq!(e.field, spec.name, "{e}");
                assert!(e.to_string().contains(spec.name), "{e}");
                assert_eq!(e.reason, spec.reason(), "{e}");
                checked += 1;
            }
        }
        // The typed accessors refuse with the table's words, and the choice reasons name every
        // code the enum has (generated from its choice list).
        let p = Params {
            fade_mode: 9,
            mip_mode: 3,
            angle_index_mode: 2,
            tree_cull: 3,
            ..Default::default()
        };
        for (field, e) in [
            ("fade_mode", p.fade().unwrap_err()),
            ("mip_mode", p.mips().unwrap_err()),
            ("angle_index_mode", p.angle_mode().unwrap_err()),
            ("tree_cull", p.tree_culling().unwrap_err()),
        ] {
            assert_eq!(e.field, field);
            assert!(e.value.parse::<u32>().is_ok(), "{e}: the stored code");
            let spec = param(field).unwrap();
            assert_eq!(e.reason, spec.reason());
            if let ParamKind::Choice(choices) = spec.kind {
                for (name, code) in choices() {
                    assert!(
                        spec.reason().contains(&format!("{code} ({name})")),
                        "{field}: {name}"
                    );
                }
            }
        }
        assert!(checked >= 40, "only {checked} impossible values tried");
    }

    #[test]
    fn extremes_that_are_allowed() {
        for spec in &PARAMS {
            for v in extremes(spec) {
                let mut p = Params::default();
                (spec.set)(&mut p, v);
                p.validate()
                    .unwrap_or_else(|e| panic!("{} = {v} refused: {e}", spec.name));
            }
        }
        // Degenerate but meaningful: a zero-width fade band, billboards from the eye on, nothing
        // drawn; a single angle and a one-texel billboard.
        for p in [
            Params {
                fade_width: 0.0,
                lod1_transition: 0.0,
                draw_distance: 0.0,
                ..Default::default()
            },
            Params {
                angle_count: 1,
                texture_size: 1,
                ..Default::default()
            },
        ] {
            p.validate().unwrap();
        }
    }
}
