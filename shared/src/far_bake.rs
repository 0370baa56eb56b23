//! The far level's bake formulas (issue 32 item 2; G§2.2-2.4, the design study's §G1) that the
//! reference (`reference/src/far_bake.rs`) and the GPU twin (`gpu/src/far_bake.rs`,
//! `gpu/src/shaders/far_bake.wgsl`) share: the cell grid, the orthographic slice views, the
//! reduction of a cell's pixel block to one side colour, and the **whole** assembly of a
//! [`FarLevel`] from the leaves' cells (dropping, both parent rules). The GPU twin renders and
//! reduces the leaves; the parent rules run on the CPU from its leaf cells, through this module
//! (no WGSL port: they are a small sequential pass over the kept cells).
//!
//! ## Contract
//! - **Cell grid** (G§2.4, read in 3D): a node's box `box_center ± extent` (content-tight,
//!   G§2.1, `crate::far` module docs) is cut into `cs³` equal cells, `cs = cluster_size`, by the
//!   planes [`grid_plane`] `lo + (hi − lo)·j/cs` (`j = cs` is `hi` exactly), per axis. Cell
//!   `(i0, i1, i2)` (along X, Y, Z) is number `i0 + cs·(i1 + cs·i2)` ([`cell_index`]).
//! - **Views** (G§2.2 "rendered from six sides", G§2.4 "6 × clusterSize sides"): side `s`
//!   ([`crate::side_of`], axis `a = s / 2`) and slice `k` (`0..cs` along `a`) is one orthographic
//!   render looking along `-side_normal(s)` ([`FarView`]): window = the box's cross-section,
//!   near and far planes = the slice's bounding planes (the eye on the `+a` side for even `s`,
//!   so the slice's upper plane is near), `(cs · FAR_BAKE_PIXELS)²` pixels.
//! - **Image orientation** ([`image_axes`]): image right is the first axis of
//!   `image_axes(a)`, image up the second: `(Y, Z)` for the X sides, `(X, Z)` for the Y sides
//!   (trees upright in both), `(X, Y)` for the Z sides. The same for both sides of an axis, so
//!   the `-a` view is the mirror image of what an eye there would see: the projection is still
//!   orthographic and nothing is culled, so coverage and colour are those of the unmirrored view
//!   (up to which of two triangles sharing an edge owns a pixel centre on it). Block `(bx, by)`
//!   (pixels `8bx..8bx + 8` from the left, `8by..8by + 8` from the top) is the cell with
//!   `i_right = bx`, `i_up = cs − 1 − by`, `i_a = k` ([`FarView::block_cell`]).
//! - **Reduction** ([`far_block_colour`], design study G1 "use RGBA"): a block's
//!   `FAR_BAKE_PIXELS²` pixels (RGBA8, sRGB colour) give alpha = mean pixel alpha and colour =
//!   the alpha-weighted mean of the pixels' linear colours (0 when no pixel is covered), summed
//!   row by row in `f32`, packed with [`pack_far_colour`].
//! - **Dropping** (G§2.4 "too little alpha"): a cell whose six alphas are all below
//!   [`FAR_ALPHA_MIN`] is dropped ([`cell_is_empty`]): one covered pixel of 64 keeps it (its
//!   alpha byte is 4, `4/255 ≥ 1/64`). Kept cells are stored per node in cell-number order.
//! - **Parents** (G§2.2): an interior node's cells are the `cs³` grid over **its** box; each
//!   gathers the children's kept cells whose centre lies in it ([`cell_of`]: half-open along the
//!   planes, the last cell closed, points outside clamped to the nearest cell, so every child
//!   cell is gathered exactly once). Per side, by [`ParentRule`]:
//!   - `average` (the seed, [`average_side`]): alpha = the mean of the gathered cells' alphas on
//!     that side, **over every gathered cell** (a gathered cell transparent on this side counts as
//!     alpha 0; a child's dropped cells and empty space are not gathered and do not count, as the
//!     seed averages the children it has); colour = the alpha-weighted mean of their colours. So
//!     each channel lies between the gathered cells' least and greatest (8-bit, exactly: the mean
//!     of decoded bytes re-encodes between them).
//!   - `composite` (occlusion-aware, [`composite_side`]): each gathered cell's box, clipped to the
//!     parent cell, is projected on the parent's face `⊥ a` as a rectangle of the cell's uniform
//!     colour and alpha on side `s`, ordered front to back by its clipped box's centre along `a`
//!     (ties by gathering order); on the arrangement of every rectangle edge (and the face's own),
//!     each sub-rectangle composites the rectangles covering it with "over" (premultiplied); the
//!     parent side's colour = the area integral of premultiplied colour / that of alpha, its
//!     alpha = the alpha integral / the face's area. **Cost**: `m` gathered cells give at most
//!     `(2m + 1)²` sub-rectangles, each testing `m` rectangles: `O(m³)` per side, every loop
//!     bounded by `m`. `m` is about `2³` (octree) or `2²` (quadtree) per parent cell when the
//!     children's boxes are half the parent's; a child much smaller than its parent can put all
//!     its `cs³` cells in one parent cell, the worst case `m = children · cs³`.
//! - Pure functions of their inputs in a fixed order: the result does not depend on threads.

