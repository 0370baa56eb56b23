//! The two pipelines the thesis measures against (E§5; SPEC §9), on the reference rasterizer, so
//! that cost and accuracy are measured by the same machinery as ours.
//!
//! ## Vegetation (E§5: "renders the entire geometry for every tree")
//! Every tree at full mesh (the geometry of our LOD0), with **per-tree** frustum culling and the
//! per-tree draw-distance test: the oracle [`crate::select::select_per_tree`] decides each tree
//! alone. The visible trees are compacted mesh by mesh into an instance list and drawn with the
//! very draw stage of our pipeline ([`crate::draw::draw_frame`]): one instanced command per mesh
//! that has visible trees, LOD0, no fade. So its pixels differ from ours exactly where our LOD
//! choices differ.
//!
//! ## Primitive (E§5: "billboard quads for each tree, simulating the geometry by doing ray casting
//! on simple geometry in the fragment shader ... a sphere on top of a cylinder")
//! Per visible tree (the same per-tree culling), one camera-facing quad whose fragment stage
//! ray-casts a proxy and **writes the hit's depth** ([`crate::raster::FragmentOutput::depth`], the
//! `gl_FragDepth` the thesis blames for Primitive's cost: it defeats early-Z on a GPU). The proxy,
//! from the mesh's bounding box, scaled by the tree's scale (yaw is irrelevant: it is symmetric
//! about the trunk axis `x = y = 0`):
//! - crown sphere of radius `R` = the box's half-width (`max(extent x, extent y) / 2`), centred on
//!   the trunk axis so that it touches the box top: `z_c = max(z_max - R, z_min + R)`;
//! - trunk cylinder of radius [`TRUNK_RADIUS_FRACTION`]`· R` from the box bottom up to the sphere
//!   centre. Its caps are not traced: the bottom rests on the ground, the top is inside the crown.
//!
//! Colour is flat: the species' average colour as seen from the side, the mean linear RGB of the
//! texels that pass the alpha test in the mesh's level-0 billboard bake at elevation 0 (layer
//! `mesh · K`, [`crate::bake`]): the crown dominates it, the trunk adds its visible share. The mean
//! over the raw texture would instead weigh the bark region of the atlas as much as its area, and
//! comes out brown. One colour for sphere and trunk alike. The quad lies in the plane perpendicular
//! to the view direction at the proxy's nearest view depth (its bounding sphere's), sized to cover
//! the proxy's projection (bound in [`primitive_quad`]), so every ray-cast depth is at or behind
//! the quad's: the conservative-depth contract the rasterizer's early test needs. A proxy within
//! [`NEAR_FALLBACK_FACTOR`] near-plane distances of the eye gets a full-screen quad at the near
//! plane instead.
//!
//! ## GPU twins
//! `gpu/src/cull.rs` (per-tree culling and Vegetation's compaction, [`vegetation_commands`]) and
//! `gpu/src/primitive.rs` (the Primitive's quads and ray cast, one [`ProxyRecord`] per mesh),
//! judged by `tests/tests/parity/baselines.rs`.
//!
//! ## Counters
//! Both report the trees tested (every tree: the per-tree culling work), trees drawn, commands,
//! the rasterizer's [`DrawStats`], and the bytes the method adds to the scene data
//! ([`BaselineFrame::memory_bytes`]).

use std::time::Instant;

use forestlod_shared::{
    COMMAND_SHIFT, Camera, CommandData, DrawCommand, LOD_MESH, MeshMeta, Params, ProxyRecord,
    SelectCounters,
};
use glam::{Vec3, Vec4};

use crate::draw::{DrawResources, LOD_ID_MESH, draw_frame, sky_and_ground};
use crate::pipeline::{FrameTimings, Prepared};
use crate::raster::{
    DrawState, DrawStats, Fragment, FragmentOutput, RenderTarget, Triangle, Vertex,
};
use crate::scene::{Scene, tree_sphere};
use crate::select::{Decision, Selection, select_per_tree, tree_within_draw_distance};
use crate::texture::srgb_to_linear;

/// Trunk radius of the Primitive proxy as a fraction of the crown radius: a 20 m spruce with a
/// 3 m crown radius gets a 0.3 m trunk, about what the procedural bark cards show.
pub const TRUNK_RADIUS_FRACTION: f32 = 0.1;

