//! The parameter table: one entry per [`Params`] field a user can set, from which the command-line
//! flags (`experiments/src/options.rs`), the TOML sweep axes and settings
//! (`experiments/src/sweep/spec.rs`), the metrics JSON of the main job and the validation messages all
//! come. Adding a parameter is one entry here (plus the field, its `validate` rule and the code
//! that reads it); no match on parameter names exists anywhere else.
//!
//! Each entry has a canonical `name` (the `Params` field, a TOML key), the `flag` the CLI spells
//! it with (`--{flag}`; its underscore form is also a TOML key and the metrics key), aliases, a
//! kind (a float, an unsigned integer or a named choice) and a getter and setter through `f64`
//! (exact for every `f32` and `u32`). Choices are stored in `Params` as their `u32` codes; their
//! names come from the enums' own `name()` (one spelling per mode, in one place), and so do the
//! names in a choice's refusal reason and `--help` line (generated: adding a mode is no edit here).
//!
//! Rejected design: a `match name` per consumer (CLI struct fields, a TOML `set_param`, metrics
//! keys), as before issue 11: a parameter added to one was silently missing from the others.

use std::borrow::Cow;

use crate::azimuth::MAX_AZIMUTH_COUNT;
use crate::cut::MAX_HIERARCHY_DEPTH;
use crate::far::MAX_CLUSTER_SIZE;
use crate::impostor::{MAX_IMPOSTOR_PIXELS, MIN_IMPOSTOR_PIXELS};
use crate::octahedral::{MAX_OCTAHEDRAL_GRID, MIN_OCTAHEDRAL_GRID};
use crate::params::{MAX_ANGLE_COUNT, MAX_DISTANCE, MAX_TEXTURE_SIZE, MIN_GRID_SIZE, ParamError};
use crate::points::{DetailPreset, Lod1, MAX_POINT_GRID, MAX_POINTS_PER_MESH, PointSelect};
use crate::{
    AngleIndexMode, AzimuthMode, Coalesce, CommandOrder, DitherSpace, FadeGranularity, FadeMode,
    FarLod, Hierarchy, LodMetric, MipMode, Occlusion, OcclusionOrder, OctahedralDepth, Params,
    ParentRule, Shading, SubsetMode, TreeCull, ViewSphere,
};

/// What values a parameter takes, and so what [`Params::validate`] accepts.
#[derive(Clone, Copy, Debug)]
pub enum ParamKind {
    /// An `f32`, finite, in `min..=max`.
    Float {
        /// Smallest valid value.
        min: f32,
        /// Largest valid value.
        max: f32,
    },
    /// A `u32` in `min..=max`, and a power of two where `power_of_two`.
    Uint {
        /// Smallest valid value.
        min: u32,
        /// Largest valid value.
        max: u32,
        /// Whether only powers of two are valid.
        power_of_two: bool,
    },
    /// One of named modes, stored as its `u32` code: `(name, code)` pairs.
    Choice(fn() -> Vec<(&'static str, u32)>),
}

/// The `--help` line of a parameter ([`ParamSpec::help`] renders it).
#[derive(Clone, Copy, Debug)]
pub enum Help {
    /// The whole line, written out (numbers).
    Text(&'static str),
    /// `before`, then the choice names in code order joined by `, ` (each followed by
    /// ` (cite)` where `cite` of its code gives one: the enum's `cite()`), then `after`.
    Choices {
        /// Text before the names.
        before: &'static str,
        /// The source cited beside a choice, by code.
        cite: fn(u32) -> Option<&'static str>,
        /// Text after the names.
        after: &'static str,
    },
}

/// One user-settable parameter (module docs).
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    /// Canonical name: the [`Params`] field, a TOML key, a sweep CSV column.
    pub name: &'static str,
    /// Command-line flag without the dashes; with `-` read as `_`, also a TOML key and the key of
    /// the main job's metrics.
    pub flag: &'static str,
    /// Further keys accepted for it (TOML, and CSV columns written before a rename).
    pub aliases: &'static [&'static str],
    /// One-line help (the CLI's `--help`): [`ParamSpec::help`].
    pub help: Help,
    /// Values it takes.
    pub kind: ParamKind,
    /// Why a number outside `kind` is refused; `None` for a choice, whose reason is generated
    /// from its codes and names. The `reason` of [`ParamError`] is [`ParamSpec::reason`].
    pub reason: Option<&'static str>,
    /// Reads it from `Params` (choices: their code).
    pub get: fn(&Params) -> f64,
    /// Writes it into `Params` (exact for the kind's values).
    pub set: fn(&mut Params, f64),
}

/// Why a value could not be parsed for a parameter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// What a valid value looks like.
    pub expected: String,
}

