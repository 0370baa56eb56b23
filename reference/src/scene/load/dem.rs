//! Elevation models as terrain (issue 34): a GeoTIFF or an ESRI ASCII grid read into a
//! [`Raster`] in world coordinates (`f64`), checked, then resampled to a vertex budget into the
//! [`HeightGrid`] both rasterizers draw and the ray-traced truth intersects
//! ([`crate::scene::Terrain::Grid`]).
//!
//! # Contract
//! - **Formats.** GeoTIFF: one band of 16-bit integer (signed or unsigned) or 32-bit float
//!   samples (64-bit float too), in strips or tiles, uncompressed, deflate or LZW, north-up
//!   (`ModelPixelScale` + `ModelTiepoint`, or a `ModelTransformation` without rotation terms),
//!   `PixelIsArea` (the default) or `PixelIsPoint` (`GTRasterTypeGeoKey`), GDAL's nodata tag
//!   (42113). ESRI ASCII grid: `ncols`, `nrows`, `xllcorner`/`xllcenter`, `yllcorner`/`yllcenter`,
//!   `cellsize`, optional `NODATA_value`, then the rows from the north.
//! - **Library.** The pure-Rust `tiff` crate (strips, tiles, deflate, LZW, predictors) plus the
//!   GeoTIFF tags read here, not GDAL: it needs no system package, so `scripts/install-deps` and
//!   CI stay as they are (GDAL's bindings need `libgdal-dev` and a C++ build), and the few
//!   GeoTIFF keys a north-up DEM needs are a page of code. GeoPackage (SQLite) is not read.
//! - **Georeferencing.** Sample `(col, row)` (row 0 the northern one) has its centre at
//!   `(x0 + col · dx, y0 - row · dy)`, world metres; `PixelIsArea` tie points name the top-left
//!   pixel's corner, `PixelIsPoint` its centre (GeoTIFF 1.1 §2.5.2.2). A geographic CRS (degrees)
//!   is refused: trees and heights are metres. The CRS is reported as its EPSG code; the world
//!   coordinates go into the scene's `f64` origin like a CSV's (SPEC §3, §7).
//! - **Refused, naming the file, the field and the value** (never a panic, never misread): a
//!   truncated or undecodable file, a sample format other than the above, more than one band, a
//!   rotated or sheared transformation, no georeferencing, zero or negative spacing, NaN samples
//!   unless the nodata value is NaN, every sample nodata, and a declared size of more than
//!   [`MAX_DEM_SAMPLES`] samples or (uncompressed, or the ASCII grid) more than the file can
//!   hold, before any sample buffer is allocated.
//! - **Nodata** samples are missing: a tree over one is outside the DEM; for drawing they are
//!   filled from the nearest valid sample of their row, rows without one from the nearest row
//!   that has one.
//! - **Resampling.** [`resample`]: the native grid if it has at most `budget` vertices (heights
//!   bit for bit), else the largest grid with the same extent and aspect within the budget,
//!   bilinear in the native samples.

use std::path::Path;

use super::paths::{label, read_limited};
use crate::InputError;
use crate::scene::HeightGrid;

/// Most samples an elevation model may declare (a 1 m DEM of 8 km × 8 km; 256 MiB as `f32`).
pub const MAX_DEM_SAMPLES: u64 = 1 << 26;
/// Largest elevation-model file read, bytes.
pub const MAX_DEM_FILE_BYTES: u64 = 1 << 30;
/// Default vertex budget of a DEM terrain's drawn grid (257² ≈ 66,000 vertices, 131,000
/// triangles).
pub const DEFAULT_DEM_VERTICES: u32 = 257 * 257;
/// Largest vertex budget a scene file may ask for.
pub const MAX_DEM_VERTICES: u32 = 2049 * 2049;

/// An elevation model as read, in world coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Raster {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// World `x` of the centre of the western column.
    pub x0: f64,
    /// World `y` of the centre of the northern row.
    pub y0: f64,
    /// Column spacing, metres (> 0).
    pub dx: f64,
    /// Row spacing, metres (> 0; rows go south).
    pub dy: f64,
    /// Heights, row by row from the north, NaN where nodata.
    pub samples: Vec<f32>,
    /// The CRS as read (`EPSG:32633`), when the file names one.
    pub crs: Option<String>,
}

