//! Metamorphic relations (issue 15): properties that relate two runs of one backend, so they
//! hold whatever the oracle says and catch a bug that the reference and the GPU twin share (or one
//! that no parity scenario reaches). Each runs on every backend: the reference and the GPU twin
//! (`gpu(from-cpu: none)`: the whole GPU pipeline for frames; both compactions of `select.wgsl`
//! for selections). Images are judged by the classes of `forestlod_harness::image_compare` (the
//! transformed frame as the "GPU" side, the plain frame of the same backend as the "reference",
//! the reference's cutoff-shifted frames of the plain case as the alternatives), so "unchanged"
//! means "unchanged up to the classified rounding ambiguities", with every budget and bias gate.
//!
//! - **Translation**: the scene and the camera moved together, by a large offset of the `f64`
//!   origin (UTM scale: 5e5, 5.3e6 m) *and* by 2 km of the local `f32` coordinates (the extent of
//!   `synthetic`, the largest local offsets the relative-`f32` rule of SPEC §3 produces), gives the
//!   same commands (as a multiset) and the same image. A stage that reads absolute positions
//!   where it should read eye-relative ones breaks it.
//! - **Permutation**: the trees in another order give the same commands, as a multiset of
//!   (mesh, LOD, billboard, fading, set of trees), and the same image up to depth ties.
//! - **LOD0 everywhere is Vegetation**: with one LOD level (every tree drawn as its mesh), our
//!   pipeline renders what the per-tree Vegetation baseline (E§5) renders.
//! - **Monotone LOD**: a lone tree moved away from the camera goes through LOD0, LOD0 + LOD1 (the
//!   band), LOD1 and culled, in that order and never back; every state is reached.
//!
//! - **Four tiles are the frame**: the frame rendered as four tiles of unequal sizes (each a
//!   tile camera, `Camera::tile`: an off-centre projection, the tile's own frustum planes for
//!   selection, refine and cull, the frame's pixel coordinates for the dither) and stitched
//!   together equals the frame rendered whole, up to the classified rounding ambiguities (the
//!   tile's projection is the frame's times a scale and offset, so vertex positions may round
//!   differently by an ulp).

use forestlod_harness::alternatives::alpha_test_alternatives;
use forestlod_harness::backend::{GpuRenderer, gpu_backends};
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu};
use forestlod_harness::image_compare::{Images, compare_images, write_failure_images};
use forestlod_harness::stage::images_of;
use forestlod_harness::stage::{Backend, Draw, FrameInput, Reference, Select, SelectInput};
use forestlod_reference::baselines::render_vegetation;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin::{self, ForestConfig};
use forestlod_reference::scene::{Scene, Terrain};
use forestlod_shared::{Camera, Decision, FadeMode, Params};
use forestlod_tests::assert_no_failures;
use forestlod_tests::scenarios::tiny_params;

/// `tiny` on flat ground (hills are not translation-invariant).
fn flat_tiny() -> Scene {
    builtin::forest(&ForestConfig {
        terrain: Terrain::Flat { z: 0.0 },
        ..builtin::tiny_config()
    })
    .expect("flat tiny")
}

/// The frame backends: the reference and the whole GPU pipeline.
fn draw_backends() -> Vec<Box<dyn Backend<Draw>>> {
    let ctx = gpu_context().expect("a GPU adapter (FORESTLOD_ALLOW_NO_GPU=1 skips)");
    vec![
        Box::new(Reference),
        Box::new(GpuRenderer {
            ctx,
            option: StagesFromCpu::NONE,
        }),
    ]
}

/// The selection backends: the reference and both GPU compactions.
fn select_backends() -> Vec<Box<dyn Backend<Select>>> {
    let mut out: Vec<Box<dyn Backend<Select>>> = vec![Box::new(Reference)];
    for b in gpu_backends() {
        out.push(Box::new(b));
    }
    out
}

/// One frame of `backend`.
fn frame(backend: &dyn Backend<Draw>, p: &Prepared, camera: &Camera, params: &Params) -> Images {
    backend.run(FrameInput {
        prepared: p,
        camera,
        params,
    })
}

/// Judges `got` against `want` (same backend, transformed vs plain case); a failure line, if any.
fn judge(
    name: &str,
    got: &Images,
    want: &Images,
    alternatives: &[Images],
    camera: &Camera,
) -> Option<String> {
    let report = compare_images(name, got, want, alternatives, camera);
    eprintln!("{report}");
    (!report.passed()).then(|| {
        let dir = write_failure_images(&report, got, want);
        format!(
            "{name}: {} (images in {})",
            report.failures().join("; "),
            dir.display()
        )
    })
}

