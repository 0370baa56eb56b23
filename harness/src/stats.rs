//! Statistical parity (issue 15): beside the per-element tolerances of [`crate::texel_compare`]
//! and [`crate::image_compare`], the *distribution* of the signed differences (GPU minus
//! reference) of every compared buffer: its histogram, its mean (the bias) and the fraction of
//! elements at the tolerance edge.
//!
//! Why: a per-element tolerance of ±1 cannot see a rounding rule changed so that many texels move
//! by one unit in the same direction; every element stays within ±1 and the comparison passes.
//! Rounding noise of a correct port is symmetric (round-to-nearest on either side of a boundary,
//! an `f32` vs `f64` interpolation error of either sign), so its mean is near 0 however many
//! elements differ; a systematic error moves the mean. The gate ([`SignedHistogram::bias_failure`])
//! fails when both
//! - the mean exceeds a per-buffer limit (the effect size, a named constant at each call site,
//!   measured on a correct build), and
//! - the signs are unbalanced beyond chance: `|positive - negative| >
//!   BIAS_SIGN_Z · sqrt(positive + negative)` (a sign test), so that three one-signed roundings in a 4x4 texture, a large
//!   mean over few elements, are not a failure, while a one-signed shift over thousands is.
//!
//! Colour and texel buffers are gated *per distinct reference value*
//! ([`SignedHistogram::value_bias_failure`]): a flat surface repeats one rounding thousands of
//! times, which is one sample, not thousands (measured: the Primitive's near-fallback quads, one
//! colour, +1 in R on 56 % of a frame's pixels, on a correct build).

use std::collections::BTreeMap;
use std::fmt;

/// The sign-test threshold of the bias gate, in standard deviations of the difference between
/// the positive and negative counts under "no bias" (a fair coin per differing element).
///
/// Why 5: the suite runs hundreds of comparisons; at 5 σ a symmetric rounding noise trips the
/// sign test with probability under 1e-6 per comparison, while a one-signed shift of `n`
/// elements has `|P - N| = n` against `5 sqrt(n)`: it is caught from 26 elements on.
pub const BIAS_SIGN_Z: f64 = 5.0;

/// Largest fraction of the decisions (batches or trees) of a selection-parity run that may be
/// classified *ambiguous near a threshold* (`tests/tests/parity/{select,refine,baselines}.rs`),
/// plus [`DECISION_AMBIGUOUS_FLOOR`].
///
/// Why 1e-3: on a correct build every run measured 0 (`parity::select`: 0 of 6,591 random,
/// 1,328 knife-edge and 12,000 scan batches; `parity::refine`: 0 of 3.4M trees; `parity::baselines`
/// cull: 0 of 1.65M trees); near-threshold rounding is that rare. A rule changed at a classified
/// boundary (a margin dropped, a comparison flipped at equality) lands in the forgiven band on
/// every decision that sits near it, which is many more than one in a thousand.
pub const DECISION_AMBIGUOUS_MAX_FRACTION: f64 = 1e-3;

/// Ambiguous decisions allowed on top of [`DECISION_AMBIGUOUS_MAX_FRACTION`] (a run of a few
/// hundred decisions may meet one genuine near-threshold case).
pub const DECISION_AMBIGUOUS_FLOOR: u64 = 2;

/// Why `ambiguous` of `decisions` exceeds its budget, or `None`; `what` names the run and the
/// class. The count is reported beside the budget either way by the caller.
pub fn decision_budget_failure(what: &str, ambiguous: u64, decisions: u64) -> Option<String> {
    let budget = (DECISION_AMBIGUOUS_MAX_FRACTION * decisions as f64).ceil() as u64
        + DECISION_AMBIGUOUS_FLOOR;
    (ambiguous > budget).then(|| {
        format!(
            "{what}: {ambiguous} ambiguous decisions of {decisions} exceed the class budget \
             {budget} (a correct build has about none)"
        )
    })
}

