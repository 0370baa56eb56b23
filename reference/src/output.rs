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

/// Reads a PNG as RGBA8 (any colour type is converted).
pub fn read_png(path: &Path) -> Result<Rgba8Image, InputError> {
    let img = image::open(path)
        .map_err(|e| InputError::new(path.display().to_string(), "read", "", e.to_string()))?
        .to_rgba8();
    let (width, height) = img.dimensions();
    Ok(Rgba8Image {
        width,
        height,
        texels: img.pixels().map(|p| p.0).collect(),
    })
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

/// Reads a single-channel float EXR written by [`write_depth_exr`].
pub fn read_depth_exr(path: &Path) -> Result<(u32, u32, Vec<f32>), InputError> {
    use exr::prelude::*;
    let err = |e: &dyn std::fmt::Display| {
        InputError::new(path.display().to_string(), "read", "", e.to_string())
    };
    let image = read_first_flat_layer_from_file(path).map_err(|e| err(&e))?;
    let size = image.layer_data.size;
    let channel = image
        .layer_data
        .channel_data
        .list
        .first()
        .ok_or_else(|| err(&"no channel"))?;
    let values: Vec<f32> = channel.sample_data.values_as_f32().collect();
    Ok((size.0 as u32, size.1 as u32, values))
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
