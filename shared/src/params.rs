//! Pipeline parameters (SPEC §2, §5) with the thesis defaults (E§4.5.1, E§5.0.2), their limits
//! and the error of an impossible one. Validation against the parameter table is in
//! `validate.rs` (which imports the table, `registry.rs`, which imports this file: one way).
//!
//! `Params` is `Pod` so that it uploads unchanged as the uniform of the `select` and `draw` shaders.
//! Keep in sync with `struct Params` in `gpu/src/shaders/common.wgsl`.

use bytemuck::{Pod, Zeroable};
use core::fmt;
use std::borrow::Cow;

use crate::modes::modes;

modes! {
    /// How billboard mip levels are built (SPEC §5.2).
    pub enum MipMode {
        /// Alpha-weighted downsampling plus alpha equalization, E Alg. 3.2.
        AlphaAware = 0 => "alpha-aware",
        /// Plain per-channel box filter: the "blit" the thesis rejects (E Fig. 3.5).
        Box = 1 => "box",
        /// Coverage-preserving scaling (Castaño 2010, NVTT).
        CoveragePreserving = 2 => "coverage",
    }
}

modes! {
    /// Which billboard layer index the draw stage uses (SPEC §6).
    pub enum AngleIndexMode {
        /// Nearest baked elevation, clamped, NaN-free: [`crate::angle_index`].
        Nearest = 0 => "nearest",
        /// E Eq. 3.1 as written, then clamped to `0..K-1` (its bins do not centre on the bake angles).
        Eq31Clamped = 1 => "eq31-clamped" ("E Eq. 3.1"),
    }
}

modes! {
    /// Per-tree culling after batch selection (the `refine` stage, `reference/src/refine.rs`): beyond
    /// the thesis. Grouped selection (E§3.5) draws every tree of a batch that touches the view; at 10x
    /// density and 500 m cells that is hundreds of thousands of trees outside the frustum or in the
    /// wrong LOD (`experiments/results/README.md`). `refine` tests each tree of the chosen commands
    /// alone (the per-tree oracle's rule) and keeps the ones that need the command's LOD.
    pub enum TreeCull {
        /// The thesis: no per-tree test; a command draws its whole batch.
        None = 0 => "none",
        /// Refine LOD0 (mesh) commands only: the near trees, few, and the expensive ones.
        Lod0 = 1 => "lod0",
        /// Refine every command: the per-tree oracle's trees exactly, at per-tree culling cost for
        /// the trees of selected batches.
        All = 2 => "all",
    }
}

modes! {
    /// How trees are grouped for selection (issue 13; beyond the thesis's grid). Every mode other
    /// than `grid` builds a [`crate::NodeMeta`] hierarchy (`reference/src/hierarchy.rs`) whose
    /// leaves replace the grid batches and whose cut is evaluated per frame
    /// (`reference/src/hier_select.rs`, `gpu/src/shaders/hier_select.wgsl`). The images are those of
    /// the grid for the same fade mode (the fade is per fragment); only the work changes.
    pub enum Hierarchy {
        /// The thesis (E§3.4, §4.2): grid batches, one sphere each, decided flat.
        Grid = 0 => "grid" ("E§4.2"),
        /// The grid's batches as a depth-1 hierarchy decided on the intersection of the sphere's
        /// and the bounding box's view-depth intervals, culled by either (E§7 "tighter bounding
        /// volumes").
        GridAabb = 1 => "grid-aabb" ("E§7 bounds"),
        /// Celba 2007 §4.5: bottom-up quadtree of at most `nodes_per_node` children per node, AABB
        /// frustum culling; interior nodes never draw as a unit.
        Quadtree = 2 => "quadtree" ("C§4.5"),
        /// Guerrero 2006 §3 (Fig. 4): octree with leaves of at most `nodes_per_node` trees; a node
        /// wholly past the fade band's end (view-depth interval) draws as one LOD1 command unless
        /// partially visible above `max_cull_depth`.
        Octree = 3 => "octree" ("G§3"),
        /// [`Hierarchy::Octree`] with the seed's Euclidean `dist_to(octant.bound) < LOD_dist`
        /// deciding whether to recurse, and units drawn as billboards only: **not conservative**
        /// (view depth <= Euclidean distance, so a unit can hold fragments that need LOD0). Kept to
        /// reproduce the seed; never the default.
        OctreeEuclidean = 4 => "octree-euclidean" ("G§3 as written, not conservative"),
        /// E§7 "density-aware batches": the trees of each mesh clustered by size-constrained
        /// k-means (deterministic seeds from balanced bisection, a bounded number of Lloyd
        /// iterations, clusters above `nodes_per_node` trees split at the median) into batches
        /// of about `nodes_per_node` trees whatever the local density; a depth-1 hierarchy
        /// decided as `grid-aabb`.
        Kmeans = 5 => "kmeans" ("E§7 density-aware batches"),
    }
}

