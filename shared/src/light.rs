//! Sun-depth tree shading (G§5, Figs. 7-9; issue 30): the lightness of a point of a tree is its
//! depth along the sun direction inside the tree's crown ellipsoid, a cheap stand-in for
//! self-shadowing that needs no normals and no shadow map.
//!
//! G§5 gives no formula and no constants ("the diffuse factor for a vertex in a tree is determined
//! by its distance from the tree center along the sun direction"; fn. 6: "the tree radius is
//! larger in the vertical directions"). Our reading (`../shared/design/variants.md` §G4):
//!
//! ## Contract
//! - **Crown** ([`crown_radii`]): the ellipsoid of the tree's bounding box: centre the box centre
//!   (the tree's bounding-sphere centre, which both draw stages already compute), horizontal
//!   radius `R_h` the box's horizontal circumradius (`MeshMeta::billboard_half_width`, what the
//!   billboard's half-width is), vertical radius `R_v` half the box height, both times the tree's
//!   scale. No new per-mesh data: the seed's "tree center" and "radius" are the box's.
//! - **Sun depth** ([`sun_depth`]): `δ = ((p − c) · s) / h(s)` with `s` the unit direction
//!   *towards* the sun and `h(s) = √((R_h |s_xy|)² + (R_v s_z)²)` the ellipsoid's support
//!   function: the crown spans `[−h, h]` along the sun, so `δ = 1` at the first point the sun
//!   reaches and `−1` at the last, and every point of the ellipsoid lies in `[−1, 1]`. Clamped
//!   to `[−1, 1]` (box corners reach `√2`; NaN maps to −1). The design study's reading divided by
//!   the ellipsoid's *radius* along `s`, `1 / √((|s_xy| / R_h)² + (s_z / R_v)²)`, which is not
//!   the crown's extent along the sun: for a conifer (`R_v` = 5 `R_h`) under a 45° sun it is a
//!   third of it, so most of the crown clamped to 1 or to the ambient level, and the
//!   per-vertex interpolation of those clamped values across a crown-sized card missed the
//!   model truth by 0.058 of FLIP at the `close` camera (`shading` sweep, synthetic, sun 45°: 0.072
//!   against 0.014 unlit).
//! - **Lightness** ([`lightness`]): `L = a + (1 − a)(δ + 1) / 2` in `[a, 1]`, `a` the ambient
//!   level: monotone in `δ`, `a` on the far side, 1 on the sunlit side.
//! - **Where a vertex is lit** ([`light_point`]): a mesh (LOD0) vertex where it stands. A
//!   billboard (LOD1) vertex where it stands under [`Shading::SunDepth`], the seed's "before"
//!   (Fig. 8: the billboard sits near the tree centre's depth, so it shows medium lightness from
//!   every side), and on the lighting plane under [`Shading::SunDepthPlane`] (Fig. 9: "all
//!   billboard vertices are projected onto a plane for lighting calculation. This plane has an
//!   offset towards the camera, usually half the radius of the tree"): the vertical plane
//!   perpendicular to `ĥ` through `c + ½ R_h ĥ`, `ĥ` the unit horizontal direction from the tree
//!   to the eye (the billboard's facing in yaw), and `p' = p + (½ R_h − (p − c) · ĥ) ĥ`, the
//!   orthogonal **projection** onto it, as the seed says. The design study's reading `p' = p +
//!   ½ R_h ĥ` (a translation) is wrong for our billboards: they tilt to the baked elevation
//!   nearest the view (E Alg. 3.1), so a billboard seen from 10° above leans away from the eye
//!   and its upper vertices lie behind the crown centre; translated, they kept that lean, and
//!   the lone-tree test (`tests/tests/reference/shading.rs`) measured the sunlit side seen from
//!   the sun only 0.011 brighter than the shaded side (species 0), where the projection gives
//!   the full half-radius offset whatever the tilt.
//! - Under [`Shading::SunDepth`] the same tilt is why the defect is *worse* than the seed's Fig. 8
//!   away from the level view: the leaning vertices sit on the crown's far side, so the side
//!   facing the sun looks darker than the side away from it (measured: 0.54 against 0.81 for
//!   species 0 from 9° above). At the level view (layer 0, no tilt) it is the seed's defect:
//!   both sides equally medium.
//! - **Interpolation**: `L` is computed per vertex (G§5 lights vertices) and interpolated
//!   perspective-correctly; the fragment multiplies its texel's linear RGB by it. `δ` is affine in
//!   `p`, so on a mesh the interpolated `L` equals the `L` of the point itself except where the
//!   clamp bends it: the model truth (`reference/src/ground_truth.rs`) evaluates `L` at each ray
//!   hit, and the two agree to rounding away from the clamp.
//! - **Unlit** ([`Shading::Unlit`], the default): no multiplication at all, so frames are bit for
//!   bit those before issue 30 (a multiplication by an interpolated 1.0 need not be exact on a
//!   GPU).
//! - Baked billboards stay unlit (E Alg. 3.1 bakes albedo); the ground is not shaded by any mode
//!   (no variant models its lighting, so the truths leave it unlit too).
//! - The seed's mixing of leaf normals into the mesh lightness is not modelled: our meshes carry
//!   no normals (crossed alpha cards), and a card's normal says little about a leaf's.
//!
//! Twin: `common.wgsl` (`sun_depth`, `lightness`, `light_point`), read by `draw.wgsl`. The sun
//! direction is computed once on the CPU ([`sun_direction`]) and uploaded, so no trigonometry
//! happens on the GPU.

