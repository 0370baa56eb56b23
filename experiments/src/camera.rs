//! The camera of `forestlod render` and `forestlod select`: a named camera of E§5.0.1 (`--camera
//! far|medium|close`, turned by `--yaw`), or a free one (`--eye X,Y,Z --look-at X,Y,Z [--fov
//! DEG]`) in scene-local metres: the coordinates of the scene's trees and terrain, that is world
//! coordinates minus the scene's `f64` origin, Z up (`forestlod scene info` prints the origin and
//! the footprint).

use clap::Args;
use forestlod_reference::InputError;
use forestlod_reference::cameras::{NAMED_FOV_Y_DEGREES, named_camera};
use forestlod_reference::scene::Scene;
use forestlod_shared::Camera;

/// Smallest and largest vertical field of view accepted by `--fov`, degrees (the camera model
/// takes fov_y in (1e-4, 3.1) radians, 3.1 rad being about 177.6°).
pub const FOV_RANGE_DEGREES: (f32, f32) = (0.01, 177.0);

/// Smallest sine of the angle between the free camera's view and the vertical: the camera model
/// needs a defined roll (`Camera::validate` rejects a forward within 1e-4 rad of +Z).
const MIN_SIN_FROM_VERTICAL: f32 = 2e-4;

/// A validated free camera: eye, look-at point (scene-local metres), vertical fov (degrees).
pub type FreeView = ([f32; 3], [f32; 3], f32);

/// Which camera to render from.
#[derive(Args, Clone, Debug)]
pub struct CameraArgs {
    /// Named camera: far, medium, close (E§5.0.1). Replaced by --eye/--look-at.
    #[arg(long, default_value = "medium")]
    pub camera: String,
    /// Horizontal rotation of the named camera, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw: f32,
    /// Free camera: eye position X,Y,Z in scene-local metres (the scene's coordinates, origin
    /// subtracted, Z up); needs --look-at.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, requires = "look_at",
          conflicts_with_all = ["camera", "yaw"])]
    pub eye: Option<String>,
    /// Free camera: the point looked at, X,Y,Z in scene-local metres; not straight above or
    /// below the eye.
    #[arg(
        long,
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        requires = "eye"
    )]
    pub look_at: Option<String>,
    /// Free camera: vertical field of view, degrees in 0.01..=177 (default 60, as the named ones).
    #[arg(
        long,
        value_name = "DEG",
        allow_negative_numbers = true,
        requires = "eye"
    )]
    pub fov: Option<f32>,
}

impl Default for CameraArgs {
    fn default() -> Self {
        Self {
            camera: "medium".into(),
            yaw: 0.0,
            eye: None,
            look_at: None,
            fov: None,
        }
    }
}

fn flag_error(flag: &str, value: impl std::fmt::Display, reason: impl Into<String>) -> InputError {
    InputError::new("<command line>", flag, value, reason)
}

/// Parses `X,Y,Z` into three finite numbers.
pub fn parse_point(flag: &str, text: &str) -> Result<[f32; 3], InputError> {
    let bad = || {
        flag_error(
            flag,
            text,
            "expected X,Y,Z: three finite numbers in scene-local metres",
        )
    };
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut p = [0.0f32; 3];
    for (out, part) in p.iter_mut().zip(&parts) {
        *out = part.parse::<f32>().map_err(|_| bad())?;
        if !out.is_finite() {
            return Err(bad());
        }
    }
    Ok(p)
}

impl CameraArgs {
    /// Whether the free camera is chosen.
    pub fn is_free(&self) -> bool {
        self.eye.is_some()
    }

    /// A short name for summaries and file names: the named camera, or `free`.
    pub fn label(&self) -> &str {
        if self.is_free() { "free" } else { &self.camera }
    }

