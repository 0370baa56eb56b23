//! Shared helpers for the cross-crate tests in `tests/tests/`: small random scenes, cameras and
//! parameters as proptest strategies, built without the procedural generators so the properties
//! exercise the selection rules alone.

pub mod azimuth;
pub mod far_fixture;
pub mod scenarios;
pub mod stage_cases;

use forestlod_gpu::CullTree;
use forestlod_harness::bridge::cull_trees_of;
use forestlod_reference::baselines::tree_spheres;
use forestlod_reference::batches::{Batches, build_batches};
use forestlod_reference::geometry::{PackedGeometry, pack_geometry};
use forestlod_reference::scene::{Instance, Scene, Terrain, TreeMesh};
use forestlod_reference::select::{Selection, select};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{Camera, Params};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};

/// A crossed-card tree of `height` metres and crown half-width `half_width`: 4 triangles.
pub fn card_tree(name: &str, height: f32, half_width: f32) -> TreeMesh {
    let (h, w) = (height, half_width);
    TreeMesh {
        name: name.to_string(),
        positions: vec![
            [-w, 0.0, 0.0],
            [w, 0.0, 0.0],
            [w, 0.0, h],
            [-w, 0.0, h],
            [0.0, -w, 0.0],
            [0.0, w, 0.0],
            [0.0, w, h],
            [0.0, -w, h],
        ],
        uvs: vec![
            [0.0, 1.0],
            [1.0, 1.0],
            [1.0, 0.0],
            [0.0, 0.0],
            [0.0, 1.0],
            [1.0, 1.0],
            [1.0, 0.0],
            [0.0, 0.0],
        ],
        indices: vec![0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7],
        texture: Rgba8Image::new(4, 4, [40, 120, 40, 255]),
    }
}

/// `n` trees of the five built-in species, scales 0.6..1.6, spread by a fixed hash over a 600 m
/// square from the origin: the hierarchical impostors' test forest (issue 33 item 2;
/// `properties::impostor_properties`, `parity::impostors`).
pub fn species_forest(n: u32) -> Scene {
    let trees = (0..n)
        .map(|i| {
            let h =
                |k: u32| forestlod_shared::points::point_hash(i, k, 77, 2) as f32 / u32::MAX as f32;
            Instance {
                position: [600.0 * h(1), 600.0 * h(2), 0.0],
                yaw: std::f32::consts::TAU * h(3),
                scale: 0.6 + 1.0 * h(4),
                mesh: i % 5,
            }
        })
        .collect();
    Scene {
        meshes: forestlod_reference::scene::builtin::species_meshes(),
        ..scene_of(trees)
    }
}

/// A scene of the given trees over three card-tree species of different heights.
pub fn scene_of(instances: Vec<Instance>) -> Scene {
    let mut bounds = [
        f32::INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
    ];
    for t in &instances {
        bounds = [
            bounds[0].min(t.position[0]),
            bounds[1].min(t.position[1]),
            bounds[2].max(t.position[0]),
            bounds[3].max(t.position[1]),
        ];
    }
    Scene {
        name: "proptest".into(),
        origin: [0.0; 3],
        meshes: vec![
            card_tree("short", 8.0, 2.0),
            card_tree("mid", 18.0, 4.0),
            card_tree("tall", 32.0, 5.0),
        ],
        instances,
        terrain: Terrain::Flat { z: 0.0 },
        bounds,
    }
}

/// Random trees in a square of half-side `extent` around the origin.
pub fn instances(max_trees: usize) -> impl Strategy<Value = Vec<Instance>> {
    (10.0f32..3000.0).prop_flat_map(move |extent| {
        prop::collection::vec(
            (
                -extent..extent,
                -extent..extent,
                -20.0f32..60.0,
                0.0f32..6.3,
                0.3f32..2.5,
                0u32..3,
            )
                .prop_map(|(x, y, z, yaw, scale, mesh)| Instance {
                    position: [x, y, z],
                    yaw,
                    scale,
                    mesh,
                }),
            1..max_trees,
        )
    })
}

