//! The reference-to-GPU bridge: a prepared scene's buffers, textures and trees converted to the
//! GPU drivers' types and uploaded. The GPU frame (`crate::gpu_frame`) and the stage backends use
//! it; nothing here runs a stage except [`gpu_textures`], which runs the GPU's bake and mips on
//! the scene's own meshes, as the reference's `prepare` runs its own.

use forestlod_gpu::command_order::OrderInputs;
use forestlod_gpu::draw::MipLevel;
use forestlod_gpu::readback::upload_storage;
use forestlod_gpu::{
    BakeMesh, CullTree, DrawInstance, DrawSceneDesc, DrawVertex, GpuBake, GpuBaked,
    GpuCommandOrder, GpuContext, GpuError, SelectBuffers, terrain_vertices_of,
    upload_texture_array,
};
use forestlod_reference::baselines::{proxies, tree_spheres};
use forestlod_reference::coalesce::run_offsets;
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::sampler::Texture;
use forestlod_reference::scene::Scene;
use forestlod_reference::select::Selection;
use forestlod_shared::{Coalesce, MeshMeta, NodeMeta, Params, ProxyRecord};

/// The draw stage's static inputs of a prepared scene, converted from the reference's types.
pub struct DrawSceneData {
    /// Packed vertices.
    pub vertices: Vec<DrawVertex>,
    /// Trees.
    pub instances: Vec<DrawInstance>,
    /// The ground, from the reference scene's terrain.
    pub terrain: Vec<forestlod_gpu::TerrainVertex>,
    /// The point LOD's records (issue 33, `forestlod_gpu::draw::point_words` of the prepared
    /// `PointLod`), empty without one.
    pub points: Vec<u32>,
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
            terrain: terrain_vertices_of(scene.ground_triangles()),
            points: prepared.points.as_ref().map_or_else(Vec::new, |p| {
                let sets: Vec<_> = p
                    .sets
                    .iter()
                    .map(|s| (s.records.as_slice(), s.cut_order.as_slice()))
                    .collect();
                forestlod_gpu::draw::point_words(&sets)
            }),
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
            far: prepared.far.as_ref(),
            points: &self.points,
            iota_first_index: prepared.geometry.far.first_index,
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

/// The textures a frame's draw samples: the mesh textures (one layer per mesh), the billboard
/// array and, under `octahedral_depth = on` (issue 32), the depth channel's array.
#[derive(Debug)]
pub struct SceneTextures {
    /// One layer per mesh, with mips.
    pub mesh: wgpu::Texture,
    /// The billboard array, with mips.
    pub billboards: wgpu::Texture,
    /// The octahedral impostors' depth channel, a layer per billboard layer, when baked.
    pub depth: Option<wgpu::Texture>,
}

impl SceneTextures {
    /// The draw's views of them.
    pub fn draw_textures(&self) -> Result<forestlod_gpu::DrawTextures, GpuError> {
        let textures = forestlod_gpu::DrawTextures::new(&self.mesh, &self.billboards)?;
        match &self.depth {
            Some(depth) => textures.with_depth(depth),
            None => Ok(textures),
        }
    }
}

/// Uploads the reference's mesh textures (one layer per mesh), billboard array and depth channel.
pub fn upload_reference_textures(
    ctx: &GpuContext,
    prepared: &Prepared,
) -> Result<SceneTextures, GpuError> {
    let meshes: Vec<&Texture> = prepared.mesh_textures.iter().collect();
    let mesh = upload_texture_array(ctx, "mesh textures (cpu)", &mip_levels(&meshes))?;
    let billboards = upload_texture_array(
        ctx,
        "billboards (cpu)",
        &mip_levels(&[&prepared.billboards.texture]),
    )?;
    let depth = match &prepared.billboards.depth {
        Some(d) => Some(upload_texture_array(
            ctx,
            "billboard depth (cpu)",
            &mip_levels(&[&d.texture]),
        )?),
        None => None,
    };
    Ok(SceneTextures {
        mesh,
        billboards,
        depth,
    })
}

/// The GPU's own textures for a prepared scene: the mesh textures' chains built by the GPU mips
/// stage (one layer per mesh; they must be square, of one power-of-two size) and the billboard
/// array baked and mipmapped by the GPU bake stage, both with `params`' mip mode and alpha
/// cutoff, as the reference's `prepare` builds its own.
pub fn gpu_textures(
    ctx: &GpuContext,
    prepared: &Prepared,
    params: &Params,
) -> Result<SceneTextures, GpuError> {
    gpu_textures_with(ctx, prepared, params, BillboardLevel0::Gpu)
}

/// Where the billboards' level 0 comes from in [`gpu_textures_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BillboardLevel0 {
    /// The GPU's bake (`bake.wgsl`).
    Gpu,
    /// The reference's bake as prepared (its billboard texture's level 0, which its mips never
    /// modify: `reference/src/mips.rs`), uploaded (`--stage-from-cpu bake`).
    Reference,
}

