//! Loading a sweep file (issue 28, "hostile input at every entry point"): the file is read through
//! [`forestlod_reference::files`] (a regular file of at most [`MAX_SWEEP_FILE_BYTES`]), parsed by
//! the pure [`parse_sweep_toml`], and every setting is checked there, before anything is built
//! or written:
//!
//! - **Validated where read, named where written.** An error names the sweep file, the line and
//!   column (from the TOML parser's spans: [`toml::de::DeTable`]), the key (`cameras[1].yaw_steps`)
//!   and the value. Parameters are checked by the parameter table ([`Params::validate`]), value by
//!   value where they are written, then on every parameter set.
//! - **Nothing given twice.** A parameter named twice in one table (`grid_size` and its flag
//!   spelling `grid-size`), an axis given twice (by any spelling), an axis that a setting or
//!   `[params]` also sets (its value would never be used), a repeated axis value, setting label,
//!   camera, distance, frame size, scene, variant or backend, and a top-level `resolutions` beside
//!   an explicit `width`/`height`, are errors (in `[quick]`, `resolutions` replaces its
//!   `width`/`height`, as the format documents). A `[quick]` axis must name an axis of the file.
//! - **Work and memory refused up front** ([`Estimate`], checked by [`SweepSpec::validate`]): the
//!   frames, the pixels rendered or traced, one frame's memory, the billboards' memory and the
//!   ground-truth images kept, each against a named limit, with the estimate in the error; a size
//!   whose product overflows is refused as such. The same checks run on the `[quick]` view of the
//!   file (naming the `[quick]` key that set a value) and on the sweep as configured from the
//!   command line.
//! - **Names that become paths are plain.** `name` is the output folder: letters, digits, `_`,
//!   `-` and `.`, not starting with `.` ([`check_folder_name`]).

use std::fmt;
use std::ops::Range;
use std::path::Path;

use forestlod_reference::InputError;
use forestlod_reference::error::line_col;
use forestlod_shared::Params;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

use super::spec::{QuickSpec, SweepSpec, canonical, same_param, set_param};

/// Largest sweep file read: the built-in ones are under 4 KiB; 1 MiB leaves room for long
/// descriptions and generated axes while a huge or endless file (`/dev/zero`) is refused
/// before it is read.
pub const MAX_SWEEP_FILE_BYTES: u64 = 1 << 20;

/// Most frames (CSV rows: scenes x parameter sets x frame sizes x poses x variants x backends)
/// one sweep may have. The largest built-in sweep has a few hundred; at a second a frame this
/// is more than a day of rendering, and the rows stay a few hundred MB in memory.
pub const MAX_SWEEP_FRAMES: u128 = 100_000;

/// Most pixels one sweep may render or trace ([`Estimate::pixel_work`]): each frame's timed
/// repeats, its untimed full-detail and warm-up renders, its total-error render at `samples²`
/// the pixels, and the ground truth's `samples²` rays per traced pixel. At the reference's
/// order of 10⁷ pixels a second this is more than a day.
pub const MAX_SWEEP_PIXEL_WORK: u128 = 1_000_000_000_000;

/// Largest frame side, pixels, and of the total error's supersampled frame (`samples` x the
/// side): wgpu's guaranteed 2D texture size, below the reference rasterizer's
/// [`forestlod_reference::raster::MAX_TARGET_SIZE`].
pub const MAX_FRAME_SIDE: u32 = 8192;

/// Most memory one frame may need ([`Estimate::frame_bytes`]): its render targets, every
/// variant's image kept for scoring, the total error's supersampled target and the ground-truth
/// image. An 8192x4608 frame with the total error fits (about 3.4 GiB), an 8192x8192 one does
/// not (6 GiB): a frame may take an eighth of a 32 GiB machine.
pub const MAX_FRAME_BYTES: u128 = 4 << 30;

/// Most memory the billboard bake may need: the reference's own limit
/// ([`forestlod_reference::bake::MAX_BAKE_BYTES`], 16 GiB, which `prepare` applies to the whole
/// scene), checked here at load for one species
/// ([`forestlod_reference::bake::bake_memory_bytes`], exact for what the bake keeps): a sweep
/// file does not say how many species its scenes have, so a scene of several species may still be
/// refused by `prepare` before anything is built. `--texture-size 4096 --angles 91` asks for
/// about 82 GiB a species.
pub const MAX_BILLBOARD_BYTES: u128 = forestlod_reference::bake::MAX_BAKE_BYTES as u128;

/// Most memory the ground-truth images of one sweep may take ([`Estimate::truth_bytes`]): the
/// runner keeps every pose's truth image for the whole run (they are shared by every parameter
/// set, variant and backend).
pub const MAX_TRUTH_BYTES: u128 = 8 << 30;

