//! `large_coords`: selection and images at UTM-scale coordinates in three precisions (SPEC §7).
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin large_coords -- --out out/large_coords
//! ```
//!
//! A `tiny`-like forest (the `tiny` placement, 1,468 trees on 200 m x 200 m, on flat ground) is put
//! at world coordinates of growing magnitude, from `(94, 1000)` m up to the UTM-like
//! `(5.0e5, 5.3e6)` m, and selected from a seeded sweep of cameras three ways
//! ([`forestlod_reference::precision`]):
//! - **f64**: positions, spheres and the eye in `f64`, the exact rule: the truth;
//! - **f32-world** (naive): the pipeline's `f32` code fed world coordinates, origin 0;
//! - **f32-relative** (the pipeline's default): `f64` scene origin, `f32` offsets.
//!
//! For every scale it counts batch and per-tree decisions that differ from `f64` (and of those,
//! how many drop a LOD that `f64` draws, and how many lie outside the ambiguity band where rounding
//! may legitimately go either way), and renders a few close-up frames with the reference at
//! 256 x 256 both ways and against a camera-relative ground (scene origin at the eye, so every
//! `f32` the rasterizer sees is a small offset), counting differing pixels.
//!
//! Writes `decisions.csv`, `images.csv`, `summary.json`, `disagreement.png` (rate against scale,
//! log-log) and, at the UTM scale, the three renderings of camera 0 and their difference images.
//! See `experiments/large_coords/README.md` for how to read them.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use forestlod_reference::batches::{Batches, batch_meta};
use forestlod_reference::geometry::pack_geometry;
use forestlod_reference::output::{difference_image, lod_id_image, write_png};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::precision::{
    Disagreements, Precision, PrecisionScene, default_origin, instances_at, place, sweep,
};
use forestlod_reference::raster::RenderTarget;
use forestlod_reference::scene::builtin::{forest, tiny_config};
use forestlod_reference::scene::{Scene, Terrain, tree_sphere};
use forestlod_reference::{InputError, draw};
use forestlod_shared::{Camera, Params};
use serde::Serialize;

/// Coordinate scales: the forest's centre is at `(0.0943 s, s)` metres (plus fractions), so the
/// last one is the UTM-like `(5.0e5, 5.3e6)` of SPEC §3.
const SCALES: [f64; 10] = [
    1.0e3, 3.0e3, 1.0e4, 3.0e4, 1.0e5, 3.0e5, 1.0e6, 2.0e6, 3.5e6, 5.3e6,
];
/// Batch grid of the comparison: 25 m cells give about 300 batches over the 200 m forest, so
/// batch decisions are numerous enough to count.
const GRID_SIZE: f32 = 25.0;
/// Half-side of the `tiny` placement, metres.
const HALF_SIDE: f64 = 100.0;
/// A pixel differs when any sRGB8 channel differs by more than this (±1 is 8-bit quantization,
/// SPEC §8).
const PIXEL_TOLERANCE: u8 = 1;

#[derive(Parser, Debug)]
#[command(
    about = "Selection and images at UTM-scale coordinates: f64 vs f32 world vs f32 relative"
)]
struct Args {
    /// Output folder.
    #[arg(long, default_value = "out/large_coords")]
    out: PathBuf,
    /// Cameras of the decision sweep, per scale.
    #[arg(long, default_value_t = 400)]
    cameras: usize,
    /// Seed of the camera sweep.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Side of the rendered frames, pixels.
    #[arg(long, default_value_t = 256)]
    size: u32,
}

/// The forest's centre at scale `s`, with fractional metres so that nothing lands on a round `f32`.
fn center_for(s: f64) -> [f64; 3] {
    [(0.0943 * s).round() + 0.37, s + 0.61, 212.3]
}

#[derive(Serialize)]
struct DecisionRow {
    scale: f64,
    precision: &'static str,
    cameras: usize,
    max_position_error_m: f64,
    #[serde(flatten)]
    counts: FlatCounts,
}

