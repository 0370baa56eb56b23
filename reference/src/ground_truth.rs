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
//! - **Watertight leaf test** ([`intersect_triangle`]): the ray–triangle test of Woop, Benthin and
//!   Wald, "Watertight Ray/Triangle Intersection" (JCGT 2013), double-sided, with edges and
//!   vertices inclusive: a ray through an edge or a vertex that triangles share hits one or all of
//!   them, never none, so a closed surface shows no sky or ground through its seams (the
//!   rasterizer's fill rule gives such a sample to exactly one triangle; here the tie rule below
//!   picks one). The leaf test is what is watertight; obvhs's traversal reaches both leaves of a
//!   seam because its compressed child boxes are rounded outward, and the oracle checks the whole
//!   trace end to end. It replaced obvhs's Möller–Trumbore (`Triangle::intersect`), which is not
//!   watertight: the truth oracle (`reference/tests/truth_oracle.rs`) saw rays through the shared
//!   diagonal of a two-triangle square miss both triangles (9 of 81 diagonal samples at `s = 3`,
//!   8 of 108 at 4, 6 of 135 at 5). Effect on the built-in scenes (`pair`, `tiny`, `synthetic`,
//!   cameras `far`, `medium`, `close` at yaw 30°, 320x180, `s = 4`): no pixel changed class or tree
//!   fraction; the linear colours of up to 65 % of the pixels moved by rounding (barycentrics
//!   computed differently, so the interpolated ground colour and texture lookups move by ulps:
//!   at most 2e-5 on the `far` views) and by at most 0.009 where a sample's texel or alpha test
//!   at a texel boundary flipped; at most 21 pixels per image changed in sRGB8, by at most 6
//!   levels. Cost: about 1.2x the trace time (module `intersect_triangle`'s doc and
//!   `experiments/truth_bvh/README.md`).
//! - **Alpha test as an any-hit filter**: the intersection callback obvhs calls for every
//!   candidate triangle samples the mesh texture (level 0, bilinear, linear light: the finest
//!   level the rasterizer can show) at the hit's uv and rejects the hit when alpha is below the
//!   cutoff, so the traversal goes on and finds the nearest *accepted* hit. No re-casting is needed:
//!   a rejected hit never shortens the ray. Ties at equal `t` (crossed cards meet along a line) go
//!   to the lowest triangle id, so the result does not depend on the BVH's shape.
//! - **Colour** is the unlit texture colour, as LOD0 writes it: the texel's linear RGB (its alpha
//!   only decides the test). Ground: the interpolated vertex colour. Sky: [`SKY_SRGB`].
//! - **Lighting** (issue 30, G§5; [`TruthLighting`]): a shaded frame's truth multiplies each tree
//!   hit's colour by a lightness, one of two:
//!   - *model*: the sun-depth model ([`forestlod_shared::light`]) evaluated at the hit point itself
//!     on the full mesh, so that a frame's error against it is the error of the representation
//!     (billboard, per-vertex interpolation), not of the model;
//!   - *shadow*: one ray from the hit towards the sun through the alpha-tested trees, lightness 1
//!     when it escapes and the ambient level when a tree stops it (self- and mutual shadowing,
//!     what the sun-depth model stands in for). It starts [`SHADOW_RAY_OFFSET`] off the hit (and
//!     at least 8 ulps of the hit's largest coordinate), so the hit's own card does not shadow
//!     it. One ray per hit: a hard shadow of a point sun, deterministic.
//!
//!   The ground stays unlit under both (no variant shades it, so its error would be no
//!   representation's), and the crown of each tree is the one the draw lights: its
//!   bounding-sphere centre ([`crate::scene::tree_sphere`]) and [`forestlod_shared::crown_radii`].
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

/// One traced pixel: box-filtered linear RGB, class, tree fraction and the shadow rays traced.
type TracedPixel = ([f32; 3], PixelClass, f32, u64);

/// How a truth lights its tree hits (module docs); `None` in the render calls is unlit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthLighting {
    /// Unit direction towards the sun.
    pub sun: [f32; 3],
    /// The ambient level (the sun-depth model's far side; the shadow truth's shadowed level).
    pub ambient: f32,
    /// Shadow rays (`shadow`) instead of the sun-depth model at the hit (`model`).
    pub shadows: bool,
}

