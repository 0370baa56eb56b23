//! Parity of occlusion culling on the GPU (issue 31: `gpu/src/shaders/pyramid.wgsl`,
//! `gpu/src/shaders/occlude.wgsl`, the two-pass frame of `GpuScene`) with the reference
//! (`reference/src/pyramid.rs`, `reference/src/occlude.rs`, `Prepared::render_with_history`); the
//! contract is `forestlod_shared::occlusion`'s.
//! - **pyramid**: from the same depth buffer, the GPU's pyramid equals the reference's bit for
//!   bit (`max` rounds nothing) at 1x1, 1x7, 5x3, 320x180, 333x187 and 1280x720, and the pyramid
//!   the GPU builds from a depth target it drew equals the reference's of that target read back.
//! - **occlude**: from the reference's selection, indirection and early depth (level 0 of its
//!   pyramid), the GPU's early and late commands, their lists (in order), the counters and the
//!   history equal the reference's, along two-frame paths under `two-phase`; decisions that
//!   differ are counted under [`DECISION_BUDGET_PER_MILLE`].
//! - **frames**: the GPU frame with occlusion culling (`single`, and `two-phase` along a path)
//!   equals the GPU frame without it in the dithered fade modes (and `none`) except counted depth
//!   ties ([`DEPTH_TIE_BUDGET`]); under `alpha` the differing pixels are counted; and it is judged
//!   against the reference's frame with occlusion culling by `forestlod_harness::image_compare`.
//!   Grid, `refine` (`lod0`, `all`) and octree with front-to-back commands.
//!
//! Without an adapter the tests fail with an install hint unless `FORESTLOD_ALLOW_NO_GPU=1`.

use forestlod_gpu::draw::DrawTarget;
use forestlod_gpu::readback::upload_storage;
use forestlod_gpu::{
    Compaction, DrawInputs, DrawScene, DrawTextures, GpuContext, GpuOcclude, GpuOccluded,
    GpuPyramid, SelectBuffers,
};
use forestlod_harness::alternatives::alpha_test_alternatives;
use forestlod_harness::bridge::{DrawSceneData, occlusion_footprints, upload_reference_textures};
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu, gpu_draw};
use forestlod_harness::image_compare::{Images, MaxDiffs, judge_image, print_max_diffs};
use forestlod_harness::stage::images_of;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::{Frame, Prepared, prepare};
use forestlod_reference::pyramid::Pyramid;
use forestlod_reference::select::Selection;
use forestlod_shared::{
    Camera, CommandOrder, FadeMode, Hierarchy, Occlusion, OcclusionCounters, OcclusionOrder,
    Params, TreeCull,
};
use forestlod_tests::assert_no_failures;
use forestlod_tests::scenarios::{
    crop_params, cropped_synthetic, occlusion_params, occlusion_path as path,
};

/// The sizes the pyramid is checked at: one pixel, one column, odd both ways, the sweeps' small
/// frame, odd and non-power-of-two, and the sweeps' large frame.
const PYRAMID_SIZES: [(u32, u32); 6] =
    [(1, 1), (1, 7), (5, 3), (320, 180), (333, 187), (1280, 720)];

/// Late decisions of the GPU that may differ from the reference's, per thousand trees tested,
/// over the whole run. A tree's decision compares its nearest corner depth (a perspective
/// division) with the pyramid, and its rectangle (another division, a floor) with texel
/// boundaries: a GPU may divide within 2.5 ulp (Vulkan's precision rule) and fuse the
/// projection's multiply-adds, so a tree whose nearest depth lies within a few ulps of an
/// occluder's, or whose rectangle edge lies within a few ulps of a pixel boundary, may go either
/// way. Such trees are rare (a corner exactly as deep as an occluder's fragment); one per
/// thousand leaves room for them and still catches a wrong rule, which flips whole groups of
/// trees.
const DECISION_BUDGET_PER_MILLE: u64 = 1;

/// Pixels per frame that may differ between the GPU frame with occlusion culling `reorder` and
/// without it in a dithered fade mode (`exact` may differ in none): the late pass draws after
/// the early one, so a pixel where an early
/// and a late fragment have exactly the same depth keeps the early one under LESS where the
/// frame without culling kept whichever came first in command order (module docs of
/// `forestlod_shared::occlusion`, "Images"). Exact depth ties between two trees' triangles are
/// rare (crossing crowns); a wrong pass (a cleared target, a culled visible tree) changes
/// hundreds of pixels.
const DEPTH_TIE_BUDGET: usize = 8;

