//! The far level's bake (issue 32 item 2): Guerrero's octant impostors (G§2.1-2.4) per
//! hierarchy node, filling a [`FarLevel`]'s nodes and cells. The twin of
//! `gpu/src/shaders/far_bake.wgsl`; the formulas both use (cell grid, views, reduction,
//! dropping, parent rules) live in `forestlod_shared::far_bake`, whose module docs are the
//! contract in full. In short:
//!
//! - **Box** (G§2.1 "tight octree", extent = content): a node's box is
//!   `box_center ± extent` of its [`forestlod_shared::NodeMeta`] (the box of its trees' spheres).
//! - **Leaves** (`child_count == 0`; G§2.2 "rendered from six sides and averaged", G§2.4
//!   clustering in 3D): the box is cut into `cs³` cells (`cs = cluster_size`); per side and
//!   per slice of `cs` along its axis, one orthographic render of the node's trees
//!   (`h.indirection[offset..offset + len]`) at `(cs · FAR_BAKE_PIXELS)²` pixels, window = the
//!   box's cross-section, near and far = the slice's planes; each cell's `8²` block reduces to
//!   RGBA (alpha = coverage, colour = alpha-weighted mean linear colour).
//! - **The render** is the draw's LOD0 path, unlit: each tree's mesh at `base + Rz(yaw) · scale
//!   · local` ([`forestlod_shared::far_bake::tree_point`]), its texture sampled trilinear with the
//!   implicit level of detail of the `uv` derivatives, texels with alpha below
//!   `params.alpha_cutoff` discarded, kept ones opaque; depth test LESS, no culling; the
//!   reference rasterizer ([`crate::raster`]), so the GPU's rules. A tree whose sphere does not
//!   reach a slice is skipped there (it would be clipped away whole).
//! - **Cells** whose six alphas are all below `FAR_ALPHA_MIN` are dropped (G§2.4); the kept ones
//!   are stored node by node in cell order, `FarNode { cell_offset, cell_count, 0, 0 }`.
//! - **Interior nodes** (G§2.2) from their children's kept cells by `params.parent_rule`:
//!   `average` (the seed) or `composite` (occlusion-aware, "over" along each side).
//! - **Deterministic**: leaves render in parallel (rayon), each into its own targets (which are
//!   bit-identical for any thread count, [`crate::raster`]), collected in node order; interior
//!   nodes are then made sequentially. Memory: [`FarLevel::bytes`] (`48 B` a cell, of which
//!   `24 B` colours, G§2.4's `6 × clusterSize³` colours per node).

use forestlod_shared::far_bake::{
    FarView, assemble_far_level, cell_count, scatter_slice, tree_point,
};
use forestlod_shared::{
    FarLevel, FarVertex, ParamError, Params, SIDE_COUNT, pack_far_colour, side_mix,
    unpack_far_colour,
};
use rayon::prelude::*;

use crate::geometry::PackedGeometry;
use crate::hierarchy::Hierarchy;
use crate::raster::{
    ClearValues, DrawState, Fragment, FragmentOutput, RenderTarget, Vertex, round_exact,
};
use crate::sampler::{Sampler, Texture};
use crate::scene::{Scene, tree_sphere};
use crate::texture::Rgba8Image;

/// Varyings of the far bake's render: `u, v, mesh`.
pub const FAR_BAKE_VARYINGS: usize = 3;

/// One tree of a node, placed in the world: its sphere (what [`FarView::reaches`] tests) and its
/// triangles (world position, `uv`).
#[derive(Clone, Debug)]
pub struct PlacedTree {
    /// Bounding-sphere centre ([`tree_sphere`]).
    pub center: [f32; 3],
    /// Bounding-sphere radius.
    pub radius: f32,
    /// The tree's mesh (its texture).
    pub mesh: u32,
    /// Triangle list: world position and texture coordinate per corner.
    pub triangles: Vec<[([f32; 3], [f32; 2]); 3]>,
}

