//! Elevation models and tree inventories (issue 34): every GeoTIFF variant and the ESRI ASCII
//! grid read into the same heights; bad files refused naming the file; DEM scenes through the
//! scene file (trees on the terrain, the z-mismatch report, points outside the DEM); a DEM equal
//! to `hills` on the same grid gives the same frame and the same truth; inventory mapping by
//! property (the drawn top is the given height within ULPs).

use std::path::PathBuf;

use forestlod_reference::scene::load::dem::{Raster, load_dem, parse_ascii_grid, parse_geotiff};
use forestlod_reference::scene::load::geotiff_writer::{
    Chunks, GeoTiffSpec, Placement, SampleKind, write_geotiff,
};
use forestlod_reference::scene::load::{
    LoadOptions, load_scene_file, load_scene_file_reported, parse_scene_file,
};
use forestlod_reference::scene::{Scene, Terrain};
use proptest::prelude::*;

mod common;

/// Counts this thread's heap in use and its peak (the memory-bound test: the loader is
/// single-threaded, and other tests running beside it do not count).
mod alloc {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static IN_USE: Cell<i64> = const { Cell::new(0) };
        static PEAK: Cell<i64> = const { Cell::new(0) };
    }

    pub struct Counting;

    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            let _ = IN_USE.try_with(|u| {
                u.set(u.get() + l.size() as i64);
                let _ = PEAK.try_with(|p| p.set(p.get().max(u.get())));
            });
            // SAFETY: forwarded to the system allocator with the caller's layout.
            unsafe { System.alloc(l) }
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            let _ = IN_USE.try_with(|u| u.set(u.get() - l.size() as i64));
            // SAFETY: `p` came from `alloc` above with this layout.
            unsafe { System.dealloc(p, l) }
        }
    }

    /// Resets this thread's peak to its heap in use now and returns that.
    pub fn peak_reset() -> i64 {
        let now = IN_USE.with(Cell::get);
        PEAK.with(|p| p.set(now));
        now
    }

    /// This thread's peak growth over `base`, bytes.
    pub fn peak_since(base: i64) -> u64 {
        (PEAK.with(Cell::get) - base).max(0) as u64
    }
}

#[global_allocator]
static ALLOC: alloc::Counting = alloc::Counting;

fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir("dem", test)
}

const W: u32 = 37;
const H: u32 = 29;
/// The top-left pixel's corner and the spacing of every test raster.
const CORNER: [f64; 2] = [500_000.0, 5_300_100.0];
const D: f64 = 2.0;

/// The one height field every variant stores (whole numbers: exact in 16-bit and 32-bit).
fn field(c: u32, r: u32) -> f64 {
    (300 + 3 * c as i64 - 2 * r as i64 + ((c * 7 + r * 13) % 5) as i64) as f64
}

fn samples(offset: f64) -> Vec<f64> {
    (0..H)
        .flat_map(|r| (0..W).map(move |c| field(c, r) + offset))
        .collect()
}

fn identity(b: &[u8]) -> Vec<u8> {
    b.to_vec()
}