/// Signed differences of one buffer (or one channel): a histogram with the tolerance they were
/// judged against.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SignedHistogram {
    /// Count per signed difference (GPU minus reference), zero included.
    pub bins: BTreeMap<i64, u64>,
    /// Elements recorded.
    pub n: u64,
    /// Sum of the signed differences.
    pub sum: i128,
    /// Elements with a positive difference.
    pub positive: u64,
    /// Elements with a negative difference.
    pub negative: u64,
    /// Elements whose `|difference|` equals the tolerance (the edge of what is accepted).
    pub at_edge: u64,
    /// The per-element tolerance (`0` for an exact buffer).
    pub tolerance: i64,
    /// Per reference value (a byte of a colour channel; empty for buffers recorded without
    /// one): how many elements had it and the sum of their signed differences.
    pub by_value: BTreeMap<i64, (u64, i64)>,
}

impl SignedHistogram {
    /// An empty histogram for a buffer judged with `tolerance` per element.
    pub fn new(tolerance: i64) -> Self {
        Self {
            tolerance,
            ..Self::default()
        }
    }

    /// Records one signed difference.
    pub fn record(&mut self, d: i64) {
        *self.bins.entry(d).or_insert(0) += 1;
        self.n += 1;
        self.sum += i128::from(d);
        if d > 0 {
            self.positive += 1;
        } else if d < 0 {
            self.negative += 1;
        }
        if d != 0 && d.abs() == self.tolerance {
            self.at_edge += 1;
        }
    }

    /// Records one signed difference `d` of an element whose reference value is `value` (see
    /// [`Self::value_bias`]).
    pub fn record_at(&mut self, value: i64, d: i64) {
        self.record(d);
        let e = self.by_value.entry(value).or_insert((0, 0));
        e.0 += 1;
        e.1 += d;
    }

    /// The bias per distinct reference value: `(mean over the values of their mean signed
    /// difference, values with a positive mean, values with a negative mean)`.
    ///
    /// Why per value: pixels are not independent samples. A flat-coloured surface whose one
    /// colour lies a few ulp from an sRGB rounding boundary shows thousands of one-signed +1s (one
    /// rounding, repeated), while a changed rounding rule moves *many distinct values* the same
    /// way. Counting each reference value once tells the two apart.
    pub fn value_bias(&self) -> (f64, u64, u64) {
        let means: Vec<f64> = self
            .by_value
            .values()
            .map(|&(n, sum)| sum as f64 / n.max(1) as f64)
            .collect();
        let mean = if means.is_empty() {
            0.0
        } else {
            means.iter().sum::<f64>() / means.len() as f64
        };
        let positive = means.iter().filter(|&&m| m > 0.0).count() as u64;
        let negative = means.iter().filter(|&&m| m < 0.0).count() as u64;
        (mean, positive, negative)
    }

    /// Why the differences are biased per distinct reference value, or `None`: the mean over the
    /// values exceeds `max_bias` and the values' signs are unbalanced beyond chance
    /// ([`BIAS_SIGN_Z`]). For buffers recorded with [`Self::record_at`].
    pub fn value_bias_failure(&self, what: &str, max_bias: f64) -> Option<String> {
        let (mean, p, q) = self.value_bias();
        let unbalanced = (p as f64 - q as f64).abs() > BIAS_SIGN_Z * ((p + q) as f64).sqrt();
        (mean.abs() > max_bias && unbalanced).then(|| {
            format!(
                "{what}: bias per reference value {mean:+.4} exceeds ±{max_bias} ({p} values \
                 shifted up, {q} down, of {}; element bias {:+.4}, histogram {})",
                self.by_value.len(),
                self.mean(),
                self.histogram()
            )
        })
    }

