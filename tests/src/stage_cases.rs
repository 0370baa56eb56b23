//! Parity cases walked from the stage table (issue 36, "coverage by construction"): for every
//! stage of `forestlod_harness::stages::STAGES`, one frame at **every choice** of each mode
//! parameter the row names (`StageEntry::modes`) and one with **each numeric parameter** the row
//! names (`StageEntry::params`) at its least and at its greatest accepted value (its kind in
//! `forestlod_shared::registry::PARAMS`), each extreme at every choice of the row's first mode. A stage or a mode added to the table is then walked
//! without a test being written for it.
//!
//! `tests/tests/parity/every_stage.rs` runs every case's stages on the GPU against the reference
//! and fails when a target is not reached (the stage did not run where it should) or differs;
//! `tests/tests/coverage.rs` runs the same cases on the reference as one column of the threshold
//! table. The list is built here once, so the two cannot drift apart.
//!
//! Each case starts from one of three small bases on `tiny` ([`base`]): a **flat** frame (the
//! thesis grid, `tree_cull = all`: bake, mips, select, refine, draw and the baselines run), a
//! **cut** frame (the octree with coalescing and front-to-back order: the cut's stages run) and
//! an **occluded** frame (the flat one with occlusion culling `single`: its stages run). A
//! case changes one parameter; cases that come out equal are merged (their targets joined).

use forestlod_harness::stages::STAGES;
use forestlod_shared::registry::{ParamKind, param};
use forestlod_shared::{Coalesce, CommandOrder, Hierarchy, Params, StageId, TreeCull};

use crate::tiny_hierarchy_params;

/// What a case must reach for one stage.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    /// The stage that must run (and match) in the case.
    pub stage: StageId,
    /// The parameter (a `PARAMS` name).
    pub param: &'static str,
    /// The value as users write it (`front-to-back`, `0`, `4096`).
    pub value: String,
    /// `least`, `greatest` (numbers) or `choice` (modes).
    pub reach: &'static str,
}

/// One frame of the walk (module docs).
#[derive(Clone, Debug)]
pub struct StageCase {
    /// `<base>-<param>-<value>`.
    pub name: String,
    /// The built-in scene.
    pub scene: &'static str,
    /// The frame's parameters (valid).
    pub params: Params,
    /// Everything this case must reach.
    pub targets: Vec<Target>,
}

impl StageCase {
    /// The stages the case must check, in table order, once each.
    pub fn stages(&self) -> Vec<StageId> {
        StageId::ALL
            .into_iter()
            .filter(|s| self.targets.iter().any(|t| t.stage == *s))
            .collect()
    }
}

/// Choices with which a stage does not run at all, and why: for these the walk asserts that the
/// frame's plan **skips** the stage (the GPU check returns nothing) instead of a match.
pub const CHOICES_THAT_SKIP_THE_STAGE: &[(StageId, &str, &str, &str)] = &[
    (
        StageId::HierSelect,
        "hierarchy",
        "grid",
        "the thesis grid builds no hierarchy: `select` decides its batches",
    ),
    (
        StageId::Refine,
        "tree_cull",
        "none",
        "no per-tree refinement: every command draws its whole batch",
    ),
    (
        StageId::Pyramid,
        "occlusion",
        "off",
        "no occlusion culling: one pass, no pyramid",
    ),
    (
        StageId::Occlude,
        "occlusion",
        "off",
        "no occlusion culling: the commands are drawn as selected",
    ),
];

/// Targets the stage's generic judge (`forestlod_harness::judge`) cannot judge, each with the
/// parity test (`<module>::<fn>` of `tests/tests/parity/`) that judges it in depth, and why. The
/// walk still runs them (the GPU must run without error) and checks that the named test exists.
pub const JUDGED_ELSEWHERE: &[(StageId, &str, &str, &str, &str)] = &[(
    StageId::Bake,
    "texture_size",
    "least",
    "bake::gpu_bake_equals_the_reference_at_the_extremes",
    "at r = 1 the one texel of a view is an edge texel of every triangle: the judge's budget of \
     texels beyond ±1 (a fraction of 0.006) cannot judge 50 texels (measured: 32 beyond, max 120); \
     the bake test classifies each texel against the projected triangles at r = 1, 2, 4",
)];

/// The test that judges `t` in place of the walk ([`JUDGED_ELSEWHERE`]), if any.
pub fn judged_elsewhere(t: &Target) -> Option<&'static str> {
    JUDGED_ELSEWHERE
        .iter()
        .find(|&&(s, p, r, _, _)| s == t.stage && p == t.param && r == t.reach)
        .map(|&(_, _, _, test, _)| test)
}

