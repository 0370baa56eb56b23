//! # forestlod-shared
//!
//! The plain-data types and the scalar formulas that the CPU reference (`forestlod-reference`) and the
//! wgpu twin (`forestlod-gpu`) must agree on bit for bit. Everything here is `#[repr(C)]` +
//! [`bytemuck::Pod`] with explicit padding and a compile-time size assertion, or a pure function of
//! scalars. This crate owns no I/O and must never depend on wgpu or on the reference.
//!
//! ## Conventions (SPEC §3), used by every crate of the workspace
//! - **Units** are metres. The world is **Z-up** (GIS) and right-handed. Trees stand on the XY plane or
//!   on a terrain height; batches are formed on X and Y (E§4.2).
//! - **Large coordinates**: scenes keep an `f64` origin; every `f32` position in these types is
//!   relative to that origin, so the numbers the GPU sees stay small (SPEC §7).
//! - **Camera**: position, forward, up, vertical field of view, near, far, viewport size. Clip space
//!   follows wgpu: x, y in -1..1 with y up, depth in 0..1.
//! - **Colour**: textures are sRGB-encoded RGBA8 with straight (not premultiplied) alpha; filtering
//!   and blending happen in linear `f32`; output is sRGB8 (plus linear float EXR when asked).
//! - **Rasterization** follows Vulkan: pixel centres at +0.5, 8 subpixel bits, top-left fill rule,
//!   perspective-correct interpolation, depth test LESS.
//! - **View depth** `d = (p - eye) · forward` is the one distance every LOD decision uses: batch
//!   selection projects batch centres onto it (E§3.5) and the fragment fade evaluates it per pixel, so
//!   the batch interval is conservative for every fragment of every tree in the batch.
//! - **Determinism**: every formula here is a fixed sequence of `f32` operations without fused
//!   multiply-add, so the reference reproduces it exactly; the GPU may contract or reorder, which the
//!   parity tests classify as ambiguity near thresholds (SPEC §8).

#![expect(
    clippy::manual_clamp,
    reason = "`x.max(lo).min(hi)` maps NaN to `lo` on purpose (NaN-free outputs, SPEC §7); `clamp` would propagate NaN"
)]

pub mod angle;
pub mod azimuth;
pub mod billboard;
pub mod camera;
pub mod color;
pub mod coverage;
pub mod cut;
pub mod emit;
pub mod fade;
pub mod far;
pub mod far_bake;
pub mod frame;
pub mod impostor;
pub mod interval;
pub mod light;
pub mod metric;
pub mod modes;
pub mod noise;
pub mod occlusion;
pub mod octahedral;
pub mod params;
pub mod presets;
pub mod registry;
pub mod subset;
pub mod terrain;
pub mod types;
mod validate;
pub mod view;
// Issue 33 item 1 (kept apart for the merge): Celba's point LOD, CPU preprocessing and its rules.
pub mod points;

