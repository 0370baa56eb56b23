//! The depth pyramid of occlusion culling on the GPU (issue 31; beyond the seeds: E§7 lists finer
//! culling as future work): the driver of `shaders/pyramid.wgsl`, twin of
//! `reference/src/pyramid.rs` (`Pyramid::build`). Layout, reduction and why it is exact at every
//! size: `forestlod_shared::occlusion` (`pyramid_levels`, `pyramid_reduce`).
//!
//! ## Contract
//! [`GpuPyramid::new`] sizes the pyramid of a `width x height` depth target once (one flat `f32`
//! storage buffer of [`pyramid_len`] texels, levels one after the other, rows top-down, and one
//! uniform slot per dispatch). [`GpuPyramid::encode`] records, in one compute pass: level 0 copied
//! from the depth texture (`textureLoad` of its depth aspect, as `depth_copy.wgsl` reads it), then
//! one dispatch per further level, each texel the largest of the up to 2x2 texels below it that
//! exist. One invocation per texel written, no loop: constant work per texel whatever the size.
//!
//! ## Invariants
//! - Equal to the reference's pyramid of the same depth buffer **bit for bit** (`max` rounds
//!   nothing; `tests/tests/parity/occlusion.rs` checks 1x1 up to 1280x720, odd sizes included).
//! - The texel buffer is the late test's input (`occlude.wgsl`); it is rewritten whole by every
//!   encode, so it holds no state across frames.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{MAX_PYRAMID_LEVELS, PyramidLevel, pyramid_len, pyramid_levels};

use crate::context::{Slot, WRITE, bind_group, compute_pipelines, dynamic_uniform_slot};
use crate::readback::{read_buffer, zeroed_buffer};
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{GpuContext, GpuError};

/// Side of `pyramid.wgsl`'s square workgroups (8x8 invocations, one per texel).
pub const PYRAMID_WORKGROUP_SIDE: u32 = 8;

/// The `pyramid` stage's module: `pyramid.wgsl`.
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "pyramid.wgsl",
        wgsl: include_str!("shaders/pyramid.wgsl"),
        constants: wgsl_constants![PYRAMID_WORKGROUP_SIDE],
    },
    parts: &[],
};

/// The levels one dispatch of `pyramid.wgsl` reads and writes, each `(width, height, offset, 0)`
/// ([`PyramidLevel`]). Keep in sync with `struct PyramidStep` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PyramidStep {
    /// The level read (unused by the level-0 copy).
    pub below: [u32; 4],
    /// The level written.
    pub level: [u32; 4],
}
const _: () = assert!(size_of::<PyramidStep>() == 32);

/// `(width, height, offset, 0)` of a level, as the shaders read it.
pub fn level_vec(l: PyramidLevel) -> [u32; 4] {
    [l.width, l.height, l.offset, 0]
}

compute_pipelines! {
    /// The compiled pipelines of `pyramid.wgsl`, one set per [`GpuContext`] (cached there).
    pub struct PyramidPipelines = "pyramid", SOURCE.module(), [
        Slot::DynamicUniform(size_of::<PyramidStep>() as u64),
        Slot::Texture(wgpu::TextureViewDimension::D2),
        WRITE,
    ],
    {
        copy: "pyramid_copy",
        reduce: "pyramid_reduce_level",
    }
}

/// The depth pyramid of one target size on the GPU (module docs).
pub struct GpuPyramid {
    pipelines: Arc<PyramidPipelines>,
    levels: Vec<PyramidLevel>,
    width: u32,
    height: u32,
    /// One [`PyramidStep`] per dispatch (level `L` at slot `L`), `stride` bytes apart.
    steps: wgpu::Buffer,
    stride: u64,
    texels: wgpu::Buffer,
}

impl GpuPyramid {
    /// The pyramid of a `width x height` depth target. Fails on a side of 0, on more than
    /// [`MAX_PYRAMID_LEVELS`] levels, or when the texels exceed one storage binding.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, GpuError> {
        if width == 0 || height == 0 {
            return Err(GpuError::Input {
                field: "pyramid size",
                value: format!("{width}x{height}"),
                reason: "expected at least one pixel per side",
            });
        }
        let levels = pyramid_levels(width, height);
        if levels.len() > MAX_PYRAMID_LEVELS as usize {
            return Err(GpuError::Input {
                field: "pyramid size",
                value: format!("{width}x{height}: {} levels", levels.len()),
                reason: "expected at most MAX_PYRAMID_LEVELS levels (sides up to 2^15 pixels)",
            });
        }
        let len = pyramid_len(width, height) as u64;
        ctx.check_storage_binding(
            len * 4,
            "pyramid size",
            |max| format!("{width}x{height}: {len} texels of 4 bytes, over the device's {max}"),
            "the pyramid's texels must fit one storage binding",
        )?;
        let pipelines = ctx.pipelines::<PyramidPipelines>()?;
        let align = u64::from(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
        let stride = (size_of::<PyramidStep>() as u64).next_multiple_of(align);
        let mut bytes = vec![0u8; (stride * levels.len() as u64) as usize];
        for (l, level) in levels.iter().enumerate() {
            let step = PyramidStep {
                below: level_vec(levels[l.saturating_sub(1)]),
                level: level_vec(*level),
            };
            let at = stride as usize * l;
            bytes[at..at + size_of::<PyramidStep>()].copy_from_slice(bytemuck::bytes_of(&step));
        }
        let steps = wgpu::util::DeviceExt::create_buffer_init(
            &ctx.device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("pyramid steps"),
                contents: &bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            },
        );
        use wgpu::BufferUsages as U;
        Ok(Self {
            pipelines,
            levels,
            width,
            height,
            steps,
            stride,
            texels: zeroed_buffer(
                ctx,
                "pyramid texels",
                len * 4,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
        })
    }

