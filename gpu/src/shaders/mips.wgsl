// mips.wgsl: alpha-aware mip chains for the billboard array texture (E Alg. 3.2, E§4.1;
// SPEC §5.2). The GPU twin of reference/src/mips.rs, driven by gpu/src/mips.rs; common.wgsl is
// prepended.
//
// Contract (the reference's module docs, repeated): every layer of a square power-of-two
// Rgba8UnormSrgb array texture gets its full mip chain from its level 0, in one of three modes
// (forestlod_shared::MipMode): AlphaAware (E Alg. 3.2: alpha-weighted colour, raw alpha the box
// average, then each level's alpha remapped linearly from its own raw [min, max] onto level 0's),
// Box (plain 2x2 average, no adjustment: the "blit" of E Fig. 3.5) and CoveragePreserving
// (Castaño 2010 / NVTT: alpha scaled per level so that the fraction of texels passing the alpha
// test stays level 0's). Degenerate rules as in the reference: AlphaSum = 0 gives the plain
// average colour; a level with min = max (every 1x1 level) gets MaxAlpha_0 if its alpha is
// positive, else MinAlpha_0; the coverage scale is 1 whenever it is as good as any.
//
// Structure: Alg. 3.2, per level, like the reference (not E§4.1's "min/max once in a first
// stage", which gives only level 0's range; see reference/src/mips.rs). Dispatches, in order:
// - `mips_decode` (one invocation per level-0 texel): the texel's bytes, read through an
//   Rgba8Unorm view and decoded by tables (sRGB colour, alpha byte / 255), reduced to level 0's
//   alpha range and alpha-test count in its LevelStats (level 1 decodes level 0 again as it reads
//   it, so level 0 needs no raw buffer);
// - per level k >= 1:
//   `mips_downsample` (one invocation per texel: `downsample_texel`, raw k-1 -> raw k, and the
//   level's raw alpha range by atomicMin/atomicMax on the f32 bit patterns, which order like the
//   values for the non-negative alphas used here),
//   `mips_adjust` (one invocation per layer: the level's AlphaAdjust, E Alg. 3.2 line 13; for
//   CoveragePreserving it only starts the search),
//   for CoveragePreserving, COVERAGE_ROUNDS rounds of `mips_coverage_count` (one invocation per
//   texel: how many texels pass the alpha test at the layer's trial scale) and
//   `mips_coverage_step` (one invocation per layer: the next trial scale of reference
//   `coverage_scale`, scale 1, then f32::MAX, then a fixed COVERAGE_BISECTION_STEPS bisection
//   steps over f32 bit patterns; the final scale after the last round),
//   `mips_finalize` (one invocation per texel: adjust alpha, quantize to RGBA8 bytes into the
//   output buffer, count the texels passing the alpha test).
// No invocation loops more than a few times: Mesa's llvmpipe (lavapipe, the CI adapter) silently
// ends a shader's loops after 65535 iterations in total per invocation (LP_MAX_TGSI_LOOP_ITERATIONS,
// "shared between every loop in a shader"), which a single workgroup counting a large level 33
// times would exceed. Hence one dispatch per counting pass.
// The driver then copies each level's bytes into the Rgba8UnormSrgb texture.
//
// Floating point: the same operations in the same order as the reference (sums of a footprint
// `(t00 + t10) + (t01 + t11)`, `* 0.25`, the weighted colour divided by AlphaSum). Decoding and
// quantization go through 256-entry tables computed on the CPU with the reference's exact formulas
// (gpu/src/mips.rs `mip_tables`): decode tables are the reference's values, and an encode table
// holds, per byte b, the smallest f32 the reference's formula maps to b or more, so quantization
// here is the reference's bit for bit. Raw alpha uses only (correctly rounded) additions in the
// reference's order and an exact `* 0.25`, so alpha ranges and coverage counts equal the
// reference's exactly; colour and the remap may differ by a few ulp
// (WGSL division is within 2.5 ulp, and a compiler may fuse `a * b + c`), hence ±1 per channel.

