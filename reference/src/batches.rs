//! Grid batches (E§3.4, §4.2; SPEC §5.3): the CPU precompute that groups trees so selection can
//! decide once per group.
//!
//! ## Contract
//! - Trees are grouped by their base position's grid cell `(floor(x / g), floor(y / g))` on X and Y
//!   and by mesh: one batch per occupied (cell, mesh) pair ("each unique tree mesh has its own
//!   batch, even when they occupy the same grid cell", E§3.4). A spatial hash holds only occupied
//!   cells (E§4.2), so memory grows with trees, not with the area.
//! - **Order** is deterministic: batches sorted by `(mesh, cell y, cell x)`; within a batch, trees
//!   keep their scene order. The indirection array lists every tree exactly once, batch after
//!   batch, so `offset`/`len` ranges tile it.
//! - **Bounding sphere** (E Fig. 3.7: "tree meshes have a height that also has to be taken into
//!   account"): built from the trees' own bounding spheres ([`crate::scene::tree_sphere`]), so
//!   heights are included. The centre is the midpoint of the trees' sphere centres' bounding box
//!   (a batch of one tree has exactly that tree's sphere, which makes grouped selection equal the
//!   per-tree oracle when `g` is small, SPEC §6); the radius is
//!   `max |c_t - C| + r_t`, computed in `f64` and rounded up to `f32`, so containment is exact.
//! - `box_center`/`extent` describe the bounding box of the trees' spheres (E§4.2's "geometric
//!   center" and "extent").
//!
//! Memory is reported as actually allocated, beside E Eq. 4.1 ([`MemoryReport`]).

use std::collections::HashMap;

use forestlod_shared::{BatchMeta, CommandData, DrawCommand, MeshMeta, Params};

use crate::InputError;
use crate::scene::{Scene, tree_sphere};

/// The batches of a scene: metadata plus the indirection array (E§4.2).
#[derive(Clone, Debug, PartialEq)]
pub struct Batches {
    /// Batch metadata, in batch order.
    pub metas: Vec<BatchMeta>,
    /// Tree indices, batch after batch (`metas[b].offset .. + len`).
    pub indirection: Vec<u32>,
    /// Grid cell size they were built with.
    pub grid_size: f32,
    /// Per batch, the `[least, greatest]` scale of its trees ([`scale_range`]): the screen-space
    /// metrics' group band (issue 29, [`forestlod_shared::ViewUniform::group_band`]). Parallel to
    /// `metas`, so `BatchMeta` keeps E Eq. 4.1's 64 bytes; 8 bytes a batch beside it.
    pub scales: Vec<[f32; 2]>,
}

/// The `[least, greatest]` scale of the trees `trees` of `scene` (`[1, 1]` for none).
pub fn scale_range(scene: &Scene, trees: &[u32]) -> [f32; 2] {
    if trees.is_empty() {
        return [1.0, 1.0];
    }
    trees
        .iter()
        .fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], &t| {
            let s = scene.instances[t as usize].scale;
            [lo.min(s), hi.max(s)]
        })
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

/// Cell of a base position. `None` when the index does not fit an `i32` (grid far too fine for the
/// coordinates), which [`build_batches`] reports as an error.
pub fn cell_of(x: f32, y: f32, grid_size: f32) -> Option<[i32; 2]> {
    let cx = (x as f64 / grid_size as f64).floor();
    let cy = (y as f64 / grid_size as f64).floor();
    let fits = |c: f64| c >= i32::MIN as f64 && c <= i32::MAX as f64;
    (fits(cx) && fits(cy)).then_some([cx as i32, cy as i32])
}