/// A deterministic depth buffer of `w x h`: sky (1.0) in a band of rows and columns, random
/// depths in `[0, 1)` elsewhere, a pattern that gives every block of every level both.
fn depth_buffer(w: u32, h: u32, seed: u64) -> Vec<f32> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..w * h)
        .map(|i| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let (x, y) = (i % w, i / w);
            if (x + 3 * y) % 11 == 0 {
                1.0
            } else {
                (state >> 40) as f32 / (1u64 << 24) as f32
            }
        })
        .collect()
}

/// The first texel where `got` and `want` differ in bits, with both values.
fn first_bit_difference(got: &[f32], want: &[f32]) -> Option<(usize, f32, f32)> {
    got.iter()
        .zip(want)
        .enumerate()
        .find(|(_, (g, w))| g.to_bits() != w.to_bits())
        .map(|(i, (g, w))| (i, *g, *w))
}

/// The largest absolute difference of two pyramids' texels.
fn max_abs_diff(got: &[f32], want: &[f32]) -> f32 {
    got.iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs())
        .fold(0.0, f32::max)
}

/// From the same depth buffer the GPU's pyramid equals the reference's bit for bit, at every
/// size of [`PYRAMID_SIZES`].
#[test]
fn pyramid_equals_the_reference_bit_for_bit() {
    let Some(ctx) = gpu_context() else { return };
    let mut failures = Vec::new();
    let mut max_diff = 0.0f32;
    for (w, h) in PYRAMID_SIZES {
        for seed in 0..2 {
            let depth = depth_buffer(w, h, seed);
            let want = Pyramid::build(&depth, w, h);
            let got = GpuPyramid::of_depth(ctx, &depth, w, h).expect("GPU pyramid");
            assert_eq!(got.len(), want.texels.len(), "{w}x{h}: texel count");
            max_diff = max_diff.max(max_abs_diff(&got, &want.texels));
            if let Some((i, g, r)) = first_bit_difference(&got, &want.texels) {
                failures.push(format!(
                    "{w}x{h} seed {seed}: texel {i} is {g} on the GPU, {r} on the reference"
                ));
            }
        }
    }
    println!(
        "pyramid parity: {} sizes x 2 buffers, max |GPU - reference| = {max_diff}",
        PYRAMID_SIZES.len()
    );
    assert_no_failures("pyramid parity", &failures);
}

/// A scene's draw buffers and the reference's textures on the GPU.
struct Uploaded {
    scene: DrawScene,
    textures: DrawTextures,
}

fn upload(ctx: &GpuContext, prepared: &Prepared) -> Uploaded {
    let data = DrawSceneData::new(prepared);
    let scene = DrawScene::new(ctx, &data.desc(prepared)).expect("draw scene");
    let uploaded = upload_reference_textures(ctx, prepared).expect("textures");
    Uploaded {
        textures: uploaded.draw_textures().expect("draw textures"),
        scene,
    }
}

