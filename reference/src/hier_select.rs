//! The hierarchical cut (issue 13): which nodes of a [`Hierarchy`] draw this frame, as draw
//! commands. The CPU twin of `gpu/src/shaders/hier_select.wgsl`, written shader-shaped: the
//! seeds' recursive traversals (G§3 Fig. 4 `draw_geometry`, C§4.5) become a **parallel cut
//! evaluation** with no recursion per frame:
//! 1. *decide* (one invocation per node): [`forestlod_shared::node_code`], the node's decision
//!    on its bounds plus whether a drawn interior node recurses;
//! 2. *resolve* (one invocation per node): walk the node's ancestors (at most
//!    [`forestlod_shared::MAX_HIERARCHY_DEPTH`]); the node is **visited** when every ancestor
//!    recursed, and **emitted** when it is visited, drawn and does not recurse;
//! 3. the stable compaction of `select` (scan, write): emitted nodes in node (depth-first) order,
//!    LOD0 before LOD1, command `i` with `base_vertex = i << COMMAND_SHIFT`, `first_instance` the
//!    node's range in the hierarchy's indirection, `CommandData::batch` the node index.
//!
//!
//! The cut's list is then the input of two stages of their own, run after this one by the frame
//! (`crate::frame`, `forestlod_shared::FramePlan`): [`crate::coalesce`] (runs of commands with
//! adjacent ranges and the same mesh, LOD and fading flag merged into one) and
//! [`crate::command_order`] (the commands sorted by their nearest view depth, E§7).
//!
//! This equals the seeds' recursion: the recursion reaches exactly the visited nodes and draws
//! exactly the emitted ones, in depth-first order.
//!
//! ## Invariants (`tests/tests/properties/hierarchy_properties.rs`)
//! - **Conservative** against the per-tree oracle for every mode but `octree-euclidean`: every
//!   (tree, LOD) the oracle draws is covered by exactly one command; no tree is covered twice at
//!   one LOD (the emitted nodes form an antichain).
//! - The `grid` mode on the depth-1 hierarchy of grid batches equals `select` bit for bit.
//! - Deterministic for any thread count.
//!
//! ## The far level (issue 32, `forestlod_shared::far`)
//! With a [`FarCut`] (`lod_levels = 3`) each node's code passes through
//! [`forestlod_shared::far_code`]: a drawn node that needs no mesh, lies wholly beyond `far_start`
//! and covers fewer than `far_pixels` pixels goes far (`NODE_FAR`, not recursing) and emits one
//! far command ([`forestlod_shared::emit_far_command`]) in its node's place of the list; an
//! interior node whose interval reaches `far_start` recurses. Being emitted still means
//! visited and not recursing, so the emitted set stays an antichain: every visible tree is drawn
//! once, by a mesh, a billboard or its node's far level.
//!
//! Counters: `batches_tested` counts the **visited** nodes (C§5's "nodes walked", what the
//! recursion would touch; [`HierSelection::nodes_visited`]), the culls are those of visited nodes,
//! `transition_batches` the emitted nodes with both LODs.

use forestlod_shared::{
    Camera, DECISION_DRAW, DECISION_KIND_MASK, Decision, EmitGroup, FarLevel, FarUniform,
    LOD_BILLBOARD, LOD_FAR, LOD_MESH, MeshMeta, NO_PARENT, NODE_FAR, NODE_RECURSE, Params,
    ViewUniform, code_is_far, code_recurses, count_command, emit_command, emit_far_command,
    emitted_needs, far_code, node_code,
};
use rayon::prelude::*;

use crate::hierarchy::Hierarchy;
use crate::select::Selection;

/// The node state bits, defined with the per-node rule (`forestlod_shared::cut`).
pub use forestlod_shared::{NODE_EMITTED, NODE_VISITED};

/// What the cut produced for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HierSelection {
    /// Commands, data and counters, as `select`'s.
    pub selection: Selection,
    /// Per node: [`forestlod_shared::node_code`].
    pub codes: Vec<u32>,
    /// Per node: [`NODE_VISITED`] | [`NODE_EMITTED`] bits.
    pub states: Vec<u32>,
}

impl HierSelection {
    /// Nodes the recursion would visit (C§5 "nodes walked").
    pub fn nodes_visited(&self) -> u32 {
        self.selection.counters.batches_tested
    }
}

/// Pass 2 for node `i`: its state bits from the codes of its ancestors and its own.
pub fn node_state(nodes: &[forestlod_shared::NodeMeta], codes: &[u32], i: usize) -> u32 {
    let mut p = nodes[i].parent;
    // Bounded by the depth (< MAX_HIERARCHY_DEPTH), as the shader's loop.
    while p != NO_PARENT {
        if !code_recurses(codes[p as usize]) {
            return 0;
        }
        p = nodes[p as usize].parent;
    }
    let code = codes[i];
    let drawn = code & DECISION_KIND_MASK == DECISION_DRAW;
    NODE_VISITED
        | if drawn && code & NODE_RECURSE == 0 {
            NODE_EMITTED
        } else {
            0
        }
}

