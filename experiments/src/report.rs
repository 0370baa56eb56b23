//! `forestlod report --run DIR`: the report over every sweep that `forestlod sweep --out DIR`
//! wrote (issue 35: a report a researcher reads). Images are linked relatively, so the folder can
//! be moved or zipped as a whole. It writes ([`write_report`]):
//!
//! - `DIR/index.html`, the page to open: its first screen is the trade, cost against error, per
//!   sweep, scene and camera (one point per variant with its 95 % intervals, the Pareto front
//!   drawn and its members named: [`trade`]); below, one sentence per sweep saying what it found,
//!   from the paired intervals ([`finding`]: *outside the noise* or not), linking to its page.
//!   Images are linked, not embedded (lazy thumbnails that open the full image), so the index
//!   weighs kilobytes;
//! - `DIR/sweep-<folder>.html`, one page per sweep: its section below, images linked;
//! - `DIR/report.md`, every section on one page, for reading in a repository;
//! - `DIR/report.html`, the same as one self-contained page (images embedded), for mailing;
//! - `DIR/flip_scale.png` (and `.svg`): the colour scale of the FLIP error maps, shown beside
//!   the frames.
//!
//! Per sweep: the question, the setup, a summary table (means per variant / setting / camera of
//! cost and accuracy), the paired differences, the speed-up of ours over the baselines where they
//! ran (frame-time ratios, E§5's "70 % up to 500 %"), the Pareto front of cost against FLIP (the
//! settings no other setting beats on both), per scene and camera the trade plots with their
//! fronts and intervals, the other plots, and the saved frames side by side, each column named
//! (ground truth, frame, FLIP error, LOD error, total error, LOD ids) and the error maps' colour
//! scale beside them, then ours' per-LOD error maps. Beside the LOD error and the total error,
//! the summary and the paired differences give the temporal error of camera paths
//! (`Row::temporal_mean`, [`crate::temporal`]) where the sweep has one.
//!
//! **A report reads only its run** (issue 28; a report is a file people mail around). Every path
//! a `sweep.json` names (`csv`, `plots`, every frame image) must be relative to its sweep folder,
//! without `..`, and resolve (links followed) to a regular file under the run folder; the
//! manifest itself too. Anything else is an error naming the run folder, the manifest, the key
//! and the value, and no report is written. A named image that is absent is shown as missing,
//! as before. The pages show (and `report.html` embeds) only the images so checked
//! ([`crate::html::Embeds`]), and all
//! text taken from a manifest or a CSV (titles, descriptions, captions, names, settings, labels)
//! is escaped ([`crate::html::escape_markdown`]), so it cannot become an image or a link.
//!
//! **Hostile input** (issue 28): `--run` must be a folder (after resolving links); a file, a
//! missing path, a dangling link or a special file is an error naming `--run`. Every
//! `DIR/*/sweep.json` that exists must be a regular file under the run (a FIFO, a folder or a link
//! to `/dev/zero` is an error naming it, never skipped), of at most [`MAX_MANIFEST_BYTES`], and a
//! manifest [`parse_manifest`] accepts (types, ranges, no duplicate or unknown key). The CSV is
//! read within [`crate::sweep::MAX_SWEEP_CSV_BYTES`] and must hold a row; each embedded image
//! within [`MAX_EMBEDDED_IMAGE_BYTES`], and all of a report's images together (each counted
//! every time the page shows it) within [`MAX_EMBEDDED_TOTAL_BYTES`]: sizes are checked before
//! anything is read. Every file is read through [`forestlod_reference::files`]. All of this is
//! checked and every page is made before any is written: a refused run gets no report.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::Args;
use forestlod_reference::InputError;
use forestlod_reference::error::{COMMAND_LINE, excerpt};
use forestlod_reference::files::{read_text_limited, regular_file, size_text};

use crate::html::{
    Embed, Embeds, MAX_EMBEDDED_IMAGE_BYTES, MAX_EMBEDDED_TOTAL_BYTES, code_span,
    escape_destination as dest, escape_markdown as md,
};
use crate::sweep::{Manifest, Row};

pub mod manifest;
pub mod trade;
pub use manifest::{MAX_MANIFEST_BYTES, parse_manifest};

/// The run folder resolved, and how its errors name it.
struct Run {
    /// The folder as given.
    given: PathBuf,
    /// Its canonical path: every file a report reads lies under it.
    root: PathBuf,
    /// Bytes of images the report embeds so far, every place it shows them counted
    /// ([`MAX_EMBEDDED_TOTAL_BYTES`]).
    embedded: u64,
}

/// One sweep of the run: its folder, its manifest's path and the manifest, checked.
struct Sweep {
    dir: PathBuf,
    mpath: PathBuf,
    m: Manifest,
}

impl Run {
    /// The run folder `--run` names: a folder (after resolving links), or an error naming
    /// `--run` (issue 28: a file, a missing path or a dangling link is bad input).
    fn new(given: &Path) -> Result<Self, InputError> {
        let flag = |reason: String| InputError::new(COMMAND_LINE, "--run", given.display(), reason);
        let expected = "expected the folder `forestlod sweep --out` wrote";
        let meta = std::fs::symlink_metadata(given)
            .map_err(|e| flag(format!("cannot be read ({e}); {expected}")))?;
        let target = std::fs::metadata(given).map_err(|e| {
            if meta.file_type().is_symlink() {
                flag(format!("is a link that does not resolve ({e}); {expected}"))
            } else {
                flag(format!("cannot be read ({e}); {expected}"))
            }
        })?;
        if !target.is_dir() {
            let kind = if target.is_file() {
                "a file"
            } else {
                "a special file (a FIFO, socket or device)"
            };
            return Err(flag(format!("is {kind}, not a folder; {expected}")));
        }
        let root = std::fs::canonicalize(given)
            .map_err(|e| flag(format!("cannot be resolved ({e}); {expected}")))?;
        Ok(Self {
            given: given.to_path_buf(),
            root,
            embedded: 0,
        })
    }

    /// The chain link of the run folder, outermost in every error about its files.
    fn link(&self) -> String {
        format!("run folder {}", self.given.display())
    }

    /// An error about `key = value` of the manifest `mpath`, chained through the run folder.
    fn error(&self, mpath: &Path, key: &str, value: &str, reason: String) -> InputError {
        InputError::new(
            mpath.display().to_string(),
            format!("key {key}"),
            value,
            reason,
        )
        .within(self.link())
    }

    /// The link through which an error in a file that `key = value` of `mpath` names is
    /// reached (outermost: the run folder).
    fn named_by(&self, mpath: &Path, key: &str, value: &str) -> String {
        format!(
            "{}: {}: key {key} = {}",
            self.link(),
            mpath.display(),
            excerpt(value)
        )
    }

    /// `file` resolved (links followed), when that is a regular file under the run folder.
    fn resolve(&self, file: &Path) -> Result<PathBuf, String> {
        let canon = std::fs::canonicalize(file)
            .map_err(|e| format!("cannot be resolved ({e}); reports read only their run"))?;
        if !canon.starts_with(&self.root) {
            return Err(format!(
                "resolves to {}, outside the run folder {}: reports read only their run",
                canon.display(),
                self.root.display()
            ));
        }
        if !std::fs::metadata(&canon).is_ok_and(|m| m.is_file()) {
            return Err(format!(
                "resolves to {}, not a regular file (a folder, FIFO, socket or device)",
                canon.display()
            ));
        }
        Ok(canon)
    }

    /// The manifest `mpath` (it exists), checked to be a regular file under the run folder,
    /// read within [`MAX_MANIFEST_BYTES`] and parsed ([`parse_manifest`]).
    fn manifest(&self, mpath: &Path) -> Result<Manifest, InputError> {
        self.resolve(mpath).map_err(|reason| {
            InputError::new(mpath.display().to_string(), "manifest", "", reason).within(self.link())
        })?;
        let text =
            read_text_limited(mpath, MAX_MANIFEST_BYTES).map_err(|e| e.within(self.link()))?;
        parse_manifest(&text, &mpath.display().to_string()).map_err(|e| e.within(self.link()))
    }

