//! Texture sampling as a GPU does it: sRGB RGBA8 textures with a mip chain and array layers,
//! clamp-to-edge addressing, nearest / bilinear / trilinear filtering and the implicit level of
//! detail from screen-space derivatives (SPEC §3, §8).
//!
//! ## Contract
//!
//! - **Texels** are sRGB-encoded RGBA8 with straight alpha ([`Rgba8Image`]). A fetched texel is
//!   decoded to linear light *before* any filtering (Vulkan §"Texel Input Operations", "sRGB to
//!   linear conversion" precedes §"Texel Filtering"), exactly as an `Rgba8UnormSrgb` view is
//!   sampled: colour through the sRGB curve, alpha as `a / 255`. Results are linear `[f32; 4]`,
//!   straight alpha (filtering does not premultiply).
//! - **Coordinates** `uv` are normalized: `(0, 0)` is the top-left corner of the texture, `(1, 1)` the
//!   bottom-right; texel `i` of a level of width `w` covers `u·w ∈ [i, i + 1)`, its centre at
//!   `i + 0.5` (Vulkan §"Texel Coordinate Systems"). The same `uv` addresses every mip level.
//! - **Addressing** is clamp-to-edge (Vulkan §"Wrapping Operation", `CLAMP_TO_EDGE`): each integer
//!   texel index is clamped to `[0, size - 1]` after filtering picks it. Array layers are clamped to
//!   `[0, layers - 1]` as Vulkan clamps the layer coordinate.
//! - **Nearest** (Vulkan §"Texel Filtering", `NEAREST`): texel `i = floor(u·w)`.
//! - **Bilinear** (`LINEAR`): `i0 = floor(u·w - 0.5)`, `i1 = i0 + 1`, `α = frac(u·w - 0.5)`,
//!   likewise `j0, j1, β` in v, and `τ = (1-α)(1-β)·τ00 + α(1-β)·τ10 + (1-α)β·τ01 + αβ·τ11`. At a
//!   texel centre `α = β = 0` and the texel comes back bit for bit.
//! - **Level of detail** (Vulkan §"Scale Factor Operation", §"Level-of-Detail Operation", §"Image
//!   Level(s) Selection"), from the derivatives of `uv` along framebuffer x and y:
//!   - scale to texels of level 0: `∂u/∂x·w0`, `∂v/∂x·h0`, `∂u/∂y·w0`, `∂v/∂y·h0`;
//!   - `ρx = |(∂u/∂x·w0, ∂v/∂x·h0)|`, `ρy = |(∂u/∂y·w0, ∂v/∂y·h0)|` (Euclidean lengths);
//!   - isotropic filtering: `ρ = max(ρx, ρy)` ("max of lengths"), `η = 1`, `λ_base = log2(ρ)`.
//!     Vulkan allows implementations to approximate `ρx`, `ρy` (for instance by the largest
//!     absolute component, lavapipe's opt-in `GALLIVM_PERF=rho_approx`); we use the exact lengths,
//!     which is lavapipe's default. [`LodRule`] names the alternatives the specification allows
//!     (its recommended ellipse major axis, which the NVIDIA H200 uses, and its two bounds):
//!     `forestlod-harness` draws reference frames under them to classify the GPU pixels a
//!     conforming adapter's other λ explains; [`Sampler::lod_rule`] is [`LodRule::Exact`]
//!     everywhere else;
//!   - no bias, `minLod = 0`, `maxLod` large (wgpu's sampler defaults): `λ = λ_base`;
//!     **magnification** when `λ <= 0` (the mag filter is used, on level 0), minification otherwise;
//!   - `d' = clamp(λ, 0, q)` with `q = levels - 1` ([`SamplerLod::lambda`]). Mipmap mode nearest:
//!     level `ceil(d' + 0.5) - 1` (Vulkan's preferred rounding, halves go down). Mipmap mode linear
//!     (trilinear): levels `floor(d')` and `min(floor(d') + 1, q)`, blended by `δ = frac(d')`.
//!   - `ρ = 0` gives `λ = -∞` (magnified, level 0); an infinite or NaN `ρ` (derivatives that blew
//!     up, e.g. at helper pixels beyond a grazing plane's horizon) is treated as `+∞`: the coarsest
//!     level. Vulkan leaves NaN undefined; this choice is documented, not matched.
//!
//! ## Precision against the GPU
//!
//! Filter weights here are exact `f32` fractions. lavapipe quantizes them to 8 bits of subtexel
//! precision (`subTexelPrecisionBits` = 8) and blends in reduced precision, so a filtered result
//! may differ from this one by up to ±1 per channel after encoding to 8 bits; parity allows
//! exactly that (SPEC §8). Trilinear is true trilinear on both sides (lavapipe's "brilinear"
//! shortcut is opt-in, `GALLIVM_PERF=brilinear`). The implicit LOD uses one derivative pair per 2x2 quad on both sides
//! (the rasterizer's coarse derivatives; lavapipe's default per-quad LOD), so `λ` itself agrees up
//! to the GPU's `log2` approximation.
//!
//! ## Speed-ups (issue 14), each an equality
//!
//! - Texels are decoded to linear light once, when the [`Texture`] is made, not at every fetch:
//!   decoding is a pure function of the byte texel (relies on nothing else; checked by
//!   `decoded_levels_equal_decoding_at_fetch`). Costs 16 bytes per texel beside the 4 of the
//!   sRGB level.
//! - A bilinear fetch clamps each of its two columns and two rows once, and takes its texel
//!   indices from the floors it already computed for the weights.
//! - `floor_exact` replaces libm's `floorf` (see there).
//! - The implicit LOD's `λ` is remembered per thread for the last derivatives and size
//!   (`Texture::lambda_base`): a pure function of its key, so a hit is the call's value; the
//!   quads' shared derivatives make three of four fragments hits.

