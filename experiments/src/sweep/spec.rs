//! The sweep file (`experiments/sweeps/README.md`): its TOML form ([`SweepSpec`]), validation
//! (one-line [`InputError`]s naming file, field and value), `--quick`, the parameter sets (settings
//! times the axes' product, each through [`set_param`]) and the camera poses. Pipeline and backend
//! names stay strings in the file form (and in `sweep.json`); [`SweepSpec::variant_list`] and
//! [`SweepSpec::backend_list`] turn them into [`Pipeline`]s and [`Engine`]s.

use std::collections::BTreeMap;

use forestlod_reference::InputError;
use forestlod_reference::scene::Scene;
use forestlod_shared::{Camera, Params};
use serde::{Deserialize, Serialize};

use super::variant::{Engine, Pipeline, Registered};
use crate::fair::TileSpec;

/// One camera entry of a sweep file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// `far`, `medium`, `close` (E§5.0.1, [`forestlod_reference::cameras`]), `distance`, or a
    /// scene-defined path (`PATH_NAMES` of [`super::paths`]).
    pub name: String,
    /// For paths: frames along the path (default [`super::paths::DEFAULT_PATH_STEPS`]).
    #[serde(default)]
    pub steps: Option<u32>,
    /// For named cameras: a 360° sweep in this many equal yaw steps (default 1: yaw 0 only).
    #[serde(default)]
    pub yaw_steps: Option<u32>,
    /// For `distance`: the camera's distances from the footprint's centre, metres.
    #[serde(default)]
    pub distances: Option<Vec<f32>>,
}

/// One parameter axis: every value is combined with every value of the other axes.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// Parameter name ([`set_param`]).
    pub param: String,
    /// Values: numbers, or names for the mode parameters.
    pub values: Vec<toml::Value>,
}

/// A named parameter setting (E Fig. 5.7's "default", "no LOD0", "no cross-fade").
#[derive(Clone, Debug, Deserialize, Serialize)]
pub struct SettingSpec {
    /// Label in CSVs and plots.
    pub label: String,
    /// Parameter overrides.
    #[serde(flatten)]
    pub params: toml::Table,
}

/// The `[quick]` overrides.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct QuickSpec {
    /// Scenes.
    pub scenes: Option<Vec<String>>,
    /// Image width.
    pub width: Option<u32>,
    /// Image height.
    pub height: Option<u32>,
    /// Ground-truth samples per pixel side.
    pub samples: Option<u32>,
    /// Yaw steps of every named camera.
    pub yaw_steps: Option<u32>,
    /// Frames of every camera path.
    pub path_steps: Option<u32>,
    /// Distances of the distance path.
    pub distances: Option<Vec<f32>>,
    /// Values per axis parameter.
    pub axes: Option<BTreeMap<String, Vec<toml::Value>>>,
    /// Base parameter overrides (applied after the file's `[params]`).
    pub params: Option<toml::Table>,
    /// Backends.
    pub backends: Option<Vec<String>>,
    /// Frame sizes (replace `width`/`height` and the file's `resolutions`).
    pub resolutions: Option<Vec<[u32; 2]>>,
    /// Sampled-tile truth (replaces the file's).
    pub truth_tiles: Option<TileSpec>,
}

