//! Command-line options shared by every subcommand: which scene, which camera, which parameters.

use std::path::{Path, PathBuf};

use clap::Args;
use forestlod_reference::InputError;
use forestlod_reference::scene::{Scene, builtin, load};
use forestlod_shared::{AngleIndexMode, FadeMode, MipMode, Params, TreeCull};

/// Which scene to use.
#[derive(Args, Clone, Debug)]
pub struct SceneArgs {
    /// A built-in scene name (tiny, synthetic, stress) or a path to a TOML scene file.
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
            load::load_scene_file_with(path, &options)
        } else {
            builtin::by_name(&self.scene)
        }
    }
}

/// Pipeline parameters; every flag defaults to the thesis value (E§4.5.1, E§5.0.2).
#[derive(Args, Clone, Debug)]
pub struct ParamArgs {
    /// Batch grid cell size, metres.
    #[arg(long, default_value_t = Params::default().grid_size, allow_negative_numbers = true)]
    pub grid_size: f32,
    /// Number of billboard elevation angles K.
    #[arg(long, default_value_t = Params::default().angle_count)]
    pub angles: u32,
    /// Billboard texture side r (a power of two).
    #[arg(long, default_value_t = Params::default().texture_size)]
    pub texture_size: u32,
    /// LOD levels: 1 (meshes only) or 2.
    #[arg(long, default_value_t = Params::default().lod_levels)]
    pub lod_levels: u32,
    /// View depth where billboards have fully replaced meshes, metres.
    #[arg(long, default_value_t = Params::default().lod1_transition, allow_negative_numbers = true)]
    pub transition: f32,
    /// Width of the fade band ending at the transition, metres.
    #[arg(long, default_value_t = Params::default().fade_width, allow_negative_numbers = true)]
    pub fade_width: f32,
    /// Draw distance, metres.
    #[arg(long, default_value_t = Params::default().draw_distance, allow_negative_numbers = true)]
    pub draw_distance: f32,
    /// Fade mode: none, alpha (E§4.4), dither, dither-sequential (G§4, the default).
    #[arg(long, default_value = "dither-sequential")]
    pub fade_mode: String,
    /// Mip mode: alpha-aware, box, coverage.
    #[arg(long, default_value = "alpha-aware")]
    pub mip_mode: String,
    /// Billboard layer index: nearest, eq31-clamped.
    #[arg(long, default_value = "nearest")]
    pub angle_index: String,
    /// Per-tree culling after selection (`refine`, beyond the thesis): none, lod0, all.
    #[arg(long, default_value = "none")]
    pub tree_cull: String,
}

fn unknown(field: &str, value: &str, expected: &[&str]) -> InputError {
    InputError::new(
        "<command line>",
        format!("--{field}"),
        value,
        format!("expected one of {}", expected.join(", ")),
    )
}

impl ParamArgs {
    /// The validated parameters.
    pub fn params(&self) -> Result<Params, InputError> {
        let fade = FadeMode::from_name(&self.fade_mode).ok_or_else(|| {
            unknown(
                "fade-mode",
                &self.fade_mode,
                &FadeMode::ALL.map(FadeMode::name),
            )
        })?;
        let mip = MipMode::ALL
            .into_iter()
            .find(|m| m.name() == self.mip_mode)
            .ok_or_else(|| unknown("mip-mode", &self.mip_mode, &MipMode::ALL.map(MipMode::name)))?;
        let angle = AngleIndexMode::ALL
            .into_iter()
            .find(|m| m.name() == self.angle_index)
            .ok_or_else(|| {
                unknown(
                    "angle-index",
                    &self.angle_index,
                    &AngleIndexMode::ALL.map(AngleIndexMode::name),
                )
            })?;
        let tree_cull = TreeCull::ALL
            .into_iter()
            .find(|m| m.name() == self.tree_cull)
            .ok_or_else(|| {
                unknown(
                    "tree-cull",
                    &self.tree_cull,
                    &TreeCull::ALL.map(TreeCull::name),
                )
            })?;
        let p = Params {
            grid_size: self.grid_size,
            angle_count: self.angles,
            texture_size: self.texture_size,
            lod_levels: self.lod_levels,
            lod1_transition: self.transition,
            fade_width: self.fade_width,
            draw_distance: self.draw_distance,
            fade_mode: fade as u32,
            mip_mode: mip as u32,
            angle_index_mode: angle as u32,
            tree_cull: tree_cull as u32,
            ..Params::default()
        };
        p.validate()?;
        Ok(p)
    }
}