modes! {
    /// Whether the hierarchical cut merges adjacent draw commands (issue 13): a command that
    /// continues its predecessor (same mesh, LOD and fading flag, instance range starting where
    /// the predecessor's ends) joins it, so a run of emitted sibling nodes becomes one command
    /// (`reference/src/coalesce.rs`, `gpu/src/shaders/coalesce.wgsl`). The instances drawn, and
    /// their order, are unchanged, so the images are too; only the number of draws drops. Applies
    /// to the hierarchies only: the thesis's flat grid selection never coalesces.
    pub enum Coalesce {
        /// One command per emitted node and LOD (the seeds' render calls).
        Off = 0 => "off",
        /// Runs of contiguous commands merged (default for hierarchies).
        On = 1 => "on",
    }
}

modes! {
    /// The order of the hierarchical cut's commands (issue 13, E§7 "distance-sorted commands",
    /// front to back): after coalescing, `front-to-back` sorts the commands by
    /// [`crate::command_depth_key`] (the nearest view depth of the nodes a command draws),
    /// ties broken by the command's position in the unsorted list
    /// (`reference/src/command_order.rs`, `gpu/src/shaders/command_order.wgsl`). Near trees first
    /// lets the depth test reject the hidden fragments of the trees behind them before they are
    /// shaded. The same fragments are drawn, so the images are identical except where two
    /// fragments tie in depth (the first drawn wins under `LESS`) and where order-dependent
    /// blending (the `alpha` fade mode) meets. Applies to the hierarchies only.
    pub enum CommandOrder {
        /// The cut's order: depth-first node order, LOD0 before LOD1 (the default).
        Node = 0 => "node",
        /// Sorted by nearest view depth, ascending (E§7).
        FrontToBack = 1 => "front-to-back" ("E§7 distance-sorted"),
    }
}

impl Hierarchy {
    /// Whether this mode builds a node hierarchy (everything but the thesis grid).
    pub fn is_hierarchical(self) -> bool {
        self != Hierarchy::Grid
    }
}

impl TreeCull {
    /// Whether commands of `lod` (`LOD_MESH` or `LOD_BILLBOARD`) are refined.
    pub fn refines(self, lod: u32) -> bool {
        match self {
            TreeCull::None => false,
            TreeCull::Lod0 => lod == crate::LOD_MESH,
            TreeCull::All => true,
        }
    }
}

