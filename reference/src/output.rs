//! Writing what a frame produced: colour as sRGB8 PNG, depth as a float EXR, the LOD-id view as a
//! PNG (SPEC §3, §5.5), and difference images for failed comparisons.

use std::path::Path;

use crate::InputError;
use crate::draw::lod_id_color;
use crate::texture::Rgba8Image;

fn io_error(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::new(path.display().to_string(), "write", "", e.to_string())
}

/// Writes an RGBA8 image as PNG.
pub fn write_png(path: &Path, image: &Rgba8Image) -> Result<(), InputError> {
    let bytes: Vec<u8> = image.texels.iter().flatten().copied().collect();
    image::save_buffer(
        path,
        &bytes,
        image.width,
        image.height,
        image::ColorType::Rgba8,
    )
    .map_err(|e| io_error(path, e))
}

/// Largest side of a frame image read back (a case's reference, an implementation's outputs, a
/// golden), pixels: the largest viewport [`forestlod_shared::Camera::validate`] accepts.
pub const MAX_FRAME_SIDE: u32 = 16384;

/// The most bytes a frame image file of `width`x`height` pixels may have (issue 28, unbounded
/// reads): twice its 4 bytes a pixel (an RGBA8 PNG or an `f32` EXR that does not compress, with
/// its row filters, chunk tables and headers, stays well under) plus 1 MiB for metadata.
pub const fn frame_file_limit(width: u32, height: u32) -> u64 {
    2 * 4 * (width as u64) * (height as u64) + (1 << 20)
}

/// Largest frame image file read when its size is not known beforehand ([`read_png`],
/// [`read_depth_exr`]): [`frame_file_limit`] of a [`MAX_FRAME_SIDE`]² frame (2 GiB + 1 MiB).
pub const MAX_FRAME_FILE_BYTES: u64 = frame_file_limit(MAX_FRAME_SIDE, MAX_FRAME_SIDE);

/// Checks a declared image size against [`MAX_FRAME_SIDE`] and `expected` (issue 28: a header
/// may declare 100000x100000; refused before a pixel is decoded).
fn check_declared_size(
    file: &str,
    (width, height): (u64, u64),
    expected: Option<(u32, u32)>,
) -> Result<(u32, u32), InputError> {
    let size = format!("{width}x{height}");
    if let Some((w, h)) = expected
        && (width, height) != (u64::from(w), u64::from(h))
    {
        return Err(InputError::new(
            file,
            "declared size",
            size,
            format!("expected the case's {w}x{h}"),
        ));
    }
    let side = 1..=u64::from(MAX_FRAME_SIDE);
    if !(side.contains(&width) && side.contains(&height)) {
        return Err(InputError::new(
            file,
            "declared size",
            size,
            format!("expected 1..={MAX_FRAME_SIDE} pixels a side"),
        ));
    }
    Ok((width as u32, height as u32))
}

/// A PNG frame as decoded: the image as RGBA8 and the colour type its header declares.
#[derive(Clone, Debug)]
pub struct PngFrame {
    /// The image, converted to RGBA8.
    pub image: Rgba8Image,
    /// Whether the file is 8-bit RGBA (what [`write_png`] writes), i.e. nothing was converted.
    pub is_rgba8: bool,
    /// The declared colour type, in words (`Rgba8`, `Rgb16`, `L8`...).
    pub colour_type: String,
}

