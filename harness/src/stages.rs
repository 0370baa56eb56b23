//! The stage table (issue 27): every stage of [`StageId`] as data, with where its reference twin,
//! its GPU driver and WGSL twin, its harness backend and its parity case live. vello registers
//! every stage in one list and states a missing CPU twin as data (`CpuShaderType`); this is the
//! same idea for our two twins. `tests/tests/stage_table.rs` walks it: every [`StageId`] has an
//! entry, every file named exists, and every stage has a parity case that names it.
//!
//! Every stage has a generic harness backend (`backend`: the [`crate::stage::Stage`] type whose
//! `Backend<S>` the reference and the GPU implement); the table's test fails on a row without
//! one. `tests/tests/parity/every_stage.rs` runs every row through
//! [`crate::gpu_stages::FrameStages::check`] (one arm per [`StageId`]), and its parity file still
//! judges it in depth.

use forestlod_shared::StageId;

/// One stage's row (module docs). Paths are relative to the workspace root.
#[derive(Clone, Copy, Debug)]
pub struct StageEntry {
    /// The stage.
    pub id: StageId,
    /// Seed sections it implements.
    pub seed: &'static str,
    /// The CPU twin's module file.
    pub reference: &'static str,
    /// The GPU driver's file.
    pub driver: &'static str,
    /// The WGSL twin's file.
    pub wgsl: &'static str,
    /// The harness backend family member that runs it on any backend (`Backend<S>` for
    /// the type named), when it has one.
    pub backend: Option<&'static str>,
    /// The test file that judges the GPU twin against the reference.
    pub parity: &'static str,
    /// The choice parameters (`forestlod_shared::registry::PARAMS` names) that select this
    /// stage's rule: `parity::every_stage` runs the stage on the GPU at **every** choice of each
    /// (issue 36: a mode kept on the reference only is a mode whose rule could change on one side
    /// unseen).
    pub modes: &'static [&'static str],
    /// The numeric parameters this stage's rule reads: `parity::every_stage` runs the stage on
    /// the GPU with each at its least and at its greatest accepted value (its registry kind).
    pub params: &'static [&'static str],
}

/// The numeric parameters of the view-depth selection rule, read by every selection stage
/// (`forestlod_shared::ViewUniform`: draw distance, fade band, LOD levels).
const VIEW_PARAMS: [&str; 4] = [
    "lod_levels",
    "lod1_transition",
    "fade_width",
    "draw_distance",
];

/// The numeric parameters of the scaled LOD metrics (issue 29, `forestlod_shared::LodMetric`),
/// read by every stage that decides or draws on a band: each is read under its own metric only
/// (`forestlod_tests::stage_cases` walks its extremes there).
const METRIC_PARAMS: [&str; 2] = ["lod_pixel_area", "lod_screen_error"];

/// The numeric parameters of the far-field subsets (issue 29, `forestlod_shared::subset`), read
/// by `select` (the count) and `draw` (each tree's weight) under a subset mode only.
const SUBSET_PARAMS: [&str; 2] = ["subset_distance", "subset_min"];
/// The sun-depth shading's parameters (issue 30, G§5): read by the draw under a sun-depth mode.
const LIGHT_PARAMS: [&str; 3] = ["sun_azimuth", "sun_elevation", "ambient"];