/// Random cameras over a 4 km region: anywhere from ground level to 1.5 km up, any yaw, pitch from
/// -89° to +30°, field of view 20°..100°, aspect 1:2 to 2:1.
pub fn cameras() -> impl Strategy<Value = Camera> {
    (
        -4000.0f32..4000.0,
        -4000.0f32..4000.0,
        -10.0f32..1500.0,
        0.0f32..360.0,
        -89.0f32..30.0,
        20.0f32..100.0,
        64u32..256,
        64u32..256,
    )
        .prop_map(|(x, y, z, yaw, pitch, fov, w, h)| {
            let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
            let forward = [
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            ];
            let mut c = Camera::look_at(
                [x, y, z],
                [x + forward[0], y + forward[1], z + forward[2]],
                fov,
                w,
                h,
            );
            c.forward = forward;
            c
        })
}

/// `parity::select`'s far-plane cases (and the coverage test's): random trees, cameras and
/// parameters with the far plane 50..3000 m past the near plane and the draw distance 100 km, so
/// the far plane culls before the draw distance does.
pub fn far_plane_cases() -> impl Strategy<Value = (Vec<Instance>, Camera, Params)> {
    (instances(300), cameras(), params(), 50.0f32..3000.0).prop_map(|(trees, camera, p, far)| {
        let camera = Camera {
            far: camera.near + far,
            ..camera
        };
        let p = Params {
            draw_distance: 100_000.0,
            ..p
        };
        (trees, camera, p)
    })
}

/// Random cameras around a scene's footprint `bounds` (`[x0, y0, x1, y1]`): the eye within half a
/// footprint of it, 0.5..400 m up, looking at a random point of it (-20..40 m high); field of view
/// 20°..100°, 64..256 pixels a side; only valid cameras.
pub fn cameras_around(bounds: [f32; 4]) -> impl Strategy<Value = Camera> {
    let [x0, y0, x1, y1] = bounds;
    let m = half_side(bounds);
    (
        (x0 - m)..(x1 + m),
        (y0 - m)..(y1 + m),
        0.5f32..400.0,
        x0..x1,
        y0..y1,
        -20.0f32..40.0,
        20.0f32..100.0,
        64u32..256,
        64u32..256,
    )
        .prop_map(|(ex, ey, ez, tx, ty, tz, fov, w, h)| {
            Camera::look_at([ex, ey, ez], [tx, ty, tz], fov, w, h)
        })
        .prop_filter("valid camera", |c| c.validate().is_ok())
}

/// Half the larger side of a footprint `bounds` (`[x0, y0, x1, y1]`).
pub fn half_side(bounds: [f32; 4]) -> f32 {
    let [x0, y0, x1, y1] = bounds;
    0.5 * (x1 - x0).max(y1 - y0)
}

/// Random per-frame parameters around a scene's footprint `bounds` of half-side `m`: the draw
/// distance 0..2m (often inside the footprint, so the distance cull and the per-tree discard both
/// bite) or 4 km, the transition in `lod1_transition`, the fade width in `fade_width`, one or two
/// LOD levels.
pub fn params_around(
    bounds: [f32; 4],
    lod1_transition: std::ops::Range<f32>,
    fade_width: std::ops::Range<f32>,
) -> impl Strategy<Value = Params> {
    let m = half_side(bounds);
    (
        prop_oneof![0.0f32..(2.0 * m), Just(4000.0f32)],
        lod1_transition,
        fade_width,
        1u32..=2,
    )
        .prop_map(|(d, t, w, l)| Params {
            draw_distance: d,
            lod1_transition: t,
            fade_width: w,
            lod_levels: l,
            ..Params::default()
        })
}

/// Runs `cases` random cases of `strategy` through `body`, panicking with proptest's (shrunk)
/// failure, prefixed by `what`.
pub fn run_cases<S: Strategy>(
    what: &str,
    cases: u32,
    strategy: S,
    mut body: impl FnMut(S::Value) -> Result<(), String>,
) where
    S::Value: std::fmt::Debug,
{
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    let body = std::cell::RefCell::new(&mut body);
    if let Err(e) = runner.run(&strategy, |value| {
        (body.borrow_mut())(value).map_err(TestCaseError::fail)
    }) {
        panic!("{what}: {e}");
    }
}

