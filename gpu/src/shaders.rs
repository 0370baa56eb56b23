//! The composition of the WGSL modules. WGSL has no include, so every stage's module is its
//! generated constants, then `common.wgsl`, then the stage's own file, then the parts it appends
//! (`scan.wgsl`); naga reports line numbers of that concatenation ([`StageSource::module`]).
//!
//! Each driver declares its own module (issue 27: "each GPU driver declares its own source and
//! constants; `shaders.rs` only composes them"): a [`StageSource`] (`gpu/src/<stage>.rs`,
//! `SOURCE`) naming its `.wgsl` file and the constants its driver owns (workgroup sizes, table
//! offsets). This module owns only what every module shares: the constants of `forestlod-shared`
//! ([`shared_constants`]), [`COMMON_WGSL`], and the composition; it names no stage.
//! `crate::STAGE_SOURCES` lists every stage's declaration.
//!
//! Every WGSL `const` whose value a Rust item owns (mode ids, decision codes, LOD ids, workgroup
//! sizes, table offsets) is generated from that item, never written in a `.wgsl` file: a constant
//! kept by hand on both sides is a place for the twins to drift apart silently (issue 11). The
//! `.wgsl` files keep only constants private to a shader (its state-machine states, bit
//! patterns). The crate's tests (`gpu/src/lib.rs`) check that no file redeclares a generated
//! constant, that no name is generated with two values, and that every stage's module validates.

/// Structs mirroring `forestlod-shared` and the shared scalar formulas.
pub const COMMON_WGSL: &str = include_str!("shaders/common.wgsl");