/// [`gpu_textures`] with the billboards' level 0 from `level0`; the mips of both arrays are
/// the GPU's.
pub fn gpu_textures_with(
    ctx: &GpuContext,
    prepared: &Prepared,
    params: &Params,
    level0: BillboardLevel0,
) -> Result<SceneTextures, GpuError> {
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
    let mesh_texels: Vec<&[[u8; 4]]> = scene.meshes.iter().map(|m| &m.texture.texels[..]).collect();
    let mesh_level0 = forestlod_gpu::mips::upload_level0(ctx, side, &mesh_texels)?;
    let mesh = bake
        .mips()
        .run(mesh_level0, mode, params.alpha_cutoff)?
        .texture;
    let baked = match level0 {
        BillboardLevel0::Gpu => {
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
            bake.bake(&meshes, params)?
        }
        BillboardLevel0::Reference => {
            let metas: Vec<MeshMeta> = scene.meshes.iter().map(|m| m.meta()).collect();
            let views = forestlod_shared::BillboardViews::of(params);
            let from_level0 = |t: &Texture| {
                let layers: Vec<&[[u8; 4]]> = (0..t.layer_count() as u32)
                    .map(|layer| &t.level(layer, 0).texels[..])
                    .collect();
                GpuBaked::from_cpu_level0(
                    bake.mips(),
                    &metas,
                    views,
                    params.texture_size,
                    &layers,
                    mode,
                    params.alpha_cutoff,
                )
            };
            let mut baked = from_level0(&prepared.billboards.texture)?;
            if let Some(d) = &prepared.billboards.depth {
                baked.depth = Some(from_level0(&d.texture)?.mips);
            }
            baked
        }
    };
    Ok(SceneTextures {
        mesh,
        billboards: baked.mips.texture,
        depth: baked.depth.map(|d| d.texture),
    })
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
            scale: t.scale,
        })
        .collect()
}

/// Every tree's footprint sphere `[x, y, z, radius]` (`Prepared::footprints`: its base and
/// `reference::draw::tree_footprint_radius`, computed on the CPU so both twins bound a tree by the
/// same `f32`s): the input of `GpuOcclude` (issue 31).
pub fn occlusion_footprints(prepared: &Prepared) -> Vec<[f32; 4]> {
    prepared
        .footprints
        .iter()
        .map(|&(p, r)| [p[0], p[1], p[2], r])
        .collect()
}

/// The reference's Primitive proxies of a prepared scene as GPU records (one per mesh).
pub fn proxy_records(prepared: &Prepared, params: &Params) -> Vec<ProxyRecord> {
    proxies(prepared, params.alpha_cutoff)
        .iter()
        .map(ProxyRecord::from)
        .collect()
}

