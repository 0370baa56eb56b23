//! Colour constants and the sRGB codec both renderers use (SPEC §3: textures are sRGB-encoded
//! RGBA8, filtering and blending happen in linear `f32`, output is sRGB8).
//!
//! ## Contract
//! - [`srgb_to_linear`]: the exact sRGB curve evaluated in `f64` and rounded once to `f32` (a
//!   256-entry table, computed once). The reference decodes every texel with it; the GPU's
//!   `mips.wgsl` reads it as a table (`gpu/src/mips.rs` `mip_tables`) and the GPU driver derives
//!   its clear and ground colours from it, so both sides start from the very same `f32`s.
//! - [`linear_to_srgb`]: clamp to `[0, 1]` (NaN to 0), the inverse curve in `f64`, round to
//!   nearest. [`unorm8`]: clamp (NaN to 0), `* 255 + 0.5`, floor, in `f32`.
//! - The LOD-id codes of the id target ([`LOD_ID_BACKGROUND`] …), the sky colour [`SKY_SRGB`] and
//!   the LOD-id colours of E Fig. 3.1 live here too, mirrored in `gpu/src/shaders/draw.wgsl` and
//!   `primitive.wgsl` (checked by `gpu/src/draw.rs`'s and `primitive.rs`'s tests).

use std::sync::OnceLock;

/// LOD-id of background pixels.
pub const LOD_ID_BACKGROUND: u32 = 0;
/// LOD-id of full meshes (green in E Fig. 3.1). Mirrored in `draw.wgsl` and `primitive.wgsl`.
pub const LOD_ID_MESH: u32 = 1;
/// LOD-id of billboards (blue).
pub const LOD_ID_BILLBOARD: u32 = 2;
/// LOD-id of fading fragments in the transition band (red): fragments of a fading command
/// strictly inside the band.
pub const LOD_ID_TRANSITION: u32 = 3;
/// LOD-id of the ground.
pub const LOD_ID_TERRAIN: u32 = 4;
/// LOD-id of the far level (issue 32, `crate::far`): octant impostors and batch hulls.
pub const LOD_ID_FAR: u32 = 5;

/// Sky colour (sRGB8), the clear colour of every frame.
pub const SKY_SRGB: [u8; 3] = [168, 198, 226];

#[inline]
fn decode_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0.0f32; 256];
        for (i, v) in t.iter_mut().enumerate() {
            let c = i as f64 / 255.0;
            *v = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            } as f32;
        }
        t
    })
}

/// sRGB-encoded byte to linear light in `[0, 1]`: the exact curve in `f64`, rounded once to `f32`.
#[inline]
pub fn srgb_to_linear(c: u8) -> f32 {
    decode_table()[c as usize]
}

/// Linear light to an sRGB-encoded byte, clamping to `[0, 1]` and rounding to nearest; NaN gives 0.
pub fn linear_to_srgb(l: f32) -> u8 {
    let l = (l as f64).max(0.0).min(1.0);
    let s = if l <= 0.0031308 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5).floor() as u8
}

/// Linear `[0, 1]` value to a UNORM byte, rounding to nearest; NaN gives 0.
pub fn unorm8(v: f32) -> u8 {
    (v.max(0.0).min(1.0) * 255.0 + 0.5).floor() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(c)), c);
        }
        assert_eq!(linear_to_srgb(f32::NAN), 0);
        assert_eq!(unorm8(f32::NAN), 0);
        assert_eq!(unorm8(2.0), 255);
        assert_eq!(srgb_to_linear(255), 1.0);
        assert_eq!(srgb_to_linear(0), 0.0);
    }
}
