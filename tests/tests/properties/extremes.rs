//! The numerical-extremes catalogue of SPEC §7, on the reference pipeline: one test per extreme,
//! each asserting what the pipeline does there **and** that no output buffer holds NaN (selection's
//! per-command floats, every vertex the draw stage emits, the depth buffer, the mip chains). The
//! colour buffer is RGBA8 and cannot hold NaN; a NaN colour would be clamped to 0 by the output
//! merge, so the vertex outputs (positions and varyings, the only source of fragment inputs) are
//! checked instead. README "Numerical extremes" lists every case with its outcome.
//!
//! **GPU hook.** `Backend<Frame>` is the seam for the wgpu twins: each whole-frame extreme runs
//! through [`backends`], which today returns the reference only. When the GPU draw pipeline lands,
//! an implementation pushed there runs every frame-level case unchanged (SPEC §8 tolerances apply).
//!
//! Scenes are small (`single`, `pair`, card-tree rows, `tiny` only where a forest is the point),
//! viewports at most 128 x 128, billboards at most 32² unless the texture size is the extreme.

use forestlod_harness::stage::{Backend, Reference, Stage};
use forestlod_reference::draw::{
    LOD_ID_BILLBOARD, LOD_ID_MESH, LOD_ID_TERRAIN, LOD_ID_TRANSITION, tree_triangles,
};
use forestlod_reference::mips::build_mips;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::precision::{
    Disagreements, Precision, PrecisionScene, default_origin, place, sweep,
};
use forestlod_reference::scene::builtin::{self, ForestConfig};
use forestlod_reference::scene::{Instance, Scene, Terrain, tree_sphere};
use forestlod_reference::select::{Decision, SelectUniform, Selection, batch_decisions};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{
    AngleIndexMode, Camera, FadeMode, LodNeeds, MipMode, Params, angle_index, angle_index_eq31,
    view_interval,
};
use forestlod_tests::{cameras, card_tree, instances, params, property_config};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// The backend seam and the NaN checks
// ---------------------------------------------------------------------------------------------

/// What a frame-level extreme reads back from a backend.
struct FrameBuffers {
    /// Selection's output (commands and their per-command floats).
    selection: Selection,
    /// sRGB8 colour, row-major.
    color: Vec<[u8; 4]>,
    /// Depth, row-major.
    depth: Vec<f32>,
    /// LOD ids (E Fig. 3.1), row-major.
    lod: Vec<u32>,
}

/// A whole frame from a scene (prepare, select, draw): this file's stage of the harness's one
/// backend family (`forestlod_harness::stage`). `Err` names the rejected field or value.
struct Frame;

impl Stage for Frame {
    type Input<'a> = (&'a Scene, &'a Params, &'a Camera);
    type Output = Result<FrameBuffers, String>;
}

/// The CPU oracle. Besides the buffers it checks every vertex the draw stage emits for NaN.
impl Backend<Frame> for Reference {
    fn run(
        &self,
        (scene, params, camera): (&Scene, &Params, &Camera),
    ) -> Result<FrameBuffers, String> {
        let prepared = prepare(scene.clone(), params).map_err(|e| e.to_string())?;
        render_prepared(&prepared, params, camera)
    }
}

/// The backends every frame-level extreme runs on (see the module docs).
fn backends() -> Vec<Box<dyn Backend<Frame>>> {
    vec![Box::new(Reference)]
}

/// Renders with the reference and checks the vertex stage's outputs for NaN.
fn render_prepared(
    prepared: &Prepared,
    params: &Params,
    camera: &Camera,
) -> Result<FrameBuffers, String> {
    let frame = prepared.render(camera, params).map_err(|e| e.to_string())?;
    let (triangles, _) = tree_triangles(&prepared.resources(), &frame.selection, camera, params);
    for (t, tri) in triangles.iter().enumerate() {
        for v in tri {
            assert!(
                v.clip.iter().chain(&v.varyings).all(|x| x.is_finite()),
                "triangle {t}: non-finite vertex output {v:?}"
            );
        }
    }
    let target = &frame.drawn.target;
    Ok(FrameBuffers {
        selection: frame.selection,
        color: target.color().to_vec(),
        depth: target.depth().to_vec(),
        lod: target.aux().to_vec(),
    })
}

/// No NaN (or infinity) in selection's floats, and depth finite in `[0, 1]`.
fn assert_finite(b: &FrameBuffers, what: &str) {
    for (i, d) in b.selection.data.iter().enumerate() {
        assert!(
            d.fade_start.is_finite() && d.fade_end.is_finite(),
            "{what}: command {i} has non-finite fade floats {d:?}"
        );
    }
    for (i, z) in b.depth.iter().enumerate() {
        assert!(
            z.is_finite() && (0.0..=1.0).contains(z),
            "{what}: depth[{i}] = {z}"
        );
    }
    assert_eq!(b.color.len(), b.depth.len(), "{what}");
}

/// Pixels per LOD id.
fn count(b: &FrameBuffers, id: u32) -> usize {
    b.lod.iter().filter(|&&x| x == id).count()
}

