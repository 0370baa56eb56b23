//! # mips: alpha-aware mip chains for billboard layers on the GPU (E Alg. 3.2, E§4.1; SPEC §5.2)
//!
//! The driver of `shaders/mips.wgsl`, twin of `reference/src/mips.rs` (same stage name; the WGSL
//! repeats `downsample_texel`, `passes_alpha_test` and `AlphaAdjust::apply` as `apply_adjust`,
//! and runs `coverage_scale` one counting round per dispatch).
//!
//! ## Contract
//! Input: a billboard array texture ([`create_billboard_texture`], format
//! [`BILLBOARD_FORMAT`] = `Rgba8UnormSrgb`, square, power-of-two side `r` in
//! `1..=`[`MAX_MIP_SIDE`], a full mip chain) whose level 0 holds every layer: rendered by the
//! bake stage ([`crate::bake`]) or uploaded from the CPU ([`upload_level0`], the "bisect one
//! stage" hook: the mips stage on the reference's level 0). [`GpuMips::run`] writes levels
//! `1..` of every layer in one of the three [`MipMode`]s and returns a [`MipArray`]; level 0 is
//! never modified. The rules are the reference's, degenerate ones included (AlphaSum = 0: plain
//! average colour; a level with `MinAlpha_k == MaxAlpha_k`, every 1x1 level among them:
//! `MaxAlpha_0` if positive, else `MinAlpha_0`; all-transparent and all-opaque layers; the coverage
//! scale kept at 1 whenever it is as good as any).
//!
//! ## Structure: E Alg. 3.2 per level, like the reference
//! E§4.1 computes "the maximum and minimum alpha values for each texture" once, in a first stage,
//! whereas E Alg. 3.2 computes `MinAlpha_k`, `MaxAlpha_k` per level (lines 9-10) and remaps each
//! level from its own range to level 0's (line 13). E§4.1's single range is only the remap's
//! target, so we implement Alg. 3.2 like the reference (whose module docs discuss the
//! difference), with its two loops fused per level. One compute pass holds, in order:
//! 1. `mips_decode`: level 0's bytes (read through an `Rgba8Unorm` view, i.e. undecoded) decoded
//!    to linear `f32` by tables and reduced to level 0's alpha range and alpha-test count;
//! 2. per level `k >= 1`: `mips_downsample` (raw level `k` from raw level `k - 1`, E Alg. 3.2
//!    lines 3-8, and the raw range by `atomicMin`/`atomicMax` on the `f32` bit patterns, which
//!    order like the values for non-negative floats; lines 9-10), `mips_adjust` (one invocation
//!    per layer: the level's [`MipLevelStats::adjust_kind`], line 13), for CoveragePreserving
//!    [`COVERAGE_ROUNDS`] rounds of `mips_coverage_count` (a full counting pass at the layer's
//!    trial scale) and `mips_coverage_step` (the reference's search, one step per round: scale 1,
//!    `f32::MAX`, then [`COVERAGE_BISECTION_STEPS`] bisection steps over `f32` bit patterns), and
//!    `mips_finalize` (alpha adjusted and quantized to RGBA8 into a buffer).
//!
//! Every counting pass is its own dispatch, never a loop inside one workgroup: Mesa's llvmpipe
//! (lavapipe, the CI adapter) silently ends a shader's loops after 65535 iterations in total per
//! invocation (`LP_MAX_TGSI_LOOP_ITERATIONS`, shared by every loop of the shader), which a single
//! workgroup counting a 1024² level 33 times exceeds; the first version of this stage did that
//! and chose wrong scales from 512² layers up. No invocation here loops more than 8 times.
//!
//! Raw values ping-pong between two `vec4<f32>` storage buffers (level `k >= 1` in buffer
//! `k % 2`; level 0 is decoded from the texture wherever it is read), so memory is about
//! `0.3 · layers · r² · 16` bytes, not the whole chain: a 4096² layer fits lavapipe's 128 MiB
//! storage-binding limit. The final bytes of every level
//! go to one `u32` buffer with rows padded to 256 bytes and are copied into the `Rgba8UnormSrgb`
//! texture with `copy_buffer_to_texture` (an sRGB format cannot be a storage texture).
//!
//! ## Exactness
//! Decoding uses 256-entry tables of the reference's exact values (sRGB curve in `f64`, alpha
//! `byte / 255`), and quantization an encode table per curve holding, for each byte `b`, the
//! smallest `f32` that the reference's formula maps to `b` or more ([`mip_tables`]), so
//! quantization is the reference's bit for bit. Raw alpha is built from additions and exact
//! `· 0.25` only, so raw alpha, its ranges and all coverage counts (hence the coverage scales)
//! equal the reference's exactly; colour and the remap may differ by a few ulp (WGSL division is
//! within 2.5 ulp; `a · b + c` may be fused), which the ±1-per-channel parity of SPEC §8 covers.
//! Measured on lavapipe (`tests/tests/parity/mips.rs`): ranges, adjustments, scales and counts
//! bit-identical, texels identical but for a rare colour byte one step apart.
//!
//! ## Cost
//! Per level: two per-texel dispatches and one per-layer dispatch; a CoveragePreserving level
//! adds [`COVERAGE_ROUNDS`] per-texel counting dispatches and as many per-layer steps (layers
//! whose search ended early skip the counting). Measured once on lavapipe (2 shared cores), with
//! readback: one 2048² layer 1.6-1.9 s (AlphaAware, Box) and 6 s (CoveragePreserving); one
//! 4096² layer 7 s and 22 s; the reference 0.4-0.8 s and 2-3 s.

