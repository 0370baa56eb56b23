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
//! names come from the enums' own `name()` (one spelling per mode, in one place).
//!
//! Rejected design: a `match name` per consumer (CLI struct fields, a TOML `set_param`, metrics
//! keys), as before issue 11: a parameter added to one was silently missing from the others.

use crate::{AngleIndexMode, FadeMode, MipMode, Params, TreeCull};

/// What values a parameter takes.
#[derive(Clone, Copy, Debug)]
pub enum ParamKind {
    /// An `f32`.
    Float,
    /// A `u32`.
    Uint,
    /// One of named modes, stored as its `u32` code: `(name, code)` pairs.
    Choice(fn() -> Vec<(&'static str, u32)>),
}

/// One user-settable parameter (module docs).
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    /// Canonical name: the [`Params`] field, a TOML key.
    pub name: &'static str,
    /// Command-line flag without the dashes; with `-` read as `_`, also a TOML key and the key of
    /// the main job's metrics.
    pub flag: &'static str,
    /// Further TOML keys accepted for it.
    pub aliases: &'static [&'static str],
    /// One-line help (the CLI's `--help`).
    pub help: &'static str,
    /// Values it takes.
    pub kind: ParamKind,
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

    /// The choice names, in order (empty for numbers).
    pub fn choice_names(&self) -> Vec<&'static str> {
        match self.kind {
            ParamKind::Choice(choices) => choices().into_iter().map(|(n, _)| n).collect(),
            _ => Vec::new(),
        }
    }

    /// What a valid value looks like, for error messages.
    pub fn expected(&self) -> String {
        match self.kind {
            ParamKind::Float => "expected a number".into(),
            ParamKind::Uint => "expected a non-negative integer".into(),
            ParamKind::Choice(_) => format!("expected one of {}", self.choice_names().join(", ")),
        }
    }

    /// Parses the text of a value (a flag's argument, a TOML string): a number for numeric kinds
    /// (`nan` and `inf` parse; [`Params::validate`] rejects them, naming the field), a name for
    /// choices. Returns what [`ParamSpec::set`] takes.
    pub fn parse(&self, text: &str) -> Result<f64, ParseError> {
        let text = text.trim();
        let bad = || ParseError {
            expected: self.expected(),
        };
        match self.kind {
            ParamKind::Float => text.parse::<f32>().map(f64::from).map_err(|_| bad()),
            ParamKind::Uint => text.parse::<u32>().map(f64::from).map_err(|_| bad()),
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
            ParamKind::Float => Ok(f64::from(value as f32)),
            ParamKind::Uint if value.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&value) => {
                Ok(value)
            }
            _ => Err(bad()),
        }
    }

    /// The value in `p` as users write it: a choice's name, or the number (`f32`/`u32` Display).
    pub fn format(&self, p: &Params) -> String {
        let v = (self.get)(p);
        match self.kind {
            ParamKind::Float => (v as f32).to_string(),
            ParamKind::Uint => (v as u32).to_string(),
            ParamKind::Choice(choices) => choices()
                .into_iter()
                .find(|(_, code)| f64::from(*code) == v)
                .map_or_else(|| format!("<code {v}>"), |(name, _)| name.to_string()),
        }
    }
}

fn fade_modes() -> Vec<(&'static str, u32)> {
    FadeMode::ALL
        .iter()
        .map(|m| (m.name(), *m as u32))
        .collect()
}
fn mip_modes() -> Vec<(&'static str, u32)> {
    MipMode::ALL.iter().map(|m| (m.name(), *m as u32)).collect()
}
fn angle_index_modes() -> Vec<(&'static str, u32)> {
    AngleIndexMode::ALL
        .iter()
        .map(|m| (m.name(), *m as u32))
        .collect()
}
fn tree_culls() -> Vec<(&'static str, u32)> {
    TreeCull::ALL
        .iter()
        .map(|m| (m.name(), *m as u32))
        .collect()
}

