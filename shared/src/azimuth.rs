//! Billboard azimuth views (E§7; issue 30, design study §E3): billboards baked at `J` azimuths
//! as well as `K` elevations, the draw choosing the nearest azimuth or blending the two nearest.
//!
//! E§7: to render "other radially symmetric objects, such as buildings ... multiple azimuth angles
//! are generated in addition to the multiple elevation angles". The seed gives no count, index or
//! blend. Our crossed-card trees are not radially symmetric either (SPEC §4's assumption, E§3.3.1,
//! is what lets the thesis bake one azimuth), so azimuths matter for trees too.
//!
//! ## Contract
//! - **Views** ([`BillboardViews`]): per mesh, `K` elevations times `J` azimuths. View `(k, j)`
//!   of mesh `m` is layer `(m·K + k)·J + j` = `m·K·J + k·J + j` of the billboard array
//!   ([`view_layer`]): the `J` azimuths of one elevation are adjacent, so the blend's second
//!   layer follows from the first and `J` alone ([`azimuth_second_layer`]), and `J = 1` is
//!   today's `m·K + k` exactly.
//! - **Bake azimuth** ([`bake_azimuth`]): view `j` looks at the mesh from the mesh-local
//!   horizontal direction `h_j = (cos φ_j, sin φ_j, 0)`, `φ_j = 2π·j/J`; view 0 is today's `+X`.
//!   A mesh point enters view `j`'s frame by [`azimuth_to_view`] (the identity for `j = 0`, bit
//!   for bit, so `J = 1` bakes today's layers). The extent is the elevation's
//!   ([`crate::billboard_extent`]): the horizontal circumradius `W` bounds every azimuth.
//! - **Draw azimuth** ([`azimuth_position`]): the eye's mesh-local azimuth is
//!   `φ = wrap(atan2(h.y, h.x) − yaw, [0, 2π))`, `h` the billboard's horizontal direction to the
//!   eye (`crate::billboard`, after its fallbacks for an eye straight above the tree), as a
//!   position `t = φ·J/2π` in `[0, J)`; NaN maps to 0.
//! - **Nearest** ([`AzimuthMode::Nearest`], [`azimuth_index`]): `j = round(t) mod J` (ties round
//!   up), the view nearest in circular distance.
//! - **Blend** ([`AzimuthMode::Blend`], [`azimuth_view`]): the two views around `t`,
//!   `j0 = floor(t) mod J` and `j0 + 1 mod J`, the second weighted `w = t − floor(t)` quantised to
//!   [`AZIMUTH_WEIGHT_STEPS`] (so the pair and the weight travel in the one varying that carried
//!   the layer: [`azimuth_pack`]). Weights `1 − w` and `w` lie in `[0, 1]` and sum to 1. The
//!   fragment samples both layers and mixes them ([`azimuth_mix`], premultiplied, so a texel
//!   transparent in one view does not darken the other) before the alpha test.
//! - **Limits** ([`check_billboard_layers`]): `m·K·J ≤` [`MAX_BILLBOARD_LAYERS`] (lavapipe's
//!   array-layer limit, SPEC §8), refused naming `azimuth_count`. Memory: E Eq. 4.1's `16amr²`
//!   becomes `16aJmr²` (`reference::batches::eq41_bytes`).
//!
//! Twin: `gpu/src/shaders/common.wgsl` (`view_layer`, `azimuth_position`, `azimuth_view`,
//! `azimuth_second_layer`, `azimuth_mix`, `azimuth_to_view`), read by `draw.wgsl` and `bake.wgsl`.

use core::f32::consts::TAU;

use crate::params::{ParamError, Params};

crate::modes::modes! {
    /// How the draw picks among the `J` azimuth views (module docs).
    pub enum AzimuthMode {
        /// The view nearest in circular distance (the elevation index's rule, E Eq. 3.1 made
        /// nearest, applied to the azimuth).
        Nearest = 0 => "nearest",
        /// The two nearest views, mixed by the eye's position between them.
        Blend = 1 => "blend",
    }
}

