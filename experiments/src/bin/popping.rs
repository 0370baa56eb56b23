//! Popping: how much a frame changes, from one frame to the next along a camera path, that the
//! motion itself does not explain (issue 12's temporal error), for each fade mode (E§4.4, G§4).
//!
//! The camera follows the sweeps' scene-defined **dolly**
//! (`forestlod_experiments::sweep::paths`: towards the forest's west edge at `0.15 T` above the
//! ground, 12 m at the default `T` = 80 m, from `T + W` to `T - 2W` before the edge) so that the
//! front trees cross the fade band `[transition - fade width, transition]` while they are large
//! on screen. For each consecutive pair
//! of frames `(t, t + 1)` it renders, on the reference backend:
//! - the frame with LOD, `v_t`, and
//! - the full-detail frame `f_t` (the Vegetation baseline: every visible tree at full mesh,
//!   same camera, same one-sample rasterization),
//!
//! and scores the pair with `excess = mean over pixels of max(0, FLIP(v_t, v_t+1) − FLIP(f_t,
//! f_t+1))`: the change between the two LOD frames beyond the change between the two
//! full-detail frames at the same pixel. Motion and aliasing change both sequences alike and
//! cancel; what remains is change the LOD made, which is what a user sees as a pop (a hard
//! switch) or as shimmer (a dither moving its pixel sets). Its 99th percentile over pixels is
//! reported beside the mean because a single popping tree is a few hundred pixels of a frame.
//! The measure itself (box filter, excess, mean and p99) is
//! [`forestlod_experiments::temporal`], the one implementation the sweeps' `temporal_mean` and
//! `temporal_p99` columns use too; the pop score on tiles is this program's own.
//!
//! Why not against the ray-traced truth, as the issue suggests as one option: the truth has no
//! aliasing, the rasterized frames do, so `FLIP(v_t, v_t+1) − FLIP(truth_t, truth_t+1)` would
//! measure the foliage's temporal aliasing (the same for every fade mode) on top of the LOD's
//! change. The full-detail frame shares the aliasing, as the LOD error of the sweeps does.
//!
//! `cargo run --release -p forestlod-experiments --bin popping -- --out out/popping` writes
//! `popping.csv` (one row per mode and frame pair), `popping.png` (excess against the camera's
//! distance, one line per mode), `worst_<mode>.png` (the worst pair of each mode: LOD frames and
//! their change map on top, full-detail frames and theirs below) and `summary.md` (per mode:
//! mean excess with a 95% interval over pairs, the worst pair, and whether the modes differ
//! beyond the noise). `experiments/popping/README.md` reads the committed result.

use std::fmt::Write as _;
use std::path::PathBuf;

use clap::Parser;
use forestlod_experiments::metrics::{error_image, flip_map};
use forestlod_experiments::plot::{Axes, Series, Style, xy_plot};
use forestlod_experiments::report::{mean_ci, within_noise};
use forestlod_experiments::sweep::paths::{path_camera, path_fraction};
use forestlod_experiments::temporal::{DEFAULT_POOL, full_change, pair_excess, pool, score};
use forestlod_reference::InputError;
use forestlod_reference::baselines::{render_vegetation, tree_spheres};
use forestlod_reference::draw::billboard_layer;
use forestlod_reference::error::COMMAND_LINE;
use forestlod_reference::output::write_png;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::builtin;
use forestlod_reference::select::{SelectUniform, tree_within_draw_distance};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{Camera, FadeMode, Params, view_interval};
use glam::{Vec3, Vec4};

/// The fade modes compared by default: none, the default mode, the thesis's cross-fade.
const DEFAULT_MODES: [FadeMode; 3] = [FadeMode::None, FadeMode::DitherSequential, FadeMode::Alpha];

/// `--modes`' default: [`DEFAULT_MODES`]' names, comma-separated.
fn default_modes() -> &'static str {
    static NAMES: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    NAMES.get_or_init(|| DEFAULT_MODES.map(FadeMode::name).join(","))
}

/// `--modes`' help, naming every [`FadeMode`].
fn modes_help() -> String {
    let names: Vec<&str> = FadeMode::ALL.iter().map(|m| m.name()).collect();
    format!(
        "Fade modes to compare, comma-separated ({})",
        names.join(", ")
    )
}

/// The reason an unknown `--modes` name is refused: `expected a, b or c`, every [`FadeMode`].
fn expected_mode() -> String {
    let mut names: Vec<&str> = FadeMode::ALL.iter().map(|m| m.name()).collect();
    let last = names.pop().unwrap_or_default();
    format!("expected {} or {last}", names.join(", "))
}

