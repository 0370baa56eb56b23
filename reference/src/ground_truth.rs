//! The accuracy yardstick of every experiment (SPEC §10): the scene as it "really" looks, ray-traced
//! with full meshes for **every** tree, no LOD, no batching and no draw distance (only the camera's
//! near and far planes), alpha-tested against the mesh textures, supersampled and box-filtered in
//! linear light. Users "trade speed for accuracy" (SPEC §1); this is the accuracy end of the trade.
//!
//! ## Contract
//! - **Geometry** is exactly what the rasterizer draws at LOD0 and for the ground:
//!   - tree triangles are the mesh triangles placed like [`crate::draw::vertex_stage`] places them
//!     (`p = base + Rz(yaw) · scale · local`, the same `f32` operations in the same order), one
//!     triangle per mesh triangle per tree, double-sided;
//!   - ground triangles are [`crate::draw::terrain_triangles`]' grid ([`TERRAIN_CELLS`]² cells
//!     over the footprint plus [`TERRAIN_MARGIN`](crate::draw::TERRAIN_MARGIN), sunk 0.05 m) in world space, with the vertex
//!     colours of [`crate::draw::ground_color`] interpolated barycentrically (what the rasterizer's
//!     perspective-correct varyings compute);
//!   - beyond both, the sky colour [`SKY_SRGB`].
//! - **Rays** are traced with the [obvhs](https://docs.rs/obvhs) crate: one compressed wide BVH
//!   (CWBVH, PLOC build) per scene, built once ([`GroundTruthScene::build`]) and reused for every
//!   camera. Its primitives are [`TruthLayout`]'s clusters: at most `max_triangles` (default 2)
//!   consecutive triangles of one tree, boxed together, and each ground triangle alone; a leaf
//!   tests every triangle of its cluster. Whatever the cluster size, the same world-space
//!   triangles are tested with the same intersection and the same tie rule, so the image is the
//!   same bit for bit (a unit test checks sizes 1, 2, 4 and whole trees). One primitive per
//!   triangle (the first design) peaked at 5.2 GB and built in 51 s on `stress`; two per
//!   primitive peak at 3.0 GB, build in 22 s and trace no slower (`truth_bench`,
//!   `experiments/truth_bvh/README.md`). A ray from the eye through a point
//!   of the image plane has direction `forward + x·right + y·up` (not normalized), so its parameter
//!   `t` **is** the view depth, and the interval `[near, far]` is the rasterizer's near/far clip.
//! - **Alpha test as an any-hit filter**: the intersection callback obvhs calls for every
//!   candidate triangle samples the mesh texture (level 0, bilinear, linear light: the finest
//!   level the rasterizer can show) at the hit's uv and rejects the hit when alpha is below the
//!   cutoff, so the traversal goes on and finds the nearest *accepted* hit. No re-casting is needed:
//!   a rejected hit never shortens the ray. Ties at equal `t` (crossed cards meet along a line) go
//!   to the lowest triangle id, so the result does not depend on the BVH's shape.
//! - **Colour** is the unlit texture colour, as LOD0 writes it: the texel's linear RGB (its alpha
//!   only decides the test). Ground: the interpolated vertex colour. Sky: [`SKY_SRGB`].
//! - **Supersampling**: an `s x s` ordered grid of samples per pixel, at `((i + 0.5)/s, (j + 0.5)/s)`
//!   within the pixel (stratified without jitter, so deterministic; [`sample_offsets`], rows
//!   outer), box-filtered in linear light (weight `1/s²` each, [`box_filter`]) and encoded to
//!   sRGB8 once. Default `s` = [`DEFAULT_SAMPLES_PER_AXIS`].
//! - **Classification** per pixel ([`PixelClass`], [`classify`]): *tree* when at least half the
//!   samples hit a tree, else *ground* or *sky* by majority of the rest (ties to ground). Beside
//!   it the exact fraction of samples that hit a tree ([`tree_fraction`]).
//! - **Sampling error** (the oracle of `reference/tests/truth_oracle.rs`): a pixel's tree
//!   fraction estimates the area of the pixel that trees cover. With the ordered grid the
//!   estimate is exact in every sub-cell (the `1/s x 1/s` square around a sample) that lies wholly
//!   inside or wholly outside the covered region, so it differs from the exact coverage by at
//!   most `(sub-cells the region's boundary crosses) / s²` per pixel. Analytic scenes (a square,
//!   a disc, half-planes, seen head-on) hold the truth to that bound and its colour to
//!   `fraction·c + (1 - fraction)·sky`.
//! - **Deterministic**: rows are traced in parallel (rayon) but each pixel is a pure function of the
//!   scene and the camera: identical output for any thread count.

use forestlod_shared::Camera;
use glam::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle as BvhTriangle;
use rayon::prelude::*;

use crate::InputError;
use crate::draw::{SKY_SRGB, TERRAIN_CELLS};
use crate::sampler::Texture;
use crate::scene::Scene;
use crate::texture::{Rgba8Image, linear_to_srgb, srgb_to_linear};

/// Samples per pixel side: 4 x 4 = 16 samples per pixel. At the built-in scenes' resolutions a
/// crown card's partially covered pixels then get their coverage to 1/16, well under the FLIP and
/// coverage differences the LOD variants show.
pub const DEFAULT_SAMPLES_PER_AXIS: u32 = 4;

/// What a ray (or a pixel) sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PixelClass {
    /// Nothing: the sky colour.
    Sky = 0,
    /// The ground.
    Ground = 1,
    /// A tree.
    Tree = 2,
}