/// Bytes a render target and its scoring buffers take per pixel (colour, depth and LOD id, the
/// sRGB copy and the error maps).
const TARGET_BYTES_PER_PIXEL: u128 = 32;
/// Bytes each variant's frame keeps per pixel until the pose is scored (RGBA8 and LOD id).
const KEPT_BYTES_PER_PIXEL: u128 = 8;
/// Bytes a ground-truth image takes per traced pixel (linear RGB, sRGB, class, tree fraction).
const TRUTH_BYTES_PER_PIXEL: u128 = 24;

/// One step of a key path: a table key or an array index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Seg {
    /// A table key.
    Key(String),
    /// An array index.
    Index(usize),
}

/// A key path as errors print it: `cameras[1].yaw_steps`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct KeyPath(pub Vec<Seg>);

impl KeyPath {
    fn with(&self, seg: Seg) -> Self {
        let mut p = self.clone();
        p.0.push(seg);
        p
    }
    /// `self.key`.
    pub fn key(&self, k: impl Into<String>) -> Self {
        self.with(Seg::Key(k.into()))
    }
    /// `self[i]`.
    pub fn at(&self, i: usize) -> Self {
        self.with(Seg::Index(i))
    }
}

/// `KeyPath` from a first key.
pub(crate) fn key(k: impl Into<String>) -> KeyPath {
    KeyPath::default().key(k)
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, s) in self.0.iter().enumerate() {
            match s {
                Seg::Key(k) if i == 0 => write!(f, "{k}")?,
                Seg::Key(k) => write!(f, ".{k}")?,
                Seg::Index(n) => write!(f, "[{n}]")?,
            }
        }
        Ok(())
    }
}

/// A setting of a sweep that is refused: where (a key path, or none for the sweep as a whole),
/// the value and why. [`SweepSpec::check`] returns it; [`parse_sweep_toml`] turns it into an
/// [`InputError`] with the line and column, [`SweepSpec::validate`] without.
#[derive(Clone, Debug)]
pub(crate) struct Bad {
    /// The key; empty for the sweep's size as a whole (the work and memory limits).
    pub path: KeyPath,
    /// Point at the key itself rather than its value (a key that should not be there).
    pub at_key: bool,
    /// The value, formatted.
    pub value: String,
    /// Why.
    pub reason: String,
}

impl Bad {
    pub fn new(path: KeyPath, value: impl fmt::Display, reason: impl Into<String>) -> Self {
        Self {
            path,
            at_key: false,
            value: value.to_string(),
            reason: reason.into(),
        }
    }
    fn at_key(mut self) -> Self {
        self.at_key = true;
        self
    }
    fn position(&self) -> String {
        if self.path.0.is_empty() {
            "sweep size".into()
        } else {
            format!("key {}", self.path)
        }
    }
    /// The error naming `file` and the key (no line: the sweep has no text, or it was changed
    /// from the command line).
    pub fn without_text(self, file: &str) -> InputError {
        InputError::new(file, self.position(), self.value, self.reason)
    }
    /// The error naming `file`, the line and column of the key in `doc` (the file's text), the
    /// key and the value.
    fn in_text(self, file: &str, text: &str, doc: Option<&Spanned<DeTable>>) -> InputError {
        let span = doc.and_then(|d| locate(d, &self.path, self.at_key));
        let position = match span {
            Some(s) => {
                let (line, col) = line_col(text, s.start);
                format!("line {line}, column {col}, {}", self.position())
            }
            None => self.position(),
        };
        InputError::new(file, position, self.value, self.reason)
    }
}

/// The span of `path` in `doc`: the value's (or with `at_key`, the last key's), or the deepest
/// part of the path that exists.
fn locate(doc: &Spanned<DeTable>, path: &KeyPath, at_key: bool) -> Option<Range<usize>> {
    let mut found: Option<Range<usize>> = None;
    let mut table: Option<&DeTable> = Some(doc.get_ref());
    let mut array: Option<&[Spanned<DeValue>]> = None;
    for (i, seg) in path.0.iter().enumerate() {
        let last = i + 1 == path.0.len();
        let value = match seg {
            Seg::Key(k) => {
                let (key, value) = table?.iter().find(|(key, _)| key.get_ref() == k)?;
                if last && at_key {
                    return Some(key.span());
                }
                value
            }
            Seg::Index(n) => array?.get(*n)?,
        };
        found = Some(value.span());
        (table, array) = match value.get_ref() {
            DeValue::Table(t) => (Some(t), None),
            DeValue::Array(a) => (None, Some(&a[..])),
            _ => (None, None),
        };
    }
    found
}

