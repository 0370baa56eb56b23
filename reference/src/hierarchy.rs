//! Tree hierarchies (issue 13): one [`Hierarchy`] of [`NodeMeta`] nodes over the trees of each
//! mesh, built bottom-up as Celba's quadtree (C§4.5), top-down as Guerrero's octree (G§3), or as
//! the depth-1 hierarchy of the grid batches (E§4.2, the thesis's grid as a special case). The CPU
//! precompute of `reference/src/hier_select.rs` and `gpu/src/shaders/hier_select.wgsl`.
//!
//! ## Contract (the invariants of [`NodeMeta`], property-tested in
//! `tests/tests/properties/hierarchy_properties.rs`)
//! - **Order.** Nodes in depth-first pre-order; one root per mesh (mesh order) except for the
//!   depth-1 grid hierarchy, whose roots are the grid batches in batch order. The indirection lists
//!   every tree exactly once, ordered by (mesh, depth-first leaf order); within a leaf, trees keep
//!   their scene order. So every node owns one contiguous range `offset .. offset + len`, and its
//!   children's ranges tile it in child order: any node is one `DrawCommand` (G§3 "two indices per
//!   octant"). A subtree's nodes are the index range `i .. i + subtree_size`.
//! - **Bounds.** Each node's sphere is built by [`crate::batches::batch_meta`] from its trees'
//!   spheres (so a node over a grid batch's trees has exactly the batch's sphere) and its box from
//!   the same spheres in `f64`, rounded outwards to `f32`: both contain every tree's sphere.
//! - **Quadtree** (C§4.5, the design study's reading of "subdivided by quad tree into groups with
//!   maximal number of nodes determined by NodesPerNode"): level 0 are the trees of one mesh; the
//!   square around a level's points (tree sphere centres, then node box centres) is split into
//!   quadrants until each cell holds at most `nodes_per_node` items; each cell becomes a node of the
//!   next level; repeat until one node remains. When a level would not at least halve (isolated
//!   items in many cells), it is grouped in its current order in runs of `nodes_per_node` instead,
//!   which bounds the depth by `log2(trees)`.
//! - **Octree** (G§3): the cube around a mesh's tree sphere centres is split into octants (child
//!   order `x + 2y + 4z`, empty octants dropped) while a node holds more than `nodes_per_node` trees
//!   and has non-zero size, down to depth [`MAX_HIERARCHY_DEPTH`]` - 1`.
//! - Deterministic: no hash iteration order, no thread-count dependence (node bounds are computed
//!   in parallel, each from its own range).

use forestlod_shared::{
    BatchMeta, Hierarchy as HierarchyMode, MAX_HIERARCHY_DEPTH, MeshMeta, NO_PARENT, NodeMeta,
    Params,
};
use rayon::prelude::*;

use crate::InputError;
use crate::batches::{Batches, batch_meta, build_batches};
use crate::scene::{Scene, tree_sphere};

/// A tree hierarchy: nodes in depth-first pre-order and the indirection their ranges index.
#[derive(Clone, Debug, PartialEq)]
pub struct Hierarchy {
    /// The mode it was built for (its per-node rule, [`forestlod_shared::node_code`]).
    pub mode: HierarchyMode,
    /// Nodes in depth-first pre-order.
    pub nodes: Vec<NodeMeta>,
    /// Tree indices ordered by (mesh, depth-first leaf order).
    pub indirection: Vec<u32>,
}

/// A node while building: its trees (leaves) or children (interior).
enum Build {
    Leaf(Vec<u32>),
    Interior(Vec<Build>),
}

