//! The GPU side of "one test body, several backends" (SPEC §8): the GPU backends of `select` and
//! `draw` ([`crate::stage::Backend`]), the reference-to-GPU bridge they and the CLI use, and the
//! sweeps' per-scene GPU runner.
//!
//! The GPU context is created once per test binary ([`gpu_context`]): device creation on lavapipe
//! costs about half a second, and proptest runs hundreds of cases.

use std::sync::OnceLock;

use forestlod_gpu::select::{
    DECISION_CULLED_DISTANCE, DECISION_CULLED_FRUSTUM, DECISION_DRAW, DECISION_KIND_MASK,
    DECISION_LOD0, DECISION_LOD1,
};
use forestlod_gpu::{Compaction, GpuContext, GpuSelect};
use forestlod_reference::select::{Decision, Selection};
use forestlod_shared::{Camera, LodNeeds, Params};

pub use crate::context::gpu_context;
use crate::stage::{Backend, Draw, FrameInput, Named, Select, SelectInput};
pub use crate::stage::{BackendSelection, images_of};

/// A GPU twin as a [`Backend`] of one stage, with the stage's option `O`: the compaction of
/// `select.wgsl` ([`GpuSelectBackend`]), or the stages the draw takes from the reference
/// ([`GpuRenderer`]).
pub struct GpuBackend<O> {
    /// The shared context.
    pub ctx: &'static GpuContext,
    /// The stage's option.
    pub option: O,
}

/// `select.wgsl` with one of its compactions: a [`Backend<Select>`].
pub type GpuSelectBackend = GpuBackend<Compaction>;

impl Named for GpuSelectBackend {
    fn name(&self) -> String {
        format!("gpu-{}", self.option.name())
    }
}

impl Backend<Select> for GpuSelectBackend {
    fn ordered(&self) -> bool {
        self.option == Compaction::Stable
    }
    fn run(&self, i: SelectInput<'_>) -> BackendSelection {
        let mut gpu =
            GpuSelect::new(self.ctx, i.batches, i.meshes, i.billboard).expect("GpuSelect::new");
        let out = gpu
            .run(i.camera, i.params, self.option)
            .expect("GpuSelect::run");
        let decisions = gpu
            .read_decisions()
            .expect("read decisions")
            .into_iter()
            .map(decode_decision)
            .collect();
        BackendSelection {
            selection: Selection {
                commands: out.commands,
                data: out.data,
                counters: out.counters,
            },
            decisions,
        }
    }
}

/// A GPU decision code (`forestlod_gpu::select::DECISION_*`) as the reference's [`Decision`].
pub fn decode_decision(code: u32) -> Decision {
    match code & DECISION_KIND_MASK {
        DECISION_CULLED_DISTANCE => Decision::CulledDistance,
        DECISION_CULLED_FRUSTUM => Decision::CulledFrustum,
        DECISION_DRAW => Decision::Draw(LodNeeds {
            lod0: code & DECISION_LOD0 != 0,
            lod1: code & DECISION_LOD1 != 0,
        }),
        other => panic!("GPU wrote an unknown decision kind {other} (code {code:#x})"),
    }
}

/// The GPU backends (stable and atomic compaction), empty when no adapter exists and
/// `FORESTLOD_ALLOW_NO_GPU=1`.
pub fn gpu_backends() -> Vec<GpuSelectBackend> {
    gpu_context()
        .map(|ctx| {
            Compaction::ALL
                .iter()
                .map(|&option| GpuSelectBackend { ctx, option })
                .collect()
        })
        .unwrap_or_default()
}

// ---------------------------------------------------------------------------------------------
// The draw stage (SPEC §5.5, §8): one frame rendered by the reference or by the GPU twin.

use forestlod_gpu::draw::{DrawCalls, DrawTarget, GpuDraw, MipLevel};
use forestlod_gpu::readback::upload_storage;
use forestlod_gpu::{
    BakeMesh, DrawInputs, DrawInstance, DrawScene, DrawSceneDesc, DrawTextures, DrawVertex,
    GpuBake, GpuError, GpuRefine, terrain_vertices, upload_texture_array,
};
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::refine::refine;
use forestlod_reference::sampler::Texture;
use forestlod_shared::TreeCull;