use crate::texture::{Rgba8Image, decode_texel};

/// A texture whose shape cannot be sampled: every variant names the layer/level and sizes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TextureShapeError {
    /// No layers at all.
    #[error("texture has no array layers")]
    NoLayers,
    /// A layer without levels.
    #[error("texture layer {layer} has no mip levels")]
    NoLevels {
        /// The layer.
        layer: usize,
    },
    /// Level 0 of zero size.
    #[error("texture layer {layer} level 0 is {width}x{height}: expected at least 1x1")]
    Empty {
        /// The layer.
        layer: usize,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
    },
    /// Layers disagree on the level count, or a chain is longer than halving allows.
    #[error("texture layer {layer} has {found} mip levels: expected {expected}")]
    LevelCount {
        /// The layer.
        layer: usize,
        /// Levels found.
        found: usize,
        /// Levels expected (layer 0's count, at most the full chain's).
        expected: usize,
    },
    /// A level whose size is not `max(1, size0 >> level)`, or whose texel count is not its area.
    #[error(
        "texture layer {layer} level {level} is {width}x{height} with {texels} texels: expected {expected_width}x{expected_height}"
    )]
    LevelSize {
        /// The layer.
        layer: usize,
        /// The level.
        level: usize,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// Its texel count.
        texels: usize,
        /// The width it must have.
        expected_width: u32,
        /// The height it must have.
        expected_height: u32,
    },
}

/// A sampled texture: array layers, each a mip chain of sRGB RGBA8 levels of halving size.
///
/// Speed-up (issue 14): every texel is also held decoded to linear light ([`LinearLevel`]),
/// decoded once when the texture is made instead of at every fetch. Decoding
/// ([`crate::texture::decode_texel`]) is a pure function of the byte texel, so a fetch from the
/// decoded copy returns exactly what decoding the fetched byte texel would (checked by
/// `decoded_levels_equal_decoding_at_fetch`). Costs 16 bytes per texel beside the 4 of the sRGB
/// level (about 11 MB for the built-in billboard atlas).
#[derive(Clone, Debug)]
pub struct Texture {
    /// `layers[layer][level]`.
    layers: Vec<Vec<Rgba8Image>>,
    /// `linear[layer][level]`: the same levels decoded to linear light.
    linear: Vec<Vec<LinearLevel>>,
}

/// Equal when the sRGB levels are (the decoded copies are a function of them).
impl PartialEq for Texture {
    fn eq(&self, other: &Self) -> bool {
        self.layers == other.layers
    }
}

impl Eq for Texture {}

impl Texture {
    /// Bytes of texel data held: every level as RGBA8 and decoded to linear `f32` RGBA (the
    /// bake's memory estimate, `bake::bake_memory_bytes`, counts the same).
    pub fn heap_bytes(&self) -> u64 {
        let rgba8: usize = self
            .layers
            .iter()
            .flatten()
            .map(|l| 4 * l.texels.len())
            .sum();
        let linear: usize = self
            .linear
            .iter()
            .flatten()
            .map(|l| 16 * l.texels.len())
            .sum();
        (rgba8 + linear) as u64
    }
}

/// One mip level decoded to linear light, row-major from the top-left texel.
#[derive(Clone, Debug)]
struct LinearLevel {
    width: u32,
    height: u32,
    /// `(width as f32, height as f32)`: the same conversions, done once instead of at every
    /// sample (session 12, issue 14).
    size: (f32, f32),
    texels: Vec<[f32; 4]>,
}

impl LinearLevel {
    fn decode(img: &Rgba8Image) -> Self {
        Self {
            width: img.width,
            height: img.height,
            size: (img.width as f32, img.height as f32),
            texels: img.texels.iter().map(|&t| decode_texel(t)).collect(),
        }
    }

    /// Texel `(x, y)`, clamp-to-edge.
    #[inline]
    fn at(&self, x: i64, y: i64) -> [f32; 4] {
        let x = x.clamp(0, self.width as i64 - 1) as usize;
        let y = y.clamp(0, self.height as i64 - 1) as usize;
        self.texels[y * self.width as usize + x]
    }

    /// [`LinearLevel::at`] of `(i, j)`, `(i + 1, j)`, `(i, j + 1)` and `(i + 1, j + 1)`, each
    /// coordinate clamped once.
    #[inline]
    fn quad(&self, i: i64, j: i64) -> [[f32; 4]; 4] {
        let w = self.width as usize;
        let column = |x: i64| x.clamp(0, self.width as i64 - 1) as usize;
        let row = |y: i64| y.clamp(0, self.height as i64 - 1) as usize * w;
        let (x0, x1, y0, y1) = (column(i), column(i + 1), row(j), row(j + 1));
        let t = &self.texels;
        [t[y0 + x0], t[y0 + x1], t[y1 + x0], t[y1 + x1]]
    }
}

/// How texels are filtered within one level (wgpu's `FilterMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FilterMode {
    /// The texel containing the sample point.
    #[default]
    Nearest,
    /// Bilinear between the four nearest texel centres (or linear between two levels, as the
    /// mipmap filter).
    Linear,
}