impl ParamSpec {
    /// The flag's underscore form (`angle_index` for `--angle-index`): a TOML key, the metrics key.
    pub fn key(&self) -> String {
        self.flag.replace('-', "_")
    }

    /// Whether `key` names this parameter (canonical name, flag in either form, or an alias).
    pub fn answers_to(&self, key: &str) -> bool {
        key == self.name || key == self.flag || key == self.key() || self.aliases.contains(&key)
    }

    /// The choices' `(name, code)`, in code order (empty for numbers).
    fn choices(&self) -> Vec<(&'static str, u32)> {
        match self.kind {
            ParamKind::Choice(choices) => choices(),
            _ => Vec::new(),
        }
    }

    /// The choice names, in order (empty for numbers).
    pub fn choice_names(&self) -> Vec<&'static str> {
        self.choices().into_iter().map(|(n, _)| n).collect()
    }

    /// Why a value outside `kind` is refused. For a choice: `expected 0 (a), 1 (b) or 2 (c)`,
    /// every code with its name, from the choice list.
    pub fn reason(&self) -> Cow<'static, str> {
        match self.reason {
            Some(reason) => Cow::Borrowed(reason),
            None => {
                let mut codes: Vec<String> = self
                    .choices()
                    .into_iter()
                    .map(|(name, code)| format!("{code} ({name})"))
                    .collect();
                let last = codes.pop().unwrap_or_default();
                if codes.is_empty() {
                    Cow::Owned(format!("expected {last}"))
                } else {
                    Cow::Owned(format!("expected {} or {last}", codes.join(", ")))
                }
            }
        }
    }

    /// The one-line help ([`Help`]): for a choice, its names (and their citations) come from the
    /// choice list.
    pub fn help(&self) -> Cow<'static, str> {
        match self.help {
            Help::Text(text) => Cow::Borrowed(text),
            Help::Choices {
                before,
                cite,
                after,
            } => {
                let names: Vec<String> = self
                    .choices()
                    .into_iter()
                    .map(|(name, code)| match cite(code) {
                        Some(cite) => format!("{name} ({cite})"),
                        None => name.to_string(),
                    })
                    .collect();
                Cow::Owned(format!("{before}{}{after}", names.join(", ")))
            }
        }
    }

    /// What a valid value looks like, for parse error messages.
    pub fn expected(&self) -> String {
        match self.kind {
            ParamKind::Float { .. } => "expected a number".into(),
            ParamKind::Uint { .. } => "expected a non-negative integer".into(),
            ParamKind::Choice(_) => format!("expected one of {}", self.choice_names().join(", ")),
        }
    }

    /// Parses the text of a value (a flag's argument, a TOML string, a CSV cell): a number for
    /// numeric kinds (`nan` and `inf` parse; [`ParamSpec::check`] rejects them, naming the field),
    /// a name for choices. Returns what [`ParamSpec::set`] takes.
    pub fn parse(&self, text: &str) -> Result<f64, ParseError> {
        let text = text.trim();
        let bad = || ParseError {
            expected: self.expected(),
        };
        match self.kind {
            ParamKind::Float { .. } => text.parse::<f32>().map(f64::from).map_err(|_| bad()),
            ParamKind::Uint { .. } => text.parse::<u32>().map(f64::from).map_err(|_| bad()),
            ParamKind::Choice(choices) => choices()
                .into_iter()
                .find(|(name, _)| *name == text)
                .map(|(_, code)| f64::from(code))
                .ok_or_else(bad),
        }
    }

    /// Converts a number given as such (a TOML integer or float) to what [`ParamSpec::set`]
    /// takes: integers must be whole and in `u32` range; choices take names, not numbers.
    pub fn from_number(&self, value: f64) -> Result<f64, ParseError> {
        let bad = || ParseError {
            expected: self.expected(),
        };
        match self.kind {
            ParamKind::Float { .. } => Ok(f64::from(value as f32)),
            ParamKind::Uint { .. }
                if value.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&value) =>
            {
                Ok(value)
            }
            _ => Err(bad()),
        }
    }

    /// The value in `p` as users write it: a choice's name, or the number (`f32`/`u32` Display).
    pub fn format(&self, p: &Params) -> String {
        let v = (self.get)(p);
        match self.kind {
            ParamKind::Choice(choices) => choices()
                .into_iter()
                .find(|(_, code)| f64::from(*code) == v)
                .map_or_else(|| format!("<code {v}>"), |(name, _)| name.to_string()),
            _ => self.format_raw(v),
        }
    }

    /// A stored value as a number (`f32` Display for floats, the `u32` otherwise).
    fn format_raw(&self, v: f64) -> String {
        match self.kind {
            ParamKind::Float { .. } => (v as f32).to_string(),
            _ => (v as u32).to_string(),
        }
    }

    /// Whether the value in `p` is valid (its kind's range, power of two, a known choice code);
    /// otherwise the [`ParamError`] naming the field, the value and [`ParamSpec::reason`].
    pub fn check(&self, p: &Params) -> Result<(), ParamError> {
        let v = (self.get)(p);
        let ok = match self.kind {
            ParamKind::Float { min, max } => {
                let v = v as f32;
                v.is_finite() && v >= min && v <= max
            }
            ParamKind::Uint {
                min,
                max,
                power_of_two,
            } => {
                let v = v as u32;
                (min..=max).contains(&v) && (!power_of_two || v.is_power_of_two())
            }
            ParamKind::Choice(choices) => choices().iter().any(|(_, c)| f64::from(*c) == v),
        };
        if ok {
            Ok(())
        } else {
            Err(ParamError {
                field: self.name,
                value: self.format_raw(v),
                reason: self.reason(),
            })
        }
    }
}