/// All tunable parameters of the pipeline. Distances in metres.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Params {
    /// Batch grid cell size on X and Y (E§3.4). Thesis optimum 500 m (E Fig. 5.5).
    pub grid_size: f32,
    /// Number of baked elevation angles K (E Alg. 3.1). Thesis default 10.
    pub angle_count: u32,
    /// Billboard texture side r, a power of two (E§4.5.1). Thesis default 128.
    pub texture_size: u32,
    /// Number of LOD levels l: 1 (meshes only) or 2 (meshes, then billboards). Thesis default 2.
    pub lod_levels: u32,
    /// View depth at which LOD1 (billboards) has fully replaced LOD0 (E§4.3). Thesis default 1000 m.
    pub lod1_transition: f32,
    /// Width of the fade band that ends at `lod1_transition` (E Fig. 5.7). Thesis default 250 m.
    pub fade_width: f32,
    /// View depth beyond which no tree is drawn (E§4.3). Not stated in the thesis; our default is
    /// 4000 m, four transition distances, far enough that `synthetic` seen from `medium` fills the view.
    pub draw_distance: f32,
    /// [`crate::FadeMode`] as `u32`. Default `DitherSequential` (G§4), not the thesis's alpha
    /// cross-fade (E§4.4): blending two partially transparent LODs lets up to a quarter of the
    /// background through at mid-band (`(1 - w0)(1 - w1)` = 0.25), a visible pale band in
    /// `forestlod render --fade-mode alpha`; the sequential dither draws every pixel with at least
    /// one opaque LOD. `alpha` stays available as a variant.
    pub fade_mode: u32,
    /// [`MipMode`] as `u32`.
    pub mip_mode: u32,
    /// [`AngleIndexMode`] as `u32`.
    pub angle_index_mode: u32,
    /// Alpha-test reference: fragments with alpha below it are discarded (SPEC §5.5).
    pub alpha_cutoff: f32,
    /// [`TreeCull`] as `u32`. Default `None` (the thesis).
    pub tree_cull: u32,
    /// [`Hierarchy`] as `u32`. Default `Grid` (the thesis).
    pub hierarchy: u32,
    /// Celba's `NodesPerNode` (C§4.5, default 64): the most children of a quadtree node and the
    /// most trees of a quadtree or octree leaf.
    pub nodes_per_node: u32,
    /// Guerrero's `max_cull_depth` (G§3 Fig. 4; G§6 uses 7): octree nodes at a smaller depth
    /// that are only partially visible recurse instead of drawing as one unit.
    pub max_cull_depth: u32,
    /// [`Coalesce`] as `u32`. Default `On`; read by the hierarchical cut only (the grid's flat
    /// `select` is untouched, so the main job's images and counters do not depend on it).
    pub coalesce: u32,
    /// [`CommandOrder`] as `u32`. Default `Node`; read by the hierarchical cut only (after
    /// coalescing), so the grid path and the main job do not depend on it.
    pub command_order: u32,
    /// [`crate::LodMetric`] as `u32` (issue 29). Default `Distance` (the thesis): the others make
    /// the transition depth per tree, from its size on screen (`shared/src/metric.rs`).
    pub lod_metric: u32,
    /// The `pixel-area` metrics' threshold (C§4.6.3): a tree changes to its billboard where the
    /// billboard's opaque area covers this many pixels (px²). Default 16: the built-in species' mean `√A` is
    /// 7.1 m (`reference::metric`, 4.9 to 9.4 m), so at 720 rows and 60° (`f_px` 623.5) the mean
    /// unit-scale tree changes at 7.1 · 623.5 / 4 = 1,110 m, near the thesis's 1000 m.
    pub lod_pixel_area: f32,
    /// The `screen-error` metric's threshold, pixels (3D Tiles `maximumScreenSpaceError`): the
    /// billboard is drawn where its geometric error covers at most this many pixels. Default 2:
    /// the built-in species' mean geometric error is 3.0 m (1.8 to 6.0 m), so at 720 rows and
    /// 60° the mean unit-scale tree changes at 3.0 · 623.5 / 2 = 930 m.
    pub lod_screen_error: f32,
    /// [`crate::SubsetMode`] as `u32` (issue 29, E§7 far-field subsets). Default `Off` (the
    /// thesis): every tree of a drawn batch is drawn.
    pub subset_mode: u32,
    /// View depth past which a batch draws a subset of its trees, metres (`shared/src/subset.rs`).
    /// Default 1000 m, the thesis's transition: the subsets thin the billboards only.
    pub subset_distance: f32,
    /// The least density a subset keeps, `ρ_min` in `(0, 1]`. Default 0.125: past
    /// `subset_distance · √8` (2.8 km at the default) one tree in eight is drawn.
    pub subset_min: f32,
    /// [`crate::Shading`] as `u32` (issue 30, G§5). Default `Unlit`: flat albedo, the frames of
    /// before issue 30 bit for bit (`shared/src/light.rs`).
    pub shading: u32,
    /// The sun's azimuth, degrees counter-clockwise from +X (issue 30). Default 135°: the sun
    /// in the north-west, and the named cameras (`reference::cameras`) look east, so a crown's
    /// side towards them is half in the sun: neither the seed's best view (sun behind the
    /// camera) nor its worst (sun ahead).
    pub sun_azimuth: f32,
    /// The sun's elevation above the horizon, degrees (issue 30). Default 45°, the higher of the
    /// issue's two sweep settings (15° and 45°).
    pub sun_elevation: f32,
    /// The ambient level `a` of sun-depth shading: the lightness of a crown's far side (issue
    /// 30). Default 0.35, the design study's reading (G§5 gives no constant).
    pub ambient: f32,
    /// [`crate::DitherSpace`] as `u32` (issue 30, G§4). Default `Screen`: the dithered fades'
    /// threshold is the frame pixel's, as before.
    pub dither_space: u32,
    /// [`crate::FadeGranularity`] as `u32` (issue 30, G§4). Default `Fragment`: each fragment's
    /// progress through the band is its own depth's, as before.
    pub fade_granularity: u32,
    /// Side `r_n` of the texture-space noise (`shared/src/noise.rs`), a power of two. Read only
    /// under `dither_space = texture`. Default 256: twice the billboards' default side, so a
    /// billboard seen at its own texel size already gets one noise texel per pixel at level 1;
    /// closer (magnified), noise texels grow to `r_lod / r_n` texels of the tree's texture.
    pub noise_size: u32,
    /// Billboard azimuth views `J` per elevation (issue 30, E§7; `shared/src/azimuth.rs`).
    /// Default 1: the thesis's one azimuth (trees taken as radially symmetric, E§3.3.1).
    pub azimuth_count: u32,
    /// [`crate::AzimuthMode`] as `u32` (issue 30): the nearest azimuth view or a blend of the two
    /// nearest. Default `Nearest`; with one azimuth both draw today's frame.
    pub azimuth_mode: u32,
    /// [`crate::Occlusion`] as `u32` (issue 31, `shared/src/occlusion.rs`): occlusion culling
    /// against a depth pyramid of an early pass. Default `Off`: one pass, today's frame.
    pub occlusion: u32,
    /// View depth behind the nearest in-view mesh tree within which a mesh tree's footprint must
    /// start to be an occluder under `occlusion = single`, metres. Default 100 m: the nearest rows
    /// of a forest, a few per cent of `stress`' close trees.
    pub occluder_depth: f32,
    /// [`crate::OcclusionOrder`] as `u32` (issue 31): the final pass clears and draws every tree
    /// not culled in order (`exact`, default: bit-identical frames) or draws the late trees onto
    /// the early pass (`reorder`, niagara's: each tree once).
    pub occlusion_order: u32,
    /// [`crate::ViewSphere`] as `u32` (issue 32, `shared/src/octahedral.rs`): the billboard array
    /// holds the thesis's elevation views (default) or `N×N` octahedral impostor frames.
    pub billboard_views: u32,
    /// Octahedral grid side `N` (issue 32): `N²` frames per mesh. Read only under an octahedral
    /// `billboard_views`. Default 12: Unity IMP's 12×12.
    pub octahedral_grid: u32,
    /// [`crate::AzimuthMode`] as `u32` (issue 32): the nearest octahedral frame, or the blend of
    /// the three around the eye (default, the peers'). Read only under an octahedral
    /// `billboard_views`.
    pub octahedral_blend: u32,
    /// [`crate::FarLod`] as `u32` (issue 32, `shared/src/far.rs`): the far level's primitive under
    /// `lod_levels = 3`. Default `octant-cube`, G§6's.
    pub far_lod: u32,
    /// View depth from which a whole node may go far (issue 32), metres; at least
    /// `lod1_transition` under `lod_levels = 3`, so the chain mesh → billboard → far holds per tree.
    pub far_start: f32,
    /// Screen area under which a node goes far (issue 32, C§4.6.3's metric on the node's box),
    /// pixels. Default 64.
    pub far_pixels: f32,
    /// Cells per axis of a node's far level (G§2.4 `clusterSize`, read in 3D: `cs³` cells). Default 1.
    pub cluster_size: u32,
    /// [`crate::ParentRule`] as `u32` (issue 32, G§2.2): how interior nodes' cells are made from
    /// their children's. Default `average`, the seed's.
    pub parent_rule: u32,
    /// [`crate::OctahedralDepth`] as `u32` (issue 32): whether octahedral impostors bake a depth
    /// layer per frame and the blend re-projects the nearest frame's surface point (`on`) or its
    /// plane (`off`, default). Read only under octahedral views with the blend.
    pub octahedral_depth: u32,
    /// [`crate::points::Lod1`] as `u32` (issue 33, C§4.4, `shared/src/points.rs`): what stands
    /// for a tree past the mesh level, the thesis's billboard (default) or Celba's points.
    pub lod1: u32,
    /// [`crate::points::PointSelect`] as `u32` (issue 33, C§4.6.3): which records of a tree's
    /// point hierarchy are drawn. Default `cut` (each placed point exactly once). Read only under
    /// `lod1 = points`.
    pub point_select: u32,
    /// [`crate::points::DetailPreset`] as `u32` (issue 33, C Table 5.2): the screen areas the
    /// point selection compares with. Default `normal`. Read only under `lod1 = points`.
    pub point_detail: u32,
    /// Points placed per mesh (`N_pts`, issue 33, C§4.4.4's fix). Default 1024. Read only under
    /// `lod1 = points`.
    pub point_count: u32,
    /// Side of a hierarchical impostor's tile, pixels (issue 33 item 2, C§4.6.3
    /// `ImpostorWidth`/`ImpostorHeight`, `shared/src/impostor.rs`): a node is impostored only
    /// when it covers fewer than `impostor_pixels²` pixels. Default 64. Read only under
    /// `far_lod = impostor`.
    pub impostor_pixels: u32,
    /// Tiles the impostor atlas holds (C§4.6.3 `ImpostorTextureWidth·Height` over the tile).
    /// Default 64. Read only under `far_lod = impostor`.
    pub impostor_tiles: u32,
    /// Least distance from the eye to a node's box for it to be impostored, metres (C§4.6.3
    /// `ImpostorMinimalDistance`). Default 300. Read only under `far_lod = impostor`.
    pub impostor_min_distance: f32,
    /// Deepest hierarchy level whose nodes may be impostored, the root being 0 (C§4.6.3
    /// `ImpostorHierarchyMaxDepth`). Default 3. Read only under `far_lod = impostor`.
    pub impostor_max_depth: u32,
    /// Frames between two impostor plans (C§4.6.3 `ImpostorUpdateInterval`, in frames).
    /// Default 1. Read only under `far_lod = impostor`.
    pub impostor_update_interval: u32,
    /// Frames between two refresh steps (C§4.6.3 `ImpostorRefreshInterval`, in frames).
    /// Default 4. Read only under `far_lod = impostor`.
    pub impostor_refresh_interval: u32,
    /// Impostors re-rendered per refresh step, round robin (C§4.6.3 `ImpostorRefreshNumber`).
    /// Default 4. Read only under `far_lod = impostor`.
    pub impostor_refresh_number: u32,
    /// Cells per axis of the grid a mesh's points are split by before Alg. 5 builds each cell's
    /// hierarchy (issue 33, C§4.4.3 `GridSizeX/Y/Z`, here `g³`; C§5.2 series 6). Default 1 (one
    /// hierarchy per mesh). Read only under `lod1 = points`.
    pub point_grid: u32,
}
const _: () = assert!(core::mem::size_of::<Params>() == 224);