/// The deepest key of `doc` whose key or value span holds byte `offset` (what a parser error at
/// `offset` is about), searching the whole document: the spans of `[[array]]` tables cover their
/// headers only.
fn key_at(doc: &Spanned<DeTable>, offset: usize) -> Option<KeyPath> {
    fn visit(v: &DeValue, path: &KeyPath, offset: usize, best: &mut Option<KeyPath>) {
        let mut consider = |p: KeyPath, spans: &[Range<usize>], child: &DeValue| {
            if spans.iter().any(|s| s.contains(&offset))
                && best.as_ref().is_none_or(|b| b.0.len() <= p.0.len())
            {
                *best = Some(p.clone());
            }
            visit(child, &p, offset, best);
        };
        match v {
            DeValue::Table(t) => {
                for (k, child) in t.iter() {
                    consider(
                        path.key(k.get_ref().to_string()),
                        &[k.span(), child.span()],
                        child.get_ref(),
                    );
                }
            }
            DeValue::Array(a) => {
                for (i, child) in a.iter().enumerate() {
                    consider(path.at(i), &[child.span()], child.get_ref());
                }
            }
            _ => {}
        }
    }
    let mut best = None;
    for (k, child) in doc.get_ref().iter() {
        let p = key(k.get_ref().to_string());
        if k.span().contains(&offset) || child.span().contains(&offset) {
            best = Some(p.clone());
        }
        visit(child.get_ref(), &p, offset, &mut best);
    }
    best
}

/// Each double-quoted or backquoted part of a parser's message cut to
/// [`forestlod_reference::error::MAX_EXCERPT_CHARS`] characters (marked `…`), on one line: the
/// TOML parser's messages quote the file's content.
fn cut_quoted(message: &str) -> String {
    let max = forestlod_reference::error::MAX_EXCERPT_CHARS;
    let mut out = String::new();
    let mut quote: Option<char> = None;
    let mut count = 0;
    for c in message.trim().chars() {
        let c = if c.is_control() { ' ' } else { c };
        match quote {
            None => {
                out.push(c);
                if c == '"' || c == '`' {
                    quote = Some(c);
                    count = 0;
                }
            }
            Some(q) if c == q => {
                if count > max {
                    out.push('…');
                }
                out.push(c);
                quote = None;
            }
            Some(_) => {
                count += 1;
                if count <= max {
                    out.push(c);
                }
            }
        }
    }
    if quote.is_some() && count > max {
        out.push('…');
    }
    out
}

/// The sweep file `text` (named `file` in errors), parsed and checked ([`SweepSpec::check`], on
/// the file and on its `[quick]` view). Pure: reads nothing else, so the fuzz target
/// (`fuzz/fuzz_targets/sweep_toml.rs`) and the property tests call it directly. Every error is
/// one line naming `file`, the line, column and key, and the value.
pub fn parse_sweep_toml(text: &str, file: &str) -> Result<SweepSpec, InputError> {
    let syntax = |e: toml::de::Error| {
        let (position, value) = forestlod_reference::error::span_position(text, e.span());
        InputError::new(
            file,
            position,
            value,
            format!("invalid sweep file: {}", cut_quoted(e.message())),
        )
    };
    // The spanned document first: TOML syntax and duplicate keys, and the lines of later errors.
    let doc = DeTable::parse(text).map_err(syntax)?;
    let spec: SweepSpec = toml::from_str(text).map_err(|e| {
        // A type error is about a key: name it.
        let at = e.span().and_then(|s| key_at(&doc, s.start));
        let mut err = syntax(e);
        if let Some(k) = at {
            err.position = format!("{}, key {k}", err.position);
        }
        err
    })?;
    let in_text = |b: Bad| b.in_text(file, text, Some(&doc));
    let top = doc.get_ref();
    let given = |k: &str| top.iter().any(|(key, _)| key.get_ref() == k);
    if !spec.resolutions.is_empty() {
        for k in ["width", "height"] {
            if given(k) {
                return Err(in_text(
                    Bad::new(
                        key(k),
                        k,
                        "`resolutions` gives the frame sizes: remove `width`/`height` (the size given twice)",
                    )
                    .at_key(),
                ));
            }
        }
    }
    spec.check().map_err(in_text)?;
    if let Some(q) = &spec.quick {
        let quick = spec.clone().quick();
        quick.check().map_err(|mut b| {
            b.path = quick_source(&b.path, q, &spec);
            if b.path.0.first() != Some(&Seg::Key("quick".into())) {
                b.reason = format!("{} (with the [quick] table applied)", b.reason);
            }
            in_text(b)
        })?;
    }
    Ok(spec)
}

/// Reads and parses a sweep file ([`parse_sweep_toml`]) through
/// [`forestlod_reference::files::read_text_limited`]: a regular file of at most
/// [`MAX_SWEEP_FILE_BYTES`].
pub fn load_sweep_file(path: &Path) -> Result<SweepSpec, InputError> {
    let text = forestlod_reference::files::read_text_limited(path, MAX_SWEEP_FILE_BYTES)?;
    parse_sweep_toml(&text, &path.display().to_string())
}

