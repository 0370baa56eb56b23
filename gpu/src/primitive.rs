//! The *Primitive* baseline of E§5 (SPEC §9) on the GPU: the driver of `shaders/primitive.wgsl`,
//! twin of the reference's `baselines::render_primitive`.
//!
//! ## Contract
//! One render pass into a [`DrawTarget`], cleared exactly as [`crate::GpuDraw`] clears it (sky,
//! depth 1, LOD id background), then:
//! 1. the ground, drawn by `draw.wgsl`'s own terrain entry points (the same pipeline
//!    description as `GpuDraw`'s, bound to a layout holding only the `DrawUniform` they read), so
//!    the ground is the same ground;
//! 2. the quads, with **one** `draw_indirect` whose arguments `GpuCull` wrote (`{6, visible
//!    trees, 0, 0}`): the vertex stage takes tree `indirection[instance_index]` from the cull's
//!    compacted list and places the camera-facing quad of the reference's `primitive_quad`
//!    (including the full-screen fallback at `NEAR_FALLBACK_DEPTH · near` for a proxy within
//!    [`NEAR_FALLBACK_FACTOR`] near-plane distances); the fragment stage ray-casts the proxy
//!    (`Proxy::intersect`, same operations in the same order), discards misses and hits past the
//!    far plane, and writes depth `far (t - near) / ((far - near) t)` through
//!    `@builtin(frag_depth)` (the `gl_FragDepth` E§5 blames for Primitive's cost), the mesh's flat
//!    linear colour (encoded to sRGB by the target) and [`LOD_ID_MESH`](crate::draw::LOD_ID_MESH).
//!
//! The per-mesh proxies are the reference's, uploaded once ([`GpuProxies`], one
//! [`ProxyRecord`] per mesh); the camera constants of `primitive_quad` that need `tan` are
//! derived on the CPU ([`PrimitiveUniform::new`]), so the GPU evaluates only the per-tree and
//! per-fragment arithmetic.
//!
//! ## Where the GPU may differ (judged by `tests/tests/parity/baselines.rs`)
//! The world position on the quad is interpolated by the rasterizer (`f32` plane equations on
//! lavapipe, `f64` barycentrics in the reference), so each fragment's ray direction differs in
//! the last bits; the ray cast's `t`, and so the depth, follows it, which matters only where the
//! discriminant is near 0 (a proxy's silhouette, an edge pixel) and adds a few ulp elsewhere.
//! Far from the eye the discriminant `b·b - a·(|o|² - r²)` cancels catastrophically (a 0.34 m
//! trunk 700 m away is 2 ulp of `b·b`), so whether a pixel hits a distant trunk is decided by
//! rounding, and the GPU may fuse multiply-adds; the tests classify those pixels with reference
//! frames whose root tests are moved by a few roundings (`Proxy::intersect`, its `disc_shift`). The
//! depth test runs after the shader on the GPU (the shader writes depth) and before and after it
//! in the reference (its early test uses the quad's depth, which never exceeds the ray-cast one),
//! which keeps and drops the same fragments.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use forestlod_shared::{Camera, Params, ProxyRecord};

use crate::context::{
    StagePipelines, buffer_bind_group, buffer_entry, group_layout, shader_module,
};
use crate::draw::{
    DrawScene, DrawTarget, DrawUniform, begin_target_pass, target_pipeline, terrain_pipeline,
};
use crate::readback::{frame_uniform, upload_storage};
use crate::shaders::{StageSource, WgslFile};
use crate::{GpuContext, GpuError};

/// The `primitive` stage's module: `primitive.wgsl` (it reads only shared constants; its ground is `draw.wgsl`, [`crate::draw::SOURCE`]).
pub const SOURCE: StageSource = StageSource {
    own: WgslFile {
        name: "primitive.wgsl",
        wgsl: include_str!("shaders/primitive.wgsl"),
        constants: &[],
    },
    parts: &[],
};

/// A proxy whose bounding sphere comes nearer the eye than this many near-plane distances gets a
/// full-screen quad. Keep in sync with `reference::baselines::NEAR_FALLBACK_FACTOR`.
pub const NEAR_FALLBACK_FACTOR: f32 = 2.0;
/// Depth of the full-screen quad in near-plane distances. Keep in sync with
/// `reference::baselines::NEAR_FALLBACK_DEPTH`.
pub const NEAR_FALLBACK_DEPTH: f32 = 1.001;
/// Margin of the full-screen quad over the view. Keep in sync with
/// `reference::baselines::NEAR_FALLBACK_MARGIN`.
pub const NEAR_FALLBACK_MARGIN: f32 = 1.1;
/// Widening of a proxy's bounding sphere. Keep in sync with
/// `reference::baselines::PROXY_BOUND_SCALE`.
pub const PROXY_BOUND_SCALE: f32 = 1.0 + 1e-5;
/// Vertices of one quad (two triangles, non-indexed).
pub const QUAD_VERTICES: u32 = 6;

