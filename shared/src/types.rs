//! GPU-visible records: batch metadata (E§4.2), draw commands and per-command data (E§4.3),
//! per-mesh metadata (E§4.1), selection counters and the Primitive baseline's proxy records (E§5).
//!
//! Keep in sync with `gpu/src/shaders/common.wgsl`. Every struct is `#[repr(C)]`, has only 4-byte
//! fields, explicit padding, and a size assertion; WGSL storage-buffer layout of the same fields in
//! the same order is then identical (every member 4-byte aligned, `vec3` avoided on purpose).

use bytemuck::{Pod, Zeroable};

/// One batch: the trees of one mesh inside one grid cell (E§3.4, §4.2).
///
/// Invariant: the bounding sphere (`center`, `radius`) contains the bounding sphere of every tree of
/// the batch, tree heights included (E Fig. 3.7). `center` is the centre of the trees' sphere
/// centres' bounding box, so a batch of one tree has exactly that tree's sphere.
///
/// Keep in sync with `struct BatchMeta` in `gpu/src/shaders/common.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BatchMeta {
    /// Bounding-sphere centre, relative to the scene origin.
    pub center: [f32; 3],
    /// Bounding-sphere radius, rounded up so containment survives `f32` rounding.
    pub radius: f32,
    /// Half-size of the bounding box of the trees' spheres, around `box_center`.
    pub extent: [f32; 3],
    /// Mesh (species) index shared by all trees of the batch.
    pub mesh: u32,
    /// Bounding-box centre (E§4.2 "geometric center").
    pub box_center: [f32; 3],
    /// Number of trees, the length of the batch's range in the indirection array.
    pub len: u32,
    /// 2D grid cell index `(floor(x / g), floor(y / g))`.
    pub cell: [i32; 2],
    /// Offset of the batch's range in the indirection array.
    pub offset: u32,
    /// Explicit padding.
    pub _pad0: u32,
}
const _: () = assert!(core::mem::size_of::<BatchMeta>() == 64);

/// One node of a tree hierarchy (issue 13; `reference/src/hierarchy.rs`): a quadtree (C§4.5) or
/// octree (G§3) node over the trees of one mesh, or a grid batch as a depth-1 root.
///
/// Invariants (built by `reference::hierarchy`, property-tested in
/// `tests/tests/properties/hierarchy_properties.rs`):
/// - nodes are stored in depth-first pre-order, roots (one per mesh and tree, mesh-major) one after
///   another, so a node's subtree is the index range right after it;
/// - the indirection is ordered by (mesh, depth-first leaf order), so every node owns one contiguous
///   range `offset .. offset + len` and its children's ranges tile it in child order (Guerrero's
///   "two indices per octant", G§3): any node is one `DrawCommand`;
/// - the sphere (`center`, `radius`) and the box (`box_center` ± `extent`) each contain the bounding
///   sphere of every tree in the node's range (both rounded outwards, so containment is exact).
///
/// Keep in sync with `struct NodeMeta` in `gpu/src/shaders/common.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct NodeMeta {
    /// Bounding-sphere centre (the centre of its trees' sphere centres' box, as a batch's).
    pub center: [f32; 3],
    /// Bounding-sphere radius, rounded up.
    pub radius: f32,
    /// Half-size of the box of the trees' spheres around `box_center`, rounded up.
    pub extent: [f32; 3],
    /// Mesh of every tree of the node.
    pub mesh: u32,
    /// Box centre.
    pub box_center: [f32; 3],
    /// Trees in the node's range.
    pub len: u32,
    /// Start of the node's range in the hierarchy's indirection array.
    pub offset: u32,
    /// Parent node index, [`NO_PARENT`] for a root.
    pub parent: u32,
    /// Depth: 0 for a root.
    pub depth: u32,
    /// Number of children; 0 for a leaf.
    pub child_count: u32,
}
const _: () = assert!(core::mem::size_of::<NodeMeta>() == 64);

/// [`NodeMeta::parent`] of a root.
pub const NO_PARENT: u32 = u32::MAX;

/// `wgpu::util::DrawIndexedIndirectArgs`, field for field (and `VkDrawIndexedIndirectCommand`).
///
/// How the draw stage finds its per-command data without `gl_DrawID` (which WGSL lacks): mesh index
/// buffers hold mesh-local vertex ids (< [`crate::MAX_MESH_VERTICES`]), and
/// `base_vertex = command_index << COMMAND_SHIFT`, so the vertex stage reads
/// `command = vertex_index >> COMMAND_SHIFT` and `local = vertex_index & (MAX_MESH_VERTICES - 1)`.
/// `first_instance` is the batch's offset in the indirection array, so
/// `instance_index` indexes it directly (E§4.4).
///
/// Keep in sync with `struct DrawCommand` in `gpu/src/shaders/common.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Pod, Zeroable)]
pub struct DrawCommand {
    /// Indices per instance: the mesh's, or 6 for the billboard quad.
    pub index_count: u32,
    /// Trees in the batch.
    pub instance_count: u32,
    /// Start of the mesh's (or the quad's) range in the shared index buffer.
    pub first_index: u32,
    /// `command_index << COMMAND_SHIFT`.
    pub base_vertex: i32,
    /// The batch's offset in the indirection array.
    pub first_instance: u32,
}
const _: () = assert!(core::mem::size_of::<DrawCommand>() == 20);

