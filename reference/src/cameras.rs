//! The named cameras of E§5.0.1 (`far`, `medium`, `close`), placed relative to a scene's footprint,
//! and the 360° horizontal sweeps the thesis takes its runtime statistics over.
//!
//! - `far`: 8 km from the footprint's centre, 300 m up, looking at it: beyond the default 4 km draw
//!   distance plus the footprint's half-diagonal, so every tree should be culled ("positioned so far
//!   away that all trees are beyond the draw distance").
//! - `medium`: 600 m above the terrain, 500 m outside the footprint's west edge, looking east and
//!   15° down ("the most similar to a real-world scenario").
//! - `close`: 40 m above the terrain at the footprint's centre, just above the canopy, looking east
//!   and 10° down ("a very low altitude above the forest", the most expensive).
//!
//! A sweep rotates the view direction about +Z by `yaw_degrees`, keeping the eye and the pitch.

use forestlod_shared::Camera;

use crate::InputError;
use crate::scene::Scene;

/// Names accepted by [`named_camera`].
pub const CAMERA_NAMES: [&str; 3] = ["far", "medium", "close"];

/// Vertical field of view of the named cameras, degrees.
pub const NAMED_FOV_Y_DEGREES: f32 = 60.0;

/// The named camera `name` for `scene`, rotated by `yaw_degrees` about +Z, at `width` x `height`.
pub fn named_camera(
    name: &str,
    scene: &Scene,
    yaw_degrees: f32,
    width: u32,
    height: u32,
) -> Result<Camera, InputError> {
    // Issue 28, "errors name the flag": a non-finite yaw made a NaN forward vector, reported as
    // `camera.forward: [NaN, ...]` instead of naming the flag the user typed.
    if !yaw_degrees.is_finite() {
        return Err(InputError::new(
            crate::error::COMMAND_LINE,
            "--yaw",
            yaw_degrees,
            "expected a finite angle in degrees",
        ));
    }
    let [x0, y0, x1, y1] = scene.bounds;
    let (cx, cy) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
    let ground = |x: f32, y: f32| scene.terrain.height(x, y);
    let (eye, yaw0, pitch) = match name {
        "far" => ([cx - 8000.0, cy, ground(cx, cy) + 300.0], 0.0f32, -2.0f32),
        "medium" => ([x0 - 200.0, cy, ground(x0, cy) + 250.0], 0.0, -12.0),
        "close" => ([cx, cy, ground(cx, cy) + 40.0], 0.0, -10.0),
        other => {
            return Err(InputError::new(
                "<command line>",
                "--camera",
                other,
                format!(
                    "unknown camera; expected one of {}",
                    CAMERA_NAMES.join(", ")
                ),
            ));
        }
    };
    let yaw = (yaw0 + yaw_degrees).to_radians();
    let pitch = pitch.to_radians();
    let forward = [
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    ];
    let mut camera = Camera::look_at(
        eye,
        [
            eye[0] + forward[0],
            eye[1] + forward[1],
            eye[2] + forward[2],
        ],
        NAMED_FOV_Y_DEGREES,
        width,
        height,
    );
    camera.forward = forward;
    Ok(camera)
}
