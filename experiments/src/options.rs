//! Command-line options shared by every subcommand: which scene, which camera, which parameters.

use std::path::{Path, PathBuf};

use clap::Args;
use forestlod_reference::InputError;
use forestlod_reference::scene::{Scene, builtin, load};
use std::collections::BTreeMap;

use forestlod_reference::error::COMMAND_LINE;
use forestlod_shared::{PARAMS, Params};

/// Which scene to use.
#[derive(Args, Clone, Debug)]
pub struct SceneArgs {
    /// A built-in scene name (tiny, synthetic, stress, patchy, or Celba's forests
    /// celba-<trees per ha>-<side km>, e.g. celba-20-10) or a path to a TOML scene file.
    #[arg(long, default_value = "synthetic")]
    pub scene: String,
    /// A bare instance CSV (x,y,z,yaw,scale,species) drawn with the built-in species meshes;
    /// overrides --scene.
    #[arg(long)]
    pub instances: Option<PathBuf>,
    /// Let a scene file name files (instances, meshes, textures, glTF buffers) outside its own
    /// folder; by default every named file must lie under it after resolving `..` and symlinks.
    #[arg(long)]
    pub allow_outside_paths: bool,
}

impl SceneArgs {
    /// Loads the scene, validated. `--scene` with a `.csv`, `.obj`, `.gltf` or `.glb` path is an
    /// error saying what to use instead.
    pub fn load(&self) -> Result<Scene, InputError> {
        if let Some(csv) = &self.instances {
            return load::load_instances_with_builtin_species(csv);
        }
        let path = Path::new(&self.scene);
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("csv") => {
                return Err(InputError::new(
                    "<command line>",
                    "--scene",
                    &self.scene,
                    format!(
                        "a CSV instance table is not a scene file: use --instances {} (built-in species), or name it from a scene TOML file (instances = \"{}\")",
                        self.scene, self.scene
                    ),
                ));
            }
            Some("obj" | "gltf" | "glb") => {
                return Err(InputError::new(
                    "<command line>",
                    "--scene",
                    &self.scene,
                    load::minimal_scene_hint(&self.scene),
                ));
            }
            _ => {}
        }
        let options = load::LoadOptions {
            allow_outside_paths: self.allow_outside_paths,
        };
        if self.scene.ends_with(".toml") || path.is_file() {
            // An elevation model's report (issue 34: trees whose z disagrees with it, counted
            // and never moved) goes to stderr; the outputs stay as they were.
            let (scene, report) = load::load_scene_file_reported(path, &options)?;
            if let Some(r) = report {
                eprintln!("{r}");
            }
            Ok(scene)
        } else {
            builtin::by_name(&self.scene)
        }
    }
}

/// The `--preset` flag's name.
const PRESET_ARG: &str = "preset";

/// Pipeline parameters: one flag per entry of the parameter table
/// ([`forestlod_shared::registry::PARAMS`]), each defaulting to `Params::default()` (the thesis
/// values, E§4.5.1, E§5.0.2, with the fade mode `dither-sequential`). The flags are generated
/// from the table (`clap::Args` by hand), so a parameter added there is a flag here with no edit.
#[derive(Clone, Debug, Default)]
pub struct ParamArgs {
    /// The flags' texts by canonical parameter name (every parameter: defaults filled in).
    values: BTreeMap<&'static str, String>,
    /// The parameters whose flag was given on the command line (not defaulted).
    given: std::collections::BTreeSet<&'static str>,
    /// `--preset`: a named bundle of settings (`forestlod_shared::presets`), applied before the
    /// flags given on the command line, which override it.
    preset: Option<String>,
}

impl clap::FromArgMatches for ParamArgs {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let mut args = Self::default();
        args.update_from_arg_matches(matches)?;
        Ok(args)
    }
    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        for spec in &PARAMS {
            if let Some(text) = matches.get_one::<String>(spec.name) {
                self.values.insert(spec.name, text.clone());
                if matches.value_source(spec.name) == Some(clap::parser::ValueSource::CommandLine) {
                    self.given.insert(spec.name);
                }
            }
        }
        if let Some(name) = matches.get_one::<String>(PRESET_ARG) {
            self.preset = Some(name.clone());
        }
        Ok(())
    }
}