/// Whether `(stage, param, choice)` is one of [`CHOICES_THAT_SKIP_THE_STAGE`], or the far level's
/// `lod_levels = 3` (issue 32) for `select` (a far level selects by the cut, the grid by its
/// depth-1 hierarchy) and `refine` (refused under a far level: far commands index cells).
pub fn skips(stage: StageId, param: &str, choice: &str) -> bool {
    let far = param == "lod_levels"
        && (choice == "3" || choice.starts_with("3 "))
        && matches!(stage, StageId::Select | StageId::Refine);
    far || CHOICES_THAT_SKIP_THE_STAGE
        .iter()
        .any(|&(s, p, c, _)| s == stage && p == param && c == choice)
}

/// Numeric parameters read under one choice of a mode only, with that choice: their extremes are
/// walked there (at the distance metric `lod_pixel_area` changes nothing, and a case equal to
/// its base would reach nothing).
pub const READ_ONLY_UNDER: &[(&str, &str, &str)] = &[
    ("lod_pixel_area", "lod_metric", "pixel-area"),
    ("lod_screen_error", "lod_metric", "screen-error"),
    ("subset_distance", "subset_mode", "thin"),
    ("subset_min", "subset_mode", "thin"),
    ("sun_azimuth", "shading", "sun-depth-plane"),
    ("sun_elevation", "shading", "sun-depth-plane"),
    ("ambient", "shading", "sun-depth-plane"),
    ("noise_size", "dither_space", "texture"),
    ("octahedral_grid", "billboard_views", "hemi-octahedral"),
    // Octahedral frames are `N×N` whatever `K` and `J` (`BillboardViews::per_mesh`): under
    // them the elevations' and azimuths' extremes bake the very layers of the views' own case
    // (measured: six such cases took 66 s of the bake walk's 320 s).
    ("angle_count", "billboard_views", "elevation"),
    ("azimuth_count", "billboard_views", "elevation"),
    ("far_start", "far_lod", "octant-sprite"),
    ("far_pixels", "far_lod", "octant-sprite"),
    ("impostor_pixels", "far_lod", "impostor"),
    ("impostor_tiles", "far_lod", "impostor"),
    ("impostor_min_distance", "far_lod", "impostor"),
    ("impostor_max_depth", "far_lod", "impostor"),
    ("impostor_update_interval", "far_lod", "impostor"),
    ("impostor_refresh_interval", "far_lod", "impostor"),
    ("impostor_refresh_number", "far_lod", "impostor"),
    ("point_grid", "lod1", "points"),
];

/// Azimuth views a case gets when it picks an azimuth rule other than the nearest at one view
/// ([`coherent`]): with one view there is nothing to blend, and the case would be its base.
pub const AZIMUTH_RULE_VIEWS: u32 = 4;

/// Makes a case's parameters coherent ([`Params::validate`]'s cross-field rule): far-field
/// subsets rank trees within a grid batch, so a case that turns them on drops the flat base's
/// per-tree refinement (`tree_cull = none`; refine is skipped there, as the plan says). A case
/// that picks the azimuth blend (issue 30) at one azimuth view gets [`AZIMUTH_RULE_VIEWS`], and
/// one that picks the octahedral frames' nearest rule (issue 32) gets octahedral views, and one
/// that picks their depth channel gets octahedral views with the blend.
pub fn coherent(p: &mut Params) {
    if p.subset_mode != forestlod_shared::SubsetMode::Off as u32 {
        p.tree_cull = TreeCull::None as u32;
    }
    if p.azimuth_mode != forestlod_shared::AzimuthMode::Nearest as u32 && p.azimuth_count == 1 {
        p.azimuth_count = AZIMUTH_RULE_VIEWS;
    }
    // The octahedral frames' rule (issue 32) is read under octahedral views only: a case that
    // picks its other choice draws hemi-octahedral impostors.
    if p.octahedral_blend != Params::default().octahedral_blend
        && !forestlod_shared::octahedral::is_octahedral(p.billboard_views)
    {
        p.billboard_views = forestlod_shared::ViewSphere::HemiOctahedral as u32;
    }
    // The depth channel (issue 32) is read under octahedral views with the blend only.
    if p.octahedral_depth != Params::default().octahedral_depth {
        if !forestlod_shared::octahedral::is_octahedral(p.billboard_views) {
            p.billboard_views = forestlod_shared::ViewSphere::HemiOctahedral as u32;
        }
        p.octahedral_blend = forestlod_shared::AzimuthMode::Blend as u32;
    }
    // The far level (issue 32) is read under `lod_levels = 3` only: a case that picks a far
    // primitive other than the default gets it, and a far case drops what the far level refuses
    // (per-tree refinement, occlusion culling, subsets) and pulls the transition in to a far
    // start below it (so `far_start = 0` is the extreme "everything far that can be").
    // Hierarchical impostors' settings (issue 33 item 2) are read under `far_lod = impostor`.
    let d = Params::default();
    if p.impostor_pixels != d.impostor_pixels
        || p.impostor_tiles != d.impostor_tiles
        || p.impostor_min_distance != d.impostor_min_distance
        || p.impostor_max_depth != d.impostor_max_depth
        || p.impostor_update_interval != d.impostor_update_interval
        || p.impostor_refresh_interval != d.impostor_refresh_interval
        || p.impostor_refresh_number != d.impostor_refresh_number
    {
        p.far_lod = forestlod_shared::FarLod::Impostor as u32;
    }
    if p.far_lod != d.far_lod {
        p.lod_levels = 3;
    }
    if p.lod_levels >= 3 {
        p.tree_cull = TreeCull::None as u32;
        p.occlusion = forestlod_shared::Occlusion::Off as u32;
        p.subset_mode = forestlod_shared::SubsetMode::Off as u32;
        if p.far_start < p.lod1_transition {
            p.lod1_transition = p.far_start;
            p.fade_width = p.fade_width.min(p.far_start);
        }
    }
    // The point LOD (issue 33): its rule, detail setting and count are read under
    // `lod1 = points` only, a case that picks any of them draws points; points replace the
    // billboard as the second level, so a point case has two levels (the far level follows
    // billboards only).
    if p.point_select != d.point_select
        || p.point_detail != d.point_detail
        || p.point_count != d.point_count
        || p.point_grid != d.point_grid
    {
        p.lod1 = forestlod_shared::points::Lod1::Points as u32;
    }
    if forestlod_shared::points::draws_points(p) || p.lod1 != d.lod1 {
        p.lod_levels = p.lod_levels.min(2);
    }
}