    /// The path `value` that key `key` of the manifest `mpath` (in the sweep folder `dir`)
    /// names: its file, or `None` when nothing is there.
    fn named(
        &self,
        mpath: &Path,
        dir: &Path,
        key: &str,
        value: &str,
    ) -> Result<Option<PathBuf>, InputError> {
        use std::path::Component;
        if !Path::new(value)
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
        {
            return Err(self.error(
                mpath,
                key,
                value,
                "expected a path relative to the sweep folder, without `..`: reports read only their run"
                    .into(),
            ));
        }
        let file = dir.join(value);
        if std::fs::symlink_metadata(&file).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound)
        {
            return Ok(None);
        }
        self.resolve(&file)
            .map(Some)
            .map_err(|reason| self.error(mpath, key, value, reason))
    }

    /// The rows of the sweep's CSV (key `csv`): a regular file under the run folder, read within
    /// [`crate::sweep::MAX_SWEEP_CSV_BYTES`], holding at least one row.
    fn rows(&self, sweep: &Sweep) -> Result<Vec<Row>, InputError> {
        let Sweep { dir, mpath, m } = sweep;
        if self.named(mpath, dir, "csv", &m.csv)?.is_none() {
            return Err(self.error(
                mpath,
                "csv",
                &m.csv,
                format!("names no file in {}", dir.display()),
            ));
        }
        let link = self.named_by(mpath, "csv", &m.csv);
        let rows = read_rows(&dir.join(&m.csv)).map_err(|e| e.within(link.clone()))?;
        if rows.is_empty() {
            return Err(InputError::new(
                dir.join(&m.csv).display().to_string(),
                "rows",
                "0 rows",
                "expected the sweep's frames, one row each",
            )
            .within(link));
        }
        Ok(rows)
    }

    /// Every image the sweep's manifest names, checked (a regular file under the run folder,
    /// within [`MAX_EMBEDDED_IMAGE_BYTES`], and the report's images within
    /// [`MAX_EMBEDDED_TOTAL_BYTES`] in all), keyed as the report's Markdown writes it ([`rel`]).
    fn images(&mut self, sweep: &Sweep) -> Result<Embeds, InputError> {
        let Sweep { dir, mpath, m } = sweep;
        let mut named: Vec<(String, &str)> = Vec::new();
        for (i, (p, _)) in m.plots.iter().enumerate() {
            named.push((format!("plots[{i}][0]"), p));
        }
        for (i, im) in m.images.iter().enumerate() {
            named.extend(im.named_images(i).into_iter().map(|(k, p)| (k, p.as_str())));
        }
        let mut embeds = Embeds::new();
        for (key, p) in named {
            // An empty path names nothing (an error map that was not measured).
            let file = if p.is_empty() {
                None
            } else {
                self.named(mpath, dir, &key, p)?
            };
            let embed = match file {
                None => None,
                Some(file) => {
                    let size =
                        regular_file(&file).map_err(|e| e.within(self.named_by(mpath, &key, p)))?;
                    if size > MAX_EMBEDDED_IMAGE_BYTES {
                        return Err(self.error(
                            mpath,
                            &key,
                            p,
                            format!(
                                "names an image of {}, over the limit of {} for an image a report embeds",
                                size_text(size),
                                size_text(MAX_EMBEDDED_IMAGE_BYTES)
                            ),
                        ));
                    }
                    self.embedded += size;
                    if self.embedded > MAX_EMBEDDED_TOTAL_BYTES {
                        return Err(self.error(
                            mpath,
                            &key,
                            p,
                            format!(
                                "brings the report's embedded images to {}, over the limit of {} for one report",
                                size_text(self.embedded),
                                size_text(MAX_EMBEDDED_TOTAL_BYTES)
                            ),
                        ));
                    }
                    Some(Embed {
                        file,
                        named_by: self.named_by(mpath, &key, p),
                    })
                }
            };
            embeds.insert(rel(dir, m, p), embed);
        }
        // A plot's SVG twin (issue 35: `crate::plot`, `crate::chart` write one beside each PNG),
        // when it is a regular file under the run within the per-image limit: the self-contained
        // page embeds it instead of the PNG (a quarter of the bytes, and sharp at any zoom).
        // Anything else (absent, a link out of the run, a special file) is skipped unread, and
        // the PNG is embedded.
        for (i, (p, _)) in m.plots.iter().enumerate() {
            let Some(svg) = p.strip_suffix(".png").map(|stem| format!("{stem}.svg")) else {
                continue;
            };
            let key = format!("plots[{i}][0] (its SVG twin)");
            let Ok(Some(file)) = self.named(mpath, dir, &key, &svg) else {
                continue;
            };
            let Ok(size) = regular_file(&file) else {
                continue;
            };
            if size > MAX_EMBEDDED_IMAGE_BYTES || self.embedded + size > MAX_EMBEDDED_TOTAL_BYTES {
                continue;
            }
            self.embedded += size;
            embeds.insert(
                rel(dir, m, &svg),
                Some(Embed {
                    file,
                    named_by: self.named_by(mpath, &key, &svg),
                }),
            );
        }
        Ok(embeds)
    }

    /// Every sweep of the run (each `DIR/*/sweep.json`, in name order), its manifest checked
    /// and parsed. A `sweep.json` that is not a regular file under the run (a FIFO, a link to a
    /// device or out of the run, a folder) is an error naming it, never skipped.
    fn sweeps(&self) -> Result<Vec<Sweep>, InputError> {
        let err = |p: &Path, e: &dyn std::fmt::Display| {
            InputError::new(p.display().to_string(), "read", "", e.to_string())
        };
        let mut dirs = Vec::new();
        for entry in std::fs::read_dir(&self.given).map_err(|e| err(&self.given, &e))? {
            dirs.push(entry.map_err(|e| err(&self.given, &e))?.path());
        }
        dirs.sort();
        let mut sweeps = Vec::new();
        for dir in dirs {
            let mpath = dir.join("sweep.json");
            match std::fs::symlink_metadata(&mpath) {
                Ok(_) => {}
                // Not a sweep folder (or not a folder: `report.md`).
                Err(e)
                    if e.kind() == std::io::ErrorKind::NotFound
                        || e.kind() == std::io::ErrorKind::NotADirectory =>
                {
                    continue;
                }
                Err(e) => return Err(err(&mpath, &e).within(self.link())),
            }
            let m = self.manifest(&mpath)?;
            sweeps.push(Sweep { dir, mpath, m });
        }
        if sweeps.is_empty() {
            return Err(InputError::new(
                self.given.display().to_string(),
                "sweeps",
                "",
                "no */sweep.json found: run `forestlod sweep --out DIR` first",
            ));
        }
        Ok(sweeps)
    }
}

/// The sweep folder's name, as the report's paths start (relative to the run folder).
fn folder(dir: &Path, m: &Manifest) -> String {
    dir.file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| m.name.clone())
}

/// `p` (relative to the sweep folder `dir`) relative to the run folder, as the report links it.
fn rel(dir: &Path, m: &Manifest, p: &str) -> String {
    format!("{}/{p}", folder(dir, m))
}

/// Options of `forestlod report`.
#[derive(Args, Clone, Debug)]
pub struct ReportArgs {
    /// The folder `forestlod sweep --out` wrote.
    #[arg(long)]
    pub run: PathBuf,
    /// Redraw every sweep's plots from its CSV first (after a change to the plots; sweeps
    /// written before `sweep.json` recorded the spec must be built-in sweeps run without
    /// overrides).
    #[arg(long)]
    pub replot: bool,
}

/// Means of one group of rows.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Frames averaged.
    pub frames: usize,
    /// Mean select seconds.
    pub select_s: f64,
    /// Mean draw seconds.
    pub draw_s: f64,
    /// Mean frame seconds.
    pub frame_s: f64,
    /// Mean commands.
    pub commands: f64,
    /// Mean tree triangles (NaN when no row counted them: the GPU backend).
    pub triangles: f64,
    /// Mean tree fragments shaded (NaN when no row counted them).
    pub fragments: f64,
    /// Mean overdraw (NaN when no row counted it).
    pub overdraw: f64,
    /// Mean point records drawn (`Row::points_drawn`, issue 33; NaN when no row counted them:
    /// the GPU backend, the baselines, older CSVs).
    pub points_drawn: f64,
    /// Mean trees drawn finer than per-tree selection would (SPEC §6).
    pub trees_finer: f64,
    /// Mean trees drawn coarser than per-tree selection would.
    pub trees_coarser: f64,
    /// Mean memory bytes.
    pub memory_bytes: f64,
    /// Mean FLIP.
    pub flip_mean: f64,
    /// Mean FLIP p95.
    pub flip_p95: f64,
    /// Mean FLIP p99.
    pub flip_p99: f64,
    /// Mean coverage error.
    pub coverage_error: f64,
    /// Frames left out of every mean because the ground truth shows no tree (a camera looking
    /// away from the forest measures nothing about LOD).
    pub empty: usize,
    /// Half-width of the 95% interval of the mean frame time over frames (Student t).
    pub frame_ci: f64,
    /// Half-width of the 95% interval of the mean FLIP.
    pub flip_ci: f64,
    /// Mean LOD error (FLIP against the same backend's full-detail frame; NaN when not measured).
    pub lod_flip_mean: f64,
    /// Half-width of its 95% interval.
    pub lod_flip_ci: f64,
    /// Mean 99th percentile of the LOD error.
    pub lod_flip_p99: f64,
    /// Mean fraction of pixels the LOD changed.
    pub lod_changed: f64,
    /// Mean total error (our frame at the truth's sampling rate against the truth, `crate::fair`;
    /// NaN when not measured).
    pub total_flip_mean: f64,
    /// Half-width of its 95% interval.
    pub total_flip_ci: f64,
    /// Mean coverage error at the truth's sampling rate.
    pub total_coverage_error: f64,
    /// Mean fraction of the frame the truth traced (1: full frame; less: sampled tiles).
    pub truth_fraction: f64,
    /// Mean seconds the truth of a frame took to trace.
    pub truth_s: f64,
    /// Frames with a temporal error (`Row::temporal_mean`: a camera path's frames after its
    /// first), among those counted.
    pub temporal_frames: usize,
    /// Mean temporal error over them (NaN when none: no path, or only first frames).
    pub temporal_mean: f64,
    /// Half-width of its 95% interval.
    pub temporal_ci: f64,
    /// Mean 99th percentile of the temporal error over them.
    pub temporal_p99: f64,
}