impl clap::Args for ParamArgs {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        let defaults = Params::default();
        let cmd = cmd.arg(clap::Arg::new(PRESET_ARG).long(PRESET_ARG).help(format!(
            "A named bundle of settings, applied before the other flags (which override \
                     it): {}",
            forestlod_shared::presets::preset_names().join(", ")
        )));
        PARAMS.iter().fold(cmd, |cmd, spec| {
            // clap keeps `&'static str`s; the defaults are formatted once per process.
            let default: &'static str = Box::leak(spec.format(&defaults).into_boxed_str());
            cmd.arg(
                clap::Arg::new(spec.name)
                    .long(spec.flag)
                    .help(spec.help().into_owned())
                    .default_value(default)
                    .allow_negative_numbers(true),
            )
        })
    }
    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

impl ParamArgs {
    /// The text given for (or defaulted to) a parameter's flag, by canonical name.
    pub fn text(&self, name: &str) -> Option<&str> {
        self.values.get(name).map(String::as_str)
    }

    /// The validated parameters. A value that does not parse names its flag (`--fade-mode`); one
    /// that parses but is out of range names its flag and the field (`Params::validate`).
    pub fn params(&self) -> Result<Params, InputError> {
        let mut p = Params::default();
        let preset = match &self.preset {
            Some(name) => Some(forestlod_shared::presets::preset(name).ok_or_else(|| {
                InputError::new(
                    COMMAND_LINE,
                    format!("--{PRESET_ARG}"),
                    name,
                    format!(
                        "unknown preset; expected one of {}",
                        forestlod_shared::presets::preset_names().join(", ")
                    ),
                )
            })?),
            None => None,
        };
        if let Some(pr) = preset {
            pr.apply(&mut p).map_err(InputError::from)?;
        }
        for spec in &PARAMS {
            // A preset's parameter keeps the preset's value unless its flag was given.
            if preset.is_some_and(|pr| pr.sets(spec.name)) && !self.given.contains(spec.name) {
                continue;
            }
            if let Some(text) = self.values.get(spec.name) {
                let value = spec.parse(text).map_err(|e| {
                    InputError::new(COMMAND_LINE, format!("--{}", spec.flag), text, e.expected)
                })?;
                (spec.set)(&mut p, value);
            }
        }
        // Out of range: named by the flag the user typed, with the table's field and reason
        // (issue 28, "errors name the flag").
        p.validate()
            .map_err(|e| match PARAMS.iter().find(|s| s.name == e.field) {
                Some(spec) => InputError::new(
                    COMMAND_LINE,
                    format!("--{} (field {})", spec.flag, spec.name),
                    e.value,
                    e.reason,
                ),
                None => InputError::from(e),
            })?;
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{Args, FromArgMatches};

    fn parse(args: &[&str]) -> Result<Params, InputError> {
        let cmd = ParamArgs::augment_args(clap::Command::new("t"));
        let m = cmd
            .try_get_matches_from(std::iter::once("t").chain(args.iter().copied()))
            .expect("clap parses");
        ParamArgs::from_arg_matches(&m).expect("args").params()
    }

    #[test]
    fn a_preset_applies_first_and_given_flags_override_it() {
        let p = parse(&["--preset", "celba-high"]).unwrap();
        assert_eq!(
            (p.lod_metric, p.lod_pixel_area),
            (forestlod_shared::LodMetric::PixelAreaSeed as u32, 10.0)
        );
        let p = parse(&["--preset", "celba-high", "--pixel-area", "7"]).unwrap();
        assert_eq!(p.lod_pixel_area, 7.0);
        // A flag given at its default value still overrides the preset.
        let p = parse(&["--preset", "celba-high", "--lod-metric", "distance"]).unwrap();
        assert_eq!(p.lod_metric, forestlod_shared::LodMetric::Distance as u32);
        assert_eq!(parse(&[]).unwrap(), Params::default());
        let e = parse(&["--preset", "celba-ultra"]).unwrap_err().to_string();
        assert!(e.contains("--preset") && e.contains("celba-normal"), "{e}");
    }
}