/// Groups the scene's trees into grid batches. `meshes` are the scene's mesh metadata
/// ([`Scene::mesh_metas`] or the packed geometry's). Fails, naming the tree, when a cell index
/// overflows `i32`.
pub fn build_batches(
    scene: &Scene,
    meshes: &[MeshMeta],
    grid_size: f32,
) -> Result<Batches, InputError> {
    if !(grid_size.is_finite() && grid_size > 0.0) {
        return Err(InputError::new(
            "<params>",
            "field grid_size",
            grid_size,
            "expected a finite size > 0",
        ));
    }
    // Spatial hash: only occupied (mesh, cell) keys exist (E§4.2).
    let mut cells: HashMap<(u32, i32, i32), Vec<u32>> = HashMap::new();
    for (i, t) in scene.instances.iter().enumerate() {
        let [cx, cy] = cell_of(t.position[0], t.position[1], grid_size).ok_or_else(|| {
            InputError::new(
                scene.name.clone(),
                format!("instance {i}"),
                format!("{:?}", t.position),
                format!(
                    "grid cell index overflows i32 at grid_size {grid_size}: use a coarser grid"
                ),
            )
        })?;
        cells.entry((t.mesh, cy, cx)).or_default().push(i as u32);
    }
    let mut keys: Vec<_> = cells.keys().copied().collect();
    keys.sort_unstable();

    let mut metas = Vec::with_capacity(keys.len());
    let mut scales = Vec::with_capacity(keys.len());
    let mut indirection = Vec::with_capacity(scene.instances.len());
    for (mesh, cy, cx) in keys {
        let trees = &cells[&(mesh, cy, cx)];
        let spheres: Vec<([f32; 3], f32)> = trees
            .iter()
            .map(|&t| tree_sphere(&scene.instances[t as usize], &meshes[mesh as usize]))
            .collect();
        metas.push(batch_meta(
            &spheres,
            mesh,
            [cx, cy],
            indirection.len() as u32,
        ));
        scales.push(scale_range(scene, trees));
        indirection.extend_from_slice(trees);
    }
    Ok(Batches {
        metas,
        indirection,
        grid_size,
        scales,
    })
}

/// Metadata of one batch from its trees' bounding spheres (see the module docs for the rules).
pub fn batch_meta(
    spheres: &[([f32; 3], f32)],
    mesh: u32,
    cell: [i32; 2],
    offset: u32,
) -> BatchMeta {
    let mut cmin = [f32::INFINITY; 3];
    let mut cmax = [f32::NEG_INFINITY; 3];
    let mut bmin = [f32::INFINITY; 3];
    let mut bmax = [f32::NEG_INFINITY; 3];
    for (c, r) in spheres {
        for k in 0..3 {
            cmin[k] = cmin[k].min(c[k]);
            cmax[k] = cmax[k].max(c[k]);
            bmin[k] = bmin[k].min(c[k] - r);
            bmax[k] = bmax[k].max(c[k] + r);
        }
    }
    let center: [f32; 3] = core::array::from_fn(|k| (cmin[k] + cmax[k]) * 0.5);
    let radius = spheres
        .iter()
        .map(|(c, r)| {
            let d2: f64 = (0..3)
                .map(|k| (c[k] as f64 - center[k] as f64).powi(2))
                .sum();
            d2.sqrt() + *r as f64
        })
        .fold(0.0f64, f64::max);
    BatchMeta {
        center,
        radius: f32_at_least(radius),
        extent: core::array::from_fn(|k| (bmax[k] - bmin[k]) * 0.5),
        mesh,
        box_center: core::array::from_fn(|k| (bmin[k] + bmax[k]) * 0.5),
        len: spheres.len() as u32,
        cell,
        offset,
        _pad0: 0,
    }
}

/// Statistics of a batching, for `forestlod scene info`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BatchStats {
    /// Number of batches t.
    pub batches: usize,
    /// Occupied grid cells (any mesh).
    pub cells: usize,
    /// Fewest trees in a batch.
    pub min_trees: u32,
    /// Mean trees per batch.
    pub mean_trees: f64,
    /// Most trees in a batch.
    pub max_trees: u32,
    /// Mean bounding-sphere radius, metres.
    pub mean_radius: f64,
    /// Largest bounding-sphere radius, metres.
    pub max_radius: f32,
}