/// One numeric table entry: the `Params` field, its flag, kind, refusal reason and help; the
/// getter and setter are the field's, through `f64`.
macro_rules! param {
    ($field:ident, $flag:literal, $kind:expr, $reason:literal, $help:literal) => {
        ParamSpec {
            name: stringify!($field),
            flag: $flag,
            aliases: &[],
            help: Help::Text($help),
            kind: $kind,
            reason: Some($reason),
            get: |p| f64::from(p.$field),
            set: |p, v| p.$field = v as _,
        }
    };
}

/// One choice entry: the `Params` field, its flag, its mode enum and the help's text before and
/// after the choice names; the choices, the reason and the names and citations of the help come
/// from the enum.
macro_rules! choice {
    ($field:ident, $flag:literal, $mode:ident, $before:literal, $after:literal) => {
        ParamSpec {
            name: stringify!($field),
            flag: $flag,
            aliases: &[],
            help: Help::Choices {
                before: $before,
                cite: |code| $mode::from_id(code).and_then($mode::cite),
                after: $after,
            },
            kind: ParamKind::Choice($mode::choices),
            reason: None,
            get: |p| f64::from(p.$field),
            set: |p, v| p.$field = v as _,
        }
    };
}

/// A distance-like float: finite in `min..=MAX_DISTANCE`.
const fn distance(min: f32) -> ParamKind {
    ParamKind::Float {
        min,
        max: MAX_DISTANCE,
    }
}
/// A float in `min..=max`.
const fn float(min: f32, max: f32) -> ParamKind {
    ParamKind::Float { min, max }
}
/// An integer in `min..=max`.
const fn uint(min: u32, max: u32) -> ParamKind {
    ParamKind::Uint {
        min,
        max,
        power_of_two: false,
    }
}
/// A power of two in `1..=max`.
const fn power_of_two(max: u32) -> ParamKind {
    ParamKind::Uint {
        min: 1,
        max,
        power_of_two: true,
    }
}

