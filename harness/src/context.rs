//! The GPU context of this process, created once ([`gpu_context`]): device creation on lavapipe
//! costs about half a second, and proptest runs hundreds of cases.

use std::sync::OnceLock;

use forestlod_gpu::{GpuContext, gpu_or_explain};

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