/// A command as a multiset key: mesh, LOD, billboard, fading, and its trees as indices of the
/// *original* scene (`original_of` maps the scene's tree index to it), sorted.
type CommandKey = (u32, u32, u32, u32, Vec<u32>);

fn command_multiset(
    p: &Prepared,
    camera: &Camera,
    params: &Params,
    backend: &dyn Backend<Select>,
    original_of: &dyn Fn(u32) -> u32,
) -> Vec<CommandKey> {
    let out = backend.run(SelectInput {
        batches: &p.batches.metas,
        scales: &p.batches.scales,
        meshes: &p.geometry.meshes,
        billboard: &p.geometry.billboard,
        camera,
        params,
    });
    let s = out.selection;
    let mut keys: Vec<CommandKey> = s
        .commands
        .iter()
        .zip(&s.data)
        .map(|(c, d)| {
            let first = c.first_instance as usize;
            let mut trees: Vec<u32> = p.batches.indirection
                [first..first + c.instance_count as usize]
                .iter()
                .map(|&t| original_of(t))
                .collect();
            trees.sort_unstable();
            (d.mesh, d.lod, d.billboard, d.fading, trees)
        })
        .collect();
    keys.sort();
    keys
}

/// The medium view of `tiny` and its parameters (LOD0, the band and LOD1 all show), at 96².
fn medium_case(scene: &Scene) -> (Camera, Params) {
    let camera = forestlod_reference::cameras::named_camera("medium", scene, 0.0, 96, 96)
        .expect("named camera");
    (camera, tiny_params(FadeMode::DitherSequential))
}

#[test]
fn translating_scene_and_camera_changes_nothing() {
    let scene = flat_tiny();
    let (camera, params) = medium_case(&scene);
    // A multiple of the grid size, so batch membership is the same.
    let d = [2000.0f32, -1500.0, 0.0];
    assert_eq!(d[0] % params.grid_size, 0.0);
    assert_eq!(d[1] % params.grid_size, 0.0);
    let mut moved = scene.clone();
    for t in &mut moved.instances {
        t.position = [t.position[0] + d[0], t.position[1] + d[1], t.position[2]];
    }
    let b = scene.bounds;
    moved.bounds = [b[0] + d[0], b[1] + d[1], b[2] + d[0], b[3] + d[1]];
    // World translation by UTM-scale coordinates, minus the local shift.
    moved.origin = [
        scene.origin[0] + 500_000.0 - f64::from(d[0]),
        scene.origin[1] + 5_300_000.0 - f64::from(d[1]),
        scene.origin[2],
    ];
    let mut moved_camera = camera;
    moved_camera.eye = [camera.eye[0] + d[0], camera.eye[1] + d[1], camera.eye[2]];

    let plain = prepare(scene, &params).expect("prepare");
    let shifted = prepare(moved, &params).expect("prepare moved");
    let alternatives = alpha_test_alternatives(&plain, &camera, &params);
    let mut failures = Vec::new();
    for backend in select_backends() {
        let a = command_multiset(&plain, &camera, &params, backend.as_ref(), &|t| t);
        let b = command_multiset(&shifted, &moved_camera, &params, backend.as_ref(), &|t| t);
        eprintln!("translation/{}: {} commands", backend.name(), a.len());
        assert!(
            a.iter().any(|k| k.1 == 0) && a.iter().any(|k| k.1 == 1),
            "both LODs drawn"
        );
        if a != b {
            failures.push(format!(
                "translation/{}: the command multisets differ ({} vs {} commands)",
                backend.name(),
                a.len(),
                b.len()
            ));
        }
    }
    for backend in draw_backends() {
        let want = frame(backend.as_ref(), &plain, &camera, &params);
        let got = frame(backend.as_ref(), &shifted, &moved_camera, &params);
        failures.extend(judge(
            &format!("translation/{}", backend.name()),
            &got,
            &want,
            &alternatives,
            &camera,
        ));
    }
    assert_no_failures("translation changed the output", &failures);
}

