//! Parity of issue 30's blend (G§4: the dithered fades' threshold in each LOD's texture space,
//! the progress per tree; `reference/src/blend.rs`, `draw.wgsl`) across backends: the frames of
//! `forestlod_tests::scenarios::blend_scenarios` drawn by the GPU (the reference's selection and
//! textures, so only the draw is judged; then `select.wgsl` too) and judged against the
//! reference's by the existing image classes (`forestlod_harness::image_compare`).
//!
//! The one new rounding boundary is the texture-space noise level: both twins decide it exactly
//! from the bits of `ρ²`, but from their own `uv` derivatives (the reference rasterizer's coarse
//! differences, lavapipe's `dpdxCoarse`), so a quad whose `ρ²` lies within their difference of
//! a level boundary may read another level's noise texel on the GPU. The reference's frames at
//! `ρ² · (1 ∓ s)` (`alternatives::noise_level_alternatives`) are the alternatives that classify
//! those pixels (threshold-ambiguous, beside the alpha test's); each frame also reports
//! - the *noise-level boundary* pixels: where any alternative differs from the reference (the
//!   pixels the level's rounding can change at all), and
//! - the *noise-level ambiguous* pixels: GPU pixels the reference does not match at their
//!   position but a noise-level alternative does, held to [`NOISE_LEVEL_MAX_FRACTION`].

use forestlod_harness::alternatives::{alpha_test_alternatives, noise_level_alternatives};
use forestlod_harness::backend::GpuRenderer;
use forestlod_harness::context::gpu_context;
use forestlod_harness::gpu_frame::StagesFromCpu;
use forestlod_harness::image_compare::{
    COLOR_TOLERANCE, Images, compare_images, write_failure_images,
};
use forestlod_harness::stage::{Backend, Draw, FrameInput, Named, Reference};
use forestlod_reference::pipeline::prepare;
use forestlod_tests::assert_no_failures;
use forestlod_tests::scenarios::blend_scenarios;

/// Largest fraction of a frame's pixels that may be *noise-level ambiguous* (module docs).
///
/// Why 0.12 %: a level flip re-draws the threshold of one quad's four pixels, about half of
/// which then change. Measured on lavapipe (Mesa 22.3.6, LLVM 15): at most 0.039 % (10 of
/// 25,600 pixels, `crop-medium-dither-texture-tree`, whose parallel `dither` shows both LODs'
/// noise at every band pixel), with at most 206 boundary pixels per frame at ε = 1/8; the budget
/// is 3x that, as `image_compare::budget`'s are. A wrong level formula or noise hash changes the
/// kept set of the band's pixels (a sixth of these frames) wholesale, and the level-shifted
/// frames explain only the pixels one level step away.
const NOISE_LEVEL_MAX_FRACTION: f64 = 0.0012;

/// Whether pixel `k` of `a` and `b` shows the same thing: colour within [`COLOR_TOLERANCE`] in
/// every channel, and the same LOD id.
fn same(a: &Images, b: &Images, k: usize) -> bool {
    a.lod_id[k] == b.lod_id[k]
        && a.color[k]
            .iter()
            .zip(&b.color[k])
            .all(|(x, y)| x.abs_diff(*y) <= COLOR_TOLERANCE)
}

#[test]
fn gpu_blend_matches_the_reference() {
    let Some(ctx) = gpu_context() else { return };
    let scenarios = blend_scenarios();
    let mut failures = Vec::new();
    let mut prepared = Vec::new();
    for s in &scenarios {
        // The blend parameters change no prepared data (bake, mips): one preparation per scene.
        if !prepared.iter().any(|(crop, _)| *crop == s.crop) {
            prepared.push((
                s.crop,
                prepare(s.scene(), &s.params).expect("prepare blend scene"),
            ));
        }
        let p = &prepared
            .iter()
            .find(|(crop, _)| *crop == s.crop)
            .expect("prepared")
            .1;
        let camera = s.camera(&p.scene);
        let input = FrameInput {
            prepared: p,
            camera: &camera,
            params: &s.params,
        };
        let want = Backend::<Draw>::run(&Reference, input);
        let band = want
            .lod_id
            .iter()
            .filter(|&&id| id == forestlod_shared::LOD_ID_TRANSITION)
            .count();
        assert!(
            band * 20 > want.lod_id.len(),
            "{}: the band must be on screen ({band} pixels)",
            s.name
        );
        let noise_alternatives = noise_level_alternatives(p, &camera, &s.params);
        let pixels = want.color.len();
        let boundary = (0..pixels)
            .filter(|&k| noise_alternatives.iter().any(|a| !same(a, &want, k)))
            .count();
        let mut alternatives = alpha_test_alternatives(p, &camera, &s.params);
        alternatives.extend(noise_alternatives.iter().cloned());
        for option in [StagesFromCpu::ALL, StagesFromCpu::TEXTURES] {
            let backend = GpuRenderer { ctx, option };
            let name = format!("{}/{}", s.name, backend.name());
            let got = Backend::<Draw>::run(&backend, input);
            let ambiguous = (0..pixels)
                .filter(|&k| {
                    !same(&got, &want, k) && noise_alternatives.iter().any(|a| same(&got, a, k))
                })
                .count();
            let budget = (NOISE_LEVEL_MAX_FRACTION * pixels as f64).ceil() as usize;
            eprintln!(
                "{name}: noise-level boundary pixels {boundary}, noise-level ambiguous {ambiguous} \
                 ({:.3} %, budget {budget}), band pixels {band} of {pixels}",
                100.0 * ambiguous as f64 / pixels as f64
            );
            if ambiguous > budget {
                failures.push(format!(
                    "{name}: {ambiguous} noise-level ambiguous pixels exceed the budget {budget}"
                ));
            }
            let report = compare_images(&name, &got, &want, &alternatives, &camera);
            eprintln!("{report}");
            if !report.passed() {
                let dir = write_failure_images(&report, &got, &want);
                failures.push(format!(
                    "{name}: {} (images in {})",
                    report.failures().join("; "),
                    dir.display()
                ));
            }
        }
    }
    assert_no_failures("blend parity failed", &failures);
}
