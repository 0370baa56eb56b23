//! The camera (SPEC §3) and its frustum planes.
//!
//! Keep in sync with `struct Camera` in `gpu/src/shaders/common.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use crate::ParamError;

/// A perspective camera. Positions are relative to the scene origin (SPEC §3).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Camera {
    /// Eye position.
    pub eye: [f32; 3],
    /// Vertical field of view, radians, in (0, π).
    pub fov_y: f32,
    /// View direction; need not be unit length, must not be zero or parallel to `up`.
    pub forward: [f32; 3],
    /// Near plane distance (> 0).
    pub near: f32,
    /// Approximate up vector (world +Z for GIS cameras).
    pub up: [f32; 3],
    /// Far plane distance (> near).
    pub far: f32,
    /// Viewport width in pixels.
    pub width: u32,
    /// Viewport height in pixels.
    pub height: u32,
    /// Explicit padding.
    pub _pad0: [u32; 2],
}
const _: () = assert!(core::mem::size_of::<Camera>() == 64);

/// An orthonormal camera frame: `forward`, `right`, `up` (right-handed: right = forward × up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraBasis {
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit right vector.
    pub right: Vec3,
    /// Unit up vector, orthogonal to both.
    pub up: Vec3,
}

/// Six inward-facing planes `(n, w)` with unit `n`: a point `p` is inside when `n · (p - eye) + w >= 0`.
/// Order: left, right, bottom, top, near, far. `Pod`, so [`crate::ViewUniform`] can embed it
/// (mirrored by `struct FrustumPlanes` in `gpu/src/shaders/common.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct FrustumPlanes {
    /// Planes as `[nx, ny, nz, w]`, relative to the eye.
    pub planes: [[f32; 4]; 6],
}

impl Camera {
    /// A camera at `eye` looking at `target`, world +Z up.
    pub fn look_at(
        eye: [f32; 3],
        target: [f32; 3],
        fov_y_degrees: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let forward = (Vec3::from(target) - Vec3::from(eye)).to_array();
        Self {
            eye,
            fov_y: fov_y_degrees.to_radians(),
            forward,
            near: 0.5,
            up: [0.0, 0.0, 1.0],
            far: 20_000.0,
            width,
            height,
            _pad0: [0; 2],
        }
    }

    /// Rejects cameras no stage can use, naming the field and value (SPEC §7).
    pub fn validate(&self) -> Result<(), ParamError> {
        let bad = |field, value: String, reason| {
            Err(ParamError {
                field,
                value,
                reason,
            })
        };
        let finite3 = |v: [f32; 3]| v.iter().all(|x| x.is_finite());
        if !finite3(self.eye) {
            return bad(
                "camera.eye",
                format!("{:?}", self.eye),
                "expected finite coordinates",
            );
        }
        if !finite3(self.forward) || Vec3::from(self.forward).length_squared() < 1e-12 {
            return bad(
                "camera.forward",
                format!("{:?}", self.forward),
                "expected a finite, non-zero direction",
            );
        }
        if !finite3(self.up) || Vec3::from(self.up).length_squared() < 1e-12 {
            return bad(
                "camera.up",
                format!("{:?}", self.up),
                "expected a finite, non-zero direction",
            );
        }
        let f = Vec3::from(self.forward).normalize();
        if f.cross(Vec3::from(self.up).normalize()).length() < 1e-4 {
            return bad(
                "camera.forward",
                format!("{:?}", self.forward),
                "is parallel to camera.up: the view has no defined roll; tilt it by more than 0.006° or change up",
            );
        }
        if !(self.fov_y.is_finite() && self.fov_y > 1e-4 && self.fov_y < 3.1) {
            return bad(
                "camera.fov_y",
                self.fov_y.to_string(),
                "expected a finite angle in (0.0001, 3.1) radians",
            );
        }
        if !(self.near.is_finite() && self.near > 0.0) {
            return bad(
                "camera.near",
                self.near.to_string(),
                "expected a finite distance > 0",
            );
        }
        if !(self.far.is_finite() && self.far > self.near) {
            return bad(
                "camera.far",
                self.far.to_string(),
                "expected a finite distance > near",
            );
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return bad(
                "camera.viewport",
                format!("{}x{}", self.width, self.height),
                "expected 1..=16384 pixels per side",
            );
        }
        Ok(())
    }

