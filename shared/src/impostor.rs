//! Hierarchical impostors (issue 33 item 2, C§4.6.3, Alg. 9): images of whole hierarchy nodes,
//! rendered from the current eye into an atlas, drawn as one world-space quad each, and refreshed
//! round robin while the camera moves. `--lod-levels 3 --far-lod impostor` turns them on; the
//! far level's plumbing (the cut's far code, far commands, the draw's far arm, the GPU's far
//! buffer) carries them, with the atlas as the far level's `texels`.
//!
//! ## Contract
//! - **Candidates** (C§4.6.3 `ImpostorHierarchyMaxDepth`): the hierarchy's nodes of depth at most
//!   `impostor_max_depth` (the root is depth 0).
//! - **Metric** ([`impostor_allowed`]), C§4.6.3's two parts plus one of ours: the eye lies farther
//!   than `impostor_min_distance` from the node's box; the bounding rectangle of the box's corners
//!   projected orthogonally on the plane through the box centre perpendicular to the direction to
//!   the eye covers fewer than `impostor_pixels²` pixels by C Eq. 4.3 (the corrected constant
//!   `C = f_px²`, [`crate::metric::metric_constant`]; the seed's `ImpostorWidth·ImpostorHeight`);
//!   and (ours) the box's screen rectangle ([`impostor_tile`]) fits a `impostor_pixels²` tile,
//!   every corner in front of the near plane. The last part keeps the tile at screen resolution:
//!   a freshly made impostor is the direct render of its node's trees, pixel for pixel.
//! - **Planning** (Alg. 9, `reference/src/impostor_cache.rs`): the impostored set is an
//!   **antichain** (no impostored node has an impostored ancestor). The seed's "siblings" in
//!   Alg. 9 and in "rendering impostor's node and its siblings" can only mean the descendants the
//!   impostor replaces (the design study's reading): siblings are disjoint regions.
//! - **The tile** ([`impostor_tile`]): the pixel rectangle that bounds the box's eight projected
//!   corners in the frame of the current camera, rendered by that camera restricted to the
//!   rectangle (an off-centre frustum, [`crate::Camera::tile`]). A rectangle reaching past the
//!   frame is rendered in a frame grown by a margin on every side with the same pixel size
//!   ([`impostor_tile`]'s `margin`); the dither of such a tile is the grown frame's.
//! - **The quad** ([`ImpostorQuad`]): the tile's rectangle carried back into the world on the
//!   plane through the box centre **perpendicular to the camera's view direction** (the seed:
//!   perpendicular to the direction to the box centre). Ours is parallel to the image plane, so
//!   the quad is a world rectangle whose texture mapping, seen from its creation eye, is affine:
//!   texel `(i, j)` lands on the frame pixel it was rendered from. Its depth is the box centre's
//!   view depth at creation; trees of other nodes in front of that plane but behind the node's
//!   nearest tree are sorted wrongly (counted by the properties).
//! - **Sampling**: nearest texel ([`impostor_texel`]), kept where its alpha is at least one half;
//!   kept fragments are opaque with the texel's colour (already lit by the tile's render) and
//!   the far level's LOD id. Nearest keeps the creation-eye image exact and the twins equal; the
//!   price is blocky magnification while an impostor waits for its refresh.
//! - **Refresh** (C§4.6.3): every `impostor_update_interval` frames the plan runs (removals, then
//!   creations, each rendered at once); every `impostor_refresh_interval` frames the next
//!   `impostor_refresh_number` impostors in slot order (round robin) are rendered again from the
//!   current eye, or removed when the metric no longer allows them. The state is a pure function
//!   of the camera path's prefix: replay is deterministic.
//! - **Per-node far data** ([`crate::FarNode`] under `far_lod = impostor`): `cell_offset` is the
//!   node's quad in the far level's cells, `cell_count` 1 when the node is impostored (it goes far
//!   when drawn) and 0 otherwise, `hull_count` the number of impostored strict descendants (the
//!   cut recurses through such a node so that no command covers an impostored node's trees).

use bytemuck::{Pod, Zeroable};

use crate::{Camera, Params};

/// One impostor's quad (module docs): the world rectangle `center ± right ± up` and its tile.
/// As large as a [`crate::FarCell`] (48 B), so the far level's `cells` hold quads under
/// `far_lod = impostor` (`bytemuck::cast`) and the GPU's far buffer keeps its 12-word stride.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ImpostorQuad {
    /// World centre of the rectangle.
    pub center: [f32; 3],
    /// Atlas slot of the tile.
    pub slot: u32,
    /// Half the rectangle along the image's +x (world vector).
    pub right: [f32; 3],
    /// The tile's size in texels: `width | height << 16`.
    pub size: u32,
    /// Half the rectangle along the image's up (world vector, image rows run down).
    pub up: [f32; 3],
    /// Explicit padding.
    pub _pad0: u32,
}
const _: () = assert!(core::mem::size_of::<ImpostorQuad>() == 48);
const _: () =
    assert!(core::mem::size_of::<ImpostorQuad>() == core::mem::size_of::<crate::FarCell>());