use bytemuck::{Pod, Zeroable};

use crate::far::{
    FAR_ALPHA_MIN, FAR_BAKE_PIXELS, FarCell, FarLevel, FarNode, ParentRule, SIDE_COUNT,
    pack_far_colour, unpack_far_colour,
};
use crate::{NO_PARENT, NodeMeta};

/// Cells of a node at cluster size `cs`: `cs³`.
pub fn cell_count(cs: u32) -> usize {
    (cs as usize).pow(3)
}

/// The image's (right, up) world axes for the views along `axis` (module docs).
pub const fn image_axes(axis: usize) -> [usize; 2] {
    match axis {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    }
}

/// Plane `j` (`0..=cs`) of the split of `[lo, hi]` into `cs` equal parts; `j = cs` is `hi`.
pub fn grid_plane(lo: f32, hi: f32, cs: u32, j: u32) -> f32 {
    if j >= cs {
        hi
    } else {
        lo + (hi - lo) * (j as f32 / cs as f32)
    }
}

/// The box `center ± extent` as its corners `(lo, hi)`.
pub fn node_bounds(center: [f32; 3], extent: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    (
        core::array::from_fn(|k| center[k] - extent[k]),
        core::array::from_fn(|k| center[k] + extent[k]),
    )
}

/// Cell number of `(i0, i1, i2)` at cluster size `cs` (module docs).
pub fn cell_index(cs: u32, i: [u32; 3]) -> usize {
    (i[0] + cs * (i[1] + cs * i[2])) as usize
}

/// The cell coordinates of cell number `n` (inverse of [`cell_index`]).
pub fn cell_coords(cs: u32, n: usize) -> [u32; 3] {
    let n = n as u32;
    [n % cs, (n / cs) % cs, n / (cs * cs)]
}

/// The corners `(lo, hi)` of cell `i` of the box `[lo, hi]` at cluster size `cs`.
pub fn cell_bounds(lo: [f32; 3], hi: [f32; 3], cs: u32, i: [u32; 3]) -> ([f32; 3], [f32; 3]) {
    (
        core::array::from_fn(|k| grid_plane(lo[k], hi[k], cs, i[k])),
        core::array::from_fn(|k| grid_plane(lo[k], hi[k], cs, i[k] + 1)),
    )
}

/// A [`FarCell`] box (centre, half-size) from its corners.
pub fn cell_box(lo: [f32; 3], hi: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    (
        core::array::from_fn(|k| (lo[k] + hi[k]) * 0.5),
        core::array::from_fn(|k| (hi[k] - lo[k]) * 0.5),
    )
}

/// The cell of the box `[lo, hi]` (cluster size `cs`) holding point `p` (module docs: half-open
/// along the planes of [`grid_plane`], the last cell closed, outside points clamped).
pub fn cell_of(lo: [f32; 3], hi: [f32; 3], cs: u32, p: [f32; 3]) -> [u32; 3] {
    core::array::from_fn(|k| {
        let t = (p[k] - lo[k]) / (hi[k] - lo[k]) * cs as f32;
        // A first guess (NaN and out-of-box points to the ends), then exact against the planes.
        let mut i = (t.floor().max(0.0).min((cs - 1) as f32)) as u32;
        while i > 0 && p[k] < grid_plane(lo[k], hi[k], cs, i) {
            i -= 1;
        }
        while i + 1 < cs && p[k] >= grid_plane(lo[k], hi[k], cs, i + 1) {
            i += 1;
        }
        i
    })
}

