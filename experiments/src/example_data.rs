//! The example scene from real public data (issue 34, item 3): a real tree census on its real
//! elevation model, read from a package of a registry this project reaches and converted into the
//! formats the scene loaders read (`reference/src/scene/load/dem.rs`, `inventory.rs`). It gives
//! the 3D-GIS setting of E§1 (trees on measured relief) a real instance beside the synthetic
//! scenes of E§4.5.1 and E§5.
//!
//! # The data
//! Debian's `r-cran-spatstat.data` [`PACKAGE_VERSION`] ships, in its lazy-load database
//! (`data/Rdata.rdx` + `Rdata.rdb`), the dataset `bei`: the positions of the 3,604 trees of
//! *Beilschmiedia pendula* (Lauraceae) in the 1000 m × 500 m forest dynamics plot of Barro Colorado
//! Island, Panama (Hubbell and Foster 1983; Condit, Hubbell and Foster 1996; Condit 1998), and
//! `bei.extra$elev`, the plot's elevation in metres on a 5 m grid (201 × 101 samples, 119.8 m to
//! 159.5 m). Licence: GPL-2+ (the package's `copyright` file), so the data are not committed
//! beside this MIT/Apache code: `scripts/fetch-example-data` fetches the package by name and
//! version, checks its sha256 and converts it on the user's machine.
//!
//! # Contract
//! - **Reader** ([`unserialize`], [`LazyLoadDb`]): R's serialization format (XDR, versions 2
//!   and 3) for the object kinds these datasets use: `NULL`, symbols, pairlists (attributes),
//!   character, logical, integer, double and generic vectors, with attributes and references;
//!   the lazy-load index (gzip) and zlib-compressed entries. Anything else (environments,
//!   closures, bzip2/xz entries, a truncated stream, a length larger than the bytes left) is an
//!   error naming the file, the object and the byte offset, never a panic and never a guess.
//! - **Checks** before anything is written: `bei` is a `ppp` with one `x` and one `y` per tree
//!   (`n` of them, all finite, inside the window); `elev` is an `im` whose `dim`, `xcol`, `yrow`
//!   and steps agree, with one square step.
//! - **Output** ([`write_scene`]): `dem.asc` (ESRI ASCII grid: the `im`'s sample centres,
//!   `xllcenter`/`yllcenter`, rows from the north, `NODATA_value` for R's `NA`), `trees.csv`
//!   (`tree,x,y,species`: the census order from 1, the plot's own metres) and `bei.toml` (the
//!   scene file: DEM terrain, the column map, `Beilschmiedia pendula` mapped to the built-in
//!   `oak`). Coordinates are the plot's local metres (the package gives no CRS).
//! - **Nothing invented**: the census has positions only. No height, crown or yaw column is
//!   written, so every tree is the built-in oak at its own height (scale 1) and yaw is the
//!   inventory loader's fixed function of the row.
//! - **Cut** ([`Window`]): the trees inside a window and the DEM samples covering it plus one
//!   sample each side, so every tree of a cut lies inside its DEM (the CI-sized scene).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Read;
use std::path::Path;

/// The Debian package that ships the data.
pub const PACKAGE: &str = "r-cran-spatstat.data";
/// Its pinned version (Debian 12 "bookworm").
pub const PACKAGE_VERSION: &str = "3.0-0-1";
/// The sha256 of `r-cran-spatstat.data_3.0-0-1_all.deb` (also checked by the fetch script).
pub const PACKAGE_SHA256: &str = "51fb43790f2c7aa0e40b6b17a0c7640b0001d16ce7f09e027b267b136910f84e";
/// Where the package keeps its datasets, relative to the root it is unpacked into.
pub const DATA_DIR_IN_PACKAGE: &str = "usr/lib/R/site-library/spatstat.data/data";
/// The species name the scene's inventory carries (the census is of this one species).
pub const SPECIES_NAME: &str = "Beilschmiedia pendula";
/// The built-in species it is drawn as (a broad-leaved crown; 17 m).
pub const DRAWN_AS: &str = "oak";
/// Most nesting the reader follows (the datasets nest four deep).
const MAX_DEPTH: usize = 64;
/// Largest decompressed object read, bytes (`bei.extra` is about 330 kB).
const MAX_OBJECT_BYTES: usize = 64 << 20;

/// An error of the conversion: the file, where in it, and what was wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct DataError(pub String);

impl std::fmt::Display for DataError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DataError {}

fn derr(msg: impl Into<String>) -> DataError {
    DataError(msg.into())
}

