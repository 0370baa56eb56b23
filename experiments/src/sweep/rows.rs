//! What a sweep writes: one CSV [`Row`] per frame (variant and backend as their names, one column
//! per parameter), the [`FrameImages`] saved for the first pose of each camera, and the
//! [`Manifest`] (`sweep.json`) that `forestlod report` reads back.
//!
//! The parameter columns come from the parameter table, not from `Row`'s fields: a parameter
//! added to [`forestlod_shared::registry::PARAMS`] gets its CSV column with no edit here or in the
//! runner. Reading accepts any key the table answers to (so CSVs written before a column was
//! renamed still read) and takes the default for a parameter a CSV lacks (it predates it).

use std::path::Path;

use csv::StringRecord;
use forestlod_reference::InputError;
use forestlod_shared::{PARAMS, ParamSpec, Params, param};
use serde::{Deserialize, Serialize};

use crate::metrics::Accuracy;

use super::spec::SweepSpec;

/// One CSV row: one frame of one variant.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// The frame's index in the sweep's canonical order (scene, parameter set, pose, backend,
    /// variant): what `sweep merge` orders shards' rows by. 0 in CSVs written before sharding.
    #[serde(default)]
    pub frame: u64,
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
    /// Every parameter of the frame. In the CSV: one column per entry of the parameter table
    /// ([`forestlod_shared::registry::PARAMS`], named by its canonical name, valued as users write
    /// it) right after `setting` ([`write_csv`], [`read_csv`]); serde skips it.
    #[serde(skip)]
    pub params: Params,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Seconds the ground truth of this frame's pose took to trace (shared by every row of
    /// the pose; empty in CSVs written before it was recorded).
    #[serde(default)]
    pub truth_s: Option<f64>,
    /// Fraction of the frame's pixels the truth traced: 1 for the full frame, less for sampled
    /// tiles (`crate::fair::TruthLayout`), on which every error against the truth is then
    /// computed. Empty in older CSVs (full frame).
    #[serde(default)]
    pub truth_fraction: Option<f64>,
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
    /// Ours: trees missing a LOD per-tree selection gives them (conservative selection: 0). Under
    /// hierarchical impostors (issue 33 item 2): the trees drawn inside an impostor that needed
    /// their mesh (an impostor replaces its node's trees whatever their LOD).
    pub trees_missing_lod: u64,
    /// Tree triangles submitted (reference backend; the GPU has no such counter here).
    pub triangles: Option<u64>,
    /// Tree fragments shaded (reference backend).
    pub fragments: Option<u64>,
    /// Tree fragments written (reference backend).
    pub fragments_written: Option<u64>,
    /// `fragments_written / pixels` (reference backend).
    pub overdraw: Option<f64>,
    /// Point records the draw expanded under `lod1 = points` (issue 33, C§5.2's "points
    /// rendered": [`forestlod_reference::draw::DrawnFrame::points_drawn`]): ours on the reference
    /// backend only, 0 under billboards. Empty for GPU rows (the GPU counts no points; its vertex
    /// stage visits every record of a tree and drops the rest as degenerate quads), for the
    /// baselines (they draw no points) and in CSVs written before the column existed.
    #[serde(default)]
    pub points_drawn: Option<u64>,
    /// Bytes the method adds to the scene data (ours: E Eq. 4.1's terms as allocated).
    pub memory_bytes: u64,
    /// Temporal (popping) error of this frame against the previous frame of its camera path
    /// (`crate::temporal`: mean over pixels of the LOD frames' change beyond the full-detail
    /// frames' change, both box-filtered by [`crate::temporal::DEFAULT_POOL`]), scored against the
    /// same scene, setting, backend and variant at the path's previous pose. Empty for a path's
    /// first frame, for cameras that are no path and in CSVs written before it existed; never NaN.
    #[serde(default)]
    pub temporal_mean: Option<f64>,
    /// Temporal error: 99th percentile over pixels (empty where `temporal_mean` is).
    #[serde(default)]
    pub temporal_p99: Option<f64>,
    /// Hierarchical impostors (issue 33 item 2): wall seconds of this frame's impostor step (the
    /// plan and the tile renders, reference backend), outside `frame_s`: a path's frame costs
    /// `frame_s + impostor_s`. Empty without impostors.
    #[serde(default)]
    pub impostor_s: Option<f64>,
    /// Tiles this frame's impostor step rendered (created and refreshed).
    #[serde(default)]
    pub tiles_rendered: Option<u64>,
    /// Of those tiles, the ones whose rectangle lies wholly outside the frame (the seed's
    /// suspected "refresh of not seen parts", C§5.4).
    #[serde(default)]
    pub tiles_off_screen: Option<u64>,
    /// Texels of those tiles.
    #[serde(default)]
    pub tile_texels: Option<u64>,
    /// Triangles those tile renders drew.
    #[serde(default)]
    pub tile_triangles: Option<u64>,
    /// Impostors in the atlas after the step.
    #[serde(default)]
    pub impostors_held: Option<u64>,
    /// Accuracy against the ground truth. In the CSV: [`Accuracy`]'s columns, last
    /// ([`write_csv`]); serde skips it here, so a figure added to `Accuracy` is a column with
    /// no edit of this file or the runner.
    #[serde(skip)]
    pub accuracy: Accuracy,
}

