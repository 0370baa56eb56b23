//! Creating and uploading buffers (`Pod` data, the stages' uniforms) and reading buffers and
//! textures back, for the stage drivers, for parity tests (SPEC §8) and for the experiments'
//! reports.
//!
//! Readback copies into a `MAP_READ` staging buffer, submits, maps it and blocks on
//! [`wgpu::Device::poll`] until the map completes. Texture rows are copied with
//! `bytes_per_row` padded to [`wgpu::COPY_BYTES_PER_ROW_ALIGNMENT`] (256 bytes) and unpadded on
//! the way out.

use bytemuck::Pod;
use wgpu::util::DeviceExt;

use crate::{GpuContext, GpuError};

/// Smallest buffer this module creates: wgpu rejects bindings of zero size, and an empty scene
/// still binds its (empty) batch array.
pub const MIN_BUFFER_SIZE: u64 = 16;

/// Creates a buffer holding `data` with `STORAGE | COPY_SRC | COPY_DST | extra` usage, zero-padded
/// to at least one `T` and [`MIN_BUFFER_SIZE`] bytes (so an empty slice still binds).
pub fn upload_storage<T: Pod>(
    ctx: &GpuContext,
    label: &str,
    data: &[T],
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let usage = wgpu::BufferUsages::STORAGE
        | wgpu::BufferUsages::COPY_SRC
        | wgpu::BufferUsages::COPY_DST
        | extra;
    let bytes: &[u8] = bytemuck::cast_slice(data);
    // At least one element (a binding's minimum size is one struct) and a multiple of 4 bytes.
    let min = (MIN_BUFFER_SIZE as usize).max(size_of::<T>());
    let len = bytes.len().max(min).next_multiple_of(4);
    let contents: std::borrow::Cow<[u8]> = if len == bytes.len() {
        bytes.into()
    } else {
        let mut padded = bytes.to_vec();
        padded.resize(len, 0);
        padded.into()
    };
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: &contents,
            usage,
        })
}

/// Creates a zeroed buffer of at least `size` bytes (rounded up to 4, at least
/// [`MIN_BUFFER_SIZE`]) with the given usage.
pub fn zeroed_buffer(
    ctx: &GpuContext,
    label: &str,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.next_multiple_of(4).max(MIN_BUFFER_SIZE),
        usage,
        mapped_at_creation: false,
    })
}

/// A zeroed `UNIFORM | COPY_DST` buffer the size of `T`, labelled `label`: the uniform a driver
/// owning per-scene outputs rewrites each frame from a `&mut self` method (crate docs).
pub(crate) fn stage_uniform<T>(ctx: &GpuContext, label: &str) -> wgpu::Buffer {
    zeroed_buffer(
        ctx,
        label,
        size_of::<T>() as u64,
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    )
}

/// A fresh `UNIFORM` buffer holding `value`, for one recorded frame.
///
/// Stage drivers never keep a uniform buffer of their own behind `&self` and rewrite it through
/// the queue: `queue.write_buffer` lands at the next submit *of any thread*, so two threads that
/// record frames with one driver would each draw with whichever camera was written last (the race
/// behind a flaky parity test, issue 10). A per-call buffer, bound into the per-call bind group,
/// makes that impossible by construction; it costs one small allocation per frame (wgpu keeps it
/// alive until the command buffer that uses it has run).
pub(crate) fn frame_uniform<T: Pod>(ctx: &GpuContext, label: &str, value: &T) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::bytes_of(value),
            usage: wgpu::BufferUsages::UNIFORM,
        })
}

/// Reads `count` elements of `T` starting at byte `offset` of `buffer` (which needs `COPY_SRC`;
/// `offset` a multiple of 4). Blocks until the GPU is done.
pub fn read_buffer<T: Pod>(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    offset: u64,
    count: usize,
) -> Result<Vec<T>, GpuError> {
    let len = (count * size_of::<T>()) as u64;
    if len == 0 {
        return Ok(Vec::new());
    }
    if offset & 3 != 0 || offset + len > buffer.size() {
        return Err(GpuError::Input {
            field: "read_buffer range",
            value: format!("{offset}..{} of {} bytes", offset + len, buffer.size()),
            reason: "expected a range inside the buffer starting at a multiple of 4",
        });
    }
    // Copies move multiples of 4 bytes; a T of odd size reads a little more and truncates.
    let copy_len = len.next_multiple_of(4).min(buffer.size() - offset);
    let bytes = copy_and_read(
        ctx,
        "readback",
        copy_len.next_multiple_of(4),
        |encoder, staging| {
            encoder.copy_buffer_to_buffer(buffer, offset, staging, 0, copy_len);
        },
    )?;
    Ok(bytemuck::pod_collect_to_vec(&bytes[..len as usize]))
}