/// Most azimuth views `J`: one every 5.6°. Beyond it the layer count, not the view, is the limit
/// (`K = 10` elevations and 64 azimuths are 640 layers a mesh).
pub const MAX_AZIMUTH_COUNT: u32 = 64;

/// Most billboard array layers, `m·K·J`: lavapipe's `max_texture_array_layers` (SPEC §8; 2048 is
/// also Direct3D 12's and most desktop Vulkan drivers' limit). The GPU upload still checks the
/// device's own limit.
pub const MAX_BILLBOARD_LAYERS: u32 = 2048;

/// The blend weight is quantised to this many steps (12 bits), so that it rides with the layer
/// (at most [`MAX_BILLBOARD_LAYERS`], 12 bits) in one varying an `f32` holds exactly (24 bits).
pub const AZIMUTH_WEIGHT_STEPS: u32 = 4095;

/// Bits of the packed varying ([`azimuth_pack`]) that hold the layer.
pub const AZIMUTH_LAYER_BITS: u32 = 12;

/// One step of the blend weight, `1 / AZIMUTH_WEIGHT_STEPS`, rounded once to `f32` (the GPU
/// twin reads these bits).
pub const AZIMUTH_WEIGHT_SCALE: f32 = 1.0 / AZIMUTH_WEIGHT_STEPS as f32;

/// Turns per radian, `1/2π`, rounded once to `f32` (the GPU twin reads these bits).
pub const AZIMUTH_TURN: f32 = 1.0 / TAU;

const _: () = assert!(MAX_BILLBOARD_LAYERS <= 1 << AZIMUTH_LAYER_BITS);
const _: () = assert!(AZIMUTH_WEIGHT_STEPS < 1 << (24 - AZIMUTH_LAYER_BITS));

/// The views baked per mesh: `K` elevations times `J` azimuths (module docs), or `N×N`
/// octahedral frames (issue 32, `crate::octahedral`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BillboardViews {
    /// Elevations `K` (E Alg. 3.1).
    pub angle_count: u32,
    /// Azimuths `J` (E§7).
    pub azimuth_count: u32,
    /// [`crate::ViewSphere`] as `u32`: elevation views, or octahedral frames.
    pub sphere: u32,
    /// Octahedral grid side `N` (read only when `sphere` is octahedral).
    pub grid: u32,
}

impl BillboardViews {
    /// The views of `params`.
    pub fn of(params: &Params) -> Self {
        Self {
            angle_count: params.angle_count,
            azimuth_count: params.azimuth_count,
            sphere: params.billboard_views,
            grid: params.octahedral_grid,
        }
    }

    /// `K` elevations at one azimuth (the thesis).
    pub fn elevations(angle_count: u32) -> Self {
        Self {
            angle_count,
            azimuth_count: 1,
            sphere: crate::ViewSphere::Elevation as u32,
            grid: 0,
        }
    }

    /// Whether the views are octahedral frames.
    pub fn octahedral(&self) -> bool {
        crate::octahedral::is_octahedral(self.sphere)
    }

    /// Layers per mesh, `K·J`, or `N²` octahedral frames.
    pub fn per_mesh(&self) -> u32 {
        if self.octahedral() {
            self.grid * self.grid
        } else {
            self.angle_count * self.azimuth_count
        }
    }

    /// The array layer of view `(k, j)` of mesh `mesh` ([`view_layer`]; an octahedral frame
    /// `k = f` is layer `mesh·N² + f`, issue 32).
    pub fn layer(&self, mesh: u32, k: u32, j: u32) -> u32 {
        if self.octahedral() {
            crate::octahedral::octahedral_layer(mesh, k, self.grid)
        } else {
            view_layer(mesh, k, self.angle_count, j, self.azimuth_count)
        }
    }