/// One orthographic slice view of the bake (module docs): `clip = ((p_r − c_r)/e_r,
/// (p_u − c_u)/e_u, (p_a − near)·depth_scale, 1)` with `(r, u) = image_axes(a)`. The constants
/// are computed here once, on the CPU, for both twins (`far_bake.wgsl`'s `FarView`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FarView {
    /// Image-right world axis.
    pub right: u32,
    /// Image-up world axis.
    pub up: u32,
    /// View axis `a`.
    pub axis: u32,
    /// Cluster size `cs` (cells per image side).
    pub cs: u32,
    /// Box centre along `right` and `up`.
    pub center: [f32; 2],
    /// `1 / extent` along `right` and `up`.
    pub inv_extent: [f32; 2],
    /// The slice's near plane along `axis` (depth 0).
    pub near: f32,
    /// The slice's far plane along `axis` (depth 1).
    pub far: f32,
    /// `1 / (far − near)`: depth 1 at the far plane.
    pub depth_scale: f32,
    /// Side (`0..6`).
    pub side: u32,
    /// Slice (`0..cs`).
    pub slice: u32,
    /// The alpha test's cutoff (`params.alpha_cutoff`; the GPU's fragment stage reads it here,
    /// the reference's shader from `params`).
    pub alpha_cutoff: f32,
    /// Padding to 16-byte rows.
    pub _pad: [u32; 2],
}
const _: () = assert!(core::mem::size_of::<FarView>() == 64);

impl FarView {
    /// The view of slice `slice` from side `side` of the box `center ± extent` at cluster size
    /// `cs` (module docs).
    pub fn new(center: [f32; 3], extent: [f32; 3], cs: u32, side: usize, slice: u32) -> Self {
        Self::with_cutoff(center, extent, cs, side, slice, 0.0)
    }

    /// [`FarView::new`] with the alpha test's cutoff `alpha_cutoff`.
    pub fn with_cutoff(
        center: [f32; 3],
        extent: [f32; 3],
        cs: u32,
        side: usize,
        slice: u32,
        alpha_cutoff: f32,
    ) -> Self {
        let axis = side / 2;
        let [right, up] = image_axes(axis);
        let (lo, hi) = node_bounds(center, extent);
        let (below, above) = (
            grid_plane(lo[axis], hi[axis], cs, slice),
            grid_plane(lo[axis], hi[axis], cs, slice + 1),
        );
        // The eye on the +a side looks along -a: the upper plane is near.
        let (near, far) = if side.is_multiple_of(2) {
            (above, below)
        } else {
            (below, above)
        };
        let span = far - near;
        let span = if span.abs() >= f32::MIN_POSITIVE {
            span
        } else {
            f32::MIN_POSITIVE.copysign(span)
        };
        let inv = |e: f32| 1.0 / e.max(f32::MIN_POSITIVE);
        Self {
            right: right as u32,
            up: up as u32,
            axis: axis as u32,
            cs,
            center: [center[right], center[up]],
            inv_extent: [inv(extent[right]), inv(extent[up])],
            near,
            far,
            depth_scale: 1.0 / span,
            side: side as u32,
            slice,
            alpha_cutoff,
            _pad: [0; 2],
        }
    }

    /// Whether a sphere (centre `center`, radius `radius`) reaches the slice along its axis: a
    /// tree whose sphere does not is clipped away whole, so the bake skips it (an equality: its
    /// triangles lie inside its sphere, [`tree_point`]).
    pub fn reaches(&self, center: [f32; 3], radius: f32) -> bool {
        let c = center[self.axis as usize];
        let (lo, hi) = (self.near.min(self.far), self.near.max(self.far));
        c + radius >= lo && c - radius <= hi
    }

    /// Clip-space position of world point `p` (struct docs).
    pub fn clip(&self, p: [f32; 3]) -> [f32; 4] {
        [
            (p[self.right as usize] - self.center[0]) * self.inv_extent[0],
            (p[self.up as usize] - self.center[1]) * self.inv_extent[1],
            (p[self.axis as usize] - self.near) * self.depth_scale,
            1.0,
        ]
    }

    /// The image's side in pixels, `cs · FAR_BAKE_PIXELS`.
    pub fn image_side(&self) -> u32 {
        self.cs * FAR_BAKE_PIXELS
    }

