//! The wgpu adapter, device and queue every stage runs on (SPEC §8: CI has no GPU and runs on
//! Mesa's lavapipe, a Vulkan adapter of device type `Cpu`).
//!
//! [`GpuContext::new`] checks every adapter of every backend against what the pipeline needs
//! ([`REQUIRED_FEATURES`], [`REQUIRED_DOWNLEVEL`], [`REQUIRED_STORAGE_BUFFERS_PER_STAGE`]) and takes
//! the best suitable one (discrete before integrated before CPU adapters such as lavapipe's
//! "llvmpipe"; Vulkan first), saying in one line why each other adapter was passed over. It
//! enables each optional feature the pipeline can use when the adapter offers it
//! ([`WANTED_FEATURES`]) and takes the adapter's own limits. Tests get their context through [`gpu_or_explain`], which fails
//! with an install hint when no adapter exists.
//!
//! Crate-internal helpers hold the pipeline boilerplate the stage drivers share: `buffer_entry`
//! and `texture_entry` (one binding of a bind-group layout), `compute_stage` (a compute stage's
//! WGSL module, its one bind-group layout of `Slot`s and a compute pipeline per entry point) and
//! `compute_pass` (one labelled compute pass with the stage's bind group set).
//!
//! **One pipeline cache.** Every stage's compiled pipelines (a type implementing
//! [`StagePipelines`]) are created once per context on first use and shared by every driver of
//! that stage ([`GpuContext::pipelines`]), keyed by the type: this module names no stage.

use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// The environment variable that lets GPU tests skip (instead of fail) without an adapter.
pub const ALLOW_NO_GPU_ENV: &str = "FORESTLOD_ALLOW_NO_GPU";

/// What a test prints (and panics with) when no adapter exists.
pub const NO_GPU_HINT: &str = "no GPU adapter that can run the pipeline: install Mesa's lavapipe (`apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1`) or set FORESTLOD_ALLOW_NO_GPU=1 to skip GPU tests";

/// Optional features requested when the adapter offers them:
/// - `MULTI_DRAW_INDIRECT_COUNT`: the draw stage takes its command count from the `select`
///   counters buffer, so the CPU never reads it back (E§4.4);
/// - `INDIRECT_FIRST_INSTANCE`: without it, wgpu ignores `first_instance` in indirect arguments,
///   and the draw stage needs it to find a batch's range of the indirection array;
/// - `TIMESTAMP_QUERY`: per-stage GPU timings for the experiments;
/// - `FLOAT32_FILTERABLE`: linear filtering of float textures (depth and error images).
pub const WANTED_FEATURES: wgpu::Features = wgpu::Features::MULTI_DRAW_INDIRECT_COUNT
    .union(wgpu::Features::INDIRECT_FIRST_INSTANCE)
    .union(wgpu::Features::TIMESTAMP_QUERY)
    .union(wgpu::Features::FLOAT32_FILTERABLE);

/// Features the pipeline cannot run without: the draw stage finds a batch's trees through
/// `first_instance` of its indirect draws (E§4.4), which wgpu ignores without this feature.
pub const REQUIRED_FEATURES: wgpu::Features = wgpu::Features::INDIRECT_FIRST_INSTANCE;

/// Downlevel capabilities every stage relies on (all present on any Vulkan 1.1 or Metal or D3D12
/// adapter; wgpu's GL backend lacks some, which is why it used to fail half-way through a frame):
/// compute shaders (select, cull, refine, bake, mips), indirect execution and base vertex (the
/// draw of selected commands), storage buffers read by vertex and fragment stages (`draw.wgsl`),
/// per-target blend state (the colour target blends, the LOD-id target cannot) and texture view
/// formats (the billboard array is written through an `Rgba8Unorm` view of an sRGB texture).
pub const REQUIRED_DOWNLEVEL: wgpu::DownlevelFlags = wgpu::DownlevelFlags::COMPUTE_SHADERS
    .union(wgpu::DownlevelFlags::INDIRECT_EXECUTION)
    .union(wgpu::DownlevelFlags::BASE_VERTEX)
    .union(wgpu::DownlevelFlags::VERTEX_STORAGE)
    .union(wgpu::DownlevelFlags::FRAGMENT_STORAGE)
    .union(wgpu::DownlevelFlags::INDEPENDENT_BLEND)
    .union(wgpu::DownlevelFlags::VIEW_FORMATS);

