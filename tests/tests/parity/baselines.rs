//! Parity of the GPU baselines of E§5 (SPEC §9) with the reference's `baselines.rs`:
//! - **cull** (`gpu/src/shaders/cull.wgsl`): the visible set equals `baselines::visible_trees`
//!   (the per-tree oracle `select_per_tree`) exactly, tree for tree, except for trees whose
//!   decision sits within `forestlod_harness::judge::AMBIGUITY_REL` of a threshold (classified *ambiguous*, counted and
//!   reported); the commands equal the reference Vegetation's (`vegetation_commands`) for the GPU's
//!   own visible set bit for bit, in order, with the counters, and, when nothing is ambiguous, the
//!   reference's commands as a multiset of `(mesh, instance_count, index_count, first_index)`; each
//!   command's range of the compacted indirection holds that mesh's visible trees; the Primitive's
//!   indirect arguments are `{6, visible, 0, 0}`. Scenarios: `tiny` from the named cameras (and
//!   yawed), the cropped `synthetic` of `parity::draw`, 64 random cameras and parameters around each
//!   of them, and 64 random scenes of card trees with random cameras.
//! - **images** (Vegetation through `draw.wgsl`, Primitive through `primitive.wgsl`, both rendered
//!   by `GpuScene`, the sweeps' runner): judged by `forestlod_harness::image_compare` against
//!   `render_vegetation` / `render_primitive`, with its named tolerances and alternative frames
//!   (Vegetation: the alpha-test cutoff moved, `ALPHA_TEST_SHIFTS`; Primitive: the ray cast's
//!   root tests moved by a few roundings, `PRIMITIVE_DISC_SHIFTS`); scenarios from far to close,
//!   two of them close enough for Primitive's full-screen near fallback.
//! - the runner's own path for our pipeline (`GpuPipeline::Ours`) against the reference frame.
//!
//! Without an adapter the tests fail with an install hint unless `FORESTLOD_ALLOW_NO_GPU=1`.

use std::time::Instant;

use forestlod_gpu::{Compaction, GpuContext, GpuCull};
use forestlod_harness::alternatives::{
    alpha_test_alternatives, primitive_alternatives, vegetation_alternatives,
};
use forestlod_harness::bridge::cull_trees;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, GpuTimedFrame, StagesFromCpu};
use forestlod_harness::image_compare::{Images, MaxDiffs, judge_image, print_max_diffs};
use forestlod_harness::judge::{CullCase, Culled, judge_cull as harness_judge_cull};
use forestlod_harness::stage::images_of;
use forestlod_harness::stage::{Backend, Cull, Draw, FrameInput, Reference};
use forestlod_harness::stats::decision_budget_failure;
use forestlod_reference::baselines::{
    self, BaselineFrame, Proxy, primitive_quad, proxies, render_primitive, render_vegetation,
    tree_spheres,
};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::draw::LOD_ID_MESH;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::{Scene, builtin};
use forestlod_reference::select::Selection;
use forestlod_shared::{Camera, FadeMode, Params, ProxyRecord};
use forestlod_tests::scenarios::{
    crop_params, cropped_synthetic, named_views, tiny_and_crop_frames, tiny_params,
};
use forestlod_tests::{
    CullInput, assert_no_failures, cameras, cameras_around, instances, params, params_around,
    run_cases, scene_of,
};
use glam::Vec3;
use proptest::prelude::*;

/// Random cases per random property.
const CASES: u32 = 64;

/// Tallies of the cull comparisons, printed at the end.
#[derive(Clone, Debug, Default)]
struct CullTally {
    cases: u32,
    exact_cases: u32,
    trees: u64,
    visible: u64,
    commands: u64,
    ambiguous_trees: u64,
    ambiguous_cases: u32,
}

impl std::fmt::Display for CullTally {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} cases ({} exact, {} with ambiguous trees), {} trees culled, {} visible, \
             {} commands compared, {} ambiguous trees",
            self.cases,
            self.exact_cases,
            self.ambiguous_cases,
            self.trees,
            self.visible,
            self.commands,
            self.ambiguous_trees
        )
    }
}

/// A scene's trees ready to cull: their [`CullInput`] and the [`GpuCull`] over it.
struct SceneCull<'a> {
    scene: &'a Scene,
    input: CullInput,
    gpu: GpuCull<'static>,
}

