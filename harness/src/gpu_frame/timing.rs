//! Timestamp queries around the two submits of a GPU frame (selection or culling, then the draw
//! pass), where the adapter offers `TIMESTAMP_QUERY` (as `experiments/src/bin/gpu_bench.rs`: empty
//! compute passes that write a timestamp at their beginning).

use forestlod_gpu::readback::read_buffer;
use forestlod_gpu::{GpuContext, GpuError};

/// The frame's four timestamps and their resolve buffer.
pub(super) struct Timestamps {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
}

impl Timestamps {
    pub(super) const COUNT: u32 = 4;

    pub(super) fn new(ctx: &GpuContext) -> Option<Self> {
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

    pub(super) fn mark(&self, encoder: &mut wgpu::CommandEncoder, index: u32) {
        encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &self.queries,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            }),
        });
    }

    /// Records the resolve of the four timestamps (at the end of the last submit).
    pub(super) fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.queries, 0..Self::COUNT, &self.resolve, 0);
    }

    /// GPU seconds of the two stages (timestamps 0 to 1, 2 to 3). Blocks.
    pub(super) fn read(&self, ctx: &GpuContext) -> Result<(f64, f64), GpuError> {
        let ticks: Vec<u64> = read_buffer(ctx, &self.resolve, 0, Self::COUNT as usize)?;
        let period_s = ctx.queue.get_timestamp_period() as f64 * 1e-9;
        Ok((
            ticks[1].saturating_sub(ticks[0]) as f64 * period_s,
            ticks[3].saturating_sub(ticks[2]) as f64 * period_s,
        ))
    }
}
