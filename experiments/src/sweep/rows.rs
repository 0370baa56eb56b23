//! What a sweep writes: one CSV [`Row`] per frame (variant and backend as their names, one column
//! per parameter), the [`FrameImages`] saved for the first pose of each camera, and the
//! [`Manifest`] (`sweep.json`) that `forestlod report` reads back.

use serde::{Deserialize, Serialize};

use crate::metrics::Accuracy;

use super::spec::SweepSpec;

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
