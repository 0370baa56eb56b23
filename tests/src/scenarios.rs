//! The golden scenarios (SPEC §8): a few scenes x cameras x fade modes, small enough that a
//! software rasterizer (the reference, and lavapipe for the GPU) renders each in well under a
//! second. The reference writes the goldens; the GPU is compared against the reference and the
//! goldens.

use forestlod_reference::cameras::named_camera;
use forestlod_reference::pipeline::{Prepared, prepare};
use forestlod_reference::scene::{Scene, builtin};
use forestlod_shared::{Camera, FadeMode, Params};

/// Side of every golden image, pixels.
pub const GOLDEN_SIZE: u32 = 96;

/// One golden scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// File stem under `goldens/`.
    pub name: String,
    /// Built-in scene name.
    pub scene: &'static str,
    /// Named camera.
    pub camera: &'static str,
    /// Parameters (fade mode varies; distances scaled to the small scene so every LOD shows).
    pub params: Params,
}

impl Scenario {
    /// The scene.
    pub fn scene(&self) -> Scene {
        builtin::by_name(self.scene).expect("built-in scene")
    }
    /// The camera at [`GOLDEN_SIZE`]².
    pub fn camera(&self, scene: &Scene) -> Camera {
        named_camera(self.camera, scene, 0.0, GOLDEN_SIZE, GOLDEN_SIZE).expect("named camera")
    }
}

/// Parameters for `tiny` (200 m across): the transition pulled in to 400 m with an 80 m band so
/// the `medium` view holds LOD0, the band and LOD1; 8 angles at 32² keep the bake cheap.
pub fn tiny_params(fade: FadeMode) -> Params {
    Params {
        grid_size: 50.0,
        angle_count: 8,
        texture_size: 32,
        lod1_transition: 400.0,
        fade_width: 80.0,
        draw_distance: 4000.0,
        fade_mode: fade as u32,
        ..Params::default()
    }
}

/// Every golden scenario: `tiny` from `medium` in each fade mode but `dither`, `tiny` from
/// `close` and `far`, and `pair` (two trees) up close.
pub fn golden_scenarios() -> Vec<Scenario> {
    let mut out = Vec::new();
    for fade in [FadeMode::None, FadeMode::Alpha, FadeMode::DitherSequential] {
        out.push(Scenario {
            name: format!("tiny-medium-{}", fade.name()),
            scene: "tiny",
            camera: "medium",
            params: tiny_params(fade),
        });
    }
    out.push(Scenario {
        name: "tiny-close-dither-sequential".into(),
        scene: "tiny",
        camera: "close",
        params: tiny_params(FadeMode::DitherSequential),
    });
    out.push(Scenario {
        name: "tiny-far-alpha".into(),
        scene: "tiny",
        camera: "far",
        params: tiny_params(FadeMode::Alpha),
    });
    out
}

/// `synthetic` cropped to the square of half-side `half` metres around its centre (its trees,
/// meshes and terrain unchanged), so a software rasterizer renders it quickly.
pub fn cropped_synthetic(half: f32) -> Scene {
    let mut scene = builtin::synthetic();
    let [x0, y0, x1, y1] = scene.bounds;
    let (cx, cy) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
    scene
        .instances
        .retain(|t| (t.position[0] - cx).abs() <= half && (t.position[1] - cy).abs() <= half);
    scene.bounds = [cx - half, cy - half, cx + half, cy + half];
    scene.name = format!("synthetic-crop{}", 2.0 * half);
    scene
}

/// Parameters for the cropped `synthetic`: 100 m cells, transition at 550 m with a 150 m band, so
/// the `medium` view (trees 200..800 m away) holds LOD0, the band and LOD1.
pub fn crop_params(fade: FadeMode) -> Params {
    Params {
        grid_size: 100.0,
        angle_count: 10,
        texture_size: 64,
        lod1_transition: 550.0,
        fade_width: 150.0,
        fade_mode: fade as u32,
        ..Params::default()
    }
}

/// One view of [`named_views`].
#[derive(Clone, Debug)]
pub struct NamedView {
    /// The named camera (`medium`, `close`, `far`).
    pub camera_name: &'static str,
    /// Its yaw, degrees.
    pub yaw: f32,
    /// The camera.
    pub camera: Camera,
    /// The parameters, with the view's draw distance.
    pub params: Params,
}

/// The per-tree parity tests' named views of `scene` (`parity::baselines`' cull,
/// `parity::refine`): `medium`, `close` and `far` at `size`², each yawed by 0°, 40° and 200°, each
/// with `p`'s draw distance and with it pulled in to 150 m.
pub fn named_views(scene: &Scene, p: &Params, size: u32) -> Vec<NamedView> {
    let mut out = Vec::new();
    for camera_name in ["medium", "close", "far"] {
        for yaw in [0.0, 40.0, 200.0] {
            for draw_distance in [p.draw_distance, 150.0] {
                out.push(NamedView {
                    camera_name,
                    yaw,
                    camera: named_camera(camera_name, scene, yaw, size, size).unwrap(),
                    params: Params {
                        draw_distance,
                        ..*p
                    },
                });
            }
        }
    }
    out
}

