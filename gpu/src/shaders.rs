//! The WGSL sources. WGSL has no include, so every stage's module is `common.wgsl` followed by the
//! stage's own file; naga reports line numbers of that concatenation.

/// Structs mirroring `forestlod-shared` and the shared scalar formulas.
pub const COMMON_WGSL: &str = include_str!("shaders/common.wgsl");

/// The full source of a stage: [`COMMON_WGSL`] then `stage`.
pub fn with_common(stage: &str) -> String {
    format!("{COMMON_WGSL}\n{stage}")
}

/// A stage's own source `shaders/<file>` (const `$own`, documented by the given doc) and its full
/// module source (fn `$full`: [`with_common`] of it).
macro_rules! stage_source {
    ($(#[$doc:meta])* $own:ident, $full:ident, $file:literal) => {
        $(#[$doc])*
        pub const $own: &str = include_str!(concat!("shaders/", $file));

        #[doc = concat!("The full `", $file, "` module source: [`COMMON_WGSL`] then [`", stringify!($own), "`].")]
        pub fn $full() -> String {
            with_common($own)
        }
    };
}

stage_source!(
    /// The `select` stage's own source (without [`COMMON_WGSL`]).
    SELECT_WGSL, select_source, "select.wgsl"
);
stage_source!(
    /// The `draw` stage's own source (without [`COMMON_WGSL`]).
    DRAW_WGSL, draw_source, "draw.wgsl"
);
stage_source!(
    /// The `mips` stage's own source (without [`COMMON_WGSL`]).
    MIPS_WGSL, mips_source, "mips.wgsl"
);
stage_source!(
    /// The `bake` stage's own source (without [`COMMON_WGSL`]).
    BAKE_WGSL, bake_source, "bake.wgsl"
);
stage_source!(
    /// The `cull` stage's own source (without [`COMMON_WGSL`]): the baselines' per-tree culling.
    CULL_WGSL, cull_source, "cull.wgsl"
);
stage_source!(
    /// The `primitive` stage's own source (without [`COMMON_WGSL`]): the Primitive baseline's quads.
    PRIMITIVE_WGSL, primitive_source, "primitive.wgsl"
);
stage_source!(
    /// The `refine` stage's own source (without [`COMMON_WGSL`]): per-tree refinement of the
    /// selected commands (beyond the thesis).
    REFINE_WGSL, refine_source, "refine.wgsl"
);

/// The depth read-back by compute (`DrawTarget::read`), standalone: [`COMMON_WGSL`] is not
/// prepended.
pub const DEPTH_COPY_WGSL: &str = include_str!("shaders/depth_copy.wgsl");
