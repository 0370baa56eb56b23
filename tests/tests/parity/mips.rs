//! Parity of the GPU `mips` stage (`gpu/src/shaders/mips.wgsl`) with the reference
//! (`reference/src/mips.rs`), SPEC §5.2 and §8: E Alg. 3.2 (AlphaAware), the Box "blit" and
//! CoveragePreserving, every level of every layer, degenerate cases included.
//!
//! One test body ([`check`]) runs the reference and the GPU backends of
//! `forestlod_harness::texel_compare` on the same level-0 layers (the GPU gets them uploaded from the
//! CPU: the "bisect one stage" hook) and judges the GPU against the reference:
//! - every texel of every level within [`TEXEL_TOLERANCE`] per channel; the count of differing
//!   texels and the largest difference are reported per mode;
//! - the raw alpha range of every level (E Alg. 3.2's `MinAlpha_k`, `MaxAlpha_k`) bit for bit,
//!   the adjustment's kind exactly, and its parameters bit for bit (the remap's ranges and the
//!   coverage scale derive from exact raw alpha and exact counts, see `gpu/src/mips.rs`);
//! - each level's alpha-test count exactly wherever the two final alpha channels agree.
//!
//! Inputs: 256 random cases (sides 1..=64, powers of two, one to three layers, many black
//! transparent texels, sometimes all transparent or all opaque; random alpha reference), every
//! case in all three modes; a fixed set of degenerate layers; a 512² layer (large enough that a
//! coverage search looping inside one workgroup would hit llvmpipe's loop limiter); and the
//! built-in species' baked layers (the reference's `bake_layer`) at r = 128, K = 10.
//!
//! Measured on lavapipe: every alpha range, adjustment and alpha-test count bit-identical; texels
//! identical except for a rare colour byte one step apart (0 to 3 per run of ~600k texels per
//! mode; a 2048² layer: 3 of 5.6M).
//!
//! Without an adapter the tests fail with an install hint unless `FORESTLOD_ALLOW_NO_GPU=1`.

use std::time::Instant;

use forestlod_gpu::mips::{
    TABLE_SRGB_DECODE, TABLE_SRGB_ENCODE, TABLE_UNORM_DECODE, TABLE_UNORM_ENCODE, encode_byte,
    mip_tables,
};
use forestlod_harness::stage::{Backend, Bake, BakeInput, Mips, MipsInput, Reference};
use forestlod_harness::texel_compare::{
    GpuMipsBackend, LevelOut, MIPS_BIAS_MAX, TexelTally, gpu_bake,
};
use forestlod_reference::mips::AlphaAdjust;
use forestlod_reference::scene::builtin::species_meshes;
use forestlod_reference::texture::{Rgba8Image, linear_to_srgb, srgb_to_linear, unorm8};
use forestlod_shared::MipMode;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};

/// Largest per-channel difference allowed between a GPU and a reference texel.
///
/// Why ±1 (SPEC §8): quantization itself is exact on both sides (the GPU encodes through tables
/// of the reference's own formulas, checked byte for byte below), and raw alpha is exact; but the
/// alpha-weighted colour divides (WGSL allows 2.5 ulp), the remap divides and multiplies, and a
/// compiler may fuse `a * b + c`. A value a few ulp from a rounding boundary of the sRGB or UNORM
/// encoding can then land on the other byte: one step, never two. Measured maximum: 1.
const TEXEL_TOLERANCE: u8 = 1;

/// Proptest cases (each runs all three modes, so 768 GPU chains).
const CASES: u32 = 256;

/// Per-mode tallies over a run.
#[derive(Default)]
struct Tally {
    /// Chains compared (one per layer and mode).
    chains: u64,
    /// Levels compared.
    levels: u64,
    /// Levels whose alpha-test count was compared exactly.
    counts_compared: u64,
    /// Texel comparison per mode, in `MipMode::ALL` order.
    texels: [TexelTally; 3],
}

impl Tally {
    fn report(&self, what: &str, started: Instant) {
        eprintln!(
            "{what}: {} chains, {} levels ({} alpha-test counts compared exactly), {:.2} s",
            self.chains,
            self.levels,
            self.counts_compared,
            started.elapsed().as_secs_f64()
        );
        for (mode, t) in MipMode::ALL.iter().zip(&self.texels) {
            eprintln!("{what} {}: {}", mode.name(), t.summary());
            if let Some((where_, got, want)) = &t.first_over {
                eprintln!("  first beyond tolerance: {where_}: gpu {got:?} reference {want:?}");
            }
        }
    }