/// The trees of node `node` of `h`, placed ([`PlacedTree`]).
pub fn placed_trees(
    h: &Hierarchy,
    scene: &Scene,
    geometry: &PackedGeometry,
    node: usize,
) -> Vec<PlacedTree> {
    let n = &h.nodes[node];
    h.indirection[n.offset as usize..(n.offset + n.len) as usize]
        .iter()
        .map(|&t| {
            let tree = &scene.instances[t as usize];
            let meta = &geometry.meshes[tree.mesh as usize];
            let (center, radius) = tree_sphere(tree, meta);
            let (sin, cos) = tree.yaw.sin_cos();
            let first = meta.first_vertex as usize;
            let index = &geometry.indices
                [meta.first_index as usize..(meta.first_index + meta.index_count) as usize];
            let triangles = index
                .chunks_exact(3)
                .map(|t| {
                    core::array::from_fn(|k| {
                        let v = geometry.vertices[first + t[k] as usize];
                        (
                            tree_point(tree.position, sin, cos, tree.scale, v.position),
                            v.uv,
                        )
                    })
                })
                .collect();
            PlacedTree {
                center,
                radius,
                mesh: tree.mesh,
                triangles,
            }
        })
        .collect()
}

/// Renders `trees` in `view` (module docs; its alpha test at `view.alpha_cutoff`): the
/// `(cs · FAR_BAKE_PIXELS)²` slice image.
pub fn render_view(trees: &[PlacedTree], mesh_textures: &[Texture], view: &FarView) -> Rgba8Image {
    let alpha_cutoff = view.alpha_cutoff;
    let triangles: Vec<[Vertex<FAR_BAKE_VARYINGS>; 3]> = trees
        .iter()
        .filter(|t| view.reaches(t.center, t.radius))
        .flat_map(|t| {
            t.triangles.iter().map(|tri| {
                core::array::from_fn(|k| {
                    let (p, uv) = tri[k];
                    Vertex::new(view.clip(p), [uv[0], uv[1], t.mesh as f32])
                })
            })
        })
        .collect();
    let shader = |f: &Fragment<FAR_BAKE_VARYINGS>| {
        let [u, v, mesh] = f.varyings;
        let texture = &mesh_textures[round_exact(mesh) as usize];
        let texel = texture.sample(
            &Sampler::TRILINEAR,
            0,
            [u, v],
            [f.ddx[0], f.ddx[1]],
            [f.ddy[0], f.ddy[1]],
        );
        (texel[3] >= alpha_cutoff).then_some(FragmentOutput {
            color: [texel[0], texel[1], texel[2], 1.0],
            id: 1,
            depth: None,
        })
    };
    let w = view.image_side();
    let mut target = RenderTarget::new(w, w, ClearValues::default());
    target.draw(&triangles, &shader, &DrawState::OPAQUE);
    target.color_image()
}

/// The `cs³` cells' side colours of one leaf's placed trees (cell-number order; module docs).
pub fn leaf_cells(
    center: [f32; 3],
    extent: [f32; 3],
    trees: &[PlacedTree],
    mesh_textures: &[Texture],
    params: &Params,
) -> Vec<[u32; SIDE_COUNT]> {
    let cs = params.cluster_size;
    let mut raw = vec![[0u32; SIDE_COUNT]; cell_count(cs)];
    for side in 0..SIDE_COUNT {
        for slice in 0..cs {
            let view = FarView::with_cutoff(center, extent, cs, side, slice, params.alpha_cutoff);
            let image = render_view(trees, mesh_textures, &view);
            scatter_slice(&view, &image.texels, &mut raw);
        }
    }
    raw
}

/// The far level of hierarchy `h` over `scene` (module docs): `geometry` and `mesh_textures`
/// are the draw's ([`crate::pipeline::Prepared`]). Refuses invalid `params` (a
/// [`ParamError`] naming the field: `cluster_size` out of `1..=12`, an unknown `parent_rule`).
pub fn far_bake(
    h: &Hierarchy,
    scene: &Scene,
    geometry: &PackedGeometry,
    mesh_textures: &[Texture],
    params: &Params,
) -> Result<FarLevel, ParamError> {
    params.validate()?;
    let rule = params.far_parent_rule()?;
    let leaves: Vec<Option<Vec<[u32; SIDE_COUNT]>>> = (0..h.nodes.len())
        .into_par_iter()
        .map(|i| {
            let n = &h.nodes[i];
            (n.child_count == 0).then(|| {
                let trees = placed_trees(h, scene, geometry, i);
                leaf_cells(n.box_center, n.extent, &trees, mesh_textures, params)
            })
        })
        .collect();
    Ok(assemble_far_level(
        &h.nodes,
        params.cluster_size,
        rule,
        leaves,
    ))
}