pub use angle::{
    angle_index, angle_index_eq31, angle_index_eq31_clamped, angle_index_for, bake_elevation,
};
pub use azimuth::{
    AZIMUTH_LAYER_BITS, AZIMUTH_TURN, AZIMUTH_WEIGHT_SCALE, AZIMUTH_WEIGHT_STEPS, AzimuthMode,
    AzimuthView, BillboardViews, MAX_AZIMUTH_COUNT, MAX_BILLBOARD_LAYERS, azimuth_index,
    azimuth_mix, azimuth_pack, azimuth_position, azimuth_second_layer, azimuth_to_view,
    azimuth_unpack, azimuth_view, azimuth_weights, bake_azimuth, check_billboard_layers,
    view_layer,
};
pub use billboard::{BillboardExtent, billboard_extent, dither_threshold};
pub use camera::{Camera, CameraBasis, FrustumPlanes};
pub use color::{
    LOD_ID_BACKGROUND, LOD_ID_BILLBOARD, LOD_ID_FAR, LOD_ID_MESH, LOD_ID_TERRAIN,
    LOD_ID_TRANSITION, SKY_SRGB, linear_to_srgb, srgb_to_linear, unorm8,
};
pub use cut::{
    MAX_HIERARCHY_DEPTH, NODE_EMITTED, NODE_FAR, NODE_RECURSE, NODE_VISITED, aabb_distance,
    code_is_far, code_recurses, command_depth_key, continues_run, decide_node, emitted_needs,
    far_code, node_code, node_interval, node_near_depth,
};
pub use emit::{EmitGroup, count_command, emit_command, emit_far_command};
pub use fade::{
    DitherSpace, FadeGranularity, FadeMode, LodWeights, fade_progress, lod_weights,
    tree_lod_weights, weights_at,
};
pub use far::{
    CUBE_VERTICES, FAR_ALPHA_MIN, FAR_BAKE_PIXELS, FarCell, FarLevel, FarLod, FarNode, FarUniform,
    FarVertex, LOD_FAR, MAX_CLUSTER_SIZE, MAX_HULL_TRIANGLES, ParentRule, SIDE_COUNT,
    SPRITE_VERTICES, box_area_along, cube_corner, far_eligible, pack_far_colour, side_mix,
    side_normal, side_of, side_weights, sprite_corner, sprite_half, unpack_far_colour,
};
pub use frame::{FramePart, FramePlan, SelectionPlan, StageId};
pub use interval::{
    LodNeeds, ViewInterval, aabb_margin, aabb_view_interval, lod_needs, selection_margin,
    view_interval,
};
pub use light::{
    MIN_CROWN_RADIUS, Shading, TruthLight, crown_radii, light_point, lightness, sun_depth,
    sun_direction, vertex_lightness,
};
pub use metric::{LodMetric, band_ratio, focal_px, mesh_size, metric_factor};
pub use noise::{
    noise_at, noise_index, noise_level, noise_level_of, noise_level_scaled, noise_level_texels,
    noise_texel, texture_noise,
};
pub use occlusion::{
    MAX_PYRAMID_LEVELS, OCCLUSION_SLACK_PX, OCCLUSION_SLACK_REL, OCCLUSION_Z_SLACK, Occlusion,
    OcclusionBound, OcclusionCounters, OcclusionOrder, OcclusionRect, PyramidLevel, effective_mode,
    final_includes_early, is_early, is_occluder, may_occlude, nearest_occluder_depth, occluded,
    occlusion_bounds, occlusion_slot, pyramid_len, pyramid_level_floor, pyramid_level_for,
    pyramid_levels, pyramid_reduce, pyramid_texels_max,
};
pub use octahedral::{
    MAX_OCTAHEDRAL_GRID, MIN_OCTAHEDRAL_GRID, OCTAHEDRAL_LAYER_BITS, OCTAHEDRAL_STEP,
    OCTAHEDRAL_STEPS, OctahedralDepth, OctahedralFrames, OctahedralView, ViewSphere,
    check_octahedral_layers, depth_channel, depth_offset, fitted_corner, frame_basis,
    frame_direction, frame_uv, octahedral_decode, octahedral_encode, octahedral_frames,
    octahedral_layer, octahedral_mix, octahedral_pack, octahedral_unpack, octahedral_view,
    parallax_uv, quad_fit, quad_point, reproject_duv, reproject_uv, view_direction,
};
pub use params::{
    AngleIndexMode, Coalesce, CommandOrder, Hierarchy, MipMode, ParamError, Params, TreeCull,
};
pub use registry::{PARAMS, ParamKind, ParamSpec, param};
pub use subset::{
    SUBSET_FADE, SUBSET_WEIGHT_STEPS, SubsetMode, subset_count, subset_density,
    subset_dither_shift, subset_fragment_weight, subset_pack, subset_scale, subset_weight_code,
};
pub use terrain::{
    GridAxes, TERRAIN_CELLS, TERRAIN_MARGIN, TERRAIN_SINK, axes_grid, axes_triangles,
    axes_vertices, grid_surface_height, ground_color, terrain_grid, terrain_grid_triangles,
    terrain_grid_vertices, terrain_vertex, uniform_axes,
};
pub use types::{
    BatchMeta, CommandData, DrawCommand, MeshMeta, NO_PARENT, NodeMeta, ProxyRecord, SelectCounters,
};
pub use view::{
    DECISION_CULLED_DISTANCE, DECISION_CULLED_FRUSTUM, DECISION_DRAW, DECISION_KIND_MASK,
    DECISION_LOD0, DECISION_LOD1, Decision, ViewUniform,
};

/// Number of low bits of `DrawCommand::base_vertex` that carry the mesh-local vertex index; the
/// command index sits above them (see [`DrawCommand`]). Meshes therefore hold at most 256 vertices,
/// ample for < 20-triangle trees (E§3.1). Keep in sync with `gpu/src/shaders/common.wgsl`
/// (and its use in `gpu/src/shaders/draw.wgsl`).
pub const COMMAND_SHIFT: u32 = 8;
/// The most vertices one tree mesh (or the billboard quad) may have: `1 << COMMAND_SHIFT`.
pub const MAX_MESH_VERTICES: u32 = 1 << COMMAND_SHIFT;
/// The most commands one frame can address: `base_vertex` is an `i32`.
pub const MAX_COMMANDS: u32 = 1 << (31 - COMMAND_SHIFT);
/// Level of detail of full meshes (E§3.1).
pub const LOD_MESH: u32 = 0;
/// Level of detail of camera-facing billboards (E§3.3).
pub const LOD_BILLBOARD: u32 = 1;

/// Helpers shared by this crate's unit tests.
#[cfg(test)]
pub(crate) mod test_support {
    use proptest::prelude::ProptestConfig;

    /// The property tests' configuration: 512 cases each.
    pub(crate) fn proptest_config() -> ProptestConfig {
        ProptestConfig {
            cases: 512,
            ..ProptestConfig::default()
        }
    }
}
