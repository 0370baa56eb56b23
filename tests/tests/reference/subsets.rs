//! Issue 29's far-field subsets (E§7, `forestlod_shared::subset`) on whole frames of the
//! reference:
//! - an infinite subset distance (the greatest accepted, 1e7 m) draws today's frame bit for bit,
//!   although the batches' trees come in their progressive order, not the grid's;
//! - nearer than the subset distance exactly the oracle's trees are drawn (the trees of the
//!   same frame without subsets), and past it only a subset of them, so the frame is not
//!   trivially equal.

use std::collections::BTreeSet;

use forestlod_harness::stage::images_of;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::draw::{DrawUniform, tree_stage};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_shared::{Camera, FadeMode, Params, SubsetMode, TreeCull, view_interval};
use forestlod_tests::differing_pixels;

fn thin(p: &Params, d_sub: f32) -> Params {
    Params {
        subset_mode: SubsetMode::Thin as u32,
        subset_distance: d_sub,
        ..*p
    }
}

/// The base frame: `tiny`'s thesis grid, small bands so that both LODs are on screen.
fn base() -> Params {
    Params {
        lod1_transition: 150.0,
        fade_width: 50.0,
        grid_size: 50.0,
        texture_size: 32,
        tree_cull: TreeCull::None as u32,
        ..Params::default()
    }
}

#[test]
fn an_infinite_subset_distance_draws_todays_frame_bit_for_bit() {
    let mut checked = 0;
    for fade in [
        FadeMode::DitherSequential,
        FadeMode::None,
        FadeMode::Dither,
        FadeMode::Alpha,
    ] {
        let off = Params {
            fade_mode: fade as u32,
            ..base()
        };
        let on = thin(&off, forestlod_shared::params::MAX_DISTANCE);
        let today = prepare(builtin::tiny(), &off).expect("prepare");
        let subset = prepare(builtin::tiny(), &on).expect("prepare");
        assert_ne!(
            today.batches.indirection, subset.batches.indirection,
            "the subset order is not the grid's: the test would be trivial"
        );
        for (name, yaw) in [("close", 0.0), ("medium", 45.0), ("far", 180.0)] {
            let camera = named_camera(name, &today.scene, yaw, 160, 90).expect("camera");
            let want = images_of(&today.render(&camera, &off).expect("render").drawn.target);
            let got = images_of(&subset.render(&camera, &on).expect("render").drawn.target);
            assert_eq!(
                differing_pixels(&want, &got),
                (0, 0, 0),
                "{name} yaw {yaw}, {}: subsets at 1e7 m differ from today (colour, depth, LOD-id pixels)",
                fade.name()
            );
            checked += 1;
        }
    }
    println!("frames equal with an infinite subset distance: {checked}");
}

/// The trees each LOD of a frame draws: `(lod, tree)` for every instance of every command that
/// the draw's vertex stage keeps.
fn drawn(prepared: &Prepared, camera: &Camera, params: &Params) -> BTreeSet<(u32, u32)> {
    let selection = prepared.select(camera, params);
    let res = prepared.resources();
    let uniform = DrawUniform::new(camera, params);
    let mut out = BTreeSet::new();
    for (k, (cmd, data)) in selection.commands.iter().zip(&selection.data).enumerate() {
        for i in cmd.first_instance..cmd.first_instance + cmd.instance_count {
            if tree_stage(&res, &selection, &uniform, k as u32, i).is_some() {
                out.insert((data.lod, prepared.batches.indirection[i as usize]));
            }
        }
    }
    out
}

#[test]
fn nearer_than_the_subset_distance_exactly_the_oracles_trees_are_drawn() {
    let off = base();
    let today = prepare(builtin::tiny(), &off).expect("prepare");
    // The order is chosen at prepare by the mode alone; the distance is a per-frame parameter.
    let subset = prepare(builtin::tiny(), &thin(&off, 0.0)).expect("prepare");
    let (mut thinned, mut frames) = (0, 0);
    for (name, yaw) in [
        ("close", 0.0),
        ("close", 180.0),
        ("medium", 0.0),
        ("far", 90.0),
    ] {
        let camera = named_camera(name, &today.scene, yaw, 160, 90).expect("camera");
        let forward = camera.basis().forward.to_array();
        let depth = |tree: u32| {
            let c = today.tree_spheres[tree as usize].0;
            view_interval(c, 0.0, camera.eye, forward).d
        };
        let want = drawn(&today, &camera, &off);
        // Subset distances at the quartiles of the drawn trees' depths: batches straddle them.
        let mut depths: Vec<f32> = want.iter().map(|&(_, t)| depth(t)).collect();
        depths.sort_by(f32::total_cmp);
        println!("{name} yaw {yaw}: {} tree LODs drawn", depths.len());
        if depths.len() < 20 {
            continue;
        }
        for q in [1, 2, 3] {
            let d_sub = depths[depths.len() * q / 4];
            let on = thin(&off, d_sub);
            let got = drawn(&subset, &camera, &on);
            let near = |s: &BTreeSet<(u32, u32)>| -> BTreeSet<(u32, u32)> {
                s.iter()
                    .copied()
                    .filter(|&(_, t)| depth(t) <= d_sub)
                    .collect()
            };
            assert_eq!(
                near(&got),
                near(&want),
                "{name} yaw {yaw}, d_sub {d_sub}: the trees nearer than the subset distance differ"
            );
            assert!(
                got.is_subset(&want),
                "{name} yaw {yaw}, d_sub {d_sub}: a tree drawn only with subsets"
            );
            thinned += want.len() - got.len();
            frames += 1;
        }
    }
    println!("trees dropped past the subset distance, over {frames} frames: {thinned}");
    assert!(
        thinned > 0 && frames >= 6,
        "{thinned} trees dropped over {frames} frames: the frames are trivially equal"
    );
}