impl ImpostorQuad {
    /// The quad as a far cell (the far level's `cells` under `far_lod = impostor`).
    pub fn to_cell(self) -> crate::FarCell {
        bytemuck::cast(self)
    }

    /// The quad a far cell holds under `far_lod = impostor`.
    pub fn from_cell(cell: crate::FarCell) -> Self {
        bytemuck::cast(cell)
    }

    /// The tile's `(width, height)` in texels.
    pub fn tile_size(&self) -> (u32, u32) {
        (self.size & 0xffff, self.size >> 16)
    }
}

/// The greatest `impostor_pixels` (a tile side): also the greatest margin a tile's grown frame
/// needs, `u16` pixel coordinates with room.
pub const MAX_IMPOSTOR_PIXELS: u32 = 256;

/// The smallest `impostor_pixels`.
pub const MIN_IMPOSTOR_PIXELS: u32 = 8;

/// The most texels of an atlas (`impostor_tiles · impostor_pixels²`): 64 MiB of RGBA8.
pub const MAX_IMPOSTOR_TEXELS: u64 = 1 << 24;

/// The corner `v` (`0..6`, two triangles) of an impostor quad as `(s, t)` in `[-1, 1]²`, `t` up
/// (as [`crate::sprite_corner`]), and its texture coordinate `(u, v)` in `[0, 1]²`, `v` down.
pub fn impostor_corner(v: u32) -> ([f32; 2], [f32; 2]) {
    let c = crate::sprite_corner(v);
    (c, [(c[0] + 1.0) * 0.5, (1.0 - c[1]) * 0.5])
}

/// The texel of a tile of `size = width | height << 16` at texture coordinate `(u, v)`
/// (nearest, module docs): its index in the tile's slot of `side²` texels, row by row.
/// Coordinates outside `[0, 1]` clamp to the edge texel; NaN reads texel 0.
pub fn impostor_texel(size: u32, side: u32, u: f32, v: f32) -> u32 {
    let (w, h) = (size & 0xffff, size >> 16);
    let x = ((u * w as f32).floor().max(0.0) as u32).min(w.max(1) - 1);
    let y = ((v * h as f32).floor().max(0.0) as u32).min(h.max(1) - 1);
    y * side + x
}

/// Whether a texel word (RGBA8, linear alpha in the top byte) is kept (module docs).
pub fn impostor_texel_kept(word: u32) -> bool {
    (word >> 24) >= 128
}

/// A node's tile (module docs): the camera that renders it and the quad it is drawn on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpostorTile {
    /// The camera of the tile: the frame's camera (grown by `margin` pixels on each side when the
    /// rectangle reaches past the frame) restricted to the rectangle.
    pub camera: Camera,
    /// The whole frame the tile is a window of: the frame's own camera, or the grown one. The
    /// reference renders the tile as this frame's pixels in the rectangle (a masked draw), so
    /// that a tile inside the frame is bit for bit the frame's own pixels.
    pub frame: Camera,
    /// The quad, `slot` 0 (the cache sets it).
    pub quad: ImpostorQuad,
    /// The rectangle in the frame's pixels: `x0, y0` (may be negative) and `width, height`.
    pub rect: [i32; 4],
    /// Pixels the frame was grown by on each side (0 when the rectangle lies in the frame).
    pub margin: u32,
}

/// The eight corners of the box `center ± extent`.
pub fn box_corners(center: [f32; 3], extent: [f32; 3]) -> [[f32; 3]; 8] {
    core::array::from_fn(|k| {
        core::array::from_fn(|a| {
            let s = if k >> a & 1 == 1 { 1.0 } else { -1.0 };
            center[a] + s * extent[a]
        })
    })
}

