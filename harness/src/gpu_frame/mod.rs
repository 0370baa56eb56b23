//! The GPU frame, run in one place (issue 27; pbrt-v4's wavefront integrator has one `Render()`
//! that calls named stages in order, each on the CPU or the GPU). A [`GpuScene`] holds one
//! prepared scene on the GPU; [`GpuScene::render`] runs one frame of a [`GpuPipeline`]: ours, the
//! stages of its `forestlod_shared::FramePlan` in the plan's order (textures, the selection chain
//! [`selection::SelectionChain`], `refine` when the plan has it, the draw), or a baseline (E§5:
//! `cull.wgsl`, then the draw or `primitive.wgsl`). Every tool that draws a GPU frame goes
//! through it: `render` ([`render_gpu`]), `export-case`, the sweeps, `gpu_bench`, the parity
//! tests; `check`, `diagnose` and `draw_split` (which times `select`, `refine` and the draw's
//! parts apart) run its selection chain ([`SelectionChain`]).
//!
//! Which stages the reference computes instead is one [`StagesFromCpu`] (`--stage-from-cpu`, by
//! stage name: the reference computes that stage and every one before it, the GPU the rest). A
//! frame reports which stage ran where, in order ([`GpuTimedFrame::stages`]).
//!
//! ## Contract
//! - The plan is `FramePlan::new(params)`, decided nowhere else; a scene prepared with a
//!   hierarchy must be drawn with a cut plan and one prepared without with a flat plan (an error
//!   says so otherwise).
//! - A frame is two submits, each waited for and timed from submit to completion: stage 1
//!   (selection and `refine`, or the baselines' culling) and stage 2 (the draw pass); then the
//!   counters and the target are read back (not timed).
//! - With occlusion culling (issue 31, `FramePlan::occlusion`; ours and Vegetation), stage 1 ends
//!   with `occlude`'s early split and stage 2 is the early pass, the `pyramid` of its depth, the
//!   late test and the final pass (`exact`: cleared and drawn again in the frame's order;
//!   `reorder`: the late trees onto the early targets). Two-phase's history lives in the scene
//!   (one for ours, one for Vegetation) from frame to frame: [`GpuScene::reset_history`] starts a
//!   camera path.
//! - Everything a scene needs is uploaded once, the first time a frame needs it: the GPU
//!   selection chain, `refine`'s trees, the baselines' culling and proxies. A frame fed from the
//!   reference's selection builds its chain for that frame (its buffers are bound at creation).
//! - `params` must be those the scene was prepared with, apart from the per-frame fields (fade,
//!   distances, LOD levels, coalesce, command order, tree culling).
//! - Under hierarchical impostors (issue 33 item 2, C§4.6.3) the far level is a frame's impostor
//!   state: the scene uploads it in the shape of an empty cache (`impostor_tiles`,
//!   `impostor_pixels` fixed at creation), and [`GpuScene::render_impostors`] writes a state
//!   (`ImpostorCache::level`, stepped by the caller; its tiles rendered by the reference) over it
//!   before the frame, for the GPU cut and the draw. [`GpuScene::render`] draws a path's first
//!   frame, as the reference's `Prepared::render`: a fresh cache stepped once.

mod from_cpu;
pub mod selection;
mod timing;

use std::collections::HashMap;
use std::sync::OnceLock;
use std::time::Instant;

use forestlod_gpu::draw::{DrawCalls, DrawTarget};
use forestlod_gpu::readback::{read_buffer, upload_storage};
use forestlod_gpu::{
    Compaction, DrawInputs, DrawScene, DrawTextures, GpuContext, GpuCull, GpuDraw, GpuError,
    GpuOcclude, GpuPrimitive, GpuProxies, GpuPyramid, GpuRefine, PrimitiveInputs,
};
use forestlod_reference::pipeline::Prepared;
use forestlod_shared::{
    Camera, FramePlan, Occlusion, OcclusionCounters, Params, SelectCounters, StageId,
};

pub use from_cpu::StagesFromCpu;
pub use selection::SelectionChain;

use crate::bridge::{
    BillboardLevel0, DrawSceneData, cull_trees, gpu_textures, gpu_textures_with,
    occlusion_footprints, proxy_records, upload_reference_textures,
};
use crate::image_compare::Images;
use timing::Timestamps;