/// The nearest accepted hit of one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceHit {
    /// Ray parameter; the view depth for primary rays.
    pub t: f32,
    /// Triangle index in scene order: tree `i`'s mesh triangle `k` comes before tree `i + 1`'s,
    /// ground triangles last (see [`GroundTruthScene::triangles`]).
    pub triangle: u32,
    /// Tree or ground.
    pub class: PixelClass,
    /// Linear RGB of the hit.
    pub color: [f32; 3],
}

/// What the ground truth's BVH holds as primitives (module docs): clusters of at most
/// `max_triangles` consecutive triangles of one tree (in mesh index order), and each ground
/// triangle alone. The image does not depend on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TruthLayout {
    /// Triangles per cluster at most, >= 1; 1 is one primitive per triangle (the first design).
    pub max_triangles: u32,
}

impl TruthLayout {
    /// One primitive per triangle: the first design, kept to check and measure the default by.
    pub const TRIANGLES: Self = Self { max_triangles: 1 };
    /// One primitive per tree ([`crate::scene::MAX_TREE_TRIANGLES`] covers every mesh).
    pub const TREES: Self = Self {
        max_triangles: crate::scene::MAX_TREE_TRIANGLES as u32,
    };
}

impl Default for TruthLayout {
    /// Two triangles per primitive: traces as fast as one per triangle (or faster), builds in half
    /// the time and peaks at ~0.6x the memory; one per tree would halve the memory again but
    /// traces up to 1.2x slower on `patchy` (`truth_bench`, `experiments/truth_bvh/README.md`).
    fn default() -> Self {
        Self { max_triangles: 2 }
    }
}

/// The BVH and shading data of one scene, built once and traced for any camera.
pub struct GroundTruthScene {
    bvh: CwBvh,
    layout: TruthLayout,
    /// Every triangle in scene order: trees in instance order, each its mesh's triangles in index
    /// order, then the ground.
    triangles: Vec<BvhTriangle>,
    /// Scene index of tree `i`'s first triangle; `tree_first[n]` = the tree triangle count.
    tree_first: Vec<u32>,
    /// Scene index of each cluster's first triangle, and one past the last cluster's last.
    cluster_first: Vec<u32>,
    /// The tree of each cluster.
    cluster_tree: Vec<u32>,
    /// Tree mesh index per tree.
    tree_mesh: Vec<u32>,
    /// Per mesh: uvs of each triangle's three corners.
    mesh_uvs: Vec<Vec<[[f32; 2]; 3]>>,
    /// Per mesh: its texture, level 0 only.
    textures: Vec<Texture>,
    /// Ground vertex colours per ground triangle (linear RGB at each corner).
    ground_colors: Vec<[[f32; 3]; 3]>,
    alpha_cutoff: f32,
    build_seconds: f64,
}

/// A ground-truth image.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundTruthImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel side.
    pub samples_per_axis: u32,
    /// Box-filtered linear RGB per pixel, row-major from the top-left.
    pub linear: Vec<[f32; 3]>,
    /// The same encoded to sRGB8 (alpha 255).
    pub srgb: Rgba8Image,
    /// Per-pixel class (module docs).
    pub class: Vec<PixelClass>,
    /// Fraction of each pixel's samples that hit a tree.
    pub tree_fraction: Vec<f32>,
    /// Rays traced.
    pub rays: u64,
}

/// World-space ray through framebuffer point `(fx, fy)` (pixels from the top-left, `+0.5` for a
/// pixel centre) of a validated camera: origin at the eye, direction `forward + x·right + y·up`
/// scaled so that `t` is the view depth (module docs). The inverse of the camera's projection
/// (`Camera::projection_matrix`) and wgpu's flipped viewport.
pub fn primary_ray(camera: &Camera, fx: f32, fy: f32) -> ([f32; 3], [f32; 3]) {
    let b = camera.basis();
    let ty = (camera.fov_y * 0.5).tan();
    let tx = ty * camera.aspect();
    let ndc_x = 2.0 * fx / camera.width as f32 - 1.0;
    let ndc_y = 1.0 - 2.0 * fy / camera.height as f32;
    let d = b.forward + b.right * (ndc_x * tx) + b.up * (ndc_y * ty);
    (camera.eye, d.to_array())
}

/// The supersampling pattern (module docs, *Supersampling*): the `s x s` ordered grid of sample
/// offsets within a pixel, in pixels from the pixel's top-left corner, for `s =
/// samples_per_axis` (0 reads as 1). Sample `k = j·s + i` (row `j` outer, column `i` inner: the
/// order [`GroundTruthScene::render_region`] traces and sums them in) lies at
/// `((i + 0.5)/s, (j + 0.5)/s)`, computed in `f32` as `(i as f32 + 0.5) / s as f32`: the centres
/// of the `s²` equal sub-cells of the pixel, so every sample is strictly inside the pixel and
/// their centroid is the pixel centre. Pixel `(x, y)` traces the primary rays
/// ([`primary_ray`]) through `(x + ox, y + oy)`.
pub fn sample_offsets(samples_per_axis: u32) -> Vec<[f32; 2]> {
    let s = samples_per_axis.max(1);
    (0..s)
        .flat_map(|j| {
            (0..s).map(move |i| [(i as f32 + 0.5) / s as f32, (j as f32 + 0.5) / s as f32])
        })
        .collect()
}

/// The box filter (module docs): every one of a pixel's `s²` samples has weight `1/s²`; the
/// pixel's linear colour is the `f64` sum of its samples' colours divided by `s²`, rounded once
/// to `f32`.
pub fn box_filter(sum: [f64; 3], samples_per_axis: u32) -> [f32; 3] {
    let s = samples_per_axis.max(1);
    let n = (s * s) as f64;
    sum.map(|v| (v / n) as f32)
}