/// Storage buffers the busiest compute stage binds (`cull.wgsl`: 9).
pub const REQUIRED_STORAGE_BUFFERS_PER_STAGE: u32 = 9;

/// Why `adapter` cannot run the pipeline (missing features, downlevel flags or limits, one line),
/// or `None` when it can.
pub fn adapter_shortfall(adapter: &wgpu::Adapter) -> Option<String> {
    let mut missing = Vec::new();
    let features = REQUIRED_FEATURES - adapter.features();
    missing.extend(features.iter_names().map(|(n, _)| format!("feature {n}")));
    let downlevel = adapter.get_downlevel_capabilities();
    let flags = REQUIRED_DOWNLEVEL - downlevel.flags;
    missing.extend(
        flags
            .iter_names()
            .map(|(n, _)| format!("downlevel flag {n}")),
    );
    let storage = adapter.limits().max_storage_buffers_per_shader_stage;
    if storage < REQUIRED_STORAGE_BUFFERS_PER_STAGE {
        missing.push(format!(
            "{storage} storage buffers per shader stage (needs {REQUIRED_STORAGE_BUFFERS_PER_STAGE})"
        ));
    }
    (!missing.is_empty()).then(|| format!("lacks {}", missing.join(", ")))
}

/// Everything that can go wrong talking to the GPU.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter that can run the pipeline on any backend (the reasons, one line).
    #[error("{NO_GPU_HINT} ({0})")]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("the adapter {adapter:?} refused to create a device: {reason}")]
    RequestDevice {
        /// Adapter name.
        adapter: String,
        /// wgpu's reason.
        reason: String,
    },
    /// Waiting for the GPU failed (device lost, timeout).
    #[error("waiting for the GPU failed: {0}")]
    Poll(String),
    /// Mapping a readback buffer failed.
    #[error("mapping a readback buffer failed: {0}")]
    Map(String),
    /// A wgpu validation or out-of-memory error caught by an error scope.
    #[error("wgpu rejected {what}: {reason}")]
    Validation {
        /// What was being created or run.
        what: String,
        /// wgpu's message.
        reason: String,
    },
    /// An input a stage cannot use (empty where it must not be, index out of range, too large).
    #[error("invalid input {field} = {value}: {reason}")]
    Input {
        /// Which input.
        field: &'static str,
        /// The offending value.
        value: String,
        /// What a valid value looks like.
        reason: &'static str,
    },
}

/// An adapter, its device and queue, and what they support.
pub struct GpuContext {
    /// The adapter the device was created on.
    pub adapter: wgpu::Adapter,
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Adapter name, backend, device type, driver.
    pub info: wgpu::AdapterInfo,
    /// The optional features actually enabled (a subset of [`WANTED_FEATURES`]).
    pub features: wgpu::Features,
    /// The device limits (the adapter's own).
    pub limits: wgpu::Limits,
    /// One line per adapter [`GpuContext::new`] found but could not use, with the reason.
    pub passed_over: Vec<String>,
    /// Every stage's compiled pipelines, by type ([`GpuContext::pipelines`]).
    pipelines: Mutex<HashMap<TypeId, Arc<dyn Any + Send + Sync>>>,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("info", &self.info)
            .field("features", &self.features)
            .finish_non_exhaustive()
    }
}