#[derive(Parser, Debug)]
struct Args {
    /// Built-in scene.
    #[arg(long, default_value = "tiny")]
    scene: String,
    // Fade modes to compare: the help names every mode (`modes_help`).
    #[arg(long, value_delimiter = ',', default_value = default_modes(), help = modes_help())]
    modes: Vec<String>,
    /// LOD1 transition distance, metres (the end of the fade band).
    #[arg(long, default_value_t = 80.0)]
    transition: f32,
    /// Fade band width, metres.
    #[arg(long, default_value_t = 30.0)]
    fade_width: f32,
    /// Billboard texture side r: lower it to make the mesh-to-billboard switch itself visible
    /// (the check that the pop score sees a pop).
    #[arg(long, default_value_t = 128)]
    texture_size: u32,
    /// Batch grid cell, metres: small enough (50 m in a 200 m scene, as the quick sweeps) that
    /// batches, not the whole forest, cross the band.
    #[arg(long, default_value_t = 50.0)]
    grid_size: f32,
    /// Frames along the path (pairs = frames - 1).
    #[arg(long, default_value_t = 61)]
    frames: u32,
    /// Viewport width.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Viewport height.
    #[arg(long, default_value_t = 360)]
    height: u32,
    /// Box-filter every frame by this factor before scoring (4: 640x360 frames scored at
    /// 160x90). One-sample alpha-tested foliage shimmers from any sub-pixel motion, in the
    /// full-detail frames as much as in ours, and that shimmer is not what a pop is; the filter
    /// averages it out as a supersampled render would, while a tree that changes LOD still
    /// changes the mean colour of the blocks it covers. 1 scores the frames as rendered. The
    /// sweeps' `temporal_mean` column uses the same measure at this default
    /// (`forestlod_experiments::temporal`).
    #[arg(long, default_value_t = DEFAULT_POOL)]
    pool: u32,
    /// Explain one pair instead of scoring the path: for pair `N` (frames `N`, `N + 1`) and each
    /// mode, which trees change LOD or baked elevation layer, and how much of the pair's excess
    /// lies on them (`explain_pair<N>_<mode>.csv`, `explain_pair<N>_<mode>.png`,
    /// `explain_pair<N>.md`), plus the layer and LOD changes of every pair of the path
    /// (`explain_layers_<mode>.csv`).
    #[arg(long)]
    explain_pair: Option<u32>,
    /// Output folder.
    #[arg(long, default_value = "out/popping")]
    out: PathBuf,
}

/// One frame pair's scores.
struct Pair {
    /// Camera distance at the pair's first frame.
    distance: f32,
    /// Mean over pixels of the LOD's excess change.
    excess_mean: f64,
    /// 99th percentile over pixels of it.
    excess_p99: f64,
    /// The pop score: the largest mean excess of any [`TILE`]² tile. A tree that switches LOD
    /// in one step changes a compact group of pixels at once; the same change spread over the
    /// frames of a fade, or scattered by a dither, raises no tile as much.
    pop: f64,
    /// The pop score over the tiles that do not touch the frame's border, where the image moves
    /// fastest under the dolly and content that differs between the LOD and full-detail frames
    /// (billboard against mesh) changes by different amounts under the same motion.
    pop_interior: f64,
    /// Mean FLIP between the two LOD frames.
    lod_change: f64,
    /// Mean FLIP between the two full-detail frames.
    full_change: f64,
    /// LOD error of the pair's first frame: mean FLIP against its full-detail frame.
    lod_error: f64,
}

