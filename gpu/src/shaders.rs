//! The WGSL sources. WGSL has no include, so every stage's module is `common.wgsl` followed by the
//! stage's own file; naga reports line numbers of that concatenation.

/// Structs mirroring `forestlod-shared` and the shared scalar formulas.
pub const COMMON_WGSL: &str = include_str!("shaders/common.wgsl");
/// The `select` stage's own source (without [`COMMON_WGSL`]).
pub const SELECT_WGSL: &str = include_str!("shaders/select.wgsl");
/// The `draw` stage's own source (without [`COMMON_WGSL`]).
pub const DRAW_WGSL: &str = include_str!("shaders/draw.wgsl");

/// The full source of a stage: [`COMMON_WGSL`] then `stage`.
pub fn with_common(stage: &str) -> String {
    format!("{COMMON_WGSL}\n{stage}")
}

/// The full `select` module source.
pub fn select_source() -> String {
    with_common(SELECT_WGSL)
}

/// The `mips` stage's own source (without [`COMMON_WGSL`]).
pub const MIPS_WGSL: &str = include_str!("shaders/mips.wgsl");

/// The full `mips` module source.
pub fn mips_source() -> String {
    with_common(MIPS_WGSL)
}

/// The `bake` stage's own source (without [`COMMON_WGSL`]).
pub const BAKE_WGSL: &str = include_str!("shaders/bake.wgsl");

/// The full `bake` module source.
pub fn bake_source() -> String {
    with_common(BAKE_WGSL)
}

/// The full `draw` module source.
pub fn draw_source() -> String {
    with_common(DRAW_WGSL)
}

/// The `cull` stage's own source (without [`COMMON_WGSL`]): the baselines' per-tree culling.
pub const CULL_WGSL: &str = include_str!("shaders/cull.wgsl");

/// The full `cull` module source.
pub fn cull_source() -> String {
    with_common(CULL_WGSL)
}

/// The `primitive` stage's own source (without [`COMMON_WGSL`]): the Primitive baseline's quads.
pub const PRIMITIVE_WGSL: &str = include_str!("shaders/primitive.wgsl");

/// The full `primitive` module source.
pub fn primitive_source() -> String {
    with_common(PRIMITIVE_WGSL)
}

/// The `refine` stage's own source (without [`COMMON_WGSL`]): per-tree refinement of the
/// selected commands (beyond the thesis).
pub const REFINE_WGSL: &str = include_str!("shaders/refine.wgsl");

/// The full `refine` module source.
pub fn refine_source() -> String {
    with_common(REFINE_WGSL)
}

/// The depth read-back by compute (`DrawTarget::read`), standalone: [`COMMON_WGSL`] is not
/// prepended.
pub const DEPTH_COPY_WGSL: &str = include_str!("shaders/depth_copy.wgsl");