/// Which pipeline a [`GpuScene`] renders (E§5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GpuPipeline {
    /// Ours: the frame plan's selection stages (the flat selection with this compaction; a cut
    /// has the stable order only), `refine` when planned, then `draw.wgsl`.
    Ours(Compaction),
    /// Every visible tree as a full mesh: `cull.wgsl`, then `draw.wgsl` on its compacted list.
    Vegetation,
    /// One ray-cast proxy quad per visible tree: `cull.wgsl`, then `primitive.wgsl`.
    Primitive,
}

impl GpuPipeline {
    /// Name for reports and CSVs: `ours-stable`, `ours-atomic`, `vegetation`, `primitive`.
    pub fn name(self) -> String {
        match self {
            GpuPipeline::Ours(c) => format!("ours-{}", c.name()),
            GpuPipeline::Vegetation => "vegetation".into(),
            GpuPipeline::Primitive => "primitive".into(),
        }
    }
}

/// Where a stage of a frame ran.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RanOn {
    /// The GPU twin.
    Gpu,
    /// The reference (`--stage-from-cpu`), its output uploaded.
    Reference,
}

/// One frame of a [`GpuScene`], timed.
#[derive(Clone, Debug)]
pub struct GpuTimedFrame {
    /// Colour, depth and LOD id, read back.
    pub images: Images,
    /// The frame's stages in the order they ran, and where (ours: the plan's; baselines:
    /// `cull`, then `draw` or `primitive`).
    pub stages: Vec<(StageId, RanOn)>,
    /// The draw calls recorded (ours and Vegetation; `None` for Primitive).
    pub calls: Option<DrawCalls>,
    /// Wall seconds from submit to completion (`ctx.wait`) of selection (ours, with `refine`
    /// when the plan has it) or culling (baselines).
    pub select_s: f64,
    /// Wall seconds from submit to completion of the draw pass (readback excluded).
    pub draw_s: f64,
    /// GPU seconds of selection (with `refine` where it runs) / culling between timestamps, where
    /// `TIMESTAMP_QUERY` is offered.
    pub gpu_select_s: Option<f64>,
    /// GPU seconds of the draw pass between timestamps, where `TIMESTAMP_QUERY` is offered.
    pub gpu_draw_s: Option<f64>,
    /// Draw commands, read back from the counters: ours and Vegetation `counters.commands`;
    /// Primitive 1 when any tree is visible (its one `draw_indirect`), else 0, as the reference
    /// counts it.
    pub commands: u64,
    /// Baselines: the visible trees (`counters.instances`, the Primitive's instance count);
    /// ours: `None`.
    pub trees_drawn: Option<u64>,
    /// Ours with occlusion culling (issue 31): the `occlude` stage's counters, read back.
    pub occlusion: Option<OcclusionCounters>,
}

/// What [`render_gpu`] used and produced.
#[derive(Debug)]
pub struct GpuFrame {
    /// The buffers read back.
    pub images: Images,
    /// The CPU-side draw calls it recorded.
    pub calls: DrawCalls,
    /// Where its inputs came from.
    pub from_cpu: StagesFromCpu,
    /// Its stages in the order they ran, and where.
    pub stages: Vec<(StageId, RanOn)>,
}

/// One prepared scene on the GPU (module docs): the draw buffers and textures uploaded at
/// creation, the rest the first time a frame needs it.
pub struct GpuScene<'a> {
    ctx: &'a GpuContext,
    from_cpu: StagesFromCpu,
    scene: DrawScene,
    textures: DrawTextures,
    /// The selection chain on the GPU (built by the first frame of ours that runs one).
    chain: Option<SelectionChain<'a>>,
    /// The chain of the last frame of ours fed by the reference's selection, if the last frame
    /// of ours was one.
    fed: Option<SelectionChain<'a>>,
    refine: Option<GpuRefine<'a>>,
    /// Vegetation's occlusion culling (issue 31), with its own history.
    occlude_vegetation: Option<GpuOcclude<'a>>,
    /// Occlusion culling's footprints and history (issue 31; built by the first frame with
    /// occlusion culling; the history lives as long as the scene, [`GpuScene::reset_history`]).
    occlude: Option<GpuOcclude<'a>>,
    /// One depth pyramid per target size.
    pyramids: HashMap<(u32, u32), GpuPyramid>,
    cull: Option<GpuCull<'a>>,
    proxies: Option<GpuProxies>,
    draw: &'a GpuDraw,
    primitive: Option<&'a GpuPrimitive>,
    targets: HashMap<(u32, u32), DrawTarget>,
    timestamps: Option<Timestamps>,
    /// `(instances, batches, hierarchy nodes)` of the prepared scene, to refuse another.
    shape: (usize, usize, Option<usize>),
}