/// Every user-settable parameter, in the order the CLI lists them.
pub const PARAMS: [ParamSpec; 12] = [
    ParamSpec {
        name: "grid_size",
        flag: "grid-size",
        aliases: &[],
        help: "Batch grid cell size, metres (E§4.2)",
        kind: ParamKind::Float,
        get: |p| f64::from(p.grid_size),
        set: |p, v| p.grid_size = v as f32,
    },
    ParamSpec {
        name: "angle_count",
        flag: "angles",
        aliases: &[],
        help: "Number of billboard elevation angles K (E§3.3)",
        kind: ParamKind::Uint,
        get: |p| f64::from(p.angle_count),
        set: |p, v| p.angle_count = v as u32,
    },
    ParamSpec {
        name: "texture_size",
        flag: "texture-size",
        aliases: &[],
        help: "Billboard texture side r, a power of two (E§3.3)",
        kind: ParamKind::Uint,
        get: |p| f64::from(p.texture_size),
        set: |p, v| p.texture_size = v as u32,
    },
    ParamSpec {
        name: "lod_levels",
        flag: "lod-levels",
        aliases: &[],
        help: "LOD levels: 1 (meshes only) or 2",
        kind: ParamKind::Uint,
        get: |p| f64::from(p.lod_levels),
        set: |p, v| p.lod_levels = v as u32,
    },
    ParamSpec {
        name: "lod1_transition",
        flag: "transition",
        aliases: &[],
        help: "View depth where billboards have fully replaced meshes, metres (E§3.5)",
        kind: ParamKind::Float,
        get: |p| f64::from(p.lod1_transition),
        set: |p, v| p.lod1_transition = v as f32,
    },
    ParamSpec {
        name: "fade_width",
        flag: "fade-width",
        aliases: &[],
        help: "Width of the fade band ending at the transition, metres (E§3.5)",
        kind: ParamKind::Float,
        get: |p| f64::from(p.fade_width),
        set: |p, v| p.fade_width = v as f32,
    },
    ParamSpec {
        name: "draw_distance",
        flag: "draw-distance",
        aliases: &[],
        help: "Draw distance, metres (E§4.4)",
        kind: ParamKind::Float,
        get: |p| f64::from(p.draw_distance),
        set: |p, v| p.draw_distance = v as f32,
    },
    ParamSpec {
        name: "alpha_cutoff",
        flag: "alpha-cutoff",
        aliases: &[],
        help: "Alpha-test cutoff of foliage, in 0..=1",
        kind: ParamKind::Float,
        get: |p| f64::from(p.alpha_cutoff),
        set: |p, v| p.alpha_cutoff = v as f32,
    },
    ParamSpec {
        name: "fade_mode",
        flag: "fade-mode",
        aliases: &[],
        help: "Fade mode: none, alpha (E§4.4), dither, dither-sequential (G§4)",
        kind: ParamKind::Choice(fade_modes),
        get: |p| f64::from(p.fade_mode),
        set: |p, v| p.fade_mode = v as u32,
    },
    ParamSpec {
        name: "mip_mode",
        flag: "mip-mode",
        aliases: &[],
        help: "Billboard mip mode: alpha-aware, box, coverage (E§3.3.2)",
        kind: ParamKind::Choice(mip_modes),
        get: |p| f64::from(p.mip_mode),
        set: |p, v| p.mip_mode = v as u32,
    },
    ParamSpec {
        name: "angle_index_mode",
        flag: "angle-index",
        aliases: &[],
        help: "Billboard layer index: nearest, eq31-clamped (E Eq. 3.1)",
        kind: ParamKind::Choice(angle_index_modes),
        get: |p| f64::from(p.angle_index_mode),
        set: |p, v| p.angle_index_mode = v as u32,
    },
    ParamSpec {
        name: "tree_cull",
        flag: "tree-cull",
        aliases: &[],
        help: "Per-tree culling after selection (refine, beyond the thesis): none, lod0, all",
        kind: ParamKind::Choice(tree_culls),
        get: |p| f64::from(p.tree_cull),
        set: |p, v| p.tree_cull = v as u32,
    },
];

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