impl GpuContext {
    /// Picks an adapter and creates a device with every offered feature of [`WANTED_FEATURES`]
    /// and the adapter's limits. Blocks (wgpu's futures are driven by `pollster`).
    ///
    /// Every adapter of every backend is checked against what the pipeline needs
    /// ([`adapter_shortfall`]); among those that can run it, a discrete GPU beats an integrated,
    /// virtual, then CPU one (lavapipe's "llvmpipe"), and Vulkan beats other backends at equal
    /// type. Each adapter passed over is named with its reason in [`GpuContext::passed_over`],
    /// one line each. With none suitable the error names every adapter and what it lacks.
    /// `WGPU_BACKEND` and friends still restrict the backends, as everywhere in wgpu.
    pub fn new() -> Result<Self, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::all();
        let instance = wgpu::Instance::new(desc.with_env());
        let mut adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let rank = |a: &wgpu::Adapter| {
            let info = a.get_info();
            let kind = match info.device_type {
                wgpu::DeviceType::DiscreteGpu => 0,
                wgpu::DeviceType::IntegratedGpu => 1,
                wgpu::DeviceType::VirtualGpu => 2,
                wgpu::DeviceType::Cpu => 3,
                wgpu::DeviceType::Other => 4,
            };
            (kind, info.backend != wgpu::Backend::Vulkan)
        };
        adapters.sort_by_key(rank);
        let mut passed_over = Vec::new();
        for adapter in adapters {
            let info = adapter.get_info();
            match adapter_shortfall(&adapter) {
                None => {
                    let mut ctx = Self::from_adapter(adapter)?;
                    ctx.passed_over = passed_over;
                    return Ok(ctx);
                }
                Some(why) => passed_over.push(format!(
                    "passed over GPU adapter {} ({:?}, {:?}): {why}",
                    info.name, info.backend, info.device_type
                )),
            }
        }
        Err(GpuError::NoAdapter(if passed_over.is_empty() {
            "wgpu found no adapter on any backend".to_string()
        } else {
            passed_over.join("; ")
        }))
    }

    /// Creates the device on a chosen adapter (see [`GpuContext::new`]).
    pub fn from_adapter(adapter: wgpu::Adapter) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let features = adapter.features() & WANTED_FEATURES;
        let limits = adapter.limits();
        let desc = wgpu::DeviceDescriptor {
            label: Some("forestlod"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc)).map_err(|e| {
            GpuError::RequestDevice {
                adapter: info.name.clone(),
                reason: e.to_string(),
            }
        })?;
        Ok(Self {
            adapter,
            device,
            queue,
            info,
            features,
            limits,
            passed_over: Vec::new(),
            pipelines: Mutex::new(HashMap::new()),
        })
    }

    /// The compiled pipelines of stage `T`, created by [`StagePipelines::create`] on first use
    /// and shared by every later caller (every driver of the stage on this context). Concurrent
    /// first uses may each compile a set; the first one stored wins and the others are dropped
    /// (every set works alike). A failed `create` stores nothing and returns its error, so a later
    /// call tries again. The lock is not held while compiling.
    pub fn pipelines<T: StagePipelines>(&self) -> Result<Arc<T>, GpuError> {
        let key = TypeId::of::<T>();
        let cached = |map: &HashMap<TypeId, Arc<dyn Any + Send + Sync>>| {
            map.get(&key).map(|p| {
                Arc::clone(p)
                    .downcast::<T>()
                    .expect("the cache stores each type under its own TypeId")
            })
        };
        if let Some(p) = cached(&self.pipelines.lock().unwrap_or_else(|e| e.into_inner())) {
            return Ok(p);
        }
        let created: Arc<dyn Any + Send + Sync> = Arc::new(T::create(self)?);
        let mut map = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        map.entry(key).or_insert(created);
        Ok(cached(&map).expect("just stored"))
    }

    /// One line for logs: name, backend, device type and the enabled optional features.
    pub fn describe(&self) -> String {
        let names: Vec<String> = self
            .features
            .iter_names()
            .map(|(name, _)| name.to_string())
            .collect();
        format!(
            "{} ({:?}, {:?}, driver {} {}) features [{}]",
            self.info.name,
            self.info.backend,
            self.info.device_type,
            self.info.driver,
            self.info.driver_info,
            names.join(", ")
        )
    }

    /// Whether `first_instance` of indirect draws is honoured (see [`WANTED_FEATURES`]).
    pub fn has_indirect_first_instance(&self) -> bool {
        self.features
            .contains(wgpu::Features::INDIRECT_FIRST_INSTANCE)
    }

    /// Blocks until all submitted work is done.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Poll(e.to_string()))
    }

    /// Records commands into a fresh encoder labelled `label` with `record` and submits them, all
    /// inside [`GpuContext::checked`] naming `what`. Does not wait.
    pub(crate) fn submit<T>(
        &self,
        what: &str,
        label: &str,
        record: impl FnOnce(&mut wgpu::CommandEncoder) -> T,
    ) -> Result<T, GpuError> {
        self.checked(what, || {
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
            let value = record(&mut encoder);
            self.queue.submit([encoder.finish()]);
            value
        })
    }

    /// Checks that a storage buffer of `bytes` fits one binding: the smaller of the device's
    /// storage binding and buffer size limits. Otherwise fails with [`GpuError::Input`] on
    /// `field`, its value `value(limit)` (the limit in bytes) and `reason`.
    pub(crate) fn check_storage_binding(
        &self,
        bytes: u64,
        field: &'static str,
        value: impl FnOnce(u64) -> String,
        reason: &'static str,
    ) -> Result<(), GpuError> {
        let limit = self
            .limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size);
        if bytes > limit {
            return Err(GpuError::Input {
                field,
                value: value(limit),
                reason,
            });
        }
        Ok(())
    }

    /// Workgroup counts `(x, y)` of a dispatch of `groups` workgroups, spilling into `y` beyond
    /// the per-dimension limit (`x · y ≥ groups`; the shaders skip the excess).
    pub(crate) fn workgroup_grid(&self, groups: u32) -> (u32, u32) {
        let max_x = self.limits.max_compute_workgroups_per_dimension.max(1);
        let x = groups.min(max_x);
        let y = if x == 0 { 0 } else { groups.div_ceil(x) };
        (x, y)
    }

    /// Runs `f` inside a validation + out-of-memory error scope and turns a caught error into
    /// [`GpuError::Validation`] naming `what`.
    pub fn checked<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = f();
        let errors = [
            pollster::block_on(validation.pop()),
            pollster::block_on(oom.pop()),
        ];
        match errors.into_iter().flatten().next() {
            Some(e) => Err(GpuError::Validation {
                what: what.to_string(),
                reason: e.to_string(),
            }),
            None => Ok(value),
        }
    }
}

