//! Per-batch far-field subsets (E§7, issue 29): beyond `subset_distance` a batch draws only a
//! nested, spatially even prefix of its trees, the trees leaving the prefix fading out one by one.
//!
//! E§7 asks for "subsets of trees for each batch with predefined densities ... sorting the indices
//! in the batches such that drawing a larger subset evenly increases the density of the drawn
//! trees, without leaving obvious gaps", and gives no densities, distances or compensation.
//!
//! ## Contract
//! - **Order** (`reference::subset`): each grid batch's indirection range is sorted once, at
//!   prepare, in a progressive order: every prefix is an even subset of the batch and a larger
//!   prefix holds every tree of a smaller one (nested). The indirection stays E Eq. 4.1's `4n`
//!   bytes; only its order within a batch changes, and only when [`SubsetMode`] is not `off`.
//! - **Density** ([`subset_density`]): `ρ(d) = max(ρ_min, (d_sub / d)²)` past `d_sub`, 1 before:
//!   the kept trees per unit of screen area stay about constant as the batch recedes (screen area
//!   falls as `1/d²`), down to the floor `ρ_min`.
//! - **Per tree** ([`subset_weight`]): the tree at rank `r` of `len` has `q = (r + 0.5) / len`; at
//!   its own centre depth `d` it is kept whole for `q ≤ ρ(d)`, dropped for `q ≥ ρ(d)·(1 + F)`,
//!   and fades linearly between ([`SUBSET_FADE`] `F`): a tree leaves its subset over a depth
//!   range of `√(1 + F)` = 12 %, not at a hard cut (the "fade per tree").
//! - **Per command** ([`subset_count`]): selection draws the first `⌈ρ(lo)·(1 + F)·len⌉ + 1`
//!   trees of the batch (at most `len`), `lo` the near end of the batch's view-depth interval.
//!   `ρ` falls with depth and every tree's centre lies at or past `lo`, so every tree with a
//!   non-zero weight is in its command (the `+ 1` absorbs the ulps of `ρ` at `lo` versus at the
//!   tree; property-tested). Selection stays conservative in *which batches and LODs* it draws;
//!   inside a batch the subset drops trees by design.
//! - **Compensation** ([`subset_scale`]): `thin` draws kept trees as they are (the seed says
//!   nothing); `thin-scale` enlarges each drawn tree by `1/√ρ(d)` about its base, which keeps the
//!   batch's expected canopy area (`ρ · s²` per tree slot) constant. The enlarged tree can poke
//!   out of its batch's bounding sphere; the batch is still culled on its own sphere, so at the
//!   frustum's side planes an enlarged tree of a batch wholly outside them is missing (a known,
//!   measured error of the option, not of the seed's reading).
//! - **Screen-door fade**: a fading tree keeps a fragment when a per-tree threshold (the frame
//!   pixel's [`crate::dither_threshold`] with the column shifted by a hash of the tree's rank, so
//!   overlapping fading trees do not open the same holes) is below its weight quantised to
//!   [`SUBSET_WEIGHT_STEPS`]; under the `alpha` fade mode the weight multiplies the alpha instead.
//!
//! `subset_distance` is a view depth, like `lod1_transition`: the subset is a distance rule, so
//! its density falls the same way under every LOD metric.
//!
//! Twin: `common.wgsl` (`subset_density`, `subset_count`, `subset_weight_code`), read by
//! `select.wgsl` and `draw.wgsl`.

crate::modes::modes! {
    /// Whether and how far batches draw a subset of their trees (module docs).
    pub enum SubsetMode {
        /// Every tree of a drawn batch is drawn (the thesis).
        Off = 0 => "off",
        /// Far batches draw an even subset, trees unchanged (E§7 as written).
        Thin = 1 => "thin" ("E§7"),
        /// As `thin`, each kept tree enlarged by `1/√ρ` to keep the canopy area.
        ThinScale = 2 => "thin-scale",
    }
}

/// The fade width in density: a tree at rank fraction `q` fades while `ρ(d)` falls from `q` to
/// `q / (1 + F)`, a depth range of `√(1 + F)` = 1.118 (12 %), about half the relative width of
/// the thesis's LOD fade band (250 m of 1000 m).
pub const SUBSET_FADE: f32 = 0.25;

/// The per-tree keep weight is quantised to this many steps (8 bits), so that it travels with the
/// tree's rank hash in one varying that an `f32` holds exactly (24 bits; `reference::draw`).
pub const SUBSET_WEIGHT_STEPS: u32 = 255;