/// Two-sided 95% quantiles of Student's t for 1..=30 degrees of freedom; 1.96 beyond.
const T95: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];

/// Mean of `values` and the half-width of its 95% confidence interval (Student t over the
/// values, which are frames or repeats); the half-width is NaN for fewer than two values, the
/// mean NaN for none.
pub fn mean_ci(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, f64::NAN);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let t = T95.get(n - 2).copied().unwrap_or(1.96);
    (mean, t * (var / n as f64).sqrt())
}

/// Whether two means lie within each other's noise: their 95% intervals overlap (or either
/// has none).
pub fn within_noise((a, a_ci): (f64, f64), (b, b_ci): (f64, f64)) -> bool {
    !(a_ci.is_finite() && b_ci.is_finite()) || (a - b).abs() <= a_ci + b_ci
}

/// Means of `rows` over the frames whose ground truth shows a tree (the others are counted in
/// [`Summary::empty`]), with 95% intervals for frame time, FLIP, LOD error, total error and
/// temporal error (over the frames that have one: not a path's first).
pub fn summarize<'a>(rows: impl Iterator<Item = &'a Row>) -> Summary {
    let mut s = Summary::default();
    let (mut counted, mut points_counted) = (0usize, 0usize);
    let (mut times, mut flips, mut lod_flips) = (Vec::new(), Vec::new(), Vec::new());
    let (mut lod_p99, mut lod_changed) = (0.0, 0.0);
    let (mut totals, mut total_cov) = (Vec::new(), 0.0);
    let (mut truth_fraction, mut truth_s) = (0.0, 0.0);
    let (mut temporal, mut temporal_p99) = (Vec::new(), 0.0);
    for r in rows {
        if r.accuracy.gt_tree_fraction <= 0.0 {
            s.empty += 1;
            continue;
        }
        times.push(r.frame_s);
        flips.push(r.accuracy.flip_mean);
        lod_flips.push(r.accuracy.lod_flip_mean);
        lod_p99 += r.accuracy.lod_flip_p99;
        lod_changed += r.accuracy.lod_changed;
        totals.push(r.accuracy.total_flip_mean);
        total_cov += r.accuracy.total_coverage_error;
        truth_fraction += r.truth_fraction.unwrap_or(1.0);
        truth_s += r.truth_s.unwrap_or(f64::NAN);
        if let Some(t) = r.temporal_mean {
            temporal.push(t);
            temporal_p99 += r.temporal_p99.unwrap_or(f64::NAN);
        }
        s.frames += 1;
        s.select_s += r.select_s;
        s.draw_s += r.draw_s;
        s.frame_s += r.frame_s;
        s.commands += r.commands as f64;
        if let (Some(t), Some(f), Some(o)) = (r.triangles, r.fragments, r.overdraw) {
            counted += 1;
            s.triangles += t as f64;
            s.fragments += f as f64;
            s.overdraw += o;
        }
        if let Some(p) = r.points_drawn {
            points_counted += 1;
            s.points_drawn += p as f64;
        }
        s.trees_finer += r.trees_finer as f64;
        s.trees_coarser += r.trees_coarser as f64;
        s.memory_bytes += r.memory_bytes as f64;
        s.flip_mean += r.accuracy.flip_mean;
        s.flip_p95 += r.accuracy.flip_p95;
        s.flip_p99 += r.accuracy.flip_p99;
        s.coverage_error += r.accuracy.coverage_error;
    }
    let n = s.frames.max(1) as f64;
    for v in [
        &mut s.select_s,
        &mut s.draw_s,
        &mut s.frame_s,
        &mut s.commands,
        &mut s.trees_finer,
        &mut s.trees_coarser,
        &mut s.memory_bytes,
        &mut s.flip_mean,
        &mut s.flip_p95,
        &mut s.flip_p99,
        &mut s.coverage_error,
    ] {
        *v /= n;
    }
    let c = if counted == 0 {
        f64::NAN
    } else {
        counted as f64
    };
    for v in [&mut s.triangles, &mut s.fragments, &mut s.overdraw] {
        *v /= c;
    }
    s.points_drawn = if points_counted == 0 {
        f64::NAN
    } else {
        s.points_drawn / points_counted as f64
    };
    s.frame_ci = mean_ci(&times).1;
    s.flip_ci = mean_ci(&flips).1;
    (s.lod_flip_mean, s.lod_flip_ci) = mean_ci(&lod_flips);
    s.lod_flip_p99 = lod_p99 / n;
    s.lod_changed = lod_changed / n;
    (s.total_flip_mean, s.total_flip_ci) = mean_ci(&totals);
    s.total_coverage_error = total_cov / n;
    s.truth_fraction = truth_fraction / n;
    s.truth_s = truth_s / n;
    s.temporal_frames = temporal.len();
    (s.temporal_mean, s.temporal_ci) = mean_ci(&temporal);
    s.temporal_p99 = temporal_p99 / temporal.len() as f64;
    s
}

/// A row's variant with its backend, e.g. `ours (gpu)`.
pub fn variant_label(r: &Row) -> String {
    format!("{} ({})", r.variant, r.backend)
}

/// The group a row is summarized in: by distance for the distance path, else by camera (a
/// path's frames and a named camera's differ too much to share one interval); always by
/// variant and setting.
pub fn group_key(x_axis: &str, r: &Row) -> String {
    match x_axis {
        "distance" => format!("{:>6} m, {}, {}", r.distance_m, variant_label(r), r.setting),
        _ => format!("{}, {}, {}", r.camera, variant_label(r), r.setting),
    }
}

/// Reads a sweep's CSV ([`crate::sweep::read_csv`]).
pub fn read_rows(path: &Path) -> Result<Vec<Row>, InputError> {
    crate::sweep::read_csv(path)
}

/// `mean ± half` with `digits` decimals; `-` for NaN, no `±` without an interval.
fn pm(mean: f64, half: f64, digits: usize) -> String {
    if mean.is_nan() {
        "-".into()
    } else if half.is_nan() {
        format!("{mean:.digits$}")
    } else {
        format!("{mean:.digits$} ± {half:.digits$}")
    }
}

/// `v` with `digits` decimals, `-` for NaN.
fn opt(v: f64, digits: usize) -> String {
    if v.is_nan() {
        "-".into()
    } else {
        format!("{v:.digits$}")
    }
}

fn ms(s: f64) -> String {
    format!("{:.2}", s * 1e3)
}

fn big(v: f64) -> String {
    if v.is_nan() {
        "-".into()
    } else if v >= 1e6 {
        format!("{:.2}M", v / 1e6)
    } else if v >= 1e3 {
        format!("{:.1}k", v / 1e3)
    } else {
        format!("{v:.0}")
    }
}

/// The Pareto front of `points` `(x, y)`, both to be small: the indices of the points no other
/// point beats on both (at most as large on each, smaller on one), by increasing `x` (ties in
/// input order). The one front rule of the report: [`pareto`] and the trade plots
/// ([`trade::fronts`]).
pub fn pareto_indices(points: &[(f64, f64)]) -> Vec<usize> {
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let a = points[i];
            !points
                .iter()
                .any(|b| b.0 <= a.0 && b.1 <= a.1 && (b.0 < a.0 || b.1 < a.1))
        })
        .collect();
    front.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    front
}