impl<'a> SceneCull<'a> {
    fn new(ctx: &'static GpuContext, scene: &'a Scene) -> Result<Self, String> {
        let input = CullInput::new(scene);
        let gpu =
            GpuCull::new(ctx, &input.trees, &input.geometry.meshes).map_err(|e| e.to_string())?;
        Ok(Self { scene, input, gpu })
    }
}

/// Culls one frame of `cull`'s scene on the GPU and judges it against the reference with the
/// harness's judge (`forestlod_harness::judge::judge_cull`, module docs).
fn judge_cull(
    name: &str,
    cull: &mut SceneCull,
    camera: &Camera,
    params: &Params,
    tally: &mut CullTally,
) -> Result<(), String> {
    let case = CullCase {
        scene: cull.scene,
        meshes: &cull.input.geometry.meshes,
        spheres: &cull.input.spheres,
        camera,
        params,
    };
    let gpu = &mut cull.gpu;
    gpu.dispatch(camera, params).map_err(|e| e.to_string())?;
    let got = gpu.read().map_err(|e| e.to_string())?;
    let got = Culled {
        selection: Selection {
            commands: got.selection.commands,
            data: got.selection.data,
            counters: got.selection.counters,
        },
        indirection: got.indirection,
        draw_args: got.draw_args,
    };
    let want = Backend::<Cull>::run(&Reference, case);
    let j = harness_judge_cull(case, &want, &got).map_err(|e| format!("{name}: {e}"))?;
    tally.cases += 1;
    tally.trees += case.spheres.len() as u64;
    tally.visible += j.visible;
    tally.commands += got.selection.commands.len() as u64;
    if j.ambiguous == 0 {
        tally.exact_cases += 1;
    } else {
        tally.ambiguous_cases += 1;
        tally.ambiguous_trees += j.ambiguous;
    }
    Ok(())
}

/// Random cameras around a scene's footprint (eye within half a footprint of it, 0.5..400 m
/// up, looking at a random point of it) and random per-frame parameters (draw distance often
/// inside the footprint, so the distance cull and the per-tree discard both bite).
fn cases_around(bounds: [f32; 4]) -> impl Strategy<Value = (Camera, Params)> {
    (
        cameras_around(bounds),
        params_around(bounds, 0.0..2000.0, 0.0..500.0),
    )
}

#[test]
fn gpu_cull_matches_per_tree_culling() {
    let Some(ctx) = gpu_context() else { return };
    let started = Instant::now();
    let mut failures = Vec::new();
    let mut tally = CullTally::default();
    let tiny = builtin::tiny();
    let crop = cropped_synthetic(300.0);
    for (scene, p, size) in [
        (&tiny, tiny_params(FadeMode::Alpha), 96),
        (&crop, crop_params(FadeMode::Alpha), 160),
    ] {
        let mut cull = SceneCull::new(ctx, scene).expect("GpuCull::new");
        // The named cameras of parity_draw, yawed, and the draw distance pulled in.
        for v in named_views(scene, &p, size) {
            let case = format!(
                "{}-{}-yaw{}-dd{}",
                scene.name, v.camera_name, v.yaw, v.params.draw_distance
            );
            if let Err(e) = judge_cull(&case, &mut cull, &v.camera, &v.params, &mut tally) {
                failures.push(e);
            }
        }
        // Random cameras and parameters around the scene.
        let random = format!("{} random", scene.name);
        run_cases(
            &format!("{random} cameras"),
            CASES,
            cases_around(scene.bounds),
            |(camera, params)| judge_cull(&random, &mut cull, &camera, &params, &mut tally),
        );
    }
    // Random scenes of card trees, random cameras (`parity::select`'s generators).
    run_cases(
        "random scenes",
        CASES,
        (instances(300), cameras(), params()),
        |(trees, camera, params)| {
            let scene = scene_of(trees);
            let mut cull = SceneCull::new(ctx, &scene)?;
            judge_cull("random scene", &mut cull, &camera, &params, &mut tally)
        },
    );
    println!(
        "cull parity: {tally} in {:.2} s",
        started.elapsed().as_secs_f64()
    );
    assert!(tally.cases >= 64 + 36, "too few cases ran: {}", tally.cases);
    failures.extend(decision_budget_failure(
        "cull near-threshold trees",
        tally.ambiguous_trees,
        tally.trees + tally.visible,
    ));
    assert_no_failures("cull parity failed", &failures);
}

