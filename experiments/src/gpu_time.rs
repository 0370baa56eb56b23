//! GPU time between timestamps for the experiment programs (`gpu_bench`, `draw_split`): the
//! commands one closure records, bracketed by empty compute passes that write a timestamp at their
//! beginning (wgpu offers timestamps at pass boundaries only).

use forestlod_gpu::GpuContext;

/// GPU seconds spent by the commands `record` adds to an encoder, from timestamps written by empty
/// compute passes before and after them; `None` without `TIMESTAMP_QUERY`.
pub fn timestamped(
    ctx: &GpuContext,
    record: &mut dyn FnMut(&mut wgpu::CommandEncoder) -> Result<(), forestlod_gpu::GpuError>,
) -> Result<Option<f64>, Box<dyn std::error::Error>> {
    if !ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY) {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        record(&mut encoder)?;
        ctx.queue.submit([encoder.finish()]);
        ctx.wait()?;
        return Ok(None);
    }
    let queries = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("stage timestamps"),
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("timestamp resolve"),
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let mark = |encoder: &mut wgpu::CommandEncoder, index: u32| {
        encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &queries,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            }),
        });
    };
    mark(&mut encoder, 0);
    record(&mut encoder)?;
    mark(&mut encoder, 1);
    encoder.resolve_query_set(&queries, 0..2, &resolve, 0);
    ctx.queue.submit([encoder.finish()]);
    ctx.wait()?;
    let ticks: Vec<u64> = forestlod_gpu::readback::read_buffer(ctx, &resolve, 0, 2)?;
    let period_ns = ctx.queue.get_timestamp_period() as f64;
    Ok(Some(
        ticks[1].saturating_sub(ticks[0]) as f64 * period_ns * 1e-9,
    ))
}