    /// The orthonormal frame. Call on a validated camera.
    pub fn basis(&self) -> CameraBasis {
        let forward = Vec3::from(self.forward).normalize();
        let right = forward.cross(Vec3::from(self.up)).normalize();
        let up = right.cross(forward);
        CameraBasis { forward, right, up }
    }

    /// Width over height.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }

    /// World-to-view matrix (right-handed, looking down -Z in view space).
    pub fn view_matrix(&self) -> Mat4 {
        let b = self.basis();
        let eye = Vec3::from(self.eye);
        // Rows: right, up, -forward; translation moves the eye to the origin.
        Mat4::from_cols(
            glam::Vec4::new(b.right.x, b.up.x, -b.forward.x, 0.0),
            glam::Vec4::new(b.right.y, b.up.y, -b.forward.y, 0.0),
            glam::Vec4::new(b.right.z, b.up.z, -b.forward.z, 0.0),
            glam::Vec4::new(-b.right.dot(eye), -b.up.dot(eye), b.forward.dot(eye), 1.0),
        )
    }

    /// View-to-clip matrix with wgpu's depth range 0..1.
    pub fn projection_matrix(&self) -> Mat4 {
        // Right-handed view space (looking down -Z) to wgpu clip space with depth 0 at near, 1 at far.
        let f = 1.0 / (self.fov_y * 0.5).tan();
        let range = self.far / (self.near - self.far);
        Mat4::from_cols(
            glam::Vec4::new(f / self.aspect(), 0.0, 0.0, 0.0),
            glam::Vec4::new(0.0, f, 0.0, 0.0),
            glam::Vec4::new(0.0, 0.0, range, -1.0),
            glam::Vec4::new(0.0, 0.0, range * self.near, 0.0),
        )
    }

    /// `projection * view`.
    pub fn view_projection(&self) -> Mat4 {
        self.projection_matrix() * self.view_matrix()
    }

    /// The six frustum planes, built directly from the basis (no matrix inversion, so they are as
    /// exact as `f32` allows).
    pub fn frustum(&self) -> FrustumPlanes {
        let b = self.basis();
        let ty = (self.fov_y * 0.5).tan();
        let tx = ty * self.aspect();
        let plane = |n: Vec3, w: f32| {
            let len = n.length();
            [n.x / len, n.y / len, n.z / len, w / len]
        };
        FrustumPlanes {
            planes: [
                plane(b.forward * tx + b.right, 0.0),
                plane(b.forward * tx - b.right, 0.0),
                plane(b.forward * ty + b.up, 0.0),
                plane(b.forward * ty - b.up, 0.0),
                plane(b.forward, -self.near),
                plane(-b.forward, self.far),
            ],
        }
    }
}

impl FrustumPlanes {
    /// Whether the sphere `(center, radius)` may intersect the frustum. Keep in sync with
    /// `sphere_visible` in `gpu/src/shaders/common.wgsl`. Conservative: a sphere that
    /// is outside only by less than [`crate::selection_margin`] counts as inside, and a sphere outside
    /// no single plane but outside the frustum near a corner counts as inside (the usual plane test).
    pub fn sphere_visible(&self, center: [f32; 3], radius: f32, eye: [f32; 3]) -> bool {
        let rel = [center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]];
        let m = crate::selection_margin(rel, radius);
        self.planes
            .iter()
            .all(|p| p[0] * rel[0] + p[1] * rel[1] + p[2] * rel[2] + p[3] >= -radius - m)
    }
}