use crate::image_compare::Images;

/// Which GPU stages take their input from the reference twin instead of the GPU stage before
/// them (`forestlod render --stage-from-cpu select,textures`; vello's `force_gpu_from` is the
/// model). The draw stage itself always runs on the GPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StagesFromCpu {
    /// Draw the reference's selection (uploaded with `SelectBuffers::from_cpu`) instead of
    /// `select.wgsl`'s.
    pub select: bool,
    /// Sample the reference's mesh mips and billboard bake (uploaded with
    /// `upload_texture_array`) instead of the textures of the GPU mips (`mips.wgsl`, on the mesh
    /// textures) and bake (`bake.wgsl`, then `mips.wgsl`) stages.
    pub textures: bool,
}

impl StagesFromCpu {
    /// Every stage on the GPU.
    pub const NONE: Self = Self {
        select: false,
        textures: false,
    };
    /// Only the draw stage on the GPU: it alone is judged.
    pub const ALL: Self = Self {
        select: true,
        textures: true,
    };

    /// Parses a comma-separated list of `select`, `textures` (empty or `none`: nothing).
    pub fn parse(list: &str) -> Result<Self, String> {
        let mut out = Self::NONE;
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "select" => out.select = true,
                "textures" => out.textures = true,
                "none" => {}
                other => {
                    return Err(format!(
                        "unknown stage {other:?} in --stage-from-cpu {list:?}: expected a comma-separated list of select, textures (or none)"
                    ));
                }
            }
        }
        Ok(out)
    }

    /// The list form [`StagesFromCpu::parse`] reads, `none` when empty.
    pub fn name(self) -> String {
        let mut parts = Vec::new();
        if self.select {
            parts.push("select");
        }
        if self.textures {
            parts.push("textures");
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(",")
        }
    }
}

/// The reference frames with the alpha-test cutoff moved by each of
/// `±image_compare::ALPHA_TEST_SHIFTS`: the alternatives that classify threshold-ambiguous
/// pixels (`image_compare` module docs). Drawn together (`Prepared::render_cutoffs`: one
/// selection, one setup and one walk for all, each frame its own draw's bit for bit).
pub fn alpha_test_alternatives(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    let cutoffs: Vec<f32> = cutoff_shifted(params, |p| p.alpha_cutoff);
    prepared
        .render_cutoffs(camera, params, &cutoffs, None)
        .expect("reference render")
        .into_iter()
        .map(|drawn| moved_images(drawn.target))
        .collect()
}

/// [`alpha_test_alternatives`] drawn only at `pixels` (`image_compare::alternative_pixels` of
/// the two frames to compare; the rest of each alternative is sky and never read), the six
/// cutoffs sharing one selection and one setup (`Prepared::render_cutoffs`): the same comparison
/// for a fraction of one frame's cost. None at all when no pixel needs one.
pub fn alpha_test_alternatives_at(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
    pixels: &[bool],
) -> Vec<Images> {
    if !pixels.contains(&true) {
        return Vec::new();
    }
    let cutoffs: Vec<f32> = cutoff_shifted(params, |p| p.alpha_cutoff);
    prepared
        .render_cutoffs(camera, params, &cutoffs, Some(pixels.to_vec()))
        .expect("reference render")
        .into_iter()
        .map(|drawn| moved_images(drawn.target))
        .collect()
}

/// A target's buffers as [`Images`], moved, not copied.
fn moved_images(target: RenderTarget) -> Images {
    let (width, height) = (target.width(), target.height());
    let (color, depth, lod_id) = target.into_buffers();
    Images {
        width,
        height,
        color,
        depth,
        lod_id,
    }
}

/// `render` with the alpha-test cutoff moved by each of `±image_compare::ALPHA_TEST_SHIFTS`
/// (clamped to `0..=1`).
fn cutoff_shifted<T>(params: &Params, render: impl Fn(&Params) -> T) -> Vec<T> {
    crate::image_compare::ALPHA_TEST_SHIFTS
        .iter()
        .flat_map(|&d| [-d, d])
        .map(|d| {
            render(&Params {
                alpha_cutoff: (params.alpha_cutoff + d).clamp(0.0, 1.0),
                ..*params
            })
        })
        .collect()
}