use crate::MeshMeta;

crate::modes::modes! {
    /// How trees are shaded (module docs).
    pub enum Shading {
        /// Flat albedo, as before issue 30 (the default; bit-identical frames).
        Unlit = 0 => "unlit",
        /// Sun depth at every vertex where it stands, billboards too: the seed's Fig. 8 defect.
        SunDepth = 1 => "sun-depth" ("G§5 Fig. 8"),
        /// Sun depth with billboard vertices lit on a plane offset towards the camera by half
        /// the crown radius (G§5 Fig. 9).
        SunDepthPlane = 2 => "sun-depth-plane" ("G§5 Fig. 9"),
    }
}

crate::modes::modes! {
    /// How the ray-traced ground truth lights trees when the frame is lit (module docs of
    /// `reference/src/ground_truth.rs`); an unlit frame's truth is unlit whatever this says.
    /// Not a pipeline parameter (no stage reads it): a sweep file's `truth_light` key and the
    /// CLI's truth commands choose it.
    pub enum TruthLight {
        /// The sun-depth model evaluated at each ray hit on the full meshes: the truth the
        /// billboard's shading error is measured against.
        Model = 0 => "model",
        /// One shadow ray per hit towards the sun through the alpha-tested trees: lit (1) or in
        /// shadow (the ambient level). What the sun-depth model approximates.
        Shadow = 1 => "shadow",
    }
}

/// The unit direction towards the sun, `(cos e cos a, cos e sin a, sin e)`, from its azimuth `a`
/// (degrees, counter-clockwise from +X) and elevation `e` (degrees above the horizon). Computed
/// once per frame on the CPU; both draw stages read the result.
pub fn sun_direction(azimuth_deg: f32, elevation_deg: f32) -> [f32; 3] {
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    let (se, ce) = elevation_deg.to_radians().sin_cos();
    [ce * ca, ce * sa, se]
}

/// The crown radii `[R_h, R_v]` of a tree of `mesh` at `scale` (module docs).
pub fn crown_radii(mesh: &MeshMeta, scale: f32) -> [f32; 2] {
    [
        mesh.billboard_half_width * scale,
        (mesh.bbox_max[2] - mesh.bbox_min[2]) * 0.5 * scale,
    ]
}

