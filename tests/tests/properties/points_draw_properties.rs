//! The point LOD's draw (issue 33 item 1; `reference::draw`'s point commands under
//! `lod1 = points`, `forestlod_shared::points`'s keep test), on small forests of the five
//! built-in species prepared once (`point_count` 256, 32² billboards: fast):
//! - under `point_select = cut` every placed point of every drawn tree is represented exactly
//!   once by the frame's kept records (at every camera, transition, fade mode and detail
//!   preset), and the records the draw expands are [`DrawnFrame::points_drawn`];
//! - at a distance where every record is sub-pixel each tree draws its roots only, and each
//!   square writes at most one pixel (so the points cover at most one pixel per root; the
//!   billboards' coverage of the same trees is printed beside it);
//! - the frame (colour, depth, ids, counters) is identical on 1 and 3 threads;
//! - the interval rule's holes and doubles per frame are printed (the cut's are asserted 0).
//!
//! 64 cases each (a case draws two or three small frames; 256 would take about a minute here).

use std::sync::OnceLock;

use forestlod_reference::draw::{DrawnFrame, LOD_ID_BILLBOARD, drawn_point_records};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::points::representation_counts;
use forestlod_reference::scene::Instance;
use forestlod_reference::scene::Scene;
use forestlod_shared::points::{DetailPreset, Lod1, NO_PARENT, PointSelect};
use forestlod_shared::{Camera, FadeMode, Params};
use forestlod_tests::{scene_of, with_threads};
use proptest::prelude::*;

/// `scene_of` over the five built-in species (the card trees of `scene_of` are solid squares).
fn species_scene(trees: Vec<Instance>) -> Scene {
    Scene {
        meshes: forestlod_reference::scene::builtin::species_meshes(),
        ..scene_of(trees)
    }
}

/// Cases per property (module docs).
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 64,
        ..ProptestConfig::default()
    }
}

/// The parameters the forests are prepared with: points, cut, 256 points per mesh.
fn base() -> Params {
    Params {
        lod1: Lod1::Points as u32,
        point_select: PointSelect::Cut as u32,
        point_count: 256,
        texture_size: 32,
        ..Params::default()
    }
}

/// 60 trees of every species in a 120 m square east of the origin, scales 0.5..2, prepared once.
fn forest() -> &'static Prepared {
    static P: OnceLock<Prepared> = OnceLock::new();
    P.get_or_init(|| {
        let trees = (0..60u32)
            .map(|i| {
                let h = |k: u32| {
                    forestlod_shared::points::point_hash(i, k, 33, 1) as f32 / u32::MAX as f32
                };
                Instance {
                    position: [40.0 + 120.0 * h(1), 120.0 * h(2) - 60.0, 0.0],
                    yaw: std::f32::consts::TAU * h(3),
                    scale: 0.5 + 1.5 * h(4),
                    mesh: i % 5,
                }
            })
            .collect();
        prepare(species_scene(trees), &base()).expect("a valid forest")
    })
}

/// A camera west of the forest looking roughly east, 2..60 m up, 24..120 x 16..90 pixels.
fn cameras() -> impl Strategy<Value = Camera> {
    (
        -80.0f32..30.0,
        -40.0f32..40.0,
        2.0f32..60.0,
        -30.0f32..30.0,
        -20.0f32..5.0,
        24u32..120,
        16u32..90,
    )
        .prop_map(|(x, y, z, yaw, pitch, w, h)| {
            let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
            let f = [
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            ];
            Camera::look_at([x, y, z], [x + f[0], y + f[1], z + f[2]], 60.0, w, h)
        })
}

/// Frame parameters: every fade mode and detail preset, transition 0..150 m, fade 0..60 m.
fn frame_params(select: PointSelect) -> impl Strategy<Value = Params> {
    (
        0usize..FadeMode::ALL.len(),
        0usize..DetailPreset::ALL.len(),
        0.0f32..150.0,
        0.0f32..60.0,
    )
        .prop_map(move |(f, d, t, w)| Params {
            fade_mode: FadeMode::ALL[f] as u32,
            point_detail: DetailPreset::ALL[d] as u32,
            point_select: select as u32,
            lod1_transition: t,
            fade_width: w.min(t),
            ..base()
        })
}

/// Colour, depth bits, ids, and the fragments, discarded trees and points counters of a frame.
type Fingerprint = (Vec<[u8; 4]>, Vec<u32>, Vec<u32>, u64, u64, u64);