#[test]
fn permuting_the_trees_changes_nothing_but_depth_ties() {
    let scene = flat_tiny();
    let (camera, params) = medium_case(&scene);
    let n = scene.instances.len() as u32;
    // A deterministic shuffle: tree i of the permuted scene is tree perm[i] of the original.
    let mut perm: Vec<u32> = (0..n).collect();
    perm.sort_by_key(|&i| (i.wrapping_mul(2_654_435_761) ^ 0x5bd1_e995).rotate_left(7));
    assert_ne!(perm, (0..n).collect::<Vec<_>>());
    let mut permuted = scene.clone();
    permuted.instances = perm.iter().map(|&i| scene.instances[i as usize]).collect();

    let plain = prepare(scene, &params).expect("prepare");
    let shuffled = prepare(permuted, &params).expect("prepare permuted");
    let alternatives = alpha_test_alternatives(&plain, &camera, &params);
    let mut failures = Vec::new();
    for backend in select_backends() {
        let a = command_multiset(&plain, &camera, &params, backend.as_ref(), &|t| t);
        let b = command_multiset(&shuffled, &camera, &params, backend.as_ref(), &|t| {
            perm[t as usize]
        });
        eprintln!("permutation/{}: {} commands", backend.name(), a.len());
        if a != b {
            failures.push(format!(
                "permutation/{}: the command multisets differ ({} vs {} commands)",
                backend.name(),
                a.len(),
                b.len()
            ));
        }
    }
    for backend in draw_backends() {
        let want = frame(backend.as_ref(), &plain, &camera, &params);
        let got = frame(backend.as_ref(), &shuffled, &camera, &params);
        failures.extend(judge(
            &format!("permutation/{}", backend.name()),
            &got,
            &want,
            &alternatives,
            &camera,
        ));
    }
    assert_no_failures("permuting the trees changed the output", &failures);
}

#[test]
fn lod0_everywhere_equals_the_vegetation_baseline() {
    let scene = flat_tiny();
    let (camera, params) = medium_case(&scene);
    let params = Params {
        lod_levels: 1,
        ..params
    };
    let p = prepare(scene, &params).expect("prepare");
    let alternatives = alpha_test_alternatives(&p, &camera, &params);
    let mut failures = Vec::new();
    // Reference.
    let ours = frame(&Reference, &p, &camera, &params);
    let vegetation = images_of(&render_vegetation(&p, &p.tree_spheres, &camera, &params).target);
    assert!(
        ours.lod_id
            .contains(&forestlod_reference::draw::LOD_ID_MESH),
        "the frame shows meshes"
    );
    failures.extend(judge(
        "lod0-is-vegetation/reference",
        &ours,
        &vegetation,
        &alternatives,
        &camera,
    ));
    // GPU: ours and Vegetation through the sweeps' runner (GPU textures, select, cull, draw).
    let ctx = gpu_context().expect("a GPU adapter (FORESTLOD_ALLOW_NO_GPU=1 skips)");
    let mut sweep = GpuScene::new(ctx, &p, &params, StagesFromCpu::NONE).expect("GpuScene");
    let ours = sweep
        .render(
            &p,
            GpuPipeline::Ours(forestlod_gpu::Compaction::Stable),
            &camera,
            &params,
        )
        .expect("ours")
        .images;
    let vegetation = sweep
        .render(&p, GpuPipeline::Vegetation, &camera, &params)
        .expect("vegetation")
        .images;
    failures.extend(judge(
        "lod0-is-vegetation/gpu",
        &ours,
        &vegetation,
        &alternatives,
        &camera,
    ));
    assert_no_failures("LOD0 everywhere differs from Vegetation", &failures);
}

/// The rank of a decision along the distance: LOD0, LOD0 + LOD1, LOD1, culled.
fn rank(d: Decision) -> u8 {
    match d {
        Decision::Draw(n) if n.lod0 && !n.lod1 => 0,
        Decision::Draw(n) if n.lod0 && n.lod1 => 1,
        Decision::Draw(n) if n.lod1 => 2,
        // A drawn batch without a LOD draws nothing: as culled.
        Decision::Draw(_) | Decision::CulledDistance | Decision::CulledFrustum => 3,
    }
}

#[test]
fn a_trees_lod_is_monotone_in_its_distance() {
    let scene = builtin::single();
    let params = Params {
        grid_size: 50.0,
        lod1_transition: 400.0,
        fade_width: 80.0,
        draw_distance: 900.0,
        lod_levels: 2,
        ..Params::default()
    };
    let p = prepare(
        scene,
        &Params {
            texture_size: 16,
            angle_count: 2,
            ..params
        },
    )
    .expect("prepare");
    assert_eq!(p.batches.metas.len(), 1);
    let mut failures = Vec::new();
    for backend in select_backends() {
        let mut ranks = Vec::new();
        // Distances 2..1200 m, the camera looking at the tree along -x, 10 m up.
        for step in 0..150u32 {
            let x = 2.0 + step as f32 * 8.0;
            let camera = Camera::look_at([-x, 0.3, 10.0], [0.0, 0.0, 8.0], 50.0, 64, 64);
            let out = backend.run(SelectInput {
                batches: &p.batches.metas,
                scales: &p.batches.scales,
                meshes: &p.geometry.meshes,
                billboard: &p.geometry.billboard,
                camera: &camera,
                params: &params,
            });
            ranks.push((x, rank(out.decisions[0])));
        }
        let backwards: Vec<String> = ranks
            .windows(2)
            .filter(|w| w[1].1 < w[0].1)
            .map(|w| format!("{} m: {} then {} m: {}", w[0].0, w[0].1, w[1].0, w[1].1))
            .collect();
        let reached: std::collections::BTreeSet<u8> = ranks.iter().map(|r| r.1).collect();
        eprintln!(
            "monotone/{}: ranks reached {reached:?}, {} steps back",
            backend.name(),
            backwards.len()
        );
        if !backwards.is_empty() {
            failures.push(format!(
                "monotone/{}: the LOD goes back as the tree moves away: {}",
                backend.name(),
                backwards.join(", ")
            ));
        }
        if reached.len() != 4 {
            failures.push(format!(
                "monotone/{}: not every state reached (LOD0, band, LOD1, culled): {reached:?}",
                backend.name()
            ));
        }
    }
    assert_no_failures("LOD not monotone in distance", &failures);
}