/// How the implicit level of detail's scale factor `ρ` is computed from the derivatives in
/// level-0 texels per pixel, `m_ux = |∂u/∂x|·w0`, `m_vx = |∂v/∂x|·h0` and likewise along y
/// (Vulkan, "Scale Factor Operation"): the exact lengths, or a model the specification allows.
/// Measured on real adapters by `tests/tests/parity/sampler_lod.rs`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LodRule {
    /// `ρ = max(ρx, ρy)` with the Euclidean lengths (module docs): the reference's, lavapipe's.
    #[default]
    Exact,
    /// `ρ` the major axis of the footprint's ellipse, the larger singular value of the 2x2
    /// Jacobian (the specification: `ρ_max` "should be" the ellipse's major axis). The NVIDIA
    /// H200 (driver 580.159.04) computes this: up to 0.5 of a level above [`LodRule::Exact`]
    /// where the two derivatives are sheared, equal where they are orthogonal.
    Ellipse,
    /// The specification's lower bound: `ρx >= max(m_ux, m_vx)` (and likewise `ρy`).
    SpecLower,
    /// The specification's upper bound: `ρx <= sqrt(2) (m_ux + m_vx)` (and likewise `ρy`).
    SpecUpper,
}

/// Filter state of a sampler (wgpu's `SamplerDescriptor` filters; addressing is always
/// clamp-to-edge, LOD clamps are wgpu's defaults).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    /// Filter within a level when magnified (`λ <= 0`).
    pub mag_filter: FilterMode,
    /// Filter within a level when minified (`λ > 0`).
    pub min_filter: FilterMode,
    /// Filter between mip levels.
    pub mipmap_filter: FilterMode,
    /// How the implicit level of detail's `ρ` is computed ([`LodRule::Exact`] in every sampler
    /// of the pipeline).
    pub lod_rule: LodRule,
}

impl Sampler {
    /// Nearest texel of the nearest level.
    pub const NEAREST: Self = Self {
        mag_filter: FilterMode::Nearest,
        min_filter: FilterMode::Nearest,
        mipmap_filter: FilterMode::Nearest,
        lod_rule: LodRule::Exact,
    };
    /// Bilinear within the nearest level.
    pub const BILINEAR: Self = Self {
        mag_filter: FilterMode::Linear,
        min_filter: FilterMode::Linear,
        mipmap_filter: FilterMode::Nearest,
        lod_rule: LodRule::Exact,
    };
    /// Bilinear within two levels, blended linearly.
    pub const TRILINEAR: Self = Self {
        mag_filter: FilterMode::Linear,
        min_filter: FilterMode::Linear,
        mipmap_filter: FilterMode::Linear,
        lod_rule: LodRule::Exact,
    };
}

/// The level-of-detail computation for one set of derivatives (module docs), exposed for tests
/// and debug views.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplerLod {
    /// Length of the x derivative in level-0 texels per pixel.
    pub rho_x: f32,
    /// Length of the y derivative in level-0 texels per pixel.
    pub rho_y: f32,
    /// `max(ρx, ρy)`; NaN if either is NaN.
    pub rho: f32,
    /// `log2(ρ)`, unclamped (may be `±∞` or NaN).
    pub lambda_base: f32,
    /// `λ_base` clamped to `[0, levels - 1]`, NaN read as `+∞`: the (fractional) level sampled.
    pub lambda: f32,
    /// Whether the mag filter applies (`λ_base <= 0`).
    pub magnified: bool,
}

impl Texture {
    /// A single-layer texture from its mip chain (level 0 first).
    pub fn new(levels: Vec<Rgba8Image>) -> Result<Self, TextureShapeError> {
        Self::new_array(vec![levels])
    }

    /// An array texture: `layers[layer][level]`. Every layer has the same level count and sizes;
    /// level `k` is `max(1, w0 >> k)` x `max(1, h0 >> k)`; a chain may stop before 1x1.
    pub fn new_array(layers: Vec<Vec<Rgba8Image>>) -> Result<Self, TextureShapeError> {
        let first = layers.first().ok_or(TextureShapeError::NoLayers)?;
        let base = first
            .first()
            .ok_or(TextureShapeError::NoLevels { layer: 0 })?;
        let (w0, h0) = (base.width, base.height);
        let full_chain = (32 - w0.max(h0).leading_zeros()) as usize;
        let expected = first.len().min(full_chain.max(1));
        for (layer, levels) in layers.iter().enumerate() {
            let Some(l0) = levels.first() else {
                return Err(TextureShapeError::NoLevels { layer });
            };
            if l0.width == 0 || l0.height == 0 {
                return Err(TextureShapeError::Empty {
                    layer,
                    width: l0.width,
                    height: l0.height,
                });
            }
            if levels.len() != expected {
                return Err(TextureShapeError::LevelCount {
                    layer,
                    found: levels.len(),
                    expected,
                });
            }
            for (level, img) in levels.iter().enumerate() {
                let (ew, eh) = ((w0 >> level).max(1), (h0 >> level).max(1));
                if img.width != ew
                    || img.height != eh
                    || img.texels.len() != ew as usize * eh as usize
                {
                    return Err(TextureShapeError::LevelSize {
                        layer,
                        level,
                        width: img.width,
                        height: img.height,
                        texels: img.texels.len(),
                        expected_width: ew,
                        expected_height: eh,
                    });
                }
            }
        }
        let linear = layers
            .iter()
            .map(|levels| levels.iter().map(LinearLevel::decode).collect())
            .collect();
        Ok(Self { layers, linear })
    }

    /// Width of level 0.
    pub fn width(&self) -> u32 {
        self.layers[0][0].width
    }

    /// Height of level 0.
    pub fn height(&self) -> u32 {
        self.layers[0][0].height
    }

    /// Number of mip levels (`q + 1`).
    pub fn level_count(&self) -> usize {
        self.layers[0].len()
    }

    /// Number of array layers.
    pub fn layer_count(&self) -> usize {
        self.layers.len()
    }

