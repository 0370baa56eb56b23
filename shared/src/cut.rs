//! The per-node rule of the hierarchical cut (issue 13): what one node of a [`NodeMeta`]
//! hierarchy decides for a frame, and the `u32` code the GPU writes for it. Used by
//! `reference/src/hier_select.rs` and mirrored by `node_code` in `gpu/src/shaders/common.wgsl`.
//!
//! ## Contract
//! - [`decide_node`]: the batch rule of [`ViewUniform::decide`] on the node's bounds. With
//!   [`Hierarchy::Grid`] only the sphere counts (the thesis, so a depth-1 hierarchy of grid batches
//!   decides exactly as `select`); every other mode intersects the sphere's and the box's view-depth
//!   intervals ([`view_interval`], [`aabb_view_interval`]) and culls when either volume is outside a
//!   frustum plane (E§7 "tighter bounding volumes"; C§4.5's AABB culling). Both volumes contain every
//!   tree's sphere, so the intersection is still conservative.
//! - [`node_code`]: the decision's `DECISION_*` code, plus [`NODE_RECURSE`] when a drawn interior
//!   node hands the frame to its children instead of drawing as one unit:
//!   - `grid`: never, and likewise `grid-aabb` and `kmeans` (depth-1: every node is a leaf);
//!   - `quadtree` (C§4.5): always ("forest node → children"; interior nodes only cull);
//!   - `octree` (G§3 Fig. 4, conservative reading): when the node needs LOD0 (its interval starts
//!     before the fade band's end, the seed's `dist_to(bound) < LOD_dist` on view depth) or when
//!     its box is only partially inside the frustum and `depth < max_cull_depth`;
//!   - `octree-euclidean` (G§3 as written): the same with the Euclidean distance from the eye to
//!     the box instead of the interval, **not conservative** (module docs of [`Hierarchy`]).
//! - A node is *visited* when every ancestor is drawn with [`NODE_RECURSE`]; a visited node that
//!   is drawn without it is *emitted* with [`emitted_needs`] (its interval's LODs; billboards only
//!   for an `octree-euclidean` unit, as the seed's static billboard geometry).
//! - [`continues_run`]: the command coalescing rule (`reference/src/coalesce.rs`, twinned in
//!   `gpu/src/shaders/coalesce.wgsl`). The cut emits commands in depth-first node order and a
//!   node's range is its subtree's leaves' (one contiguous range per node, G§3 "two indices per
//!   octant"), so emitted siblings at one LOD often own adjacent ranges: a command *continues* its
//!   predecessor in the list when both draw the same geometry (`first_index`, `index_count`,
//!   mesh), the same LOD with the same fading flag (the draw stage's only per-command switches),
//!   and its range starts where the predecessor's ends. G§3 draws each octant as one render
//!   call; merging them is the point of its contiguous serialization.
//! - [`command_depth_key`]: the sort key of `command_order = front-to-back` (E§7 "distance-sorted
//!   commands", `reference/src/command_order.rs`, twinned in `gpu/src/shaders/command_order.wgsl`).
//!   A node's key is its [`node_near_depth`], the lower end of the same sphere ∩ box view-depth
//!   interval the cut decides on, clamped at 0 and taken as its `f32` bits; a coalesced command's
//!   key is the minimum over the nodes it merged. Why it is a valid front-to-back key: both volumes
//!   contain every tree's sphere, so every fragment a command draws lies at or beyond its key's view
//!   depth; sorting ascending puts first the commands whose nearest possible fragment is nearest,
//!   which is the order E§7 asks for (commands whose intervals overlap cannot be ordered exactly by
//!   any per-command key). Non-negative `f32`s order like their `u32` bits, and the clamp makes
//!   `-0.0` and a negative lower end (a node around the eye) key 0, so the key is a plain `u32`
//!   both backends compare the same way; ties are broken by the position in the unsorted list.

use crate::{
    CommandData, DECISION_DRAW, DECISION_KIND_MASK, Decision, DrawCommand, Hierarchy, LodNeeds,
    NodeMeta, ViewUniform, aabb_view_interval, lod_needs, view_interval,
};

/// Node code bit: a drawn interior node whose children decide instead (module docs).
pub const NODE_RECURSE: u32 = 16;

/// Node code bit: the node goes far (issue 32, `crate::far`): emitted as one far command, its
/// subtree not visited. Set only by [`far_code`], with no LOD bit and no [`NODE_RECURSE`].
pub const NODE_FAR: u32 = 32;

