//! The GPU twin of each stage run **alone** (issue 27): [`GpuStage`] is a
//! [`Backend`] of every stage of the table; for the list stages and the baselines it uploads the
//! reference's input of that one stage, runs only its GPU driver and reads its output back, so a
//! difference is that stage's own (the select, draw, mips and bake stages use their existing
//! isolated backends: `GpuSelectBackend`, `GpuRenderer` with every input from the CPU,
//! `GpuMipsBackend` on uploaded level 0, `GpuBakeBackend`).
//!
//! [`FrameStages`] builds every stage's input from one reference frame (the
//! [`SelectionTrace`] of `select_stages`, kept) and judges the GPU's output of any stage
//! ([`FrameStages::check`], one arm per [`StageId`], so a new stage does not compile until it is
//! judged here); `tests/tests/parity/every_stage.rs` and [`crate::diagnose`] call it.
//!
//! Drivers used: `GpuHierSelect` (`read_uncoalesced`, `read_codes_and_states` only: the raw cut),
//! `GpuCoalesce` on `SelectBuffers::from_cpu`, `GpuCommandOrder` on uploaded nodes, raw cut, run
//! offsets (`forestlod_reference::coalesce::run_offsets`) and coalesced runs, `GpuRefine` on the
//! uploaded selection, `GpuCull`, and `GpuPrimitive` on the reference's visible trees.

use forestlod_gpu::draw::DrawTarget;
use forestlod_gpu::readback::{read_buffer, upload_storage};
use forestlod_gpu::{
    Compaction, DrawScene, GpuCoalesce, GpuContext, GpuCull, GpuError, GpuHierSelect, GpuOcclude,
    GpuProxies, GpuPyramid, GpuRefine, GpuSelection, PrimitiveInputs, SelectBuffers,
};
use forestlod_reference::baselines::{tree_spheres, visible_trees};
use forestlod_reference::frame::SelectionTrace;
use forestlod_reference::hier_select::HierSelection;
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::refine::Refined;
use forestlod_reference::select::Selection;
use forestlod_reference::select::tree_bands;
use forestlod_shared::{
    Camera, Coalesce as CoalesceMode, CommandOrder as OrderMode, MipMode, Params, SelectionPlan,
    StageId, ViewUniform,
};

use crate::backend::{GpuRenderer, GpuSelectBackend};
use crate::bridge::{DrawSceneData, OrderFromCpu, cull_trees, cull_trees_of, proxy_records};
use crate::gpu_frame::{StagesFromCpu, gpu_primitive};
use crate::image_compare::Images;
use crate::judge::{CullCase, Culled, RefineCase, Refinement, primitive_args};
use crate::stage::{
    Backend, Bake, BakeInput, Coalesce, CoalesceInput, Coalesced, CommandOrder, CommandOrderInput,
    Cull, Draw, FarBake, FarBakeInput, FrameInput, HierSelect, HierSelectInput, Mips, MipsInput,
    Named, Occlude, OccludeInput, Occluded, Ordered, Primitive, Pyramid, PyramidInput, Reference,
    Refine, RefineInput, Select, SelectInput, StageCheck, compare,
};
use crate::texel_compare::{GpuBakeBackend, GpuMipsBackend, gpu_bake};

/// The GPU twin of one stage run alone on uploaded input (module docs): a [`Backend`] of
/// `hier_select`, `coalesce`, `command_order`, `refine`, `cull` and `primitive`.
#[derive(Clone, Copy)]
pub struct GpuStage {
    /// The shared context.
    pub ctx: &'static GpuContext,
}

impl Named for GpuStage {
    fn name(&self) -> String {
        "gpu(stage alone)".into()
    }
}

/// Panics naming the backend and what failed (the [`Backend::run`] contract).
fn ok<T>(what: &str, r: Result<T, GpuError>) -> T {
    r.unwrap_or_else(|e| panic!("gpu(stage alone): {what}: {e}"))
}

/// The reference's frame, or a panic naming the input error (inputs are valid).
fn ok_input<T>(r: Result<T, forestlod_reference::InputError>) -> T {
    r.unwrap_or_else(|e| panic!("gpu(stage alone): the reference's frame: {e}"))
}