// MIP_* mode ids, ADJUST_* (AlphaAdjust kinds), COVERAGE_BISECTION_STEPS, COVERAGE_ROUNDS
// (counting rounds of a CoveragePreserving level: scale 1, f32::MAX, then the bisection steps),
// MIPS_TILE, MIPS_LAYER_WORKGROUP_SIZE and TABLE_* (offsets of the four tables in `tables`):
// generated from Rust (the mode ids: gpu/src/shaders.rs; the rest: gpu/src/mips.rs, SOURCE).

// CoverageState::phase: which count the state waits for.
const COVERAGE_AT_ONE: u32 = 0u;
const COVERAGE_AT_MAX: u32 = 1u;
const COVERAGE_BISECT: u32 = 2u;
const COVERAGE_DONE: u32 = 3u;
// f32::MAX.to_bits(): the upper end of the coverage bracket.
const F32_MAX_BITS: u32 = 0x7F7FFFFFu;
// +inf bits: the identity of atomicMin over non-negative f32 bit patterns.
const F32_INF_BITS: u32 = 0x7F800000u;

// Keep in sync with forestlod_gpu::mips::MipsUniform (gpu/src/mips.rs). One per level, bound with
// a dynamic offset.
struct MipsUniform {
    // This level's index (0 = the input).
    level: u32,
    // This level's side.
    side: u32,
    layer_count: u32,
    // forestlod_shared::MipMode as u32.
    mode: u32,
    alpha_ref: f32,
    // Index (in u32 texels) of this level's first texel in `out_texels`.
    out_offset: u32,
    // Texels per (padded) row of this level in `out_texels`.
    out_row: u32,
    // Side of level 0.
    level0_side: u32,
}

// Keep in sync with forestlod_gpu::mips::MipLevelStats (same layout, atomics as u32).
struct LevelStats {
    // Bit pattern of the level's smallest raw alpha (E Alg. 3.2 MinAlpha_k).
    alpha_min: atomic<u32>,
    // Bit pattern of the level's largest raw alpha (MaxAlpha_k).
    alpha_max: atomic<u32>,
    // Texels of the final (quantized) level passing the alpha test, byte / 255 > alpha_ref.
    pass_count: atomic<u32>,
    // ADJUST_* kind.
    adjust_kind: u32,
    // REMAP: (from min, from max, to min, to max); CONSTANT: (alpha, 0, 0, 0);
    // SCALE: (s, 0, 0, 0); KEEP: zeros.
    adjust: vec4<f32>,
}

// The coverage search of one layer (reference `coverage_scale`), advanced one counting round at
// a time; reused by every level. Keep in sync with forestlod_gpu::mips::CoverageState.
struct CoverageState {
    // Texels passing the alpha test at `test_bits`, summed by `mips_coverage_count`.
    count: atomic<u32>,
    // Bits of the scale the next counting round tests.
    test_bits: u32,
    // COVERAGE_*.
    phase: u32,
    // Bisection steps done.
    step: u32,
    // The bracket (f32 bit patterns) and its counts: count(lo) · 4^k < goal <= count(hi) · 4^k.
    lo: u32,
    hi: u32,
    count_lo: u32,
    count_hi: u32,
    count_at_one: u32,
    goal: u32,
    // Level 0's alpha-test count.
    count0: u32,
    // 4^k = level-0 texels / level-k texels.
    four_k: u32,
}

@group(0) @binding(0) var<uniform> u: MipsUniform;
// TABLE_SRGB_DECODE: sRGB byte -> linear; TABLE_UNORM_DECODE: byte -> byte / 255;
// TABLE_*_ENCODE[b], b in 1..=255: smallest f32 that quantizes to b or more ([0] unused).
@group(0) @binding(1) var<storage, read> tables: array<f32>;
// Raw values of the previous level (k >= 2), all layers: layer-major, then rows.
@group(0) @binding(2) var<storage, read> src: array<vec4<f32>>;
// Raw values of this level (unadjusted alpha), same layout.
@group(0) @binding(3) var<storage, read_write> dst: array<vec4<f32>>;
// Per (level, layer), level-major.
@group(0) @binding(4) var<storage, read_write> stats: array<LevelStats>;
// Final RGBA8 texels (r | g << 8 | b << 16 | a << 24) of every level >= 1, rows padded for
// copy_buffer_to_texture.
@group(0) @binding(5) var<storage, read_write> out_texels: array<u32>;
// Level 0 of every layer through an Rgba8Unorm view: the stored bytes, not decoded.
@group(0) @binding(6) var level0: texture_2d_array<f32>;
// One per layer.
@group(0) @binding(7) var<storage, read_write> coverage: array<CoverageState>;