impl Default for Params {
    fn default() -> Self {
        Self {
            grid_size: 500.0,
            angle_count: 10,
            texture_size: 128,
            lod_levels: 2,
            lod1_transition: 1000.0,
            fade_width: 250.0,
            draw_distance: 4000.0,
            fade_mode: crate::FadeMode::DitherSequential as u32,
            mip_mode: MipMode::AlphaAware as u32,
            angle_index_mode: AngleIndexMode::Nearest as u32,
            alpha_cutoff: 0.5,
            tree_cull: TreeCull::None as u32,
            hierarchy: Hierarchy::Grid as u32,
            nodes_per_node: 64,
            max_cull_depth: 7,
            coalesce: Coalesce::On as u32,
            command_order: CommandOrder::Node as u32,
            lod_metric: crate::LodMetric::Distance as u32,
            lod_pixel_area: 16.0,
            lod_screen_error: 2.0,
            subset_mode: crate::SubsetMode::Off as u32,
            subset_distance: 1000.0,
            subset_min: 0.125,
            shading: crate::Shading::Unlit as u32,
            sun_azimuth: 135.0,
            sun_elevation: 45.0,
            ambient: 0.35,
            dither_space: crate::DitherSpace::Screen as u32,
            fade_granularity: crate::FadeGranularity::Fragment as u32,
            noise_size: 256,
            azimuth_count: 1,
            azimuth_mode: crate::AzimuthMode::Nearest as u32,
            occlusion: crate::Occlusion::Off as u32,
            occluder_depth: 100.0,
            occlusion_order: crate::OcclusionOrder::Exact as u32,
            billboard_views: crate::ViewSphere::Elevation as u32,
            octahedral_grid: 12,
            octahedral_blend: crate::AzimuthMode::Blend as u32,
            far_lod: crate::FarLod::OctantCube as u32,
            far_start: 2000.0,
            far_pixels: 64.0,
            cluster_size: 1,
            parent_rule: crate::ParentRule::Average as u32,
            octahedral_depth: crate::OctahedralDepth::Off as u32,
            lod1: crate::points::Lod1::Billboard as u32,
            point_select: crate::points::PointSelect::Cut as u32,
            point_detail: crate::points::DetailPreset::Normal as u32,
            point_count: 1024,
            impostor_pixels: 64,
            impostor_tiles: 64,
            impostor_min_distance: 300.0,
            impostor_max_depth: 3,
            impostor_update_interval: 1,
            impostor_refresh_interval: 4,
            impostor_refresh_number: 4,
            point_grid: 1,
        }
    }
}