/// Where in the file a key of the `[quick]` view (`spec.quick()`) came from: its `[quick]` key
/// when that table set it, else the file's own key.
fn quick_source(path: &KeyPath, q: &QuickSpec, spec: &SweepSpec) -> KeyPath {
    let quick = key("quick");
    let segs = &path.0;
    let Some(Seg::Key(first)) = segs.first() else {
        return path.clone();
    };
    let rest = |from: usize, base: KeyPath| KeyPath([base.0, segs[from..].to_vec()].concat());
    let set = match first.as_str() {
        "scenes" => q.scenes.is_some(),
        "width" => q.width.is_some(),
        "height" => q.height.is_some(),
        "samples" => q.samples.is_some(),
        "backends" => q.backends.is_some(),
        "resolutions" => q.resolutions.is_some(),
        "truth_tiles" => q.truth_tiles.is_some(),
        _ => false,
    };
    if set {
        return rest(1, quick.key(first.clone()));
    }
    match (first.as_str(), segs.get(1), segs.get(2)) {
        ("cameras", Some(Seg::Index(_)), Some(Seg::Key(k))) => {
            let from = match k.as_str() {
                "yaw_steps" if q.yaw_steps.is_some() => "yaw_steps",
                "steps" if q.path_steps.is_some() => "path_steps",
                "distances" if q.distances.is_some() => "distances",
                _ => return path.clone(),
            };
            rest(3, quick.key(from))
        }
        ("axes", Some(Seg::Index(i)), Some(Seg::Key(v))) if v == "values" => {
            let axis = spec.axes.get(*i).map(|a| a.param.as_str()).unwrap_or("");
            match q.axes.as_ref().and_then(|m| {
                m.keys()
                    .find(|k| same_param(k, axis))
                    .map(|k| quick.key("axes").key(k.clone()))
            }) {
                Some(base) => rest(3, base),
                None => path.clone(),
            }
        }
        ("params", Some(Seg::Key(k)), _)
            if q.params.as_ref().is_some_and(|p| p.contains_key(k)) =>
        {
            rest(1, quick.key("params"))
        }
        _ => path.clone(),
    }
}

impl SweepSpec {
    /// Parses and validates a sweep file's text ([`parse_sweep_toml`]: errors name the file,
    /// line, column, key and value).
    pub fn parse(text: &str, file: &str) -> Result<Self, InputError> {
        parse_sweep_toml(text, file)
    }
}

/// Checks that `name` is a plain folder name: 1 to 64 letters, digits, `_`, `-` or `.`, not
/// starting with `.`. A sweep's name is its output folder (`--out/NAME`): a `/` or `..` would
/// write outside `--out`.
pub fn check_folder_name(name: &str) -> Result<(), String> {
    let ok = (1..=64).contains(&name.len())
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if ok {
        Ok(())
    } else {
        Err("expected 1 to 64 letters, digits, `_`, `-` or `.`, not starting with `.` (the output folder's name)".into())
    }
}

/// A parameter table (`[params]`, a setting, `[quick].params`): every key a known parameter, none
/// named twice (by any spelling), and each value valid for it (the parameter table's own check,
/// [`Params::validate`], on the value alone).
fn check_param_table<'a>(
    entries: impl Iterator<Item = (&'a String, &'a toml::Value)>,
    at: &KeyPath,
) -> Result<Vec<&'static str>, Bad> {
    let mut seen: Vec<(&'static str, &String)> = Vec::new();
    for (k, v) in entries {
        let path = at.key(k.clone());
        let name = check_param_value(k, v, &path)?;
        if let Some((_, first)) = seen.iter().find(|(n, _)| *n == name) {
            return Err(Bad::new(
                path,
                k,
                format!("parameter {name} given twice in this table (also as `{first}`)"),
            )
            .at_key());
        }
        seen.push((name, k));
    }
    Ok(seen.into_iter().map(|(n, _)| n).collect())
}

/// One parameter value, checked by the parameter table: returns the parameter's canonical name.
fn check_param_value(k: &str, v: &toml::Value, path: &KeyPath) -> Result<&'static str, Bad> {
    if k == super::spec::PRESET_KEY {
        let mut p = Params::default();
        super::spec::apply_preset(&mut p, v, "").map_err(|e| {
            Bad::new(
                path.clone(),
                super::spec::value_label(v),
                e.reason.to_string(),
            )
        })?;
        return Ok(super::spec::PRESET_KEY);
    }
    let Some(name) = canonical(k) else {
        return Err(Bad::new(
            path.clone(),
            k,
            format!(
                "unknown parameter; expected {}",
                forestlod_shared::registry::param_names().join(", ")
            ),
        )
        .at_key());
    };
    let bad = |reason: &str| {
        Bad::new(
            path.clone(),
            super::spec::value_label(v),
            format!("parameter {name}: {reason}"),
        )
    };
    let mut p = Params::default();
    set_param(&mut p, k, v, "").map_err(|e| bad(&e.reason))?;
    p.validate().map_err(|e| bad(&e.reason))?;
    Ok(name)
}

/// The first item of `items` whose key (`key_of`) an earlier one has: `(index, first index)`.
/// Hashed, so a list as long as the file allows is checked in linear time.
fn repeated<T, K: std::hash::Hash + Eq>(
    items: &[T],
    key_of: impl Fn(&T) -> K,
) -> Option<(usize, usize)> {
    let mut seen = std::collections::HashMap::new();
    items
        .iter()
        .enumerate()
        .find_map(|(i, t)| seen.insert(key_of(t), i).map(|j| (i, j)))
}