/// The near-threshold classification, shared with the harness's judges (`forestlod_harness::judge`).
pub use forestlod_harness::judge::{Thresholds, threshold_ambiguity};

/// Random valid parameters: grid 1 m..5 km, transition 0..2 km, fade 0..500 m, draw distance
/// 0..6 km, one or two LOD levels.
pub fn params() -> impl Strategy<Value = Params> {
    (
        1.0f32..5000.0,
        0.0f32..2000.0,
        0.0f32..500.0,
        0.0f32..6000.0,
        1u32..=2,
    )
        .prop_map(|(g, t, w, d, l)| Params {
            grid_size: g,
            lod1_transition: t,
            fade_width: w,
            draw_distance: d,
            lod_levels: l,
            ..Params::default()
        })
}

/// The random properties' configuration: 256 cases each.
pub fn property_config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        ..ProptestConfig::default()
    }
}

/// A tree of species 0 on the x axis at `x`, unrotated and unscaled.
pub fn tree_at_x(x: f32) -> Instance {
    Instance {
        position: [x, 0.0, 0.0],
        yaw: 0.0,
        scale: 1.0,
        mesh: 0,
    }
}

/// Random `trees` (`scene_of`) made ready for the stages: packed geometry, the trees' bounding
/// spheres and the batches at `grid_size`.
pub struct Packed {
    pub scene: Scene,
    pub geometry: PackedGeometry,
    pub spheres: Vec<([f32; 3], f32)>,
    pub batches: Batches,
}

impl Packed {
    /// Every tree's scale (`refine`'s per-tree band, issue 29).
    pub fn scales(&self) -> Vec<f32> {
        self.scene.instances.iter().map(|t| t.scale).collect()
    }

    pub fn new(trees: Vec<Instance>, grid_size: f32) -> Self {
        let scene = scene_of(trees);
        let geometry = pack_geometry(&scene);
        let spheres = tree_spheres(&scene, &geometry.meshes);
        let batches = build_batches(&scene, &geometry.meshes, grid_size).unwrap();
        Packed {
            scene,
            geometry,
            spheres,
            batches,
        }
    }
}

/// `scene` made ready for the per-tree GPU stages (`parity::baselines`' cull, `parity::refine`):
/// its packed geometry, the trees' bounding spheres and their [`CullTree`] records.
pub struct CullInput {
    pub geometry: PackedGeometry,
    pub spheres: Vec<([f32; 3], f32)>,
    pub trees: Vec<CullTree>,
}

impl CullInput {
    pub fn new(scene: &Scene) -> Self {
        let geometry = pack_geometry(scene);
        let spheres = tree_spheres(scene, &geometry.meshes);
        let trees = cull_trees_of(scene, &spheres);
        CullInput {
            geometry,
            spheres,
            trees,
        }
    }
}

/// A hand-checked frame of `trees` (`scene_of`) at the default parameters: its packed geometry and
/// batches, and a 64² camera (60°) at (0, 0, 5) looking along +x.
pub struct AxisFrame {
    pub geometry: PackedGeometry,
    pub params: Params,
    pub batches: Batches,
    pub camera: Camera,
}

impl AxisFrame {
    pub fn new(trees: Vec<Instance>) -> Self {
        let scene = scene_of(trees);
        let geometry = pack_geometry(&scene);
        let params = Params::default();
        let batches = build_batches(&scene, &geometry.meshes, params.grid_size).unwrap();
        let camera = Camera::look_at([0.0, 0.0, 5.0], [100.0, 0.0, 5.0], 60.0, 64, 64);
        AxisFrame {
            geometry,
            params,
            batches,
            camera,
        }
    }

    /// The reference's selection of this frame.
    pub fn select(&self) -> Selection {
        let g = &self.geometry;
        select(
            &self.batches.metas,
            &self.batches.scales,
            &g.meshes,
            &g.billboard,
            &self.camera,
            &self.params,
        )
    }
}

/// Runs `f` inside a rayon pool of `threads` threads.
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("rayon pool")
        .install(f)
}

/// Asserts that no check failed: else panics with `what` and the failures, one a line.
pub fn assert_no_failures(what: &str, failures: &[String]) {
    assert!(failures.is_empty(), "{what}:\n{}", failures.join("\n"));
}

