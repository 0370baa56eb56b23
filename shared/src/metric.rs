//! The LOD metric (issue 29): where a tree changes from its mesh (LOD0) to its billboard (LOD1).
//!
//! The thesis switches every tree at one view depth, `lod1_transition` (E§4.3): the
//! `distance` metric. Two screen-space metrics make the transition depth **per tree**, from the
//! tree's size on screen, so that it follows the viewport and the field of view:
//!
//! - **Pixel area** (C§4.6.3, Eqs. 4.1-4.5). A world area `A` at view depth `D`, facing the eye
//!   at the centre of the view, covers `A_s = C·A/D²` pixels (Eq. 4.3), so it covers `A_thr`
//!   pixels at `D = √(C·A/A_thr)` (Eq. 4.5). Celba's constant (Eq. 4.2) is
//!   `C = WIDTH·HEIGHT·N²/(W·H)` with `H = N·tan(FOVY/2)`, `W = (WIDTH/HEIGHT)·H` (Eq. 4.1); but
//!   his `W` and `H` are the **half**-sizes of the near-plane rectangle, whose area is `4WH`, so
//!   the pixels of an area are `A·N²/D² · WIDTH·HEIGHT/(4WH)`: the true constant is
//!   `C = (HEIGHT / (2 tan(FOVY/2)))² = f_px²` (`f_px`, the focal length in pixels; `N` cancels)
//!   and the seed's is 4x too large: its areas are 4x too many pixels and its switch depths 2x
//!   too far. [`LodMetric::PixelArea`] uses the true constant; [`LodMetric::PixelAreaSeed`]
//!   reproduces the seed as it behaved (its Table 5.2 thresholds then mean what they meant in
//!   its runs). The calibration test (`tests/tests/reference/metric.rs`) renders a square and
//!   counts its pixels: the seed's constant fails it by 4x. Eq. 4.3 ignores foreshortening and the
//!   off-axis stretch of a perspective view (a LOD metric, not a coverage count).
//! - **Screen-space error** (the 3D Tiles convention, `maximumScreenSpaceError`): a level whose
//!   geometric error is `e` metres shows `e · HEIGHT / (D · 2 tan(FOVY/2)) = e·f_px/D` pixels of
//!   error at depth `D`; LOD1 is allowed where that is at most the threshold `τ` pixels, from
//!   `D = e·f_px/τ` on ([`LodMetric::ScreenError`]).
//!
//! Both give a transition depth `T = s · size_m · factor`, with `s` the tree's scale, `size_m` a
//! measure of its mesh at unit scale ([`MeshMeta::area_size`], `√A` of the billboard's opaque
//! area; [`MeshMeta::error_size`], the billboard's geometric error; both measured at a level-view
//! bake, `reference::metric`) and `factor` one number per frame ([`metric_factor`]: `f_px·√(c/A_thr)`
//! or `f_px/τ`). The fade band keeps the distance mode's relative width: `[T·ρ, T]` with
//! `ρ = fade_start / lod1_transition` (the thesis's 750/1000).
//!
//! ## Contract (where the rule lives)
//! - [`crate::ViewUniform`] carries the metric (`metric`, `metric_factor`, `band_ratio`),
//!   so every stage that reads a band reads it from one place: [`crate::ViewUniform::mesh_band`]
//!   (a mesh at unit scale), [`crate::ViewUniform::group_band`] (a batch or node: its smallest
//!   tree's start, its largest tree's end) and [`crate::ViewUniform::with_band`] (the view
//!   constants with that band, so the one selection rule [`crate::ViewUniform::decide`] and the
//!   cut's [`crate::decide_node`] decide on it unchanged).
//! - **Conservative per tree**: a tree's band is `s·[k_s, k_e]` (`f32` products); a group's is
//!   `[s_min·k_s, s_max·k_e]` and contains every tree's band exactly (a product with a positive
//!   `f32` is monotone under rounding to nearest).
//! - With `distance` every band is the frame's `[fade_start, lod1_transition]`, bit for bit the
//!   thesis. With a scaled metric, unit scales and `size·factor = lod1_transition` (and the
//!   thesis's band, whose ratio is exact), every band is the frame's too: selection and images
//!   equal the distance mode's bit for bit (tested).
//! - The draw stage reads a command's mesh band from its `CommandData` and scales it by the tree's
//!   own scale; the per-tree `refine` does the same.
//!
//! Rejected design: uploading `k_m` per mesh per frame (the design study's reading) needs a new
//! buffer in four shaders; the product `size_m · factor` on both sides is the same `f32` and
//! needs none.

