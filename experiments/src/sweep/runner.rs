//! Runs a sweep: for every scene, parameter set, pose, backend and variant, renders the frame
//! ([`render_variant`] on the reference, [`render_gpu_variant`] on the wgpu twin), scores it
//! against the shared ground-truth image, and writes the CSV, images, plots and manifest.
//! [`Runner`] keeps the scene, its ground-truth BVH and images, and the GPU context across sweeps.
//! Along a camera path it keeps the previous pose's frames ([`PathFrames`]) for the temporal
//! error (`crate::temporal`).

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use forestlod_gpu::{GpuContext, GpuError};
use forestlod_harness::gpu_frame::{GpuPipeline, GpuScene, StagesFromCpu};
use forestlod_reference::InputError;
use forestlod_reference::baselines::{
    INSTANCE_INDEX_BYTES, PROXY_BYTES, Proxy, proxies, render_primitive, render_vegetation,
    tree_spheres,
};
use forestlod_reference::cameras::named_camera;
use forestlod_reference::ground_truth::{GroundTruthImage, GroundTruthScene, TruthLighting};
use forestlod_reference::impostor_cache::ImpostorCache;
use forestlod_reference::output::{lod_id_image, write_png};
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::{Scene, builtin, load};
use forestlod_reference::select::{BatchingCounts, batching_counts_banded, tree_bands};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{Camera, CommandData, DrawCommand, FramePlan, Occlusion, Params};
use indicatif::{ProgressBar, ProgressStyle};

use crate::fair::{TruthLayout, box_filter, supersampled};
use crate::legend::{with_caption, with_flip_scale, with_lod_legend};
use crate::metrics::{Accuracy, accuracy, error_image, lod_error, per_lod_error_maps, total_error};
use crate::temporal::{DEFAULT_POOL, TemporalError, full_change, pair_excess, pool, score};

use super::io::io_err;
use super::paths::path_camera;
use super::plots::write_plots;
use super::rows::{FrameImages, Manifest, Row, write_csv};
use super::shard::Shard;
use super::spec::{ParamSet, Pose, SweepSpec, distance_camera};
use super::variant::{Engine, Pipeline, ReferenceRenderer, Registered};

fn load_scene(name: &str) -> Result<Scene, InputError> {
    let path = Path::new(name);
    if name.ends_with(".toml") || path.is_file() {
        load::load_scene_file(path)
    } else {
        builtin::by_name(name)
    }
}

/// What one variant produced for one frame.
struct VariantFrame {
    color: Rgba8Image,
    aux: Vec<u32>,
    select_s: f64,
    draw_s: f64,
    gpu_select_s: Option<f64>,
    gpu_draw_s: Option<f64>,
    batches_tested: u64,
    commands: u64,
    trees_drawn: u64,
    batching: BatchingCounts,
    triangles: Option<u64>,
    fragments: Option<u64>,
    fragments_written: Option<u64>,
    /// Ours on the reference backend: [`Row::points_drawn`]; `None` elsewhere.
    points_drawn: Option<u64>,
    memory_bytes: u64,
}

impl VariantFrame {
    /// Keeps the minimum of each time over repeats (the work and images are the same).
    fn keep_fastest(mut self, other: VariantFrame) -> Self {
        self.select_s = self.select_s.min(other.select_s);
        self.draw_s = self.draw_s.min(other.draw_s);
        self.gpu_select_s = min_of(self.gpu_select_s, other.gpu_select_s);
        self.gpu_draw_s = min_of(self.gpu_draw_s, other.gpu_draw_s);
        self
    }
}