/// The tile of the box `center ± extent` seen by the whole-frame `camera` (module docs), or
/// `None` when a corner lies at or before the near plane, the rectangle is wider or taller than
/// `side` pixels, or a grown frame would not fit `u16` pixel coordinates.
pub fn impostor_tile(
    camera: &Camera,
    center: [f32; 3],
    extent: [f32; 3],
    side: u32,
) -> Option<ImpostorTile> {
    let b = camera.basis();
    let eye = glam::Vec3::from(camera.eye);
    let t = (camera.fov_y * 0.5).tan();
    let a = camera.aspect();
    let (fw, fh) = (camera.width as f32, camera.height as f32);
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
    for p in box_corners(center, extent) {
        let rel = glam::Vec3::from(p) - eye;
        let z = rel.dot(b.forward);
        // NaN is not greater and rejects the node.
        if z.partial_cmp(&camera.near) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        let x = rel.dot(b.right) / (z * t * a);
        let y = rel.dot(b.up) / (z * t);
        let (px, py) = ((x + 1.0) * 0.5 * fw, (1.0 - y) * 0.5 * fh);
        x_lo = x_lo.min(px);
        x_hi = x_hi.max(px);
        y_lo = y_lo.min(py);
        y_hi = y_hi.max(py);
    }
    let (rw, rh) = (x_hi - x_lo, y_hi - y_lo);
    if rw.is_nan() || rh.is_nan() || rw > side as f32 || rh > side as f32 {
        return None;
    }
    let x0 = x_lo.floor() as i32;
    let y0 = y_lo.floor() as i32;
    let w = (x_hi.ceil() as i32 - x0).max(1) as u32;
    let h = (y_hi.ceil() as i32 - y0).max(1) as u32;
    if w > side || h > side {
        return None;
    }
    // The margin: 0 inside the frame, else the side rounded up (every rectangle that fits a tile
    // then lies in the grown frame).
    let inside =
        x0 >= 0 && y0 >= 0 && x0 as u32 + w <= camera.width && y0 as u32 + h <= camera.height;
    let margin = if inside { 0 } else { MAX_IMPOSTOR_PIXELS };
    let (gw, gh) = (camera.width + 2 * margin, camera.height + 2 * margin);
    if gw > 0xffff || gh > 0xffff {
        return None;
    }
    let gx = x0 + margin as i32;
    let gy = y0 + margin as i32;
    if gx < 0 || gy < 0 || gx as u32 + w > gw || gy as u32 + h > gh {
        return None;
    }
    let grown = if margin == 0 {
        *camera
    } else {
        // Same pixel size and centre: tan(fov'/2) = tan(fov/2)·gh/fh.
        Camera {
            fov_y: 2.0 * (t * gh as f32 / fh).atan(),
            width: gw,
            height: gh,
            ..*camera
        }
    };
    let tile_camera = grown.tile(gx as u32, gy as u32, w, h);
    // The quad: the rectangle's corners carried to the plane of view depth `d` (module docs).
    let d = (glam::Vec3::from(center) - eye).dot(b.forward);
    let ndc_x = |px: f32| 2.0 * px / fw - 1.0;
    let ndc_y = |py: f32| 1.0 - 2.0 * py / fh;
    let (cx, cy) = (
        ndc_x(x0 as f32 + w as f32 * 0.5),
        ndc_y(y0 as f32 + h as f32 * 0.5),
    );
    let (hx, hy) = (w as f32 / fw, h as f32 / fh);
    let quad_center = eye + b.forward * d + b.right * (cx * t * a * d) + b.up * (cy * t * d);
    let quad = ImpostorQuad {
        center: quad_center.to_array(),
        slot: 0,
        right: (b.right * (hx * t * a * d)).to_array(),
        size: w | (h << 16),
        up: (b.up * (hy * t * d)).to_array(),
        _pad0: 0,
    };
    Some(ImpostorTile {
        camera: tile_camera,
        frame: grown,
        quad,
        rect: [x0, y0, w as i32, h as i32],
        margin,
    })
}

/// C§4.6.3's impostor metric on the box `center ± extent` for `camera` (module docs): the pixels
/// of its bounding rectangle on the plane through its centre perpendicular to the direction to
/// the eye, by C Eq. 4.3 at the distance to the centre. Infinite when the eye is at the centre.
pub fn impostor_pixels(camera: &Camera, center: [f32; 3], extent: [f32; 3]) -> f64 {
    let rel = glam::Vec3::from(center) - glam::Vec3::from(camera.eye);
    let dist = rel.length();
    if dist.is_nan() || dist <= 0.0 {
        return f64::INFINITY;
    }
    let v = (-rel / dist).to_array();
    let (r, u) = crate::octahedral::frame_basis(v);
    let half = crate::sprite_half(extent, r, u);
    let area = 4.0 * half[0] as f64 * half[1] as f64;
    crate::metric::pixel_area(
        crate::metric::metric_constant(camera, false),
        area,
        dist as f64,
    )
}