/// Decodes PNG `bytes` (`file` names them in errors) as an RGBA8 frame (any colour type is
/// converted, [`PngFrame::is_rgba8`] says whether it had to be). The size the header declares is
/// checked against `expected` (when given) and [`MAX_FRAME_SIDE`] before decoding, and the decoder
/// runs under an allocation limit of that size (issue 28).
pub fn decode_png_frame(
    bytes: &[u8],
    file: &str,
    expected: Option<(u32, u32)>,
) -> Result<PngFrame, InputError> {
    use image::ImageDecoder;
    let invalid = |e: image::ImageError| {
        InputError::new(
            file,
            "file",
            format!("{} bytes", bytes.len()),
            format!("invalid PNG: {e}"),
        )
    };
    // The header alone, without limits: its size is what is checked first.
    let decoder =
        image::codecs::png::PngDecoder::new(std::io::Cursor::new(bytes)).map_err(invalid)?;
    let (width, height) = decoder.dimensions();
    check_declared_size(file, (width.into(), height.into()), expected)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // The decoded image at up to 16 bytes a pixel (RGBA 16-bit, then its RGBA8 copy) and slack.
    limits.max_alloc = Some(16 * u64::from(width) * u64::from(height) + (1 << 20));
    let decoder = image::codecs::png::PngDecoder::with_limits(std::io::Cursor::new(bytes), limits)
        .map_err(invalid)?;
    let colour = decoder.color_type();
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(invalid)?
        .to_rgba8();
    Ok(PngFrame {
        image: Rgba8Image {
            width,
            height,
            texels: img.pixels().map(|p| p.0).collect(),
        },
        is_rgba8: colour == image::ColorType::Rgba8,
        colour_type: format!("{colour:?}"),
    })
}

/// Reads a PNG as RGBA8 (any colour type is converted): a regular file of at most
/// [`MAX_FRAME_FILE_BYTES`], at most [`MAX_FRAME_SIDE`] a side ([`decode_png_frame`]).
pub fn read_png(path: &Path) -> Result<Rgba8Image, InputError> {
    let bytes = crate::files::read_limited(path, MAX_FRAME_FILE_BYTES)?;
    Ok(decode_png_frame(&bytes, &path.display().to_string(), None)?.image)
}

/// Reads a PNG frame that must be `width`x`height`: a regular file of at most
/// [`frame_file_limit`]`(width, height)` bytes, its declared size checked before decoding.
pub fn read_png_sized(path: &Path, width: u32, height: u32) -> Result<PngFrame, InputError> {
    let bytes = crate::files::read_limited(path, frame_file_limit(width, height))?;
    decode_png_frame(&bytes, &path.display().to_string(), Some((width, height)))
}

/// Writes a depth buffer as a single-channel (`Z`) 32-bit float EXR.
pub fn write_depth_exr(
    path: &Path,
    width: u32,
    height: u32,
    depth: &[f32],
) -> Result<(), InputError> {
    use exr::prelude::*;
    let channel = AnyChannel::new("Z", FlatSamples::F32(depth.to_vec()));
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::named("depth"),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(smallvec::smallvec![channel]),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| io_error(path, e))
}

/// A depth EXR as decoded.
#[derive(Clone, Debug)]
pub struct DepthExr {
    /// Pixels.
    pub width: u32,
    /// Pixels.
    pub height: u32,
    /// One value a pixel, top row first.
    pub values: Vec<f32>,
    /// The channel's name (`Z` as [`write_depth_exr`] writes it).
    pub channel: String,
    /// Whether the channel holds 32-bit floats (as [`write_depth_exr`] writes them; else 16-bit).
    pub is_f32: bool,
}