impl Hierarchy {
    /// The hierarchy `params.hierarchy` asks for over `scene` (`None` for the thesis's grid).
    /// `meshes` are the scene's (packed) mesh metadata. Fails, naming the field, on an invalid
    /// mode or a grid cell overflow, and on a hierarchy deeper than [`MAX_HIERARCHY_DEPTH`].
    pub fn build(
        scene: &Scene,
        meshes: &[MeshMeta],
        params: &Params,
    ) -> Result<Option<Self>, InputError> {
        let mode = params.hierarchy_mode()?;
        let spheres: Vec<([f32; 3], f32)> = scene
            .instances
            .par_iter()
            .map(|t| tree_sphere(t, &meshes[t.mesh as usize]))
            .collect();
        let cap = params.nodes_per_node.max(2) as usize;
        let roots: Vec<(u32, Build)> = match mode {
            HierarchyMode::Grid => return Ok(None),
            HierarchyMode::GridAabb => {
                let batches = build_batches(scene, meshes, params.grid_size)?;
                return Ok(Some(Self::from_batches(&batches, &spheres, mode)));
            }
            HierarchyMode::Quadtree => per_mesh(scene, |trees| quadtree(trees, &spheres, cap)),
            HierarchyMode::Octree | HierarchyMode::OctreeEuclidean => {
                per_mesh(scene, |trees| octree(trees, &spheres, cap, 0))
            }
        };
        let h = Self::serialize(roots, &spheres, scene, mode);
        if let Some(n) = h.nodes.iter().find(|n| n.depth >= MAX_HIERARCHY_DEPTH) {
            return Err(InputError::new(
                scene.name.clone(),
                "field nodes_per_node",
                params.nodes_per_node,
                format!(
                    "the {} hierarchy reaches depth {} (at most {} levels): raise nodes_per_node",
                    mode.name(),
                    n.depth,
                    MAX_HIERARCHY_DEPTH
                ),
            ));
        }
        Ok(Some(h))
    }

    /// The depth-1 hierarchy of grid batches (each batch a root leaf, batch order; the
    /// indirection is the batches'). Decided with [`HierarchyMode::Grid`] it selects exactly as
    /// `select` does.
    pub fn from_batches(
        batches: &Batches,
        spheres: &[([f32; 3], f32)],
        mode: HierarchyMode,
    ) -> Self {
        let nodes = batches
            .metas
            .par_iter()
            .map(|b| {
                let range = &batches.indirection[b.offset as usize..(b.offset + b.len) as usize];
                node_meta(range, spheres, b.mesh, b.offset, NO_PARENT, 0, 0)
            })
            .collect();
        Self {
            mode,
            nodes,
            indirection: batches.indirection.clone(),
        }
    }

    /// Depth-first pre-order serialization of the built trees (module docs).
    fn serialize(
        roots: Vec<(u32, Build)>,
        spheres: &[([f32; 3], f32)],
        scene: &Scene,
        mode: HierarchyMode,
    ) -> Self {
        // First pass: structure (mesh, offset, len, parent, depth, children), no bounds.
        struct Shape {
            mesh: u32,
            offset: u32,
            len: u32,
            parent: u32,
            depth: u32,
            children: u32,
        }
        fn walk(
            b: Build,
            mesh: u32,
            parent: u32,
            depth: u32,
            shapes: &mut Vec<Shape>,
            indirection: &mut Vec<u32>,
        ) {
            let index = shapes.len();
            let offset = indirection.len() as u32;
            shapes.push(Shape {
                mesh,
                offset,
                len: 0,
                parent,
                depth,
                children: 0,
            });
            match b {
                Build::Leaf(trees) => indirection.extend_from_slice(&trees),
                Build::Interior(children) => {
                    shapes[index].children = children.len() as u32;
                    for c in children {
                        walk(c, mesh, index as u32, depth + 1, shapes, indirection);
                    }
                }
            }
            shapes[index].len = indirection.len() as u32 - offset;
        }
        let mut shapes = Vec::new();
        let mut indirection = Vec::with_capacity(scene.instances.len());
        for (mesh, root) in roots {
            walk(root, mesh, NO_PARENT, 0, &mut shapes, &mut indirection);
        }
        let nodes = shapes
            .par_iter()
            .map(|s| {
                let range = &indirection[s.offset as usize..(s.offset + s.len) as usize];
                node_meta(
                    range, spheres, s.mesh, s.offset, s.parent, s.depth, s.children,
                )
            })
            .collect();
        Self {
            mode,
            nodes,
            indirection,
        }
    }

    /// The leaves as grid-like batches (`cell` = `[node index, depth]`), over the same
    /// indirection: the batches the rest of the pipeline (flat `select`, `refine`, memory)
    /// sees.
    pub fn leaf_batches(&self, grid_size: f32) -> Batches {
        let metas = self
            .nodes
            .iter()
            .enumerate()
            .filter(|(_, n)| n.child_count == 0)
            .map(|(i, n)| BatchMeta {
                center: n.center,
                radius: n.radius,
                extent: n.extent,
                mesh: n.mesh,
                box_center: n.box_center,
                len: n.len,
                cell: [i as i32, n.depth as i32],
                offset: n.offset,
                _pad0: 0,
            })
            .collect();
        Batches {
            metas,
            indirection: self.indirection.clone(),
            grid_size,
        }
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().filter(|n| n.child_count == 0).count()
    }