/// What one sweep would cost, from its counts (no parameter set is built to count them).
/// `None` in a field: the product overflows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Estimate {
    /// CSV rows: scenes x parameter sets x frame sizes x poses x variants x backends.
    pub frames: u128,
    /// Pixels rendered or traced ([`MAX_SWEEP_PIXEL_WORK`]).
    pub pixel_work: u128,
    /// The largest frame's memory ([`MAX_FRAME_BYTES`]).
    pub frame_bytes: u128,
    /// The largest billboard set of one species ([`MAX_BILLBOARD_BYTES`]).
    pub billboard_bytes: u128,
    /// Every ground-truth image kept ([`MAX_TRUTH_BYTES`]).
    pub truth_bytes: u128,
}

/// `a x b`, or `None` on overflow.
fn mul(a: Option<u128>, b: u128) -> Option<u128> {
    a?.checked_mul(b)
}

fn bytes_text(b: u128) -> String {
    forestlod_reference::files::size_text(u64::try_from(b).unwrap_or(u64::MAX))
}

impl SweepSpec {
    /// The poses of every camera, counted without building them (saturating).
    fn pose_count(&self) -> u128 {
        self.cameras
            .iter()
            .map(|c| {
                if c.name == "distance" {
                    c.distances.as_ref().map_or(0, Vec::len) as u128
                } else if super::paths::is_path(&c.name) {
                    u128::from(c.steps.unwrap_or(super::paths::DEFAULT_PATH_STEPS))
                } else {
                    u128::from(c.yaw_steps.unwrap_or(1))
                }
            })
            .fold(0u128, u128::saturating_add)
    }

    /// The sweep's frames and pixel work ([`Estimate`]), or a [`Bad`] when a product
    /// overflows. Memory needs the parameter sets ([`SweepSpec::memory_estimate`]).
    fn work_estimate(&self) -> Result<Estimate, Bad> {
        let overflow = |what: &str| {
            Bad::new(
                KeyPath::default(),
                what,
                format!(
                    "the sweep's size overflows 128 bits (scenes x settings x axis values x sizes x poses x variants x backends); at most {MAX_SWEEP_FRAMES} frames (MAX_SWEEP_FRAMES)"
                ),
            )
        };
        let sets = self
            .axes
            .iter()
            .try_fold(self.settings.len().max(1) as u128, |n, a| {
                n.checked_mul(a.values.len() as u128)
            })
            .ok_or_else(|| overflow("parameter sets"))?;
        let sizes = self.sizes();
        let poses = self.pose_count();
        let units = mul(mul(Some(self.scenes.len() as u128), sets), poses)
            .ok_or_else(|| overflow("poses"))?;
        let per_unit = (self.variants.len() * self.backends.len()) as u128;
        let frames = mul(mul(Some(units), sizes.len() as u128), per_unit)
            .ok_or_else(|| overflow("frames"))?;
        let s2 = u128::from(self.samples) * u128::from(self.samples);
        let fraction = self.truth_tiles.map_or(1.0, |t| t.fraction.clamp(0.0, 1.0));
        let pixels: u128 = sizes
            .iter()
            .map(|[w, h]| u128::from(*w) * u128::from(*h))
            .sum();
        // Per pose and size: each frame's repeats, warm-up and full-detail render, the total
        // error at s² the pixels, and the truth's s² rays on the traced fraction.
        let renders = mul(
            Some(u128::from(self.repeats) + 2 + if self.total_error { s2 } else { 0 }),
            per_unit,
        )
        .and_then(|r| r.checked_add((s2 as f64 * fraction).ceil() as u128))
        .ok_or_else(|| overflow("pixel work"))?;
        let pixel_work =
            mul(mul(Some(units), pixels), renders).ok_or_else(|| overflow("pixel work"))?;
        let truth_px: u128 = sizes
            .iter()
            .map(|[w, h]| ((u128::from(*w) * u128::from(*h)) as f64 * fraction).ceil() as u128)
            .sum();
        let truth_bytes = mul(
            mul(mul(Some(self.scenes.len() as u128), poses), truth_px),
            TRUTH_BYTES_PER_PIXEL,
        )
        .ok_or_else(|| overflow("ground-truth images"))?;
        let frame_bytes = sizes
            .iter()
            .map(|[w, h]| {
                let px = u128::from(*w) * u128::from(*h);
                px * (TARGET_BYTES_PER_PIXEL
                    + KEPT_BYTES_PER_PIXEL * self.variants.len() as u128
                    + TRUTH_BYTES_PER_PIXEL)
                    + if self.total_error {
                        px * s2 * TARGET_BYTES_PER_PIXEL
                    } else {
                        0
                    }
            })
            .max()
            .unwrap_or(0);
        Ok(Estimate {
            frames,
            pixel_work,
            frame_bytes,
            billboard_bytes: 0,
            truth_bytes,
        })
    }