/// Per-command data read by the draw stage (E§4.3): the fade gradient and what to draw.
///
/// 32 bytes, so a command costs 20 + 32 = 52 bytes: exactly E Eq. 4.1's `52 l t` term.
///
/// Keep in sync with `struct CommandData` in `gpu/src/shaders/common.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CommandData {
    /// View depth where the fade band starts (`lod1_transition - fade_width`).
    pub fade_start: f32,
    /// View depth where the fade band ends (`lod1_transition`).
    pub fade_end: f32,
    /// Batch this command draws.
    pub batch: u32,
    /// Mesh index.
    pub mesh: u32,
    /// Level of detail: [`crate::LOD_MESH`] or [`crate::LOD_BILLBOARD`].
    pub lod: u32,
    /// 1 when the command draws billboards.
    pub billboard: u32,
    /// 1 when the batch's interval overlaps the fade band, so the fragment stage must fade.
    pub fading: u32,
    /// The indirection index of rank 0 of the command's group (its batch's offset): a tree's
    /// rank in its batch's subset order is `instance_index - first_tree` (issue 29, E§7
    /// far-field subsets, `shared/src/subset.rs`).
    pub first_tree: u32,
    /// Trees in the command's group (the batch's `len`; `instance_count` is at most it); 0 when
    /// the command's instances carry no subset rank (baselines, refined and coalesced commands).
    pub group_len: u32,
    /// Explicit padding.
    pub _pad0: u32,
}
const _: () = assert!(core::mem::size_of::<CommandData>() == 40);

/// Per-mesh metadata for command generation and billboards (E§4.1).
///
/// Keep in sync with `struct MeshMeta` in `gpu/src/shaders/common.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MeshMeta {
    /// First index of the mesh in the shared index buffer.
    pub first_index: u32,
    /// Index count (3 per triangle).
    pub index_count: u32,
    /// First vertex of the mesh in the shared vertex buffer.
    pub first_vertex: u32,
    /// Vertex count (<= [`crate::MAX_MESH_VERTICES`]).
    pub vertex_count: u32,
    /// Mesh-local bounding-box minimum (unit scale, zero yaw).
    pub bbox_min: [f32; 3],
    /// Billboard half-width: the bounding box's horizontal circumradius (trees are radially
    /// symmetric, E§3.3.1, so this covers every yaw).
    pub billboard_half_width: f32,
    /// Mesh-local bounding-box maximum.
    pub bbox_max: [f32; 3],
    /// Local bounding-sphere radius (half the box diagonal) around the box centre.
    pub sphere_radius: f32,
    /// `√A`, `A` the opaque area (alpha >= 0.5) of the mesh's level-view billboard at unit scale,
    /// m (issue 29, the pixel-area metrics' size; `reference::metric::measure_mesh`). 0 for the
    /// billboard quad's record.
    pub area_size: f32,
    /// The level-view billboard's geometric error at unit scale, m: the largest distance of the
    /// mesh surface it shows from the billboard's plane (issue 29, the `screen-error` metric's
    /// size; `reference::metric::measure_mesh`).
    pub error_size: f32,
    /// Explicit padding.
    pub _pad0: u32,
    /// Explicit padding.
    pub _pad1: u32,
}
const _: () = assert!(core::mem::size_of::<MeshMeta>() == 64);

/// Work counters of one selection pass.
///
/// Keep in sync with `struct SelectCounters` in `gpu/src/shaders/common.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SelectCounters {
    /// Batches examined.
    pub batches_tested: u32,
    /// Batches culled because wholly beyond the draw distance.
    pub culled_distance: u32,
    /// Batches culled because wholly outside the frustum.
    pub culled_frustum: u32,
    /// Commands emitted.
    pub commands: u32,
    /// Commands with LOD0.
    pub lod0_commands: u32,
    /// Commands with LOD1.
    pub lod1_commands: u32,
    /// Batches that emitted two commands (overlap the fade band).
    pub transition_batches: u32,
    /// Tree instances across all emitted commands.
    pub instances: u32,
}
const _: () = assert!(core::mem::size_of::<SelectCounters>() == 32);

/// One Primitive proxy (E§5, SPEC §9: the "sphere on top of a cylinder" baseline) per mesh, as the
/// GPU reads it: the reference's `baselines::Proxy`, mesh-local, unit scale. 32 bytes, the
/// reference's `PROXY_BYTES`.
///
/// Keep in sync with `struct ProxyRecord` in `gpu/src/shaders/primitive.wgsl` (layout checked by
/// `gpu/tests/layout.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ProxyRecord {
    /// Crown sphere radius.
    pub crown_radius: f32,
    /// Height of the crown sphere's centre above the base.
    pub crown_z: f32,
    /// Trunk cylinder radius.
    pub trunk_radius: f32,
    /// Height of the trunk's bottom.
    pub bottom_z: f32,
    /// Flat colour, linear RGB.
    pub color: [f32; 3],
    /// Explicit padding.
    pub _pad0: u32,
}
const _: () = assert!(core::mem::size_of::<ProxyRecord>() == 32);