    /// Adds another histogram's counts (same tolerance).
    pub fn merge(&mut self, other: &SignedHistogram) {
        for (&d, &c) in &other.bins {
            *self.bins.entry(d).or_insert(0) += c;
        }
        self.n += other.n;
        self.sum += other.sum;
        self.positive += other.positive;
        self.negative += other.negative;
        self.at_edge += other.at_edge;
        self.tolerance = self.tolerance.max(other.tolerance);
        for (&v, &(n, sum)) in &other.by_value {
            let e = self.by_value.entry(v).or_insert((0, 0));
            e.0 += n;
            e.1 += sum;
        }
    }

    /// The mean signed difference (the bias), 0 when empty.
    pub fn mean(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.sum as f64 / self.n as f64
        }
    }

    /// The fraction of the elements at the tolerance edge.
    pub fn edge_fraction(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.at_edge as f64 / self.n as f64
        }
    }

    /// Whether the signs of the differing elements are unbalanced beyond chance
    /// ([`BIAS_SIGN_Z`]).
    pub fn signs_unbalanced(&self) -> bool {
        let (p, q) = (self.positive as f64, self.negative as f64);
        (p - q).abs() > BIAS_SIGN_Z * (p + q).sqrt()
    }

    /// Why the differences are biased, or `None`: the mean exceeds `max_bias` in magnitude and
    /// the signs are unbalanced ([`Self::signs_unbalanced`]). `what` names the buffer.
    pub fn bias_failure(&self, what: &str, max_bias: f64) -> Option<String> {
        (self.mean().abs() > max_bias && self.signs_unbalanced()).then(|| {
            format!(
                "{what}: bias {:+.5} exceeds ±{max_bias} ({} elements +, {} -, of {}; histogram {})",
                self.mean(),
                self.positive,
                self.negative,
                self.n,
                self.histogram()
            )
        })
    }

    /// The non-zero bins, `difference:count`, grouped into power-of-two ranges when there are
    /// more than 12.
    pub fn histogram(&self) -> String {
        let bins: Vec<(i64, u64)> = self
            .bins
            .iter()
            .filter(|&(&d, _)| d != 0)
            .map(|(&d, &c)| (d, c))
            .collect();
        if bins.is_empty() {
            return "[all 0]".into();
        }
        if bins.len() <= 12 {
            let parts: Vec<String> = bins.iter().map(|(d, c)| format!("{d:+}:{c}")).collect();
            return format!("[{}]", parts.join(" "));
        }
        // Power-of-two ranges: ±1, ±2..3, ±4..7, ...
        let mut grouped: BTreeMap<i64, u64> = BTreeMap::new();
        for (d, c) in bins {
            let k = 64 - (d.unsigned_abs()).leading_zeros() as i64; // 1 for 1, 2 for 2..3, ...
            *grouped.entry(d.signum() * k).or_insert(0) += c;
        }
        let parts: Vec<String> = grouped
            .iter()
            .map(|(&k, &c)| {
                let lo = 1i64 << (k.abs() - 1);
                let hi = (1i64 << k.abs()) - 1;
                let s = if k < 0 { "-" } else { "+" };
                if lo == hi {
                    format!("{s}{lo}:{c}")
                } else {
                    format!("{s}{lo}..{hi}:{c}")
                }
            })
            .collect();
        format!("[{}]", parts.join(" "))
    }
}

