//! The built-in scene `patchy` (issue 13): forest patches and clearings, local density 1-10x the
//! normal 36,700 trees/km² (E§4.5.1), where density-aware grouping can matter (E§7) and a fixed
//! grid puts very different tree counts into its cells.
//!
//! Deterministic: the `stress` scene's trees as candidates (the same 2 km x 2 km area, terrain,
//! species stands and 10x density jittered grid), each kept with probability `factor(x, y) / 10`
//! by a hash of its index, where `factor` is 0 in clearings and rises from 1 to 10 inside patches
//! following a two-octave value noise (cells of 320 m and 110 m). No RNG state, no thread-count
//! dependence.
//!
//! This file takes the candidates and their density factor as arguments
//! (`builtin.rs`'s `patchy()` passes `stress()` and `STRESS_DENSITY_FACTOR`), so it imports
//! nothing of `builtin.rs`, which calls it.

use super::Scene;

/// Seed of the patch map.
pub const PATCHY_SEED: u64 = 0x9a7c_4e11;
/// Noise below this is a clearing (no tree).
pub const CLEARING_BELOW: f64 = 0.38;

fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn lattice(seed: u64, i: i64, j: i64) -> f64 {
    let h = mix64(seed ^ mix64((i as u64) ^ mix64((j as u64) ^ 0x5bd1_e995)));
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in 0..1 with lattice spacing `cell` metres.
fn value_noise(seed: u64, x: f64, y: f64, cell: f64) -> f64 {
    let (fx, fy) = (x / cell, y / cell);
    let (i, j) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - i, fy - j);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(tx), s(ty));
    let (i, j) = (i as i64, j as i64);
    let a = lattice(seed, i, j) * (1.0 - sx) + lattice(seed, i + 1, j) * sx;
    let b = lattice(seed, i, j + 1) * (1.0 - sx) + lattice(seed, i + 1, j + 1) * sx;
    a * (1.0 - sy) + b * sy
}

/// Local density factor over the normal density at `(x, y)`: 0 in clearings, else 1..=10.
pub fn density_factor(x: f64, y: f64) -> f64 {
    let n = 0.65 * value_noise(PATCHY_SEED, x, y, 320.0)
        + 0.35 * value_noise(PATCHY_SEED ^ 0xff, x, y, 110.0);
    if n < CLEARING_BELOW {
        return 0.0;
    }
    let u = ((n - CLEARING_BELOW) / (1.0 - CLEARING_BELOW)).min(1.0);
    1.0 + 9.0 * u.sqrt()
}

/// `patchy` (module docs) from its candidates, the `stress` scene, whose density is
/// `candidate_density_factor` (10) times the normal density.
pub fn patchy_from(candidates: Scene, candidate_density_factor: f64) -> Scene {
    let mut scene = candidates;
    scene.name = "patchy".into();
    let keep = |i: usize, x: f32, y: f32| {
        let p = density_factor(x as f64, y as f64) / candidate_density_factor;
        let h = mix64(PATCHY_SEED ^ mix64(i as u64));
        ((h >> 11) as f64 / (1u64 << 53) as f64) < p
    };
    scene.instances = scene
        .instances
        .iter()
        .enumerate()
        .filter(|(i, t)| keep(*i, t.position[0], t.position[1]))
        .map(|(_, t)| *t)
        .collect();
    scene
}