/// A GPU selection read back, as the reference's.
fn selection_of(s: GpuSelection) -> Selection {
    Selection {
        commands: s.commands,
        data: s.data,
        counters: s.counters,
    }
}

/// `s` uploaded.
fn upload(ctx: &GpuContext, s: &Selection) -> SelectBuffers {
    ok(
        "upload the selection",
        SelectBuffers::from_cpu(ctx, &s.commands, &s.data, &s.counters),
    )
}

/// Records `record` into a fresh encoder and submits it, validation errors reported.
fn submit(ctx: &GpuContext, what: &str, record: impl FnOnce(&mut wgpu::CommandEncoder)) {
    ok(
        what,
        ctx.checked(what, || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(what) });
            record(&mut encoder);
            ctx.queue.submit([encoder.finish()]);
        }),
    );
}

impl Backend<HierSelect> for GpuStage {
    fn run(&self, i: HierSelectInput<'_>) -> HierSelection {
        let h = i.hierarchy;
        let mut gpu = ok(
            "GpuHierSelect::new",
            GpuHierSelect::new(
                self.ctx,
                &h.nodes,
                &h.scales,
                h.mode as u32,
                i.meshes,
                i.billboard,
                i.far.map(|f| forestlod_gpu::hier_select::FarNodes {
                    nodes: &f.level.nodes,
                    first_index: f.first_index,
                }),
            ),
        );
        ok(
            "hier_select dispatch",
            gpu.dispatch(i.camera, i.params).map(|_| ()),
        );
        let raw = ok("read the raw cut", gpu.read_uncoalesced());
        let (codes, states) = ok("read codes and states", gpu.read_codes_and_states());
        HierSelection {
            selection: selection_of(raw),
            codes,
            states,
        }
    }
}

impl Backend<Coalesce> for GpuStage {
    fn run(&self, i: CoalesceInput<'_>) -> Coalesced {
        let ctx = self.ctx;
        let input = upload(ctx, i.raw);
        let mut gpu = ok("GpuCoalesce::new", GpuCoalesce::new(ctx, &input));
        submit(ctx, "coalesce", |e| gpu.encode(e, i.mode));
        Coalesced {
            selection: selection_of(ok("read the runs", gpu.buffers().read(ctx))),
            run_offsets: ok(
                "read the run offsets",
                read_buffer(ctx, gpu.run_offsets(), 0, i.raw.commands.len()),
            ),
        }
    }
}

impl Backend<CommandOrder> for GpuStage {
    fn run(&self, i: CommandOrderInput<'_>) -> Ordered {
        let ctx = self.ctx;
        let mode = i.params.command_ordering().expect("valid parameters");
        let OrderFromCpu {
            out,
            order: mut gpu,
            ..
        } = ok(
            "upload the cut and bind the order",
            OrderFromCpu::new(ctx, i.nodes, i.raw, i.coalesced, i.coalesce),
        );
        let view = ViewUniform::new(i.camera, i.params);
        submit(ctx, "command_order", |e| gpu.encode(e, &view, mode));
        let selection = selection_of(ok("read the ordered commands", out.read(ctx)));
        let pairs = match mode {
            OrderMode::Node => Vec::new(),
            _ => ok("read the pairs", gpu.read_pairs(selection.commands.len())),
        };
        Ordered { selection, pairs }
    }
}

impl Backend<Refine> for GpuStage {
    fn run(&self, i: RefineInput<'_>) -> Refinement {
        let (ctx, c) = (self.ctx, i.case);
        let mut gpu = ok(
            "GpuRefine::new",
            GpuRefine::new(ctx, i.trees, c.batch_indirection),
        );
        let mut buffers = upload(ctx, c.selection);
        ok(
            "refine dispatch",
            gpu.dispatch(&mut buffers, c.camera, c.params),
        );
        let got = ok("read the refinement", gpu.read(&buffers));
        Refinement {
            selection: selection_of(got.selection),
            refined: Refined {
                indirection: got.indirection,
                trees_tested: u64::from(got.counters.trees_tested),
                trees_kept: u64::from(got.counters.trees_kept),
            },
        }
    }
}

