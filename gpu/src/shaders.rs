//! The WGSL sources. WGSL has no include, so every stage's module is `common.wgsl` followed by the
//! stage's own file; naga reports line numbers of that concatenation.

/// Structs mirroring `forestlod-shared` and the shared scalar formulas.
pub const COMMON_WGSL: &str = include_str!("shaders/common.wgsl");
/// The `select` stage's own source (without [`COMMON_WGSL`]).
pub const SELECT_WGSL: &str = include_str!("shaders/select.wgsl");

/// The full source of a stage: [`COMMON_WGSL`] then `stage`.
pub fn with_common(stage: &str) -> String {
    format!("{COMMON_WGSL}\n{stage}")
}

/// The full `select` module source.
pub fn select_source() -> String {
    with_common(SELECT_WGSL)
}