/// A [`GpuError::Input`] for a frame's inputs.
fn input_error(field: &'static str, value: String, reason: &'static str) -> GpuError {
    GpuError::Input {
        field,
        value,
        reason,
    }
}

impl GpuScene<'static> {
    /// [`GpuScene::with_pipelines`] with this process's compiled draw and Primitive pipelines
    /// ([`try_gpu_draw`], [`gpu_primitive`]): every pipeline, the baselines' included.
    pub fn new(
        ctx: &'static GpuContext,
        prepared: &Prepared,
        params: &Params,
        from_cpu: StagesFromCpu,
    ) -> Result<Self, GpuError> {
        let mut scene = Self::with_pipelines(ctx, try_gpu_draw(ctx)?, prepared, params, from_cpu)?;
        scene.primitive = Some(gpu_primitive(ctx)?);
        Ok(scene)
    }
}

impl<'a> GpuScene<'a> {
    /// Uploads `prepared`'s draw buffers (prepared with `params`) and its textures: the GPU's bake
    /// and mips with `params`' mip mode and alpha cutoff, or the reference's as `from_cpu` says.
    /// Without a Primitive pipeline ([`GpuScene::new`] has one), [`GpuPipeline::Primitive`] is
    /// refused.
    pub fn with_pipelines(
        ctx: &'a GpuContext,
        draw: &'a GpuDraw,
        prepared: &Prepared,
        params: &Params,
        from_cpu: StagesFromCpu,
    ) -> Result<Self, GpuError> {
        let data = DrawSceneData::new(prepared);
        // Under hierarchical impostors (issue 33 item 2) the far level is the frame's impostor
        // state: uploaded in the shape of an empty cache, overwritten before each frame.
        let impostor_shape = impostor_level_shape(prepared, params)?;
        let mut desc = data.desc(prepared);
        if let Some(level) = &impostor_shape {
            desc.far = Some(level);
        }
        let scene = DrawScene::new(ctx, &desc)?;
        drop(impostor_shape);
        // The CPU copies are uploaded: free them before the frame (the main job's peak memory is
        // its frame's, issue 14).
        drop(data);
        let textures = match from_cpu.textures {
            None => gpu_textures(ctx, prepared, params)?,
            Some(StageId::Bake) => {
                gpu_textures_with(ctx, prepared, params, BillboardLevel0::Reference)?
            }
            Some(_) => upload_reference_textures(ctx, prepared)?,
        }
        .draw_textures()?;
        Ok(Self {
            ctx,
            from_cpu,
            scene,
            textures,
            chain: None,
            fed: None,
            refine: None,
            occlude: None,
            occlude_vegetation: None,
            pyramids: HashMap::new(),
            cull: None,
            proxies: None,
            draw,
            primitive: None,
            targets: HashMap::new(),
            timestamps: Timestamps::new(ctx),
            shape: shape_of(prepared),
        })
    }

    /// The stages this scene takes from the reference.
    pub fn from_cpu(&self) -> StagesFromCpu {
        self.from_cpu
    }