/// Every user-settable parameter, in the order the CLI lists them and [`Params::validate`]
/// checks them. Kept one entry to a line or two (`rustfmt::skip`): it is a table.
#[rustfmt::skip]
pub const PARAMS: [ParamSpec; 56] = [
    param!(grid_size, "grid-size", distance(MIN_GRID_SIZE), "expected a finite size in 0.01..=1e7 m",
        "Batch grid cell size, metres (E§4.2)"),
    param!(angle_count, "angles", uint(1, MAX_ANGLE_COUNT), "expected 1..=91 elevation angles",
        "Number of billboard elevation angles K (E§3.3)"),
    param!(texture_size, "texture-size", power_of_two(MAX_TEXTURE_SIZE), "expected a power of two in 1..=4096",
        "Billboard texture side r, a power of two (E§3.3)"),
    param!(lod_levels, "lod-levels", uint(1, 3),
        "expected 1 (meshes only), 2 (meshes then billboards) or 3 (then the far level of far-lod)",
        "LOD levels: 1 (meshes only), 2 (then billboards) or 3 (then far-lod, issue 32)"),
    param!(lod1_transition, "transition", distance(0.0), "expected a finite distance in 0..=1e7 m",
        "View depth where billboards have fully replaced meshes, metres (E§3.5)"),
    param!(fade_width, "fade-width", distance(0.0), "expected a finite width in 0..=1e7 m",
        "Width of the fade band ending at the transition, metres (E§3.5)"),
    param!(draw_distance, "draw-distance", distance(0.0), "expected a finite distance in 0..=1e7 m",
        "Draw distance, metres (E§4.4)"),
    param!(alpha_cutoff, "alpha-cutoff", float(0.0, 1.0), "expected a finite alpha in 0..=1",
        "Alpha-test cutoff of foliage, in 0..=1"),
    choice!(fade_mode, "fade-mode", FadeMode, "Fade mode: ", ""),
    choice!(mip_mode, "mip-mode", MipMode, "Billboard mip mode: ", " (E§3.3.2)"),
    choice!(angle_index_mode, "angle-index", AngleIndexMode, "Billboard layer index: ", ""),
    choice!(tree_cull, "tree-cull", TreeCull, "Per-tree culling after selection (refine, beyond the thesis): ", ""),
    choice!(hierarchy, "hierarchy", Hierarchy, "Tree grouping: ", ""),
    param!(nodes_per_node, "nodes-per-node", uint(2, 1 << 20), "expected 2..=1048576 children or trees per node",
        "Most children of a quadtree node and most trees of a hierarchy leaf (C§4.5 NodesPerNode)"),
    param!(max_cull_depth, "max-cull-depth", uint(0, 64), "expected a depth in 0..=64",
        "Octree depth below which partially visible nodes recurse (G§3 max_cull_depth)"),
    choice!(coalesce, "coalesce", Coalesce, "Merge adjacent draw commands of the hierarchical cut (issue 13): ", ""),
    choice!(command_order, "command-order", CommandOrder, "Order of the hierarchical cut's commands after coalescing: ", ""),
    choice!(lod_metric, "lod-metric", LodMetric, "Where a tree changes to its billboard (issue 29): ", ""),
    param!(lod_pixel_area, "pixel-area", float(MIN_METRIC_THRESHOLD, MAX_METRIC_THRESHOLD),
        "expected a finite area in 1e-6..=1e9 px²",
        "Pixel-area metrics: billboard once the tree's opaque area covers at most this many px² (C§4.6.3)"),
    param!(lod_screen_error, "screen-error", float(MIN_METRIC_THRESHOLD, MAX_METRIC_THRESHOLD),
        "expected a finite error in 1e-6..=1e9 px",
        "Screen-error metric: billboard once its geometric error covers at most this many px (3D Tiles)"),
    choice!(subset_mode, "subset", SubsetMode, "Far-field subsets of each batch's trees (issue 29): ", ""),
    param!(subset_distance, "subset-distance", distance(0.0), "expected a finite distance in 0..=1e7 m",
        "View depth past which batches draw a thinning subset of their trees, metres (E§7)"),
    param!(subset_min, "subset-min", float(MIN_SUBSET_DENSITY, 1.0), "expected a finite density in 0.001..=1",
        "Least density of a far-field subset, in 0.001..=1 (E§7)"),
    choice!(shading, "shading", Shading, "Tree shading (issue 30): ", ""),
    param!(sun_azimuth, "sun-azimuth", float(-360.0, 360.0), "expected a finite azimuth in -360..=360 degrees",
        "Sun azimuth, degrees counter-clockwise from +X (G§5)"),
    param!(sun_elevation, "sun-elevation", float(0.0, 90.0), "expected a finite elevation in 0..=90 degrees",
        "Sun elevation above the horizon, degrees (G§5)"),
    param!(ambient, "ambient", float(0.0, 1.0), "expected a finite level in 0..=1",
        "Ambient level of sun-depth shading: the lightness of a crown's far side, in 0..=1 (G§5)"),
    choice!(dither_space, "dither-space", DitherSpace, "Where the dithered fades' threshold comes from (issue 30): ", ""),
    choice!(fade_granularity, "fade-granularity", FadeGranularity, "What a fade's progress through the band is taken from (issue 30): ", ""),
    param!(noise_size, "noise-size", power_of_two(MAX_TEXTURE_SIZE), "expected a power of two in 1..=4096",
        "Side of the texture-space noise under dither-space texture, a power of two (G§4)"),
    param!(azimuth_count, "azimuths", uint(1, MAX_AZIMUTH_COUNT), "expected 1..=64 azimuth views",
        "Number of billboard azimuth views J per elevation (E§7)"),
    choice!(azimuth_mode, "azimuth-mode", AzimuthMode, "Billboard azimuth view (issue 30): ", ""),
    choice!(occlusion, "occlusion", Occlusion, "Occlusion culling against a depth pyramid (issue 31): ", ""),
    param!(occluder_depth, "occluder-depth", distance(0.0), "expected a finite distance in 0..=1e7 m",
        "Depth behind the nearest mesh tree within which mesh trees are occluders under occlusion single, metres"),
    choice!(occlusion_order, "occlusion-order", OcclusionOrder, "Pass order of occlusion culling (issue 31): ", ""),
    choice!(billboard_views, "billboard-views", ViewSphere, "Views the billboard array holds (issue 32): ", ""),
    param!(octahedral_grid, "octahedral-grid", uint(MIN_OCTAHEDRAL_GRID, MAX_OCTAHEDRAL_GRID), "expected 2..=32 frames a side",
        "Side N of the octahedral impostor grid, N x N frames per mesh"),
    choice!(octahedral_blend, "octahedral-blend", AzimuthMode, "Octahedral impostor frames drawn (issue 32): ", ""),
    choice!(far_lod, "far-lod", FarLod, "Far level of whole nodes under lod-levels 3 (issue 32): ", ""),
    param!(far_start, "far-start", distance(0.0), "expected a finite distance in 0..=1e7 m",
        "View depth from which a whole node may go far, metres (issue 32)"),
    param!(far_pixels, "far-pixels", float(0.0, MAX_METRIC_THRESHOLD), "expected a finite area in 0..=1e9 pixels",
        "Screen area under which a node goes far, pixels (C§4.6.3 metric on its box)"),
    param!(cluster_size, "cluster-size", uint(1, MAX_CLUSTER_SIZE), "expected 1..=12 cells per axis",
        "Cells per axis of a node's far level (G§2.4 clusterSize, cs^3 cells)"),
    choice!(parent_rule, "parent-rule", ParentRule, "How interior nodes' far cells come from their children (G§2.2): ", ""),
    choice!(octahedral_depth, "octahedral-depth", OctahedralDepth, "Depth channel of octahedral impostors for the blend (issue 32): ", ""),
    choice!(lod1, "lod1", Lod1, "What a tree is drawn as past the mesh level (issue 33): ", ""),
    choice!(point_select, "point-select", PointSelect, "Which records of a tree's point hierarchy are drawn under lod1 points: ", ""),
    choice!(point_detail, "point-detail", DetailPreset, "Point selection's screen areas under lod1 points: ", ""),
    param!(point_count, "point-count", uint(1, MAX_POINTS_PER_MESH), "expected 1..=4096 points per mesh",
        "Points placed per mesh under lod1 points (C§4.4.4 N_pts)"),
    param!(impostor_pixels, "impostor-pixels", uint(MIN_IMPOSTOR_PIXELS, MAX_IMPOSTOR_PIXELS), "expected 8..=256 pixels",
        "Side of a hierarchical impostor's tile under far-lod impostor, pixels (C§4.6.3 ImpostorWidth)"),
    param!(impostor_tiles, "impostor-tiles", uint(1, 4096), "expected 1..=4096 tiles",
        "Tiles of the impostor atlas under far-lod impostor (C§4.6.3 ImpostorTextureWidth)"),
    param!(impostor_min_distance, "impostor-min-distance", distance(0.0), "expected a finite distance in 0..=1e7 m",
        "Least distance from the eye to a node's box for an impostor, metres (C§4.6.3 ImpostorMinimalDistance)"),
    param!(impostor_max_depth, "impostor-max-depth", uint(0, MAX_HIERARCHY_DEPTH), "expected 0..=32 levels",
        "Deepest hierarchy level that may be impostored, root 0 (C§4.6.3 ImpostorHierarchyMaxDepth)"),
    param!(impostor_update_interval, "impostor-update-interval", uint(1, 1 << 20), "expected 1..=1048576 frames",
        "Frames between two impostor plans (C§4.6.3 ImpostorUpdateInterval)"),
    param!(impostor_refresh_interval, "impostor-refresh-interval", uint(1, 1 << 20), "expected 1..=1048576 frames",
        "Frames between two impostor refresh steps (C§4.6.3 ImpostorRefreshInterval)"),
    param!(impostor_refresh_number, "impostor-refresh-number", uint(0, 4096), "expected 0..=4096 impostors",
        "Impostors re-rendered per refresh step, round robin (C§4.6.3 ImpostorRefreshNumber)"),
    param!(point_grid, "point-grid", uint(1, MAX_POINT_GRID), "expected 1..=10 cells per axis",
        "Grid a mesh's points are split by under lod1 points, g^3 cells (C§4.4.3 GridSizeX/Y/Z)"),
];