    /// The extent of view `k` of a mesh: its elevation's ([`crate::billboard_extent`]; every
    /// azimuth of an elevation shares it), or an octahedral frame's square `[-S, S]²` about the
    /// sphere centre (issue 32, `S` the sphere radius).
    pub fn extent(&self, meta: &crate::MeshMeta, k: u32) -> crate::BillboardExtent {
        if self.octahedral() {
            let s = meta.sphere_radius;
            crate::BillboardExtent {
                half_width: s,
                bottom: -s,
                height: 2.0 * s,
            }
        } else {
            crate::billboard_extent(meta, crate::bake_elevation(k, self.angle_count))
        }
    }

    /// Layers of `meshes` meshes, `m·K·J` (saturating).
    pub fn layers(&self, meshes: usize) -> u64 {
        (meshes as u64).saturating_mul(u64::from(self.per_mesh()))
    }

    /// Every `(mesh, k, j)` of `meshes` meshes in layer order ([`view_layer`]); octahedral
    /// frames come as `(mesh, f, 0)`, frame `f` in `0..N²` (layer `mesh·N² + f`).
    pub fn views(&self, meshes: usize) -> impl Iterator<Item = (usize, u32, u32)> + use<> {
        let (k_count, j_count) = if self.octahedral() {
            (self.grid * self.grid, 1)
        } else {
            (self.angle_count, self.azimuth_count)
        };
        (0..meshes)
            .flat_map(move |m| (0..k_count).flat_map(move |k| (0..j_count).map(move |j| (m, k, j))))
    }
}

/// The billboard array layer of view `(k, j)` of mesh `mesh`: `(mesh·K + k)·J + j` (module docs).
pub fn view_layer(mesh: u32, k: u32, k_count: u32, j: u32, j_count: u32) -> u32 {
    (mesh * k_count + k) * j_count + j
}

/// The mesh-local azimuth (radians) view `j` of `J` is baked from: `2π·j/J`, 0 for `J <= 1`.
/// `j` beyond the last view is clamped.
pub fn bake_azimuth(j: u32, j_count: u32) -> f32 {
    if j_count <= 1 {
        return 0.0;
    }
    TAU / j_count as f32 * j.min(j_count - 1) as f32
}

/// A mesh-local point in the frame of the view baked from azimuth `φ` (`sin_a`, `cos_a` its sine
/// and cosine): `x` toward the viewer `h = (cos φ, sin φ)`, `y` along `Z × h`, `z` unchanged.
/// The identity, bit for bit, for `φ = 0` (`sin_a = 0`, `cos_a = 1`), today's `+X` view.
pub fn azimuth_to_view(p: [f32; 3], sin_a: f32, cos_a: f32) -> [f32; 3] {
    if sin_a == 0.0 && cos_a == 1.0 {
        return p;
    }
    [
        cos_a * p[0] + sin_a * p[1],
        cos_a * p[1] - sin_a * p[0],
        p[2],
    ]
}

/// The eye's azimuth position `t = φ·J/2π` in `[0, J)` (module docs): `(h_x, h_y)` the billboard's
/// horizontal direction from the tree to the eye, `yaw` the tree's. 0 for `J <= 1` (no `atan2`
/// is evaluated: today's draw) and for NaN.
pub fn azimuth_position(h_x: f32, h_y: f32, yaw: f32, j_count: u32) -> f32 {
    if j_count <= 1 {
        return 0.0;
    }
    let turns = (h_y.atan2(h_x) - yaw) * AZIMUTH_TURN;
    let j = j_count as f32;
    let t = (turns - turns.floor()) * j;
    // `t` rounds up to `J` just below a whole turn (the same view as 0); NaN fails both tests.
    if t >= 0.0 && t < j { t } else { 0.0 }
}