/// A bind-group layout entry for a buffer without dynamic offset: `binding`, seen from
/// `visibility`, of type `ty`, with `min_binding_size` bytes at least (0: no minimum, for
/// runtime-sized arrays; wgpu then checks the size at draw or dispatch time instead of at bind
/// group creation). [`dynamic_uniform_entry`], [`texture_entry`] and [`sampler_entry`] make the
/// other kinds of entry.
pub(crate) fn buffer_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
    min_binding_size: u64,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: wgpu::BufferSize::new(min_binding_size),
        },
        count: None,
    }
}

/// A bind-group layout entry for a float texture without multisampling: `binding`, seen from
/// `visibility`, `filterable` or not, of view dimension `view_dimension`.
pub(crate) fn texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    filterable: bool,
    view_dimension: wgpu::TextureViewDimension,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension,
            multisampled: false,
        },
        count: None,
    }
}

/// Compiles the WGSL `source` into a shader module labelled `label`.
pub(crate) fn shader_module(
    device: &wgpu::Device,
    label: &str,
    source: &str,
) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// A bind-group layout of `entries` and a pipeline layout of that one group (no immediates), both
/// labelled `label`.
pub(crate) fn group_layout(
    device: &wgpu::Device,
    label: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> (wgpu::BindGroupLayout, wgpu::PipelineLayout) {
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    (layout, pipeline_layout)
}

/// A bind-group layout entry for a uniform buffer picked by a dynamic offset: `binding`, seen
/// from `visibility`, `min_binding_size` bytes a slot.
pub(crate) fn dynamic_uniform_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    min_binding_size: u64,
) -> wgpu::BindGroupLayoutEntry {
    let mut entry = buffer_entry(
        binding,
        visibility,
        wgpu::BufferBindingType::Uniform,
        min_binding_size,
    );
    if let wgpu::BindingType::Buffer {
        has_dynamic_offset, ..
    } = &mut entry.ty
    {
        *has_dynamic_offset = true;
    }
    entry
}