/// One frame of the image comparisons.
struct ImageScenario {
    name: String,
    prepared_key: usize,
    camera: Camera,
    params: Params,
    /// The scenario is there for Primitive's near fallback: some visible tree must take it.
    near_fallback: bool,
    /// The scenario is there for the crown sphere's far root (`Proxy::intersect`): the view's
    /// forward ray meets this tree's crown sphere with its near root before the near plane and
    /// its far root past it, so the far root is the hit the image shows at its centre.
    crown_far_root: Option<usize>,
    /// Vegetation is judged too. Not with a crown across the near plane: there the leaves lie
    /// within centimetres of it, and the depth judge fails on both such views (bias +15 ulps over
    /// 3,461 pixels from inside the oak's crown, -21 over 7,545 from just outside it, past its ±8;
    /// 5,755 and 1,669 edge-ambiguous pixels past their class budget): a near-plane depth
    /// question of Vegetation's own, left to its own issue, not the Primitive baseline's.
    vegetation: bool,
}

/// The roots `(near, far)` of the crown sphere of `inst` (proxy `proxy`) along `eye + t·dir`,
/// computed as `Proxy::intersect` does, or `None` when the ray misses it.
fn crown_roots(
    proxy: &Proxy,
    inst: &forestlod_reference::scene::Instance,
    eye: Vec3,
    dir: Vec3,
) -> Option<(f32, f32)> {
    let c = Vec3::from(inst.position) + Vec3::Z * proxy.crown_z * inst.scale;
    let r = proxy.crown_radius * inst.scale;
    let oc = eye - c;
    let (a, b) = (dir.dot(dir), oc.dot(dir));
    let disc = b * b - a * (oc.dot(oc) - r * r);
    (disc >= 0.0).then(|| ((-b - disc.sqrt()) / a, (-b + disc.sqrt()) / a))
}

/// The gap between the eye and the oak's crown sphere in `pair-near-plane-across-oak-crown`,
/// in near-plane distances: under 1, so the near plane cuts the crown (the near root lies
/// before it) with the eye outside the sphere; well above 0, so that is not a float tie.
const CROWN_GAP_NEARS: f32 = 0.6;

/// Visible trees whose Primitive quad is the full-screen near fallback (the reference's
/// `primitive_quad` condition).
fn near_fallback_trees(
    prepared: &Prepared,
    proxy_list: &[Proxy],
    visible: &[u32],
    camera: &Camera,
) -> usize {
    let b = camera.basis();
    visible
        .iter()
        .filter(|&&t| {
            let inst = &prepared.scene.instances[t as usize];
            let proxy = &proxy_list[inst.mesh as usize];
            let center = Vec3::from(inst.position) + Vec3::Z * proxy.center_z() * inst.scale;
            let radius = proxy.bounding_radius() * inst.scale;
            let d_c = (center - Vec3::from(camera.eye)).dot(b.forward);
            d_c - radius < baselines::NEAR_FALLBACK_FACTOR * camera.near
        })
        .count()
}