/// The smaller of two optional times (either one where the other is missing).
fn min_of(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Per-scene state kept across sweeps of one run: the scene and its ground-truth BVH, the
/// ground-truth images already rendered, and the GPU context once a sweep asks for it.
#[derive(Default)]
pub struct Runner {
    scene: Option<(String, Scene, GroundTruthScene)>,
    /// Ground-truth images by pose, size, sampling and layout, with the seconds each took.
    images: HashMap<String, (GroundTruthImage, f64)>,
    rays: u64,
    truth_seconds: f64,
    gpu: Option<&'static GpuContext>,
    /// Render every full-detail frame on its own, even where a timed Vegetation frame is the same
    /// image ([`full_frame_source`]): the slower path, kept for the test that both give the same
    /// rows and images.
    no_full_frame_reuse: bool,
}

impl Runner {
    /// A runner that renders every full-detail frame on its own ([`full_frame_source`]'s reuse
    /// off): for the test that the reuse changes no row and no image.
    pub fn without_full_frame_reuse() -> Self {
        Self {
            no_full_frame_reuse: true,
            ..Self::default()
        }
    }

    fn scene(
        &mut self,
        name: &str,
        alpha_cutoff: f32,
    ) -> Result<(&Scene, &GroundTruthScene), InputError> {
        let key = format!("{name}@{alpha_cutoff}");
        if self.scene.as_ref().is_none_or(|(k, ..)| *k != key) {
            self.scene = None; // free the previous BVH first
            let scene = load_scene(name)?;
            let gt = GroundTruthScene::build(&scene, alpha_cutoff)?;
            self.scene = Some((key, scene, gt));
        }
        let (_, s, g) = self.scene.as_ref().expect("just set");
        Ok((s, g))
    }

    /// The GPU context, created on first use (an error with the install hint when there is no
    /// adapter: the GPU backend was asked for, so it is not skipped).
    fn gpu(&mut self) -> Result<&'static GpuContext, GpuError> {
        if let Some(ctx) = self.gpu {
            return Ok(ctx);
        }
        let ctx: &'static GpuContext = Box::leak(Box::new(GpuContext::new()?));
        self.gpu = Some(ctx);
        Ok(ctx)
    }

    /// Runs one sweep into `out/<name>/`.
    pub fn run_sweep(
        &mut self,
        spec: &SweepSpec,
        quick: bool,
        shard: Option<Shard>,
        out: &Path,
    ) -> Result<Manifest, Box<dyn std::error::Error>> {
        let start = Instant::now();
        let file = format!("<sweep {}>", spec.name);
        let sets = spec.param_sets(&file)?;
        let poses = spec.poses();
        let dir = out.join(&spec.name);
        let img_dir = dir.join("img");
        std::fs::create_dir_all(&img_dir).map_err(|e| io_err(&img_dir, e))?;
        let variants = spec.variant_list(&file)?;
        let backends = spec.backend_list(&file)?;
        let use_gpu = backends.contains(&Engine::Gpu);
        let gpu_ctx = if use_gpu { Some(self.gpu()?) } else { None };
        let per_unit = spec.variants.len() * spec.backends.len();
        let units = spec.scenes.len() * sets.len() * poses.len();
        let mine = |unit: usize| shard.is_none_or(|s| s.contains(unit));
        let frames = (0..units).filter(|&u| mine(u)).count() * per_unit;
        let bar = ProgressBar::new(frames as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{msg:>16} [{bar:30}] {pos}/{len} frames [{elapsed} / ~{duration}]",
            )
            .expect("static template")
            .progress_chars("=> "),
        );
        bar.set_message(spec.name.clone());
        let alpha_cutoff = sets.first().map(|s| s.params.alpha_cutoff).unwrap_or(0.5);
        let mut rows = Vec::new();
        let mut images = Vec::new();
        let mut bvh_info = Vec::new();
        let rays_before = self.rays;
        let truth_seconds_before = self.truth_seconds;
        let mut truth_memory = 0u64;
        let mut truth_layouts: Vec<String> = Vec::new();
        // Checked when the file was loaded (`load.rs`); `model` for a spec built in code.
        let truth_light = forestlod_shared::TruthLight::from_name(&spec.truth_light)
            .unwrap_or(forestlod_shared::TruthLight::Model);
        for (scene_i, scene_name) in spec.scenes.iter().enumerate() {
            self.scene(scene_name, alpha_cutoff)?;
            let (_, scene, gt_scene) = self.scene.as_ref().expect("loaded");
            bvh_info.push((
                scene.name.clone(),
                gt_scene.triangle_count(),
                gt_scene.build_seconds(),
            ));
            truth_memory = truth_memory.max(gt_scene.memory_bytes());
            for (set_i, set) in sets.iter().enumerate() {
                // The unit of sharding is one pose of one parameter set of one scene: its
                // ground truth and full-detail frames are shared by its variants and backends.
                let unit_of = |pose_i: usize| (scene_i * sets.len() + set_i) * poses.len() + pose_i;
                if !(0..poses.len()).any(|p| mine(unit_of(p))) {
                    continue;
                }
                let prepared = prepare(scene.clone(), &set.params)?;
                let spheres = tree_spheres(&prepared.scene, &prepared.geometry.meshes);
                let baselines = variants.iter().any(|v| v.is_baseline());
                let proxy_list: Vec<Proxy> = if baselines {
                    proxies(&prepared, set.params.alpha_cutoff)
                } else {
                    Vec::new()
                };
                // The GPU side of this parameter set: buffers uploaded and textures baked once.
                let mut gpu_scene = match gpu_ctx {
                    Some(ctx) => Some(GpuScene::new(
                        ctx,
                        &prepared,
                        &set.params,
                        StagesFromCpu::NONE,
                    )?),
                    None => None,
                };
                let mut gpu_warm = false;
                let (width, height) = (set.width, set.height);
                let layout = TruthLayout::new(width, height, spec.truth_tiles);
                let layout_text = format!("{width}x{height}: {}", layout.describe(width, height));
                if !truth_layouts.contains(&layout_text) {
                    truth_layouts.push(layout_text);
                }
                // Hierarchical impostors (issue 33 item 2): the path's impostor state, one at
                // the frame's resolution and one at the total error's (a tile is screen
                // pixels), stepped once per pose in path order, the poses of other shards
                // included (so a shard's frames are the unsharded run's).
                let impostor_path = set.params.lod_levels >= 3
                    && set.params.far_level() == Ok(forestlod_shared::FarLod::Impostor);
                let mut caches = if impostor_path {
                    Some((
                        ImpostorCache::new(&prepared, &set.params)?,
                        ImpostorCache::new(&prepared, &set.params)?,
                    ))
                } else {
                    None
                };
                // The previous pose's frames, box-filtered, while they are a path's previous
                // frame (the temporal error's predecessor: [`PathFrames`]).
                let mut previous: Option<PathFrames> = None;
                for (pose_i, pose) in poses.iter().enumerate() {
                    let unit = unit_of(pose_i);
                    // This pose's impostor step (a path's frame: plan, refresh, tile renders),
                    // from an empty atlas at a path's first pose.
                    // The state the previous pose was drawn with: a shard that does not own
                    // it draws it again for the temporal error (an unsharded run owns every
                    // pose and needs no copy).
                    let caches_before = if shard.is_some() {
                        caches.clone()
                    } else {
                        None
                    };
                    let impostor_step = match caches.as_mut() {
                        Some((cache, cache_ss)) => {
                            let (camera, pose) =
                                pose_camera(pose, scene, &set.params, width, height)?;
                            if !pose.follows_previous() {
                                *cache = ImpostorCache::new(&prepared, &set.params)?;
                                *cache_ss = ImpostorCache::new(&prepared, &set.params)?;
                            }
                            let step = cache.step(&prepared, &camera, &set.params)?;
                            if spec.total_error {
                                let camera_ss = supersampled(&camera, spec.samples);
                                cache_ss.step(&prepared, &camera_ss, &set.params)?;
                            }
                            Some((step, cache.occupancy().1 as u64))
                        }
                        None => None,
                    };
                    if !mine(unit) {
                        continue;
                    }
                    let (camera, pose) = pose_camera(pose, scene, &set.params, width, height)?;
                    let pose = &pose;
                    // This pose's predecessor, when this run rendered it; and whether the next
                    // pose will want this one's frames.
                    let before = previous
                        .take()
                        .filter(|p| pose.follows_previous() && p.pose + 1 == pose_i);
                    let keep = poses.get(pose_i + 1).is_some_and(Pose::follows_previous);
                    let mut current = PathFrames {
                        pose: pose_i,
                        backends: Vec::new(),
                    };
                    // A shaded set's truth is lit the same way (issue 30): its lighting is part
                    // of the truth's identity.
                    let lighting = TruthLighting::of(&set.params, truth_light);
                    let key = format!(
                        "{}|{}|{}|{}|{}x{}|{}|{:?}|{:?}",
                        scene.name,
                        pose.camera,
                        pose.yaw_deg,
                        pose.distance_m,
                        width,
                        height,
                        spec.samples,
                        layout,
                        lighting
                    );
                    if !self.images.contains_key(&key) {
                        let t0 = Instant::now();
                        let img = layout.render_truth(gt_scene, &camera, spec.samples, lighting);
                        let seconds = t0.elapsed().as_secs_f64();
                        self.rays += img.rays;
                        self.truth_seconds += seconds;
                        self.images.insert(key.clone(), (img, seconds));
                    }
                    let (gt, truth_s) = (&self.images[&key].0, self.images[&key].1);
                    // The same frame at the truth's sampling rate (`crate::fair`).
                    let camera_ss = supersampled(&camera, spec.samples);
                    // This pose's impostor step (a path's frame: plan, refresh, tile renders).
                    let frame = Frame {
                        prepared: &prepared,
                        spheres: &spheres,
                        proxies: &proxy_list,
                        camera: &camera,
                        params: &set.params,
                        impostors: caches.as_ref().map(|c| &c.0),
                    };
                    let frame_ss = Frame {
                        camera: &camera_ss,
                        impostors: caches.as_ref().map(|c| &c.1),
                        ..frame
                    };
                    for (backend_i, &backend) in backends.iter().enumerate() {
                        // `counters`: whether the row's work counters are wanted (not for the
                        // warm-up and the untimed full-detail frame, whose images alone are used).
                        let mut render =
                            |variant: Pipeline, frame: &Frame, repeats: u32, counters: bool| {
                                if backend == Engine::Gpu {
                                    let gs = gpu_scene.as_mut().expect("created when use_gpu");
                                    if !gpu_warm {
                                        // First frame of a parameter set: pipelines, bind groups and
                                        // lavapipe's shader JIT warm up outside the timed renders.
                                        render_gpu_variant(gs, variant, frame, 1, false)?;
                                        gpu_warm = true;
                                    }
                                    render_gpu_variant(gs, variant, frame, repeats, counters)
                                } else {
                                    render_variant(variant, frame, repeats).map_err(Into::into)
                                }
                            };
                        // The LOD error's reference: this backend's full-detail frame (every
                        // visible tree at its full mesh, the Vegetation baseline), untimed, or
                        // the timed Vegetation variant's own frame where that is the same image
                        // ([`full_frame_source`]).
                        let source = if self.no_full_frame_reuse {
                            FullFrame::Untimed
                        } else {
                            full_frame_source(backend, &variants)
                        };
                        let untimed_full = match source {
                            FullFrame::Untimed => {
                                Some(render(Pipeline::Vegetation, &frame, 1, false)?.color)
                            }
                            FullFrame::Pipeline(_) => None,
                        };
                        // Every variant's timed frames first, in the sweep's order, then the
                        // untimed scoring (the same renders and measurements as scoring each
                        // variant right after its frames; only the order of untimed work moves).
                        let mut timed = Vec::with_capacity(variants.len());
                        for &variant in &variants {
                            timed.push(render(variant, &frame, spec.repeats, true)?);
                        }
                        let full = match (source, untimed_full) {
                            (FullFrame::Pipeline(i), _) => timed[i].color.clone(),
                            (FullFrame::Untimed, Some(full)) => full,
                            (FullFrame::Untimed, None) => unreachable!("rendered above"),
                        };
                        // The temporal error against the path's previous pose ([`PathFrames`]).
                        let pooled_full = pool(&full, DEFAULT_POOL);
                        let pooled: Vec<Rgba8Image> = timed
                            .iter()
                            .map(|vf| pool(&vf.color, DEFAULT_POOL))
                            .collect();
                        let rendered_before;
                        let frames_before = if !pose.follows_previous() {
                            None
                        } else if let Some(b) = &before {
                            Some(&b.backends[backend_i])
                        } else {
                            // A shard that does not own the path's previous pose renders its
                            // frames again, untimed: the same images the run that owns it
                            // scores, so merged shards equal the unsharded run.
                            let (camera_before, _) =
                                pose_camera(&poses[pose_i - 1], scene, &set.params, width, height)?;
                            let frame_before = Frame {
                                camera: &camera_before,
                                impostors: caches_before.as_ref().map(|c| &c.0),
                                ..frame
                            };
                            let full_before =
                                render(Pipeline::Vegetation, &frame_before, 1, false)?.color;
                            let mut lods = Vec::with_capacity(variants.len());
                            for &variant in &variants {
                                let vf = render(variant, &frame_before, 1, false)?;
                                lods.push(pool(&vf.color, DEFAULT_POOL));
                            }
                            rendered_before = (pool(&full_before, DEFAULT_POOL), lods);
                            Some(&rendered_before)
                        };
                        let temporal: Vec<Option<TemporalError>> = match frames_before {
                            None => vec![None; variants.len()],
                            Some((full_before, lods_before)) => {
                                let full_map = full_change(full_before, &pooled_full);
                                lods_before
                                    .iter()
                                    .zip(&pooled)
                                    .map(|(a, b)| Some(score(&pair_excess(a, b, &full_map).1)))
                                    .collect()
                            }
                        };
                        if keep {
                            current.backends.push((pooled_full, pooled));
                        }
                        for (variant_i, (&variant, vf)) in variants.iter().zip(timed).enumerate() {
                            let frame_index =
                                (unit * per_unit + backend_i * variants.len() + variant_i) as u64;
                            let truth_aux = layout.gather(&vf.aux, width);
                            let (mut acc, map) = accuracy(
                                gt,
                                &layout.gather_image(&vf.color),
                                &truth_aux,
                                layout.tile(),
                            );
                            let lod_map = lod_error(&mut acc, &full, &vf.color, &vf.aux);
                            // The total error: this frame at the truth's sampling rate, untimed.
                            let total = if spec.total_error {
                                let big = render(variant, &frame_ss, 1, false)?;
                                let (color, aux) = box_filter(&big.color, &big.aux, spec.samples);
                                let aux = layout.gather(&aux, width);
                                let color = layout.gather_image(&color);
                                let map = total_error(&mut acc, gt, &color, &aux, layout.tile());
                                Some((map, aux))
                            } else {
                                None
                            };
                            let pixels = (width as u64 * height as u64).max(1);
                            let p = &set.params;
                            rows.push(Row {
                                frame: frame_index,
                                sweep: spec.name.clone(),
                                scene: scene.name.clone(),
                                camera: pose.camera.clone(),
                                yaw_deg: pose.yaw_deg,
                                distance_m: pose.distance_m,
                                variant: variant.name().into(),
                                backend: backend.name().into(),
                                setting: set.label.clone(),
                                params: *p,
                                width,
                                height,
                                truth_s: Some(truth_s),
                                truth_fraction: Some(layout.fraction(width, height)),
                                select_s: vf.select_s,
                                draw_s: vf.draw_s,
                                frame_s: vf.select_s + vf.draw_s,
                                gpu_select_s: vf.gpu_select_s,
                                gpu_draw_s: vf.gpu_draw_s,
                                batches_tested: vf.batches_tested,
                                commands: vf.commands,
                                trees_drawn: vf.trees_drawn,
                                trees_finer: vf.batching.trees_finer,
                                trees_coarser: vf.batching.trees_coarser,
                                trees_outside_view: vf.batching.trees_outside_view,
                                trees_missing_lod: vf.batching.trees_missing_lod,
                                triangles: vf.triangles,
                                fragments: vf.fragments,
                                fragments_written: vf.fragments_written,
                                overdraw: vf.fragments_written.map(|f| f as f64 / pixels as f64),
                                points_drawn: vf.points_drawn,
                                memory_bytes: vf.memory_bytes,
                                temporal_mean: temporal[variant_i].map(|t| t.mean),
                                temporal_p99: temporal[variant_i].map(|t| t.p99),
                                impostor_s: impostor_step.map(|(st, _)| st.seconds),
                                tiles_rendered: impostor_step
                                    .map(|(st, _)| st.tiles_rendered as u64),
                                tiles_off_screen: impostor_step
                                    .map(|(st, _)| st.tiles_off_screen as u64),
                                tile_texels: impostor_step.map(|(st, _)| st.texels_rendered),
                                tile_triangles: impostor_step.map(|(st, _)| st.triangles),
                                impostors_held: impostor_step.map(|(_, n)| n),
                                accuracy: acc,
                            });
                            if pose.save_images {
                                images.push(save_frame_images(
                                    frame_index,
                                    &dir,
                                    scene,
                                    pose,
                                    (variant, backend),
                                    set,
                                    gt,
                                    (&vf.color, &vf.aux, &truth_aux),
                                    (&map, &lod_map, total.as_ref()),
                                    acc,
                                )?);
                            }
                            bar.inc(1);
                        }
                    }
                    if keep {
                        previous = Some(current);
                    }
                }
            }
        }
        bar.finish();
        let csv_name = format!("{}.csv", spec.name);
        let csv_path = dir.join(&csv_name);
        write_csv(&csv_path, &rows)?;
        // A shard's plots would show part of the sweep: `sweep merge` draws them.
        let plots = if shard.is_some() {
            Vec::new()
        } else {
            write_plots(spec, &rows, &dir)?
        };
        let manifest = Manifest {
            name: spec.name.clone(),
            title: spec.title.clone(),
            description: spec.description.clone(),
            quick,
            x_axis: spec.x_axis.clone(),
            scenes: spec.scenes.clone(),
            variants: spec.variants.clone(),
            backends: spec.backends.clone(),
            gpu_adapter: gpu_ctx.map(GpuContext::describe),
            width: sets.first().map_or(spec.width, |s| s.width),
            height: sets.first().map_or(spec.height, |s| s.height),
            ground_truth_spp: spec.samples * spec.samples,
            frames: rows.len(),
            csv: csv_name,
            plots,
            images,
            wall_seconds: start.elapsed().as_secs_f64(),
            ground_truth_bvh: bvh_info,
            ground_truth_rays: self.rays - rays_before,
            ground_truth_seconds: Some(self.truth_seconds - truth_seconds_before),
            ground_truth_memory_bytes: Some(truth_memory),
            ground_truth_layout: truth_layouts,
            total_error: spec.total_error,
            spec: Some(spec.clone()),
            shard: shard.map(|s| s.to_string()),
            build: Some(super::shard::build_id()),
            spec_hash: Some(format!(
                "{:016x}",
                super::shard::fnv1a(serde_json::to_string(spec)?.as_bytes())
            )),
        };
        let mpath = dir.join("sweep.json");
        std::fs::write(&mpath, serde_json::to_string_pretty(&manifest)?)
            .map_err(|e| io_err(&mpath, e))?;
        Ok(manifest)
    }
}