/// The pyramid `pyramid.wgsl` builds from a depth target the GPU drew (level 0 read from the
/// `Depth32Float` texture, not from values given) equals the reference's pyramid of that target
/// read back, bit for bit.
#[test]
fn pyramid_of_a_drawn_depth_target_equals_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let scene = cropped_synthetic(300.0);
    let params = crop_params(FadeMode::DitherSequential);
    let prepared = prepare(scene.clone(), &params).expect("prepare");
    let up = upload(ctx, &prepared);
    let draw = gpu_draw(ctx);
    let mut failures = Vec::new();
    for (w, h) in [(333, 187), (64, 48), (1, 7)] {
        let camera = named_camera("close", &scene, 0.0, w, h).expect("camera");
        let frame = prepared.render(&camera, &params).expect("reference frame");
        let selection = SelectBuffers::from_cpu(
            ctx,
            &frame.selection.commands,
            &frame.selection.data,
            &frame.selection.counters,
        )
        .expect("selection");
        let target = DrawTarget::new(ctx, w, h).expect("target");
        let inputs = DrawInputs {
            scene: &up.scene,
            textures: &up.textures,
            selection: &selection,
            indirection: None,
        };
        draw.render(ctx, &inputs, &camera, &params, &target)
            .expect("draw");
        let pyramid = GpuPyramid::new(ctx, w, h).expect("pyramid");
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        pyramid.encode_from_depth(ctx, &mut encoder, target.depth_texture());
        ctx.queue.submit([encoder.finish()]);
        let got = pyramid.read(ctx).expect("read pyramid");
        let depth = target.read(ctx).expect("read target").depth;
        let want = Pyramid::build(&depth, w, h);
        let sky = depth.iter().filter(|&&d| d == 1.0).count();
        println!(
            "drawn {w}x{h}: {} of {} pixels sky, max |GPU - reference| = {}",
            sky,
            depth.len(),
            max_abs_diff(&got, &want.texels)
        );
        if let Some((i, g, r)) = first_bit_difference(&got, &want.texels) {
            failures.push(format!(
                "{w}x{h}: texel {i} is {g} on the GPU, {r} on the reference"
            ));
        }
    }
    assert_no_failures("pyramid of a drawn target", &failures);
}

/// One configuration of the frame: its name and parameters (on top of the scene's), and whether
/// the scene is prepared with a hierarchy.
struct Config {
    name: &'static str,
    apply: fn(&mut Params),
}

/// Grid, `refine` `lod0` and `all`, and octree with front-to-back commands (module docs).
const CONFIGS: [Config; 4] = [
    Config {
        name: "grid",
        apply: |_| {},
    },
    Config {
        name: "refine-lod0",
        apply: |p| p.tree_cull = TreeCull::Lod0 as u32,
    },
    Config {
        name: "refine-all",
        apply: |p| p.tree_cull = TreeCull::All as u32,
    },
    Config {
        name: "octree-front-to-back",
        apply: |p| {
            p.hierarchy = Hierarchy::Octree as u32;
            p.command_order = CommandOrder::FrontToBack as u32;
        },
    },
];

/// The multiset difference size of two tree lists (trees in one and not the other, counted with
/// multiplicity): how many decisions made them differ.
fn list_difference(a: &[u32], b: &[u32]) -> u64 {
    let (mut a, mut b) = (a.to_vec(), b.to_vec());
    a.sort_unstable();
    b.sort_unstable();
    let (mut i, mut j, mut d) = (0, 0, 0u64);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
            std::cmp::Ordering::Less => {
                d += 1;
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                d += 1;
                j += 1;
            }
        }
    }
    d + (a.len() - i + b.len() - j) as u64
}

/// Per command of a phase, the reference's and the GPU's lists: `(differing decisions, whether
/// any list or command differs)`.
fn compare_phase(
    what: &str,
    got: &GpuOccluded,
    got_sel: &[forestlod_shared::DrawCommand],
    want_sel: &Selection,
    want_ind: &[u32],
    notes: &mut Vec<String>,
) -> u64 {
    let mut differing = 0;
    assert_eq!(
        got_sel.len(),
        want_sel.commands.len(),
        "{what}: command count"
    );
    for (i, (g, w)) in got_sel.iter().zip(&want_sel.commands).enumerate() {
        let range = |c: &forestlod_shared::DrawCommand, ind: &[u32]| {
            ind[c.first_instance as usize..(c.first_instance + c.instance_count) as usize].to_vec()
        };
        assert_eq!(
            g.first_instance, w.first_instance,
            "{what}: command {i}'s slot"
        );
        let (gl, wl) = (range(g, &got.indirection), range(w, want_ind));
        if gl != wl || (g.index_count, g.base_vertex) != (w.index_count, w.base_vertex) {
            let d = list_difference(&gl, &wl);
            if d == 0 && notes.len() < 8 {
                notes.push(format!("{what}: command {i}: same trees, another order"));
            }
            differing += d.max(1);
        }
    }
    differing
}

/// Tallies of the stage parity.
#[derive(Default)]
struct Tally {
    frames: u32,
    exact_frames: u32,
    counters: OcclusionCounters,
    differing: u64,
}