use std::sync::{Arc, OnceLock};

use bytemuck::{Pod, Zeroable};
use forestlod_shared::MipMode;

use crate::context::{Slot, bind_group, compute_pipelines, dynamic_uniform_slot};
use crate::readback::{read_buffer, upload_storage, zeroed_buffer};
use crate::shaders::{StageSource, WgslFile, wgsl_constants};
use crate::{GpuContext, GpuError};

/// Largest layer side accepted (as `reference::mips::MAX_MIP_SIDE`).
pub const MAX_MIP_SIDE: u32 = 4096;

/// Format of the billboard array texture: sRGB colour, linear alpha (SPEC §3).
pub const BILLBOARD_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The view format through which `mips_decode` reads level 0's stored bytes undecoded; every
/// billboard texture lists it in its `view_formats`.
pub const BILLBOARD_BYTES_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Bisection steps of the coverage search (generated into [`SOURCE`]); keep in sync with
/// `reference::mips::COVERAGE_BISECTION_STEPS` (31 halvings of the bit-pattern gap
/// `0x7F7F_FFFF < 2^31` end on adjacent floats).
pub const COVERAGE_BISECTION_STEPS: u32 = 31;

/// Counting rounds of a CoveragePreserving level: scale 1, `f32::MAX`, then
/// [`COVERAGE_BISECTION_STEPS`] bisection steps (generated into [`SOURCE`]).
pub const COVERAGE_ROUNDS: u32 = COVERAGE_BISECTION_STEPS + 2;

/// Side of the square workgroups of the per-texel passes (generated into [`SOURCE`]).
pub const MIPS_TILE: u32 = 8;
/// Invocations per workgroup of the per-layer passes (`mips_adjust`, `mips_coverage_step`;
/// generated into [`SOURCE`]).
pub const MIPS_LAYER_WORKGROUP_SIZE: u32 = 64;

/// [`MipLevelStats::adjust_kind`]: alpha unchanged (level 0, Box).
pub const ADJUST_KEEP: u32 = 0;
/// [`MipLevelStats::adjust_kind`]: linear remap `adjust = [from_min, from_max, to_min, to_max]`.
pub const ADJUST_REMAP: u32 = 1;
/// [`MipLevelStats::adjust_kind`]: every texel gets `adjust[0]` (the degenerate remap).
pub const ADJUST_CONSTANT: u32 = 2;
/// [`MipLevelStats::adjust_kind`]: coverage scale `α' = clamp(α · adjust[0], 0, 1)`.
pub const ADJUST_SCALE: u32 = 3;

/// Offset of the sRGB decode table in [`mip_tables`] (byte to linear). This and the
/// other offsets are generated into [`SOURCE`].
pub const TABLE_SRGB_DECODE: usize = 0;
/// Offset of the UNORM decode table (byte to `byte / 255`).
pub const TABLE_UNORM_DECODE: usize = 256;
/// Offset of the sRGB encode thresholds (entry `b` in `1..=255`: smallest `f32` that encodes
/// to `b` or more; entry 0 unused).
pub const TABLE_SRGB_ENCODE: usize = 512;
/// Offset of the UNORM encode thresholds.
pub const TABLE_UNORM_ENCODE: usize = 768;
/// Length of [`mip_tables`].
pub const TABLE_LEN: usize = 1024;

/// The `mips` stage's module: `mips.wgsl`, with the constants above that it reads.
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "mips.wgsl",
        wgsl: include_str!("shaders/mips.wgsl"),
        constants: wgsl_constants![
            MIPS_TILE,
            MIPS_LAYER_WORKGROUP_SIZE,
            COVERAGE_BISECTION_STEPS,
            COVERAGE_ROUNDS,
            ADJUST_KEEP,
            ADJUST_REMAP,
            ADJUST_CONSTANT,
            ADJUST_SCALE,
            TABLE_SRGB_DECODE as u32,
            TABLE_UNORM_DECODE as u32,
            TABLE_SRGB_ENCODE as u32,
            TABLE_UNORM_ENCODE as u32,
        ],
    },
    parts: &[],
};

/// Output rows are padded to this many texels (256 bytes, `COPY_BYTES_PER_ROW_ALIGNMENT`).
const OUT_ROW_ALIGN_TEXELS: u32 = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT / 4;

// The sRGB codec and UNORM quantization the tables encode are the reference's own
// (`forestlod_shared::color`: exact curve in `f64`, rounded once; clamp with NaN to 0, round to
// nearest), re-exported under the names this module always gave them.
pub use forestlod_shared::color::{
    linear_to_srgb as linear_to_srgb_exact, srgb_to_linear as srgb_to_linear_exact,
    unorm8 as unorm8_exact,
};

