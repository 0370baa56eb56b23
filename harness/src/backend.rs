//! The GPU backends of the stages `select` and `draw` in the one backend family
//! ([`crate::stage::Backend`], "one test body, several backends", SPEC §8). The GPU frame they
//! run is [`crate::gpu_frame`]; the reference-to-GPU bridge is [`crate::bridge`].

use forestlod_gpu::select::{
    DECISION_CULLED_DISTANCE, DECISION_CULLED_FRUSTUM, DECISION_DRAW, DECISION_KIND_MASK,
    DECISION_LOD0, DECISION_LOD1,
};
use forestlod_gpu::{Compaction, GpuContext, GpuSelect};
use forestlod_reference::select::{Decision, Selection};
use forestlod_shared::LodNeeds;

use crate::context::gpu_context;
use crate::gpu_frame::{StagesFromCpu, gpu_draw, render_gpu};
use crate::image_compare::Images;
use crate::stage::{Backend, BackendSelection, Draw, FrameInput, Named, Select, SelectInput};

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
        let mut gpu = GpuSelect::new(self.ctx, i.batches, i.scales, i.meshes, i.billboard)
            .expect("GpuSelect::new");
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
