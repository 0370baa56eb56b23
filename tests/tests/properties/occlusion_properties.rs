//! Properties of occlusion culling (issue 31; `shared/src/occlusion.rs`,
//! `reference/src/{pyramid,occlude}.rs`). Each random property runs 256 cases: small forests seen
//! from near the ground (where trees hide each other), every fade mode, hierarchy, `refine` mode
//! and command order, odd and non-power-of-two frame sizes.
//!
//! - No false cull, against the oracle ([`Prepared::false_cull_pixels`]: the culled trees drawn
//!   alone have no fragment at or in front of the frame's depth). Over-draw (trees drawn with no
//!   visible fragment) is reported by `occlusion_overdraw_is_reported`.
//! - Frames bit-identical to the frame without occlusion culling in the dithered modes (and
//!   `none`); under `alpha` every differing pixel is a fade-band pixel (counted).
//! - Two-phase along a path equals the frame without culling at every frame.
//! - The pyramid is conservative at every size from 1x1 to 1920x1080; niagara's level rule is not.

use forestlod_reference::occlude::{occlude_early, occlude_late};
use forestlod_reference::pipeline::{Frame, Prepared, prepare};
use forestlod_reference::pyramid::Pyramid;
use forestlod_reference::scene::{Instance, Scene};
use forestlod_shared::{
    Camera, CommandOrder, FadeMode, Hierarchy, LOD_ID_TRANSITION, Occlusion, OcclusionOrder,
    OcclusionRect, Params, TreeCull, pyramid_level_floor, pyramid_level_for,
};
use forestlod_tests::{property_config, scene_of, with_threads};
use proptest::prelude::*;

/// A forest of 20..250 trees in a square of half-side 15..200 m on flat ground.
fn forest() -> impl Strategy<Value = Vec<Instance>> {
    (15.0f32..200.0).prop_flat_map(|s| {
        prop::collection::vec(
            (
                -s..s,
                -s..s,
                -1.0f32..1.0,
                0.0f32..6.3,
                0.5f32..2.0,
                0u32..3,
            )
                .prop_map(|(x, y, z, yaw, scale, mesh)| Instance {
                    position: [x, y, z],
                    yaw,
                    scale,
                    mesh,
                }),
            20..250,
        )
    })
}

/// A camera near the ground west of the forest, looking roughly east: 1..40 m up, 0..120 m out,
/// yaw -40°..40°, pitch -25°..5°, field of view 30°..90°, 16..200 x 16..150 pixels (odd sizes
/// included).
fn ground_cameras() -> impl Strategy<Value = Camera> {
    (
        -250.0f32..-20.0,
        -60.0f32..60.0,
        1.0f32..40.0,
        -40.0f32..40.0,
        -25.0f32..5.0,
        30.0f32..90.0,
        16u32..200,
        16u32..150,
    )
        .prop_map(|(x, y, z, yaw, pitch, fov, w, h)| {
            let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
            let f = [
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            ];
            let mut c = Camera::look_at([x, y, z], [x + f[0], y + f[1], z + f[2]], fov, w, h);
            c.forward = f;
            c
        })
}

/// Parameters: every fade mode, hierarchy, `refine` mode and command order; transition 0..300 m,
/// fade 0..150 m, occluder depth 0..300 m, grid 10..200 m; small billboards (fast bakes).
fn occlusion_params() -> impl Strategy<Value = Params> {
    (
        0usize..FadeMode::ALL.len(),
        0usize..Hierarchy::ALL.len(),
        0usize..TreeCull::ALL.len(),
        0usize..CommandOrder::ALL.len(),
        0.0f32..300.0,
        0.0f32..150.0,
        0.0f32..300.0,
        10.0f32..200.0,
    )
        .prop_map(|(f, h, c, o, t, w, d, g)| Params {
            fade_mode: FadeMode::ALL[f] as u32,
            hierarchy: Hierarchy::ALL[h] as u32,
            tree_cull: TreeCull::ALL[c] as u32,
            command_order: CommandOrder::ALL[o] as u32,
            lod1_transition: t,
            fade_width: w,
            occluder_depth: d,
            grid_size: g,
            texture_size: 32,
            ..Params::default()
        })
}