/// The GPU `occlude` stage, fed the reference's selection, indirection and early depth, equals
/// the reference's `occlude_early` / `occlude_late` (module docs): for both modes, every
/// configuration, two fade modes (a dithered one: every command may occlude; `alpha`: the fading
/// commands may not), two-frame paths (the second frame's `two-phase` early pass reads the
/// history the first wrote, on each side its own).
#[test]
fn occlude_equals_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let scene = cropped_synthetic(300.0);
    let mut failures = Vec::new();
    let mut notes = Vec::new();
    let mut tally = Tally::default();
    for config in &CONFIGS {
        let mut base = occlusion_params(FadeMode::DitherSequential);
        (config.apply)(&mut base);
        let prepared = prepare(scene.clone(), &base).expect("prepare");
        let footprints = occlusion_footprints(&prepared);
        for (fade, order) in [
            (FadeMode::DitherSequential, OcclusionOrder::Exact),
            (FadeMode::Alpha, OcclusionOrder::Exact),
            (FadeMode::DitherSequential, OcclusionOrder::Reorder),
        ] {
            for mode in [Occlusion::Single, Occlusion::TwoPhase] {
                for (view, size) in [((250.0, 0.0), (96, 64)), ((120.0, 25.0), (75, 61))] {
                    let params = Params {
                        fade_mode: fade as u32,
                        occlusion: mode as u32,
                        occlusion_order: order as u32,
                        ..base
                    };
                    let mut occlude = GpuOcclude::new(ctx, &footprints).expect("occlude");
                    let pyramid = GpuPyramid::new(ctx, size.0, size.1).expect("pyramid");
                    let mut history: Vec<u32> = Vec::new();
                    for (k, camera) in path(&scene, view, size, 2).iter().enumerate() {
                        let name = format!(
                            "{}/{}/{}/{}/{view:?}/frame {k}",
                            config.name,
                            fade.name(),
                            mode.name(),
                            order.name()
                        );
                        let frame = prepared
                            .render_with_history(camera, &params, &history)
                            .expect("reference frame");
                        let got = gpu_occlude(
                            ctx,
                            &prepared,
                            &frame,
                            &mut occlude,
                            &pyramid,
                            camera,
                            &params,
                        );
                        let occ = frame.occlusion.as_ref().expect("occlusion ran");
                        let mut differing = compare_phase(
                            &format!("{name} early"),
                            &got,
                            &got.early.commands,
                            &occ.early,
                            &occ.indirection,
                            &mut notes,
                        );
                        differing += compare_phase(
                            &format!("{name} late"),
                            &got,
                            &got.late.commands,
                            &occ.late,
                            &occ.indirection,
                            &mut notes,
                        );
                        let visible_differ = got
                            .visible
                            .iter()
                            .zip(&occ.visible)
                            .filter(|(g, w)| g != w)
                            .count() as u64;
                        tally.frames += 1;
                        let c = occ.counters;
                        tally.counters.tested += c.tested;
                        tally.counters.occluded += c.occluded;
                        tally.counters.early += c.early;
                        tally.counters.late += c.late;
                        tally.counters.offscreen += c.offscreen;
                        tally.counters.unbounded += c.unbounded;
                        if differing == 0 && visible_differ == 0 {
                            tally.exact_frames += 1;
                            if got.counters != c {
                                failures.push(format!(
                                    "{name}: same lists, counters differ: GPU {:?}, reference {c:?}",
                                    got.counters
                                ));
                            }
                        } else {
                            notes.push(format!(
                                "{name}: {differing} list decisions and {visible_differ} history \
                                 entries differ (counters GPU {:?}, reference {c:?})",
                                got.counters
                            ));
                            tally.differing += differing + visible_differ;
                        }
                        history = occ.visible.clone();
                    }
                }
            }
        }
    }
    for n in &notes {
        println!("  {n}");
    }
    let budget = (u64::from(tally.counters.tested) * DECISION_BUDGET_PER_MILLE).div_ceil(1000);
    println!(
        "occlude parity: {} frames ({} exact), {} trees tested, {} occluded, {} early, {} late, \
         {} offscreen, {} unbounded; {} differing decisions (budget {budget})",
        tally.frames,
        tally.exact_frames,
        tally.counters.tested,
        tally.counters.occluded,
        tally.counters.early,
        tally.counters.late,
        tally.counters.offscreen,
        tally.counters.unbounded,
        tally.differing,
    );
    assert!(
        tally.counters.occluded > 0,
        "no tree was occluded: the cases test nothing"
    );
    assert!(
        tally.counters.early > 0,
        "no early tree: the cases test nothing"
    );
    if tally.differing > budget {
        failures.push(format!(
            "{} differing decisions over a budget of {budget} ({} per mille of {} tested)",
            tally.differing, DECISION_BUDGET_PER_MILLE, tally.counters.tested
        ));
    }
    assert_no_failures("occlude parity", &failures);
}