/// Radii below this (metres) are raised to it: a flat or degenerate box would divide by zero.
pub const MIN_CROWN_RADIUS: f32 = 1.0e-6;

/// The clamped sun depth `δ ∈ [−1, 1]` of point `p` in the crown of centre `centre` and radii
/// `radii` (`[R_h, R_v]`), sun direction `sun` (unit, towards the sun). A fixed sequence of `f32`
/// operations (no fused multiply-add), twin of `sun_depth` in `common.wgsl`.
pub fn sun_depth(p: [f32; 3], centre: [f32; 3], radii: [f32; 2], sun: [f32; 3]) -> f32 {
    let dx = p[0] - centre[0];
    let dy = p[1] - centre[1];
    let dz = p[2] - centre[2];
    let along = dx * sun[0] + dy * sun[1] + dz * sun[2];
    let rh = radii[0].max(MIN_CROWN_RADIUS);
    let rv = radii[1].max(MIN_CROWN_RADIUS);
    let sh = (sun[0] * sun[0] + sun[1] * sun[1]).sqrt() * rh;
    let sv = sun[2] * rv;
    let extent = (sh * sh + sv * sv).sqrt();
    (along / extent).max(-1.0).min(1.0)
}

/// The lightness `a + (1 − a)(δ + 1) / 2` of sun depth `delta` under ambient level `ambient`
/// (module docs): in `[a, 1]` for `δ ∈ [−1, 1]`, monotone.
pub fn lightness(delta: f32, ambient: f32) -> f32 {
    ambient + (1.0 - ambient) * ((delta + 1.0) * 0.5)
}

/// Where vertex `p` of a tree of crown centre `centre` is lit (module docs): `p` itself for a
/// mesh and under [`Shading::SunDepth`]; for a billboard under [`Shading::SunDepthPlane`], its
/// projection `p + (½ R_h − (p − c) · ĥ) ĥ` onto the lighting plane, `ĥ` (`toward_eye`) the unit
/// horizontal direction from the tree to the eye.
pub fn light_point(
    p: [f32; 3],
    billboard: bool,
    shading: u32,
    (toward_eye, centre): ([f32; 3], [f32; 3]),
    r_h: f32,
) -> [f32; 3] {
    if !billboard || shading != Shading::SunDepthPlane as u32 {
        return p;
    }
    let along = (p[0] - centre[0]) * toward_eye[0]
        + (p[1] - centre[1]) * toward_eye[1]
        + (p[2] - centre[2]) * toward_eye[2];
    let o = 0.5 * r_h - along;
    [
        p[0] + o * toward_eye[0],
        p[1] + o * toward_eye[1],
        p[2] + o * toward_eye[2],
    ]
}

