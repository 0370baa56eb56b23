//! Shared helpers for the cross-crate tests in `tests/tests/`: small random scenes, cameras and
//! parameters as proptest strategies, built without the procedural generators so the properties
//! exercise the selection rules alone.

pub mod backend;
pub mod image_compare;
pub mod scenarios;
pub mod texel_compare;

use forestlod_reference::scene::{Instance, Scene, Terrain, TreeMesh};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{Camera, Params};
use proptest::prelude::*;

/// A crossed-card tree of `height` metres and crown half-width `half_width`: 4 triangles.
pub fn card_tree(name: &str, height: f32, half_width: f32) -> TreeMesh {
    let (h, w) = (height, half_width);
    TreeMesh {
        name: name.to_string(),
        positions: vec![
            [-w, 0.0, 0.0],
            [w, 0.0, 0.0],
            [w, 0.0, h],
            [-w, 0.0, h],
            [0.0, -w, 0.0],
            [0.0, w, 0.0],
            [0.0, w, h],
            [0.0, -w, h],
        ],
        uvs: vec![
            [0.0, 1.0],
            [1.0, 1.0],
            [1.0, 0.0],
            [0.0, 0.0],
            [0.0, 1.0],
            [1.0, 1.0],
            [1.0, 0.0],
            [0.0, 0.0],
        ],
        indices: vec![0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7],
        texture: Rgba8Image::new(4, 4, [40, 120, 40, 255]),
    }
}

/// A scene of the given trees over three card-tree species of different heights.
pub fn scene_of(instances: Vec<Instance>) -> Scene {
    let mut bounds = [
        f32::INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
    ];
    for t in &instances {
        bounds = [
            bounds[0].min(t.position[0]),
            bounds[1].min(t.position[1]),
            bounds[2].max(t.position[0]),
            bounds[3].max(t.position[1]),
        ];
    }
    Scene {
        name: "proptest".into(),
        origin: [0.0; 3],
        meshes: vec![
            card_tree("short", 8.0, 2.0),
            card_tree("mid", 18.0, 4.0),
            card_tree("tall", 32.0, 5.0),
        ],
        instances,
        terrain: Terrain::Flat { z: 0.0 },
        bounds,
    }
}

/// Random trees in a square of half-side `extent` around the origin.
pub fn instances(max_trees: usize) -> impl Strategy<Value = Vec<Instance>> {
    (10.0f32..3000.0).prop_flat_map(move |extent| {
        prop::collection::vec(
            (
                -extent..extent,
                -extent..extent,
                -20.0f32..60.0,
                0.0f32..6.3,
                0.3f32..2.5,
                0u32..3,
            )
                .prop_map(|(x, y, z, yaw, scale, mesh)| Instance {
                    position: [x, y, z],
                    yaw,
                    scale,
                    mesh,
                }),
            1..max_trees,
        )
    })
}

/// Random cameras over a 4 km region: anywhere from ground level to 1.5 km up, any yaw, pitch from
/// -89° to +30°, field of view 20°..100°, aspect 1:2 to 2:1.
pub fn cameras() -> impl Strategy<Value = Camera> {
    (
        -4000.0f32..4000.0,
        -4000.0f32..4000.0,
        -10.0f32..1500.0,
        0.0f32..360.0,
        -89.0f32..30.0,
        20.0f32..100.0,
        64u32..256,
        64u32..256,
    )
        .prop_map(|(x, y, z, yaw, pitch, fov, w, h)| {
            let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
            let forward = [
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            ];
            let mut c = Camera::look_at(
                [x, y, z],
                [x + forward[0], y + forward[1], z + forward[2]],
                fov,
                w,
                h,
            );
            c.forward = forward;
            c
        })
}

/// Random valid parameters: grid 1 m..5 km, transition 0..2 km, fade 0..500 m, draw distance
/// 0..6 km, one or two LOD levels.
pub fn params() -> impl Strategy<Value = Params> {
    (
        1.0f32..5000.0,
        0.0f32..2000.0,
        0.0f32..500.0,
        0.0f32..6000.0,
        1u32..=2,
    )
        .prop_map(|(g, t, w, d, l)| Params {
            grid_size: g,
            lod1_transition: t,
            fade_width: w,
            draw_distance: d,
            lod_levels: l,
            ..Params::default()
        })
}

/// Runs `f` inside a rayon pool of `threads` threads.
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("rayon pool")
        .install(f)
}