/// A sweep file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// Name: the output sub-folder and CSV name.
    pub name: String,
    /// One-line title for plots and the report.
    pub title: String,
    /// What question the sweep answers.
    #[serde(default)]
    pub description: String,
    /// Scenes: built-in names or scene files.
    pub scenes: Vec<String>,
    /// Variants: `ours`, `ours-atomic`, `vegetation`, `primitive`.
    #[serde(default = "default_variants")]
    pub variants: Vec<String>,
    /// Backends: `reference` (default), `gpu`.
    #[serde(default = "default_backends")]
    pub backends: Vec<String>,
    /// Image width (default 1280).
    #[serde(default = "default_width")]
    pub width: u32,
    /// Image height (default 720).
    #[serde(default = "default_height")]
    pub height: u32,
    /// Frame sizes as an axis, `[[1280, 720], [1920, 1080]]`: every parameter set at each
    /// (labelled with the size when there is more than one). Empty: `width` x `height`.
    #[serde(default)]
    pub resolutions: Vec<[u32; 2]>,
    /// Ground-truth samples per pixel side.
    #[serde(default = "default_samples")]
    pub samples: u32,
    /// Trace the truth on sampled tiles only (`crate::fair::TruthLayout`); absent: the full frame.
    #[serde(default)]
    pub truth_tiles: Option<TileSpec>,
    /// How the truth lights a shaded set's trees (issue 30): `model` (default, the sun-depth
    /// model at each hit: the representation's error) or `shadow` (shadow rays: the model's
    /// error too); [`forestlod_shared::TruthLight`]. Unlit sets' truths are unlit.
    #[serde(default = "default_truth_light")]
    pub truth_light: String,
    /// Measure the total error: every frame rendered again at the truth's sampling rate
    /// (`samples`² times the pixels, untimed) and box-filtered (`crate::fair`). Default true.
    #[serde(default = "default_true")]
    pub total_error: bool,
    /// Timed renders per frame; the minimum is kept.
    #[serde(default = "default_repeats")]
    pub repeats: u32,
    /// The runtime plots' x axis: `yaw`, `distance` or a parameter name.
    #[serde(default = "default_x_axis")]
    pub x_axis: String,
    /// Base parameter overrides (thesis defaults otherwise).
    #[serde(default)]
    pub params: toml::Table,
    /// Cameras.
    pub cameras: Vec<CameraSpec>,
    /// Parameter axes (their Cartesian product).
    #[serde(default)]
    pub axes: Vec<AxisSpec>,
    /// Registered settings (each combined with every axis point).
    #[serde(default)]
    pub settings: Vec<SettingSpec>,
    /// Quick-mode overrides.
    #[serde(default)]
    pub quick: Option<QuickSpec>,
}

/// A non-empty list of registry names as entries, or an error naming `file`, `field` and the bad
/// name (or `[]`).
fn typed<T: Registered>(names: &[String], file: &str, field: &str) -> Result<Vec<T>, InputError> {
    if names.is_empty() {
        return Err(InputError::new(file, field, "[]", T::expected()));
    }
    names
        .iter()
        .map(|n| T::parse(n).map_err(|e| InputError::new(file, field, n, e)))
        .collect()
}

fn default_variants() -> Vec<String> {
    vec!["ours".into()]
}
fn default_backends() -> Vec<String> {
    vec!["reference".into()]
}
fn default_width() -> u32 {
    1280
}
fn default_height() -> u32 {
    720
}
fn default_true() -> bool {
    true
}
fn default_truth_light() -> String {
    forestlod_shared::TruthLight::Model.name().to_string()
}
fn default_samples() -> u32 {
    forestlod_reference::ground_truth::DEFAULT_SAMPLES_PER_AXIS
}
fn default_repeats() -> u32 {
    1
}
fn default_x_axis() -> String {
    "yaw".into()
}

/// Applies one parameter to `p`: any key of the parameter table
/// ([`forestlod_shared::registry::PARAMS`]: canonical names, flags and aliases). Numbers take TOML
/// numbers, modes take their names. Adding a parameter needs no edit here.
pub fn set_param(
    p: &mut Params,
    name: &str,
    value: &toml::Value,
    file: &str,
) -> Result<(), InputError> {
    let Some(spec) = forestlod_shared::param(name) else {
        return Err(InputError::new(
            file,
            "param name",
            name,
            format!(
                "unknown parameter; expected {}",
                forestlod_shared::registry::param_names().join(", ")
            ),
        ));
    };
    let parsed = match value {
        toml::Value::Integer(i) => spec.from_number(*i as f64),
        toml::Value::Float(f) => spec.from_number(*f),
        toml::Value::String(s) if matches!(spec.kind, forestlod_shared::ParamKind::Choice(_)) => {
            spec.parse(s)
        }
        _ => Err(forestlod_shared::registry::ParseError {
            expected: spec.expected(),
        }),
    }
    .map_err(|e| InputError::new(file, format!("param {name}"), value, e.expected))?;
    (spec.set)(p, parsed);
    Ok(())
}

