//! `forestlod sweep`: measure the speed–accuracy trade (SPEC §1, §10; E§5).
//!
//! A sweep is a small TOML file (format in `experiments/sweeps/README.md`): scenes, cameras (named
//! 360° sweeps or a distance path), which parameters take which values, and which variants run
//! (`ours`, `vegetation`, `primitive`: SPEC §9, [`forestlod_reference::baselines`]). For every
//! frame it records cost (select / draw / frame seconds, work counters, memory, and how many trees
//! batching drew finer or coarser than per-tree selection would: SPEC §6) and accuracy against the ray-traced ground truth
//! ([`forestlod_reference::ground_truth`], [`crate::metrics`]), writes one CSV row per frame, and
//! plots cost against accuracy plus thesis-style runtime plots (E Fig. 5.1–5.7) as PNGs.
//!
//! Built-in sweeps are the files under `experiments/sweeps/`, embedded in the binary
//! ([`BUILTIN_SWEEPS`]). `--quick` applies each file's `[quick]` table (small scene, small images,
//! few steps): `forestlod sweep --quick --out DIR` runs all of them, the CI smoke test of the whole
//! experiment machinery.
//!
//! Every variant runs on the backends the file names (`backends = ["reference", "gpu"]`, or
//! `--backend`): the reference (CPU) rasterizer, or the wgpu twin through
//! [`forestlod_harness::backend::GpuSweepScene`] (GPU selection or per-tree culling, the GPU-baked
//! textures, `draw.wgsl` / `primitive.wgsl`). Timings are wall-clock seconds, the minimum over
//! `repeats` renders of a frame: CPU time on the reference, submit-to-completion on the GPU (plus
//! timestamp-query times where the adapter has them). Ratios are only meaningful between rows of
//! one backend. Ground-truth images are rendered once per scene and camera pose and shared by
//! every variant, backend and parameter set.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use forestlod_gpu::{Compaction, GpuContext, GpuError};
use forestlod_harness::backend::{GpuSweepScene, GpuVariant};
use forestlod_reference::InputError;
use forestlod_reference::baselines::{
    INSTANCE_INDEX_BYTES, PROXY_BYTES, Proxy, proxies, render_primitive, render_vegetation,
    tree_spheres, trees_drawn_by_selection,
};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::ground_truth::{GroundTruthImage, GroundTruthScene};
use forestlod_reference::output::{lod_id_image, write_png};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::{Scene, builtin, load};
use forestlod_reference::select::{BatchingCounts, batching_counts};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{
    AngleIndexMode, Camera, CommandData, DrawCommand, FadeMode, MipMode, Params, TreeCull,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};

use crate::metrics::{Accuracy, accuracy, error_image, per_lod_error_maps};
use crate::plot::{Axes, Series, Style, bar_plot, xy_plot};

/// The built-in sweeps: `(name, TOML)`, in the order `--quick` runs them.
pub const BUILTIN_SWEEPS: [(&str, &str); 11] = [
    ("camera360", include_str!("../sweeps/camera360.toml")),
    ("distance", include_str!("../sweeps/distance.toml")),
    ("grid_size", include_str!("../sweeps/grid_size.toml")),
    (
        "angles_texture",
        include_str!("../sweeps/angles_texture.toml"),
    ),
    ("lod_settings", include_str!("../sweeps/lod_settings.toml")),
    ("fade_mode", include_str!("../sweeps/fade_mode.toml")),
    ("mip_mode", include_str!("../sweeps/mip_mode.toml")),
    ("angle_index", include_str!("../sweeps/angle_index.toml")),
    ("compaction", include_str!("../sweeps/compaction.toml")),
    ("grid_stress", include_str!("../sweeps/grid_stress.toml")),
    ("tree_cull", include_str!("../sweeps/tree_cull.toml")),
];

/// Variant names accepted in `variants`: ours (stable compaction on the GPU), ours with the
/// thesis's atomic-counter compaction (E§4.3; GPU backend only: the reference has one, stable,
/// compaction, equal to the atomic one as a multiset), and the two baselines of E§5.
pub const VARIANTS: [&str; 4] = ["ours", "ours-atomic", "vegetation", "primitive"];

/// Backend names accepted in `backends`: the CPU reference and the wgpu twin (`gpu/`).
pub const BACKENDS: [&str; 2] = ["reference", "gpu"];

/// Options of `forestlod sweep`.
#[derive(Args, Clone, Debug)]
pub struct SweepArgs {
    /// A sweep TOML file or a built-in sweep name; all built-in sweeps when omitted.
    pub file: Option<String>,
    /// Output folder: one sub-folder per sweep.
    #[arg(long)]
    pub out: PathBuf,
    /// Apply each sweep's `[quick]` table: small scene, small images, few steps.
    #[arg(long)]
    pub quick: bool,
    /// Replace the sweep's scene list with this one scene (built-in name or scene file).
    #[arg(long)]
    pub scene: Option<String>,
    /// Replace the image width.
    #[arg(long)]
    pub width: Option<u32>,
    /// Replace the image height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Replace the yaw steps of every 360° camera.
    #[arg(long)]
    pub yaw_steps: Option<u32>,
    /// Replace the number of timed renders per frame (the minimum is kept).
    #[arg(long)]
    pub repeats: Option<u32>,
    /// Replace the backends: `reference`, `gpu`, or both comma-separated (`reference,gpu`).
    #[arg(long)]
    pub backend: Option<String>,
}

/// One camera entry of a sweep file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// `far`, `medium`, `close` (E§5.0.1, [`forestlod_reference::cameras`]) or `distance`.
    pub name: String,
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
    /// Distances of the distance path.
    pub distances: Option<Vec<f32>>,
    /// Values per axis parameter.
    pub axes: Option<BTreeMap<String, Vec<toml::Value>>>,
    /// Base parameter overrides (applied after the file's `[params]`).
    pub params: Option<toml::Table>,
    /// Backends.
    pub backends: Option<Vec<String>>,
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
    /// Image width.
    #[serde(default = "default_width")]
    pub width: u32,
    /// Image height.
    #[serde(default = "default_height")]
    pub height: u32,
    /// Ground-truth samples per pixel side.
    #[serde(default = "default_samples")]
    pub samples: u32,
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
    /// Named settings (each combined with every axis point).
    #[serde(default)]
    pub settings: Vec<SettingSpec>,
    /// Quick-mode overrides.
    #[serde(default)]
    pub quick: Option<QuickSpec>,
}