/// Tree pixels of any LOD.
fn tree_pixels(b: &FrameBuffers) -> usize {
    count(b, LOD_ID_MESH) + count(b, LOD_ID_BILLBOARD) + count(b, LOD_ID_TRANSITION)
}

/// Small, fast parameters: K = 4 angles, r = 32.
fn small_params() -> Params {
    Params {
        angle_count: 4,
        texture_size: 32,
        ..Params::default()
    }
}

/// A camera at `eye` looking along `forward`, 60° field of view, `side`² pixels.
fn camera(eye: [f32; 3], forward: [f32; 3], side: u32) -> Camera {
    let mut c = Camera::look_at(eye, [eye[0] + 1.0, eye[1], eye[2]], 60.0, side, side);
    c.forward = forward;
    c
}

/// One card-tree species (10 m tall, 2.5 m crown half-width) with `texture`, trees at `xs` on the
/// X axis, flat ground at z = 0.
fn card_row(xs: &[f32], texture: Rgba8Image) -> Scene {
    let mut mesh = card_tree("card", 10.0, 2.5);
    mesh.texture = texture;
    Scene {
        name: "card-row".into(),
        origin: [0.0; 3],
        meshes: vec![mesh],
        instances: xs
            .iter()
            .map(|&x| Instance {
                position: [x, 0.0, 0.0],
                yaw: 0.3,
                scale: 1.0,
                mesh: 0,
            })
            .collect(),
        terrain: Terrain::Flat { z: 0.0 },
        bounds: [xs[0].min(0.0), -5.0, xs[xs.len() - 1].max(0.0), 5.0],
    }
}

/// A row of card trees every 5 m from 10 m to 120 m, opaque green.
fn green_row() -> Scene {
    let xs: Vec<f32> = (0..23).map(|i| 10.0 + 5.0 * i as f32).collect();
    card_row(&xs, Rgba8Image::new(8, 8, [40, 140, 50, 255]))
}

/// A camera beside [`green_row`], looking along it at a slant so no tree hides the next: trees at
/// x = 30 m are about 33 m deep, those at 120 m about 118 m.
fn side_camera(side: u32) -> Camera {
    camera([0.0, -15.0, 6.0], [1.0, 0.35, -0.05], side)
}