/// The base frame of a stage (module docs): the cut's stages on the octree cut, the rest flat.
pub fn base(stage: StageId) -> (&'static str, Params) {
    match stage {
        StageId::HierSelect | StageId::Coalesce | StageId::CommandOrder => (
            "cut",
            Params {
                coalesce: Coalesce::On as u32,
                command_order: CommandOrder::FrontToBack as u32,
                tree_cull: TreeCull::Lod0 as u32,
                ..tiny_hierarchy_params(Hierarchy::Octree)
            },
        ),
        // Occlusion culling's stages run only with it on (issue 31): `single`, so that its
        // other modes (the fade mode's occluder rule) are walked with the stages running.
        StageId::Pyramid | StageId::Occlude => (
            "occluded",
            Params {
                tree_cull: TreeCull::All as u32,
                occlusion: forestlod_shared::Occlusion::Single as u32,
                ..tiny_hierarchy_params(Hierarchy::Grid)
            },
        ),
        // The far level (issue 32) is baked under `lod_levels = 3`, over the octree.
        StageId::FarBake => (
            "far",
            Params {
                lod_levels: 3,
                ..tiny_hierarchy_params(Hierarchy::Octree)
            },
        ),
        _ => (
            "flat",
            Params {
                tree_cull: TreeCull::All as u32,
                ..tiny_hierarchy_params(Hierarchy::Grid)
            },
        ),
    }
}

/// A numeric kind's least and greatest accepted values.
pub fn extremes(kind: ParamKind) -> Option<(f64, f64)> {
    match kind {
        ParamKind::Float { min, max } => Some((f64::from(min), f64::from(max))),
        ParamKind::Uint { min, max, .. } => Some((f64::from(min), f64::from(max))),
        ParamKind::Choice(_) => None,
    }
}

/// Billboards of the greatest texture side are baked for one species at one angle
/// ([`SINGLE_SPECIES`]): `tiny`'s five species at ten angles would be 50 layers of 4096² texels
/// (several GB on the reference), and five layers of 4096² exceed lavapipe's storage-buffer
/// binding limit in the mips stage (measured: 335,544,320 bytes of level-1 texels refused).
/// Likewise the greatest azimuth count (issue 30): `tiny`'s five species at ten angles and 64
/// azimuths are 3200 layers, past the array-layer limit (`MAX_BILLBOARD_LAYERS`); one species'
/// 640 fit.
fn affordable(scene: &mut &'static str, p: &mut Params) {
    if p.texture_size >= 1024 {
        *scene = SINGLE_SPECIES;
        p.angle_count = 1;
        p.octahedral_grid = forestlod_shared::MIN_OCTAHEDRAL_GRID;
    }
    let species = forestlod_reference::scene::builtin::Species::ALL.len();
    if forestlod_shared::check_billboard_layers(species, p).is_err() {
        *scene = SINGLE_SPECIES;
    }
}