/// Decodes EXR `bytes` (`file` names them in errors) as a depth buffer: one layer, flat (not
/// deep), exactly one float channel (16 or 32 bit). The header is read first: its size is checked
/// against `expected` (when given) and [`MAX_FRAME_SIDE`], and its layers and channels counted,
/// before a pixel is decoded (issue 28).
pub fn decode_depth_exr(
    bytes: &[u8],
    file: &str,
    expected: Option<(u32, u32)>,
) -> Result<DepthExr, InputError> {
    use exr::prelude::*;
    let invalid = |e: &dyn std::fmt::Display| {
        InputError::new(
            file,
            "file",
            format!("{} bytes", bytes.len()),
            format!("invalid EXR: {e}"),
        )
    };
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| invalid(&e))?;
    let [header] = meta.headers.as_slice() else {
        return Err(InputError::new(
            file,
            "layers",
            meta.headers.len(),
            "expected one layer holding the depth",
        ));
    };
    if header.deep {
        return Err(InputError::new(
            file,
            "layers",
            "deep data",
            "expected a flat layer",
        ));
    }
    let size = header.layer_size;
    let (width, height) = check_declared_size(file, (size.0 as u64, size.1 as u64), expected)?;
    let [channel] = header.channels.list.as_slice() else {
        let names: Vec<String> = header
            .channels
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        return Err(InputError::new(
            file,
            "channels",
            names.join(","),
            "expected exactly one channel (Z) holding the depth",
        ));
    };
    let name = channel.name.to_string();
    let is_f32 = match channel.sample_type {
        SampleType::F32 => true,
        SampleType::F16 => false,
        SampleType::U32 => {
            return Err(InputError::new(
                file,
                format!("channel {name}"),
                "u32",
                "expected float samples (f32, as depth is written)",
            ));
        }
    };
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| invalid(&e))?;
    let channel = image
        .layer_data
        .channel_data
        .list
        .first()
        .ok_or_else(|| invalid(&"no channel"))?;
    let values: Vec<f32> = channel.sample_data.values_as_f32().collect();
    if values.len() as u64 != u64::from(width) * u64::from(height) {
        return Err(InputError::new(
            file,
            format!("channel {name}"),
            format!("{} samples", values.len()),
            format!("expected {width}x{height}"),
        ));
    }
    Ok(DepthExr {
        width,
        height,
        values,
        channel: name,
        is_f32,
    })
}

/// Reads a single-channel float EXR written by [`write_depth_exr`]: a regular file of at most
/// [`MAX_FRAME_FILE_BYTES`], at most [`MAX_FRAME_SIDE`] a side ([`decode_depth_exr`]).
pub fn read_depth_exr(path: &Path) -> Result<(u32, u32, Vec<f32>), InputError> {
    let bytes = crate::files::read_limited(path, MAX_FRAME_FILE_BYTES)?;
    let d = decode_depth_exr(&bytes, &path.display().to_string(), None)?;
    Ok((d.width, d.height, d.values))
}

/// Reads a depth EXR that must be `width`x`height`: a regular file of at most
/// [`frame_file_limit`]`(width, height)` bytes, its declared size checked before decoding.
pub fn read_depth_exr_sized(path: &Path, width: u32, height: u32) -> Result<DepthExr, InputError> {
    let bytes = crate::files::read_limited(path, frame_file_limit(width, height))?;
    decode_depth_exr(&bytes, &path.display().to_string(), Some((width, height)))
}

/// The LOD-id view of E Fig. 3.1 as an image.
pub fn lod_id_image(width: u32, height: u32, ids: &[u32]) -> Rgba8Image {
    Rgba8Image {
        width,
        height,
        texels: ids.iter().map(|&id| lod_id_color(id)).collect(),
    }
}

/// A depth buffer as a grey image (near white, far and cleared black) for people to look at.
pub fn depth_preview(width: u32, height: u32, depth: &[f32]) -> Rgba8Image {
    Rgba8Image {
        width,
        height,
        texels: depth
            .iter()
            .map(|&d| {
                let v = if d >= 1.0 {
                    0
                } else {
                    (255.0 * (1.0 - d).powf(0.1)).round() as u8
                };
                [v, v, v, 255]
            })
            .collect(),
    }
}

/// Per-pixel absolute difference of two equally sized images, amplified x4 for visibility, with
/// the maximum per-channel difference.
pub fn difference_image(a: &Rgba8Image, b: &Rgba8Image) -> (Rgba8Image, u8) {
    let mut max = 0u8;
    let texels = a
        .texels
        .iter()
        .zip(&b.texels)
        .map(|(x, y)| {
            let d: [u8; 4] = core::array::from_fn(|c| x[c].abs_diff(y[c]));
            max = max.max(d.iter().copied().max().unwrap_or(0));
            [
                d[0].saturating_mul(4),
                d[1].saturating_mul(4),
                d[2].saturating_mul(4),
                255,
            ]
        })
        .collect();
    (
        Rgba8Image {
            width: a.width,
            height: a.height,
            texels,
        },
        max,
    )
}