/// What a GPU frame used and produced.
#[derive(Debug)]
pub struct GpuFrame {
    /// The buffers read back.
    pub images: Images,
    /// The CPU-side draw calls it recorded.
    pub calls: DrawCalls,
    /// Where its inputs came from.
    pub from_cpu: StagesFromCpu,
}

/// The draw stage's static inputs of a prepared scene, converted from the reference's types.
pub struct DrawSceneData {
    /// Packed vertices.
    pub vertices: Vec<DrawVertex>,
    /// Trees.
    pub instances: Vec<DrawInstance>,
    /// The ground, from the reference scene's terrain.
    pub terrain: Vec<forestlod_gpu::TerrainVertex>,
}

impl DrawSceneData {
    /// Converts the prepared scene's geometry, instances and terrain.
    pub fn new(prepared: &Prepared) -> Self {
        let scene = &prepared.scene;
        Self {
            vertices: prepared
                .geometry
                .vertices
                .iter()
                .map(|v| DrawVertex {
                    position: v.position,
                    uv: v.uv,
                })
                .collect(),
            instances: scene
                .instances
                .iter()
                .map(|t| DrawInstance {
                    position: t.position,
                    yaw: t.yaw,
                    scale: t.scale,
                    mesh: t.mesh,
                })
                .collect(),
            terrain: terrain_vertices(scene.bounds, |x, y| scene.terrain.height(x, y)),
        }
    }

    /// The descriptor [`DrawScene::new`] uploads.
    pub fn desc<'a>(&'a self, prepared: &'a Prepared) -> DrawSceneDesc<'a> {
        DrawSceneDesc {
            vertices: &self.vertices,
            indices: &prepared.geometry.indices,
            meshes: &prepared.geometry.meshes,
            billboard: prepared.geometry.billboard,
            instances: &self.instances,
            indirection: &prepared.batches.indirection,
            terrain: &self.terrain,
        }
    }
}

/// The layers of reference textures as [`MipLevel`]s: every layer of every texture, in order.
pub fn mip_levels<'a>(textures: &[&'a Texture]) -> Vec<Vec<MipLevel<'a>>> {
    textures
        .iter()
        .flat_map(|t| {
            (0..t.layer_count() as u32).map(move |layer| {
                (0..t.level_count())
                    .map(|level| {
                        let img = t.level(layer, level);
                        MipLevel {
                            width: img.width,
                            height: img.height,
                            texels: &img.texels,
                        }
                    })
                    .collect()
            })
        })
        .collect()
}

/// Uploads the reference's mesh textures (one layer per mesh) and billboard array.
pub fn upload_reference_textures(
    ctx: &GpuContext,
    prepared: &Prepared,
) -> Result<(wgpu::Texture, wgpu::Texture), GpuError> {
    let meshes: Vec<&Texture> = prepared.mesh_textures.iter().collect();
    let mesh = upload_texture_array(ctx, "mesh textures (cpu)", &mip_levels(&meshes))?;
    let billboards = upload_texture_array(
        ctx,
        "billboards (cpu)",
        &mip_levels(&[&prepared.billboards.texture]),
    )?;
    Ok((mesh, billboards))
}