/// One generated WGSL `u32` constant: the name of the Rust item that owns it, and its value.
pub type WgslConstant = (&'static str, u32);

/// The [`WgslConstant`]s of the listed `u32` items (a `usize` one as `NAME as u32`), each named
/// after its item, so a constant's WGSL name cannot drift from the Rust one.
macro_rules! wgsl_constants {
    ($($name:ident $(as $ty:ty)?),* $(,)?) => {
        &[$((stringify!($name), $name $(as $ty)?)),*]
    };
}
pub(crate) use wgsl_constants;

/// A file of `gpu/src/shaders/` and the generated constants that its driver owns and it reads.
#[derive(Clone, Copy, Debug)]
pub struct WgslFile {
    /// The file's name in `gpu/src/shaders/` (`select.wgsl`), the key of [`mutant_or`].
    pub name: &'static str,
    /// Its compiled-in text (`include_str!`).
    pub wgsl: &'static str,
    /// The constants it reads beyond [`shared_constants`] ([`wgsl_constants!`]).
    pub constants: &'static [WgslConstant],
}

/// A stage's WGSL module, declared by its driver: its own file, then the parts appended to it
/// (a file shared by several stages, declared by the driver that owns its constants).
#[derive(Clone, Copy, Debug)]
pub struct StageSource {
    /// The stage's own file, `gpu/src/shaders/<stage>.wgsl`.
    pub own: WgslFile,
    /// Appended after `own`, in order.
    pub parts: &'static [WgslFile],
}

impl StageSource {
    /// The module's files in order: [`Self::own`], then [`Self::parts`].
    pub fn files(&self) -> impl Iterator<Item = &WgslFile> {
        std::iter::once(&self.own).chain(self.parts)
    }

    /// Every constant the module declares: [`shared_constants`], then each file's own, in order.
    pub fn constants(&self) -> Vec<(String, u32)> {
        let own = self
            .files()
            .flat_map(|f| f.constants)
            .map(|&(n, v)| (n.to_string(), v));
        shared_constants().into_iter().chain(own).collect()
    }

    /// The full module source: [`constants_wgsl`] of [`Self::constants`], [`COMMON_WGSL`], then
    /// the files, each on a new line (each file's text through [`mutant_or`]).
    pub fn module(&self) -> String {
        let parts: Vec<String> = std::iter::once(compose(
            &self.constants(),
            &mutant_or(self.own.name, self.own.wgsl),
        ))
        .chain(self.parts.iter().map(|p| mutant_or(p.name, p.wgsl)))
        .collect();
        parts.join("\n")
    }
}

/// The `(name, value)` of every constant that every module declares: the ones `forestlod-shared`
/// owns (the stages' own come with their [`StageSource`]).
pub fn shared_constants() -> Vec<(String, u32)> {
    use forestlod_shared as s;
    let mut out: Vec<(String, u32)> = [
        ("COMMAND_SHIFT", s::COMMAND_SHIFT),
        ("LOD_MESH", s::LOD_MESH),
        ("LOD_BILLBOARD", s::LOD_BILLBOARD),
        ("DECISION_CULLED_DISTANCE", s::DECISION_CULLED_DISTANCE),
        ("DECISION_CULLED_FRUSTUM", s::DECISION_CULLED_FRUSTUM),
        ("DECISION_DRAW", s::DECISION_DRAW),
        ("DECISION_KIND_MASK", s::DECISION_KIND_MASK),
        ("DECISION_LOD0", s::DECISION_LOD0),
        ("DECISION_LOD1", s::DECISION_LOD1),
        ("LOD_ID_MESH", s::LOD_ID_MESH),
        ("LOD_ID_BILLBOARD", s::LOD_ID_BILLBOARD),
        ("LOD_ID_TRANSITION", s::LOD_ID_TRANSITION),
        ("LOD_ID_TERRAIN", s::LOD_ID_TERRAIN),
        ("NO_PARENT", s::NO_PARENT),
        ("NODE_RECURSE", s::NODE_RECURSE),
        ("NODE_VISITED", s::NODE_VISITED),
        ("NODE_EMITTED", s::NODE_EMITTED),
        ("MAX_HIERARCHY_DEPTH", s::MAX_HIERARCHY_DEPTH),
        ("SUBSET_WEIGHT_STEPS", s::SUBSET_WEIGHT_STEPS),
        // An f32 constant as its bits (`bitcast<f32>` in common.wgsl): the same value, exactly.
        ("SUBSET_FADE_BITS", s::SUBSET_FADE.to_bits()),
        ("MIN_CROWN_RADIUS_BITS", s::MIN_CROWN_RADIUS.to_bits()),
        ("AZIMUTH_WEIGHT_STEPS", s::AZIMUTH_WEIGHT_STEPS),
        ("AZIMUTH_LAYER_BITS", s::AZIMUTH_LAYER_BITS),
        ("AZIMUTH_TURN_BITS", s::AZIMUTH_TURN.to_bits()),
        (
            "AZIMUTH_WEIGHT_SCALE_BITS",
            s::AZIMUTH_WEIGHT_SCALE.to_bits(),
        ),
        // Occlusion culling (issue 31, shared/src/occlusion.rs).
        ("MAX_PYRAMID_LEVELS", s::MAX_PYRAMID_LEVELS),
        ("OCCLUSION_SLACK_PX_BITS", s::OCCLUSION_SLACK_PX.to_bits()),
        ("OCCLUSION_SLACK_REL_BITS", s::OCCLUSION_SLACK_REL.to_bits()),
        ("OCCLUSION_Z_SLACK_BITS", s::OCCLUSION_Z_SLACK.to_bits()),
        // Octahedral impostors (issue 32, shared/src/octahedral.rs).
        ("OCTAHEDRAL_STEPS", s::OCTAHEDRAL_STEPS),
        ("OCTAHEDRAL_LAYER_BITS", s::OCTAHEDRAL_LAYER_BITS),
        ("MIN_OCTAHEDRAL_GRID", s::MIN_OCTAHEDRAL_GRID),
        // The far level (issue 32, shared/src/far.rs).
        ("LOD_FAR", s::LOD_FAR),
        ("NODE_FAR", s::NODE_FAR),
        ("LOD_ID_FAR", s::LOD_ID_FAR),
        ("CUBE_VERTICES", s::CUBE_VERTICES),
        ("SPRITE_VERTICES", s::SPRITE_VERTICES),
        // The point LOD (issue 33, shared/src/points.rs).
        ("POINT_NO_PARENT", s::points::NO_PARENT),
    ]
    .into_iter()
    .map(|(n, v)| (n.to_string(), v))
    .collect();
    // Mode ids: `<PREFIX>_<NAME>` from the mode's user-facing name (`dither-sequential` ->
    // `FADE_DITHER_SEQUENTIAL`), so a new mode reaches the shaders with its declaration.
    let modes = [
        ("FADE", s::FadeMode::choices()),
        ("MIP", s::MipMode::choices()),
        ("ANGLE_INDEX", s::AngleIndexMode::choices()),
        ("TREE_CULL", s::TreeCull::choices()),
        ("HIERARCHY", s::Hierarchy::choices()),
        ("COALESCE", s::Coalesce::choices()),
        ("COMMAND_ORDER", s::CommandOrder::choices()),
        ("LOD_METRIC", s::LodMetric::choices()),
        ("SUBSET_MODE", s::SubsetMode::choices()),
        ("SHADING", s::Shading::choices()),
        ("DITHER_SPACE", s::DitherSpace::choices()),
        ("FADE_GRANULARITY", s::FadeGranularity::choices()),
        ("AZIMUTH_MODE", s::AzimuthMode::choices()),
        ("OCCLUSION", s::Occlusion::choices()),
        ("VIEW_SPHERE", s::ViewSphere::choices()),
        ("FAR_LOD", s::FarLod::choices()),
        ("LOD1", s::points::Lod1::choices()),
        ("POINT_SELECT", s::points::PointSelect::choices()),
    ];
    for (prefix, choices) in modes {
        for (name, id) in choices {
            let name = name.to_uppercase().replace('-', "_");
            out.push((format!("{prefix}_{name}"), id));
        }
    }
    out
}

/// `constants` as WGSL, one `const NAME: u32 = Vu;` line each.
pub fn constants_wgsl(constants: &[(String, u32)]) -> String {
    let mut out = String::from(
        "// Generated by gpu/src/shaders.rs from the Rust items that own these values.\n",
    );
    for (name, value) in constants {
        out.push_str(&format!("const {name}: u32 = {value}u;\n"));
    }
    out
}

/// [`constants_wgsl`] of `constants`, [`COMMON_WGSL`], then `stage`.
fn compose(constants: &[(String, u32)], stage: &str) -> String {
    let common = mutant_or("common.wgsl", COMMON_WGSL);
    format!("{}{common}\n{stage}", constants_wgsl(constants))
}

/// `stage` after [`shared_constants`] and [`COMMON_WGSL`]: a module of `common.wgsl` alone (with
/// `""`), or with a test's own declarations.
pub fn with_common(stage: &str) -> String {
    compose(&shared_constants(), stage)
}

/// The mutation-testing hook (`forestlod-experiments`' `mutate`, issue 15): when the environment
/// variable `FORESTLOD_MUTANT_WGSL` is `<file>=<path>` (e.g. `select.wgsl=/tmp/m17.wgsl`), the
/// module source of `<file>` is read from `<path>` instead of the compiled-in text, so a WGSL
/// mutant costs a test run, not a rebuild. Unset (always, outside `mutate`), the compiled-in text.
pub fn mutant_or(file: &str, own: &str) -> String {
    if let Ok(v) = std::env::var("FORESTLOD_MUTANT_WGSL")
        && let Some(path) = mutant_path(&v, file)
    {
        return std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("FORESTLOD_MUTANT_WGSL: {path}: {e}"));
    }
    own.to_string()
}