/// The per-frame uniform of `primitive.wgsl`. Keep in sync with `struct PrimitiveUniform` there
/// (layout checked by this module's tests).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PrimitiveUniform {
    /// `projection * view`, column-major.
    pub view_proj: [[f32; 4]; 4],
    /// Eye position.
    pub eye: [f32; 3],
    /// Near plane distance.
    pub near: f32,
    /// Unit view direction (`Camera::basis().forward`).
    pub forward: [f32; 3],
    /// Far plane distance.
    pub far: f32,
    /// Unit right vector of the basis.
    pub right: [f32; 3],
    /// `NEAR_FALLBACK_FACTOR * near`.
    pub fallback_distance: f32,
    /// Unit up vector of the basis.
    pub up: [f32; 3],
    /// `near * NEAR_FALLBACK_DEPTH`.
    pub fallback_depth: f32,
    /// Half-width of the full-screen quad.
    pub fallback_half_x: f32,
    /// Half-height of the full-screen quad.
    pub fallback_half_y: f32,
    /// [`PROXY_BOUND_SCALE`].
    pub bound_scale: f32,
    /// Explicit padding.
    pub _pad0: u32,
}
const _: () = assert!(size_of::<PrimitiveUniform>() == 144);

impl PrimitiveUniform {
    /// The uniform of a validated camera, with the reference's `primitive_quad` fallback constants
    /// computed as it computes them.
    pub fn new(camera: &Camera) -> Self {
        let b = camera.basis();
        let d_q = camera.near * NEAR_FALLBACK_DEPTH;
        let ty = (camera.fov_y * 0.5).tan() * d_q * NEAR_FALLBACK_MARGIN;
        Self {
            view_proj: camera.view_projection().to_cols_array_2d(),
            eye: camera.eye,
            near: camera.near,
            forward: b.forward.to_array(),
            far: camera.far,
            right: b.right.to_array(),
            fallback_distance: NEAR_FALLBACK_FACTOR * camera.near,
            up: b.up.to_array(),
            fallback_depth: d_q,
            fallback_half_x: ty * camera.aspect(),
            fallback_half_y: ty,
            bound_scale: PROXY_BOUND_SCALE,
            _pad0: 0,
        }
    }
}

/// One [`ProxyRecord`] per mesh on the GPU.
#[derive(Debug)]
pub struct GpuProxies {
    buffer: wgpu::Buffer,
    count: u32,
}

impl GpuProxies {
    /// Uploads the proxies, in mesh order.
    pub fn new(ctx: &GpuContext, proxies: &[ProxyRecord]) -> Self {
        Self {
            buffer: upload_storage(
                ctx,
                "primitive proxies",
                proxies,
                wgpu::BufferUsages::empty(),
            ),
            count: proxies.len() as u32,
        }
    }

    /// Number of proxies.
    pub fn len(&self) -> u32 {
        self.count
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

/// Everything one Primitive frame reads.
#[derive(Clone, Copy, Debug)]
pub struct PrimitiveInputs<'a> {
    /// Static scene buffers (instances and the ground).
    pub scene: &'a DrawScene,
    /// One proxy per mesh.
    pub proxies: &'a GpuProxies,
    /// The visible trees, compacted (`GpuCull::indirection`).
    pub indirection: &'a wgpu::Buffer,
    /// `DrawIndirectArgs {6, visible trees, 0, 0}` (`GpuCull::draw_args`), `INDIRECT` usage.
    pub draw_args: &'a wgpu::Buffer,
}

/// The compiled Primitive pipelines, one set per [`GpuContext`] (cached there).
#[derive(Debug)]
pub struct PrimitivePipelines {
    layout: wgpu::BindGroupLayout,
    terrain_layout: wgpu::BindGroupLayout,
    quads: wgpu::RenderPipeline,
    terrain: wgpu::RenderPipeline,
}

/// The Primitive baseline's draw on one device: the context's [`PrimitivePipelines`]. Holds no
/// per-frame state (`&self`, `Sync`).
#[derive(Debug)]
pub struct GpuPrimitive {
    pipelines: Arc<PrimitivePipelines>,
}

impl GpuPrimitive {
    /// Takes the context's compiled `primitive.wgsl` pipelines (compiling them on first use).
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        Ok(Self {
            pipelines: ctx.pipelines::<PrimitivePipelines>()?,
        })
    }
}