/// Stitches `tiles` (each `(x0, y0, images)`) into a `width x height` frame; every pixel must be
/// covered exactly once.
fn stitch(width: u32, height: u32, tiles: &[(u32, u32, Images)]) -> Images {
    let n = (width * height) as usize;
    let mut out = Images {
        width,
        height,
        color: vec![[0; 4]; n],
        depth: vec![f32::NAN; n],
        lod_id: vec![u32::MAX; n],
    };
    let mut covered = vec![0u8; n];
    for (x0, y0, t) in tiles {
        for y in 0..t.height {
            for x in 0..t.width {
                let (src, dst) = (
                    (y * t.width + x) as usize,
                    ((y0 + y) * width + x0 + x) as usize,
                );
                out.color[dst] = t.color[src];
                out.depth[dst] = t.depth[src];
                out.lod_id[dst] = t.lod_id[src];
                covered[dst] += 1;
            }
        }
    }
    assert!(
        covered.iter().all(|&c| c == 1),
        "the tiles cover the frame once"
    );
    out
}

#[test]
fn four_tiles_equal_the_whole_frame() {
    let scene = flat_tiny();
    let (camera, params) = medium_case(&scene);
    let (w, h) = (camera.width, camera.height);
    // Unequal tiles (40 + 56 wide, 80 + 16 high: the trees start at row 73 of this view, so every
    // tile shows some): the off-centre maps are not powers of two.
    let (sx, sy) = (40, 80);
    let rects = [
        (0, 0, sx, sy),
        (sx, 0, w - sx, sy),
        (0, sy, sx, h - sy),
        (sx, sy, w - sx, h - sy),
    ];
    let tiles: Vec<Camera> = rects
        .iter()
        .map(|&(x0, y0, tw, th)| {
            let t = camera.tile(x0, y0, tw, th);
            t.validate().expect("a valid tile camera");
            t
        })
        .collect();
    let p = prepare(scene, &params).expect("prepare");
    let alternatives = alpha_test_alternatives(&p, &camera, &params);
    let mut failures = Vec::new();
    // Each tile's frustum is its own: a tile selects fewer trees than the frame, and no tree the
    // frame does not select.
    for backend in select_backends() {
        let trees = |c: &Camera| -> std::collections::BTreeSet<u32> {
            command_multiset(&p, c, &params, backend.as_ref(), &|t| t)
                .into_iter()
                .flat_map(|k| k.4)
                .collect()
        };
        let whole = trees(&camera);
        let per_tile: Vec<_> = tiles.iter().map(trees).collect();
        eprintln!(
            "tiles/{}: {} trees in the frame, per tile {:?}",
            backend.name(),
            whole.len(),
            per_tile.iter().map(|t| t.len()).collect::<Vec<_>>()
        );
        for (i, t) in per_tile.iter().enumerate() {
            if !t.is_subset(&whole) || t.len() >= whole.len() || t.is_empty() {
                failures.push(format!(
                    "tiles/{}: tile {i} selects {} trees, {} of them not the frame's ({} trees): \
                     its frustum is not a non-empty part of the frame's",
                    backend.name(),
                    t.len(),
                    t.difference(&whole).count(),
                    whole.len()
                ));
            }
        }
    }
    for backend in draw_backends() {
        let want = frame(backend.as_ref(), &p, &camera, &params);
        let parts: Vec<(u32, u32, Images)> = rects
            .iter()
            .zip(&tiles)
            .map(|(r, t)| (r.0, r.1, frame(backend.as_ref(), &p, t, &params)))
            .collect();
        let got = stitch(w, h, &parts);
        assert!(
            want.lod_id
                .contains(&forestlod_reference::draw::LOD_ID_TRANSITION),
            "the frame shows the fade band (the dither origin matters)"
        );
        failures.extend(judge(
            &format!("tiles/{}", backend.name()),
            &got,
            &want,
            &alternatives,
            &camera,
        ));
    }
    assert_no_failures("four tiles differ from the whole frame", &failures);
}