fn prepared(trees: Vec<Instance>, p: &Params) -> Prepared {
    let scene: Scene = scene_of(trees);
    prepare(scene, p).expect("valid case")
}

/// Pixels where two frames differ (colour, depth bits or id), those of them where the depths are
/// equal (a tie between two fragments that the draw order settles), and those that are neither a
/// tie nor a fade-band pixel in either frame.
fn differences(a: &Frame, b: &Frame) -> (usize, usize, usize) {
    let (a, b) = (&a.drawn.target, &b.drawn.target);
    let (mut diff, mut ties, mut unclassified) = (0, 0, 0);
    for i in 0..a.color().len() {
        let same_depth = a.depth()[i].to_bits() == b.depth()[i].to_bits();
        let same = a.color()[i] == b.color()[i] && same_depth && a.aux()[i] == b.aux()[i];
        if !same {
            diff += 1;
            if same_depth {
                ties += 1;
            } else if a.aux()[i] != LOD_ID_TRANSITION && b.aux()[i] != LOD_ID_TRANSITION {
                unclassified += 1;
            }
        }
    }
    (diff, ties, unclassified)
}

proptest! {
    #![proptest_config(property_config())]

    /// Zero false culls, and frames equal to the frame without occlusion culling: under `exact`
    /// bit-identical outside `alpha`; under `reorder` differing only where two fragments tie in
    /// depth; under `alpha` differing only at fade-band pixels (and ties). Mutation-checked (see
    /// the issue 31 note): reading only the rectangle's top-left texel, culling at
    /// `z_min >= max`, and letting a fading command occlude under `alpha` each fail it.
    #[test]
    fn no_false_culls_and_frames_unchanged(trees in forest(), camera in ground_cameras(), p in occlusion_params(), two in any::<bool>(), reorder in any::<bool>()) {
        let prepared = prepared(trees, &p);
        let off = prepared.render(&camera, &p).unwrap();
        let mode = if two { Occlusion::TwoPhase } else { Occlusion::Single };
        let order = if reorder { OcclusionOrder::Reorder } else { OcclusionOrder::Exact };
        let q = Params { occlusion: mode as u32, occlusion_order: order as u32, ..p };
        // Two-phase's history: two trees in three of the frame without culling's.
        let history: Vec<u32> = if two {
            let mut h = vec![0u32; prepared.footprints.len()];
            let ind = off.indirection(&prepared);
            for c in &off.selection.commands {
                for &t in &ind[c.first_instance as usize..(c.first_instance + c.instance_count) as usize] {
                    h[t as usize] = (t % 3 != 0) as u32;
                }
            }
            h
        } else {
            Vec::new()
        };
        let on = prepared.render_with_history(&camera, &q, &history).unwrap();
        let false_culls = prepared.false_cull_pixels(&camera, &q, &on);
        prop_assert_eq!(false_culls, 0, "pixels of culled trees at or in front of the frame");
        let (diff, ties, unclassified) = differences(&off, &on);
        if p.fade_mode == FadeMode::Alpha as u32 {
            prop_assert_eq!(unclassified, 0, "alpha: {} differing pixels, {} neither ties nor fade band", diff, unclassified);
        } else if reorder {
            prop_assert_eq!(diff, ties, "reorder: {} differing pixels, {} of them ties", diff, ties);
        } else {
            prop_assert_eq!(diff, 0, "the frame changed at {} pixels", diff);
        }
        let occ = on.occlusion.as_ref().unwrap();
        let c = occ.counters;
        let count = |s: &forestlod_reference::select::Selection| s.commands.iter().map(|c| c.instance_count).sum::<u32>();
        prop_assert_eq!((count(&occ.early), count(&occ.late)), (c.early, c.late));
        prop_assert!(c.occluded + c.offscreen <= c.tested);
    }

    /// Two-phase along a path of four frames (the eye moving 2..10 m a frame), each frame with
    /// the previous one's history, draws the frame without culling at every frame (dithered
    /// modes) with zero false culls. The history changes only which trees are drawn early (the
    /// cost, which the `occlusion` sweep measures), never the frame.
    #[test]
    fn two_phase_along_a_path_equals_no_culling(trees in forest(), camera in ground_cameras(), p in occlusion_params(), step in 2.0f32..10.0) {
        let p = Params { fade_mode: FadeMode::DitherSequential as u32, ..p };
        let prepared = prepared(trees, &p);
        let q = Params { occlusion: Occlusion::TwoPhase as u32, ..p };
        let mut history = Vec::new();
        for k in 0..4 {
            let mut c = camera;
            c.eye[0] += step * k as f32;
            c.eye[1] += 0.5 * step * k as f32;
            let off = prepared.render(&c, &p).unwrap();
            let on = prepared.render_with_history(&c, &q, &history).unwrap();
            prop_assert_eq!(prepared.false_cull_pixels(&c, &q, &on), 0, "frame {}", k);
            prop_assert_eq!(differences(&off, &on).0, 0, "frame {} differs", k);
            history = on.occlusion.unwrap().visible;
        }
    }

    /// The early split and the late test give identical output with 1 and 2 threads.
    #[test]
    fn occlusion_is_thread_count_independent(trees in forest(), camera in ground_cameras(), p in occlusion_params()) {
        let prepared = prepared(trees, &p);
        let q = Params { occlusion: Occlusion::Single as u32, ..p };
        let frame = prepared.render(&camera, &q).unwrap();
        let pyramid = &frame.occlusion.as_ref().unwrap().pyramid;
        let ind = frame.indirection(&prepared);
        let run = || {
            let (early, mut out) = occlude_early(&frame.selection, ind, &prepared.footprints, &camera, &q, &[]);
            let late = occlude_late(&frame.selection, ind, &prepared.footprints, &camera, &q, &[], pyramid, &mut out);
            (early, late, out)
        };
        prop_assert_eq!(with_threads(1, run), with_threads(2, run));
    }

    /// The pyramid is conservative: at the chosen level, the texels under a random rectangle hold
    /// at least the largest depth under it, at random sizes from 1x1 to 1920x1080. Mutation-
    /// checked: reducing with `min` or picking one level coarser than needed without reading the
    /// third texel fails at once.
    #[test]
    fn pyramid_is_conservative(w in 1u32..=1920, h in 1u32..=1080, seed in any::<u64>(), rects in prop::collection::vec((0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0), 16)) {
        let depth = random_depth(w, h, seed);
        let pyramid = Pyramid::build(&depth, w, h);
        for (a, b, c, d) in rects {
            let r = rect_of(w, h, a, b, c, d);
            let truth = max_under(&depth, w, &r);
            let got = pyramid.max_under(&r);
            prop_assert!(got >= truth, "{}x{} {:?}: pyramid {} < depth {}", w, h, r, got, truth);
        }
    }
}