impl Raster {
    /// World extent of the sample centres, `[x_min, y_min, x_max, y_max]`.
    pub fn extent(&self) -> [f64; 4] {
        [
            self.x0,
            self.y0 - self.dy * (self.height - 1) as f64,
            self.x0 + self.dx * (self.width - 1) as f64,
            self.y0,
        ]
    }

    /// Bilinear height at world `(x, y)`, `None` outside the sample centres' extent or where a
    /// sample of the cell is nodata.
    pub fn height_at(&self, x: f64, y: f64) -> Option<f64> {
        let fc = (x - self.x0) / self.dx;
        let fr = (self.y0 - y) / self.dy;
        let (w, h) = ((self.width - 1) as f64, (self.height - 1) as f64);
        if !((0.0..=w).contains(&fc) && (0.0..=h).contains(&fr)) {
            return None;
        }
        let (c, r) = (
            (fc.floor() as usize).min(self.width.saturating_sub(2)),
            (fr.floor() as usize).min(self.height.saturating_sub(2)),
        );
        let (tx, ty) = (fc - c as f64, fr - r as f64);
        let s = |c: usize, r: usize| {
            let c = c.min(self.width - 1);
            let r = r.min(self.height - 1);
            f64::from(self.samples[r * self.width + c])
        };
        let (a, b, cc, d) = (s(c, r), s(c + 1, r), s(c, r + 1), s(c + 1, r + 1));
        let v = (a * (1.0 - tx) + b * tx) * (1.0 - ty) + (cc * (1.0 - tx) + d * tx) * ty;
        v.is_finite().then_some(v)
    }
}

fn err(
    file: &str,
    field: impl Into<String>,
    value: impl std::fmt::Display,
    why: impl Into<String>,
) -> InputError {
    InputError::new(file, field, value, why)
}

/// Reads an elevation model by its extension: `.tif`/`.tiff` GeoTIFF, `.asc` ESRI ASCII grid.
pub fn load_dem(path: &Path) -> Result<Raster, InputError> {
    let file = label(path);
    let bytes = read_limited(path, MAX_DEM_FILE_BYTES)?;
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("tif" | "tiff") => parse_geotiff(&bytes, &file),
        Some("asc") => parse_ascii_grid(&bytes, &file),
        other => Err(err(
            &file,
            "file extension",
            other.unwrap_or(""),
            "expected a GeoTIFF (.tif, .tiff) or an ESRI ASCII grid (.asc)",
        )),
    }
}

/// Checks the declared size before anything is allocated: at most [`MAX_DEM_SAMPLES`], and at
/// most what `available` bytes of `bytes_per_sample` each can hold (`None`: compressed, no bound
/// from the file).
fn check_size(
    file: &str,
    width: u64,
    height: u64,
    bytes_per_sample: u64,
    available: Option<u64>,
) -> Result<(), InputError> {
    let size = format!("{width}x{height}");
    if width < 2 || height < 2 {
        return Err(err(file, "size", size, "expected at least 2x2 samples"));
    }
    let n = width.saturating_mul(height);
    if n > MAX_DEM_SAMPLES {
        return Err(err(
            file,
            "size",
            size,
            format!("more than {MAX_DEM_SAMPLES} samples: cut or coarsen the elevation model"),
        ));
    }
    if let Some(avail) = available
        && n.saturating_mul(bytes_per_sample) > avail
    {
        return Err(err(
            file,
            "size",
            size,
            format!(
                "declares {} bytes of samples but the file holds {avail}: truncated or corrupt",
                n * bytes_per_sample
            ),
        ));
    }
    Ok(())
}

