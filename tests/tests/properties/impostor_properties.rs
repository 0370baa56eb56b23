//! Hierarchical impostors (issue 33 item 2, C§4.6.3, Alg. 9; `reference/src/impostor_cache.rs`,
//! `forestlod_shared::impostor`), on a small forest of the five built-in species under an octree,
//! prepared once, along random camera paths (4 frames, 96x54 pixels) with random impostor
//! settings:
//! - after every step the **impostored set is an antichain**, the atlas holds at most
//!   `impostor_tiles` impostors, each node at most once, the per-node far data say exactly which
//!   nodes are impostored and how many impostored descendants each node has, and (planning every
//!   frame) every impostored node is allowed by the metric at this eye;
//! - **every tree is drawn exactly once** by the frame's commands: by a mesh and/or a billboard as
//!   the per-tree oracle asks, or inside its impostored node's image, never both, never twice;
//!   and no tree of an impostored node is drawn as a tree (its impostor stands for it);
//! - **a fresh impostor is the direct render of its node**: seen from its creation eye, its quad
//!   drawn alone covers exactly the pixels the node's trees drawn alone cover, with the same
//!   colours, bit for bit (tiles inside the frame; a tile past the frame is rendered in a grown
//!   frame, whose projection rounds differently and whose dither differs: such tiles are
//!   counted, not compared);
//! - the replay is deterministic: the same path on 1 and 3 threads gives the same atlas, quads
//!   and per-node data;
//! - the depth-order errors of a frame (pixels where the impostor frame differs from the frame
//!   without impostors) are printed for a fixed case.
//!
//! 256 cases each (about 3 s in all here).

use std::sync::OnceLock;

use forestlod_reference::draw::draw_trees_into;
use forestlod_reference::impostor_cache::{ImpostorCache, tile_selection};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::raster::{ClearValues, RenderTarget};
use forestlod_reference::select::{Selection, select_per_tree};
use forestlod_shared::impostor::impostor_allowed;
use forestlod_shared::{Camera, FarLod, Hierarchy, LOD_FAR, LOD_ID_BACKGROUND, NO_PARENT, Params};
use forestlod_tests::{species_forest, with_threads};
use proptest::prelude::*;

/// Cases per property (module docs).
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        ..ProptestConfig::default()
    }
}

/// The parameters the forest is prepared with: an octree, three levels, impostors.
fn base() -> Params {
    Params {
        hierarchy: Hierarchy::Octree as u32,
        lod_levels: 3,
        far_lod: FarLod::Impostor as u32,
        lod1_transition: 150.0,
        fade_width: 30.0,
        far_start: 150.0,
        texture_size: 32,
        grid_size: 100.0,
        ..Params::default()
    }
}

/// 400 trees of the five species on a 600 m square, prepared once.
fn forest() -> &'static Prepared {
    static P: OnceLock<Prepared> = OnceLock::new();
    P.get_or_init(|| {
        let scene = species_forest(400);
        prepare(scene, &base()).expect("a valid forest")
    })
}

/// Random impostor settings on top of [`base`].
fn impostor_params() -> impl Strategy<Value = Params> {
    (
        prop::sample::select(vec![8u32, 16, 32, 64]),
        1u32..12,
        0.0f32..400.0,
        0u32..5,
        1u32..4,
        0u32..4,
    )
        .prop_map(
            |(pixels, tiles, min_distance, depth, interval, number)| Params {
                impostor_pixels: pixels,
                impostor_tiles: tiles,
                impostor_min_distance: min_distance,
                impostor_max_depth: depth,
                impostor_update_interval: 1,
                impostor_refresh_interval: interval,
                impostor_refresh_number: number,
                ..base()
            },
        )
}