    /// The selection chain of the last frame of ours (for tests: its buffers, decisions, codes
    /// and order pairs; refined in place when the plan had `refine`): the one fed by the
    /// reference when that frame took its selection from the reference, else the GPU's.
    pub fn chain(&self) -> Option<&SelectionChain<'a>> {
        self.fed.as_ref().or(self.chain.as_ref())
    }

    /// The GPU selection chain, built now if no frame has built it yet.
    pub fn chain_mut(&mut self, prepared: &Prepared) -> Result<&mut SelectionChain<'a>, GpuError> {
        self.check_scene(prepared)?;
        if self.chain.is_none() {
            self.chain = Some(SelectionChain::gpu(self.ctx, prepared)?);
        }
        Ok(self.chain.as_mut().expect("built above"))
    }

    /// The per-tree refinement of the last frame that ran it on the GPU (for tests:
    /// `GpuRefine::read`).
    pub fn refine(&self) -> Option<&GpuRefine<'a>> {
        self.refine.as_ref()
    }

    /// The occlusion culling of the last frame that ran it (for tests: `GpuOcclude::read`).
    pub fn occlude(&self) -> Option<&GpuOcclude<'a>> {
        self.occlude.as_ref()
    }

    /// Starts a camera path: the next frame with occlusion culling `two-phase` has no history
    /// (its early pass is empty, the reference's `render` of a path's first frame).
    pub fn reset_history(&mut self) {
        for o in [&mut self.occlude, &mut self.occlude_vegetation]
            .into_iter()
            .flatten()
        {
            o.reset_history();
        }
    }

    /// The baselines' culling of the last baseline frame (for tests: `GpuCull::read`).
    pub fn cull(&self) -> Option<&GpuCull<'a>> {
        self.cull.as_ref()
    }

    /// The draw buffers and textures, for a caller recording its own draw pass
    /// (`draw_split`'s probes).
    pub fn draw_inputs<'s>(
        &'s self,
        selection: &'s forestlod_gpu::SelectBuffers,
        indirection: Option<&'s wgpu::Buffer>,
    ) -> DrawInputs<'s> {
        DrawInputs {
            scene: &self.scene,
            textures: &self.textures,
            selection,
            indirection,
        }
    }

    fn check_scene(&self, prepared: &Prepared) -> Result<(), GpuError> {
        let got = shape_of(prepared);
        if got != self.shape {
            return Err(input_error(
                "prepared",
                format!(
                    "(instances, batches, nodes) {got:?}, the scene was uploaded with {:?}",
                    self.shape
                ),
                "a GpuScene draws the prepared scene it was created from",
            ));
        }
        Ok(())
    }

    /// Renders one frame of `pipeline` of `prepared` (the scene this was created from) as the
    /// module docs say. Under hierarchical impostors (issue 33 item 2) the frame is a path's
    /// first, as the reference's `Prepared::render`: a fresh impostor cache stepped once from
    /// `camera` (its tiles rendered by the reference), drawn by [`GpuScene::render_impostors`].
    pub fn render(
        &mut self,
        prepared: &Prepared,
        pipeline: GpuPipeline,
        camera: &Camera,
        params: &Params,
    ) -> Result<GpuTimedFrame, GpuError> {
        self.validate(camera, params)?;
        let first = prepared.first_impostor_frame(camera, params).map_err(|e| {
            input_error(
                "far_lod",
                e.to_string(),
                "the impostor cache of the frame could not be made",
            )
        })?;
        match first {
            Some((cache, _)) => {
                self.render_on(prepared, pipeline, camera, params, Some(cache.level()))
            }
            None => self.render_on(prepared, pipeline, camera, params, None),
        }
    }

    /// One frame of a camera path under hierarchical impostors (issue 33 item 2,
    /// `forestlod_shared::impostor`): `far` is the frame's impostor state
    /// (`forestlod_reference::impostor_cache::ImpostorCache::level`, stepped for this frame by
    /// the caller: its plan and its tiles are the reference's), uploaded over the scene's far
    /// level before the frame; the cut and the draw read it. `params` must have `lod_levels = 3`
    /// and `far_lod = impostor`, with the impostor shape (`impostor_tiles`, `impostor_pixels`)
    /// the scene was created with.
    pub fn render_impostors(
        &mut self,
        prepared: &Prepared,
        pipeline: GpuPipeline,
        camera: &Camera,
        params: &Params,
        far: &forestlod_shared::FarLevel,
    ) -> Result<GpuTimedFrame, GpuError> {
        self.validate(camera, params)?;
        if !is_impostor(params) {
            return Err(input_error(
                "far_lod",
                format!(
                    "lod_levels {}, far_lod {}",
                    params.lod_levels,
                    forestlod_shared::FarLod::from_id(params.far_lod).map_or("?", |f| f.name())
                ),
                "render_impostors draws frames with lod_levels = 3 and far_lod = impostor",
            ));
        }
        self.render_on(prepared, pipeline, camera, params, Some(far))
    }

    fn validate(&self, camera: &Camera, params: &Params) -> Result<(), GpuError> {
        camera.validate().map_err(|e| {
            input_error(
                "camera",
                e.to_string(),
                "expected a valid camera (Camera::validate)",
            )
        })?;
        params.validate().map_err(|e| {
            input_error(
                "params",
                e.to_string(),
                "expected valid parameters (Params::validate)",
            )
        })?;
        Ok(())
    }

    /// [`GpuScene::render`] with `far` (the frame's impostor state) in place of the scene's far
    /// level, when given.
    fn render_on(
        &mut self,
        prepared: &Prepared,
        pipeline: GpuPipeline,
        camera: &Camera,
        params: &Params,
        far: Option<&forestlod_shared::FarLevel>,
    ) -> Result<GpuTimedFrame, GpuError> {
        let plan = FramePlan::new(params).map_err(|e| {
            input_error(
                "params",
                e.to_string(),
                "expected valid parameters (Params::validate)",
            )
        })?;
        self.check_scene(prepared)?;
        if plan.is_cut() != prepared.hierarchy.is_some() {
            return Err(input_error(
                "params.hierarchy",
                format!(
                    "a {} plan for a scene prepared {} a hierarchy",
                    if plan.is_cut() { "cut" } else { "flat" },
                    if prepared.hierarchy.is_some() {
                        "with"
                    } else {
                        "without"
                    }
                ),
                "render with the parameters the scene was prepared with",
            ));
        }
        let ctx = self.ctx;
        let key = (camera.width, camera.height);
        let occlusion = match pipeline {
            GpuPipeline::Ours(_) | GpuPipeline::Vegetation => plan.occlusion,
            GpuPipeline::Primitive => Occlusion::Off,
        };
        if occlusion != Occlusion::Off
            && let std::collections::hash_map::Entry::Vacant(slot) = self.pyramids.entry(key)
        {
            slot.insert(GpuPyramid::new(ctx, camera.width, camera.height)?);
        }
        if let std::collections::hash_map::Entry::Vacant(slot) = self.targets.entry(key) {
            slot.insert(DrawTarget::new(ctx, camera.width, camera.height)?);
        }

        // What stage 1 records, and where each stage runs.
        let mut stages = Vec::new();
        let mut cpu_chain: Option<SelectionChain<'a>> = None;
        let mut cpu_indirection = None;
        let mut gpu_refine = false;
        match pipeline {
            GpuPipeline::Ours(_) => {
                for s in [StageId::Bake, StageId::Mips] {
                    stages.push((s, self.ran_on(&plan, s)));
                }
                if let Some(last) = self.from_cpu.last_selection_stage(&plan) {
                    let trace = prepared.select_stages_on(far, camera, params, true);
                    cpu_chain = Some(SelectionChain::from_cpu(
                        ctx, prepared, &plan, &trace, last,
                    )?);
                    if last == StageId::Refine {
                        let r = trace.refined.as_ref().expect("the plan has refine");
                        cpu_indirection = Some(upload_storage(
                            ctx,
                            "refined indirection (cpu)",
                            &r.indirection,
                            wgpu::BufferUsages::empty(),
                        ));
                    }
                } else if self.chain.is_none() {
                    self.chain = Some(SelectionChain::gpu(ctx, prepared)?);
                }
                if let Some(far) = far {
                    // The frame's impostor state over the uploaded far level (issue 33 item 2):
                    // the GPU cut's node records and the draw's quads and atlas.
                    if let Some(chain) = &self.chain {
                        chain.write_far_nodes(&far.nodes)?;
                    }
                    self.scene.write_far(ctx, far)?;
                }
                for s in plan.selection_stages() {
                    stages.push((s, self.ran_on(&plan, s)));
                }
                gpu_refine =
                    plan.refine.is_some() && !self.from_cpu.computes(&plan, StageId::Refine);
                if gpu_refine && self.refine.is_none() {
                    self.refine = Some(GpuRefine::new(
                        ctx,
                        &cull_trees(prepared),
                        &prepared.batches.indirection,
                    )?);
                }
                if occlusion != Occlusion::Off {
                    stages.extend([
                        (StageId::Pyramid, RanOn::Gpu),
                        (StageId::Occlude, RanOn::Gpu),
                    ]);
                    if self.occlude.is_none() {
                        self.occlude = Some(GpuOcclude::new(ctx, &occlusion_footprints(prepared))?);
                    }
                }
                stages.push((StageId::Draw, RanOn::Gpu));
            }
            GpuPipeline::Vegetation | GpuPipeline::Primitive => {
                if self.cull.is_none() {
                    self.cull = Some(GpuCull::new(
                        ctx,
                        &cull_trees(prepared),
                        &prepared.geometry.meshes,
                    )?);
                }
                stages.push((StageId::Cull, RanOn::Gpu));
                if pipeline == GpuPipeline::Primitive {
                    if self.primitive.is_none() {
                        return Err(input_error(
                            "pipeline",
                            pipeline.name(),
                            "this GpuScene has no Primitive pipelines (GpuScene::new has them)",
                        ));
                    }
                    if self.proxies.is_none() {
                        self.proxies = Some(GpuProxies::new(ctx, &proxy_records(prepared, params)));
                    }
                    stages.push((StageId::Primitive, RanOn::Gpu));
                } else {
                    // Vegetation with occlusion culling (issue 31: the modern per-tree peer):
                    // the same stage over `cull.wgsl`'s commands, its own history.
                    if occlusion != Occlusion::Off {
                        stages.extend([
                            (StageId::Pyramid, RanOn::Gpu),
                            (StageId::Occlude, RanOn::Gpu),
                        ]);
                        if self.occlude_vegetation.is_none() {
                            self.occlude_vegetation =
                                Some(GpuOcclude::new(ctx, &occlusion_footprints(prepared))?);
                        }
                    }
                    stages.push((StageId::Draw, RanOn::Gpu));
                }
            }
        }

        if matches!(pipeline, GpuPipeline::Ours(_)) {
            self.fed = cpu_chain;
        }
        let chain = match &mut self.fed {
            Some(c) => Some(c),
            None => self.chain.as_mut(),
        };
        let target = &self.targets[&key];
        let stamps = self.timestamps.as_ref();
        // An encoder that starts with timestamp `stamp` where timestamps are offered.
        let begin = |label: &str, stamp: u32| {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
            if let Some(s) = stamps {
                s.mark(&mut encoder, stamp);
            }
            encoder
        };
        let submit_timed = |encoder: wgpu::CommandEncoder| -> Result<f64, GpuError> {
            let commands = encoder.finish();
            let t = Instant::now();
            ctx.queue.submit([commands]);
            ctx.wait()?;
            Ok(t.elapsed().as_secs_f64())
        };

        // Stage 1: selection (and refine) or culling; with occlusion culling the early split.
        let refine = self.refine.as_mut();
        let cull = self.cull.as_mut();
        let occlude = match pipeline {
            GpuPipeline::Ours(_) => self.occlude.as_mut(),
            GpuPipeline::Vegetation => self.occlude_vegetation.as_mut(),
            GpuPipeline::Primitive => None,
        };
        let tree_count = prepared.scene.instances.len() as u32;
        let scene_indirection = self.scene.indirection();
        // The indirection the frame's commands index, and its length `m`.
        let refined = gpu_refine || cpu_indirection.is_some();
        let m = if refined {
            3 * prepared.batches.indirection.len() as u32
        } else {
            prepared.batches.indirection.len() as u32
        };
        let (encoder, chain, cull, mut occlude) = ctx.checked("frame select/cull", || {
            let mut encoder = begin("frame select", 0);
            let mut chain = chain;
            let mut cull = cull;
            let mut occlude = occlude;
            match pipeline {
                GpuPipeline::Ours(compaction) => {
                    let chain = chain.as_deref_mut().expect("ours has a chain");
                    chain.encode(&mut encoder, camera, params, compaction);
                    let refine_indirection = if gpu_refine {
                        let refine = refine.expect("created above");
                        refine.encode(&mut encoder, chain.buffers_mut(), camera, params);
                        Some(refine.indirection())
                    } else {
                        None
                    };
                    if occlusion != Occlusion::Off {
                        let input = cpu_indirection
                            .as_ref()
                            .or(refine_indirection)
                            .unwrap_or(scene_indirection);
                        occlude
                            .as_deref_mut()
                            .expect("created above")
                            .encode_early(
                                &mut encoder,
                                chain.buffers(),
                                input,
                                m,
                                camera,
                                params,
                            )?;
                    }
                }
                GpuPipeline::Vegetation | GpuPipeline::Primitive => {
                    let cull = cull.as_deref_mut().expect("created above");
                    cull.encode(&mut encoder, camera, params);
                    if occlusion != Occlusion::Off {
                        // Its commands index the compacted list of one entry per tree.
                        occlude
                            .as_deref_mut()
                            .expect("created above")
                            .encode_early(
                                &mut encoder,
                                cull.buffers(),
                                cull.indirection(),
                                tree_count,
                                camera,
                                params,
                            )?;
                    }
                }
            }
            if let Some(s) = stamps {
                s.mark(&mut encoder, 1);
            }
            Ok((encoder, chain, cull, occlude))
        })??;
        let select_s = submit_timed(encoder)?;

        // Stage 2: the draw pass.
        let refine = self.refine.as_ref();
        let chain = chain.map(|c| &*c);
        let cull = cull.map(|c| &*c);
        let indirection = match (&cpu_indirection, gpu_refine) {
            (Some(b), _) => Some(b),
            (None, true) => refine.map(|r| r.indirection()),
            (None, false) => None,
        };
        let (scene, textures, draw) = (&self.scene, &self.textures, self.draw);
        let pyramid = self.pyramids.get(&key);
        let (primitive, proxies) = (self.primitive, self.proxies.as_ref());
        let (encoder, calls) = ctx.checked("frame draw", || -> Result<_, GpuError> {
            let mut encoder = begin("frame draw", 2);
            let calls = match pipeline {
                GpuPipeline::Ours(_) | GpuPipeline::Vegetation => {
                    if let (GpuPipeline::Ours(_) | GpuPipeline::Vegetation, Some(occlude)) = (
                        pipeline,
                        occlude
                            .as_deref_mut()
                            .filter(|_| occlusion != Occlusion::Off),
                    ) {
                        // Issue 31: early pass (cleared, ground first), the pyramid of its
                        // depth, the late test, the final pass (`exact`: cleared again, every
                        // tree not culled; `reorder`: the late trees loading the same targets).
                        let selection = match pipeline {
                            GpuPipeline::Ours(_) => chain.expect("ours has a chain").buffers(),
                            _ => cull.expect("created above").buffers(),
                        };
                        let (early, late) = (
                            occlude.early_buffers(selection),
                            occlude.late_buffers(selection),
                        );
                        let inputs = |selection| DrawInputs {
                            scene,
                            textures,
                            selection,
                            indirection: Some(occlude.indirection()),
                        };
                        let calls = draw.encode(
                            ctx,
                            &mut encoder,
                            &inputs(&early),
                            camera,
                            params,
                            target,
                        )?;
                        let pyramid = pyramid.expect("created above");
                        pyramid.encode_from_depth(ctx, &mut encoder, target.depth_texture());
                        occlude.encode_late(&mut encoder, selection, pyramid, camera, params)?;
                        let late_inputs = DrawInputs {
                            scene,
                            textures,
                            selection: &late,
                            indirection: Some(occlude.indirection()),
                        };
                        if forestlod_shared::final_includes_early(params.occlusion_order) {
                            // `exact`: the early pass was a depth pre-pass; the final pass
                            // clears and draws every tree not culled in the frame's order.
                            draw.encode(ctx, &mut encoder, &late_inputs, camera, params, target)?;
                        } else {
                            // `reorder`: the late trees onto the early pass's targets.
                            draw.encode_late(
                                ctx,
                                &mut encoder,
                                &late_inputs,
                                camera,
                                params,
                                target,
                            )?;
                        }
                        if let Some(s) = stamps {
                            s.mark(&mut encoder, 3);
                            s.resolve(&mut encoder);
                        }
                        return Ok((encoder, Some(calls)));
                    }
                    let inputs = match pipeline {
                        GpuPipeline::Ours(_) => DrawInputs {
                            scene,
                            textures,
                            selection: chain.expect("ours has a chain").buffers(),
                            indirection,
                        },
                        _ => {
                            let cull = cull.expect("created above");
                            DrawInputs {
                                scene,
                                textures,
                                selection: cull.buffers(),
                                indirection: Some(cull.indirection()),
                            }
                        }
                    };
                    Some(draw.encode(ctx, &mut encoder, &inputs, camera, params, target)?)
                }
                GpuPipeline::Primitive => {
                    let cull = cull.expect("created above");
                    let inputs = PrimitiveInputs {
                        scene,
                        proxies: proxies.expect("created above"),
                        indirection: cull.indirection(),
                        draw_args: cull.draw_args(),
                    };
                    primitive.expect("checked above").encode(
                        ctx,
                        &mut encoder,
                        &inputs,
                        camera,
                        params,
                        target,
                    )?;
                    None
                }
            };
            if let Some(s) = stamps {
                s.mark(&mut encoder, 3);
                s.resolve(&mut encoder);
            }
            Ok((encoder, calls))
        })??;
        let draw_s = submit_timed(encoder)?;

        // Readback (not timed).
        let (gpu_select_s, gpu_draw_s) = match stamps {
            Some(s) => {
                let (a, b) = s.read(ctx)?;
                (Some(a), Some(b))
            }
            None => (None, None),
        };
        let counters_buffer = match pipeline {
            GpuPipeline::Ours(_) => &chain.expect("ours has a chain").buffers().counters,
            _ => &cull.expect("created above").buffers().counters,
        };
        let counters = read_buffer::<SelectCounters>(ctx, counters_buffer, 0, 1)?[0];
        let (commands, trees_drawn) = match pipeline {
            GpuPipeline::Ours(_) => (counters.commands as u64, None),
            GpuPipeline::Vegetation => (counters.commands as u64, Some(counters.instances as u64)),
            GpuPipeline::Primitive => (
                (counters.instances > 0) as u64,
                Some(counters.instances as u64),
            ),
        };
        let occlusion_counters = match (&occlude, occlusion) {
            (Some(o), o_mode) if o_mode != Occlusion::Off => Some(o.read_counters()?),
            _ => None,
        };
        let out = target.read(ctx)?;
        Ok(GpuTimedFrame {
            images: Images::from(out),
            stages,
            calls,
            select_s,
            draw_s,
            gpu_select_s,
            gpu_draw_s,
            commands,
            trees_drawn,
            occlusion: occlusion_counters,
        })
    }

    fn ran_on(&self, plan: &FramePlan, stage: StageId) -> RanOn {
        if self.from_cpu.computes(plan, stage) {
            RanOn::Reference
        } else {
            RanOn::Gpu
        }
    }
}

