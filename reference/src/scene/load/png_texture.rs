//! Textures: 8-bit RGBA PNG files (module docs, "Meshes"). A texture must decode to 8-bit RGBA
//! (colour type 6 at bit depth 8, or a palette with transparency), be square, with a
//! power-of-two side of at most [`MAX_TEXTURE_SIDE`]; colour is sRGB, alpha straight. Every
//! refusal names the file and what it holds (e.g. the PNG's declared colour type).
//!
//! Depends on `paths` (reading the file).

use std::io::Cursor;
use std::path::Path;

use image::ImageDecoder;

use super::paths::{MAX_TEXTURE_FILE_BYTES, label, read_limited};
use crate::InputError;
use crate::texture::Rgba8Image;

/// Largest texture side accepted, texels.
pub const MAX_TEXTURE_SIDE: u32 = 4096;

/// Loads an 8-bit RGBA PNG texture ([`decode_png_texture`]).
pub fn load_png_texture(path: &Path) -> Result<Rgba8Image, InputError> {
    let bytes = read_limited(path, MAX_TEXTURE_FILE_BYTES)?;
    decode_png_texture(&bytes, &label(path))
}

/// The colour type and bit depth a PNG's header declares, in words: `RGB, 8-bit`, `palette,
/// 4-bit, no transparency`, `grey+alpha, 16-bit`... (`bytes` has been accepted by the decoder, so
/// its IHDR chunk is where the PNG standard puts it.)
fn png_colour_type_name(bytes: &[u8]) -> String {
    let (Some(&depth), Some(&colour)) = (bytes.get(24), bytes.get(25)) else {
        return "unknown".into();
    };
    let name = match colour {
        0 => "grey",
        2 => "RGB",
        3 => "palette",
        4 => "grey+alpha",
        6 => "RGBA",
        _ => return format!("colour type {colour}, {depth}-bit"),
    };
    // A palette or grey/RGB image may carry its transparency in a tRNS chunk.
    // (It comes before the first IDAT; walk the chunks up to there.)
    let mut has_trns = false;
    let mut at = 8usize;
    while let Some(header) = bytes.get(at..at + 8) {
        let length = u32::from_be_bytes([header[0], header[1], header[2], header[3]]) as usize;
        match &header[4..8] {
            b"tRNS" => has_trns = true,
            b"IDAT" => break,
            _ => {}
        }
        at = at.saturating_add(length).saturating_add(12);
    }
    let transparency = match (colour, has_trns) {
        (0 | 2 | 3, false) => ", no transparency",
        (0 | 2 | 3, true) => ", with tRNS transparency",
        _ => "",
    };
    format!("{name}, {depth}-bit{transparency}")
}

/// Decodes PNG `bytes` (`file` names them in errors) as a texture: the image must decode to 8-bit
/// RGBA (colour type 6 at bit depth 8, or a palette with transparency), square, with a power-of-two
/// side of at most [`MAX_TEXTURE_SIDE`]. Colour is taken as sRGB, alpha as straight (SPEC §3).
pub fn decode_png_texture(bytes: &[u8], file: &str) -> Result<Rgba8Image, InputError> {
    let size = format!("{} bytes", bytes.len());
    let decoder = image::codecs::png::PngDecoder::new(Cursor::new(bytes))
        .map_err(|e| InputError::new(file, "file", &size, format!("invalid PNG: {e}")))?;
    let (width, height) = decoder.dimensions();
    if decoder.color_type() != image::ColorType::Rgba8 {
        return Err(InputError::new(
            file,
            "colour type",
            png_colour_type_name(bytes),
            "expected RGBA, 8-bit (PNG colour type 6, straight alpha) or a palette with transparency (tRNS): re-export the texture as 8-bit RGBA",
        ));
    }
    for (what, side) in [("width", width), ("height", height)] {
        if side == 0 || !side.is_power_of_two() || side > MAX_TEXTURE_SIDE {
            return Err(InputError::new(
                file,
                what,
                side,
                format!("expected a power of two in 1..={MAX_TEXTURE_SIDE}"),
            ));
        }
    }
    // The mips stage (E Alg. 3.2) builds square chains only; say so here, where the file is known,
    // rather than in `prepare`, which no longer knows it.
    if width != height {
        return Err(InputError::new(
            file,
            "size",
            format!("{width}x{height}"),
            "expected a square texture (the mip chain of every texture is square)",
        ));
    }
    let image = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| InputError::new(file, "image data", &size, format!("invalid PNG: {e}")))?
        .into_rgba8();
    let texels = image.pixels().map(|p| p.0).collect();
    Ok(Rgba8Image {
        width,
        height,
        texels,
    })
}

#[cfg(test)]
mod tests {
    use super::super::test_util::assert_mentions;
    use super::*;

    fn png(color: image::ExtendedColorType, w: u32, h: u32) -> Vec<u8> {
        use image::ImageEncoder;
        let channels = match color {
            image::ExtendedColorType::Rgba8 => 4,
            image::ExtendedColorType::Rgb8 => 3,
            image::ExtendedColorType::L8 => 1,
            image::ExtendedColorType::Rgba16 => 8,
            _ => unreachable!(),
        };
        let data = vec![7u8; (w * h) as usize * channels];
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&data, w, h, color)
            .unwrap();
        out
    }

    #[test]
    fn png_must_be_rgba8_power_of_two_and_small() {
        use image::ExtendedColorType::{L8, Rgb8, Rgba8, Rgba16};
        let t = decode_png_texture(&png(Rgba8, 8, 8), "t.png").unwrap();
        assert_eq!((t.width, t.height), (8, 8));
        assert_eq!(t.texels[0], [7, 7, 7, 7]);
        let err = |bytes: &[u8]| decode_png_texture(bytes, "t.png").unwrap_err().to_string();
        let e = err(&png(Rgba8, 8, 4));
        assert_mentions(&e, &["t.png", "8x4", "square"]);
        let e = err(&png(Rgb8, 8, 8));
        assert_mentions(&e, &["t.png", "colour type", "RGB, 8-bit"]);
        let e = err(&png(L8, 8, 8));
        assert!(e.contains("colour type"), "{e}");
        let e = err(&png(Rgba16, 8, 8));
        assert!(e.contains("colour type"), "{e}");
        let e = err(&png(Rgba8, 6, 8));
        assert_mentions(&e, &["width", "6"]);
        let e = err(&png(Rgba8, 8192, 1));
        assert_mentions(&e, &["width", "8192"]);
        let e = err(b"not a png");
        assert!(e.contains("invalid PNG"), "{e}");
        let full = png(Rgba8, 8, 8);
        assert!(decode_png_texture(&full[..full.len() / 2], "t.png").is_err());
    }
}