/// The GPU twin of one reference frame `want` (drawn from `input`), judged two ways: the
/// diagnosis's stage checks (`forestlod_harness::diagnose::check_stages`, each printed), then
/// the draw alone (`StagesFromCpu::ALL`) and fed by the GPU's selection
/// (`StagesFromCpu::TEXTURES`), each image judged by the image classes against `want` with the
/// alpha test's alternatives. Failures are named by `name`; maxima go to `max`.
pub fn gpu_frame_failures(
    ctx: &'static forestlod_gpu::GpuContext,
    name: &str,
    input: forestlod_harness::stage::FrameInput<'_>,
    want: &forestlod_harness::image_compare::Images,
    max: &mut forestlod_harness::image_compare::MaxDiffs,
) -> Vec<String> {
    use forestlod_harness::stage::{Backend, Named};
    let (prepared, camera, params) = (input.prepared, input.camera, input.params);
    let alternatives =
        forestlod_harness::alternatives::alpha_test_alternatives(prepared, camera, params);
    let mut failures = Vec::new();
    for option in [
        forestlod_harness::gpu_frame::StagesFromCpu::ALL,
        forestlod_harness::gpu_frame::StagesFromCpu::TEXTURES,
    ] {
        let checks = forestlod_harness::diagnose::check_stages(
            ctx,
            prepared,
            camera,
            params,
            true,
            option.selection.is_some(),
        );
        for c in &checks {
            eprintln!("{name}: stage {}: {}", c.stage, c.summary);
        }
        if let Some(f) = forestlod_harness::diagnose::first_differing(&checks) {
            failures.push(format!("{name}: {f}"));
        }
        let backend = forestlod_harness::backend::GpuRenderer { ctx, option };
        let got = backend.run(input);
        let label = format!("{name}/{}", backend.name());
        failures.extend(forestlod_harness::image_compare::judge_image(
            &label,
            &got,
            want,
            &alternatives,
            camera,
            max,
        ));
    }
    failures
}

/// The differing pixels of a frame drawn with `command_order = node` against the same frame drawn
/// `front-to-back` (issue 13, E§7), each classified ([`classify_order_diffs`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OrderDiffs {
    /// Pixels whose colour, depth bits or LOD id differ.
    pub differing: usize,
    /// Differing pixels of equal depth: two fragments tie and `LESS` keeps whichever came first.
    pub ties: usize,
    /// Differing pixels where either frame shows a fading (transition) fragment in the `alpha`
    /// fade mode: blending is order-dependent there.
    pub blend_order: usize,
    /// Differing pixels neither class explains: a bug of the reorder.
    pub unclassified: usize,
}

/// Classifies every pixel where `a` and `b` differ (module of [`OrderDiffs`]): in the `alpha`
/// fade mode (`alpha`), a pixel whose LOD id is [`forestlod_shared::LOD_ID_TRANSITION`] in either
/// frame is *blend order*; otherwise a pixel whose depth bits are equal is a *tie*; the rest are
/// *unclassified*. A reorder draws the same fragments, and with depth `LESS` and no blending the
/// nearest fragment wins whatever the order, so the depth buffer never differs outside blending.
pub fn classify_order_diffs(
    a: &forestlod_harness::image_compare::Images,
    b: &forestlod_harness::image_compare::Images,
    alpha: bool,
) -> OrderDiffs {
    let mut out = OrderDiffs::default();
    for i in 0..a.color.len() {
        let same_depth = a.depth[i].to_bits() == b.depth[i].to_bits();
        if a.color[i] == b.color[i] && same_depth && a.lod_id[i] == b.lod_id[i] {
            continue;
        }
        out.differing += 1;
        let transition = a.lod_id[i] == forestlod_shared::LOD_ID_TRANSITION
            || b.lod_id[i] == forestlod_shared::LOD_ID_TRANSITION;
        if alpha && transition {
            out.blend_order += 1;
        } else if same_depth {
            out.ties += 1;
        } else {
            out.unclassified += 1;
        }
    }
    out
}