/// Groups whose (frame time, FLIP mean) no other group beats on both (the Pareto front), fastest
/// first.
pub fn pareto(groups: &[(String, Summary)]) -> Vec<(String, Summary)> {
    let xy: Vec<(f64, f64)> = groups
        .iter()
        .map(|(_, s)| (s.frame_s, s.flip_mean))
        .collect();
    pareto_indices(&xy)
        .into_iter()
        .map(|i| groups[i].clone())
        .collect()
}

/// A pose's identity within a camera: what pairs two groups' frames (the same view rendered
/// with two settings).
fn pose_key(r: &Row) -> (String, String, u32, u32, String) {
    (
        r.scene.clone(),
        r.camera.clone(),
        r.yaw_deg.to_bits(),
        r.distance_m.to_bits(),
        format!("{}x{} {}", r.width, r.height, r.backend),
    )
}

/// Mean and 95% half-width of the per-pose differences `f(a) - f(b)` over the poses both groups
/// rendered whose truth shows trees (NaN differences skipped).
pub fn paired_difference(a: &[&Row], b: &[&Row], f: fn(&Row) -> f64) -> (f64, f64, usize) {
    let diffs: Vec<f64> = a
        .iter()
        .filter(|r| r.accuracy.gt_tree_fraction > 0.0)
        .filter_map(|r| {
            let k = pose_key(r);
            let o = b.iter().find(|o| pose_key(o) == k)?;
            let d = f(r) - f(o);
            d.is_finite().then_some(d)
        })
        .collect();
    let (m, h) = mean_ci(&diffs);
    (m, h, diffs.len())
}

/// Each group's errors against the first group of its camera (or distance: the key's first
/// part, [`group_key`]), **paired by pose**: the mean of the per-frame differences with its 95%
/// Student-t interval ([`paired_difference`]). Views differ far more than settings do, so pairing
/// removes the pose-to-pose spread an unpaired comparison of the two means would carry. A
/// difference is *outside the noise* when its interval excludes 0.
pub fn noise_section(out: &mut String, groups: &[(String, Vec<&Row>)]) {
    let camera = |k: &str| k.split(", ").next().unwrap_or("").to_string();
    let mut firsts: Vec<(String, usize)> = Vec::new();
    for (i, (k, _)) in groups.iter().enumerate() {
        if !firsts.iter().any(|(c, _)| *c == camera(k)) {
            firsts.push((camera(k), i));
        }
    }
    if groups.len() <= firsts.len() {
        return; // no group has a first one to be compared with
    }
    let _ = writeln!(
        out,
        "Differences from the first group of the same camera, paired by pose (mean of the per-frame differences ± its 95% interval; *outside the noise* when the interval excludes 0):\n"
    );
    let _ = writeln!(
        out,
        "| group | against | pairs | LOD error | LOD error, billboards | total error | temporal error | FLIP (1 sample) |"
    );
    let _ = writeln!(out, "|---|---|--:|--:|--:|--:|--:|--:|");
    let cell = |(m, h, _): (f64, f64, usize)| {
        if m.is_nan() {
            "-".to_string()
        } else if h.is_nan() {
            format!("{m:+.4} (one pair: no interval)")
        } else if m.abs() > h {
            format!("{m:+.4} ± {h:.4} (**outside the noise**)")
        } else {
            format!("{m:+.4} ± {h:.4} (within noise)")
        }
    };
    for (i, (k, rows)) in groups.iter().enumerate() {
        let Some(&(_, first)) = firsts.iter().find(|(c, _)| *c == camera(k)) else {
            continue;
        };
        if first == i {
            continue;
        }
        let (fk, base) = (&groups[first].0, &groups[first].1);
        let lod = paired_difference(rows, base, |r| r.accuracy.lod_flip_mean);
        // Issue 30: the billboards' own LOD error (NaN, so skipped, where a frame has none).
        let billboard = paired_difference(rows, base, |r| r.accuracy.lod_flip_billboard);
        let total = paired_difference(rows, base, |r| r.accuracy.total_flip_mean);
        let flip = paired_difference(rows, base, |r| r.accuracy.flip_mean);
        // A path's first pose has no temporal error: it pairs nothing (NaN is skipped).
        let temporal = paired_difference(rows, base, |r| r.temporal_mean.unwrap_or(f64::NAN));
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            md(k),
            md(fk),
            lod.2.max(flip.2),
            cell(lod),
            cell(billboard),
            cell(total),
            cell(temporal),
            cell(flip)
        );
    }
    let _ = writeln!(out);
}

/// The trade per scene and camera ([`trade`]): the sweep's trade plots, and under each its
/// Pareto front with the intervals of its points. A run written before the trade plots existed
/// (or before they were drawn per camera) gets the fronts and a hint to redraw the plots
/// (`--replot`).
fn trade_section(out: &mut String, m: &Manifest, rows: &[Row], rel: &dyn Fn(&str) -> String) {
    let views = trade::views(rows);
    let any = views.iter().any(|v| {
        let points = trade::trade_points(rows, &v.scene, &v.camera);
        !trade::plots(&points).is_empty()
    });
    if !any {
        return; // no group shows a tree
    }
    let _ = writeln!(
        out,
        "### The trade: cost against error

Per scene and camera, one point per variant / backend / setting: mean error against mean frame time and mean tree fragments (reference backend only), over the group's frames that show trees, with 95% intervals. The error is the LOD error (FLIP against the same backend's full-detail frame), the total error and the temporal error where the sweep measured them, else FLIP against the ray-traced truth. The **Pareto front** (per backend: times of two backends are not comparable) is the groups no other group beats on both; in the plots its points are numbered and joined by a line. Each plot is also written as SVG beside the PNG.
"
    );
    for view in &views {
        let points = trade::trade_points(rows, &view.scene, &view.camera);
        for (cost, error) in trade::plots(&points) {
            let fronts = trade::fronts(&points, cost, error);
            let name = trade::plot_name(&view.stem, cost, error);
            let plot = m.plots.iter().find(|(p, _)| *p == name);
            let _ = writeln!(
                out,
                "Scene {}, camera {}, {} against {}:
",
                crate::html::code_span(&view.scene),
                crate::html::code_span(&view.camera),
                cost.label(),
                error.name()
            );
            match plot {
                Some((p, caption)) => {
                    let caption = md(caption);
                    let _ = writeln!(
                        out,
                        "![{caption}]({})

*{caption}*
",
                        rel(p)
                    );
                }
                None => {
                    let _ = writeln!(
                        out,
                        "(No plot in this run: `forestlod report --replot` draws it.)
"
                    );
                }
            }
            let _ = writeln!(
                out,
                "| # | Pareto front | backend | frames | {} ±95% | {} ±95% |
|--:|---|---|--:|--:|--:|",
                error.name(),
                cost.label()
            );
            let mut number = 0;
            for (backend, front) in &fronts {
                for &i in front {
                    number += 1;
                    let p = &points[i];
                    let (e, eh) = error.of(p);
                    let (c, h) = cost.of(p);
                    let _ = writeln!(
                        out,
                        "| {number} | **{}** | {} | {} | {} | {} |",
                        md(&p.group),
                        md(backend),
                        p.frames,
                        pm(e, eh, 4),
                        if cost == trade::Cost::Fragments {
                            if h.is_nan() {
                                big(c)
                            } else {
                                format!("{} ± {}", big(c), big(h))
                            }
                        } else {
                            pm(c, h, 2)
                        }
                    );
                }
            }
            let _ = writeln!(out);
        }
    }
}

/// The error a sweep's finding is about: the first of [`trade::errors`] over all its rows.
fn headline_error(rows: &[Row]) -> trade::ErrorKind {
    let measured = |f: fn(&Row) -> f64| rows.iter().any(|r| f(r).is_finite());
    if measured(|r| r.accuracy.lod_flip_mean) {
        trade::ErrorKind::Lod
    } else if measured(|r| r.accuracy.total_flip_mean) {
        trade::ErrorKind::Total
    } else {
        trade::ErrorKind::Truth
    }
}

/// The per-frame value of `error`.
fn error_value(error: trade::ErrorKind) -> fn(&Row) -> f64 {
    match error {
        trade::ErrorKind::Lod => |r| r.accuracy.lod_flip_mean,
        trade::ErrorKind::Total => |r| r.accuracy.total_flip_mean,
        trade::ErrorKind::Temporal => |r| r.temporal_mean.unwrap_or(f64::NAN),
        trade::ErrorKind::Truth => |r| r.accuracy.flip_mean,
    }
}

