//! The wgpu adapter, device and queue every stage runs on (SPEC §8: CI has no GPU and runs on
//! Mesa's lavapipe, a Vulkan adapter of device type `Cpu`).
//!
//! [`GpuContext::new`] asks for a Vulkan adapter first (preferring a high-performance one, but
//! accepting CPU adapters such as lavapipe's "llvmpipe"), then for any backend. It enables each
//! optional feature the pipeline can use when the adapter offers it ([`WANTED_FEATURES`]) and
//! takes the adapter's own limits. Tests get their context through [`gpu_or_explain`], which fails
//! with an install hint when no adapter exists.
//!
//! Crate-internal helpers hold the pipeline boilerplate the stage drivers share: `buffer_entry`
//! (one buffer binding of a bind-group layout), `compute_pipelines` (a stage's WGSL module, its one
//! bind-group layout and a compute pipeline per entry point) and `cached_pipelines` (a stage's
//! pipelines compiled once per context).

use std::sync::OnceLock;

/// The environment variable that lets GPU tests skip (instead of fail) without an adapter.
pub const ALLOW_NO_GPU_ENV: &str = "FORESTLOD_ALLOW_NO_GPU";

/// What a test prints (and panics with) when no adapter exists.
pub const NO_GPU_HINT: &str = "no GPU adapter found: install Mesa's lavapipe (`apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1`) or set FORESTLOD_ALLOW_NO_GPU=1 to skip GPU tests";

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

/// Everything that can go wrong talking to the GPU.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter on any backend.
    #[error("{NO_GPU_HINT} (wgpu: {0})")]
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
    /// Compiled `select` pipelines, created on first use and shared by every [`crate::GpuSelect`].
    pub(crate) select_pipelines: OnceLock<crate::select::SelectPipelines>,
    /// Compiled `cull` pipelines, created on first use and shared by every [`crate::GpuCull`].
    pub(crate) cull_pipelines: OnceLock<crate::cull::CullPipelines>,
    /// Compiled `refine` pipeline, created on first use and shared by every [`crate::GpuRefine`].
    pub(crate) refine_pipelines: OnceLock<crate::refine::RefinePipelines>,
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
    /// Picks an adapter (Vulkan first, then any backend; high performance preferred, CPU adapters
    /// accepted) and creates a device with every offered feature of [`WANTED_FEATURES`] and the
    /// adapter's limits. Blocks (wgpu's futures are driven by `pollster`).
    pub fn new() -> Result<Self, GpuError> {
        let mut last_error = String::from("no backend tried");
        for backends in [wgpu::Backends::VULKAN, wgpu::Backends::all()] {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
            desc.backends = backends;
            // WGPU_BACKEND and friends still override, as everywhere in wgpu.
            let instance = wgpu::Instance::new(desc.with_env());
            let options = wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: None,
                apply_limit_buckets: false,
            };
            match pollster::block_on(instance.request_adapter(&options)) {
                Ok(adapter) => return Self::from_adapter(adapter),
                Err(e) => last_error = e.to_string(),
            }
        }
        Err(GpuError::NoAdapter(last_error))
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
            select_pipelines: OnceLock::new(),
            cull_pipelines: OnceLock::new(),
            refine_pipelines: OnceLock::new(),
        })
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
/// group creation). Entries with dynamic offsets, textures and samplers are written out where
/// they are used.
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

/// Compiles one compute stage: the WGSL module `source` (labelled `"{label}.wgsl"`), a bind-group
/// layout of `entries` and a pipeline layout of that one group (both labelled `label`), and one
/// pipeline per name of `entry_points` (each labelled with its entry point), in that order. Every
/// pipeline of the stage shares the layout, so one bind group serves all its dispatches.
///
/// wgpu reports a WGSL or layout error through error scopes, not through the return value: call
/// this inside [`GpuContext::checked`], which turns it into [`GpuError::Validation`].
pub(crate) fn compute_pipelines<const N: usize>(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
    entry_points: [&str; N],
) -> (wgpu::BindGroupLayout, [wgpu::ComputePipeline; N]) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&format!("{label}.wgsl")),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
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
}

/// The pipelines in `cell` (one of [`GpuContext`]'s caches), compiled by `create` on first use.
/// Concurrent first uses may each compile a set; the first one stored wins and the others are
/// dropped (every set works alike). A failed `create` stores nothing and returns its error, so a
/// later call tries again.
pub(crate) fn cached_pipelines<T>(
    cell: &OnceLock<T>,
    create: impl FnOnce() -> Result<T, GpuError>,
) -> Result<&T, GpuError> {
    if let Some(pipelines) = cell.get() {
        return Ok(pipelines);
    }
    let pipelines = create()?;
    let _ = cell.set(pipelines);
    Ok(cell.get().expect("the pipelines were just set"))
}

/// The context for a GPU test. Without an adapter it **panics** with [`NO_GPU_HINT`], unless the
/// environment sets [`ALLOW_NO_GPU_ENV`]`=1`, in which case it prints that the test is skipped and
/// returns `None` (CI never sets it: SPEC §8). Setting `XDG_RUNTIME_DIR` (which silences harmless
/// Mesa warnings) is the caller's business.
pub fn gpu_or_explain() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
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