/// The shared `tiny` and cropped `synthetic` frames (the draw distance pulled in to 300 m), and
/// `pair` from inside its trees' bounding spheres for Primitive's near fallback.
fn image_scenarios() -> (Vec<Prepared>, Vec<ImageScenario>) {
    let p = tiny_params(FadeMode::Alpha);
    let dd300 = Params {
        draw_distance: 300.0,
        ..p
    };
    let (mut prepared, frames) = tiny_and_crop_frames(&[("draw-distance-300", dd300)]);
    let mut out: Vec<ImageScenario> = frames
        .into_iter()
        .map(|f| ImageScenario {
            name: f.name,
            prepared_key: f.prepared_key,
            camera: f.camera,
            params: f.params,
            near_fallback: false,
            crown_far_root: None,
            vegetation: true,
        })
        .collect();
    // `pair` (a spruce at x = -6, an oak at x = 6) from inside their bounding spheres.
    let pair = builtin::pair();
    let pair_params = Params {
        texture_size: 64,
        ..Params::default()
    };
    prepared.push(prepare(pair, &pair_params).expect("prepare pair"));
    out.push(ImageScenario {
        name: "pair-near-spruce-crown".into(),
        prepared_key: 2,
        camera: Camera::look_at([-11.0, -3.0, 9.0], [-6.0, 0.0, 8.0], 60.0, 96, 96),
        params: pair_params,
        near_fallback: true,
        crown_far_root: None,
        vegetation: true,
    });
    out.push(ImageScenario {
        name: "pair-near-oak-trunk".into(),
        prepared_key: 2,
        camera: Camera::look_at([1.0, -2.5, 1.5], [6.0, 0.0, 3.0], 70.0, 96, 96),
        params: pair_params,
        near_fallback: true,
        crown_far_root: None,
        vegetation: true,
    });
    // The oak's crown across the near plane (issue 36's WGSL survivor 581: the crown sphere's
    // far root decides only there): from inside the crown sphere, and from just outside it with
    // the near plane inside it. Both take the near fallback (the eye is within the tree's
    // bounding sphere).
    let oak = 1;
    let inst = &prepared[2].scene.instances[oak];
    let proxy = proxies(&prepared[2], pair_params.alpha_cutoff)[inst.mesh as usize];
    let c = Vec3::from(inst.position) + Vec3::Z * proxy.crown_z * inst.scale;
    let r = proxy.crown_radius * inst.scale;
    // `Camera::look_at`'s near plane (the same for every eye).
    let near = Camera::look_at([0.0; 3], [1.0, 0.0, 0.0], 70.0, 96, 96).near;
    let gap = CROWN_GAP_NEARS * near;
    for (name, eye, target, vegetation) in [
        (
            "pair-eye-in-oak-crown",
            c - Vec3::new(0.5 * r, 0.2 * r, 0.0),
            c + Vec3::new(r, 0.0, 0.3 * r),
            false,
        ),
        (
            "pair-near-plane-across-oak-crown",
            c - Vec3::X * (r + gap),
            c + Vec3::Z * (0.2 * r),
            false,
        ),
    ] {
        out.push(ImageScenario {
            name: name.into(),
            prepared_key: 2,
            camera: Camera::look_at(eye.to_array(), target.to_array(), 70.0, 96, 96),
            params: pair_params,
            near_fallback: true,
            crown_far_root: Some(oak),
            vegetation,
        });
    }
    (prepared, out)
}

/// Renders the baseline `variant` of `s` with the sweeps' runner and judges it against the
/// reference's frame `want`: the same trees drawn and commands (asserted), and the image (named
/// `name`) within tolerance of `want`'s or of one of `alternatives` (a failure goes to
/// `failures`). Returns the GPU frame.
#[allow(clippy::too_many_arguments)]
fn judge_baseline(
    sweep: &mut GpuScene,
    prepared: &Prepared,
    variant: GpuPipeline,
    s: &ImageScenario,
    want: &BaselineFrame,
    name: &str,
    alternatives: &[Images],
    max: &mut MaxDiffs,
    failures: &mut Vec<String>,
) -> GpuTimedFrame {
    let label = format!("{variant:?}");
    let got = sweep
        .render(prepared, variant, &s.camera, &s.params)
        .unwrap_or_else(|e| panic!("{label} frame: {e:?}"));
    assert_eq!(
        got.trees_drawn,
        Some(want.visible.len() as u64),
        "{}: {label} trees drawn",
        s.name
    );
    assert_eq!(got.commands, want.commands, "{}: {label} commands", s.name);
    if let Some(f) = judge_image(
        name,
        &got.images,
        &images_of(&want.target),
        alternatives,
        &s.camera,
        max,
    ) {
        failures.push(f);
    }
    got
}