/// The camera of `pose` in `scene` for a parameter set of `width x height` frames, and the pose
/// with a path's yaw and distance filled in (a path's pose gets them from the path,
/// `super::paths`).
fn pose_camera(
    pose: &Pose,
    scene: &Scene,
    params: &Params,
    width: u32,
    height: u32,
) -> Result<(Camera, Pose), InputError> {
    let mut pose = pose.clone();
    let camera = if pose.camera == "distance" {
        distance_camera(scene, pose.distance_m, width, height)
    } else if let Some((c, yaw, d)) =
        path_camera(&pose.camera, scene, params, pose.path_t, width, height)
    {
        (pose.yaw_deg, pose.distance_m) = (yaw, d);
        c
    } else {
        named_camera(&pose.camera, scene, pose.yaw_deg, width, height)?
    };
    camera.validate().map_err(InputError::from)?;
    Ok((camera, pose))
}

/// One pose's frames, kept for the temporal error of the next pose when that is the next frame
/// of the same camera path (`crate::temporal`): per backend (in the sweep's order) the
/// full-detail frame and each variant's frame (in the sweep's order), box-filtered by
/// [`DEFAULT_POOL`]. Only the previous pose's frames are kept, so the memory is one pose's.
///
/// **Shards**: a shard that owns a path's pose but not the one before it (units are dealt
/// round-robin, so with `N > 1` that is most of them) renders the previous pose's full-detail
/// and LOD frames again, untimed, and scores against those: the reference is deterministic, so
/// every `temporal_*` cell of the merged CSV equals the unsharded run's
/// (`experiments/tests/sweep_shard.rs`). It costs those shards one extra untimed render per
/// variant and backend of such a pose; no timed figure changes.
struct PathFrames {
    /// The pose's index in the sweep's poses.
    pose: usize,
    /// Per backend: `(full-detail frame, each variant's frame)`.
    backends: Vec<(Rgba8Image, Vec<Rgba8Image>)>,
}