    /// One level of one layer, both clamped to what exists.
    #[inline]
    pub fn level(&self, layer: u32, level: usize) -> &Rgba8Image {
        let levels = &self.layers[(layer as usize).min(self.layers.len() - 1)];
        &levels[level.min(levels.len() - 1)]
    }

    /// One level of one layer decoded to linear light, both clamped to what exists.
    #[inline]
    fn linear_level(&self, layer: u32, level: usize) -> &LinearLevel {
        let levels = &self.linear[(layer as usize).min(self.linear.len() - 1)];
        &levels[level.min(levels.len() - 1)]
    }

    /// Texel `(x, y)` of a level, clamp-to-edge, decoded to linear light (colour through the sRGB
    /// curve, alpha as `a / 255`; read from the decoded copy, see [`Texture`]).
    #[inline]
    pub fn texel(&self, layer: u32, level: usize, x: i64, y: i64) -> [f32; 4] {
        self.linear_level(layer, level).at(x, y)
    }

    /// Nearest-texel sample of one level: texel `floor(uv · size)`, clamped.
    pub fn nearest(&self, layer: u32, level: usize, uv: [f32; 2]) -> [f32; 4] {
        let img = self.linear_level(layer, level);
        let u = uv[0] * img.size.0;
        let v = uv[1] * img.size.1;
        img.at(floor_index(u), floor_index(v))
    }

    /// Bilinear sample of one level (module docs): exact `f32` weights, filtered in linear light.
    #[inline]
    pub fn bilinear(&self, layer: u32, level: usize, uv: [f32; 2]) -> [f32; 4] {
        let img = self.linear_level(layer, level);
        let u = uv[0] * img.size.0 - 0.5;
        let v = uv[1] * img.size.1 - 0.5;
        let (fu, fv) = (floor_exact(u), floor_exact(v));
        let (alpha, beta) = (u - fu, v - fv);
        // `floor_index(u)` is `floor_exact(u) as i64`: the floors above, not computed again.
        let (i0, j0) = (fu as i64, fv as i64);
        let [t00, t10, t01, t11] = img.quad(i0, j0);
        let mut out = [0.0f32; 4];
        for (c, o) in out.iter_mut().enumerate() {
            *o = (1.0 - alpha) * (1.0 - beta) * t00[c]
                + alpha * (1.0 - beta) * t10[c]
                + (1.0 - alpha) * beta * t01[c]
                + alpha * beta * t11[c];
        }
        out
    }

    /// Trilinear sample at fractional level `lambda` (clamped to `[0, levels - 1]`): bilinear in
    /// levels `floor(λ)` and `floor(λ) + 1`, blended by `frac(λ)`.
    pub fn trilinear(&self, layer: u32, uv: [f32; 2], lambda: f32) -> [f32; 4] {
        self.sample_level(&Sampler::TRILINEAR, layer, uv, lambda.max(0.0))
    }

    /// The level of detail for `uv` derivatives along framebuffer x (`ddx`) and y (`ddy`).
    #[inline]
    pub fn lod(&self, ddx: [f32; 2], ddy: [f32; 2]) -> SamplerLod {
        self.lod_by(LodRule::Exact, ddx, ddy)
    }

    /// [`Texture::lod`] with `ρ` computed by `rule` ([`LodRule`]; `rho_x`, `rho_y` stay the
    /// exact lengths).
    #[inline]
    pub fn lod_by(&self, rule: LodRule, ddx: [f32; 2], ddy: [f32; 2]) -> SamplerLod {
        let (w0, h0) = (self.width() as f32, self.height() as f32);
        let length = |d: [f32; 2]| {
            let (du, dv) = (d[0] * w0, d[1] * h0);
            (du * du + dv * dv).sqrt()
        };
        let (rho_x, rho_y) = (length(ddx), length(ddy));
        let rho = if rho_x.is_nan() || rho_y.is_nan() {
            f32::NAN
        } else {
            match rule {
                LodRule::Exact => rho_x.max(rho_y),
                LodRule::Ellipse => {
                    let m = [ddx[0] * w0, ddx[1] * h0, ddy[0] * w0, ddy[1] * h0].map(f64::from);
                    let s = m.iter().map(|x| x * x).sum::<f64>();
                    let det = m[0] * m[3] - m[1] * m[2];
                    ((s + (s * s - 4.0 * det * det).max(0.0).sqrt()) / 2.0).sqrt() as f32
                }
                LodRule::SpecLower => (ddx[0] * w0)
                    .abs()
                    .max((ddx[1] * h0).abs())
                    .max((ddy[0] * w0).abs().max((ddy[1] * h0).abs())),
                LodRule::SpecUpper => {
                    std::f32::consts::SQRT_2
                        * ((ddx[0] * w0).abs() + (ddx[1] * h0).abs())
                            .max((ddy[0] * w0).abs() + (ddy[1] * h0).abs())
                }
            }
        };
        let lambda_base = rho.log2();
        SamplerLod {
            rho_x,
            rho_y,
            rho,
            lambda_base,
            lambda: self.clamp_lambda(lambda_base),
            magnified: lambda_base <= 0.0,
        }
    }

    /// Samples with the implicit level of detail of `uv`'s derivatives, like WGSL `textureSample`.
    #[inline]
    pub fn sample(
        &self,
        sampler: &Sampler,
        layer: u32,
        uv: [f32; 2],
        ddx: [f32; 2],
        ddy: [f32; 2],
    ) -> [f32; 4] {
        self.sample_level(
            sampler,
            layer,
            uv,
            self.lambda_base(sampler.lod_rule, ddx, ddy),
        )
    }