    /// Statistical parity over the whole run, per mode: panics when a mode's signed differences
    /// are biased ([`MIPS_BIAS_MAX`] and the sign test of `forestlod_harness::stats`).
    fn assert_unbiased(&self, what: &str) {
        let failures: Vec<String> = MipMode::ALL
            .iter()
            .zip(&self.texels)
            .flat_map(|(mode, t)| {
                t.bias_failures(&format!("{what} {}", mode.name()), MIPS_BIAS_MAX)
            })
            .collect();
        assert!(failures.is_empty(), "biased mips:\n{}", failures.join("\n"));
    }
}

/// The bits of an adjustment, for an exact comparison.
fn adjust_bits(a: AlphaAdjust) -> (u32, [u32; 4]) {
    match a {
        AlphaAdjust::Keep => (0, [0; 4]),
        AlphaAdjust::Remap { from, to } => (1, [from[0], from[1], to[0], to[1]].map(f32::to_bits)),
        AlphaAdjust::Constant(v) => (2, [v.to_bits(), 0, 0, 0]),
        AlphaAdjust::Scale(s) => (3, [s.to_bits(), 0, 0, 0]),
    }
}

/// Judges the GPU's chains against the reference's (module docs); updates `tally`.
fn judge(
    what: &str,
    mode: MipMode,
    alpha_ref: f32,
    got: &[Vec<LevelOut>],
    want: &[Vec<LevelOut>],
    tally: &mut Tally,
) -> Result<(), TestCaseError> {
    prop_assert_eq!(got.len(), want.len(), "{}: layer count", what);
    let mut texels = TexelTally::default();
    for (layer, (g, w)) in got.iter().zip(want).enumerate() {
        prop_assert_eq!(g.len(), w.len(), "{}: level count of layer {}", what, layer);
        tally.chains += 1;
        for (k, (gl, wl)) in g.iter().zip(w).enumerate() {
            let at = format!("{what} {} layer {layer} level {k}", mode.name());
            tally.levels += 1;
            prop_assert_eq!(
                (gl.image.width, gl.image.height),
                (wl.image.width, wl.image.height),
                "{}: size",
                at
            );
            texels.compare(&at, &gl.image.texels, &wl.image.texels, TEXEL_TOLERANCE);
            prop_assert_eq!(
                gl.raw_alpha_range.map(f32::to_bits),
                wl.raw_alpha_range.map(f32::to_bits),
                "{}: raw alpha range {:?} vs reference {:?}",
                at,
                gl.raw_alpha_range,
                wl.raw_alpha_range
            );
            prop_assert_eq!(
                adjust_bits(gl.adjust),
                adjust_bits(wl.adjust),
                "{}: adjust {:?} vs reference {:?}",
                at,
                gl.adjust,
                wl.adjust
            );
            // The GPU's count is its own bytes' count; equal to the reference's where the alpha
            // channels agree.
            let own = gl
                .image
                .texels
                .iter()
                .filter(|t| t[3] as f32 / 255.0 > alpha_ref)
                .count() as u64;
            prop_assert_eq!(
                gl.pass_count,
                own,
                "{}: GPU pass count vs its own texels",
                at
            );
            let alpha_equal = gl
                .image
                .texels
                .iter()
                .zip(&wl.image.texels)
                .all(|(a, b)| a[3] == b[3]);
            if alpha_equal {
                tally.counts_compared += 1;
                prop_assert_eq!(gl.pass_count, wl.pass_count, "{}: alpha-test count", at);
            }
        }
    }
    tally.texels[mode as usize].merge(&texels);
    prop_assert_eq!(
        texels.over_tolerance,
        0,
        "{}: texels beyond ±{}: first {:?}",
        what,
        TEXEL_TOLERANCE,
        texels.first_over
    );
    Ok(())
}

/// The one test body: both backends on `layers` in `mode`; the GPU judged against the reference.
fn check(
    what: &str,
    gpu: &dyn Backend<Mips>,
    layers: &[Rgba8Image],
    mode: MipMode,
    alpha_ref: f32,
    tally: &mut Tally,
) -> Result<(), TestCaseError> {
    let input = MipsInput {
        layers,
        mode,
        alpha_ref,
    };
    let want = Backend::<Mips>::run(&Reference, input);
    let got = gpu.run(input);
    judge(what, mode, alpha_ref, &got, &want, tally)
}