/// Whether `params` draw hierarchical impostors (issue 33 item 2).
fn is_impostor(params: &Params) -> bool {
    params.lod_levels >= 3 && params.far_level() == Ok(forestlod_shared::FarLod::Impostor)
}

/// Under hierarchical impostors, the far level of an empty impostor cache of `prepared`: the
/// shape (nodes, quads, atlas) every frame's state has, which the scene uploads (issue 33 item 2).
fn impostor_level_shape(
    prepared: &Prepared,
    params: &Params,
) -> Result<Option<forestlod_shared::FarLevel>, GpuError> {
    if !is_impostor(params) {
        return Ok(None);
    }
    let cache =
        forestlod_reference::impostor_cache::ImpostorCache::new(prepared, params).map_err(|e| {
            input_error(
                "far_lod",
                e.to_string(),
                "hierarchical impostors need a scene prepared with a hierarchy",
            )
        })?;
    Ok(Some(cache.level().clone()))
}

/// `(instances, batches, hierarchy nodes)` of a prepared scene.
fn shape_of(prepared: &Prepared) -> (usize, usize, Option<usize>) {
    (
        prepared.scene.instances.len(),
        prepared.batches.metas.len(),
        prepared.hierarchy.as_ref().map(|h| h.nodes.len()),
    )
}