/// Runs the GPU's early split, the pyramid of the reference's early depth and the late test on
/// the reference's selection of `frame`; reads the result back.
fn gpu_occlude(
    ctx: &GpuContext,
    prepared: &Prepared,
    frame: &Frame,
    occlude: &mut GpuOcclude,
    pyramid: &GpuPyramid,
    camera: &Camera,
    params: &Params,
) -> GpuOccluded {
    let sel = &frame.selection;
    let selection =
        SelectBuffers::from_cpu(ctx, &sel.commands, &sel.data, &sel.counters).expect("selection");
    let indirection = frame.indirection(prepared);
    let input = upload_storage(
        ctx,
        "occlude input",
        indirection,
        wgpu::BufferUsages::empty(),
    );
    let occ = frame.occlusion.as_ref().expect("occlusion ran");
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    occlude
        .encode_early(
            &mut encoder,
            &selection,
            &input,
            indirection.len() as u32,
            camera,
            params,
        )
        .expect("early");
    pyramid
        .encode_from_values(ctx, &mut encoder, &occ.pyramid.texels[..w * h])
        .expect("pyramid");
    occlude
        .encode_late(&mut encoder, &selection, pyramid, camera, params)
        .expect("late");
    ctx.queue.submit([encoder.finish()]);
    occlude.read(&selection).expect("read occlude")
}

/// Steps between a tree's nearest depth and the constant pyramid of a knife-edge probe, in
/// ulps: the GPU's nearest depth is a perspective division of fused or unfused sums, within a few
/// ulps of the reference's (Vulkan allows 2.5 ulp for the division alone); 4 ulps keeps both
/// probes on their side of it, and lies well inside `OCCLUSION_Z_SLACK` (16 ulps at depth 1),
/// so a late test that dropped or doubled the slack falls on the wrong side.
const KNIFE_EDGE_ULPS: u32 = 4;

/// Knife-edge probes the GPU may decide otherwise than the reference: none. A probe sits
/// [`KNIFE_EDGE_ULPS`] from the threshold, beyond the GPU's rounding of the nearest depth.
const KNIFE_EDGE_BUDGET: usize = 0;

/// `x` moved by `steps` ulps (up for positive `steps`), for positive finite `x`.
fn ulps_from(x: f32, steps: i32) -> f32 {
    f32::from_bits((x.to_bits() as i64 + i64::from(steps)) as u32)
}