fn main() {
    if let Err(e) = run(&Args::parse()) {
        eprintln!("popping: {e}");
        std::process::exit(1);
    }
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    if args.frames < 2 {
        return Err(
            InputError::new(COMMAND_LINE, "--frames", args.frames, "expected at least 2").into(),
        );
    }
    let modes: Vec<FadeMode> = args
        .modes
        .iter()
        .map(|m| {
            FadeMode::from_name(m)
                .ok_or_else(|| InputError::new(COMMAND_LINE, "--modes", m, expected_mode()))
        })
        .collect::<Result<_, _>>()?;
    let scene = builtin::by_name(&args.scene)?;
    let base = Params {
        lod1_transition: args.transition,
        fade_width: args.fade_width,
        grid_size: args.grid_size,
        texture_size: args.texture_size,
        ..Params::default()
    };
    base.validate().map_err(InputError::from)?;
    std::fs::create_dir_all(&args.out)?;
    // The scene-defined dolly: its eye height is 0.15 T, a drone's view low enough that trees
    // in the band are large on screen (at 150 m, the sweeps' distance path, a tree in the band
    // is a dozen pixels and a billboard is indistinguishable from its mesh).
    let (cameras, distances): (Vec<Camera>, Vec<f32>) = (0..args.frames)
        .map(|i| {
            let t = path_fraction("dolly", i, args.frames);
            let (c, _, d) = path_camera("dolly", &scene, &base, t, args.width, args.height)
                .expect("dolly is a path");
            (c, d)
        })
        .unzip();
    for c in &cameras {
        c.validate().map_err(InputError::from)?;
    }

    if let Some(pair) = args.explain_pair {
        return explain_pair(args, &scene, &base, &modes, &cameras, &distances, pair);
    }

    // The full-detail sequence does not depend on the fade mode: render it once.
    let prepared = prepare(scene.clone(), &base)?;
    let spheres = tree_spheres(&prepared.scene, &prepared.geometry.meshes);
    let full: Vec<Rgba8Image> = cameras
        .iter()
        .map(|c| {
            render_vegetation(&prepared, &spheres, c, &base)
                .target
                .color_image()
        })
        .collect();
    let full_pooled: Vec<Rgba8Image> = full.iter().map(|f| pool(f, args.pool)).collect();
    let full_maps: Vec<Vec<f32>> = full_pooled
        .windows(2)
        .map(|w| full_change(&w[0], &w[1]))
        .collect();
    let (pw, ph) = (full_pooled[0].width, full_pooled[0].height);

    let mut csv = String::from(
        "mode,pair,distance_m,excess_mean,excess_p99,pop,lod_change,full_change,lod_error,pop_interior\n",
    );
    let mut summary = String::new();
    let mut series = Vec::new();
    let mut stats: Vec<(FadeMode, (f64, f64))> = Vec::new();
    let _ = writeln!(
        summary,
        "| fade mode | pairs | pop score ±95% | worst pop (pair, distance) | excess mean ±95% | excess p99 (mean) | LOD error ±95% | interior pop ±95% | worst interior (pair, distance) |\n|---|--:|--:|--:|--:|--:|--:|--:|--:|"
    );
    for &mode in &modes {
        let params = Params {
            fade_mode: mode as u32,
            ..base
        };
        let prepared = prepare(scene.clone(), &params)?;
        let frames: Vec<Rgba8Image> = cameras
            .iter()
            .map(|c| {
                prepared
                    .render(c, &params)
                    .map(|f| f.drawn.target.color_image())
            })
            .collect::<Result<_, _>>()?;
        let pooled: Vec<Rgba8Image> = frames.iter().map(|f| pool(f, args.pool)).collect();
        let mut pairs = Vec::new();
        let mut excess_maps = Vec::new();
        for t in 0..frames.len() - 1 {
            let (lod_map, excess) = pair_excess(&pooled[t], &pooled[t + 1], &full_maps[t]);
            let n = excess.len().max(1) as f64;
            let mean = |m: &[f32]| m.iter().map(|&e| e as f64).sum::<f64>() / n;
            let scored = score(&excess);
            pairs.push(Pair {
                distance: distances[t],
                excess_mean: scored.mean,
                excess_p99: scored.p99,
                pop: worst_tile(&excess, pw as usize, ph as usize),
                pop_interior: interior_worst_tile(&excess, pw as usize, ph as usize),
                lod_change: mean(&lod_map),
                full_change: mean(&full_maps[t]),
                lod_error: mean(&flip_map(&full_pooled[t], &pooled[t])),
            });
            excess_maps.push((lod_map, excess));
        }
        for (i, p) in pairs.iter().enumerate() {
            let _ = writeln!(
                csv,
                "{},{i},{},{},{},{},{},{},{},{}",
                mode.name(),
                p.distance,
                p.excess_mean,
                p.excess_p99,
                p.pop,
                p.lod_change,
                p.full_change,
                p.lod_error,
                p.pop_interior
            );
        }
        let means: Vec<f64> = pairs.iter().map(|p| p.excess_mean).collect();
        let (mean, ci) = mean_ci(&means);
        let pops: Vec<f64> = pairs.iter().map(|p| p.pop).collect();
        let (pop, pop_ci) = mean_ci(&pops);
        let interior: Vec<f64> = pairs.iter().map(|p| p.pop_interior).collect();
        let (inner, inner_ci) = mean_ci(&interior);
        let worst_inner = (0..pairs.len())
            .max_by(|&a, &b| interior[a].total_cmp(&interior[b]))
            .expect("at least one pair");
        let p99 = pairs.iter().map(|p| p.excess_p99).sum::<f64>() / pairs.len() as f64;
        let lod_errors: Vec<f64> = pairs.iter().map(|p| p.lod_error).collect();
        let (lod_mean, lod_ci) = mean_ci(&lod_errors);
        let worst = (0..pairs.len())
            .max_by(|&a, &b| pairs[a].pop.total_cmp(&pairs[b].pop))
            .expect("at least one pair");
        let _ = writeln!(
            summary,
            "| {} | {} | {pop:.4} ± {pop_ci:.4} | {:.4} ({worst}, {:.1} m) | {mean:.5} ± {ci:.5} | {p99:.4} | {lod_mean:.5} ± {lod_ci:.5} | {inner:.4} ± {inner_ci:.4} | {:.4} ({worst_inner}, {:.1} m) |",
            mode.name(),
            pairs.len(),
            pairs[worst].pop,
            pairs[worst].distance,
            interior[worst_inner],
            pairs[worst_inner].distance,
        );
        stats.push((mode, (pop, pop_ci)));
        series.push(Series {
            label: mode.name().into(),
            points: pairs.iter().map(|p| (p.distance as f64, p.pop)).collect(),
        });
        let (w, h) = (args.width, args.height);
        let up = |map: &[f32]| upscale(&error_image(map, pw, ph), w, h);
        let strip = tile(
            &[
                &frames[worst],
                &frames[worst + 1],
                &up(&excess_maps[worst].1),
                &full[worst],
                &full[worst + 1],
                &up(&full_maps[worst]),
            ],
            3,
        );
        write_png(&args.out.join(format!("worst_{}.png", mode.name())), &strip)?;
    }
    let _ = writeln!(
        summary,
        "\nDifferences of the mean pop score beyond the noise (95% intervals do not overlap):\n"
    );
    for (i, (a, sa)) in stats.iter().enumerate() {
        for (b, sb) in &stats[i + 1..] {
            let verdict = if within_noise(*sa, *sb) {
                "within the noise"
            } else if sa.0 > sb.0 {
                "first pops more"
            } else {
                "second pops more"
            };
            let _ = writeln!(
                summary,
                "- {} vs {}: {verdict} ({:.2}x)",
                a.name(),
                b.name(),
                sa.0 / sb.0
            );
        }
    }
    std::fs::write(args.out.join("popping.csv"), csv)?;
    std::fs::write(args.out.join("summary.md"), &summary)?;
    xy_plot(
        &args.out.join("popping.png"),
        &Axes::linear(
            format!(
                "{}: LOD change beyond motion, band {}-{} m",
                args.scene,
                args.transition - args.fade_width,
                args.transition
            ),
            "camera distance before the forest's west edge [m]",
            "pop score per frame pair (worst tile of excess FLIP)",
        ),
        &series,
        Style::Lines,
    )?;
    print!("{summary}");
    println!(
        "wrote popping.csv, popping.png, worst_<mode>.png, summary.md to {}",
        args.out.display()
    );
    Ok(())
}