impl Backend<FarBake> for GpuStage {
    fn run(&self, i: FarBakeInput<'_>) -> forestlod_shared::FarLevel {
        let p = i.prepared;
        let h = p
            .hierarchy
            .as_ref()
            .expect("a far level is baked over a hierarchy");
        let lists = crate::bridge::far_bake_vertices(p);
        let refs: Vec<&[forestlod_shared::far_bake::FarBakeVertex]> =
            lists.iter().map(Vec::as_slice).collect();
        let textures: Vec<&forestlod_reference::sampler::Texture> =
            p.mesh_textures.iter().collect();
        let mesh = ok(
            "mesh textures (cpu)",
            forestlod_gpu::upload_texture_array(
                self.ctx,
                "far bake mesh textures (cpu)",
                &crate::bridge::mip_levels(&textures),
            ),
        );
        let bake = ok("GpuFarBake::new", forestlod_gpu::GpuFarBake::new(self.ctx));
        ok("far bake", bake.far_bake(&h.nodes, &refs, &mesh, i.params))
    }
}

impl Backend<Pyramid> for GpuStage {
    fn run(&self, i: PyramidInput<'_>) -> Vec<f32> {
        ok(
            "the pyramid of a depth buffer",
            GpuPyramid::of_depth(self.ctx, i.depth, i.width, i.height),
        )
    }
}

impl Backend<Occlude> for GpuStage {
    fn run(&self, i: OccludeInput<'_>) -> Occluded {
        let ctx = self.ctx;
        let footprints: Vec<[f32; 4]> = i
            .footprints
            .iter()
            .map(|&(p, r)| [p[0], p[1], p[2], r])
            .collect();
        let mut gpu = ok("GpuOcclude::new", GpuOcclude::new(ctx, &footprints));
        let pyramid = ok(
            "GpuPyramid::new",
            GpuPyramid::new(ctx, i.camera.width, i.camera.height),
        );
        let buffers = upload(ctx, i.selection);
        let input = upload_storage(
            ctx,
            "occlude input",
            i.indirection,
            wgpu::BufferUsages::empty(),
        );
        let m = i.indirection.len() as u32;
        submit(ctx, "occlude", |e| {
            ok(
                "early split",
                gpu.encode_early(e, &buffers, &input, m, i.camera, i.params),
            );
            ok("pyramid", pyramid.encode_from_values(ctx, e, i.early_depth));
            ok(
                "late test",
                gpu.encode_late(e, &buffers, &pyramid, i.camera, i.params),
            );
        });
        let got = ok("read the occlusion", gpu.read(&buffers));
        Occluded {
            early: selection_of(got.early),
            late: selection_of(got.late),
            indirection: got.indirection,
            counters: got.counters,
            visible: got.visible,
        }
    }
}

impl Backend<Cull> for GpuStage {
    fn run(&self, i: CullCase<'_>) -> Culled {
        let trees = cull_trees_of(i.scene, i.spheres);
        let mut gpu = ok("GpuCull::new", GpuCull::new(self.ctx, &trees, i.meshes));
        ok("cull dispatch", gpu.dispatch(i.camera, i.params));
        let got = ok("read the culling", gpu.read());
        Culled {
            selection: selection_of(got.selection),
            indirection: got.indirection,
            draw_args: got.draw_args,
        }
    }
}

impl Backend<Primitive> for GpuStage {
    fn run(&self, i: FrameInput<'_>) -> Images {
        let (ctx, p) = (self.ctx, i.prepared);
        let data = DrawSceneData::new(p);
        let scene = ok("DrawScene::new", DrawScene::new(ctx, &data.desc(p)));
        drop(data);
        let proxies = GpuProxies::new(ctx, &proxy_records(p, i.params));
        // The reference's `cull` output: its visible trees and the arguments drawing them.
        let visible = visible_trees(
            &tree_spheres(&p.scene, &p.geometry.meshes),
            i.camera,
            i.params,
        );
        let indirection = upload_storage(
            ctx,
            "primitive visible trees (cpu)",
            &visible,
            wgpu::BufferUsages::empty(),
        );
        let draw_args = upload_storage(
            ctx,
            "primitive draw args (cpu)",
            &[primitive_args(visible.len())],
            wgpu::BufferUsages::INDIRECT,
        );
        let target = ok(
            "DrawTarget::new",
            DrawTarget::new(ctx, i.camera.width, i.camera.height),
        );
        let inputs = PrimitiveInputs {
            scene: &scene,
            proxies: &proxies,
            indirection: &indirection,
            draw_args: &draw_args,
        };
        let primitive = ok("compile primitive.wgsl", gpu_primitive(ctx));
        ok(
            "primitive render",
            primitive.render(ctx, &inputs, i.camera, i.params, &target),
        );
        Images::from(ok("read the frame", target.read(ctx)))
    }
}