#[test]
fn gpu_baseline_images_match_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let started = Instant::now();
    let (prepared, scenarios) = image_scenarios();
    let mut sweeps: Vec<GpuScene> = prepared
        .iter()
        .zip([
            tiny_params(FadeMode::Alpha),
            crop_params(FadeMode::Alpha),
            Params {
                texture_size: 64,
                ..Params::default()
            },
        ])
        .map(|(p, params)| {
            GpuScene::new(ctx, p, &params, StagesFromCpu::NONE).expect("GpuScene::new")
        })
        .collect();
    let mut failures = Vec::new();
    let (mut max_vegetation, mut max_primitive): (MaxDiffs, MaxDiffs) = Default::default();
    let (mut fallback_scenarios, mut crown_scenarios) = (0, 0);
    for s in &scenarios {
        let p = &prepared[s.prepared_key];
        let sweep = &mut sweeps[s.prepared_key];
        let spheres = tree_spheres(&p.scene, &p.geometry.meshes);
        let proxy_list = proxies(p, s.params.alpha_cutoff);

        // Vegetation.
        if s.vegetation {
            let want = render_vegetation(p, &spheres, &s.camera, &s.params);
            judge_baseline(
                sweep,
                p,
                GpuPipeline::Vegetation,
                s,
                &want,
                &format!("{}/vegetation", s.name),
                &vegetation_alternatives(p, &spheres, &s.camera, &s.params),
                &mut max_vegetation,
                &mut failures,
            );
        }

        // Primitive.
        let want = render_primitive(p, &spheres, &proxy_list, &s.camera, &s.params);
        let fallbacks = near_fallback_trees(p, &proxy_list, &want.visible, &s.camera);
        if s.near_fallback {
            assert!(
                fallbacks > 0,
                "{}: no visible tree takes the near fallback",
                s.name
            );
            assert!(
                want.target.aux().contains(&LOD_ID_MESH),
                "{}: the reference shows no proxy",
                s.name
            );
            fallback_scenarios += 1;
        }
        if let Some(tree) = s.crown_far_root {
            let inst = &p.scene.instances[tree];
            let (eye, forward) = (Vec3::from(s.camera.eye), s.camera.basis().forward);
            let roots = crown_roots(&proxy_list[inst.mesh as usize], inst, eye, forward);
            assert!(
                roots.is_some_and(|(t0, t1)| t0 < s.camera.near && t1 >= s.camera.near),
                "{}: the forward ray's crown roots {roots:?} do not straddle the near plane {}",
                s.name,
                s.camera.near
            );
            let centre = (s.camera.height / 2 * s.camera.width + s.camera.width / 2) as usize;
            assert_eq!(
                want.target.aux()[centre],
                LOD_ID_MESH,
                "{}: the reference shows no proxy at the image centre",
                s.name
            );
            crown_scenarios += 1;
        }
        let got = judge_baseline(
            sweep,
            p,
            GpuPipeline::Primitive,
            s,
            &want,
            &format!("{}/primitive ({fallbacks} near-fallback quads)", s.name),
            &primitive_alternatives(p, &spheres, &proxy_list, &s.camera, &s.params),
            &mut max_primitive,
            &mut failures,
        );
        println!(
            "  ({}: Vegetation and Primitive, GPU select {:.2} ms, draw {:.2} ms)",
            s.name,
            got.select_s * 1e3,
            got.draw_s * 1e3
        );
    }
    println!(
        "baseline images: {} scenarios ({} with Vegetation, all with Primitive; \
         {fallback_scenarios} with the near fallback, {crown_scenarios} with a crown across the \
         near plane) in {:.1} s",
        scenarios.len(),
        scenarios.iter().filter(|s| s.vegetation).count(),
        started.elapsed().as_secs_f64()
    );
    print_max_diffs("Vegetation", &max_vegetation);
    print_max_diffs("Primitive", &max_primitive);
    assert!(fallback_scenarios >= 4 && crown_scenarios == 2);
    assert_no_failures("baseline image parity failed", &failures);
}