/// The GPU's own textures for a prepared scene: the mesh textures' chains built by the GPU mips
/// stage (one layer per mesh; they must be square, of one power-of-two size) and the billboard
/// array baked and mipmapped by the GPU bake stage, both with `params`' mip mode and alpha
/// cutoff, as the reference's `prepare` builds its own.
pub fn gpu_textures(
    ctx: &GpuContext,
    prepared: &Prepared,
    params: &Params,
) -> Result<(wgpu::Texture, wgpu::Texture), GpuError> {
    let scene = &prepared.scene;
    let mode = params.mips().map_err(|e| GpuError::Input {
        field: "params.mip_mode",
        value: e.to_string(),
        reason: "expected a MipMode id",
    })?;
    let side = scene.meshes.first().map_or(0, |m| m.texture.width);
    if let Some(m) = scene
        .meshes
        .iter()
        .find(|m| m.texture.width != side || m.texture.height != side)
    {
        return Err(GpuError::Input {
            field: "mesh texture size",
            value: format!(
                "mesh {:?} is {}x{}, mesh 0 is {side}x{side}",
                m.name, m.texture.width, m.texture.height
            ),
            reason: "the GPU mips stage builds one square array: every mesh texture must have mesh 0's square size",
        });
    }
    let bake = GpuBake::new(ctx)?;
    let level0: Vec<&[[u8; 4]]> = scene.meshes.iter().map(|m| &m.texture.texels[..]).collect();
    let mesh_level0 = forestlod_gpu::mips::upload_level0(ctx, side, &level0)?;
    let mesh = bake
        .mips()
        .run(mesh_level0, mode, params.alpha_cutoff)?
        .texture;
    let meshes: Vec<BakeMesh> = scene
        .meshes
        .iter()
        .map(|m| BakeMesh {
            positions: &m.positions,
            uvs: &m.uvs,
            indices: &m.indices,
            texture_width: m.texture.width,
            texture_height: m.texture.height,
            texture: &m.texture.texels,
            meta: m.meta(),
        })
        .collect();
    let billboards = bake.bake(&meshes, params)?.mips.texture;
    Ok((mesh, billboards))
}

/// Renders one frame on the GPU, reading the buffers back: `select.wgsl` (stable compaction) or
/// the reference's selection, then, when `params.tree_cull` is not `none`, `refine.wgsl` on the
/// GPU's selection or the reference's `refine` on its own (its `3n` indirection uploaded), the
/// GPU stages' textures ([`gpu_textures`]) or the reference's, then `draw.wgsl`. `draw` holds the
/// compiled pipelines (see [`gpu_draw`]).
pub fn render_gpu(
    ctx: &GpuContext,
    draw: &GpuDraw,
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
    from_cpu: StagesFromCpu,
) -> Result<GpuFrame, GpuError> {
    let data = DrawSceneData::new(prepared);
    let scene = DrawScene::new(ctx, &data.desc(prepared))?;
    // The CPU copies are uploaded: free them before the frame (the main job's peak memory is
    // this frame's, issue 14).
    drop(data);
    let (mesh, billboards) = if from_cpu.textures {
        upload_reference_textures(ctx, prepared)?
    } else {
        gpu_textures(ctx, prepared, params)?
    };
    let textures = DrawTextures::new(&mesh, &billboards)?;
    let target = DrawTarget::new(ctx, camera.width, camera.height)?;
    let refining = params.tree_cull != TreeCull::None as u32;
    let mut gpu_select;
    let cpu_buffers;
    let mut gpu_refine;
    let cpu_indirection;
    let (selection, indirection) = if from_cpu.select {
        // The reference's selection, refined by the reference when `tree_cull` asks for it.
        let mut s = prepared.select(camera, params);
        let refined = refining.then(|| {
            refine(
                &mut s,
                &prepared.batches.indirection,
                &prepared.tree_spheres,
                camera,
                params,
            )
        });
        cpu_buffers =
            forestlod_gpu::SelectBuffers::from_cpu(ctx, &s.commands, &s.data, &s.counters)?;
        let indirection = match refined {
            Some(r) => {
                cpu_indirection = upload_storage(
                    ctx,
                    "refined indirection (cpu)",
                    &r.indirection,
                    wgpu::BufferUsages::empty(),
                );
                Some(&cpu_indirection)
            }
            None => None,
        };
        (&cpu_buffers, indirection)
    } else {
        gpu_select = OursSelect::new(ctx, prepared)?;
        gpu_select.dispatch(camera, params, Compaction::Stable)?;
        let indirection = if refining {
            gpu_refine = GpuRefine::new(ctx, &cull_trees(prepared), &prepared.batches.indirection)?;
            gpu_refine.dispatch(gpu_select.buffers_mut(), camera, params)?;
            Some(gpu_refine.indirection())
        } else {
            None
        };
        (gpu_select.buffers(), indirection)
    };
    let inputs = DrawInputs {
        scene: &scene,
        textures: &textures,
        selection,
        indirection,
    };
    let calls = draw.render(ctx, &inputs, camera, params, &target)?;
    let out = target.read(ctx)?;
    Ok(GpuFrame {
        images: Images::from(out),
        calls,
        from_cpu,
    })
}

