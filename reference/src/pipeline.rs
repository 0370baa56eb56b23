//! The whole reference pipeline for one scene and one frame (E Fig. 3.2): the slow path
//! (batches, mesh mips, billboard bake and mips) once per scene and parameters, then selection and
//! draw per frame, with the wall time of every stage and the work counters of E§5.
//!
//! `prepare` is what the thesis reruns only when geometry or instances change; `render` is the
//! per-frame path.

use std::time::Instant;

use forestlod_shared::{Camera, Params, StageId};
use serde::Serialize;

use crate::InputError;
use crate::bake::{BakedBillboards, bake, mesh_textures};
use crate::batches::{Batches, MemoryReport, build_batches, memory_report};
use crate::draw::{
    DrawResources, DrawnFrame, draw_frame, draw_frame_cutoffs, draw_trees_into, sky_and_ground,
    tree_footprint_radius,
};
use crate::frame::{SelectScene, SelectionTrace, select_stages};
use crate::geometry::{PackedGeometry, pack_geometry};
use crate::hier_select::{HierSelection, hier_select};
use crate::hierarchy::Hierarchy;
use crate::occlude::{Footprint, occlude_early, occlude_late};
use crate::pyramid::Pyramid;
use crate::raster::DrawStats;
use crate::refine::Refined;
use crate::sampler::Texture;
use crate::scene::{Scene, tree_sphere};
use crate::select::Selection;

/// Seconds spent in each slow-path stage.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PrepareTimings {
    /// Packing meshes into shared buffers.
    pub pack: f64,
    /// Grid batches (E§4.2).
    pub batches: f64,
    /// Mesh texture mips.
    pub mesh_mips: f64,
    /// Billboard bake and mips (E Alg. 3.1, 3.2).
    pub bake: f64,
    /// The far level's bake (issue 32; 0 without one).
    pub far_bake: f64,
    /// The point LOD's placement and hierarchies (issue 33; 0 without one).
    pub points: f64,
}

/// Everything the per-frame path reads, built once per scene and parameters.
pub struct Prepared {
    /// The scene.
    pub scene: Scene,
    /// Packed geometry.
    pub geometry: PackedGeometry,
    /// Batches and indirection: the grid's, or the hierarchy's leaves over its indirection
    /// ([`Hierarchy::leaf_batches`]) when `params.hierarchy` is not `grid`.
    pub batches: Batches,
    /// The tree hierarchy when `params.hierarchy` is not `grid` ([`Hierarchy::build`]); then
    /// [`Prepared::select`] evaluates its cut ([`hier_select`]) instead of deciding the batches.
    pub hierarchy: Option<Hierarchy>,
    /// The hierarchy's far level (issue 32, `forestlod_shared::far`) under `lod_levels = 3`.
    pub far: Option<forestlod_shared::FarLevel>,
    /// The point LOD (issue 33) under `lod1 = points`: every mesh's point hierarchy.
    pub points: Option<crate::points::PointLod>,
    /// Mesh textures with mips.
    pub mesh_textures: Vec<Texture>,
    /// The billboard array texture.
    pub billboards: BakedBillboards,
    /// Memory beside E Eq. 4.1.
    pub memory: MemoryReport,
    /// Every tree's bounding sphere ([`tree_sphere`]), the input of the `refine` stage.
    pub tree_spheres: Vec<([f32; 3], f32)>,
    /// Every tree's scale: `refine`'s per-tree band under a scaled LOD metric (issue 29).
    pub tree_scales: Vec<f32>,
    /// Every tree's footprint sphere (its base and [`tree_footprint_radius`]): what occlusion
    /// culling bounds a tree by (issue 31, [`crate::occlude`]).
    pub footprints: Vec<Footprint>,
    /// Slow-path timings.
    pub timings: PrepareTimings,
}