/// The sweeps' runner draws our pipeline like the reference, with the reference's command count,
/// and reports its timings.
#[test]
fn sweep_runner_renders_ours_like_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let tiny = builtin::tiny();
    let p = tiny_params(FadeMode::Alpha);
    let prepared = prepare(tiny.clone(), &p).expect("prepare tiny");
    let camera = named_camera("medium", &tiny, 0.0, 96, 96).unwrap();
    let want = Backend::<Draw>::run(
        &Reference,
        FrameInput {
            prepared: &prepared,
            camera: &camera,
            params: &p,
        },
    );
    let alternatives = alpha_test_alternatives(&prepared, &camera, &p);
    let commands = prepared.select(&camera, &p).commands.len() as u64;
    let mut sweep = GpuScene::new(ctx, &prepared, &p, StagesFromCpu::NONE).expect("GpuScene::new");
    let timestamps = ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY);
    let mut failures = Vec::new();
    for compaction in Compaction::ALL {
        let variant = GpuPipeline::Ours(compaction);
        let frame = sweep
            .render(&prepared, variant, &camera, &p)
            .expect("frame");
        assert_eq!(frame.commands, commands, "{}", variant.name());
        assert_eq!(frame.trees_drawn, None);
        assert!(frame.select_s > 0.0 && frame.draw_s > 0.0);
        assert_eq!(frame.gpu_select_s.is_some(), timestamps);
        assert_eq!(frame.gpu_draw_s.is_some(), timestamps);
        println!(
            "{}: select {:.2} ms (GPU {:?}), draw {:.2} ms (GPU {:?})",
            variant.name(),
            frame.select_s * 1e3,
            frame.gpu_select_s.map(|s| s * 1e3),
            frame.draw_s * 1e3,
            frame.gpu_draw_s.map(|s| s * 1e3)
        );
        if let Some(f) = judge_image(
            &format!("sweep-runner/{}", variant.name()),
            &frame.images,
            &want,
            &alternatives,
            &camera,
            &mut (0, 0, 0.0),
        ) {
            failures.push(f);
        }
    }
    // The cull buffers the baselines leave behind agree with the runner's own tree list.
    let frame = sweep
        .render(&prepared, GpuPipeline::Vegetation, &camera, &p)
        .expect("frame");
    let visible = sweep
        .cull()
        .expect("a baseline frame culled")
        .read_visible()
        .expect("read_visible");
    assert_eq!(frame.trees_drawn, Some(visible.len() as u64));
    assert_eq!(cull_trees(&prepared).len(), prepared.scene.instances.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The constants the GPU Primitive repeats from the reference (it may not depend on it), and the
/// proxy record.
#[test]
fn primitive_constants_agree_with_the_reference() {
    use forestlod_gpu::primitive as gpu;
    assert_eq!(gpu::NEAR_FALLBACK_FACTOR, baselines::NEAR_FALLBACK_FACTOR);
    assert_eq!(gpu::NEAR_FALLBACK_DEPTH, baselines::NEAR_FALLBACK_DEPTH);
    assert_eq!(gpu::NEAR_FALLBACK_MARGIN, baselines::NEAR_FALLBACK_MARGIN);
    assert_eq!(gpu::PROXY_BOUND_SCALE, baselines::PROXY_BOUND_SCALE);
    assert_eq!(
        size_of::<ProxyRecord>() as u64,
        baselines::PROXY_BYTES,
        "PROXY_BYTES"
    );
    let proxy = Proxy {
        crown_radius: 3.0,
        crown_z: 15.0,
        trunk_radius: 0.3,
        bottom_z: -0.5,
        color: [0.1, 0.2, 0.3],
    };
    assert_eq!(
        ProxyRecord::from(&proxy),
        ProxyRecord {
            crown_radius: 3.0,
            crown_z: 15.0,
            trunk_radius: 0.3,
            bottom_z: -0.5,
            color: [0.1, 0.2, 0.3],
            _pad0: 0,
        }
    );
    // The quad the GPU's uniform describes for the fallback is the reference's.
    let camera = Camera::look_at([0.0, 0.0, 2.0], [10.0, 3.0, 2.0], 60.0, 160, 90);
    let u = gpu::PrimitiveUniform::new(&camera);
    let q = primitive_quad(&camera, Vec3::new(0.5, 0.0, 2.0), 3.0);
    let b = camera.basis();
    let mid = Vec3::from(camera.eye) + b.forward * u.fallback_depth;
    assert_eq!(
        q[0],
        mid - Vec3::from(u.right) * u.fallback_half_x - Vec3::from(u.up) * u.fallback_half_y
    );
    assert_eq!(
        q[2],
        mid + Vec3::from(u.right) * u.fallback_half_x + Vec3::from(u.up) * u.fallback_half_y
    );
}