    /// The cell number shown by pixel block `(bx, by)` (module docs).
    pub fn block_cell(&self, bx: u32, by: u32) -> usize {
        let mut i = [0u32; 3];
        i[self.right as usize] = bx;
        i[self.up as usize] = self.cs - 1 - by;
        i[self.axis as usize] = self.slice;
        cell_index(self.cs, i)
    }
}

/// One corner of a node's world-space triangle list as the GPU twin's vertex buffer holds it:
/// [`tree_point`] of a mesh vertex, its texture coordinate and the tree's mesh (its layer of
/// the mesh texture array). Keep in sync with `gpu/src/far_bake.rs`'s vertex layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FarBakeVertex {
    /// World position.
    pub position: [f32; 3],
    /// The tree's mesh.
    pub mesh: u32,
    /// Texture coordinate.
    pub uv: [f32; 2],
}
const _: () = assert!(core::mem::size_of::<FarBakeVertex>() == 24);

/// A tree's mesh-local point `local` in the world: `base + Rz(yaw) · scale · local`, with
/// `(sin, cos)` of the yaw (the draw's LOD0 vertex transform, `reference/src/draw.rs`, written
/// out once here so that both bakes place the trees alike).
pub fn tree_point(base: [f32; 3], sin: f32, cos: f32, scale: f32, local: [f32; 3]) -> [f32; 3] {
    let p = [local[0] * scale, local[1] * scale, local[2] * scale];
    [
        base[0] + (cos * p[0] - sin * p[1]),
        base[1] + (sin * p[0] + cos * p[1]),
        base[2] + p[2],
    ]
}

/// Side colour of pixel block `(bx, by)` of a `width`-wide RGBA8 image (row-major, sRGB
/// colour), module docs' reduction.
pub fn far_block_colour(texels: &[[u8; 4]], width: u32, bx: u32, by: u32) -> u32 {
    let n = FAR_BAKE_PIXELS;
    let mut sum_a = 0.0f32;
    let mut sum_c = [0.0f32; 3];
    for y in by * n..(by + 1) * n {
        for x in bx * n..(bx + 1) * n {
            let t = texels[(y * width + x) as usize];
            let a = t[3] as f32 / 255.0;
            for k in 0..3 {
                sum_c[k] += a * crate::srgb_to_linear(t[k]);
            }
            sum_a += a;
        }
    }
    block_colour(sum_c, sum_a)
}

/// The packed colour of a block's sums (module docs): alpha `sum_a / FAR_BAKE_PIXELS²`, colour
/// `sum_c / sum_a` (0 for an empty block).
pub fn block_colour(sum_c: [f32; 3], sum_a: f32) -> u32 {
    let c = if sum_a > 0.0 {
        [sum_c[0] / sum_a, sum_c[1] / sum_a, sum_c[2] / sum_a]
    } else {
        [0.0; 3]
    };
    let alpha = sum_a / (FAR_BAKE_PIXELS * FAR_BAKE_PIXELS) as f32;
    pack_far_colour([c[0], c[1], c[2], alpha])
}

/// Writes the side colours of every block of one slice image ([`FarView::image_side`] square,
/// RGBA8) into `raw` (one `[u32; 6]` per cell number, `cs³` of them).
pub fn scatter_slice(view: &FarView, texels: &[[u8; 4]], raw: &mut [[u32; SIDE_COUNT]]) {
    let w = view.image_side();
    for by in 0..view.cs {
        for bx in 0..view.cs {
            raw[view.block_cell(bx, by)][view.side as usize] = far_block_colour(texels, w, bx, by);
        }
    }
}

/// The linear alpha of a packed side colour.
pub fn side_alpha(c: u32) -> f32 {
    (c >> 24) as f32 / 255.0
}

/// Whether a cell is dropped: every side's alpha below [`FAR_ALPHA_MIN`] (G§2.4).
pub fn cell_is_empty(colours: &[u32; SIDE_COUNT]) -> bool {
    colours.iter().all(|&c| side_alpha(c) < FAR_ALPHA_MIN)
}