/// One sentence saying what a sweep found, from the paired intervals of [`noise_section`]: each
/// group against the first group of its camera (or distance), paired by pose, in the headline
/// error ([`headline_error`]) and in frame time; how many differences are *outside the noise*
/// (the 95 % interval of the mean paired difference excludes 0), and the largest of them.
pub fn finding(m: &Manifest, rows: &[Row]) -> String {
    let error = headline_error(rows);
    let mut order: Vec<String> = Vec::new();
    let mut groups: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    for r in rows {
        let k = group_key(&m.x_axis, r);
        if !groups.contains_key(&k) {
            order.push(k.clone());
        }
        groups.entry(k).or_default().push(r);
    }
    let camera = |k: &str| k.split(", ").next().unwrap_or("").to_string();
    let mut firsts: Vec<(String, String)> = Vec::new();
    for k in &order {
        if !firsts.iter().any(|(c, _)| *c == camera(k)) {
            firsts.push((camera(k), k.clone()));
        }
    }
    // (group, against, error difference, time difference)
    type Diff = (f64, f64, usize);
    let mut diffs: Vec<(String, String, Diff, Diff)> = Vec::new();
    for k in &order {
        let Some((_, first)) = firsts.iter().find(|(c, _)| *c == camera(k)) else {
            continue;
        };
        if first == k {
            continue;
        }
        let (a, b) = (&groups[k], &groups[first]);
        diffs.push((
            k.clone(),
            first.clone(),
            paired_difference(a, b, error_value(error)),
            paired_difference(a, b, |r| r.frame_s * 1e3),
        ));
    }
    let outside = |d: &Diff| d.0.is_finite() && d.1.is_finite() && d.0.abs() > d.1;
    let compared: Vec<_> = diffs
        .iter()
        .filter(|(_, _, e, _)| e.0.is_finite())
        .collect();
    if compared.is_empty() {
        return format!(
            "one group per {}: nothing to compare, see the plots for the trade.",
            if m.x_axis == "distance" {
                "distance"
            } else {
                "camera"
            }
        );
    }
    let out_error: Vec<_> = compared.iter().filter(|(_, _, e, _)| outside(e)).collect();
    let out_time = compared.iter().filter(|(_, _, _, t)| outside(t)).count();
    let mut s = format!(
        "of {} groups compared with the first of their {} (paired by pose), {} differ in {} outside the noise",
        compared.len(),
        if m.x_axis == "distance" {
            "distance"
        } else {
            "camera"
        },
        out_error.len(),
        error.name()
    );
    if let Some((k, first, e, _)) = out_error
        .iter()
        .max_by(|a, b| a.2.0.abs().total_cmp(&b.2.0.abs()))
    {
        let _ = write!(
            s,
            " (largest: {} against {}, {:+.4} ± {:.4})",
            code_span(k.trim()),
            code_span(first.trim()),
            e.0,
            e.1
        );
    }
    let _ = write!(
        s,
        ", {} within it; {} differ in frame time outside the noise.",
        compared.len() - out_error.len(),
        out_time
    );
    s
}