/// The scene name of `single` with its one species only (built-in scenes carry all five meshes).
pub const SINGLE_SPECIES: &str = "single-species";

/// The scene a case names: a built-in scene, or [`SINGLE_SPECIES`].
pub fn scene(name: &str) -> forestlod_reference::scene::Scene {
    use forestlod_reference::scene::builtin;
    if name == SINGLE_SPECIES {
        let mut s = builtin::single();
        let mesh = s.instances[0].mesh as usize;
        s.meshes = vec![s.meshes[mesh].clone()];
        s.instances[0].mesh = 0;
        s.name = SINGLE_SPECIES.to_string();
        return s;
    }
    builtin::by_name(name).unwrap_or_else(|e| panic!("{e}"))
}

/// Every case of the walk (module docs), merged where equal.
pub fn stage_cases() -> Vec<StageCase> {
    let mut out: Vec<StageCase> = Vec::new();
    let mut push = |name: String, scene: &'static str, mut params: Params, target: Target| {
        coherent(&mut params);
        if let Some(c) = out
            .iter_mut()
            .find(|c| c.scene == scene && c.params == params)
        {
            c.targets.push(target);
        } else {
            out.push(StageCase {
                name,
                scene,
                params,
                targets: vec![target],
            });
        }
    };
    for e in STAGES {
        let (base_name, base_params) = base(e.id);
        for &name in e.modes {
            let spec =
                param(name).unwrap_or_else(|| panic!("{}: no parameter {name}", e.id.name()));
            let ParamKind::Choice(choices) = spec.kind else {
                panic!("{}: {name} is not a choice", e.id.name());
            };
            for (choice, code) in choices() {
                let mut p = base_params;
                (spec.set)(&mut p, f64::from(code));
                push(
                    format!("{base_name}-{name}-{choice}"),
                    "tiny",
                    p,
                    Target {
                        stage: e.id,
                        param: name,
                        value: choice.to_string(),
                        reach: "choice",
                    },
                );
            }
        }
        // The extremes at every choice of the stage's first mode (a rule may differ per mode
        // exactly at an extreme: the mips' alpha test at cutoff 0 counts only in the coverage
        // mode), choices that turn the stage off left out.
        let first_mode: Vec<(&str, u32, &str)> = match e.modes.first() {
            Some(&m) => {
                let spec = param(m).expect("a mode parameter");
                let ParamKind::Choice(choices) = spec.kind else {
                    panic!("{}: {m} is not a choice", e.id.name());
                };
                choices()
                    .into_iter()
                    .filter(|(c, _)| !skips(e.id, m, c))
                    .map(|(c, code)| (m, code, c))
                    .collect()
            }
            None => vec![("", 0, "")],
        };
        for &name in e.params {
            let spec =
                param(name).unwrap_or_else(|| panic!("{}: no parameter {name}", e.id.name()));
            let (least, greatest) = extremes(spec.kind)
                .unwrap_or_else(|| panic!("{}: {name} is not numeric", e.id.name()));
            let only_under = READ_ONLY_UNDER.iter().find(|r| r.0 == name);
            for &(mode, code, choice) in &first_mode {
                // The first mode is the one the parameter is read under: its own choice only.
                if only_under.is_some_and(|&(_, m, c)| m == mode && c != choice) {
                    continue;
                }
                for (reach, v) in [("least", least), ("greatest", greatest)] {
                    let mut p = base_params;
                    if let Some(m) = param(mode) {
                        (m.set)(&mut p, f64::from(code));
                    }
                    (spec.set)(&mut p, v);
                    let mut value = spec.format(&p);
                    if !mode.is_empty() {
                        value = format!("{value} with {mode} = {choice}");
                    }
                    if let Some(&(_, m, c)) = only_under {
                        let spec = param(m).expect("a mode parameter");
                        let ParamKind::Choice(choices) = spec.kind else {
                            panic!("{m} is not a choice");
                        };
                        let (_, code) = choices()
                            .into_iter()
                            .find(|&(x, _)| x == c)
                            .unwrap_or_else(|| panic!("{m} has no choice {c}"));
                        (spec.set)(&mut p, f64::from(code));
                        if m != mode {
                            value = format!("{value} with {m} = {c}");
                        }
                    }
                    // After the mode a parameter is read under is set: what it costs depends
                    // on it (octahedral frames' layers, issue 32).
                    let mut scene = "tiny";
                    affordable(&mut scene, &mut p);
                    push(
                        format!("{base_name}-{name}-{value}"),
                        scene,
                        p,
                        Target {
                            stage: e.id,
                            param: name,
                            value,
                            reach,
                        },
                    );
                }
            }
        }
    }
    out
}