/// A proxy whose bounding sphere comes nearer the eye than this many near-plane distances gets a
/// full-screen quad (the projected-size bound divides by the nearest depth, which would blow up).
pub const NEAR_FALLBACK_FACTOR: f32 = 2.0;

/// Depth of the near fallback's full-screen quad, in near-plane distances.
pub const NEAR_FALLBACK_DEPTH: f32 = 1.001;

/// Margin of the near fallback's full-screen quad over the view's half-extent.
pub const NEAR_FALLBACK_MARGIN: f32 = 1.1;

/// Factor [`Proxy::bounding_radius`] widens the proxy's box circumradius by, so the bounding
/// sphere holds the proxy whatever the `f32` rounding.
pub const PROXY_BOUND_SCALE: f32 = 1.0 + 1e-5;

/// Bytes per visible tree in a baseline's compacted instance list (one `u32` tree index).
pub const INSTANCE_INDEX_BYTES: u64 = 4;
/// Bytes of one Primitive proxy record per mesh: crown radius, crown centre height, trunk radius,
/// bottom height and linear RGB plus padding (8 `f32`).
pub const PROXY_BYTES: u64 = 32;
const _: () = assert!(core::mem::size_of::<ProxyRecord>() as u64 == PROXY_BYTES);

/// Which baseline (E§5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    /// Full meshes for every visible tree.
    Vegetation,
    /// One ray-cast sphere-on-cylinder quad per visible tree.
    Primitive,
}

impl Baseline {
    /// Both, in the thesis's order.
    pub const ALL: [Baseline; 2] = [Baseline::Vegetation, Baseline::Primitive];
    /// Name used on the command line and in CSVs.
    pub fn name(self) -> &'static str {
        match self {
            Baseline::Vegetation => "vegetation",
            Baseline::Primitive => "primitive",
        }
    }
}

/// One frame of a baseline.
pub struct BaselineFrame {
    /// Colour, depth and id buffers (ids: [`LOD_ID_MESH`] for trees,
    /// [`LOD_ID_TERRAIN`](crate::draw::LOD_ID_TERRAIN), background).
    pub target: RenderTarget,
    /// Ground draw counters.
    pub terrain_stats: DrawStats,
    /// Tree draw counters.
    pub tree_stats: DrawStats,
    /// Trees culled one by one (every tree of the scene).
    pub trees_tested: u64,
    /// Visible trees, ascending tree indices.
    pub visible: Vec<u32>,
    /// Draw commands issued for trees.
    pub commands: u64,
    /// Culling (as `select`) and drawing (as `draw`) wall times.
    pub timings: FrameTimings,
    /// Bytes the method adds to the scene data: the compacted instance list plus its commands
    /// (Vegetation) or proxy records (Primitive).
    pub memory_bytes: u64,
    /// What occlusion culling did (issue 31): Vegetation with `params.occlusion` not `off`, the
    /// modern per-tree peer (niagara's and Bevy's per-object cull against a depth pyramid).
    pub occlusion: Option<crate::pipeline::OcclusionFrame>,
}

/// Bounding spheres of every tree ([`tree_sphere`]), the input of per-tree culling.
pub fn tree_spheres(scene: &Scene, meshes: &[MeshMeta]) -> Vec<([f32; 3], f32)> {
    scene
        .instances
        .iter()
        .map(|t| tree_sphere(t, &meshes[t.mesh as usize]))
        .collect()
}

/// Per-tree culling (the oracle of [`select_per_tree`]): the trees drawn, ascending.
pub fn visible_trees(spheres: &[([f32; 3], f32)], camera: &Camera, params: &Params) -> Vec<u32> {
    select_per_tree(spheres, camera, params)
        .iter()
        .enumerate()
        .filter(|(_, d)| matches!(d, Decision::Draw(_)))
        .map(|(i, _)| i as u32)
        .collect()
}

