//! Selection at UTM-scale coordinates in three precisions (SPEC §7: "trees at UTM-scale
//! coordinates, where f32 positions lose decimetres: compare selection and images computed in f64
//! against f32 and against camera-relative f32, and report the disagreement rates").
//!
//! Not a pipeline stage: a measuring instrument for `experiments/src/bin/large_coords.rs` and the
//! test `large_coordinates_relative_f32_agrees_with_f64` in `tests/tests/properties/extremes.rs`.
//!
//! ## The three precisions
//! - **f64** ([`ViewF64::decide`]): tree and batch spheres and the eye in `f64` world coordinates,
//!   the selection rule of E§3.5 / §4.3 ([`crate::select::SelectUniform::decide`]) evaluated
//!   exactly, without the `f32` rounding margin. The ground truth.
//! - **naive f32** ([`Precision::NaiveWorld`]): the pipeline's own `f32` code fed world
//!   coordinates (origin 0): at `y ≈ 5.3e6 m` an `f32` has a spacing of 0.5 m, so every position
//!   (and the eye) moves by up to 0.25 m per axis before any arithmetic happens.
//! - **relative f32** ([`Precision::Relative`]): what the pipeline does by default (SPEC §3): the
//!   scene keeps an `f64` origin, positions and the eye are `f32` offsets from it, computed in `f64`
//!   and rounded once.
//!
//! Batch *membership* is the same in all three (the relative scene's grid batches), so a
//! disagreement is a disagreement about the same set of trees.
//!
//! ## Ambiguity
//! A decision compares a few quantities with thresholds (`lo` with the draw distance and the fade
//! end, `hi` with the fade start, the sphere's signed distance with each frustum plane). Where the
//! `f64` value of one of them lies within [`ViewF64::ambiguity_band`] of its threshold, any `f32`
//! evaluation may land on either side (SPEC §8: classify, do not weaken the whole comparison); the
//! band bounds every rounding of the relative path in metres.

use forestlod_shared::{BatchMeta, Camera, LodNeeds, MeshMeta, Params};
use glam::DVec3;

use crate::batches::{Batches, batch_meta};
use crate::scene::{Instance, Scene, footprint, tree_sphere};
use crate::select::{Decision, SelectUniform};

/// Units of `f32::EPSILON` in the ambiguity band: the relative path rounds each position and the
/// eye once (½ ε each), the tree sphere's rotation and scale (≤ 3 ε), the batch centre (½ ε), the
/// projection and its margin (≤ 8 ε, the margin itself being 4 ε) and the fade start `T - W`
/// (½ ε); 16 bounds their sum with room to spare.
pub const AMBIGUITY_EPSILONS: f64 = 16.0;

/// A sphere in `f64` world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereF64 {
    /// Centre, metres, world.
    pub center: [f64; 3],
    /// Radius, metres.
    pub radius: f64,
}

/// Tree `instance`'s bounding sphere in `f64` world coordinates for a tree whose base stands at
/// `base_world`: the same construction as [`tree_sphere`], evaluated in `f64`.
pub fn tree_sphere_f64(base_world: [f64; 3], instance: &Instance, mesh: &MeshMeta) -> SphereF64 {
    let scale = instance.scale as f64;
    let local = (DVec3::from(mesh.bbox_min.map(f64::from))
        + DVec3::from(mesh.bbox_max.map(f64::from)))
        * 0.5
        * scale;
    let (s, c) = (instance.yaw as f64).sin_cos();
    let rotated = DVec3::new(
        c * local.x - s * local.y,
        s * local.x + c * local.y,
        local.z,
    );
    SphereF64 {
        center: (DVec3::from(base_world) + rotated).to_array(),
        radius: mesh.sphere_radius as f64 * scale,
    }
}

/// The batch sphere of E Fig. 3.7 over `spheres`, exactly as [`batch_meta`] builds it (centre of
/// the centres' bounding box, radius `max |c_t - C| + r_t`), in `f64`.
pub fn batch_sphere_f64(spheres: &[SphereF64]) -> SphereF64 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for s in spheres {
        lo = lo.min(DVec3::from(s.center));
        hi = hi.max(DVec3::from(s.center));
    }
    let center = (lo + hi) * 0.5;
    let radius = spheres
        .iter()
        .map(|s| (DVec3::from(s.center) - center).length() + s.radius)
        .fold(0.0, f64::max);
    SphereF64 {
        center: center.to_array(),
        radius,
    }
}

