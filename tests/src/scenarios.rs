//! The golden scenarios (SPEC §8): a few scenes x cameras x fade modes, small enough that a
//! software rasterizer (the reference, and lavapipe for the GPU) renders each in well under a
//! second. The reference writes the goldens; the GPU is compared against the reference and the
//! goldens.

use forestlod_reference::cameras::named_camera;
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