/// Whether `params` allow the node with box `center ± extent` to be impostored from `camera`
/// (module docs: distance, C§4.6.3's area, and a tile that fits), with its tile when they do.
pub fn impostor_allowed(
    camera: &Camera,
    params: &Params,
    center: [f32; 3],
    extent: [f32; 3],
) -> Option<ImpostorTile> {
    let distance = crate::aabb_distance(center, extent, camera.eye);
    if distance.is_nan() || distance <= params.impostor_min_distance {
        return None;
    }
    let side = params.impostor_pixels;
    let pixels = impostor_pixels(camera, center, extent);
    if pixels.is_nan() || pixels >= (side as f64) * (side as f64) {
        return None;
    }
    impostor_tile(camera, center, extent, side)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera::look_at([0.0, -500.0, 30.0], [0.0, 0.0, 15.0], 60.0, 640, 360)
    }

    #[test]
    fn a_tile_inside_the_frame_is_the_frames_own_window() {
        let cam = camera();
        let tile = impostor_tile(&cam, [0.0, 0.0, 15.0], [10.0, 10.0, 15.0], 128).expect("fits");
        assert_eq!(tile.margin, 0);
        let [x0, y0, w, h] = tile.rect;
        assert_eq!(tile.camera.pixel_origin(), [x0 as u32, y0 as u32]);
        assert_eq!(
            [tile.camera.width, tile.camera.height],
            [w as u32, h as u32]
        );
        // The quad's corners project onto the rectangle's corners.
        let vp = cam.view_projection();
        let q = tile.quad;
        for (s, t) in [(-1.0f32, 1.0f32), (1.0, -1.0)] {
            let p = glam::Vec3::from(q.center)
                + glam::Vec3::from(q.right) * s
                + glam::Vec3::from(q.up) * t;
            let c = vp * p.extend(1.0);
            let px = (c.x / c.w + 1.0) * 0.5 * 640.0;
            let py = (1.0 - c.y / c.w) * 0.5 * 360.0;
            let ex = x0 as f32 + if s > 0.0 { w as f32 } else { 0.0 };
            let ey = y0 as f32 + if t > 0.0 { 0.0 } else { h as f32 };
            assert!(
                (px - ex).abs() < 1e-3 && (py - ey).abs() < 1e-3,
                "{px} {py} vs {ex} {ey}"
            );
        }
    }

    #[test]
    fn a_rectangle_past_the_frame_grows_the_frame_and_keeps_the_pixel_size() {
        let cam = camera();
        // Far to the right of the view axis, still in front.
        let c = [560.0, 0.0, 15.0];
        let tile = impostor_tile(&cam, c, [10.0, 10.0, 15.0], 256).expect("fits");
        assert_eq!(tile.margin, MAX_IMPOSTOR_PIXELS);
        let f = 1.0 / (tile.camera.fov_y * 0.5).tan() * tile.camera.frame_size()[1] as f32;
        let f0 = 1.0 / (cam.fov_y * 0.5).tan() * cam.height as f32;
        assert!((f / f0 - 1.0).abs() < 1e-5, "pixel size {f} vs {f0}");
    }

    #[test]
    fn the_metric_refuses_near_large_and_behind() {
        let cam = camera();
        let p = Params {
            impostor_min_distance: 100.0,
            impostor_pixels: 64,
            ..Params::default()
        };
        let small = [10.0, 10.0, 15.0];
        assert!(impostor_allowed(&cam, &p, [0.0, 0.0, 15.0], small).is_some());
        // Too near (the eye within 100 m of the box).
        assert!(impostor_allowed(&cam, &p, [0.0, -450.0, 15.0], small).is_none());
        // Behind the eye.
        assert!(impostor_allowed(&cam, &p, [0.0, -900.0, 15.0], small).is_none());
        // Too large on screen.
        assert!(impostor_allowed(&cam, &p, [0.0, 0.0, 15.0], [100.0, 100.0, 15.0]).is_none());
    }

    #[test]
    fn nearest_texels_clamp_and_land_on_their_pixel() {
        let size = 10 | (4 << 16);
        assert_eq!(impostor_texel(size, 16, 0.0, 0.0), 0);
        assert_eq!(impostor_texel(size, 16, 0.999, 0.999), 3 * 16 + 9);
        assert_eq!(impostor_texel(size, 16, 1.5, -1.0), 9);
        assert_eq!(impostor_texel(size, 16, f32::NAN, 0.0), 0);
        assert_eq!(impostor_texel(size, 16, 0.55 / 10.0 * 10.0 / 10.0, 0.0), 0);
        assert_eq!(impostor_texel(size, 16, 3.5 / 10.0, 1.5 / 4.0), 16 + 3);
    }
}