    /// Checks the whole sweep (module docs): every setting where it is written, then its size
    /// against the work and memory limits, then every parameter set. The first refusal, with
    /// its key path.
    pub(crate) fn check(&self) -> Result<(), Bad> {
        let e = |p: KeyPath, v: &dyn fmt::Display, r: &str| Err(Bad::new(p, v, r));
        check_folder_name(&self.name).or_else(|r| e(key("name"), &self.name, &r))?;
        if self.title.trim().is_empty() {
            return e(key("title"), &"", "expected a one-line title");
        }
        for (field, empty) in [
            ("scenes", self.scenes.is_empty()),
            ("cameras", self.cameras.is_empty()),
            ("variants", self.variants.is_empty()),
            ("backends", self.backends.is_empty()),
        ] {
            if empty {
                let what = field.trim_end_matches('s');
                return e(key(field), &"[]", &format!("expected at least one {what}"));
            }
        }
        for (i, s) in self.scenes.iter().enumerate() {
            if s.trim().is_empty() {
                return e(
                    key("scenes").at(i),
                    s,
                    "expected a built-in scene name or a scene file",
                );
            }
        }
        if let Some((i, j)) = repeated(&self.scenes, |s| s.clone()) {
            return e(
                key("scenes").at(i),
                &self.scenes[i],
                &format!("scene given twice (also scenes[{j}])"),
            );
        }
        use super::variant::{Engine, Pipeline, Registered};
        let mut variants = Vec::new();
        for (i, v) in self.variants.iter().enumerate() {
            variants.push(Pipeline::parse(v).map_err(|r| Bad::new(key("variants").at(i), v, r))?);
        }
        let mut backends = Vec::new();
        for (i, b) in self.backends.iter().enumerate() {
            backends.push(Engine::parse(b).map_err(|r| Bad::new(key("backends").at(i), b, r))?);
        }
        if let Some((i, j)) = repeated(&variants, |v| v.name()) {
            return e(
                key("variants").at(i),
                &self.variants[i],
                &format!("variant given twice (also variants[{j}])"),
            );
        }
        if let Some((i, j)) = repeated(&backends, |b| b.name()) {
            return e(
                key("backends").at(i),
                &self.backends[i],
                &format!("backend given twice (also backends[{j}])"),
            );
        }
        if let (Some(i), true) = (
            variants.iter().position(|v| v.gpu_only()),
            backends.contains(&Engine::Reference),
        ) {
            return e(
                key("variants").at(i),
                &self.variants[i],
                "the atomic-counter compaction exists on the gpu backend only (the reference's stable compaction equals it as a multiset); use backends = [\"gpu\"]",
            );
        }
        self.check_cameras()?;
        for (field, v) in [
            ("width", self.width),
            ("height", self.height),
            ("samples", self.samples),
            ("repeats", self.repeats),
        ] {
            if v == 0 {
                return e(key(field), &0, "expected a positive value");
            }
        }
        let sizes = self.sizes();
        for (i, &[w, h]) in sizes.iter().enumerate() {
            let at = if self.resolutions.is_empty() {
                key(if w == 0 || (h != 0 && w >= h) {
                    "width"
                } else {
                    "height"
                })
            } else {
                key("resolutions").at(i)
            };
            let side = u64::from(w.max(h));
            let big = side * u64::from(self.samples);
            if w == 0 || h == 0 || side > u64::from(MAX_FRAME_SIDE) {
                return e(
                    at,
                    &format!("{w}x{h}"),
                    &format!(
                        "expected positive frame sizes of at most {MAX_FRAME_SIDE} pixels a side (MAX_FRAME_SIDE)"
                    ),
                );
            }
            if self.total_error && big > u64::from(MAX_FRAME_SIDE) {
                return e(
                    at,
                    &format!("{w}x{h}"),
                    &format!(
                        "the total error's supersampled frame ({} per side: samples = {}) must be at most {MAX_FRAME_SIDE} pixels a side (MAX_FRAME_SIDE); lower samples or set total_error = false",
                        big, self.samples
                    ),
                );
            }
        }
        if let Some((i, j)) = repeated(&self.resolutions, |r| *r) {
            return e(
                key("resolutions").at(i),
                &format!("{:?}", self.resolutions[i]),
                &format!("frame size given twice (also resolutions[{j}])"),
            );
        }
        if let Some(t) = &self.truth_tiles {
            t.check()
                .or_else(|r| e(key("truth_tiles"), &format!("{t:?}"), &r))?;
        }
        if forestlod_shared::TruthLight::from_name(&self.truth_light).is_none() {
            let names: Vec<_> = forestlod_shared::TruthLight::ALL.map(|m| m.name()).to_vec();
            return e(
                key("truth_light"),
                &self.truth_light,
                &format!("expected one of {}", names.join(", ")),
            );
        }
        let axes = self.check_params()?;
        let x = self.x_axis.as_str();
        if !["yaw", "distance", "setting"].contains(&x) && !axes.iter().any(|a| same_param(a, x)) {
            return e(
                key("x_axis"),
                &x,
                "expected yaw, distance, setting or the parameter of an axis",
            );
        }
        // The size, before any parameter set is built.
        let est = self.work_estimate()?;
        let over = |what: &str, value: String, limit: String, name: &str| {
            Err(Bad::new(
                KeyPath::default(),
                value,
                format!("{what} is over the limit of {limit} ({name}); make the sweep smaller"),
            ))
        };
        if est.frames > MAX_SWEEP_FRAMES {
            return over(
                "the number of frames (scenes x parameter sets x sizes x poses x variants x backends)",
                format!("{} frames", est.frames),
                MAX_SWEEP_FRAMES.to_string(),
                "MAX_SWEEP_FRAMES",
            );
        }
        if est.pixel_work > MAX_SWEEP_PIXEL_WORK {
            return over(
                "the pixels to render and trace (frames x pixels x renders per frame, plus the truth's rays)",
                format!("{:.3e} pixels", est.pixel_work as f64),
                format!("{:.0e} pixels", MAX_SWEEP_PIXEL_WORK as f64),
                "MAX_SWEEP_PIXEL_WORK",
            );
        }
        if est.frame_bytes > MAX_FRAME_BYTES {
            return over(
                "one frame's memory (render targets, kept images, the total error's supersampled target, the truth)",
                bytes_text(est.frame_bytes),
                bytes_text(MAX_FRAME_BYTES),
                "MAX_FRAME_BYTES",
            );
        }
        if est.truth_bytes > MAX_TRUTH_BYTES {
            return over(
                "the ground-truth images kept (scenes x poses x sizes)",
                bytes_text(est.truth_bytes),
                bytes_text(MAX_TRUTH_BYTES),
                "MAX_TRUTH_BYTES",
            );
        }
        // Every parameter set, through the parameter table, and its billboards' memory.
        let sets = self.param_sets("").map_err(|err| {
            Bad::new(
                KeyPath::default(),
                err.value.clone(),
                format!("{}: {}", err.position, err.reason),
            )
        })?;
        for set in &sets {
            let p = &set.params;
            let bytes = u128::from(forestlod_reference::bake::bake_memory_bytes(1, p));
            if bytes > MAX_BILLBOARD_BYTES {
                return over(
                    &format!(
                        "the billboards of one species at angle_count = {}, texture_size = {} (setting {:?}: angles x texture_size² texels, baked, mipmapped and uploaded)",
                        p.angle_count, p.texture_size, set.label
                    ),
                    bytes_text(bytes),
                    bytes_text(MAX_BILLBOARD_BYTES),
                    "MAX_BILLBOARD_BYTES = MAX_BAKE_BYTES",
                );
            }
        }
        Ok(())
    }