/// Renders one frame of ours on the GPU and reads it back: a [`GpuScene`] of `prepared` with
/// `from_cpu`'s stages from the reference, one frame of [`GpuPipeline::Ours`] (stable
/// compaction). `draw` holds the compiled pipelines (see [`gpu_draw`]).
pub fn render_gpu(
    ctx: &GpuContext,
    draw: &GpuDraw,
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
    from_cpu: StagesFromCpu,
) -> Result<GpuFrame, GpuError> {
    let mut scene = GpuScene::with_pipelines(ctx, draw, prepared, params, from_cpu)?;
    let frame = scene.render(
        prepared,
        GpuPipeline::Ours(Compaction::Stable),
        camera,
        params,
    )?;
    Ok(GpuFrame {
        images: frame.images,
        calls: frame.calls.expect("ours records draw calls"),
        from_cpu,
        stages: frame.stages,
    })
}

/// `cell`'s value, made by `make` on first use; an error leaves the cell empty (the next call
/// tries again and reports again).
fn once<T>(
    cell: &'static OnceLock<T>,
    make: impl FnOnce() -> Result<T, GpuError>,
) -> Result<&'static T, GpuError> {
    if let Some(v) = cell.get() {
        return Ok(v);
    }
    let v = make()?;
    Ok(cell.get_or_init(|| v))
}

/// The draw pipelines of this test binary's context (compiled once).
pub fn gpu_draw(ctx: &'static GpuContext) -> &'static GpuDraw {
    try_gpu_draw(ctx).expect("GpuDraw::new")
}

/// The draw pipelines of this process's context, compiled once (fallible twin of [`gpu_draw`]).
pub fn try_gpu_draw(ctx: &'static GpuContext) -> Result<&'static GpuDraw, GpuError> {
    static DRAW: OnceLock<GpuDraw> = OnceLock::new();
    once(&DRAW, || GpuDraw::new(ctx))
}

/// The Primitive pipelines of this process's context, compiled once.
pub fn gpu_primitive(ctx: &'static GpuContext) -> Result<&'static GpuPrimitive, GpuError> {
    static PRIMITIVE: OnceLock<GpuPrimitive> = OnceLock::new();
    once(&PRIMITIVE, || GpuPrimitive::new(ctx))
}