    /// Deepest node's depth plus one (1 for the depth-1 grid hierarchy).
    pub fn levels(&self) -> u32 {
        self.nodes.iter().map(|n| n.depth + 1).max().unwrap_or(0)
    }

    /// Bytes of the node array (64 per node), beside E Eq. 4.1's `64 t` for batches.
    pub fn node_bytes(&self) -> u64 {
        (self.nodes.len() * core::mem::size_of::<NodeMeta>()) as u64
    }
}

/// The trees of each mesh, in scene order, built into one root each (meshes without trees skipped).
fn per_mesh(scene: &Scene, build: impl Fn(Vec<u32>) -> Build + Sync) -> Vec<(u32, Build)> {
    let mut by_mesh: Vec<Vec<u32>> = vec![Vec::new(); scene.meshes.len()];
    for (i, t) in scene.instances.iter().enumerate() {
        by_mesh[t.mesh as usize].push(i as u32);
    }
    by_mesh
        .into_par_iter()
        .enumerate()
        .filter(|(_, trees)| !trees.is_empty())
        .map(|(m, trees)| (m as u32, build(trees)))
        .collect()
}

/// Node metadata of the trees `range` (module docs: sphere as a batch's, box rounded outwards).
fn node_meta(
    range: &[u32],
    spheres: &[([f32; 3], f32)],
    mesh: u32,
    offset: u32,
    parent: u32,
    depth: u32,
    child_count: u32,
) -> NodeMeta {
    let s: Vec<([f32; 3], f32)> = range.iter().map(|&t| spheres[t as usize]).collect();
    let b = batch_meta(&s, mesh, [0, 0], offset);
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (c, r) in &s {
        for k in 0..3 {
            lo[k] = lo[k].min(c[k] as f64 - *r as f64);
            hi[k] = hi[k].max(c[k] as f64 + *r as f64);
        }
    }
    let box_center: [f32; 3] = core::array::from_fn(|k| ((lo[k] + hi[k]) * 0.5) as f32);
    let extent = core::array::from_fn(|k| {
        let c = box_center[k] as f64;
        f32_at_least((hi[k] - c).max(c - lo[k]))
    });
    NodeMeta {
        center: b.center,
        radius: b.radius,
        extent,
        mesh,
        box_center,
        len: range.len() as u32,
        offset,
        parent,
        depth,
        child_count,
    }
}

/// Rounds a non-negative `f64` up to the nearest `f32` not below it.
fn f32_at_least(x: f64) -> f32 {
    let y = x as f32;
    if (y as f64) < x {
        f32::from_bits(y.to_bits() + 1)
    } else {
        y
    }
}