use crate::{Camera, MeshMeta, Params};

crate::modes::modes! {
    /// Which metric places the LOD0 → LOD1 transition (module docs).
    pub enum LodMetric {
        /// One view depth for every tree, `lod1_transition` (the thesis).
        Distance = 0 => "distance" ("E§4.3"),
        /// The tree's billboard covers `lod_pixel_area` pixels (C Eq. 4.3-4.5, constant corrected).
        PixelArea = 1 => "pixel-area" ("C§4.6.3, corrected"),
        /// As `pixel-area` with Celba's constant as printed, 4x too large (C Eq. 4.2 as written).
        PixelAreaSeed = 2 => "pixel-area-seed" ("C Eq. 4.2 as written"),
        /// The billboard's geometric error covers `lod_screen_error` pixels (3D Tiles).
        ScreenError = 3 => "screen-error" ("3D Tiles SSE"),
    }
}

impl LodMetric {
    /// Whether the transition depth scales with the tree (every metric but `distance`).
    pub fn is_scaled(self) -> bool {
        self != LodMetric::Distance
    }
}

/// The focal length in pixels, `HEIGHT / (2 tan(FOVY/2))`, of the whole frame (a tile camera's
/// frame, [`Camera::frame_size`]: tiles of one frame share its metric).
pub fn focal_px(camera: &Camera) -> f64 {
    camera.frame_size()[1] as f64 / (2.0 * (camera.fov_y as f64 * 0.5).tan())
}

/// Celba's metric constant `C` (Eq. 4.2): `f_px²` (corrected, `seed = false`), or the seed's
/// `4 f_px²` (module docs).
pub fn metric_constant(camera: &Camera, seed: bool) -> f64 {
    let f = focal_px(camera);
    f * f * if seed { 4.0 } else { 1.0 }
}

/// C Eq. 4.3: the pixels `A_s = C·A/D²` of a world area `A` at view depth `D`.
pub fn pixel_area(c: f64, area: f64, depth: f64) -> f64 {
    c * area / (depth * depth)
}

/// C Eq. 4.4: the world area `A = D²·A_s/C` that covers `A_s` pixels at view depth `D`.
pub fn area_for_pixels(c: f64, pixels: f64, depth: f64) -> f64 {
    depth * depth * pixels / c
}

/// C Eq. 4.5: the view depth `D = √(C·A/A_s)` at which a world area `A` covers `A_s` pixels.
pub fn depth_for_pixels(c: f64, area: f64, pixels: f64) -> f64 {
    (c * area / pixels).sqrt()
}

/// The 3D Tiles screen-space error, in pixels, of a geometric error `e` metres at view depth `D`:
/// `e · HEIGHT / (D · 2 tan(FOVY/2))`.
pub fn screen_space_error(camera: &Camera, error: f64, depth: f64) -> f64 {
    error * focal_px(camera) / depth
}

/// The frame's transition depth per unit of mesh size (module docs), `f32`: `f_px·√(c/A_thr)`
/// for the pixel-area metrics (`c` = 1, or 4 for the seed's), `f_px/τ` for `screen-error`, and 0
/// for `distance` (unused). Valid camera and parameters.
pub fn metric_factor(camera: &Camera, params: &Params) -> f32 {
    let f = focal_px(camera);
    match params.lod_metric_mode() {
        Ok(LodMetric::PixelArea) => (f / (params.lod_pixel_area as f64).sqrt()) as f32,
        Ok(LodMetric::PixelAreaSeed) => (f * (4.0 / params.lod_pixel_area as f64).sqrt()) as f32,
        Ok(LodMetric::ScreenError) => (f / params.lod_screen_error as f64) as f32,
        Ok(LodMetric::Distance) | Err(_) => 0.0,
    }
}