/// Parses a GeoTIFF (module docs).
pub fn parse_geotiff(bytes: &[u8], file: &str) -> Result<Raster, InputError> {
    use tiff::decoder::{Decoder, DecodingResult, Limits};
    use tiff::tags::Tag;
    let tiff_err = |what: &str, e: tiff::TiffError| {
        err(file, what, "", format!("not a readable GeoTIFF: {e}"))
    };
    let mut limits = Limits::default();
    limits.decoding_buffer_size = (MAX_DEM_SAMPLES * 8) as usize;
    let mut dec = Decoder::new(std::io::Cursor::new(bytes))
        .map_err(|e| tiff_err("header", e))?
        .with_limits(limits);
    let (w, h) = dec.dimensions().map_err(|e| tiff_err("size", e))?;
    let spp = dec
        .find_tag_unsigned::<u16>(Tag::SamplesPerPixel)
        .map_err(|e| tiff_err("SamplesPerPixel", e))?
        .unwrap_or(1);
    if spp != 1 {
        return Err(err(
            file,
            "SamplesPerPixel",
            spp,
            "expected one band (a single-band elevation model)",
        ));
    }
    let bits = dec
        .find_tag_unsigned_vec::<u16>(Tag::BitsPerSample)
        .map_err(|e| tiff_err("BitsPerSample", e))?
        .unwrap_or_else(|| vec![1]);
    let format = dec
        .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
        .map_err(|e| tiff_err("SampleFormat", e))?
        .unwrap_or_else(|| vec![1]);
    let (b, f) = (
        bits.first().copied().unwrap_or(1),
        format.first().copied().unwrap_or(1),
    );
    let bytes_per_sample = match (b, f) {
        (16, 1 | 2) => 2,
        (32, 3) => 4,
        (64, 3) => 8,
        _ => {
            return Err(err(
                file,
                "BitsPerSample/SampleFormat",
                format!("{b} bits, format {f}"),
                "expected 16-bit integer (format 1 or 2) or 32/64-bit float (format 3) samples",
            ));
        }
    };
    let compression = dec
        .find_tag_unsigned::<u16>(Tag::Compression)
        .map_err(|e| tiff_err("Compression", e))?
        .unwrap_or(1);
    if !matches!(compression, 1 | 5 | 8 | 32946) {
        return Err(err(
            file,
            "Compression",
            compression,
            "expected none (1), LZW (5) or deflate (8, 32946)",
        ));
    }
    let available = (compression == 1).then_some(bytes.len() as u64);
    check_size(file, w.into(), h.into(), bytes_per_sample, available)?;

    // Georeferencing.
    let f64s =
        |dec: &mut Decoder<_>, tag: Tag, name: &str| -> Result<Option<Vec<f64>>, InputError> {
            match dec.find_tag(tag).map_err(|e| tiff_err(name, e))? {
                None => Ok(None),
                Some(v) => v.into_f64_vec().map(Some).map_err(|e| tiff_err(name, e)),
            }
        };
    let keys = dec
        .find_tag_unsigned_vec::<u16>(Tag::GeoKeyDirectoryTag)
        .map_err(|e| tiff_err("GeoKeyDirectory", e))?
        .unwrap_or_default();
    let key = |id: u16| -> Option<u16> {
        // Header of 4 shorts, then (key, location, count, value) entries; location 0 = inline.
        keys.get(4..)?
            .chunks_exact(4)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    };
    if key(1024) == Some(2) {
        return Err(err(
            file,
            "GTModelTypeGeoKey",
            2,
            "a geographic CRS (degrees): expected a projected CRS in metres (e.g. UTM); reproject the DEM",
        ));
    }
    let pixel_is_point = key(1025) == Some(2);
    let crs = key(3072)
        .or_else(|| key(2048))
        .filter(|&c| c != 0 && c != 32767)
        .map(|c| format!("EPSG:{c}"));
    let transform = f64s(&mut dec, Tag::ModelTransformationTag, "ModelTransformation")?;
    let (sx, sy, tx, ty) = if let Some(m) = transform {
        if m.len() != 16 || m.iter().any(|v| !v.is_finite()) {
            return Err(err(
                file,
                "ModelTransformation",
                format!("{m:?}"),
                "expected 16 finite values",
            ));
        }
        if m[1] != 0.0 || m[4] != 0.0 {
            return Err(err(
                file,
                "ModelTransformation",
                format!("[{}, {}; {}, {}]", m[0], m[1], m[4], m[5]),
                "rotated or sheared: expected a north-up raster (warp it north-up first)",
            ));
        }
        (m[0], -m[5], m[3], m[7])
    } else {
        let scale = f64s(&mut dec, Tag::ModelPixelScaleTag, "ModelPixelScale")?;
        let tie = f64s(&mut dec, Tag::ModelTiepointTag, "ModelTiepoint")?;
        match (scale, tie) {
            (Some(s), Some(t)) if s.len() >= 2 && t.len() >= 6 => {
                if t.len() > 6 {
                    return Err(err(
                        file,
                        "ModelTiepoint",
                        format!("{} tie points", t.len() / 6),
                        "several tie points (a warped raster): expected one and a pixel scale",
                    ));
                }
                (s[0], s[1], t[3] - t[0] * s[0], t[4] + t[1] * s[1])
            }
            _ => {
                return Err(err(
                    file,
                    "georeferencing",
                    "",
                    "missing: expected ModelPixelScale and ModelTiepoint, or ModelTransformation",
                ));
            }
        }
    };
    if !(sx.is_finite()
        && sy.is_finite()
        && sx > 0.0
        && sy > 0.0
        && tx.is_finite()
        && ty.is_finite())
    {
        return Err(err(
            file,
            "pixel scale",
            format!("[{sx}, {sy}] at [{tx}, {ty}]"),
            "expected finite positive spacing (north-up: x east, rows south) and a finite tie point",
        ));
    }
    let (x0, y0) = if pixel_is_point {
        (tx, ty)
    } else {
        (tx + 0.5 * sx, ty - 0.5 * sy)
    };
    let nodata = match dec
        .find_tag(Tag::GdalNodata)
        .map_err(|e| tiff_err("GDAL_NODATA", e))?
    {
        None => None,
        Some(v) => {
            let text = v.into_string().map_err(|e| tiff_err("GDAL_NODATA", e))?;
            let t = text.trim_matches(char::from(0)).trim();
            Some(
                t.parse::<f64>()
                    .map_err(|_| err(file, "GDAL_NODATA", t, "expected a number (or nan)"))?,
            )
        }
    };
    // The `tiff` crate asserts on some malformed LZW streams (0.10.3, `LZWReader::read`): a
    // panic there is this file's error, not the program's.
    let image = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| dec.read_image()))
        .map_err(|_| {
            err(
                file,
                "samples",
                "",
                "not a readable GeoTIFF: the decoder failed on the compressed samples",
            )
        })?
        .map_err(|e| tiff_err("samples", e))?;
    let samples: Vec<f64> = match image {
        DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F64(v) => v,
        _ => return Err(err(file, "samples", "", "unexpected sample type")),
    };
    finish(
        file,
        w as usize,
        h as usize,
        [x0, y0, sx, sy],
        samples,
        nodata,
        crs,
    )
}