/// The layer (varying 3) of every billboard vertex the draw stage emits.
fn billboard_layers(prepared: &Prepared, params: &Params, camera: &Camera) -> Vec<u32> {
    let selection = prepared.select(camera, params);
    let (triangles, _) = tree_triangles(&prepared.resources(), &selection, camera, params);
    triangles
        .iter()
        .flatten()
        .filter(|v| selection.data[v.varyings[4].round() as usize].billboard != 0)
        .map(|v| v.varyings[3].round() as u32)
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Camera extremes
// ---------------------------------------------------------------------------------------------

/// Tolerance of the "inside the sphere" construction: the eye is placed at most this fraction of
/// `r - near` from the centre, so it is strictly inside and the sphere reaches past the near plane.
const INSIDE_FRACTION: f32 = 0.99;

proptest! {
    #![proptest_config(property_config())]

    /// SPEC §7 "camera at or inside a batch sphere": the batch is drawn, always with LOD0 (its
    /// interval starts behind the eye, before any transition distance), never culled.
    #[test]
    fn camera_inside_a_batch_sphere_draws_it_with_lod0(
        trees in instances(40),
        p in params(),
        pick in 0usize..1000,
        dir in (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
        f in 0.0f32..INSIDE_FRACTION,
        view in cameras(),
    ) {
        let scene = forestlod_tests::scene_of(trees);
        let metas = scene.mesh_metas();
        let batches = forestlod_reference::batches::build_batches(&scene, &metas, p.grid_size).unwrap();
        let b = &batches.metas[pick % batches.metas.len()];
        let d = glam::Vec3::new(dir.0, dir.1, dir.2);
        let d = if d.length() > 1e-3 { d.normalize() } else { glam::Vec3::X };
        let reach = (b.radius - view.near).max(0.0) * f;
        let eye = glam::Vec3::from(b.center) + d * reach;
        let cam = Camera { eye: eye.to_array(), ..view };
        prop_assume!(cam.validate().is_ok());
        let decision = SelectUniform::new(&cam, &p).decide(b.center, b.radius);
        prop_assert!(
            matches!(decision, Decision::Draw(LodNeeds { lod0: true, .. })),
            "eye {eye:?} inside batch {b:?}: {decision:?}"
        );
    }
}

/// The same extreme through a whole frame: the eye at the centre of `pair`'s spruce sphere.
#[test]
fn camera_at_a_sphere_centre_renders_without_nan() {
    let scene = builtin::pair();
    let metas = scene.mesh_metas();
    let (center, _) = tree_sphere(&scene.instances[0], &metas[0]);
    for transition in [1000.0, 0.0] {
        let p = Params {
            lod1_transition: transition,
            ..small_params()
        };
        let cam = camera(center, [1.0, 0.2, 0.0], 64);
        for backend in backends() {
            let b = backend.run((&scene, &p, &cam)).unwrap();
            assert_finite(&b, &backend.name());
            // Batches sort by mesh first: the spruce (mesh 0) batch is batch 0.
            assert!(
                b.selection.data.iter().any(|d| d.lod == 0 && d.batch == 0),
                "{}: the batch around the eye must draw LOD0",
                backend.name()
            );
        }
    }
}

/// SPEC §7 "camera exactly above a tree (V parallel to U)". `Camera::validate` rejects a forward
/// parallel to up (no defined roll), so the camera looks down 0.06° off vertical; the eye is
/// exactly above the tree's base, so V · U = 1: Eq. 3.1 gives `a` (one past the last layer) and the
/// pipeline's index the top layer K - 1.
#[test]
fn view_straight_down_uses_the_top_layer() {
    for k in [2u32, 4, 10] {
        assert_eq!(
            angle_index_eq31(1.0, k),
            k as f32,
            "Eq. 3.1 at V·U = 1, K = {k}"
        );
        assert_eq!(angle_index(1.0, k), k - 1);
    }
    let exact = camera([0.0, 0.0, 60.0], [0.0, 0.0, -1.0], 64);
    let e = exact.validate().unwrap_err();
    assert_eq!(e.field, "camera.forward", "{e}");

    let scene = builtin::single();
    let p = Params {
        lod1_transition: 0.0,
        fade_width: 0.0,
        ..small_params()
    };
    let cam = camera([0.0, 0.0, 60.0], [1.0e-3, 0.0, -1.0], 64);
    cam.validate().unwrap();
    let prepared = prepare(scene.clone(), &p).unwrap();
    let layers = billboard_layers(&prepared, &p, &cam);
    assert!(!layers.is_empty());
    assert!(
        layers.iter().all(|&l| l == p.angle_count - 1),
        "straight down must use the top layer: {layers:?}"
    );
    let b = render_prepared(&prepared, &p, &cam).unwrap();
    assert_finite(&b, "straight down");
    assert!(
        count(&b, LOD_ID_BILLBOARD) > 0,
        "the top-down billboard is visible"
    );
}

/// SPEC §7 "below the horizon": the eye 5 m below the tree's base (the tree stands on a ledge
/// 10 m above the ground, so the ground does not hide it). Eq. 3.1 goes negative; the pipeline
/// clamps to the level layer 0 (a billboard cannot show the underside).
#[test]
fn below_the_horizon_uses_the_level_layer() {
    assert!(angle_index_eq31(-0.2, 10) < 0.0);
    assert_eq!(angle_index(-0.2, 10), 0);
    let mut scene = builtin::single();
    scene.instances[0].position[2] = 10.0;
    let p = Params {
        lod1_transition: 0.0,
        fade_width: 0.0,
        ..small_params()
    };
    let cam = camera([-30.0, 0.0, 5.0], [1.0, 0.0, 0.3], 64);
    let prepared = prepare(scene, &p).unwrap();
    let layers = billboard_layers(&prepared, &p, &cam);
    assert!(
        !layers.is_empty() && layers.iter().all(|&l| l == 0),
        "{layers:?}"
    );
    let b = render_prepared(&prepared, &p, &cam).unwrap();
    assert_finite(&b, "below the horizon");
    assert!(count(&b, LOD_ID_BILLBOARD) > 0);
}

/// SPEC §7 "zero-length V": the eye exactly at the tree's base, so `V = eye - base = 0` and
/// `V · U = 0 / 0 = NaN`. The pipeline's index maps NaN to layer 0 and the billboard's facing falls
/// back to the camera's horizontal back vector: no NaN reaches a vertex.
#[test]
fn zero_length_view_vector_at_a_tree_base() {
    assert!(angle_index_eq31(f32::NAN, 10).is_nan());
    assert_eq!(angle_index(f32::NAN, 10), 0);
    let scene = builtin::single();
    for mode in AngleIndexMode::ALL {
        let p = Params {
            lod1_transition: 0.0,
            fade_width: 0.0,
            angle_index_mode: mode as u32,
            ..small_params()
        };
        let cam = camera([0.0, 0.0, 0.0], [1.0, 0.0, 0.2], 64);
        let prepared = prepare(scene.clone(), &p).unwrap();
        let layers = billboard_layers(&prepared, &p, &cam);
        assert!(layers.iter().all(|&l| l == 0), "{mode:?}: {layers:?}");
        for backend in backends() {
            let b = backend.run((&scene, &p, &cam)).unwrap();
            assert_finite(&b, &backend.name());
        }
    }
}

// ---------------------------------------------------------------------------------------------
// LOD parameter extremes
// ---------------------------------------------------------------------------------------------

/// SPEC §7 "fade width 0": the band is one depth; every fade mode becomes a hard switch, so no
/// fragment is in transition, and both LODs still show on either side of it.
#[test]
fn fade_width_zero_is_a_hard_switch() {
    let scene = green_row();
    let cam = side_camera(128);
    for fade in FadeMode::ALL {
        let p = Params {
            lod1_transition: 40.0,
            fade_width: 0.0,
            fade_mode: fade as u32,
            ..small_params()
        };
        for backend in backends() {
            let b = backend.run((&scene, &p, &cam)).unwrap();
            assert_finite(&b, &backend.name());
            assert!(
                b.selection
                    .data
                    .iter()
                    .all(|d| d.fade_start == 40.0 && d.fade_end == 40.0)
            );
            assert_eq!(count(&b, LOD_ID_TRANSITION), 0, "{fade:?}");
            assert!(
                count(&b, LOD_ID_MESH) > 0 && count(&b, LOD_ID_BILLBOARD) > 0,
                "{fade:?}"
            );
        }
    }
}

/// SPEC §7 "transition 0" (E Fig. 5.7 "no LOD0"): no batch wholly in front of the eye gets a LOD0
/// command, and no mesh fragment is drawn.
#[test]
fn transition_zero_means_no_lod0() {
    let scene = green_row();
    let cam = camera([0.0, 0.0, 6.0], [1.0, 0.0, -0.05], 128);
    for fade_width in [0.0, 250.0] {
        let p = Params {
            lod1_transition: 0.0,
            fade_width,
            ..small_params()
        };
        for backend in backends() {
            let b = backend.run((&scene, &p, &cam)).unwrap();
            assert_finite(&b, &backend.name());
            assert_eq!(b.selection.counters.lod0_commands, 0, "fade {fade_width}");
            assert!(b.selection.counters.lod1_commands > 0);
            assert_eq!(count(&b, LOD_ID_MESH), 0);
            assert!(count(&b, LOD_ID_BILLBOARD) > 0);
        }
    }
    // Batches that straddle the eye plane keep LOD0 (their interval reaches behind the eye).
    let p = Params {
        lod1_transition: 0.0,
        ..small_params()
    };
    let scene = builtin::tiny();
    let metas = scene.mesh_metas();
    let batches = forestlod_reference::batches::build_batches(&scene, &metas, 50.0).unwrap();
    let cam = camera([0.0, 0.0, 30.0], [1.0, 0.3, -0.2], 64);
    let u = SelectUniform::new(&cam, &p);
    for (meta, d) in batches
        .metas
        .iter()
        .zip(batch_decisions(&batches.metas, &cam, &p))
    {
        let i = view_interval(meta.center, meta.radius, cam.eye, u.forward);
        if d.needs().lod0 {
            assert!(i.lo < 0.0, "LOD0 for a batch wholly in front: {i:?}");
        }
    }
}

/// SPEC §7 "draw distance 0": every batch in front of the eye is culled by distance; nothing but
/// ground is drawn.
#[test]
fn draw_distance_zero_draws_no_tree() {
    let scene = green_row();
    let cam = camera([0.0, 0.0, 6.0], [1.0, 0.0, -0.05], 64);
    let p = Params {
        draw_distance: 0.0,
        ..small_params()
    };
    for backend in backends() {
        let b = backend.run((&scene, &p, &cam)).unwrap();
        assert_finite(&b, &backend.name());
        assert_eq!(b.selection.counters.commands, 0);
        assert_eq!(
            b.selection.counters.culled_distance,
            b.selection.counters.batches_tested
        );
        assert_eq!(tree_pixels(&b), 0);
        assert!(count(&b, LOD_ID_TERRAIN) > 0);
    }
}

/// SPEC §7 "draw distance huge" (1e7 m, the largest accepted): nothing is culled by distance, so a
/// forest 8 km away (beyond the default 4 km) is drawn, as billboards.
#[test]
fn draw_distance_huge_culls_nothing_by_distance() {
    let scene = green_row();
    let cam = camera([-8000.0, 0.0, 20.0], [1.0, 0.0, -0.002], 64);
    let near = Params {
        draw_distance: 4000.0,
        ..small_params()
    };
    let huge = Params {
        draw_distance: 1.0e7,
        ..small_params()
    };
    for backend in backends() {
        let b = backend.run((&scene, &near, &cam)).unwrap();
        assert_eq!(b.selection.counters.commands, 0);
        let b = backend.run((&scene, &huge, &cam)).unwrap();
        assert_finite(&b, &backend.name());
        assert_eq!(b.selection.counters.culled_distance, 0);
        assert!(b.selection.counters.lod1_commands > 0);
        assert_eq!(b.selection.counters.lod0_commands, 0);
    }
}

/// Parameters at `grid_size` with a small bake (2 angles, 16² textures) for the grid-size extremes.
fn small_bake_params(grid_size: f32) -> Params {
    Params {
        grid_size,
        angle_count: 2,
        texture_size: 16,
        ..Params::default()
    }
}

/// SPEC §7 "grid size tiny": at 1 m, `tiny`'s 1,468 trees make 1,467 batches (one 1 m cell holds
/// two trees of one species); at 0.5 m every batch holds one tree, and grouped selection then
/// equals the per-tree oracle exactly (SPEC §6).
#[test]
fn grid_size_tiny_gives_one_tree_per_batch() {
    let scene = builtin::tiny();
    let metas = scene.mesh_metas();
    let one_metre = forestlod_reference::batches::build_batches(&scene, &metas, 1.0).unwrap();
    assert_eq!(one_metre.metas.len(), scene.instances.len() - 1);
    assert_eq!(one_metre.metas.iter().map(|b| b.len).max(), Some(2));
    let p = small_bake_params(0.5);
    let batches = forestlod_reference::batches::build_batches(&scene, &metas, p.grid_size).unwrap();
    assert_eq!(batches.metas.len(), scene.instances.len());
    assert!(batches.metas.iter().all(|b| b.len == 1));
    let cam = camera([-120.0, 0.0, 40.0], [1.0, 0.1, -0.25], 64);
    let grouped = batch_decisions(&batches.metas, &cam, &p);
    let spheres = forestlod_reference::baselines::tree_spheres(&scene, &metas);
    let oracle = forestlod_reference::select::select_per_tree(&spheres, &cam, &p);
    let u = SelectUniform::new(&cam, &p);
    for (b, meta) in batches.metas.iter().enumerate() {
        let tree = batches.indirection[meta.offset as usize] as usize;
        let drawn = forestlod_reference::select::tree_within_draw_distance(&u, spheres[tree].0);
        let effective = if drawn {
            grouped[b].needs()
        } else {
            LodNeeds::default()
        };
        assert_eq!(effective, oracle[tree].needs(), "tree {tree}");
    }
    for backend in backends() {
        let b = backend.run((&scene, &p, &cam)).unwrap();
        assert_finite(&b, &backend.name());
        assert!(tree_pixels(&b) > 0);
    }
}

/// SPEC §7 "grid size huge" (1e6 m): one batch per mesh *and per quadrant*: the grid is anchored at
/// the scene origin and `tiny` is centred on it, so its trees fall into the four cells around the
/// origin. The batch spheres then span the whole forest (radius ≈ 150 m) and the camera stands
/// inside them.
#[test]
fn grid_size_huge_gives_one_batch_per_mesh_and_quadrant() {
    let scene = builtin::tiny();
    let metas = scene.mesh_metas();
    let p = small_bake_params(1.0e6);
    let batches = forestlod_reference::batches::build_batches(&scene, &metas, p.grid_size).unwrap();
    let mut keys: Vec<(u32, bool, bool)> = scene
        .instances
        .iter()
        .map(|t| (t.mesh, t.position[0] < 0.0, t.position[1] < 0.0))
        .collect();
    keys.sort();
    keys.dedup();
    assert_eq!(batches.metas.len(), keys.len());
    assert!(batches.metas.len() <= 4 * scene.meshes.len());
    assert!(
        batches
            .metas
            .iter()
            .all(|b| (-1..=0).contains(&b.cell[0]) && (-1..=0).contains(&b.cell[1]))
    );
    let cam = camera([0.0, 0.0, 30.0], [1.0, 0.1, -0.25], 64);
    for backend in backends() {
        let b = backend.run((&scene, &p, &cam)).unwrap();
        assert_finite(&b, &backend.name());
        // Every batch contains the eye: none is culled, each draws LOD0 (the near trees).
        assert_eq!(
            b.selection.counters.culled_frustum + b.selection.counters.culled_distance,
            0
        );
        assert_eq!(
            b.selection.counters.lod0_commands as usize,
            batches.metas.len()
        );
        assert!(tree_pixels(&b) > 0);
    }
}

// ---------------------------------------------------------------------------------------------
// Texture extremes
// ---------------------------------------------------------------------------------------------

/// No NaN or infinity in any linear level of any chain, and the alpha-aware range rule holds.
fn assert_chains_finite(chains: &[forestlod_reference::mips::MipChain], what: &str) {
    for (layer, chain) in chains.iter().enumerate() {
        for (k, level) in chain.levels.iter().enumerate() {
            assert!(
                level
                    .linear
                    .texels
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite() && (0.0..=1.0).contains(x)),
                "{what}: layer {layer} level {k} has a value outside [0, 1]"
            );
        }
    }
}

/// `scene` prepared for billboards only (transition 0) at `texture_size` and `angle_count`, with
/// those parameters: one baked layer per mesh and angle, and every chain finite (`what` names the
/// case).
fn prepare_billboards_only(
    scene: &Scene,
    texture_size: u32,
    angle_count: u32,
    what: &str,
) -> (Params, Prepared) {
    let p = Params {
        texture_size,
        angle_count,
        lod1_transition: 0.0,
        ..Params::default()
    };
    let prepared = prepare(scene.clone(), &p).unwrap();
    assert_eq!(
        prepared.billboards.layers.len(),
        scene.meshes.len() * angle_count as usize,
        "{what}"
    );
    assert_chains_finite(&prepared.billboards.chains, what);
    (p, prepared)
}

/// SPEC §7 "r = 1, 2" (and 256): bake and mips at the smallest sizes and a large one: the chain
/// has `log2(r) + 1` levels, nothing is NaN, and the frame (billboards only) renders.
#[test]
fn texture_sizes_1_2_and_256_bake_and_draw() {
    let scene = builtin::single();
    let cam = camera([-40.0, 0.0, 8.0], [1.0, 0.0, -0.05], 64);
    for r in [1u32, 2, 256] {
        let (p, prepared) = prepare_billboards_only(&scene, r, 2, &format!("r = {r}"));
        let baked = &prepared.billboards;
        assert!(baked.layers.iter().all(|l| l.width == r && l.height == r));
        assert!(
            baked
                .chains
                .iter()
                .all(|c| c.levels.len() as u32 == r.ilog2() + 1)
        );
        let b = render_prepared(&prepared, &p, &cam).unwrap();
        assert_finite(&b, &format!("r = {r}"));
        assert_eq!(b.selection.counters.lod0_commands, 0);
    }
}

/// SPEC §7 "r = 4096": the mips stage on one 4096² layer (a disc of opaque texels with a soft
/// edge): 13 levels down to 1x1, the alpha-aware range rule at every level, no NaN. The bake at
/// 4096 is the same rasterizer at a larger target (covered at 256 above); it is left out to keep
/// this file fast.
#[test]
fn mips_at_4096() {
    const R: u32 = 4096;
    let mut layer = Rgba8Image::new(R, R, [0, 0, 0, 0]);
    let c = R as f32 / 2.0;
    for y in 0..R {
        for x in 0..R {
            let d = ((x as f32 + 0.5 - c).powi(2) + (y as f32 + 0.5 - c).powi(2)).sqrt() / c;
            let a = ((1.0 - d) * 8.0).clamp(0.0, 1.0);
            layer.texels[(y * R + x) as usize] = [30, 120, 40, (a * 255.0).round() as u8];
        }
    }
    let chain = build_mips(&layer, MipMode::AlphaAware, 0.5).unwrap();
    assert_eq!(chain.levels.len(), 13);
    assert_eq!(chain.levels[12].linear.width, 1);
    assert_chains_finite(core::slice::from_ref(&chain), "4096");
    let range0 = chain.levels[0].raw_alpha_range;
    for (k, level) in chain.levels.iter().enumerate().skip(1) {
        let (lo, hi) = level
            .linear
            .texels
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), t| {
                (lo.min(t[3]), hi.max(t[3]))
            });
        let raw = level.raw_alpha_range;
        if raw[0] < raw[1] {
            assert_eq!([lo, hi], range0, "level {k}");
        } else {
            // The degenerate rule (uniform raw alpha: every 1x1 level, and here the 2x2 level
            // whose four quadrants of the disc average alike): every texel gets MaxAlpha_0.
            assert_eq!([lo, hi], [range0[1]; 2], "level {k}");
        }
    }
}