/// Our selection stage on the GPU for a prepared scene: `select.wgsl` over the batches, or
/// `hier_select.wgsl` over the hierarchy when the scene was prepared with one (issue 13). Both
/// write a [`forestlod_gpu::SelectBuffers`] that `refine` and the draw stage read.
pub enum OursSelect<'a> {
    /// Flat selection over the grid batches.
    Flat(GpuSelect<'a>),
    /// The hierarchical cut (always the stable order: it has no atomic compaction).
    Hier(forestlod_gpu::GpuHierSelect<'a>),
}

impl<'a> OursSelect<'a> {
    /// Uploads the prepared scene's batches or hierarchy.
    pub fn new(ctx: &'a GpuContext, prepared: &Prepared) -> Result<Self, GpuError> {
        let g = &prepared.geometry;
        Ok(match &prepared.hierarchy {
            Some(h) => OursSelect::Hier(forestlod_gpu::GpuHierSelect::new(
                ctx,
                &h.nodes,
                h.mode as u32,
                &g.meshes,
                &g.billboard,
            )?),
            None => OursSelect::Flat(GpuSelect::new(
                ctx,
                &prepared.batches.metas,
                &g.meshes,
                &g.billboard,
            )?),
        })
    }

    /// Records one frame's selection (`compaction` applies to the flat selection only).
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) {
        match self {
            OursSelect::Flat(s) => s.encode(encoder, camera, params, compaction),
            OursSelect::Hier(s) => s.encode(encoder, camera, params),
        }
    }

    /// Runs one frame's selection, leaving the commands on the GPU.
    pub fn dispatch(
        &mut self,
        camera: &Camera,
        params: &Params,
        compaction: Compaction,
    ) -> Result<&forestlod_gpu::SelectBuffers, GpuError> {
        match self {
            OursSelect::Flat(s) => s.dispatch(camera, params, compaction),
            OursSelect::Hier(s) => s.dispatch(camera, params),
        }
    }

    /// The output buffers.
    pub fn buffers(&self) -> &forestlod_gpu::SelectBuffers {
        match self {
            OursSelect::Flat(s) => s.buffers(),
            OursSelect::Hier(s) => s.buffers(),
        }
    }

    /// The output buffers, for `refine` to rewrite in place.
    pub fn buffers_mut(&mut self) -> &mut forestlod_gpu::SelectBuffers {
        match self {
            OursSelect::Flat(s) => s.buffers_mut(),
            OursSelect::Hier(s) => s.buffers_mut(),
        }
    }
}

