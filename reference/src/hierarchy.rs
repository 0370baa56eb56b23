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
//! - **K-means** (E§7 "density-aware batches", depth 1 like the grid): per mesh, `k =
//!   ceil(trees / nodes_per_node)` clusters of the trees' X/Y sphere centres. Seeds: the centroids
//!   of a balanced bisection (the point set split at the median of its longer side, `k` divided
//!   in proportion), so seeding is deterministic and already density-aware. Then at most
//!   [`KMEANS_ITERATIONS`] Lloyd iterations (exact nearest centre through a uniform grid of the
//!   centres, ties to the lower index; centroids summed in `f64` in tree order; stop when no
//!   assignment changes). Size constraint: a cluster of more than `nodes_per_node` trees is split
//!   at the median of its longer side until every part fits. Clusters keep the seed order (the
//!   bisection's, spatially coherent), splits in place, empty clusters dropped; trees keep scene
//!   order within a cluster.
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
    /// Per node, the `[least, greatest]` scale of its trees (issue 29's group band,
    /// [`crate::batches::scale_range`]), parallel to `nodes`.
    pub scales: Vec<[f32; 2]>,
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
            // The flat selection needs none; a far level (issue 32) selects by the cut, over the
            // depth-1 hierarchy of the grid batches, whose cut equals `select`.
            HierarchyMode::Grid if params.lod_levels < 3 => return Ok(None),
            HierarchyMode::Grid => {
                let batches = build_batches(scene, meshes, params.grid_size)?;
                return Ok(Some(Self::from_batches(&batches, &spheres, mode)));
            }
            HierarchyMode::GridAabb => {
                let batches = build_batches(scene, meshes, params.grid_size)?;
                return Ok(Some(Self::from_batches(&batches, &spheres, mode)));
            }
            HierarchyMode::Quadtree => per_mesh(scene, |trees| quadtree(trees, &spheres, cap)),
            HierarchyMode::Octree | HierarchyMode::OctreeEuclidean => {
                per_mesh(scene, |trees| octree(trees, &spheres, cap, 0))
            }
            // Depth 1: every cluster is a root leaf of its mesh.
            HierarchyMode::Kmeans => per_mesh(scene, |trees| {
                Build::Interior(
                    kmeans(&trees, &spheres, cap)
                        .into_iter()
                        .map(Build::Leaf)
                        .collect(),
                )
            })
            .into_iter()
            .flat_map(|(mesh, b)| match b {
                Build::Interior(leaves) => leaves.into_iter().map(move |l| (mesh, l)),
                Build::Leaf(_) => unreachable!("kmeans returns its clusters as children"),
            })
            .collect(),
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
            scales: batches.scales.clone(),
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
        let scales = shapes
            .par_iter()
            .map(|s| {
                let range = &indirection[s.offset as usize..(s.offset + s.len) as usize];
                crate::batches::scale_range(scene, range)
            })
            .collect();
        Self {
            mode,
            nodes,
            indirection,
            scales,
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
        let scales = self
            .nodes
            .iter()
            .zip(&self.scales)
            .filter(|(n, _)| n.child_count == 0)
            .map(|(_, s)| *s)
            .collect();
        Batches {
            metas,
            indirection: self.indirection.clone(),
            grid_size,
            scales,
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

/// Most Lloyd iterations of the `kmeans` builder (module docs): bounded so the build time is
/// bounded; the assignment rarely changes after a few, as the seeds are already balanced.
pub const KMEANS_ITERATIONS: usize = 8;

/// The X/Y point of tree `t` (its sphere centre), in `f64`.
fn xy(spheres: &[([f32; 3], f32)], t: u32) -> [f64; 2] {
    let c = spheres[t as usize].0;
    [c[0] as f64, c[1] as f64]
}

/// Splits `trees` (indices into `spheres`) into `parts` groups of sizes as equal as possible, by
/// recursive bisection at the median of the longer side of their X/Y box (the sphere centres'; Y
/// only when strictly longer), the set sorted along that side (ties by tree index), the first
/// `len · ⌊parts/2⌋ / parts` trees going left with `⌊parts/2⌋` of the parts; appends the groups to
/// `out` in bisection order (left before right) and leaves `trees` permuted. Deterministic. With
/// `1 <= parts <= trees.len()` it appends exactly `parts` groups whose sizes differ by at most
/// one, and each split separates its halves along its axis (property-tested in
/// `tests/tests/properties/hierarchy_properties.rs`). The k-means builder's seeds (module docs).
pub fn bisect(
    trees: &mut [u32],
    parts: usize,
    spheres: &[([f32; 3], f32)],
    out: &mut Vec<Vec<u32>>,
) {
    if parts <= 1 || trees.len() <= 1 {
        out.push(trees.to_vec());
        return;
    }
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for &t in trees.iter() {
        let p = xy(spheres, t);
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let axis = usize::from(hi[1] - lo[1] > hi[0] - lo[0]);
    trees.sort_unstable_by(|&a, &b| {
        xy(spheres, a)[axis]
            .total_cmp(&xy(spheres, b)[axis])
            .then(a.cmp(&b))
    });
    let left_parts = parts / 2;
    let mid = trees.len() * left_parts / parts;
    let (l, r) = trees.split_at_mut(mid);
    bisect(l, left_parts, spheres, out);
    bisect(r, parts - left_parts, spheres, out);
}

/// A uniform grid over centres for exact nearest-centre queries.
struct CentreGrid {
    origin: [f64; 2],
    cell: f64,
    dims: [usize; 2],
    /// Per cell, the indices of its centres (ascending).
    cells: Vec<Vec<u32>>,
}

impl CentreGrid {
    fn new(centres: &[[f64; 2]]) -> Self {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for c in centres {
            for k in 0..2 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        let side = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6);
        // About one centre per cell.
        let per_side = (centres.len() as f64).sqrt().ceil().max(1.0);
        let cell = side / per_side;
        let dims = [0, 1].map(|k| (((hi[k] - lo[k]) / cell) as usize + 1).min(1 << 12));
        let mut cells = vec![Vec::new(); dims[0] * dims[1]];
        let grid = Self {
            origin: lo,
            cell,
            dims,
            cells: Vec::new(),
        };
        for (i, c) in centres.iter().enumerate() {
            let [x, y] = grid.cell_of(*c);
            cells[y * dims[0] + x].push(i as u32);
        }
        Self { cells, ..grid }
    }

    fn cell_of(&self, p: [f64; 2]) -> [usize; 2] {
        [0, 1].map(|k| {
            (((p[k] - self.origin[k]) / self.cell).max(0.0) as usize).min(self.dims[k] - 1)
        })
    }

    /// The nearest centre to `p` (squared distance, ties to the lower index): rings of cells
    /// around `p`'s cell until no unvisited cell can hold a nearer centre.
    fn nearest(&self, p: [f64; 2], centres: &[[f64; 2]]) -> u32 {
        let [cx, cy] = self.cell_of(p);
        let mut best = (f64::INFINITY, u32::MAX);
        let max_ring = self.dims[0].max(self.dims[1]);
        for ring in 0..=max_ring {
            let (x0, x1) = (cx as i64 - ring as i64, cx as i64 + ring as i64);
            let (y0, y1) = (cy as i64 - ring as i64, cy as i64 + ring as i64);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let on_ring = x == x0 || x == x1 || y == y0 || y == y1;
                    if !on_ring
                        || x < 0
                        || y < 0
                        || x >= self.dims[0] as i64
                        || y >= self.dims[1] as i64
                    {
                        continue;
                    }
                    for &i in &self.cells[y as usize * self.dims[0] + x as usize] {
                        let c = centres[i as usize];
                        let d = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
                        if d < best.0 || (d == best.0 && i < best.1) {
                            best = (d, i);
                        }
                    }
                }
            }
            // Every centre in a later ring is at least `ring * cell` away (p may lie outside
            // the grid's box, then the bound only grows: the clamp moves p's cell towards it).
            let reach = ring as f64 * self.cell;
            if best.1 != u32::MAX && best.0 <= reach * reach {
                break;
            }
        }
        best.1
    }
}

/// Size-constrained k-means over one mesh's trees (module docs): the clusters of `trees` (indices
/// into `spheres`; `cap >= 1`), each of at most `cap` trees, in the order the hierarchy's nodes
/// take. What [`Hierarchy::build`] runs per mesh for [`HierarchyMode::Kmeans`]; public so that the
/// builder's contract can be property-tested on its own.
pub fn kmeans(trees: &[u32], spheres: &[([f32; 3], f32)], cap: usize) -> Vec<Vec<u32>> {
    let k = trees.len().div_ceil(cap);
    let mut seeds = Vec::with_capacity(k);
    bisect(&mut trees.to_vec(), k, spheres, &mut seeds);
    let centroid = |members: &[u32]| {
        let mut s = [0.0f64; 2];
        for &t in members {
            let p = xy(spheres, t);
            s[0] += p[0];
            s[1] += p[1];
        }
        let n = members.len().max(1) as f64;
        [s[0] / n, s[1] / n]
    };
    let mut centres: Vec<[f64; 2]> = seeds.iter().map(|m| centroid(m)).collect();
    // Trees in scene order (the indirection order within a cluster).
    let mut order = trees.to_vec();
    order.sort_unstable();
    let mut assign: Vec<u32> = vec![u32::MAX; order.len()];
    for _ in 0..KMEANS_ITERATIONS {
        let grid = CentreGrid::new(&centres);
        let next: Vec<u32> = order
            .par_iter()
            .map(|&t| grid.nearest(xy(spheres, t), &centres))
            .collect();
        if next == assign {
            break;
        }
        assign = next;
        let mut sums = vec![([0.0f64; 2], 0usize); centres.len()];
        for (&t, &c) in order.iter().zip(&assign) {
            let p = xy(spheres, t);
            let s = &mut sums[c as usize];
            s.0[0] += p[0];
            s.0[1] += p[1];
            s.1 += 1;
        }
        for (c, (s, n)) in centres.iter_mut().zip(sums) {
            if n > 0 {
                *c = [s[0] / n as f64, s[1] / n as f64];
            }
        }
    }
    let mut clusters: Vec<Vec<u32>> = vec![Vec::new(); centres.len()];
    for (&t, &c) in order.iter().zip(&assign) {
        clusters[c as usize].push(t);
    }
    // The size constraint: split oversized clusters in place; drop empty ones.
    let mut out = Vec::with_capacity(clusters.len());
    for mut c in clusters {
        if c.is_empty() {
            continue;
        }
        if c.len() <= cap {
            out.push(c);
            continue;
        }
        let mut parts = Vec::new();
        let parts_wanted = c.len().div_ceil(cap);
        bisect(&mut c, parts_wanted, spheres, &mut parts);
        for mut p in parts {
            p.sort_unstable();
            out.push(p);
        }
    }
    out
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

    /// The leaves of a built tree, depth first, each its trees in order.
    fn leaves(b: &Build) -> Vec<Vec<u32>> {
        match b {
            Build::Leaf(trees) => vec![trees.clone()],
            Build::Interior(children) => children.iter().flat_map(leaves).collect(),
        }
    }

    /// The quadtree's fallback at its boundary (module docs: "when a level would not at least
    /// halve ... grouped in its current order in runs"): a level of 4 trees the quadrant split
    /// puts into 2 cells halves exactly, so it keeps the cells (trees 0 and 2 west, 1 and 3 east),
    /// not runs of scene order; 3 trees in 2 cells do not halve, so they become runs. The trees
    /// alternate between two stands 100 m apart so that cells and runs differ. Added for issue
    /// 36's Rust mutant 1392 (`groups.len() * 2 > items.len()` -> `>=` at level 0, which made
    /// the 4-tree level runs `[0, 1], [2, 3]`).
    #[test]
    fn quadtree_level_that_exactly_halves_keeps_its_cells_and_one_that_does_not_becomes_runs() {
        let at = |x: f32| ([x, 0.0, 4.0], 3.0);
        let spheres = vec![at(0.0), at(100.0), at(1.0), at(101.0)];
        // The quadrant split alone: two cells of two, a tie (2 · 2 = 4 items).
        let items: Vec<([f64; 2], u32)> = spheres
            .iter()
            .enumerate()
            .map(|(i, (c, _))| ([c[0] as f64, c[1] as f64], i as u32))
            .collect();
        assert_eq!(quadtree_groups(&items, 2), vec![vec![0, 2], vec![1, 3]]);
        let tie = quadtree(vec![0, 1, 2, 3], &spheres, 2);
        assert_eq!(
            leaves(&tie),
            vec![vec![0, 2], vec![1, 3]],
            "4 trees in 2 cells (an exact halving) must keep the quadtree's cells"
        );
        // One tree fewer: 2 cells for 3 trees do not halve the level: runs of 2 in scene order.
        let past = quadtree(vec![0, 1, 2], &spheres, 2);
        assert_eq!(
            leaves(&past),
            vec![vec![0, 1], vec![2]],
            "3 trees in 2 cells (no halving) must fall back to runs of scene order"
        );
    }

    /// The centre grid's ring search is the brute-force nearest centre (ties to the lower index),
    /// for points inside and outside the centres' box. Mutation-checked: stopping at the first
    /// ring with a centre fails it.
    #[test]
    fn centre_grid_finds_the_nearest_centre() {
        let centres: Vec<[f64; 2]> = (0..200)
            .map(|i| [((i * 37) % 113) as f64 * 1.7, ((i * 91) % 61) as f64 * 3.1])
            .collect();
        let grid = CentreGrid::new(&centres);
        for j in 0..2000 {
            let p = [(j % 97) as f64 * 2.5 - 20.0, (j % 89) as f64 * 2.6 - 20.0];
            let d = |c: &[f64; 2]| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
            let want = (0..centres.len())
                .min_by(|&a, &b| d(&centres[a]).total_cmp(&d(&centres[b])).then(a.cmp(&b)))
                .unwrap() as u32;
            assert_eq!(grid.nearest(p, &centres), want, "point {p:?}");
        }
    }

    /// Density-aware: a dense patch (100x the density of its surroundings) gets clusters of
    /// about `cap` trees like the sparse part, never more than `cap`; every tree in exactly one.
    /// Mutation-checked: dropping the median split of oversized clusters fails it (and
    /// `hierarchy_properties`' leaf-size check).
    #[test]
    fn kmeans_clusters_hold_at_most_cap_trees_whatever_the_density() {
        let mut spheres = Vec::new();
        for i in 0..2000u32 {
            // 1000 trees in a 100 m square, 1000 in a 1 km square.
            let (side, k) = if i < 1000 {
                (100.0, i)
            } else {
                (1000.0, i - 1000)
            };
            let x = ((k * 7919) % 1000) as f32 / 1000.0 * side;
            let y = ((k * 104_729) % 997) as f32 / 997.0 * side;
            spheres.push(([x, y, 0.0], 5.0));
        }
        let trees: Vec<u32> = (0..2000).collect();
        let clusters = kmeans(&trees, &spheres, 50);
        let mut all: Vec<u32> = clusters.concat();
        all.sort_unstable();
        assert_eq!(all, trees);
        assert!(clusters.iter().all(|c| !c.is_empty() && c.len() <= 50));
        let mean = 2000.0 / clusters.len() as f64;
        assert!(mean >= 25.0, "{} clusters, mean {mean}", clusters.len());
    }
}
