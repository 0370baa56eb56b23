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
    /// Viewport width in pixels (of the tile, for a tile camera).
    pub width: u32,
    /// Viewport height in pixels (of the tile, for a tile camera).
    pub height: u32,
    /// `[0, 0]` for a whole frame. A tile camera ([`Camera::tile`]) renders the pixels
    /// `x0..x0 + width`, `y0..y0 + height` of a `frame_w x frame_h` frame of the same camera:
    /// `[x0 | y0 << 16, frame_w | frame_h << 16]` (an off-centre projection; issue 15's
    /// four-tiles relation). The GPU reads none of it: the projection, the frustum planes and
    /// the dither origin are derived on the CPU.
    pub tile: [u32; 2],
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
            tile: [0; 2],
        }
    }

    /// The camera of the tile `x0..x0 + w`, `y0..y0 + h` (pixels, from the top-left) of this
    /// whole-frame camera's frame: its projection is this camera's, followed by the map of that
    /// rectangle of NDC onto the tile's own NDC (an off-centre frustum), its frustum planes bound
    /// the tile's pyramid, and its fragments use the frame's pixel coordinates for the dither
    /// ([`Camera::pixel_origin`]). Call on a validated whole-frame camera; the rectangle must lie
    /// inside the frame ([`Camera::validate`] checks).
    pub fn tile(&self, x0: u32, y0: u32, w: u32, h: u32) -> Camera {
        assert!(self.tile == [0; 2], "a tile of a tile");
        Camera {
            width: w,
            height: h,
            tile: [x0 | (y0 << 16), self.width | (self.height << 16)],
            ..*self
        }
    }

    /// Whether this is a tile camera ([`Camera::tile`]).
    pub fn is_tile(&self) -> bool {
        self.tile != [0; 2]
    }

    /// The frame's pixel of this viewport's pixel `(0, 0)`: `(x0, y0)` of a tile, `(0, 0)` of a
    /// whole frame. The dither threshold of a fragment is that of its frame pixel.
    pub fn pixel_origin(&self) -> [u32; 2] {
        [self.tile[0] & 0xffff, self.tile[0] >> 16]
    }

    /// The whole frame's size: `(width, height)` of a whole-frame camera.
    pub fn frame_size(&self) -> [u32; 2] {
        if self.is_tile() {
            [self.tile[1] & 0xffff, self.tile[1] >> 16]
        } else {
            [self.width, self.height]
        }
    }

    /// Rejects cameras no stage can use, naming the field and value (SPEC §7).
    pub fn validate(&self) -> Result<(), ParamError> {
        let bad = |field, value: String, reason: &'static str| {
            Err(ParamError {
                field,
                value,
                reason: reason.into(),
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
        if self.is_tile() {
            let [x0, y0] = self.pixel_origin();
            let [fw, fh] = self.frame_size();
            if fw == 0 || fh == 0 || x0 + self.width > fw || y0 + self.height > fh {
                return bad(
                    "camera.tile",
                    format!(
                        "{}x{} at ({x0}, {y0}) of {fw}x{fh}",
                        self.width, self.height
                    ),
                    "expected a tile inside its frame",
                );
            }
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

    /// Width over height (of the whole frame, for a tile camera).
    pub fn aspect(&self) -> f32 {
        let [w, h] = self.frame_size();
        w as f32 / h as f32
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

    /// View-to-clip matrix with wgpu's depth range 0..1. For a tile camera: the frame's
    /// projection followed by the map of the tile's NDC rectangle onto `[-1, 1]²` (x and y only:
    /// depth and `w` are the frame's).
    pub fn projection_matrix(&self) -> Mat4 {
        // Right-handed view space (looking down -Z) to wgpu clip space with depth 0 at near, 1 at far.
        let f = 1.0 / (self.fov_y * 0.5).tan();
        let range = self.far / (self.near - self.far);
        let frame = Mat4::from_cols(
            glam::Vec4::new(f / self.aspect(), 0.0, 0.0, 0.0),
            glam::Vec4::new(0.0, f, 0.0, 0.0),
            glam::Vec4::new(0.0, 0.0, range, -1.0),
            glam::Vec4::new(0.0, 0.0, range * self.near, 0.0),
        );
        if !self.is_tile() {
            return frame;
        }
        // Frame pixel px = (x_ndc + 1) W / 2; tile pixel px - x0 = (x'_ndc + 1) w / 2, so
        // x' = x W / w + (W - 2 x0 - w) / w; y points up in NDC and down in pixels:
        // y' = y H / h + (h - H + 2 y0) / h. In clip space the offsets multiply w.
        let [x0, y0] = self.pixel_origin().map(|v| v as f32);
        let [fw, fh] = self.frame_size().map(|v| v as f32);
        let (w, h) = (self.width as f32, self.height as f32);
        let to_tile = Mat4::from_cols(
            glam::Vec4::new(fw / w, 0.0, 0.0, 0.0),
            glam::Vec4::new(0.0, fh / h, 0.0, 0.0),
            glam::Vec4::new(0.0, 0.0, 1.0, 0.0),
            glam::Vec4::new((fw - 2.0 * x0 - w) / w, (h - fh + 2.0 * y0) / h, 0.0, 1.0),
        );
        to_tile * frame
    }

    /// `projection * view`.
    pub fn view_projection(&self) -> Mat4 {
        self.projection_matrix() * self.view_matrix()
    }

    /// The six frustum planes, built directly from the basis (no matrix inversion, so they are as
    /// exact as `f32` allows). A tile camera's side planes bound the tile's (off-centre) pyramid.
    pub fn frustum(&self) -> FrustumPlanes {
        let b = self.basis();
        let ty = (self.fov_y * 0.5).tan();
        let tx = ty * self.aspect();
        let plane = |n: Vec3, w: f32| {
            let len = n.length();
            [n.x / len, n.y / len, n.z / len, w / len]
        };
        if self.is_tile() {
            // The tangents of the tile's edges (left, right, bottom, top) as fractions of the
            // frame's half-extents; the whole frame's are -tx, tx, -ty, ty.
            let [x0, y0] = self.pixel_origin().map(|v| v as f32);
            let [fw, fh] = self.frame_size().map(|v| v as f32);
            let (w, h) = (self.width as f32, self.height as f32);
            let left = tx * (2.0 * x0 / fw - 1.0);
            let right = tx * (2.0 * (x0 + w) / fw - 1.0);
            let top = ty * (1.0 - 2.0 * y0 / fh);
            let bottom = ty * (1.0 - 2.0 * (y0 + h) / fh);
            return FrustumPlanes {
                planes: [
                    plane(b.right - b.forward * left, 0.0),
                    plane(b.forward * right - b.right, 0.0),
                    plane(b.up - b.forward * bottom, 0.0),
                    plane(b.forward * top - b.up, 0.0),
                    plane(b.forward, -self.near),
                    plane(-b.forward, self.far),
                ],
            };
        }
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
            .all(|p| sphere_inside_plane(p, rel, radius, m))
    }

    /// Per plane (left, right, bottom, top, near, far): whether the sphere is outside it, by the
    /// test of [`FrustumPlanes::sphere_visible`] (which is "outside none"). For threshold
    /// coverage (`crate::coverage`).
    pub fn sphere_outside_planes(&self, center: [f32; 3], radius: f32, eye: [f32; 3]) -> [bool; 6] {
        let rel = [center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]];
        let m = crate::selection_margin(rel, radius);
        self.planes
            .map(|p| !sphere_inside_plane(&p, rel, radius, m))
    }
}

/// The sphere's plane test: `n · (c - e) + w >= -r - margin`.
#[inline(always)]
fn sphere_inside_plane(p: &[f32; 4], rel: [f32; 3], radius: f32, m: f32) -> bool {
    p[0] * rel[0] + p[1] * rel[1] + p[2] * rel[2] + p[3] >= -radius - m
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

    /// The degenerate-direction bound of `validate` (squared length 1e-12) on both sides: a
    /// forward of squared length 5e-13 is refused naming `camera.forward`, one of 2.25e-12 is
    /// accepted. Added for a survivor of issue 36's Rust sample (mutant 1773: the bound 1e-12 →
    /// 1e-13 went unseen).
    #[test]
    fn a_forward_just_below_the_degenerate_bound_is_refused_and_just_above_accepted() {
        let refused = Camera {
            forward: [5e-13f32.sqrt(), 0.0, 0.0],
            ..cam()
        };
        let err = refused.validate().expect_err("a degenerate forward");
        assert!(format!("{err}").contains("camera.forward"), "{err}");
        let accepted = Camera {
            forward: [1.5e-6, 0.0, 0.0],
            ..cam()
        };
        accepted.validate().expect("a short but valid forward");
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
    fn a_tile_sees_its_rectangle_of_the_frame() {
        let c = cam();
        let t = c.tile(40, 30, 70, 50);
        t.validate().unwrap();
        assert_eq!((t.pixel_origin(), t.frame_size()), ([40, 30], [160, 90]));
        let (vp, tp, tf) = (c.view_projection(), t.view_projection(), t.frustum());
        let mut inside = 0;
        for i in 0..40 {
            for j in 0..20 {
                let p = [60.0f32, -60.0 + 3.0 * i as f32, -20.0 + 3.0 * j as f32];
                let (a, b) = (
                    vp * glam::Vec4::new(p[0], p[1], p[2], 1.0),
                    tp * glam::Vec4::new(p[0], p[1], p[2], 1.0),
                );
                // Frame pixel and tile pixel (wgpu: y down), and depth.
                let fx = (a.x / a.w + 1.0) * 0.5 * 160.0;
                let fy = (1.0 - a.y / a.w) * 0.5 * 90.0;
                let tx = (b.x / b.w + 1.0) * 0.5 * 70.0;
                let ty = (1.0 - b.y / b.w) * 0.5 * 50.0;
                assert!(
                    (fx - 40.0 - tx).abs() < 1e-3 && (fy - 30.0 - ty).abs() < 1e-3,
                    "{p:?}"
                );
                assert!((a.z / a.w - b.z / b.w).abs() < 1e-6, "{p:?}");
                // The tile's frustum planes bound exactly its rectangle (away from the edges,
                // where the selection margin widens them).
                let in_tile = (0.0..70.0).contains(&tx) && (0.0..50.0).contains(&ty);
                let near_edge = [tx, 70.0 - tx, ty, 50.0 - ty].iter().any(|d| d.abs() < 0.5);
                if !near_edge {
                    assert_eq!(tf.sphere_visible(p, 0.0, c.eye), in_tile, "{p:?}");
                    inside += usize::from(in_tile);
                }
            }
        }
        assert!(inside > 50 && inside < 700, "{inside} points in the tile");
        let outside = Camera { width: 121, ..t };
        assert_eq!(outside.validate().unwrap_err().field, "camera.tile");
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