/// The path [`mutant_or`]'s hook reads `file` from, given the variable's value `var`: the text
/// after the first `=` when the text before it is `file` exactly; `None` for another file or a
/// value without `=`.
fn mutant_path<'a>(var: &'a str, file: &str) -> Option<&'a str> {
    var.split_once('=')
        .and_then(|(f, path)| (f == file).then_some(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mutation hook's parsing (`mutant_path`): `<file>=<path>` gives `file` its path (the
    /// text after the first `=`, which may itself hold `=`), every other file none, and a value
    /// without `=`, an empty one or a file name that only starts or ends like `file` none. Added
    /// for issue 36's Rust mutant 514 (`f == file` -> `!=`: every other module read the mutant,
    /// the mutated one its own text; with the variable unset nothing else sees it).
    #[test]
    fn the_mutation_hook_gives_the_named_file_its_path_and_no_other() {
        let var = "select.wgsl=/tmp/m17.wgsl";
        assert_eq!(
            mutant_path(var, "select.wgsl"),
            Some("/tmp/m17.wgsl"),
            "the named file"
        );
        for other in [
            "common.wgsl",
            "draw.wgsl",
            "select",
            "elect.wgsl",
            "select.wgsl2",
            "",
        ] {
            assert_eq!(mutant_path(var, other), None, "file `{other}`");
        }
        assert_eq!(
            mutant_path("draw.wgsl=/tmp/a=b.wgsl", "draw.wgsl"),
            Some("/tmp/a=b.wgsl")
        );
        for malformed in ["select.wgsl", "", "/tmp/m17.wgsl"] {
            assert_eq!(
                mutant_path(malformed, "select.wgsl"),
                None,
                "value `{malformed}`"
            );
        }
    }

    /// The shared values are the Rust ones (a spot check of each source of values).
    #[test]
    fn shared_values_are_the_rust_items() {
        let src = constants_wgsl(&shared_constants());
        for line in [
            "const DECISION_LOD1: u32 = 8u;",
            "const FADE_DITHER_SEQUENTIAL: u32 = 3u;",
            "const MIP_COVERAGE: u32 = 2u;",
            "const ANGLE_INDEX_EQ31_CLAMPED: u32 = 1u;",
            "const TREE_CULL_ALL: u32 = 2u;",
            "const HIERARCHY_OCTREE_EUCLIDEAN: u32 = 4u;",
            "const NO_PARENT: u32 = 4294967295u;",
            "const LOD_ID_TERRAIN: u32 = 4u;",
        ] {
            assert!(src.contains(line), "shared constants lack `{line}`:\n{src}");
        }
    }

    /// A stage's constants are named after their items and follow the shared ones; its module is
    /// the constants, `common.wgsl`, its own file and its parts, in that order.
    #[test]
    fn a_stage_module_is_its_constants_common_and_files_in_order() {
        const ONE: u32 = 7;
        const PART: WgslFile = WgslFile {
            name: "part.wgsl",
            wgsl: "// the part",
            constants: &[("PART_CONST", 9)],
        };
        const STAGE: StageSource = StageSource {
            own: WgslFile {
                name: "stage.wgsl",
                wgsl: "// the stage",
                constants: wgsl_constants![ONE],
            },
            parts: &[PART],
        };
        let constants = STAGE.constants();
        let shared = shared_constants();
        assert_eq!(constants[..shared.len()], shared[..]);
        assert_eq!(
            constants[shared.len()..],
            [("ONE".to_string(), 7), ("PART_CONST".to_string(), 9)]
        );
        let module = STAGE.module();
        let at = |s: &str| module.find(s).unwrap_or_else(|| panic!("{s} missing"));
        assert!(at("const ONE: u32 = 7u;") < at("struct Camera"));
        assert!(at("struct Camera") < at("// the stage"));
        assert!(at("// the stage") < at("// the part"));
        assert!(module.starts_with(&constants_wgsl(&constants)));
    }
}