/// The trees our grouped pipeline draws in a frame: every tree of every command's instance range
/// in `indirection` (the batches', or the `refine` stage's: [`crate::pipeline::Frame::indirection`])
/// that passes the draw stage's per-tree draw-distance discard, ascending and without repeats.
pub fn trees_drawn_by_selection(
    prepared: &Prepared,
    selection: &Selection,
    indirection: &[u32],
    camera: &Camera,
    params: &Params,
) -> Vec<u32> {
    trees_drawn_with_far(
        prepared,
        prepared.far.as_ref(),
        selection,
        indirection,
        camera,
        params,
    )
}

/// [`trees_drawn_by_selection`] with the frame's far level `far` (a hierarchical impostor
/// frame's is its cache's, issue 33 item 2; else the prepared one).
pub fn trees_drawn_with_far(
    prepared: &Prepared,
    far: Option<&forestlod_shared::FarLevel>,
    selection: &Selection,
    indirection: &[u32],
    camera: &Camera,
    params: &Params,
) -> Vec<u32> {
    let u = crate::select::SelectUniform::new(camera, params);
    // A far command stands for its nodes' trees (issue 32).
    let selection =
        crate::hier_select::tree_view(selection, prepared.hierarchy.as_ref(), far, params);
    let mut out: Vec<u32> = selection
        .commands
        .iter()
        .flat_map(|c| {
            indirection[c.first_instance as usize..(c.first_instance + c.instance_count) as usize]
                .iter()
                .copied()
        })
        .filter(|&t| {
            let tree = &prepared.scene.instances[t as usize];
            let (center, _) = tree_sphere(tree, &prepared.geometry.meshes[tree.mesh as usize]);
            tree_within_draw_distance(&u, center)
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Vegetation's compaction (module docs): the visible trees (ascending) grouped mesh by mesh into
/// an instance list (`meshes` with their packed index ranges, [`crate::geometry::pack_geometry`]), and one instanced LOD0 command per mesh with visible trees, in mesh order
/// (`base_vertex = i << COMMAND_SHIFT`, `first_instance` the mesh's offset in the list, no fade).
/// Returns the commands, with the counters the GPU twin (`gpu/src/cull.rs`) also writes: trees
/// tested in `batches_tested`, `commands` = `lod0_commands`, visible trees in `instances` (the
/// culled counts stay 0), and the list.
pub fn vegetation_commands(
    scene: &Scene,
    meshes: &[MeshMeta],
    visible: &[u32],
    camera: &Camera,
    params: &Params,
) -> (Selection, Vec<u32>) {
    // Compact mesh by mesh: one instanced command per mesh with visible trees.
    let mut by_mesh: Vec<Vec<u32>> = vec![Vec::new(); scene.meshes.len()];
    for &tree in visible {
        by_mesh[scene.instances[tree as usize].mesh as usize].push(tree);
    }
    let mut indirection = Vec::with_capacity(visible.len());
    let mut selection = Selection::default();
    let u = crate::select::SelectUniform::new(camera, params);
    for (mesh, trees) in by_mesh.iter().enumerate() {
        if trees.is_empty() {
            continue;
        }
        let range = &meshes[mesh];
        selection.commands.push(DrawCommand {
            index_count: range.index_count,
            instance_count: trees.len() as u32,
            first_index: range.first_index,
            base_vertex: (selection.commands.len() as i32) << COMMAND_SHIFT,
            first_instance: indirection.len() as u32,
        });
        selection.data.push(CommandData {
            fade_start: u.fade_start,
            fade_end: u.fade_end,
            batch: 0,
            mesh: mesh as u32,
            lod: LOD_MESH,
            billboard: 0,
            fading: 0,
            first_tree: 0,
            group_len: 0,
            _pad0: 0,
        });
        indirection.extend_from_slice(trees);
    }
    let n = selection.commands.len() as u32;
    selection.counters = SelectCounters {
        batches_tested: scene.instances.len() as u32,
        commands: n,
        lod0_commands: n,
        instances: visible.len() as u32,
        ..SelectCounters::default()
    };
    (selection, indirection)
}

/// Renders one frame of *Vegetation* (module docs) with our draw stage.
pub fn render_vegetation(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    camera: &Camera,
    params: &Params,
) -> BaselineFrame {
    render_vegetation_with_history(prepared, spheres, camera, params, &[])
}

/// [`render_vegetation`] as one frame of a camera path: under occlusion culling `two-phase`,
/// `history` is the previous frame's `OcclusionFrame::visible` (empty for none).
pub fn render_vegetation_with_history(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    camera: &Camera,
    params: &Params,
    history: &[u32],
) -> BaselineFrame {
    let t = Instant::now();
    let visible = visible_trees(spheres, camera, params);
    let (selection, indirection) = vegetation_commands(
        &prepared.scene,
        &prepared.geometry.meshes,
        &visible,
        camera,
        params,
    );
    let select_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (drawn, occlusion, occlusion_seconds) =
        if params.occlusion == forestlod_shared::Occlusion::Off as u32 {
            let res = DrawResources {
                scene: &prepared.scene,
                geometry: &prepared.geometry,
                indirection: &indirection,
                mesh_textures: &prepared.mesh_textures,
                billboards: &prepared.billboards,
                far: None,
                points: prepared.points.as_ref(),
                lod_rule: crate::sampler::LodRule::Exact,
            };
            (draw_frame(&res, &selection, camera, params), None, 0.0)
        } else {
            // The same stage as ours (issue 31) over Vegetation's commands: every tree a mesh,
            // none fading, so the occluders are the trees within `occluder_depth`.
            let (drawn, occ, seconds) =
                prepared.draw_occluded(&selection, &indirection, camera, params, history);
            (drawn, Some(occ), seconds)
        };
    let draw_seconds = t.elapsed().as_secs_f64() - occlusion_seconds;
    let commands = selection.commands.len() as u64;
    BaselineFrame {
        target: drawn.target,
        terrain_stats: drawn.terrain_stats,
        tree_stats: drawn.tree_stats,
        trees_tested: spheres.len() as u64,
        memory_bytes: visible.len() as u64 * INSTANCE_INDEX_BYTES
            + commands
                * (core::mem::size_of::<DrawCommand>() + core::mem::size_of::<CommandData>())
                    as u64,
        visible,
        commands,
        timings: FrameTimings {
            select: select_seconds,
            refine: 0.0,
            draw: draw_seconds,
            occlusion: occlusion_seconds,
            impostors: 0.0,
        },
        occlusion,
    }
}

/// The *Primitive* proxy of one mesh, in mesh-local coordinates (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proxy {
    /// Crown sphere radius.
    pub crown_radius: f32,
    /// Height of the crown sphere's centre above the base.
    pub crown_z: f32,
    /// Trunk cylinder radius.
    pub trunk_radius: f32,
    /// Height of the trunk's bottom (the box bottom).
    pub bottom_z: f32,
    /// Flat colour, linear RGB: the mean of the side view's texels that pass the alpha test.
    pub color: [f32; 3],
}

impl Proxy {
    /// The proxy of a mesh from its bounding box and its side view (the level-0 bake at elevation
    /// 0; module docs).
    pub fn of_mesh(
        meta: &MeshMeta,
        side_view: &crate::texture::Rgba8Image,
        alpha_cutoff: f32,
    ) -> Self {
        let ex = meta.bbox_max[0] - meta.bbox_min[0];
        let ey = meta.bbox_max[1] - meta.bbox_min[1];
        let r = 0.5 * ex.max(ey);
        let crown_z = (meta.bbox_max[2] - r).max(meta.bbox_min[2] + r);
        let mut sum = [0.0f64; 3];
        let mut n = 0u64;
        for t in &side_view.texels {
            if t[3] as f32 / 255.0 >= alpha_cutoff {
                for c in 0..3 {
                    sum[c] += srgb_to_linear(t[c]) as f64;
                }
                n += 1;
            }
        }
        let color = if n == 0 {
            [0.0; 3]
        } else {
            sum.map(|s| (s / n as f64) as f32)
        };
        Self {
            crown_radius: r,
            crown_z,
            trunk_radius: TRUNK_RADIUS_FRACTION * r,
            bottom_z: meta.bbox_min[2],
            color,
        }
    }

    /// Radius of a sphere centred on the trunk axis at [`Proxy::center_z`] that holds the proxy
    /// (the circumsphere of its bounding box).
    pub fn bounding_radius(&self) -> f32 {
        let half_h = 0.5 * (self.crown_z + self.crown_radius - self.bottom_z);
        (2.0 * self.crown_radius * self.crown_radius + half_h * half_h).sqrt() * PROXY_BOUND_SCALE
    }

    /// Height of the proxy's bounding-box centre.
    pub fn center_z(&self) -> f32 {
        0.5 * (self.crown_z + self.crown_radius + self.bottom_z)
    }

    /// Nearest ray parameter `t >= t_min` where `origin + t·dir` meets the proxy of a tree standing
    /// at `base` with `scale`, or `None`. `origin` and `dir` need not be normalized.
    ///
    /// `disc_shift` moves each root test `disc >= 0` (sphere and cylinder) to
    /// `disc >= disc_shift · ε · m`, `m` the larger magnitude of the two products the discriminant
    /// subtracts (`b·b` and `a·(|o|² - r²)`) and `ε` = `f32::EPSILON`: positive shifts shrink the
    /// proxy's silhouettes, negative ones widen them, by `disc_shift` roundings of the
    /// discriminant; `0.0` is the exact test, what the baseline renders with. The GPU parity tests render
    /// alternative frames with it: far from the eye the discriminant cancels catastrophically
    /// (a trunk 0.34 m wide 700 m away has `r² ≈ 2` units in the last place of `b·b`), so a
    /// rounding difference (a fused multiply-add on the GPU) decides its hits there.
    pub fn intersect(
        &self,
        base: Vec3,
        scale: f32,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        disc_shift: f32,
    ) -> Option<f32> {
        let threshold = |p: f32, q: f32| {
            if disc_shift == 0.0 {
                0.0
            } else {
                disc_shift * f32::EPSILON * p.abs().max(q.abs())
            }
        };
        let mut best: Option<f32> = None;
        let mut take = |t: f32| {
            if t >= t_min && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        };
        // Sphere.
        let c = base + Vec3::new(0.0, 0.0, self.crown_z * scale);
        let r = self.crown_radius * scale;
        let oc = origin - c;
        let a = dir.dot(dir);
        let b = oc.dot(dir);
        let (p, q) = (b * b, a * (oc.dot(oc) - r * r));
        let disc = p - q;
        if disc >= threshold(p, q) {
            let s = disc.sqrt();
            take((-b - s) / a);
            take((-b + s) / a);
        }
        // Vertical cylinder from the bottom to the crown centre, no caps.
        let rt = self.trunk_radius * scale;
        let (z0, z1) = (base.z + self.bottom_z * scale, c.z);
        let (ox, oy) = (origin.x - base.x, origin.y - base.y);
        let a2 = dir.x * dir.x + dir.y * dir.y;
        if a2 > 0.0 {
            let b2 = ox * dir.x + oy * dir.y;
            let (p, q) = (b2 * b2, a2 * (ox * ox + oy * oy - rt * rt));
            let disc = p - q;
            if disc >= threshold(p, q) {
                let s = disc.sqrt();
                for t in [(-b2 - s) / a2, (-b2 + s) / a2] {
                    let z = origin.z + t * dir.z;
                    if z >= z0 && z <= z1 {
                        take(t);
                    }
                }
            }
        }
        best
    }
}

impl From<&Proxy> for ProxyRecord {
    /// The proxy as the GPU twin reads it (`gpu/src/shaders/primitive.wgsl`).
    fn from(p: &Proxy) -> Self {
        Self {
            crown_radius: p.crown_radius,
            crown_z: p.crown_z,
            trunk_radius: p.trunk_radius,
            bottom_z: p.bottom_z,
            color: p.color,
            _pad0: 0,
        }
    }
}

/// Proxies of every mesh of a prepared scene.
pub fn proxies(prepared: &Prepared, alpha_cutoff: f32) -> Vec<Proxy> {
    // The level view from `+X` of mesh `m`: layer `m·K·J` (`forestlod_shared::view_layer`).
    let views = prepared.billboards.views();
    prepared
        .geometry
        .meshes
        .iter()
        .enumerate()
        .map(|(m, meta)| {
            // The level view from +X: layer (m, 0, 0), or under octahedral frames (issue 32) the
            // frame nearest to +X (its opaque texels' mean is the proxy's colour).
            let k = if views.octahedral() {
                let hemi = forestlod_shared::octahedral::is_hemi(views.sphere);
                let fr = forestlod_shared::octahedral_frames(
                    forestlod_shared::octahedral_view([1.0, 0.0, 0.0], views.grid, hemi),
                    views.grid,
                );
                fr.frames[fr.nearest]
            } else {
                0
            };
            let layer = views.layer(m as u32, k, 0);
            Proxy::of_mesh(
                meta,
                &prepared.billboards.layers[layer as usize],
                alpha_cutoff,
            )
        })
        .collect()
}

/// Varyings of the Primitive quads: world position on the quad (3) and the tree index.
const PRIMITIVE_VARYINGS: usize = 4;

/// World-space corners of the camera-facing quad of a proxy with bounding sphere `(center,
/// radius)` (module docs): in the plane perpendicular to the view direction at depth
/// `d_q = d_c - radius`, centred on the centre's projection, half-side `radius·(1 + |lat|/d_c)`
/// with `lat` the centre's offset from the view axis. Every point `p` of the sphere projects (from
/// the eye, onto that plane) within that distance of the centre's projection: with `d_p >= d_q`
/// the projected offset is `d_q·|lat_c(1/d_p - 1/d_c) + lat_u·radius/d_p| <= radius(|lat|/d_c + 1)`.
/// Near the eye ([`NEAR_FALLBACK_FACTOR`]) the quad covers the whole view at `1.001·near`.
pub fn primitive_quad(camera: &Camera, center: Vec3, radius: f32) -> [Vec3; 4] {
    let b = camera.basis();
    let eye = Vec3::from(camera.eye);
    let rel = center - eye;
    let d_c = rel.dot(b.forward);
    let (mid, half_x, half_y) = if d_c - radius < NEAR_FALLBACK_FACTOR * camera.near {
        let d_q = camera.near * NEAR_FALLBACK_DEPTH;
        let ty = (camera.fov_y * 0.5).tan() * d_q * NEAR_FALLBACK_MARGIN;
        (eye + b.forward * d_q, ty * camera.aspect(), ty)
    } else {
        let d_q = d_c - radius;
        let lat = (rel - b.forward * d_c).length();
        let half = radius * (1.0 + lat / d_c);
        (eye + rel * (d_q / d_c), half, half)
    };
    [
        mid - b.right * half_x - b.up * half_y,
        mid + b.right * half_x - b.up * half_y,
        mid + b.right * half_x + b.up * half_y,
        mid - b.right * half_x + b.up * half_y,
    ]
}

/// Renders one frame of *Primitive* (module docs).
pub fn render_primitive(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    proxies: &[Proxy],
    camera: &Camera,
    params: &Params,
) -> BaselineFrame {
    render_primitive_shifted(prepared, spheres, proxies, camera, params, 0.0)
}

/// [`render_primitive`] with every ray cast's root tests moved by `disc_shift` roundings
/// ([`Proxy::intersect`]); `0.0` is exactly [`render_primitive`]. For the GPU parity
/// tests' alternative frames.
pub fn render_primitive_shifted(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    proxies: &[Proxy],
    camera: &Camera,
    params: &Params,
    disc_shift: f32,
) -> BaselineFrame {
    let t = Instant::now();
    let visible = visible_trees(spheres, camera, params);
    let select_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (mut target, terrain_stats) = sky_and_ground(&prepared.scene, camera);
    let view_proj = camera.view_projection();

    // The vertex stage: one quad (two triangles) per visible tree.
    let quads: Vec<Triangle<PRIMITIVE_VARYINGS>> = visible
        .iter()
        .flat_map(|&tree| {
            let inst = &prepared.scene.instances[tree as usize];
            let proxy = &proxies[inst.mesh as usize];
            let base = Vec3::from(inst.position);
            let center = base + Vec3::new(0.0, 0.0, proxy.center_z() * inst.scale);
            let corners = primitive_quad(camera, center, proxy.bounding_radius() * inst.scale);
            let v = corners.map(|p| {
                let clip = view_proj * Vec4::new(p.x, p.y, p.z, 1.0);
                Vertex::new(clip.to_array(), [p.x, p.y, p.z, tree as f32])
            });
            [[v[0], v[1], v[2]], [v[0], v[2], v[3]]]
        })
        .collect();
    let eye = Vec3::from(camera.eye);
    let forward = camera.basis().forward;
    let (near, far) = (camera.near, camera.far);
    let shader = |f: &Fragment<PRIMITIVE_VARYINGS>| {
        let [x, y, z, tree] = f.varyings;
        let inst = &prepared.scene.instances[tree.round() as usize];
        let proxy = &proxies[inst.mesh as usize];
        let dir = Vec3::new(x, y, z) - eye;
        let along = dir.dot(forward);
        if along <= 0.0 {
            return None;
        }
        // Scale the ray so that t is the view depth, then clip to the near plane.
        let dir = dir / along;
        let t = proxy.intersect(
            Vec3::from(inst.position),
            inst.scale,
            eye,
            dir,
            near,
            disc_shift,
        )?;
        if t > far {
            return None;
        }
        // wgpu depth of view depth t: far (t - near) / ((far - near) t).
        let depth = far * (t - near) / ((far - near) * t);
        Some(FragmentOutput {
            color: [proxy.color[0], proxy.color[1], proxy.color[2], 1.0],
            id: LOD_ID_MESH,
            depth: Some(depth),
        })
    };
    let tree_stats = target.draw(&quads, &shader, &DrawState::OPAQUE);
    let draw_seconds = t.elapsed().as_secs_f64();
    BaselineFrame {
        target,
        terrain_stats,
        tree_stats,
        trees_tested: spheres.len() as u64,
        memory_bytes: visible.len() as u64 * INSTANCE_INDEX_BYTES
            + proxies.len() as u64 * PROXY_BYTES,
        commands: (!visible.is_empty()) as u64,
        visible,
        timings: FrameTimings {
            select: select_seconds,
            refine: 0.0,
            draw: draw_seconds,
            occlusion: 0.0,
            impostors: 0.0,
        },
        occlusion: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_proxy_ray_cast_hits_crown_and_trunk_and_misses_beside() {
        let proxy = Proxy {
            crown_radius: 3.0,
            crown_z: 15.0,
            trunk_radius: 0.3,
            bottom_z: 0.0,
            color: [0.1, 0.3, 0.1],
        };
        let base = Vec3::new(10.0, 0.0, 2.0);
        let o = Vec3::new(0.0, 0.0, 2.0);
        // Through the crown centre: the sphere's near side at x = 7 (t = 7 with a unit x ray).
        let t = proxy.intersect(base, 1.0, o + Vec3::Z * 15.0, Vec3::X, 0.1, 0.0);
        assert!((t.unwrap() - 7.0).abs() < 1e-4);
        // Through the trunk at 5 m: the cylinder's near side at x = 9.7.
        let t = proxy.intersect(base, 1.0, o + Vec3::Z * 5.0, Vec3::X, 0.1, 0.0);
        assert!((t.unwrap() - 9.7).abs() < 1e-4);
        // Beside the trunk, below the crown: a miss.
        let t = proxy.intersect(base, 1.0, o + Vec3::new(0.0, 1.0, 5.0), Vec3::X, 0.1, 0.0);
        assert_eq!(t, None);
        // Scaled by 2: the crown centre is at 30 m, radius 6.
        let t = proxy.intersect(base, 2.0, o + Vec3::Z * 30.0, Vec3::X, 0.1, 0.0);
        assert!((t.unwrap() - 4.0).abs() < 1e-4);
    }

    /// How far (metres, at the meshes' unit scale) the proxy's measures may sit from the mesh's
    /// own extents: both are `f32` sums and halvings of the same vertex coordinates (tens of
    /// metres at most), a few ulps; a wrong proxy is off by a good fraction of a crown.
    const PROXY_EXTENT_EPS: f32 = 1e-4;

    /// The Primitive's proxy against its definition (module docs) and the meshes it stands for:
    /// the crown sphere's radius is half the mesh's larger horizontal extent (so the sphere is as
    /// wide as the crown, no wider), it touches the box top (or, on a squat box, the bottom), the
    /// trunk is [`TRUNK_RADIUS_FRACTION`] of the crown and starts at the box bottom. Checked on a
    /// hand-made box with unequal widths and on every species mesh, whose extents are recomputed
    /// from its vertices. Both backends read the same proxies, so parity cannot see a wrong one:
    /// added for issue 36's Rust mutant 878 (`let r = 0.5 * ex.max(ey)` -> `1.5 *`).
    #[test]
    fn the_proxy_is_the_crown_and_trunk_its_doc_derives_from_the_mesh_box() {
        let view = crate::texture::Rgba8Image::new(1, 1, [50, 120, 40, 255]);
        let boxed = |lo: [f32; 3], hi: [f32; 3]| MeshMeta {
            bbox_min: lo,
            bbox_max: hi,
            ..bytemuck::Zeroable::zeroed()
        };
        // Tall, 4 m by 6 m: R = 3, the sphere from 14 to 20 m.
        let tall = Proxy::of_mesh(&boxed([-2.0, -3.0, 0.5], [2.0, 3.0, 20.0]), &view, 0.5);
        assert_eq!(
            (tall.crown_radius, tall.crown_z, tall.bottom_z),
            (3.0, 17.0, 0.5),
            "{tall:?}"
        );
        assert_eq!(tall.trunk_radius, TRUNK_RADIUS_FRACTION * 3.0, "{tall:?}");
        // Squat, 10 m by 8 m and 6 m high: R = 5, the sphere rests on the box bottom.
        let squat = Proxy::of_mesh(&boxed([-5.0, -4.0, 0.0], [5.0, 4.0, 6.0]), &view, 0.5);
        assert_eq!((squat.crown_radius, squat.crown_z), (5.0, 5.0), "{squat:?}");
        let scene = crate::scene::builtin::pair();
        for mesh in &scene.meshes {
            let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
            for p in &mesh.positions {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            let width = (hi[0] - lo[0]).max(hi[1] - lo[1]);
            let proxy = Proxy::of_mesh(&mesh.meta(), &view, 0.5);
            let diameter = 2.0 * proxy.crown_radius;
            assert!(
                (diameter - width).abs() <= PROXY_EXTENT_EPS,
                "{}: crown diameter {diameter} m, the mesh's larger horizontal extent {width} m",
                mesh.name
            );
            let top = proxy.crown_z + proxy.crown_radius;
            let bottom = proxy.crown_z - proxy.crown_radius;
            assert!(
                (top - hi[2]).abs() <= PROXY_EXTENT_EPS
                    || (bottom - lo[2]).abs() <= PROXY_EXTENT_EPS,
                "{}: crown sphere {bottom}..{top} m touches neither the mesh's top {} nor its \
                 bottom {}",
                mesh.name,
                hi[2],
                lo[2]
            );
            assert!(
                bottom >= lo[2] - PROXY_EXTENT_EPS,
                "{}: crown sphere reaches {bottom} m, below the mesh's bottom {}",
                mesh.name,
                lo[2]
            );
            assert_eq!(proxy.bottom_z, lo[2], "{}", mesh.name);
            assert_eq!(
                proxy.trunk_radius,
                TRUNK_RADIUS_FRACTION * proxy.crown_radius,
                "{}",
                mesh.name
            );
        }
    }

    #[test]
    fn the_quad_covers_the_projection_of_its_sphere() {
        let camera = Camera::look_at([0.0, 0.0, 5.0], [100.0, 10.0, 0.0], 60.0, 64, 48);
        let b = camera.basis();
        let eye = Vec3::from(camera.eye);
        for center in [Vec3::new(40.0, 10.0, 3.0), Vec3::new(30.0, -20.0, 12.0)] {
            let radius = 6.0;
            let q = primitive_quad(&camera, center, radius);
            let mid = (q[0] + q[2]) * 0.5;
            let d_q = (mid - eye).dot(b.forward);
            let half = (q[1] - q[0]).length() * 0.5;
            // Sample the sphere's surface and project each point onto the quad's plane.
            for i in 0..64 {
                for j in 0..32 {
                    let (th, ph) = (i as f32 * 0.098, j as f32 * 0.098);
                    let p = center
                        + Vec3::new(ph.sin() * th.cos(), ph.sin() * th.sin(), ph.cos()) * radius;
                    let rel = p - eye;
                    let proj = eye + rel * (d_q / rel.dot(b.forward));
                    let off = proj - mid;
                    assert!(off.dot(b.right).abs() <= half * 1.0001);
                    assert!(off.dot(b.up).abs() <= half * 1.0001);
                }
            }
        }
    }
}