/// The far level a cut may select (module docs): the hierarchy's baked [`FarLevel`], the frame's
/// far constants and the first index of the packed geometry's far iota range.
#[derive(Clone, Copy, Debug)]
pub struct FarCut<'a> {
    /// The baked far level of the cut's hierarchy (one [`forestlod_shared::FarNode`] per node).
    pub level: &'a FarLevel,
    /// The frame's far constants (`kind` 0: no far level).
    pub uniform: FarUniform,
    /// `PackedGeometry::far`'s first index.
    pub first_index: u32,
}

impl<'a> FarCut<'a> {
    /// The far level of a frame with `camera` and `params` (`None` without `lod_levels = 3`).
    pub fn new(
        level: Option<&'a FarLevel>,
        first_index: u32,
        camera: &Camera,
        params: &Params,
    ) -> Option<Self> {
        let uniform = FarUniform::new(camera, params);
        Some(Self {
            level: level.filter(|_| uniform.kind != 0)?,
            uniform,
            first_index,
        })
    }

    /// Kept cells of node `i` (0 when the level has no such node).
    fn cells(&self, i: usize) -> u32 {
        self.level.nodes.get(i).map_or(0, |n| n.cell_count)
    }

    /// Impostored strict descendants of node `i` under `far_lod = impostor`
    /// (`forestlod_shared::impostor`'s per-node far data; 0 otherwise).
    fn impostored_below(&self, i: usize) -> u32 {
        self.level.nodes.get(i).map_or(0, |n| n.hull_count)
    }
}

/// The cut of `h` for one frame (module docs). `meshes` carry their packed index ranges; `params`
/// must be valid ([`Params::validate`]); `far` is the far level when the frame has one.
pub fn hier_select(
    h: &Hierarchy,
    meshes: &[MeshMeta],
    billboard: &MeshMeta,
    far: Option<FarCut<'_>>,
    camera: &Camera,
    params: &Params,
) -> HierSelection {
    let u = ViewUniform::new(camera, params);
    // Each node decides on its group band (issue 29; the frame's band under `distance`).
    let codes: Vec<u32> = h
        .nodes
        .par_iter()
        .zip(&h.scales)
        .enumerate()
        .map(|(i, (n, &s))| {
            let band = u.group_band(u.mesh_band(&meshes[n.mesh as usize]), s);
            let banded = u.with_band(band);
            let code = node_code(&banded, n, h.mode, params.max_cull_depth);
            match &far {
                Some(f) => far_code(
                    code,
                    &banded,
                    &f.uniform,
                    n,
                    h.mode,
                    f.cells(i),
                    f.impostored_below(i),
                ),
                None => code,
            }
        })
        .collect();
    resolve_and_compact(h, codes, meshes, billboard, far, &u)
}

/// Passes 2 and 3 on given per-node codes (the reference's, or a GPU's read back, to check the
/// GPU's resolution and compaction on its own decisions).
pub fn resolve_and_compact(
    h: &Hierarchy,
    codes: Vec<u32>,
    meshes: &[MeshMeta],
    billboard: &MeshMeta,
    far: Option<FarCut<'_>>,
    u: &ViewUniform,
) -> HierSelection {
    let states: Vec<u32> = (0..h.nodes.len())
        .into_par_iter()
        .map(|i| node_state(&h.nodes, &codes, i))
        .collect();
    let mut out = Selection::default();
    for (i, (n, (&code, &state))) in h.nodes.iter().zip(codes.iter().zip(&states)).enumerate() {
        if forestlod_shared::coverage::enabled() {
            use forestlod_shared::coverage::{Threshold::*, hit};
            hit(CutVisited, state & NODE_VISITED != 0);
            if state & NODE_VISITED != 0
                && n.child_count > 0
                && code & DECISION_KIND_MASK == DECISION_DRAW
            {
                hit(CutRecurse, code_recurses(code));
            }
        }
        if state & NODE_VISITED == 0 {
            continue;
        }
        out.counters.batches_tested += 1;
        match Decision::from_code(code & !(NODE_RECURSE | NODE_FAR)) {
            Decision::CulledDistance => out.counters.culled_distance += 1,
            Decision::CulledFrustum => out.counters.culled_frustum += 1,
            Decision::Draw(_) => {}
        }
        if state & NODE_EMITTED == 0 {
            continue;
        }
        if code_is_far(code) {
            // `far_code` sets NODE_FAR only with a far level whose node has cells.
            let Some(f) = far.as_ref() else { continue };
            let Some(kind) = f.uniform.far_lod() else {
                continue;
            };
            let slot = out.commands.len() as u32;
            let (command, data) = emit_far_command(
                slot,
                i as u32,
                n.mesh,
                &f.level.nodes[i],
                kind,
                f.first_index,
            );
            count_command(&mut out.counters, &command, LOD_FAR);
            out.commands.push(command);
            out.data.push(data);
            continue;
        }
        let needs = emitted_needs(code, n, h.mode, u.lod_levels);
        out.counters.transition_batches += needs.both() as u32;
        // Commands carry the mesh's band at unit scale; the draw scales it per tree.
        let mesh_band = u.mesh_band(&meshes[n.mesh as usize]);
        let group = EmitGroup {
            index: i as u32,
            mesh: n.mesh,
            len: n.len,
            offset: n.offset,
            fading: needs.both(),
            fade_start: mesh_band[0],
            fade_end: mesh_band[1],
            // Far-field subsets are the grid's (issue 29): a node draws all its trees.
            count: n.len,
        };
        for (lod, wanted) in [(LOD_MESH, needs.lod0), (LOD_BILLBOARD, needs.lod1)] {
            if !wanted {
                continue;
            }
            let slot = out.commands.len() as u32;
            let (command, data) =
                emit_command(slot, &group, lod, &meshes[n.mesh as usize], billboard);
            count_command(&mut out.counters, &command, lod);
            out.commands.push(command);
            out.data.push(data);
        }
    }
    out.counters.commands = out.commands.len() as u32;
    HierSelection {
        selection: out,
        codes,
        states,
    }
}