    /// [`SamplerLod::lambda_base`] of [`Texture::lod`], remembered per thread for the last
    /// derivatives and level-0 size it was asked for: the four fragments of a 2x2 quad carry
    /// the same (coarse) derivatives, so three of them find their `λ` here instead of in two
    /// square roots and a `log2f` (issue 14, session 10). The key is every input of
    /// [`Texture::lod`] as bits, so a hit returns what the call would, bit for bit.
    ///
    /// The key is three `u64`s built in registers (session 11): built as a `[u32; 6]` on the
    /// stack and compared as two vectors, the compare's 16-byte load could not be forwarded from
    /// the key's narrower stores and stalled; that one instruction held a fifth of the tree
    /// shader's samples (`perf annotate`).
    #[inline]
    /// The rule is part of the key (in the top bits of the height, far above any texture size).
    fn lambda_base(&self, rule: LodRule, ddx: [f32; 2], ddy: [f32; 2]) -> f32 {
        type Key = (u64, u64, u64);
        thread_local! {
            static LAST: std::cell::Cell<(Key, f32)> = const {
                // No texture has size 0, so this key matches no call.
                std::cell::Cell::new(((0, 0, 0), 0.0))
            };
        }
        let pair = |a: u32, b: u32| (u64::from(a) << 32) | u64::from(b);
        let key = (
            pair(self.width(), self.height() | ((rule as u32) << 30)),
            pair(ddx[0].to_bits(), ddx[1].to_bits()),
            pair(ddy[0].to_bits(), ddy[1].to_bits()),
        );
        LAST.with(|last| {
            let (k, lambda) = last.get();
            if k == key {
                return lambda;
            }
            let lambda = self.lod_by(rule, ddx, ddy).lambda_base;
            last.set((key, lambda));
            lambda
        })
    }

    /// Samples at an explicit `λ` (before clamping to the chain), like WGSL `textureSampleLevel`.
    #[inline]
    pub fn sample_level(
        &self,
        sampler: &Sampler,
        layer: u32,
        uv: [f32; 2],
        lambda: f32,
    ) -> [f32; 4] {
        let magnified = lambda <= 0.0;
        let filter = if magnified {
            sampler.mag_filter
        } else {
            sampler.min_filter
        };
        let d = self.clamp_lambda(lambda);
        let q = self.level_count() - 1;
        match sampler.mipmap_filter {
            FilterMode::Nearest => {
                let level = if magnified {
                    0
                } else {
                    ((d + 0.5).ceil() - 1.0) as usize
                };
                self.filter(filter, layer, level.min(q), uv)
            }
            FilterMode::Linear => {
                let hi = floor_exact(d);
                let delta = d - hi;
                let hi = hi as usize;
                let t_hi = self.filter(filter, layer, hi, uv);
                if delta == 0.0 {
                    return t_hi;
                }
                let t_lo = self.filter(filter, layer, (hi + 1).min(q), uv);
                let mut out = [0.0f32; 4];
                for (c, o) in out.iter_mut().enumerate() {
                    *o = (1.0 - delta) * t_hi[c] + delta * t_lo[c];
                }
                out
            }
        }
    }

    #[inline]
    fn filter(&self, mode: FilterMode, layer: u32, level: usize, uv: [f32; 2]) -> [f32; 4] {
        match mode {
            FilterMode::Nearest => self.nearest(layer, level, uv),
            FilterMode::Linear => self.bilinear(layer, level, uv),
        }
    }

    /// `clamp(λ, 0, q)`, NaN read as `+∞`.
    #[inline]
    fn clamp_lambda(&self, lambda: f32) -> f32 {
        let q = (self.level_count() - 1) as f32;
        if lambda.is_nan() {
            q
        } else {
            lambda.clamp(0.0, q)
        }
    }
}

/// `floor(c)` as a texel index; non-finite or huge coordinates saturate (and then clamp to the
/// edge).
fn floor_index(c: f32) -> i64 {
    floor_exact(c) as i64
}

/// `c.floor()` bit for bit (signed zeros and infinities included; a NaN stays a NaN, its payload
/// possibly quieted) without a call to libm's
/// `floorf`, which is what `f32::floor` compiles to on x86-64's baseline (no SSE4.1 `roundss`):
/// three calls per bilinear sample were 3 % of the reference frame (issue 14). A value of
/// magnitude at least 2^23, a NaN, an infinity or a zero is already integral and returned as it
/// is; otherwise truncation towards zero through `i32` is exact, and one is subtracted when that
/// rounded a negative value up. Checked against `f32::floor` by `floor_exact_equals_floor`.
///
/// Where SSE4.1 is enabled at compile time (this workspace's `.cargo/config.toml` builds for
/// x86-64-v2 on x86-64), `f32::floor` is the single instruction `roundss` and is used as is
/// (session 10: the branches and conversions below were 6 % of the `medium` frame's samples).
#[inline]
fn floor_exact(c: f32) -> f32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    return c.floor();
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    floor_by_truncation(c)
}