fn default_variants() -> Vec<String> {
    vec!["ours".into()]
}
fn default_backends() -> Vec<String> {
    vec!["reference".into()]
}
fn default_width() -> u32 {
    320
}
fn default_height() -> u32 {
    180
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

/// One CSV row: one frame of one variant.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// Sweep name.
    pub sweep: String,
    /// Scene name.
    pub scene: String,
    /// Camera name.
    pub camera: String,
    /// Yaw, degrees.
    pub yaw_deg: f32,
    /// Distance of the distance path, metres (0 for named cameras).
    pub distance_m: f32,
    /// `ours`, `ours-atomic`, `vegetation` or `primitive`.
    pub variant: String,
    /// `reference` or `gpu`.
    pub backend: String,
    /// Parameter-set label (setting plus axis values).
    pub setting: String,
    /// Parameters.
    pub grid_size: f32,
    /// K.
    pub angle_count: u32,
    /// r.
    pub texture_size: u32,
    /// l.
    pub lod_levels: u32,
    /// Transition distance.
    pub lod1_transition: f32,
    /// Fade band width.
    pub fade_width: f32,
    /// Draw distance.
    pub draw_distance: f32,
    /// Fade mode name.
    pub fade_mode: String,
    /// Mip mode name.
    pub mip_mode: String,
    /// Angle index mode name.
    pub angle_index: String,
    /// Per-tree culling after selection (`none`, `lod0`, `all`).
    #[serde(default)]
    pub tree_cull: String,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Selection (ours) or per-tree culling (baselines), wall seconds (GPU: submit to completion).
    pub select_s: f64,
    /// Draw, ground included, wall seconds (GPU: submit to completion, readback excluded).
    pub draw_s: f64,
    /// `select_s + draw_s`.
    pub frame_s: f64,
    /// GPU backend: selection / culling time from timestamp queries, seconds, where offered.
    pub gpu_select_s: Option<f64>,
    /// GPU backend: draw pass time from timestamp queries, seconds, where offered.
    pub gpu_draw_s: Option<f64>,
    /// Batches tested (ours) or trees tested (baselines).
    pub batches_tested: u64,
    /// Draw commands.
    pub commands: u64,
    /// Trees drawn.
    pub trees_drawn: u64,
    /// Ours: trees given the full mesh although per-tree selection would not (SPEC §6,
    /// [`forestlod_reference::select::BatchingCounts`]); baselines: 0 (they select per tree).
    pub trees_finer: u64,
    /// Ours: trees given a billboard although per-tree selection would not; baselines: 0.
    pub trees_coarser: u64,
    /// Ours: trees drawn although per-tree culling would drop them; baselines: 0.
    pub trees_outside_view: u64,
    /// Ours: trees missing a LOD per-tree selection gives them (conservative selection: 0).
    pub trees_missing_lod: u64,
    /// Tree triangles submitted (reference backend; the GPU has no such counter here).
    pub triangles: Option<u64>,
    /// Tree fragments shaded (reference backend).
    pub fragments: Option<u64>,
    /// Tree fragments written (reference backend).
    pub fragments_written: Option<u64>,
    /// `fragments_written / pixels` (reference backend).
    pub overdraw: Option<f64>,
    /// Bytes the method adds to the scene data (ours: E Eq. 4.1's terms as allocated).
    pub memory_bytes: u64,
    /// FLIP mean against the ground truth.
    pub flip_mean: f64,
    /// FLIP 95th percentile.
    pub flip_p95: f64,
    /// FLIP 99th percentile.
    pub flip_p99: f64,
    /// Tree / not-tree disagreement with the ground truth, fraction of pixels.
    pub coverage_error: f64,
    /// Tree pixels in the ground truth, fraction.
    pub gt_tree_fraction: f64,
    /// Tree pixels in the frame, fraction.
    pub tree_fraction: f64,
}

/// Images saved for one frame (paths relative to the sweep folder).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FrameImages {
    /// Camera.
    pub camera: String,
    /// Yaw, degrees.
    pub yaw_deg: f32,
    /// Distance, metres.
    pub distance_m: f32,
    /// Variant.
    pub variant: String,
    /// Backend.
    #[serde(default)]
    pub backend: String,
    /// Parameter-set label.
    pub setting: String,
    /// The frame's colour.
    pub color: String,
    /// The frame's LOD-id view.
    pub lod: String,
    /// The FLIP error map.
    pub flip: String,
    /// Per-LOD FLIP maps: `(label, path, mean FLIP, pixels)`.
    pub per_lod: Vec<(String, String, f64, u64)>,
    /// The ground truth.
    pub ground_truth: String,
    /// The ground truth's classes.
    pub ground_truth_class: String,
    /// Accuracy figures of the frame.
    pub accuracy: Accuracy,
}

/// What a sweep wrote: `sweep.json` in its folder, read by `forestlod report`.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Manifest {
    /// Sweep name.
    pub name: String,
    /// Title.
    pub title: String,
    /// Description.
    pub description: String,
    /// Quick mode.
    pub quick: bool,
    /// The runtime plots' x axis.
    pub x_axis: String,
    /// Scenes.
    pub scenes: Vec<String>,
    /// Variants.
    pub variants: Vec<String>,
    /// Backends.
    #[serde(default)]
    pub backends: Vec<String>,
    /// The GPU adapter, when the GPU backend ran.
    #[serde(default)]
    pub gpu_adapter: Option<String>,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Ground-truth samples per pixel.
    pub ground_truth_spp: u32,
    /// Frames rendered.
    pub frames: usize,
    /// The CSV (relative path).
    pub csv: String,
    /// Plots (relative paths) with captions.
    pub plots: Vec<(String, String)>,
    /// Saved frame images.
    pub images: Vec<FrameImages>,
    /// Wall time of the whole sweep, seconds.
    pub wall_seconds: f64,
    /// Ground-truth BVH triangles and build seconds per scene.
    pub ground_truth_bvh: Vec<(String, usize, f64)>,
    /// Ground-truth rays traced.
    pub ground_truth_rays: u64,
    /// The sweep as it ran (quick mode and command-line overrides applied), so that
    /// `forestlod report --replot` can redraw the plots from the CSV.
    #[serde(default)]
    pub spec: Option<SweepSpec>,
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