/// SPEC §7 "K = 1 and 2": K = 1 bakes one level layer (90°/(K-1) is defined as 0°) and every view,
/// even straight down, uses it; K = 2 bakes 0° and 90°, and the view picks the nearer.
#[test]
fn one_and_two_angles() {
    let scene = builtin::single();
    let down = camera([0.0, 0.0, 60.0], [1.0e-3, 0.0, -1.0], 64);
    let level = camera([-40.0, 0.0, 5.0], [1.0, 0.0, 0.0], 64);
    for (k, down_layer, level_layer) in [(1u32, 0u32, 0u32), (2, 1, 0)] {
        let (p, prepared) = prepare_billboards_only(&scene, 32, k, &format!("K = {k}"));
        // Layers of mesh 0 (the spruce) are 0..K.
        let down_layers = billboard_layers(&prepared, &p, &down);
        assert!(
            down_layers.iter().all(|&l| l == down_layer),
            "K = {k}: {down_layers:?}"
        );
        let level_layers = billboard_layers(&prepared, &p, &level);
        assert!(
            level_layers.iter().all(|&l| l == level_layer),
            "K = {k}: {level_layers:?}"
        );
        for cam in [down, level] {
            let b = render_prepared(&prepared, &p, &cam).unwrap();
            assert_finite(&b, &format!("K = {k}"));
            let billboards = count(&b, LOD_ID_BILLBOARD);
            if k == 1 && cam == down {
                // The only layer is the level view: from straight above its quad stands vertical,
                // seen edge-on, and covers no pixel centre. With K = 1, billboard trees vanish
                // from directly above.
                assert_eq!(billboards, 0, "K = 1 from above");
            } else {
                assert!(billboards > 0, "K = {k}");
            }
        }
    }
}