/// A camera's selection uniform in `f64`: the eye in world coordinates, the view frame and the
/// frustum planes of [`Camera::frustum`] in `f64`.
#[derive(Clone, Copy, Debug)]
pub struct ViewF64 {
    /// Eye, world.
    pub eye: DVec3,
    /// Unit forward.
    pub forward: DVec3,
    /// Inward plane normals and offsets, relative to the eye (left, right, bottom, top, near, far).
    pub planes: [(DVec3, f64); 6],
    /// Fade band start, `T - W`.
    pub fade_start: f64,
    /// Fade band end, `T`.
    pub fade_end: f64,
    /// Draw distance.
    pub draw_distance: f64,
    /// LOD levels.
    pub lod_levels: u32,
}

impl ViewF64 {
    /// The `f64` view of `camera` (its direction, field of view, near, far and viewport; its
    /// `eye` is ignored) placed at `eye_world`.
    pub fn new(eye_world: [f64; 3], camera: &Camera, params: &Params) -> Self {
        let forward = DVec3::from(camera.forward.map(f64::from)).normalize();
        let right = forward
            .cross(DVec3::from(camera.up.map(f64::from)))
            .normalize();
        let up = right.cross(forward);
        let ty = (camera.fov_y as f64 * 0.5).tan();
        let tx = ty * camera.width as f64 / camera.height as f64;
        let plane = |n: DVec3, w: f64| {
            let len = n.length();
            (n / len, w / len)
        };
        Self {
            eye: DVec3::from(eye_world),
            forward,
            planes: [
                plane(forward * tx + right, 0.0),
                plane(forward * tx - right, 0.0),
                plane(forward * ty + up, 0.0),
                plane(forward * ty - up, 0.0),
                plane(forward, -(camera.near as f64)),
                plane(-forward, camera.far as f64),
            ],
            fade_start: params.lod1_transition as f64 - params.fade_width as f64,
            fade_end: params.lod1_transition as f64,
            draw_distance: params.draw_distance as f64,
            lod_levels: params.lod_levels,
        }
    }

    /// The exact decision for one sphere: the rule of [`SelectUniform::decide`] without margin.
    pub fn decide(&self, s: &SphereF64) -> Decision {
        let rel = DVec3::from(s.center) - self.eye;
        let d = rel.dot(self.forward);
        let (lo, hi) = (d - s.radius, d + s.radius);
        if lo > self.draw_distance {
            Decision::CulledDistance
        } else if self.planes.iter().any(|(n, w)| n.dot(rel) + w < -s.radius) {
            Decision::CulledFrustum
        } else if self.lod_levels < 2 {
            Decision::Draw(LodNeeds {
                lod0: true,
                lod1: false,
            })
        } else {
            Decision::Draw(LodNeeds {
                lod0: lo < self.fade_end,
                lod1: hi >= self.fade_start,
            })
        }
    }

    /// The smallest distance, metres, between a quantity the decision of `s` compares and its
    /// threshold.
    pub fn slack(&self, s: &SphereF64) -> f64 {
        let rel = DVec3::from(s.center) - self.eye;
        let d = rel.dot(self.forward);
        let (lo, hi) = (d - s.radius, d + s.radius);
        let mut slack = (lo - self.draw_distance).abs();
        for (n, w) in &self.planes {
            slack = slack.min((n.dot(rel) + w + s.radius).abs());
        }
        if self.lod_levels >= 2 {
            slack = slack
                .min((lo - self.fade_end).abs())
                .min((hi - self.fade_start).abs());
        }
        slack
    }

    /// The ambiguity band of `s` for a scene with origin `origin`: [`AMBIGUITY_EPSILONS`] ·
    /// `f32::EPSILON` times the sum of the magnitudes the relative path rounds (the sphere's and
    /// the eye's offsets from the origin, their difference, the radius and the thresholds).
    pub fn ambiguity_band(&self, s: &SphereF64, origin: [f64; 3]) -> f64 {
        let o = DVec3::from(origin);
        let c = DVec3::from(s.center);
        let l1 = |v: DVec3| v.x.abs() + v.y.abs() + v.z.abs();
        let scale = l1(c - o)
            + l1(self.eye - o)
            + l1(c - self.eye)
            + s.radius
            + self.fade_end.abs()
            + self.fade_start.abs()
            + self.draw_distance;
        AMBIGUITY_EPSILONS * f32::EPSILON as f64 * scale
    }
}