/// The draw pipelines of this test binary's context (compiled once).
pub fn gpu_draw(ctx: &'static GpuContext) -> &'static GpuDraw {
    static DRAW: OnceLock<GpuDraw> = OnceLock::new();
    DRAW.get_or_init(|| GpuDraw::new(ctx).expect("GpuDraw::new"))
}

/// `draw.wgsl` fed by the chosen stages (which inputs come from the reference): a
/// [`Backend<Draw>`].
pub type GpuRenderer = GpuBackend<StagesFromCpu>;

impl Named for GpuRenderer {
    fn name(&self) -> String {
        format!("gpu(from-cpu: {})", self.option.name())
    }
}

impl Backend<Draw> for GpuRenderer {
    fn run(&self, i: FrameInput<'_>) -> Images {
        render_gpu(
            self.ctx,
            gpu_draw(self.ctx),
            i.prepared,
            i.camera,
            i.params,
            self.option,
        )
        .unwrap_or_else(|e| panic!("{}: {e}", self.name()))
        .images
    }
}

// ---------------------------------------------------------------------------------------------
// The sweeps' per-scene GPU runner (E§5; SPEC §9): our pipeline and both baselines on one
// scene, everything uploaded once, each frame timed stage by stage.

use std::collections::HashMap;
use std::time::Instant;

use forestlod_gpu::readback::read_buffer;
use forestlod_gpu::{CullTree, GpuCull, GpuPrimitive, GpuProxies, PrimitiveInputs};
use forestlod_reference::baselines::{
    Proxy, proxies, render_primitive_shifted, render_vegetation, tree_spheres,
};
use forestlod_reference::raster::RenderTarget;
use forestlod_reference::scene::Scene;
use forestlod_shared::{ProxyRecord, SelectCounters};

/// The reference Vegetation frames with the alpha-test cutoff moved by each of
/// `±image_compare::ALPHA_TEST_SHIFTS` ([`alpha_test_alternatives`] for Vegetation).
pub fn vegetation_alternatives(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    cutoff_shifted(params, |p| {
        images_of(&render_vegetation(prepared, spheres, camera, p).target)
    })
}

/// The reference Primitive frames with the ray cast's root tests moved by each of
/// `±image_compare::PRIMITIVE_DISC_SHIFTS` roundings (`Proxy::intersect`): the
/// alternatives that classify the pixels a rounding of the discriminant decides.
pub fn primitive_alternatives(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    proxies: &[Proxy],
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    crate::image_compare::PRIMITIVE_DISC_SHIFTS
        .iter()
        .flat_map(|&d| [-d, d])
        .map(|d| {
            images_of(
                &render_primitive_shifted(prepared, spheres, proxies, camera, params, d).target,
            )
        })
        .collect()
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

/// Every tree's bounding sphere (`baselines::tree_spheres`, computed on the CPU) and mesh: the
/// input of [`GpuCull`].
pub fn cull_trees(prepared: &Prepared) -> Vec<CullTree> {
    let spheres = tree_spheres(&prepared.scene, &prepared.geometry.meshes);
    cull_trees_of(&prepared.scene, &spheres)
}

/// The [`GpuCull`] / `GpuRefine` input of `scene`'s trees from their bounding spheres (as
/// `baselines::tree_spheres` computes them, one per instance).
pub fn cull_trees_of(scene: &Scene, spheres: &[([f32; 3], f32)]) -> Vec<CullTree> {
    spheres
        .iter()
        .zip(&scene.instances)
        .map(|(&(center, radius), t)| CullTree {
            center,
            radius,
            mesh: t.mesh,
        })
        .collect()
}

/// The reference's Primitive proxies of a prepared scene as GPU records (one per mesh).
pub fn proxy_records(prepared: &Prepared, params: &Params) -> Vec<ProxyRecord> {
    proxies(prepared, params.alpha_cutoff)
        .iter()
        .map(ProxyRecord::from)
        .collect()
}

/// Which pipeline a [`GpuSweepScene`] renders (E§5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GpuVariant {
    /// Ours: `select.wgsl` with this compaction, then `draw.wgsl`.
    Ours(forestlod_gpu::Compaction),
    /// Every visible tree as a full mesh: `cull.wgsl`, then `draw.wgsl` on its compacted list.
    Vegetation,
    /// One ray-cast proxy quad per visible tree: `cull.wgsl`, then `primitive.wgsl`.
    Primitive,
}

impl GpuVariant {
    /// Name for reports and CSVs: `ours-stable`, `ours-atomic`, `vegetation`, `primitive`.
    pub fn name(self) -> String {
        match self {
            GpuVariant::Ours(c) => format!("ours-{}", c.name()),
            GpuVariant::Vegetation => "vegetation".into(),
            GpuVariant::Primitive => "primitive".into(),
        }
    }
}

/// One frame of a [`GpuSweepScene`], timed.
#[derive(Clone, Debug)]
pub struct GpuTimedFrame {
    /// Colour, depth and LOD id, read back (as [`render_gpu`] returns them).
    pub images: Images,
    /// Wall seconds from submit to completion (`ctx.wait`) of selection (ours, with `refine`
    /// when `params.tree_cull` asks for it) or culling (baselines).
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
}

/// Timestamp queries around the two stages of a frame (as `experiments/src/bin/gpu_bench.rs`:
/// empty compute passes that write a timestamp at their beginning).
struct Timestamps {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
}

impl Timestamps {
    const COUNT: u32 = 4;

    fn new(ctx: &GpuContext) -> Option<Self> {
        if !ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        Some(Self {
            queries: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("sweep timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: Self::COUNT,
            }),
            resolve: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("sweep timestamp resolve"),
                size: 8 * Self::COUNT as u64,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
        })
    }

    fn mark(&self, encoder: &mut wgpu::CommandEncoder, index: u32) {
        encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &self.queries,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            }),
        });
    }
}