/// The trees grouped as `params` says (the frame's plan, [`forestlod_shared::FramePlan`]): the
/// grid's batches for a flat selection, else the hierarchy ([`Hierarchy::build`]) with its leaves
/// as the batches over its indirection ([`Hierarchy::leaf_batches`]). `params` must be valid.
pub fn group_trees(
    scene: &Scene,
    meshes: &[forestlod_shared::MeshMeta],
    params: &Params,
) -> Result<(Option<Hierarchy>, Batches), InputError> {
    let hierarchy = Hierarchy::build(scene, meshes, params)?;
    let batches = match &hierarchy {
        Some(h) => h.leaf_batches(params.grid_size),
        None => {
            let mut batches = build_batches(scene, meshes, params.grid_size)?;
            // Far-field subsets draw prefixes of each batch (issue 29, E§7): their order.
            if params.subset()? != forestlod_shared::SubsetMode::Off {
                crate::subset::order_batches(scene, &mut batches);
            }
            batches
        }
    };
    Ok((hierarchy, batches))
}

/// Memory beside E Eq. 4.1 of a grouped scene: the hierarchy's interior nodes, when there is one,
/// beside the leaves (which `batch_meta` already counts, 64 bytes each).
pub fn scene_memory(
    scene: &Scene,
    batches: &Batches,
    hierarchy: Option<&Hierarchy>,
    params: &Params,
) -> MemoryReport {
    let mut memory = memory_report(
        scene.instances.len(),
        batches.metas.len(),
        scene.meshes.len(),
        params,
    );
    if let Some(h) = hierarchy {
        let interior = h.node_bytes() - memory.batch_meta;
        memory.hierarchy_nodes = interior;
        memory.total += interior;
    }
    memory
}

/// Every tree's footprint sphere ([`Prepared::footprints`]).
pub fn tree_footprints(
    scene: &Scene,
    meshes: &[forestlod_shared::MeshMeta],
    params: &Params,
) -> Vec<Footprint> {
    let octahedral = forestlod_shared::octahedral::is_octahedral(params.billboard_views);
    scene
        .instances
        .iter()
        .map(|t| {
            (
                t.position,
                tree_footprint_radius(t, &meshes[t.mesh as usize], octahedral),
            )
        })
        .collect()
}

/// Runs the slow path. `params` must be valid (it is validated again here).
pub fn prepare(scene: Scene, params: &Params) -> Result<Prepared, InputError> {
    params.validate()?;
    // Refused before anything is built (issue 28): a bake no machine of ours could hold.
    crate::bake::check_bake_memory(scene.meshes.len(), params)?;
    // The billboard array's `m·K·J` layers (issue 30), refused naming `azimuth_count`.
    forestlod_shared::check_billboard_layers(scene.meshes.len(), params)?;
    let mut timings = PrepareTimings::default();
    let t = Instant::now();
    let geometry = pack_geometry(&scene);
    timings.pack = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (hierarchy, batches) = group_trees(&scene, &geometry.meshes, params)?;
    timings.batches = t.elapsed().as_secs_f64();
    let mode = params.mips()?;
    let t = Instant::now();
    let textures = mesh_textures(&scene, mode, params.alpha_cutoff)?;
    timings.mesh_mips = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let billboards = bake(&scene, &geometry.meshes, &textures, params)?;
    timings.bake = t.elapsed().as_secs_f64();
    // The far level (issue 32): the octant cells of every node, and under `far_lod = hull` each
    // node's hull coloured from them.
    let t = Instant::now();
    let far = match forestlod_shared::FramePlan::new(params)?.far {
        None => None,
        // Hierarchical impostors (issue 33 item 2) bake nothing: per node an empty far record,
        // which the frame's `ImpostorCache` replaces (`crate::impostor_cache`).
        Some(forestlod_shared::FarLod::Impostor) => {
            let h = hierarchy
                .as_ref()
                .expect("a far level groups the trees in a hierarchy (FramePlan)");
            Some(forestlod_shared::FarLevel {
                nodes: vec![forestlod_shared::FarNode::default(); h.nodes.len()],
                ..Default::default()
            })
        }
        Some(kind) => {
            let h = hierarchy
                .as_ref()
                .expect("a far level groups the trees in a hierarchy (FramePlan)");
            let mut level = crate::far_bake::far_bake(h, &scene, &geometry, &textures, params)?;
            if kind == forestlod_shared::FarLod::Hull {
                crate::far_bake::far_hulls(&mut level, h, &scene, &geometry.meshes).map_err(
                    |e| {
                        InputError::new(
                            format!("<scene {}>", scene.name),
                            "far level, field far_lod",
                            "hull",
                            e.to_string(),
                        )
                    },
                )?;
            }
            Some(level)
        }
    };
    timings.far_bake = t.elapsed().as_secs_f64();
    // The point LOD (issue 33): every mesh's points, once.
    let t = Instant::now();
    let points = crate::points::PointLod::build(&scene.meshes, params)?;
    timings.points = t.elapsed().as_secs_f64();
    let mut memory = scene_memory(&scene, &batches, hierarchy.as_ref(), params);
    if let Some(f) = &far {
        memory.far_level = f.bytes();
        memory.total += memory.far_level;
    }
    let tree_spheres = {
        use rayon::prelude::*;
        scene
            .instances
            .par_iter()
            .map(|t| tree_sphere(t, &geometry.meshes[t.mesh as usize]))
            .collect()
    };
    let tree_scales = scene.instances.iter().map(|t| t.scale).collect();
    let footprints = scene
        .instances
        .iter()
        .map(|t| {
            (
                t.position,
                tree_footprint_radius(
                    t,
                    &geometry.meshes[t.mesh as usize],
                    forestlod_shared::octahedral::is_octahedral(params.billboard_views),
                ),
            )
        })
        .collect();
    Ok(Prepared {
        tree_scales,
        footprints,
        scene,
        geometry,
        batches,
        hierarchy,
        far,
        points,
        mesh_textures: textures,
        billboards,
        memory,
        tree_spheres,
        timings,
    })
}