/// Checks the samples and builds the raster: nodata (and NaN when the nodata value is NaN)
/// becomes NaN; any other NaN or infinity is refused; all-nodata is refused.
fn finish(
    file: &str,
    width: usize,
    height: usize,
    [x0, y0, dx, dy]: [f64; 4],
    samples: Vec<f64>,
    nodata: Option<f64>,
    crs: Option<String>,
) -> Result<Raster, InputError> {
    if samples.len() != width * height {
        return Err(err(
            file,
            "samples",
            samples.len(),
            format!("expected {width}x{height} samples"),
        ));
    }
    let mut out = Vec::with_capacity(samples.len());
    let mut valid = 0usize;
    for (k, v) in samples.into_iter().enumerate() {
        let missing = match nodata {
            Some(n) if n.is_nan() => v.is_nan(),
            Some(n) => v == n,
            None => false,
        };
        if missing {
            out.push(f32::NAN);
            continue;
        }
        if !v.is_finite() || v.abs() > 1.0e5 {
            return Err(err(
                file,
                format!("sample (column {}, row {})", k % width, k / width),
                v,
                "expected a finite height within ±100 km (declare NaN as nodata if it marks missing samples)",
            ));
        }
        valid += 1;
        out.push(v as f32);
    }
    if valid == 0 {
        return Err(err(
            file,
            "samples",
            format!("{width}x{height}, nodata {:?}", nodata.unwrap_or(f64::NAN)),
            "every sample is nodata",
        ));
    }
    Ok(Raster {
        width,
        height,
        x0,
        y0,
        dx,
        dy,
        samples: out,
        crs,
    })
}

