//! Billboard elevation angles: the bake angles of E Alg. 3.1 and the layer index of E Eq. 3.1.
//!
//! **Convention for V.** `V` is the unit vector *from the tree towards the eye* and `U` the tree's
//! up vector (world +Z, trees stand upright), so `V · U = sin(elevation)` where elevation is the
//! angle of the eye above the tree's horizon. Seen level, `V · U = 0`; seen from straight above,
//! `V · U = 1`; from below the horizon, negative. With this reading Eq. 3.1 maps level views to
//! layer 0 and top-down views to layer `a`, matching the bake order of Alg. 3.1, where layer `k` is
//! rendered at elevation `90° / (K - 1) · k`.
//!
//! Keep in sync with `gpu/src/shaders/common.wgsl` (`angle_index`).

use core::f32::consts::{FRAC_PI_2, PI};

/// E Eq. 3.1 exactly as written: `i = a - floor((2a / π) · acos(V · U))`, in `f32`.
///
/// Returned as `f32` so that its failures stay visible (shown by tests):
/// - `V · U = 1` (straight down) gives `i = a`: one past the last layer `a - 1`;
/// - views from below the horizon give negative `i`;
/// - `|V · U| > 1`, reachable by rounding when normalizing `V`, gives NaN from `acos`;
/// - its bins `(k - 1, k] · 90° / a` do not centre on the bake angles `90° / (a - 1) · k`.
pub fn angle_index_eq31(v_dot_u: f32, a: u32) -> f32 {
    let a = a as f32;
    a - ((2.0 * a / PI) * v_dot_u.acos()).floor()
}

/// Elevation (radians) at which layer `k` of `k_count` is baked: `90° / (K - 1) · k` (E Alg. 3.1).
///
/// `K = 1` would divide by zero; we define its single layer as the level view (0°), the view that
/// dominates a GIS camera over a forest. `k` beyond the last layer is clamped.
pub fn bake_elevation(k: u32, k_count: u32) -> f32 {
    if k_count <= 1 {
        return 0.0;
    }
    let k = k.min(k_count - 1);
    FRAC_PI_2 / (k_count - 1) as f32 * k as f32
}

/// The layer the pipeline uses: the baked elevation nearest to the true elevation, clamped to
/// `0..K-1`, NaN-free.
///
/// `v_dot_u` is clamped to `[0, 1]` first: views from below the horizon use the level layer (a
/// billboard cannot show a tree's underside), rounding past 1 uses the top layer, and NaN (a
/// zero-length view vector, SPEC §7) uses layer 0. The elevation is `asin(v_dot_u)`; its nearest
/// bake angle is `round(elevation / step)`, ties (exactly between two bake angles) rounding up.
///
/// Properties (proved by property tests): the result is in `0..K`, monotone non-decreasing in
/// `v_dot_u`, and no baked angle is closer to the true elevation than the chosen one.
pub fn angle_index(v_dot_u: f32, k_count: u32) -> u32 {
    if k_count <= 1 {
        return 0;
    }
    // `f32::max`/`min` return the non-NaN operand, so NaN maps to 0.
    let s = v_dot_u.max(0.0).min(1.0);
    let elevation = s.asin();
    let step = FRAC_PI_2 / (k_count - 1) as f32;
    let i = (elevation / step + 0.5).floor();
    (i as u32).min(k_count - 1)
}

/// E Eq. 3.1, clamped into `0..K-1` and NaN-free: the thesis's index made safe, kept as a variant so
/// experiments can measure what the bin offset costs (`AngleIndexMode::Eq31Clamped`).
pub fn angle_index_eq31_clamped(v_dot_u: f32, k_count: u32) -> u32 {
    let s = v_dot_u.max(-1.0).min(1.0);
    let i = angle_index_eq31(s, k_count);
    if i.is_nan() {
        0
    } else {
        i.max(0.0).min((k_count.max(1) - 1) as f32) as u32
    }
}

