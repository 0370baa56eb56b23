//! Round trips through the readback helpers (`gpu/src/readback.rs`): buffers of odd sizes, and
//! texture layers and mip levels whose rows are not multiples of the 256-byte copy alignment.
//! Without an adapter these fail with the install hint unless `FORESTLOD_ALLOW_NO_GPU=1`.

use forestlod_gpu::gpu_or_explain;
use forestlod_gpu::readback::{read_buffer, read_texture, upload_storage};

#[test]
fn buffers_round_trip() {
    let Some(ctx) = gpu_or_explain() else {
        return;
    };
    eprintln!("adapter: {}", ctx.describe());
    let data: Vec<u32> = (0..1001u32)
        .map(|i| i.wrapping_mul(2_654_435_761))
        .collect();
    let buffer = upload_storage(&ctx, "roundtrip", &data, wgpu::BufferUsages::empty());
    assert_eq!(
        read_buffer::<u32>(&ctx, &buffer, 0, data.len()).unwrap(),
        data
    );
    assert_eq!(
        read_buffer::<u32>(&ctx, &buffer, 40, 5).unwrap(),
        data[10..15]
    );
    // An empty upload still makes a bindable buffer; reading nothing gives nothing.
    let empty = upload_storage::<[f32; 3]>(&ctx, "empty", &[], wgpu::BufferUsages::empty());
    assert!(empty.size() >= 12);
    assert!(read_buffer::<u32>(&ctx, &empty, 0, 0).unwrap().is_empty());
    // Out of range is an error, not a panic inside wgpu.
    assert!(read_buffer::<u32>(&ctx, &buffer, 0, 5000).is_err());
}

/// A range `read_buffer` cannot read is refused with an error naming the input, the range asked
/// for and the rule it breaks, with the real alignment (4 bytes: `copy_buffer_to_buffer`'s):
/// a misaligned start and a range past the end. Added for issue 36's Rust mutant 453 (the
/// message's "a multiple of 4" -> "5": the project's rule is that errors name the field and
/// value, so a wrong rule in the message misleads the caller).
#[test]
fn a_bad_range_is_refused_naming_the_range_and_the_alignment() {
    let Some(ctx) = gpu_or_explain() else {
        return;
    };
    let data: Vec<u32> = (0..16).collect();
    let buffer = upload_storage(&ctx, "bad range", &data, wgpu::BufferUsages::empty());
    let size = buffer.size();
    for (offset, count, range) in [
        (2u64, 3usize, format!("2..14 of {size} bytes")),
        (8, 40, format!("8..168 of {size} bytes")),
    ] {
        let message = read_buffer::<u32>(&ctx, &buffer, offset, count)
            .expect_err("a bad range must be refused")
            .to_string();
        assert_eq!(
            message,
            format!(
                "invalid input read_buffer range = {range}: expected a range inside the buffer \
                 starting at a multiple of 4"
            ),
            "offset {offset}, {count} elements"
        );
    }
}

#[test]
fn texture_layers_and_levels_round_trip() {
    let Some(ctx) = gpu_or_explain() else {
        return;
    };
    // 37 texels of RGBA8 = 148-byte rows: padded to 256 on the way out, unpadded by the helper.
    let (w, h, layers, mips) = (37u32, 5u32, 3u32, 2u32);
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("readback test"),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: layers,
        },
        mip_level_count: mips,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let texel = |layer: u32, mip: u32, x: u32, y: u32| {
        [x as u8, y as u8, (layer * 16 + mip) as u8, 255 - x as u8]
    };
    for layer in 0..layers {
        for mip in 0..mips {
            let (mw, mh) = ((w >> mip).max(1), (h >> mip).max(1));
            let bytes: Vec<u8> = (0..mh)
                .flat_map(|y| (0..mw).flat_map(move |x| texel(layer, mip, x, y)))
                .collect();
            ctx.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: mip,
                    origin: wgpu::Origin3d {
                        x: 0,
                        y: 0,
                        z: layer,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                &bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(mw * 4),
                    rows_per_image: Some(mh),
                },
                wgpu::Extent3d {
                    width: mw,
                    height: mh,
                    depth_or_array_layers: 1,
                },
            );
        }
    }
    for layer in 0..layers {
        for mip in 0..mips {
            let level = read_texture(&ctx, &texture, layer, mip).unwrap();
            let (mw, mh) = ((w >> mip).max(1), (h >> mip).max(1));
            assert_eq!(
                (level.width, level.height, level.bytes_per_texel),
                (mw, mh, 4)
            );
            let texels: Vec<[u8; 4]> = level.cast();
            for y in 0..mh {
                for x in 0..mw {
                    assert_eq!(
                        texels[(y * mw + x) as usize],
                        texel(layer, mip, x, y),
                        "layer {layer} mip {mip} texel ({x}, {y})"
                    );
                }
            }
        }
    }
    assert!(read_texture(&ctx, &texture, layers, 0).is_err());
}