/// Parses an ESRI ASCII grid (module docs).
pub fn parse_ascii_grid(bytes: &[u8], file: &str) -> Result<Raster, InputError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        err(
            file,
            format!("byte {}", e.valid_up_to()),
            "",
            "expected ASCII text",
        )
    })?;
    let mut tokens = text.split_ascii_whitespace().peekable();
    let mut header: Vec<(String, f64)> = Vec::new();
    while let Some(t) = tokens.peek() {
        if !t.chars().next().is_some_and(|c| c.is_ascii_alphabetic()) {
            break;
        }
        let name = tokens.next().unwrap_or_default().to_ascii_lowercase();
        let value = tokens.next().unwrap_or("");
        let v: f64 = value
            .parse()
            .map_err(|_| err(file, format!("header {name}"), value, "expected a number"))?;
        if header.len() >= 8 {
            return Err(err(
                file,
                format!("header {name}"),
                value,
                "too many header lines",
            ));
        }
        header.push((name, v));
    }
    let get = |k: &str| header.iter().find(|(n, _)| n == k).map(|(_, v)| *v);
    let need = |k: &str| get(k).ok_or_else(|| err(file, format!("header {k}"), "", "missing"));
    let (ncols, nrows, cell) = (need("ncols")?, need("nrows")?, need("cellsize")?);
    let whole = |k: &str, v: f64| {
        if v.fract() == 0.0 && (2.0..=1.0e9).contains(&v) {
            Ok(v as u64)
        } else {
            Err(err(
                file,
                format!("header {k}"),
                v,
                "expected a whole number >= 2",
            ))
        }
    };
    let (w, h) = (whole("ncols", ncols)?, whole("nrows", nrows)?);
    // Each sample takes at least two bytes (a digit and a separator).
    check_size(file, w, h, 2, Some(bytes.len() as u64 + 1))?;
    if !(cell.is_finite() && cell > 0.0) {
        return Err(err(
            file,
            "header cellsize",
            cell,
            "expected a finite positive spacing",
        ));
    }
    let (xc, yc) = match (
        get("xllcorner"),
        get("yllcorner"),
        get("xllcenter"),
        get("yllcenter"),
    ) {
        (Some(x), Some(y), None, None) => (x + 0.5 * cell, y + 0.5 * cell),
        (None, None, Some(x), Some(y)) => (x, y),
        _ => {
            return Err(err(
                file,
                "header xllcorner/yllcorner",
                "",
                "expected xllcorner and yllcorner, or xllcenter and yllcenter",
            ));
        }
    };
    if !(xc.is_finite() && yc.is_finite()) {
        return Err(err(
            file,
            "header xllcorner",
            xc,
            "expected finite coordinates",
        ));
    }
    let nodata = get("nodata_value");
    let n = (w * h) as usize;
    let mut samples = Vec::with_capacity(n);
    for t in tokens {
        if samples.len() == n {
            return Err(err(
                file,
                format!("sample {}", n + 1),
                t,
                format!("more than {w}x{h} samples"),
            ));
        }
        let v: f64 = t.parse().map_err(|_| {
            err(
                file,
                format!(
                    "sample (column {}, row {})",
                    samples.len() as u64 % w,
                    samples.len() as u64 / w
                ),
                t,
                "expected a number",
            )
        })?;
        samples.push(v);
    }
    if samples.len() != n {
        return Err(err(
            file,
            "samples",
            samples.len(),
            format!("expected {w}x{h} = {n}: truncated"),
        ));
    }
    let y0 = yc + cell * (h - 1) as f64;
    finish(
        file,
        w as usize,
        h as usize,
        [xc, y0, cell, cell],
        samples,
        nodata,
        None,
    )
}