/// [`check`]s every case `(what, layers)` in every mode at each of `alpha_refs`; reports the
/// tally as `report` at the end, or before panicking with the first failure.
fn check_all(
    report: &str,
    started: Instant,
    gpu: &GpuMipsBackend,
    cases: &[(&str, Vec<Rgba8Image>)],
    alpha_refs: &[f32],
) {
    let mut tally = Tally::default();
    for (what, layers) in cases {
        for mode in MipMode::ALL {
            for &alpha_ref in alpha_refs {
                if let Err(e) = check(what, gpu, layers, mode, alpha_ref, &mut tally) {
                    tally.report(report, started);
                    panic!("{what}, {mode:?}, alpha_ref {alpha_ref}: {e}");
                }
            }
        }
    }
    tally.report(report, started);
    tally.assert_unbiased(report);
}

/// The GPU mips stage, or `None` (saying the test is skipped) without an adapter.
fn gpu_backend() -> Option<GpuMipsBackend> {
    let gpu = gpu_bake().map(|bake| GpuMipsBackend { bake });
    if gpu.is_none() {
        eprintln!("skipped, no GPU adapter");
    }
    gpu
}

fn image(side: u32, texels: Vec<[u8; 4]>) -> Rgba8Image {
    Rgba8Image {
        width: side,
        height: side,
        texels,
    }
}

fn with_alpha(alpha: u8) -> impl Strategy<Value = [u8; 4]> {
    any::<[u8; 3]>().prop_map(move |c| [c[0], c[1], c[2], alpha])
}

/// Many black transparent texels, some coloured transparent ones (AlphaSum = 0 with colour),
/// opaque ones and anything.
fn texel() -> impl Strategy<Value = [u8; 4]> {
    prop_oneof![
        4 => Just([0u8, 0, 0, 0]),
        1 => with_alpha(0),
        2 => with_alpha(255),
        3 => any::<[u8; 4]>(),
    ]
}

/// One to three layers of one side `2^0..=2^6`: mostly mixed, sometimes all transparent or all
/// opaque (each layer drawn independently).
fn layers() -> impl Strategy<Value = Vec<Rgba8Image>> {
    (0u32..=6).prop_flat_map(|e| {
        let side = 1u32 << e;
        let n = (side * side) as usize;
        let layer = prop_oneof![
            8 => prop::collection::vec(texel(), n),
            1 => prop::collection::vec(with_alpha(0), n),
            1 => prop::collection::vec(with_alpha(255), n),
        ]
        .prop_map(move |t| image(side, t));
        prop::collection::vec(layer, 1..=3)
    })
}

fn alpha_ref() -> impl Strategy<Value = f32> {
    prop_oneof![Just(0.5f32), 0.0f32..=1.0]
}

#[test]
fn gpu_tables_are_the_reference_formulas() {
    // CPU-only: the tables mips.wgsl decodes and quantizes with are the reference's functions.
    let t = mip_tables();
    for b in 0..=255u8 {
        let i = b as usize;
        assert_eq!(
            t[TABLE_SRGB_DECODE + i].to_bits(),
            srgb_to_linear(b).to_bits()
        );
        assert_eq!(t[TABLE_UNORM_DECODE + i], b as f32 / 255.0);
        if b > 0 {
            for (table, f) in [
                (TABLE_SRGB_ENCODE, linear_to_srgb as fn(f32) -> u8),
                (TABLE_UNORM_ENCODE, unorm8),
            ] {
                let x = t[table + i];
                let below = f32::from_bits(x.to_bits() - 1);
                assert_eq!(f(x), b, "threshold of {b} in table {table}");
                assert_eq!(
                    f(below),
                    b - 1,
                    "below the threshold of {b} in table {table}"
                );
            }
        }
    }
    // A sweep: every 2^12-th f32 in [0, 1], and the specials.
    let one = 1.0f32.to_bits();
    for bits in (0..=one).step_by(1 << 12).chain([one]) {
        let x = f32::from_bits(bits);
        assert_eq!(encode_byte(x, TABLE_SRGB_ENCODE), linear_to_srgb(x), "{x}");
        assert_eq!(encode_byte(x, TABLE_UNORM_ENCODE), unorm8(x), "{x}");
    }
    for x in [f32::NAN, -0.0, -1.0, 1.5, f32::INFINITY] {
        assert_eq!(encode_byte(x, TABLE_SRGB_ENCODE), linear_to_srgb(x), "{x}");
        assert_eq!(encode_byte(x, TABLE_UNORM_ENCODE), unorm8(x), "{x}");
    }
}