/// What the draw does with one tree in one frame: drawn as a mesh, as a billboard (both while
/// it fades) and, as a billboard, with which baked elevation layer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct TreeState {
    mesh: bool,
    billboard: bool,
    layer: u32,
    /// View depth of the tree's bounding-sphere centre.
    depth: f32,
    /// How many of the six (sphere's near end, centre, far end) × (band start, band end) pairs
    /// have the point nearer than the edge: it changes when a band edge enters or leaves the
    /// tree or crosses its centre, where its fragments' LOD weights change (a hard switch at
    /// `fade_end`; a billboard's fragments lie near the centre's depth).
    edges_passed: u8,
}

impl TreeState {
    fn lod(&self) -> &'static str {
        match (self.mesh, self.billboard) {
            (false, false) => "none",
            (true, false) => "mesh",
            (false, true) => "billboard",
            (true, true) => "fade",
        }
    }
}

/// Every tree's [`TreeState`] for one camera: selection (and refine), the draw stage's per-tree
/// draw-distance discard, and the vertex stage's layer ([`billboard_layer`]).
fn tree_states(prepared: &Prepared, camera: &Camera, params: &Params) -> Vec<TreeState> {
    let (selection, refined) = prepared.select_refined(camera, params);
    let indirection = refined
        .as_ref()
        .map_or(&prepared.batches.indirection[..], |r| &r.indirection[..]);
    let u = SelectUniform::new(camera, params);
    let eye = Vec3::from(camera.eye);
    let mut states = vec![TreeState::default(); prepared.scene.instances.len()];
    for (c, d) in selection.commands.iter().zip(&selection.data) {
        for j in 0..c.instance_count {
            let tree = indirection[(c.first_instance + j) as usize] as usize;
            if !tree_within_draw_distance(&u, prepared.tree_spheres[tree].0) {
                continue;
            }
            let s = &mut states[tree];
            let (centre, radius) = prepared.tree_spheres[tree];
            let i = view_interval(centre, 0.0, camera.eye, u.forward);
            let (near, far) = (i.d - radius, i.d + radius);
            s.depth = i.d;
            s.edges_passed = [
                near < u.fade_end,
                near < u.fade_start,
                i.d < u.fade_end,
                i.d < u.fade_start,
                far < u.fade_end,
                far < u.fade_start,
            ]
            .iter()
            .map(|&b| b as u8)
            .sum();
            if d.billboard != 0 {
                s.billboard = true;
                let base = Vec3::from(prepared.scene.instances[tree].position);
                s.layer = billboard_layer(base, eye, params);
            } else {
                s.mesh = true;
            }
        }
    }
    states
}

/// Whether the tree is drawn in either state and a fade band edge enters or leaves it, or its
/// command's LOD changes, between the two.
fn crosses_band_edge(a: &TreeState, b: &TreeState) -> bool {
    (a.lod() != "none" || b.lod() != "none")
        && (a.edges_passed != b.edges_passed || a.lod() != b.lod())
}

/// Elevation of the eye above a tree base's horizon, degrees (what the layer index rounds).
fn elevation_deg(base: Vec3, eye: Vec3) -> f32 {
    let v = eye - base;
    (v.z / v.length()).clamp(-1.0, 1.0).asin().to_degrees()
}