/// An R object as far as these datasets need one.
#[derive(Clone, Debug, PartialEq)]
pub enum RData {
    /// `NULL`.
    Null,
    /// A symbol (its name).
    Symbol(String),
    /// A character vector (`None` is `NA`).
    Str(Vec<Option<String>>),
    /// A logical or integer vector (`i32::MIN` is `NA`).
    Int(Vec<i32>),
    /// A double vector (R's `NA` is a NaN).
    Real(Vec<f64>),
    /// A generic vector (`list`).
    List(Vec<RValue>),
    /// A pairlist: tagged values (attributes are one).
    Pairs(Vec<(Option<String>, RValue)>),
}

/// An R object and its attributes.
#[derive(Clone, Debug, PartialEq)]
pub struct RValue {
    /// The object.
    pub data: RData,
    /// Its attributes, by name, in order.
    pub attrs: Vec<(String, RValue)>,
}

impl RValue {
    fn plain(data: RData) -> RValue {
        RValue {
            data,
            attrs: Vec::new(),
        }
    }

    /// The attribute `name`.
    pub fn attr(&self, name: &str) -> Option<&RValue> {
        self.attrs.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    /// The `names` attribute as strings.
    pub fn names(&self) -> Vec<String> {
        match self.attr("names").map(|v| &v.data) {
            Some(RData::Str(s)) => s.iter().map(|n| n.clone().unwrap_or_default()).collect(),
            _ => Vec::new(),
        }
    }

    /// Whether the `class` attribute contains `class`.
    pub fn has_class(&self, class: &str) -> bool {
        matches!(self.attr("class").map(|v| &v.data),
            Some(RData::Str(s)) if s.iter().any(|c| c.as_deref() == Some(class)))
    }

    /// The element `name` of a named list.
    pub fn field(&self, name: &str) -> Option<&RValue> {
        match &self.data {
            RData::List(items) => self
                .names()
                .iter()
                .position(|n| n == name)
                .and_then(|i| items.get(i)),
            _ => None,
        }
    }

    /// The numbers of an integer or double vector, as `f64`.
    pub fn numbers(&self) -> Option<Vec<f64>> {
        match &self.data {
            RData::Real(v) => Some(v.clone()),
            RData::Int(v) => Some(
                v.iter()
                    .map(|&i| {
                        if i == i32::MIN {
                            f64::NAN
                        } else {
                            f64::from(i)
                        }
                    })
                    .collect(),
            ),
            _ => None,
        }
    }
}

/// R's serialization type codes this reader knows (R Internals §1.8).
mod sexp {
    pub const NIL: u32 = 0;
    pub const SYM: u32 = 1;
    pub const LIST: u32 = 2;
    pub const CHAR: u32 = 9;
    pub const LGL: u32 = 10;
    pub const INT: u32 = 13;
    pub const REAL: u32 = 14;
    pub const STR: u32 = 16;
    pub const VEC: u32 = 19;
    pub const REF: u32 = 255;
    pub const NILVALUE: u32 = 254;
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    refs: Vec<RValue>,
    what: &'a str,
}

impl<'a> Reader<'a> {
    fn fail(&self, msg: impl std::fmt::Display) -> DataError {
        derr(format!("{}: byte {}: {msg}", self.what, self.pos))
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], DataError> {
        if n > self.bytes.len() - self.pos {
            return Err(self.fail(format_args!(
                "needs {n} bytes, {} left (truncated?)",
                self.bytes.len() - self.pos
            )));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn int(&mut self) -> Result<i32, DataError> {
        let b = self.take(4)?;
        Ok(i32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A vector length: a count of items of `item_bytes` each, checked against the bytes left.
    fn length(&mut self, item_bytes: usize) -> Result<usize, DataError> {
        let n = self.int()?;
        let n: i64 = if n == -1 {
            let (hi, lo) = (self.int()?, self.int()?);
            (i64::from(hi) << 32) | i64::from(lo as u32)
        } else {
            i64::from(n)
        };
        let left = (self.bytes.len() - self.pos) as i64;
        if n < 0 || n.saturating_mul(item_bytes as i64) > left {
            return Err(self.fail(format_args!(
                "length {n} needs more than the {left} bytes left"
            )));
        }
        Ok(n as usize)
    }

    fn header(&mut self) -> Result<(), DataError> {
        if self.take(2)? != b"X\n" {
            self.pos = 0;
            return Err(self.fail("not R's XDR serialization (expected \"X\\n\")"));
        }
        let version = self.int()?;
        let _writer = self.int()?;
        let _min_reader = self.int()?;
        match version {
            2 => Ok(()),
            3 => {
                let n = self.length(1)?;
                self.take(n)?;
                Ok(())
            }
            v => Err(self.fail(format_args!("serialization version {v}, expected 2 or 3"))),
        }
    }

    fn item(&mut self, depth: usize) -> Result<RValue, DataError> {
        if depth > MAX_DEPTH {
            return Err(self.fail(format_args!("nested deeper than {MAX_DEPTH}")));
        }
        let at = self.pos;
        let flags = self.int()? as u32;
        let kind = flags & 0xff;
        let (has_attr, has_tag) = (flags & (1 << 9) != 0, flags & (1 << 10) != 0);
        let data = match kind {
            sexp::NILVALUE | sexp::NIL => return Ok(RValue::plain(RData::Null)),
            sexp::REF => {
                let i = match flags >> 8 {
                    0 => self.int()? as usize,
                    i => i as usize,
                };
                return self.refs.get(i.wrapping_sub(1)).cloned().ok_or_else(|| {
                    self.fail(format_args!("reference {i} to one of {}", self.refs.len()))
                });
            }
            sexp::SYM => {
                let name = match self.item(depth + 1)?.data {
                    RData::Str(mut s) if s.len() == 1 => s.pop().flatten().unwrap_or_default(),
                    _ => return Err(self.fail("a symbol whose name is not a string")),
                };
                let v = RValue::plain(RData::Symbol(name));
                self.refs.push(v.clone());
                return Ok(v);
            }
            sexp::LIST => {
                let mut attrs = Vec::new();
                if has_attr {
                    attrs = self.attributes(depth)?;
                }
                let tag = if has_tag {
                    match self.item(depth + 1)?.data {
                        RData::Symbol(s) => Some(s),
                        _ => return Err(self.fail("a pairlist tag that is not a symbol")),
                    }
                } else {
                    None
                };
                let car = self.item(depth + 1)?;
                let mut pairs = vec![(tag, car)];
                match self.item(depth + 1)? {
                    RValue {
                        data: RData::Null, ..
                    } => {}
                    RValue {
                        data: RData::Pairs(rest),
                        ..
                    } => pairs.extend(rest),
                    _ => return Err(self.fail("a pairlist whose tail is not a pairlist")),
                }
                return Ok(RValue {
                    data: RData::Pairs(pairs),
                    attrs,
                });
            }
            sexp::CHAR => {
                let n = self.int()?;
                if n == -1 {
                    RData::Str(vec![None])
                } else {
                    let n = usize::try_from(n).map_err(|_| self.fail("negative string length"))?;
                    let b = self.take(n)?;
                    RData::Str(vec![Some(String::from_utf8_lossy(b).into_owned())])
                }
            }
            sexp::LGL | sexp::INT => {
                let n = self.length(4)?;
                let b = self.take(4 * n)?;
                RData::Int(
                    b.chunks_exact(4)
                        .map(|c| i32::from_be_bytes([c[0], c[1], c[2], c[3]]))
                        .collect(),
                )
            }
            sexp::REAL => {
                let n = self.length(8)?;
                let b = self.take(8 * n)?;
                RData::Real(
                    b.chunks_exact(8)
                        .map(|c| f64::from_be_bytes(c.try_into().expect("8 bytes")))
                        .collect(),
                )
            }
            sexp::STR => {
                let n = self.length(4)?;
                let mut s = Vec::with_capacity(n);
                for _ in 0..n {
                    match self.item(depth + 1)?.data {
                        RData::Str(mut one) if one.len() == 1 => s.push(one.pop().flatten()),
                        _ => return Err(self.fail("a character vector holding a non-string")),
                    }
                }
                RData::Str(s)
            }
            sexp::VEC => {
                let n = self.length(4)?;
                let mut items = Vec::with_capacity(n);
                for _ in 0..n {
                    items.push(self.item(depth + 1)?);
                }
                RData::List(items)
            }
            k => {
                self.pos = at;
                return Err(self.fail(format_args!(
                    "R object type {k} (flags {flags:#x}) is not one these datasets use"
                )));
            }
        };
        let attrs = if has_attr && kind != sexp::CHAR {
            self.attributes(depth)?
        } else {
            Vec::new()
        };
        Ok(RValue { data, attrs })
    }

    fn attributes(&mut self, depth: usize) -> Result<Vec<(String, RValue)>, DataError> {
        match self.item(depth + 1)?.data {
            RData::Pairs(p) => Ok(p
                .into_iter()
                .map(|(t, v)| (t.unwrap_or_default(), v))
                .collect()),
            RData::Null => Ok(Vec::new()),
            _ => Err(self.fail("attributes that are not a pairlist")),
        }
    }
}

/// Reads one serialized R object (`"X\n"` header, XDR) from `bytes`; `what` names it in errors.
pub fn unserialize(bytes: &[u8], what: &str) -> Result<RValue, DataError> {
    let mut r = Reader {
        bytes,
        pos: 0,
        refs: Vec::new(),
        what,
    };
    r.header()?;
    r.item(0)
}

/// An R package's lazy-load database (`Rdata.rdx` index, `Rdata.rdb` entries).
pub struct LazyLoadDb {
    rdb: Vec<u8>,
    rdb_name: String,
    entries: BTreeMap<String, (usize, usize)>,
}

impl LazyLoadDb {
    /// Opens `dir/Rdata.rdx` and `dir/Rdata.rdb`.
    pub fn open(dir: &Path) -> Result<LazyLoadDb, DataError> {
        let read = |name: &str| {
            let p = dir.join(name);
            std::fs::read(&p).map_err(|e| derr(format!("{}: {e}", p.display())))
        };
        let rdx_name = dir.join("Rdata.rdx").display().to_string();
        let rdb_name = dir.join("Rdata.rdb").display().to_string();
        let (rdx, rdb) = (read("Rdata.rdx")?, read("Rdata.rdb")?);
        let mut index = Vec::new();
        flate2::read::GzDecoder::new(rdx.as_slice())
            .take(MAX_OBJECT_BYTES as u64)
            .read_to_end(&mut index)
            .map_err(|e| derr(format!("{rdx_name}: not gzip: {e}")))?;
        let index = unserialize(&index, &rdx_name)?;
        let compressed = index
            .field("compressed")
            .and_then(RValue::numbers)
            .and_then(|v| v.first().copied());
        if compressed != Some(1.0) {
            return Err(derr(format!(
                "{rdx_name}: field compressed = {compressed:?}: only zlib entries (1) are read"
            )));
        }
        let vars = index
            .field("variables")
            .ok_or_else(|| derr(format!("{rdx_name}: no field \"variables\"")))?;
        let RData::List(items) = &vars.data else {
            return Err(derr(format!("{rdx_name}: field variables is not a list")));
        };
        let mut entries = BTreeMap::new();
        for (name, v) in vars.names().into_iter().zip(items) {
            match v.numbers().as_deref() {
                Some(&[off, len]) if off >= 0.0 && len >= 4.0 && off + len <= rdb.len() as f64 => {
                    entries.insert(name, (off as usize, len as usize));
                }
                other => {
                    return Err(derr(format!(
                        "{rdx_name}: entry {name:?} = {other:?}: expected an offset and a length within {rdb_name} ({} bytes)",
                        rdb.len()
                    )));
                }
            }
        }
        Ok(LazyLoadDb {
            rdb,
            rdb_name,
            entries,
        })
    }

    /// The names of the objects the database holds.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.keys().map(String::as_str)
    }

    /// The object `name`: a 4-byte big-endian length, then a zlib stream of that many bytes.
    pub fn get(&self, name: &str) -> Result<RValue, DataError> {
        let what = format!("{}: object {name:?}", self.rdb_name);
        let &(off, len) = self
            .entries
            .get(name)
            .ok_or_else(|| derr(format!("{}: no object {name:?}", self.rdb_name)))?;
        let raw = &self.rdb[off..off + len];
        let out_len = u32::from_be_bytes([raw[0], raw[1], raw[2], raw[3]]) as usize;
        if out_len > MAX_OBJECT_BYTES {
            return Err(derr(format!(
                "{what}: declares {out_len} bytes, more than {MAX_OBJECT_BYTES}"
            )));
        }
        let mut bytes = Vec::with_capacity(out_len);
        flate2::read::ZlibDecoder::new(&raw[4..])
            .take(out_len as u64 + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| derr(format!("{what}: not a zlib stream: {e}")))?;
        if bytes.len() != out_len {
            return Err(derr(format!(
                "{what}: {} bytes after decompression, {out_len} declared",
                bytes.len()
            )));
        }
        unserialize(&bytes, &what)
    }
}

/// The census: tree positions in the plot's metres, and the plot's window.
#[derive(Clone, Debug, PartialEq)]
pub struct Census {
    /// Easting of each tree, metres.
    pub x: Vec<f64>,
    /// Northing of each tree, metres.
    pub y: Vec<f64>,
    /// `[x_min, y_min, x_max, y_max]` of the plot.
    pub window: [f64; 4],
}

/// An elevation grid as spatstat's `im` holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct Elevation {
    /// Sample-centre `x` of each column, west to east.
    pub xcol: Vec<f64>,
    /// Sample-centre `y` of each row, south to north.
    pub yrow: Vec<f64>,
    /// The grid step, metres (the same in `x` and `y`).
    pub step: f64,
    /// Heights, `v[row + col * rows]` (R's column-major matrix), NaN where `NA`.
    pub v: Vec<f64>,
}

impl Elevation {
    /// The height of sample `(col, row)`, row 0 the southern one.
    pub fn at(&self, col: usize, row: usize) -> f64 {
        self.v[row + col * self.yrow.len()]
    }

    /// Lowest and highest height, ignoring `NA`.
    pub fn range(&self) -> [f64; 2] {
        self.v
            .iter()
            .filter(|h| h.is_finite())
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], &h| {
                [lo.min(h), hi.max(h)]
            })
    }
}

fn numbers_of(v: &RValue, field: &str, what: &str) -> Result<Vec<f64>, DataError> {
    v.field(field)
        .and_then(RValue::numbers)
        .ok_or_else(|| derr(format!("{what}: no numeric field {field:?}")))
}

/// `bei` as a [`Census`], checked (module docs).
pub fn census(ppp: &RValue, what: &str) -> Result<Census, DataError> {
    if !ppp.has_class("ppp") {
        return Err(derr(format!("{what}: not a point pattern (class ppp)")));
    }
    let (x, y) = (numbers_of(ppp, "x", what)?, numbers_of(ppp, "y", what)?);
    let n = numbers_of(ppp, "n", what)?;
    let w = ppp
        .field("window")
        .ok_or_else(|| derr(format!("{what}: no field \"window\"")))?;
    let (xr, yr) = (
        numbers_of(w, "xrange", what)?,
        numbers_of(w, "yrange", what)?,
    );
    if n.as_slice() != [x.len() as f64] || x.len() != y.len() || xr.len() != 2 || yr.len() != 2 {
        return Err(derr(format!(
            "{what}: n = {n:?} with {} x and {} y, window {xr:?} x {yr:?}",
            x.len(),
            y.len()
        )));
    }
    let window = [xr[0], yr[0], xr[1], yr[1]];
    if let Some(i) = (0..x.len()).find(|&i| {
        !(x[i].is_finite()
            && y[i].is_finite()
            && (window[0]..=window[2]).contains(&x[i])
            && (window[1]..=window[3]).contains(&y[i]))
    }) {
        return Err(derr(format!(
            "{what}: tree {} at ({}, {}) is outside the window {window:?}",
            i + 1,
            x[i],
            y[i]
        )));
    }
    Ok(Census { x, y, window })
}

/// `bei.extra$elev` as an [`Elevation`], checked (module docs).
pub fn elevation(im: &RValue, what: &str) -> Result<Elevation, DataError> {
    if !im.has_class("im") {
        return Err(derr(format!("{what}: not a pixel image (class im)")));
    }
    let v = numbers_of(im, "v", what)?;
    let dim = numbers_of(im, "dim", what)?;
    let (xcol, yrow) = (numbers_of(im, "xcol", what)?, numbers_of(im, "yrow", what)?);
    let (xstep, ystep) = (
        numbers_of(im, "xstep", what)?,
        numbers_of(im, "ystep", what)?,
    );
    let (rows, cols) = (yrow.len(), xcol.len());
    let consistent = dim.as_slice() == [rows as f64, cols as f64]
        && v.len() == rows * cols
        && rows >= 2
        && cols >= 2
        && xstep.len() == 1
        && xstep == ystep
        && xstep[0] > 0.0
        && xcol
            .windows(2)
            .chain(yrow.windows(2))
            .all(|p| ((p[1] - p[0]) - xstep[0]).abs() <= 1e-9 * xstep[0].max(1.0));
    if !consistent {
        return Err(derr(format!(
            "{what}: dim {dim:?}, {} samples, {cols} xcol, {rows} yrow, steps {xstep:?} x {ystep:?}: expected one square step and a consistent grid",
            v.len()
        )));
    }
    Ok(Elevation {
        xcol,
        yrow,
        step: xstep[0],
        v,
    })
}

/// Reads `bei` and `bei.extra$elev` from the package's data folder (its lazy-load database).
pub fn read_bei(data_dir: &Path) -> Result<(Census, Elevation), DataError> {
    let db = LazyLoadDb::open(data_dir)?;
    let what = |o: &str| format!("{}: {o}", data_dir.join("Rdata.rdb").display());
    let trees = census(&db.get("bei")?, &what("bei"))?;
    let extra = db.get("bei.extra")?;
    let elev = extra
        .field("elev")
        .ok_or_else(|| derr(format!("{}: no field \"elev\"", what("bei.extra"))))?;
    Ok((trees, elevation(elev, &what("bei.extra$elev"))?))
}

/// A window of the plot, `[x_min, y_min, x_max, y_max]` metres, for a cut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window(pub [f64; 4]);

impl std::str::FromStr for Window {
    type Err = String;
    fn from_str(s: &str) -> Result<Window, String> {
        let v: Vec<f64> = s
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("window {s:?}: {e}"))?;
        match v.as_slice() {
            &[a, b, c, d] if a < c && b < d && v.iter().all(|t| t.is_finite()) => {
                Ok(Window([a, b, c, d]))
            }
            _ => Err(format!(
                "window {s:?}: expected x_min,y_min,x_max,y_max with min < max"
            )),
        }
    }
}