/// A bind-group layout entry for a filtering sampler: `binding`, seen from `visibility`.
pub(crate) fn sampler_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// One binding of a compute stage's group 0 ([`compute_stage`]), bound at its index in the list.
/// Buffer sizes are the minimum binding size in bytes (0: no minimum, for runtime-sized arrays).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Slot {
    /// A uniform buffer.
    Uniform(u64),
    /// A uniform buffer picked by a dynamic offset, this many bytes a slot.
    DynamicUniform(u64),
    /// A read-only storage buffer.
    Read(u64),
    /// A read-write storage buffer.
    Write(u64),
    /// An unfilterable float texture of this view dimension.
    Texture(wgpu::TextureViewDimension),
}

/// A read-only storage buffer without minimum size (a runtime-sized array).
pub(crate) const READ: Slot = Slot::Read(0);
/// A read-write storage buffer without minimum size (a runtime-sized array).
pub(crate) const WRITE: Slot = Slot::Write(0);

impl Slot {
    /// The layout entry of this slot at `binding`.
    pub(crate) fn entry(self, binding: u32) -> wgpu::BindGroupLayoutEntry {
        use wgpu::BufferBindingType as B;
        let compute = wgpu::ShaderStages::COMPUTE;
        match self {
            Slot::Uniform(min) => buffer_entry(binding, compute, B::Uniform, min),
            Slot::DynamicUniform(min) => dynamic_uniform_entry(binding, compute, min),
            Slot::Read(min) => buffer_entry(binding, compute, B::Storage { read_only: true }, min),
            Slot::Write(min) => {
                buffer_entry(binding, compute, B::Storage { read_only: false }, min)
            }
            Slot::Texture(dimension) => texture_entry(binding, compute, false, dimension),
        }
    }
}

/// Compiles one compute stage inside [`GpuContext::checked`] (naming `"{label}.wgsl
/// pipelines"`, so a WGSL or layout error becomes [`GpuError::Validation`]): the WGSL module
/// `source` (labelled `"{label}.wgsl"`), a bind-group layout of `slots` (binding `i` is
/// `slots[i]`) and a pipeline layout of that one group (both labelled `label`), and one pipeline
/// per name of `entry_points` (each labelled with its entry point), in that order. Every pipeline
/// of the stage shares the layout, so one bind group serves all its dispatches.
pub(crate) fn compute_stage<const N: usize>(
    ctx: &GpuContext,
    label: &str,
    source: &str,
    slots: &[Slot],
    entry_points: [&str; N],
) -> Result<(wgpu::BindGroupLayout, [wgpu::ComputePipeline; N]), GpuError> {
    ctx.checked(&format!("{label}.wgsl pipelines"), || {
        let device = &ctx.device;
        let module = shader_module(device, &format!("{label}.wgsl"), source);
        let entries: Vec<_> = (0..).zip(slots).map(|(i, s)| s.entry(i)).collect();
        let (layout, pipeline_layout) = group_layout(device, label, &entries);
        let pipelines = entry_points.map(|entry_point| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry_point),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry_point),
                compilation_options: Default::default(),
                cache: None,
            })
        });
        (layout, pipelines)
    })
}