/// One prepared scene on the GPU for the sweeps: the draw buffers, the GPU-built textures
/// ([`gpu_textures`], with the parameters' mip mode), our selection ([`GpuSelect`]) and its
/// per-tree refinement ([`GpuRefine`], run when `params.tree_cull` asks for it), the baselines'
/// per-tree culling ([`GpuCull`]) and proxies, and a render target per viewport size.
/// [`GpuSweepScene::new`] uploads everything once; [`GpuSweepScene::render`] only records, submits
/// and reads back one frame.
pub struct GpuSweepScene {
    ctx: &'static GpuContext,
    scene: DrawScene,
    textures: DrawTextures,
    select: OursSelect<'static>,
    refine: GpuRefine<'static>,
    cull: GpuCull<'static>,
    proxies: GpuProxies,
    draw: &'static GpuDraw,
    primitive: &'static GpuPrimitive,
    targets: HashMap<(u32, u32), DrawTarget>,
    timestamps: Option<Timestamps>,
}

impl GpuSweepScene {
    /// Uploads `prepared` (prepared with `params`; the textures are built by the GPU stages with
    /// `params`' mip mode and alpha cutoff, the Primitive proxies are the reference's).
    pub fn new(
        ctx: &'static GpuContext,
        prepared: &Prepared,
        params: &Params,
    ) -> Result<Self, GpuError> {
        let data = DrawSceneData::new(prepared);
        let scene = DrawScene::new(ctx, &data.desc(prepared))?;
        let (mesh, billboards) = gpu_textures(ctx, prepared, params)?;
        let textures = DrawTextures::new(&mesh, &billboards)?;
        let select = OursSelect::new(ctx, prepared)?;
        let trees = cull_trees(prepared);
        let refine = GpuRefine::new(ctx, &trees, &prepared.batches.indirection)?;
        let cull = GpuCull::new(ctx, &trees, &prepared.geometry.meshes)?;
        let proxies = GpuProxies::new(ctx, &proxy_records(prepared, params));
        Ok(Self {
            ctx,
            scene,
            textures,
            select,
            refine,
            cull,
            proxies,
            draw: try_gpu_draw(ctx)?,
            primitive: gpu_primitive(ctx)?,
            targets: HashMap::new(),
            timestamps: Timestamps::new(ctx),
        })
    }