    /// The cameras: known names, each field only where it applies, positive counts, finite
    /// distances in range, nothing twice.
    fn check_cameras(&self) -> Result<(), Bad> {
        for (i, c) in self.cameras.iter().enumerate() {
            let at = key("cameras").at(i);
            let is_path = super::paths::is_path(&c.name);
            let is_distance = c.name == "distance";
            let is_named = forestlod_reference::cameras::CAMERA_NAMES.contains(&c.name.as_str());
            if !(is_path || is_distance || is_named) {
                return Err(Bad::new(
                    at.key("name"),
                    &c.name,
                    format!(
                        "expected {}, distance or a path ({})",
                        forestlod_reference::cameras::CAMERA_NAMES.join(", "),
                        super::paths::PATH_NAMES.join(", ")
                    ),
                ));
            }
            for (field, given, applies, hint) in [
                (
                    "yaw_steps",
                    c.yaw_steps.is_some(),
                    is_named,
                    "for the named cameras far, medium and close",
                ),
                (
                    "steps",
                    c.steps.is_some(),
                    is_path,
                    "for the scene-defined paths (PATH_NAMES)",
                ),
                (
                    "distances",
                    c.distances.is_some(),
                    is_distance,
                    "for the distance camera",
                ),
            ] {
                if given && !applies {
                    return Err(Bad::new(
                        at.key(field),
                        &c.name,
                        format!(
                            "`{field}` is {hint} only; camera {:?} would ignore it",
                            c.name
                        ),
                    )
                    .at_key());
                }
            }
            if c.yaw_steps == Some(0) {
                return Err(Bad::new(
                    at.key("yaw_steps"),
                    0,
                    "expected at least 1 yaw step",
                ));
            }
            if c.steps == Some(0) {
                return Err(Bad::new(
                    at.key("steps"),
                    0,
                    "expected at least 1 frame along the path",
                ));
            }
            if is_distance {
                let d = c.distances.as_deref().unwrap_or(&[]);
                if d.is_empty() {
                    return Err(Bad::new(
                        at.key("distances"),
                        "[]",
                        "a distance camera needs a non-empty `distances` list",
                    ));
                }
                let max = forestlod_shared::params::MAX_DISTANCE;
                if let Some(k) = d
                    .iter()
                    .position(|x| !(x.is_finite() && (0.0..=max).contains(x)))
                {
                    return Err(Bad::new(
                        at.key("distances").at(k),
                        d[k],
                        format!("expected a finite distance in 0..={max} metres"),
                    ));
                }
                if let Some((k, j)) = repeated(d, |x| (x + 0.0).to_bits()) {
                    return Err(Bad::new(
                        at.key("distances").at(k),
                        d[k],
                        format!("distance given twice (also distances[{j}])"),
                    ));
                }
            }
        }
        if let Some((i, j)) = repeated(&self.cameras, |c| c.name.clone()) {
            return Err(Bad::new(
                key("cameras").at(i).key("name"),
                &self.cameras[i].name,
                format!("camera given twice (also cameras[{j}]): its poses would repeat"),
            ));
        }
        Ok(())
    }