/// A node's kept cells from its `cs³` cells' colours `raw` (cell-number order), its box `[lo,
/// hi]`.
pub fn keep_cells(lo: [f32; 3], hi: [f32; 3], cs: u32, raw: &[[u32; SIDE_COUNT]]) -> Vec<FarCell> {
    raw.iter()
        .enumerate()
        .filter(|(_, c)| !cell_is_empty(c))
        .map(|(n, c)| {
            let (clo, chi) = cell_bounds(lo, hi, cs, cell_coords(cs, n));
            let (center, extent) = cell_box(clo, chi);
            FarCell {
                center,
                extent,
                colours: *c,
            }
        })
        .collect()
}

/// `average` (module docs): the side colour of the gathered cells' side colours `sides`.
pub fn average_side(sides: &[u32]) -> u32 {
    if sides.is_empty() {
        return 0;
    }
    let (mut sum_a, mut sum_c) = (0.0f64, [0.0f64; 3]);
    for &c in sides {
        let l = unpack_far_colour(c);
        let a = l[3] as f64;
        for k in 0..3 {
            sum_c[k] += a * l[k] as f64;
        }
        sum_a += a;
    }
    let c: [f32; 3] = if sum_a > 0.0 {
        core::array::from_fn(|k| (sum_c[k] / sum_a) as f32)
    } else {
        [0.0; 3]
    };
    pack_far_colour([c[0], c[1], c[2], (sum_a / sides.len() as f64) as f32])
}

/// `composite` (module docs): side `side` of the parent cell `[plo, phi]` from the gathered
/// cells `cells`, in gathering order.
pub fn composite_side(plo: [f32; 3], phi: [f32; 3], side: usize, cells: &[FarCell]) -> u32 {
    let a = side / 2;
    let [r, u] = image_axes(a);
    // (rectangle on the face, depth key, linear colour) of every cell that reaches the face.
    let mut rects: Vec<([f64; 4], f64, [f32; 4])> = Vec::with_capacity(cells.len());
    for c in cells {
        let clip = |k: usize| {
            let lo = (c.center[k] - c.extent[k]).max(plo[k]) as f64;
            let hi = (c.center[k] + c.extent[k]).min(phi[k]) as f64;
            (lo, hi)
        };
        let ((r0, r1), (u0, u1), (a0, a1)) = (clip(r), clip(u), clip(a));
        if !(r1 > r0 && u1 > u0) {
            continue;
        }
        // Front first: the largest centre along a seen from +a, the smallest from -a.
        let centre = (a0 + a1) * 0.5;
        let key = if side.is_multiple_of(2) {
            -centre
        } else {
            centre
        };
        rects.push(([r0, r1, u0, u1], key, unpack_far_colour(c.colours[side])));
    }
    // Stable: ties keep the gathering order.
    rects.sort_by(|x, y| x.1.total_cmp(&y.1));
    let face = [plo[r] as f64, phi[r] as f64, plo[u] as f64, phi[u] as f64];
    let face_area = (face[1] - face[0]) * (face[3] - face[2]);
    let edges = |lo: usize| {
        let mut e: Vec<f64> = rects.iter().flat_map(|x| [x.0[lo], x.0[lo + 1]]).collect();
        e.extend([face[lo], face[lo + 1]]);
        e.sort_by(f64::total_cmp);
        e.dedup();
        e
    };
    let (xs, ys) = (edges(0), edges(2));
    let (mut sum_c, mut sum_a) = ([0.0f64; 3], 0.0f64);
    for xw in xs.windows(2) {
        let mx = (xw[0] + xw[1]) * 0.5;
        for yw in ys.windows(2) {
            let my = (yw[0] + yw[1]) * 0.5;
            let area = (xw[1] - xw[0]) * (yw[1] - yw[0]);
            let (mut acc_c, mut acc_a) = ([0.0f64; 3], 0.0f64);
            for (b, _, col) in &rects {
                if acc_a >= 1.0 {
                    break;
                }
                if mx > b[0] && mx < b[1] && my > b[2] && my < b[3] {
                    let t = (1.0 - acc_a) * col[3] as f64;
                    for k in 0..3 {
                        acc_c[k] += t * col[k] as f64;
                    }
                    acc_a += t;
                }
            }
            for k in 0..3 {
                sum_c[k] += acc_c[k] * area;
            }
            sum_a += acc_a * area;
        }
    }
    let c: [f32; 3] = if sum_a > 0.0 {
        core::array::from_fn(|k| (sum_c[k] / sum_a) as f32)
    } else {
        [0.0; 3]
    };
    let alpha = if face_area > 0.0 {
        sum_a / face_area
    } else {
        0.0
    };
    pack_far_colour([c[0], c[1], c[2], alpha as f32])
}

