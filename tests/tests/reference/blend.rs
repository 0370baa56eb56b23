//! Issue 30's blend (G§4, `forestlod_reference::blend`) on whole frames of the reference, per
//! tree: every fragment of every tree of a frame with its fade decision
//! ([`probe_fragments`]: the draw stage's own vertex stage and fragment rule, no depth test),
//! on `tiny` seen along +y exactly from its south edge with a wide band (many trees in it).
//!
//! - under `fade_granularity = tree` every fragment of a tree, in both LODs, reads one `t`;
//! - under `tree`, a pixel that both LODs of a tree cover (alpha-tested) keeps one of them, in
//!   every threshold space (the frame-level form of `shared::fade`'s
//!   `dither_sequential_covers_every_pixel`; under `fragment` the two LODs' fragments have two
//!   depths and may straddle mid-band, which is counted and printed);
//! - the kept fraction of a tree's distinct noise texels (texture space) or pixels (screen space)
//!   in a LOD is that LOD's cover at the tree's `t` within binomial sampling error;
//! - translating the camera parallel to the image plane by whole pixels (at the band's middle
//!   depth; every tree's centre depth unchanged, exactly) keeps each tree's kept texel set under
//!   `texture` + `tree`, and does not under `screen` (the point of G§4's texture-space noise).

use std::collections::{BTreeMap, BTreeSet};

use forestlod_reference::blend::{ProbedFragment, probe_fragments};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_reference::scene::tree_sphere;
use forestlod_shared::{
    Camera, DitherSpace, FadeGranularity, FadeMode, Params, fade_progress, view_interval,
};
use forestlod_tests::scenarios::with_blend;

/// Frame size of every probe (small: the probe draws each tree alone).
const WIDTH: u32 = 128;
/// See [`WIDTH`].
const HEIGHT: u32 = 96;
/// Vertical field of view, degrees.
const FOV_Y: f32 = 60.0;
/// The band: `[START, START + WIDTH_M]` metres of view depth, most of `tiny`'s depth from the
/// eye 30 m south of its edge.
const BAND_START_M: f32 = 40.0;
/// See [`BAND_START_M`].
const BAND_WIDTH_M: f32 = 120.0;

/// `tiny`'s parameters with the wide band and the dithered sequential fade.
fn base() -> Params {
    Params {
        grid_size: 50.0,
        angle_count: 8,
        texture_size: 32,
        lod1_transition: BAND_START_M + BAND_WIDTH_M,
        fade_width: BAND_WIDTH_M,
        fade_mode: FadeMode::DitherSequential as u32,
        ..Params::default()
    }
}

/// The camera 30 m south of `tiny`'s south edge, 12 m above the ground, looking along +y exactly
/// (so a translation along x leaves every view depth unchanged bit for bit), moved `dx` metres
/// along x.
fn camera(p: &Prepared, dx: f32) -> Camera {
    let [x0, y0, x1, _] = p.scene.bounds;
    let (x, y) = ((x0 + x1) * 0.5 + dx, y0 - 30.0);
    let eye = [x, y, p.scene.terrain.height(x, y) + 12.0];
    let c = Camera::look_at(eye, [eye[0], eye[1] + 100.0, eye[2]], FOV_Y, WIDTH, HEIGHT);
    assert_eq!(
        c.basis().forward.to_array(),
        [0.0, 1.0, 0.0],
        "forward is +y exactly"
    );
    c
}

/// One pixel's width in metres at the band's middle depth: the translation of a whole pixel there.
fn pixel_at_mid_band() -> f32 {
    let d = BAND_START_M + 0.5 * BAND_WIDTH_M;
    2.0 * d * (0.5 * FOV_Y.to_radians()).tan() / HEIGHT as f32
}

/// Every fragment of `p`'s frame from `camera` under `params`.
fn probe(p: &Prepared, camera: &Camera, params: &Params) -> Vec<ProbedFragment> {
    params.validate().expect("valid");
    let selection = p.select(camera, params);
    probe_fragments(&p.resources(), &selection, camera, params)
}

/// The fragments a fade decides inside the band: fading, alpha-kept, `0 < t < 1`.
fn in_band(fragments: &[ProbedFragment]) -> impl Iterator<Item = &ProbedFragment> {
    fragments
        .iter()
        .filter(|f| f.alpha_kept && f.fade.is_some_and(|d| d.in_band()))
}

