//! Sensitivity of the gates (issue 36, class 2): each statistical gate and each forgiving budget
//! of the harness is tested with one input it must pass and one it must fail, placed either side
//! of its limit (at the limit passes, one step past fails, by the gate's exact rule). Most live
//! beside their gate as unit tests (`cargo test --workspace --lib gate_`); the texture-stage check
//! of [`forestlod_harness::diagnose`] is tested here through its public API.
//!
//! | gate | limit | test |
//! |---|---|---|
//! | `stats::SignedHistogram::bias_failure`, sign test | `\|P-N\| > 5 sqrt(P+N)` | `stats::tests::gate_sign_test_sparse_one_sided_among_zeros_fails`, `gate_sign_test_balanced_large_noise_passes`, `gate_sign_test_boundary_is_26_elements` |
//! | `bias_failure` / `value_bias_failure`, mean | `\|mean\| > max_bias` | `stats::tests::gate_bias_mean_at_limit_passes_one_past_fails` |
//! | `stats::decision_budget_failure` | `ceil(1e-3 n) + 2` | `stats::tests::gate_decision_budget_at_budget_passes_one_more_fails` |
//! | `image_compare` class budgets (window, threshold colour/depth/id, translucent, edge colour/depth/id), `CLASS_BUDGET_FLOOR` | `ceil(f · of) + 4` | `image_compare::tests::gate_every_class_budget_at_budget_passes_one_more_fails` |
//! | `ImageReport::compound_budget` | `floor(1e-5 n)` | `image_compare::tests::gate_compound_budget_at_budget_passes_one_more_fails` |
//! | `DEPTH_TIE_MAX_FRACTION`, `FLIP_MEAN_MAX`, `COLOR_BIAS_MAX`, `DEPTH_BIAS_MAX_ULPS` | 1 %, 0.03, 1.5, 8 ulp | `image_compare::tests::gate_depth_tie_flip_and_bias_limits` |
//! | `COLOR_TOLERANCE` | 8 | `image_compare::tests::gate_color_tolerance_at_tolerance_passes_one_more_fails` |
//! | `DEPTH_MAX_ULPS` | 64 | `image_compare::tests::depth_is_judged_in_ulps` |
//! | `TEXEL_BIAS_MAX`, `MIPS_BIAS_MAX` | 0.05, 1e-3 per value | `texel_compare::tests::gate_texel_and_mips_bias_at_limit_pass_one_past_fail` |
//! | `TexelTally` tolerance | ±1 | `texel_compare::tests::gate_texel_tolerance_at_tolerance_passes_one_more_fails` |
//! | `judge::AMBIGUITY_REL` | `\|x-t\| <= rel (\|c-e\|₁ + r + \|t\|)` | `judge::tests::gate_ambiguity_rel_flips_at_its_boundary` |
//! | `judge::check_order` key bound (`contraction::near_depth_bound`) | `\|key - key_ref\| <= bound` | `judge::tests::gate_key_bound_at_bound_ambiguous_one_step_past_fails`, `contraction::tests::near_depth_bound_covers_every_contraction` |
//! | `diagnose::STAGE_TEXEL_MAX_FRACTION`, `BAKE_BIAS_MAX` | 6e-3, 0.5 per value | this file: `texel_check_fraction_and_bias_at_limit_pass_one_past_fail` |

use forestlod_harness::diagnose::{BAKE_BIAS_MAX, STAGE_TEXEL_MAX_FRACTION, texel_check};
use forestlod_harness::texel_compare::TexelTally;

/// `diagnose::texel_check`: 6 of 1,000 texels beyond ±1 is exactly [`STAGE_TEXEL_MAX_FRACTION`]
/// (the stage does not differ), 7 differ; 100 of 200 red values one step up is a per-value bias
/// of exactly [`BAKE_BIAS_MAX`] (does not differ), 101 differ.
#[test]
fn texel_check_fraction_and_bias_at_limit_pass_one_past_fail() {
    let beyond = |over: u32| {
        let mut tally = TexelTally::default();
        // Alternating +2 / -2 in green on `over` texels: beyond ±1, and no bias (one green
        // reference value, its differences near balance).
        for i in 0..1000u32 {
            let want = [9, 100, (i % 250) as u8, 255];
            let mut got = want;
            if i < over {
                got[1] = if i % 2 == 0 { 102 } else { 98 };
            }
            tally.texel(|| format!("texel {i}"), got, want, 1);
        }
        tally
    };
    let at = beyond(6);
    assert_eq!(
        at.over_tolerance as f64 / at.texels as f64,
        STAGE_TEXEL_MAX_FRACTION
    );
    let check = texel_check("textures", &at);
    assert!(!check.differs, "{}", check.summary);
    let check = texel_check("textures", &beyond(7));
    assert!(
        check.differs && check.summary.contains("7 beyond ±1"),
        "{}",
        check.summary
    );

    let biased = |up: u8| {
        let mut tally = TexelTally::default();
        for v in 0..200u8 {
            let want = [v, 0, 0, 255];
            let got = [v + u8::from(v < up), 0, 0, 255];
            tally.texel(|| format!("value {v}"), got, want, 1);
        }
        tally
    };
    let at = biased(100);
    assert_eq!(at.channels[0].value_bias().0, BAKE_BIAS_MAX);
    let check = texel_check("textures", &at);
    assert!(!check.differs, "{}", check.summary);
    let check = texel_check("textures", &biased(101));
    assert!(
        check.differs && check.summary.contains("textures channel R: bias"),
        "{}",
        check.summary
    );
}