/// The key of a parameter table that names a preset ([`forestlod_shared::presets`]): applied
/// first, the table's other keys override it.
pub const PRESET_KEY: &str = "preset";

/// Applies a parameter table (`[params]`, a setting): its [`PRESET_KEY`] first, then every
/// other key ([`set_param`]).
pub fn apply_table(p: &mut Params, table: &toml::Table, file: &str) -> Result<(), InputError> {
    if let Some(v) = table.get(PRESET_KEY) {
        apply_preset(p, v, file)?;
    }
    for (k, v) in table.iter().filter(|(k, _)| k.as_str() != PRESET_KEY) {
        set_param(p, k, v, file)?;
    }
    Ok(())
}

/// Applies the preset a table's [`PRESET_KEY`] names.
pub fn apply_preset(p: &mut Params, value: &toml::Value, file: &str) -> Result<(), InputError> {
    use forestlod_shared::presets::{preset, preset_names};
    let found = value.as_str().and_then(preset).ok_or_else(|| {
        InputError::new(
            file,
            PRESET_KEY,
            value_label(value),
            format!(
                "unknown preset; expected one of {}",
                preset_names().join(", ")
            ),
        )
    })?;
    found.apply(p).map_err(InputError::from)
}

pub(super) fn value_label(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

pub(super) fn value_number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Integer(i) => Some(*i as f64),
        toml::Value::Float(f) => Some(*f),
        _ => None,
    }
}

/// One parameter set of a sweep.
#[derive(Clone, Debug)]
pub struct ParamSet {
    /// Label: the setting's label and the axis values, e.g. `default grid_size=500`.
    pub label: String,
    /// The label without the x-axis parameter (the plots' series).
    pub series: String,
    /// The x-axis parameter's value, if the x axis is a numeric parameter.
    pub x: Option<f64>,
    /// The parameters, validated.
    pub params: Params,
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
}

/// One camera pose.
#[derive(Clone, Debug)]
pub struct Pose {
    /// Camera name.
    pub camera: String,
    /// Yaw, degrees.
    pub yaw_deg: f32,
    /// Distance of the distance path (0 otherwise).
    pub distance_m: f32,
    /// Whether this pose's images are saved (the first pose of each camera entry).
    pub save_images: bool,
    /// For a camera path: where along it, in `[0, 1]` ([`super::paths::path_fraction`]).
    pub path_t: f32,
    /// For a camera path: the frame's index along it (0 otherwise). A path's frames are
    /// consecutive poses, so the pose before one with `path_step > 0` is the path's previous
    /// frame: what the temporal error compares with (`crate::temporal`).
    pub path_step: u32,
}

impl Pose {
    /// Whether the pose before this one is the previous frame of the same camera path (the
    /// temporal error's predecessor; none for a path's first frame and for other cameras).
    pub fn follows_previous(&self) -> bool {
        super::paths::is_path(&self.camera) && self.path_step > 0
    }
}

/// The canonical name of parameter key `k` (any spelling the parameter table answers to).
pub(crate) fn canonical(k: &str) -> Option<&'static str> {
    forestlod_shared::param(k).map(|s| s.name)
}

/// Whether two keys name the same parameter.
pub(crate) fn same_param(a: &str, b: &str) -> bool {
    a == b || canonical(a).is_some_and(|c| Some(c) == canonical(b))
}