/// Batch hulls (issue 32 item 4, E§7 "an entire batch as a single opaque ultra-low-polygon-count
/// mesh, of similar shape to the convex hull of the batch"): each node's convex hull
/// ([`crate::hull::batch_hull`] of its trees' boxes, at most `MAX_HULL_TRIANGLES` triangles),
/// every triangle coloured by its outward normal `n` from the node's six side colours
/// ([`forestlod_shared::side_mix`], `w_a = n_a²`: a face that looks along `+X` shows the node's
/// `+X` side), opaque. The node's six colours are its kept cells' per side, alpha-weighted (its
/// one cell under `cluster_size = 1`); a side no cell covers takes the mean of the covered ones.
/// A node without kept cells gets no hull (it never goes far). Deterministic: nodes in parallel,
/// collected in node order.
pub fn far_hulls(
    level: &mut FarLevel,
    h: &Hierarchy,
    scene: &Scene,
    meshes: &[forestlod_shared::MeshMeta],
) -> Result<(), crate::hull::HullError> {
    let hulls: Vec<Vec<FarVertex>> = (0..h.nodes.len())
        .into_par_iter()
        .map(|i| {
            let far = level.nodes[i];
            if far.cell_count == 0 {
                return Ok(Vec::new());
            }
            let n = &h.nodes[i];
            let trees = &h.indirection[n.offset as usize..(n.offset + n.len) as usize];
            let boxes = crate::hull::tree_boxes(scene, meshes, trees);
            let triangles = crate::hull::batch_hull(&boxes)?;
            let cells =
                &level.cells[far.cell_offset as usize..(far.cell_offset + far.cell_count) as usize];
            let colours = node_side_colours(cells);
            Ok(triangles
                .iter()
                .flat_map(|t| {
                    let colour = pack_far_colour(side_mix(&colours, face_normal(t)));
                    let opaque = colour | 0xff00_0000;
                    t.map(|position| FarVertex {
                        position,
                        colour: opaque,
                    })
                })
                .collect())
        })
        .collect::<Result<_, _>>()?;
    for (node, vertices) in level.nodes.iter_mut().zip(hulls) {
        node.hull_offset = level.hull.len() as u32;
        node.hull_count = vertices.len() as u32;
        level.hull.extend(vertices);
    }
    Ok(())
}

/// A node's six side colours from its kept cells (alpha-weighted per side, opaque), for its hull.
fn node_side_colours(cells: &[forestlod_shared::FarCell]) -> [u32; SIDE_COUNT] {
    let mut sums = [[0.0f64; 4]; SIDE_COUNT];
    for c in cells {
        for (s, sum) in sums.iter_mut().enumerate() {
            let [r, g, b, a] = unpack_far_colour(c.colours[s]);
            let a = a as f64;
            sum[0] += r as f64 * a;
            sum[1] += g as f64 * a;
            sum[2] += b as f64 * a;
            sum[3] += a;
        }
    }
    let covered: Vec<[f64; 3]> = sums
        .iter()
        .filter(|s| s[3] > 0.0)
        .map(|s| [s[0] / s[3], s[1] / s[3], s[2] / s[3]])
        .collect();
    let fallback = if covered.is_empty() {
        [0.0; 3]
    } else {
        let k = covered.len() as f64;
        [0, 1, 2].map(|j| covered.iter().map(|c| c[j]).sum::<f64>() / k)
    };
    sums.map(|s| {
        let rgb = if s[3] > 0.0 {
            [s[0] / s[3], s[1] / s[3], s[2] / s[3]]
        } else {
            fallback
        };
        pack_far_colour([rgb[0] as f32, rgb[1] as f32, rgb[2] as f32, 1.0])
    })
}

/// The unit outward normal of a counter-clockwise triangle (`+Z` for a degenerate one).
fn face_normal(t: &[[f32; 3]; 3]) -> [f32; 3] {
    let [a, b, c] = t.map(|p| p.map(f64::from));
    let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len > 0.0 {
        n.map(|x| (x / len) as f32)
    } else {
        [0.0, 0.0, 1.0]
    }
}
