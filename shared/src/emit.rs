//! Command emission, one rule for both selections (issue 27): the flat `select` emits a batch's
//! commands and the cut (`hier_select`) an emitted node's with [`emit_command`], and both count
//! what they emit with [`count_command`]. The WGSL twin is `emit_command` in
//! `gpu/src/shaders/common.wgsl`, called by `select.wgsl` and `hier_select.wgsl`.
//!
//! A group (a batch, or a node) of `len` trees at `offset` in the indirection needs LOD0, LOD1 or
//! both (E§3.1: "the batch needs to be drawn twice" when it overlaps the fade band); each LOD is
//! one indexed indirect command over the group's instance range: LOD0 the group's mesh, LOD1 the
//! billboard quad (E§3.3). Command `slot` of the output list carries
//! `base_vertex = slot << COMMAND_SHIFT`, how the draw stage finds its [`CommandData`]
//! ([`DrawCommand`]).

use crate::{
    COMMAND_SHIFT, CUBE_VERTICES, CommandData, DrawCommand, FarLod, FarNode, LOD_BILLBOARD,
    LOD_FAR, LOD_MESH, MeshMeta, SPRITE_VERTICES, SelectCounters,
};

/// What a group contributes to one command: its index (`CommandData::batch`), mesh, instance
/// range and fade band.
#[derive(Clone, Copy, Debug)]
pub struct EmitGroup {
    /// Batch or node index.
    pub index: u32,
    /// Its species mesh.
    pub mesh: u32,
    /// Trees in it.
    pub len: u32,
    /// First of its trees in the indirection.
    pub offset: u32,
    /// Whether it needs both LODs (then both commands fade, E§4.4).
    pub fading: bool,
    /// The frame's fade band start ([`crate::ViewUniform::fade_start`]).
    pub fade_start: f32,
    /// The frame's fade band end.
    pub fade_end: f32,
    /// How many of its trees the commands draw: `len`, or the far-field subset's count
    /// ([`crate::ViewUniform::subset_count`], issue 29).
    pub count: u32,
}

/// The command of `group` at `lod` in output slot `slot`: over the index range of `mesh` (the
/// group's species mesh) for [`LOD_MESH`], of the `billboard` quad for [`LOD_BILLBOARD`].
pub fn emit_command(
    slot: u32,
    group: &EmitGroup,
    lod: u32,
    mesh: &MeshMeta,
    billboard: &MeshMeta,
) -> (DrawCommand, CommandData) {
    let range = if lod == LOD_MESH { mesh } else { billboard };
    let command = DrawCommand {
        index_count: range.index_count,
        instance_count: group.count,
        first_index: range.first_index,
        base_vertex: (slot << COMMAND_SHIFT) as i32,
        first_instance: group.offset,
    };
    let data = CommandData {
        fade_start: group.fade_start,
        fade_end: group.fade_end,
        batch: group.index,
        mesh: group.mesh,
        lod,
        billboard: (lod == LOD_BILLBOARD) as u32,
        fading: group.fading as u32,
        first_tree: group.offset,
        group_len: group.len,
        _pad0: 0,
    };
    (command, data)
}

/// The far command of node `node` (issue 32, `crate::far`'s "command encoding") in output slot
/// `slot`: one instance per kept cell over the primitive's iota range from `first_index` (the
/// packed geometry's far range) for the octant impostors; for a hull one instance whose index
/// is the node's (the vertex stage reads its [`FarNode`]), over its `3·triangles` vertices.
/// `CommandData::first_tree` and `group_len` carry the instance range, so coalescing merges
/// far commands of adjacent ranges like tree commands.
pub fn emit_far_command(
    slot: u32,
    node: u32,
    mesh: u32,
    far_node: &FarNode,
    far_lod: FarLod,
    first_index: u32,
) -> (DrawCommand, CommandData) {
    let (index_count, instance_count, first_instance) = match far_lod {
        FarLod::OctantSprite => (SPRITE_VERTICES, far_node.cell_count, far_node.cell_offset),
        FarLod::OctantCube => (CUBE_VERTICES, far_node.cell_count, far_node.cell_offset),
        FarLod::Hull => (far_node.hull_count, 1, node),
        // One quad, the node's (`crate::impostor`'s per-node far data).
        FarLod::Impostor => (SPRITE_VERTICES, far_node.cell_count, far_node.cell_offset),
    };
    let command = DrawCommand {
        index_count,
        instance_count,
        first_index,
        base_vertex: (slot << COMMAND_SHIFT) as i32,
        first_instance,
    };
    let data = CommandData {
        fade_start: 0.0,
        fade_end: 0.0,
        batch: node,
        mesh,
        lod: LOD_FAR,
        billboard: 0,
        fading: 0,
        first_tree: first_instance,
        group_len: instance_count,
        _pad0: 0,
    };
    (command, data)
}

/// Counts one emitted command in `counters` (its instances and its LOD's command count; the
/// caller sets `commands` to the list's length). A far command (issue 32) counts its
/// instances (cells, or one hull) and neither LOD's commands.
pub fn count_command(counters: &mut SelectCounters, command: &DrawCommand, lod: u32) {
    counters.instances += command.instance_count;
    if lod == LOD_MESH {
        counters.lod0_commands += 1;
    } else if lod == LOD_BILLBOARD {
        counters.lod1_commands += 1;
    }
}