    /// The baselines' culling (for tests: `GpuCull::read` after a baseline frame).
    pub fn cull(&self) -> &GpuCull<'static> {
        &self.cull
    }

    /// Our selection's buffers (for tests: `SelectBuffers::read` after a frame of ours; refined
    /// in place when `params.tree_cull` was not `none`).
    pub fn selection(&self) -> &forestlod_gpu::SelectBuffers {
        self.select.buffers()
    }

    /// Our per-tree refinement (for tests: `GpuRefine::read` after a frame of ours with
    /// `params.tree_cull` not `none`).
    pub fn refine(&self) -> &GpuRefine<'static> {
        &self.refine
    }

    /// Renders one frame of `variant`: stage 1 (selection or culling; for ours with
    /// `params.tree_cull` not `none`, selection then `refine.wgsl`, in the same submit) and
    /// stage 2 (the draw pass, of the refined commands and indirection where refined) are
    /// recorded, submitted and waited for separately, each timed from submit to completion; then
    /// the counters and the target are read back. `params` must be what the scene was prepared
    /// with, apart from the per-frame fields (fade, distances, LOD levels, tree culling).
    pub fn render(
        &mut self,
        variant: GpuVariant,
        camera: &Camera,
        params: &Params,
    ) -> Result<GpuTimedFrame, GpuError> {
        camera.validate().map_err(|e| GpuError::Input {
            field: "camera",
            value: e.to_string(),
            reason: "expected a valid camera (Camera::validate)",
        })?;
        params.validate().map_err(|e| GpuError::Input {
            field: "params",
            value: e.to_string(),
            reason: "expected valid parameters (Params::validate)",
        })?;
        let key = (camera.width, camera.height);
        if !self.targets.contains_key(&key) {
            let target = DrawTarget::new(self.ctx, camera.width, camera.height)?;
            self.targets.insert(key, target);
        }
        let ctx = self.ctx;
        let refining = params.tree_cull != TreeCull::None as u32;
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

        // Stage 1: selection or culling.
        let encoder = ctx.checked("sweep select/cull", || {
            let mut encoder = begin("sweep select", 0);
            match variant {
                GpuVariant::Ours(compaction) => {
                    self.select.encode(&mut encoder, camera, params, compaction);
                    if refining {
                        self.refine
                            .encode(&mut encoder, self.select.buffers_mut(), camera, params);
                    }
                }
                GpuVariant::Vegetation | GpuVariant::Primitive => {
                    self.cull.encode(&mut encoder, camera, params)
                }
            }
            if let Some(s) = stamps {
                s.mark(&mut encoder, 1);
            }
            encoder
        })?;
        let select_s = submit_timed(encoder)?;

        // Stage 2: the draw pass.
        let encoder = ctx.checked("sweep draw", || -> Result<_, GpuError> {
            let mut encoder = begin("sweep draw", 2);
            match variant {
                GpuVariant::Ours(_) | GpuVariant::Vegetation => {
                    let inputs = match variant {
                        GpuVariant::Ours(_) => DrawInputs {
                            scene: &self.scene,
                            textures: &self.textures,
                            selection: self.select.buffers(),
                            indirection: refining.then(|| self.refine.indirection()),
                        },
                        _ => DrawInputs {
                            scene: &self.scene,
                            textures: &self.textures,
                            selection: self.cull.buffers(),
                            indirection: Some(self.cull.indirection()),
                        },
                    };
                    self.draw
                        .encode(ctx, &mut encoder, &inputs, camera, params, target)?;
                }
                GpuVariant::Primitive => {
                    let inputs = PrimitiveInputs {
                        scene: &self.scene,
                        proxies: &self.proxies,
                        indirection: self.cull.indirection(),
                        draw_args: self.cull.draw_args(),
                    };
                    self.primitive
                        .encode(ctx, &mut encoder, &inputs, camera, params, target)?;
                }
            }
            if let Some(s) = stamps {
                s.mark(&mut encoder, 3);
                encoder.resolve_query_set(&s.queries, 0..Timestamps::COUNT, &s.resolve, 0);
            }
            Ok(encoder)
        })??;
        let draw_s = submit_timed(encoder)?;

        // Readback (not timed).
        let (gpu_select_s, gpu_draw_s) = match stamps {
            Some(s) => {
                let ticks: Vec<u64> = read_buffer(ctx, &s.resolve, 0, Timestamps::COUNT as usize)?;
                let period_s = ctx.queue.get_timestamp_period() as f64 * 1e-9;
                (
                    Some(ticks[1].saturating_sub(ticks[0]) as f64 * period_s),
                    Some(ticks[3].saturating_sub(ticks[2]) as f64 * period_s),
                )
            }
            None => (None, None),
        };
        let counters_buffer = match variant {
            GpuVariant::Ours(_) => &self.select.buffers().counters,
            _ => &self.cull.buffers().counters,
        };
        let counters = read_buffer::<SelectCounters>(ctx, counters_buffer, 0, 1)?[0];
        let (commands, trees_drawn) = match variant {
            GpuVariant::Ours(_) => (counters.commands as u64, None),
            GpuVariant::Vegetation => (counters.commands as u64, Some(counters.instances as u64)),
            GpuVariant::Primitive => (
                (counters.instances > 0) as u64,
                Some(counters.instances as u64),
            ),
        };
        let out = target.read(ctx)?;
        Ok(GpuTimedFrame {
            images: Images::from(out),
            select_s,
            draw_s,
            gpu_select_s,
            gpu_draw_s,
            commands,
            trees_drawn,
        })
    }
}