/// SPEC §7 "all-transparent textures": every baked layer and every mip level has alpha 0, and the
/// frame equals the frame without trees, pixel for pixel.
#[test]
fn all_transparent_texture_draws_nothing() {
    let xs: Vec<f32> = (0..23).map(|i| 10.0 + 5.0 * i as f32).collect();
    let scene = card_row(&xs, Rgba8Image::new(8, 8, [200, 40, 40, 0]));
    let cam = side_camera(64);
    let p = Params {
        lod1_transition: 40.0,
        fade_width: 20.0,
        ..small_params()
    };
    let prepared = prepare(scene, &p).unwrap();
    assert!(
        prepared
            .billboards
            .chains
            .iter()
            .flat_map(|c| &c.levels)
            .all(|l| l.rgba8.texels.iter().all(|t| t[3] == 0))
    );
    assert_chains_finite(&prepared.billboards.chains, "transparent");
    let b = render_prepared(&prepared, &p, &cam).unwrap();
    assert_finite(&b, "transparent");
    assert!(b.selection.counters.commands > 0, "selection still emits");
    assert_eq!(tree_pixels(&b), 0);
    let none = render_prepared(
        &prepared,
        &Params {
            draw_distance: 0.0,
            ..p
        },
        &cam,
    )
    .unwrap();
    assert_eq!(b.color, none.color);
    assert_eq!(b.depth, none.depth);
}