/// The lightness of tree vertex `p` (module docs): 1 under `unlit` (and an unknown id), else
/// [`lightness`] of the [`sun_depth`] of [`light_point`].
#[allow(clippy::too_many_arguments)]
pub fn vertex_lightness(
    shading: u32,
    p: [f32; 3],
    billboard: bool,
    toward_eye: [f32; 3],
    centre: [f32; 3],
    radii: [f32; 2],
    sun: [f32; 3],
    ambient: f32,
) -> f32 {
    if shading != Shading::SunDepth as u32 && shading != Shading::SunDepthPlane as u32 {
        return 1.0;
    }
    let q = light_point(p, billboard, shading, (toward_eye, centre), radii[0]);
    lightness(sun_depth(q, centre, radii, sun), ambient)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// `L ∈ [a, 1]`, and monotone in `δ`, for every ambient level.
        #[test]
        fn lightness_lies_in_ambient_to_one_and_is_monotone(
            d0 in -1.0f32..=1.0, d1 in -1.0f32..=1.0, a in 0.0f32..=1.0,
        ) {
            let (l0, l1) = (lightness(d0, a), lightness(d1, a));
            prop_assert!((a..=1.0).contains(&l0), "L({d0}) = {l0} outside [{a}, 1]");
            if d0 <= d1 {
                prop_assert!(l0 <= l1, "L({d0}) = {l0} > L({d1}) = {l1}");
            }
        }

        /// The sun depth is clamped to `[−1, 1]` and NaN-free for any point, crown and sun
        /// direction, including degenerate crowns.
        #[test]
        fn sun_depth_is_clamped_and_nan_free(
            p in prop::array::uniform3(-1.0e4f32..1.0e4),
            c in prop::array::uniform3(-1.0e4f32..1.0e4),
            rh in 0.0f32..100.0, rv in 0.0f32..100.0,
            az in -360.0f32..360.0, el in 0.0f32..=90.0,
        ) {
            let d = sun_depth(p, c, [rh, rv], sun_direction(az, el));
            prop_assert!((-1.0..=1.0).contains(&d), "δ = {d}");
        }
    }

    #[test]
    fn the_sunlit_pole_is_one_and_the_far_pole_minus_one() {
        let sun = sun_direction(30.0, 40.0);
        let (rh, rv) = (3.0f32, 15.0f32);
        let c = [10.0, -4.0, 6.0];
        // The ellipsoid's point where the sun's tangent plane touches it: c + (R_h² s_xy, R_v² s_z)
        // / h, h the support function; it lies on the ellipsoid and has δ = 1.
        let h = ((rh * sun[0].hypot(sun[1])).powi(2) + (rv * sun[2]).powi(2)).sqrt();
        let e = [
            rh * rh * sun[0] / h,
            rh * rh * sun[1] / h,
            rv * rv * sun[2] / h,
        ];
        let on = (e[0].hypot(e[1]) / rh).powi(2) + (e[2] / rv).powi(2);
        assert!(
            (on - 1.0).abs() < 1e-5,
            "the tangent point is on the ellipsoid: {on}"
        );
        let p = |k: f32| [0, 1, 2].map(|i| c[i] + k * e[i]);
        let radii = [rh, rv];
        assert!((sun_depth(p(1.0), c, radii, sun) - 1.0).abs() < 1e-5);
        assert!((sun_depth(p(-1.0), c, radii, sun) + 1.0).abs() < 1e-5);
        assert!((sun_depth(p(0.5), c, radii, sun) - 0.5).abs() < 1e-5);
        // The top of the crown, on the ellipsoid, is inside [−1, 1] (the radius reading put it
        // at 2.5 under a 45° sun).
        let top = [c[0], c[1], c[2] + rv];
        let d = sun_depth(top, c, radii, sun_direction(0.0, 45.0));
        assert!(d > 0.0 && d < 1.0, "top of the crown: δ = {d}");
        assert_eq!(lightness(1.0, 0.35), 1.0);
        assert_eq!(lightness(-1.0, 0.35), 0.35);
    }

    #[test]
    fn only_billboards_under_the_plane_mode_move() {
        let p = [1.0, 2.0, 3.0];
        let h = [0.0, 1.0, 0.0];
        let c = [0.0, 0.5, 0.0];
        let plane = Shading::SunDepthPlane as u32;
        assert_eq!(light_point(p, false, plane, (h, c), 4.0), p);
        assert_eq!(
            light_point(p, true, Shading::SunDepth as u32, (h, c), 4.0),
            p
        );
        // Projected onto the plane `y = c.y + ½ R_h = 2.5`, whatever its own `y`.
        assert_eq!(light_point(p, true, plane, (h, c), 4.0), [1.0, 2.5, 3.0]);
        assert_eq!(
            light_point([1.0, -7.0, 3.0], true, plane, (h, c), 4.0),
            [1.0, 2.5, 3.0]
        );
        assert_eq!(
            vertex_lightness(0, p, true, h, p, [1.0, 1.0], [1.0, 0.0, 0.0], 0.3),
            1.0
        );
    }
}