/// The coalesced runs `runs` uploaded into buffers of `capacity` slots (at least theirs), as the
/// GPU's coalescing writes them into buffers of the raw cut's capacity: the command order's keys
/// pass visits every raw slot below the output's capacity, so its output buffers must be that
/// large (`gpu/src/command_order.rs`).
pub fn runs_in_capacity(ctx: &GpuContext, runs: &Selection, capacity: u32) -> SelectBuffers {
    let out = SelectBuffers::with_capacity(ctx, capacity.max(runs.commands.len() as u32));
    if !runs.commands.is_empty() {
        ctx.queue
            .write_buffer(&out.commands, 0, bytemuck::cast_slice(&runs.commands));
        ctx.queue
            .write_buffer(&out.data, 0, bytemuck::cast_slice(&runs.data));
    }
    ctx.queue
        .write_buffer(&out.counters, 0, bytemuck::bytes_of(&runs.counters));
    out
}

/// `command_order.wgsl` fed from the reference: the hierarchy's nodes, the raw cut, its
/// coalescing's run offsets ([`run_offsets`] under the coalesce mode) and the coalesced runs
/// ([`runs_in_capacity`], in buffers of the raw cut's capacity) uploaded, and the order bound to
/// them. It reorders `out` in place.
pub struct OrderFromCpu<'a> {
    /// The raw cut.
    pub raw: SelectBuffers,
    /// The coalesced runs, reordered in place by `order`.
    pub out: SelectBuffers,
    /// The coalescing's run offsets (kept alive with the order that reads them).
    pub offsets: wgpu::Buffer,
    /// The command order's driver.
    pub order: GpuCommandOrder<'a>,
}

impl<'a> OrderFromCpu<'a> {
    /// Uploads the reference's cut of `nodes` (`raw`) and its coalescing under `mode`
    /// (`coalesced`), and binds the order to them.
    pub fn new(
        ctx: &'a GpuContext,
        nodes: &[NodeMeta],
        raw: &Selection,
        coalesced: &Selection,
        mode: Coalesce,
    ) -> Result<Self, GpuError> {
        let nodes = upload_storage(ctx, "order nodes (cpu)", nodes, wgpu::BufferUsages::empty());
        let raw_buffers = SelectBuffers::from_cpu(ctx, &raw.commands, &raw.data, &raw.counters)?;
        let offsets = upload_storage(
            ctx,
            "order run offsets (cpu)",
            &run_offsets(raw, mode),
            wgpu::BufferUsages::empty(),
        );
        let out = runs_in_capacity(ctx, coalesced, raw_buffers.capacity);
        let order = GpuCommandOrder::new(
            ctx,
            OrderInputs {
                nodes: &nodes,
                raw: &raw_buffers,
                run_offsets: &offsets,
                out: &out,
            },
        )?;
        Ok(Self {
            raw: raw_buffers,
            out,
            offsets,
            order,
        })
    }
}

/// Per node of `prepared`'s hierarchy, the far bake's world-space triangle list of a leaf's
/// trees (`forestlod_reference::far_bake::placed_trees`, as the reference renders them), empty
/// for interior nodes: the GPU far bake's input (issue 32, `forestlod_gpu::far_bake`).
pub fn far_bake_vertices(
    prepared: &Prepared,
) -> Vec<Vec<forestlod_shared::far_bake::FarBakeVertex>> {
    let Some(h) = prepared.hierarchy.as_ref() else {
        return Vec::new();
    };
    (0..h.nodes.len())
        .map(|i| {
            if h.nodes[i].child_count > 0 {
                return Vec::new();
            }
            forestlod_reference::far_bake::placed_trees(h, &prepared.scene, &prepared.geometry, i)
                .iter()
                .flat_map(|t| {
                    t.triangles.iter().flat_map(move |tri| {
                        tri.iter().map(move |&(position, uv)| {
                            forestlod_shared::far_bake::FarBakeVertex {
                                position,
                                mesh: t.mesh,
                                uv,
                            }
                        })
                    })
                })
                .collect()
        })
        .collect()
}