/// The density kept at view depth `d` (module docs): 1 up to `d_sub`, then `(d_sub / d)²`, not
/// below `rho_min`. NaN `d` keeps everything.
pub fn subset_density(d: f32, d_sub: f32, rho_min: f32) -> f32 {
    if d.partial_cmp(&d_sub) != Some(core::cmp::Ordering::Greater) {
        return 1.0;
    }
    let r = d_sub / d;
    (r * r).max(rho_min)
}

/// How many of a group's `len` trees a command draws when the group's nearest view depth is `lo`
/// (module docs): `len` when the subsets are off.
pub fn subset_count(len: u32, lo: f32, mode: u32, d_sub: f32, rho_min: f32) -> u32 {
    if mode == SubsetMode::Off as u32 {
        return len;
    }
    let rho = subset_density(lo, d_sub, rho_min);
    if rho >= 1.0 {
        return len;
    }
    let want = (rho * (1.0 + SUBSET_FADE) * len as f32).ceil() as u32;
    want.saturating_add(1).min(len)
}

/// The keep weight of the tree at `rank` of a group of `len`, its centre at view depth `d`,
/// quantised to `0..=SUBSET_WEIGHT_STEPS` (module docs): `SUBSET_WEIGHT_STEPS` is whole, 0 is
/// dropped.
pub fn subset_weight_code(rank: u32, len: u32, d: f32, mode: u32, d_sub: f32, rho_min: f32) -> u32 {
    if mode == SubsetMode::Off as u32 || len == 0 {
        return SUBSET_WEIGHT_STEPS;
    }
    let rho = subset_density(d, d_sub, rho_min);
    if rho >= 1.0 {
        return SUBSET_WEIGHT_STEPS;
    }
    let q = (rank as f32 + 0.5) / len as f32;
    let w = ((rho * (1.0 + SUBSET_FADE) - q) / (rho * SUBSET_FADE)).clamp(0.0, 1.0);
    (w * SUBSET_WEIGHT_STEPS as f32 + 0.5) as u32
}

/// The scale factor a drawn tree at view depth `d` gets (module docs): `1/√ρ(d)` under
/// `thin-scale`, written `d / d_sub` (or `1/√ρ_min` at the floor) so that both twins compute it
/// with one division; 1 otherwise.
pub fn subset_scale(d: f32, mode: u32, d_sub: f32, rho_min: f32) -> f32 {
    if mode != SubsetMode::ThinScale as u32
        || d.partial_cmp(&d_sub) != Some(core::cmp::Ordering::Greater)
    {
        return 1.0;
    }
    let r = d_sub / d;
    if r * r > rho_min {
        d / d_sub
    } else {
        1.0 / rho_min.sqrt()
    }
}

/// The column shift of a fading tree's screen-door threshold: a hash of its rank (module docs).
pub fn subset_dither_shift(rank: u32) -> u32 {
    rank.wrapping_mul(0x9E37_79B9) >> 16
}

/// The packed per-tree varying of the draw: `rank shift << 8 | weight code` (24 bits, exact in an
/// `f32`).
pub fn subset_pack(rank: u32, code: u32) -> u32 {
    ((subset_dither_shift(rank) & 0xFFFF) << 8) | (code & 0xFF)
}