/// Depths from a hash of the pixel and `seed`, in `[0, 1)`, with some sky (1.0).
fn random_depth(w: u32, h: u32, seed: u64) -> Vec<f32> {
    (0..w as u64 * h as u64)
        .map(|i| {
            let mut x = i.wrapping_add(seed).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            x ^= x >> 31;
            x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x ^= x >> 29;
            if x % 17 == 0 {
                1.0
            } else {
                (x >> 40) as f32 / (1u64 << 24) as f32
            }
        })
        .collect()
}

/// The rectangle with corners at fractions `(a, b)` and `(c, d)` of the frame.
fn rect_of(w: u32, h: u32, a: f64, b: f64, c: f64, d: f64) -> OcclusionRect {
    let px = |f: f64, n: u32| ((f * n as f64) as u32).min(n - 1);
    let (x0, x1) = (px(a.min(c), w), px(a.max(c), w));
    let (y0, y1) = (px(b.min(d), h), px(b.max(d), h));
    OcclusionRect {
        x0,
        y0,
        x1,
        y1,
        z_min: 0.0,
    }
}

fn max_under(depth: &[f32], w: u32, r: &OcclusionRect) -> f32 {
    let mut m = f32::MIN;
    for y in r.y0..=r.y1 {
        for x in r.x0..=r.x1 {
            m = m.max(depth[(y * w + x) as usize]);
        }
    }
    m
}