/// One reference frame with every stage's input ready (module docs): the prepared scene, camera,
/// parameters and the reference's selection stages' outputs, kept.
pub struct FrameStages<'a> {
    /// The scene, prepared with `params`.
    pub prepared: &'a Prepared,
    /// The camera (valid).
    pub camera: &'a Camera,
    /// Parameters (valid).
    pub params: &'a Params,
    /// The reference's selection stages, every output kept.
    pub trace: SelectionTrace,
    /// Under hierarchical impostors (issue 33 item 2), the frame's impostor state: a path's
    /// first frame, as `Prepared::render` draws it; the selection stages read its far level.
    pub impostors: Option<forestlod_reference::impostor_cache::ImpostorCache>,
}

impl<'a> FrameStages<'a> {
    /// Runs the reference's selection stages of `params`' plan, keeping every output.
    pub fn new(prepared: &'a Prepared, camera: &'a Camera, params: &'a Params) -> Self {
        let impostors = ok_input(prepared.first_impostor_frame(camera, params)).map(|(c, _)| c);
        let far = impostors.as_ref().map(|c| c.level());
        Self {
            prepared,
            camera,
            params,
            trace: prepared.select_stages_on(far, camera, params, true),
            impostors,
        }
    }

    /// The frame's far level: the impostor state under impostors, else the prepared one.
    pub fn far_level(&self) -> Option<&forestlod_shared::FarLevel> {
        match &self.impostors {
            Some(c) => Some(c.level()),
            None => self.prepared.far.as_ref(),
        }
    }

    /// The coalesce and command-order modes of the plan, for a cut.
    fn cut_modes(&self) -> Option<(CoalesceMode, OrderMode)> {
        match self.trace.plan.selection {
            SelectionPlan::Cut {
                coalesce, order, ..
            } => Some((coalesce, order)),
            SelectionPlan::Flat => None,
        }
    }