/// The total error's FLIP map and the filtered frame's LOD ids, on the truth's layout.
type TotalMap = (Vec<f32>, Vec<u32>);

/// One frame's inputs, shared by every variant and backend.
struct Frame<'a> {
    prepared: &'a Prepared,
    spheres: &'a [([f32; 3], f32)],
    proxies: &'a [Proxy],
    camera: &'a Camera,
    params: &'a Params,
    /// Hierarchical impostors (issue 33 item 2): the path's impostor state as stepped for this
    /// frame at this camera's resolution; `None` without them.
    impostors: Option<&'a ImpostorCache>,
}

/// Where a pose's full-detail frame (the LOD error's reference) comes from, per backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FullFrame {
    /// An untimed Vegetation render of its own.
    Untimed,
    /// The timed frame of the variant at this index, which is Vegetation.
    Pipeline(usize),
}

/// The reference is deterministic (bit-identical output for identical input), so where the sweep
/// times the Vegetation variant on the reference backend, that frame **is** the full-detail frame
/// and a second render of it would be the same image: it is reused. On the GPU backend the
/// untimed Vegetation frame is rendered as before: it is also what warms up the Vegetation
/// pipelines before the first timed frame of a parameter set, and a timed frame would be a
/// different measurement without it.
fn full_frame_source(backend: Engine, variants: &[Pipeline]) -> FullFrame {
    match variants.iter().position(|&v| v == Pipeline::Vegetation) {
        Some(i) if backend == Engine::Reference => FullFrame::Pipeline(i),
        _ => FullFrame::Untimed,
    }
}