/// Smallest non-negative `f32` in `[0, 1]` that `encode` maps to `b` or more (`encode` must be
/// non-decreasing on `[0, 1]` and map 1 to 255), by bisection over the bit patterns.
fn threshold(b: u8, encode: fn(f32) -> u8) -> f32 {
    let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
    if encode(0.0) >= b {
        return 0.0;
    }
    // Invariant: encode(lo) < b <= encode(hi).
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if encode(f32::from_bits(mid)) >= b {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    f32::from_bits(hi)
}

/// The four tables `mips.wgsl` reads (offsets `TABLE_*`): the sRGB and UNORM decode tables and
/// the encode thresholds of [`linear_to_srgb_exact`] and [`unorm8_exact`]. Computed once.
pub fn mip_tables() -> &'static [f32; TABLE_LEN] {
    static TABLES: OnceLock<[f32; TABLE_LEN]> = OnceLock::new();
    TABLES.get_or_init(|| {
        let mut t = [0.0f32; TABLE_LEN];
        for b in 0..=255u8 {
            let i = b as usize;
            t[TABLE_SRGB_DECODE + i] = srgb_to_linear_exact(b);
            t[TABLE_UNORM_DECODE + i] = f32::from(b) / 255.0;
            t[TABLE_SRGB_ENCODE + i] = threshold(b, linear_to_srgb_exact);
            t[TABLE_UNORM_ENCODE + i] = threshold(b, unorm8_exact);
        }
        // Entry 0 is never read by the search (it starts at b + step >= 1).
        t[TABLE_SRGB_ENCODE] = f32::NEG_INFINITY;
        t[TABLE_UNORM_ENCODE] = f32::NEG_INFINITY;
        t
    })
}

/// The byte `mips.wgsl`'s `encode_byte` gives `x` with the encode table at `table`
/// ([`TABLE_SRGB_ENCODE`] or [`TABLE_UNORM_ENCODE`]): the same 8-step search, on the CPU.
pub fn encode_byte(x: f32, table: usize) -> u8 {
    let t = mip_tables();
    let mut b = 0usize;
    let mut step = 128usize;
    while step > 0 {
        if x >= t[table + b + step] {
            b += step;
        }
        step >>= 1;
    }
    b as u8
}

/// Number of mip levels of a side-`side` texture, down to 1x1 (0 for `side = 0`).
pub fn mip_level_count(side: u32) -> u32 {
    u32::BITS - side.leading_zeros()
}

/// The per-level uniform of `mips.wgsl`. Keep in sync with `struct MipsUniform` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MipsUniform {
    /// The level's index (0: the input).
    pub level: u32,
    /// The level's side.
    pub side: u32,
    /// Layers of the array.
    pub layer_count: u32,
    /// [`MipMode`] as `u32`.
    pub mode: u32,
    /// Alpha-test reference.
    pub alpha_ref: f32,
    /// First texel of this level in the output buffer.
    pub out_offset: u32,
    /// Texels per padded output row.
    pub out_row: u32,
    /// Side of level 0.
    pub level0_side: u32,
}
const _: () = assert!(size_of::<MipsUniform>() == 32);

/// What `mips.wgsl` records per layer and level (`struct LevelStats` there, atomics read as
/// `u32`): the twin of the reference's `MipLevel::{raw_alpha_range, adjust,
/// alpha_test_pass_count}`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MipLevelStats {
    /// Bits of the level's smallest raw alpha (`MinAlpha_k`).
    pub alpha_min_bits: u32,
    /// Bits of the level's largest raw alpha (`MaxAlpha_k`).
    pub alpha_max_bits: u32,
    /// Texels of the final level whose alpha byte passes the alpha test (`byte / 255 > ref`).
    pub pass_count: u32,
    /// `ADJUST_*`: how raw alpha became final alpha.
    pub adjust_kind: u32,
    /// The adjustment's parameters (see the `ADJUST_*` consts).
    pub adjust: [f32; 4],
}
const _: () = assert!(size_of::<MipLevelStats>() == 32);

impl MipLevelStats {
    /// The initial record: empty range (`min = +inf`), no count, [`ADJUST_KEEP`].
    const INIT: Self = Self {
        alpha_min_bits: 0x7F80_0000,
        alpha_max_bits: 0,
        pass_count: 0,
        adjust_kind: ADJUST_KEEP,
        adjust: [0.0; 4],
    };

    /// `[MinAlpha_k, MaxAlpha_k]` of the raw level.
    pub fn raw_alpha_range(&self) -> [f32; 2] {
        [
            f32::from_bits(self.alpha_min_bits),
            f32::from_bits(self.alpha_max_bits),
        ]
    }
}