fn sweep_section(out: &mut String, dir: &Path, m: &Manifest, rows: &[Row]) {
    let rel = |p: &str| dest(&rel(dir, m, p));
    let _ = writeln!(
        out,
        "## {}\n",
        md(&format!("{} ({})", m.title, m.scenes.join(", ")))
    );
    if !m.description.is_empty() {
        let _ = writeln!(out, "{}\n", md(m.description.trim()));
    }
    let bvh: Vec<String> = m
        .ground_truth_bvh
        .iter()
        .map(|(s, t, secs)| format!("{s}: {t} triangles, built in {secs:.2} s"))
        .collect();
    let truth_cost = format!(
        "traced on {}; {:.1} s tracing{}{}",
        if m.ground_truth_layout.is_empty() {
            "the full frame".to_string()
        } else {
            md(&m.ground_truth_layout.join(", "))
        },
        m.ground_truth_seconds.unwrap_or(f64::NAN),
        m.ground_truth_memory_bytes
            .map(|b| format!(", {:.1} MB held (BVH, triangles, textures)", b as f64 / 1e6))
            .unwrap_or_default(),
        if m.total_error {
            format!(
                "; total error: our frames rendered again at {0}x{0} samples per pixel and box-filtered",
                (m.ground_truth_spp as f64).sqrt().round()
            )
        } else {
            "; total error not measured".to_string()
        }
    );
    let _ = writeln!(
        out,
        "Setup: scenes {}; variants {}; backends {}{}; {}x{} pixels; ground truth {} rays/pixel ({} rays, BVH {}; {truth_cost}); \
         {} frames in {:.1} s{}. Data: [{}]({}).\n",
        md(&m.scenes.join(", ")),
        md(&m.variants.join(", ")),
        if m.backends.is_empty() {
            "reference".to_string()
        } else {
            md(&m.backends.join(", "))
        },
        m.gpu_adapter
            .as_ref()
            .map(|a| format!(" (GPU: {})", md(a)))
            .unwrap_or_default(),
        m.width,
        m.height,
        m.ground_truth_spp,
        m.ground_truth_rays,
        md(&bvh.join("; ")),
        m.frames,
        m.wall_seconds,
        if m.quick {
            " (**quick mode**: a smoke test, not a measurement)"
        } else {
            ""
        },
        code_span(&m.csv),
        rel(&m.csv)
    );

    // Summary table.
    let mut groups: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    let mut order: Vec<String> = Vec::new();
    for r in rows {
        let k = group_key(&m.x_axis, r);
        if !groups.contains_key(&k) {
            order.push(k.clone());
        }
        groups.entry(k).or_default().push(r);
    }
    if m.x_axis == "distance" {
        order.sort();
    }
    let summaries: Vec<(String, Summary)> = order
        .iter()
        .map(|k| (k.clone(), summarize(groups[k].iter().copied())))
        .collect();
    let _ = writeln!(
        out,
        "| group | frames (no tree) | frame ms ±95% | select ms | draw ms | commands | trees finer / coarser | triangles | fragments | points | overdraw | memory MB | FLIP mean ±95% | FLIP p95 | FLIP p99 | coverage err | LOD error ±95% | LOD p99 | LOD changed | total error ±95% | total coverage err | temporal error ±95% (pairs) | temporal p99 | truth traced |"
    );
    let _ = writeln!(
        out,
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"
    );
    for (k, s) in &summaries {
        let _ = writeln!(
            out,
            "| {} | {} ({}) | {} | {} | {} | {} | {} / {} | {} | {} | {} | {} | {:.2} | {} | {:.4} | {:.4} | {:.4} | {} | {} | {} | {} | {} | {} | {} | {} |",
            md(k),
            s.frames,
            s.empty,
            pm(s.frame_s * 1e3, s.frame_ci * 1e3, 2),
            ms(s.select_s),
            ms(s.draw_s),
            big(s.commands),
            big(s.trees_finer),
            big(s.trees_coarser),
            big(s.triangles),
            big(s.fragments),
            big(s.points_drawn),
            if s.overdraw.is_nan() {
                "-".to_string()
            } else {
                format!("{:.2}", s.overdraw)
            },
            s.memory_bytes / 1e6,
            pm(s.flip_mean, s.flip_ci, 4),
            s.flip_p95,
            s.flip_p99,
            s.coverage_error,
            pm(s.lod_flip_mean, s.lod_flip_ci, 4),
            opt(s.lod_flip_p99, 4),
            if s.lod_changed.is_nan() {
                "-".to_string()
            } else {
                format!("{:.2}%", s.lod_changed * 100.0)
            },
            pm(s.total_flip_mean, s.total_flip_ci, 4),
            opt(s.total_coverage_error, 4),
            if s.temporal_frames == 0 {
                "-".to_string()
            } else {
                format!(
                    "{} ({})",
                    pm(s.temporal_mean, s.temporal_ci, 4),
                    s.temporal_frames
                )
            },
            opt(s.temporal_p99, 4),
            if s.frames == 0 {
                "-".to_string()
            } else {
                format!("{:.1}%", s.truth_fraction * 100.0)
            },
        );
    }
    let _ = writeln!(out);
    let grouped: Vec<(String, Vec<&Row>)> = order
        .iter()
        .map(|k| (k.clone(), groups[k].clone()))
        .collect();
    noise_section(out, &grouped);

    // Ratios against the baselines, per camera (or overall).
    if m.variants.len() > 1 && m.variants.iter().any(|v| v == "ours") {
        let _ = writeln!(
            out,
            "Speed-up of ours (mean frame time of the baseline / ours, same frames, same backend) and accuracy:\n"
        );
        let _ = writeln!(
            out,
            "| backend | camera | ours ms | vegetation ms | primitive ms | vegetation / ours | primitive / ours | FLIP ours / veg / prim | coverage err ours / veg / prim |"
        );
        let _ = writeln!(out, "|---|---|--:|--:|--:|--:|--:|---|---|");
        let mut pairs: Vec<(String, String)> = Vec::new();
        for r in rows {
            let key = (r.backend.clone(), r.camera.clone());
            if !pairs.contains(&key) {
                pairs.push(key);
            }
        }
        for (backend, cam) in pairs {
            let s = |v: &str| {
                summarize(
                    rows.iter()
                        .filter(|r| r.camera == cam && r.variant == v && r.backend == backend),
                )
            };
            let (o, veg, prim) = (s("ours"), s("vegetation"), s("primitive"));
            // No ratio for frames that drew nothing; a ratio whose two means lie within each
            // other's 95% interval is marked as noise.
            let ratio = |b: &Summary| {
                if b.frames == 0 || o.frames == 0 || o.commands <= 0.0 || o.frame_s <= 0.0 {
                    "-".to_string()
                } else if within_noise((b.frame_s, b.frame_ci), (o.frame_s, o.frame_ci)) {
                    format!("{:.2}x (within noise)", b.frame_s / o.frame_s)
                } else {
                    format!("{:.2}x", b.frame_s / o.frame_s)
                }
            };
            let f = |s: &Summary, v: f64| {
                if s.frames == 0 {
                    "-".into()
                } else {
                    format!("{v:.4}")
                }
            };
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} | {} | {} / {} / {} | {} / {} / {} |",
                md(&backend),
                md(&cam),
                ms(o.frame_s),
                if veg.frames > 0 {
                    ms(veg.frame_s)
                } else {
                    "-".into()
                },
                if prim.frames > 0 {
                    ms(prim.frame_s)
                } else {
                    "-".into()
                },
                ratio(&veg),
                ratio(&prim),
                f(&o, o.flip_mean),
                f(&veg, veg.flip_mean),
                f(&prim, prim.flip_mean),
                f(&o, o.coverage_error),
                f(&veg, veg.coverage_error),
                f(&prim, prim.coverage_error),
            );
        }
        let _ = writeln!(out);
    }

    // Pareto fronts: per camera for 360° sweeps (cameras are not comparable), per distance for
    // the distance path, over all settings otherwise.
    let mut sections: Vec<String> = Vec::new();
    // Times of different backends are not comparable: one front per backend.
    let section_of = |r: &Row| match m.x_axis.as_str() {
        "yaw" => format!("{} ({})", r.camera, r.backend),
        "distance" => format!("{} m ({})", r.distance_m, r.backend),
        _ => format!("all frames ({})", r.backend),
    };
    for r in rows {
        let s = section_of(r);
        if !sections.contains(&s) {
            sections.push(s);
        }
    }
    if summaries.len() > 1 {
        let _ = writeln!(
            out,
            "Best speed/accuracy trade-offs (Pareto front of mean frame time against mean FLIP: every other group is slower *and* less accurate than one of these):
"
        );
        for section in &sections {
            let in_section: Vec<(String, Summary)> = summaries
                .iter()
                .filter(|(k, _)| groups[k].first().is_some_and(|r| section_of(r) == *section))
                .cloned()
                .collect();
            let front = pareto(&in_section);
            let _ = writeln!(
                out,
                "- {}: {}",
                md(section),
                front
                    .iter()
                    .map(|(k, s)| format!(
                        "**{}** ({} ms, FLIP {:.4})",
                        md(k.trim()),
                        ms(s.frame_s),
                        s.flip_mean
                    ))
                    .collect::<Vec<_>>()
                    .join("; ")
            );
        }
        let _ = writeln!(out);
    }

    trade_section(out, m, rows, &rel);

    // Plots (the trade plots are shown above).
    for (p, caption) in &m.plots {
        if p.starts_with(trade::TRADE_PREFIX) {
            continue;
        }
        let caption = md(caption);
        let _ = writeln!(out, "![{caption}]({})\n\n*{caption}*\n", rel(p));
    }

    // Frames side by side.
    if !m.images.is_empty() {
        let _ = writeln!(out, "### Frames\n");
        let _ = writeln!(
            out,
            "Per pose and variant, side by side: the ray-traced **ground truth**, the **frame** the variant rendered on its backend, and the error maps: **FLIP error** against the truth, **LOD error** against the same backend's full-detail frame, **total error** at the truth's sampling rate; then the **LOD ids** (colours of E Fig. 3.1). The error maps' colour scale: ![FLIP error scale]({FLIP_SCALE})\n"
        );
        let _ = writeln!(
            out,
            "| pose | variant / setting | ground truth | frame | FLIP error | LOD error | total error | LOD ids |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
        // The worst frames first (FLIP against the truth).
        let mut images: Vec<_> = m.images.iter().collect();
        images.sort_by(|a, b| b.accuracy.flip_mean.total_cmp(&a.accuracy.flip_mean));
        for im in images {
            let pose = if im.camera == "distance" {
                format!("distance {} m", im.distance_m)
            } else {
                format!("{} yaw {}°", md(&im.camera), im.yaw_deg)
            };
            let _ = writeln!(
                out,
                "| {pose} | {} ({}) / {} (FLIP {:.4}, cov {:.4}, LOD error {}, total error {}) | ![]({}) | ![]({}) | ![]({}) | {} | {} | ![]({}) |",
                md(&im.variant),
                if im.backend.is_empty() {
                    "reference".to_string()
                } else {
                    md(&im.backend)
                },
                md(&im.setting),
                im.accuracy.flip_mean,
                im.accuracy.coverage_error,
                opt(im.accuracy.lod_flip_mean, 4),
                opt(im.accuracy.total_flip_mean, 4),
                rel(&im.ground_truth),
                rel(&im.color),
                rel(&im.flip),
                if im.lod_flip.is_empty() {
                    "-".to_string()
                } else {
                    format!("![]({})", rel(&im.lod_flip))
                },
                if im.total_flip.is_empty() {
                    "-".to_string()
                } else {
                    format!("![]({})", rel(&im.total_flip))
                },
                rel(&im.lod)
            );
        }
        let _ = writeln!(out);
        let with_lod: Vec<_> = m.images.iter().filter(|i| !i.per_lod.is_empty()).collect();
        if !with_lod.is_empty() {
            let _ = writeln!(
                out,
                "Per-LOD FLIP maps of ours (the error where the frame drew LOD0, LOD1, the transition band, ground, sky; mean FLIP and pixel count in the caption): against the truth at 1 sample (`truth`, on the truth's tiles when sampled), the LOD error's (`LOD`, full frame) and the total error's (`total`, at the truth's sampling rate, on its tiles):\n"
            );
            for im in with_lod {
                let cells: Vec<String> = im
                    .per_lod
                    .iter()
                    .map(|m| (m, "truth"))
                    .chain(im.per_lod_lod_error.iter().map(|m| (m, "LOD")))
                    .chain(im.per_lod_total.iter().map(|m| (m, "total")))
                    .map(|((label, p, mean, px), against)| {
                        let label = md(label);
                        format!(
                            "![{label}]({})<br>{label} ({against}): {mean:.4} ({px} px)",
                            rel(p)
                        )
                    })
                    .collect();
                let _ = writeln!(
                    out,
                    "{} {} yaw {}° d {} m: \n\n| {} |\n|{}\n",
                    md(&im.setting),
                    md(&im.camera),
                    im.yaw_deg,
                    im.distance_m,
                    cells.join(" | "),
                    "---|".repeat(cells.len())
                );
            }
        }
    }
}

/// The file name of the FLIP colour scale the report writes beside its pages.
pub const FLIP_SCALE: &str = "flip_scale.png";

/// The file name of the page of the sweep in folder `folder` (beside the index).
pub fn sweep_page(folder: &str) -> String {
    format!("sweep-{folder}.html")
}