/// The trees a far command of the cut stands for (issue 32), as a range of the hierarchy's
/// indirection: from its first node's (`data.batch`) first tree to the end of the last node its
/// instances cover. An octant command's instances are cells, node by node in node order (the
/// following nodes whose kept cells lie in its range, as coalescing merges adjacent ranges, skipping
/// each node's own subtree); a hull command's are node indices. Consecutive emitted nodes own
/// adjacent tree ranges (children's ranges tile their parent's in order), so the range is theirs.
pub fn far_command_trees(
    h: &Hierarchy,
    level: &FarLevel,
    kind: forestlod_shared::FarLod,
    cmd: &forestlod_shared::DrawCommand,
    data: &forestlod_shared::CommandData,
) -> std::ops::Range<u32> {
    let end = cmd.first_instance + cmd.instance_count;
    let covered = |j: usize| -> bool {
        let f = &level.nodes[j];
        match kind {
            forestlod_shared::FarLod::Hull => (j as u32) >= cmd.first_instance && (j as u32) < end,
            _ => f.cell_count > 0 && f.cell_offset >= cmd.first_instance && f.cell_offset < end,
        }
    };
    let first = &h.nodes[data.batch as usize];
    let mut last_end = first.offset + first.len;
    let mut j = data.batch as usize;
    let count = h.nodes.len().min(level.nodes.len());
    while j < count && covered(j) {
        let n = h.nodes[j];
        last_end = n.offset + n.len;
        j += 1;
        // Past the node's own subtree (an emitted node's descendants are not emitted).
        while j < count && h.nodes[j].depth > n.depth && h.nodes[j].offset < n.offset + n.len {
            j += 1;
        }
    }
    first.offset..last_end
}

/// `selection` with each far command (issue 32) replaced by a billboard command over the trees it
/// stands for ([`far_command_trees`]): what the per-tree counts of a frame (trees drawn,
/// `crate::select::batching_counts`) read, a far tree counted as drawn coarser than a mesh, as a
/// billboard is. Without a far level, `selection` itself.
pub fn tree_view(
    selection: &Selection,
    h: Option<&Hierarchy>,
    level: Option<&FarLevel>,
    params: &Params,
) -> Selection {
    let (Some(h), Some(level), Ok(kind)) = (h, level, params.far_level()) else {
        return selection.clone();
    };
    if kind == forestlod_shared::FarLod::Impostor {
        return impostor_tree_view(selection, h, level);
    }
    let mut out = selection.clone();
    for (c, d) in out.commands.iter_mut().zip(out.data.iter_mut()) {
        if d.lod == LOD_FAR {
            let r = far_command_trees(h, level, kind, c, d);
            c.first_instance = r.start;
            c.instance_count = r.end - r.start;
            d.lod = LOD_BILLBOARD;
            d.billboard = 1;
        }
    }
    out
}

/// [`tree_view`] under hierarchical impostors (issue 33 item 2, `forestlod_shared::impostor`): an
/// impostor command's instances are atlas slots, whose nodes need not be adjacent in node order
/// (coalescing merges commands of adjacent slots), so each slot becomes a billboard command over
/// its own node's trees. `level` is the frame's (the impostor cache's) far level.
fn impostor_tree_view(selection: &Selection, h: &Hierarchy, level: &FarLevel) -> Selection {
    let mut node_of_slot = std::collections::HashMap::new();
    for (i, f) in level.nodes.iter().enumerate() {
        if f.cell_count > 0 {
            node_of_slot.insert(f.cell_offset, i);
        }
    }
    let mut out = Selection {
        counters: selection.counters,
        ..Selection::default()
    };
    for (c, d) in selection.commands.iter().zip(&selection.data) {
        if d.lod != LOD_FAR {
            out.commands.push(*c);
            out.data.push(*d);
            continue;
        }
        for slot in c.first_instance..c.first_instance + c.instance_count {
            let Some(&node) = node_of_slot.get(&slot) else {
                continue;
            };
            let n = &h.nodes[node];
            let mut c = *c;
            let mut d = *d;
            c.first_instance = n.offset;
            c.instance_count = n.len;
            d.lod = LOD_BILLBOARD;
            d.billboard = 1;
            out.commands.push(c);
            out.data.push(d);
        }
    }
    out
}