/// An interior node's kept cells (module docs) over its box `[lo, hi]` from its children's kept
/// cells `children` (child order, each child's cells in order).
pub fn parent_cells(
    rule: ParentRule,
    lo: [f32; 3],
    hi: [f32; 3],
    cs: u32,
    children: &[FarCell],
) -> Vec<FarCell> {
    let mut gathered: Vec<Vec<FarCell>> = vec![Vec::new(); cell_count(cs)];
    for c in children {
        gathered[cell_index(cs, cell_of(lo, hi, cs, c.center))].push(*c);
    }
    let raw: Vec<[u32; SIDE_COUNT]> = gathered
        .iter()
        .enumerate()
        .map(|(n, cells)| {
            if cells.is_empty() {
                return [0; SIDE_COUNT];
            }
            core::array::from_fn(|s| match rule {
                ParentRule::Average => {
                    let sides: Vec<u32> = cells.iter().map(|c| c.colours[s]).collect();
                    average_side(&sides)
                }
                ParentRule::Composite => {
                    let (plo, phi) = cell_bounds(lo, hi, cs, cell_coords(cs, n));
                    composite_side(plo, phi, s, cells)
                }
            })
        })
        .collect();
    keep_cells(lo, hi, cs, &raw)
}

/// The children of every node (child order = index order), from the `parent` links.
pub fn node_children(nodes: &[NodeMeta]) -> Vec<Vec<usize>> {
    let mut children = vec![Vec::new(); nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if n.parent != NO_PARENT && (n.parent as usize) < nodes.len() {
            children[n.parent as usize].push(i);
        }
    }
    children
}