/// The fraction of a pixel's `s²` samples that hit a tree ([`GroundTruthImage::tree_fraction`]):
/// `counts[Tree] / s²` in `f32`. `counts` are the samples per class, indexed by
/// `PixelClass as usize`.
pub fn tree_fraction(counts: [u32; 3], samples_per_axis: u32) -> f32 {
    let s = samples_per_axis.max(1);
    counts[PixelClass::Tree as usize] as f32 / (s * s) as f32
}

/// The classification rule (module docs) of a pixel whose `s²` samples fell `counts[c]` in
/// class `c` (indexed by `PixelClass as usize`): [`PixelClass::Tree`] when at least half the
/// samples hit a tree (`2·trees >= s²`), else [`PixelClass::Ground`] when at least as many
/// samples hit the ground as the sky (ties to ground), else [`PixelClass::Sky`].
pub fn classify(counts: [u32; 3], samples_per_axis: u32) -> PixelClass {
    let s = samples_per_axis.max(1);
    if 2 * counts[PixelClass::Tree as usize] >= s * s {
        PixelClass::Tree
    } else if counts[PixelClass::Ground as usize] >= counts[PixelClass::Sky as usize] {
        PixelClass::Ground
    } else {
        PixelClass::Sky
    }
}

/// Ray–triangle intersection, the Möller–Trumbore formulation of obvhs's
/// `Triangle::intersect` (same operations, so the same `t` bit for bit, which a unit test checks),
/// also returning the barycentric weights `(u, v)` of `v1` and `v2`: the hit point is
/// `(1 - u - v)·v0 + u·v1 + v·v2`. `None` for a miss or a `t` outside `[tmin, tmax]`.
pub fn intersect_triangle(tri: &BvhTriangle, ray: &Ray) -> Option<(f32, f32, f32)> {
    let e1 = tri.v0 - tri.v1;
    let e2 = tri.v2 - tri.v0;
    let n = e1.cross(e2);
    let c = tri.v0 - ray.origin;
    let r = ray.direction.cross(c);
    let inv_det = 1.0 / n.dot(ray.direction);
    let u = r.dot(e2) * inv_det;
    let v = r.dot(e1) * inv_det;
    let w = 1.0 - u - v;
    let signs = u.to_bits() | v.to_bits() | w.to_bits();
    if inv_det != 0.0 && signs & 0x8000_0000 == 0 {
        let t = n.dot(c) * inv_det;
        if t >= ray.tmin && t <= ray.tmax {
            return Some((t, u, v));
        }
    }
    None
}

fn lerp3<const N: usize>(c: &[[f32; N]; 3], u: f32, v: f32) -> [f32; N] {
    std::array::from_fn(|i| (1.0 - u - v) * c[0][i] + u * c[1][i] + v * c[2][i])
}

/// World-space vertices of the ground grid, as [`crate::draw::terrain_triangles`] builds them
/// before projection: `(position, linear colour)` of grid vertex `(i, j)`
/// ([`forestlod_shared::terrain_vertex`]).
pub fn terrain_vertex(scene: &Scene, i: u32, j: u32) -> ([f32; 3], [f32; 3]) {
    forestlod_shared::terrain_vertex(scene.bounds, &|x, y| scene.terrain.height(x, y), i, j)
}

impl GroundTruthScene {
    /// Builds the BVH over every tree triangle and the ground of a validated scene, one primitive
    /// per tree ([`TruthLayout::TREES`]). `alpha_cutoff` is the alpha test's reference
    /// (`Params::alpha_cutoff`).
    pub fn build(scene: &Scene, alpha_cutoff: f32) -> Result<Self, InputError> {
        Self::build_with(scene, alpha_cutoff, TruthLayout::default())
    }