/// One frame of a prepared scene to render and compare.
#[derive(Clone, Debug)]
pub struct FrameScenario {
    /// Report name.
    pub name: String,
    /// Index of the prepared scene it renders.
    pub prepared_key: usize,
    /// The camera.
    pub camera: Camera,
    /// The parameters.
    pub params: Params,
}

/// The image scenarios of the GPU baselines and refinement: `tiny` (prepared key 0, alpha fade)
/// from `medium` at yaws 0° and 40°, `close` and `far`, then from `medium` once for each of
/// `tiny_medium` (name suffix, parameters), then the cropped `synthetic` of 600 m (key 1) from
/// `medium` (160²) and `close` (128²).
pub fn tiny_and_crop_frames(tiny_medium: &[(&str, Params)]) -> (Vec<Prepared>, Vec<FrameScenario>) {
    let mut prepared = Vec::new();
    let mut out = Vec::new();
    let tiny = builtin::tiny();
    let p = tiny_params(FadeMode::Alpha);
    prepared.push(prepare(tiny.clone(), &p).expect("prepare tiny"));
    for (name, yaw) in [
        ("medium", 0.0),
        ("medium", 40.0),
        ("close", 0.0),
        ("far", 0.0),
    ] {
        out.push(FrameScenario {
            name: format!("tiny-{name}-yaw{yaw}"),
            prepared_key: 0,
            camera: named_camera(name, &tiny, yaw, 96, 96).unwrap(),
            params: p,
        });
    }
    for (suffix, params) in tiny_medium {
        out.push(FrameScenario {
            name: format!("tiny-medium-{suffix}"),
            prepared_key: 0,
            camera: named_camera("medium", &tiny, 0.0, 96, 96).unwrap(),
            params: *params,
        });
    }
    let crop = cropped_synthetic(300.0);
    let crop_p = crop_params(FadeMode::Alpha);
    prepared.push(prepare(crop.clone(), &crop_p).expect("prepare crop"));
    for (name, size) in [("medium", 160), ("close", 128)] {
        out.push(FrameScenario {
            name: format!("{}-{name}", crop.name),
            prepared_key: 1,
            camera: named_camera(name, &crop, 0.0, size, size).unwrap(),
            params: crop_p,
        });
    }
    (prepared, out)
}

/// `tiny` from `medium` with `tree_cull = none` and the draw distance pulled in so that drawn
/// **mesh** batches straddle it: nothing refines the trees before the draw, so the draw stage's
/// own per-tree distance test (`draw.wgsl`'s `tree_within_draw_distance` in the vertex stage) is
/// the only thing removing those past it (issue 36, class 4). The draw distance is the view depth
/// of the tree centre at 40 % of the trees nearer than the fade start (rounded to 1 m), so that
/// it cuts through the LOD0 trees whatever the scene's layout. Used by
/// `parity::draw::unrefined_mesh_batches_straddling_the_draw_distance` and by
/// `tests/tests/coverage.rs` (row "draw: mesh tree centre vs draw distance").
pub fn unrefined_straddling_case() -> (Prepared, Camera, Params) {
    let tiny = builtin::tiny();
    let base = Params {
        tree_cull: forestlod_shared::TreeCull::None as u32,
        ..tiny_params(FadeMode::DitherSequential)
    };
    let camera = named_camera("medium", &tiny, 0.0, 96, 96).expect("camera");
    let prepared = prepare(tiny, &base).expect("prepare tiny");
    let u = forestlod_shared::ViewUniform::new(&camera, &base);
    let mut depths: Vec<f32> = prepared
        .scene
        .instances
        .iter()
        .map(|t| {
            let meta = &prepared.geometry.meshes[t.mesh as usize];
            let (centre, _) = forestlod_reference::scene::tree_sphere(t, meta);
            forestlod_shared::view_interval(centre, 0.0, u.eye, u.forward).d
        })
        .filter(|&d| d > 0.0 && d < u.fade_start)
        .collect();
    depths.sort_by(f32::total_cmp);
    let draw_distance = depths
        .get(depths.len() * 2 / 5)
        .expect("trees nearer than the fade start")
        .round();
    let params = Params {
        draw_distance,
        ..base
    };
    (prepared, camera, params)
}

/// `parity::refine`'s image frames (and the coverage test's mirror of them): the shared `tiny` and cropped `synthetic` frames, with the
/// draw distance pulled in to 150 m and to 300 m, the transition to 120 m.
pub fn refine_image_frames() -> (Vec<Prepared>, Vec<FrameScenario>) {
    let p = tiny_params(FadeMode::Alpha);
    tiny_and_crop_frames(&[
        (
            "draw-distance-150",
            Params {
                draw_distance: 150.0,
                ..p
            },
        ),
        (
            "transition-120",
            Params {
                lod1_transition: 120.0,
                fade_width: 40.0,
                ..p
            },
        ),
        // Issue 36: the only frame where refine drops a needed tree for its centre being past the
        // draw distance (the row "refine: needed tree vs draw distance" of the coverage table;
        // at 150 m no needed tree's centre lies past it).
        (
            "draw-distance-300",
            Params {
                draw_distance: 300.0,
                ..p
            },
        ),
    ])
}

