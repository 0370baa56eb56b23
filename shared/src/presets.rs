//! Named parameter presets: bundles of parameter settings that a seed names (issue 29). A preset
//! is applied first; every parameter given on its own (a CLI flag, a sweep setting's key) then
//! overrides it. The texts are parsed by the parameter table ([`crate::registry`]), so a preset
//! is checked like any other input.
//!
//! Celba 2007 Table 5.2 names five metric settings, extra high to extra low (C§5.2-§5.4). Their
//! "tree level point size" is the screen area (px²) at which a whole tree leaves its detailed
//! representation for its aggregate one. Here the aggregate is the billboard, and the area is
//! the billboard's opaque area under Celba's own constant (`pixel-area-seed`, 4x the true area,
//! C Eq. 4.2 as written), so each preset means what it meant in his runs. The preset is the
//! table's largest tree-level point size: 5, 10, 15, 20 and 30 px². The table's other columns
//! (point and triangle sizes) set the point representation of Celba's later variant and mean
//! nothing for billboards.
//!
//! Guerrero 2006 §4 names one blend (issue 30): `guerrero-blend` is the sequential dithered fade
//! with the noise in each LOD's texture space and the blend factor per tree
//! (`shared/src/fade.rs`, `shared/src/noise.rs`).
//!
//! `far-hulls` (issue 32) is the best trade the far-level sweep found: a third LOD level of
//! Eichner's batch hulls (E§7) for octree nodes past 1000 m under 1024 pixels.

use crate::registry::{ParseError, param};
use crate::{ParamError, Params};

/// One named preset.
#[derive(Clone, Copy, Debug)]
pub struct Preset {
    /// What users type (`--preset celba-high`, `preset = "celba-high"`).
    pub name: &'static str,
    /// Where the values come from.
    pub seed: &'static str,
    /// `(parameter, value)` pairs, as a CLI flag's or a sweep file's text.
    pub settings: &'static [(&'static str, &'static str)],
}

/// Every preset, in table order (module docs).
pub const PRESETS: [Preset; 7] = [
    celba("celba-extra-high", &[CELBA_METRIC, ("lod_pixel_area", "5")]),
    celba("celba-high", &[CELBA_METRIC, ("lod_pixel_area", "10")]),
    celba("celba-normal", &[CELBA_METRIC, ("lod_pixel_area", "15")]),
    celba("celba-low", &[CELBA_METRIC, ("lod_pixel_area", "20")]),
    celba("celba-extra-low", &[CELBA_METRIC, ("lod_pixel_area", "30")]),
    Preset {
        name: "guerrero-blend",
        seed: "G§4",
        settings: &[
            ("fade_mode", "dither-sequential"),
            ("dither_space", "texture"),
            ("fade_granularity", "tree"),
        ],
    },
    // The best trade of the far levels (issue 32, `experiments/results/far_levels/README.md`):
    // Eichner's batch hulls on the octree past the transition.
    Preset {
        name: "far-hulls",
        seed: "E§7 batch hull, issue 32",
        settings: &[
            ("lod_levels", "3"),
            ("hierarchy", "octree"),
            ("nodes_per_node", "64"),
            ("far_lod", "hull"),
            ("far_start", "1000"),
            ("far_pixels", "1024"),
        ],
    },
];

/// Celba's presets select on his own metric, constant as printed.
const CELBA_METRIC: (&str, &str) = ("lod_metric", "pixel-area-seed");

const fn celba(name: &'static str, settings: &'static [(&'static str, &'static str)]) -> Preset {
    Preset {
        name,
        seed: "C Table 5.2",
        settings,
    }
}

/// The preset named `name`.
pub fn preset(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}

/// Every preset's name, for "expected one of" messages.
pub fn preset_names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.name).collect()
}

impl Preset {
    /// Whether the preset sets parameter `name` (a canonical `Params` field name).
    pub fn sets(&self, name: &str) -> bool {
        self.settings
            .iter()
            .any(|(k, _)| param(k).is_some_and(|s| s.name == name))
    }

    /// Applies the preset's settings to `p` (parsed by the parameter table).
    pub fn apply(&self, p: &mut Params) -> Result<(), ParamError> {
        for &(key, text) in self.settings {
            let spec = param(key).expect("a preset names table parameters (tested)");
            let value = spec
                .parse(text)
                .map_err(|ParseError { expected }| ParamError {
                    field: spec.name,
                    value: text.to_string(),
                    reason: expected.into(),
                })?;
            (spec.set)(p, value);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_is_valid_and_named_once() {
        let mut names = std::collections::HashSet::new();
        for pr in &PRESETS {
            assert!(names.insert(pr.name), "{} twice", pr.name);
            let mut p = Params::default();
            pr.apply(&mut p)
                .unwrap_or_else(|e| panic!("{}: {e}", pr.name));
            p.validate().unwrap_or_else(|e| panic!("{}: {e}", pr.name));
            assert_ne!(p, Params::default(), "{} changes nothing", pr.name);
        }
    }

    #[test]
    fn celbas_presets_are_table_5_2s_tree_level_sizes_under_his_constant() {
        let areas: Vec<f32> = PRESETS
            .iter()
            .filter(|pr| pr.seed == "C Table 5.2")
            .map(|pr| {
                let mut p = Params::default();
                pr.apply(&mut p).unwrap();
                assert_eq!(p.lod_metric, crate::LodMetric::PixelAreaSeed as u32);
                p.lod_pixel_area
            })
            .collect();
        assert_eq!(areas, [5.0, 10.0, 15.0, 20.0, 30.0]);
        assert!(preset("celba-high").unwrap().sets("lod_pixel_area"));
        assert!(!preset("celba-high").unwrap().sets("grid_size"));
        assert!(preset("celba-ultra").is_none());
    }

    #[test]
    fn guerreros_blend_is_the_sequential_dither_in_texture_space_per_tree() {
        let mut p = Params::default();
        preset("guerrero-blend").unwrap().apply(&mut p).unwrap();
        assert_eq!(p.fade().unwrap(), crate::FadeMode::DitherSequential);
        assert_eq!(p.dither().unwrap(), crate::DitherSpace::Texture);
        assert_eq!(p.granularity().unwrap(), crate::FadeGranularity::Tree);
        assert_eq!(
            Params {
                dither_space: 0,
                fade_granularity: 0,
                ..p
            },
            Params::default(),
            "the preset changes the space and the granularity only"
        );
    }
}
