//! The per-frame view constants every selection-like stage reads ([`ViewUniform`]), and the
//! per-sphere selection rule on them ([`ViewUniform::decide`], E§3.5, §4.3; SPEC §5.4) with its
//! result ([`Decision`]) and the `u32` codes the GPU writes for it (`DECISION_*`).
//!
//! ## Contract
//! - [`ViewUniform::new`] is the one place the view constants are derived from a camera and
//!   parameters: frustum planes ([`Camera::frustum`]), eye, unit forward
//!   ([`Camera::basis`]), the fade band `[fade_start, fade_end] = [Params::fade_start(),
//!   lod1_transition]`, draw distance and LOD levels. The reference's `select` (as
//!   `reference::select::SelectUniform`), `refine`, `draw` and baselines use it as is; the GPU's
//!   `select`, `cull` and `refine` uniforms embed it as their first member, and `common.wgsl`
//!   mirrors it once (`struct ViewUniform`; `gpu/tests/layout.rs` checks every offset).
//! - [`ViewUniform::decide`]: the same rule for a batch's and for a lone tree's bounding sphere:
//!   culled beyond the draw distance (the interval's near end, `lo > draw_distance`), else culled
//!   outside one frustum plane, else drawn with the LODs the interval needs ([`lod_needs`]).
//!   Twin of `decide_sphere` in `common.wgsl`.
//! - [`Decision::code`] / [`Decision::from_code`]: the `DECISION_*` encoding `select.wgsl`
//!   writes per batch (low two bits the kind, then one bit per LOD); mirrored in `common.wgsl`.

use bytemuck::{Pod, Zeroable};

use crate::{
    Camera, FrustumPlanes, LodMetric, LodNeeds, MeshMeta, Params, band_ratio, lod_needs, mesh_size,
    metric_factor, view_interval,
};

/// Decision code (low two bits): culled beyond the draw distance.
pub const DECISION_CULLED_DISTANCE: u32 = 0;
/// Decision code: culled outside the frustum.
pub const DECISION_CULLED_FRUSTUM: u32 = 1;
/// Decision code: drawn, with [`DECISION_LOD0`] / [`DECISION_LOD1`] bits.
pub const DECISION_DRAW: u32 = 2;
/// Mask of the decision kind.
pub const DECISION_KIND_MASK: u32 = 3;
/// Decision bit: LOD0 needed.
pub const DECISION_LOD0: u32 = 4;
/// Decision bit: LOD1 needed.
pub const DECISION_LOD1: u32 = 8;

/// Why a batch (or a tree, in the per-tree oracle) was not drawn, or which LODs it needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Decision {
    /// Wholly beyond the draw distance.
    CulledDistance,
    /// Wholly outside the view frustum.
    CulledFrustum,
    /// Drawn with these LODs.
    Draw(LodNeeds),
}

impl Decision {
    /// The LODs drawn (none when culled).
    pub fn needs(self) -> LodNeeds {
        match self {
            Decision::Draw(n) => n,
            _ => LodNeeds::default(),
        }
    }

    /// The `DECISION_*` code of this decision (what `select.wgsl` writes per batch).
    pub fn code(self) -> u32 {
        match self {
            Decision::CulledDistance => DECISION_CULLED_DISTANCE,
            Decision::CulledFrustum => DECISION_CULLED_FRUSTUM,
            Decision::Draw(n) => {
                DECISION_DRAW
                    | if n.lod0 { DECISION_LOD0 } else { 0 }
                    | if n.lod1 { DECISION_LOD1 } else { 0 }
            }
        }
    }

    /// The decision of a `DECISION_*` code (a kind of 3, which no shader writes, decodes as a
    /// frustum cull).
    pub fn from_code(code: u32) -> Self {
        match code & DECISION_KIND_MASK {
            DECISION_CULLED_DISTANCE => Decision::CulledDistance,
            DECISION_DRAW => Decision::Draw(LodNeeds {
                lod0: code & DECISION_LOD0 != 0,
                lod1: code & DECISION_LOD1 != 0,
            }),
            _ => Decision::CulledFrustum,
        }
    }
}

/// Per-frame view constants of selection (module docs), uniform-compatible: each `vec3` is
/// followed by an `f32`, padded to a multiple of 16 bytes. Keep in sync with `struct ViewUniform`
/// in `common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ViewUniform {
    /// Frustum planes relative to the eye ([`Camera::frustum`]).
    pub frustum: FrustumPlanes,
    /// Eye position.
    pub eye: [f32; 3],
    /// Start of the fade band, [`Params::fade_start`].
    pub fade_start: f32,
    /// Unit view direction (`Camera::basis().forward`).
    pub forward: [f32; 3],
    /// End of the fade band, `lod1_transition`.
    pub fade_end: f32,
    /// Draw distance.
    pub draw_distance: f32,
    /// LOD levels (1 or 2).
    pub lod_levels: u32,
    /// The [`crate::LodMetric`] id (an unknown id decides as `distance`).
    pub metric: u32,
    /// The frame's transition depth per unit of mesh size ([`crate::metric_factor`]).
    pub metric_factor: f32,
    /// The scaled bands' start over end ([`crate::band_ratio`]).
    pub band_ratio: f32,
    /// The [`crate::SubsetMode`] id (issue 29, `shared/src/subset.rs`).
    pub subset_mode: u32,
    /// View depth past which batches draw a subset, `Params::subset_distance`.
    pub subset_distance: f32,
    /// The least subset density, `Params::subset_min`.
    pub subset_min: f32,
}
const _: () = assert!(size_of::<ViewUniform>() == 160);