/// Counts of one pair's changes: trees drawn as billboards (alone or fading) in both frames,
/// those of them whose layer changes, and trees drawn in either frame that a band edge enters or
/// leaves.
fn pair_changes(a: &[TreeState], b: &[TreeState]) -> (usize, usize, usize) {
    let both = a
        .iter()
        .zip(b)
        .filter(|(a, b)| a.billboard && b.billboard)
        .count();
    let layer = a
        .iter()
        .zip(b)
        .filter(|(a, b)| a.billboard && b.billboard && a.layer != b.layer)
        .count();
    let lod = a
        .iter()
        .zip(b)
        .filter(|(a, b)| crosses_band_edge(a, b))
        .count();
    (both, layer, lod)
}

/// `--explain-pair N`: which trees change between frames `N` and `N + 1`, and how much of the
/// pair's excess lies on them. Each pixel of the pooled frame is given to the nearest tree whose
/// projected bounding sphere covers it (an approximation of visibility: spheres are larger than
/// crowns), or to no tree (ground, sky).
#[allow(clippy::too_many_arguments)]
fn explain_pair(
    args: &Args,
    scene: &forestlod_reference::scene::Scene,
    base: &Params,
    modes: &[FadeMode],
    cameras: &[Camera],
    distances: &[f32],
    pair: u32,
) -> Result<(), Box<dyn std::error::Error>> {
    let pairs = cameras.len() - 1;
    if pair as usize >= pairs {
        return Err(InputError::new(
            COMMAND_LINE,
            "--explain-pair",
            pair,
            format!("expected a pair below {pairs} (--frames - 1)"),
        )
        .into());
    }
    let p = pair as usize;
    let k = args.pool.max(1);
    let full_prepared = prepare(scene.clone(), base)?;
    let spheres = tree_spheres(&full_prepared.scene, &full_prepared.geometry.meshes);
    let full_frames: Vec<Rgba8Image> = cameras[p..p + 2]
        .iter()
        .map(|c| {
            render_vegetation(&full_prepared, &spheres, c, base)
                .target
                .color_image()
        })
        .collect();
    let full: Vec<Rgba8Image> = full_frames.iter().map(|f| pool(f, k)).collect();
    let full_map = full_change(&full[0], &full[1]);
    let mut md = format!(
        "# Pair {pair} ({:.1} m to {:.1} m before the forest's west edge)\n\n",
        distances[p],
        distances[p + 1]
    );
    for &mode in modes {
        let params = Params {
            fade_mode: mode as u32,
            ..*base
        };
        let prepared = prepare(scene.clone(), &params)?;
        // Every pair of the path: how many billboards change layer, how many trees change LOD.
        let states: Vec<Vec<TreeState>> = cameras
            .iter()
            .map(|c| tree_states(&prepared, c, &params))
            .collect();
        let mut layers_csv =
            String::from("pair,distance_m,billboards_in_both,layer_changes,band_edge_crossed\n");
        for t in 0..pairs {
            let (both, layer, lod) = pair_changes(&states[t], &states[t + 1]);
            let _ = writeln!(layers_csv, "{t},{},{both},{layer},{lod}", distances[t]);
        }
        std::fs::write(
            args.out.join(format!("explain_layers_{}.csv", mode.name())),
            layers_csv,
        )?;
        // The pair itself.
        let frames: Vec<Rgba8Image> = cameras[p..p + 2]
            .iter()
            .map(|c| {
                prepared
                    .render(c, &params)
                    .map(|f| f.drawn.target.color_image())
            })
            .collect::<Result<_, _>>()?;
        let pooled: Vec<Rgba8Image> = frames.iter().map(|f| pool(f, k)).collect();
        let (_, excess) = pair_excess(&pooled[0], &pooled[1], &full_map);
        let (pw, ph) = (pooled[0].width as usize, pooled[0].height as usize);
        let (score, wx, wy) = worst_tile_at(&excess, pw, ph);
        let interior = interior_worst_tile(&excess, pw, ph);
        let (a, b) = (&states[p], &states[p + 1]);
        let camera = &cameras[p];
        let eye = Vec3::from(camera.eye);
        let view_proj = camera.view_projection();
        let focal = 1.0 / (camera.fov_y * 0.5).tan() * camera.height as f32 * 0.5 / k as f32;
        // Owner of every pooled pixel: the nearest covering tree drawn in either frame.
        let mut owner: Vec<Option<(f32, usize)>> = vec![None; pw * ph];
        let mut discs = Vec::new();
        for tree in 0..a.len() {
            if a[tree].lod() == "none" && b[tree].lod() == "none" {
                continue;
            }
            let (c, r) = prepared.tree_spheres[tree];
            let clip = view_proj * Vec4::new(c[0], c[1], c[2], 1.0);
            if clip.w <= 0.0 {
                continue;
            }
            let x = (clip.x / clip.w + 1.0) * 0.5 * pw as f32;
            let y = (1.0 - clip.y / clip.w) * 0.5 * ph as f32;
            let rp = r * focal / clip.w;
            discs.push((tree, x, y, rp));
            let (x0, x1) = ((x - rp).floor().max(0.0), (x + rp).ceil().min(pw as f32));
            let (y0, y1) = ((y - rp).floor().max(0.0), (y + rp).ceil().min(ph as f32));
            for py in y0 as usize..y1 as usize {
                for px in x0 as usize..x1 as usize {
                    let (dx, dy) = (px as f32 + 0.5 - x, py as f32 + 0.5 - y);
                    if dx * dx + dy * dy <= rp * rp {
                        let o = &mut owner[py * pw + px];
                        if o.is_none_or(|(d, _)| clip.w < d) {
                            *o = Some((clip.w, tree));
                        }
                    }
                }
            }
        }
        let mut owned = vec![(0usize, 0.0f64, 0.0f64); a.len()];
        let in_tile = |i: usize| {
            let (x, y) = (i % pw, i / pw);
            (wx * TILE..(wx + 1) * TILE).contains(&x) && (wy * TILE..(wy + 1) * TILE).contains(&y)
        };
        // Excess by class of owner: [layer change, LOD change, unchanged tree, no tree], whole
        // frame and worst tile.
        let class = |t: usize| {
            if a[t].billboard && b[t].billboard && a[t].layer != b[t].layer {
                0
            } else if crosses_band_edge(&a[t], &b[t]) {
                1
            } else {
                2
            }
        };
        let (mut frame_by, mut tile_by) = ([0.0f64; 4], [0.0f64; 4]);
        for (i, (o, &e)) in owner.iter().zip(&excess).enumerate() {
            let c = o.map_or(3, |(_, t)| class(t));
            frame_by[c] += e as f64;
            if in_tile(i) {
                tile_by[c] += e as f64;
            }
            if let Some((_, t)) = o {
                owned[*t].0 += 1;
                owned[*t].1 += e as f64;
                if in_tile(i) {
                    owned[*t].2 += e as f64;
                }
            }
        }
        let mut csv = String::from(
            "tree,x,y,z,distance_m,elevation_a_deg,elevation_b_deg,depth_a,depth_b,radius,edges_passed_a,edges_passed_b,lod_a,lod_b,layer_a,layer_b,owned_px,excess_sum,excess_in_worst_tile\n",
        );
        for &(tree, ..) in &discs {
            let t = &prepared.scene.instances[tree];
            let base_pos = Vec3::from(t.position);
            let (n, sum, tile_sum) = owned[tree];
            let _ = writeln!(
                csv,
                "{tree},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{n},{sum},{tile_sum}",
                t.position[0],
                t.position[1],
                t.position[2],
                (base_pos - eye).truncate().length(),
                elevation_deg(base_pos, eye),
                elevation_deg(base_pos, Vec3::from(cameras[p + 1].eye)),
                a[tree].depth,
                b[tree].depth,
                prepared.tree_spheres[tree].1,
                a[tree].edges_passed,
                b[tree].edges_passed,
                a[tree].lod(),
                b[tree].lod(),
                a[tree].layer,
                b[tree].layer,
            );
        }
        std::fs::write(
            args.out
                .join(format!("explain_pair{pair}_{}.csv", mode.name())),
            csv,
        )?;
        // The image: both LOD frames and the excess map, on which red circles mark trees that
        // change layer, cyan ones trees a band edge crosses, and a white square the worst tile.
        let (w, h) = (args.width, args.height);
        let mut marked = upscale(&error_image(&excess, pw as u32, ph as u32), w, h);
        let s = k as f32;
        for &(tree, x, y, r) in &discs {
            let colour = match class(tree) {
                0 => [255, 40, 40, 255],
                1 => [40, 230, 255, 255],
                _ => continue,
            };
            circle(&mut marked, x * s, y * s, (r * s).max(2.0), colour);
        }
        let t = (TILE as u32) * k;
        rectangle(
            &mut marked,
            wx as u32 * t,
            wy as u32 * t,
            t,
            [255, 255, 255, 255],
        );
        let full_change = upscale(&error_image(&full_map, pw as u32, ph as u32), w, h);
        let strip = tile(
            &[
                &frames[0],
                &frames[1],
                &marked,
                &full_frames[0],
                &full_frames[1],
                &full_change,
            ],
            3,
        );
        write_png(
            &args
                .out
                .join(format!("explain_pair{pair}_{}.png", mode.name())),
            &strip,
        )?;
        // The worst tile's surroundings, enlarged: LOD frames on top, full-detail frames below.
        let (cx, cy) = (
            (wx as u32 * t + t / 2) as i64,
            (wy as u32 * t + t / 2) as i64,
        );
        let zoom = |img: &Rgba8Image| crop_zoom(img, cx, cy, ZOOM_SIDE, ZOOM_FACTOR);
        let zoomed = [
            zoom(&frames[0]),
            zoom(&frames[1]),
            zoom(&full_frames[0]),
            zoom(&full_frames[1]),
        ];
        write_png(
            &args
                .out
                .join(format!("explain_pair{pair}_{}_zoom.png", mode.name())),
            &tile(&zoomed.iter().collect::<Vec<_>>(), 2),
        )?;
        let (both, layer, lod) = pair_changes(a, b);
        let total: f64 = frame_by.iter().sum();
        let tile_total: f64 = tile_by.iter().sum();
        let share = |v: f64, of: f64| if of > 0.0 { 100.0 * v / of } else { 0.0 };
        let _ = writeln!(
            md,
            "## {}\n\npop score {score:.4} (worst tile at pooled ({}, {}) of {pw}x{ph}; {interior:.4} over the tiles that do not touch the frame's border); {both} trees drawn as billboards (alone or fading) in both frames, {layer} of them change layer; a fade band edge enters or leaves {lod} trees.\n\n| excess on | whole frame | worst tile |\n|---|--:|--:|\n| trees changing layer | {:.1}% | {:.1}% |\n| trees a band edge crosses | {:.1}% | {:.1}% |\n| other trees | {:.1}% | {:.1}% |\n| no tree (ground, sky) | {:.1}% | {:.1}% |\n",
            mode.name(),
            wx * TILE,
            wy * TILE,
            share(frame_by[0], total),
            share(tile_by[0], tile_total),
            share(frame_by[1], total),
            share(tile_by[1], tile_total),
            share(frame_by[2], total),
            share(tile_by[2], tile_total),
            share(frame_by[3], total),
            share(tile_by[3], tile_total),
        );
    }
    std::fs::write(args.out.join(format!("explain_pair{pair}.md")), &md)?;
    print!("{md}");
    println!(
        "wrote explain_pair{pair}.md, explain_pair{pair}_<mode>.csv/png, explain_layers_<mode>.csv to {}",
        args.out.display()
    );
    Ok(())
}