var<workgroup> wg_min: atomic<u32>;
var<workgroup> wg_max: atomic<u32>;
var<workgroup> wg_count: atomic<u32>;

fn stats_index(level: u32, layer: u32) -> u32 {
    return level * u.layer_count + layer;
}

// The byte a linear value quantizes to with the encode table at `table`: the largest b with
// `x >= tables[table + b]` (0 if none; NaN gives 0), by an 8-step binary search.
fn encode_byte(x: f32, table: u32) -> u32 {
    var b = 0u;
    for (var step = 128u; step > 0u; step = step >> 1u) {
        if x >= tables[table + b + step] {
            b = b + step;
        }
    }
    return b;
}

// reference `passes_alpha_test`: quantized to UNORM8 first, then byte / 255 > alpha_ref.
fn passes_alpha_test(alpha: f32) -> bool {
    return tables[TABLE_UNORM_DECODE + encode_byte(alpha, TABLE_UNORM_ENCODE)] > u.alpha_ref;
}

// reference `AlphaAdjust::Scale(s).apply`: min(max(α · s, 0), 1).
fn scale_alpha(alpha: f32, s: f32) -> f32 {
    return min(max(alpha * s, 0.0), 1.0);
}

// reference `AlphaAdjust::apply`.
fn apply_adjust(alpha: f32, kind: u32, p: vec4<f32>) -> f32 {
    switch kind {
        case ADJUST_REMAP: {
            let t = (alpha - p.x) / (p.y - p.x);
            let remapped = p.z * (1.0 - t) + p.w * t;
            return min(max(remapped, p.z), p.w);
        }
        case ADJUST_CONSTANT: {
            return p.x;
        }
        case ADJUST_SCALE: {
            return scale_alpha(alpha, p.x);
        }
        default: {
            return alpha;
        }
    }
}

// reference `downsample_texel`: texel `tij` at (2x + i, 2y + j) of the previous raw level.
fn downsample_texel(t00: vec4<f32>, t10: vec4<f32>, t01: vec4<f32>, t11: vec4<f32>, mode: u32) -> vec4<f32> {
    let alpha_sum = (t00.w + t10.w) + (t01.w + t11.w);
    let weighted = mode != MIP_BOX && alpha_sum > 0.0;
    var rgb: vec3<f32>;
    if weighted {
        // E Alg. 3.2 line 6: Σ(c · α) / AlphaSum, each product rounded before the sums.
        let p00 = t00.xyz * t00.w;
        let p10 = t10.xyz * t10.w;
        let p01 = t01.xyz * t01.w;
        let p11 = t11.xyz * t11.w;
        rgb = ((p00 + p10) + (p01 + p11)) / alpha_sum;
    } else {
        rgb = ((t00.xyz + t10.xyz) + (t01.xyz + t11.xyz)) * 0.25;
    }
    // E Alg. 3.2 line 7: AlphaSum / 4.
    return vec4<f32>(rgb, alpha_sum * 0.25);
}

// Starts a tiled pass: one invocation clears the workgroup's stats, then all wait for it (call
// it first, from uniform control flow).
fn reset_workgroup_stats(lid: u32) {
    if lid == 0u {
        atomicStore(&wg_min, F32_INF_BITS);
        atomicStore(&wg_max, 0u);
        atomicStore(&wg_count, 0u);
    }
    workgroupBarrier();
}

// The builtins of a per-texel pass: one MIPS_TILE² workgroup per tile of the level, `z` the
// layer.
struct TexelInvocation {
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
}