/// The far level of a hierarchy (module docs) from its leaves' `cs³` cell colours: `leaves[i]`
/// is `Some(raw)` for every leaf `i` (`child_count == 0`) and `None` for interior nodes.
/// Interior nodes are made from their children in reverse node order (children follow their
/// parent in depth-first pre-order); cells are stored node by node in node order.
pub fn assemble_far_level(
    nodes: &[NodeMeta],
    cs: u32,
    rule: ParentRule,
    leaves: Vec<Option<Vec<[u32; SIDE_COUNT]>>>,
) -> FarLevel {
    let children = node_children(nodes);
    let mut kept: Vec<Vec<FarCell>> = vec![Vec::new(); nodes.len()];
    for (i, raw) in leaves.into_iter().enumerate().rev() {
        let n = &nodes[i];
        let (lo, hi) = node_bounds(n.box_center, n.extent);
        kept[i] = match raw {
            Some(raw) => keep_cells(lo, hi, cs, &raw),
            None => {
                let from: Vec<FarCell> = children[i]
                    .iter()
                    .flat_map(|&c| kept[c].iter().copied())
                    .collect();
                parent_cells(rule, lo, hi, cs, &from)
            }
        };
    }
    let mut level = FarLevel::default();
    for cells in kept {
        level.nodes.push(FarNode {
            cell_offset: level.cells.len() as u32,
            cell_count: cells.len() as u32,
            hull_offset: 0,
            hull_count: 0,
        });
        level.cells.extend(cells);
    }
    level
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_and_blocks_round_trip() {
        for cs in [1, 3, 12] {
            for n in 0..cell_count(cs) {
                assert_eq!(cell_index(cs, cell_coords(cs, n)), n);
            }
            let (lo, hi) = ([-1.0, 2.0, 0.5], [3.0, 2.5, 9.0]);
            for n in 0..cell_count(cs) {
                let i = cell_coords(cs, n);
                let (clo, chi) = cell_bounds(lo, hi, cs, i);
                let (c, _) = cell_box(clo, chi);
                assert_eq!(cell_of(lo, hi, cs, c), i);
                assert_eq!(cell_of(lo, hi, cs, clo), i, "lower corner in its cell");
            }
            assert_eq!(cell_of(lo, hi, cs, hi), [cs - 1; 3]);
            assert_eq!(cell_of(lo, hi, cs, [-9.0, 99.0, f32::NAN]), [0, cs - 1, 0]);
            // Every block of every view is a different cell of its slice.
            for side in 0..6 {
                for k in 0..cs {
                    let v = FarView::new([0.0; 3], [1.0; 3], cs, side, k);
                    let mut seen: Vec<usize> =
                        (0..cs * cs).map(|b| v.block_cell(b % cs, b / cs)).collect();
                    seen.sort_unstable();
                    seen.dedup();
                    assert_eq!(seen.len(), (cs * cs) as usize);
                    assert!(seen.iter().all(|&n| cell_coords(cs, n)[side / 2] == k));
                }
            }
        }
    }

    #[test]
    fn a_view_maps_its_slice_to_the_unit_depth_range_eye_side_first() {
        let (c, e) = ([1.0, 2.0, 3.0], [2.0, 4.0, 8.0]);
        for side in 0..6 {
            let v = FarView::new(c, e, 2, side, 1);
            let a = side / 2;
            // Slice 1 of 2 is the upper half along a.
            let mut top = c;
            top[a] = c[a] + e[a];
            let mut mid = c;
            mid[a] = c[a];
            let (zt, zm) = (v.clip(top)[2], v.clip(mid)[2]);
            if side % 2 == 0 {
                assert_eq!((zt, zm), (0.0, 1.0), "side {side}");
            } else {
                assert_eq!((zt, zm), (1.0, 0.0), "side {side}");
            }
            let corner = core::array::from_fn(|k| c[k] + e[k]);
            let clip = v.clip(corner);
            assert_eq!((clip[0], clip[1]), (1.0, 1.0));
        }
    }

    #[test]
    fn average_of_one_is_itself_and_empty_blocks_are_zero() {
        let c = pack_far_colour([0.3, 0.6, 0.1, 0.5]);
        assert_eq!(average_side(&[c]), c);
        assert_eq!(block_colour([0.0; 3], 0.0), 0);
        assert!(cell_is_empty(&[0; 6]));
        // One covered pixel of 64 keeps a cell.
        assert!(!cell_is_empty(&[
            block_colour([0.5; 3], 1.0),
            0,
            0,
            0,
            0,
            0
        ]));
    }

    #[test]
    fn composite_of_one_face_filling_cell_is_itself_and_hides_what_is_behind() {
        let (plo, phi) = ([0.0; 3], [1.0; 3]);
        let red = pack_far_colour([1.0, 0.0, 0.0, 1.0]);
        let blue = pack_far_colour([0.0, 0.0, 1.0, 1.0]);
        let front = FarCell {
            center: [0.5, 0.5, 0.75],
            extent: [0.5, 0.5, 0.25],
            colours: [red; 6],
        };
        let back = FarCell {
            center: [0.5, 0.5, 0.25],
            extent: [0.5, 0.5, 0.25],
            colours: [blue; 6],
        };
        assert_eq!(composite_side(plo, phi, 4, &[front]), red);
        assert_eq!(
            composite_side(plo, phi, 4, &[back, front]),
            red,
            "+Z sees the top"
        );
        assert_eq!(
            composite_side(plo, phi, 5, &[front, back]),
            blue,
            "-Z the bottom"
        );
        // A quarter of the face, opaque: alpha 1/4.
        let quarter = FarCell {
            center: [0.25, 0.25, 0.5],
            extent: [0.25, 0.25, 0.5],
            colours: [red; 6],
        };
        assert_eq!(
            composite_side(plo, phi, 4, &[quarter]),
            pack_far_colour([1.0, 0.0, 0.0, 0.25])
        );
        // Two half-covered layers: "over" gives 1 - (1 - 1/2)² = 3/4, the front one's colour
        // weighted 1/2, the back one's 1/4 (an additive composite would give alpha 1).
        let half = |c: FarCell, rgb: [f32; 3]| FarCell {
            colours: [pack_far_colour([rgb[0], rgb[1], rgb[2], 0.5]); 6],
            ..c
        };
        let (hf, hb) = (half(front, [1.0, 0.0, 0.0]), half(back, [0.0, 0.0, 1.0]));
        let got = unpack_far_colour(composite_side(plo, phi, 4, &[hb, hf]));
        let a = unpack_far_colour(hf.colours[4])[3];
        let want_alpha = a + (1.0 - a) * a;
        assert!((got[3] - want_alpha).abs() <= 0.5 / 255.0, "{got:?}");
        assert!(got[0] > got[2], "the front layer weighs more: {got:?}");
    }
}
