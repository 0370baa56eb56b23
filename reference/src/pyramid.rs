//! The depth pyramid of occlusion culling (issue 31): the reference twin of
//! `gpu/src/shaders/pyramid.wgsl`. Level 0 is the early pass's depth buffer; each further level
//! holds, per texel, the **largest** (farthest under depth LESS) of the up to 2x2 texels below it
//! that exist ([`forestlod_shared::pyramid_reduce`]), so texel `(i, j)` of level `L` is the exact
//! maximum of its `2^L x 2^L` block of pixels clipped to the frame, at every size (odd and
//! non-power-of-two included). Layout and reduction: `forestlod_shared::occlusion`.
//!
//! Rejected design: niagara's pyramid (`depthreduce.comp`) starts at the previous power of two of
//! the viewport and reads it through a min/max reduction sampler, so a texel of a non-power-of-two
//! viewport does not cover whole blocks; the exact `ceil` layout costs at most one extra texel a
//! row and column per level.

use forestlod_shared::{
    OcclusionRect, PyramidLevel, pyramid_level_for, pyramid_levels, pyramid_reduce,
    pyramid_texels_max,
};

/// A depth pyramid (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Pyramid {
    /// The levels' sizes and offsets ([`pyramid_levels`]).
    pub levels: Vec<PyramidLevel>,
    /// Every level's texels, one after the other, rows top-down.
    pub texels: Vec<f32>,
}

impl Pyramid {
    /// The pyramid of a `width x height` depth buffer (row-major from the top-left pixel).
    ///
    /// # Panics
    /// If `depth` does not hold `width · height` values or a side is 0.
    pub fn build(depth: &[f32], width: u32, height: u32) -> Self {
        assert_eq!(
            depth.len(),
            (width * height) as usize,
            "one depth per pixel"
        );
        let levels = pyramid_levels(width, height);
        let mut texels = Vec::with_capacity(forestlod_shared::pyramid_len(width, height));
        texels.extend_from_slice(depth);
        for pair in levels.windows(2) {
            let (below, level) = (pair[0], pair[1]);
            for j in 0..level.height {
                for i in 0..level.width {
                    let v = pyramid_reduce(below, i, j, |x, y| {
                        texels[(below.offset + y * below.width + x) as usize]
                    });
                    texels.push(v);
                }
            }
        }
        Self { levels, texels }
    }

    /// Texel `(i, j)` of level `level`.
    pub fn texel(&self, level: u32, i: u32, j: u32) -> f32 {
        let l = self.levels[level as usize];
        self.texels[(l.offset + j * l.width + i) as usize]
    }

    /// The largest texel at [`pyramid_level_for`]'s level under `rect`: at least every depth of the
    /// buffer under it.
    pub fn max_under(&self, rect: &OcclusionRect) -> f32 {
        let level = pyramid_level_for(rect, self.levels.len() as u32);
        pyramid_texels_max(rect, level, |l, i, j| self.texel(l, i, j))
    }
}