/// The coverage search of one layer as `mips.wgsl` keeps it between counting rounds (`struct
/// CoverageState` there); only the layout matters on the CPU.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct CoverageState {
    /// Texels passing at `test_bits` (atomic there).
    pub count: u32,
    /// Bits of the scale the next round tests.
    pub test_bits: u32,
    /// Which count the state waits for (scale 1, `f32::MAX`, bisection, done).
    pub phase: u32,
    /// Bisection steps done.
    pub step: u32,
    /// Lower end of the bracket (bits).
    pub lo: u32,
    /// Upper end of the bracket (bits).
    pub hi: u32,
    /// Count at `lo`.
    pub count_lo: u32,
    /// Count at `hi`.
    pub count_hi: u32,
    /// Count at scale 1.
    pub count_at_one: u32,
    /// `min(count0, count(f32::MAX) · 4^k)`.
    pub goal: u32,
    /// Level 0's alpha-test count.
    pub count0: u32,
    /// `4^k`.
    pub four_k: u32,
}
const _: () = assert!(size_of::<CoverageState>() == 48);

/// One level of one layer, read back.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MipTexels {
    /// Side of the level.
    pub side: u32,
    /// `side²` texels, row-major from the top-left: sRGB colour bytes, linear alpha byte.
    pub texels: Vec<[u8; 4]>,
}

/// Checks a layer side: a power of two in `1..=MAX_MIP_SIDE`.
fn validate_side(side: u32) -> Result<(), GpuError> {
    if side.is_power_of_two() && side <= MAX_MIP_SIDE {
        Ok(())
    } else {
        Err(GpuError::Input {
            field: "mip layer side",
            value: side.to_string(),
            reason: "expected a power of two in 1..=4096",
        })
    }
}

fn validate_layers(ctx: &GpuContext, layers: u32) -> Result<(), GpuError> {
    if (1..=ctx.limits.max_texture_array_layers).contains(&layers) {
        Ok(())
    } else {
        Err(GpuError::Input {
            field: "array layers",
            value: format!(
                "{layers} (device limit {})",
                ctx.limits.max_texture_array_layers
            ),
            reason: "expected at least one layer and at most the device's max_texture_array_layers",
        })
    }
}

/// Creates an empty billboard array texture: `side x side`, `layers` layers, the full mip
/// chain, [`BILLBOARD_FORMAT`] with [`BILLBOARD_BYTES_FORMAT`] as an extra view format, usable as
/// a render attachment (the bake), a sampled texture (the draw stage) and a copy source and
/// destination.
pub fn create_billboard_texture(
    ctx: &GpuContext,
    side: u32,
    layers: u32,
    label: &str,
) -> Result<wgpu::Texture, GpuError> {
    validate_side(side)?;
    validate_layers(ctx, layers)?;
    ctx.checked("billboard array texture", || {
        ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: layers,
            },
            mip_level_count: mip_level_count(side),
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: BILLBOARD_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::COPY_DST,
            view_formats: &[BILLBOARD_BYTES_FORMAT],
        })
    })
}

/// Checks that every layer of `level` holds `side²` texels.
fn check_texels(level: u32, side: u32, layers: &[&[[u8; 4]]]) -> Result<(), GpuError> {
    let want = side as usize * side as usize;
    match layers.iter().position(|l| l.len() != want) {
        None => Ok(()),
        Some(i) => Err(GpuError::Input {
            field: "layer texels",
            value: format!(
                "layer {i} level {level}: {} texels for side {side}",
                layers[i].len()
            ),
            reason: "expected side² texels per layer",
        }),
    }
}

/// Writes one level of every layer (`layers[i]`: `side²` texels of layer `i`).
fn write_level(ctx: &GpuContext, texture: &wgpu::Texture, level: u32, layers: &[&[[u8; 4]]]) {
    let side = (texture.width() >> level).max(1);
    let mut bytes = Vec::with_capacity(layers.len() * side as usize * side as usize * 4);
    for layer in layers {
        bytes.extend_from_slice(bytemuck::cast_slice(layer));
    }
    ctx.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: level,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        &bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(side * 4),
            rows_per_image: Some(side),
        },
        wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: layers.len() as u32,
        },
    );
}

/// The CPU-input hook for the mips stage: a billboard texture whose level 0 holds `layers`
/// (each `side²` RGBA8 texels, sRGB colour, e.g. the reference's baked layers), other levels
/// zero. Run [`GpuMips::run`] on it to test the mips stage alone.
pub fn upload_level0(
    ctx: &GpuContext,
    side: u32,
    layers: &[&[[u8; 4]]],
) -> Result<wgpu::Texture, GpuError> {
    let texture =
        create_billboard_texture(ctx, side, layers.len() as u32, "billboards (cpu level 0)")?;
    check_texels(0, side, layers)?;
    ctx.checked("upload level 0", || write_level(ctx, &texture, 0, layers))?;
    Ok(texture)
}

/// The CPU-input hook for the draw stage: a billboard texture holding full mip chains computed
/// elsewhere (`chains[layer][level]`, level `k` of side `max(1, side >> k)`, every layer with
/// `mip_level_count(side)` levels; e.g. the reference's `MipChain`s).
pub fn upload_chains(
    ctx: &GpuContext,
    side: u32,
    chains: &[Vec<&[[u8; 4]]>],
) -> Result<wgpu::Texture, GpuError> {
    let levels = mip_level_count(side);
    if let Some(i) = chains.iter().position(|c| c.len() != levels as usize) {
        return Err(GpuError::Input {
            field: "mip chain",
            value: format!("layer {i}: {} levels for side {side}", chains[i].len()),
            reason: "expected the full chain down to 1x1",
        });
    }
    let texture =
        create_billboard_texture(ctx, side, chains.len() as u32, "billboards (cpu chains)")?;
    for level in 0..levels {
        let layers: Vec<&[[u8; 4]]> = chains.iter().map(|c| c[level as usize]).collect();
        check_texels(level, side >> level, &layers)?;
        ctx.checked("upload mip chains", || {
            write_level(ctx, &texture, level, &layers)
        })?;
    }
    Ok(texture)
}

