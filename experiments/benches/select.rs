//! Grouped selection (E§3.5, §4.3) against per-tree selection (E§5's *Vegetation* culling) on the
//! CPU reference, for `synthetic` and `stress` at the named cameras of E§5.0.1.
//!
//! Run: `cargo bench -p forestlod-experiments --bench select`. Both variants run side by side in one
//! process on the same thread pool; report ratios, not absolute times, across machines.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use forestlod_reference::batches::build_batches;
use forestlod_reference::cameras::named_camera;
use forestlod_reference::geometry::pack_geometry;
use forestlod_reference::scene::{builtin, tree_sphere};
use forestlod_reference::select::{select, select_per_tree};
use forestlod_shared::Params;
use std::time::Duration;

fn selection(c: &mut Criterion) {
    let params = Params::default();
    let mut group = c.benchmark_group("select");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for name in ["synthetic", "stress"] {
        let scene = builtin::by_name(name).expect("built-in scene");
        let geometry = pack_geometry(&scene);
        let batches = build_batches(&scene, &geometry.meshes, params.grid_size).expect("batches");
        let spheres: Vec<_> = scene
            .instances
            .iter()
            .map(|t| tree_sphere(t, &geometry.meshes[t.mesh as usize]))
            .collect();
        for camera_name in ["far", "medium", "close"] {
            let camera = named_camera(camera_name, &scene, 0.0, 1280, 720).expect("camera");
            let id = format!("{name}/{camera_name}");
            group.bench_function(BenchmarkId::new("grouped", &id), |b| {
                b.iter(|| {
                    select(
                        &batches.metas,
                        &batches.scales,
                        &geometry.meshes,
                        &geometry.billboard,
                        &camera,
                        &params,
                    )
                })
            });
            group.bench_function(BenchmarkId::new("per_tree", &id), |b| {
                b.iter(|| select_per_tree(&spheres, &camera, &params))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, selection);
criterion_main!(benches);