/// [`floor_exact`] without `roundss`: truncation through `i32` (see there).
#[cfg_attr(
    all(target_arch = "x86_64", target_feature = "sse4.1"),
    allow(dead_code)
)]
#[inline]
fn floor_by_truncation(c: f32) -> f32 {
    if c.is_nan() || c.abs() >= 8_388_608.0 || c == 0.0 {
        return c;
    }
    let t = c as i32 as f32;
    if t > c { t - 1.0 } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{linear_to_srgb, srgb_to_linear};

    /// A `w` x `h` level whose texel `(x, y)` has red `8x`, green `8y`, blue `30·level`, alpha
    /// `255 - x` (all mod 256).
    fn gradient(w: u32, h: u32, level: u8) -> Rgba8Image {
        let mut img = Rgba8Image::new(w, h, [0; 4]);
        for y in 0..h {
            for x in 0..w {
                img.texels[(y * w + x) as usize] = [
                    (x * 8 % 256) as u8,
                    (y * 8 % 256) as u8,
                    level.wrapping_mul(30),
                    255 - (x % 256) as u8,
                ];
            }
        }
        img
    }

    fn chain(w: u32, h: u32) -> Vec<Rgba8Image> {
        let mut levels = Vec::new();
        let (mut w, mut h, mut k) = (w, h, 0u8);
        loop {
            levels.push(gradient(w, h, k));
            if w == 1 && h == 1 {
                return levels;
            }
            (w, h, k) = ((w / 2).max(1), (h / 2).max(1), k + 1);
        }
    }

    fn linear(t: [u8; 4]) -> [f32; 4] {
        [
            srgb_to_linear(t[0]),
            srgb_to_linear(t[1]),
            srgb_to_linear(t[2]),
            t[3] as f32 / 255.0,
        ]
    }

    fn close(a: [f32; 4], b: [f32; 4]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-6)
    }

    /// The decoded copy (speed-up, [`Texture`]) returns, for every texel of every level and
    /// layer and for indices past every edge, the bits that decoding the byte texel at the
    /// clamped position gives.
    #[test]
    fn decoded_levels_equal_decoding_at_fetch() {
        let mut second = chain(16, 8);
        for level in &mut second {
            for t in &mut level.texels {
                *t = [t[1], t[0], t[3], t[2].wrapping_add(77)];
            }
        }
        let tex = Texture::new_array(vec![chain(16, 8), second]).unwrap();
        for layer in 0..3u32 {
            for level in 0..tex.level_count() + 1 {
                let img = tex.level(layer, level);
                for y in -2..img.height as i64 + 2 {
                    for x in -2..img.width as i64 + 2 {
                        let byte = img.get(
                            x.clamp(0, img.width as i64 - 1) as u32,
                            y.clamp(0, img.height as i64 - 1) as u32,
                        );
                        let expected = linear(byte).map(f32::to_bits);
                        let got = tex.texel(layer, level, x, y).map(f32::to_bits);
                        assert_eq!(
                            got, expected,
                            "layer {layer} level {level} texel ({x}, {y})"
                        );
                    }
                }
            }
        }
        // Every byte value of every channel passes through the decoded copy.
        let all = Rgba8Image {
            width: 256,
            height: 1,
            texels: (0..=255u8).map(|b| [b, 255 - b, b ^ 0x5a, b]).collect(),
        };
        let tex = Texture::new(vec![all.clone()]).unwrap();
        for (x, &t) in all.texels.iter().enumerate() {
            let got = tex.texel(0, 0, x as i64, 0).map(f32::to_bits);
            assert_eq!(got, linear(t).map(f32::to_bits), "byte texel {t:?}");
        }
    }

    /// `floor_exact` equals `f32::floor` bit for bit: special values, both sides of every integer
    /// near zero, and a sample of bit patterns over the whole `f32` range. A NaN gives a NaN:
    /// its bits are not compared, since `roundss` (SSE4.1) quiets a signalling NaN that the
    /// truncation fallback returns as it is, and libm's `floorf` may do either.
    #[test]
    fn floor_exact_equals_floor() {
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let check = |c: f32| {
            assert!(
                same(floor_exact(c), c.floor()),
                "floor({c:e}) ({:#x})",
                c.to_bits()
            );
            // The fallback for builds without SSE4.1, tested whatever this build uses.
            assert!(
                same(floor_by_truncation(c), c.floor()),
                "floor_by_truncation({c:e}) ({:#x})",
                c.to_bits()
            );
            assert_eq!(floor_index(c), c.floor() as i64, "floor_index({c:e})");
        };
        for c in [
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::MAX,
            f32::MIN,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            1e30,
            -1e30,
        ] {
            check(c);
        }
        for i in -300..=300 {
            let c = i as f32 * 0.5;
            for b in [c.to_bits().wrapping_sub(1), c.to_bits(), c.to_bits() + 1] {
                check(f32::from_bits(b));
            }
        }
        for bits in (0..=u32::MAX).step_by(65_521) {
            check(f32::from_bits(bits));
        }
    }

    #[test]
    fn bilinear_at_texel_centres_returns_the_texel_exactly() {
        let tex = Texture::new(chain(16, 8)).unwrap();
        for level in 0..tex.level_count() {
            let img = tex.level(0, level).clone();
            for y in 0..img.height {
                for x in 0..img.width {
                    let uv = [
                        (x as f32 + 0.5) / img.width as f32,
                        (y as f32 + 0.5) / img.height as f32,
                    ];
                    assert_eq!(tex.bilinear(0, level, uv), linear(img.get(x, y)));
                    assert_eq!(tex.nearest(0, level, uv), linear(img.get(x, y)));
                }
            }
        }
    }

    /// The remembered `λ` equals the computed one bit for bit whatever the order of calls:
    /// textures differing in width only or height only, derivatives repeating, changing in one
    /// component, of either sign of zero, NaN and infinite.
    #[test]
    fn remembered_lambda_equals_the_computed_one() {
        let textures = [chain(64, 32), chain(64, 64), chain(32, 32), chain(32, 64)]
            .map(|c| Texture::new(c).unwrap());
        let values = [
            0.0,
            -0.0,
            1.0 / 64.0,
            3.0 / 64.0,
            -0.25,
            1e-30,
            f32::NAN,
            f32::INFINITY,
        ];
        let mut next = {
            let mut seed = 0x2545_f491_4f6c_dd1d_u64;
            move |n: usize| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed % n as u64) as usize
            }
        };
        let rules = [
            LodRule::Exact,
            LodRule::Ellipse,
            LodRule::SpecLower,
            LodRule::SpecUpper,
        ];
        let (mut ddx, mut ddy, mut t, mut rule) = ([0.0f32; 2], [0.0f32; 2], 0, LodRule::Exact);
        let mut checked = 0;
        for _ in 0..20_000 {
            // Mostly repeat (the quad's case), sometimes change one input.
            match next(9) {
                0 => ddx[next(2)] = values[next(values.len())],
                1 => ddy[next(2)] = values[next(values.len())],
                2 => t = next(textures.len()),
                3 => rule = rules[next(rules.len())],
                _ => {}
            }
            let tex = &textures[t];
            let want = tex.lod_by(rule, ddx, ddy).lambda_base;
            let got = tex.lambda_base(rule, ddx, ddy);
            assert_eq!(got.to_bits(), want.to_bits(), "{ddx:?} {ddy:?}");
            checked += 1;
        }
        assert_eq!(checked, 20_000);
    }

    #[test]
    fn bilinear_halfway_between_texels_averages_in_linear_light() {
        let tex = Texture::new(chain(16, 8)).unwrap();
        let img = tex.level(0, 0).clone();
        // Halfway between texel (3, 2) and (4, 2): u·w = 4.0.
        let got = tex.bilinear(0, 0, [4.0 / 16.0, 2.5 / 8.0]);
        let (a, b) = (linear(img.get(3, 2)), linear(img.get(4, 2)));
        let want = std::array::from_fn(|c| 0.5 * (a[c] + b[c]));
        assert!(close(got, want), "{got:?} vs {want:?}");
        // The average of the decoded values, not the decode of the averaged bytes.
        let encoded_average =
            srgb_to_linear(((img.get(3, 2)[0] as u16 + img.get(4, 2)[0] as u16) / 2) as u8);
        assert_ne!(got[0], encoded_average);
        // The centre of four texels averages all four.
        let got = tex.bilinear(0, 0, [4.0 / 16.0, 3.0 / 8.0]);
        let t = [img.get(3, 2), img.get(4, 2), img.get(3, 3), img.get(4, 3)].map(linear);
        let want = std::array::from_fn(|c| 0.25 * (t[0][c] + t[1][c] + t[2][c] + t[3][c]));
        assert!(close(got, want), "{got:?} vs {want:?}");
    }

    #[test]
    fn addressing_clamps_to_the_edge() {
        let tex = Texture::new(chain(16, 8)).unwrap();
        let img = tex.level(0, 0).clone();
        // Every tap clamps to the corner texel (weights sum to 1 up to f32 rounding).
        assert!(close(
            tex.bilinear(0, 0, [-3.0, -0.2]),
            linear(img.get(0, 0))
        ));
        assert!(close(
            tex.bilinear(0, 0, [1.7, 2.0]),
            linear(img.get(15, 7))
        ));
        assert_eq!(tex.nearest(0, 0, [1.0, 1.0]), linear(img.get(15, 7)));
        // Half a texel from the left border: only column 0 contributes.
        assert_eq!(tex.bilinear(0, 0, [0.0, 0.5 / 8.0]), linear(img.get(0, 0)));
        assert_eq!(tex.nearest(0, 0, [f32::NAN, 0.0]), linear(img.get(0, 0)));
    }

    #[test]
    fn lambda_is_log2_of_texels_per_pixel() {
        let tex = Texture::new(chain(64, 32)).unwrap();
        let one = tex.lod([1.0 / 64.0, 0.0], [0.0, 1.0 / 32.0]);
        assert_eq!((one.rho, one.lambda_base, one.lambda), (1.0, 0.0, 0.0));
        assert!(one.magnified);
        let two = tex.lod([2.0 / 64.0, 0.0], [0.0, 2.0 / 32.0]);
        assert_eq!((two.rho, two.lambda_base, two.lambda), (2.0, 1.0, 1.0));
        assert!(!two.magnified);
        // Max of lengths: the longer derivative decides, diagonals count by their length.
        let aniso = tex.lod([4.0 / 64.0, 0.0], [0.0, 1.0 / 32.0]);
        assert_eq!(aniso.lambda, 2.0);
        let diag = tex.lod([3.0 / 64.0, 4.0 / 32.0], [0.0, 0.0]);
        assert_eq!(diag.rho, 5.0);
        // Clamped to the chain; magnification clamps to 0; NaN goes to the coarsest level.
        assert_eq!(tex.lod([1e6, 0.0], [0.0, 0.0]).lambda, 6.0);
        assert_eq!(tex.lod([0.0; 2], [0.0; 2]).lambda, 0.0);
        assert_eq!(tex.lod([f32::NAN, 0.0], [0.0; 2]).lambda, 6.0);
        assert_eq!(tex.lod([f32::INFINITY, 0.0], [0.0; 2]).lambda, 6.0);
    }

    /// The specification's scale-factor models ([`LodRule`]) on the sheared footprint the H200
    /// measured (`parity::sampler_lod`: `∂uv/∂x = (29.34, 0)`, `∂uv/∂y = (29.34, 12.45)` texels):
    /// the exact `ρ` is the longer derivative, the ellipse's major axis the larger singular value
    /// (`λ` 0.41 higher, the H200's), the bounds the largest component and `sqrt(2)` times the
    /// larger sum; on an orthogonal footprint the ellipse equals the exact `ρ`.
    #[test]
    fn lod_rules_follow_the_specification_models() {
        let tex = Texture::new(chain(256, 256)).unwrap();
        let (ddx, ddy) = ([29.34 / 256.0, 0.0], [29.34 / 256.0, 12.45 / 256.0]);
        let rho = |rule| f64::from(tex.lod_by(rule, ddx, ddy).rho);
        let exact = (29.34f64 * 29.34 + 12.45 * 12.45).sqrt();
        assert!((rho(LodRule::Exact) - exact).abs() < 1e-4);
        let (a, b, d) = (29.34f64, 29.34, 12.45);
        let s = a * a + b * b + d * d;
        let major = ((s + (s * s - 4.0 * a * a * d * d).sqrt()) / 2.0).sqrt();
        assert!(
            (rho(LodRule::Ellipse) - major).abs() < 1e-3,
            "{}",
            rho(LodRule::Ellipse)
        );
        assert!((rho(LodRule::SpecLower) - 29.34).abs() < 1e-4);
        assert!((rho(LodRule::SpecUpper) - 2f64.sqrt() * (29.34 + 12.45)).abs() < 1e-3);
        assert!(rho(LodRule::SpecLower) <= rho(LodRule::Exact));
        assert!(rho(LodRule::Exact) < rho(LodRule::Ellipse));
        assert!(rho(LodRule::Ellipse) <= rho(LodRule::SpecUpper));
        let (ddx, ddy) = (
            [0.6 * 8.0 / 256.0, -0.8 * 8.0 / 256.0],
            [0.8 * 8.0 / 256.0, 0.6 * 8.0 / 256.0],
        );
        let (e, x) = (
            tex.lod_by(LodRule::Ellipse, ddx, ddy).rho,
            tex.lod(ddx, ddy).rho,
        );
        assert!((e - x).abs() < 1e-5, "orthogonal: ellipse {e}, exact {x}");
    }

    #[test]
    fn level_selection_follows_the_mipmap_mode() {
        let tex = Texture::new(chain(64, 64)).unwrap();
        let uv = [0.3, 0.6];
        // Nearest mipmap: d' = 1.5 rounds down to level 1, 1.51 to level 2.
        let at = |lambda| tex.sample_level(&Sampler::BILINEAR, 0, uv, lambda);
        assert_eq!(at(1.5), tex.bilinear(0, 1, uv));
        assert_eq!(at(1.51), tex.bilinear(0, 2, uv));
        assert_eq!(at(-3.0), tex.bilinear(0, 0, uv));
        assert_eq!(at(99.0), tex.bilinear(0, 6, uv));
        // Linear mipmap: halfway between levels 2 and 3.
        let (a, b) = (tex.bilinear(0, 2, uv), tex.bilinear(0, 3, uv));
        let want = std::array::from_fn(|c| 0.5 * (a[c] + b[c]));
        assert!(close(tex.trilinear(0, uv, 2.5), want));
        assert_eq!(tex.trilinear(0, uv, 2.0), a);
        // Magnified: mag filter on level 0; minified: min filter.
        let mixed = Sampler {
            mag_filter: FilterMode::Nearest,
            min_filter: FilterMode::Linear,
            mipmap_filter: FilterMode::Nearest,
            lod_rule: LodRule::Exact,
        };
        assert_eq!(tex.sample_level(&mixed, 0, uv, 0.0), tex.nearest(0, 0, uv));
        assert_eq!(
            tex.sample_level(&mixed, 0, uv, 0.25),
            tex.bilinear(0, 0, uv)
        );
        // Implicit LOD: 4 texels per pixel selects level 2.
        let d = 4.0 / 64.0;
        assert_eq!(
            tex.sample(&Sampler::NEAREST, 0, uv, [d, 0.0], [0.0, d]),
            tex.nearest(0, 2, uv)
        );
    }

    #[test]
    fn array_layers_are_separate_and_clamped() {
        let mut other = chain(8, 8);
        for img in &mut other {
            img.texels
                .iter_mut()
                .for_each(|t| *t = [255, 255, 255, 255]);
        }
        let tex = Texture::new_array(vec![chain(8, 8), other]).unwrap();
        assert_eq!(tex.layer_count(), 2);
        let white = tex.bilinear(1, 0, [0.5, 0.5]);
        assert_eq!(white, [1.0; 4]);
        assert_eq!(tex.bilinear(7, 0, [0.5, 0.5]), white);
        assert_ne!(tex.bilinear(0, 0, [0.5, 0.5]), white);
        assert_eq!(linear_to_srgb(white[0]), 255);
    }

    #[test]
    fn malformed_chains_are_named() {
        assert_eq!(Texture::new_array(vec![]), Err(TextureShapeError::NoLayers));
        assert_eq!(
            Texture::new(vec![]),
            Err(TextureShapeError::NoLevels { layer: 0 })
        );
        let mut bad = chain(8, 4);
        bad[2] = gradient(3, 1, 2);
        assert!(matches!(
            Texture::new(bad),
            Err(TextureShapeError::LevelSize {
                level: 2,
                expected_width: 2,
                ..
            })
        ));
        let mut long = chain(4, 4);
        long.push(gradient(1, 1, 9));
        assert!(matches!(
            Texture::new(long),
            Err(TextureShapeError::LevelCount {
                found: 4,
                expected: 3,
                ..
            })
        ));
        let short = chain(8, 8)[..2].to_vec();
        assert!(Texture::new_array(vec![chain(8, 8)[..2].to_vec(), short]).is_ok());
        assert!(matches!(
            Texture::new_array(vec![chain(8, 8), chain(8, 8)[..2].to_vec()]),
            Err(TextureShapeError::LevelCount { layer: 1, .. })
        ));
    }
}