/// The late test at the knife edge of its depth rule (`forestlod_shared::occluded`): per tree of
/// a dense view, the pyramid is one constant [`KNIFE_EDGE_ULPS`] behind or in front of the tree's
/// nearest depth as the reference bounds it (`occlusion_bounds`, with `OCCLUSION_Z_SLACK`); the
/// GPU keeps the tree exactly when the reference does (the tree passes when the constant is
/// behind its nearest depth). Mutation-checked: `occlusion_bounds` without the z slack in
/// `common.wgsl` culls every "behind" probe.
#[test]
fn late_decisions_at_the_knife_edge_follow_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let scene = cropped_synthetic(300.0);
    let params = Params {
        occlusion: Occlusion::Single as u32,
        occluder_depth: 0.0,
        ..crop_params(FadeMode::DitherSequential)
    };
    let prepared = prepare(scene.clone(), &params).expect("prepare");
    let footprints = occlusion_footprints(&prepared);
    let camera = path(&scene, (120.0, 25.0), (64, 48), 1)[0];
    let (w, h) = (camera.width, camera.height);
    let view_proj = camera.view_projection();
    let command = forestlod_shared::DrawCommand {
        index_count: 3,
        instance_count: 1,
        first_index: 0,
        base_vertex: 0,
        first_instance: 0,
    };
    // A billboard command: never an occluder under `single` (whose nearest occluder depth would
    // make the one tree early), so every probe is tested.
    let data = forestlod_shared::CommandData {
        lod: forestlod_shared::LOD_BILLBOARD,
        billboard: 1,
        ..bytemuck::Zeroable::zeroed()
    };
    let counters = forestlod_shared::SelectCounters {
        commands: 1,
        ..Default::default()
    };
    let selection = SelectBuffers::from_cpu(ctx, &[command], &[data], &counters).expect("sel");
    let mut occlude = GpuOcclude::new(ctx, &footprints).expect("occlude");
    let pyramid = GpuPyramid::new(ctx, w, h).expect("pyramid");
    let (mut probes, mut failures) = (0usize, Vec::new());
    let trees =
        footprints.iter().enumerate().filter_map(
            |(t, f)| match forestlod_shared::occlusion_bounds(
                &view_proj,
                camera.near,
                [f[0], f[1], f[2]],
                f[3],
                w,
                h,
            ) {
                forestlod_shared::OcclusionBound::Rect(r) if r.z_min > 0.0 && r.z_min < 1.0 => {
                    Some((t as u32, r))
                }
                _ => None,
            },
        );
    for (t, rect) in trees.take(48) {
        let input = upload_storage(ctx, "knife-edge input", &[t], wgpu::BufferUsages::empty());
        for steps in [KNIFE_EDGE_ULPS as i32, -(KNIFE_EDGE_ULPS as i32)] {
            let p = ulps_from(rect.z_min, steps);
            let want_kept = !forestlod_shared::occluded(&rect, p);
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            occlude
                .encode_early(&mut encoder, &selection, &input, 1, &camera, &params)
                .expect("early");
            pyramid
                .encode_from_values(ctx, &mut encoder, &vec![p; (w * h) as usize])
                .expect("pyramid");
            occlude
                .encode_late(&mut encoder, &selection, &pyramid, &camera, &params)
                .expect("late");
            ctx.queue.submit([encoder.finish()]);
            let got = occlude.read(&selection).expect("read");
            let got_kept = got.late.commands[0].instance_count == 1;
            probes += 1;
            if got_kept != want_kept {
                failures.push(format!(
                    "tree {t}: nearest depth {} (reference), pyramid {p} ({steps:+} ulps): GPU \
                     {}, reference {}",
                    rect.z_min,
                    if got_kept { "keeps" } else { "culls" },
                    if want_kept { "keeps" } else { "culls" }
                ));
            }
        }
    }
    println!(
        "{probes} knife-edge probes at ±{KNIFE_EDGE_ULPS} ulps: {} decided otherwise than the \
         reference (budget {KNIFE_EDGE_BUDGET})",
        failures.len()
    );
    assert!(probes >= 32, "too few bounded trees: {probes} probes");
    if failures.len() > KNIFE_EDGE_BUDGET {
        assert_no_failures("knife-edge probes", &failures);
    }
}

/// Pixels where two frames differ in colour, depth bits or LOD id.
fn differing_pixels(a: &Images, b: &Images) -> usize {
    (0..a.color.len())
        .filter(|&i| {
            a.color[i] != b.color[i]
                || a.depth[i].to_bits() != b.depth[i].to_bits()
                || a.lod_id[i] != b.lod_id[i]
        })
        .count()
}