/// The columns and values of `value` as the csv crate's serde support writes them (a flat
/// struct: `Row` without its skipped parts, [`Accuracy`]).
fn columns_of<T: Serialize>(value: &T) -> Result<(StringRecord, StringRecord), csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.serialize(value)?;
    let bytes = w.into_inner().map_err(|e| e.into_error())?;
    let mut r = csv::Reader::from_reader(&bytes[..]);
    let headers = r.headers()?.clone();
    let record = r.records().next().transpose()?.unwrap_or_default();
    Ok((headers, record))
}

/// Where the parameter columns go: after `setting`.
fn params_at(headers: &StringRecord) -> usize {
    headers
        .iter()
        .position(|h| h == "setting")
        .map_or(0, |i| i + 1)
}

/// Writes `rows` as a sweep CSV: `Row`'s columns with one column per parameter-table entry
/// spliced in after `setting`, and [`Accuracy`]'s columns last.
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<(), InputError> {
    let fail = |e: &dyn std::fmt::Display| {
        InputError::new(path.display().to_string(), "write", "", e.to_string())
    };
    let mut w = csv::Writer::from_path(path).map_err(|e| fail(&e))?;
    for (i, row) in rows.iter().enumerate() {
        let (headers, record) = columns_of(row).map_err(|e| fail(&e))?;
        let (acc_headers, acc_record) = columns_of(&row.accuracy).map_err(|e| fail(&e))?;
        let at = params_at(&headers);
        let splice = |own: &StringRecord, params: Vec<String>, acc: &StringRecord| -> Vec<String> {
            let own: Vec<String> = own.iter().map(str::to_string).collect();
            let acc: Vec<String> = acc.iter().map(str::to_string).collect();
            [&own[..at], &params[..], &own[at..], &acc[..]].concat()
        };
        if i == 0 {
            let names = PARAMS.iter().map(|s| s.name.to_string()).collect();
            w.write_record(splice(&headers, names, &acc_headers))
                .map_err(|e| fail(&e))?;
        }
        let values = PARAMS.iter().map(|s| s.format(&row.params)).collect();
        w.write_record(splice(&record, values, &acc_record))
            .map_err(|e| fail(&e))?;
    }
    w.flush().map_err(|e| fail(&e))
}

/// Largest sweep CSV read back (`sweep merge`, `report`): a row is about 1 KiB, so the
/// [`super::MAX_SWEEP_FRAMES`] rows a sweep may have fit in about 100 MiB; twice that is room
/// for long labels.
pub const MAX_SWEEP_CSV_BYTES: u64 = 256 << 20;