/// `params` with the blend of issue 30 (G§4): the dithered fades' threshold `space` and the
/// progress `granularity` (`reference::blend`).
pub fn with_blend(
    params: Params,
    space: forestlod_shared::DitherSpace,
    granularity: forestlod_shared::FadeGranularity,
) -> Params {
    Params {
        dither_space: space as u32,
        fade_granularity: granularity as u32,
        ..params
    }
}

/// One frame of [`blend_scenarios`].
#[derive(Clone, Debug)]
pub struct BlendScenario {
    /// `<scene>-<camera>-<fade>-<space>-<granularity>[-<note>]`.
    pub name: String,
    /// The cropped `synthetic` ([`cropped_synthetic`]`(300)`) or `tiny`.
    pub crop: bool,
    /// The named camera.
    pub camera_name: &'static str,
    /// Its side, pixels.
    pub size: u32,
    /// The parameters.
    pub params: Params,
}

impl BlendScenario {
    /// The scene the scenario draws.
    pub fn scene(&self) -> Scene {
        if self.crop {
            cropped_synthetic(300.0)
        } else {
            builtin::tiny()
        }
    }

    /// The camera on `scene` ([`Self::scene`]).
    pub fn camera(&self, scene: &Scene) -> Camera {
        named_camera(self.camera_name, scene, 0.0, self.size, self.size).expect("named camera")
    }
}

/// The blend frames of issue 30 (G§4) that `parity::blend` compares across backends and the
/// coverage table runs: the cropped `synthetic` from `medium` ([`crop_params`]: meshes, the band
/// and billboards on screen) in `dither-sequential` at every space and granularity but the
/// defaults (which `parity::draw` compares), `alpha` and `dither` per tree, and `tiny` from
/// `close` with the band pulled in and a 32-texel noise, whose near trees take noise level 0
/// (magnified noise: G§4's "too small" texture) beside coarser levels.
pub fn blend_scenarios() -> Vec<BlendScenario> {
    use forestlod_shared::{DitherSpace as S, FadeGranularity as G};
    let mut out = Vec::new();
    let crop = |fade: FadeMode, space: S, granularity: G| BlendScenario {
        name: format!(
            "crop-medium-{}-{}-{}",
            fade.name(),
            space.name(),
            granularity.name()
        ),
        crop: true,
        camera_name: "medium",
        size: 160,
        params: with_blend(crop_params(fade), space, granularity),
    };
    for (space, granularity) in [
        (S::Texture, G::Tree),
        (S::Texture, G::Fragment),
        (S::Screen, G::Tree),
    ] {
        out.push(crop(FadeMode::DitherSequential, space, granularity));
    }
    out.push(crop(FadeMode::Alpha, S::Texture, G::Tree));
    out.push(crop(FadeMode::Dither, S::Texture, G::Tree));
    out.push(BlendScenario {
        name: "tiny-close-dither-sequential-texture-tree-noise32".into(),
        crop: false,
        camera_name: "close",
        size: 128,
        params: Params {
            lod1_transition: 90.0,
            fade_width: 60.0,
            noise_size: 32,
            ..with_blend(tiny_params(FadeMode::DitherSequential), S::Texture, G::Tree)
        },
    });
    out
}

/// `parity::occlusion`'s views (issue 31): a camera path through the crop at tree height, where
/// trees hide each other: `frames` cameras
/// of `size`, the first `back` metres west of the crop's centre, 4 m above the trees' mean base,
/// looking east (yawed by `yaw` degrees), each next one 3 m further along its view and 1.5 m to
/// its side (the motion a path's frames have).
pub fn occlusion_path(
    scene: &Scene,
    (back, yaw): (f32, f32),
    size: (u32, u32),
    frames: usize,
) -> Vec<Camera> {
    let [x0, y0, x1, y1] = scene.bounds;
    let (cx, cy) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
    let n = scene.instances.len().max(1) as f32;
    let z = scene.instances.iter().map(|t| t.position[2]).sum::<f32>() / n + 4.0;
    let eye = [cx - back, cy, z];
    let yaw = yaw.to_radians();
    let first = Camera::look_at(
        eye,
        [eye[0] + yaw.cos(), eye[1] + yaw.sin(), z],
        60.0,
        size.0,
        size.1,
    );
    (0..frames)
        .map(|k| {
            let mut c = first;
            let (f, r) = (c.basis().forward, c.basis().right);
            for a in 0..3 {
                c.eye[a] += k as f32 * (3.0 * f[a] + 1.5 * r[a]);
            }
            c
        })
        .collect()
}

/// The parameters of `parity::occlusion`'s frames (issue 31): the crop's, occluders within 150 m.
pub fn occlusion_params(fade: FadeMode) -> Params {
    Params {
        occluder_depth: 150.0,
        ..crop_params(fade)
    }
}