/// A parameter that cannot be used, with its name, its value and why.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamError {
    /// Field name, as in [`Params`].
    pub field: &'static str,
    /// The offending value, formatted.
    pub value: String,
    /// What a valid value looks like.
    pub reason: Cow<'static, str>,
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "invalid parameter {} = {}: {}",
            self.field, self.value, self.reason
        )
    }
}

impl std::error::Error for ParamError {}

/// Largest texture side we accept: 4096 (SPEC §7 extreme; wgpu's default 2D limit is 8192).
pub const MAX_TEXTURE_SIZE: u32 = 4096;
/// Most elevation angles: one degree apart is already finer than any billboard can show.
pub const MAX_ANGLE_COUNT: u32 = 91;
/// Smallest grid cell: 1 cm. Below it cell indices of a 10 km scene overflow nothing, but batches of
/// one tree are already reached at about 1 m, so smaller cells only cost memory.
pub const MIN_GRID_SIZE: f32 = 0.01;
/// Largest distances we accept (grid, transition, draw distance): 1e7 m, beyond Earth's diameter.
pub const MAX_DISTANCE: f32 = 1.0e7;

impl Params {
    /// Start of the fade band, `lod1_transition - fade_width` (its end is `lod1_transition`).
    /// The one place the band's start is derived in `f32` ([`crate::ViewUniform::new`] uses it).
    pub fn fade_start(&self) -> f32 {
        self.lod1_transition - self.fade_width
    }

    /// The unit direction towards the sun ([`crate::sun_direction`] of `sun_azimuth` and
    /// `sun_elevation`): the one place it is derived.
    pub fn sun_dir(&self) -> [f32; 3] {
        crate::sun_direction(self.sun_azimuth, self.sun_elevation)
    }

    /// Number of mip levels of a billboard layer, `log2(r) + 1` (r = 1 has one level).
    pub fn mip_level_count(&self) -> u32 {
        self.texture_size.max(1).ilog2() + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_ids_look_up() {
        assert_eq!(
            MipMode::from_name("coverage"),
            Some(MipMode::CoveragePreserving)
        );
        assert_eq!(TreeCull::from_id(2), Some(TreeCull::All));
        assert_eq!(AngleIndexMode::from_id(2), None);
        assert_eq!(Hierarchy::from_name("grid-aabb"), Some(Hierarchy::GridAabb));
    }
}