#[derive(Serialize)]
struct FlatCounts {
    batch_total: u64,
    batch_differ: u64,
    batch_missing: u64,
    batch_differ_outside_band: u64,
    tree_total: u64,
    tree_differ: u64,
    tree_missing: u64,
    tree_differ_outside_band: u64,
}

impl From<Disagreements> for FlatCounts {
    fn from(d: Disagreements) -> Self {
        Self {
            batch_total: d.batches.total,
            batch_differ: d.batches.differ,
            batch_missing: d.batches.missing,
            batch_differ_outside_band: d.batches.differ_outside_band,
            tree_total: d.trees.total,
            tree_differ: d.trees.differ,
            tree_missing: d.trees.missing,
            tree_differ_outside_band: d.trees.differ_outside_band,
        }
    }
}

#[derive(Serialize, Clone)]
struct ImageRow {
    scale: f64,
    camera: usize,
    pixels: u64,
    world_vs_ground_pixels: u64,
    world_vs_ground_lod_ids: u64,
    relative_vs_ground_pixels: u64,
    relative_vs_ground_lod_ids: u64,
    world_vs_relative_pixels: u64,
}

/// The close-up cameras of the image comparison: eye offset from the forest centre (metres),
/// yaw and pitch (degrees). Near trees move by whole pixels when their positions move by 0.25 m.
const RENDER_CAMERAS: [([f64; 3], f32, f32); 3] = [
    ([-140.0, 0.0, 30.0], 0.0, -10.0),
    ([0.0, -150.0, 60.0], 90.0, -20.0),
    ([-60.0, -60.0, 8.0], 45.0, -3.0),
];

fn render_camera(k: usize, size: u32) -> (Camera, [f64; 3]) {
    let (offset, yaw, pitch) = RENDER_CAMERAS[k];
    let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
    let forward = [
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    ];
    let mut camera = Camera::look_at([0.0; 3], forward, 60.0, size, size);
    camera.forward = forward;
    (camera, offset)
}

/// Parameters of the image comparison: a fade band through the forest so every LOD shows.
fn render_params() -> Params {
    Params {
        grid_size: GRID_SIZE,
        lod1_transition: 140.0,
        fade_width: 40.0,
        draw_distance: 1000.0,
        ..Params::default()
    }
}

/// `scene` drawn with the resources of `base` (same meshes, so the bake is shared) and the batch
/// membership of `membership`, with each batch's sphere recomputed from `scene`'s trees.
fn prepared_like(base: &Prepared, scene: Scene, membership: &Batches) -> Prepared {
    let geometry = pack_geometry(&scene);
    let spheres: Vec<_> = scene
        .instances
        .iter()
        .map(|t| tree_sphere(t, &geometry.meshes[t.mesh as usize]))
        .collect();
    let metas = membership
        .metas
        .iter()
        .map(|b| {
            let members = &membership.indirection[b.offset as usize..(b.offset + b.len) as usize];
            let s: Vec<_> = members.iter().map(|&t| spheres[t as usize]).collect();
            batch_meta(&s, b.mesh, b.cell, b.offset)
        })
        .collect();
    Prepared {
        tree_scales: scene.instances.iter().map(|t| t.scale).collect(),
        footprints: forestlod_reference::pipeline::tree_footprints(
            &scene,
            &geometry.meshes,
            &render_params(),
        ),
        scene,
        geometry,
        batches: Batches {
            metas,
            indirection: membership.indirection.clone(),
            grid_size: membership.grid_size,
            scales: membership.scales.clone(),
        },
        hierarchy: None,
        far: None,
        points: None,
        mesh_textures: base.mesh_textures.clone(),
        billboards: base.billboards.clone(),
        memory: base.memory.clone(),
        tree_spheres: spheres,
        timings: Default::default(),
    }
}

