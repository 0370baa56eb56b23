//! Billboard geometry shared by the bake (E Alg. 3.1) and the draw stage (E§3.3.1, §4.4), and the
//! per-pixel dither threshold of the dithered fades (G§4).
//!
//! **Frame.** A billboard of layer `k` is the tree seen along the baked view direction
//! `V_k = h cos e_k + Z sin e_k`, where `h` is the unit horizontal direction from the tree to the eye
//! and `e_k` the layer's bake elevation ([`crate::bake_elevation`]). Its plane is spanned by the
//! horizontal right vector `R = normalize(Z × h)` (the right vector of a camera looking along `-V_k`) and the tilted up vector
//! `U_k = Z cos e_k - h sin e_k`, so it faces the camera in yaw and snaps its tilt to the baked
//! elevation (E§3.3.1: "the billboards are not completely view-oriented and instead snap to discrete
//! evenly spaced vertical angles").
//!
//! **Extent.** Trees are radially symmetric (E§3.3.1), so the mesh's horizontal circumradius `W`
//! bounds every yaw. A point at height `z` and horizontal offset `s ∈ [-W, W]` along `h` projects to
//! `z cos e - s sin e` on `U_k`; the orthographic projection "fitted to the bounding box"
//! (E Alg. 3.1) therefore spans `[-W, W]` on `R` and `[bottom, bottom + height]` on `U_k` with
//! `bottom = z_min cos e - W sin e`, `height = (z_max - z_min) cos e + 2 W sin e`.
//!
//! Keep in sync with `gpu/src/shaders/common.wgsl` (`billboard_extent`, `dither_threshold`).

use crate::MeshMeta;

/// The rectangle a baked layer covers in the billboard frame, in mesh units (multiply by scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BillboardExtent {
    /// Half-width along `R`.
    pub half_width: f32,
    /// Lower edge along `U_k`, relative to the tree's base.
    pub bottom: f32,
    /// Height along `U_k`.
    pub height: f32,
}

/// The extent of a mesh's billboard baked at `elevation` radians (see the module docs).
pub fn billboard_extent(mesh: &MeshMeta, elevation: f32) -> BillboardExtent {
    let (s, c) = elevation.sin_cos();
    let w = mesh.billboard_half_width;
    let (z0, z1) = (mesh.bbox_min[2], mesh.bbox_max[2]);
    BillboardExtent {
        half_width: w,
        bottom: z0 * c - w * s,
        height: (z1 - z0) * c + 2.0 * w * s,
    }
}

/// A per-pixel threshold in `[0, 1)` for the dithered fades: an integer hash of the pixel
/// coordinates (the "noise" of G§4), identical on CPU and GPU because it uses only `u32` wrapping
/// arithmetic. 24 bits of the hash become the fraction.
pub fn dither_threshold(x: u32, y: u32) -> f32 {
    // PCG-style integer hash (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering").
    let mut v = x
        .wrapping_mul(1_664_525)
        .wrapping_add(y.wrapping_mul(1_013_904_223))
        .wrapping_add(0x9E37_79B9);
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    v = (word >> 22) ^ word;
    (v >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> MeshMeta {
        MeshMeta {
            bbox_min: [-3.0, -3.0, 0.0],
            bbox_max: [3.0, 3.0, 20.0],
            billboard_half_width: 4.0,
            ..bytemuck::Zeroable::zeroed()
        }
    }

    #[test]
    fn level_view_spans_the_height_and_top_view_the_width() {
        let level = billboard_extent(&meta(), 0.0);
        assert_eq!(
            (level.half_width, level.bottom, level.height),
            (4.0, 0.0, 20.0)
        );
        let top = billboard_extent(&meta(), core::f32::consts::FRAC_PI_2);
        assert!(
            (top.bottom + 4.0).abs() < 1e-5 && (top.height - 8.0).abs() < 1e-5,
            "{top:?}"
        );
    }

    #[test]
    fn dither_is_in_unit_interval_and_roughly_uniform() {
        let mut below_half = 0;
        for y in 0..256 {
            for x in 0..256 {
                let h = dither_threshold(x, y);
                assert!((0.0..1.0).contains(&h));
                below_half += (h < 0.5) as u32;
            }
        }
        let frac = below_half as f32 / 65536.0;
        assert!((frac - 0.5).abs() < 0.01, "{frac}");
    }
}