/// Every buffer and counter of a drawn frame, for bitwise comparison.
fn fingerprint(d: &DrawnFrame) -> Fingerprint {
    (
        d.target.color().to_vec(),
        d.target.depth().iter().map(|x| x.to_bits()).collect(),
        d.target.aux().to_vec(),
        d.tree_stats.fragments_written,
        d.trees_discarded,
        d.points_drawn,
    )
}

proptest! {
    #![proptest_config(config())]

    /// Cut mode: each placed point of each drawn tree is represented exactly once in the frame's
    /// kept records, and the draw expanded exactly those records.
    #[test]
    fn cut_draws_every_placed_point_once(camera in cameras(), p in frame_params(PointSelect::Cut)) {
        let prepared = forest();
        let frame = prepared.render(&camera, &p).unwrap();
        let res = prepared.resources();
        let records = drawn_point_records(&res, &frame.selection, &camera, &p);
        let sets = &prepared.points.as_ref().unwrap().sets;
        let mut total = 0u64;
        for (tree, kept) in &records {
            let set = &sets[prepared.scene.instances[*tree as usize].mesh as usize];
            let counts = representation_counts(set, kept);
            let bad = counts.iter().filter(|&&c| c != 1).count();
            prop_assert_eq!(bad, 0, "tree {}: {} placed points not represented once", tree, bad);
            total += kept.len() as u64;
        }
        prop_assert_eq!(total, frame.drawn.points_drawn);
    }

    /// The frame is the same on 1 and 3 threads (both selection rules).
    #[test]
    fn point_frames_are_thread_count_independent(camera in cameras(), p in frame_params(PointSelect::Cut), interval in any::<bool>()) {
        let p = if interval { Params { point_select: PointSelect::Interval as u32, ..p } } else { p };
        let prepared = forest();
        let one = with_threads(1, || prepared.render(&camera, &p).unwrap());
        let three = with_threads(3, || prepared.render(&camera, &p).unwrap());
        prop_assert!(fingerprint(&one.drawn) == fingerprint(&three.drawn), "frames differ between 1 and 3 threads");
    }
}

/// The interval rule's holes and doubles in a frame (slip (c), reported, not asserted: the
/// seed's rule is not a cut), beside the cut's (none), for the forest at one camera per
/// detail preset.
#[test]
fn interval_frames_report_holes_and_doubles() {
    use forestlod_reference::points::holes_and_doubles;
    let prepared = forest();
    let camera = Camera::look_at([-20.0, 0.0, 20.0], [100.0, 0.0, 0.0], 60.0, 96, 54);
    let sets = &prepared.points.as_ref().unwrap().sets;
    for detail in DetailPreset::ALL {
        let mut line = format!("{}:", detail.name());
        for select in PointSelect::ALL {
            let p = Params {
                point_select: select as u32,
                point_detail: detail as u32,
                lod1_transition: 0.0,
                fade_width: 0.0,
                ..base()
            };
            let frame = prepared.render(&camera, &p).unwrap();
            let records = drawn_point_records(&prepared.resources(), &frame.selection, &camera, &p);
            let (mut holes, mut doubles, mut placed) = (0, 0, 0);
            for (tree, kept) in &records {
                let set = &sets[prepared.scene.instances[*tree as usize].mesh as usize];
                let (h, d) = holes_and_doubles(set, kept);
                holes += h;
                doubles += d;
                placed += set.placed().count();
            }
            if select == PointSelect::Cut {
                assert_eq!(
                    (holes, doubles),
                    (0, 0),
                    "the cut has no hole and no double"
                );
            }
            line += &format!(
                " {} {} trees, {} points drawn, holes {holes} doubles {doubles} of {placed} placed;",
                select.name(),
                records.len(),
                frame.drawn.points_drawn
            );
        }
        println!("{line}");
    }
}