    /// The GPU twin of `stage` run alone on the reference's input of it and judged against the
    /// reference ([`crate::stage::Judged`]); `None` when this frame's plan does not run the stage
    /// (a cut stage of a flat selection, `select` of a cut, `refine` with `tree_cull = none`).
    /// `textures` (bake, mips) and `draw` always run; the baselines (`cull`, `primitive`) read
    /// no selection and always run.
    pub fn check(&self, ctx: &'static GpuContext, stage: StageId) -> Option<StageCheck> {
        let (p, camera, params) = (self.prepared, self.camera, self.params);
        let g = &p.geometry;
        let gpu = GpuStage { ctx };
        let frame = FrameInput {
            prepared: p,
            camera,
            params,
        };
        let cut = self.trace.cut.as_ref();
        Some(match stage {
            StageId::Bake => {
                let input = BakeInput {
                    meshes: &p.scene.meshes,
                    angle_count: params.angle_count,
                    azimuth_count: params.azimuth_count,
                    sphere: params.billboard_views,
                    grid: params.octahedral_grid,
                    side: params.texture_size,
                    depth: forestlod_shared::depth_channel(params),
                };
                compare::<Bake>(&Reference, &GpuBakeBackend { bake: gpu_bake()? }, input)
            }
            StageId::Mips => {
                let input = MipsInput {
                    layers: &p.billboards.layers,
                    mode: params.mips().unwrap_or(MipMode::Box),
                    alpha_ref: params.alpha_cutoff,
                };
                compare::<Mips>(&Reference, &GpuMipsBackend { bake: gpu_bake()? }, input)
            }
            StageId::Select => {
                if self.trace.plan.is_cut() {
                    return None;
                }
                let input = SelectInput {
                    batches: &p.batches.metas,
                    scales: &p.batches.scales,
                    meshes: &g.meshes,
                    billboard: &g.billboard,
                    camera,
                    params,
                };
                let stable = GpuSelectBackend {
                    ctx,
                    option: Compaction::Stable,
                };
                compare::<Select>(&Reference, &stable, input)
            }
            StageId::HierSelect => {
                let input = HierSelectInput {
                    hierarchy: p.hierarchy.as_ref()?,
                    meshes: &g.meshes,
                    billboard: &g.billboard,
                    far: forestlod_reference::hier_select::FarCut::new(
                        self.far_level(),
                        g.far.first_index,
                        camera,
                        params,
                    ),
                    camera,
                    params,
                };
                compare::<HierSelect>(&Reference, &gpu, input)
            }
            StageId::Coalesce => {
                let (mode, _) = self.cut_modes()?;
                let input = CoalesceInput {
                    raw: &cut?.cut.selection,
                    mode,
                };
                compare::<Coalesce>(&Reference, &gpu, input)
            }
            StageId::CommandOrder => {
                let (coalesce, _) = self.cut_modes()?;
                let input = CommandOrderInput {
                    nodes: &p.hierarchy.as_ref()?.nodes,
                    raw: &cut?.cut.selection,
                    coalesced: cut?.coalesced.as_ref()?,
                    coalesce,
                    camera,
                    params,
                };
                compare::<CommandOrder>(&Reference, &gpu, input)
            }
            StageId::Refine => {
                self.trace.plan.refine?;
                let trees = cull_trees(p);
                let bands = tree_bands(&p.scene, &p.geometry.meshes, camera, params);
                let input = RefineInput {
                    case: RefineCase {
                        selection: self.trace.unrefined.as_ref()?,
                        batch_indirection: &p.batches.indirection,
                        spheres: &p.tree_spheres,
                        scales: &p.tree_scales,
                        bands: &bands,
                        camera,
                        params,
                    },
                    trees: &trees,
                };
                compare::<Refine>(&Reference, &gpu, input)
            }
            StageId::Pyramid | StageId::Occlude => {
                if self.trace.plan.occlusion == forestlod_shared::Occlusion::Off {
                    return None;
                }
                // The reference's frame with occlusion culling: its selection, indirection and
                // early depth (level 0 of its pyramid) are the stages' inputs.
                let f = ok_input(p.render(camera, params));
                let occ = f.occlusion.as_ref()?;
                let (w, h) = (camera.width, camera.height);
                let early_depth = &occ.pyramid.texels[..(w * h) as usize];
                if stage == StageId::Pyramid {
                    let input = PyramidInput {
                        depth: early_depth,
                        width: w,
                        height: h,
                    };
                    compare::<Pyramid>(&Reference, &gpu, input)
                } else {
                    let input = OccludeInput {
                        selection: &f.selection,
                        indirection: f.indirection(p),
                        footprints: &p.footprints,
                        camera,
                        params,
                        early_depth,
                    };
                    compare::<Occlude>(&Reference, &gpu, input)
                }
            }
            StageId::Draw => {
                let renderer = GpuRenderer {
                    ctx,
                    option: StagesFromCpu::ALL,
                };
                compare::<Draw>(&Reference, &renderer, frame)
            }
            StageId::Cull => {
                let spheres = tree_spheres(&p.scene, &g.meshes);
                let input = CullCase {
                    scene: &p.scene,
                    meshes: &g.meshes,
                    spheres: &spheres,
                    camera,
                    params,
                };
                compare::<Cull>(&Reference, &gpu, input)
            }
            StageId::Primitive => compare::<Primitive>(&Reference, &gpu, frame),
            StageId::FarBake => {
                self.trace.plan.far?;
                p.hierarchy.as_ref()?;
                compare::<FarBake>(
                    &Reference,
                    &gpu,
                    FarBakeInput {
                        prepared: p,
                        params,
                    },
                )
            }
        })
    }
}