/// What a CSV column holds.
enum Column {
    /// A parameter of the table.
    Param(&'static ParamSpec),
    /// A figure of [`Accuracy`].
    Accuracy,
    /// One of `Row`'s own fields.
    Own,
}

/// Reads a sweep CSV written by [`write_csv`] (or before a parameter column was added or
/// renamed: module docs): a regular file of at most [`MAX_SWEEP_CSV_BYTES`]
/// ([`forestlod_reference::files`]). A cell that does not parse is an error naming the row and
/// column.
pub fn read_csv(path: &Path) -> Result<Vec<Row>, InputError> {
    let bytes = forestlod_reference::files::read_limited(path, MAX_SWEEP_CSV_BYTES)?;
    parse_csv(&bytes, &path.display().to_string())
}

/// [`read_csv`] of the bytes of a CSV; `file` names it in errors.
pub fn parse_csv(bytes: &[u8], file: &str) -> Result<Vec<Row>, InputError> {
    let file = file.to_string();
    let mut reader = csv::Reader::from_reader(bytes);
    let headers = reader
        .headers()
        .map_err(|e| InputError::new(file.clone(), "header", "", e.to_string()))?
        .clone();
    // Each column is a parameter of the table, a figure of `Accuracy` or one of `Row`'s own.
    let (acc_names, _) = columns_of(&Accuracy::default())
        .map_err(|e| InputError::new(file.clone(), "header", "", e.to_string()))?;
    let kinds: Vec<Column> = headers
        .iter()
        .map(|h| match param(h) {
            Some(spec) => Column::Param(spec),
            None if acc_names.iter().any(|a| a == h) => Column::Accuracy,
            None => Column::Own,
        })
        .collect();
    let pick = |record: &StringRecord, want: fn(&Column) -> bool| -> StringRecord {
        record
            .iter()
            .zip(&kinds)
            .filter(|(_, k)| want(k))
            .map(|(v, _)| v)
            .collect()
    };
    let is_own: fn(&Column) -> bool = |k| matches!(k, Column::Own);
    let is_acc: fn(&Column) -> bool = |k| matches!(k, Column::Accuracy);
    let (own_headers, acc_headers) = (pick(&headers, is_own), pick(&headers, is_acc));
    let mut rows = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let at = format!("row {}", i + 2);
        let bad = |e: &dyn std::fmt::Display| {
            InputError::new(file.clone(), at.clone(), "", e.to_string())
        };
        let record = record.map_err(|e| bad(&e))?;
        // A cell that does not deserialize: named by its column and value where the csv crate
        // says which field it was.
        let cell = |picked: &StringRecord, names: &StringRecord, e: csv::Error| {
            if let csv::ErrorKind::Deserialize { err, .. } = e.kind()
                && let Some(i) = err.field().map(|i| i as usize)
                && let (Some(name), Some(value)) = (names.get(i), picked.get(i))
            {
                return InputError::new(
                    file.clone(),
                    format!("{at}, column {name}"),
                    value,
                    err.kind().to_string(),
                );
            }
            bad(&e)
        };
        let own = pick(&record, is_own);
        let mut row: Row = own
            .deserialize(Some(&own_headers))
            .map_err(|e| cell(&own, &own_headers, e))?;
        let acc = pick(&record, is_acc);
        row.accuracy = acc
            .deserialize(Some(&acc_headers))
            .map_err(|e| cell(&acc, &acc_headers, e))?;
        for ((kind, value), column) in kinds.iter().zip(&record).zip(&headers) {
            if let Column::Param(spec) = kind {
                let v = spec.parse(value).map_err(|e| {
                    InputError::new(
                        file.clone(),
                        format!("{at}, column {column}"),
                        value,
                        e.expected,
                    )
                })?;
                (spec.set)(&mut row.params, v);
            }
        }
        rows.push(row);
    }
    Ok(rows)
}

/// Images saved for one frame (paths relative to the sweep folder).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FrameImages {
    /// The frame's index ([`Row::frame`]).
    #[serde(default)]
    pub frame: u64,
    /// Camera.
    pub camera: String,
    /// Yaw, degrees.
    pub yaw_deg: f32,
    /// Distance, metres.
    pub distance_m: f32,
    /// Pipeline.
    pub variant: String,
    /// Engine.
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
    /// The LOD error map: FLIP against the same backend's full-detail frame.
    #[serde(default)]
    pub lod_flip: String,
    /// Per-LOD FLIP maps: `(label, path, mean FLIP, pixels)`.
    pub per_lod: Vec<(String, String, f64, u64)>,
    /// Per-LOD maps of the LOD error, likewise (ours only).
    #[serde(default)]
    pub per_lod_lod_error: Vec<(String, String, f64, u64)>,
    /// The total error's map: our frame at the truth's sampling rate against the truth (empty
    /// when not measured).
    #[serde(default)]
    pub total_flip: String,
    /// Per-LOD maps of the total error, likewise (ours only; classes of the filtered frame).
    #[serde(default)]
    pub per_lod_total: Vec<(String, String, f64, u64)>,
    /// The ground truth.
    pub ground_truth: String,
    /// The ground truth's classes.
    pub ground_truth_class: String,
    /// Accuracy figures of the frame.
    pub accuracy: Accuracy,
}

impl FrameImages {
    /// Every image path this entry names, with its manifest key for errors: the seven fixed
    /// images (`images[{index}].color`, ...), then each per-LOD map
    /// (`images[{index}].per_lod[{j}][1]`, ...). Empty paths are included (an error map that was
    /// not measured); `report` and `sweep merge` read exactly these.
    pub fn named_images(&self, index: usize) -> Vec<(String, &String)> {
        let mut named: Vec<(String, &String)> = [
            ("color", &self.color),
            ("lod", &self.lod),
            ("flip", &self.flip),
            ("lod_flip", &self.lod_flip),
            ("total_flip", &self.total_flip),
            ("ground_truth", &self.ground_truth),
            ("ground_truth_class", &self.ground_truth_class),
        ]
        .into_iter()
        .map(|(k, p)| (format!("images[{index}].{k}"), p))
        .collect();
        for (k, maps) in [
            ("per_lod", &self.per_lod),
            ("per_lod_lod_error", &self.per_lod_lod_error),
            ("per_lod_total", &self.per_lod_total),
        ] {
            for (j, (_, p, _, _)) in maps.iter().enumerate() {
                named.push((format!("images[{index}].{k}[{j}][1]"), p));
            }
        }
        named
    }
}