/// Declares a compute stage's pipelines (`$vis struct $name`: its group-0 `layout` and one
/// `ComputePipeline` field per entry point) and their [`StagePipelines`] impl, which compiles
/// `$source` through [`compute_stage`] labelled `$label` with the bindings `$slots`.
macro_rules! compute_pipelines {
    (
        $(#[$doc:meta])*
        $vis:vis struct $name:ident = $label:literal, $source:expr, $slots:expr,
        { $($field:ident: $entry:literal),+ $(,)? }
    ) => {
        $(#[$doc])*
        #[derive(Debug)]
        $vis struct $name {
            layout: wgpu::BindGroupLayout,
            $($field: wgpu::ComputePipeline,)+
        }

        impl $crate::context::StagePipelines for $name {
            fn create(ctx: &$crate::GpuContext) -> Result<Self, $crate::GpuError> {
                let (layout, [$($field),+]) = $crate::context::compute_stage(
                    ctx,
                    $label,
                    &$source,
                    &$slots,
                    [$($entry),+],
                )?;
                Ok(Self { layout, $($field),+ })
            }
        }
    };
}
pub(crate) use compute_pipelines;

/// How one step of [`compute_pass`] dispatches.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Dispatch<'a> {
    /// `(x, y, 1)` workgroups.
    Groups(u32, u32),
    /// The workgroup counts the GPU wrote at offset 0 of this `INDIRECT` buffer.
    Indirect(&'a wgpu::Buffer),
}

/// Records one compute pass labelled `label` on `encoder`, `bind_group` at group 0 (no dynamic
/// offsets), running `steps` in order: each sets its pipeline and dispatches.
pub(crate) fn compute_pass(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    bind_group: &wgpu::BindGroup,
    steps: &[(&wgpu::ComputePipeline, Dispatch<'_>)],
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: None,
    });
    pass.set_bind_group(0, bind_group, &[]);
    for &(pipeline, dispatch) in steps {
        pass.set_pipeline(pipeline);
        match dispatch {
            Dispatch::Groups(x, y) => pass.dispatch_workgroups(x, y, 1),
            Dispatch::Indirect(buffer) => pass.dispatch_workgroups_indirect(buffer, 0),
        }
    }
}

/// Begins a render pass labelled `label` that clears each colour attachment of `colors` (a view
/// and its clear colour) and stores it, and clears the depth attachment `depth` to 1 and ends it
/// with `depth_store`.
pub(crate) fn cleared_render_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colors: &[(&wgpu::TextureView, wgpu::Color)],
    depth: &wgpu::TextureView,
    depth_store: wgpu::StoreOp,
) -> wgpu::RenderPass<'e> {
    let color_attachments: Vec<_> = colors
        .iter()
        .map(|&(view, clear)| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                },
            })
        })
        .collect();
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &color_attachments,
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: depth_store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// A bind group on `layout` labelled `label`: binding `i` is `resources[i]`.
pub fn bind_group<'a>(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: impl IntoIterator<Item = wgpu::BindingResource<'a>>,
) -> wgpu::BindGroup {
    let entries: Vec<_> = (0..)
        .zip(resources)
        .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// The binding of one `T`-sized slot of a uniform `buffer` picked by a dynamic offset
/// ([`Slot::DynamicUniform`]).
pub(crate) fn dynamic_uniform_slot<T>(buffer: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: 0,
        size: std::num::NonZeroU64::new(size_of::<T>() as u64),
    })
}

/// [`bind_group`] of whole buffers: binding `i` is all of `buffers[i]`.
pub(crate) fn buffer_bind_group(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    bind_group(
        device,
        label,
        layout,
        buffers.iter().map(|b| b.as_entire_binding()),
    )
}

/// A stage's compiled pipelines (bind-group layouts, pipelines, samplers: nothing per frame),
/// created once per [`GpuContext`] and cached there ([`GpuContext::pipelines`]).
pub trait StagePipelines: Any + Send + Sync + Sized {
    /// Compiles the stage's WGSL and creates its pipelines on `ctx`'s device.
    fn create(ctx: &GpuContext) -> Result<Self, GpuError>;
}

/// The context for a GPU test. Without an adapter it **panics** with [`NO_GPU_HINT`], unless the
/// environment sets [`ALLOW_NO_GPU_ENV`]`=1`, in which case it prints that the test is skipped and
/// returns `None` (CI never sets it: SPEC §8). Setting `XDG_RUNTIME_DIR` (which silences harmless
/// Mesa warnings) is the caller's business.
pub fn gpu_or_explain() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => {
            for line in &ctx.passed_over {
                eprintln!("{line}");
            }
            Some(ctx)
        }
        Err(e) => {
            if std::env::var(ALLOW_NO_GPU_ENV).is_ok_and(|v| v == "1") {
                eprintln!("skipping GPU test: {e} ({ALLOW_NO_GPU_ENV}=1)");
                None
            } else {
                panic!("{e}");
            }
        }
    }
}