/// The cover of `lod` at progress `t` under `dither-sequential` (G§4 Fig. 5).
fn cover(lod: u32, t: f32) -> f32 {
    if lod == 0 {
        (2.0 - 2.0 * t).min(1.0)
    } else {
        (2.0 * t).min(1.0)
    }
}

fn prepared() -> Prepared {
    prepare(builtin::tiny(), &base()).expect("prepare tiny")
}

#[test]
fn under_tree_granularity_every_fragment_of_a_tree_reads_one_t() {
    let p = prepared();
    let camera = camera(&p, 0.0);
    for space in DitherSpace::ALL {
        for granularity in FadeGranularity::ALL {
            let params = with_blend(base(), space, granularity);
            let fragments = probe(&p, &camera, &params);
            let mut ts: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
            for f in &fragments {
                if let Some(d) = f.fade {
                    ts.entry(f.tree).or_default().insert(d.t.to_bits());
                }
            }
            let trees = ts.len();
            let split = ts.values().filter(|t| t.len() > 1).count();
            println!(
                "{} {}: {trees} fading trees, {split} with more than one t",
                space.name(),
                granularity.name()
            );
            assert!(trees > 50, "the frame must show the band: {trees} trees");
            match granularity {
                FadeGranularity::Tree => {
                    assert_eq!(split, 0, "a tree read two values of t");
                    // And it is the tree's centre's progress through the band (the distance
                    // metric: every tree's band is the frame's).
                    let metas = p.scene.mesh_metas();
                    for (&tree, t) in &ts {
                        let instance = &p.scene.instances[tree as usize];
                        let (centre, _) = tree_sphere(instance, &metas[instance.mesh as usize]);
                        let d = view_interval(
                            centre,
                            0.0,
                            camera.eye,
                            camera.basis().forward.to_array(),
                        )
                        .d;
                        let want = fade_progress(d, params.fade_start(), params.lod1_transition);
                        assert_eq!(
                            t.iter().next().copied(),
                            Some(want.to_bits()),
                            "tree {tree}: t is not its centre's progress {want}"
                        );
                    }
                }
                // The test has teeth: per fragment, t follows the depth.
                FadeGranularity::Fragment => assert!(split > trees / 2, "{split} of {trees}"),
            }
        }
    }
}

#[test]
fn under_tree_granularity_a_pixel_both_lods_cover_keeps_one() {
    let p = prepared();
    let camera = camera(&p, 0.0);
    for space in DitherSpace::ALL {
        for granularity in FadeGranularity::ALL {
            let params = with_blend(base(), space, granularity);
            let fragments = probe(&p, &camera, &params);
            // Per (tree, pixel): whether LOD0 / LOD1 has an alpha-kept fading fragment there,
            // and whether one of them is kept by the fade.
            let mut at: BTreeMap<(u32, [u32; 2]), [bool; 3]> = BTreeMap::new();
            for f in fragments
                .iter()
                .filter(|f| f.alpha_kept && f.fade.is_some())
            {
                let e = at.entry((f.tree, f.pixel)).or_default();
                e[f.lod as usize] = true;
                e[2] |= f.kept();
            }
            let both = at.values().filter(|e| e[0] && e[1]).count();
            let lost = at.values().filter(|e| e[0] && e[1] && !e[2]).count();
            println!(
                "{} {}: {both} tree pixels covered by both LODs, {lost} lost",
                space.name(),
                granularity.name()
            );
            assert!(both > 500, "the test needs pixels both LODs cover: {both}");
            if granularity == FadeGranularity::Tree {
                assert_eq!(lost, 0, "{} tree: pixels lost both LODs", space.name());
            }
        }
    }
}

/// Largest deviation of a tree's kept fraction from its cover, in binomial standard deviations
/// (`σ = √(c(1-c)/N)`), beyond one sample: 5σ is passed by chance by one group in about 1.7
/// million, and the frame has some hundreds of groups.
const KEPT_FRACTION_SIGMAS: f32 = 5.0;

/// A (tree, LOD) group: the tree's `t` and each distinct sample's kept status.
type Group = (f32, BTreeMap<[u32; 3], bool>);

/// A (tree, LOD, noise texel `[level, i, j]`) key.
type TexelKey = (u32, u32, [u32; 3]);

/// Least samples (distinct texels or pixels) of a (tree, LOD) group to be judged.
const MIN_GROUP: usize = 30;