impl TruthLighting {
    /// The lighting a frame of validated `params` is measured against under truth mode `mode`:
    /// `None` when its trees are unlit, else its sun and ambient level.
    pub fn of(
        params: &forestlod_shared::Params,
        mode: forestlod_shared::TruthLight,
    ) -> Option<Self> {
        if params.shading_mode().ok()? == forestlod_shared::Shading::Unlit {
            return None;
        }
        Some(Self {
            sun: params.sun_dir(),
            ambient: params.ambient,
            shadows: mode == forestlod_shared::TruthLight::Shadow,
        })
    }
}

/// The least distance a shadow ray starts from its hit, metres (module docs): a centimetre, far
/// below a leaf card's size and above the rounding of a hit point in a scene of a few km.
pub const SHADOW_RAY_OFFSET: f32 = 0.01;

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
    /// Per tree, its crown for the lit truths: `[centre x, y, z, R_h, R_v]` (module docs).
    tree_crown: Vec<[f32; 5]>,
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

/// Ray–triangle intersection, **watertight**: the algorithm of Woop, Benthin and Wald,
/// "Watertight Ray/Triangle Intersection" (JCGT 2(1), 2013; the test pbrt-v3/v4's
/// `Triangle::Intersect` uses), double-sided. Returns `(t, u, v)` with `u`, `v` the barycentric
/// weights of `v1` and `v2` (the hit point is `(1 - u - v)·v0 + u·v1 + v·v2`), or `None` for a
/// miss, a `t` outside `[tmin, tmax]` (NaN included), a zero direction, or a triangle seen edge-on
/// (zero determinant).
///
/// The steps (paper §3):
/// 1. **Permute** the axes so the ray's largest direction component `kz` (the first of equal
///    maxima) becomes z, `kx`, `ky` the next two cyclically; **translate** every vertex by the ray
///    origin and **shear** it so the ray becomes the +z axis from the origin: `x = q[kx] -
///    sx·q[kz]`, `y = q[ky] - sy·q[kz]` with `q = vertex - origin`, `sx = d[kx]/d[kz]`,
///    `sy = d[ky]/d[kz]`. The transformed vertex depends on the vertex and the ray only, so two
///    triangles that share a vertex see it at the same `f32` point.
/// 2. **Edge functions** of the 2D triangle at the origin, the same expression for every edge
///    `p -> q`: `E = q.x·p.y - q.y·p.x` (`e0` for `v1 -> v2`, `e1` for `v2 -> v0`, `e2` for
///    `v0 -> v1`; `e0 : e1 : e2` are the barycentrics of `v0`, `v1`, `v2`). Two triangles that share
///    an edge compute the same products, so their edge functions are exact negatives (or equal, if
///    their windings disagree). Each is `fl(fl(a) - fl(b))` of two rounded products: when it is
///    not 0 its sign is exact (rounding is monotonic); when any is exactly 0 all three are
///    recomputed in `f64`, where the products of `f32`s are exact, so the sign is the exact sign of
///    the edge function of the transformed vertices, and a shared edge gets opposite signs (or 0)
///    on its two sides.
/// 3. **Inclusive sign test** (the consistent rule for zeros): hit when no edge function is
///    negative or none is positive (double-sided); an edge function of exactly 0 (the ray through
///    an edge or a vertex) counts as inside. A ray through an edge shared by two triangles, or a
///    vertex shared by a fan, therefore hits one or all of them, never none; the caller's tie rule
///    (nearest `t`, then lowest triangle id) picks one, deterministically.
/// 4. `det = e0 + e1 + e2` (0 when the ray lies in the triangle's plane: a miss);
///    `t = (e0·z0 + e1·z1 + e2·z2) / det` with `z = q[kz] / d[kz]`, the ray parameter of the
///    vertex's depth (so `t` is in units of the unnormalized direction, as the rays need);
///    `u = e1 / det`, `v = e2 / det`.
///
/// The `f64` fallback is not what keeps a shared edge closed (the inclusive rule does: an `f32`
/// edge function of 0 is 0 on both sides, and a non-zero one has its exact sign); it makes a 0
/// mean "exactly on the edge of the transformed triangle", so a ray that passes outside a
/// silhouette by less than the products' rounding is not taken for a hit. No test pins that
/// (the unit tests pass without the fallback); it is the paper's algorithm, kept whole.
///
/// Why not Möller–Trumbore (obvhs's `Triangle::intersect`, this function's first form): its
/// barycentrics of a point on a shared edge are computed from each triangle's own edge vectors
/// and rounded differently on either side, so a ray exactly through the edge can get a tiny
/// negative weight in **both** triangles and miss the closed surface. The truth oracle
/// (`reference/tests/truth_oracle.rs`) measured it: on a pixel-aligned square of two triangles,
/// 9 of 81 samples on its diagonal saw the sky at `s = 3`, 8 of 108 at `s = 4`, 6 of 135 at
/// `s = 5`. Away from edges the two agree on hit or miss, with `t` within rounding (a unit test
/// compares them). It costs about 1.2x Möller–Trumbore's trace time on the built-in scenes
/// (`experiments/truth_bvh/README.md`); the shear is computed once per ray (`RayShear`).
pub fn intersect_triangle(tri: &BvhTriangle, ray: &Ray) -> Option<(f32, f32, f32)> {
    RayShear::new(ray)?.intersect(tri, ray.tmin, ray.tmax)
}