    /// The free camera's eye, look-at point and fov, validated (None for a named camera).
    pub fn free(&self) -> Result<Option<FreeView>, InputError> {
        let (Some(eye_text), Some(look_text)) = (&self.eye, &self.look_at) else {
            return Ok(None);
        };
        let eye = parse_point("--eye", eye_text)?;
        let look = parse_point("--look-at", look_text)?;
        let d = [look[0] - eye[0], look[1] - eye[1], look[2] - eye[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(len.is_finite() && len > 1e-3) {
            return Err(flag_error(
                "--look-at",
                look_text,
                "expected a point at least 1 mm away from --eye",
            ));
        }
        if (d[0] * d[0] + d[1] * d[1]).sqrt() / len < MIN_SIN_FROM_VERTICAL {
            return Err(flag_error(
                "--look-at",
                look_text,
                "is straight above or below --eye: a view along Z has no defined roll; move it sideways",
            ));
        }
        let fov = self.fov.unwrap_or(NAMED_FOV_Y_DEGREES);
        let (lo, hi) = FOV_RANGE_DEGREES;
        if !(fov.is_finite() && (lo..=hi).contains(&fov)) {
            return Err(flag_error(
                "--fov",
                fov,
                format!("expected a vertical field of view in degrees, {lo}..={hi}"),
            ));
        }
        Ok(Some((eye, look, fov)))
    }

    /// The validated camera for `scene` at `width` x `height`.
    pub fn camera(&self, scene: &Scene, width: u32, height: u32) -> Result<Camera, InputError> {
        let camera = match self.free()? {
            Some((eye, look, fov)) => Camera::look_at(eye, look, fov, width, height),
            None => named_camera(&self.camera, scene, self.yaw, width, height)?,
        };
        camera.validate()?;
        Ok(camera)
    }

    /// The camera as JSON for the metrics.
    pub fn json(&self) -> serde_json::Value {
        match self.free() {
            Ok(Some((eye, look, fov))) => serde_json::json!({
                "camera": "free", "eye": eye, "look_at": look, "fov_y_degrees": fov,
            }),
            _ => serde_json::json!({ "camera": self.camera, "yaw_degrees": self.yaw }),
        }
    }
}

/// The warning printed when a frame shows no tree, or None when it shows some.
pub fn no_tree_warning(
    scene: &Scene,
    commands: u32,
    tree_fragments: Option<u64>,
) -> Option<String> {
    if commands > 0 && tree_fragments.is_none_or(|f| f > 0) {
        return None;
    }
    let [x0, y0, x1, y1] = scene.bounds;
    Some(format!(
        "warning: this frame shows no tree ({commands} draw commands{}); the trees of scene {} stand in x {x0:.0}..{x1:.0}, y {y0:.0}..{y1:.0} m (scene-local)",
        tree_fragments
            .map(|f| format!(", {f} tree fragments written"))
            .unwrap_or_default(),
        scene.name,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn free(eye: &str, look: &str, fov: Option<f32>) -> Result<Option<FreeView>, InputError> {
        CameraArgs {
            eye: Some(eye.into()),
            look_at: Some(look.into()),
            fov,
            ..Default::default()
        }
        .free()
    }

    #[test]
    fn free_camera_validation() {
        assert!(free("0,0,10", "100,0,0", None).unwrap().is_some());
        assert!(free("-5, 2.5, 10", "100,0,0", Some(90.0)).is_ok());
        for (eye, look, fov, flag) in [
            ("0,0", "1,0,0", None, "--eye"),
            ("0,0,nan", "1,0,0", None, "--eye"),
            ("0,0,inf", "1,0,0", None, "--eye"),
            ("0,0,0", "1,0,x", None, "--look-at"),
            ("1,2,3", "1,2,3", None, "--look-at"),
            ("0,0,100", "0,0,0", None, "--look-at"),
            ("0,0,0", "1,0,0", Some(0.0), "--fov"),
            ("0,0,0", "1,0,0", Some(180.0), "--fov"),
            ("0,0,0", "1,0,0", Some(f32::NAN), "--fov"),
        ] {
            let e = free(eye, look, fov).unwrap_err();
            assert_eq!(e.position, flag, "{eye} {look} {fov:?}: {e}");
        }
    }
}