/// The nearest view to azimuth position `t` ([`azimuth_position`]): `round(t) mod J`, ties up,
/// in `0..J`, NaN-free.
pub fn azimuth_index(t: f32, j_count: u32) -> u32 {
    if j_count <= 1 {
        return 0;
    }
    let t = t.max(0.0).min(j_count as f32);
    ((t + 0.5).floor() as u32) % j_count
}

/// The azimuth view a billboard draws: view `j` and, under the blend, the quantised weight
/// `code / AZIMUTH_WEIGHT_STEPS` of the next view `j + 1 mod J` (0 under the nearest rule).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AzimuthView {
    /// The (first) view, in `0..J`.
    pub j: u32,
    /// The weight code of the second view, `0..=AZIMUTH_WEIGHT_STEPS`.
    pub code: u32,
}

/// The view(s) of `mode` (an [`AzimuthMode`] id) at azimuth position `t` of `J` (module docs).
pub fn azimuth_view(mode: u32, t: f32, j_count: u32) -> AzimuthView {
    if j_count <= 1 {
        return AzimuthView { j: 0, code: 0 };
    }
    if mode != AzimuthMode::Blend as u32 {
        return AzimuthView {
            j: azimuth_index(t, j_count),
            code: 0,
        };
    }
    let t = t.max(0.0).min(j_count as f32);
    let lo = t.floor();
    let w = t - lo;
    AzimuthView {
        j: (lo as u32) % j_count,
        code: (w * AZIMUTH_WEIGHT_STEPS as f32 + 0.5) as u32,
    }
}

/// The weights `[1 − w, w]` of the first and second view of a blend code.
pub fn azimuth_weights(code: u32) -> [f32; 2] {
    let w = code.min(AZIMUTH_WEIGHT_STEPS) as f32 * AZIMUTH_WEIGHT_SCALE;
    [1.0 - w, w]
}

/// The layer varying of a tree: `layer | code << AZIMUTH_LAYER_BITS` (24 bits, exact in an `f32`;
/// a mesh command's layer, and every layer at `J = 1`, has code 0: the word is the layer).
pub fn azimuth_pack(layer: u32, code: u32) -> u32 {
    (layer & ((1 << AZIMUTH_LAYER_BITS) - 1))
        | (code.min(AZIMUTH_WEIGHT_STEPS) << AZIMUTH_LAYER_BITS)
}

/// The layer and the weight code of a packed varying ([`azimuth_pack`]).
pub fn azimuth_unpack(word: u32) -> (u32, u32) {
    (
        word & ((1 << AZIMUTH_LAYER_BITS) - 1),
        word >> AZIMUTH_LAYER_BITS,
    )
}

/// The layer of the view after `layer`'s in azimuth (`j + 1 mod J`, same mesh and elevation).
pub fn azimuth_second_layer(layer: u32, j_count: u32) -> u32 {
    if j_count <= 1 {
        return layer;
    }
    let j = layer % j_count;
    layer - j + (j + 1) % j_count
}

/// Two straight-alpha linear texels of the first and second view mixed with blend code `code`:
/// premultiplied (`rgb = (a₀(1−w)·rgb₀ + a₁w·rgb₁) / α`, `α = a₀(1−w) + a₁w`), so a texel that is
/// transparent in one view keeps the other's colour instead of darkening toward it; where both are
/// transparent the colours mix straight. Code 0 returns `first` bit for bit.
pub fn azimuth_mix(first: [f32; 4], second: [f32; 4], code: u32) -> [f32; 4] {
    if code == 0 {
        return first;
    }
    let [v, w] = azimuth_weights(code);
    let (a0, a1) = (first[3] * v, second[3] * w);
    let alpha = a0 + a1;
    if alpha > 0.0 {
        let c = |i: usize| (first[i] * a0 + second[i] * a1) / alpha;
        [c(0), c(1), c(2), alpha]
    } else {
        let c = |i: usize| first[i] * v + second[i] * w;
        [c(0), c(1), c(2), alpha]
    }
}

