//! Sharding a sweep over machines: `forestlod sweep --shard I/N` runs a deterministic 1/N of a
//! sweep's frames, `forestlod sweep merge --out DIR SHARD_DIR...` joins the shards into the result
//! the unsharded run writes (same rows in the same order, the plots drawn from all of them).
//!
//! The unit of work is one pose of one parameter set of one scene (its ground-truth image and
//! full-detail frame are shared by every variant and backend of the pose); units are numbered in
//! the sweep's canonical order and shard `I` takes the units `u` with `u mod N = I`, so the
//! shards of a 360° sweep each get every N-th yaw, not one slow camera each. Every row carries
//! its frame index ([`Row::frame`]), which the merge orders by. Timings differ between machines
//! as between runs; everything else is deterministic.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use forestlod_reference::InputError;

use super::plots::write_plots;
use super::rows::{Manifest, Row, read_csv, write_csv};

/// Shard `index` of `count` (`I/N` on the command line, `0 <= I < N`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which shard, from 0.
    pub index: usize,
    /// How many shards.
    pub count: usize,
}

impl Shard {
    /// Whether work unit `unit` (module docs) belongs to this shard.
    pub fn contains(self, unit: usize) -> bool {
        unit % self.count == self.index
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// `--shard auto` (issue 34): the shard from a scheduler's variables, read through `var`.
    /// `auto`: a Slurm job array, index `SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN` (min 0 when
    /// unset) of `SLURM_ARRAY_TASK_COUNT`. `auto/N`: a Kubernetes Indexed Job of `N` completions,
    /// index `JOB_COMPLETION_INDEX` (the Job's own variable; the count is not in the pod's
    /// environment, so it is given). Errors name the variable and its value.
    pub fn from_scheduler(
        text: &str,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<Self, String> {
        let num = |name: &str| -> Result<usize, String> {
            let v = var(name).ok_or_else(|| format!("shard {text:?}: {name} is not set"))?;
            v.trim()
                .parse()
                .map_err(|_| format!("shard {text:?}: {name}={v:?} is not a whole number"))
        };
        let (index, count, from) = if text == "auto" {
            if var("SLURM_ARRAY_TASK_ID").is_none() {
                return Err(format!(
                    "shard {text:?}: SLURM_ARRAY_TASK_ID is not set (for a Kubernetes Indexed Job give the count: --shard auto/N, index from JOB_COMPLETION_INDEX)"
                ));
            }
            let id = num("SLURM_ARRAY_TASK_ID")?;
            let min = match var("SLURM_ARRAY_TASK_MIN") {
                Some(_) => num("SLURM_ARRAY_TASK_MIN")?,
                None => 0,
            };
            let count = num("SLURM_ARRAY_TASK_COUNT")?;
            if id < min {
                return Err(format!(
                    "shard {text:?}: SLURM_ARRAY_TASK_ID {id} below SLURM_ARRAY_TASK_MIN {min}"
                ));
            }
            (id - min, count, "SLURM_ARRAY_TASK_ID")
        } else {
            let n = text
                .strip_prefix("auto/")
                .and_then(|n| n.trim().parse::<usize>().ok())
                .ok_or_else(|| format!("shard {text:?}: expected auto, auto/N or I/N"))?;
            (num("JOB_COMPLETION_INDEX")?, n, "JOB_COMPLETION_INDEX")
        };
        if count == 0 || index >= count {
            return Err(format!(
                "shard {text:?}: index {index} (from {from}) is not below the count {count}"
            ));
        }
        Ok(Self { index, count })
    }
}

impl FromStr for Shard {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        if text.starts_with("auto") {
            return Self::from_scheduler(text, |name| std::env::var(name).ok());
        }
        let bad = || format!("shard {text:?}: expected I/N with 0 <= I < N, e.g. 0/4");
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

/// Largest shard manifest (`sweep.json`) `sweep merge` reads: a manifest lists the sweep's
/// definition and the images of the first pose of each camera, tens of KiB for the built-in
/// sweeps; 16 MiB is room for the largest sweep [`super::MAX_SWEEP_FRAMES`] allows.
pub const MAX_SHARD_MANIFEST_BYTES: u64 = 16 << 20;

/// Largest image `sweep merge` copies from a shard: a PNG of a frame of at most
/// [`super::MAX_FRAME_SIDE`] pixels a side, uncompressed (256 MiB) plus headers.
pub const MAX_SHARD_IMAGE_BYTES: u64 = (256 << 20) + (1 << 20);

/// Reads a shard's manifest (issue 28): a regular file of at most [`MAX_SHARD_MANIFEST_BYTES`],
/// whose names that become paths are plain (`name`: a folder name, `csv`: a file name in it) and
/// whose sweep definition passes [`SweepSpec::validate`] (`merge` draws plots from it).
fn read_manifest(path: &Path) -> Result<Manifest, InputError> {
    let file = path.display().to_string();
    let text = forestlod_reference::files::read_text_limited(path, MAX_SHARD_MANIFEST_BYTES)?;
    let m: Manifest = serde_json::from_str(&text).map_err(|e| {
        InputError::new(
            file.clone(),
            format!("line {}, column {}", e.line(), e.column()),
            "",
            format!("invalid sweep.json: {e}"),
        )
    })?;
    let bad = |k: &str, v: &str, r: String| InputError::new(file.clone(), format!("key {k}"), v, r);
    super::check_folder_name(&m.name).map_err(|r| bad("name", &m.name, r))?;
    let csv_ok = m
        .csv
        .strip_suffix(".csv")
        .is_some_and(|stem| super::check_folder_name(stem).is_ok());
    if !csv_ok {
        return Err(bad(
            "csv",
            &m.csv,
            "expected a file name NAME.csv in the sweep folder (no folders, no `..`)".into(),
        ));
    }
    if let Some(spec) = &m.spec {
        spec.validate(&format!("{file}: key spec"))?;
        if spec.name != m.name {
            return Err(bad(
                "spec.name",
                &spec.name,
                format!("expected the manifest's name {:?}", m.name),
            ));
        }
    }
    Ok(m)
}

/// The image `p` that key `key` of the manifest of shard folder `dir` names, when it is a regular
/// file of at most [`MAX_SHARD_IMAGE_BYTES`] under `dir` named `img/...` without `..`;
/// otherwise an error naming the manifest, the key and the path (a merge reads only its shards).
/// Returns the file to copy.
fn check_image(dir: &Path, key: &str, p: &str) -> Result<PathBuf, InputError> {
    use std::path::Component;
    let manifest = dir.join("sweep.json").display().to_string();
    let bad = |r: String| InputError::new(manifest.clone(), format!("key {key}"), p, r);
    let rel = Path::new(p);
    if !rel.starts_with("img") || !rel.components().all(|c| matches!(c, Component::Normal(_))) {
        return Err(bad(
            "expected a path img/NAME in the shard's sweep folder, without `..`: a merge reads only its shards".into(),
        ));
    }
    let root = std::fs::canonicalize(dir).map_err(|e| bad(format!("{}: {e}", dir.display())))?;
    let file = dir.join(rel);
    let canon =
        std::fs::canonicalize(&file).map_err(|e| bad(format!("cannot be resolved ({e})")))?;
    if !canon.starts_with(&root) {
        return Err(bad(format!(
            "resolves to {}, outside the shard folder {}: a merge reads only its shards",
            canon.display(),
            root.display()
        )));
    }
    forestlod_reference::files::open_limited(&file, MAX_SHARD_IMAGE_BYTES)
        .map_err(|e| e.within(format!("{manifest}: key {key}")))?;
    Ok(file)
}

/// Joins shard runs (each a `--out` folder of `forestlod sweep --shard I/N`) into `out`: for every
/// sweep they hold, the rows of all N shards in canonical order, the saved images, the plots and
/// one manifest. Errors name the folder when a shard is missing, repeated, of another sweep
/// definition, or when two shards claim one frame.
///
/// Everything is read and checked before anything is written; `out_existed` says whether `out`
/// existed before (what a failed merge created there is removed again).
pub fn merge(
    shard_dirs: &[PathBuf],
    out: &Path,
    out_existed: bool,
) -> Result<Vec<Manifest>, Box<dyn std::error::Error>> {
    if shard_dirs.is_empty() {
        return Err(InputError::new(
            "<command line>",
            "sweep merge",
            "",
            "expected the shard folders to join",
        )
        .into());
    }
    // sweep name -> (shard dir, manifest)
    let mut sweeps: BTreeMap<String, Vec<(PathBuf, Manifest)>> = BTreeMap::new();
    for dir in shard_dirs {
        let entries = std::fs::read_dir(dir).map_err(|e| {
            InputError::new(
                dir.display().to_string(),
                "read",
                "",
                format!("{e}; expected a `forestlod sweep --shard` output folder"),
            )
        })?;
        let mut found = false;
        for entry in entries {
            let sub = entry?.path();
            let mpath = sub.join("sweep.json");
            // A `sweep.json` that is not a regular file is refused by `read_manifest`, not
            // skipped.
            if sub.is_dir() && std::fs::symlink_metadata(&mpath).is_ok() {
                let m = read_manifest(&mpath)?;
                found = true;
                sweeps.entry(m.name.clone()).or_default().push((sub, m));
            }
        }
        if !found {
            return Err(InputError::new(
                dir.display().to_string(),
                "sweep.json",
                "",
                "no sweep in this folder",
            )
            .into());
        }
    }
    // Everything checked and read first; then written.
    let mut plan = Vec::new();
    for (name, parts) in &sweeps {
        let first = &parts[0].1;
        let count = shard_of(&parts[0].0, first)?.count;
        // Shard index -> folder: a map, not a list of `count` (a manifest's count is its own
        // word: `0/1000000000000` must not allocate).
        let mut seen: BTreeMap<usize, &PathBuf> = BTreeMap::new();
        for (dir, m) in parts.iter() {
            let shard = shard_of(dir, m)?;
            let field = |what: &str, why: String| {
                InputError::new(
                    dir.join("sweep.json").display().to_string(),
                    what.to_string(),
                    shard.to_string(),
                    why,
                )
            };
            if shard.count != count {
                return Err(field(
                    "shard",
                    format!(
                        "sweep {name}: shards of {count} and of {} mixed",
                        shard.count
                    ),
                )
                .into());
            }
            if m.build != first.build {
                return Err(field(
                    "build",
                    format!(
                        "sweep {name}: made by {} but {} by {}: rerun the shards with one build",
                        m.build.as_deref().unwrap_or("an unknown build"),
                        parts[0].0.display(),
                        first.build.as_deref().unwrap_or("an unknown build")
                    ),
                )
                .into());
            }
            if serde_json::to_value(&m.spec)? != serde_json::to_value(&first.spec)?
                || m.quick != first.quick
                || m.spec_hash != first.spec_hash
            {
                return Err(field(
                    "spec",
                    format!(
                        "sweep {name}: not the sweep definition of {}",
                        parts[0].0.display()
                    ),
                )
                .into());
            }
            if let Some(other) = seen.insert(shard.index, dir) {
                return Err(field(
                    "shard",
                    format!("sweep {name}: shard given twice (also {})", other.display()),
                )
                .into());
            }
        }
        // Every missing index named (at most 32 of them, then a count).
        let missing: Vec<usize> = (0..count)
            .filter(|i| !seen.contains_key(i))
            .take(33)
            .collect();
        if !missing.is_empty() {
            let mut names: Vec<String> = missing
                .iter()
                .take(32)
                .map(|i| format!("{i}/{count}"))
                .collect();
            if missing.len() > 32 {
                names.push("...".into());
            }
            return Err(InputError::new(
                "<command line>",
                "sweep merge",
                format!("{name} {}", names.join(" ")),
                // The true count, not the named ones' (every index `seen` holds is below
                // `count`, checked above).
                match count - seen.len() {
                    1 => "a shard is missing".to_string(),
                    n => format!("{n} shards are missing"),
                },
            )
            .into());
        }
        let mut rows: Vec<Row> = Vec::new();
        let mut manifest = Manifest {
            shard: None,
            plots: Vec::new(),
            images: Vec::new(),
            wall_seconds: 0.0,
            ground_truth_rays: 0,
            ground_truth_seconds: first.ground_truth_seconds.map(|_| 0.0),
            ..first.clone()
        };
        // (path in the sweep folder, the shard's file)
        let mut images: Vec<(String, PathBuf)> = Vec::new();
        for (shard_dir, m) in parts {
            rows.extend(read_csv(&shard_dir.join(&m.csv))?);
            for (i, im) in m.images.iter().enumerate() {
                for (key, p) in im
                    .named_images(i)
                    .into_iter()
                    .filter(|(_, p)| !p.is_empty())
                {
                    if !images.iter().any(|(q, _)| q == p) {
                        images.push((p.clone(), check_image(shard_dir, &key, p)?));
                    }
                }
            }
            manifest.images.extend(m.images.iter().cloned());
            manifest.wall_seconds += m.wall_seconds;
            manifest.ground_truth_rays += m.ground_truth_rays;
            if let (Some(a), Some(b)) = (&mut manifest.ground_truth_seconds, m.ground_truth_seconds)
            {
                *a += b;
            }
        }
        rows.sort_by_key(|r| r.frame);
        if let Some(w) = rows.windows(2).find(|w| w[0].frame == w[1].frame) {
            return Err(InputError::new(
                "<command line>",
                "sweep merge",
                format!("{name} frame {}", w[0].frame),
                "two shards hold this frame",
            )
            .into());
        }
        manifest.images.sort_by_key(|im| im.frame);
        manifest.frames = rows.len();
        plan.push((name.clone(), manifest, rows, images));
    }
    let names: Vec<String> = plan.iter().map(|(n, ..)| n.clone()).collect();
    let mut guard = super::OutGuard::new(out, out_existed, &names);
    let mut merged = Vec::new();
    for (name, mut manifest, rows, images) in plan {
        let dir = out.join(&name);
        std::fs::create_dir_all(dir.join("img"))?;
        for (p, from) in images {
            let bytes = forestlod_reference::files::read_limited(&from, MAX_SHARD_IMAGE_BYTES)?;
            std::fs::write(dir.join(p), bytes)?;
        }
        write_csv(&dir.join(&manifest.csv), &rows)?;
        if let Some(spec) = &manifest.spec {
            manifest.plots = write_plots(spec, &rows, &dir)?;
        }
        std::fs::write(
            dir.join("sweep.json"),
            serde_json::to_string_pretty(&manifest)?,
        )?;
        merged.push(manifest);
    }
    guard.done = true;
    Ok(merged)
}

fn shard_of(dir: &Path, m: &Manifest) -> Result<Shard, InputError> {
    let file = dir.join("sweep.json").display().to_string();
    let text = m.shard.as_deref().ok_or_else(|| {
        InputError::new(
            file.clone(),
            "shard",
            "",
            "not a shard: run with --shard I/N",
        )
    })?;
    text.parse()
        .map_err(|e: String| InputError::new(file, "shard", text, e))
}

/// The build a shard's manifest names (issue 34): the package version and a 64-bit FNV-1a hash
/// of the running executable, so shards of different builds are not merged.
pub fn build_id() -> String {
    static ID: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ID.get_or_init(|| {
        let exe = std::env::current_exe()
            .ok()
            .and_then(|p| std::fs::read(p).ok())
            .map(|b| format!("{:016x}", fnv1a(&b)))
            .unwrap_or_else(|| "unknown".into());
        format!("forestlod {} {exe}", env!("CARGO_PKG_VERSION"))
    })
    .clone()
}

/// 64-bit FNV-1a of `bytes`: the hash of a shard's sweep definition and of its build.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--shard auto` under each scheduler's variables is the explicit shard: Slurm (with and
    /// without a non-zero array start), Kubernetes (`auto/N`); unset or inconsistent variables
    /// are errors naming the variable.
    #[test]
    fn auto_shards_are_the_explicit_ones() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| {
                pairs
                    .iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            }
        };
        let slurm = Shard::from_scheduler(
            "auto",
            env(&[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "5"),
            ]),
        );
        assert_eq!(slurm, "2/5".parse());
        let from_one = Shard::from_scheduler(
            "auto",
            env(&[
                ("SLURM_ARRAY_TASK_ID", "3"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ]),
        );
        assert_eq!(from_one, "2/4".parse());
        let k8s = Shard::from_scheduler("auto/6", env(&[("JOB_COMPLETION_INDEX", "5")]));
        assert_eq!(k8s, "5/6".parse());
        for (text, vars, want) in [
            ("auto", env(&[]), "SLURM_ARRAY_TASK_ID"),
            (
                "auto",
                env(&[("SLURM_ARRAY_TASK_ID", "1")]),
                "SLURM_ARRAY_TASK_COUNT",
            ),
            (
                "auto",
                env(&[
                    ("SLURM_ARRAY_TASK_ID", "4"),
                    ("SLURM_ARRAY_TASK_COUNT", "4"),
                ]),
                "not below",
            ),
            ("auto/3", env(&[]), "JOB_COMPLETION_INDEX"),
            (
                "auto/3",
                env(&[("JOB_COMPLETION_INDEX", "x")]),
                "JOB_COMPLETION_INDEX",
            ),
            ("auto/0", env(&[("JOB_COMPLETION_INDEX", "0")]), "not below"),
        ] {
            let e = Shard::from_scheduler(text, vars).unwrap_err();
            assert!(e.contains(want), "{text}: {e}");
        }
    }

    #[test]
    fn shards_parse_and_partition_the_units() {
        let s: Shard = "1/3".parse().unwrap();
        assert_eq!((s.index, s.count), (1, 3));
        assert_eq!(s.to_string(), "1/3");
        for bad in ["3/3", "1/0", "a/2", "1", "-1/2", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        for unit in 0..10 {
            let owners = (0..3)
                .filter(|&i| Shard { index: i, count: 3 }.contains(unit))
                .count();
            assert_eq!(owners, 1, "unit {unit}");
        }
    }
}