/// Bytes ours adds to the scene data: E Eq. 4.1's terms as allocated, plus the `refine` stage's
/// `3n`-entry indirection array when it runs (`reference/src/refine.rs`).
fn ours_memory(prepared: &Prepared, params: &Params) -> u64 {
    // Whether `refine` runs is the frame's plan's to say (`FramePlan::new`), not this count's.
    let refine = if FramePlan::new(params).is_ok_and(|plan| plan.refine.is_some()) {
        3 * prepared.batches.indirection.len() as u64 * 4
    } else {
        0
    };
    prepared.memory.total + refine
}

/// A variant the reference cannot render (validation rejects it before anything runs).
fn unknown_variant(variant: Pipeline) -> InputError {
    InputError::new("<sweep>", "variant", variant.name(), Pipeline::expected())
}

/// Runs `frame` `repeats` times (at least once), keeping the fastest
/// ([`VariantFrame::keep_fastest`]).
fn fastest_of<E>(
    repeats: u32,
    mut frame: impl FnMut() -> Result<VariantFrame, E>,
) -> Result<VariantFrame, E> {
    let mut best = frame()?;
    for _ in 1..repeats.max(1) {
        best = best.keep_fastest(frame()?);
    }
    Ok(best)
}

/// Renders one variant on the reference backend, `repeats` times, keeping the minimum select
/// and draw times.
fn render_variant(variant: Pipeline, f: &Frame, repeats: u32) -> Result<VariantFrame, InputError> {
    let Frame {
        prepared,
        spheres,
        proxies: proxy_list,
        camera,
        params,
        impostors,
    } = *f;
    fastest_of(repeats, || {
        let vf = match variant.reference_renderer() {
            Some(ReferenceRenderer::Ours) => {
                let frame = match impostors {
                    Some(cache) => prepared.render_impostors(camera, params, cache)?,
                    None => prepared.render(camera, params)?,
                };
                let c = frame.selection.counters;
                let indirection = frame.indirection(prepared);
                // Under occlusion culling (issue 31) the trees of its two passes.
                let trees = match &frame.occlusion {
                    Some(occ) => occ.trees_drawn(prepared, camera, params),
                    None => forestlod_reference::baselines::trees_drawn_with_far(
                        prepared,
                        impostors.map_or(prepared.far.as_ref(), |c| Some(c.level())),
                        &frame.selection,
                        indirection,
                        camera,
                        params,
                    ),
                };
                let bands = tree_bands(&prepared.scene, &prepared.geometry.meshes, camera, params);
                // Far commands (issue 32) counted by the trees they stand for.
                let tree_cmds = forestlod_reference::hier_select::tree_view(
                    &frame.selection,
                    prepared.hierarchy.as_ref(),
                    impostors.map_or(prepared.far.as_ref(), |c| Some(c.level())),
                    params,
                );
                let batching = batching_counts_banded(
                    spheres,
                    &bands,
                    indirection,
                    &tree_cmds,
                    camera,
                    params,
                );
                let s = frame.drawn.tree_stats;
                let target = frame.drawn.target;
                VariantFrame {
                    select_s: frame.timings.select + frame.timings.refine,
                    // The occlusion stage's pyramid and tests run between the two draws.
                    draw_s: frame.timings.draw + frame.timings.occlusion,
                    gpu_select_s: None,
                    gpu_draw_s: None,
                    batches_tested: c.batches_tested as u64,
                    commands: c.commands as u64,
                    trees_drawn: trees.len() as u64,
                    batching,
                    triangles: Some(s.triangles_in),
                    fragments: Some(s.fragments_shaded),
                    fragments_written: Some(s.fragments_written),
                    points_drawn: Some(frame.drawn.points_drawn),
                    memory_bytes: ours_memory(prepared, params),
                    color: target.color_image(),
                    aux: target.aux().to_vec(),
                }
            }
            Some(renderer @ (ReferenceRenderer::Vegetation | ReferenceRenderer::Primitive)) => {
                let f = if renderer == ReferenceRenderer::Vegetation {
                    render_vegetation(prepared, spheres, camera, params)
                } else {
                    render_primitive(prepared, spheres, proxy_list, camera, params)
                };
                let s = f.tree_stats;
                let trees_drawn = match &f.occlusion {
                    Some(occ) => occ.trees_drawn(prepared, camera, params).len(),
                    None => f.visible.len(),
                } as u64;
                VariantFrame {
                    select_s: f.timings.select,
                    draw_s: f.timings.draw + f.timings.occlusion,
                    gpu_select_s: None,
                    gpu_draw_s: None,
                    batches_tested: f.trees_tested,
                    commands: f.commands,
                    trees_drawn,
                    batching: BatchingCounts::default(),
                    triangles: Some(s.triangles_in),
                    fragments: Some(s.fragments_shaded),
                    fragments_written: Some(s.fragments_written),
                    points_drawn: None,
                    memory_bytes: f.memory_bytes,
                    color: f.target.color_image(),
                    aux: f.target.aux().to_vec(),
                }
            }
            None => return Err(unknown_variant(variant)),
        };
        Ok(vf)
    })
}