impl fmt::Display for SignedHistogram {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "bias {:+.2e} over {} ({} +, {} -), {:.2e} at the ±{} edge, histogram {}",
            self.mean(),
            self.n,
            self.positive,
            self.negative,
            self.edge_fraction(),
            self.tolerance,
            self.histogram()
        )?;
        if !self.by_value.is_empty() {
            let (mean, p, q) = self.value_bias();
            write!(
                f,
                "; per value {mean:+.2e} ({p} values up, {q} down, of {})",
                self.by_value.len()
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_noise_has_no_bias() {
        let mut h = SignedHistogram::new(1);
        for i in 0..10_000 {
            h.record(match i % 10 {
                0 => 1,
                1 => -1,
                _ => 0,
            });
        }
        assert_eq!(h.mean(), 0.0);
        assert_eq!(h.edge_fraction(), 0.2);
        assert!(h.bias_failure("noise", 1e-3).is_none(), "{h}");
    }

    #[test]
    fn a_one_signed_shift_within_tolerance_is_a_bias() {
        let mut h = SignedHistogram::new(1);
        for _ in 0..1000 {
            h.record(1);
        }
        let why = h.bias_failure("all +1", 1e-3).expect("a bias");
        assert!(why.contains("all +1") && why.contains("+1.00000"), "{why}");
    }

    #[test]
    fn few_one_signed_roundings_are_not_a_bias() {
        // Three +1 in a 4x4 texture: a large mean, but not beyond chance.
        let mut h = SignedHistogram::new(1);
        for i in 0..16 {
            h.record(i64::from(i < 3));
        }
        assert!(h.mean() > 0.1);
        assert!(h.bias_failure("small", 1e-3).is_none(), "{h}");
    }

    #[test]
    fn a_repeated_rounding_is_one_value_a_changed_rule_is_many() {
        // One flat colour (value 77) one step up everywhere: no bias per value.
        let mut flat = SignedHistogram::new(1);
        for i in 0..10_000 {
            flat.record_at(77, 1);
            flat.record_at(i64::from(i % 200), 0);
        }
        assert!(flat.bias_failure("flat", 1e-3).is_some());
        assert!(flat.value_bias_failure("flat", 0.1).is_none(), "{flat}");
        // Every value one step up: biased.
        let mut shifted = SignedHistogram::new(1);
        for i in 0..10_000 {
            shifted.record_at(i64::from(i % 256), 1);
        }
        let why = shifted.value_bias_failure("shifted", 0.1).expect("biased");
        assert!(why.contains("256 values shifted up"), "{why}");
    }

    /// `n` elements, `plus` of them `+d`, the rest 0.
    fn sparse(n: u64, plus: u64, d: i64) -> SignedHistogram {
        let mut h = SignedHistogram::new(1);
        for i in 0..n {
            h.record(if i < plus { d } else { 0 });
        }
        h
    }

    /// Sensitivity (issue 36, class 2): sparse one-sided differences among many equal elements.
    /// 100 of 10,000 elements +1: mean 0.01 above a limit of 1e-3, and `|P - N| = 100` against
    /// `BIAS_SIGN_Z sqrt(P + N) = 50`: biased. A sign test that counted the zeros too
    /// (`sqrt(n)`: 500) would pass it.
    #[test]
    fn gate_sign_test_sparse_one_sided_among_zeros_fails() {
        let h = sparse(10_000, 100, 1);
        assert_eq!((h.positive, h.negative, h.n), (100, 0, 10_000));
        assert!(h.signs_unbalanced(), "{h}");
        let why = h
            .bias_failure("sparse", 1e-3)
            .unwrap_or_else(|| panic!("100 of 10,000 elements +1 must be a bias: {h}"));
        assert!(why.contains("100 elements +, 0 -, of 10000"), "{why}");
        // The same shape per reference value: 10,000 distinct values, 100 of them +1.
        let mut v = SignedHistogram::new(1);
        for i in 0..10_000 {
            v.record_at(i, i64::from(i < 100));
        }
        let why = v
            .value_bias_failure("sparse values", 1e-3)
            .unwrap_or_else(|| {
                panic!("100 of 10,000 values shifted up must be a bias per value: {v}")
            });
        assert!(
            why.contains("100 values shifted up, 0 down, of 10000"),
            "{why}"
        );
    }

    /// Balanced noise of a large magnitude passes: 520 elements +10 and 480 -10 have a mean of
    /// +0.4 (above a limit of 0.1) and 10 per element, but `|P - N| = 40 <= 5 sqrt(1000) = 158`:
    /// chance. The same per reference value.
    #[test]
    fn gate_sign_test_balanced_large_noise_passes() {
        let mut h = SignedHistogram::new(10);
        for i in 0..1000 {
            h.record(if i < 520 { 10 } else { -10 });
        }
        assert!(h.mean() > 0.1, "{h}");
        assert!(!h.signs_unbalanced(), "{h}");
        assert_eq!(h.bias_failure("balanced", 0.1), None, "{h}");
        let mut v = SignedHistogram::new(10);
        for i in 0..1000 {
            v.record_at(i, if i < 520 { 10 } else { -10 });
        }
        assert!(v.value_bias().0 > 0.1, "{v}");
        assert_eq!(v.value_bias_failure("balanced values", 0.1), None, "{v}");
    }

    /// The doc's claim "caught from 26 elements on": `n` one-signed elements are unbalanced
    /// exactly when `n > 5 sqrt(n)`, i.e. `n > 25`. Per element and per value.
    #[test]
    fn gate_sign_test_boundary_is_26_elements() {
        for (n, biased) in [(25, false), (26, true)] {
            let h = sparse(n, n, 1);
            assert_eq!(
                h.bias_failure("one-signed", 1e-3).is_some(),
                biased,
                "{n} one-signed elements: {h}"
            );
            let mut v = SignedHistogram::new(1);
            for i in 0..n as i64 {
                v.record_at(i, -1);
            }
            assert_eq!(
                v.value_bias_failure("one-signed values", 1e-3).is_some(),
                biased,
                "{n} values shifted down: {v}"
            );
        }
    }

    /// The mean gate at its limit passes and one element past it fails (the sign test firing):
    /// 100 of 1,000 elements +1 is a mean of exactly 0.1.
    #[test]
    fn gate_bias_mean_at_limit_passes_one_past_fails() {
        let at = sparse(1000, 100, 1);
        assert_eq!(at.mean(), 0.1);
        assert!(at.signs_unbalanced(), "{at}");
        assert_eq!(at.bias_failure("at", 0.1), None, "{at}");
        let past = sparse(1000, 101, 1);
        assert!(past.bias_failure("past", 0.1).is_some(), "{past}");
        // Per value: 1,000 values, 100 (then 101) of them +1, the same means.
        let values = |plus: i64| {
            let mut v = SignedHistogram::new(1);
            for i in 0..1000 {
                v.record_at(i, i64::from(i < plus));
            }
            v
        };
        let at = values(100);
        assert_eq!(at.value_bias().0, 0.1);
        assert_eq!(at.value_bias_failure("at", 0.1), None, "{at}");
        assert!(values(101).value_bias_failure("past", 0.1).is_some());
    }

    /// `decision_budget_failure`: the budget is `ceil(1e-3 · decisions) + 2`; at it passes, one
    /// more fails naming the run. Literal budgets, so a changed fraction or floor shows.
    #[test]
    fn gate_decision_budget_at_budget_passes_one_more_fails() {
        // (decisions, budget): the floor alone; the fraction rounded up; the fraction.
        for (decisions, budget) in [(0u64, 2u64), (1001, 4), (10_000, 12), (1_000_000, 1002)] {
            assert_eq!(
                decision_budget_failure("run", budget, decisions),
                None,
                "{budget} of {decisions} is within the budget"
            );
            let why = decision_budget_failure("run", budget + 1, decisions)
                .unwrap_or_else(|| panic!("{} of {decisions} must exceed it", budget + 1));
            assert!(
                why.starts_with("run: ") && why.contains(&format!("class budget {budget} ")),
                "{why}"
            );
        }
    }

    #[test]
    fn many_bins_are_grouped() {
        let mut h = SignedHistogram::new(64);
        for d in -40..=40 {
            h.record(d);
        }
        assert_eq!(
            h.histogram(),
            "[-32..63:9 -16..31:16 -8..15:8 -4..7:4 -2..3:2 -1:1 +1:1 +2..3:2 +4..7:4 +8..15:8 +16..31:16 +32..63:9]"
        );
    }
}