/// A path of 4 cameras: an eye 200..1500 m from the forest's centre, 5..200 m up, looking at a
/// point of the forest, then moving by up to 60 m per frame; 96x54 pixels.
fn paths() -> impl Strategy<Value = Vec<Camera>> {
    (
        0.0f32..std::f32::consts::TAU,
        200.0f32..4000.0,
        5.0f32..400.0,
        (0.0f32..600.0, 0.0f32..600.0),
        prop::collection::vec((-60.0f32..60.0, -60.0f32..60.0, -10.0f32..10.0), 3),
    )
        .prop_map(|(angle, dist, height, (tx, ty), moves)| {
            let mut eye = [
                300.0 + dist * angle.cos(),
                300.0 + dist * angle.sin(),
                height,
            ];
            let target = [tx, ty, 10.0];
            let mut path = vec![Camera::look_at(eye, target, 50.0, 96, 54)];
            for (dx, dy, dz) in moves {
                eye = [eye[0] + dx, eye[1] + dy, (eye[2] + dz).max(2.0)];
                path.push(Camera::look_at(eye, target, 50.0, 96, 54));
            }
            path
        })
}

/// The frame's trees per representation `[mesh, billboard, impostor]`, by the frame's commands
/// over the batches' indirection and each far instance's slot.
fn coverage(prepared: &Prepared, cache: &ImpostorCache, selection: &Selection) -> Vec<[u32; 3]> {
    let h = prepared.hierarchy.as_ref().expect("an octree");
    let mut covered = vec![[0u32; 3]; prepared.scene.instances.len()];
    for (c, d) in selection.commands.iter().zip(&selection.data) {
        if d.lod == LOD_FAR {
            for slot in c.first_instance..c.first_instance + c.instance_count {
                let node = cache
                    .node_in_slot(slot)
                    .expect("a far instance shows a node");
                let n = &h.nodes[node as usize];
                for &t in &h.indirection[n.offset as usize..(n.offset + n.len) as usize] {
                    covered[t as usize][2] += 1;
                }
            }
        } else {
            let range = c.first_instance as usize..(c.first_instance + c.instance_count) as usize;
            for &t in &prepared.batches.indirection[range] {
                covered[t as usize][d.lod.min(1) as usize] += 1;
            }
        }
    }
    covered
}

/// The state checks of one step (module docs), returning a failure message.
fn check_state(
    prepared: &Prepared,
    cache: &ImpostorCache,
    camera: &Camera,
    p: &Params,
) -> Result<(), String> {
    let h = prepared.hierarchy.as_ref().expect("an octree");
    let imp = cache.impostored();
    let (slots, used) = cache.occupancy();
    if slots != p.impostor_tiles as usize || used > slots || used != imp.len() {
        return Err(format!(
            "atlas {used} of {slots} tiles, {} nodes",
            imp.len()
        ));
    }
    if imp.windows(2).any(|w| w[0] == w[1]) {
        return Err(format!("a node twice in the atlas: {imp:?}"));
    }
    let is_imp = |i: u32| imp.binary_search(&i).is_ok();
    for &i in &imp {
        let mut a = h.nodes[i as usize].parent;
        while a != NO_PARENT {
            if is_imp(a) {
                return Err(format!("node {i} and its ancestor {a} both impostored"));
            }
            a = h.nodes[a as usize].parent;
        }
        let n = &h.nodes[i as usize];
        if n.depth > p.impostor_max_depth {
            return Err(format!("node {i} at depth {} impostored", n.depth));
        }
        if impostor_allowed(camera, p, n.box_center, n.extent).is_none() {
            return Err(format!("node {i} impostored but not allowed at this eye"));
        }
    }
    let level = cache.level();
    for (i, f) in level.nodes.iter().enumerate() {
        let below = imp
            .iter()
            .filter(|&&k| {
                let mut a = h.nodes[k as usize].parent;
                while a != NO_PARENT {
                    if a as usize == i {
                        return true;
                    }
                    a = h.nodes[a as usize].parent;
                }
                false
            })
            .count() as u32;
        let want = is_imp(i as u32) as u32;
        if f.cell_count != want || f.hull_count != below {
            return Err(format!(
                "node {i}: far data {f:?}, impostored {want}, {below} impostored below"
            ));
        }
        if want == 1 && cache.node_in_slot(f.cell_offset) != Some(i as u32) {
            return Err(format!(
                "node {i}'s slot {} shows another node",
                f.cell_offset
            ));
        }
    }
    Ok(())
}

/// A transparent target of `camera`'s size.
fn transparent(camera: &Camera) -> RenderTarget {
    RenderTarget::new(
        camera.width,
        camera.height,
        ClearValues {
            color: [0.0; 4],
            depth: 1.0,
            aux: LOD_ID_BACKGROUND,
        },
    )
}