/// Which `f32` path a decision is computed by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// `f32` world coordinates, origin 0.
    NaiveWorld,
    /// `f32` offsets from the scene's `f64` origin (the pipeline's default).
    Relative,
}

impl Precision {
    /// Both paths.
    pub const ALL: [Precision; 2] = [Precision::NaiveWorld, Precision::Relative];
    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Precision::NaiveWorld => "f32-world",
            Precision::Relative => "f32-relative",
        }
    }
}

/// A scene prepared for comparing the three precisions: one batch membership, spheres in each.
#[derive(Clone, Debug)]
pub struct PrecisionScene {
    /// The scene the pipeline sees: `f64` origin, `f32` offsets rounded once from the world
    /// positions (what [`crate::scene::load`] does with a CSV).
    pub relative: Scene,
    /// The same trees at `f32` world positions, origin 0 (the naive path).
    pub naive: Scene,
    /// Tree base positions, `f64` world: the truth.
    pub world: Vec<[f64; 3]>,
    /// Batches of the relative scene (membership shared by all precisions).
    pub batches: Batches,
    /// Tree spheres, `f64` world.
    pub trees_f64: Vec<SphereF64>,
    /// Batch spheres, `f64` world.
    pub batches_f64: Vec<SphereF64>,
    /// Tree spheres of the relative path (what the pipeline computes).
    pub trees_relative: Vec<([f32; 3], f32)>,
    /// Tree spheres computed from `f32` world positions.
    pub trees_world: Vec<([f32; 3], f32)>,
    /// Batch metadata of the relative path.
    pub batches_relative: Vec<BatchMeta>,
    /// Batch metadata computed from the `f32` world tree spheres.
    pub batches_world: Vec<BatchMeta>,
}

impl PrecisionScene {
    /// The trees of `template` (meshes, yaws, scales, species; its positions and terrain are
    /// ignored) standing at `world` (`f64`, one per instance), for a scene origin `origin`, on flat
    /// ground under the lowest tree, batched with grid size `grid_size`.
    pub fn new(
        template: &Scene,
        world: &[[f64; 3]],
        origin: [f64; 3],
        grid_size: f32,
    ) -> Result<Self, crate::InputError> {
        assert_eq!(
            template.instances.len(),
            world.len(),
            "one position per tree"
        );
        let with_positions = |origin: [f64; 3]| {
            let instances = instances_at(&template.instances, world, origin);
            let bounds = footprint(instances.iter().map(|t| t.position));
            // Flat ground under the lowest tree, as the loaders choose it.
            let lowest = world.iter().map(|w| w[2]).fold(f64::INFINITY, f64::min);
            let terrain = crate::scene::Terrain::Flat {
                z: (lowest - origin[2]) as f32,
            };
            Scene {
                name: template.name.clone(),
                origin,
                meshes: template.meshes.clone(),
                instances,
                terrain,
                bounds,
            }
        };
        let relative = with_positions(origin);
        let naive = with_positions([0.0; 3]);
        let metas = relative.mesh_metas();
        let batches = crate::batches::build_batches(&relative, &metas, grid_size)?;
        let trees_f64: Vec<SphereF64> = relative
            .instances
            .iter()
            .zip(world)
            .map(|(t, w)| tree_sphere_f64(*w, t, &metas[t.mesh as usize]))
            .collect();
        let spheres = |scene: &Scene| -> Vec<([f32; 3], f32)> {
            scene
                .instances
                .iter()
                .map(|t| tree_sphere(t, &metas[t.mesh as usize]))
                .collect()
        };
        let trees_relative = spheres(&relative);
        let trees_world = spheres(&naive);
        let members =
            |b: &BatchMeta| &batches.indirection[b.offset as usize..(b.offset + b.len) as usize];
        let batches_f64 = batches
            .metas
            .iter()
            .map(|b| {
                let s: Vec<SphereF64> = members(b).iter().map(|&t| trees_f64[t as usize]).collect();
                batch_sphere_f64(&s)
            })
            .collect();
        let batches_world = batches
            .metas
            .iter()
            .map(|b| {
                let s: Vec<_> = members(b)
                    .iter()
                    .map(|&t| trees_world[t as usize])
                    .collect();
                batch_meta(&s, b.mesh, b.cell, b.offset)
            })
            .collect();
        Ok(Self {
            batches_relative: batches.metas.clone(),
            relative,
            naive,
            world: world.to_vec(),
            batches,
            trees_f64,
            batches_f64,
            trees_relative,
            trees_world,
            batches_world,
        })
    }