#[test]
fn gpu_mips_equal_the_reference_on_random_layers() {
    let Some(gpu) = gpu_backend() else { return };
    let started = Instant::now();
    let tally = std::cell::RefCell::new(Tally::default());
    let mut runner = TestRunner::new(Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(&(layers(), alpha_ref()), |(layers, alpha_ref)| {
        for mode in MipMode::ALL {
            let what = format!("{} layer(s) of {}²", layers.len(), layers[0].width);
            check(
                &what,
                &gpu,
                &layers,
                mode,
                alpha_ref,
                &mut tally.borrow_mut(),
            )?;
        }
        Ok(())
    });
    tally.borrow().report("random layers", started);
    if let Err(e) = result {
        panic!("{e}");
    }
    tally.borrow().assert_unbiased("random layers");
}

#[test]
fn gpu_mips_equal_the_reference_on_degenerate_layers() {
    let Some(gpu) = gpu_backend() else { return };
    let started = Instant::now();
    let side = 16;
    let n = (side * side) as usize;
    let lone = {
        let mut t = vec![[0u8; 4]; n];
        t[5 * 16 + 9] = [200, 120, 40, 255];
        t
    };
    let cases: Vec<(&str, Vec<Rgba8Image>)> = vec![
        ("1x1 opaque", vec![image(1, vec![[10, 200, 30, 255]])]),
        ("1x1 transparent", vec![image(1, vec![[10, 200, 30, 0]])]),
        ("1x1 half", vec![image(1, vec![[10, 200, 30, 128]])]),
        (
            "all transparent black",
            vec![image(side, vec![[0, 0, 0, 0]; n])],
        ),
        (
            "all transparent coloured (AlphaSum = 0 everywhere)",
            vec![image(
                side,
                (0..n).map(|i| [i as u8, 255 - i as u8, 77, 0]).collect(),
            )],
        ),
        (
            "all opaque",
            vec![image(
                side,
                (0..n).map(|i| [i as u8, (i * 7) as u8, 200, 255]).collect(),
            )],
        ),
        (
            "uniform alpha (min = max on every level)",
            vec![image(side, vec![[90, 160, 20, 100]; n])],
        ),
        ("one opaque texel", vec![image(side, lone)]),
        (
            "mixed array: opaque, transparent, half",
            vec![
                image(side, vec![[1, 2, 3, 255]; n]),
                image(side, vec![[0; 4]; n]),
                image(side, vec![[200, 100, 50, 128]; n]),
            ],
        ),
    ];
    check_all("degenerate layers", started, &gpu, &cases, &[0.0, 0.5, 1.0]);
}

#[test]
fn gpu_mips_equal_the_reference_on_baked_species() {
    let Some(gpu) = gpu_backend() else { return };
    let started = Instant::now();
    // The reference's baked layers of the five built-in species, r = 128, K = 10.
    let layers = Backend::<Bake>::run(
        &Reference,
        BakeInput {
            meshes: &species_meshes(),
            angle_count: 10,
            azimuth_count: 1,
            sphere: 0,
            grid: 0,
            side: 128,
            depth: false,
        },
    );
    assert_eq!(layers.len(), 50);
    let cases = [("species r=128 K=10", layers)];
    check_all("baked species", started, &gpu, &cases, &[0.5]);
}

#[test]
fn gpu_mips_equal_the_reference_on_a_large_layer() {
    // 512², every mode: 65536 texels per level-1 layer. A coverage search counting in one
    // workgroup loops 33 · 256 times per invocation there, which llvmpipe's loop limiter (65535
    // iterations per invocation, shared by all loops) cut short in the stage's first version;
    // the stage now counts one dispatch per round (gpu/src/mips.rs).
    let Some(gpu) = gpu_backend() else { return };
    let started = Instant::now();
    let side = 512u32;
    let texels: Vec<[u8; 4]> = (0..side * side)
        .map(|i| {
            let h = i.wrapping_mul(2_654_435_761);
            if h % 3 == 0 { [0; 4] } else { h.to_le_bytes() }
        })
        .collect();
    let cases = [("512² hashed", vec![image(side, texels)])];
    check_all("large layer", started, &gpu, &cases, &[0.5]);
}
