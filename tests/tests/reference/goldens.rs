//! Golden images (SPEC §8): the reference renders every scenario of
//! `forestlod_tests::scenarios` and compares colour (PNG), LOD-id (PNG) and depth (EXR) with the
//! files in `goldens/`. `BLESS=1 cargo test -p forestlod-tests --test reference goldens::` rewrites
//! them; a failure writes the actual images and a difference image to `target/test-failures/goldens/`.

use std::path::{Path, PathBuf};

use forestlod_reference::output::{
    difference_image, lod_id_image, read_depth_exr, read_png, write_depth_exr, write_png,
};
use forestlod_reference::pipeline::prepare;
use forestlod_reference::texture::Image;
use forestlod_tests::assert_no_failures;
use forestlod_tests::scenarios::golden_scenarios;

/// Largest per-channel colour difference tolerated against a golden. The reference is
/// deterministic, but its transcendental functions (`sin`/`cos` of the terrain and the yaw,
/// `asin` of the angle index, `powf` of the sRGB curve) come from the platform's libm, whose
/// last-bit results may differ between glibc versions; one unit of 8-bit colour covers that.
const GOLDEN_MAX_CHANNEL_DIFF: u8 = 1;
/// Pixels allowed to differ at all (by at most [`GOLDEN_MAX_CHANNEL_DIFF`]), as a fraction: a last-bit
/// libm difference moves at most a few edge pixels.
const GOLDEN_MAX_DIFF_FRACTION: f64 = 0.002;
/// Largest depth difference tolerated: depth is in `[0, 1]`, and a libm last-bit change moves a
/// vertex by far less than this.
const GOLDEN_MAX_DEPTH_DIFF: f32 = 1e-5;

fn goldens_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../goldens")
}

fn failures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/test-failures/goldens")
}

/// How many texels of `a` differ from `b`'s.
fn texels_differing<T: PartialEq>(a: &Image<T>, b: &Image<T>) -> usize {
    a.texels
        .iter()
        .zip(&b.texels)
        .filter(|(x, y)| x != y)
        .count()
}

#[test]
fn reference_matches_goldens() {
    let bless = std::env::var("BLESS").is_ok_and(|v| v == "1");
    let mut failures = Vec::new();
    for s in golden_scenarios() {
        let scene = s.scene();
        let camera = s.camera(&scene);
        let prepared = prepare(scene, &s.params).expect("prepare");
        let frame = prepared.render(&camera, &s.params).expect("render");
        let target = &frame.drawn.target;
        let (w, h) = (target.width(), target.height());
        let color = target.color_image();
        let lod = lod_id_image(w, h, target.aux());
        let depth = target.depth().to_vec();
        assert!(
            depth.iter().all(|d| d.is_finite()),
            "{}: NaN in depth",
            s.name
        );
        let dir = goldens_dir();
        let (color_path, lod_path, depth_path) = (
            dir.join(format!("{}.png", s.name)),
            dir.join(format!("{}.lod.png", s.name)),
            dir.join(format!("{}.depth.exr", s.name)),
        );
        if bless {
            std::fs::create_dir_all(&dir).unwrap();
            write_png(&color_path, &color).unwrap();
            write_png(&lod_path, &lod).unwrap();
            write_depth_exr(&depth_path, w, h, &depth).unwrap();
            eprintln!("blessed {}", s.name);
            continue;
        }
        let golden = read_png(&color_path)
            .unwrap_or_else(|e| panic!("{e}: run with BLESS=1 to create the goldens"));
        let golden_lod = read_png(&lod_path).unwrap_or_else(|e| panic!("{e}"));
        let (gw, gh, golden_depth) = read_depth_exr(&depth_path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            (golden.width, golden.height, gw, gh),
            (w, h, w, h),
            "{}: golden size",
            s.name
        );
        let (diff, max) = difference_image(&color, &golden);
        let differing = texels_differing(&color, &golden);
        let lod_mismatch = texels_differing(&lod, &golden_lod);
        let depth_max = depth
            .iter()
            .zip(&golden_depth)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        eprintln!(
            "{}: colour max diff {max}, {differing} pixels differ; LOD-id mismatches {lod_mismatch}; depth max diff {depth_max:e}",
            s.name
        );
        let fraction = differing as f64 / (w * h) as f64;
        let lod_fraction = lod_mismatch as f64 / (w * h) as f64;
        if max > GOLDEN_MAX_CHANNEL_DIFF
            || fraction > GOLDEN_MAX_DIFF_FRACTION
            || lod_fraction > GOLDEN_MAX_DIFF_FRACTION
            || depth_max > GOLDEN_MAX_DEPTH_DIFF
        {
            let out = failures_dir();
            std::fs::create_dir_all(&out).unwrap();
            write_png(&out.join(format!("{}.actual.png", s.name)), &color).unwrap();
            write_png(&out.join(format!("{}.diff.png", s.name)), &diff).unwrap();
            write_png(&out.join(format!("{}.lod.actual.png", s.name)), &lod).unwrap();
            failures.push(format!(
                "{}: colour max {max} over {differing} px, LOD-id {lod_mismatch} px, depth {depth_max:e} (images in {})",
                s.name,
                out.display()
            ));
        }
    }
    assert_no_failures("golden mismatches", &failures);
}

/// The goldens show what they should: `medium` holds all three LOD classes, `far` holds no tree.
#[test]
fn golden_scenarios_show_every_lod_class() {
    use forestlod_reference::draw::{LOD_ID_BILLBOARD, LOD_ID_MESH, LOD_ID_TRANSITION};
    for s in golden_scenarios() {
        let scene = s.scene();
        let camera = s.camera(&scene);
        let prepared = prepare(scene, &s.params).expect("prepare");
        let frame = prepared.render(&camera, &s.params).expect("render");
        let ids = frame.drawn.target.aux();
        let count = |id: u32| ids.iter().filter(|&&x| x == id).count();
        let (mesh, billboard, transition) = (
            count(LOD_ID_MESH),
            count(LOD_ID_BILLBOARD),
            count(LOD_ID_TRANSITION),
        );
        eprintln!(
            "{}: LOD0 {mesh} px, LOD1 {billboard} px, transition {transition} px",
            s.name
        );
        if s.camera == "far" {
            assert_eq!(
                mesh + billboard + transition,
                0,
                "{}: the far camera must see no tree",
                s.name
            );
        } else if s.camera == "medium" {
            assert!(
                mesh > 0 && billboard > 0,
                "{}: expected LOD0 and LOD1 pixels",
                s.name
            );
        }
    }
}