/// Largest difference, per sRGB8 channel, between a tree pixel of a uniformly coloured opaque
/// texture and that colour: trilinear filtering of equal texels is exact, then one rounding.
const SOLID_TOLERANCE: u8 = 1;

/// SPEC §7 "all-opaque textures": alpha 1 at every mip level of the mesh texture, and every tree
/// pixel, LOD0 or billboard, shows the texture's colour (no dark fringe, E Fig. 3.5).
#[test]
fn all_opaque_texture_is_solid() {
    let colour = [200u8, 40, 40, 255];
    let xs: Vec<f32> = (0..23).map(|i| 10.0 + 5.0 * i as f32).collect();
    let scene = card_row(&xs, Rgba8Image::new(8, 8, colour));
    let cam = side_camera(128);
    let p = Params {
        lod1_transition: 40.0,
        fade_width: 20.0,
        ..small_params()
    };
    let mesh_chain = build_mips(&scene.meshes[0].texture, MipMode::AlphaAware, 0.5).unwrap();
    assert!(
        mesh_chain
            .levels
            .iter()
            .all(|l| l.rgba8.texels.iter().all(|t| t[3] == 255))
    );
    let prepared = prepare(scene, &p).unwrap();
    assert_chains_finite(&prepared.billboards.chains, "opaque");
    let b = render_prepared(&prepared, &p, &cam).unwrap();
    assert_finite(&b, "opaque");
    assert!(count(&b, LOD_ID_MESH) > 0 && count(&b, LOD_ID_BILLBOARD) > 0);
    for (i, (&id, c)) in b.lod.iter().zip(&b.color).enumerate() {
        if id == LOD_ID_MESH || id == LOD_ID_BILLBOARD || id == LOD_ID_TRANSITION {
            assert!(
                (0..3).all(|k| c[k].abs_diff(colour[k]) <= SOLID_TOLERANCE),
                "pixel {i} (id {id}) is {c:?}, not {colour:?}"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Bad values
// ---------------------------------------------------------------------------------------------

/// SPEC §7 / brief: NaN or ±inf in every float field of `Params` (and an impossible value in every
/// integer field) is rejected by `Params::validate` naming the field, and neither `prepare` nor
/// `Prepared::render` runs on it.
#[test]
fn bad_values_in_every_params_field_are_rejected() {
    let scene = card_row(&[10.0], Rgba8Image::new(4, 4, [40, 140, 50, 255]));
    let good = small_params();
    let prepared = prepare(scene.clone(), &good).unwrap();
    let cam = camera([0.0, 0.0, 6.0], [1.0, 0.0, 0.0], 16);
    type Set = fn(&mut Params, f32);
    let floats: [(&str, Set); 5] = [
        ("grid_size", |p, v| p.grid_size = v),
        ("lod1_transition", |p, v| p.lod1_transition = v),
        ("fade_width", |p, v| p.fade_width = v),
        ("draw_distance", |p, v| p.draw_distance = v),
        ("alpha_cutoff", |p, v| p.alpha_cutoff = v),
    ];
    let mut cases: Vec<(&str, Params)> = Vec::new();
    for (field, set) in floats {
        for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0] {
            let mut p = good;
            set(&mut p, v);
            cases.push((field, p));
        }
    }
    type SetU = fn(&mut Params);
    let ints: [(&str, SetU); 11] = [
        ("angle_count", |p| p.angle_count = 0),
        ("angle_count", |p| p.angle_count = 92),
        ("texture_size", |p| p.texture_size = 100),
        ("lod_levels", |p| p.lod_levels = 0),
        ("fade_mode", |p| p.fade_mode = 4),
        ("mip_mode", |p| p.mip_mode = 3),
        ("angle_index_mode", |p| p.angle_index_mode = 2),
        // Issue 30: no azimuth, too many, an unknown rule, and one mesh's K·J views over the
        // billboard array's layer limit (91 x 64 = 5824 > 2048).
        ("azimuth_count", |p| p.azimuth_count = 0),
        ("azimuth_count", |p| p.azimuth_count = 65),
        ("azimuth_mode", |p| p.azimuth_mode = 2),
        ("azimuth_count", |p| {
            p.angle_count = 91;
            p.azimuth_count = 64;
        }),
    ];
    for (field, set) in ints {
        let mut p = good;
        set(&mut p);
        cases.push((field, p));
    }
    for (field, p) in cases {
        let e = p.validate().expect_err(field);
        assert_eq!(e.field, field, "{e}");
        let e = prepare(scene.clone(), &p).err().expect(field).to_string();
        assert!(e.contains(field), "prepare: {e}");
        let e = prepared.render(&cam, &p).err().expect(field).to_string();
        assert!(e.contains(field), "render: {e}");
    }
}

/// The same for every `Camera` field: NaN and ±inf in each component of eye, forward and up, in
/// the field of view, near and far, and a zero viewport side; `Prepared::render` validates before
/// selection.
#[test]
fn bad_values_in_every_camera_field_are_rejected() {
    let scene = card_row(&[10.0], Rgba8Image::new(4, 4, [40, 140, 50, 255]));
    let p = small_params();
    let prepared = prepare(scene, &p).unwrap();
    let good = camera([0.0, 0.0, 6.0], [1.0, 0.0, 0.0], 16);
    good.validate().unwrap();
    type Set = fn(&mut Camera, f32);
    let fields: [(&str, Set); 12] = [
        ("camera.eye", |c, v| c.eye[0] = v),
        ("camera.eye", |c, v| c.eye[1] = v),
        ("camera.eye", |c, v| c.eye[2] = v),
        ("camera.forward", |c, v| c.forward[0] = v),
        ("camera.forward", |c, v| c.forward[1] = v),
        ("camera.forward", |c, v| c.forward[2] = v),
        ("camera.up", |c, v| c.up[0] = v),
        ("camera.up", |c, v| c.up[1] = v),
        ("camera.up", |c, v| c.up[2] = v),
        ("camera.fov_y", |c, v| c.fov_y = v),
        ("camera.near", |c, v| c.near = v),
        ("camera.far", |c, v| c.far = v),
    ];
    let mut cases = Vec::new();
    for (field, set) in fields {
        for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut c = good;
            set(&mut c, v);
            cases.push((field, c));
        }
    }
    cases.push(("camera.viewport", Camera { width: 0, ..good }));
    cases.push(("camera.viewport", Camera { height: 0, ..good }));
    cases.push((
        "camera.forward",
        Camera {
            forward: [0.0; 3],
            ..good
        },
    ));
    for (field, c) in cases {
        let e = c.validate().expect_err(field);
        assert_eq!(e.field, field, "{c:?}: {e}");
        let e = prepared.render(&c, &p).err().expect(field).to_string();
        assert!(e.contains(field), "{e}");
    }
}

// ---------------------------------------------------------------------------------------------
// Large coordinates
// ---------------------------------------------------------------------------------------------

/// Cameras of the large-coordinate check (the experiment `large_coords` runs 400 per scale).
const LARGE_COORD_CAMERAS: usize = 120;

/// SPEC §7 "trees at UTM-scale coordinates": the `tiny` placement at `(5.0e5, 5.3e6)` m. The
/// pipeline's default (an `f64` origin, `f32` offsets) agrees with the `f64` selection on every
/// batch and tree decision outside the ambiguity band
/// ([`forestlod_reference::precision::AMBIGUITY_EPSILONS`] ε of the magnitudes involved, about a
/// centimetre here), over a sweep of cameras; naive `f32` world coordinates (0.5 m spacing at
/// y = 5.3e6) do not.
#[test]
fn large_coordinates_relative_f32_agrees_with_f64() {
    let template = builtin::forest(&ForestConfig {
        terrain: Terrain::Flat { z: 0.0 },
        ..builtin::tiny_config()
    })
    .unwrap();
    let center = [500_000.37, 5_300_000.61, 212.3];
    let world = place(&template, center);
    let ps = PrecisionScene::new(&template, &world, default_origin(&world), 25.0).unwrap();
    let base = Params {
        grid_size: 25.0,
        ..Params::default()
    };
    let cases = sweep(LARGE_COORD_CAMERAS, 7, center, 100.0, &base, 128, 128);
    let mut totals = [Disagreements::default(); 2];
    for case in &cases {
        for (i, precision) in Precision::ALL.into_iter().enumerate() {
            totals[i].merge(ps.compare(&case.camera, case.eye_world, &case.params, precision));
        }
    }
    let [naive, relative] = totals;
    eprintln!("f32-world {naive:?}\nf32-relative {relative:?}");
    assert!(relative.batches.total > 10_000 && relative.trees.total > 100_000);
    assert_eq!(relative.batches.differ_outside_band, 0, "{relative:?}");
    assert_eq!(relative.trees.differ_outside_band, 0, "{relative:?}");
    // The comparison has teeth: world-coordinate f32 gets decisions wrong here.
    assert!(naive.trees.differ_outside_band > 0, "{naive:?}");
}