/// The pixels where a fresh impostor drawn alone and its node's trees drawn alone differ
/// (coverage or colour), for every impostor the last step created or refreshed inside the frame;
/// and the number of such impostors whose tile lay past the frame (not compared).
fn fresh_mismatches(
    prepared: &Prepared,
    cache: &ImpostorCache,
    camera: &Camera,
    p: &Params,
) -> (u64, u32, u32, u8) {
    let h = prepared.hierarchy.as_ref().expect("an octree");
    let (mut bad, mut compared, mut skipped, mut worst) = (0u64, 0u32, 0u32, 0u8);
    for node in cache.impostored() {
        let n = &h.nodes[node as usize];
        let Some(tile) = impostor_allowed(camera, p, n.box_center, n.extent) else {
            continue;
        };
        if tile.margin != 0 {
            skipped += 1;
            continue;
        }
        let quad = cache.quad_of(node).expect("impostored");
        // The quad as stored is the one made at this eye only if the tile is the same.
        if quad.size != tile.quad.size {
            continue;
        }
        compared += 1;
        let slot = quad.slot;
        let command = forestlod_shared::DrawCommand {
            index_count: forestlod_shared::SPRITE_VERTICES,
            instance_count: 1,
            first_index: prepared.geometry.far.first_index,
            base_vertex: 0,
            first_instance: slot,
        };
        let data = forestlod_shared::CommandData {
            batch: node,
            lod: LOD_FAR,
            first_tree: slot,
            group_len: 1,
            ..bytemuck::Zeroable::zeroed()
        };
        let alone = Selection {
            commands: vec![command],
            data: vec![data],
            ..Selection::default()
        };
        let res = forestlod_reference::draw::DrawResources {
            far: Some(cache.level()),
            ..prepared.resources()
        };
        let mut a = transparent(camera);
        draw_trees_into(&res, &alone, camera, p, &mut a);
        let direct = tile_selection(prepared, p, camera, n.offset, n.len);
        let mut b = transparent(camera);
        draw_trees_into(&prepared.resources(), &direct, camera, p, &mut b);
        for k in 0..a.aux().len() {
            let (ca, cb) = (
                a.aux()[k] != LOD_ID_BACKGROUND,
                b.aux()[k] != LOD_ID_BACKGROUND,
            );
            let diff = (0..3)
                .map(|c| a.color()[k][c].abs_diff(b.color()[k][c]))
                .max()
                .unwrap_or(0);
            if ca && cb {
                worst = worst.max(diff);
            }
            if ca != cb || (ca && diff > 0) {
                bad += 1;
                if std::env::var("IMPOSTOR_DEBUG").is_ok() {
                    let (x, y) = (k as u32 % camera.width, k as u32 / camera.width);
                    eprintln!(
                        "node {node} px ({x},{y}) rect {:?} quad-alone {ca} {:?} direct {cb} {:?}",
                        tile.rect,
                        a.color()[k],
                        b.color()[k]
                    );
                }
            }
        }
    }
    (bad, compared, skipped, worst)
}