/// Seconds per frame stage.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FrameTimings {
    /// Selection and command generation (E§4.3).
    pub select: f64,
    /// Per-tree refinement of the commands (`refine`, [`Params::tree_cull`]); 0 when off.
    pub refine: f64,
    /// Draw execution (E§4.4), ground included (both passes under occlusion culling).
    pub draw: f64,
    /// Occlusion culling (issue 31) outside the draws: the early split, the pyramid and the late
    /// test; 0 when off.
    pub occlusion: f64,
    /// Hierarchical impostors (issue 33 item 2): the step's plan and tile renders before the
    /// frame ([`crate::impostor_cache::ImpostorCache::step`]); 0 without them.
    pub impostors: f64,
}

/// What occlusion culling did in one frame (issue 31, [`crate::occlude`]).
#[derive(Clone, Debug)]
pub struct OcclusionFrame {
    /// The stage's counters.
    pub counters: forestlod_shared::OcclusionCounters,
    /// The early pass's commands (the depth pre-pass), over [`OcclusionFrame::indirection`].
    pub early: Selection,
    /// The final pass's commands (every tree not culled), over [`OcclusionFrame::indirection`].
    pub late: Selection,
    /// The `4m` indirection both index ([`forestlod_shared::occlusion_slot`]).
    pub indirection: Vec<u32>,
    /// The early pass's tree counters.
    pub early_stats: DrawStats,
    /// The final pass's tree counters.
    pub late_stats: DrawStats,
    /// The pyramid of the early pass's depth.
    pub pyramid: Pyramid,
    /// Per tree, 1 when it passed this frame's test: the next frame's history under two-phase.
    pub visible: Vec<u32>,
}

impl OcclusionFrame {
    /// The trees the frame drew for good (within the draw distance), ascending, each once: the
    /// final pass's, and under `reorder` the early pass's too.
    pub fn trees_drawn(&self, prepared: &Prepared, camera: &Camera, params: &Params) -> Vec<u32> {
        let mut trees = crate::baselines::trees_drawn_by_selection(
            prepared,
            &self.late,
            &self.indirection,
            camera,
            params,
        );
        if !forestlod_shared::final_includes_early(params.occlusion_order) {
            trees.extend(crate::baselines::trees_drawn_by_selection(
                prepared,
                &self.early,
                &self.indirection,
                camera,
                params,
            ));
            trees.sort_unstable();
            trees.dedup();
        }
        trees
    }
}