impl ViewUniform {
    /// The view constants of a validated camera and validated parameters.
    pub fn new(camera: &Camera, params: &Params) -> Self {
        Self {
            frustum: camera.frustum(),
            eye: camera.eye,
            fade_start: params.fade_start(),
            forward: camera.basis().forward.to_array(),
            fade_end: params.lod1_transition,
            draw_distance: params.draw_distance,
            lod_levels: params.lod_levels,
            metric: params.lod_metric,
            metric_factor: metric_factor(camera, params),
            band_ratio: band_ratio(params),
            subset_mode: params.subset_mode,
            subset_distance: params.subset_distance,
            subset_min: params.subset_min,
        }
    }

    /// The scaled metric of these constants, or `None` for `distance` (and an unknown id).
    pub fn scaled_metric(&self) -> Option<LodMetric> {
        LodMetric::from_id(self.metric).filter(|m| m.is_scaled())
    }

    /// The LOD band `[start, end]` of a tree of `mesh` at unit scale (`shared/src/metric.rs`): the
    /// frame's `[fade_start, fade_end]` under `distance`, else `end = size · metric_factor`
    /// (the size the metric reads, [`crate::mesh_size`]), `start = end · band_ratio`.
    pub fn mesh_band(&self, mesh: &MeshMeta) -> [f32; 2] {
        let Some(metric) = self.scaled_metric() else {
            return [self.fade_start, self.fade_end];
        };
        let end = mesh_size(metric, mesh) * self.metric_factor;
        [end * self.band_ratio, end]
    }

    /// The band of a group (a batch, a node, or one tree: `scale = [s, s]`) whose trees' scales
    /// lie in `scale = [min, max]`, from their mesh's band: `[min · start, max · end]`, which
    /// contains every tree's own band; the mesh band itself under `distance`.
    pub fn group_band(&self, mesh_band: [f32; 2], scale: [f32; 2]) -> [f32; 2] {
        if self.scaled_metric().is_none() {
            return mesh_band;
        }
        [scale[0] * mesh_band[0], scale[1] * mesh_band[1]]
    }

    /// How many of a group's `len` trees its commands draw when its nearest view depth is `lo`
    /// ([`crate::subset_count`] on these constants).
    pub fn subset_count(&self, len: u32, lo: f32) -> u32 {
        crate::subset_count(
            len,
            lo,
            self.subset_mode,
            self.subset_distance,
            self.subset_min,
        )
    }

    /// These view constants with the band `[start, end]` in place of the frame's: what the
    /// selection rule ([`ViewUniform::decide`], [`crate::decide_node`]) of a group decides on.
    pub fn with_band(&self, band: [f32; 2]) -> Self {
        Self {
            fade_start: band[0],
            fade_end: band[1],
            ..*self
        }
    }

    /// The decision for one bounding sphere: the same rule for a batch and for a lone tree
    /// (module docs).
    pub fn decide(&self, center: [f32; 3], radius: f32) -> Decision {
        let i = view_interval(center, radius, self.eye, self.forward);
        if i.lo > self.draw_distance {
            Decision::CulledDistance
        } else if !self.frustum.sphere_visible(center, radius, self.eye) {
            Decision::CulledFrustum
        } else {
            Decision::Draw(lod_needs(
                i.lo,
                i.hi,
                self.fade_start,
                self.fade_end,
                self.lod_levels,
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decision_codes_round_trip() {
        for d in [
            Decision::CulledDistance,
            Decision::CulledFrustum,
            Decision::Draw(LodNeeds {
                lod0: true,
                lod1: false,
            }),
            Decision::Draw(LodNeeds {
                lod0: false,
                lod1: true,
            }),
            Decision::Draw(LodNeeds {
                lod0: true,
                lod1: true,
            }),
            Decision::Draw(LodNeeds {
                lod0: false,
                lod1: false,
            }),
        ] {
            assert_eq!(Decision::from_code(d.code()), d);
        }
        assert_eq!(DECISION_DRAW | DECISION_LOD0 | DECISION_LOD1, 14);
    }

    #[test]
    fn fade_band_comes_from_params() {
        let p = Params::default();
        let c = Camera::look_at([0.0, -10.0, 2.0], [0.0, 0.0, 0.0], 60.0, 64, 48);
        let u = ViewUniform::new(&c, &p);
        assert_eq!(u.fade_start, p.lod1_transition - p.fade_width);
        assert_eq!(u.fade_end, p.lod1_transition);
    }
}