/// Renders one variant on the GPU backend ([`GpuScene`]), `repeats` times, keeping the
/// minimum times and the first frame's images. Work counters the GPU does not report (trees
/// drawn by ours, the batching counts) come from the reference's selection of the same frame,
/// which the parity tests prove equal to the GPU's (`tests/tests/parity/select.rs`); triangles
/// and fragments stay empty. That selection depends only on the frame, not on the repeat, so it
/// runs once, after the timed repeats, and not at all without `counters` (the warm-up and the
/// untimed full-detail frame, whose counters no row reports: they are left zero).
fn render_gpu_variant(
    gs: &mut GpuScene,
    variant: Pipeline,
    f: &Frame,
    repeats: u32,
    counters: bool,
) -> Result<VariantFrame, Box<dyn std::error::Error>> {
    let gpu_variant = variant.gpu_variant();
    // Each frame on its own, as the reference renders it: under occlusion culling `two-phase`
    // a path's first frame (the scene keeps a history from render to render otherwise, issue 31).
    // Under hierarchical impostors (issue 33 item 2) ours draws the path's stepped state.
    let far = f.impostors.map(ImpostorCache::level);
    let frame = |gs: &mut GpuScene| match (far, gpu_variant) {
        (Some(level), GpuPipeline::Ours(_)) => {
            gs.render_impostors(f.prepared, gpu_variant, f.camera, f.params, level)
        }
        _ => gs.render(f.prepared, gpu_variant, f.camera, f.params),
    };
    gs.reset_history();
    let mut g = frame(gs)?;
    for _ in 1..repeats.max(1) {
        gs.reset_history();
        let next = frame(gs)?;
        g.select_s = g.select_s.min(next.select_s);
        g.draw_s = g.draw_s.min(next.draw_s);
        g.gpu_select_s = min_of(g.gpu_select_s, next.gpu_select_s);
        g.gpu_draw_s = min_of(g.gpu_draw_s, next.gpu_draw_s);
    }
    let (batches_tested, trees_drawn, batching, memory_bytes) = if !counters {
        (0, 0, BatchingCounts::default(), 0)
    } else {
        match gpu_variant {
            GpuPipeline::Ours(_) => {
                let trace = f.prepared.select_stages_on(far, f.camera, f.params, false);
                let (selection, refined) = (trace.selection, trace.refined);
                let indirection = refined
                    .as_ref()
                    .map_or(&f.prepared.batches.indirection[..], |r| &r.indirection[..]);
                let trees = forestlod_reference::baselines::trees_drawn_with_far(
                    f.prepared,
                    far.or(f.prepared.far.as_ref()),
                    &selection,
                    indirection,
                    f.camera,
                    f.params,
                );
                let bands = tree_bands(
                    &f.prepared.scene,
                    &f.prepared.geometry.meshes,
                    f.camera,
                    f.params,
                );
                let tree_cmds = forestlod_reference::hier_select::tree_view(
                    &selection,
                    f.prepared.hierarchy.as_ref(),
                    far.or(f.prepared.far.as_ref()),
                    f.params,
                );
                let batching = batching_counts_banded(
                    f.spheres,
                    &bands,
                    indirection,
                    &tree_cmds,
                    f.camera,
                    f.params,
                );
                // Under occlusion culling (issue 31) the trees of the final pass: the
                // reference's frame, whose decisions the GPU's equal
                // (`tests/tests/parity/occlusion.rs`); each GPU frame here starts a path.
                let trees_drawn = if f.params.occlusion != Occlusion::Off as u32 {
                    let frame = f.prepared.render(f.camera, f.params)?;
                    frame
                        .occlusion
                        .as_ref()
                        .map_or(0, |o| o.trees_drawn(f.prepared, f.camera, f.params).len())
                } else {
                    trees.len()
                };
                (
                    // Batches tested (the grid) or nodes the cut visits (a hierarchy), from
                    // the reference's selection of the same frame.
                    selection.counters.batches_tested as u64,
                    trees_drawn as u64,
                    batching,
                    ours_memory(f.prepared, f.params),
                )
            }
            GpuPipeline::Vegetation | GpuPipeline::Primitive => {
                let visible = g.trees_drawn.unwrap_or(0);
                // Under occlusion culling (issue 31) Vegetation draws its final pass's trees:
                // the reference's, as for ours.
                let drawn = if gpu_variant == GpuPipeline::Vegetation
                    && f.params.occlusion != Occlusion::Off as u32
                {
                    let v = forestlod_reference::baselines::render_vegetation(
                        f.prepared, f.spheres, f.camera, f.params,
                    );
                    v.occlusion.as_ref().map_or(visible, |o| {
                        o.trees_drawn(f.prepared, f.camera, f.params).len() as u64
                    })
                } else {
                    visible
                };
                // The reference baselines' accounting (reference/src/baselines.rs).
                let extra = if gpu_variant == GpuPipeline::Vegetation {
                    g.commands * (size_of::<DrawCommand>() + size_of::<CommandData>()) as u64
                } else {
                    f.proxies.len() as u64 * PROXY_BYTES
                };
                (
                    f.spheres.len() as u64,
                    drawn,
                    BatchingCounts::default(),
                    visible * INSTANCE_INDEX_BYTES + extra,
                )
            }
        }
    };
    Ok(VariantFrame {
        color: Rgba8Image {
            width: g.images.width,
            height: g.images.height,
            texels: g.images.color,
        },
        aux: g.images.lod_id,
        select_s: g.select_s,
        draw_s: g.draw_s,
        gpu_select_s: g.gpu_select_s,
        gpu_draw_s: g.gpu_draw_s,
        batches_tested,
        commands: g.commands,
        trees_drawn,
        batching,
        triangles: None,
        fragments: None,
        fragments_written: None,
        points_drawn: None,
        memory_bytes,
    })
}