/// [`worst_tile`] over the tiles that do not touch the border of the `width x height` map.
fn interior_worst_tile(map: &[f32], width: usize, height: usize) -> f64 {
    let (tw, th) = (width / TILE, height / TILE);
    if tw < 3 || th < 3 {
        return 0.0;
    }
    let inner: Vec<f32> = (TILE..(th - 1) * TILE)
        .flat_map(|y| {
            map[y * width + TILE..y * width + (tw - 1) * TILE]
                .iter()
                .copied()
        })
        .collect();
    worst_tile(&inner, (tw - 2) * TILE, (th - 2) * TILE)
}

/// Side, frame pixels, of the region around the worst tile that `--explain-pair` enlarges.
const ZOOM_SIDE: u32 = 64;
/// Its enlargement (nearest neighbour).
const ZOOM_FACTOR: u32 = 4;

/// The `side x side` region of `img` centred on `(cx, cy)` (black outside the image), enlarged
/// `factor` times.
fn crop_zoom(img: &Rgba8Image, cx: i64, cy: i64, side: u32, factor: u32) -> Rgba8Image {
    let half = side as i64 / 2;
    Rgba8Image::from_fn(side * factor, side * factor, |x, y| {
        let (sx, sy) = (
            cx - half + (x / factor) as i64,
            cy - half + (y / factor) as i64,
        );
        if sx < 0 || sy < 0 || sx >= img.width as i64 || sy >= img.height as i64 {
            [0, 0, 0, 255]
        } else {
            img.get(sx as u32, sy as u32)
        }
    })
}