impl StagePipelines for PrimitivePipelines {
    /// Compiles `primitive.wgsl` and the ground of `draw.wgsl`.
    fn create(ctx: &GpuContext) -> Result<Self, GpuError> {
        ctx.checked("primitive.wgsl pipelines", || {
            let device = &ctx.device;
            let module = shader_module(device, "primitive.wgsl", &SOURCE.module());
            let draw_module =
                shader_module(device, "draw.wgsl (terrain)", &crate::draw::SOURCE.module());
            use wgpu::ShaderStages as S;
            let storage = wgpu::BufferBindingType::Storage { read_only: true };
            let uniform = |size| {
                buffer_entry(
                    0,
                    S::VERTEX_FRAGMENT,
                    wgpu::BufferBindingType::Uniform,
                    size,
                )
            };
            let (layout, quad_layout) = group_layout(
                device,
                "primitive",
                &[
                    uniform(size_of::<PrimitiveUniform>() as u64),
                    buffer_entry(1, S::VERTEX_FRAGMENT, storage, 0),
                    buffer_entry(2, S::VERTEX, storage, 0),
                    buffer_entry(3, S::VERTEX_FRAGMENT, storage, 0),
                ],
            );
            // The terrain entry points of draw.wgsl read only binding 0, its DrawUniform.
            let (terrain_layout, terrain_pipeline_layout) = group_layout(
                device,
                "primitive terrain",
                &[uniform(size_of::<DrawUniform>() as u64)],
            );
            let terrain = terrain_pipeline(device, &draw_module, &terrain_pipeline_layout);
            let quads = target_pipeline(
                device,
                "primitive quads",
                &quad_layout,
                &module,
                ("primitive_vertex", "primitive_fragment"),
                &[],
                None,
            );
            Self {
                layout,
                terrain_layout,
                quads,
                terrain,
            }
        })
    }
}

impl GpuPrimitive {
    /// Records one frame's pass into `encoder` (its uniforms are fresh buffers of this call,
    /// [`frame_uniform`], so threads sharing one `GpuPrimitive` never mix cameras): clear, ground, then every visible tree's quad with one
    /// `draw_indirect`. `camera` and `params` should be validated. Errors: fewer proxies than the
    /// scene has meshes.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &PrimitiveInputs,
        camera: &Camera,
        params: &Params,
        target: &DrawTarget,
    ) -> Result<(), GpuError> {
        let PrimitiveInputs {
            scene,
            proxies,
            indirection,
            draw_args,
        } = *inputs;
        if proxies.len() < scene.mesh_count() {
            return Err(GpuError::Input {
                field: "primitive proxies",
                value: format!(
                    "{} proxies for {} meshes",
                    proxies.len(),
                    scene.mesh_count()
                ),
                reason: "expected one proxy per mesh",
            });
        }
        let uniform = frame_uniform(ctx, "primitive uniform", &PrimitiveUniform::new(camera));
        let terrain_uniform = scene.draw_uniform(ctx, "primitive terrain uniform", camera, params);
        let bind_group = buffer_bind_group(
            &ctx.device,
            "primitive",
            &self.pipelines.layout,
            &[&uniform, &scene.instances, indirection, &proxies.buffer],
        );
        let terrain_group = buffer_bind_group(
            &ctx.device,
            "primitive terrain",
            &self.pipelines.terrain_layout,
            &[&terrain_uniform],
        );
        let mut pass = begin_target_pass(encoder, target, "primitive");
        pass.set_pipeline(&self.pipelines.terrain);
        pass.set_bind_group(0, &terrain_group, &[]);
        pass.set_vertex_buffer(0, scene.terrain.slice(..));
        pass.draw(0..scene.terrain_vertex_count, 0..1);
        pass.set_pipeline(&self.pipelines.quads);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.draw_indirect(draw_args, 0);
        Ok(())
    }

    /// Records and submits one frame (does not wait; read the target to wait).
    pub fn render(
        &self,
        ctx: &GpuContext,
        inputs: &PrimitiveInputs,
        camera: &Camera,
        params: &Params,
        target: &DrawTarget,
    ) -> Result<(), GpuError> {
        ctx.checked("primitive pass", || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("primitive"),
                });
            self.encode(ctx, &mut encoder, inputs, camera, params, target)?;
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw::LOD_ID_MESH;
    use crate::draw::tests::draw_instance_layout;
    use crate::wgsl_layout::{assert_layout, rust_layout, validate};

    /// `PrimitiveUniform` and `DrawInstance` have their WGSL twins' layout in `primitive.wgsl`
    /// (naga reflection, which also validates the module; `ProxyRecord` is checked with the
    /// shared records in `gpu/tests/layout.rs`).
    #[test]
    fn wgsl_layouts_match_rust() {
        let module = validate(&SOURCE.module());
        assert_layout(
            &module,
            &rust_layout!(PrimitiveUniform {
                view_proj,
                eye,
                near,
                forward,
                far,
                right,
                fallback_distance,
                up,
                fallback_depth,
                fallback_half_x,
                fallback_half_y,
                bound_scale,
                _pad0
            }),
        );
        assert_layout(&module, &draw_instance_layout());
        assert_eq!(LOD_ID_MESH, 1, "primitive.wgsl's LOD_ID_MESH");
    }
}