/// Splits `items` (with their X/Y points) by a quadtree over their square until every cell holds
/// at most `cap`; returns the cells' items in quadrant order (`x + 2y`, depth first).
fn quadtree_groups<T: Copy>(items: &[([f64; 2], T)], cap: usize) -> Vec<Vec<T>> {
    fn split<T: Copy>(
        items: Vec<([f64; 2], T)>,
        x0: f64,
        y0: f64,
        side: f64,
        depth: u32,
        cap: usize,
        out: &mut Vec<Vec<T>>,
    ) {
        if items.len() <= cap || side <= 0.0 || depth >= 60 {
            // A cell of more than `cap` coincident items is cut into runs of `cap`.
            for chunk in items.chunks(cap) {
                out.push(chunk.iter().map(|(_, t)| *t).collect());
            }
            return;
        }
        let h = side * 0.5;
        let mut q: [Vec<([f64; 2], T)>; 4] = Default::default();
        for it in items {
            let qx = (it.0[0] >= x0 + h) as usize;
            let qy = (it.0[1] >= y0 + h) as usize;
            q[qx + 2 * qy].push(it);
        }
        for (k, part) in q.into_iter().enumerate() {
            if !part.is_empty() {
                let (x, y) = (x0 + h * (k & 1) as f64, y0 + h * (k >> 1) as f64);
                split(part, x, y, h, depth + 1, cap, out);
            }
        }
    }
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for (p, _) in items {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let side = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let mut out = Vec::new();
    split(items.to_vec(), lo[0], lo[1], side, 0, cap, &mut out);
    out
}

/// Celba's bottom-up quadtree over one mesh's trees (module docs).
fn quadtree(trees: Vec<u32>, spheres: &[([f32; 3], f32)], cap: usize) -> Build {
    let point = |t: u32| {
        let c = spheres[t as usize].0;
        [c[0] as f64, c[1] as f64]
    };
    // Level 0 → leaves.
    let items: Vec<([f64; 2], u32)> = trees.iter().map(|&t| (point(t), t)).collect();
    let mut groups = quadtree_groups(&items, cap);
    if groups.len() * 2 > items.len() && items.len() > cap {
        groups = trees.chunks(cap).map(|c| c.to_vec()).collect();
    }
    // Each level's nodes with their point (the centre of their trees' centres' box).
    let centre = |ts: &[u32]| {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for &t in ts {
            let p = point(t);
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        [(lo[0] + hi[0]) * 0.5, (lo[1] + hi[1]) * 0.5]
    };
    let mut level: Vec<(Build, Vec<u32>)> = groups
        .into_iter()
        .map(|g| (Build::Leaf(g.clone()), g))
        .collect();
    while level.len() > 1 {
        let items: Vec<([f64; 2], usize)> = level
            .iter()
            .enumerate()
            .map(|(i, (_, ts))| (centre(ts), i))
            .collect();
        let mut groups = quadtree_groups(&items, cap);
        if groups.len() * 2 > items.len() {
            let order: Vec<usize> = (0..level.len()).collect();
            groups = order.chunks(cap).map(|c| c.to_vec()).collect();
        }
        let mut slots: Vec<Option<(Build, Vec<u32>)>> = level.into_iter().map(Some).collect();
        level = groups
            .into_iter()
            .map(|g| {
                let mut children = Vec::with_capacity(g.len());
                let mut ts = Vec::new();
                for i in g {
                    let (b, t) = slots[i].take().expect("each node in one group");
                    ts.extend_from_slice(&t);
                    children.push(b);
                }
                (Build::Interior(children), ts)
            })
            .collect();
    }
    level.pop().expect("a mesh with trees has a root").0
}

/// Guerrero's top-down octree over one mesh's trees (module docs).
fn octree(trees: Vec<u32>, spheres: &[([f32; 3], f32)], cap: usize, depth: u32) -> Build {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &t in &trees {
        let c = spheres[t as usize].0;
        for k in 0..3 {
            lo[k] = lo[k].min(c[k] as f64);
            hi[k] = hi[k].max(c[k] as f64);
        }
    }
    let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    octant(trees, spheres, cap, depth, lo, side)
}

fn octant(
    trees: Vec<u32>,
    spheres: &[([f32; 3], f32)],
    cap: usize,
    depth: u32,
    origin: [f64; 3],
    side: f64,
) -> Build {
    if trees.len() <= cap || side <= 0.0 || depth + 1 >= MAX_HIERARCHY_DEPTH {
        return Build::Leaf(trees);
    }
    let h = side * 0.5;
    let mut parts: [Vec<u32>; 8] = Default::default();
    for t in trees {
        let c = spheres[t as usize].0;
        let k: usize = (0..3)
            .map(|a| ((c[a] as f64 >= origin[a] + h) as usize) << a)
            .sum();
        parts[k].push(t);
    }
    let children = parts
        .into_iter()
        .enumerate()
        .filter(|(_, p)| !p.is_empty())
        .map(|(k, p)| {
            let o = core::array::from_fn(|a| origin[a] + h * ((k >> a) & 1) as f64);
            octant(p, spheres, cap, depth + 1, o, h)
        })
        .collect();
    Build::Interior(children)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadtree_groups_respect_the_cap_and_keep_every_item() {
        let items: Vec<([f64; 2], u32)> = (0..1000)
            .map(|i| ([(i * 37 % 101) as f64, (i * 53 % 97) as f64], i))
            .collect();
        let groups = quadtree_groups(&items, 16);
        assert!(groups.iter().all(|g| !g.is_empty() && g.len() <= 16));
        let mut all: Vec<u32> = groups.concat();
        all.sort_unstable();
        assert_eq!(all, (0..1000).collect::<Vec<_>>());
        // Coincident points are cut into runs.
        let same: Vec<([f64; 2], u32)> = (0..10).map(|i| ([1.0, 1.0], i)).collect();
        assert_eq!(quadtree_groups(&same, 4).len(), 3);
    }
}