/// The frame tests' small poses: a 96x72 [`named_camera`](forestlod_reference::cameras::named_camera)
/// of `scene` for each `(name, yaw in degrees)` of `poses`, with the name and yaw for messages (the
/// hierarchy and command-order frame comparisons loop over these, then over fade modes).
pub fn small_poses(
    scene: &Scene,
    poses: &[(&'static str, f32)],
) -> Vec<(&'static str, f32, Camera)> {
    poses
        .iter()
        .map(|&(name, yaw)| {
            let camera = forestlod_reference::cameras::named_camera(name, scene, yaw, 96, 72)
                .unwrap_or_else(|e| panic!("camera {name} at yaw {yaw}: {e}"));
            (name, yaw, camera)
        })
        .collect()
}

/// The hierarchy frame tests' parameters on `tiny`: small cells (50 m grid, 8 trees per node,
/// octree culling depth 3) so that a cut emits many sibling nodes, a 120 m transition with a 40 m
/// fade so that both LODs and the fade band are on screen at the small poses ([`small_poses`]),
/// 32-texel billboards to keep the bake cheap; `hierarchy` as given.
pub fn tiny_hierarchy_params(hierarchy: forestlod_shared::Hierarchy) -> Params {
    Params {
        grid_size: 50.0,
        lod1_transition: 120.0,
        fade_width: 40.0,
        texture_size: 32,
        nodes_per_node: 8,
        max_cull_depth: 3,
        hierarchy: hierarchy as u32,
        ..Params::default()
    }
}

/// The whole cut of one frame (`hier_select`, then `coalesce` and `command_order` with the modes
/// of `params`, as the frame runs them: `forestlod_reference::frame::cut`), in the shape the
/// cut's tests read: the ordered commands, the raw cut's per-node codes and states, and the
/// ordered commands' keys.
pub fn full_cut(
    h: &forestlod_reference::hierarchy::Hierarchy,
    meshes: &[forestlod_shared::MeshMeta],
    billboard: &forestlod_shared::MeshMeta,
    camera: &Camera,
    params: &Params,
) -> FullCut {
    let (selection, trace) =
        forestlod_reference::frame::cut(h, meshes, billboard, None, camera, params);
    FullCut {
        selection,
        codes: trace.cut.codes,
        states: trace.cut.states,
        keys: trace.keys,
    }
}

/// [`full_cut`] on given per-node codes (a GPU's, read back) with the given modes.
pub fn full_resolve(
    h: &forestlod_reference::hierarchy::Hierarchy,
    codes: Vec<u32>,
    meshes: &[forestlod_shared::MeshMeta],
    billboard: &forestlod_shared::MeshMeta,
    u: &forestlod_shared::ViewUniform,
    coalesce: forestlod_shared::Coalesce,
    order: forestlod_shared::CommandOrder,
) -> FullCut {
    let raw =
        forestlod_reference::hier_select::resolve_and_compact(h, codes, meshes, billboard, None, u);
    let merged = forestlod_reference::coalesce::coalesce(&raw.selection, coalesce);
    let keys = forestlod_reference::command_order::run_keys(
        &h.nodes,
        &raw.selection,
        &merged,
        u,
        coalesce,
    );
    let (selection, keys) = forestlod_reference::command_order::order(merged, keys, order);
    FullCut {
        selection,
        codes: raw.codes,
        states: raw.states,
        keys,
    }
}

/// What [`full_cut`] returns.
#[derive(Clone, Debug, PartialEq)]
pub struct FullCut {
    /// The ordered commands.
    pub selection: Selection,
    /// Per node: `forestlod_shared::node_code`.
    pub codes: Vec<u32>,
    /// Per node: visited / emitted bits.
    pub states: Vec<u32>,
    /// Per output command: its front-to-back key.
    pub keys: Vec<u32>,
}

impl FullCut {
    /// Nodes the recursion would visit (C§5 "nodes walked").
    pub fn nodes_visited(&self) -> u32 {
        self.selection.counters.batches_tested
    }
}

/// Cameras aimed at the hard side of the octree's partial-visibility test (issue 36, class 5):
/// for interior nodes above `params.max_cull_depth` whose box and sphere centres are apart, a
/// camera `width x height` (50° vertical field of view) past the fade end of the node (so the
/// octree tests partial visibility instead of recursing for LOD0), turned so that one side plane
/// passes between the two centres: the "wholly inside" test on the box centre and the same test
/// on the sphere centre then decide differently, which random cameras almost never do. Returns
/// `(node, camera)` pairs, at most `want`, in node order; each camera sees its node drawn
/// (within the draw distance, inside the frustum). Deterministic: a scan of yaw offsets.
pub fn straddling_cameras(
    nodes: &[forestlod_shared::NodeMeta],
    params: &Params,
    width: u32,
    height: u32,
    want: usize,
) -> Vec<(usize, Camera)> {
    let mut out = Vec::new();
    for (i, n) in nodes.iter().enumerate() {
        if out.len() >= want {
            break;
        }
        let apart = (0..3)
            .map(|k| (n.center[k] - n.box_center[k]).powi(2))
            .sum::<f32>()
            .sqrt();
        if n.child_count == 0 || n.depth >= params.max_cull_depth || apart < 0.05 * n.radius {
            continue;
        }
        let far = params.lod1_transition + 2.0 * n.radius + 20.0;
        if far - n.radius > params.draw_distance {
            continue;
        }
        let c = n.box_center;
        'node: for heading in [0.3f32, 2.0, 3.6, 5.1] {
            let eye = [
                c[0] - far * heading.cos(),
                c[1] - far * heading.sin(),
                c[2] + 5.0,
            ];
            for step in 0..=800 {
                let a = -1.0 + step as f32 * (2.0 / 800.0);
                let (s, co) = a.sin_cos();
                let d = [c[0] - eye[0], c[1] - eye[1]];
                let target = [
                    eye[0] + co * d[0] - s * d[1],
                    eye[1] + s * d[0] + co * d[1],
                    c[2],
                ];
                let camera = Camera::look_at(eye, target, 50.0, width, height);
                let f = camera.frustum();
                let drawn = f.sphere_visible(n.center, n.radius, eye)
                    && f.aabb_visible(n.box_center, n.extent, eye);
                if drawn
                    && f.aabb_inside(n.box_center, n.extent, eye)
                        != f.aabb_inside(n.center, n.extent, eye)
                {
                    out.push((i, camera));
                    break 'node;
                }
            }
        }
    }
    out
}

/// The parameters [`straddling_cameras`]' cases use with `mode` (an octree mode): eight trees per
/// leaf and a culling depth of 8 so that `tiny`'s octree has interior nodes that test partial
/// visibility, a 60 m transition (20 m fade) so that the cameras stand past the fade end, the
/// draw distance far away.
pub fn straddling_params(mode: forestlod_shared::Hierarchy) -> Params {
    Params {
        hierarchy: mode as u32,
        grid_size: 50.0,
        nodes_per_node: 8,
        max_cull_depth: 8,
        lod1_transition: 60.0,
        fade_width: 20.0,
        draw_distance: 4000.0,
        texture_size: 32,
        ..Params::default()
    }
}

/// `tiny`'s tree positions with the test scenes' three card trees ([`scene_of`]: mesh index
/// modulo 3), the trees of [`straddling_cameras`]' cases.
pub fn tiny_card_trees() -> Vec<Instance> {
    forestlod_reference::scene::builtin::tiny()
        .instances
        .iter()
        .map(|t| Instance {
            mesh: t.mesh % 3,
            ..*t
        })
        .collect()
}

/// How many pixels of two frames differ in colour, in depth (as bits) and in LOD id: the count a
/// bit-for-bit frame equality asserts to be `(0, 0, 0)`.
pub fn differing_pixels(
    a: &forestlod_harness::image_compare::Images,
    b: &forestlod_harness::image_compare::Images,
) -> (usize, usize, usize) {
    let colour = a.color.iter().zip(&b.color).filter(|(x, y)| x != y).count();
    let depth = (a.depth.iter().zip(&b.depth))
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count();
    let ids = a
        .lod_id
        .iter()
        .zip(&b.lod_id)
        .filter(|(x, y)| x != y)
        .count();
    (colour, depth, ids)
}