/// The GPU frame with occlusion culling (module docs): against the GPU frame without it
/// (bit-identical in the dithered modes and `none` but for [`DEPTH_TIE_BUDGET`] depth ties per
/// frame; counted under `alpha`), and against the reference's frame with occlusion culling
/// (`image_compare`'s tolerances), for `single` and a three-frame `two-phase` path, every
/// configuration.
#[test]
fn frames_with_occlusion_culling_equal_frames_without() {
    let Some(ctx) = gpu_context() else { return };
    let scene = cropped_synthetic(300.0);
    let mut failures = Vec::new();
    let mut max: MaxDiffs = Default::default();
    let (mut max_dithered, mut alpha_pixels, mut frames) = (0usize, 0usize, 0u32);
    let mut counters = OcclusionCounters::default();
    // Frames whose judge against the reference fails as the same frame without culling does.
    let mut draw_failures = Vec::new();
    for config in &CONFIGS {
        let mut base = occlusion_params(FadeMode::DitherSequential);
        (config.apply)(&mut base);
        let prepared = prepare(scene.clone(), &base).expect("prepare");
        let mut gpu = GpuScene::new(
            ctx,
            &prepared,
            &base,
            StagesFromCpu::parse("textures").unwrap(),
        )
        .expect("GPU scene");
        for (fade, order) in [
            (FadeMode::DitherSequential, OcclusionOrder::Exact),
            (FadeMode::None, OcclusionOrder::Exact),
            (FadeMode::Alpha, OcclusionOrder::Exact),
            (FadeMode::DitherSequential, OcclusionOrder::Reorder),
        ] {
            // `exact` is the frame without culling bit for bit; `reorder` but for depth ties.
            let budget = match order {
                OcclusionOrder::Exact => 0,
                OcclusionOrder::Reorder => DEPTH_TIE_BUDGET,
            };
            for mode in [Occlusion::Single, Occlusion::TwoPhase] {
                let frames_of_path = if mode == Occlusion::TwoPhase { 3 } else { 1 };
                let off = Params {
                    fade_mode: fade as u32,
                    ..base
                };
                let on = Params {
                    occlusion: mode as u32,
                    occlusion_order: order as u32,
                    ..off
                };
                // The dense view at tree height (heavy occlusion), and `parity::draw`'s close
                // view of the crop (where the draw's judge passes without culling).
                let named = named_camera("close", &scene, 0.0, 96, 72).expect("camera");
                let views = [
                    (
                        "ground",
                        path(&scene, (120.0, 25.0), (96, 72), frames_of_path),
                    ),
                    ("close", vec![named; frames_of_path]),
                ];
                for (view, cameras) in &views {
                    gpu.reset_history();
                    let mut history: Vec<u32> = Vec::new();
                    for (k, camera) in cameras.iter().enumerate() {
                        let name = format!(
                            "{}/{}/{}/{}/{view}/frame {k}",
                            config.name,
                            fade.name(),
                            mode.name(),
                            order.name()
                        );
                        let pipeline = GpuPipeline::Ours(Compaction::Stable);
                        let without = gpu
                            .render(&prepared, pipeline, camera, &off)
                            .expect("off")
                            .images;
                        let with = gpu.render(&prepared, pipeline, camera, &on).expect("on");
                        let c = with.occlusion.expect("counters");
                        counters.tested += c.tested;
                        counters.occluded += c.occluded;
                        counters.early += c.early;
                        counters.late += c.late;
                        frames += 1;
                        let d = differing_pixels(&with.images, &without);
                        if fade == FadeMode::Alpha {
                            alpha_pixels += d;
                        } else {
                            max_dithered = max_dithered.max(d);
                            if d > budget {
                                failures.push(format!(
                                    "{name}: {d} pixels differ from the frame without occlusion \
                                 culling (budget {budget})"
                                ));
                            }
                        }
                        let reference = prepared
                            .render_with_history(camera, &on, &history)
                            .expect("reference frame");
                        let ref_occ = reference.occlusion.as_ref().expect("occlusion");
                        if c != ref_occ.counters {
                            failures.push(format!(
                                "{name}: GPU counters {c:?}, reference {:?}",
                                ref_occ.counters
                            ));
                        }
                        // The reference's frame with culling equals its frame without
                        // (`properties/occlusion_properties.rs`), so the alternatives of the latter
                        // classify the GPU's near-threshold pixels as for any frame.
                        let alternatives = alpha_test_alternatives(&prepared, camera, &off);
                        let want = images_of(&reference.drawn.target);
                        if let Some(f) =
                            judge_image(&name, &with.images, &want, &alternatives, camera, &mut max)
                        {
                            // The same judge of the frames without culling: a failure there too is
                            // the draw's (this view is denser than `parity::draw`'s), not culling's.
                            let plain = prepared.render(camera, &off).expect("reference frame");
                            let mut ignored = MaxDiffs::default();
                            let plain_judged = judge_image(
                                &format!("{name} without culling"),
                                &without,
                                &images_of(&plain.drawn.target),
                                &alternatives,
                                camera,
                                &mut ignored,
                            );
                            match plain_judged {
                                Some(_) => draw_failures.push(f),
                                None => failures.push(f),
                            }
                        }
                        history = ref_occ.visible.clone();
                    }
                }
            }
        }
    }
    print_max_diffs("GPU occlusion frames against the reference's", &max);
    println!(
        "{} frames fail the judge against the reference as their frames without culling do (the \
         draw stage's, not culling's):",
        draw_failures.len()
    );
    for f in &draw_failures {
        println!("  {f}");
    }
    println!(
        "{frames} frames: {} trees tested, {} occluded, {} early, {} late; at most {max_dithered} \
         pixels differ from the frame without culling in a dithered mode (budget \
         {DEPTH_TIE_BUDGET}), {alpha_pixels} pixels under alpha in all",
        counters.tested, counters.occluded, counters.early, counters.late
    );
    assert!(
        counters.occluded > 0,
        "no tree was occluded: the frames test nothing"
    );
    assert_no_failures("occlusion frames", &failures);
}