/// At a distance where every record of every tree is sub-pixel (each tree's root covers 0.7 px²
/// at its centre's depth), cut mode draws each tree's roots only and every square writes at
/// most one pixel: the points cover at most as many pixels as roots drawn, and (the sanity
/// check) no more than the billboards of the same trees (printed beside it). Deterministic (one forest: a prepare per case would be
/// slow): 40 trees spread across the view, each at its own depth.
#[test]
fn sub_pixel_points_cover_at_most_a_pixel_each() {
    let params = Params {
        lod1_transition: 10.0,
        fade_width: 0.0,
        ..base()
    };
    let camera = Camera::look_at([0.0, 0.0, 2.0], [1.0, 0.0, 2.0], 60.0, 320, 180);
    let c = forestlod_shared::metric::metric_constant(&camera, false);
    // Each species' root area (one cell: one root), from a prepare of the species alone.
    let sets = forestlod_reference::points::build_points(
        &forestlod_reference::scene::builtin::species_meshes(),
        &forestlod_shared::points::PointParams::from_params(&params),
    )
    .expect("valid point parameters");
    let root = |m: usize| {
        let set = &sets[m];
        set.records
            .iter()
            .filter(|r| r.parent == NO_PARENT)
            .map(|r| r.area)
            .fold(0.0f32, f32::max)
    };
    let trees: Vec<Instance> = (0..40u32)
        .map(|i| {
            let mesh = i % 5;
            let scale = 0.6 + 0.02 * i as f32;
            let d = scale as f64 * (root(mesh as usize) as f64 * c / 0.7).sqrt();
            let lateral = (i as f32 / 39.0 - 0.5) * 0.9 * d as f32;
            Instance {
                position: [d as f32, lateral, 0.0],
                yaw: i as f32,
                scale,
                mesh,
            }
        })
        .collect();
    let prepared = prepare(species_scene(trees), &params).expect("a valid forest");
    let frame = prepared.render(&camera, &params).unwrap();
    let res = prepared.resources();
    let records = drawn_point_records(&res, &frame.selection, &camera, &params);
    let sets = &prepared.points.as_ref().unwrap().sets;
    for (tree, kept) in &records {
        let set = &sets[prepared.scene.instances[*tree as usize].mesh as usize];
        assert!(
            kept.iter()
                .all(|&i| set.records[i as usize].parent == NO_PARENT),
            "tree {tree} draws a non-root"
        );
    }
    let pixels = |d: &DrawnFrame| {
        d.target
            .aux()
            .iter()
            .filter(|&&id| id == LOD_ID_BILLBOARD)
            .count() as u64
    };
    let billboards = prepared
        .render(
            &camera,
            &Params {
                lod1: Lod1::Billboard as u32,
                ..params
            },
        )
        .unwrap();
    println!(
        "sub-pixel points: {} trees, {} points drawn, {} fragments written, {} pixels; billboards {} pixels",
        records.len(),
        frame.drawn.points_drawn,
        frame.drawn.tree_stats.fragments_written,
        pixels(&frame.drawn),
        pixels(&billboards.drawn),
    );
    assert!(
        records.len() >= 30,
        "most trees are drawn ({})",
        records.len()
    );
    assert!(frame.drawn.tree_stats.fragments_written <= frame.drawn.points_drawn);
    assert!(
        pixels(&frame.drawn) <= pixels(&billboards.drawn),
        "sub-pixel points cover more than the billboards"
    );
}

/// Not a property: points drawn and draw time of the default scene (`synthetic`) at the
/// `medium` camera, 1280x720, points (cut, normal, 1024 per mesh) against billboards, on the
/// reference. `cargo test --release -p forestlod-tests --test properties -- --ignored
/// points_against_billboards --nocapture`.
#[test]
#[ignore = "a measurement on the 146,800-tree default scene (minutes in a debug build), printed: run with --ignored --nocapture"]
fn points_against_billboards_on_the_default_scene() {
    let scene = forestlod_reference::scene::builtin::synthetic();
    for lod1 in [Lod1::Billboard, Lod1::Points] {
        let params = Params {
            lod1: lod1 as u32,
            ..Params::default()
        };
        let prepared = prepare(scene.clone(), &params).expect("prepare synthetic");
        let camera =
            forestlod_reference::cameras::named_camera("medium", &prepared.scene, 0.0, 1280, 720)
                .expect("the medium camera");
        let frame = prepared.render(&camera, &params).unwrap();
        println!(
            "{}: prepare points {:.2} s; select {:.3} s, draw {:.3} s; {} points, {} triangles, {} fragments written",
            lod1.name(),
            prepared.timings.points,
            frame.timings.select,
            frame.timings.draw,
            frame.drawn.points_drawn,
            frame.drawn.tree_stats.triangles_in,
            frame.drawn.tree_stats.fragments_written,
        );
    }
}