    /// The scene origin.
    pub fn origin(&self) -> [f64; 3] {
        self.relative.origin
    }

    /// `camera` (direction, lens, viewport) placed at `eye_world`, as the `f32` path `precision`
    /// sees it.
    pub fn camera_for(&self, camera: &Camera, eye_world: [f64; 3], precision: Precision) -> Camera {
        let eye = match precision {
            Precision::NaiveWorld => eye_world.map(|c| c as f32),
            Precision::Relative => {
                core::array::from_fn(|k| (eye_world[k] - self.relative.origin[k]) as f32)
            }
        };
        Camera { eye, ..*camera }
    }

    /// Compares the `f32` path `precision` with `f64` for one camera, over every batch and tree.
    pub fn compare(
        &self,
        camera: &Camera,
        eye_world: [f64; 3],
        params: &Params,
        precision: Precision,
    ) -> Disagreements {
        let view = ViewF64::new(eye_world, camera, params);
        let u = SelectUniform::new(&self.camera_for(camera, eye_world, precision), params);
        let (batches, trees) = match precision {
            Precision::NaiveWorld => (&self.batches_world, &self.trees_world),
            Precision::Relative => (&self.batches_relative, &self.trees_relative),
        };
        let mut out = Disagreements::default();
        for (meta, exact) in batches.iter().zip(&self.batches_f64) {
            out.batches.add(
                &view,
                exact,
                self.origin(),
                u.decide(meta.center, meta.radius),
            );
        }
        for (&(c, r), exact) in trees.iter().zip(&self.trees_f64) {
            out.trees.add(&view, exact, self.origin(), u.decide(c, r));
        }
        out
    }
}

/// Counts of decisions that differ from `f64`, for one kind of object (batches or trees).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct DecisionCounts {
    /// Decisions compared.
    pub total: u64,
    /// Decisions that differ from `f64` in any way.
    pub differ: u64,
    /// ... of which the `f32` path lacks a LOD `f64` draws (non-conservative: a visible error).
    pub missing: u64,
    /// ... of which the `f64` value lies outside the ambiguity band (see the module docs).
    pub differ_outside_band: u64,
}

impl DecisionCounts {
    fn add(&mut self, view: &ViewF64, exact: &SphereF64, origin: [f64; 3], got: Decision) {
        let want = view.decide(exact);
        self.total += 1;
        if want != got {
            self.differ += 1;
            if !got.needs().covers(want.needs()) {
                self.missing += 1;
            }
            if view.slack(exact) > view.ambiguity_band(exact, origin) {
                self.differ_outside_band += 1;
            }
        }
    }

    /// Adds `other`'s counts.
    pub fn merge(&mut self, other: DecisionCounts) {
        self.total += other.total;
        self.differ += other.differ;
        self.missing += other.missing;
        self.differ_outside_band += other.differ_outside_band;
    }
}

/// Per-batch and per-tree disagreement counts of one comparison.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Disagreements {
    /// Batch decisions.
    pub batches: DecisionCounts,
    /// Per-tree decisions (each tree's own sphere, as [`crate::select::select_per_tree`]
    /// without the draw-distance discard).
    pub trees: DecisionCounts,
}

impl Disagreements {
    /// Adds `other`'s counts.
    pub fn merge(&mut self, other: Disagreements) {
        self.batches.merge(other.batches);
        self.trees.merge(other.trees);
    }
}

/// One case of a camera sweep: a camera (its `eye` field unused), where it stands in `f64` world
/// coordinates, and the parameters it is selected with.
#[derive(Clone, Copy, Debug)]
pub struct SweepCase {
    /// Direction, lens and viewport.
    pub camera: Camera,
    /// Eye, `f64` world.
    pub eye_world: [f64; 3],
    /// Parameters (transition, fade width and draw distance vary per case).
    pub params: Params,
}