    /// `[params]`, the axes and the settings (module docs), each value by the parameter table.
    /// Returns the axes' canonical parameter names.
    fn check_params(&self) -> Result<Vec<&'static str>, Bad> {
        let base = check_param_table(self.params.iter(), &key("params"))?;
        let mut axes: Vec<&'static str> = Vec::new();
        for (i, a) in self.axes.iter().enumerate() {
            let at = key("axes").at(i);
            let Some(name) = canonical(&a.param) else {
                return Err(Bad::new(
                    at.key("param"),
                    &a.param,
                    format!(
                        "unknown parameter; expected {}",
                        forestlod_shared::registry::param_names().join(", ")
                    ),
                ));
            };
            if let Some(j) = axes.iter().position(|n| *n == name) {
                return Err(Bad::new(
                    at.key("param"),
                    &a.param,
                    format!(
                        "axis {name} given twice (also axes[{j}]): its rows would not be rendered at the values their labels say"
                    ),
                ));
            }
            if let Some(k) = self.params.keys().find(|k| same_param(k, name)) {
                return Err(Bad::new(
                    key("params").key(k.clone()),
                    k,
                    format!("parameter {name} is also axes[{i}]: the axis replaces this value in every row"),
                )
                .at_key());
            }
            if a.values.is_empty() {
                return Err(Bad::new(
                    at.key("values"),
                    "[]",
                    "expected at least one value",
                ));
            }
            let spec = forestlod_shared::param(name).expect("known");
            let mut parsed: Vec<u64> = Vec::new();
            for (j, v) in a.values.iter().enumerate() {
                check_param_value(&a.param, v, &at.key("values").at(j))?;
                let mut p = Params::default();
                set_param(&mut p, &a.param, v, "").expect("checked above");
                // As stored: 10 and 10.0 are the same value (and 0.0 and -0.0).
                parsed.push(((spec.get)(&p) + 0.0).to_bits());
            }
            if let Some((j, k)) = repeated(&parsed, |x| *x) {
                return Err(Bad::new(
                    at.key("values").at(j),
                    super::spec::value_label(&a.values[j]),
                    format!("value given twice (also values[{k}])"),
                ));
            }
            axes.push(name);
        }
        let _ = base;
        if let Some((i, j)) = repeated(&self.settings, |s| s.label.clone()) {
            return Err(Bad::new(
                key("settings").at(i).key("label"),
                &self.settings[i].label,
                format!(
                    "label given twice (also settings[{j}]): their rows could not be told apart"
                ),
            ));
        }
        for (i, s) in self.settings.iter().enumerate() {
            let at = key("settings").at(i);
            if s.label.trim().is_empty() {
                return Err(Bad::new(
                    at.key("label"),
                    &s.label,
                    "expected a non-empty label",
                ));
            }
            let names = check_param_table(s.params.iter(), &at)?;
            if let Some((k, j)) = s
                .params
                .keys()
                .zip(&names)
                .find_map(|(k, n)| axes.iter().position(|a| a == n).map(|j| (k, j)))
            {
                return Err(Bad::new(
                    at.key(k.clone()),
                    k,
                    format!("parameter {k} is also axes[{j}]: the axis replaces the setting's value in every row"),
                )
                .at_key());
            }
        }
        if let Some(q) = &self.quick {
            if let Some(p) = &q.params {
                check_param_table(p.iter(), &key("quick").key("params"))?;
            }
            if let Some(m) = &q.axes {
                let mut seen: Vec<&'static str> = Vec::new();
                for k in m.keys() {
                    let at = key("quick").key("axes").key(k.clone());
                    let Some(name) = canonical(k).filter(|n| axes.contains(n)) else {
                        return Err(Bad::new(
                            at,
                            k,
                            "names no axis of this sweep (a [quick] axis replaces the values of an [[axes]] entry)",
                        )
                        .at_key());
                    };
                    if seen.contains(&name) {
                        return Err(Bad::new(
                            at,
                            k,
                            format!("axis {name} given twice in [quick].axes"),
                        )
                        .at_key());
                    }
                    seen.push(name);
                }
            }
        }
        Ok(axes)
    }
}