// Starts a per-texel pass (reset_workgroup_stats); whether the invocation's texel lies within
// the level (`u.side`²).
fn begin_texel_pass(inv: TexelInvocation) -> bool {
    reset_workgroup_stats(inv.lid);
    return inv.gid.x < u.side && inv.gid.y < u.side;
}

// Index of the invocation's texel in a level of `u.side`² texels per layer (`src`, `dst`).
fn level_index(inv: TexelInvocation) -> u32 {
    return (inv.gid.z * u.side + inv.gid.y) * u.side + inv.gid.x;
}

// Folds a raw texel's alpha (its bits: non-negative floats order as their bits) into the
// workgroup's range.
fn add_to_alpha_range(raw: vec4<f32>) {
    let bits = bitcast<u32>(raw.w);
    atomicMin(&wg_min, bits);
    atomicMax(&wg_max, bits);
}

// Merges the workgroup's alpha range into `stats[s]` (one invocation, after a barrier).
fn merge_alpha_range(s: u32) {
    atomicMin(&stats[s].alpha_min, atomicLoad(&wg_min));
    atomicMax(&stats[s].alpha_max, atomicLoad(&wg_max));
}

// Level 0's raw value at (x, y) of `layer`: the stored bytes decoded by the tables.
fn load_level0(layer: u32, x: u32, y: u32) -> vec4<f32> {
    let stored = textureLoad(level0, vec2<u32>(x, y), layer, 0);
    // UNORM bytes back from the view's float (exact after rounding).
    let bytes = vec4<u32>(round(stored * 255.0));
    return vec4<f32>(
        tables[TABLE_SRGB_DECODE + bytes.x],
        tables[TABLE_SRGB_DECODE + bytes.y],
        tables[TABLE_SRGB_DECODE + bytes.z],
        tables[TABLE_UNORM_DECODE + bytes.w],
    );
}

// Level 0: its alpha range and alpha-test count (its raw values are decoded again where level 1
// reads them, so level 0 needs no buffer of its own).
@compute @workgroup_size(MIPS_TILE, MIPS_TILE, 1)
fn mips_decode(inv: TexelInvocation) {
    let inside = begin_texel_pass(inv);
    let layer = inv.gid.z;
    if inside {
        let raw = load_level0(layer, inv.gid.x, inv.gid.y);
        add_to_alpha_range(raw);
        if passes_alpha_test(scale_alpha(raw.w, 1.0)) {
            atomicAdd(&wg_count, 1u);
        }
    }
    workgroupBarrier();
    if inv.lid == 0u {
        let s = stats_index(0u, layer);
        merge_alpha_range(s);
        atomicAdd(&stats[s].pass_count, atomicLoad(&wg_count));
    }
}

// Level k >= 1: raw level k from raw level k - 1 (level 0 read from the texture), and its raw
// alpha range.
@compute @workgroup_size(MIPS_TILE, MIPS_TILE, 1)
fn mips_downsample(inv: TexelInvocation) {
    let inside = begin_texel_pass(inv);
    let layer = inv.gid.z;
    if inside {
        let x = 2u * inv.gid.x;
        let y = 2u * inv.gid.y;
        var t00: vec4<f32>;
        var t10: vec4<f32>;
        var t01: vec4<f32>;
        var t11: vec4<f32>;
        if u.level == 1u {
            t00 = load_level0(layer, x, y);
            t10 = load_level0(layer, x + 1u, y);
            t01 = load_level0(layer, x, y + 1u);
            t11 = load_level0(layer, x + 1u, y + 1u);
        } else {
            let prev = u.side * 2u;
            let row0 = (layer * prev + y) * prev + x;
            let row1 = row0 + prev;
            t00 = src[row0];
            t10 = src[row0 + 1u];
            t01 = src[row1];
            t11 = src[row1 + 1u];
        }
        let raw = downsample_texel(t00, t10, t01, t11, u.mode);
        dst[level_index(inv)] = raw;
        add_to_alpha_range(raw);
    }
    workgroupBarrier();
    if inv.lid == 0u {
        merge_alpha_range(stats_index(u.level, layer));
    }
}