/// Vegetation with occlusion culling on the GPU (issue 31: the modern per-tree peer, the same
/// stage over `cull.wgsl`'s commands with its own history): its frames equal Vegetation's
/// without culling (`exact`: no pixel; `reorder`: [`DEPTH_TIE_BUDGET`]), and its counters equal
/// the reference's `render_vegetation_with_history`, along a three-frame `two-phase` path and
/// under `single`.
#[test]
fn vegetation_with_occlusion_culling_equals_vegetation_without() {
    use forestlod_reference::baselines::{render_vegetation_with_history, tree_spheres};
    let Some(ctx) = gpu_context() else { return };
    let scene = cropped_synthetic(300.0);
    let base = occlusion_params(FadeMode::DitherSequential);
    let prepared = prepare(scene.clone(), &base).expect("prepare");
    let spheres = tree_spheres(&prepared.scene, &prepared.geometry.meshes);
    let mut gpu = GpuScene::new(
        ctx,
        &prepared,
        &base,
        StagesFromCpu::parse("textures").unwrap(),
    )
    .expect("GPU scene");
    let (mut failures, mut counters, mut max_pixels) =
        (Vec::new(), OcclusionCounters::default(), 0usize);
    for order in [OcclusionOrder::Exact, OcclusionOrder::Reorder] {
        let budget = match order {
            OcclusionOrder::Exact => 0,
            OcclusionOrder::Reorder => DEPTH_TIE_BUDGET,
        };
        for mode in [Occlusion::Single, Occlusion::TwoPhase] {
            let on = Params {
                occlusion: mode as u32,
                occlusion_order: order as u32,
                ..base
            };
            gpu.reset_history();
            let mut history: Vec<u32> = Vec::new();
            for (k, camera) in path(&scene, (120.0, 25.0), (96, 72), 3).iter().enumerate() {
                let name = format!("vegetation/{}/{}/frame {k}", mode.name(), order.name());
                let without = gpu
                    .render(&prepared, GpuPipeline::Vegetation, camera, &base)
                    .expect("off")
                    .images;
                let with = gpu
                    .render(&prepared, GpuPipeline::Vegetation, camera, &on)
                    .expect("on");
                let c = with.occlusion.expect("counters");
                let d = differing_pixels(&with.images, &without);
                max_pixels = max_pixels.max(d);
                if d > budget {
                    failures.push(format!(
                        "{name}: {d} pixels differ from Vegetation without culling (budget {budget})"
                    ));
                }
                let reference =
                    render_vegetation_with_history(&prepared, &spheres, camera, &on, &history);
                let occ = reference.occlusion.as_ref().expect("occlusion ran");
                if c != occ.counters {
                    failures.push(format!(
                        "{name}: GPU counters {c:?}, reference {:?}",
                        occ.counters
                    ));
                }
                counters.tested += c.tested;
                counters.occluded += c.occluded;
                counters.early += c.early;
                counters.late += c.late;
                history = occ.visible.clone();
            }
        }
    }
    println!(
        "vegetation: {} tested, {} occluded, {} early, {} late; at most {max_pixels} pixels differ \
         from Vegetation without culling",
        counters.tested, counters.occluded, counters.early, counters.late
    );
    assert!(
        counters.occluded > 0,
        "no tree was occluded: the frames test nothing"
    );
    assert_no_failures("Vegetation with occlusion culling", &failures);
}