fn value_label(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

fn value_number(v: &toml::Value) -> Option<f64> {
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
}

impl SweepSpec {
    /// Parses and validates a sweep file's text.
    pub fn parse(text: &str, file: &str) -> Result<Self, InputError> {
        let spec: SweepSpec =
            toml::from_str(text).map_err(|e| InputError::new(file, "TOML", "", e.to_string()))?;
        spec.validate(file)?;
        Ok(spec)
    }

    fn validate(&self, file: &str) -> Result<(), InputError> {
        if self.scenes.is_empty() {
            return Err(InputError::new(
                file,
                "scenes",
                "[]",
                "expected at least one scene",
            ));
        }
        if self.cameras.is_empty() {
            return Err(InputError::new(
                file,
                "cameras",
                "[]",
                "expected at least one camera",
            ));
        }
        // Non-empty lists of known names.
        for (field, list, known) in [
            ("variants", &self.variants, &VARIANTS[..]),
            ("backends", &self.backends, &BACKENDS[..]),
        ] {
            let expected = format!("expected one of {}", known.join(", "));
            if list.is_empty() {
                return Err(InputError::new(file, field, "[]", expected));
            }
            if let Some(bad) = list.iter().find(|v| !known.contains(&v.as_str())) {
                return Err(InputError::new(file, field, bad, expected));
            }
        }
        if self.variants.iter().any(|v| v == "ours-atomic")
            && self.backends.iter().any(|b| b == "reference")
        {
            return Err(InputError::new(
                file,
                "variants",
                "ours-atomic",
                "the atomic-counter compaction exists on the gpu backend only (the reference's stable compaction equals it as a multiset); use backends = [\"gpu\"]",
            ));
        }
        for c in &self.cameras {
            if c.yaw_steps == Some(0) {
                return Err(InputError::new(
                    file,
                    "cameras.yaw_steps",
                    0,
                    "expected at least 1 yaw step",
                ));
            }
            if c.name == "distance" {
                if c.distances.as_ref().is_none_or(|d| d.is_empty()) {
                    return Err(InputError::new(
                        file,
                        "cameras.distances",
                        "",
                        "a distance camera needs a non-empty `distances` list",
                    ));
                }
            } else if !forestlod_reference::cameras::CAMERA_NAMES.contains(&c.name.as_str()) {
                return Err(InputError::new(
                    file,
                    "cameras.name",
                    &c.name,
                    "expected far, medium, close or distance",
                ));
            }
        }
        if self.width == 0 || self.height == 0 || self.samples == 0 || self.repeats == 0 {
            return Err(InputError::new(
                file,
                "width/height/samples/repeats",
                format!(
                    "{} {} {} {}",
                    self.width, self.height, self.samples, self.repeats
                ),
                "expected positive values",
            ));
        }
        self.param_sets(file)?;
        Ok(())
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
        self.samples = q.samples.unwrap_or(self.samples);
        for c in &mut self.cameras {
            if c.name == "distance" {
                if let Some(d) = &q.distances {
                    c.distances = Some(d.clone());
                }
            } else if q.yaw_steps.is_some() {
                c.yaw_steps = q.yaw_steps;
            }
        }
        if let Some(axes) = q.axes {
            for a in &mut self.axes {
                if let Some(v) = axes.get(&a.param) {
                    a.values = v.clone();
                }
            }
        }
        if let Some(p) = q.params {
            self.params.extend(p);
        }
        if let Some(b) = q.backends {
            self.backends = b;
        }
        self
    }

    /// Every parameter set: settings (or one "default") times the axes' Cartesian product.
    pub fn param_sets(&self, file: &str) -> Result<Vec<ParamSet>, InputError> {
        let mut base = Params::default();
        for (k, v) in &self.params {
            set_param(&mut base, k, v, file)?;
        }
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
                for (k, v) in &s.params {
                    set_param(&mut params, k, v, file)?;
                }
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
                    if *k == self.x_axis {
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

fn load_scene(name: &str) -> Result<Scene, InputError> {
    let path = Path::new(name);
    if name.ends_with(".toml") || path.is_file() {
        load::load_scene_file(path)
    } else {
        builtin::by_name(name)
    }
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::new(path.display().to_string(), "write", "", e.to_string())
}

/// What one variant produced for one frame.
struct VariantFrame {
    color: Rgba8Image,
    aux: Vec<u32>,
    select_s: f64,
    draw_s: f64,
    gpu_select_s: Option<f64>,
    gpu_draw_s: Option<f64>,
    batches_tested: u64,
    commands: u64,
    trees_drawn: u64,
    batching: BatchingCounts,
    triangles: Option<u64>,
    fragments: Option<u64>,
    fragments_written: Option<u64>,
    memory_bytes: u64,
}

impl VariantFrame {
    /// Keeps the minimum of each time over repeats (the work and images are the same).
    fn keep_fastest(mut self, other: VariantFrame) -> Self {
        let min_opt = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self.select_s = self.select_s.min(other.select_s);
        self.draw_s = self.draw_s.min(other.draw_s);
        self.gpu_select_s = min_opt(self.gpu_select_s, other.gpu_select_s);
        self.gpu_draw_s = min_opt(self.gpu_draw_s, other.gpu_draw_s);
        self
    }
}

/// Per-scene state kept across sweeps of one run: the scene and its ground-truth BVH, the
/// ground-truth images already rendered, and the GPU context once a sweep asks for it.
#[derive(Default)]
pub struct Runner {
    scene: Option<(String, Scene, GroundTruthScene)>,
    images: HashMap<String, GroundTruthImage>,
    rays: u64,
    gpu: Option<&'static GpuContext>,
}

impl Runner {
    fn scene(
        &mut self,
        name: &str,
        alpha_cutoff: f32,
    ) -> Result<(&Scene, &GroundTruthScene), InputError> {
        let key = format!("{name}@{alpha_cutoff}");
        if self.scene.as_ref().is_none_or(|(k, ..)| *k != key) {
            self.scene = None; // free the previous BVH first
            let scene = load_scene(name)?;
            let gt = GroundTruthScene::build(&scene, alpha_cutoff)?;
            self.scene = Some((key, scene, gt));
        }
        let (_, s, g) = self.scene.as_ref().expect("just set");
        Ok((s, g))
    }

    /// The GPU context, created on first use (an error with the install hint when there is no
    /// adapter: the GPU backend was asked for, so it is not skipped).
    fn gpu(&mut self) -> Result<&'static GpuContext, GpuError> {
        if let Some(ctx) = self.gpu {
            return Ok(ctx);
        }
        let ctx: &'static GpuContext = Box::leak(Box::new(GpuContext::new()?));
        self.gpu = Some(ctx);
        Ok(ctx)
    }

    /// Runs one sweep into `out/<name>/`.
    pub fn run_sweep(
        &mut self,
        spec: &SweepSpec,
        quick: bool,
        out: &Path,
    ) -> Result<Manifest, Box<dyn std::error::Error>> {
        let start = Instant::now();
        let file = format!("<sweep {}>", spec.name);
        let sets = spec.param_sets(&file)?;
        let poses = spec.poses();
        let dir = out.join(&spec.name);
        let img_dir = dir.join("img");
        std::fs::create_dir_all(&img_dir).map_err(|e| io_err(&img_dir, e))?;
        let use_gpu = spec.backends.iter().any(|b| b == "gpu");
        let gpu_ctx = if use_gpu { Some(self.gpu()?) } else { None };
        let frames = spec.scenes.len()
            * sets.len()
            * poses.len()
            * spec.variants.len()
            * spec.backends.len();
        let bar = ProgressBar::new(frames as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{msg:>16} [{bar:30}] {pos}/{len} frames [{elapsed} / ~{duration}]",
            )
            .expect("static template")
            .progress_chars("=> "),
        );
        bar.set_message(spec.name.clone());
        let alpha_cutoff = sets.first().map(|s| s.params.alpha_cutoff).unwrap_or(0.5);
        let mut rows = Vec::new();
        let mut images = Vec::new();
        let mut bvh_info = Vec::new();
        let rays_before = self.rays;
        for scene_name in &spec.scenes {
            self.scene(scene_name, alpha_cutoff)?;
            let (_, scene, gt_scene) = self.scene.as_ref().expect("loaded");
            bvh_info.push((
                scene.name.clone(),
                gt_scene.triangle_count(),
                gt_scene.build_seconds(),
            ));
            for set in &sets {
                let prepared = prepare(scene.clone(), &set.params)?;
                let spheres = tree_spheres(&prepared.scene, &prepared.geometry.meshes);
                let baselines = spec
                    .variants
                    .iter()
                    .any(|v| v == "vegetation" || v == "primitive");
                let proxy_list: Vec<Proxy> = if baselines {
                    proxies(&prepared, set.params.alpha_cutoff)
                } else {
                    Vec::new()
                };
                // The GPU side of this parameter set: buffers uploaded and textures baked once.
                let mut gpu_scene = match gpu_ctx {
                    Some(ctx) => Some(GpuSweepScene::new(ctx, &prepared, &set.params)?),
                    None => None,
                };
                let mut gpu_warm = false;
                for pose in &poses {
                    let camera = if pose.camera == "distance" {
                        distance_camera(scene, pose.distance_m, spec.width, spec.height)
                    } else {
                        named_camera(&pose.camera, scene, pose.yaw_deg, spec.width, spec.height)?
                    };
                    camera.validate().map_err(InputError::from)?;
                    let key = format!(
                        "{}|{}|{}|{}|{}x{}|{}",
                        scene.name,
                        pose.camera,
                        pose.yaw_deg,
                        pose.distance_m,
                        spec.width,
                        spec.height,
                        spec.samples
                    );
                    if !self.images.contains_key(&key) {
                        let img = gt_scene.render(&camera, spec.samples);
                        self.rays += img.rays;
                        self.images.insert(key.clone(), img);
                    }
                    let gt = &self.images[&key];
                    for backend in &spec.backends {
                        for variant in &spec.variants {
                            let frame = Frame {
                                prepared: &prepared,
                                spheres: &spheres,
                                proxies: &proxy_list,
                                camera: &camera,
                                params: &set.params,
                            };
                            let vf = if backend == "gpu" {
                                let gs = gpu_scene.as_mut().expect("created when use_gpu");
                                if !gpu_warm {
                                    // First frame of a parameter set: pipelines, bind groups and
                                    // lavapipe's shader JIT warm up outside the timed renders.
                                    render_gpu_variant(gs, variant, &frame, 1)?;
                                    gpu_warm = true;
                                }
                                render_gpu_variant(gs, variant, &frame, spec.repeats)?
                            } else {
                                render_variant(variant, &frame, spec.repeats)?
                            };
                            let (acc, map) = accuracy(gt, &vf.color, &vf.aux);
                            let pixels = (spec.width as u64 * spec.height as u64).max(1);
                            let p = &set.params;
                            rows.push(Row {
                                sweep: spec.name.clone(),
                                scene: scene.name.clone(),
                                camera: pose.camera.clone(),
                                yaw_deg: pose.yaw_deg,
                                distance_m: pose.distance_m,
                                variant: variant.clone(),
                                backend: backend.clone(),
                                setting: set.label.clone(),
                                grid_size: p.grid_size,
                                angle_count: p.angle_count,
                                texture_size: p.texture_size,
                                lod_levels: p.lod_levels,
                                lod1_transition: p.lod1_transition,
                                fade_width: p.fade_width,
                                draw_distance: p.draw_distance,
                                fade_mode: p.fade().map(FadeMode::name).unwrap_or("?").into(),
                                mip_mode: p.mips().map(MipMode::name).unwrap_or("?").into(),
                                angle_index: p
                                    .angle_mode()
                                    .map(AngleIndexMode::name)
                                    .unwrap_or("?")
                                    .into(),
                                tree_cull: p
                                    .tree_culling()
                                    .map(TreeCull::name)
                                    .unwrap_or("?")
                                    .into(),
                                width: spec.width,
                                height: spec.height,
                                select_s: vf.select_s,
                                draw_s: vf.draw_s,
                                frame_s: vf.select_s + vf.draw_s,
                                gpu_select_s: vf.gpu_select_s,
                                gpu_draw_s: vf.gpu_draw_s,
                                batches_tested: vf.batches_tested,
                                commands: vf.commands,
                                trees_drawn: vf.trees_drawn,
                                trees_finer: vf.batching.trees_finer,
                                trees_coarser: vf.batching.trees_coarser,
                                trees_outside_view: vf.batching.trees_outside_view,
                                trees_missing_lod: vf.batching.trees_missing_lod,
                                triangles: vf.triangles,
                                fragments: vf.fragments,
                                fragments_written: vf.fragments_written,
                                overdraw: vf.fragments_written.map(|f| f as f64 / pixels as f64),
                                memory_bytes: vf.memory_bytes,
                                flip_mean: acc.flip_mean,
                                flip_p95: acc.flip_p95,
                                flip_p99: acc.flip_p99,
                                coverage_error: acc.coverage_error,
                                gt_tree_fraction: acc.gt_tree_fraction,
                                tree_fraction: acc.tree_fraction,
                            });
                            if pose.save_images {
                                images.push(save_frame_images(
                                    &dir,
                                    scene,
                                    pose,
                                    (variant, backend),
                                    set,
                                    gt,
                                    (&vf.color, &vf.aux),
                                    &map,
                                    acc,
                                )?);
                            }
                            bar.inc(1);
                        }
                    }
                }
            }
        }
        bar.finish();
        let csv_name = format!("{}.csv", spec.name);
        let csv_path = dir.join(&csv_name);
        let mut w = csv::Writer::from_path(&csv_path).map_err(|e| io_err(&csv_path, e))?;
        for r in &rows {
            w.serialize(r).map_err(|e| io_err(&csv_path, e))?;
        }
        w.flush().map_err(|e| io_err(&csv_path, e))?;
        let plots = write_plots(spec, &rows, &dir)?;
        let manifest = Manifest {
            name: spec.name.clone(),
            title: spec.title.clone(),
            description: spec.description.clone(),
            quick,
            x_axis: spec.x_axis.clone(),
            scenes: spec.scenes.clone(),
            variants: spec.variants.clone(),
            backends: spec.backends.clone(),
            gpu_adapter: gpu_ctx.map(GpuContext::describe),
            width: spec.width,
            height: spec.height,
            ground_truth_spp: spec.samples * spec.samples,
            frames: rows.len(),
            csv: csv_name,
            plots,
            images,
            wall_seconds: start.elapsed().as_secs_f64(),
            ground_truth_bvh: bvh_info,
            ground_truth_rays: self.rays - rays_before,
            spec: Some(spec.clone()),
        };
        let mpath = dir.join("sweep.json");
        std::fs::write(&mpath, serde_json::to_string_pretty(&manifest)?)
            .map_err(|e| io_err(&mpath, e))?;
        Ok(manifest)
    }
}

/// One frame's inputs, shared by every variant and backend.
struct Frame<'a> {
    prepared: &'a Prepared,
    spheres: &'a [([f32; 3], f32)],
    proxies: &'a [Proxy],
    camera: &'a Camera,
    params: &'a Params,
}

/// Bytes ours adds to the scene data: E Eq. 4.1's terms as allocated, plus the `refine` stage's
/// `3n`-entry indirection array when it runs (`reference/src/refine.rs`).
fn ours_memory(prepared: &Prepared, params: &Params) -> u64 {
    let refine = if params.tree_culling().is_ok_and(|m| m != TreeCull::None) {
        3 * prepared.batches.indirection.len() as u64 * 4
    } else {
        0
    };
    prepared.memory.total + refine
}

fn unknown_variant(variant: &str) -> InputError {
    InputError::new(
        "<sweep>",
        "variant",
        variant,
        format!("expected one of {}", VARIANTS.join(", ")),
    )
}

/// Renders one variant on the reference backend, `repeats` times, keeping the minimum select
/// and draw times.
fn render_variant(variant: &str, f: &Frame, repeats: u32) -> Result<VariantFrame, InputError> {
    let Frame {
        prepared,
        spheres,
        proxies: proxy_list,
        camera,
        params,
    } = *f;
    let mut best: Option<VariantFrame> = None;
    for _ in 0..repeats.max(1) {
        let vf = match variant {
            "ours" => {
                let frame = prepared.render(camera, params)?;
                let c = frame.selection.counters;
                let indirection = frame.indirection(prepared);
                let trees = trees_drawn_by_selection(
                    prepared,
                    &frame.selection,
                    indirection,
                    camera,
                    params,
                );
                let batching =
                    batching_counts(spheres, indirection, &frame.selection, camera, params);
                let s = frame.drawn.tree_stats;
                let target = frame.drawn.target;
                VariantFrame {
                    select_s: frame.timings.select + frame.timings.refine,
                    draw_s: frame.timings.draw,
                    gpu_select_s: None,
                    gpu_draw_s: None,
                    batches_tested: c.batches_tested as u64,
                    commands: c.commands as u64,
                    trees_drawn: trees.len() as u64,
                    batching,
                    triangles: Some(s.triangles_in),
                    fragments: Some(s.fragments_shaded),
                    fragments_written: Some(s.fragments_written),
                    memory_bytes: ours_memory(prepared, params),
                    color: target.color_image(),
                    aux: target.aux().to_vec(),
                }
            }
            "vegetation" | "primitive" => {
                let f = if variant == "vegetation" {
                    render_vegetation(prepared, spheres, camera, params)
                } else {
                    render_primitive(prepared, spheres, proxy_list, camera, params)
                };
                let s = f.tree_stats;
                VariantFrame {
                    select_s: f.timings.select,
                    draw_s: f.timings.draw,
                    gpu_select_s: None,
                    gpu_draw_s: None,
                    batches_tested: f.trees_tested,
                    commands: f.commands,
                    trees_drawn: f.visible.len() as u64,
                    batching: BatchingCounts::default(),
                    triangles: Some(s.triangles_in),
                    fragments: Some(s.fragments_shaded),
                    fragments_written: Some(s.fragments_written),
                    memory_bytes: f.memory_bytes,
                    color: f.target.color_image(),
                    aux: f.target.aux().to_vec(),
                }
            }
            other => return Err(unknown_variant(other)),
        };
        best = Some(match best {
            None => vf,
            Some(b) => b.keep_fastest(vf),
        });
    }
    Ok(best.expect("at least one repeat"))
}

/// Renders one variant on the GPU backend ([`GpuSweepScene`]), `repeats` times, keeping the
/// minimum times. Work counters the GPU does not report (trees drawn by ours, the batching
/// counts) come from the reference's selection of the same frame, which the parity tests prove
/// equal to the GPU's (`tests/tests/parity_select.rs`); triangles and fragments stay empty.
fn render_gpu_variant(
    gs: &mut GpuSweepScene,
    variant: &str,
    f: &Frame,
    repeats: u32,
) -> Result<VariantFrame, Box<dyn std::error::Error>> {
    let Frame {
        prepared,
        spheres,
        proxies: proxy_list,
        camera,
        params,
    } = *f;
    let gpu_variant = match variant {
        "ours" => GpuVariant::Ours(Compaction::Stable),
        "ours-atomic" => GpuVariant::Ours(Compaction::Atomic),
        "vegetation" => GpuVariant::Vegetation,
        "primitive" => GpuVariant::Primitive,
        other => return Err(unknown_variant(other).into()),
    };
    let mut best: Option<VariantFrame> = None;
    for _ in 0..repeats.max(1) {
        let g = gs.render(gpu_variant, camera, params)?;
        let (batches_tested, trees_drawn, batching, memory_bytes) = match gpu_variant {
            GpuVariant::Ours(_) => {
                let (selection, refined) = prepared.select_refined(camera, params);
                let indirection = refined
                    .as_ref()
                    .map_or(&prepared.batches.indirection[..], |r| &r.indirection[..]);
                let trees =
                    trees_drawn_by_selection(prepared, &selection, indirection, camera, params);
                let batching = batching_counts(spheres, indirection, &selection, camera, params);
                (
                    prepared.batches.metas.len() as u64,
                    trees.len() as u64,
                    batching,
                    ours_memory(prepared, params),
                )
            }
            GpuVariant::Vegetation | GpuVariant::Primitive => {
                let visible = g.trees_drawn.unwrap_or(0);
                // The reference baselines' accounting (reference/src/baselines.rs).
                let extra = if gpu_variant == GpuVariant::Vegetation {
                    g.commands * (size_of::<DrawCommand>() + size_of::<CommandData>()) as u64
                } else {
                    proxy_list.len() as u64 * PROXY_BYTES
                };
                (
                    spheres.len() as u64,
                    visible,
                    BatchingCounts::default(),
                    visible * INSTANCE_INDEX_BYTES + extra,
                )
            }
        };
        let vf = VariantFrame {
            color: Rgba8Image {
                width: g.images.width,
                height: g.images.height,
                texels: g.images.color,
            },
            aux: g.images.lod_id,
            select_s: g.select_s,
            draw_s: g.draw_s,
            gpu_select_s: g.gpu_select_s,
            gpu_draw_s: g.gpu_draw_s,
            batches_tested,
            commands: g.commands,
            trees_drawn,
            batching,
            triangles: None,
            fragments: None,
            fragments_written: None,
            memory_bytes,
        };
        best = Some(match best {
            None => vf,
            Some(b) => b.keep_fastest(vf),
        });
    }
    Ok(best.expect("at least one repeat"))
}

fn slug(s: &str) -> String {
    let mut out: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    while out.contains("__") {
        out = out.replace("__", "_");
    }
    out.trim_matches('_').to_string()
}

#[allow(clippy::too_many_arguments)]
fn save_frame_images(
    dir: &Path,
    scene: &Scene,
    pose: &Pose,
    (variant, backend): (&str, &str),
    set: &ParamSet,
    gt: &GroundTruthImage,
    (color, aux): (&Rgba8Image, &[u32]),
    map: &[f32],
    acc: Accuracy,
) -> Result<FrameImages, InputError> {
    let pose_slug = if pose.camera == "distance" {
        format!("{}_{}_d{}", scene.name, pose.camera, pose.distance_m)
    } else {
        format!("{}_{}_y{}", scene.name, pose.camera, pose.yaw_deg)
    };
    let stem = slug(&format!("{pose_slug}_{variant}_{backend}_{}", set.label));
    let (w, h) = (color.width, color.height);
    let rel = |name: String| format!("img/{name}");
    let gt_path = rel(format!("{}_gt.png", slug(&pose_slug)));
    let gt_class = rel(format!("{}_gt_class.png", slug(&pose_slug)));
    if !dir.join(&gt_path).is_file() {
        write_png(&dir.join(&gt_path), &gt.srgb)?;
        write_png(&dir.join(&gt_class), &gt.class_image())?;
    }
    let color_path = rel(format!("{stem}_color.png"));
    let lod = rel(format!("{stem}_lod.png"));
    let flip = rel(format!("{stem}_flip.png"));
    write_png(&dir.join(&color_path), color)?;
    write_png(&dir.join(&lod), &lod_id_image(w, h, aux))?;
    write_png(&dir.join(&flip), &error_image(map, w, h))?;
    let mut per_lod = Vec::new();
    if variant.starts_with("ours") {
        for m in per_lod_error_maps(map, aux, w, h) {
            if m.pixels == 0 {
                continue;
            }
            let p = rel(format!("{stem}_flip_{}.png", m.label));
            write_png(&dir.join(&p), &m.image)?;
            per_lod.push((m.label.to_string(), p, m.flip_mean, m.pixels));
        }
    }
    Ok(FrameImages {
        camera: pose.camera.clone(),
        yaw_deg: pose.yaw_deg,
        distance_m: pose.distance_m,
        variant: variant.into(),
        backend: backend.into(),
        setting: set.label.clone(),
        color: color_path,
        lod,
        flip,
        per_lod,
        ground_truth: gt_path,
        ground_truth_class: gt_class,
        accuracy: acc,
    })
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Series label of a row: the variant, plus the parameter set's series label when there is one.
fn series_of(row: &Row, sets: &HashMap<String, String>, variants: usize) -> String {
    let series = sets.get(&row.setting).cloned().unwrap_or_default();
    match (variants > 1, series.is_empty()) {
        (true, true) => row.variant.clone(),
        (true, false) => format!("{} {series}", row.variant),
        (false, true) => row.variant.clone(),
        (false, false) => series,
    }
}

/// Writes the sweep's plots; returns `(relative path, caption)` pairs.
pub fn write_plots(
    spec: &SweepSpec,
    rows: &[Row],
    dir: &Path,
) -> Result<Vec<(String, String)>, InputError> {
    let file = format!("<sweep {}>", spec.name);
    let sets = spec.param_sets(&file)?;
    let series_by_label: HashMap<String, String> = sets
        .iter()
        .map(|s| (s.label.clone(), s.series.clone()))
        .collect();
    let x_by_label: HashMap<String, Option<f64>> =
        sets.iter().map(|s| (s.label.clone(), s.x)).collect();
    // With several backends a series is a (variant, backend) pair: relabel the variant.
    let (rows, variants): (Vec<Row>, Vec<String>) = if spec.backends.len() > 1 {
        // Short backend names keep legends readable: `ours ref`, `vegetation gpu`.
        let label = |v: &str, b: &str| {
            let b = if b == "reference" { "ref" } else { b };
            format!("{v} {b}")
        };
        (
            rows.iter()
                .map(|r| Row {
                    variant: label(&r.variant, &r.backend),
                    ..r.clone()
                })
                .collect(),
            spec.backends
                .iter()
                .flat_map(|b| spec.variants.iter().map(move |v| label(v, b)))
                .collect(),
        )
    } else {
        (rows.to_vec(), spec.variants.clone())
    };
    let rows = &rows[..];
    let nv = variants.len();
    let backend_label = if spec.backends.len() > 1 {
        "reference CPU and GPU backends".to_string()
    } else if spec.backends.iter().any(|b| b == "gpu") {
        "GPU backend".to_string()
    } else {
        "reference CPU backend".to_string()
    };
    let mut out = Vec::new();
    let mut plot = |name: &str,
                    caption: String,
                    f: &dyn Fn(&Path) -> std::io::Result<()>|
     -> Result<(), InputError> {
        let path = dir.join(name);
        f(&path).map_err(|e| io_err(&path, e))?;
        out.push((name.to_string(), caption));
        Ok(())
    };
    // Group rows into series, keeping first-seen order.
    let group = |rows: &[&Row],
                 y: &dyn Fn(&Row) -> f64,
                 x: &dyn Fn(&Row) -> f64,
                 avg: bool|
     -> Vec<Series> {
        let mut order: Vec<String> = Vec::new();
        let mut pts: HashMap<String, Vec<(f64, f64)>> = HashMap::new();
        for r in rows {
            let s = series_of(r, &series_by_label, nv);
            if !pts.contains_key(&s) {
                order.push(s.clone());
            }
            pts.entry(s).or_default().push((x(r), y(r)));
        }
        order
            .into_iter()
            .map(|label| {
                let mut points = pts.remove(&label).unwrap_or_default();
                if avg {
                    let mut by_x: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
                    for (x, y) in &points {
                        by_x.entry(x.to_bits()).or_default().push(*y);
                    }
                    points = by_x
                        .into_iter()
                        .map(|(x, ys)| (f64::from_bits(x), mean(ys.into_iter())))
                        .collect();
                }
                Series { label, points }
            })
            .collect()
    };
    let all: Vec<&Row> = rows.iter().collect();
    // 1. Cost against accuracy, every frame.
    for (name, ylabel, y) in [
        (
            "cost_vs_flip.png",
            "FLIP mean vs ground truth",
            (|r: &Row| r.flip_mean) as fn(&Row) -> f64,
        ),
        (
            "cost_vs_coverage.png",
            "coverage error (fraction of pixels)",
            |r: &Row| r.coverage_error,
        ),
    ] {
        let series = group(&all, &y, &|r: &Row| r.frame_s, false);
        let axes = Axes {
            title: format!("{}: cost vs accuracy", spec.name),
            x_label: format!("frame time [s] ({backend_label}, log)"),
            y_label: ylabel.into(),
            log_x: true,
            log_y: false,
        };
        plot(
            name,
            format!("Every frame: frame time against {ylabel}, one colour per variant / setting."),
            &|p| xy_plot(p, &axes, &series, Style::Scatter),
        )?;
    }
    // 2. Thesis-style runtime plots.
    match spec.x_axis.as_str() {
        "yaw" => {
            let cameras: Vec<String> = {
                let mut c: Vec<String> = rows.iter().map(|r| r.camera.clone()).collect();
                c.dedup();
                let mut seen = Vec::new();
                for x in c {
                    if !seen.contains(&x) {
                        seen.push(x);
                    }
                }
                seen
            };
            for cam in &cameras {
                let rs: Vec<&Row> = rows.iter().filter(|r| &r.camera == cam).collect();
                let series = group(&rs, &|r| r.frame_s * 1e3, &|r| r.yaw_deg as f64, true);
                let axes = Axes {
                    title: format!("{}: {cam} benchmark runtime over 360 deg", spec.name),
                    x_label: "camera yaw [deg]".into(),
                    y_label: "frame time [ms]".into(),
                    log_x: false,
                    log_y: false,
                };
                plot(
                    &format!("runtime_{cam}.png"),
                    format!("Runtime over the 360° sweep of camera `{cam}` (E Fig. 5.1–5.3 b)."),
                    &|p| xy_plot(p, &axes, &series, Style::Lines),
                )?;
                // Mean time of each pass per variant (E Fig. 5.1c).
                let values: Vec<Vec<f64>> = variants
                    .iter()
                    .map(|v| {
                        let vr: Vec<&&Row> = rs.iter().filter(|r| &r.variant == v).collect();
                        vec![
                            mean(vr.iter().map(|r| r.select_s * 1e3)),
                            mean(vr.iter().map(|r| r.draw_s * 1e3)),
                        ]
                    })
                    .collect();
                let axes = Axes {
                    title: format!("{}: {cam} mean pass times", spec.name),
                    x_label: "variant".into(),
                    y_label: "mean time [ms]".into(),
                    log_x: false,
                    log_y: false,
                };
                plot(
                    &format!("passes_{cam}.png"),
                    format!(
                        "Mean time of each pass for camera `{cam}` (E Fig. 5.1–5.3 c): select = selection or per-tree culling, draw = rasterization."
                    ),
                    &|p| {
                        bar_plot(
                            p,
                            &axes,
                            &variants,
                            &["select".into(), "draw".into()],
                            &values,
                        )
                    },
                )?;
            }
        }
        "distance" => {
            for (name, ylabel, y, cap) in [
                (
                    "runtime_distance.png",
                    "frame time [ms]",
                    (|r: &Row| r.frame_s * 1e3) as fn(&Row) -> f64,
                    "Runtime along the distance path (E Fig. 5.4).",
                ),
                (
                    "accuracy_distance.png",
                    "FLIP mean",
                    |r: &Row| r.flip_mean,
                    "FLIP mean along the distance path.",
                ),
                (
                    "coverage_distance.png",
                    "coverage error",
                    |r: &Row| r.coverage_error,
                    "Coverage error along the distance path.",
                ),
            ] {
                let series = group(&all, &y, &|r| r.distance_m as f64, true);
                let axes = Axes {
                    title: format!("{}: {ylabel} vs distance", spec.name),
                    x_label: "camera distance from the forest centre [m]".into(),
                    y_label: ylabel.into(),
                    log_x: false,
                    log_y: false,
                };
                plot(name, cap.into(), &|p| {
                    xy_plot(p, &axes, &series, Style::Lines)
                })?;
            }
        }
        param => {
            let numeric = sets.iter().all(|s| s.x.is_some());
            if numeric {
                let x = |r: &Row| {
                    x_by_label
                        .get(&r.setting)
                        .copied()
                        .flatten()
                        .unwrap_or(f64::NAN)
                };
                let log_x = {
                    let xs: Vec<f64> = sets.iter().filter_map(|s| s.x).collect();
                    let (lo, hi) = xs
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
                    lo > 0.0 && hi / lo > 20.0
                };
                // Select and draw time, then the errors, against the parameter (E Fig. 5.5a / 5.6).
                type Metric = (&'static str, fn(&Row) -> f64);
                let times: [Metric; 3] = [
                    ("select", |r| r.select_s * 1e3),
                    ("draw", |r| r.draw_s * 1e3),
                    ("frame", |r| r.frame_s * 1e3),
                ];
                let errors: [Metric; 3] = [
                    ("FLIP mean", |r| r.flip_mean),
                    ("FLIP p95", |r| r.flip_p95),
                    ("coverage err", |r| r.coverage_error),
                ];
                for (file, title, y_label, caption, metrics) in [
                    (
                        "runtime.png",
                        "mean pass times",
                        "mean time [ms]",
                        format!(
                            "Mean select, draw and frame time against `{param}` (thesis-style, E Fig. 5.5–5.6)."
                        ),
                        times,
                    ),
                    (
                        "accuracy.png",
                        "accuracy",
                        "error vs ground truth",
                        format!("Mean FLIP, FLIP p95 and coverage error against `{param}`."),
                        errors,
                    ),
                ] {
                    let mut series = Vec::new();
                    for (what, y) in metrics {
                        for mut s in group(&all, &y, &x, true) {
                            s.label = format!("{what} {}", s.label);
                            series.push(s);
                        }
                    }
                    let axes = Axes {
                        title: format!("{}: {title} vs {param}", spec.name),
                        x_label: format!("{param}{}", if log_x { " (log)" } else { "" }),
                        y_label: y_label.into(),
                        log_x,
                        log_y: false,
                    };
                    plot(file, caption, &|p| xy_plot(p, &axes, &series, Style::Lines))?;
                }
            } else {
                // Categorical settings: grouped bars (E Fig. 5.7).
                let labels: Vec<String> = sets.iter().map(|s| s.label.clone()).collect();
                let passes: Vec<Vec<f64>> = labels
                    .iter()
                    .map(|l| {
                        let rs: Vec<&Row> = rows.iter().filter(|r| &r.setting == l).collect();
                        vec![
                            mean(rs.iter().map(|r| r.select_s * 1e3)),
                            mean(rs.iter().map(|r| r.draw_s * 1e3)),
                        ]
                    })
                    .collect();
                let axes = Axes {
                    title: format!("{}: mean pass times", spec.name),
                    x_label: "setting".into(),
                    y_label: "mean time [ms]".into(),
                    log_x: false,
                    log_y: false,
                };
                plot(
                    "runtime.png",
                    "Mean select and draw time per setting (thesis-style, E Fig. 5.7).".into(),
                    &|p| {
                        bar_plot(
                            p,
                            &axes,
                            &labels,
                            &["select".into(), "draw".into()],
                            &passes,
                        )
                    },
                )?;
                let acc: Vec<Vec<f64>> = labels
                    .iter()
                    .map(|l| {
                        let rs: Vec<&Row> = rows.iter().filter(|r| &r.setting == l).collect();
                        vec![
                            mean(rs.iter().map(|r| r.flip_mean)),
                            mean(rs.iter().map(|r| r.flip_p95)),
                            mean(rs.iter().map(|r| r.coverage_error)),
                        ]
                    })
                    .collect();
                let axes = Axes {
                    title: format!("{}: accuracy per setting", spec.name),
                    x_label: "setting".into(),
                    y_label: "error vs ground truth".into(),
                    log_x: false,
                    log_y: false,
                };
                plot(
                    "accuracy.png",
                    "Mean FLIP, FLIP p95 and coverage error per setting.".into(),
                    &|p| {
                        bar_plot(
                            p,
                            &axes,
                            &labels,
                            &["FLIP mean".into(), "FLIP p95".into(), "coverage err".into()],
                            &acc,
                        )
                    },
                )?;
            }
        }
    }
    Ok(out)
}

/// Resolves the sweeps `forestlod sweep` runs: a file, a built-in name, or every built-in.
pub fn resolve(file: Option<&str>) -> Result<Vec<SweepSpec>, InputError> {
    match file {
        None => BUILTIN_SWEEPS
            .iter()
            .map(|(name, text)| SweepSpec::parse(text, &format!("<built-in sweep {name}>")))
            .collect(),
        Some(f) => {
            if let Some((name, text)) = BUILTIN_SWEEPS.iter().find(|(n, _)| *n == f) {
                return Ok(vec![SweepSpec::parse(
                    text,
                    &format!("<built-in sweep {name}>"),
                )?]);
            }
            let text = std::fs::read_to_string(f).map_err(|e| {
                InputError::new(
                    f,
                    "read",
                    "",
                    format!(
                        "{e}; expected a sweep TOML file or a built-in sweep name ({})",
                        BUILTIN_SWEEPS.map(|(n, _)| n).join(", ")
                    ),
                )
            })?;
            Ok(vec![SweepSpec::parse(&text, f)?])
        }
    }
}

/// Variants that run on the GPU backend only.
pub const GPU_ONLY_VARIANTS: [&str; 1] = ["ours-atomic"];

/// A sweep as `forestlod sweep` runs it: `--quick` and the command-line overrides applied, then
/// validated. `None` when nothing is left to run: `--backend reference` on a sweep of GPU-only
/// variants (the dropped variants are named on stderr).
pub fn configure(spec: SweepSpec, args: &SweepArgs) -> Result<Option<SweepSpec>, InputError> {
    // Zero would be clamped or make an empty sweep: name the flag instead.
    for (flag, value) in [
        ("--repeats", args.repeats),
        ("--yaw-steps", args.yaw_steps),
        ("--width", args.width),
        ("--height", args.height),
    ] {
        if value == Some(0) {
            return Err(InputError::new(
                "<command line>",
                flag,
                0,
                "expected at least 1",
            ));
        }
    }
    let mut spec = if args.quick { spec.quick() } else { spec };
    if let Some(s) = &args.scene {
        spec.scenes = vec![s.clone()];
    }
    spec.width = args.width.unwrap_or(spec.width);
    spec.height = args.height.unwrap_or(spec.height);
    spec.repeats = args.repeats.unwrap_or(spec.repeats);
    if let Some(b) = &args.backend {
        spec.backends = b.split(',').map(|s| s.trim().to_string()).collect();
        if !spec.backends.iter().any(|b| b == "gpu") {
            let (gpu_only, keep): (Vec<String>, Vec<String>) = spec
                .variants
                .iter()
                .cloned()
                .partition(|v| GPU_ONLY_VARIANTS.contains(&v.as_str()));
            if !gpu_only.is_empty() {
                eprintln!(
                    "sweep {}: variant(s) {} need the gpu backend; not run with --backend {b}",
                    spec.name,
                    gpu_only.join(", ")
                );
            }
            spec.variants = keep;
            if spec.variants.is_empty() {
                return Ok(None);
            }
        }
    }
    if let Some(n) = args.yaw_steps {
        for c in &mut spec.cameras {
            if c.name != "distance" {
                c.yaw_steps = Some(n);
            }
        }
    }
    spec.validate(&format!("<sweep {}>", spec.name))?;
    Ok(Some(spec))
}

/// `forestlod sweep`.
pub fn run(args: &SweepArgs) -> Result<(), Box<dyn std::error::Error>> {
    // Every sweep is configured (and so validated) before anything runs or is written.
    let mut specs = Vec::new();
    for spec in resolve(args.file.as_deref())? {
        let name = spec.name.clone();
        match configure(spec, args)? {
            Some(spec) => specs.push(spec),
            None => eprintln!("sweep {name}: nothing to run on the chosen backends"),
        }
    }
    std::fs::create_dir_all(&args.out).map_err(|e| io_err(&args.out, e))?;
    let mut runner = Runner::default();
    let start = Instant::now();
    for spec in specs {
        let m = runner.run_sweep(&spec, args.quick, &args.out)?;
        println!(
            "sweep {}: {} frames in {:.1} s -> {}",
            m.name,
            m.frames,
            m.wall_seconds,
            args.out.join(&m.name).join(&m.csv).display()
        );
    }
    println!(
        "all sweeps: {:.1} s; `forestlod report --run {}` writes the report",
        start.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_sweep_parses_in_both_modes() {
        for (name, text) in BUILTIN_SWEEPS {
            let spec = SweepSpec::parse(text, name).unwrap();
            assert_eq!(spec.name, name);
            assert!(!spec.param_sets(name).unwrap().is_empty());
            let quick = spec.quick();
            quick.validate(name).unwrap();
            assert!(!quick.poses().is_empty());
        }
    }

    #[test]
    fn bad_sweeps_are_named() {
        // (file body after the common head, the text the error must name)
        let head = "name = 'x'\ntitle = 't'\nscenes = ['tiny']\n";
        let far = "[[cameras]]\nname = 'far'\n";
        for (body, named) in [
            ("[[cameras]]\nname = 'sideways'\n".to_string(), "sideways"),
            (
                format!("{far}[[axes]]\nparam = 'grid_size'\nvalues = [-1]\n"),
                "grid_size",
            ),
            (format!("variants = ['fast']\n{far}"), "fast"),
            (format!("backends = ['cuda']\n{far}"), "cuda"),
            (format!("backends = []\n{far}"), "backends"),
            (format!("variants = ['ours-atomic']\n{far}"), "ours-atomic"),
            (
                format!("{far}[[axes]]\nparam = 'tree_cull'\nvalues = ['some']\n"),
                "tree_cull",
            ),
            (
                "[[cameras]]\nname = 'far'\nyaw_steps = 0\n".to_string(),
                "cameras.yaw_steps",
            ),
        ] {
            let e = SweepSpec::parse(&format!("{head}{body}"), "f.toml").unwrap_err();
            assert!(e.to_string().contains(named), "{named}: {e}");
        }
    }

    #[test]
    fn axes_multiply_and_settings_apply() {
        let spec = SweepSpec::parse(
            "name = 'x'\ntitle = 't'\nscenes = ['tiny']\nx_axis = 'angle_count'\n[[cameras]]\nname = 'far'\nyaw_steps = 4\n\
             [[axes]]\nparam = 'angle_count'\nvalues = [2, 10]\n[[axes]]\nparam = 'texture_size'\nvalues = [32, 64, 128]\n\
             [[settings]]\nlabel = 'a'\n[[settings]]\nlabel = 'b'\nfade_mode = 'alpha'\n",
            "f.toml",
        )
        .unwrap();
        let sets = spec.param_sets("f").unwrap();
        assert_eq!(sets.len(), 2 * 2 * 3);
        assert!(
            sets.iter().any(
                |s| s.params.fade_mode == FadeMode::Alpha as u32 && s.params.texture_size == 64
            )
        );
        assert_eq!(sets[0].x, Some(2.0));
        assert_eq!(sets[0].series, "a texture_size=32");
        let yaws: Vec<f32> = spec.poses().iter().map(|p| p.yaw_deg).collect();
        assert_eq!(yaws, [0.0, 90.0, 180.0, 270.0]);
    }
}