// reference `coverage_scale`'s error, in units of n_k texels: with N0 = 4^k · n_k, the
// reference's |count · N0 - count0 · n_k| is n_k · |count · 4^k - count0|, so every comparison is
// the reference's and fits in u32 (count · 4^k <= N0 <= 2^24).
fn coverage_error(count: u32, four_k: u32, count0: u32) -> u32 {
    let scaled = count * four_k;
    return max(scaled, count0) - min(scaled, count0);
}

// Level k >= 1: the level's AlphaAdjust per layer (reference `alpha_aware_adjust`; Box keeps
// alpha); for CoveragePreserving, the start of the search (the first round counts at scale 1).
@compute @workgroup_size(MIPS_LAYER_WORKGROUP_SIZE, 1, 1)
fn mips_adjust(@builtin(global_invocation_id) gid: vec3<u32>) {
    let layer = gid.x;
    if layer >= u.layer_count {
        return;
    }
    let s = stats_index(u.level, layer);
    let s0 = stats_index(0u, layer);
    let raw_min = bitcast<f32>(atomicLoad(&stats[s].alpha_min));
    let raw_max = bitcast<f32>(atomicLoad(&stats[s].alpha_max));
    let min0 = bitcast<f32>(atomicLoad(&stats[s0].alpha_min));
    let max0 = bitcast<f32>(atomicLoad(&stats[s0].alpha_max));
    if u.mode == MIP_ALPHA_AWARE {
        if raw_min < raw_max {
            stats[s].adjust_kind = ADJUST_REMAP;
            stats[s].adjust = vec4<f32>(raw_min, raw_max, min0, max0);
        } else if raw_max > 0.0 {
            stats[s].adjust_kind = ADJUST_CONSTANT;
            stats[s].adjust = vec4<f32>(max0, 0.0, 0.0, 0.0);
        } else {
            stats[s].adjust_kind = ADJUST_CONSTANT;
            stats[s].adjust = vec4<f32>(min0, 0.0, 0.0, 0.0);
        }
    } else if u.mode == MIP_COVERAGE {
        atomicStore(&coverage[layer].count, 0u);
        coverage[layer].test_bits = bitcast<u32>(1.0);
        coverage[layer].phase = COVERAGE_AT_ONE;
        coverage[layer].step = 0u;
        coverage[layer].count0 = atomicLoad(&stats[s0].pass_count);
        coverage[layer].four_k = (u.level0_side * u.level0_side) / (u.side * u.side);
        // Written again when the search ends; a valid adjustment meanwhile.
        stats[s].adjust_kind = ADJUST_SCALE;
        stats[s].adjust = vec4<f32>(1.0, 0.0, 0.0, 0.0);
    }
}

// One counting pass of the coverage search (reference `alpha_test_count` at the layer's trial
// scale): every texel of the level, reduced per workgroup, summed per layer.
@compute @workgroup_size(MIPS_TILE, MIPS_TILE, 1)
fn mips_coverage_count(inv: TexelInvocation) {
    let inside = begin_texel_pass(inv);
    let layer = inv.gid.z;
    let searching = coverage[layer].phase != COVERAGE_DONE;
    if searching && inside {
        let alpha = dst[level_index(inv)].w;
        let scale = bitcast<f32>(coverage[layer].test_bits);
        if passes_alpha_test(scale_alpha(alpha, scale)) {
            atomicAdd(&wg_count, 1u);
        }
    }
    workgroupBarrier();
    if inv.lid == 0u && searching {
        atomicAdd(&coverage[layer].count, atomicLoad(&wg_count));
    }
}

// Ends a layer's search with scale `s`.
fn finish_coverage(layer: u32, s: f32) {
    coverage[layer].phase = COVERAGE_DONE;
    let i = stats_index(u.level, layer);
    stats[i].adjust_kind = ADJUST_SCALE;
    stats[i].adjust = vec4<f32>(s, 0.0, 0.0, 0.0);
}

