//! Textures: sRGB-encoded RGBA8 with straight alpha (SPEC §3), and the exact colour conversions
//! every stage uses.
//!
//! Decoding uses the exact sRGB transfer function in `f64`, rounded once to `f32` (a 256-entry
//! table); encoding rounds to nearest after the inverse function. Both match what a GPU's
//! `Rgba8UnormSrgb` format does to within the ±1 per channel that parity allows (SPEC §8).

/// A `width` x `height` image of texels `T`, row-major from the top-left texel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image<T> {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width * height` texels.
    pub texels: Vec<T>,
}

/// An RGBA8 image, row-major from the top-left texel, sRGB colour, straight alpha (linear).
pub type Rgba8Image = Image<[u8; 4]>;

/// A linear `f32` RGBA image (straight alpha), row-major from the top-left texel; each texel
/// `[r, g, b, a]` in linear light.
pub type LinearImage = Image<[f32; 4]>;

impl<T: Copy> Image<T> {
    /// A `width` x `height` image filled with `fill`.
    pub fn new(width: u32, height: u32, fill: T) -> Self {
        Self {
            width,
            height,
            texels: vec![fill; (width as usize) * (height as usize)],
        }
    }
    /// A `width` x `height` image whose texel at column `x`, row `y` is `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, f: impl Fn(u32, u32) -> T) -> Self {
        Self {
            width,
            height,
            texels: (0..height)
                .flat_map(|y| (0..width).map(move |x| (x, y)))
                .map(|(x, y)| f(x, y))
                .collect(),
        }
    }
    /// Texel at column `x`, row `y`.
    pub fn get(&self, x: u32, y: u32) -> T {
        self.texels[(y * self.width + x) as usize]
    }
    /// The same size, every texel through `f`.
    pub fn map<U>(&self, f: impl Fn(T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            texels: self.texels.iter().map(|&t| f(t)).collect(),
        }
    }
}

impl Rgba8Image {
    /// Decodes to linear light (colour through the sRGB curve, alpha as is).
    pub fn to_linear(&self) -> LinearImage {
        self.map(decode_texel)
    }
}

impl LinearImage {
    /// Encodes to sRGB8 (colour through the inverse curve, alpha linearly), rounding to nearest.
    pub fn to_rgba8(&self) -> Rgba8Image {
        self.map(encode_texel)
    }
}

/// Decodes one sRGB8 texel to linear light: colour by [`srgb_to_linear`], alpha as `byte / 255`.
pub fn decode_texel(t: [u8; 4]) -> [f32; 4] {
    [
        srgb_to_linear(t[0]),
        srgb_to_linear(t[1]),
        srgb_to_linear(t[2]),
        t[3] as f32 / 255.0,
    ]
}

/// Encodes one linear texel to sRGB8: colour by [`linear_to_srgb`], alpha by [`unorm8`], each
/// rounded to nearest.
pub fn encode_texel(t: [f32; 4]) -> [u8; 4] {
    [
        linear_to_srgb(t[0]),
        linear_to_srgb(t[1]),
        linear_to_srgb(t[2]),
        unorm8(t[3]),
    ]
}

/// The sRGB codec and UNORM quantization live in `forestlod-shared` (one definition for both
/// renderers); re-exported here, where the reference's texture code always found them.
pub use forestlod_shared::color::{linear_to_srgb, srgb_to_linear, unorm8};
// Their round-trip test lives with them (`shared/src/color.rs`).