/// Checks that `texture` is a billboard texture ([`create_billboard_texture`]); returns its side,
/// layer count and level count.
fn check_billboard_texture(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
) -> Result<(u32, u32, u32), GpuError> {
    let (side, layers) = (texture.width(), texture.depth_or_array_layers());
    validate_side(side)?;
    validate_layers(ctx, layers)?;
    let levels = mip_level_count(side);
    if texture.height() != side
        || texture.format() != BILLBOARD_FORMAT
        || texture.mip_level_count() != levels
    {
        return Err(GpuError::Input {
            field: "billboard texture",
            value: format!(
                "{}x{} {:?} with {} levels",
                texture.width(),
                texture.height(),
                texture.format(),
                texture.mip_level_count()
            ),
            reason: "expected a texture from create_billboard_texture (square, Rgba8UnormSrgb, full chain)",
        });
    }
    Ok((side, layers, levels))
}

compute_pipelines! {
    /// The compiled pipelines of `mips.wgsl`.
    struct MipsPipelines = "mips", SOURCE.module(), [
        // One uniform slot per level, picked by dynamic offset.
        Slot::DynamicUniform(size_of::<MipsUniform>() as u64),
        Slot::Read((TABLE_LEN * 4) as u64),
        Slot::Read(16),
        Slot::Write(16),
        Slot::Write(size_of::<MipLevelStats>() as u64),
        Slot::Write(4),
        Slot::Texture(wgpu::TextureViewDimension::D2Array),
        Slot::Write(size_of::<CoverageState>() as u64),
    ],
    {
        decode: "mips_decode",
        downsample: "mips_downsample",
        adjust: "mips_adjust",
        coverage_count: "mips_coverage_count",
        coverage_step: "mips_coverage_step",
        finalize: "mips_finalize",
    }
}

/// The mips stage, its pipelines compiled once; run it on any number of textures.
#[derive(Debug)]
pub struct GpuMips<'a> {
    ctx: &'a GpuContext,
    pipelines: Arc<MipsPipelines>,
}

/// A billboard array texture with its full mip chains, and what the mips stage recorded.
#[derive(Debug)]
pub struct MipArray {
    /// The texture ([`BILLBOARD_FORMAT`], every level of every layer written).
    pub texture: wgpu::Texture,
    /// Side of level 0.
    pub side: u32,
    /// Number of layers.
    pub layer_count: u32,
    /// Levels per layer, [`mip_level_count`]`(side)`.
    pub level_count: u32,
    /// The mode the levels were built with (for textures uploaded from the CPU: as declared).
    pub mode: MipMode,
    /// The alpha-test reference they were built with.
    pub alpha_ref: f32,
    /// [`MipLevelStats`] per (level, layer), level-major; `None` for uploaded chains.
    stats: Option<wgpu::Buffer>,
}

impl MipArray {
    /// Wraps full chains uploaded from the CPU ([`upload_chains`]) so the draw stage can take
    /// them like the GPU's own; `mode` and `alpha_ref` are what the chains were built with.
    pub fn from_cpu_chains(
        ctx: &GpuContext,
        side: u32,
        chains: &[Vec<&[[u8; 4]]>],
        mode: MipMode,
        alpha_ref: f32,
    ) -> Result<Self, GpuError> {
        let texture = upload_chains(ctx, side, chains)?;
        Ok(Self {
            texture,
            side,
            layer_count: chains.len() as u32,
            level_count: mip_level_count(side),
            mode,
            alpha_ref,
            stats: None,
        })
    }

    /// Wraps a billboard texture as it is, without running the mips stage (e.g. the bake's level
    /// 0, to read it back with [`MipArray::read_level0`]); `mode` and `alpha_ref` are declared,
    /// not applied.
    pub fn from_texture(
        ctx: &GpuContext,
        texture: wgpu::Texture,
        mode: MipMode,
        alpha_ref: f32,
    ) -> Result<Self, GpuError> {
        let (side, layer_count, level_count) = check_billboard_texture(ctx, &texture)?;
        Ok(Self {
            texture,
            side,
            layer_count,
            level_count,
            mode,
            alpha_ref,
            stats: None,
        })
    }