/// `n` seeded cameras around a forest centred at `center_world` (`f64` world) of half-side
/// `half_side` metres: eyes up to `half_side + 1000` m from the centre horizontally and 2..500 m
/// up, looking roughly at the forest (yaw towards the centre ±60°, pitch towards it ±10°, within
/// -80°..5°), 60° field of view at `width` x `height`; transition 20..600 m, fade width 0..150 m,
/// draw distance 100..1500 m, so the thresholds cut through the forest. The same seed gives the
/// same cameras *relative to the centre* at every centre, so only the coordinate scale changes.
pub fn sweep(
    n: usize,
    seed: u64,
    center_world: [f64; 3],
    half_side: f64,
    base: &Params,
    width: u32,
    height: u32,
) -> Vec<SweepCase> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let radius: f64 = rng.random_range(0.0..half_side + 1000.0);
            let angle: f64 = rng.random_range(0.0..core::f64::consts::TAU);
            let height_m: f64 = rng.random_range(2.0..500.0);
            let offset = DVec3::new(radius * angle.cos(), radius * angle.sin(), height_m);
            let to_center = -offset;
            let horizontal = to_center.truncate().length().max(1.0);
            let yaw =
                to_center.y.atan2(to_center.x) + rng.random_range(-60.0f64..60.0).to_radians();
            let pitch = (to_center.z.atan2(horizontal)
                + rng.random_range(-10.0f64..10.0).to_radians())
            .clamp(-80f64.to_radians(), 5f64.to_radians());
            let forward = [
                (yaw.cos() * pitch.cos()) as f32,
                (yaw.sin() * pitch.cos()) as f32,
                pitch.sin() as f32,
            ];
            let mut camera = Camera::look_at([0.0; 3], forward, 60.0, width, height);
            camera.forward = forward;
            let params = Params {
                lod1_transition: rng.random_range(20.0f32..600.0),
                fade_width: rng.random_range(0.0f32..150.0),
                draw_distance: rng.random_range(100.0f32..1500.0),
                ..*base
            };
            SweepCase {
                camera,
                eye_world: (DVec3::from(center_world) + offset).to_array(),
                params,
            }
        })
        .collect()
}

/// World positions (`f64`) of `template`'s trees placed so that the template's origin lands at
/// `center_world`, plus a deterministic sub-millimetre jitter per tree (surveyed positions carry
/// more digits than any `f32`).
pub fn place(template: &Scene, center_world: [f64; 3]) -> Vec<[f64; 3]> {
    template
        .instances
        .iter()
        .enumerate()
        .map(|(i, t)| {
            core::array::from_fn(|k| {
                let h = (i as u64 * 3 + k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
                let jitter = (h as f64 / (1u64 << 53) as f64 - 0.5) * 1.0e-3;
                center_world[k] + t.position[k] as f64 + jitter
            })
        })
        .collect()
}

/// The origin the loaders would choose (SPEC §3): the centre of the trees' bounding box rounded to
/// whole metres ([`crate::scene::load`]).
pub fn default_origin(world: &[[f64; 3]]) -> [f64; 3] {
    crate::scene::load::default_origin(world.iter().copied())
}

/// `template` (yaws, scales, meshes) standing at `world` (`f64`, one per instance), positions
/// `f32` relative to `origin`, each rounded once from the `f64` difference.
pub fn instances_at(template: &[Instance], world: &[[f64; 3]], origin: [f64; 3]) -> Vec<Instance> {
    template
        .iter()
        .zip(world)
        .map(|(t, w)| Instance {
            position: core::array::from_fn(|k| (w[k] - origin[k]) as f32),
            ..*t
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f64_decision_matches_f32_far_from_thresholds() {
        let camera = Camera::look_at([0.0, 0.0, 10.0], [100.0, 0.0, 10.0], 60.0, 64, 64);
        let p = Params::default();
        let view = ViewF64::new([0.0, 0.0, 10.0], &camera, &p);
        let u = SelectUniform::new(&camera, &p);
        for (c, r) in [
            ([100.0f32, 0.0, 10.0], 5.0f32),
            ([900.0, 0.0, 10.0], 5.0),
            ([2000.0, 0.0, 10.0], 5.0),
            ([5000.0, 0.0, 10.0], 5.0),
            ([-100.0, 0.0, 10.0], 5.0),
        ] {
            let s = SphereF64 {
                center: c.map(f64::from),
                radius: r as f64,
            };
            assert_eq!(view.decide(&s), u.decide(c, r), "{c:?}");
        }
    }

    #[test]
    fn batch_sphere_of_one_tree_is_that_tree() {
        let s = SphereF64 {
            center: [5.0e5, 5.3e6, 12.0],
            radius: 7.5,
        };
        assert_eq!(batch_sphere_f64(&[s]), s);
    }
}