/// The fade weight of one fragment of a tree whose packed varying is `packed`
/// ([`subset_pack`]), at frame pixel `(x, y)` under fade mode `fade_mode`: the quantised weight
/// under `alpha`, else 1 where the tree's shifted threshold is below it and 0 elsewhere.
pub fn subset_fragment_weight(packed: u32, fade_mode: u32, x: u32, y: u32) -> f32 {
    let code = packed & 0xFF;
    if code >= SUBSET_WEIGHT_STEPS {
        return 1.0;
    }
    let w = code as f32 * (1.0 / SUBSET_WEIGHT_STEPS as f32);
    if fade_mode == crate::FadeMode::Alpha as u32 {
        return w;
    }
    let h = crate::dither_threshold(x.wrapping_add(packed >> 8), y);
    if h < w { 1.0 } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::test_support::proptest_config;

    const THIN: u32 = SubsetMode::Thin as u32;

    proptest! {
        #![proptest_config(proptest_config())]

        /// Every tree with a non-zero weight lies inside its command's count, for any tree depth
        /// at or past the group's near end (the per-command contract).
        #[test]
        fn the_count_covers_every_tree_with_weight(
            len in 1u32..20_000, lo in 0.0f32..2e4, extra in 0.0f32..2e4,
            d_sub in 1.0f32..5e3, rho_min in 0.001f32..1.0, rank_f in 0.0f64..1.0,
        ) {
            let count = subset_count(len, lo, THIN, d_sub, rho_min);
            let d = lo + extra;
            let rank = ((rank_f * len as f64) as u32).min(len - 1);
            if rank >= count {
                prop_assert_eq!(subset_weight_code(rank, len, d, THIN, d_sub, rho_min), 0,
                    "rank {} of {} past count {} at d {} (lo {})", rank, len, count, d, lo);
            }
            // And the count is not wasteful: past the last rank with a weight at `lo`, only the
            // `+ 1`, the ceiling and the ranks whose weight rounds to code 0 (half a step of
            // the band, `0.5 / 255 · ρ F len` < len / 1000).
            let last = (0..len).rev().find(|&r| subset_weight_code(r, len, lo, THIN, d_sub, rho_min) > 0);
            prop_assert!(count <= last.map_or(0, |r| r + 1) + 3 + len / 1000, "count {} last {:?}", count, last);
        }

        /// Weights fall with rank and with depth (nested subsets; a receding batch only loses trees).
        #[test]
        fn weights_fall_with_rank_and_depth(
            len in 1u32..20_000, d in 0.0f32..2e4, extra in 0.0f32..2e4,
            d_sub in 1.0f32..5e3, rho_min in 0.001f32..1.0, a in 0u32..20_000, b in 0u32..20_000,
        ) {
            let (a, b) = (a % len, b % len);
            let (r0, r1) = (a.min(b), a.max(b));
            let w = |r, d| subset_weight_code(r, len, d, THIN, d_sub, rho_min);
            prop_assert!(w(r0, d) >= w(r1, d));
            prop_assert!(w(r0, d) >= w(r0, d + extra));
        }
    }

    #[test]
    fn off_and_near_keep_everything() {
        for mode in [SubsetMode::Off as u32, THIN] {
            assert_eq!(subset_count(100, 10.0, mode, 500.0, 0.1), 100);
            assert_eq!(subset_weight_code(99, 100, 499.0, mode, 500.0, 0.1), 255);
        }
        assert_eq!(
            subset_count(100, 1e4, SubsetMode::Off as u32, 500.0, 0.1),
            100
        );
        assert_eq!(subset_weight_code(99, 100, f32::NAN, THIN, 500.0, 0.1), 255);
    }

    #[test]
    fn density_halves_per_octave_of_area_down_to_the_floor() {
        assert_eq!(subset_density(1000.0, 500.0, 0.1), 0.25);
        assert_eq!(subset_density(4000.0, 500.0, 0.1), 0.1);
        // At twice d_sub, a quarter of the trees (+ the fade) are drawn.
        assert_eq!(subset_count(1000, 1000.0, THIN, 500.0, 0.1), 314);
        // Rank fraction 0.2 < 0.25: whole; 0.3 in the band: partial; 0.32 > 0.3125: dropped.
        assert_eq!(subset_weight_code(199, 1000, 1000.0, THIN, 500.0, 0.1), 255);
        let mid = subset_weight_code(280, 1000, 1000.0, THIN, 500.0, 0.1);
        assert!(mid > 0 && mid < 255, "{mid}");
        assert_eq!(subset_weight_code(320, 1000, 1000.0, THIN, 500.0, 0.1), 0);
    }

    #[test]
    fn compensation_preserves_the_expected_area() {
        let mode = SubsetMode::ThinScale as u32;
        for d in [600.0f32, 1000.0, 1500.0, 3000.0] {
            let rho = subset_density(d, 500.0, 0.1);
            let s = subset_scale(d, mode, 500.0, 0.1);
            assert!((rho * s * s - 1.0).abs() < 1e-5, "d {d}: ρ {rho} s {s}");
        }
        assert_eq!(subset_scale(3000.0, THIN, 500.0, 0.1), 1.0);
        assert_eq!(subset_scale(400.0, mode, 500.0, 0.1), 1.0);
    }

    #[test]
    fn fragment_weight_is_a_screen_door_of_the_weight() {
        // Over many pixels, the kept fraction is the weight within 2 %.
        let packed = subset_pack(17, 128);
        let n = 256 * 256;
        let kept = (0..n)
            .filter(|i| subset_fragment_weight(packed, 3, i % 256, i / 256) == 1.0)
            .count();
        assert!(
            (kept as f32 / n as f32 - 128.0 / 255.0).abs() < 0.02,
            "{kept}"
        );
        assert_eq!(subset_fragment_weight(subset_pack(5, 255), 3, 1, 1), 1.0);
        assert_eq!(
            subset_fragment_weight(subset_pack(5, 51), 1, 1, 1),
            51.0 * (1.0 / 255.0)
        );
        assert!(subset_pack(u32::MAX, 255) < 1 << 24);
    }
}
