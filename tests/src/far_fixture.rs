//! A far level made without a bake (issue 32, `forestlod_shared::far`), for the tests of the cut
//! and the draw: one cell per node, the node's box, side colours from the node's index; under
//! `hull`, the box's twelve triangles, opaque. Test code only: the pipeline's far level is the
//! bake's.

use forestlod_reference::hierarchy::Hierarchy;
use forestlod_shared::{
    CUBE_VERTICES, FarCell, FarLevel, FarLod, FarNode, FarVertex, SIDE_COUNT, cube_corner,
};

/// The side colours of node `i`: distinct per side and node, alpha between 128 and 255.
pub fn node_colours(i: u32) -> [u32; SIDE_COUNT] {
    core::array::from_fn(|s| {
        let h = (i.wrapping_mul(2_654_435_761) ^ (s as u32).wrapping_mul(40_503)) | 0x0080_8080;
        (h & 0x00ff_ffff) | (128 + (i * 37 + s as u32 * 11) % 128) << 24
    })
}

/// One cell per node of `h` (module docs).
pub fn synthetic_far_level(h: &Hierarchy, kind: FarLod) -> FarLevel {
    let mut far = FarLevel::default();
    for (i, n) in h.nodes.iter().enumerate() {
        let colours = node_colours(i as u32);
        let hull_offset = far.hull.len() as u32;
        if kind == FarLod::Hull {
            for v in 0..CUBE_VERTICES {
                let (face, s) = cube_corner(v);
                far.hull.push(FarVertex {
                    position: core::array::from_fn(|k| n.box_center[k] + s[k] * n.extent[k]),
                    colour: colours[face as usize] | 0xff00_0000,
                });
            }
        }
        far.nodes.push(FarNode {
            cell_offset: far.cells.len() as u32,
            cell_count: 1,
            hull_offset,
            hull_count: if kind == FarLod::Hull {
                CUBE_VERTICES
            } else {
                0
            },
        });
        far.cells.push(FarCell {
            center: n.box_center,
            extent: n.extent,
            colours,
        });
    }
    far
}