/// The index page's Markdown: the headline trade plot of every sweep, scene and camera first
/// (the first screen), then one sentence per sweep saying what it found ([`finding`]), each
/// linking to the sweep's page.
fn index_markdown(run: &Path, sweeps: &[(Sweep, Vec<Row>)]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "# forestlod: the speed–accuracy trade, measured\n");
    let _ = writeln!(
        out,
        "One plot per sweep, scene and camera: one point per variant (mean error against mean frame time over the frames that show trees, 95% intervals as bars), the **Pareto front** (no other variant is both faster and more accurate) as a line, its members numbered. Click a plot for full size; [what each sweep found](#what-each-sweep-found) is below the plots, and each sweep's page has its tables, plots and frames. Generated by {}; `report.md` (for reading in a repository) and `report.html` (one self-contained file, for mailing) hold the same.\n",
        code_span(&format!("forestlod report --run {}", run.display()))
    );
    let _ = writeln!(out, "## The trade per scene and camera\n");
    let mut line = String::new();
    for (Sweep { dir, m, .. }, rows) in sweeps {
        for view in trade::views(rows) {
            let points = trade::trade_points(rows, &view.scene, &view.camera);
            let Some(&(cost, error)) = trade::plots(&points).first() else {
                continue;
            };
            let name = trade::plot_name(&view.stem, cost, error);
            match m.plots.iter().find(|(p, _)| *p == name) {
                Some((p, _)) => {
                    let alt = md(&format!(
                        "{}: scene {}, camera {}, {} against {}",
                        m.name,
                        view.scene,
                        view.camera,
                        cost.label(),
                        error.name()
                    ));
                    let _ = write!(line, "![{alt}]({}) ", dest(&rel(dir, m, p)));
                }
                None => {
                    let _ = write!(
                        line,
                        "\n\n({}: scene {}, camera {}: no trade plot in this run; `forestlod report --replot` draws it.)\n\n",
                        code_span(&m.name),
                        code_span(&view.scene),
                        code_span(&view.camera)
                    );
                }
            }
        }
    }
    let _ = writeln!(out, "{}\n", line.trim_end());
    let _ = writeln!(out, "## What each sweep found\n");
    for (Sweep { dir, m, .. }, rows) in sweeps {
        let _ = writeln!(
            out,
            "- **[{}]({})** ({}): {}",
            md(&m.title),
            dest(&sweep_page(&folder(dir, m))),
            code_span(&m.name),
            finding(m, rows)
        );
    }
    let _ = writeln!(out);
    out
}

/// Writes the report of the run `run` from every `DIR/*/sweep.json`; returns the Markdown's
/// path. The pages (issue 35):
///
/// - `DIR/index.html`: the first screen, [`index_markdown`]; images linked, not embedded;
/// - `DIR/sweep-<folder>.html` ([`sweep_page`]): one page per sweep, its section of the report
///   with its images linked (lazy-loaded thumbnails that open the full image);
/// - `DIR/report.md`: every sweep on one page, for reading in a repository;
/// - `DIR/report.html`: `report.md` as one self-contained page (images embedded), for mailing;
/// - `DIR/flip_scale.png` (and `.svg`): the colour scale of the FLIP error maps.
///
/// Every input is read and checked (module docs) and every page is made before any is written,
/// so a refused run gets no report.
pub fn write_report(run: &Path) -> Result<PathBuf, InputError> {
    let mut checked = Run::new(run)?;
    let mut sweeps = Vec::new();
    let mut embeds = Embeds::new();
    for sweep in checked.sweeps()? {
        let rows = checked.rows(&sweep)?;
        embeds.append(&mut checked.images(&sweep)?);
        sweeps.push((sweep, rows));
    }
    // Built-in order first, then by name.
    let rank = |n: &str| {
        crate::sweep::BUILTIN_SWEEPS
            .iter()
            .position(|(b, _)| *b == n)
            .unwrap_or(usize::MAX)
    };
    sweeps
        .sort_by(|(a, _), (b, _)| (rank(&a.m.name), &a.m.name).cmp(&(rank(&b.m.name), &b.m.name)));
    let mut out = String::new();
    let _ = writeln!(out, "# forestlod: the speed–accuracy trade, measured\n");
    let _ = writeln!(
        out,
        "Generated by {} from the sweeps `forestlod sweep` wrote there. \
         Cost is measured on the backend each sweep names (its Setup line): the **reference (CPU)** \
         backend's wall-clock select and draw time of the software rasterizer, or the **GPU** \
         backend's submit-to-completion times of the wgpu twin (timestamp queries beside them in \
         the CSV where the adapter offers them); plus work counters that carry over to a GPU (commands, triangles, \
         fragments, points drawn under `lod1 = points`, overdraw) and memory (E Eq. 4.1). Accuracy is the error against a ray-traced \
         ground truth of full meshes for every tree, alpha-tested and supersampled (SPEC §10): FLIP \
         mean and 95th/99th percentiles, and the fraction of pixels whose tree / not-tree class \
         differs. Thesis references: E§5 (Eichner 2024). The error maps' colour scale: \
         ![FLIP error scale]({FLIP_SCALE})\n",
        code_span(&format!("forestlod report --run {}", run.display()))
    );
    let _ = writeln!(
        out,
        "What each sweep found (paired by pose; details in its section):\n"
    );
    for (Sweep { m, .. }, rows) in &sweeps {
        let heading = format!("{} ({})", m.title, m.scenes.join(", "));
        let anchor = crate::html::anchor(&heading);
        let _ = writeln!(
            out,
            "- [{}](#{anchor}) ({}): {}",
            md(&heading),
            code_span(&m.name),
            finding(m, rows)
        );
    }
    let _ = writeln!(out);
    // The FLIP scale is the report's own image: drawn into a private temporary folder (removed
    // whatever happens), embedded from there, and copied beside the pages with them, so a
    // refused run still gets nothing written.
    struct Scratch(PathBuf);
    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
    let scratch = Scratch(std::env::temp_dir().join(format!(
        "forestlod-report-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos())
    )));
    let write_error = |p: &Path, e: &dyn std::fmt::Display| {
        InputError::new(p.display().to_string(), "write", "", e.to_string())
    };
    std::fs::create_dir_all(&scratch.0).map_err(|e| write_error(&scratch.0, &e))?;
    let scale = scratch.0.join(FLIP_SCALE);
    crate::chart::colour_scale(
        &scale,
        "FLIP error (error maps: black 0, no error; yellow-white 1)",
        &|v| {
            let t = crate::metrics::error_image(&[v as f32], 1, 1).texels[0];
            [t[0], t[1], t[2]]
        },
    )
    .map_err(|e| write_error(&scale, &e))?;
    embeds.insert(
        FLIP_SCALE.to_string(),
        Some(crate::html::Embed {
            file: scale.clone(),
            named_by: "the report's FLIP colour scale".into(),
        }),
    );
    let mut pages: Vec<(PathBuf, String)> = Vec::new();
    let back = format!(
        "[← all sweeps](index.html) · the error maps' colour scale: ![FLIP error scale]({FLIP_SCALE})\n\n"
    );
    for (Sweep { dir, m, .. }, rows) in &sweeps {
        let mut section = String::new();
        sweep_section(&mut section, dir, m, rows);
        out.push_str(&section);
        let title = format!("forestlod: {}", m.title);
        pages.push((
            run.join(sweep_page(&folder(dir, m))),
            crate::html::linked_page(&format!("{back}{section}"), &embeds, &title),
        ));
    }
    let page = crate::html::report_page(&out, &embeds, "forestlod sweep report")?;
    let index = crate::html::linked_page(
        &index_markdown(run, &sweeps),
        &embeds,
        "forestlod: the speed–accuracy trade",
    );
    pages.push((run.join("index.html"), index));
    let path = run.join("report.md");
    pages.push((path.clone(), out));
    pages.push((run.join("report.html"), page));
    for (file, text) in &pages {
        std::fs::write(file, text).map_err(|e| write_error(file, &e))?;
    }
    for ext in ["png", "svg"] {
        let to = run.join(FLIP_SCALE).with_extension(ext);
        std::fs::copy(scale.with_extension(ext), &to).map_err(|e| write_error(&to, &e))?;
    }
    Ok(path)
}

/// Redraws the plots of every `DIR/*/sweep.json` from its CSV and records them in the manifest;
/// returns how many sweeps were redrawn. Every manifest and CSV is read and checked before the
/// first plot is drawn.
pub fn replot(run: &Path) -> Result<usize, InputError> {
    let err = |p: &Path, e: &dyn std::fmt::Display| {
        InputError::new(p.display().to_string(), "replot", "", e.to_string())
    };
    let checked = Run::new(run)?;
    let mut sweeps = Vec::new();
    for sweep in checked.sweeps()? {
        let rows = checked.rows(&sweep)?;
        let spec = match &sweep.m.spec {
            Some(spec) => spec.clone(),
            None => {
                let spec = crate::sweep::resolve(Some(&sweep.m.name))
                    .map_err(|e| e.within(checked.named_by(&sweep.mpath, "name", &sweep.m.name)))?
                    .pop()
                    .expect("resolve returns one spec for a name");
                if sweep.m.quick { spec.quick() } else { spec }
            }
        };
        sweeps.push((sweep, rows, spec));
    }
    let n = sweeps.len();
    for (Sweep { dir, mpath, mut m }, rows, spec) in sweeps {
        m.plots = crate::sweep::write_plots(&spec, &rows, &dir)?;
        m.spec = Some(spec);
        let json = serde_json::to_string_pretty(&m).map_err(|e| err(&mpath, &e))?;
        std::fs::write(&mpath, json).map_err(|e| err(&mpath, &e))?;
    }
    Ok(n)
}