proptest! {
    #![proptest_config(config())]

    /// Antichain, atlas and per-node data after every step, and each tree drawn exactly once.
    #[test]
    fn impostors_form_an_antichain_and_each_tree_is_drawn_once(path in paths(), p in impostor_params()) {
        let prepared = forest();
        let mut cache = ImpostorCache::new(prepared, &p).unwrap();
        for camera in &path {
            cache.step(prepared, camera, &p).unwrap();
            if let Err(e) = check_state(prepared, &cache, camera, &p) {
                prop_assert!(false, "frame {}: {}", cache.frames() - 1, e);
            }
            let frame = prepared.render_impostors(camera, &p, &cache).unwrap();
            let covered = coverage(prepared, &cache, &frame.selection);
            // An impostored node's trees are never drawn as trees: where the node is in view its
            // impostor stands for them (the cut recurses through its ancestors).
            let h = prepared.hierarchy.as_ref().expect("an octree");
            for node in cache.impostored() {
                let n = &h.nodes[node as usize];
                for &t in &h.indirection[n.offset as usize..(n.offset + n.len) as usize] {
                    let [c0, c1, _] = covered[t as usize];
                    prop_assert!(c0 == 0 && c1 == 0, "tree {} of impostored node {} drawn as a tree: {:?}", t, node, covered[t as usize]);
                }
            }
            let oracle = select_per_tree(&prepared.tree_spheres, camera, &p);
            for (t, want) in oracle.iter().enumerate() {
                let [c0, c1, ci] = covered[t];
                prop_assert!(c0 <= 1 && c1 <= 1 && ci <= 1, "tree {} drawn {:?} times", t, covered[t]);
                if ci == 1 {
                    prop_assert!(c0 == 0 && c1 == 0, "tree {} inside an impostor and drawn: {:?}", t, covered[t]);
                } else {
                    let need = want.needs();
                    prop_assert!(!need.lod0 || c0 == 1, "tree {} needs its mesh: {:?}", t, covered[t]);
                    prop_assert!(!need.lod1 || c1 == 1, "tree {} needs its billboard: {:?}", t, covered[t]);
                }
            }
        }
    }

    /// A fresh impostor seen from its creation eye is its node's direct render (module docs).
    #[test]
    fn a_fresh_impostor_is_the_direct_render_of_its_node(path in paths(), p in impostor_params()) {
        let prepared = forest();
        let mut cache = ImpostorCache::new(prepared, &p).unwrap();
        // The first step creates every impostor at the first eye.
        cache.step(prepared, &path[0], &p).unwrap();
        let (bad, compared, _, worst) = fresh_mismatches(prepared, &cache, &path[0], &p);
        if std::env::var("IMPOSTOR_DEBUG").is_ok() {
            eprintln!("compared {}", compared.min(3));
        }
        prop_assert_eq!(bad, 0, "pixels where a fresh impostor differs from its node's render (worst colour difference {})", worst);
    }

    /// The same path on 1 and 3 threads: the same impostor state.
    #[test]
    fn replay_is_deterministic_and_thread_count_independent(path in paths(), p in impostor_params()) {
        let prepared = forest();
        let run = |threads| with_threads(threads, || {
            let mut cache = ImpostorCache::new(prepared, &p).unwrap();
            for camera in &path {
                cache.step(prepared, camera, &p).unwrap();
            }
            (cache.impostored(), cache.level().clone())
        });
        let (a, b) = (run(1), run(3));
        prop_assert_eq!(&a.0, &b.0);
        prop_assert!(a.1 == b.1, "the far level differs between 1 and 3 threads");
    }
}

/// A fixed case: how many impostors the first step makes, how many of them the fresh-image check
/// compares, and the frame's depth-order errors (pixels where it differs from the same frame
/// without impostors), printed; the counts must show the check is not vacuous.
#[test]
fn a_fixed_path_makes_impostors_and_counts_its_depth_order_errors() {
    let prepared = forest();
    let p = Params {
        impostor_pixels: 64,
        impostor_tiles: 16,
        impostor_min_distance: 100.0,
        impostor_max_depth: 3,
        ..base()
    };
    let camera = Camera::look_at([-500.0, 300.0, 60.0], [300.0, 300.0, 10.0], 50.0, 192, 108);
    let mut cache = ImpostorCache::new(prepared, &p).unwrap();
    let step = cache.step(prepared, &camera, &p).unwrap();
    let (bad, compared, skipped, worst) = fresh_mismatches(prepared, &cache, &camera, &p);
    let with = prepared.render_impostors(&camera, &p, &cache).unwrap();
    let empty = ImpostorCache::new(prepared, &p).unwrap();
    let without = prepared.render_impostors(&camera, &p, &empty).unwrap();
    let differ = with
        .drawn
        .target
        .color()
        .iter()
        .zip(without.drawn.target.color())
        .filter(|(a, b)| a[..3] != b[..3])
        .count();
    println!(
        "impostors: {} created, {} compared fresh ({} past the frame), {bad} mismatching pixels (worst colour difference {worst}); \
         depth-order errors: {differ} of {} pixels",
        step.created,
        compared,
        skipped,
        192 * 108
    );
    assert!(
        step.created > 0 && compared > 0,
        "the fixed case made no impostor to compare"
    );
    assert_eq!(bad, 0);
}