/// Creates a `MAP_READ | COPY_DST` staging buffer of `size` bytes (labelled `"{label} staging"`),
/// records the copies into it with `copy` in an encoder labelled `label`, submits them and
/// returns the staging buffer's bytes ([`map_and_read`]). Blocks.
fn copy_and_read(
    ctx: &GpuContext,
    label: &str,
    size: u64,
    copy: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::Buffer),
) -> Result<Vec<u8>, GpuError> {
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(&format!("{label} staging")),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    copy(&mut encoder, &staging);
    ctx.queue.submit([encoder.finish()]);
    map_and_read(ctx, &staging)
}

/// Maps a whole `MAP_READ` buffer, copies its bytes out and unmaps it.
pub(crate) fn map_and_read(ctx: &GpuContext, staging: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    let (sender, receiver) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |result| {
        // The receiver outlives the poll below; a failed send only means nobody listens.
        let _ = sender.send(result);
    });
    ctx.wait()?;
    receiver
        .recv()
        .map_err(|e| GpuError::Map(e.to_string()))?
        .map_err(|e| GpuError::Map(e.to_string()))?;
    let bytes = {
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| GpuError::Map(e.to_string()))?;
        view.to_vec()
    };
    staging.unmap();
    Ok(bytes)
}

/// The texels of one layer and mip level of a texture, rows tightly packed.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureLevel {
    /// Width in texels of the level.
    pub width: u32,
    /// Height in texels of the level.
    pub height: u32,
    /// Bytes per texel (the format's block copy size).
    pub bytes_per_texel: u32,
    /// `height` rows of `width * bytes_per_texel` bytes.
    pub data: Vec<u8>,
}

impl TextureLevel {
    /// The data as `T` per texel or channel (`T`'s size must divide the row size).
    pub fn cast<T: Pod>(&self) -> Vec<T> {
        bytemuck::pod_collect_to_vec(&self.data)
    }
}

/// Reads one array layer and mip level of a 2D (array) texture with `COPY_SRC` usage. Colour
/// formats copy all channels; depth(-stencil) formats copy the depth aspect (formats whose depth
/// cannot be copied, like `Depth24Plus`, give [`GpuError::Input`]).
pub fn read_texture(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    layer: u32,
    mip_level: u32,
) -> Result<TextureLevel, GpuError> {
    let format = texture.format();
    let aspect = if format.has_depth_aspect() {
        wgpu::TextureAspect::DepthOnly
    } else {
        wgpu::TextureAspect::All
    };
    let bytes_per_texel = format
        .block_copy_size(Some(aspect))
        .filter(|_| format.block_dimensions() == (1, 1))
        .ok_or(GpuError::Input {
            field: "read_texture format",
            value: format!("{format:?}"),
            reason: "expected an uncompressed format whose texels can be copied to a buffer",
        })?;
    if layer >= texture.depth_or_array_layers() || mip_level >= texture.mip_level_count() {
        return Err(GpuError::Input {
            field: "read_texture layer/mip",
            value: format!("layer {layer} mip {mip_level}"),
            reason: "expected a layer and mip level the texture has",
        });
    }
    let size = texture
        .size()
        .mip_level_size(mip_level, texture.dimension());
    let (width, height) = (size.width, size.height);
    let row = width * bytes_per_texel;
    let padded_row = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let size = u64::from(padded_row) * u64::from(height);
    let padded = copy_and_read(ctx, "texture readback", size, |encoder, staging| {
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level,
                origin: wgpu::Origin3d {
                    x: 0,
                    y: 0,
                    z: layer,
                },
                aspect,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded_row),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
    })?;
    let mut data = Vec::with_capacity((row * height) as usize);
    for y in 0..height as usize {
        let start = y * padded_row as usize;
        data.extend_from_slice(&padded[start..start + row as usize]);
    }
    Ok(TextureLevel {
        width,
        height,
        bytes_per_texel,
        data,
    })
}