/// Every stage, in [`StageId::ALL`] order.
pub const STAGES: &[StageEntry] = &[
    StageEntry {
        id: StageId::Bake,
        seed: "E Alg. 3.1, §4.1",
        reference: "reference/src/bake.rs",
        driver: "gpu/src/bake.rs",
        wgsl: "gpu/src/shaders/bake.wgsl",
        backend: Some("stage::Bake"),
        parity: "tests/tests/parity/bake.rs",
        modes: &["billboard_views", "octahedral_depth"],
        params: &[
            "texture_size",
            "angle_count",
            "azimuth_count",
            "octahedral_grid",
        ],
    },
    StageEntry {
        id: StageId::Mips,
        seed: "E Alg. 3.2, §3.3.2, §4.1",
        reference: "reference/src/mips.rs",
        driver: "gpu/src/mips.rs",
        wgsl: "gpu/src/shaders/mips.wgsl",
        backend: Some("stage::Mips"),
        parity: "tests/tests/parity/mips.rs",
        modes: &["mip_mode"],
        params: &["texture_size", "alpha_cutoff"],
    },
    StageEntry {
        id: StageId::FarBake,
        seed: "G§2.2-2.4",
        reference: "reference/src/far_bake.rs",
        driver: "gpu/src/far_bake.rs",
        wgsl: "gpu/src/shaders/far_bake.wgsl",
        backend: Some("stage::FarBake"),
        parity: "tests/tests/parity/far_bake.rs",
        modes: &["parent_rule"],
        params: &["cluster_size", "alpha_cutoff"],
    },
    StageEntry {
        id: StageId::Select,
        seed: "E§3.5, §4.3",
        reference: "reference/src/select.rs",
        driver: "gpu/src/select.rs",
        wgsl: "gpu/src/shaders/select.wgsl",
        backend: Some("stage::Select"),
        parity: "tests/tests/parity/select.rs",
        modes: &["lod_metric", "subset_mode"],
        params: &[
            "grid_size",
            VIEW_PARAMS[0],
            VIEW_PARAMS[1],
            VIEW_PARAMS[2],
            VIEW_PARAMS[3],
            METRIC_PARAMS[0],
            METRIC_PARAMS[1],
            SUBSET_PARAMS[0],
            SUBSET_PARAMS[1],
        ],
    },
    StageEntry {
        id: StageId::HierSelect,
        seed: "G§3 Fig. 4, C§4.5",
        reference: "reference/src/hier_select.rs",
        driver: "gpu/src/hier_select.rs",
        wgsl: "gpu/src/shaders/hier_select.wgsl",
        backend: Some("stage::HierSelect"),
        parity: "tests/tests/parity/hier_select.rs",
        modes: &["hierarchy", "lod_metric", "far_lod"],
        params: &[
            "far_start",
            "far_pixels",
            "nodes_per_node",
            "max_cull_depth",
            "grid_size",
            VIEW_PARAMS[0],
            VIEW_PARAMS[1],
            VIEW_PARAMS[2],
            VIEW_PARAMS[3],
            METRIC_PARAMS[0],
            METRIC_PARAMS[1],
        ],
    },
    StageEntry {
        id: StageId::Coalesce,
        seed: "G§3 (contiguous octant ranges)",
        reference: "reference/src/coalesce.rs",
        driver: "gpu/src/coalesce.rs",
        wgsl: "gpu/src/shaders/coalesce.wgsl",
        backend: Some("stage::Coalesce"),
        parity: "tests/tests/parity/hier_select.rs",
        modes: &["coalesce"],
        params: &[],
    },
    StageEntry {
        id: StageId::CommandOrder,
        seed: "E§7 (distance-sorted commands)",
        reference: "reference/src/command_order.rs",
        driver: "gpu/src/command_order.rs",
        wgsl: "gpu/src/shaders/command_order.wgsl",
        backend: Some("stage::CommandOrder"),
        parity: "tests/tests/parity/hier_select.rs",
        modes: &["command_order"],
        params: &[],
    },
    StageEntry {
        id: StageId::Refine,
        seed: "E§3.5, §7 (beyond the thesis)",
        reference: "reference/src/refine.rs",
        driver: "gpu/src/refine.rs",
        wgsl: "gpu/src/shaders/refine.wgsl",
        backend: Some("stage::Refine"),
        parity: "tests/tests/parity/refine.rs",
        modes: &["tree_cull", "lod_metric"],
        params: &[
            VIEW_PARAMS[0],
            VIEW_PARAMS[1],
            VIEW_PARAMS[2],
            VIEW_PARAMS[3],
            METRIC_PARAMS[0],
            METRIC_PARAMS[1],
        ],
    },
    StageEntry {
        id: StageId::Pyramid,
        seed: "beyond the seeds (issue 31; E§7 future work: finer culling)",
        reference: "reference/src/pyramid.rs",
        driver: "gpu/src/pyramid.rs",
        wgsl: "gpu/src/shaders/pyramid.wgsl",
        backend: Some("stage::Pyramid"),
        parity: "tests/tests/parity/occlusion.rs",
        modes: &["occlusion"],
        params: &[],
    },
    StageEntry {
        id: StageId::Occlude,
        seed: "beyond the seeds (issue 31; E§7 future work: finer culling)",
        reference: "reference/src/occlude.rs",
        driver: "gpu/src/occlude.rs",
        wgsl: "gpu/src/shaders/occlude.wgsl",
        backend: Some("stage::Occlude"),
        parity: "tests/tests/parity/occlusion.rs",
        modes: &["occlusion", "fade_mode", "occlusion_order"],
        params: &["occluder_depth"],
    },
    StageEntry {
        id: StageId::Draw,
        seed: "E§3.3.1, §4.4, G§4",
        reference: "reference/src/draw.rs",
        driver: "gpu/src/draw.rs",
        wgsl: "gpu/src/shaders/draw.wgsl",
        backend: Some("stage::Draw"),
        parity: "tests/tests/parity/draw.rs",
        modes: &[
            "fade_mode",
            "angle_index_mode",
            "lod_metric",
            "subset_mode",
            "shading",
            "dither_space",
            "fade_granularity",
            "azimuth_mode",
            "billboard_views",
            "octahedral_blend",
            "octahedral_depth",
            "far_lod",
            "lod1",
            "point_select",
            "point_detail",
        ],
        params: &[
            "alpha_cutoff",
            "angle_count",
            "texture_size",
            LIGHT_PARAMS[0],
            LIGHT_PARAMS[1],
            LIGHT_PARAMS[2],
            "azimuth_count",
            VIEW_PARAMS[0],
            VIEW_PARAMS[1],
            VIEW_PARAMS[2],
            VIEW_PARAMS[3],
            METRIC_PARAMS[0],
            METRIC_PARAMS[1],
            SUBSET_PARAMS[0],
            SUBSET_PARAMS[1],
            "noise_size",
            "octahedral_grid",
            "point_count",
            // Hierarchical impostors (issue 33 item 2): the atlas the draw samples and the plan
            // (`reference/src/impostor_cache.rs`, CPU-side as in C§4.6.3) that fills it.
            "impostor_pixels",
            "impostor_tiles",
            "impostor_min_distance",
            "impostor_max_depth",
            "impostor_update_interval",
            "impostor_refresh_interval",
            "impostor_refresh_number",
            "point_grid",
        ],
    },
    StageEntry {
        id: StageId::Cull,
        seed: "E§5 (Vegetation, Primitive)",
        reference: "reference/src/baselines.rs",
        driver: "gpu/src/cull.rs",
        wgsl: "gpu/src/shaders/cull.wgsl",
        backend: Some("stage::Cull"),
        parity: "tests/tests/parity/baselines.rs",
        modes: &[],
        params: &VIEW_PARAMS,
    },
    StageEntry {
        id: StageId::Primitive,
        seed: "E§5 (Primitive)",
        reference: "reference/src/baselines.rs",
        driver: "gpu/src/primitive.rs",
        wgsl: "gpu/src/shaders/primitive.wgsl",
        backend: Some("stage::Primitive"),
        parity: "tests/tests/parity/baselines.rs",
        modes: &[],
        params: &[],
    },
];

/// The row of `id`.
pub fn entry(id: StageId) -> &'static StageEntry {
    STAGES
        .iter()
        .find(|e| e.id == id)
        .expect("every stage has a row (tests/tests/stage_table.rs)")
}
