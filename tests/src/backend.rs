//! "One test body, several backends" (SPEC §8): the reference and the GPU twins behind one trait,
//! so a parity test runs the same body over every backend and compares each with the reference.
//!
//! The GPU context is created once per test binary ([`gpu_context`]): device creation on lavapipe
//! costs about half a second, and proptest runs hundreds of cases.

use std::sync::OnceLock;

use forestlod_gpu::select::{
    DECISION_CULLED_DISTANCE, DECISION_CULLED_FRUSTUM, DECISION_DRAW, DECISION_KIND_MASK,
    DECISION_LOD0, DECISION_LOD1,
};
use forestlod_gpu::{Compaction, GpuContext, GpuSelect, gpu_or_explain};
use forestlod_reference::select::{Decision, Selection, batch_decisions, select};
use forestlod_shared::{BatchMeta, Camera, LodNeeds, MeshMeta, Params};

/// The shared GPU context of this test binary, or `None` when no adapter exists and
/// `FORESTLOD_ALLOW_NO_GPU=1` (without it, the first call panics with the install hint).
pub fn gpu_context() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| {
        let ctx = gpu_or_explain();
        if let Some(ctx) = &ctx {
            eprintln!("GPU adapter: {}", ctx.describe());
        }
        ctx
    })
    .as_ref()
}

/// What a backend's selection produced: the output buffers and the per-batch decisions.
#[derive(Clone, Debug, PartialEq)]
pub struct BackendSelection {
    /// Commands, data and counters, as the reference's [`Selection`].
    pub selection: Selection,
    /// The decision of each batch, in batch order.
    pub decisions: Vec<Decision>,
}

/// A `select` implementation: the reference or a GPU twin.
pub trait SelectBackend {
    /// Name for reports, e.g. `gpu-stable`.
    fn name(&self) -> String;
    /// Whether commands come out in the reference's order (else: compare as a multiset).
    fn ordered(&self) -> bool;
    /// Runs selection for one frame.
    fn select(
        &self,
        batches: &[BatchMeta],
        meshes: &[MeshMeta],
        billboard: &MeshMeta,
        camera: &Camera,
        params: &Params,
    ) -> BackendSelection;
}

/// The CPU oracle, `forestlod_reference::select`.
pub struct ReferenceBackend;

impl SelectBackend for ReferenceBackend {
    fn name(&self) -> String {
        "reference".into()
    }
    fn ordered(&self) -> bool {
        true
    }
    fn select(
        &self,
        batches: &[BatchMeta],
        meshes: &[MeshMeta],
        billboard: &MeshMeta,
        camera: &Camera,
        params: &Params,
    ) -> BackendSelection {
        BackendSelection {
            selection: select(batches, meshes, billboard, camera, params),
            decisions: batch_decisions(batches, camera, params),
        }
    }
}

/// `select.wgsl` with one of its compactions.
pub struct GpuBackend {
    /// The shared context.
    pub ctx: &'static GpuContext,
    /// Which compaction.
    pub compaction: Compaction,
}

impl SelectBackend for GpuBackend {
    fn name(&self) -> String {
        format!("gpu-{}", self.compaction.name())
    }
    fn ordered(&self) -> bool {
        self.compaction == Compaction::Stable
    }
    fn select(
        &self,
        batches: &[BatchMeta],
        meshes: &[MeshMeta],
        billboard: &MeshMeta,
        camera: &Camera,
        params: &Params,
    ) -> BackendSelection {
        let gpu = GpuSelect::new(self.ctx, batches, meshes, billboard).expect("GpuSelect::new");
        let out = gpu
            .run(camera, params, self.compaction)
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
pub fn gpu_backends() -> Vec<GpuBackend> {
    gpu_context()
        .map(|ctx| {
            Compaction::ALL
                .iter()
                .map(|&compaction| GpuBackend { ctx, compaction })
                .collect()
        })
        .unwrap_or_default()
}
