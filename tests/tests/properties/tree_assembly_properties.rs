//! The tree draw's input assembly (issue 14, session 11): the reference hands the rasterizer its
//! tree triangles a piece at a time and runs the per-tree share of the vertex stage once per
//! tree (`forestlod_reference::draw::tree_stage`); concatenated, the pieces must be exactly the
//! plain multi-draw's triangles: for every command, every instance, every index, the vertex
//! stage called on its own (`vertex_stage`), a tree dropped whole when it discards it.

use forestlod_reference::cameras::named_camera;
use forestlod_reference::draw::{DrawUniform, TREE_VARYINGS, tree_triangles, vertex_stage};
use forestlod_reference::pipeline::prepare;
use forestlod_reference::raster::{SETUP_CHUNK, Triangle};
use forestlod_reference::scene::builtin;
use forestlod_shared::Params;

/// The multi-draw spelled out: each index of each instance through [`vertex_stage`], no vertex
/// cache, no pieces; with the number of trees the vertex stage discarded.
fn plain_assembly(
    prepared: &forestlod_reference::pipeline::Prepared,
    selection: &forestlod_reference::select::Selection,
    camera: &forestlod_shared::Camera,
    params: &Params,
) -> (Vec<Triangle<TREE_VARYINGS>>, u64) {
    let res = prepared.resources();
    let uniform = DrawUniform::new(camera, params);
    let (mut out, mut discarded) = (Vec::new(), 0u64);
    for cmd in &selection.commands {
        let indices = &res.geometry.indices
            [cmd.first_index as usize..(cmd.first_index + cmd.index_count) as usize];
        'tree: for j in 0..cmd.instance_count {
            let instance = cmd.first_instance + j;
            let mut tris = Vec::new();
            for t in indices.chunks_exact(3) {
                let mut tri = Vec::new();
                for &index in t {
                    let vertex_index = (index as i32 + cmd.base_vertex) as u32;
                    match vertex_stage(&res, selection, &uniform, vertex_index, instance) {
                        Some(v) => tri.push(v),
                        None => {
                            discarded += 1;
                            continue 'tree;
                        }
                    }
                }
                tris.push([tri[0], tri[1], tri[2]]);
            }
            out.extend(tris);
        }
    }
    (out, discarded)
}

#[test]
fn tree_triangles_in_pieces_equal_the_plain_multi_draw() {
    let scene = builtin::synthetic();
    // A draw distance inside the selected batches, so that the vertex stage discards trees.
    let params = Params {
        draw_distance: 1500.0,
        ..Params::default()
    };
    let prepared = prepare(scene, &params).expect("prepare");
    let (mut pieces_checked, mut discards_checked, mut billboards, mut meshes) = (0, 0, 0, 0);
    for name in ["medium", "close", "far"] {
        let camera = named_camera(name, &prepared.scene, 0.0, 320, 180).expect("camera");
        let selection = prepared.select(&camera, &params);
        let (want, want_discarded) = plain_assembly(&prepared, &selection, &camera, &params);
        let (got, got_discarded) =
            tree_triangles(&prepared.resources(), &selection, &camera, &params);
        assert_eq!(got_discarded, want_discarded, "{name}: trees discarded");
        assert_eq!(got.len(), want.len(), "{name}: triangle count");
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            for k in 0..3 {
                let bits = |v: &forestlod_reference::raster::Vertex<TREE_VARYINGS>| {
                    (v.clip.map(f32::to_bits), v.varyings.map(f32::to_bits))
                };
                assert_eq!(bits(&g[k]), bits(&w[k]), "{name}: triangle {i} vertex {k}");
            }
        }
        pieces_checked += usize::from(want.len() > 2 * SETUP_CHUNK);
        discards_checked += usize::from(want_discarded > 0);
        for data in &selection.data {
            if data.billboard != 0 {
                billboards += 1;
            } else {
                meshes += 1;
            }
        }
    }
    // What the cases must reach to test anything: lists of several pieces, discarded trees,
    // both kinds of command.
    assert!(pieces_checked >= 1, "no frame spans several pieces");
    assert!(discards_checked >= 1, "no frame discards a tree");
    assert!(
        billboards > 0 && meshes > 0,
        "{billboards} billboard and {meshes} mesh commands"
    );
}