/// niagara's level rule (`floor(log2(size))`, then a 2x2 read from the rectangle's first texel)
/// is not conservative where its comment says: a rectangle 15 pixels wide starting at pixel 7
/// spans three texels of level 3, and the farthest depth under it lies in the third. Ours picks
/// level 4 there and reads it. Random rectangles on random buffers find many more.
#[test]
fn niagaras_floor_rule_misses_depth() {
    let (w, h) = (64u32, 8u32);
    let mut depth = vec![0.1f32; (w * h) as usize];
    depth[20] = 0.9; // pixel (20, 0): in texel 2 of level 3
    let pyramid = Pyramid::build(&depth, w, h);
    let r = OcclusionRect {
        x0: 7,
        y0: 0,
        x1: 21,
        y1: 0,
        z_min: 0.5,
    };
    let floor = pyramid_level_floor(&r);
    assert_eq!(floor, 3);
    let (i, j) = (r.x0 >> floor, r.y0 >> floor);
    let niagara = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
        .iter()
        .filter(|&&(a, b)| {
            let l = pyramid.levels[floor as usize];
            a < l.width && b < l.height
        })
        .map(|&(a, b)| pyramid.texel(floor, a, b))
        .fold(f32::MIN, f32::max);
    assert_eq!(niagara, 0.1, "the floor rule reads texels 0 and 1 only");
    assert!(
        r.z_min > niagara,
        "so it would cull a tree at depth 0.5 behind 0.9"
    );
    assert_eq!(pyramid_level_for(&r, pyramid.levels.len() as u32), 4);
    assert_eq!(pyramid.max_under(&r), 0.9, "ours reads the whole rectangle");
    // On buffers at 0.1 with one far pixel inside a random rectangle, the floor rule misses
    // the far pixel often; ours never.
    let mut misses = 0;
    let mut cases = 0;
    for seed in 0..500u64 {
        let (w, h) = (97 + seed as u32 % 300, 53 + (seed as u32 * 7) % 200);
        let f = |k: u64| {
            let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(k);
            x ^= x >> 29;
            x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let r = rect_of(w, h, f(1), f(2), f(3), f(4));
        let mut depth = vec![0.1f32; (w * h) as usize];
        let fx = r.x0 + ((r.x1 - r.x0 + 1) as f64 * f(5)) as u32;
        let fy = r.y0 + ((r.y1 - r.y0 + 1) as f64 * f(6)) as u32;
        depth[(fy * w + fx) as usize] = 0.9;
        let p = Pyramid::build(&depth, w, h);
        let l = pyramid_level_floor(&r).min(p.levels.len() as u32 - 1);
        let lv = p.levels[l as usize];
        let (i, j) = (r.x0 >> l, r.y0 >> l);
        let mut m = f32::MIN;
        for (a, b) in [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)] {
            if a < lv.width && b < lv.height {
                m = m.max(p.texel(l, a, b));
            }
        }
        cases += 1;
        misses += (m < 0.9) as u32;
        assert_eq!(p.max_under(&r), 0.9, "ours reads the far pixel");
    }
    println!("niagara's floor rule missed the maximum in {misses} of {cases} random rectangles");
    assert!(misses > 0);
}