/// Node state bit of the cut: every ancestor recursed (the node is visited).
pub const NODE_VISITED: u32 = 1;
/// Node state bit of the cut: visited, drawn and not recursing: the node emits its commands.
pub const NODE_EMITTED: u32 = 2;

/// The most levels a hierarchy may have (root depth 0 .. `MAX_HIERARCHY_DEPTH - 1`): the GPU walks
/// at most this many ancestors per node, far below llvmpipe's 65,535 iterations per loop.
pub const MAX_HIERARCHY_DEPTH: u32 = 32;

/// Euclidean distance from the eye to the box `center ± extent` (0 inside): Guerrero's `dist_to`.
pub fn aabb_distance(center: [f32; 3], extent: [f32; 3], eye: [f32; 3]) -> f32 {
    let mut s = 0.0f32;
    for k in 0..3 {
        let g = ((center[k] - eye[k]).abs() - extent[k]).max(0.0);
        s += g * g;
    }
    s.sqrt()
}

/// The view-depth interval `[lo, hi]` a node decides on under `mode` (module docs): its sphere's
/// for `grid`, the sphere's ∩ the box's otherwise.
pub fn node_interval(u: &ViewUniform, n: &NodeMeta, mode: Hierarchy) -> (f32, f32) {
    let s = view_interval(n.center, n.radius, u.eye, u.forward);
    if mode == Hierarchy::Grid {
        return (s.lo, s.hi);
    }
    let b = aabb_view_interval(n.box_center, n.extent, u.eye, u.forward);
    (s.lo.max(b.lo), s.hi.min(b.hi))
}

/// The node's decision under `mode`'s bounds (module docs).
pub fn decide_node(u: &ViewUniform, n: &NodeMeta, mode: Hierarchy) -> Decision {
    if mode == Hierarchy::Grid {
        return u.decide(n.center, n.radius);
    }
    let (lo, hi) = node_interval(u, n, mode);
    if lo > u.draw_distance {
        Decision::CulledDistance
    } else if !u.frustum.sphere_visible(n.center, n.radius, u.eye)
        || !u.frustum.aabb_visible(n.box_center, n.extent, u.eye)
    {
        if crate::coverage::enabled() {
            let sphere = u.frustum.sphere_visible(n.center, n.radius, u.eye);
            let aabb = u.frustum.aabb_visible(n.box_center, n.extent, u.eye);
            if sphere != aabb {
                crate::coverage::hit(crate::coverage::Threshold::CutCullSphereVsBox, sphere);
            }
        }
        Decision::CulledFrustum
    } else {
        Decision::Draw(lod_needs(lo, hi, u.fade_start, u.fade_end, u.lod_levels))
    }
}

/// The node's code: [`Decision::code`] plus [`NODE_RECURSE`] (module docs).
pub fn node_code(u: &ViewUniform, n: &NodeMeta, mode: Hierarchy, max_cull_depth: u32) -> u32 {
    let decision = decide_node(u, n, mode);
    let code = decision.code();
    let Decision::Draw(needs) = decision else {
        return code;
    };
    if n.child_count == 0 {
        return code;
    }
    let partial = || {
        if crate::coverage::enabled() {
            record_partial(u, n, max_cull_depth);
        }
        n.depth < max_cull_depth && !u.frustum.aabb_inside(n.box_center, n.extent, u.eye)
    };
    if crate::coverage::enabled() && mode == Hierarchy::OctreeEuclidean && u.lod_levels >= 2 {
        let near = aabb_distance(n.box_center, n.extent, u.eye) < u.fade_end;
        crate::coverage::hit(crate::coverage::Threshold::CutEuclidean, !near);
    }
    let recurse = match mode {
        Hierarchy::Grid | Hierarchy::GridAabb | Hierarchy::Kmeans => false,
        Hierarchy::Quadtree => true,
        Hierarchy::Octree => needs.lod0 || partial(),
        Hierarchy::OctreeEuclidean => {
            u.lod_levels < 2
                || aabb_distance(n.box_center, n.extent, u.eye) < u.fade_end
                || partial()
        }
    };
    code | if recurse { NODE_RECURSE } else { 0 }
}