impl SweepSpec {
    /// Checks every setting, the sweep's size against the work and memory limits and every
    /// parameter set ([`super::load`]'s checks), naming `file` and the key (no line: for a sweep
    /// changed by `--quick` or the command line, or read back from a manifest).
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        self.check().map_err(|b| b.without_text(file))
    }

    /// The variants, typed: an error naming `variants` and the bad name (or `[]`) otherwise.
    pub fn variant_list(&self, file: &str) -> Result<Vec<Pipeline>, InputError> {
        typed(&self.variants, file, "variants")
    }

    /// The backends, typed: an error naming `backends` and the bad name (or `[]`) otherwise.
    pub fn backend_list(&self, file: &str) -> Result<Vec<Engine>, InputError> {
        typed(&self.backends, file, "backends")
    }

    /// Applies the `[quick]` table.
    pub fn quick(mut self) -> Self {
        let Some(q) = self.quick.clone() else {
            return self;
        };
        if let Some(s) = q.scenes {
            self.scenes = s;
        }
        self.width = q.width.unwrap_or(self.width);
        self.height = q.height.unwrap_or(self.height);
        if q.width.is_some() || q.height.is_some() {
            self.resolutions.clear();
        }
        if let Some(r) = q.resolutions {
            self.resolutions = r;
        }
        if q.truth_tiles.is_some() {
            self.truth_tiles = q.truth_tiles;
        }
        self.samples = q.samples.unwrap_or(self.samples);
        for c in &mut self.cameras {
            if c.name == "distance" {
                if let Some(d) = &q.distances {
                    c.distances = Some(d.clone());
                }
            } else if super::paths::is_path(&c.name) {
                if q.path_steps.is_some() {
                    c.steps = q.path_steps;
                }
            } else if q.yaw_steps.is_some() {
                c.yaw_steps = q.yaw_steps;
            }
        }
        // A `[quick]` axis or parameter replaces the file's by any spelling of its name.
        if let Some(axes) = q.axes {
            for a in &mut self.axes {
                if let Some((_, v)) = axes.iter().find(|(k, _)| same_param(k, &a.param)) {
                    a.values = v.clone();
                }
            }
        }
        if let Some(p) = q.params {
            for (k, v) in p {
                self.params.retain(|old, _| !same_param(old, &k));
                self.params.insert(k, v);
            }
        }
        if let Some(b) = q.backends {
            self.backends = b;
        }
        self
    }

    /// The frame sizes: `resolutions`, or `width` x `height`.
    pub fn sizes(&self) -> Vec<[u32; 2]> {
        if self.resolutions.is_empty() {
            vec![[self.width, self.height]]
        } else {
            self.resolutions.clone()
        }
    }

    /// Every parameter set: settings (or one "default") times the axes' Cartesian product, times
    /// the frame sizes ([`SweepSpec::sizes`]; labelled `WxH` when there is more than one).
    pub fn param_sets(&self, file: &str) -> Result<Vec<ParamSet>, InputError> {
        let sizes = self.sizes();
        let mut out = Vec::new();
        for set in self.param_sets_one_size(file)? {
            for &[width, height] in &sizes {
                let mut s = set.clone();
                if sizes.len() > 1 {
                    let size = format!("{width}x{height}");
                    s.label = format!("{} {size}", s.label);
                    s.series = [s.series.as_str(), size.as_str()]
                        .into_iter()
                        .filter(|p| !p.is_empty())
                        .collect::<Vec<_>>()
                        .join(" ");
                }
                (s.width, s.height) = (width, height);
                out.push(s);
            }
        }
        Ok(out)
    }

    fn param_sets_one_size(&self, file: &str) -> Result<Vec<ParamSet>, InputError> {
        let mut base = Params::default();
        apply_table(&mut base, &self.params, file)?;
        let settings: Vec<SettingSpec> = if self.settings.is_empty() {
            vec![SettingSpec {
                label: "default".into(),
                params: toml::Table::new(),
            }]
        } else {
            self.settings.clone()
        };
        // Cartesian product of the axes, as lists of (param, value).
        let mut points: Vec<Vec<(String, toml::Value)>> = vec![Vec::new()];
        for axis in &self.axes {
            if axis.values.is_empty() {
                return Err(InputError::new(
                    file,
                    format!("axes.{}", axis.param),
                    "[]",
                    "expected at least one value",
                ));
            }
            points = points
                .into_iter()
                .flat_map(|p| {
                    axis.values.iter().map(move |v| {
                        let mut q = p.clone();
                        q.push((axis.param.clone(), v.clone()));
                        q
                    })
                })
                .collect();
        }
        let mut out = Vec::new();
        for s in &settings {
            for point in &points {
                let mut params = base;
                apply_table(&mut params, &s.params, file)?;
                let mut label = vec![s.label.clone()];
                let mut series = if settings.len() > 1 {
                    vec![s.label.clone()]
                } else {
                    vec![]
                };
                let mut x = None;
                for (k, v) in point {
                    set_param(&mut params, k, v, file)?;
                    label.push(format!("{k}={}", value_label(v)));
                    if same_param(k, &self.x_axis) {
                        x = value_number(v);
                    } else {
                        series.push(format!("{k}={}", value_label(v)));
                    }
                }
                params.validate().map_err(|e| {
                    InputError::new(
                        file,
                        format!("setting {:?}, field {}", label.join(" "), e.field),
                        e.value,
                        e.reason,
                    )
                })?;
                out.push(ParamSet {
                    label: label.join(" "),
                    series: series.join(" "),
                    x,
                    params,
                    width: self.width,
                    height: self.height,
                });
            }
        }
        Ok(out)
    }

    /// Every camera pose.
    pub fn poses(&self) -> Vec<Pose> {
        let mut out = Vec::new();
        for c in &self.cameras {
            if c.name == "distance" {
                for (i, &d) in c.distances.iter().flatten().enumerate() {
                    out.push(Pose {
                        camera: "distance".into(),
                        yaw_deg: 0.0,
                        distance_m: d,
                        save_images: i == 0,
                        path_t: 0.0,
                        path_step: 0,
                    });
                }
            } else if super::paths::is_path(&c.name) {
                let steps = c.steps.unwrap_or(super::paths::DEFAULT_PATH_STEPS);
                for i in 0..steps {
                    out.push(Pose {
                        camera: c.name.clone(),
                        yaw_deg: 0.0,
                        distance_m: 0.0,
                        save_images: i == 0,
                        path_t: super::paths::path_fraction(&c.name, i, steps),
                        path_step: i,
                    });
                }
            } else {
                // `validate` rejects `yaw_steps = 0`.
                let steps = c.yaw_steps.unwrap_or(1);
                for i in 0..steps {
                    out.push(Pose {
                        camera: c.name.clone(),
                        yaw_deg: 360.0 * i as f32 / steps as f32,
                        distance_m: 0.0,
                        save_images: i == 0,
                        path_t: 0.0,
                        path_step: 0,
                    });
                }
            }
        }
        out
    }
}