/// The scene with its origin moved to `origin` (f64), positions recomputed from `world`.
fn rebased(scene: &Scene, world: &[[f64; 3]], origin: [f64; 3]) -> Scene {
    let instances = instances_at(&scene.instances, world, origin);
    let Terrain::Flat { z } = scene.terrain else {
        unreachable!("precision scenes stand on flat ground")
    };
    let shift: [f32; 3] = core::array::from_fn(|k| (scene.origin[k] - origin[k]) as f32);
    let [x0, y0, x1, y1] = scene.bounds;
    Scene {
        origin,
        instances,
        terrain: Terrain::Flat { z: z + shift[2] },
        bounds: [x0 + shift[0], y0 + shift[1], x1 + shift[0], y1 + shift[1]],
        ..scene.clone()
    }
}

/// Whether a LOD id is a tree's (mesh, billboard or transition), not sky or ground.
fn is_tree(id: u32) -> bool {
    matches!(
        id,
        draw::LOD_ID_MESH | draw::LOD_ID_BILLBOARD | draw::LOD_ID_TRANSITION
    )
}

/// Pixels showing a tree in either image whose colour differs by more than [`PIXEL_TOLERANCE`] in
/// any channel, and pixels whose LOD id differs. Pixels that are ground in both are left out: the
/// ground's colour ramp follows the height relative to the scene origin
/// (`forestlod_reference::draw::terrain_triangles`), so it changes with the origin by design.
fn pixel_diff(a: &RenderTarget, b: &RenderTarget) -> (u64, u64) {
    let colour = (0..a.color().len())
        .filter(|&i| {
            (is_tree(a.aux()[i]) || is_tree(b.aux()[i]))
                && (0..4).any(|c| a.color()[i][c].abs_diff(b.color()[i][c]) > PIXEL_TOLERANCE)
        })
        .count() as u64;
    let ids = a.aux().iter().zip(b.aux()).filter(|(x, y)| x != y).count() as u64;
    (colour, ids)
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let started = Instant::now();
    let template = forest(&forestlod_reference::scene::builtin::ForestConfig {
        name: "tiny-flat".into(),
        terrain: Terrain::Flat { z: 0.0 },
        ..tiny_config()
    })?;
    let base_params = Params {
        grid_size: GRID_SIZE,
        ..Params::default()
    };
    // The bake depends only on the meshes: do it once.
    let base = prepare(template.clone(), &render_params())?;
    println!(
        "large_coords: {} trees, grid {GRID_SIZE} m, {} cameras per scale, seed {}",
        template.instances.len(),
        args.cameras,
        args.seed
    );

    let mut decisions = Vec::new();
    let mut images = Vec::new();
    let mut utm_frames = None;
    for &scale in &SCALES {
        let center = center_for(scale);
        let world = place(&template, center);
        let origin = default_origin(&world);
        let ps = PrecisionScene::new(&template, &world, origin, GRID_SIZE)?;
        let cases = sweep(
            args.cameras,
            args.seed,
            center,
            HALF_SIDE,
            &base_params,
            args.size,
            args.size,
        );
        for precision in Precision::ALL {
            let mut total = Disagreements::default();
            for case in &cases {
                total.merge(ps.compare(&case.camera, case.eye_world, &case.params, precision));
            }
            let scene = match precision {
                Precision::NaiveWorld => &ps.naive,
                Precision::Relative => &ps.relative,
            };
            let max_position_error_m = scene
                .instances
                .iter()
                .zip(&world)
                .flat_map(|(t, w)| {
                    (0..3).map(move |k| (scene.origin[k] + t.position[k] as f64 - w[k]).abs())
                })
                .fold(0.0, f64::max);
            println!(
                "  scale {scale:>9.0} m  {:<13} position error ≤ {:.2e} m | batches: {:>6} of {:>7} differ ({} drop a LOD, {} outside the band) | trees: {:>6} of {:>8} differ ({} drop, {} outside)",
                precision.name(),
                max_position_error_m,
                total.batches.differ,
                total.batches.total,
                total.batches.missing,
                total.batches.differ_outside_band,
                total.trees.differ,
                total.trees.total,
                total.trees.missing,
                total.trees.differ_outside_band,
            );
            decisions.push(DecisionRow {
                scale,
                precision: precision.name(),
                cameras: cases.len(),
                max_position_error_m,
                counts: total.into(),
            });
        }

        // Images: f32-world and f32-relative against the camera-relative ground.
        let p = render_params();
        let relative = prepared_like(&base, ps.relative.clone(), &ps.batches);
        let naive = prepared_like(&base, ps.naive.clone(), &ps.batches);
        for k in 0..RENDER_CAMERAS.len() {
            let (camera, offset) = render_camera(k, args.size);
            let eye_world: [f64; 3] = core::array::from_fn(|i| center[i] + offset[i]);
            let ground =
                prepared_like(&base, rebased(&ps.relative, &world, eye_world), &ps.batches);
            let cam_ground = Camera {
                eye: [0.0; 3],
                ..camera
            };
            let cam_rel = ps.camera_for(&camera, eye_world, Precision::Relative);
            let cam_world = ps.camera_for(&camera, eye_world, Precision::NaiveWorld);
            let draw = |prep: &Prepared, cam: &Camera| -> Result<RenderTarget, InputError> {
                Ok(prep.render(cam, &p)?.drawn.target)
            };
            let t_world = draw(&naive, &cam_world)?;
            let t_rel = draw(&relative, &cam_rel)?;
            let t_ground = draw(&ground, &cam_ground)?;
            let (wg, wg_ids) = pixel_diff(&t_world, &t_ground);
            let (rg, rg_ids) = pixel_diff(&t_rel, &t_ground);
            let (wr, _) = pixel_diff(&t_world, &t_rel);
            images.push(ImageRow {
                scale,
                camera: k,
                pixels: args.size as u64 * args.size as u64,
                world_vs_ground_pixels: wg,
                world_vs_ground_lod_ids: wg_ids,
                relative_vs_ground_pixels: rg,
                relative_vs_ground_lod_ids: rg_ids,
                world_vs_relative_pixels: wr,
            });
            if scale == SCALES[SCALES.len() - 1] && k == 0 {
                let images = |t: &RenderTarget| {
                    (
                        t.color_image(),
                        lod_id_image(t.width(), t.height(), t.aux()),
                    )
                };
                utm_frames = Some([images(&t_world), images(&t_rel), images(&t_ground)]);
            }
        }
        let last = &images[images.len() - RENDER_CAMERAS.len()..];
        println!(
            "  scale {scale:>9.0} m  images ({} cameras, {}x{}): pixels differing from the camera-relative ground: f32-world {}, f32-relative {}",
            RENDER_CAMERAS.len(),
            args.size,
            args.size,
            last.iter().map(|r| r.world_vs_ground_pixels).sum::<u64>(),
            last.iter()
                .map(|r| r.relative_vs_ground_pixels)
                .sum::<u64>(),
        );
    }

    // Everything computed: write.
    std::fs::create_dir_all(&args.out)?;
    write_csv(&args.out.join("decisions.csv"), &decisions)?;
    write_csv(&args.out.join("images.csv"), &images)?;
    std::fs::write(
        args.out.join("summary.json"),
        serde_json::to_string_pretty(&serde_json::json!({
            "trees": template.instances.len(),
            "grid_size": GRID_SIZE,
            "cameras_per_scale": args.cameras,
            "seed": args.seed,
            "ambiguity_epsilons": forestlod_reference::precision::AMBIGUITY_EPSILONS,
            "pixel_tolerance": PIXEL_TOLERANCE,
            "decisions": decisions,
            "images": images,
            "seconds": started.elapsed().as_secs_f64(),
        }))?,
    )?;
    if let Some([world_f, rel_f, ground_f]) = &utm_frames {
        write_png(&args.out.join("utm_f32_world.png"), &world_f.0)?;
        write_png(&args.out.join("utm_f32_relative.png"), &rel_f.0)?;
        write_png(&args.out.join("utm_ground.png"), &ground_f.0)?;
        write_png(&args.out.join("utm_f32_world_lod.png"), &world_f.1)?;
        write_png(&args.out.join("utm_f32_relative_lod.png"), &rel_f.1)?;
        write_png(
            &args.out.join("utm_diff_f32_world.png"),
            &difference_image(&world_f.0, &ground_f.0).0,
        )?;
        write_png(
            &args.out.join("utm_diff_f32_relative.png"),
            &difference_image(&rel_f.0, &ground_f.0).0,
        )?;
    }
    plot::disagreement(&args.out.join("disagreement.png"), &decisions, &images)?;
    println!(
        "wrote decisions.csv, images.csv, summary.json, disagreement.png and utm_*.png to {} in {:.1} s",
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Writes rows as CSV with a header from their serialized field names (numbers and plain strings
/// only, so no quoting is needed).
fn write_csv<T: Serialize>(path: &Path, rows: &[T]) -> Result<(), Box<dyn std::error::Error>> {
    let mut out = String::new();
    for (i, row) in rows.iter().enumerate() {
        let serde_json::Value::Object(map) = serde_json::to_value(row)? else {
            return Err("CSV rows must serialize to objects".into());
        };
        if i == 0 {
            out.push_str(&map.keys().cloned().collect::<Vec<_>>().join(","));
            out.push('\n');
        }
        let fields: Vec<String> = map
            .values()
            .map(|v| match v {
                serde_json::Value::String(s) => s.clone(),
                other => other.to_string(),
            })
            .collect();
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    std::fs::write(path, out)?;
    Ok(())
}

/// The log-log plot of disagreement rate against coordinate scale, drawn with tiny-skia.
mod plot {
    use std::path::Path;

    use tiny_skia::{Color, Paint, PathBuilder, Pixmap, Rect, Stroke, Transform};

    use super::{DecisionRow, ImageRow};

    const W: u32 = 900;
    const H: u32 = 560;
    const LEFT: f32 = 90.0;
    const RIGHT: f32 = 30.0;
    const TOP: f32 = 30.0;
    const BOTTOM: f32 = 70.0;
    /// One plotted line: `(scale, rate)` points, colour, dash pattern (solid when `None`).
    type Series = (Vec<(f64, f64)>, Color, Option<Vec<f32>>);

    /// Rates below this are drawn on the bottom axis (a log axis has no zero).
    const FLOOR: f64 = 1.0e-7;

    /// 3x5 bitmap glyphs (rows top to bottom, bit 2 = left column) for tick labels, axis titles
    /// and the legend: digits, `e`, `-`, `.`, `/`, space and the capitals used.
    fn glyph(c: char) -> [u8; 5] {
        match c {
            '0' => [7, 5, 5, 5, 7],
            '1' => [2, 6, 2, 2, 7],
            '2' => [7, 1, 7, 4, 7],
            '3' => [7, 1, 7, 1, 7],
            '4' => [5, 5, 7, 1, 1],
            '5' => [7, 4, 7, 1, 7],
            '6' => [7, 4, 7, 5, 7],
            '7' => [7, 1, 1, 1, 1],
            '8' => [7, 5, 7, 5, 7],
            '9' => [7, 5, 7, 1, 7],
            'e' => [0, 7, 7, 4, 7],
            '-' => [0, 0, 7, 0, 0],
            '.' => [0, 0, 0, 0, 2],
            '/' => [1, 1, 2, 4, 4],
            'A' => [2, 5, 7, 5, 5],
            'B' => [6, 5, 6, 5, 6],
            'C' => [3, 4, 4, 4, 3],
            'D' => [6, 5, 5, 5, 6],
            'E' => [7, 4, 6, 4, 7],
            'F' => [7, 4, 6, 4, 4],
            'G' => [3, 4, 5, 5, 3],
            'H' => [5, 5, 7, 5, 5],
            'I' => [7, 2, 2, 2, 7],
            'L' => [4, 4, 4, 4, 7],
            'M' => [5, 7, 7, 5, 5],
            'N' => [6, 5, 5, 5, 5],
            'O' => [2, 5, 5, 5, 2],
            'P' => [6, 5, 6, 4, 4],
            'R' => [6, 5, 6, 5, 5],
            'S' => [3, 4, 2, 1, 6],
            'T' => [7, 2, 2, 2, 2],
            'U' => [5, 5, 5, 5, 7],
            'V' => [5, 5, 5, 5, 2],
            'W' => [5, 5, 7, 7, 5],
            'X' => [5, 5, 2, 5, 5],
            'Y' => [5, 5, 2, 2, 2],
            _ => [0; 5],
        }
    }

    /// Strokes the open polyline through `points`.
    fn polyline(
        pix: &mut Pixmap,
        points: &[(f32, f32)],
        paint: &Paint,
        stroke: &Stroke,
    ) -> Result<(), &'static str> {
        let mut pb = PathBuilder::new();
        for (i, &(x, y)) in points.iter().enumerate() {
            if i == 0 {
                pb.move_to(x, y);
            } else {
                pb.line_to(x, y);
            }
        }
        pix.stroke_path(
            &pb.finish().ok_or("path")?,
            paint,
            stroke,
            Transform::identity(),
            None,
        );
        Ok(())
    }

    fn text(pix: &mut Pixmap, s: &str, x: f32, y: f32, px: f32) {
        let mut paint = Paint::default();
        paint.set_color(Color::from_rgba8(30, 30, 30, 255));
        for (i, c) in s.chars().enumerate() {
            let rows = glyph(c);
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        let rect = Rect::from_xywh(
                            x + (i as f32 * 4.0 + col as f32) * px,
                            y + r as f32 * px,
                            px,
                            px,
                        )
                        .expect("positive rect");
                        pix.fill_rect(rect, &paint, Transform::identity(), None);
                    }
                }
            }
        }
    }

    /// Series: f32-world and f32-relative per-tree and per-batch disagreement rates (solid: trees,
    /// dashed: batches), and the fraction of pixels differing from the ground (dotted).
    pub fn disagreement(
        path: &Path,
        decisions: &[DecisionRow],
        images: &[ImageRow],
    ) -> Result<(), Box<dyn std::error::Error>> {
        let mut pix = Pixmap::new(W, H).ok_or("pixmap")?;
        pix.fill(Color::WHITE);
        let scales: Vec<f64> = super::SCALES.to_vec();
        let (x_lo, x_hi) = (scales[0].log10(), scales[scales.len() - 1].log10());
        let (y_lo, y_hi) = (FLOOR.log10(), 0.0);
        let px =
            |s: f64| LEFT + ((s.log10() - x_lo) / (x_hi - x_lo)) as f32 * (W as f32 - LEFT - RIGHT);
        let py = |r: f64| {
            let l = r.max(FLOOR).log10();
            TOP + ((y_hi - l) / (y_hi - y_lo)) as f32 * (H as f32 - TOP - BOTTOM)
        };
        // Grid and ticks.
        let mut grid = Paint::default();
        grid.set_color(Color::from_rgba8(220, 220, 220, 255));
        let thin = Stroke {
            width: 1.0,
            ..Stroke::default()
        };
        for e in (y_lo as i32)..=(y_hi as i32) {
            let y = py(10f64.powi(e));
            polyline(&mut pix, &[(LEFT, y), (W as f32 - RIGHT, y)], &grid, &thin)?;
            text(&mut pix, &format!("1e{e}"), 20.0, y - 7.0, 3.0);
        }
        for e in 3..=6 {
            let x = px(10f64.powi(e));
            polyline(&mut pix, &[(x, TOP), (x, H as f32 - BOTTOM)], &grid, &thin)?;
            text(
                &mut pix,
                &format!("1e{e}"),
                x - 16.0,
                H as f32 - BOTTOM + 14.0,
                3.0,
            );
        }
        let mut axis = Paint::default();
        axis.set_color(Color::from_rgba8(60, 60, 60, 255));
        let corner = (LEFT, H as f32 - BOTTOM);
        let axes = [(LEFT, TOP), corner, (W as f32 - RIGHT, H as f32 - BOTTOM)];
        polyline(&mut pix, &axes, &axis, &thin)?;

        let series = |precision: &str, batches: bool| -> Vec<(f64, f64)> {
            decisions
                .iter()
                .filter(|d| d.precision == precision)
                .map(|d| {
                    let (n, t) = if batches {
                        (d.counts.batch_differ, d.counts.batch_total)
                    } else {
                        (d.counts.tree_differ, d.counts.tree_total)
                    };
                    (d.scale, n as f64 / t.max(1) as f64)
                })
                .collect()
        };
        let pixels = |world: bool| -> Vec<(f64, f64)> {
            scales
                .iter()
                .map(|&s| {
                    let rows: Vec<_> = images.iter().filter(|r| r.scale == s).collect();
                    let n: u64 = rows
                        .iter()
                        .map(|r| {
                            if world {
                                r.world_vs_ground_pixels
                            } else {
                                r.relative_vs_ground_pixels
                            }
                        })
                        .sum();
                    let t: u64 = rows.iter().map(|r| r.pixels).sum();
                    (s, n as f64 / t.max(1) as f64)
                })
                .collect()
        };
        let red = Color::from_rgba8(210, 50, 40, 255);
        let blue = Color::from_rgba8(40, 90, 210, 255);
        let lines: [Series; 6] = [
            (series("f32-world", false), red, None),
            (series("f32-world", true), red, Some(vec![10.0, 6.0])),
            (pixels(true), red, Some(vec![2.0, 4.0])),
            (series("f32-relative", false), blue, None),
            (series("f32-relative", true), blue, Some(vec![10.0, 6.0])),
            (pixels(false), blue, Some(vec![2.0, 4.0])),
        ];
        let labels = [
            "F32 WORLD - TREE DECISIONS",
            "F32 WORLD - BATCH DECISIONS",
            "F32 WORLD - PIXELS VS GROUND",
            "F32 RELATIVE - TREE DECISIONS",
            "F32 RELATIVE - BATCH DECISIONS",
            "F32 RELATIVE - PIXELS VS GROUND",
        ];
        let mut white = Paint::default();
        white.set_color(Color::WHITE);
        let legend =
            Rect::from_xywh(LEFT + 12.0, TOP + 8.0, 300.0, 6.0 * 18.0 + 8.0).ok_or("rect")?;
        pix.fill_rect(legend, &white, Transform::identity(), None);
        for (row, ((points, color, dash), label)) in lines.into_iter().zip(labels).enumerate() {
            let mut paint = Paint::default();
            paint.set_color(color);
            paint.anti_alias = true;
            let stroke = Stroke {
                width: 2.5,
                dash: dash.and_then(|d| tiny_skia::StrokeDash::new(d, 0.0)),
                ..Stroke::default()
            };
            let plotted: Vec<(f32, f32)> = points.iter().map(|&(s, r)| (px(s), py(r))).collect();
            polyline(&mut pix, &plotted, &paint, &stroke)?;
            for (s, r) in &points {
                let dot = PathBuilder::from_circle(px(*s), py(*r), 4.0).ok_or("circle")?;
                pix.fill_path(
                    &dot,
                    &paint,
                    tiny_skia::FillRule::Winding,
                    Transform::identity(),
                    None,
                );
            }
            let y = TOP + 20.0 + row as f32 * 18.0;
            polyline(
                &mut pix,
                &[(LEFT + 20.0, y), (LEFT + 60.0, y)],
                &paint,
                &stroke,
            )?;
            text(&mut pix, label, LEFT + 70.0, y - 5.0, 2.0);
        }
        text(
            &mut pix,
            "FOREST COORDINATE SCALE / M  -  RATES OF 0 ARE DRAWN AT 1e-7",
            LEFT + 120.0,
            H as f32 - 28.0,
            2.0,
        );
        pix.save_png(path)?;
        Ok(())
    }
}