/// The index of `mode` for `v_dot_u`.
pub fn angle_index_for(mode: crate::AngleIndexMode, v_dot_u: f32, k_count: u32) -> u32 {
    match mode {
        crate::AngleIndexMode::Nearest => angle_index(v_dot_u, k_count),
        crate::AngleIndexMode::Eq31Clamped => angle_index_eq31_clamped(v_dot_u, k_count),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::test_support::proptest_config;

    /// Eq. 3.1 at the extremes that SPEC §6 asks us to show.
    #[test]
    fn eq31_straight_down_is_one_past_the_last_layer() {
        for a in [2u32, 10, 16] {
            assert_eq!(angle_index_eq31(1.0, a), a as f32, "a = {a}");
        }
    }

    #[test]
    fn eq31_below_the_horizon_is_negative() {
        assert_eq!(angle_index_eq31(-1.0, 10), -10.0);
        assert!(angle_index_eq31(-0.2, 10) < 0.0);
    }

    #[test]
    fn eq31_past_one_from_rounding_is_nan() {
        // A normalized vector whose dot with +Z rounds past 1 in f32.
        let v_dot_u = 1.0f32 + f32::EPSILON;
        assert!(angle_index_eq31(v_dot_u, 10).is_nan());
        assert!(angle_index_eq31(-1.0 - f32::EPSILON, 10).is_nan());
        // The pipeline index stays defined there.
        assert_eq!(angle_index(v_dot_u, 10), 9);
        assert_eq!(angle_index(f32::NAN, 10), 0);
    }

    #[test]
    fn eq31_level_view_is_zero_and_just_above_is_one() {
        assert_eq!(angle_index_eq31(0.0, 10), 0.0);
        // Any elevation in (0, 9°] lands in bin 1 for a = 10: bins are (k-1, k]·90°/a.
        let e = 0.5f32.to_radians();
        assert_eq!(angle_index_eq31(e.sin(), 10), 1.0);
    }

    #[test]
    fn eq31_bins_do_not_centre_on_bake_angles() {
        // Bake angle of layer 5 of K = 10 is 50°; Eq. 3.1 bins have width 9° and edges at multiples
        // of 9°, so 50° falls into bin 6 (45°, 54°], not 5: every bin is offset from its layer.
        let a = 10;
        let e = bake_elevation(5, a);
        assert!((e.to_degrees() - 50.0).abs() < 1e-4);
        assert_eq!(angle_index_eq31(e.sin(), a), 6.0);
        assert_eq!(angle_index(e.sin(), a), 5);
        // Edge: exactly at a bin edge of Eq. 3.1 (45°) the floor jumps.
        let below = 44.99f32.to_radians().sin();
        let above = 45.01f32.to_radians().sin();
        assert_eq!(angle_index_eq31(below, a), 5.0);
        assert_eq!(angle_index_eq31(above, a), 6.0);
    }

    #[test]
    fn k_equals_one_and_two_are_defined() {
        assert_eq!(bake_elevation(0, 1), 0.0);
        assert_eq!(angle_index(1.0, 1), 0);
        assert_eq!(angle_index(0.3, 1), 0);
        assert_eq!(bake_elevation(1, 2), FRAC_PI_2);
        assert_eq!(angle_index(0.0, 2), 0);
        assert_eq!(angle_index(1.0, 2), 1);
        // 45° is the tie between 0° and 90°: rounds up.
        assert_eq!(angle_index(0.80, 2), 1);
        assert_eq!(angle_index(0.60, 2), 0);
    }

    proptest! {
        #![proptest_config(proptest_config())]

        #[test]
        fn used_index_is_always_in_range(v in proptest::num::f32::ANY, k in 1u32..=91) {
            let i = angle_index(v, k);
            prop_assert!(i < k, "index {i} for v·u = {v}, K = {k}");
            let j = angle_index_eq31_clamped(v, k);
            prop_assert!(j < k, "eq31 clamped {j} for v·u = {v}, K = {k}");
        }

        #[test]
        fn used_index_is_monotone_in_elevation(a in -1.5f32..1.5, b in -1.5f32..1.5, k in 1u32..=91) {
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            prop_assert!(angle_index(lo, k) <= angle_index(hi, k));
        }

        #[test]
        fn used_index_is_the_nearest_bake_angle(elev_deg in 0.0f64..=90.0, k in 1u32..=91) {
            let s = (elev_deg.to_radians().sin()) as f32;
            let i = angle_index(s, k);
            // True elevation of the f32 input, in f64.
            let e = (s as f64).clamp(0.0, 1.0).asin();
            let chosen = (e - bake_elevation(i, k) as f64).abs();
            for j in 0..k {
                let other = (e - bake_elevation(j, k) as f64).abs();
                // 1e-5 rad: f32 asin and the f32 bake angles are each within a few ulp (~1e-7 rad)
                // of exact; only true ties (other == chosen up to rounding) may go either way.
                prop_assert!(chosen <= other + 1e-5, "K={k} e={e} chose {i} ({chosen}) but {j} is {other}");
            }
        }
    }
}