fn deflate(b: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

fn lzw(b: &[u8]) -> Vec<u8> {
    weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
        .encode(b)
        .unwrap()
}

/// A compression: its name, its TIFF code and the compressor.
type Compression = (&'static str, u16, fn(&[u8]) -> Vec<u8>);

fn compressions() -> [Compression; 3] {
    [
        ("none", 1, identity),
        ("deflate", 8, deflate),
        ("lzw", 5, lzw),
    ]
}

fn expect_field(r: &Raster, offset: f64, what: &str) {
    assert_eq!((r.width, r.height), (W as usize, H as usize), "{what}");
    assert_eq!(
        [r.x0, r.y0, r.dx, r.dy],
        [CORNER[0] + D / 2.0, CORNER[1] - D / 2.0, D, D],
        "{what}: georeferencing"
    );
    for row in 0..H {
        for c in 0..W {
            assert_eq!(
                f64::from(r.samples[(row * W + c) as usize]),
                field(c, row) + offset,
                "{what}: sample ({c}, {row})"
            );
        }
    }
}

/// Every variant of item 1 (16-bit int signed and unsigned, 32-bit float; strips and tiles;
/// none, deflate, LZW; pixel-is-area and pixel-is-point; scale + tie point and a transformation
/// matrix; with a nodata tag that no sample hits) reads the one height field.
#[test]
fn every_geotiff_variant_reads_the_same_heights() {
    let mut n = 0;
    for kind in [SampleKind::U16, SampleKind::I16, SampleKind::F32] {
        // Signed samples below zero, to see the sign kept.
        let offset = if kind == SampleKind::I16 { -400.0 } else { 0.0 };
        for chunks in [Chunks::Strips(4), Chunks::Strips(H), Chunks::Tiles(16, 16)] {
            for (cname, code, f) in compressions() {
                if cname == "lzw" && matches!(chunks, Chunks::Tiles(..)) && kind != SampleKind::F32
                {
                    continue; // below: the `tiff` crate's limitation on padded 16-bit LZW tiles
                }
                for variant in 0..3 {
                    let mut spec = GeoTiffSpec::new(W, H, samples(offset), kind, CORNER, D);
                    spec.chunks = chunks;
                    match variant {
                        1 => {
                            // Pixel-is-point: the tie point is the top-left pixel's centre.
                            spec.pixel_is_point = true;
                            spec.placement = Placement::ScaleTie {
                                scale: [D, D],
                                tie: [CORNER[0] + D / 2.0, CORNER[1] - D / 2.0],
                            };
                        }
                        2 => {
                            spec.placement = Placement::Matrix([
                                D, 0.0, 0.0, CORNER[0], 0.0, -D, 0.0, CORNER[1], 0.0, 0.0, 0.0,
                                0.0, 0.0, 0.0, 0.0, 1.0,
                            ]);
                            spec.nodata = Some("-9999".into());
                        }
                        _ => {}
                    }
                    let bytes = write_geotiff(&spec, code, &f);
                    let what = format!("{kind:?} {chunks:?} {cname} variant {variant}");
                    let r =
                        parse_geotiff(&bytes, "dem.tif").unwrap_or_else(|e| panic!("{what}: {e}"));
                    expect_field(&r, offset, &what);
                    assert_eq!(r.crs.as_deref(), Some("EPSG:32633"), "{what}");
                    n += 1;
                }
            }
        }
    }
    assert_eq!(n, 75);
    // 16-bit LZW tiles: read when the raster fills its tiles (a 32 x 32 raster in 16 x 16
    // tiles). The `tiff` crate (0.10.3 and 0.11.3) fails on 16-bit LZW edge tiles with padding
    // ("no lzw end code found" while skipping the padding; 0.10.3 panicked there): such a file
    // is refused with that error, naming it.
    let aligned: Vec<f64> = (0..32 * 32).map(|k| f64::from(k % 97)).collect();
    let mut spec = GeoTiffSpec::new(32, 32, aligned.clone(), SampleKind::U16, CORNER, D);
    spec.chunks = Chunks::Tiles(16, 16);
    let r = parse_geotiff(&write_geotiff(&spec, 5, &lzw), "tiles.tif").unwrap();
    assert_eq!(
        r.samples,
        aligned.iter().map(|&v| v as f32).collect::<Vec<_>>()
    );
    let mut padded = GeoTiffSpec::new(W, H, samples(0.0), SampleKind::U16, CORNER, D);
    padded.chunks = Chunks::Tiles(16, 16);
    let e = parse_geotiff(&write_geotiff(&padded, 5, &lzw), "padded.tif").unwrap_err();
    assert!(e.to_string().contains("padded.tif"), "{e}");
}

fn ascii_grid(center: bool, nodata: Option<&str>) -> String {
    let mut s = format!("ncols {W}\nnrows {H}\n");
    if center {
        s += &format!(
            "xllcenter {}\nyllcenter {}\n",
            CORNER[0] + D / 2.0,
            CORNER[1] - D * H as f64 + D / 2.0
        );
    } else {
        s += &format!(
            "xllcorner {}\nyllcorner {}\n",
            CORNER[0],
            CORNER[1] - D * H as f64
        );
    }
    s += &format!("cellsize {D}\n");
    if let Some(n) = nodata {
        s += &format!("NODATA_value {n}\n");
    }
    for r in 0..H {
        let row: Vec<String> = (0..W).map(|c| field(c, r).to_string()).collect();
        s += &row.join(" ");
        s += "\n";
    }
    s
}

/// The ESRI ASCII grid, with corner or centre coordinates, reads the same heights as the GeoTIFFs.
#[test]
fn ascii_grids_read_the_same_heights() {
    for center in [false, true] {
        let r = parse_ascii_grid(ascii_grid(center, Some("-9999")).as_bytes(), "dem.asc").unwrap();
        expect_field(&r, 0.0, &format!("ascii center={center}"));
    }
}

fn refused(bytes: &[u8], wants: &[&str]) {
    let e = parse_geotiff(bytes, "bad.tif").unwrap_err().to_string();
    assert!(e.contains("bad.tif"), "{e}");
    for w in wants {
        assert!(e.contains(w), "expected {w:?} in: {e}");
    }
}

/// Bad files are refused naming the file: truncated, wrong sample format, rotated, all nodata,
/// NaN samples, a declared size far larger than the file; no panic.
#[test]
fn bad_geotiffs_are_refused_naming_the_file() {
    let good = GeoTiffSpec::new(W, H, samples(0.0), SampleKind::F32, CORNER, D);
    let bytes = write_geotiff(&good, 1, &identity);
    // Truncated: the IFD (at the end) cut off, and the samples cut in half.
    refused(&bytes[..bytes.len() / 2], &["GeoTIFF"]);
    let mut cut = good.clone();
    cut.chunks = Chunks::Strips(H);
    let full = write_geotiff(&cut, 1, &identity);
    // Move the IFD: write then zero the middle of the samples region's length by truncating
    // the data while keeping the header's IFD pointer valid is not possible with this layout,
    // so the declared-size check covers the samples (below).
    assert!(parse_geotiff(&full, "ok.tif").is_ok());

    let mut u8s = good.clone();
    u8s.kind = SampleKind::U8;
    refused(
        &write_geotiff(&u8s, 1, &identity),
        &["BitsPerSample", "8 bits"],
    );

    let mut rotated = good.clone();
    rotated.placement = Placement::Matrix([
        D, 0.5, 0.0, CORNER[0], 0.5, -D, 0.0, CORNER[1], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);
    refused(
        &write_geotiff(&rotated, 1, &identity),
        &["ModelTransformation", "rotated"],
    );

    let mut nodata = good.clone();
    nodata.samples = vec![-9999.0; (W * H) as usize];
    nodata.nodata = Some("-9999".into());
    refused(
        &write_geotiff(&nodata, 1, &identity),
        &["every sample is nodata"],
    );

    let mut nan = good.clone();
    nan.samples[5 * W as usize + 3] = f64::NAN;
    refused(
        &write_geotiff(&nan, 1, &identity),
        &["column 3, row 5", "NaN"],
    );
    // NaN declared as nodata is missing data, not an error.
    nan.nodata = Some("nan".into());
    let r = parse_geotiff(&write_geotiff(&nan, 1, &identity), "nan.tif").unwrap();
    assert!(r.samples[5 * W as usize + 3].is_nan());

    let mut geographic = good.clone();
    geographic.model_type = 2;
    refused(&write_geotiff(&geographic, 1, &identity), &["geographic"]);

    // A declared size far larger than the file: 4000 x 4000 floats in a file of a few KiB,
    // refused before the samples are allocated (uncompressed), and past the sample limit.
    let mut huge = good.clone();
    huge.width = 4000;
    huge.height = 4000;
    huge.chunks = Chunks::Strips(4000);
    let tiny = write_geotiff(
        &GeoTiffSpec {
            samples: vec![0.0; 4],
            width: 2,
            height: 2,
            ..good.clone()
        },
        1,
        &identity,
    );
    let mut lying = tiny.clone();
    // Patch ImageWidth and ImageLength (first two IFD entries, LONG inline values).
    let ifd = u32::from_le_bytes(lying[4..8].try_into().unwrap()) as usize;
    for (k, v) in [(0usize, 4000u32), (1, 4000)] {
        let e = ifd + 2 + 12 * k;
        lying[e + 8..e + 12].copy_from_slice(&v.to_le_bytes());
    }
    // Refused by the `tiff` crate's own consistency check (strip sizes) or by ours (the
    // declared size against the file), before the samples are allocated.
    refused(&lying, &[]);
    let mut absurd = tiny.clone();
    for (k, v) in [(0usize, 100_000u32), (1, 100_000)] {
        let e = ifd + 2 + 12 * k;
        absurd[e + 8..e + 12].copy_from_slice(&v.to_le_bytes());
    }
    refused(&absurd, &[]);
    let _ = huge;
}

/// The ASCII grid's bad files: truncated, a NaN sample, all nodata, a declared size larger than
/// the file.
#[test]
fn bad_ascii_grids_are_refused_naming_the_file() {
    let good = ascii_grid(false, Some("-9999"));
    let e = |t: &str| {
        parse_ascii_grid(t.as_bytes(), "bad.asc")
            .unwrap_err()
            .to_string()
    };
    let t = e(&good[..good.len() - 40]);
    assert!(t.contains("bad.asc") && t.contains("truncated"), "{t}");
    let t = e(&good.replacen(" 304 ", " nan ", 1));
    assert!(t.contains("bad.asc") && t.contains("NaN"), "{t}");
    let mut all =
        "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -1\n".to_string();
    all += "-1 -1\n-1 -1\n";
    let t = e(&all);
    assert!(t.contains("every sample is nodata"), "{t}");
    let t = e("ncols 100000\nnrows 50000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n");
    // Refused by the size guard before the sample buffer is allocated (not by running out of
    // samples after allocating it).
    assert!(
        t.contains("100000x50000") && t.contains("more than 67108864 samples"),
        "{t}"
    );
    // Within the sample limit but more than the file can hold (two bytes a sample).
    let t = e("ncols 4000
nrows 4000
xllcorner 0
yllcorner 0
cellsize 1
1 2 3
");
    assert!(
        t.contains("4000x4000") && t.contains("the file holds"),
        "{t}"
    );
}

/// A scene with a GeoTIFF DEM and a named-column CSV inventory: trees without z stand on the
/// drawn terrain, trees with z keep it (the mismatch counted and the worst one named), the
/// terrain is drawn on the DEM's own grid; a tree outside the DEM is an error naming the file,
/// the row and the value.
#[test]
fn a_dem_scene_places_trees_and_reports_mismatches() {
    let dir = temp_dir("scene");
    let spec = GeoTiffSpec::new(W, H, samples(0.0), SampleKind::F32, CORNER, D);
    common::write(&dir, "dem.tif", write_geotiff(&spec, 8, &deflate));
    // Tree 2 says z = 400 over ground near 330: a 70 m mismatch.
    common::write(
        &dir,
        "plot.csv",
        "TreeID,E,N,Elev,H_m,Art\n1,500010.5,5300080.25,,21.5,Fichte\n2,500040,5300060,400,30,Kiefer\n3,500020,5300070,,12,Fichte\n",
    );
    let toml = r#"
instances = "plot.csv"
[terrain]
kind = "dem"
file = "dem.tif"
z_tolerance = 0.5
[columns]
x = "E"
y = "N"
z = "Elev"
height = "H_m"
species = "Art"
[species_names]
Fichte = "spruce"
Kiefer = "pine"
"#;
    let path = common::write(&dir, "forest.toml", toml);
    let (scene, report) = load_scene_file_reported(&path, &LoadOptions::default()).unwrap();
    let report = report.expect("a DEM report");
    assert_eq!(
        (report.trees_given_z, report.trees_placed, report.mismatches),
        (1, 2, 1)
    );
    let (at, z, _) = report.worst.clone().unwrap();
    assert_eq!((at.as_str(), z), ("line 3", 400.0));
    assert!(
        report.to_string().contains("1 differ from the DEM"),
        "{report}"
    );
    let Terrain::Grid(grid) = &scene.terrain else {
        panic!("expected a grid terrain")
    };
    assert_eq!((grid.nx, grid.ny), (W as usize, H as usize));
    for t in [0usize, 2] {
        let p = scene.instances[t].position;
        assert_eq!(
            p[2],
            scene.terrain.height(p[0], p[1]),
            "tree {t} stands on the terrain"
        );
    }
    assert_eq!(
        scene.instances[1].position[2] as f64 + scene.origin[2],
        400.0
    );
    // Outside the DEM.
    common::write(
        &dir,
        "plot.csv",
        "TreeID,E,N,Elev,H_m,Art\n1,500010.5,5300080.25,,21.5,Fichte\n2,499000,5300060,,30,Kiefer\n",
    );
    let e = load_scene_file(&path).unwrap_err().to_string();
    for w in [
        "plot.csv",
        "line 3",
        "499000",
        "outside the elevation model",
        "dem.tif",
    ] {
        assert!(e.contains(w), "expected {w:?} in {e}");
    }
    // An unknown species and a missing column name the file, the row and the value.
    common::write(
        &dir,
        "plot.csv",
        "TreeID,E,N,Elev,H_m,Art\n1,500010.5,5300080.25,,21.5,Buche\n",
    );
    let e = load_scene_file(&path).unwrap_err().to_string();
    for w in ["plot.csv", "line 2", "Buche", "unknown species"] {
        assert!(e.contains(w), "expected {w:?} in {e}");
    }
    common::write(
        &dir,
        "plot.csv",
        "TreeID,E,N,Elev,Height,Art\n1,500010.5,5300080.25,,21.5,Fichte\n",
    );
    let e = load_scene_file(&path).unwrap_err().to_string();
    for w in ["plot.csv", "line 1", "H_m", "missing column"] {
        assert!(e.contains(w), "expected {w:?} in {e}");
    }
}

/// A GeoJSON inventory on an ASCII-grid DEM: points from the geometry, properties by the
/// column map.
#[test]
fn a_geojson_inventory_on_an_ascii_grid() {
    let dir = temp_dir("geojson");
    common::write(&dir, "dem.asc", ascii_grid(false, None));
    common::write(
        &dir,
        "trees.geojson",
        r#"{"type":"FeatureCollection","features":[
 {"type":"Feature","geometry":{"type":"Point","coordinates":[500010,5300080]},"properties":{"sp":"spruce","h":20}},
 {"type":"Feature","geometry":{"type":"Point","coordinates":[500030,5300070,333.5]},"properties":{"sp":"oak","h":15,"yaw":90}}]}"#,
    );
    let path = common::write(
        &dir,
        "forest.toml",
        "instances = \"trees.geojson\"\n[terrain]\nkind = \"dem\"\nfile = \"dem.asc\"\n[columns]\nspecies = \"sp\"\nheight = \"h\"\n",
    );
    let scene = load_scene_file(&path).unwrap();
    assert_eq!(scene.instances.len(), 2);
    assert_eq!(
        scene.instances[1].position[2] as f64 + scene.origin[2],
        333.5
    );
    assert!((scene.instances[1].yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
    let p = scene.instances[0].position;
    assert_eq!(p[2], scene.terrain.height(p[0], p[1]));
}

fn frame_bits(scene: &Scene) -> (forestlod_reference::raster::RenderTarget, Vec<[u8; 4]>) {
    use forestlod_reference::ground_truth::GroundTruthScene;
    use forestlod_shared::{Camera, Params};
    let params = Params::default();
    let prepared = forestlod_reference::pipeline::prepare(scene.clone(), &params).unwrap();
    let camera = Camera::look_at([-60.0, -90.0, 45.0], [40.0, 30.0, 0.0], 60.0, 96, 64);
    let frame = prepared.render(&camera, &params).unwrap();
    let truth = GroundTruthScene::build(scene, params.alpha_cutoff)
        .unwrap()
        .render(&camera, 1);
    (frame.drawn.target, truth.srgb.texels.clone())
}

/// A DEM terrain equal to a `hills` terrain sampled on the same grid gives the same frame and
/// the same ray-traced truth, bit for bit: the DEM's extent is the hills grid's (the footprint
/// plus the margin), its 65 x 65 samples are the hills heights at the grid's vertices.
#[test]
fn a_dem_equal_to_hills_on_the_same_grid_gives_the_same_frame() {
    use forestlod_reference::scene::builtin;
    let dir = temp_dir("hills");
    let hills = builtin::HILLS;
    // Trees over [0, 80] x [0, 60]; the grid spans [-2000, 2080] x [-2000, 2060]: 4080 / 64 and
    // 4060 / 64 are not whole, so take a footprint whose grid lines are exact: [0, 96] x [0, 64]
    // -> spans 4096 and 4064 (64 and 63.5 m cells, exact in f32 and f64).
    let trees = [
        [0.0f32, 0.0],
        [96.0, 64.0],
        [40.0, 30.0],
        [60.0, 10.0],
        [20.0, 50.0],
    ];
    let hscene = {
        let mut s = builtin::tiny();
        s.instances.truncate(trees.len());
        for (t, xy) in s.instances.iter_mut().zip(trees) {
            t.position = [xy[0], xy[1], hills.height(xy[0], xy[1])];
        }
        s.origin = [0.0; 3];
        s.bounds = forestlod_reference::scene::footprint(s.instances.iter().map(|i| i.position));
        s.terrain = hills.clone();
        s
    };
    let axes = forestlod_shared::uniform_axes(hscene.bounds);
    let (nx, ny) = (axes.xs.len(), axes.ys.len());
    let mut dem = Vec::with_capacity(nx * ny);
    for j in (0..ny).rev() {
        for i in 0..nx {
            dem.push(f64::from(hills.height(axes.xs[i], axes.ys[j])));
        }
    }
    let (dx, dy) = (
        f64::from(axes.xs[1] - axes.xs[0]),
        f64::from(axes.ys[1] - axes.ys[0]),
    );
    let mut spec = GeoTiffSpec::new(nx as u32, ny as u32, dem, SampleKind::F32, [0.0, 0.0], dx);
    spec.pixel_is_point = true;
    spec.placement = Placement::ScaleTie {
        scale: [dx, dy],
        tie: [f64::from(axes.xs[0]), f64::from(axes.ys[ny - 1])],
    };
    common::write(&dir, "dem.tif", write_geotiff(&spec, 1, &identity));
    let mut csv = String::from("x,y,z,yaw,scale,species\n");
    for t in &hscene.instances {
        let name = &hscene.meshes[t.mesh as usize].name;
        csv += &format!(
            "{},{},{},{},{},{name}\n",
            t.position[0], t.position[1], t.position[2], t.yaw, t.scale
        );
    }
    common::write(&dir, "trees.csv", csv);
    let path = common::write(
        &dir,
        "forest.toml",
        "instances = \"trees.csv\"\norigin = [0.0, 0.0, 0.0]\n[terrain]\nkind = \"dem\"\nfile = \"dem.tif\"\nvertices = 5000\n",
    );
    let dscene = load_scene_file(&path).unwrap();
    assert_eq!(
        dscene.ground_axes(),
        axes,
        "the DEM is drawn on the hills grid's lines"
    );
    assert_eq!(dscene.instances, hscene.instances);
    let (a, b) = (frame_bits(&hscene), frame_bits(&dscene));
    assert!(a.0 == b.0, "the rasterized frame differs");
    assert!(a.1 == b.1, "the ray-traced truth differs");
}

/// A 1 km x 1 km DEM at 1 m (1001 x 1001 float samples, 4 MB of samples) loads, resampled to the
/// default budget, with the raster and the drawn grid within [`DEM_MEMORY_BOUND`]: the raster's
/// samples once as `f32` plus one `f64` decode buffer (the `tiff` crate's) and the grid.
#[test]
fn a_1km_dem_at_1m_loads_within_its_memory_bound() {
    /// 1001² samples: 4 B raster + 8 B decoded `f64` + 4 B file bytes of the uncompressed file
    /// + 4 B of the `tiff` crate's own buffer = 20 B a sample, plus 1 MiB of slack.
    const DEM_MEMORY_BOUND: u64 = 1001 * 1001 * 20 + (1 << 20);
    let dir = temp_dir("km");
    let n = 1001u32;
    let s: Vec<f64> = (0..n * n).map(|k| f64::from(k % 977) * 0.1).collect();
    let spec = GeoTiffSpec::new(n, n, s, SampleKind::F32, CORNER, 1.0);
    let path = common::write(&dir, "dem.tif", write_geotiff(&spec, 1, &identity));
    let before = alloc::peak_reset();
    let r = load_dem(&path).unwrap();
    let grid =
        forestlod_reference::scene::load::dem::resample(&r, 257 * 257, [CORNER[0], CORNER[1], 0.0]);
    let peak = alloc::peak_since(before);
    println!(
        "1 km DEM at 1 m: peak heap growth {peak} B (bound {DEM_MEMORY_BOUND} B), drawn {}x{}",
        grid.nx, grid.ny
    );
    assert!(peak <= DEM_MEMORY_BOUND, "{peak} > {DEM_MEMORY_BOUND}");
    assert!(grid.nx * grid.ny <= 257 * 257);
}

fn mesh_top(scene: &Scene, mesh: u32) -> f32 {
    scene.meshes[mesh as usize].bounds_meta().bbox_max[2]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Height to scale: the drawn top (`scale · mesh top`) is the given height within 2 ULPs,
    /// for any height in (0.5, 80] m and every built-in species, through a named-column CSV.
    #[test]
    fn inventory_height_gives_the_drawn_top(heights in proptest::collection::vec(0.5f64..80.0, 1..6), sp in 0usize..5) {
        let dir = temp_dir("height");
        let names = ["spruce", "pine", "oak", "birch", "poplar"];
        let mut csv = String::from("X,Y,Z,HT,SPEC\n");
        for (k, h) in heights.iter().enumerate() {
            csv += &format!("{},{},{},{h},{}\n", 1000.0 + k as f64 * 7.0, 2000.0, 100.0, names[(sp + k) % 5]);
        }
        common::write(&dir, "inv.csv", &csv);
        let toml = "instances = \"inv.csv\"\n[columns]\nx = \"X\"\ny = \"Y\"\nz = \"Z\"\nheight = \"HT\"\nspecies = \"SPEC\"\n";
        let scene = parse_scene_file(toml.as_bytes(), &dir.join("f.toml")).unwrap();
        for (t, h) in scene.instances.iter().zip(&heights) {
            let top = t.scale * mesh_top(&scene, t.mesh);
            let ulp = f32::EPSILON * (*h as f32);
            prop_assert!((f64::from(top) - h).abs() <= 2.0 * f64::from(ulp), "top {top} vs height {h}");
        }
    }

    /// Species mapping: every row's mesh is the species its inventory name maps to, whatever the
    /// order of the `[species_names]` entries and rows.
    #[test]
    fn inventory_species_map_to_their_entries(rows in proptest::collection::vec(0usize..3, 1..8)) {
        let dir = temp_dir("species");
        let inv = ["Picea abies", "Pinus sylvestris", "Quercus robur"];
        let scene_sp = ["spruce", "pine", "oak"];
        let mut csv = String::from("x,y,z,species\n");
        for (k, &r) in rows.iter().enumerate() {
            csv += &format!("{},0,0,\"{}\"\n", k as f64 * 5.0, inv[r]);
        }
        common::write(&dir, "inv.csv", &csv);
        let toml = "instances = \"inv.csv\"\n[columns]\nx = \"x\"\ny = \"y\"\nz = \"z\"\nspecies = \"species\"\n[species_names]\n\"Quercus robur\" = \"oak\"\n\"Picea abies\" = \"spruce\"\n\"Pinus sylvestris\" = \"pine\"\n";
        let scene = parse_scene_file(toml.as_bytes(), &dir.join("f.toml")).unwrap();
        for (t, &r) in scene.instances.iter().zip(&rows) {
            prop_assert_eq!(&scene.meshes[t.mesh as usize].name, scene_sp[r]);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Hostile bytes (issue 28's rule for every reader): a valid GeoTIFF (tiled, deflate or LZW)
    /// or ASCII grid with up to 8 bytes changed and maybe cut short is read or refused, never a
    /// panic that escapes the reader.
    #[test]
    fn hostile_dem_bytes_never_panic(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
        which in 0usize..3,
    ) {
        let mut spec = GeoTiffSpec::new(W, H, samples(0.0), SampleKind::F32, CORNER, D);
        spec.chunks = Chunks::Tiles(16, 16);
        let mut bytes = match which {
            0 => write_geotiff(&spec, 8, &deflate),
            1 => write_geotiff(&spec, 5, &lzw),
            _ => ascii_grid(false, Some("-9999")).into_bytes(),
        };
        for (at, b) in &edits {
            let k = at.index(bytes.len());
            bytes[k] = *b;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len()));
        }
        let result = std::panic::catch_unwind(|| {
            if which == 2 {
                parse_ascii_grid(&bytes, "h.asc").map(|_| ())
            } else {
                parse_geotiff(&bytes, "h.tif").map(|_| ())
            }
        });
        prop_assert!(result.is_ok(), "the reader panicked");
        if let Ok(Err(e)) = result {
            let e = e.to_string();
            prop_assert!(e.contains("h.tif") || e.contains("h.asc"), "{}", e);
        }
    }
}
