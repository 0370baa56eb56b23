//! A minimal GeoTIFF writer (issue 34): what the DEM reader's tests and the CLI tests write
//! their elevation models with, one height field in every variant the reader takes (16-bit
//! integer or 32-bit float samples, strips or tiles, any compression the caller supplies,
//! pixel-is-area or pixel-is-point, scale + tie point or a transformation matrix, a nodata tag).
//! Little-endian classic TIFF, one image, one band. Not a general writer: no reader-side
//! guarantee rests on it (the `tiff` crate reads what it writes, and the tests compare the
//! heights read against the field written).

/// Sample type of a written GeoTIFF.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// Unsigned 16-bit integers.
    U16,
    /// Signed 16-bit integers.
    I16,
    /// 32-bit floats.
    F32,
    /// 8-bit unsigned (a format the reader refuses).
    U8,
}

/// How the samples are cut into chunks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chunks {
    /// Strips of this many rows.
    Strips(u32),
    /// Tiles of this size (a multiple of 16).
    Tiles(u32, u32),
}

/// How the raster is placed.
#[derive(Clone, Debug, PartialEq)]
pub enum Placement {
    /// `ModelPixelScale [dx, dy, 0]` and one `ModelTiepoint (0, 0, 0, x, y, 0)`.
    ScaleTie {
        /// Spacing.
        scale: [f64; 2],
        /// World position of raster point (0, 0).
        tie: [f64; 2],
    },
    /// A `ModelTransformation` (row-major 4x4).
    Matrix([f64; 16]),
}

/// A GeoTIFF to write.
#[derive(Clone, Debug)]
pub struct GeoTiffSpec {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Samples, row by row from the north, as `f64` (converted to `kind`).
    pub samples: Vec<f64>,
    /// Sample type.
    pub kind: SampleKind,
    /// Strips or tiles.
    pub chunks: Chunks,
    /// Placement.
    pub placement: Placement,
    /// `GTRasterTypeGeoKey` = PixelIsPoint (else PixelIsArea).
    pub pixel_is_point: bool,
    /// `GTModelTypeGeoKey`: 1 projected, 2 geographic.
    pub model_type: u16,
    /// `ProjectedCSTypeGeoKey` (an EPSG code).
    pub epsg: u16,
    /// GDAL's nodata tag text.
    pub nodata: Option<String>,
}

impl GeoTiffSpec {
    /// A projected (EPSG 32633) pixel-is-area GeoTIFF of `samples` with spacing `d` whose
    /// top-left pixel corner is at `corner`, in strips of 4 rows.
    pub fn new(
        width: u32,
        height: u32,
        samples: Vec<f64>,
        kind: SampleKind,
        corner: [f64; 2],
        d: f64,
    ) -> Self {
        Self {
            width,
            height,
            samples,
            kind,
            chunks: Chunks::Strips(4),
            placement: Placement::ScaleTie {
                scale: [d, d],
                tie: corner,
            },
            pixel_is_point: false,
            model_type: 1,
            epsg: 32633,
            nodata: None,
        }
    }
}

fn sample_bytes(kind: SampleKind, v: f64, out: &mut Vec<u8>) {
    match kind {
        SampleKind::U16 => out.extend_from_slice(&(v as u16).to_le_bytes()),
        SampleKind::I16 => out.extend_from_slice(&(v as i16).to_le_bytes()),
        SampleKind::F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
        SampleKind::U8 => out.push(v as u8),
    }
}