#[test]
fn each_trees_kept_fraction_is_its_cover() {
    let p = prepared();
    let camera = camera(&p, 0.0);
    for space in DitherSpace::ALL {
        let params = with_blend(base(), space, FadeGranularity::Tree);
        let fragments = probe(&p, &camera, &params);
        // Per (tree, LOD): the tree's t and each distinct sample's kept status (texture: the
        // noise texel; screen: the pixel).
        let mut groups: BTreeMap<(u32, u32), Group> = BTreeMap::new();
        for f in in_band(&fragments) {
            let d = f.fade.expect("in band");
            let key = match space {
                DitherSpace::Texture => d.texel,
                DitherSpace::Screen => [u32::MAX, f.pixel[0], f.pixel[1]],
            };
            let g = groups
                .entry((f.tree, f.lod))
                .or_insert((d.t, BTreeMap::new()));
            g.1.insert(key, d.weight > 0.0);
        }
        let (mut judged, mut worst) = (0, 0.0f32);
        for (&(tree, lod), (t, samples)) in &groups {
            let c = cover(lod, *t);
            let n = samples.len();
            if n < MIN_GROUP || c >= 1.0 {
                continue;
            }
            let kept = samples.values().filter(|&&k| k).count() as f32 / n as f32;
            let sigma = (c * (1.0 - c) / n as f32).sqrt();
            let z = ((kept - c).abs() - 1.0 / n as f32).max(0.0) / sigma.max(1e-6);
            worst = worst.max(z);
            judged += 1;
            assert!(
                z <= KEPT_FRACTION_SIGMAS,
                "{}: tree {tree} LOD{lod} keeps {kept} of {n} samples at cover {c} (t {t}): {z:.1} σ",
                space.name()
            );
        }
        println!(
            "{}: {judged} (tree, LOD) groups judged, largest deviation {worst:.2} σ",
            space.name()
        );
        assert!(judged >= 20, "{} groups only", judged);
    }
}

/// Shared (tree, LOD, noise texel) keys with a cover strictly between 0 and 1, and how many of
/// them were kept in one fragment and discarded in another, over `frames`.
fn texel_conflicts(frames: &[Vec<ProbedFragment>]) -> (usize, usize) {
    let mut status: BTreeMap<TexelKey, (bool, bool, usize)> = BTreeMap::new();
    for (k, fragments) in frames.iter().enumerate() {
        for f in in_band(fragments) {
            let d = f.fade.expect("in band");
            if cover(f.lod, d.t) >= 1.0 {
                continue;
            }
            let e = status
                .entry((f.tree, f.lod, d.texel))
                .or_insert((false, false, 0));
            if d.weight > 0.0 {
                e.0 = true;
            } else {
                e.1 = true;
            }
            e.2 |= 1 << k;
        }
    }
    let shared: Vec<_> = status
        .values()
        .filter(|e| e.2 == (1 << frames.len()) - 1)
        .collect();
    let conflicts = shared.iter().filter(|e| e.0 && e.1).count();
    (shared.len(), conflicts)
}

#[test]
fn translating_the_camera_keeps_each_trees_kept_texels_in_texture_space() {
    let p = prepared();
    let px = pixel_at_mid_band();
    for (space, granularity) in [
        (DitherSpace::Texture, FadeGranularity::Tree),
        (DitherSpace::Screen, FadeGranularity::Tree),
        (DitherSpace::Texture, FadeGranularity::Fragment),
    ] {
        let params = with_blend(base(), space, granularity);
        let frames: Vec<Vec<ProbedFragment>> = [0.0, 3.0 * px, -8.0 * px]
            .iter()
            .map(|&dx| probe(&p, &camera(&p, dx), &params))
            .collect();
        let (shared, conflicts) = texel_conflicts(&frames);
        println!(
            "{} {}: {shared} (tree, LOD, texel) keys in all three frames, {conflicts} kept in one \
             fragment and dropped in another",
            space.name(),
            granularity.name()
        );
        assert!(shared > 1000, "the frames must share texels: {shared}");
        match (space, granularity) {
            (DitherSpace::Texture, FadeGranularity::Tree) => assert_eq!(conflicts, 0),
            // Screen space re-draws the threshold per pixel: the pattern stays on the screen
            // while the tree slides under it (G§4's point; a shower-door crawl).
            (DitherSpace::Screen, _) => assert!(
                conflicts * 10 > shared,
                "screen space keeps {conflicts} of {shared} conflicts only"
            ),
            // Per fragment, a texel's fragments lie at several depths: few conflicts, not none
            // necessarily (printed, not asserted).
            _ => {}
        }
    }
}