    /// The levels ([`pyramid_levels`] of the size).
    pub fn levels(&self) -> &[PyramidLevel] {
        &self.levels
    }

    /// `(width, height)` of level 0.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Every level's texels ([`pyramid_len`] `f32`s; the late test's input).
    pub fn texels(&self) -> &wgpu::Buffer {
        &self.texels
    }

    /// Records the pyramid of `depth` (a view that reads as an unfilterable float texture of the
    /// pyramid's size: a depth target's depth aspect, or an `R32Float` texture) into `encoder`:
    /// one compute pass, level 0 then one dispatch per further level (module docs).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        depth: &wgpu::TextureView,
    ) {
        let group = bind_group(
            &ctx.device,
            "pyramid",
            &self.pipelines.layout,
            [
                dynamic_uniform_slot::<PyramidStep>(&self.steps),
                wgpu::BindingResource::TextureView(depth),
                self.texels.as_entire_binding(),
            ],
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("pyramid"),
            timestamp_writes: None,
        });
        let side = PYRAMID_WORKGROUP_SIDE;
        for (l, level) in self.levels.iter().enumerate() {
            let pipeline = if l == 0 {
                &self.pipelines.copy
            } else {
                &self.pipelines.reduce
            };
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[(self.stride * l as u64) as u32]);
            pass.dispatch_workgroups(level.width.div_ceil(side), level.height.div_ceil(side), 1);
        }
    }

    /// Records the pyramid of a depth target's depth texture ([`GpuPyramid::encode`] of its
    /// depth aspect).
    pub fn encode_from_depth(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        depth: &wgpu::Texture,
    ) {
        let view = depth.create_view(&wgpu::TextureViewDescriptor {
            label: Some("pyramid depth"),
            aspect: wgpu::TextureAspect::DepthOnly,
            ..Default::default()
        });
        self.encode(ctx, encoder, &view);
    }

    /// Every texel, read back. Blocks.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<f32>, GpuError> {
        read_buffer(ctx, &self.texels, 0, pyramid_len(self.width, self.height))
    }

    /// Records the pyramid of a depth buffer given on the CPU (`width · height` values of the
    /// pyramid's size, row-major from the top-left pixel), through an `R32Float` texture holding
    /// the same values (written through the queue: it lands before `encoder`'s submit). What the
    /// parity tests compare with the reference's `Pyramid::build` of the same buffer, and how
    /// they feed the late test the reference's early depth.
    pub fn encode_from_values(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        depth: &[f32],
    ) -> Result<(), GpuError> {
        let (width, height) = (self.width, self.height);
        if depth.len() as u64 != u64::from(width) * u64::from(height) {
            return Err(GpuError::Input {
                field: "depth",
                value: format!("{} values for {width}x{height}", depth.len()),
                reason: "expected one depth per pixel of the pyramid's level 0",
            });
        }
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("pyramid input depth"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        ctx.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(depth),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(width * 4),
                rows_per_image: Some(height),
            },
            size,
        );
        self.encode(ctx, encoder, &texture.create_view(&Default::default()));
        Ok(())
    }

    /// The pyramid of a depth buffer given on the CPU ([`GpuPyramid::encode_from_values`]), read
    /// back. Blocks.
    pub fn of_depth(
        ctx: &GpuContext,
        depth: &[f32],
        width: u32,
        height: u32,
    ) -> Result<Vec<f32>, GpuError> {
        let pyramid = Self::new(ctx, width, height)?;
        ctx.submit("pyramid of a depth buffer", "pyramid", |encoder| {
            pyramid.encode_from_values(ctx, encoder, depth)
        })??;
        pyramid.read(ctx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wgsl_layout::{assert_layout, rust_layout, validate};

    /// `PyramidStep` has its WGSL twin's layout (naga reflection of the full module, which also
    /// validates it).
    #[test]
    fn wgsl_layouts_match_rust() {
        let module = validate(&SOURCE.module());
        assert_layout(&module, &rust_layout!(PyramidStep { below, level }));
    }
}