fn slug(s: &str) -> String {
    let mut out: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    while out.contains("__") {
        out = out.replace("__", "_");
    }
    out.trim_matches('_').to_string()
}

#[allow(clippy::too_many_arguments)]
fn save_frame_images(
    frame: u64,
    dir: &Path,
    scene: &Scene,
    pose: &Pose,
    (variant, backend): (Pipeline, Engine),
    set: &ParamSet,
    gt: &GroundTruthImage,
    (color, aux, truth_aux): (&Rgba8Image, &[u32], &[u32]),
    (map, lod_map, total): (&[f32], &[f32], Option<&TotalMap>),
    acc: Accuracy,
) -> Result<FrameImages, InputError> {
    let pose_slug = if pose.camera == "distance" {
        format!("{}_{}_d{}", scene.name, pose.camera, pose.distance_m)
    } else {
        format!("{}_{}_y{}", scene.name, pose.camera, pose.yaw_deg)
    };
    let stem = slug(&format!(
        "{pose_slug}_{}_{}_{}",
        variant.name(),
        backend.name(),
        set.label
    ));
    let (w, h) = (color.width, color.height);
    let rel = |name: String| format!("img/{name}");
    // A lit truth (issue 30) is its own image: its shading, sun and ambient level name it, so
    // the unlit truth of the same pose is not shown beside a lit frame.
    let truth_slug = match forestlod_shared::Shading::from_id(set.params.shading) {
        Some(forestlod_shared::Shading::Unlit) | None => pose_slug.clone(),
        Some(_) => format!(
            "{pose_slug}_lit_a{}_e{}_amb{}",
            set.params.sun_azimuth, set.params.sun_elevation, set.params.ambient
        ),
    };
    let gt_path = rel(format!("{}_gt.png", slug(&truth_slug)));
    let gt_class = rel(format!("{}_gt_class.png", slug(&truth_slug)));
    // Every image the report shows says what it is, the error maps with their scale (issue 35,
    // `crate::legend`: a strip below the image; the measured pixels are untouched).
    if !dir.join(&gt_path).is_file() {
        write_png(
            &dir.join(&gt_path),
            &with_caption(&gt.srgb, "ground truth (ray traced)"),
        )?;
        write_png(&dir.join(&gt_class), &gt.class_image())?;
    }
    let color_path = rel(format!("{stem}_color.png"));
    let lod = rel(format!("{stem}_lod.png"));
    let flip = rel(format!("{stem}_flip.png"));
    let lod_flip = rel(format!("{stem}_lod_flip.png"));
    write_png(
        &dir.join(&lod_flip),
        &with_flip_scale(&error_image(lod_map, w, h), "LOD error (FLIP)"),
    )?;
    write_png(
        &dir.join(&color_path),
        &with_caption(
            color,
            &format!("{} ({}), {}", variant.name(), backend.name(), set.label),
        ),
    )?;
    write_png(&dir.join(&lod), &with_lod_legend(&lod_id_image(w, h, aux)))?;
    // The errors against the truth are on its layout (the mosaic of sampled tiles, or the frame).
    let (tw, th) = (gt.width, gt.height);
    write_png(
        &dir.join(&flip),
        &with_flip_scale(&error_image(map, tw, th), "FLIP vs truth"),
    )?;
    let total_flip = match total {
        Some((total_map, _)) => {
            let p = rel(format!("{stem}_total_flip.png"));
            write_png(
                &dir.join(&p),
                &with_flip_scale(&error_image(total_map, tw, th), "total error (FLIP)"),
            )?;
            p
        }
        None => String::new(),
    };
    // Ours: every error map split by the frame's LOD class (`{stem}_{kind}_{class}.png`).
    let split = |map: &[f32], aux: &[u32], (w, h), kind: &str| -> Result<Vec<_>, InputError> {
        let mut out = Vec::new();
        if variant.is_ours() {
            for m in per_lod_error_maps(map, aux, w, h) {
                if m.pixels == 0 {
                    continue;
                }
                let p = rel(format!("{stem}_{kind}_{}.png", m.label));
                write_png(
                    &dir.join(&p),
                    &with_flip_scale(&m.image, &format!("{kind}, {}", m.label)),
                )?;
                out.push((m.label.to_string(), p, m.flip_mean, m.pixels));
            }
        }
        Ok(out)
    };
    let per_lod = split(map, truth_aux, (tw, th), "flip")?;
    let per_lod_lod_error = split(lod_map, aux, (w, h), "lod_flip")?;
    let per_lod_total = match total {
        Some((total_map, total_aux)) => split(total_map, total_aux, (tw, th), "total_flip")?,
        None => Vec::new(),
    };
    Ok(FrameImages {
        frame,
        camera: pose.camera.clone(),
        yaw_deg: pose.yaw_deg,
        distance_m: pose.distance_m,
        variant: variant.name().into(),
        backend: backend.name().into(),
        setting: set.label.clone(),
        color: color_path,
        lod,
        flip,
        lod_flip,
        per_lod,
        per_lod_lod_error,
        total_flip,
        per_lod_total,
        ground_truth: gt_path,
        ground_truth_class: gt_class,
        accuracy: acc,
    })
}