/// The file's bytes; `compress` turns a chunk's raw bytes into what is stored, `compression` is
/// its TIFF code (1 with the identity).
pub fn write_geotiff(
    spec: &GeoTiffSpec,
    compression: u16,
    compress: &dyn Fn(&[u8]) -> Vec<u8>,
) -> Vec<u8> {
    let (w, h) = (spec.width, spec.height);
    let at = |c: u32, r: u32| -> f64 {
        if c < w && r < h {
            spec.samples[(r * w + c) as usize]
        } else {
            0.0
        }
    };
    // Raw chunks.
    let mut chunks: Vec<Vec<u8>> = Vec::new();
    match spec.chunks {
        Chunks::Strips(rows) => {
            for r0 in (0..h).step_by(rows as usize) {
                let mut b = Vec::new();
                for r in r0..(r0 + rows).min(h) {
                    for c in 0..w {
                        sample_bytes(spec.kind, at(c, r), &mut b);
                    }
                }
                chunks.push(b);
            }
        }
        Chunks::Tiles(tw, th) => {
            for r0 in (0..h).step_by(th as usize) {
                for c0 in (0..w).step_by(tw as usize) {
                    let mut b = Vec::new();
                    for r in r0..r0 + th {
                        for c in c0..c0 + tw {
                            sample_bytes(spec.kind, at(c, r), &mut b);
                        }
                    }
                    chunks.push(b);
                }
            }
        }
    }
    let stored: Vec<Vec<u8>> = chunks.iter().map(|c| compress(c)).collect();
    let mut file: Vec<u8> = vec![b'I', b'I', 42, 0, 0, 0, 0, 0];
    let mut offsets = Vec::new();
    for c in &stored {
        offsets.push(file.len() as u32);
        file.extend_from_slice(c);
        if file.len() % 2 == 1 {
            file.push(0);
        }
    }
    let counts: Vec<u32> = stored.iter().map(|c| c.len() as u32).collect();
    // Entries: (tag, type, values as bytes, count).
    enum V {
        S(Vec<u16>),
        L(Vec<u32>),
        D(Vec<f64>),
        A(String),
    }
    let (bits, format) = match spec.kind {
        SampleKind::U16 => (16, 1),
        SampleKind::I16 => (16, 2),
        SampleKind::F32 => (32, 3),
        SampleKind::U8 => (8, 1),
    };
    let mut entries: Vec<(u16, V)> = vec![
        (256, V::L(vec![w])),
        (257, V::L(vec![h])),
        (258, V::S(vec![bits])),
        (259, V::S(vec![compression])),
        (262, V::S(vec![1])),
        (277, V::S(vec![1])),
        (284, V::S(vec![1])),
        (339, V::S(vec![format])),
    ];
    match spec.chunks {
        Chunks::Strips(rows) => {
            entries.push((273, V::L(offsets)));
            entries.push((278, V::L(vec![rows])));
            entries.push((279, V::L(counts)));
        }
        Chunks::Tiles(tw, th) => {
            entries.push((322, V::L(vec![tw])));
            entries.push((323, V::L(vec![th])));
            entries.push((324, V::L(offsets)));
            entries.push((325, V::L(counts)));
        }
    }
    match &spec.placement {
        Placement::ScaleTie { scale, tie } => {
            entries.push((33550, V::D(vec![scale[0], scale[1], 0.0])));
            entries.push((33922, V::D(vec![0.0, 0.0, 0.0, tie[0], tie[1], 0.0])));
        }
        Placement::Matrix(m) => entries.push((34264, V::D(m.to_vec()))),
    }
    let raster_type = if spec.pixel_is_point { 2 } else { 1 };
    entries.push((
        34735,
        V::S(vec![
            1,
            1,
            0,
            3, // version, revision, minor, key count
            1024,
            0,
            1,
            spec.model_type, // GTModelTypeGeoKey
            1025,
            0,
            1,
            raster_type, // GTRasterTypeGeoKey
            3072,
            0,
            1,
            spec.epsg, // ProjectedCSTypeGeoKey
        ]),
    ));
    if let Some(n) = &spec.nodata {
        entries.push((42113, V::A(n.clone())));
    }
    entries.sort_by_key(|e| e.0);
    // Values that do not fit in 4 bytes go before the IFD.
    let mut ifd_entries: Vec<[u8; 12]> = Vec::new();
    for (tag, v) in &entries {
        let (ty, count, bytes): (u16, u32, Vec<u8>) = match v {
            V::S(s) => (
                3,
                s.len() as u32,
                s.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ),
            V::L(s) => (
                4,
                s.len() as u32,
                s.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ),
            V::D(s) => (
                12,
                s.len() as u32,
                s.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ),
            V::A(t) => {
                let mut b = t.as_bytes().to_vec();
                b.push(0);
                (2, b.len() as u32, b)
            }
        };
        let mut e = [0u8; 12];
        e[0..2].copy_from_slice(&tag.to_le_bytes());
        e[2..4].copy_from_slice(&ty.to_le_bytes());
        e[4..8].copy_from_slice(&count.to_le_bytes());
        if bytes.len() <= 4 {
            e[8..8 + bytes.len()].copy_from_slice(&bytes);
        } else {
            let off = file.len() as u32;
            file.extend_from_slice(&bytes);
            if file.len() % 2 == 1 {
                file.push(0);
            }
            e[8..12].copy_from_slice(&off.to_le_bytes());
        }
        ifd_entries.push(e);
    }
    let ifd = file.len() as u32;
    file[4..8].copy_from_slice(&ifd.to_le_bytes());
    file.extend_from_slice(&(ifd_entries.len() as u16).to_le_bytes());
    for e in &ifd_entries {
        file.extend_from_slice(e);
    }
    file.extend_from_slice(&0u32.to_le_bytes());
    file
}