/// `forestlod report`.
pub fn run(args: &ReportArgs) -> Result<(), Box<dyn std::error::Error>> {
    if args.replot {
        let n = replot(&args.run)?;
        println!("redrew the plots of {n} sweep(s)");
    }
    let path = write_report(&args.run)?;
    println!(
        "wrote {} (open this: the trade per sweep, scene and camera, and a page per sweep), {} and {} (self-contained)",
        args.run.join("index.html").display(),
        path.display(),
        args.run.join("report.html").display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_are_student_t_and_overlap_means_noise() {
        let (m, h) = mean_ci(&[1.0, 2.0, 3.0]);
        assert!((m - 2.0).abs() < 1e-12);
        assert!((h - 4.303 / 3f64.sqrt()).abs() < 1e-9, "{h}");
        assert!(mean_ci(&[5.0]).1.is_nan());
        assert!(mean_ci(&[]).0.is_nan());
        let many: Vec<f64> = (0..100).map(|i| (i % 2) as f64).collect();
        assert!((mean_ci(&many).1 - 1.96 * (0.25f64 * 100.0 / 99.0).sqrt() / 10.0).abs() < 1e-9);
        assert!(within_noise((1.0, 0.5), (1.8, 0.4)));
        assert!(!within_noise((1.0, 0.1), (1.8, 0.1)));
    }

    #[test]
    fn frames_without_trees_are_left_out_of_the_means() {
        let csv = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("results/angles_texture/angles_texture.csv");
        let rows = read_rows(&csv).unwrap();
        let (empty, full): (Vec<&Row>, Vec<&Row>) = rows
            .iter()
            .partition(|r| r.accuracy.gt_tree_fraction <= 0.0);
        assert!(
            !empty.is_empty() && !full.is_empty(),
            "the committed sweep has both kinds"
        );
        let s = summarize(rows.iter());
        assert_eq!((s.frames, s.empty), (full.len(), empty.len()));
        let mean = full.iter().map(|r| r.accuracy.flip_mean).sum::<f64>() / full.len() as f64;
        assert!((s.flip_mean - mean).abs() < 1e-12);
        assert!(s.flip_ci > 0.0 && s.frame_ci > 0.0);
        // Written before the LOD error existed: not measured, not zero.
        assert!(s.lod_flip_mean.is_nan());
    }

    /// Issue 33: the points column is the mean over the rows that counted points (ours on the
    /// reference), not over every frame; with none (older CSVs, the GPU) it is `-`, not 0.
    #[test]
    fn points_drawn_are_averaged_over_the_rows_that_counted_them() {
        let committed =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("results/angles_texture/angles_texture.csv");
        let template = read_rows(&committed).unwrap()[0].clone();
        let row = |points: Option<u64>| {
            let mut r = template.clone();
            r.accuracy.gt_tree_fraction = 0.3;
            r.points_drawn = points;
            r
        };
        let rows = [row(Some(10)), row(Some(30)), row(None)];
        let s = summarize(rows.iter());
        assert_eq!(s.frames, 3);
        assert_eq!(s.points_drawn, 20.0);
        let older = summarize(read_rows(&committed).unwrap().iter());
        assert!(older.points_drawn.is_nan(), "{}", older.points_drawn);
        assert_eq!(big(older.points_drawn), "-");
    }

    #[test]
    fn differences_are_paired_by_pose_and_marked_outside_or_within_the_noise() {
        let committed =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("results/angles_texture/angles_texture.csv");
        let template = read_rows(&committed).unwrap()[0].clone();
        // Three poses whose errors differ a lot; setting b adds 0.010 ± 0.0002 to each (outside
        // the noise once paired, though far inside the pose-to-pose spread), c adds ±0.001.
        let row = |camera: &str, yaw: f32, setting: &str, lod: f64| {
            let mut r = template.clone();
            (r.camera, r.yaw_deg, r.setting) = (camera.into(), yaw, setting.into());
            r.accuracy.gt_tree_fraction = 0.3;
            r.accuracy.lod_flip_mean = lod;
            r
        };
        let base = [0.01, 0.05, 0.09];
        let mut rows = Vec::new();
        for (i, (&l, yaw)) in base.iter().zip([0.0, 120.0, 240.0]).enumerate() {
            rows.push(row("orbit", yaw, "a", l));
            rows.push(row("orbit", yaw, "b", l + 0.010 + 0.0002 * i as f64));
            rows.push(row("orbit", yaw, "c", l + [0.001, -0.001, 0.0005][i]));
            rows.push(row("dolly", yaw, "a", 2.0 * l));
            rows.push(row("dolly", yaw, "b", 2.0 * l + [0.001, -0.001, 0.0][i]));
        }
        let mut groups: Vec<(String, Vec<&Row>)> = Vec::new();
        for r in &rows {
            let k = group_key("angle_count", r);
            match groups.iter_mut().find(|(g, _)| *g == k) {
                Some((_, v)) => v.push(r),
                None => groups.push((k, vec![r])),
            }
        }
        let mut out = String::new();
        noise_section(&mut out, &groups);
        let line = |setting: &str, camera: &str| {
            out.lines()
                .find(|l| l.starts_with(&format!("| {camera}, ours (reference), {setting} |")))
                .unwrap_or_else(|| panic!("{setting} {camera}:\n{out}"))
                .to_string()
        };
        assert!(line("b", "orbit").contains("+0.0102 ± 0.0005 (**outside the noise**)"));
        assert!(line("c", "orbit").contains("(within noise)"));
        // Compared with its own camera's first group, not the orbit's.
        let dolly = line("b", "dolly");
        assert!(
            dolly.contains("| dolly, ours (reference), a | 3 |"),
            "{dolly}"
        );
        assert!(dolly.contains("(within noise)"), "{dolly}");
        assert!(
            !out.contains("| orbit, ours (reference), a | orbit"),
            "no self-comparison"
        );
    }

    fn s(frame_s: f64, flip_mean: f64) -> Summary {
        Summary {
            frames: 1,
            frame_s,
            flip_mean,
            ..Summary::default()
        }
    }

    #[test]
    fn the_pareto_front_keeps_only_undominated_groups() {
        let groups = vec![
            ("fast bad".to_string(), s(1.0, 0.3)),
            ("slow good".to_string(), s(3.0, 0.1)),
            ("dominated".to_string(), s(3.5, 0.2)),
            ("middle".to_string(), s(2.0, 0.2)),
        ];
        let front: Vec<String> = pareto(&groups).into_iter().map(|(k, _)| k).collect();
        assert_eq!(front, ["fast bad", "middle", "slow good"]);
    }

    proptest::proptest! {
        /// Issue 35: a point is on the Pareto front if and only if no other point is better in
        /// both cost and error (at most as large in each, smaller in one); the front lists each
        /// such point once, by increasing first coordinate. Points come from a small grid, so
        /// ties and duplicates are frequent.
        #[test]
        fn a_point_is_on_the_front_iff_no_other_beats_it_on_both(
            points in proptest::collection::vec((0u8..6, 0u8..6), 0..14)
        ) {
            let points: Vec<(f64, f64)> =
                points.iter().map(|&(x, y)| (f64::from(x), f64::from(y))).collect();
            let front = pareto_indices(&points);
            let beats = |b: (f64, f64), a: (f64, f64)| {
                b.0 <= a.0 && b.1 <= a.1 && (b.0 < a.0 || b.1 < a.1)
            };
            for (i, &a) in points.iter().enumerate() {
                let beaten = points.iter().enumerate().any(|(j, &b)| j != i && beats(b, a));
                proptest::prop_assert_eq!(front.contains(&i), !beaten, "point {} {:?} in {:?}", i, a, points);
            }
            let mut unique = front.clone();
            unique.dedup();
            proptest::prop_assert_eq!(unique.len(), front.len());
            proptest::prop_assert!(front.windows(2).all(|w| points[w[0]].0 <= points[w[1]].0));
        }
    }
}