impl Batches {
    /// Statistics of this batching.
    pub fn stats(&self) -> BatchStats {
        let t = self.metas.len();
        let cells: std::collections::HashSet<[i32; 2]> =
            self.metas.iter().map(|m| m.cell).collect();
        BatchStats {
            batches: t,
            cells: cells.len(),
            min_trees: self.metas.iter().map(|m| m.len).min().unwrap_or(0),
            mean_trees: if t == 0 {
                0.0
            } else {
                self.indirection.len() as f64 / t as f64
            },
            max_trees: self.metas.iter().map(|m| m.len).max().unwrap_or(0),
            mean_radius: if t == 0 {
                0.0
            } else {
                self.metas.iter().map(|m| m.radius as f64).sum::<f64>() / t as f64
            },
            max_radius: self.metas.iter().map(|m| m.radius).fold(0.0, f32::max),
        }
    }
}

/// E Eq. 4.1: the additional bytes of the approach, `4n + 64t + 24m + 16amr² + 52lt + 4lm`.
pub fn eq41_bytes(n: u64, t: u64, m: u64, a: u64, r: u64, l: u64) -> u64 {
    eq41_azimuth_bytes(n, t, m, a, 1, r, l)
}

/// E Eq. 4.1 extended by `j` azimuth views per angle (issue 30, E§7): the billboard term
/// `16amr²` becomes `16ajmr²`; `j = 1` is the thesis's equation.
pub fn eq41_azimuth_bytes(n: u64, t: u64, m: u64, a: u64, j: u64, r: u64, l: u64) -> u64 {
    4 * n + 64 * t + 24 * m + 16 * a * j * m * r * r + 52 * l * t + 4 * l * m
}

/// Bytes actually allocated by our pipeline, term by term beside E Eq. 4.1.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct MemoryReport {
    /// Trees n, batches t, meshes m, angles a, texture side r, LOD levels l.
    pub n: u64,
    /// Batches.
    pub t: u64,
    /// Meshes.
    pub m: u64,
    /// Angles.
    pub a: u64,
    /// Azimuth views per angle `J` (issue 30; 1 is the thesis).
    pub j: u64,
    /// Texture side.
    pub r: u64,
    /// LOD levels.
    pub l: u64,
    /// Indirection array, `4 n` (thesis `4n`).
    pub indirection: u64,
    /// Batch metadata, `size_of::<BatchMeta>() t` = 64 t (thesis `64t`).
    pub batch_meta: u64,
    /// Mesh metadata, `size_of::<MeshMeta>() m` = 48 m (thesis `24m`).
    pub mesh_meta: u64,
    /// Billboard array texture, RGBA8 with full mip chains (thesis `16amr²`, which is four
    /// bytes per texel times four; ours is 4 bytes per texel times the 4/3 of a mip chain),
    /// `J` times over with azimuth views (`16aJmr²`).
    pub billboards: u64,
    /// Command buffer plus per-command data, `(20 + 32) l t` (thesis `52lt`).
    pub commands: u64,
    /// Per-(mesh, LOD) counters `4 l m` plus the frame's [`forestlod_shared::SelectCounters`].
    pub counters: u64,
    /// Interior nodes of a hierarchy (64 bytes each; the leaves are the batches): 0 for the grid.
    pub hierarchy_nodes: u64,
    /// The far level (issue 32, `FarLevel::bytes`): nodes, cells (48 B, of which 24 B are
    /// G§2.4's six colours) and hull vertices; 0 without one.
    pub far_level: u64,
    /// Sum of the above.
    pub total: u64,
    /// E Eq. 4.1 for the same n, t, m, a, r, l, extended by `J` ([`eq41_azimuth_bytes`]).
    pub eq41: u64,
}

/// Bytes of one layer's full mip chain in RGBA8.
pub fn mip_chain_bytes(r: u64) -> u64 {
    let mut side = r.max(1);
    let mut bytes = 0;
    loop {
        bytes += 4 * side * side;
        if side == 1 {
            return bytes;
        }
        side /= 2;
    }
}

