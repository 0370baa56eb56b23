//! Helpers shared by the rasterizer's unit tests (compiled for tests only); it depends on none
//! of the other files.

/// A deterministic stream of `f32` in `[0, 1)` (a 64-bit LCG's top 24 bits) for the random
/// triangles of the mask tests.
pub(super) fn unit_random(mut seed: u64) -> impl FnMut() -> f32 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 40) as f32 / (1u64 << 24) as f32
    }
}