/// The far level's part of a node's code (issue 32, `crate::far`): `code` ([`node_code`]) as it
/// is without a far level (`far.kind == 0`) or unless the node is drawn. A drawn node that needs
/// no mesh (every tree a billboard, so the chain mesh → billboard → far stays conservative per
/// tree) and is [`crate::far_eligible`] with its `cells` becomes `DECISION_DRAW | NODE_FAR`; an
/// interior node that is not far but whose interval reaches `far.start` recurses, so that its
/// smaller descendants may go far. Under `far_lod = impostor` the node's impostor state decides
/// ([`impostor_code`]; `impostored_below` is read only there).
pub fn far_code(
    code: u32,
    u: &ViewUniform,
    far: &crate::FarUniform,
    n: &NodeMeta,
    mode: Hierarchy,
    cells: u32,
    impostored_below: u32,
) -> u32 {
    if far.kind == 0 || code & DECISION_KIND_MASK != DECISION_DRAW {
        return code;
    }
    if far.kind == 1 + crate::FarLod::Impostor as u32 {
        return impostor_code(code, n, cells, impostored_below);
    }
    let (lo, hi) = node_interval(u, n, mode);
    let billboards_only = code & crate::DECISION_LOD0 == 0;
    let goes_far =
        billboards_only && crate::far_eligible(far, lo, n.box_center, n.extent, u.eye, cells);
    if billboards_only {
        crate::coverage::hit(crate::coverage::Threshold::CutFar, goes_far);
    }
    if goes_far {
        return DECISION_DRAW | NODE_FAR;
    }
    if n.child_count > 0 && hi >= far.start {
        code | NODE_RECURSE
    } else {
        code
    }
}

/// [`far_code`] under `far_lod = impostor` (issue 33 item 2, `crate::impostor`): a drawn node
/// that is impostored (`cells` = 1) goes far whatever its trees' LODs (the impostor replaces
/// them all); a drawn interior node with impostored descendants (`impostored_below` > 0)
/// recurses, so that no command covers an impostored node's trees; any other node keeps `code`.
pub fn impostor_code(code: u32, n: &NodeMeta, cells: u32, impostored_below: u32) -> u32 {
    if cells > 0 {
        return DECISION_DRAW | NODE_FAR;
    }
    if n.child_count > 0 && impostored_below > 0 {
        code | NODE_RECURSE
    } else {
        code
    }
}

/// Whether a node code says "goes far" ([`far_code`]).
pub fn code_is_far(code: u32) -> bool {
    code & DECISION_KIND_MASK == DECISION_DRAW && code & NODE_FAR != 0
}

/// Threshold coverage of the octree's partial-visibility test (test-only counters,
/// [`crate::coverage`]): whether the depth allows the test, whether the box straddles a plane, and
/// whether the same test on the sphere's centre would decide otherwise.
fn record_partial(u: &ViewUniform, n: &NodeMeta, max_cull_depth: u32) {
    use crate::coverage::{Threshold::*, hit};
    let tested = n.depth < max_cull_depth;
    hit(CutCullDepth, !tested);
    if tested {
        let inside = u.frustum.aabb_inside(n.box_center, n.extent, u.eye);
        hit(CutPartial, !inside);
        hit(
            CutPartialCentre,
            inside != u.frustum.aabb_inside(n.center, n.extent, u.eye),
        );
    }
}

/// The lower end of the view-depth interval `decide_node` decides on for a hierarchy node (every
/// mode but `grid`): `max(sphere.lo, box.lo)`. Every point of every tree of the node lies at or
/// beyond it (module docs). Twin of `node_near_depth` in `gpu/src/shaders/common.wgsl`.
pub fn node_near_depth(u: &ViewUniform, n: &NodeMeta) -> f32 {
    let s = view_interval(n.center, n.radius, u.eye, u.forward);
    let b = aabb_view_interval(n.box_center, n.extent, u.eye, u.forward);
    s.lo.max(b.lo)
}

/// The front-to-back sort key of a view depth (module docs): its `f32` bits when it is positive,
/// else 0, so that keys order as the depths do and `-0.0` or a negative depth is never a huge
/// `u32`. A coalesced command's key is the minimum of its nodes' keys.
pub fn command_depth_key(near_depth: f32) -> u32 {
    if near_depth > 0.0 {
        near_depth.to_bits()
    } else {
        0
    }
}

/// Whether a node code says "drawn and recurse" (its children are visited).
pub fn code_recurses(code: u32) -> bool {
    code & DECISION_KIND_MASK == DECISION_DRAW && code & NODE_RECURSE != 0
}