/// Least `subset_min`: one tree in a thousand (a smaller floor leaves batches of a few hundred
/// trees with none, which is a draw distance, not a subset).
pub const MIN_SUBSET_DENSITY: f32 = 0.001;

/// Least pixel-area or screen-error threshold: below it every tree is a mesh out to 1e7 m.
pub const MIN_METRIC_THRESHOLD: f32 = 1.0e-6;
/// Greatest threshold: above it every tree is a billboard from the eye on.
pub const MAX_METRIC_THRESHOLD: f32 = 1.0e9;

/// The parameter `key` names (canonical name, flag in either form, or alias).
pub fn param(key: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|s| s.answers_to(key))
}

/// Every key a TOML file may use, for "unknown parameter" messages.
pub fn param_names() -> Vec<&'static str> {
    PARAMS.iter().map(|s| s.name).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_entry_round_trips_its_default_and_keys_are_unique() {
        let defaults = Params::default();
        let mut keys = std::collections::HashSet::new();
        for spec in &PARAMS {
            for key in [spec.name.to_string(), spec.flag.to_string(), spec.key()]
                .into_iter()
                .chain(spec.aliases.iter().map(|a| a.to_string()))
            {
                let owner = param(&key).expect("every key resolves");
                assert_eq!(
                    owner.name, spec.name,
                    "key {key} is taken by {}",
                    owner.name
                );
                keys.insert(key);
            }
            let text = spec.format(&defaults);
            let mut p = Params::default();
            (spec.set)(&mut p, 0.0); // scribble, then restore from the text
            (spec.set)(&mut p, spec.parse(&text).expect("default parses"));
            assert_eq!(p, defaults, "{} does not round-trip {text:?}", spec.name);
        }
    }

    #[test]
    fn choice_texts_come_from_the_choice_list() {
        for spec in &PARAMS {
            let choice = matches!(spec.kind, ParamKind::Choice(_));
            assert_eq!(spec.reason.is_none(), choice, "{}", spec.name);
            assert_eq!(
                matches!(spec.help, Help::Choices { .. }),
                choice,
                "{}",
                spec.name
            );
            let (reason, help) = (spec.reason(), spec.help());
            for name in spec.choice_names() {
                assert!(
                    reason.contains(&format!(" ({name})")),
                    "{}: {name}",
                    spec.name
                );
                assert!(help.contains(name), "{}: {name}", spec.name);
            }
        }
    }

    #[test]
    fn choices_take_names_numbers_take_numbers() {
        let fade = param("fade_mode").unwrap();
        assert_eq!(
            fade.parse("alpha").unwrap(),
            f64::from(FadeMode::Alpha as u32)
        );
        assert!(fade.parse("blend").unwrap_err().expected.contains("alpha"));
        assert!(fade.from_number(1.0).is_err());
        let angles = param("angles").unwrap();
        assert_eq!(angles.name, "angle_count");
        assert!(angles.from_number(2.5).is_err());
        assert!(angles.from_number(-1.0).is_err());
        assert_eq!(angles.from_number(7.0).unwrap(), 7.0);
        assert!(param("grid_size").unwrap().parse("nan").unwrap().is_nan());
        assert!(param("no_such").is_none());
        assert_eq!(param("angle_index").unwrap().name, "angle_index_mode");
        assert_eq!(param("transition").unwrap().name, "lod1_transition");
    }
}