/// The memory our pipeline allocates for `trees` trees in `batches` with `params`.
pub fn memory_report(trees: usize, batches: usize, meshes: usize, params: &Params) -> MemoryReport {
    let (n, t, m) = (trees as u64, batches as u64, meshes as u64);
    let (a, j, r, l) = (
        params.angle_count as u64,
        params.azimuth_count as u64,
        params.texture_size as u64,
        params.lod_levels as u64,
    );
    let size = |s: usize| s as u64;
    let indirection = 4 * n;
    let batch_meta = size(core::mem::size_of::<BatchMeta>()) * t;
    let mesh_meta = size(core::mem::size_of::<MeshMeta>()) * m;
    let billboards = if l >= 2 {
        // K·J views a mesh, or N² octahedral frames (issue 32).
        // The depth channel (issue 32) adds one RGBA8 layer a frame.
        let per_mesh = u64::from(forestlod_shared::BillboardViews::of(params).per_mesh())
            * if forestlod_shared::depth_channel(params) {
                2
            } else {
                1
            };
        per_mesh * m * mip_chain_bytes(r)
    } else {
        0
    };
    let commands =
        size(core::mem::size_of::<DrawCommand>() + core::mem::size_of::<CommandData>()) * l * t;
    let counters = 4 * l * m + size(core::mem::size_of::<forestlod_shared::SelectCounters>());
    MemoryReport {
        n,
        t,
        m,
        a,
        j,
        r,
        l,
        indirection,
        batch_meta,
        mesh_meta,
        billboards,
        commands,
        counters,
        hierarchy_nodes: 0,
        far_level: 0,
        total: indirection + batch_meta + mesh_meta + billboards + commands + counters,
        eq41: eq41_azimuth_bytes(n, t, m, a, j, r, l),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// E§4.5.1: 25 km², ~9.2·10^5 trees, five meshes, 500 m grid (500 batches), 10 angles, 128²,
    /// two LODs: "~16.9 MB".
    #[test]
    fn eq41_reproduces_the_thesis_figure() {
        let bytes = eq41_bytes(920_000, 500, 5, 10, 128, 2);
        assert_eq!(bytes, 16_871_360);
        assert!((bytes as f64 / 1.0e6 - 16.9).abs() < 0.05, "{bytes}");
        // Our allocation for the same counts: record the ratio so a change shows up here.
        let ours = memory_report(920_000, 500, 5, &Params::default());
        assert_eq!(ours.eq41, bytes);
        assert_eq!(ours.batch_meta, 64 * 500);
        // A command is 20 bytes of indirect arguments and 40 of per-command data (the far-field
        // subsets added 8: the group's first tree and length, issue 29).
        assert_eq!(ours.commands, 60 * 2 * 500);
        // RGBA8 + mips is 4·4/3 bytes per texel against the thesis's 16.
        assert_eq!(ours.billboards, 10 * 5 * mip_chain_bytes(128));
        assert_eq!(mip_chain_bytes(128), 87_380);
    }

    /// Issue 30: azimuth views multiply the billboard term, in ours and in the equation, and
    /// nothing else; `J = 1` is the thesis's figure.
    #[test]
    fn eq41_extended_by_azimuths_multiplies_the_billboard_term() {
        let one = memory_report(920_000, 500, 5, &Params::default());
        let four = memory_report(
            920_000,
            500,
            5,
            &Params {
                azimuth_count: 4,
                ..Params::default()
            },
        );
        assert_eq!((one.j, four.j), (1, 4));
        assert_eq!(four.billboards, 4 * one.billboards);
        assert_eq!(four.total - one.total, 3 * one.billboards);
        assert_eq!(four.eq41 - one.eq41, 3 * 16 * 10 * 5 * 128 * 128);
        assert_eq!(
            eq41_azimuth_bytes(920_000, 500, 5, 10, 1, 128, 2),
            eq41_bytes(920_000, 500, 5, 10, 128, 2)
        );
    }

    #[test]
    fn single_sphere_batch_is_that_sphere() {
        let s = ([12.3456f32, -7.891, 3.3], 4.567f32);
        let b = batch_meta(&[s], 2, [1, -1], 9);
        assert_eq!(b.center, s.0);
        assert_eq!(b.radius, s.1);
        assert_eq!((b.mesh, b.cell, b.offset, b.len), (2, [1, -1], 9, 1));
    }

    #[test]
    fn cell_index_overflow_is_detected() {
        assert_eq!(cell_of(5.0e5, 5.3e6, 500.0), Some([1000, 10600]));
        assert_eq!(cell_of(-0.5, 0.5, 1.0), Some([-1, 0]));
        assert_eq!(cell_of(1.0e6, 0.0, 1.0e-4), None);
    }
}