/// Refuses billboard arrays of more than [`MAX_BILLBOARD_LAYERS`] layers for `meshes` meshes,
/// naming `azimuth_count` (or `angle_count` when there is one azimuth: then the elevations alone
/// are too many).
pub fn check_billboard_layers(meshes: usize, params: &Params) -> Result<(), ParamError> {
    if crate::octahedral::is_octahedral(params.billboard_views) {
        return crate::octahedral::check_octahedral_layers(meshes, params);
    }
    let views = BillboardViews::of(params);
    let layers = views.layers(meshes);
    if layers <= u64::from(MAX_BILLBOARD_LAYERS) {
        return Ok(());
    }
    let (field, value) = if params.azimuth_count > 1 {
        ("azimuth_count", params.azimuth_count)
    } else {
        ("angle_count", params.angle_count)
    };
    let meshes = if meshes == 1 {
        "one mesh:".to_string()
    } else {
        format!("{meshes} meshes x")
    };
    Err(ParamError {
        field,
        value: value.to_string(),
        reason: format!(
            "{meshes} {} elevations x {} azimuths = {layers} billboard layers, over the limit of \
             {MAX_BILLBOARD_LAYERS} array layers",
            params.angle_count, params.azimuth_count
        )
        .into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::test_support::proptest_config;

    const BLEND: u32 = AzimuthMode::Blend as u32;
    const NEAREST: u32 = AzimuthMode::Nearest as u32;

    /// Circular distance between angles, radians, in f64.
    fn circular(a: f64, b: f64) -> f64 {
        let d = (a - b).rem_euclid(std::f64::consts::TAU);
        d.min(std::f64::consts::TAU - d)
    }

    /// The eye's true mesh-local azimuth in f64.
    fn true_azimuth(h_x: f32, h_y: f32, yaw: f32) -> f64 {
        (f64::from(h_y).atan2(f64::from(h_x)) - f64::from(yaw)).rem_euclid(std::f64::consts::TAU)
    }

    #[test]
    fn one_azimuth_is_today() {
        assert_eq!(bake_azimuth(0, 1), 0.0);
        assert_eq!(azimuth_position(-3.0, 0.5, 2.0, 1), 0.0);
        assert_eq!(azimuth_view(BLEND, 0.7, 1), AzimuthView { j: 0, code: 0 });
        for layer in [0, 7, 2047] {
            assert_eq!(view_layer(layer / 10, layer % 10, 10, 0, 1), layer);
            assert_eq!(azimuth_pack(layer, 0), layer);
            assert_eq!(azimuth_second_layer(layer, 1), layer);
        }
        let (s, c) = 0.0f32.sin_cos();
        let p = [-0.0, 3.5, -1.25];
        assert_eq!(
            azimuth_to_view(p, s, c).map(f32::to_bits),
            p.map(f32::to_bits)
        );
        // Weight code 0 returns the first view's texel bit for bit (a premultiplied round trip,
        // `c·a/a`, would not: 0.1·0.3/0.3 is not 0.1 in f32).
        for i in 0..=20 {
            for a in [0.0, 0.3, 0.7, 1.0] {
                let t = [i as f32 * 0.05, 0.1, 1.0 - i as f32 * 0.05, a];
                let m = azimuth_mix(t, [0.9, 0.2, 0.4, 0.6], 0);
                assert_eq!(m.map(f32::to_bits), t.map(f32::to_bits), "{t:?}");
            }
        }
    }

    #[test]
    fn layer_order_is_mesh_elevation_azimuth() {
        let v = BillboardViews {
            angle_count: 3,
            azimuth_count: 4,
            ..BillboardViews::elevations(3)
        };
        let order: Vec<u32> = v
            .views(2)
            .map(|(m, k, j)| view_layer(m as u32, k, 3, j, 4))
            .collect();
        assert_eq!(order, (0..24).collect::<Vec<_>>());
        assert_eq!(view_layer(1, 2, 3, 1, 4), 12 + 8 + 1);
        // The second view wraps within its (mesh, elevation).
        assert_eq!(azimuth_second_layer(12 + 8 + 3, 4), 12 + 8);
        assert_eq!(azimuth_second_layer(12 + 8 + 1, 4), 12 + 8 + 2);
    }

    #[test]
    fn view_frames_turn_the_mesh_toward_each_azimuth() {
        // The point at the view direction's tip comes out toward the viewer, +X, at every view.
        for j in 0..8 {
            let a = bake_azimuth(j, 8);
            let (s, c) = a.sin_cos();
            let v = azimuth_to_view([c, s, 2.0], s, c);
            assert!(
                (v[0] - 1.0).abs() < 1e-6 && v[1].abs() < 1e-6 && v[2] == 2.0,
                "{j}: {v:?}"
            );
            // Its right (Z × h) comes out along +Y.
            let r = azimuth_to_view([-s, c, 0.0], s, c);
            assert!(r[0].abs() < 1e-6 && (r[1] - 1.0).abs() < 1e-6, "{j}: {r:?}");
        }
    }

    #[test]
    fn layer_limit_names_the_azimuths() {
        let p = Params {
            azimuth_count: 64,
            ..Params::default()
        };
        check_billboard_layers(3, &p).unwrap();
        let e = check_billboard_layers(4, &p).unwrap_err();
        assert_eq!((e.field, e.value.as_str()), ("azimuth_count", "64"));
        assert!(e.to_string().contains("2560 billboard layers"), "{e}");
        let p = Params {
            angle_count: 91,
            ..Params::default()
        };
        assert_eq!(
            check_billboard_layers(23, &p).unwrap_err().field,
            "angle_count"
        );
        check_billboard_layers(22, &p).unwrap();
    }

    proptest! {
        #![proptest_config(proptest_config())]

        /// The nearest view is in `0..J`, NaN-free for any input, and no view is nearer in
        /// circular distance to the true azimuth.
        #[test]
        fn the_azimuth_index_is_the_nearest_view(
            h_x in -1.0f32..1.0, h_y in -1.0f32..1.0, yaw in -20.0f32..20.0, j_count in 1u32..=MAX_AZIMUTH_COUNT,
        ) {
            prop_assume!(h_x.abs() + h_y.abs() > 1e-3);
            let t = azimuth_position(h_x, h_y, yaw, j_count);
            prop_assert!(t >= 0.0 && t < j_count.max(1) as f32, "t {}", t);
            let j = azimuth_index(t, j_count);
            prop_assert!(j < j_count);
            let phi = true_azimuth(h_x, h_y, yaw);
            let chosen = circular(phi, f64::from(bake_azimuth(j, j_count)));
            for other in 0..j_count {
                let d = circular(phi, f64::from(bake_azimuth(other, j_count)));
                // 1e-5 rad: f32 atan2, the subtraction of a yaw up to 20 rad (ulp 2e-6) and the
                // f32 bake angles are each within a few ulps of exact; only near-ties may go
                // either way.
                prop_assert!(chosen <= d + 1e-5, "J={} φ={} chose {} ({}) but {} is {}", j_count, phi, j, chosen, other, d);
            }
        }

        /// Any `f32`, NaN and infinities included, gives a view in `0..J` and a code in range.
        #[test]
        fn views_are_in_range_for_any_input(
            h_x in proptest::num::f32::ANY, h_y in proptest::num::f32::ANY,
            yaw in proptest::num::f32::ANY, j_count in 1u32..=MAX_AZIMUTH_COUNT, blend in any::<bool>(),
        ) {
            let t = azimuth_position(h_x, h_y, yaw, j_count);
            prop_assert!(!t.is_nan());
            let mode = if blend { BLEND } else { NEAREST };
            let v = azimuth_view(mode, t, j_count);
            prop_assert!(v.j < j_count && v.code <= AZIMUTH_WEIGHT_STEPS, "{:?}", v);
            prop_assert!(azimuth_index(f32::NAN, j_count) < j_count);
        }

        /// The blend's two views are the two nearest (they bracket the true azimuth), its weights
        /// lie in `[0, 1]`, sum to 1, and favour the nearer view; the mix stays a texel.
        #[test]
        fn blend_weights_are_a_partition_toward_the_nearer_view(
            h_x in -1.0f32..1.0, h_y in -1.0f32..1.0, yaw in -20.0f32..20.0, j_count in 2u32..=MAX_AZIMUTH_COUNT,
            a in proptest::array::uniform4(0.0f32..=1.0), b in proptest::array::uniform4(0.0f32..=1.0),
        ) {
            prop_assume!(h_x.abs() + h_y.abs() > 1e-3);
            let t = azimuth_position(h_x, h_y, yaw, j_count);
            let v = azimuth_view(BLEND, t, j_count);
            let [w0, w1] = azimuth_weights(v.code);
            prop_assert!((0.0..=1.0).contains(&w0) && (0.0..=1.0).contains(&w1));
            prop_assert!((w0 + w1 - 1.0).abs() <= f32::EPSILON, "{} + {}", w0, w1);
            let phi = true_azimuth(h_x, h_y, yaw);
            let step = std::f64::consts::TAU / f64::from(j_count);
            let d0 = circular(phi, f64::from(bake_azimuth(v.j, j_count)));
            let d1 = circular(phi, f64::from(bake_azimuth((v.j + 1) % j_count, j_count)));
            // The pair brackets φ (1e-5 rad of rounding as above, plus half a weight step).
            prop_assert!(d0 + d1 <= step + 1e-5, "J={} φ={} views {} ({}) and next ({})", j_count, phi, v.j, d0, d1);
            // The second view's weight is the first's distance as a fraction of the step, within
            // half a weight step and the f32 rounding of `t`: `atan2 − yaw` (yaw up to 20 rad,
            // ulp 2e-6 rad) and the turn's fraction (ulp 5e-7 for |turns| < 4) times J, under
            // 2e-6·J.
            let exact = d0 / step;
            let slack = 0.5 / f64::from(AZIMUTH_WEIGHT_STEPS) + 2e-6 * f64::from(j_count);
            prop_assert!((f64::from(w1) - exact).abs() <= slack,
                "w1 {} for a fraction {}", w1, exact);
            let m = azimuth_mix(a, b, v.code);
            for (c, x) in m.iter().enumerate() {
                prop_assert!(x.is_finite() && *x >= -1e-6 && *x <= 1.0 + 1e-6, "channel {}: {:?}", c, m);
            }
        }
    }

    #[test]
    fn premultiplied_mix_keeps_the_opaque_colour() {
        // Half way between an opaque red texel and a transparent black one: the colour stays red,
        // alpha halves (a straight mix would give dark red).
        let m = azimuth_mix([1.0, 0.0, 0.0, 1.0], [0.0; 4], AZIMUTH_WEIGHT_STEPS / 2);
        assert!((m[0] - 1.0).abs() < 1e-6 && m[1] == 0.0, "{m:?}");
        assert!((m[3] - 0.5).abs() < 1e-3, "{m:?}");
        let all = azimuth_mix(
            [0.2, 0.4, 0.6, 0.8],
            [0.6, 0.4, 0.2, 0.8],
            AZIMUTH_WEIGHT_STEPS,
        );
        assert!(
            (all[0] - 0.6).abs() < 1e-6 && (all[3] - 0.8).abs() < 1e-6,
            "{all:?}"
        );
    }

    #[test]
    fn pack_round_trips() {
        for (layer, code) in [(0, 0), (2047, 4095), (4095, 1), (5, 2048)] {
            let w = azimuth_pack(layer, code);
            assert!(w < 1 << 24);
            assert_eq!(azimuth_unpack(w), (layer, code));
        }
    }
}