/// What [`write_scene`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// Trees in `trees.csv`.
    pub trees: usize,
    /// DEM columns and rows in `dem.asc`.
    pub dem_size: [usize; 2],
    /// Lowest and highest DEM height written, metres.
    pub relief: [f64; 2],
    /// Extent of the DEM's sample centres, `[x_min, y_min, x_max, y_max]`.
    pub dem_extent: [f64; 4],
}

/// `SOURCE.txt`, written beside the scene: where the data come from and under which licence.
pub const SOURCE: &str = "\
Barro Colorado Island forest dynamics plot, Panama: Beilschmiedia pendula (Lauraceae).

Package: Debian's r-cran-spatstat.data 3.0-0-1 (R package spatstat.data 3.0-0 by Adrian
  Baddeley, Rolf Turner and Ege Rubak), file r-cran-spatstat.data_3.0-0-1_all.deb,
  sha256 51fb43790f2c7aa0e40b6b17a0c7640b0001d16ce7f09e027b267b136910f84e.
Datasets: bei (the positions of the trees, metres, in the 1000 m x 500 m plot) and
  bei.extra$elev (elevation in metres on a 5 m grid).
Licence: GPL-2+ (the package's copyright file, copied beside this file as `copyright`).
Original data: Hubbell and Foster (1983); Condit, Hubbell and Foster (1996); Condit (1998);
  data files supplied to spatstat by Rasmus Waagepetersen; analysed by Moller and
  Waagepetersen (2007).
Converted by forestlod's scripts/fetch-example-data (experiments/src/example_data.rs): dem.asc is
  the elevation grid as an ESRI ASCII grid (sample centres, the plot's own metres, no CRS),
  trees.csv the census positions (tree = order in the dataset), bei.toml the scene file. The
  census has no heights, crowns or orientations: every tree is drawn as the built-in oak at its
  own height (17 m).
";

/// Value written for R's `NA` in the ASCII grid.
const NODATA: f64 = -9999.0;

/// The indices of the samples `c` with `lo - step <= coords[c] <= hi + step`, clamped to ones
/// that exist: the samples covering `[lo, hi]` plus one each side.
fn covering(coords: &[f64], step: f64, lo: f64, hi: f64) -> std::ops::RangeInclusive<usize> {
    let first = coords.iter().position(|&c| c >= lo - step).unwrap_or(0);
    let last = coords
        .iter()
        .rposition(|&c| c <= hi + step)
        .unwrap_or(coords.len() - 1);
    first..=last.max(first)
}

/// Writes `dem.asc`, `trees.csv` and `bei.toml` into `out` (module docs), the whole plot or the
/// `cut` of it.
pub fn write_scene(
    census: &Census,
    elev: &Elevation,
    cut: Option<Window>,
    out: &Path,
) -> Result<Written, DataError> {
    let w = cut.map_or(census.window, |c| c.0);
    let (cols, rows) = (
        covering(&elev.xcol, elev.step, w[0], w[2]),
        covering(&elev.yrow, elev.step, w[1], w[3]),
    );
    let (c0, r0) = (*cols.start(), *rows.start());
    let mut asc = String::new();
    let _ = write!(
        asc,
        "ncols {}\nnrows {}\nxllcenter {}\nyllcenter {}\ncellsize {}\nNODATA_value {NODATA}\n",
        cols.clone().count(),
        rows.clone().count(),
        elev.xcol[c0],
        elev.yrow[r0],
        elev.step
    );
    let mut relief = [f64::INFINITY, f64::NEG_INFINITY];
    for r in rows.clone().rev() {
        let line: Vec<String> = cols
            .clone()
            .map(|c| {
                let h = elev.at(c, r);
                if h.is_finite() {
                    relief = [relief[0].min(h), relief[1].max(h)];
                    format!("{h}")
                } else {
                    format!("{NODATA}")
                }
            })
            .collect();
        asc += &line.join(" ");
        asc.push('\n');
    }
    let mut csv = String::from("tree,x,y,species\n");
    let mut trees = 0;
    for (i, (&x, &y)) in census.x.iter().zip(&census.y).enumerate() {
        if (w[0]..=w[2]).contains(&x) && (w[1]..=w[3]).contains(&y) {
            let _ = writeln!(csv, "{},{x},{y},{SPECIES_NAME}", i + 1);
            trees += 1;
        }
    }
    if trees == 0 {
        return Err(derr(format!(
            "window {w:?}: no tree of the census inside it"
        )));
    }
    let toml = format!(
        r#"# Barro Colorado Island, Panama: the {n} trees of Beilschmiedia pendula (Lauraceae) in the
# 1000 m x 500 m forest dynamics plot{cut}, on the plot's 5 m elevation model.
# Source: Debian's {PACKAGE} {PACKAGE_VERSION} (datasets bei, bei.extra$elev; GPL-2+; see
# SOURCE.txt). Written by scripts/fetch-example-data (experiments/src/example_data.rs).
# The census gives positions only: every tree is the built-in {DRAWN_AS} at its own height,
# its yaw a fixed function of its row. Coordinates are the plot's own metres.
name = "bci-bei"
instances = "trees.csv"

[terrain]
kind = "dem"
file = "dem.asc"

[columns]
x = "x"
y = "y"
species = "species"

[species_names]
"{SPECIES_NAME}" = "{DRAWN_AS}"
"#,
        n = trees,
        cut = match cut {
            Some(Window(c)) => format!(" (cut to x {}..{} m, y {}..{} m)", c[0], c[2], c[1], c[3]),
            None => String::new(),
        },
    );
    std::fs::create_dir_all(out).map_err(|e| derr(format!("{}: {e}", out.display())))?;
    for (name, text) in [
        ("dem.asc", asc),
        ("trees.csv", csv),
        ("bei.toml", toml),
        ("SOURCE.txt", SOURCE.to_string()),
    ] {
        let p = out.join(name);
        std::fs::write(&p, text).map_err(|e| derr(format!("{}: {e}", p.display())))?;
    }
    Ok(Written {
        trees,
        dem_size: [cols.clone().count(), rows.clone().count()],
        relief,
        dem_extent: [
            elev.xcol[c0],
            elev.yrow[r0],
            elev.xcol[*cols.end()],
            elev.yrow[*rows.end()],
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Serializes a small R object the way R's `serialize(xdr = TRUE, version = 2)` does.
    struct W(Vec<u8>);
    impl W {
        fn new() -> W {
            let mut w = W(b"X\n".to_vec());
            for v in [2, 0x040200, 0x020300] {
                w.int(v);
            }
            w
        }
        fn int(&mut self, v: i32) -> &mut W {
            self.0.extend(v.to_be_bytes());
            self
        }
        fn charsxp(&mut self, s: &str) -> &mut W {
            self.int(0x00040009).int(s.len() as i32);
            self.0.extend(s.as_bytes());
            self
        }
        fn reals(&mut self, attr: bool, v: &[f64]) -> &mut W {
            self.int(14 | if attr { 1 << 9 } else { 0 })
                .int(v.len() as i32);
            for x in v {
                self.0.extend(x.to_be_bytes());
            }
            self
        }
        fn strs(&mut self, v: &[&str]) -> &mut W {
            self.int(16).int(v.len() as i32);
            for s in v {
                self.charsxp(s);
            }
            self
        }
        /// A pairlist cell with a tag: the first tag a new symbol, later ones references.
        fn tag_new(&mut self, name: &str) -> &mut W {
            self.int(2 | (1 << 10)).int(1).charsxp(name)
        }
    }

    #[test]
    fn reads_a_named_list_with_a_class_and_a_shared_symbol() {
        // list(x = c(1.5, -2), y = c(3)) with class "ppp" and names; the `names` symbol appears
        // twice (inner vector's names too) and is a reference the second time.
        let mut w = W::new();
        w.int(19 | (1 << 9)).int(2); // VECSXP with attributes, 2 items
        w.reals(true, &[1.5, -2.0]);
        w.tag_new("names").strs(&["a", "b"]).int(254); // attrs of item 1: names = c("a","b")
        w.reals(false, &[3.0]);
        w.tag_new("class").strs(&["ppp"]); // attrs of the list: class, then names by reference
        w.int(2 | (1 << 10))
            .int(0x0000_01ff)
            .strs(&["x", "y"])
            .int(254);
        let v = unserialize(&w.0, "test").unwrap();
        assert!(v.has_class("ppp"));
        assert_eq!(v.names(), ["x", "y"]);
        assert_eq!(v.field("x").unwrap().numbers().unwrap(), [1.5, -2.0]);
        assert_eq!(v.field("x").unwrap().names(), ["a", "b"]);
        assert_eq!(v.field("y").unwrap().numbers().unwrap(), [3.0]);
    }

    #[test]
    fn truncated_unknown_and_oversized_input_are_errors_naming_the_offset() {
        let mut w = W::new();
        w.reals(false, &[1.0, 2.0]);
        let full = w.0.clone();
        for cut in 0..full.len() {
            let e = unserialize(&full[..cut], "dem.rdb").unwrap_err();
            assert!(e.0.starts_with("dem.rdb: byte "), "{e}");
        }
        let mut w = W::new();
        w.int(4).int(0); // an environment
        let e = unserialize(&w.0, "x").unwrap_err();
        assert!(e.0.contains("R object type 4"), "{e}");
        let mut w = W::new();
        w.int(14).int(1 << 30); // 2^30 doubles in a 20-byte stream
        let e = unserialize(&w.0, "x").unwrap_err();
        assert!(e.0.contains("length 1073741824"), "{e}");
    }

    fn grid() -> Elevation {
        // 4 columns (x 0..15) by 3 rows (y 0..10), height = 100 + x + 10 y, one NA.
        let (xcol, yrow) = (vec![0.0, 5.0, 10.0, 15.0], vec![0.0, 5.0, 10.0]);
        let mut v = Vec::new();
        for x in &xcol {
            for y in &yrow {
                v.push(100.0 + x + 10.0 * y);
            }
        }
        v[1] = f64::NAN; // (col 0, row 1)
        Elevation {
            xcol,
            yrow,
            step: 5.0,
            v,
        }
    }

    /// The written grid, read back by the scene loader's DEM reader, holds every sample at its
    /// own coordinates: rows from the north, columns from R's column-major matrix.
    #[test]
    fn the_written_dem_reads_back_at_the_samples_coordinates() {
        let elev = grid();
        let census = Census {
            x: vec![2.0, 14.0],
            y: vec![9.0, 1.0],
            window: [0.0, 0.0, 15.0, 10.0],
        };
        let dir = std::env::temp_dir().join(format!("forestlod-bei-unit-{}", std::process::id()));
        let written = write_scene(&census, &elev, None, &dir).unwrap();
        assert_eq!(written.dem_size, [4, 3]);
        assert_eq!(written.trees, 2);
        let r = forestlod_reference::scene::load::dem::load_dem(&dir.join("dem.asc")).unwrap();
        for (c, &x) in elev.xcol.iter().enumerate() {
            for (row, &y) in elev.yrow.iter().enumerate() {
                let want = elev.at(c, row);
                let got = r.samples[(r.height - 1 - row) * r.width + c];
                assert!(
                    got.to_bits() == (want as f32).to_bits() || (want.is_nan() && got.is_nan()),
                    "({x}, {y}): {got} vs {want}"
                );
            }
        }
        // The north-east corner, and a cell with the `NA` corner (col 0, second row from south).
        assert_eq!(r.height_at(15.0, 10.0), Some(215.0));
        assert_eq!(r.height_at(2.5, 7.5), None);
        assert_eq!(r.height_at(12.5, 2.5), Some(100.0 + 12.5 + 25.0));
        let csv = std::fs::read_to_string(dir.join("trees.csv")).unwrap();
        assert_eq!(
            csv,
            format!("tree,x,y,species\n1,2,9,{SPECIES_NAME}\n2,14,1,{SPECIES_NAME}\n")
        );
        let cut = write_scene(
            &census,
            &elev,
            Some(Window([10.0, 0.0, 15.0, 4.0])),
            &dir.join("cut"),
        )
        .unwrap();
        assert_eq!((cut.trees, cut.dem_size), (1, [3, 2]));
        assert_eq!(cut.dem_extent, [5.0, 0.0, 15.0, 5.0]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn inconsistent_images_and_points_outside_the_window_are_refused() {
        let elev = grid();
        let im = |xstep: f64| RValue {
            data: RData::List(vec![
                RValue::plain(RData::Real(elev.v.clone())),
                RValue::plain(RData::Int(vec![3, 4])),
                RValue::plain(RData::Real(elev.xcol.clone())),
                RValue::plain(RData::Real(elev.yrow.clone())),
                RValue::plain(RData::Real(vec![xstep])),
                RValue::plain(RData::Real(vec![5.0])),
            ]),
            attrs: vec![
                (
                    "names".into(),
                    RValue::plain(RData::Str(
                        ["v", "dim", "xcol", "yrow", "xstep", "ystep"]
                            .map(|s| Some(s.to_string()))
                            .to_vec(),
                    )),
                ),
                (
                    "class".into(),
                    RValue::plain(RData::Str(vec![Some("im".into())])),
                ),
            ],
        };
        let ok = elevation(&im(5.0), "e").unwrap();
        assert_eq!(ok.v.len(), 12);
        assert!(elevation(&im(4.0), "e").unwrap_err().0.contains("steps"));
        let ppp = |x: f64| RValue {
            data: RData::List(vec![
                RValue::plain(RData::Real(vec![x])),
                RValue::plain(RData::Real(vec![1.0])),
                RValue::plain(RData::Int(vec![1])),
                RValue {
                    data: RData::List(vec![
                        RValue::plain(RData::Real(vec![0.0, 10.0])),
                        RValue::plain(RData::Real(vec![0.0, 10.0])),
                    ]),
                    attrs: vec![(
                        "names".into(),
                        RValue::plain(RData::Str(vec![
                            Some("xrange".into()),
                            Some("yrange".into()),
                        ])),
                    )],
                },
            ]),
            attrs: vec![
                (
                    "names".into(),
                    RValue::plain(RData::Str(
                        ["x", "y", "n", "window"]
                            .map(|s| Some(s.to_string()))
                            .to_vec(),
                    )),
                ),
                (
                    "class".into(),
                    RValue::plain(RData::Str(vec![Some("ppp".into())])),
                ),
            ],
        };
        assert_eq!(census(&ppp(3.0), "p").unwrap().x, [3.0]);
        let e = census(&ppp(11.0), "p").unwrap_err();
        assert!(e.0.contains("tree 1 at (11, 1) is outside"), "{e}");
    }
}