/// Fills nodata samples (module docs): from the nearest valid sample of the row, rows without
/// one from the nearest row with one. `O(width · height)`.
pub fn filled(r: &Raster) -> Vec<f32> {
    let (w, h) = (r.width, r.height);
    let mut out = r.samples.clone();
    let mut row_ok = vec![false; h];
    for (j, ok) in row_ok.iter_mut().enumerate() {
        let row = &mut out[j * w..(j + 1) * w];
        let mut last: Option<usize> = None;
        // Left to right: distance to the last valid; right to left: fill with the nearer.
        let mut left = vec![usize::MAX; w];
        for i in 0..w {
            if !row[i].is_nan() {
                last = Some(i);
            }
            if let Some(l) = last {
                left[i] = l;
            }
        }
        *ok = last.is_some();
        let mut right: Option<usize> = None;
        for i in (0..w).rev() {
            if !row[i].is_nan() {
                right = Some(i);
                continue;
            }
            let l = (left[i] != usize::MAX).then_some(left[i]);
            let pick = match (l, right) {
                (Some(l), Some(rr)) => Some(if i - l <= rr - i { l } else { rr }),
                (a, b) => a.or(b),
            };
            if let Some(p) = pick {
                row[i] = row[p];
            }
        }
    }
    let valid_rows: Vec<usize> = (0..h).filter(|&j| row_ok[j]).collect();
    for j in 0..h {
        if row_ok[j] {
            continue;
        }
        let near = valid_rows
            .iter()
            .copied()
            .min_by_key(|&k| k.abs_diff(j))
            .unwrap_or(j);
        let src: Vec<f32> = out[near * w..(near + 1) * w].to_vec();
        out[j * w..(j + 1) * w].copy_from_slice(&src);
    }
    out
}

/// The drawn grid of `raster` within `budget` vertices (module docs, "Resampling"), relative
/// to `origin` (world), rows from the south.
pub fn resample(raster: &Raster, budget: u32, origin: [f64; 3]) -> HeightGrid {
    let full = filled(raster);
    let (w, h) = (raster.width, raster.height);
    let (nx, ny) = if (w as u64) * (h as u64) <= u64::from(budget) {
        (w, h)
    } else {
        let f = (f64::from(budget) / (w as f64 * h as f64)).sqrt();
        (
            ((w as f64 * f).floor() as usize).clamp(2, w),
            ((h as f64 * f).floor() as usize).clamp(2, h),
        )
    };
    let [xmin, ymin, xmax, ymax] = raster.extent();
    let mut heights = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        // Row j of the grid from the south; native row index from the north.
        let fr_south = if ny == h {
            j as f64
        } else {
            j as f64 * (h - 1) as f64 / (ny - 1) as f64
        };
        let fr = (h - 1) as f64 - fr_south;
        for i in 0..nx {
            let fc = if nx == w {
                i as f64
            } else {
                i as f64 * (w - 1) as f64 / (nx - 1) as f64
            };
            let z = if nx == w && ny == h {
                f64::from(full[(h - 1 - j) * w + i])
            } else {
                let (c, r) = (
                    (fc.floor() as usize).min(w - 2),
                    (fr.floor() as usize).min(h - 2),
                );
                let (tx, ty) = (fc - c as f64, fr - r as f64);
                let s = |c: usize, r: usize| f64::from(full[r * w + c]);
                (s(c, r) * (1.0 - tx) + s(c + 1, r) * tx) * (1.0 - ty)
                    + (s(c, r + 1) * (1.0 - tx) + s(c + 1, r + 1) * tx) * ty
            };
            heights.push((z - origin[2]) as f32);
        }
    }
    HeightGrid {
        nx,
        ny,
        extent: [
            (xmin - origin[0]) as f32,
            (ymin - origin[1]) as f32,
            (xmax - origin[0]) as f32,
            (ymax - origin[1]) as f32,
        ],
        heights,
    }
}