/// The fade band's start as a fraction of its end, `fade_start / lod1_transition` (1, an empty
/// band, when the transition is 0): the relative band the scaled metrics keep.
pub fn band_ratio(params: &Params) -> f32 {
    if params.lod1_transition > 0.0 {
        (params.fade_start() as f64 / params.lod1_transition as f64) as f32
    } else {
        1.0
    }
}

/// The mesh size a metric scales (module docs): `√A` of the billboard's opaque area for the
/// pixel-area metrics, its geometric error for `screen-error`, 0 for `distance`.
pub fn mesh_size(metric: LodMetric, mesh: &MeshMeta) -> f32 {
    match metric {
        LodMetric::Distance => 0.0,
        LodMetric::PixelArea | LodMetric::PixelAreaSeed => mesh.area_size,
        LodMetric::ScreenError => mesh.error_size,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(w: u32, h: u32, fov_deg: f32) -> Camera {
        Camera::look_at([0.0; 3], [0.0, 1.0, 0.0], fov_deg, w, h)
    }

    #[test]
    fn eqs_4_3_to_4_5_round_trip() {
        let c = metric_constant(&camera(1280, 720, 60.0), false);
        for (a, d) in [(1.0, 10.0), (25.0, 1000.0), (0.01, 3.5)] {
            let s = pixel_area(c, a, d);
            assert!((depth_for_pixels(c, a, s) / d - 1.0).abs() < 1e-12);
            assert!((area_for_pixels(c, s, d) / a - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn the_seed_constant_is_four_times_the_true_one() {
        let cam = camera(640, 360, 45.0);
        let ratio = metric_constant(&cam, true) / metric_constant(&cam, false);
        assert_eq!(ratio, 4.0);
        // The true constant is the focal length in pixels, squared.
        let f = 360.0 / (2.0 * (22.5f64).to_radians().tan());
        assert!((metric_constant(&cam, false) / (f * f) - 1.0).abs() < 1e-6);
    }

    /// Doubling the resolution doubles the factor and so every transition depth **bit for bit**
    /// (a power-of-two product commutes with rounding): `HEIGHT` enters only through `f_px`.
    /// Planted: `focal_px` on the frame width → fails (640x360 → 1280x720 keeps the aspect, so
    /// that needs a non-16:9 pair: 800x600 → 1600x1200 is also checked, with a height-only change
    /// 800x600 → 800x1200).
    #[test]
    fn doubling_the_resolution_doubles_every_transition_depth() {
        let mesh = MeshMeta {
            area_size: 6.93,
            error_size: 2.31,
            ..bytemuck::Zeroable::zeroed()
        };
        for metric in [
            LodMetric::PixelArea,
            LodMetric::PixelAreaSeed,
            LodMetric::ScreenError,
        ] {
            let p = Params {
                lod_metric: metric as u32,
                ..Params::default()
            };
            for ((w, h), (w2, h2)) in [
                ((640, 360), (1280, 720)),
                ((800, 600), (1600, 1200)),
                ((800, 600), (800, 1200)),
                ((333, 211), (666, 422)),
            ] {
                for fov in [20.0, 60.0, 110.0] {
                    let a = crate::ViewUniform::new(&camera(w, h, fov), &p);
                    let b = crate::ViewUniform::new(&camera(w2, h2, fov), &p);
                    assert_eq!(
                        b.metric_factor,
                        2.0 * a.metric_factor,
                        "{metric:?} {w}x{h} {fov}°"
                    );
                    let (ba, bb) = (a.mesh_band(&mesh), b.mesh_band(&mesh));
                    assert_eq!(bb, [2.0 * ba[0], 2.0 * ba[1]], "{metric:?} {w}x{h} {fov}°");
                    for s in [0.31f32, 1.0, 2.7] {
                        let (ga, gb) = (a.group_band(ba, [s, s]), b.group_band(bb, [s, s]));
                        assert_eq!(gb, [2.0 * ga[0], 2.0 * ga[1]], "{metric:?} scale {s}");
                    }
                }
            }
        }
    }
}