/// What a sweep wrote: `sweep.json` in its folder, read by `forestlod report`.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Manifest {
    /// Sweep name.
    pub name: String,
    /// The build that ran it (issue 34, [`super::shard::build_id`]); `sweep merge` refuses a
    /// mix. Absent in manifests of earlier builds.
    #[serde(default)]
    pub build: Option<String>,
    /// FNV-1a of the sweep definition as run (issue 34); `sweep merge` refuses a mix.
    #[serde(default)]
    pub spec_hash: Option<String>,
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
    /// Seconds spent tracing ground-truth images (BVH builds not included: `ground_truth_bvh`).
    #[serde(default)]
    pub ground_truth_seconds: Option<f64>,
    /// Bytes of the largest scene's ground truth ([`forestlod_reference::ground_truth::GroundTruthScene::memory_bytes`]).
    #[serde(default)]
    pub ground_truth_memory_bytes: Option<u64>,
    /// Where the truth was traced, per frame size (`1280x720: 18 tiles of 80x80 (12.5% ...)`).
    #[serde(default)]
    pub ground_truth_layout: Vec<String>,
    /// Whether the total error was measured.
    #[serde(default)]
    pub total_error: bool,
    /// `I/N` when this is shard `I` of `N` (`forestlod sweep --shard`), to be joined by
    /// `forestlod sweep merge`.
    #[serde(default)]
    pub shard: Option<String>,
    /// The sweep as it ran (quick mode and command-line overrides applied), so that
    /// `forestlod report --replot` can redraw the plots from the CSV.
    #[serde(default)]
    pub spec: Option<SweepSpec>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use forestlod_shared::{FadeMode, TreeCull};

    fn row(params: Params) -> Row {
        let committed =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("results/tree_cull/tree_cull.csv");
        let mut r = read_csv(&committed).expect("a committed sweep CSV reads")[0].clone();
        r.params = params;
        r
    }

    #[test]
    fn every_parameter_gets_a_column_and_round_trips() {
        let dir = std::env::temp_dir().join(format!("forestlod-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rows.csv");
        let odd = Params {
            grid_size: 137.25,
            angle_count: 7,
            alpha_cutoff: 0.3,
            fade_mode: FadeMode::Alpha as u32,
            tree_cull: TreeCull::All as u32,
            ..Default::default()
        };
        let rows = vec![row(Params::default()), row(odd)];
        write_csv(&path, &rows).unwrap();
        let header = std::fs::read_to_string(&path).unwrap();
        let header = header.lines().next().unwrap();
        for spec in &PARAMS {
            assert!(
                header.split(',').any(|c| c == spec.name),
                "no column {} in {header}",
                spec.name
            );
        }
        let back = read_csv(&path).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert_eq!(back.len(), 2);
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(a.params, b.params);
            assert_eq!(
                (&a.setting, format!("{:?}", a.accuracy), a.gpu_draw_s),
                (&b.setting, format!("{:?}", b.accuracy), b.gpu_draw_s)
            );
        }
    }

    #[test]
    fn csvs_written_before_the_table_still_read() {
        // `angle_index/angle_index.csv` predates the table: `angle_index` (the flag's key, not
        // the field's name), floats as `500.0`, no `alpha_cutoff` and no `tree_cull` column.
        let old = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/angle_index/angle_index.csv");
        let rows = read_csv(&old).unwrap();
        assert!(!rows.is_empty());
        assert!(
            rows.iter().any(|r| r.params.angle_index_mode == 1),
            "eq31-clamped rows read"
        );
        assert!(rows.iter().any(|r| r.params.angle_count == 4));
        for r in &rows {
            r.params.validate().unwrap();
            assert_eq!(r.params.alpha_cutoff, Params::default().alpha_cutoff);
        }
    }

    #[test]
    fn no_own_column_is_taken_for_a_parameter() {
        let (headers, _) = columns_of(&row(Params::default())).unwrap();
        for h in &headers {
            assert!(
                param(h).is_none(),
                "column {h} would be read as a parameter"
            );
        }
    }
}