    /// A view of the whole array with every level, as the draw stage samples it.
    pub fn view(&self) -> wgpu::TextureView {
        self.texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("billboards"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        })
    }

    /// Reads every level of every layer back: `[layer][level]`. One copy per level into one
    /// staging buffer, one map. Blocks.
    pub fn read_chains(&self, ctx: &GpuContext) -> Result<Vec<Vec<MipTexels>>, GpuError> {
        self.read_levels(ctx, self.level_count)
    }

    /// Reads levels `0..levels` of every layer: `[layer][level]`.
    fn read_levels(&self, ctx: &GpuContext, levels: u32) -> Result<Vec<Vec<MipTexels>>, GpuError> {
        let layers = self.layer_count;
        // (offset, padded row bytes, side) per level.
        let mut regions = Vec::with_capacity(levels as usize);
        let mut size = 0u64;
        for level in 0..levels {
            let side = (self.side >> level).max(1);
            let row = (side * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
            regions.push((size, row, side));
            size += u64::from(row) * u64::from(side) * u64::from(layers);
        }
        let bytes = ctx.checked("mips readback", || {
            let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("mips readback staging"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("mips readback"),
                });
            for (level, &(offset, row, side)) in regions.iter().enumerate() {
                encoder.copy_texture_to_buffer(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.texture,
                        mip_level: level as u32,
                        origin: wgpu::Origin3d::ZERO,
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::TexelCopyBufferInfo {
                        buffer: &staging,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset,
                            bytes_per_row: Some(row),
                            rows_per_image: Some(side),
                        },
                    },
                    wgpu::Extent3d {
                        width: side,
                        height: side,
                        depth_or_array_layers: layers,
                    },
                );
            }
            ctx.queue.submit([encoder.finish()]);
            staging
        })?;
        let data = crate::readback::map_and_read(ctx, &bytes)?;
        Ok((0..layers as usize)
            .map(|layer| {
                regions
                    .iter()
                    .map(|&(offset, row, side)| {
                        let image = offset as usize + layer * (row * side) as usize;
                        let texels = (0..side as usize)
                            .flat_map(|y| {
                                let start = image + y * row as usize;
                                data[start..start + side as usize * 4]
                                    .chunks_exact(4)
                                    .map(|t| [t[0], t[1], t[2], t[3]])
                            })
                            .collect();
                        MipTexels { side, texels }
                    })
                    .collect()
            })
            .collect())
    }

    /// Reads level 0 of every layer back (the bake's output before mips). Blocks.
    pub fn read_level0(&self, ctx: &GpuContext) -> Result<Vec<MipTexels>, GpuError> {
        Ok(self
            .read_levels(ctx, 1)?
            .into_iter()
            .map(|mut chain| chain.swap_remove(0))
            .collect())
    }

    /// The recorded [`MipLevelStats`], `[layer][level]`; `None` for chains uploaded from the
    /// CPU. Blocks.
    pub fn read_stats(
        &self,
        ctx: &GpuContext,
    ) -> Result<Option<Vec<Vec<MipLevelStats>>>, GpuError> {
        let Some(buffer) = &self.stats else {
            return Ok(None);
        };
        let (levels, layers) = (self.level_count as usize, self.layer_count as usize);
        let flat: Vec<MipLevelStats> = read_buffer(ctx, buffer, 0, levels * layers)?;
        Ok(Some(
            (0..layers)
                .map(|layer| (0..levels).map(|k| flat[k * layers + layer]).collect())
                .collect(),
        ))
    }
}

impl<'a> GpuMips<'a> {
    /// Compiles `mips.wgsl` and creates its pipelines.
    pub fn new(ctx: &'a GpuContext) -> Result<Self, GpuError> {
        Ok(Self {
            ctx,
            pipelines: ctx.pipelines::<MipsPipelines>()?,
        })
    }