/// The LODs an emitted node draws (module docs): its interval's, except an `octree-euclidean`
/// interior unit, which draws billboards only when there are two LOD levels.
pub fn emitted_needs(code: u32, n: &NodeMeta, mode: Hierarchy, lod_levels: u32) -> LodNeeds {
    let needs = Decision::from_code(code & !(NODE_RECURSE | NODE_FAR)).needs();
    if mode == Hierarchy::OctreeEuclidean && n.child_count > 0 && lod_levels >= 2 && needs.lod1 {
        return LodNeeds {
            lod0: false,
            lod1: true,
        };
    }
    needs
}

/// Whether command `cur` (with its data) continues command `prev`, its predecessor in the list, so
/// that coalescing merges them (module docs). Fields the rule does not compare are equal for every
/// command of one cut (`fade_start`, `fade_end`) or follow from the compared ones (`billboard`
/// from `lod`); `batch` is the run's first node and `base_vertex` its slot.
pub fn continues_run(
    prev: &DrawCommand,
    prev_data: &CommandData,
    cur: &DrawCommand,
    cur_data: &CommandData,
) -> bool {
    prev.first_index == cur.first_index
        && prev.index_count == cur.index_count
        && prev_data.mesh == cur_data.mesh
        && prev_data.lod == cur_data.lod
        && prev_data.fading == cur_data.fading
        && prev.first_instance.wrapping_add(prev.instance_count) == cur.first_instance
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Camera, Params};

    /// The sort key at its edges (module docs): `-0.0`, `0.0` and negative depths all key 0;
    /// positive depths key as they order. Added for a survivor of issue 36's Rust sample (mutant
    /// 1892: `near_depth > 0.0` → `>= 0.0` keys `-0.0` as `0x8000_0000`, behind every node, and no
    /// test met a node whose nearest depth was exactly `-0.0`).
    #[test]
    fn depth_keys_at_zero_and_below_are_zero_and_order_like_depths_above() {
        for d in [-0.0f32, 0.0, -1e-30, -5.0, f32::MIN] {
            assert_eq!(command_depth_key(d), 0, "key of {d:?}");
        }
        let depths = [f32::MIN_POSITIVE / 2.0, 1e-6, 0.5, 1.0, 1000.0, 1e7];
        for w in depths.windows(2) {
            assert!(
                0 < command_depth_key(w[0]) && command_depth_key(w[0]) < command_depth_key(w[1]),
                "keys of {} and {}",
                w[0],
                w[1]
            );
        }
    }

    fn node(center: [f32; 3], half: f32, depth: u32, children: u32) -> NodeMeta {
        NodeMeta {
            center,
            radius: half * 3f32.sqrt(),
            extent: [half; 3],
            mesh: 0,
            box_center: center,
            len: 1,
            offset: 0,
            parent: crate::NO_PARENT,
            depth,
            child_count: children,
        }
    }

    #[test]
    fn octree_recurses_near_and_draws_far_units() {
        let c = Camera::look_at([0.0, 0.0, 10.0], [100.0, 0.0, 10.0], 60.0, 160, 90);
        let u = ViewUniform::new(&c, &Params::default());
        let near = node_code(
            &u,
            &node([200.0, 0.0, 10.0], 50.0, 3, 8),
            Hierarchy::Octree,
            7,
        );
        assert!(code_recurses(near), "{near}");
        let far = node([2000.0, 0.0, 10.0], 50.0, 3, 8);
        let code = node_code(&u, &far, Hierarchy::Octree, 7);
        assert!(!code_recurses(code));
        assert_eq!(
            Decision::from_code(code),
            Decision::Draw(LodNeeds {
                lod0: false,
                lod1: true
            })
        );
        // Straddling a side plane at a depth below max_cull_depth: recurse; at it: draw whole.
        let side = node([2000.0, 2050.0, 10.0], 50.0, 3, 8);
        assert!(code_recurses(node_code(&u, &side, Hierarchy::Octree, 7)));
        assert!(!code_recurses(node_code(&u, &side, Hierarchy::Octree, 3)));
        // Leaves never recurse; the quadtree always does when drawn.
        assert!(!code_recurses(node_code(
            &u,
            &node([200.0, 0.0, 10.0], 5.0, 3, 0),
            Hierarchy::Quadtree,
            7
        )));
        assert!(code_recurses(node_code(&u, &far, Hierarchy::Quadtree, 7)));
    }
}