/// A circle outline of radius `r` around `(x, y)`, clipped to the image.
fn circle(img: &mut Rgba8Image, x: f32, y: f32, r: f32, colour: [u8; 4]) {
    let steps = (r * 8.0).ceil().max(16.0) as u32;
    for i in 0..steps {
        let a = i as f32 / steps as f32 * std::f32::consts::TAU;
        let (px, py) = (x + r * a.cos(), y + r * a.sin());
        if px >= 0.0 && py >= 0.0 && (px as u32) < img.width && (py as u32) < img.height {
            let w = img.width as usize;
            img.texels[py as usize * w + px as usize] = colour;
        }
    }
}

/// A square outline of side `side` from `(x, y)`, clipped to the image.
fn rectangle(img: &mut Rgba8Image, x: u32, y: u32, side: u32, colour: [u8; 4]) {
    let w = img.width as usize;
    for i in 0..side {
        for (px, py) in [
            (x + i, y),
            (x + i, y + side - 1),
            (x, y + i),
            (x + side - 1, y + i),
        ] {
            if px < img.width && py < img.height {
                img.texels[py as usize * w + px as usize] = colour;
            }
        }
    }
}

/// Side of the pop score's tiles, pixels of the pooled frame: 4 (16 frame pixels at the
/// default pool), about a tree's crown in the band at 640x360.
const TILE: usize = 4;

/// `img` enlarged to `width x height` by nearest neighbour (for the strips).
fn upscale(img: &Rgba8Image, width: u32, height: u32) -> Rgba8Image {
    Rgba8Image::from_fn(width, height, |x, y| {
        img.get(
            (x * img.width / width).min(img.width - 1),
            (y * img.height / height).min(img.height - 1),
        )
    })
}

/// The largest mean of `map` (row-major, `width x height`) over the `TILE x TILE` tiles that lie
/// wholly inside the image.
fn worst_tile(map: &[f32], width: usize, height: usize) -> f64 {
    worst_tile_at(map, width, height).0
}