/// Height of the distance path's eye above the ground at distance 0, metres.
pub const DISTANCE_PATH_BASE_HEIGHT_M: f32 = 150.0;
/// Climb of the distance path's eye per metre of distance.
pub const DISTANCE_PATH_CLIMB: f32 = 0.05;
/// How far beyond the footprint's centre the distance path looks, metres.
pub const DISTANCE_PATH_LOOK_AHEAD_M: f32 = 500.0;

/// The camera of the distance path (E§5.0.2: "moving the camera away until all trees are beyond
/// the draw distance"): west of the footprint's centre by `distance`, at
/// [`DISTANCE_PATH_BASE_HEIGHT_M`]` + `[`DISTANCE_PATH_CLIMB`]`·distance` above the ground,
/// looking at the ground [`DISTANCE_PATH_LOOK_AHEAD_M`] east of the centre. The thesis also
/// returns the camera; the way back repeats the same poses, so it is not rendered twice.
pub fn distance_camera(scene: &Scene, distance: f32, width: u32, height: u32) -> Camera {
    let [x0, y0, x1, y1] = scene.bounds;
    let (cx, cy) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
    let ex = cx - distance;
    let eye = [
        ex,
        cy,
        scene.terrain.height(ex, cy) + DISTANCE_PATH_BASE_HEIGHT_M + DISTANCE_PATH_CLIMB * distance,
    ];
    let tx = cx + DISTANCE_PATH_LOOK_AHEAD_M;
    let target = [tx, cy, scene.terrain.height(tx, cy)];
    Camera::look_at(
        eye,
        target,
        forestlod_reference::cameras::NAMED_FOV_Y_DEGREES,
        width,
        height,
    )
}