    /// The context it runs on.
    pub fn context(&self) -> &'a GpuContext {
        self.ctx
    }

    /// Builds levels `1..` of every layer of `texture` (from [`create_billboard_texture`],
    /// level 0 filled) in `mode` with alpha-test reference `alpha_ref` (in `0..=1`; used by
    /// CoveragePreserving and for [`MipLevelStats::pass_count`]). Submits the work; reading the
    /// result back ([`MipArray::read_chains`]) waits for it.
    pub fn run(
        &self,
        texture: wgpu::Texture,
        mode: MipMode,
        alpha_ref: f32,
    ) -> Result<MipArray, GpuError> {
        let ctx = self.ctx;
        let (side, layers, levels) = check_billboard_texture(ctx, &texture)?;
        if !(alpha_ref.is_finite() && (0.0..=1.0).contains(&alpha_ref)) {
            return Err(GpuError::Input {
                field: "alpha_ref",
                value: alpha_ref.to_string(),
                reason: "expected a finite alpha in 0..=1",
            });
        }
        // Raw levels ping-pong: odd levels in `raw[1]`, even levels >= 2 in `raw[0]` (level 0 is
        // read from the texture), so the largest buffer holds level 1.
        let texel_bytes = 16u64;
        let raw_size = |k: u32| {
            let s = u64::from(side >> k.min(levels - 1));
            u64::from(layers) * s * s * texel_bytes
        };
        let (raw0_size, raw1_size) = (raw_size(2), raw_size(1));
        ctx.check_storage_binding(
            raw1_size,
            "billboard texture",
            |_| {
                format!("{layers} layers of {side}x{side}: {raw1_size} bytes of raw level-1 texels")
            },
            "exceeds the device's storage buffer limit; run fewer layers at a time",
        )?;

        // Per-level uniforms (dynamic offsets) and output regions (levels >= 1).
        let align = u64::from(ctx.limits.min_uniform_buffer_offset_alignment.max(1));
        let stride = (size_of::<MipsUniform>() as u64).next_multiple_of(align);
        let mut uniform_bytes = vec![0u8; (stride * u64::from(levels)) as usize];
        let mut out_len = 0u32;
        let mut regions = Vec::with_capacity(levels as usize);
        for level in 0..levels {
            let s = side >> level;
            let out_row = s.next_multiple_of(OUT_ROW_ALIGN_TEXELS);
            let uniform = MipsUniform {
                level,
                side: s,
                layer_count: layers,
                mode: mode as u32,
                alpha_ref,
                out_offset: out_len,
                out_row,
                level0_side: side,
            };
            let at = (stride * u64::from(level)) as usize;
            uniform_bytes[at..at + size_of::<MipsUniform>()]
                .copy_from_slice(bytemuck::bytes_of(&uniform));
            regions.push(uniform);
            if level > 0 {
                out_len += layers * s * out_row;
            }
        }

        use wgpu::BufferUsages as U;
        let uniforms = ctx.checked("mips uniforms", || {
            wgpu::util::DeviceExt::create_buffer_init(
                &ctx.device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some("mips uniforms"),
                    contents: &uniform_bytes,
                    usage: U::UNIFORM,
                },
            )
        })?;
        let tables = upload_storage(ctx, "mips tables", mip_tables(), U::empty());
        let stats_init = vec![MipLevelStats::INIT; (levels * layers) as usize];
        let stats = upload_storage(ctx, "mips stats", &stats_init, U::empty());
        let coverage = zeroed_buffer(
            ctx,
            "mips coverage search",
            u64::from(layers) * size_of::<CoverageState>() as u64,
            U::STORAGE,
        );
        let raw = [
            zeroed_buffer(ctx, "mips raw (even levels)", raw0_size, U::STORAGE),
            zeroed_buffer(ctx, "mips raw (odd levels)", raw1_size, U::STORAGE),
        ];
        let out = zeroed_buffer(
            ctx,
            "mips output texels",
            u64::from(out_len) * 4,
            U::STORAGE | U::COPY_SRC,
        );
        let level0 = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("billboards level 0 (bytes)"),
            format: Some(BILLBOARD_BYTES_FORMAT),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            usage: Some(wgpu::TextureUsages::TEXTURE_BINDING),
            base_mip_level: 0,
            mip_level_count: Some(1),
            ..Default::default()
        });
        // Bind group `d` writes raw buffer `d` and reads the other one.
        let bind_group = |d: usize| {
            bind_group(
                &ctx.device,
                "mips",
                &self.pipelines.layout,
                [
                    dynamic_uniform_slot::<MipsUniform>(&uniforms),
                    tables.as_entire_binding(),
                    raw[1 - d].as_entire_binding(),
                    raw[d].as_entire_binding(),
                    stats.as_entire_binding(),
                    out.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&level0),
                    coverage.as_entire_binding(),
                ],
            )
        };
        ctx.checked("mips dispatch", || {
            let groups = [bind_group(0), bind_group(1)];
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("mips"),
                });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("mips"),
                    timestamp_writes: None,
                });
                let p = &self.pipelines;
                for (level, region) in regions.iter().enumerate() {
                    let tiles = region.side.div_ceil(MIPS_TILE);
                    let offset = (stride * level as u64) as u32;
                    pass.set_bind_group(0, &groups[level % 2], &[offset]);
                    if level == 0 {
                        pass.set_pipeline(&p.decode);
                        pass.dispatch_workgroups(tiles, tiles, layers);
                        continue;
                    }
                    pass.set_pipeline(&p.downsample);
                    pass.dispatch_workgroups(tiles, tiles, layers);
                    let layer_groups = layers.div_ceil(MIPS_LAYER_WORKGROUP_SIZE);
                    pass.set_pipeline(&p.adjust);
                    pass.dispatch_workgroups(layer_groups, 1, 1);
                    if mode == MipMode::CoveragePreserving {
                        for _ in 0..COVERAGE_ROUNDS {
                            pass.set_pipeline(&p.coverage_count);
                            pass.dispatch_workgroups(tiles, tiles, layers);
                            pass.set_pipeline(&p.coverage_step);
                            pass.dispatch_workgroups(layer_groups, 1, 1);
                        }
                    }
                    pass.set_pipeline(&p.finalize);
                    pass.dispatch_workgroups(tiles, tiles, layers);
                }
            }
            for (level, region) in regions.iter().enumerate().skip(1) {
                encoder.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: &out,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: u64::from(region.out_offset) * 4,
                            bytes_per_row: Some(region.out_row * 4),
                            rows_per_image: Some(region.side),
                        },
                    },
                    wgpu::TexelCopyTextureInfo {
                        texture: &texture,
                        mip_level: level as u32,
                        origin: wgpu::Origin3d::ZERO,
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d {
                        width: region.side,
                        height: region.side,
                        depth_or_array_layers: layers,
                    },
                );
            }
            ctx.queue.submit([encoder.finish()]);
        })?;
        Ok(MipArray {
            texture,
            side,
            layer_count: layers,
            level_count: levels,
            mode,
            alpha_ref,
            stats: Some(stats),
        })
    }

    /// [`upload_level0`] then [`GpuMips::run`]: the mips stage on level-0 layers from the CPU.
    pub fn run_from_cpu(
        &self,
        side: u32,
        layers: &[&[[u8; 4]]],
        mode: MipMode,
        alpha_ref: f32,
    ) -> Result<MipArray, GpuError> {
        let texture = upload_level0(self.ctx, side, layers)?;
        self.run(texture, mode, alpha_ref)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// How long the 512 threshold searches may take: each is a bisection of at most 31 steps
    /// over the `f32` bits of `[0, 1]` (microseconds in all); a search that does not end within
    /// this is a hang, reported by name instead of as a suite that never finishes.
    const SEARCH_DEADLINE: std::time::Duration = std::time::Duration::from_secs(20);

    /// Every encode threshold is found, and is the least `f32` that encodes to its byte. Added for
    /// a survivor of issue 36's Rust sample (mutant 327: the bisection's `hi - lo > 1` → `>= 1`
    /// never ends; the suite only hung, which the mutation run counts as a timeout, not a kill).
    #[test]
    fn threshold_searches_end_at_the_least_value_of_each_byte() {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut out = Vec::new();
            for b in 1..=255u8 {
                for encode in [linear_to_srgb_exact as fn(f32) -> u8, unorm8_exact] {
                    out.push((b, encode, threshold(b, encode)));
                }
            }
            let _ = tx.send(out);
        });
        let found = rx
            .recv_timeout(SEARCH_DEADLINE)
            .expect("the threshold searches did not end within the deadline (a hang)");
        for (b, encode, t) in found {
            assert!(encode(t) >= b, "byte {b}: threshold {t} encodes below it");
            let below = f32::from_bits(t.to_bits() - 1);
            assert!(
                t == 0.0 || encode(below) < b,
                "byte {b}: threshold {t} is not the least (the value below encodes to {})",
                encode(below)
            );
        }
    }

    #[test]
    fn decode_then_encode_round_trips_every_byte() {
        let t = mip_tables();
        for b in 0..=255u8 {
            let i = b as usize;
            assert_eq!(encode_byte(t[TABLE_SRGB_DECODE + i], TABLE_SRGB_ENCODE), b);
            assert_eq!(
                encode_byte(t[TABLE_UNORM_DECODE + i], TABLE_UNORM_ENCODE),
                b
            );
        }
    }

    #[test]
    fn encode_tables_equal_the_formulas() {
        // At each threshold and one float below it, and on a dense sweep plus the extremes.
        let t = mip_tables();
        for b in 1..=255usize {
            for (table, f) in [
                (TABLE_SRGB_ENCODE, linear_to_srgb_exact as fn(f32) -> u8),
                (TABLE_UNORM_ENCODE, unorm8_exact),
            ] {
                let x = t[table + b];
                assert_eq!(encode_byte(x, table), f(x));
                let below = f32::from_bits(x.to_bits() - 1);
                assert_eq!(encode_byte(below, table), f(below));
                assert_eq!(f(below) as usize, b - 1);
            }
        }
        let mut x = 0.0f32;
        while x <= 1.0 {
            assert_eq!(
                encode_byte(x, TABLE_SRGB_ENCODE),
                linear_to_srgb_exact(x),
                "{x}"
            );
            assert_eq!(encode_byte(x, TABLE_UNORM_ENCODE), unorm8_exact(x), "{x}");
            x += 1.0 / 65_537.0;
        }
        for x in [f32::NAN, -1.0, -0.0, 2.0, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(
                encode_byte(x, TABLE_SRGB_ENCODE),
                linear_to_srgb_exact(x),
                "{x}"
            );
            assert_eq!(encode_byte(x, TABLE_UNORM_ENCODE), unorm8_exact(x), "{x}");
        }
    }

    #[test]
    fn wgsl_structs_match_their_rust_twins() {
        use crate::wgsl_layout::{assert_offsets, rust_layout, validate, wgsl_layout};
        let module = validate(&SOURCE.module());
        let uniform = rust_layout!(MipsUniform {
            level,
            side,
            layer_count,
            mode,
            alpha_ref,
            out_offset,
            out_row,
            level0_side
        });
        assert_offsets(&module, "MipsUniform", &uniform);
        let stats = rust_layout!(MipLevelStats {
            alpha_min_bits,
            alpha_max_bits,
            pass_count,
            adjust_kind,
            adjust
        });
        assert_offsets(&module, "LevelStats", &stats);
        let (members, span) = wgsl_layout(&module, "CoverageState").expect("CoverageState");
        let offsets: Vec<u32> = members.iter().map(|(_, o)| *o).collect();
        assert_eq!(offsets, (0..12).map(|i| i * 4).collect::<Vec<u32>>());
        assert_eq!(span as usize, size_of::<CoverageState>());
    }

    #[test]
    fn level_counts() {
        assert_eq!(mip_level_count(1), 1);
        assert_eq!(mip_level_count(128), 8);
        assert_eq!(mip_level_count(4096), 13);
    }
}