/// [`worst_tile`] with the tile's position, in tiles (the first of equal ones).
fn worst_tile_at(map: &[f32], width: usize, height: usize) -> (f64, usize, usize) {
    let mut worst = (0.0f64, 0, 0);
    for ty in 0..height / TILE {
        for tx in 0..width / TILE {
            let sum: f64 = (0..TILE)
                .flat_map(|y| {
                    let row = (ty * TILE + y) * width + tx * TILE;
                    map[row..row + TILE].iter().map(|&e| e as f64)
                })
                .sum();
            let mean = sum / (TILE * TILE) as f64;
            if mean > worst.0 {
                worst = (mean, tx, ty);
            }
        }
    }
    worst
}

/// Images of one size laid out `columns` to a row.
fn tile(images: &[&Rgba8Image], columns: usize) -> Rgba8Image {
    let (w, h) = (images[0].width as usize, images[0].height as usize);
    let rows = images.len().div_ceil(columns);
    let mut texels = vec![[0u8, 0, 0, 255]; w * columns * h * rows];
    for (i, img) in images.iter().enumerate() {
        let (ox, oy) = ((i % columns) * w, (i / columns) * h);
        for y in 0..h {
            let dst = (oy + y) * w * columns + ox;
            texels[dst..dst + w].copy_from_slice(&img.texels[y * w..(y + 1) * w]);
        }
    }
    Rgba8Image {
        width: (w * columns) as u32,
        height: (h * rows) as u32,
        texels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Rgba8Image {
        Rgba8Image::from_fn(w, h, f)
    }

    const GREEN: [u8; 4] = [40, 90, 30, 255];
    const SKY: [u8; 4] = [165, 195, 225, 255];

    /// The finding of `--explain-pair 21` (`experiments/popping/README.md`, "What it means"):
    /// between frames 21 and 22 of the dolly (78.5 m to 77 m before the forest) no billboard
    /// changes baked elevation layer (the eye is 12 m up, the trees 80 to 130 m away on hills:
    /// −4.7° to +0.9° of elevation, all layer 0 of K = 10, whose first edge is at +5°), while the band's far end
    /// crosses the front row. With the eye raised 15 m in the second frame hundreds of trees
    /// change layer (277): the count can see a layer switch.
    #[test]
    fn the_worst_dolly_pair_changes_no_billboard_layer() {
        let scene = builtin::tiny();
        let params = Params {
            lod1_transition: 80.0,
            fade_width: 30.0,
            grid_size: 50.0,
            // Layers and band edges do not depend on r: the smallest bake keeps the test cheap.
            texture_size: 8,
            ..Params::default()
        };
        let prepared = prepare(scene.clone(), &params).unwrap();
        let camera = |i| {
            let t = path_fraction("dolly", i, 61);
            path_camera("dolly", &scene, &params, t, 640, 360)
                .unwrap()
                .0
        };
        let a = tree_states(&prepared, &camera(21), &params);
        let b = tree_states(&prepared, &camera(22), &params);
        let (both, layer, crossed) = pair_changes(&a, &b);
        assert_eq!(
            both,
            scene.instances.len(),
            "every tree is a billboard or fading"
        );
        assert_eq!(layer, 0, "billboards changing layer in pair 21");
        assert!(
            crossed >= 20,
            "a band edge crosses {crossed} trees in pair 21"
        );
        let mut raised = camera(22);
        raised.eye[2] += 15.0;
        let (_, layer, _) = pair_changes(&a, &tree_states(&prepared, &raised, &params));
        assert!(
            layer > 100,
            "{layer} billboards change layer under a 15 m rise"
        );
    }

    /// A tree-sized block that changes in the LOD frames only is a pop; the same change in
    /// both sequences (motion) is none. The mutation this guards against: scoring the LOD
    /// frames' change alone, or averaging it over the frame, which a single tree cannot move.
    #[test]
    fn the_pop_score_sees_one_tree_switching_and_ignores_shared_motion() {
        let (w, h) = (64, 48);
        let sky = image(w, h, |_, _| SKY);
        let tree = image(w, h, |x, y| {
            if (20..36).contains(&x) && (10..30).contains(&y) {
                GREEN
            } else {
                SKY
            }
        });
        let no_motion = flip_map(&sky, &sky);
        let (_, popped) = pair_excess(&sky, &tree, &no_motion);
        let pop = worst_tile(&popped, w as usize, h as usize);
        assert!(pop > 0.3, "a whole tree appearing scores {pop}");
        let mean = popped.iter().map(|&e| e as f64).sum::<f64>() / popped.len() as f64;
        assert!(
            pop > 3.0 * mean,
            "the tile score stands out of the frame mean: {pop} vs {mean}"
        );
        // The same change in the full-detail frames is motion: nothing in excess.
        let moved = flip_map(&sky, &tree);
        let (_, shared) = pair_excess(&sky, &tree, &moved);
        assert_eq!(worst_tile(&shared, w as usize, h as usize), 0.0);
    }
}