// One step of reference `coverage_scale` per layer, from the count of the round just done.
@compute @workgroup_size(MIPS_LAYER_WORKGROUP_SIZE, 1, 1)
fn mips_coverage_step(@builtin(global_invocation_id) gid: vec3<u32>) {
    let layer = gid.x;
    if layer >= u.layer_count {
        return;
    }
    let count = atomicExchange(&coverage[layer].count, 0u);
    let four_k = coverage[layer].four_k;
    let count0 = coverage[layer].count0;
    let phase = coverage[layer].phase;
    if phase == COVERAGE_AT_ONE {
        // `count(1)` is exactly the target: keep scale 1.
        coverage[layer].count_at_one = count;
        if coverage_error(count, four_k, count0) == 0u {
            finish_coverage(layer, 1.0);
        } else {
            coverage[layer].phase = COVERAGE_AT_MAX;
            coverage[layer].test_bits = F32_MAX_BITS;
        }
    } else if phase == COVERAGE_AT_MAX {
        // `count(f32::MAX)`: the most any scale reaches.
        let goal = min(count0, count * four_k);
        if goal == 0u {
            finish_coverage(layer, select(0.0, 1.0, coverage[layer].count_at_one == 0u));
        } else {
            coverage[layer].goal = goal;
            coverage[layer].lo = 0u;
            coverage[layer].hi = F32_MAX_BITS;
            coverage[layer].count_lo = 0u;
            coverage[layer].count_hi = count;
            coverage[layer].phase = COVERAGE_BISECT;
            coverage[layer].test_bits = F32_MAX_BITS / 2u;
        }
    } else if phase == COVERAGE_BISECT {
        let mid = coverage[layer].test_bits;
        if count * four_k >= coverage[layer].goal {
            coverage[layer].hi = mid;
            coverage[layer].count_hi = count;
        } else {
            coverage[layer].lo = mid;
            coverage[layer].count_lo = count;
        }
        let step = coverage[layer].step + 1u;
        coverage[layer].step = step;
        let lo = coverage[layer].lo;
        let hi = coverage[layer].hi;
        if step < COVERAGE_BISECTION_STEPS {
            coverage[layer].test_bits = lo + (hi - lo) / 2u;
        } else {
            // Adjacent floats lo < hi: the better of the two is optimal; ties go to hi (the
            // more opaque choice), and scale 1 wins whenever it is as good.
            let error_hi = coverage_error(coverage[layer].count_hi, four_k, count0);
            let error_lo = coverage_error(coverage[layer].count_lo, four_k, count0);
            var best = bitcast<f32>(hi);
            var best_error = error_hi;
            if error_hi > error_lo {
                best = bitcast<f32>(lo);
                best_error = error_lo;
            }
            if coverage_error(coverage[layer].count_at_one, four_k, count0) <= best_error {
                best = 1.0;
            }
            finish_coverage(layer, best);
        }
    }
}

// Level k >= 1: adjusted alpha, quantized texels and the level's alpha-test count.
@compute @workgroup_size(MIPS_TILE, MIPS_TILE, 1)
fn mips_finalize(inv: TexelInvocation) {
    let inside = begin_texel_pass(inv);
    let layer = inv.gid.z;
    let s = stats_index(u.level, layer);
    if inside {
        let raw = dst[level_index(inv)];
        let alpha = apply_adjust(raw.w, stats[s].adjust_kind, stats[s].adjust);
        let r = encode_byte(raw.x, TABLE_SRGB_ENCODE);
        let g = encode_byte(raw.y, TABLE_SRGB_ENCODE);
        let b = encode_byte(raw.z, TABLE_SRGB_ENCODE);
        let a = encode_byte(alpha, TABLE_UNORM_ENCODE);
        out_texels[u.out_offset + (layer * u.side + inv.gid.y) * u.out_row + inv.gid.x] =
            r | (g << 8u) | (b << 16u) | (a << 24u);
        if tables[TABLE_UNORM_DECODE + a] > u.alpha_ref {
            atomicAdd(&wg_count, 1u);
        }
    }
    workgroupBarrier();
    if inv.lid == 0u {
        atomicAdd(&stats[s].pass_count, atomicLoad(&wg_count));
    }
}