/// One rendered frame.
pub struct Frame {
    /// What selection emitted, refined when [`Params::tree_cull`] asks for it (the commands
    /// then index [`Frame::refined`]'s indirection).
    pub selection: Selection,
    /// The `refine` stage's output, when it ran.
    pub refined: Option<Refined>,
    /// The drawn buffers and counters (both passes' under occlusion culling).
    pub drawn: DrawnFrame,
    /// What occlusion culling did, when `params.occlusion` is not `off`.
    pub occlusion: Option<OcclusionFrame>,
    /// Stage timings.
    pub timings: FrameTimings,
}

impl Frame {
    /// The indirection array the frame's commands index: the refined one when `refine` ran,
    /// else the batches'.
    pub fn indirection<'a>(&'a self, prepared: &'a Prepared) -> &'a [u32] {
        match &self.refined {
            Some(r) => &r.indirection,
            None => &prepared.batches.indirection,
        }
    }
}

impl Prepared {
    /// The resources the draw stage binds.
    pub fn resources(&self) -> DrawResources<'_> {
        DrawResources {
            scene: &self.scene,
            geometry: &self.geometry,
            indirection: &self.batches.indirection,
            mesh_textures: &self.mesh_textures,
            billboards: &self.billboards,
            far: self.far.as_ref(),
            points: self.points.as_ref(),
            lod_rule: crate::sampler::LodRule::Exact,
        }
    }

    /// What the selection stages read ([`crate::frame`]).
    pub fn select_scene(&self) -> SelectScene<'_> {
        SelectScene {
            geometry: &self.geometry,
            batches: &self.batches,
            hierarchy: self.hierarchy.as_ref(),
            far: self.far.as_ref(),
            tree_spheres: &self.tree_spheres,
            tree_scales: &self.tree_scales,
        }
    }

    /// Under hierarchical impostors (`lod_levels = 3`, `far_lod = impostor`; issue 33 item 2) the
    /// state of a frame with no path before it: a fresh cache stepped once from `camera`, what
    /// [`Prepared::render`] draws (and the GPU frame's twin uploads); `None` otherwise.
    pub fn first_impostor_frame(
        &self,
        camera: &Camera,
        params: &Params,
    ) -> Result<
        Option<(
            crate::impostor_cache::ImpostorCache,
            crate::impostor_cache::ImpostorStep,
        )>,
        InputError,
    > {
        if params.lod_levels < 3 || params.far_level()? != forestlod_shared::FarLod::Impostor {
            return Ok(None);
        }
        let mut cache = crate::impostor_cache::ImpostorCache::new(self, params)?;
        let step = cache.step(self, camera, params)?;
        Ok(Some((cache, step)))
    }

    /// [`Prepared::select_stages`] on the far level `far` in place of the prepared one (issue 33
    /// item 2: a frame's impostor state, `ImpostorCache::level`); `None` keeps the prepared one.
    pub fn select_stages_on(
        &self,
        far: Option<&forestlod_shared::FarLevel>,
        camera: &Camera,
        params: &Params,
        keep: bool,
    ) -> SelectionTrace {
        let scene = SelectScene {
            far: far.or(self.far.as_ref()),
            ..self.select_scene()
        };
        select_stages(&scene, camera, params, keep)
    }

    /// Every selection stage of the frame's plan, in order ([`crate::frame::select_stages`]);
    /// `keep` keeps each stage's output. `params` must be valid.
    pub fn select_stages(&self, camera: &Camera, params: &Params, keep: bool) -> SelectionTrace {
        select_stages(&self.select_scene(), camera, params, keep)
    }

    /// Selection for one frame: the selection stages of the frame's plan
    /// ([`crate::frame::select_stages`]), `refine` excluded.
    pub fn select(&self, camera: &Camera, params: &Params) -> Selection {
        let before_refine = Params {
            tree_cull: forestlod_shared::TreeCull::None as u32,
            ..*params
        };
        self.select_stages(camera, &before_refine, false).selection
    }

    /// The hierarchy's raw cut with its per-node codes and states (`None` without a hierarchy).
    pub fn hier_select(&self, camera: &Camera, params: &Params) -> Option<HierSelection> {
        let h = self.hierarchy.as_ref()?;
        let far = crate::hier_select::FarCut::new(
            self.far.as_ref(),
            self.geometry.far.first_index,
            camera,
            params,
        );
        Some(hier_select(
            h,
            &self.geometry.meshes,
            &self.geometry.billboard,
            far,
            camera,
            params,
        ))
    }

    /// Every selection stage of the frame, `refine` included when `params.tree_cull` asks for it
    /// (untimed; for experiments and tests that need the commands without drawing). `params`
    /// must be valid.
    pub fn select_refined(&self, camera: &Camera, params: &Params) -> (Selection, Option<Refined>) {
        let trace = self.select_stages(camera, params, false);
        (trace.selection, trace.refined)
    }

    /// The per-frame path: selection, then draw (a frame with no history: under occlusion
    /// `two-phase`, a path's first frame). The camera is validated first.
    pub fn render(&self, camera: &Camera, params: &Params) -> Result<Frame, InputError> {
        self.render_with_history(camera, params, &[])
    }

    /// The per-frame path of one frame of a camera path: selection, then draw; under occlusion
    /// culling (issue 31, `forestlod_shared::occlusion`) the early pass, the pyramid, the late
    /// test and the late pass, `history` being the previous frame's
    /// [`OcclusionFrame::visible`] (empty for none). The camera is validated first.
    pub fn render_with_history(
        &self,
        camera: &Camera,
        params: &Params,
        history: &[u32],
    ) -> Result<Frame, InputError> {
        camera.validate()?;
        params.validate()?;
        if let Some((cache, step)) = self.first_impostor_frame(camera, params)? {
            let mut frame = self.render_impostors(camera, params, &cache)?;
            frame.timings.impostors = step.seconds;
            return Ok(frame);
        }
        let trace = self.select_stages(camera, params, false);
        let (selection, refined) = (trace.selection, trace.refined);
        let indirection = refined
            .as_ref()
            .map_or(&self.batches.indirection, |r| &r.indirection);
        let t = Instant::now();
        let (drawn, occlusion, occlusion_seconds) =
            if params.occlusion == forestlod_shared::Occlusion::Off as u32 {
                let res = DrawResources {
                    indirection,
                    ..self.resources()
                };
                (draw_frame(&res, &selection, camera, params), None, 0.0)
            } else {
                let (drawn, occ, seconds) =
                    self.draw_occluded(&selection, indirection, camera, params, history);
                (drawn, Some(occ), seconds)
            };
        let draw_seconds = t.elapsed().as_secs_f64() - occlusion_seconds;
        Ok(Frame {
            selection,
            refined,
            drawn,
            occlusion,
            timings: FrameTimings {
                select: trace.seconds.selection(),
                refine: trace.seconds.get(StageId::Refine),
                draw: draw_seconds,
                occlusion: occlusion_seconds,
                impostors: 0.0,
            },
        })
    }

    /// The frame of a camera path under hierarchical impostors (issue 33 item 2): the cut and the
    /// draw read `cache`'s far level (its impostored nodes, quads and atlas), as stepped for this
    /// frame ([`crate::impostor_cache::ImpostorCache::step`], whose time the caller adds). `params`
    /// must have `lod_levels = 3` and `far_lod = impostor` (the cache's).
    pub fn render_impostors(
        &self,
        camera: &Camera,
        params: &Params,
        cache: &crate::impostor_cache::ImpostorCache,
    ) -> Result<Frame, InputError> {
        camera.validate()?;
        params.validate()?;
        let trace = self.select_stages_on(Some(cache.level()), camera, params, false);
        let res = DrawResources {
            far: Some(cache.level()),
            ..self.resources()
        };
        let t = Instant::now();
        let drawn = draw_frame(&res, &trace.selection, camera, params);
        let draw = t.elapsed().as_secs_f64();
        Ok(Frame {
            selection: trace.selection,
            refined: trace.refined,
            drawn,
            occlusion: None,
            timings: FrameTimings {
                select: trace.seconds.selection(),
                refine: 0.0,
                draw,
                occlusion: 0.0,
                impostors: 0.0,
            },
        })
    }

    /// The draw of a frame with occlusion culling (module docs of `forestlod_shared::occlusion`)
    /// of `selection` over `indirection` (ours, or a baseline's commands over its own): the drawn
    /// frame, what the stage did, and the seconds of its non-draw steps. `params` must be valid
    /// with `occlusion` not `off`; `history` is the previous frame's
    /// [`OcclusionFrame::visible`] (empty for none).
    pub fn draw_occluded(
        &self,
        selection: &Selection,
        indirection: &[u32],
        camera: &Camera,
        params: &Params,
        history: &[u32],
    ) -> (DrawnFrame, OcclusionFrame, f64) {
        let fp = &self.footprints;
        let t = Instant::now();
        let (early, mut occ_indirection) =
            occlude_early(selection, indirection, fp, camera, params, history);
        let mut seconds = t.elapsed().as_secs_f64();
        // Under `exact` the early pass is a depth pre-pass (its colour is not kept) and the final
        // pass starts again from the sky and ground; under `reorder` the late trees are drawn
        // onto the early pass.
        let exact = forestlod_shared::final_includes_early(params.occlusion_order);
        let (ground, terrain_stats) = sky_and_ground(&self.scene, camera);
        let mut early_target = if exact { ground.clone() } else { ground };
        let (early_stats, early_discarded, early_points) = {
            let res = DrawResources {
                indirection: &occ_indirection,
                ..self.resources()
            };
            draw_trees_into(&res, &early, camera, params, &mut early_target)
        };
        let t = Instant::now();
        let pyramid = Pyramid::build(early_target.depth(), camera.width, camera.height);
        let late = occlude_late(
            selection,
            indirection,
            fp,
            camera,
            params,
            history,
            &pyramid,
            &mut occ_indirection,
        );
        seconds += t.elapsed().as_secs_f64();
        let mut target = if exact {
            let (ground, _) = sky_and_ground(&self.scene, camera);
            ground
        } else {
            early_target
        };
        let (late_stats, late_discarded, late_points) = {
            let res = DrawResources {
                indirection: &occ_indirection,
                ..self.resources()
            };
            draw_trees_into(&res, &late.selection, camera, params, &mut target)
        };
        let drawn = DrawnFrame {
            target,
            terrain_stats,
            tree_stats: early_stats + late_stats,
            trees_discarded: if exact {
                late_discarded
            } else {
                early_discarded + late_discarded
            },
            points_drawn: if exact {
                late_points
            } else {
                early_points + late_points
            },
        };
        let occ = OcclusionFrame {
            counters: late.counters,
            early,
            late: late.selection,
            indirection: occ_indirection,
            early_stats,
            late_stats,
            pyramid,
            visible: late.visible,
        };
        (drawn, occ, seconds)
    }

    /// The zero-false-cull oracle of a frame drawn with occlusion culling (issue 31): the pixels
    /// where a tree the frame culled has a fragment at or in front of the frame's depth. The
    /// culled trees are drawn alone ([`crate::occlude::culled_selection`]) into a cleared
    /// target; a tree with no fragment there has none in the frame without culling either, and
    /// any tree visible without culling has one (its nearest fragment is at the frame's depth,
    /// or in front of it where culling took away what covered it). A tree culled rightly lies
    /// strictly behind an early fragment at every pixel of its rectangle, so it never ties.
    /// 0 for a frame without occlusion culling.
    pub fn false_cull_pixels(&self, camera: &Camera, params: &Params, frame: &Frame) -> u64 {
        let Some(occ) = &frame.occlusion else {
            return 0;
        };
        let indirection = frame.indirection(self);
        let (culled, culled_indirection) = crate::occlude::culled_selection(
            &frame.selection,
            indirection,
            (&occ.early, &occ.late),
            &occ.indirection,
            params.occlusion_order,
        );
        let mut target = crate::raster::RenderTarget::new(
            camera.width,
            camera.height,
            crate::raster::ClearValues {
                color: [0.0; 4],
                depth: 1.0,
                aux: forestlod_shared::LOD_ID_BACKGROUND,
            },
        );
        let res = DrawResources {
            indirection: &culled_indirection,
            ..self.resources()
        };
        draw_trees_into(&res, &culled, camera, params, &mut target);
        let frame_depth = frame.drawn.target.depth();
        target
            .aux()
            .iter()
            .zip(target.depth())
            .zip(frame_depth)
            .filter(|((id, d), f)| **id != forestlod_shared::LOD_ID_BACKGROUND && **d <= **f)
            .count() as u64
    }

    /// The frame's draw once per alpha-test cutoff of `cutoffs`, restricted to `mask` when given:
    /// selection and refine run once (they do not read the cutoff), the draws share their setup
    /// ([`draw_frame_cutoffs`]). Each frame equals [`Prepared::render`]'s with that cutoff (at the
    /// masked pixels when masked). The camera and parameters are validated first.
    pub fn render_cutoffs(
        &self,
        camera: &Camera,
        params: &Params,
        cutoffs: &[f32],
        mask: Option<Vec<bool>>,
    ) -> Result<Vec<DrawnFrame>, InputError> {
        camera.validate()?;
        params.validate()?;
        // Under hierarchical impostors, a path's first frame, as `render` (issue 33 item 2).
        let first = self.first_impostor_frame(camera, params)?;
        self.render_cutoffs_on(
            first.as_ref().map(|(c, _)| c.level()),
            camera,
            params,
            cutoffs,
            mask,
        )
    }

    /// [`Prepared::render_cutoffs`] on the far level `far` (a frame's impostor state, issue 33
    /// item 2) in place of the prepared one; `None` keeps the prepared one (no impostor cache
    /// is made).
    pub fn render_cutoffs_on(
        &self,
        far: Option<&forestlod_shared::FarLevel>,
        camera: &Camera,
        params: &Params,
        cutoffs: &[f32],
        mask: Option<Vec<bool>>,
    ) -> Result<Vec<DrawnFrame>, InputError> {
        camera.validate()?;
        params.validate()?;
        let trace = self.select_stages_on(far, camera, params, false);
        let (selection, refined) = (trace.selection, trace.refined);
        let indirection = refined.as_ref().map(|r| r.indirection.as_slice());
        let res = DrawResources {
            indirection: indirection.unwrap_or(&self.batches.indirection),
            far: far.or(self.far.as_ref()),
            ..self.resources()
        };
        Ok(draw_frame_cutoffs(
            &res, &selection, camera, params, cutoffs, mask,
        ))
    }

    /// The frame's draw once per scale-factor model of `rules` (the tree shader's sampler under
    /// [`crate::sampler::LodRule`]), restricted to `mask` when given: selection and refine run
    /// once. With [`crate::sampler::LodRule::Exact`] a frame equals [`Prepared::render`]'s (at
    /// the masked pixels when masked). The camera and parameters are validated first.
    pub fn render_lod_rules(
        &self,
        camera: &Camera,
        params: &Params,
        rules: &[crate::sampler::LodRule],
        mask: Option<Vec<bool>>,
    ) -> Result<Vec<DrawnFrame>, InputError> {
        camera.validate()?;
        params.validate()?;
        // Under hierarchical impostors, a path's first frame, as `render` (issue 33 item 2).
        let first = self.first_impostor_frame(camera, params)?;
        self.render_lod_rules_on(
            first.as_ref().map(|(c, _)| c.level()),
            camera,
            params,
            rules,
            mask,
        )
    }

    /// [`Prepared::render_lod_rules`] on the far level `far` (a frame's impostor state, issue 33
    /// item 2) in place of the prepared one; `None` keeps the prepared one.
    pub fn render_lod_rules_on(
        &self,
        far: Option<&forestlod_shared::FarLevel>,
        camera: &Camera,
        params: &Params,
        rules: &[crate::sampler::LodRule],
        mask: Option<Vec<bool>>,
    ) -> Result<Vec<DrawnFrame>, InputError> {
        camera.validate()?;
        params.validate()?;
        let trace = self.select_stages_on(far, camera, params, false);
        let (selection, refined) = (trace.selection, trace.refined);
        let indirection = refined.as_ref().map(|r| r.indirection.as_slice());
        Ok(rules
            .iter()
            .flat_map(|&lod_rule| {
                let res = DrawResources {
                    indirection: indirection.unwrap_or(&self.batches.indirection),
                    lod_rule,
                    far: far.or(self.far.as_ref()),
                    ..self.resources()
                };
                draw_frame_cutoffs(
                    &res,
                    &selection,
                    camera,
                    params,
                    &[params.alpha_cutoff],
                    mask.clone(),
                )
            })
            .collect())
    }
}