/// Step 1 of [`intersect_triangle`] for one ray, computed once per ray ([`GroundTruthScene::trace`]
/// reuses it for every triangle the traversal tests; it depends on the origin and direction only).
#[derive(Clone, Copy, Debug)]
struct RayShear {
    origin: [f32; 3],
    /// The permutation `(kx, ky, kz)`: `kz` the largest direction component.
    k: [usize; 3],
    /// `d[kx]/d[kz]`, `d[ky]/d[kz]`, `1/d[kz]`.
    s: [f32; 3],
}

impl RayShear {
    /// `None` for a zero direction.
    fn new(ray: &Ray) -> Option<Self> {
        let d = ray.direction.to_array();
        let a = d.map(f32::abs);
        let kz = if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        };
        if d[kz] == 0.0 {
            return None;
        }
        let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
        // No swap of kx and ky for d[kz] < 0 (the paper's, to keep the winding for backface
        // culling): the test is double-sided, and the mirror only flips every edge function's
        // sign and det's, which cancel in t, u and v.
        Some(Self {
            origin: ray.origin.to_array(),
            k: [kx, ky, kz],
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
        })
    }

    /// Steps 1 (the vertices) to 4 of [`intersect_triangle`].
    #[inline]
    fn intersect(&self, tri: &BvhTriangle, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        let ([kx, ky, kz], [sx, sy, sz], o) = (self.k, self.s, self.origin);
        let transform = |p: Vec3A| {
            let p = p.to_array();
            let q = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            [q[kx] - sx * q[kz], q[ky] - sy * q[kz], sz * q[kz]]
        };
        let [p0, p1, p2] = [tri.v0, tri.v1, tri.v2].map(transform);
        // Edge p -> q: q.x·p.y - q.y·p.x.
        let edge = |p: [f32; 3], q: [f32; 3]| q[0] * p[1] - q[1] * p[0];
        let mut e = [edge(p1, p2), edge(p2, p0), edge(p0, p1)];
        if e.contains(&0.0) {
            let edge64 = |p: [f32; 3], q: [f32; 3]| {
                (f64::from(q[0]) * f64::from(p[1]) - f64::from(q[1]) * f64::from(p[0])) as f32
            };
            e = [edge64(p1, p2), edge64(p2, p0), edge64(p0, p1)];
        }
        if e.iter().any(|&x| x < 0.0) && e.iter().any(|&x| x > 0.0) {
            return None;
        }
        let det = e[0] + e[1] + e[2];
        if det == 0.0 {
            return None;
        }
        let t = (e[0] * p0[2] + e[1] * p1[2] + e[2] * p2[2]) / det;
        if t >= tmin && t <= tmax {
            Some((t, e[1] / det, e[2] / det))
        } else {
            None
        }
    }
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
        for [p, q, r] in scene.ground_triangles() {
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
            tree_crown: {
                let metas: Vec<_> = scene.meshes.iter().map(|m| m.bounds_meta()).collect();
                scene
                    .instances
                    .iter()
                    .map(|t| {
                        let meta = &metas[t.mesh as usize];
                        let (c, _) = crate::scene::tree_sphere(t, meta);
                        let [rh, rv] = forestlod_shared::crown_radii(meta, t.scale);
                        [c[0], c[1], c[2], rh, rv]
                    })
                    .collect()
            },
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
            + bytes(self.tree_crown.len(), size_of::<[f32; 5]>())
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
        // Step 1 of the watertight test, once per ray; a zero direction sees nothing.
        let shear = RayShear::new(&ray)?;
        // Best (t, scene index, u, v), ties to the lowest scene index.
        let mut best: Option<(f32, u32, f32, f32)> = None;
        // Tests scene triangle `index` (of tree `tree`, or the ground), keeps it when it is the
        // best so far, and returns its `t` (infinity when it is missed or alpha-rejected).
        let mut test = |r: &Ray, index: u32, tree: Option<u32>| -> f32 {
            let Some((t, u, v)) = shear.intersect(&self.triangles[index as usize], r.tmin, r.tmax)
            else {
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
        self.render_lit(camera, samples_per_axis, None)
    }

    /// [`GroundTruthScene::render`] with the trees lit by `lighting` (module docs; `None`:
    /// unlit, the same image).
    pub fn render_lit(
        &self,
        camera: &Camera,
        samples_per_axis: u32,
        lighting: Option<TruthLighting>,
    ) -> GroundTruthImage {
        self.render_region(
            camera,
            samples_per_axis,
            [0, 0, camera.width, camera.height],
            lighting,
        )
    }

    /// The lightness of a tree hit at `t` along `origin + t·direction` on scene triangle
    /// `triangle` under `lighting` (module docs), and the shadow rays it traced (0 or 1).
    fn tree_lightness(
        &self,
        lighting: &TruthLighting,
        (origin, direction, t): ([f32; 3], [f32; 3], f32),
        triangle: u32,
    ) -> (f32, u64) {
        let Some(tree) = self.tree_of(triangle) else {
            return (1.0, 0);
        };
        let p = [0, 1, 2].map(|i| origin[i] + t * direction[i]);
        if lighting.shadows {
            let largest = p.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            let tmin = SHADOW_RAY_OFFSET.max(8.0 * f32::EPSILON * largest);
            let blocked = self
                .trace(
                    p,
                    lighting.sun,
                    tmin,
                    forestlod_shared::params::MAX_DISTANCE,
                    true,
                )
                .is_some_and(|h| h.class == PixelClass::Tree);
            return (if blocked { lighting.ambient } else { 1.0 }, 1);
        }
        let [cx, cy, cz, rh, rv] = self.tree_crown[tree as usize];
        let delta = forestlod_shared::sun_depth(p, [cx, cy, cz], [rh, rv], lighting.sun);
        (forestlod_shared::lightness(delta, lighting.ambient), 0)
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
        lighting: Option<TruthLighting>,
    ) -> GroundTruthImage {
        assert!(
            x0 + w <= camera.width && y0 + h <= camera.height,
            "region outside the frame"
        );
        let s = samples_per_axis.max(1);
        let offsets = sample_offsets(s);
        let sky = SKY_SRGB.map(srgb_to_linear);
        let rows: Vec<Vec<TracedPixel>> = (y0..y0 + h)
            .into_par_iter()
            .with_max_len(1)
            .map(|y| {
                (x0..x0 + w)
                    .map(|x| {
                        let mut sum = [0.0f64; 3];
                        let mut counts = [0u32; 3];
                        let mut shadow_rays = 0u64;
                        // The pattern's order (rows outer, columns inner) is the summation order.
                        for &[ox, oy] in &offsets {
                            let (o, d) = primary_ray(camera, x as f32 + ox, y as f32 + oy);
                            let (class, color) =
                                match self.trace(o, d, camera.near, camera.far, true) {
                                    Some(hit) => match (&lighting, hit.class) {
                                        (Some(l), PixelClass::Tree) => {
                                            let (light, rays) =
                                                self.tree_lightness(l, (o, d, hit.t), hit.triangle);
                                            shadow_rays += rays;
                                            (hit.class, hit.color.map(|c| c * light))
                                        }
                                        _ => (hit.class, hit.color),
                                    },
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
                            shadow_rays,
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
            rays: w as u64 * h as u64 * (s * s) as u64 + pixels.iter().map(|p| p.3).sum::<u64>(),
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

    /// splitmix64: seeded pseudo-random numbers for the intersection tests.
    fn mix(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A seeded uniform number in `[lo, hi)`.
    fn uniform(seed: u64, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((mix(seed) >> 11) as f64 / (1u64 << 53) as f64)
    }

    /// The ray's intersection with the triangle's plane in `f64` from the same `f32` inputs
    /// (Cramer's rule on `o + t·d = v0 + u·(v1 - v0) + v·(v2 - v0)`): `(t, u, v)`, inside or not.
    fn exact_hit(tri: &BvhTriangle, ray: &Ray) -> (f64, f64, f64) {
        let f = |v: Vec3A| glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64);
        let (v0, e1, e2) = (f(tri.v0), f(tri.v1) - f(tri.v0), f(tri.v2) - f(tri.v0));
        let (o, d) = (f(ray.origin), f(ray.direction));
        let s = o - v0;
        let det = glam::DMat3::from_cols(-d, e1, e2).determinant();
        let t = glam::DMat3::from_cols(s, e1, e2).determinant() / det;
        let u = glam::DMat3::from_cols(-d, s, e2).determinant() / det;
        let v = glam::DMat3::from_cols(-d, e1, s).determinant() / det;
        (t, u, v)
    }

    /// Relative tolerance on `t` between this test and obvhs's Möller–Trumbore, and between it and
    /// the exact (`f64`) ray parameter of the same `f32` inputs. Both are `f32` formulas with a
    /// handful of rounded products and sums each; their error is a few ulps of the products, which
    /// scale with the coordinates (up to 100 m here) over `t` times `1/|cos|` of the hit angle
    /// (the rays below come from 0.5 m off the plane at the least, to 60 m across). 2e-5 is ~170
    /// ulps of `t`, the Embree cross-check's `T_REL_TOL`; the test prints the worst it saw. A
    /// wrong `t` (another vertex's depth, a wrong weight) is off by the triangle's depth range,
    /// 1e-2 relative or more here.
    const T_REL_TOLERANCE: f64 = 2e-5;

    /// Away from edges by this much in barycentric terms (the smallest weight, exact in `f64`),
    /// the two tests must agree on hit or miss: each rounds its weights by ~1e-7 of the triangle.
    const EDGE_MARGIN: f64 = 1e-4;

    /// This test against obvhs's `Triangle::intersect` (the Möller–Trumbore it replaced) and the
    /// exact intersection, over seeded random triangles (sizes 0.1 to 20 m, placed up to 100 m
    /// from the world origin) and rays from both sides: every ray whose exact hit lies more than
    /// [`EDGE_MARGIN`] inside the triangle hits in both, every one more than that outside misses
    /// in both, `t` agrees within [`T_REL_TOLERANCE`] with obvhs's and with the exact one, and the
    /// barycentrics `(u, v)` rebuild the hit point `o + t·d` within [`T_REL_TOLERANCE`] of the
    /// scene's scale (it prints the worst of each: 1.9e-6 to obvhs, 6.5e-7 to exact, 3.3e-7 for
    /// the point when written). Mutation-checked: `u` and `v` swapped in the result, and `t` taken
    /// as one vertex's depth (`t = p0[2]`), each fail it.
    #[test]
    fn intersection_agrees_with_obvhs_away_from_edges_and_its_barycentrics_rebuild_the_hit_point() {
        let (mut inside, mut outside, mut near_edge) = (0u32, 0u32, 0u32);
        let (mut worst_obvhs, mut worst_exact, mut worst_point) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..400u64 {
            let r = |i: u64, lo: f64, hi: f64| uniform(k * 64 + i, lo, hi) as f32;
            let centre = Vec3A::new(r(0, -100.0, 100.0), r(1, -100.0, 100.0), r(2, -10.0, 30.0));
            let size = uniform(k * 64 + 3, -1.0, 1.3).exp2().powi(3) as f32 * 0.5;
            let corner = |i: u64| {
                centre
                    + Vec3A::new(r(i, -1.0, 1.0), r(i + 1, -1.0, 1.0), r(i + 2, -1.0, 1.0)) * size
            };
            let tri = BvhTriangle {
                v0: corner(4),
                v1: corner(7),
                v2: corner(10),
            };
            let normal = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize();
            for j in 0..16u64 {
                let s = |i: u64, lo: f64, hi: f64| uniform(k * 64 + 16 + j * 3 + i, lo, hi) as f32;
                // A point near the triangle (about half the rays miss), seen from 0.5 to 60 m
                // off its plane, on either side.
                let (a, b) = (s(0, -0.2, 1.2), s(1, -0.2, 1.2));
                let target = tri.v0 + (tri.v1 - tri.v0) * a + (tri.v2 - tri.v0) * (b * (1.0 - a));
                let side = if j % 2 == 0 { 1.0 } else { -1.0 };
                let away = normal * (side * s(2, 0.5, 60.0));
                let lateral = Vec3A::new(s(0, -30.0, 30.0), s(1, -30.0, 30.0), s(2, -30.0, 30.0));
                let origin = target + away + lateral.reject_from(normal) * 0.5;
                let ray = Ray::new(origin, (target - origin) * s(0, 0.05, 3.0), 0.0, 1e9);
                let (te, ue, ve) = exact_hit(&tri, &ray);
                let least = ue.min(ve).min(1.0 - ue - ve);
                let t_obvhs = tri.intersect(&ray);
                let ours = intersect_triangle(&tri, &ray);
                if least.abs() <= EDGE_MARGIN {
                    near_edge += 1;
                    continue;
                }
                if least < 0.0 {
                    outside += 1;
                    assert!(
                        ours.is_none() && t_obvhs.is_infinite(),
                        "triangle {k} ray {j}: exactly {least:e} outside, but hit: ours {ours:?}, \
                         obvhs {t_obvhs}"
                    );
                    continue;
                }
                inside += 1;
                let Some((t, u, v)) = ours else {
                    panic!(
                        "triangle {k} ray {j}: exactly {least:e} inside, missed (obvhs t {t_obvhs})"
                    )
                };
                let rel_obvhs = (t as f64 - t_obvhs as f64).abs() / t as f64;
                let rel_exact = (t as f64 - te).abs() / te;
                let p = ray.origin + ray.direction * t;
                let q = tri.v0 * (1.0 - u - v) + tri.v1 * u + tri.v2 * v;
                let scale = ray.origin.abs().max(tri.v0.abs()).max_element() as f64;
                let rel_point = (p - q).length() as f64 / scale;
                assert!(
                    rel_obvhs <= T_REL_TOLERANCE
                        && rel_exact <= T_REL_TOLERANCE
                        && rel_point <= T_REL_TOLERANCE,
                    "triangle {k} ray {j}: t {t} vs obvhs {t_obvhs} ({rel_obvhs:e}) and exact {te} \
                     ({rel_exact:e}); (u, v) = ({u}, {v}) vs exact ({ue}, {ve}) rebuild {q} for \
                     {p} ({rel_point:e} of {scale}); tolerance {T_REL_TOLERANCE:e}"
                );
                worst_obvhs = worst_obvhs.max(rel_obvhs);
                worst_exact = worst_exact.max(rel_exact);
                worst_point = worst_point.max(rel_point);
            }
        }
        println!(
            "{inside} inside, {outside} outside, {near_edge} within {EDGE_MARGIN:e} of an edge; \
             worst relative t difference to obvhs {worst_obvhs:e}, to exact {worst_exact:e}, \
             hit point rebuild {worst_point:e} (tolerance {T_REL_TOLERANCE:e})"
        );
        assert!(
            inside > 1000 && outside > 500,
            "{inside} inside, {outside} outside"
        );
    }

    /// Watertightness (Woop et al. 2013; the function's docs): rays aimed exactly (in `f32`) at a
    /// vertex shared by a closed fan of triangles, or at points of the edges the fan's triangles
    /// share, hit at least one of them: the surface has no gap. Fans: axis-aligned spokes in an
    /// axis plane (edges exactly along x and y), diagonal spokes, a tilted plane and an irregular
    /// 7-spoke fan, with centres at coordinates that are not exactly representable in `f32` (0.1,
    /// 1/3, 1000.1, ...), rays from both sides and several distances and angles, fan windings
    /// mixed. It also counts how many of the same rays obvhs's Möller–Trumbore misses on every
    /// triangle and asserts there are some: the rays reach the hard side (the truth's old leak).
    /// (obvhs misses every triangle on 207 of the 3,984 rays when written.) Mutation-checked: the
    /// old Möller–Trumbore body, a strict sign test (edge functions of 0 counted outside), and
    /// `t` from one vertex's depth each fail it.
    #[test]
    fn rays_through_shared_edges_and_vertices_of_a_fan_always_hit() {
        let third = 1.0f64 / 3.0;
        // (centre, in-plane axes a and b, spoke angles in degrees).
        let x = glam::DVec3::X;
        let y = glam::DVec3::Y;
        let z = glam::DVec3::Z;
        let tilted_a = glam::DVec3::new(1.0, 2.0, 3.0).any_orthonormal_vector();
        let tilted_b = glam::DVec3::new(1.0, 2.0, 3.0).normalize().cross(tilted_a);
        let fans: [(glam::DVec3, glam::DVec3, glam::DVec3, &[f64]); 6] = [
            (
                glam::DVec3::new(0.1, third, 7.7),
                x,
                y,
                &[0.0, 90.0, 180.0, 270.0],
            ),
            (
                glam::DVec3::new(1000.1, -2000.3, 10.7),
                x,
                z,
                &[0.0, 90.0, 180.0, 270.0],
            ),
            (
                glam::DVec3::new(-3.3, 0.7, third),
                y,
                z,
                &[45.0, 135.0, 225.0, 315.0],
            ),
            (
                glam::DVec3::new(12.345, 67.891, 0.0),
                x,
                y,
                &[0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0],
            ),
            (
                glam::DVec3::new(0.3, -0.6, 2.2),
                tilted_a,
                tilted_b,
                &[10.0, 80.0, 130.0, 200.0, 290.0],
            ),
            (
                glam::DVec3::new(-511.9, 77.7, 31.3),
                tilted_b,
                z,
                &[0.0, 51.0, 103.0, 154.0, 206.0, 257.0, 309.0],
            ),
        ];
        let (mut rays, mut obvhs_misses) = (0u32, 0u32);
        for (f, (centre, a, b, angles)) in fans.iter().enumerate() {
            let c = centre.as_vec3a();
            let spokes: Vec<Vec3A> = angles
                .iter()
                .map(|deg| {
                    let (s, co) = deg.to_radians().sin_cos();
                    // Exactly axis-aligned where the angle is a multiple of 90° and a, b are axes.
                    let dir = a * if co.abs() < 1e-12 { 0.0 } else { co }
                        + b * if s.abs() < 1e-12 { 0.0 } else { s };
                    (*centre + dir * 2.5).as_vec3a()
                })
                .collect();
            let n = spokes.len();
            let fan: Vec<BvhTriangle> = (0..n)
                .map(|k| {
                    let (p, q) = (spokes[k], spokes[(k + 1) % n]);
                    // Mixed windings: every third triangle the other way round.
                    if k % 3 == 2 {
                        BvhTriangle {
                            v0: c,
                            v1: q,
                            v2: p,
                        }
                    } else {
                        BvhTriangle {
                            v0: c,
                            v1: p,
                            v2: q,
                        }
                    }
                })
                .collect();
            // Targets: the shared vertex, and points along each shared edge (f32, so off the
            // exact line by rounding).
            let mut targets = vec![c];
            for &s in &spokes {
                for frac in [0.1f32, third as f32, 0.5, 0.77, 0.999] {
                    targets.push(c + (s - c) * frac);
                }
            }
            let normal = a.cross(*b).normalize();
            for (i, &target) in targets.iter().enumerate() {
                for k in 0..24u64 {
                    let seed = (f as u64 * 1000 + i as u64) * 100 + k;
                    let side = if k % 2 == 0 { 1.0 } else { -1.0 };
                    // From 0.3 to 200 m away, at least ~17° off the plane.
                    let off = glam::DVec3::new(
                        uniform(seed * 3, -3.0, 3.0),
                        uniform(seed * 3 + 1, -3.0, 3.0),
                        uniform(seed * 3 + 2, -3.0, 3.0),
                    )
                    .reject_from(normal);
                    let dir = (normal * side + off).normalize();
                    let dist = uniform(seed * 7 + 5, -1.2, 2.3).exp2().powi(3);
                    let origin = (target.as_dvec3() + dir * dist).as_vec3a();
                    let scale = uniform(seed * 11 + 3, 0.01, 10.0) as f32;
                    let ray = Ray::new(origin, (target - origin) * scale, 0.0, 1e9);
                    rays += 1;
                    let hits = fan
                        .iter()
                        .filter(|tri| intersect_triangle(tri, &ray).is_some())
                        .count();
                    assert!(
                        hits >= 1,
                        "fan {f} target {i} {target} ray {k} from {origin}: missed every one of \
                         the {n} triangles (a gap in a closed surface)"
                    );
                    obvhs_misses += fan.iter().all(|tri| tri.intersect(&ray).is_infinite()) as u32;
                }
            }
        }
        println!("{rays} rays through shared edges and vertices; obvhs misses {obvhs_misses}");
        assert!(
            obvhs_misses > 0,
            "none of the {rays} rays finds the gap Möller–Trumbore leaves: they miss the hard side"
        );
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

    /// [`GroundTruthScene::memory_bytes`] is what its doc lists, recounted from each structure's
    /// own length and element type (`size_of_val` of its elements, not the estimate's byte
    /// constants): the BVH's nodes and primitive index, the triangles, the per-tree and
    /// per-cluster ranges and mesh ids, the uvs, the textures' level 0 and the ground colours.
    /// For `pair` in both layouts (their primitive indices differ in length). The sweeps publish
    /// this number (`truth_memory`); added for issue 36's Rust mutant 1245 (the primitive
    /// index's 4 bytes -> 5).
    #[test]
    fn the_memory_estimate_is_the_recount_of_what_the_truth_holds() {
        use std::mem::size_of_val;
        let scene = builtin::pair();
        for layout in [TruthLayout::TREES, TruthLayout::TRIANGLES] {
            let gt = GroundTruthScene::build_with(&scene, 0.5, layout).unwrap();
            let parts: [(&str, usize); 11] = [
                ("bvh nodes", size_of_val(&gt.bvh.nodes[..])),
                (
                    "bvh primitive index",
                    size_of_val(&gt.bvh.primitive_indices[..]),
                ),
                ("triangles", size_of_val(&gt.triangles[..])),
                ("tree ranges", size_of_val(&gt.tree_first[..])),
                ("cluster ranges", size_of_val(&gt.cluster_first[..])),
                ("cluster trees", size_of_val(&gt.cluster_tree[..])),
                ("tree meshes", size_of_val(&gt.tree_mesh[..])),
                ("tree crowns", size_of_val(&gt.tree_crown[..])),
                ("uvs", gt.mesh_uvs.iter().map(|m| size_of_val(&m[..])).sum()),
                (
                    "textures",
                    gt.textures
                        .iter()
                        .map(|t| size_of_val(&t.level(0, 0).texels[..]))
                        .sum(),
                ),
                ("ground colours", size_of_val(&gt.ground_colors[..])),
            ];
            let recount: usize = parts.iter().map(|(_, n)| n).sum();
            assert!(
                parts.iter().all(|(_, n)| *n > 0),
                "{layout:?}: a structure is empty, so the recount checks nothing of it: {parts:?}"
            );
            assert_eq!(
                gt.memory_bytes(),
                recount as u64,
                "{layout:?}: the estimate differs from the recount by {} bytes: {parts:?}",
                gt.memory_bytes() as i64 - recount as i64
            );
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
        let region = gt.render_region(&camera, 2, [x0, y0, rw, rh], None);
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