    /// [`GroundTruthScene::build`] with the BVH's primitives chosen by `layout`; the images are the
    /// same whatever the layout (module docs).
    pub fn build_with(
        scene: &Scene,
        alpha_cutoff: f32,
        layout: TruthLayout,
    ) -> Result<Self, InputError> {
        let start = std::time::Instant::now();
        scene.validate(&scene.name)?;
        let mesh_tris: Vec<Vec<[[f32; 3]; 3]>> = scene
            .meshes
            .iter()
            .map(|m| {
                m.indices
                    .chunks_exact(3)
                    .map(|t| [0, 1, 2].map(|k| m.positions[t[k] as usize]))
                    .collect()
            })
            .collect();
        // Scene indices are u32: the trees' and the ground's triangles must fit.
        let tree_triangle_total: u64 = scene
            .instances
            .iter()
            .map(|t| mesh_tris[t.mesh as usize].len() as u64)
            .sum();
        let ground_triangles = 2 * u64::from(TERRAIN_CELLS) * u64::from(TERRAIN_CELLS);
        if tree_triangle_total + ground_triangles > u64::from(u32::MAX) {
            return Err(InputError::new(
                scene.name.clone(),
                "instances",
                scene.instances.len(),
                format!(
                    "the ground truth indexes triangles in 32 bits: {tree_triangle_total} tree \
                     triangles are too many"
                ),
            ));
        }
        let mesh_uvs: Vec<Vec<[[f32; 2]; 3]>> = scene
            .meshes
            .iter()
            .map(|m| {
                m.indices
                    .chunks_exact(3)
                    .map(|t| [0, 1, 2].map(|k| m.uvs[t[k] as usize]))
                    .collect()
            })
            .collect();
        let textures = scene
            .meshes
            .iter()
            .map(|m| {
                Texture::new(vec![m.texture.clone()]).map_err(|e| {
                    InputError::new(
                        scene.name.clone(),
                        format!("mesh {:?}, texture", m.name),
                        format!("{}x{}", m.texture.width, m.texture.height),
                        e.to_string(),
                    )
                })
            })
            .collect::<Result<Vec<_>, _>>()?;

        // Tree triangles in scene order, placed as the vertex stage places them.
        let mut tree_first = Vec::with_capacity(scene.instances.len() + 1);
        let mut first = 0u32;
        for t in &scene.instances {
            tree_first.push(first);
            first += mesh_tris[t.mesh as usize].len() as u32;
        }
        tree_first.push(first);
        let tree_triangle_count = first as usize;
        let mut triangles = vec![
            BvhTriangle {
                v0: Vec3A::ZERO,
                v1: Vec3A::ZERO,
                v2: Vec3A::ZERO,
            };
            tree_triangle_count
        ];
        // Each tree writes its own disjoint range, so the result is thread-independent.
        let mut ranges: Vec<&mut [BvhTriangle]> = Vec::with_capacity(scene.instances.len());
        let mut rest = triangles.as_mut_slice();
        for w in tree_first.windows(2) {
            let (head, tail) = rest.split_at_mut((w[1] - w[0]) as usize);
            ranges.push(head);
            rest = tail;
        }
        ranges
            .into_par_iter()
            .zip(scene.instances.par_iter())
            .for_each(|(out, t)| {
                let (s, c) = t.yaw.sin_cos();
                let place = |p: [f32; 3]| {
                    let p = glam::Vec3::from(p) * t.scale;
                    let rotated = glam::Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
                    Vec3A::from(glam::Vec3::from(t.position) + rotated)
                };
                for (o, tri) in out.iter_mut().zip(&mesh_tris[t.mesh as usize]) {
                    *o = BvhTriangle {
                        v0: place(tri[0]),
                        v1: place(tri[1]),
                        v2: place(tri[2]),
                    };
                }
            });
        // The ground grid, in terrain_triangles' order (`forestlod_shared::terrain_grid`, the
        // grid every renderer draws).
        let mut ground_colors = Vec::new();
        for [p, q, r] in
            forestlod_shared::terrain_grid(scene.bounds, |x, y| scene.terrain.height(x, y))
        {
            triangles.push(BvhTriangle {
                v0: Vec3A::from(p.0),
                v1: Vec3A::from(q.0),
                v2: Vec3A::from(r.0),
            });
            ground_colors.push([p.1, q.1, r.1]);
        }
        // Clusters of at most `max_triangles` consecutive triangles of one tree.
        let max = layout.max_triangles.max(1);
        let mut cluster_first = Vec::new();
        let mut cluster_tree = Vec::new();
        for (tree, w) in tree_first.windows(2).enumerate() {
            for first in (w[0]..w[1]).step_by(max as usize) {
                cluster_first.push(first);
                cluster_tree.push(tree as u32);
            }
        }
        cluster_first.push(first);
        let boxes: Vec<Aabb> = cluster_first
            .par_windows(2)
            .map(|w| {
                triangles[w[0] as usize..w[1] as usize]
                    .iter()
                    .fold(Aabb::INVALID, |b, t| b.union(&t.aabb()))
            })
            .chain(
                triangles[tree_triangle_count..]
                    .par_iter()
                    .map(|t| t.aabb()),
            )
            .collect();
        let bvh = build_cwbvh(
            &boxes,
            BvhBuildParams::fast_build(),
            &mut std::time::Duration::default(),
        );
        drop(boxes);
        Ok(Self {
            bvh,
            layout,
            triangles,
            tree_first,
            cluster_first,
            cluster_tree,
            tree_mesh: scene.instances.iter().map(|t| t.mesh).collect(),
            mesh_uvs,
            textures,
            ground_colors,
            alpha_cutoff,
            build_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The BVH's primitives.
    pub fn layout(&self) -> TruthLayout {
        self.layout
    }

    /// Triangles in the scene (trees and ground).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Tree triangles in the scene.
    pub fn tree_triangle_count(&self) -> usize {
        *self.tree_first.last().expect("n + 1 entries") as usize
    }

    /// Primitives in the BVH: one per tree and ground triangle, or one per triangle.
    pub fn primitive_count(&self) -> usize {
        self.bvh.primitive_indices.len()
    }

    /// Bytes this scene's truth holds: the BVH's nodes and index, the triangles, the per-tree
    /// ranges and mesh ids, uvs, level-0 textures and ground colours (the truth's memory cost;
    /// allocator slack and the build's transient memory not counted).
    pub fn memory_bytes(&self) -> u64 {
        let bytes = |n: usize, each: usize| (n * each) as u64;
        bytes(
            self.bvh.nodes.len(),
            size_of::<obvhs::cwbvh::node::CwBvhNode>(),
        ) + bytes(self.bvh.primitive_indices.len(), 4)
            + bytes(self.triangles.len(), size_of::<BvhTriangle>())
            + bytes(self.tree_first.len(), 4)
            + bytes(self.cluster_first.len(), 4)
            + bytes(self.cluster_tree.len(), 4)
            + bytes(self.tree_mesh.len(), 4)
            + self
                .mesh_uvs
                .iter()
                .map(|m| bytes(m.len(), size_of::<[[f32; 2]; 3]>()))
                .sum::<u64>()
            + self
                .textures
                .iter()
                .map(|t| bytes(t.width() as usize * t.height() as usize, 4))
                .sum::<u64>()
            + bytes(self.ground_colors.len(), size_of::<[[f32; 3]; 3]>())
    }

    /// Wall time of [`GroundTruthScene::build`], seconds (placing triangles plus the BVH build).
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Every triangle in scene order (trees in instance order, each its mesh's triangles in index
    /// order, then the ground): what the Embree cross-check loads.
    pub fn triangles(&self) -> Vec<[[f32; 3]; 3]> {
        self.triangles
            .iter()
            .map(|t| [t.v0.to_array(), t.v1.to_array(), t.v2.to_array()])
            .collect()
    }

    /// The texture coordinate of a hit on tree `tree`'s scene triangle `index`, and its mesh.
    fn tree_uv(&self, tree: u32, index: u32, u: f32, v: f32) -> (u32, [f32; 2]) {
        let local = index - self.tree_first[tree as usize];
        let mesh = self.tree_mesh[tree as usize];
        let uvs = &self.mesh_uvs[mesh as usize][local as usize];
        (mesh, lerp3(uvs, u, v))
    }

    /// The tree of a tree triangle (`None` for the ground); once per traced ray (its colour).
    fn tree_of(&self, index: u32) -> Option<u32> {
        if index as usize >= self.tree_triangle_count() {
            return None;
        }
        Some((self.tree_first.partition_point(|&f| f <= index) - 1) as u32)
    }

    /// Nearest hit in `[tmin, tmax]` along `origin + t·direction`. With `alpha_test`, tree hits
    /// whose texel alpha is below the cutoff are rejected (module docs); without it every triangle
    /// is opaque (the geometric query the Embree cross-check compares).
    pub fn trace(
        &self,
        origin: [f32; 3],
        direction: [f32; 3],
        tmin: f32,
        tmax: f32,
        alpha_test: bool,
    ) -> Option<TraceHit> {
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(direction), tmin, tmax);
        // Best (t, scene index, u, v), ties to the lowest scene index.
        let mut best: Option<(f32, u32, f32, f32)> = None;
        // Tests scene triangle `index` (of tree `tree`, or the ground), keeps it when it is the
        // best so far, and returns its `t` (infinity when it is missed or alpha-rejected).
        let mut test = |r: &Ray, index: u32, tree: Option<u32>| -> f32 {
            let Some((t, u, v)) = intersect_triangle(&self.triangles[index as usize], r) else {
                return f32::INFINITY;
            };
            if let (true, Some(tree)) = (alpha_test, tree) {
                let (mesh, uv) = self.tree_uv(tree, index, u, v);
                let alpha = self.textures[mesh as usize].bilinear(0, 0, uv)[3];
                if alpha < self.alpha_cutoff {
                    return f32::INFINITY;
                }
            }
            let better = match best {
                None => true,
                Some((bt, bi, ..)) => t < bt || (t == bt && index < bi),
            };
            if better {
                best = Some((t, index, u, v));
            }
            t
        };
        let mut hit = RayHit::none();
        let clusters = self.cluster_tree.len();
        let ground_first = self.tree_triangle_count();
        self.bvh.ray_traverse(ray, &mut hit, |r, leaf| {
            let p = self.bvh.primitive_indices[leaf] as usize;
            if p >= clusters {
                return test(r, (ground_first + p - clusters) as u32, None);
            }
            // Every triangle of the cluster, each against the same ray: the candidates and the
            // tie rule are those of one primitive per triangle.
            let tree = self.cluster_tree[p];
            (self.cluster_first[p]..self.cluster_first[p + 1])
                .fold(f32::INFINITY, |m, i| m.min(test(r, i, Some(tree))))
        });
        let (t, triangle, u, v) = best?;
        let (class, color) = match self.tree_of(triangle) {
            None => {
                let c = &self.ground_colors[triangle as usize - ground_first];
                (PixelClass::Ground, lerp3(c, u, v))
            }
            Some(tree) => {
                let (mesh, uv) = self.tree_uv(tree, triangle, u, v);
                let texel = self.textures[mesh as usize].bilinear(0, 0, uv);
                (PixelClass::Tree, [texel[0], texel[1], texel[2]])
            }
        };
        Some(TraceHit {
            t,
            triangle,
            class,
            color,
        })
    }
    /// Renders the ground truth for a camera with `samples_per_axis`² samples per pixel (module
    /// docs). The camera must be valid.
    pub fn render(&self, camera: &Camera, samples_per_axis: u32) -> GroundTruthImage {
        self.render_region(
            camera,
            samples_per_axis,
            [0, 0, camera.width, camera.height],
        )
    }

    /// Renders only the pixel rectangle `[x0, y0, w, h]` of the camera's frame (a `w x h` image
    /// whose pixel `(x, y)` is the frame's pixel `(x0 + x, y0 + y)`, bit for bit what
    /// [`GroundTruthScene::render`] gives there): the sampled tiles of a truth too slow to
    /// trace in full. The rectangle must lie inside the frame.
    pub fn render_region(
        &self,
        camera: &Camera,
        samples_per_axis: u32,
        [x0, y0, w, h]: [u32; 4],
    ) -> GroundTruthImage {
        assert!(
            x0 + w <= camera.width && y0 + h <= camera.height,
            "region outside the frame"
        );
        let s = samples_per_axis.max(1);
        let offsets = sample_offsets(s);
        let sky = SKY_SRGB.map(srgb_to_linear);
        let rows: Vec<Vec<([f32; 3], PixelClass, f32)>> = (y0..y0 + h)
            .into_par_iter()
            .with_max_len(1)
            .map(|y| {
                (x0..x0 + w)
                    .map(|x| {
                        let mut sum = [0.0f64; 3];
                        let mut counts = [0u32; 3];
                        // The pattern's order (rows outer, columns inner) is the summation order.
                        for &[ox, oy] in &offsets {
                            let (o, d) = primary_ray(camera, x as f32 + ox, y as f32 + oy);
                            let (class, color) =
                                match self.trace(o, d, camera.near, camera.far, true) {
                                    Some(hit) => (hit.class, hit.color),
                                    None => (PixelClass::Sky, sky),
                                };
                            counts[class as usize] += 1;
                            for c in 0..3 {
                                sum[c] += color[c] as f64;
                            }
                        }
                        (
                            box_filter(sum, s),
                            classify(counts, s),
                            tree_fraction(counts, s),
                        )
                    })
                    .collect()
            })
            .collect();
        let pixels: Vec<_> = rows.into_iter().flatten().collect();
        let linear: Vec<[f32; 3]> = pixels.iter().map(|p| p.0).collect();
        let srgb = Rgba8Image {
            width: w,
            height: h,
            texels: linear
                .iter()
                .map(|c| {
                    [
                        linear_to_srgb(c[0]),
                        linear_to_srgb(c[1]),
                        linear_to_srgb(c[2]),
                        255,
                    ]
                })
                .collect(),
        };
        GroundTruthImage {
            width: w,
            height: h,
            samples_per_axis: s,
            linear,
            srgb,
            class: pixels.iter().map(|p| p.1).collect(),
            tree_fraction: pixels.iter().map(|p| p.2).collect(),
            rays: w as u64 * h as u64 * (s * s) as u64,
        }
    }
}

impl GroundTruthImage {
    /// The classification as an image: sky light blue, ground brown, tree green.
    pub fn class_image(&self) -> Rgba8Image {
        Rgba8Image {
            width: self.width,
            height: self.height,
            texels: self
                .class
                .iter()
                .map(|c| match c {
                    PixelClass::Sky => [168, 198, 226, 255],
                    PixelClass::Ground => [120, 100, 70, 255],
                    PixelClass::Tree => [40, 160, 60, 255],
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw::terrain_triangles;
    use crate::scene::builtin;

    /// The sampling pattern against its definition (module docs, *Supersampling*): `s²` offsets,
    /// sample `k = j·s + i` at `((i + 0.5)/s, (j + 0.5)/s)`, strictly inside the pixel, distinct,
    /// one in each `1/s x 1/s` sub-cell, centroid the pixel centre (exactly for `s` a power of
    /// two, within the offsets' `f32` rounding otherwise). Mutation-checked:
    /// `+ 0.5` -> `+ 1.5`, `i` and `j` swapped, and `/ s` -> `/ (s + 1)` in `sample_offsets`
    /// each fail it.
    #[test]
    fn sample_offsets_are_the_ordered_grid_of_the_definition() {
        assert_eq!(sample_offsets(0), vec![[0.5, 0.5]], "s = 0 reads as 1");
        for s in 1..=9u32 {
            let offsets = sample_offsets(s);
            assert_eq!(offsets.len(), (s * s) as usize, "s = {s}: offset count");
            let mut cells = vec![false; (s * s) as usize];
            let (mut cx, mut cy) = (0.0f64, 0.0f64);
            for (k, &[ox, oy]) in offsets.iter().enumerate() {
                let (i, j) = (k as u32 % s, k as u32 / s);
                let want = [
                    ((i as f64 + 0.5) / s as f64) as f32,
                    ((j as f64 + 0.5) / s as f64) as f32,
                ];
                assert_eq!([ox, oy], want, "s = {s}: sample {k} (column {i}, row {j})");
                assert!(
                    ox > 0.0 && ox < 1.0 && oy > 0.0 && oy < 1.0,
                    "s = {s}: sample {k} at ({ox}, {oy}) not strictly inside the pixel"
                );
                // Its sub-cell: distinct samples, one per cell.
                let cell = ((oy * s as f32) as u32 * s + (ox * s as f32) as u32) as usize;
                assert!(!cells[cell], "s = {s}: two samples in sub-cell {cell}");
                cells[cell] = true;
                cx += ox as f64;
                cy += oy as f64;
            }
            let n = (s * s) as f64;
            let err = (cx / n - 0.5).abs().max((cy / n - 0.5).abs());
            // Exact for s a power of two (every offset is a dyadic fraction); otherwise each
            // offset is one correctly rounded f32 division, off by at most half an f32 ulp below
            // 1, and so is their mean.
            let tolerance = if s.is_power_of_two() {
                0.0
            } else {
                OFFSET_ROUNDING
            };
            assert!(
                err <= tolerance,
                "s = {s}: centroid ({}, {}) off the pixel centre by {err:e} > {tolerance:e}",
                cx / n,
                cy / n
            );
        }
    }

    /// Half an `f32` ulp in `[0.5, 1)`: the largest rounding error of one offset `(i + 0.5)/s`.
    const OFFSET_ROUNDING: f64 = 1.0 / (1u64 << 25) as f64;

    /// The box filter's weights are `1/s²` each and sum to 1: `s²` equal samples filter to their
    /// value exactly, one sample of value `1` among zeros to `1/s²`, and a ramp to its mean.
    /// Mutation-checked: dividing by `s² + 1` or by `s` in `box_filter` fails it.
    #[test]
    fn box_filter_weights_are_one_over_s_squared_and_sum_to_one() {
        for s in 1..=9u32 {
            let n = s * s;
            let c = [0.3f32, 0.7, 1.0];
            let mut sum = [0.0f64; 3];
            for _ in 0..n {
                for k in 0..3 {
                    sum[k] += c[k] as f64;
                }
            }
            assert_eq!(box_filter(sum, s), c, "s = {s}: weights do not sum to 1");
            let one = box_filter([1.0, 0.0, 2.0], s);
            let w = (1.0 / n as f64) as f32;
            assert_eq!(one, [w, 0.0, (2.0 / n as f64) as f32], "s = {s}: weight");
            // Samples 0, 1, ..., n - 1: the mean is (n - 1) / 2.
            let ramp: f64 = (0..n).map(f64::from).sum();
            assert_eq!(box_filter([ramp; 3], s)[0], (n - 1) as f32 / 2.0, "s = {s}");
        }
    }

    /// The classification rule at its boundaries (module docs): exactly half the samples on trees
    /// is a tree pixel, one fewer is not; the rest by majority, ties to ground; and the tree
    /// fraction is `trees / s²`. Mutation-checked: `>=` -> `>` in either comparison of
    /// `classify`, and the tree count read from the ground's slot, each fail it.
    #[test]
    fn classification_rule_at_its_boundaries() {
        use PixelClass::*;
        // counts are [sky, ground, tree].
        let cases: [([u32; 3], u32, PixelClass); 13] = [
            ([0, 0, 16], 4, Tree),
            ([8, 0, 8], 4, Tree),   // exactly half: tree
            ([0, 8, 8], 4, Tree),   // exactly half: tree
            ([9, 0, 7], 4, Sky),    // one short of half
            ([0, 9, 7], 4, Ground), // one short of half
            ([5, 4, 7], 4, Sky),    // one short, sky majority of the rest
            ([4, 5, 7], 4, Ground),
            ([8, 8, 0], 4, Ground), // ground-sky tie: ground
            ([9, 7, 0], 4, Sky),
            ([2, 2, 5], 3, Tree), // odd s²: 5 of 9 is more than half
            ([3, 2, 4], 3, Sky),  // 4 of 9 is less than half
            ([0, 0, 1], 1, Tree),
            ([1, 0, 0], 1, Sky),
        ];
        for (counts, s, want) in cases {
            assert_eq!(counts.iter().sum::<u32>(), s * s, "case {counts:?}");
            assert_eq!(classify(counts, s), want, "counts {counts:?}, s = {s}");
            assert_eq!(
                tree_fraction(counts, s),
                counts[2] as f32 / (s * s) as f32,
                "counts {counts:?}, s = {s}"
            );
        }
        assert_eq!(tree_fraction([8, 0, 8], 4), 0.5);
        assert_eq!((Sky as usize, Ground as usize, Tree as usize), (0, 1, 2));
    }

    #[test]
    fn intersection_matches_obvhs_and_its_barycentrics_rebuild_the_hit_point() {
        let tri = BvhTriangle {
            v0: Vec3A::new(0.0, 0.0, 0.0),
            v1: Vec3A::new(2.0, 0.0, 0.0),
            v2: Vec3A::new(0.0, 3.0, 0.0),
        };
        for (ox, oy) in [(0.3f32, 0.4f32), (1.1, 0.2), (0.1, 2.5), (1.9, 1.9)] {
            let ray = Ray::new(
                Vec3A::new(ox, oy, 5.0),
                Vec3A::new(0.01, -0.02, -1.0),
                0.0,
                1e9,
            );
            let t_obvhs = tri.intersect(&ray);
            match intersect_triangle(&tri, &ray) {
                Some((t, u, v)) => {
                    assert_eq!(t.to_bits(), t_obvhs.to_bits());
                    let p = ray.origin + ray.direction * t;
                    let q = tri.v0 * (1.0 - u - v) + tri.v1 * u + tri.v2 * v;
                    assert!((p - q).length() < 1e-5, "{p:?} vs {q:?}");
                }
                None => assert!(t_obvhs.is_infinite(), "({ox}, {oy})"),
            }
        }
    }

    #[test]
    fn primary_rays_hit_where_the_projection_puts_a_point() {
        let camera = Camera::look_at([0.0, 0.0, 10.0], [100.0, 20.0, 0.0], 60.0, 64, 48);
        let vp = camera.view_projection();
        let p = glam::Vec3::new(60.0, 30.0, 2.0);
        let clip = vp * p.extend(1.0);
        let fx = (clip.x / clip.w + 1.0) * 0.5 * 64.0;
        let fy = (1.0 - clip.y / clip.w) * 0.5 * 48.0;
        let (o, d) = primary_ray(&camera, fx, fy);
        let depth = (p - glam::Vec3::from(o)).dot(camera.basis().forward);
        let q = glam::Vec3::from(o) + glam::Vec3::from(d) * depth;
        assert!((p - q).length() < 1e-3, "{p} vs {q}");
    }

    #[test]
    fn the_ground_grid_is_the_rasterizers() {
        let scene = builtin::pair();
        let camera = Camera::look_at([0.0, -30.0, 8.0], [0.0, 0.0, 0.0], 60.0, 32, 32);
        let vp = camera.view_projection();
        let raster = terrain_triangles(&scene, &vp);
        let n = TERRAIN_CELLS;
        let mut k = 0;
        for j in 0..n {
            for i in 0..n {
                let a = terrain_vertex(&scene, i, j);
                let b = terrain_vertex(&scene, i + 1, j);
                let c = terrain_vertex(&scene, i + 1, j + 1);
                let d = terrain_vertex(&scene, i, j + 1);
                for tri in [[a, b, c], [a, c, d]] {
                    for (v, (p, color)) in raster[k].iter().zip(tri) {
                        let clip = vp * glam::Vec3::from(p).extend(1.0);
                        assert_eq!(v.clip, clip.to_array());
                        assert_eq!(v.varyings, color);
                    }
                    k += 1;
                }
            }
        }
    }

    /// The per-tree BVH (the default) and the per-triangle one give the same images and the same
    /// hits, bit for bit: both test the same triangles with the same tie rule (module docs).
    #[test]
    fn the_tree_and_triangle_layouts_trace_the_same_hits() {
        use crate::cameras::named_camera;
        for scene in [builtin::pair(), builtin::tiny()] {
            let tris = GroundTruthScene::build_with(&scene, 0.5, TruthLayout::TRIANGLES).unwrap();
            let default = GroundTruthScene::build(&scene, 0.5).unwrap();
            assert_eq!(default.layout(), TruthLayout::default());
            let trees = GroundTruthScene::build_with(&scene, 0.5, TruthLayout::TREES).unwrap();
            let fours = TruthLayout { max_triangles: 4 };
            let fours = GroundTruthScene::build_with(&scene, 0.5, fours).unwrap();
            assert_eq!(trees.triangles(), tris.triangles());
            assert_eq!(tris.primitive_count(), tris.triangle_count());
            assert_eq!(
                trees.primitive_count(),
                scene.instances.len() + trees.triangle_count() - trees.tree_triangle_count()
            );
            assert!(fours.primitive_count() > trees.primitive_count());
            let mut tree_pixels = 0;
            let mut cameras: Vec<(String, Camera)> =
                [("far", 0.0), ("medium", 30.0), ("close", 200.0)]
                    .iter()
                    .map(|(n, yaw)| {
                        (
                            n.to_string(),
                            named_camera(n, &scene, *yaw, 40, 24).unwrap(),
                        )
                    })
                    .collect();
            // Looking at the first tree from 40 m, so both scenes show trees.
            let p = scene.instances[0].position;
            let eye = [p[0] - 30.0, p[1] - 25.0, p[2] + 10.0];
            let at = [p[0], p[1], p[2] + 8.0];
            cameras.push(("tree".into(), Camera::look_at(eye, at, 60.0, 40, 24)));
            for (name, camera) in cameras {
                let b = tris.render(&camera, 2);
                for other in [&default, &trees, &fours] {
                    let a = other.render(&camera, 2);
                    let differing = (0..a.linear.len())
                        .filter(|&i| a.linear[i] != b.linear[i] || a.class[i] != b.class[i])
                        .count();
                    assert!(
                        a == b,
                        "{} {name}: {differing} pixels differ between {:?} and one triangle per \
                         primitive",
                        scene.name,
                        other.layout()
                    );
                }
                let a = trees.render(&camera, 2);
                tree_pixels += a.class.iter().filter(|c| **c == PixelClass::Tree).count();
                for y in 0..24 {
                    for x in 0..40 {
                        let (o, d) = primary_ray(&camera, x as f32 + 0.3, y as f32 + 0.7);
                        for alpha in [false, true] {
                            let expected = tris.trace(o, d, camera.near, camera.far, alpha);
                            for other in [&trees, &fours] {
                                assert_eq!(
                                    other.trace(o, d, camera.near, camera.far, alpha),
                                    expected,
                                    "{} {name} ({x}, {y}) alpha {alpha} {:?}",
                                    scene.name,
                                    other.layout()
                                );
                            }
                        }
                    }
                }
            }
            assert!(tree_pixels > 0, "{}: no tree seen", scene.name);
        }
    }

    #[test]
    fn a_pair_of_trees_is_seen_with_sky_and_ground_and_the_image_is_thread_independent() {
        let scene = builtin::pair();
        let gt = GroundTruthScene::build(&scene, 0.5).unwrap();
        let expected: usize = scene
            .instances
            .iter()
            .map(|t| scene.meshes[t.mesh as usize].indices.len() / 3)
            .sum();
        assert_eq!(gt.tree_triangle_count(), expected);
        let camera = Camera::look_at([0.0, -40.0, 10.0], [0.0, 0.0, 10.0], 60.0, 48, 32);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| gt.render(&camera, 2));
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
            .install(|| gt.render(&camera, 2));
        assert_eq!(one, two);
        // A region is the full frame's pixels there, bit for bit (the sweeps' sampled tiles).
        let (x0, y0, rw, rh) = (13, 5, 20, 17);
        let region = gt.render_region(&camera, 2, [x0, y0, rw, rh]);
        assert_eq!((region.width, region.height), (rw, rh));
        assert_eq!(region.rays, (rw * rh * 4) as u64);
        for y in 0..rh {
            for x in 0..rw {
                let (r, f) = ((y * rw + x) as usize, ((y0 + y) * 48 + x0 + x) as usize);
                assert_eq!(region.linear[r], one.linear[f], "({x}, {y})");
                assert_eq!(region.class[r], one.class[f]);
                assert_eq!(region.srgb.texels[r], one.srgb.texels[f]);
            }
        }
        assert!(gt.memory_bytes() > (gt.triangle_count() * size_of::<BvhTriangle>()) as u64);
        for class in [PixelClass::Sky, PixelClass::Ground, PixelClass::Tree] {
            assert!(one.class.contains(&class), "{class:?} missing");
        }
        // Alpha-tested: the crowns let the sky through somewhere in their bounding boxes, so some
        // rays that the opaque query stops are not stopped by the alpha-tested one.
        let mut through = 0;
        for y in 0..32 {
            for x in 0..48 {
                let (o, d) = primary_ray(&camera, x as f32 + 0.5, y as f32 + 0.5);
                let opaque = gt.trace(o, d, camera.near, camera.far, false);
                let tested = gt.trace(o, d, camera.near, camera.far, true);
                if let (Some(a), Some(b)) = (opaque, tested) {
                    assert!(a.t <= b.t);
                    through += (b.t > a.t) as u32;
                }
            }
        }
        assert!(through > 0);
    }
}