impl FrustumPlanes {
    /// Whether the axis-aligned box `center ± extent` may intersect the frustum: the plane test with
    /// the box's effective radius `Σ_k |n_k| e_k` per plane (C§4.5, C§4.6.3), widened by
    /// [`crate::interval::aabb_margin`]. Conservative like [`FrustumPlanes::sphere_visible`]. Keep in
    /// sync with `aabb_visible` in `gpu/src/shaders/common.wgsl`.
    pub fn aabb_visible(&self, center: [f32; 3], extent: [f32; 3], eye: [f32; 3]) -> bool {
        let rel = [center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]];
        let m = crate::interval::aabb_margin(rel, extent);
        self.planes.iter().all(|p| {
            let r = p[0].abs() * extent[0] + p[1].abs() * extent[1] + p[2].abs() * extent[2];
            p[0] * rel[0] + p[1] * rel[1] + p[2] * rel[2] + p[3] >= -r - m
        })
    }

    /// Whether the box lies wholly inside every plane (no margin: a box within the margin of a
    /// plane counts as partially visible). Guerrero's `partially_visible` (G§3 Fig. 4) is its
    /// negation. Keep in sync with `aabb_inside` in `gpu/src/shaders/common.wgsl`.
    pub fn aabb_inside(&self, center: [f32; 3], extent: [f32; 3], eye: [f32; 3]) -> bool {
        let rel = [center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]];
        let m = crate::interval::aabb_margin(rel, extent);
        self.planes.iter().all(|p| {
            let r = p[0].abs() * extent[0] + p[1].abs() * extent[1] + p[2].abs() * extent[2];
            p[0] * rel[0] + p[1] * rel[1] + p[2] * rel[2] + p[3] >= r + m
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera::look_at([0.0, 0.0, 10.0], [100.0, 0.0, 10.0], 60.0, 160, 90)
    }

    #[test]
    fn frustum_keeps_what_is_ahead_and_drops_what_is_behind() {
        let c = cam();
        c.validate().unwrap();
        let f = c.frustum();
        assert!(f.sphere_visible([50.0, 0.0, 10.0], 1.0, c.eye));
        assert!(!f.sphere_visible([-50.0, 0.0, 10.0], 1.0, c.eye));
        assert!(!f.sphere_visible([50.0, 100.0, 10.0], 1.0, c.eye));
        assert!(!f.sphere_visible([30_000.0, 0.0, 10.0], 1.0, c.eye));
        // Camera inside the sphere: always visible.
        assert!(f.sphere_visible([0.0, 0.0, 10.0], 5.0, c.eye));
    }

    #[test]
    fn frustum_planes_agree_with_the_projection_matrix() {
        let c = cam();
        let vp = c.view_projection();
        let f = c.frustum();
        for p in [
            [50.0f32, 20.0, 3.0],
            [50.0, 40.0, 10.0],
            [5.0, -2.0, 12.0],
            [200.0, -100.0, 40.0],
        ] {
            let clip = vp * glam::Vec4::new(p[0], p[1], p[2], 1.0);
            let ndc = clip.truncate() / clip.w;
            let inside_matrix = clip.w > 0.0
                && ndc.x.abs() <= 1.0
                && ndc.y.abs() <= 1.0
                && (0.0..=1.0).contains(&ndc.z);
            assert_eq!(
                f.sphere_visible(p, 0.0, c.eye),
                inside_matrix,
                "{p:?} ndc {ndc:?}"
            );
        }
    }

    #[test]
    fn aabb_test_keeps_boxes_that_reach_in() {
        let c = cam();
        let f = c.frustum();
        // Centre outside the left plane, but the box reaches in; the sphere of radius 1 does not.
        // At x = 50 the side planes are at |y| = 50 tan(45.7°) = 51.3.
        assert!(f.aabb_visible([50.0, 55.0, 10.0], [1.0, 5.0, 1.0], c.eye));
        assert!(!f.sphere_visible([50.0, 55.0, 10.0], 1.0, c.eye));
        assert!(!f.aabb_visible([50.0, 60.0, 10.0], [1.0, 5.0, 1.0], c.eye));
        assert!(!f.aabb_visible([-50.0, 0.0, 10.0], [1.0, 1.0, 1.0], c.eye));
        assert!(f.aabb_inside([50.0, 0.0, 10.0], [1.0, 1.0, 1.0], c.eye));
        assert!(!f.aabb_inside([50.0, 48.0, 10.0], [1.0, 5.0, 1.0], c.eye));
    }

    #[test]
    fn bad_cameras_are_named() {
        let mut c = cam();
        c.forward = [0.0; 3];
        assert_eq!(c.validate().unwrap_err().field, "camera.forward");
        let mut c = cam();
        c.forward = [0.0, 0.0, -1.0];
        assert!(c.validate().unwrap_err().reason.contains("parallel"));
        let mut c = cam();
        c.eye[1] = f32::NAN;
        assert_eq!(c.validate().unwrap_err().field, "camera.eye");
        let mut c = cam();
        c.near = 0.0;
        assert_eq!(c.validate().unwrap_err().field, "camera.near");
    }
}
