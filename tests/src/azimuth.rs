//! Issue 30's azimuth views as the tests judge them (E§7, `forestlod_shared::azimuth`): the view
//! a billboard should show, decided in `f64` from the scene alone (never through the pipeline's
//! `f32` index), and whether that decision sits within [`AZIMUTH_BIN_EPSILON`] of a rounding
//! boundary, where the two twins (or a rotated pose) may decide either way.

use forestlod_reference::draw::{DrawUniform, tree_stage};
use forestlod_reference::pipeline::Prepared;
use forestlod_shared::{AZIMUTH_WEIGHT_STEPS, AzimuthMode, BillboardViews, Camera, Params};

/// How close (in the units of a bin: views for the azimuth and the elevation, weight steps for
/// the blend code) a decision may come to its rounding boundary before it is classified
/// ambiguous.
///
/// Why 1e-3: the pipeline decides in `f32` (`atan2` of the horizontal direction, the yaw's
/// subtraction, the turn's fraction times `J`; `asin` of the elevation), a few ulps of each, under
/// 1e-5 of a bin at yaws below 2π and `J <= 8`; the GPU's `atan2` and `asin` may be a few ulps
/// further off. The tests decide in `f64` from the same scene; a hundred times the `f32` error
/// separates a true disagreement from rounding.
pub const AZIMUTH_BIN_EPSILON: f64 = 1e-3;

/// The true view position of a billboard of the tree at `base` with `yaw`, seen from `eye`, in
/// `f64`: the elevation index `k` (the nearest bake elevation is `round(k)`) and the azimuth
/// position `t = φ·J/2π` in `[0, J)`. `None` when the eye is (nearly) straight above the base
/// (the pipeline's fallbacks decide there, not the geometry).
pub fn true_view(base: [f32; 3], yaw: f32, eye: [f32; 3], v: BillboardViews) -> Option<(f64, f64)> {
    let d = [0, 1, 2].map(|i| f64::from(eye[i]) - f64::from(base[i]));
    let horizontal = (d[0] * d[0] + d[1] * d[1]).sqrt();
    if horizontal < 1e-3 {
        return None;
    }
    let elevation = d[2].atan2(horizontal).max(0.0);
    let k = if v.angle_count <= 1 {
        0.0
    } else {
        elevation / (std::f64::consts::FRAC_PI_2 / f64::from(v.angle_count - 1))
    };
    let phi = (d[1].atan2(d[0]) - f64::from(yaw)).rem_euclid(std::f64::consts::TAU);
    let t = phi / std::f64::consts::TAU * f64::from(v.azimuth_count);
    Some((k, t % f64::from(v.azimuth_count)))
}

/// Distance of `x` to the nearest `n + 0.5`.
pub fn to_half(x: f64) -> f64 {
    (x - x.floor() - 0.5).abs()
}

/// Distance of `x` to the nearest integer.
pub fn to_whole(x: f64) -> f64 {
    let f = x - x.floor();
    f.min(1.0 - f)
}

/// Whether azimuth position `t` sits within [`AZIMUTH_BIN_EPSILON`] of a boundary of `mode`'s
/// rule at `J` views: the nearest view's tie (`n + 0.5`), or, for the blend, the change of the
/// view pair (whole `t`) and the weight code's rounding.
pub fn azimuth_near_boundary(t: f64, mode: AzimuthMode, j_count: u32) -> bool {
    if j_count <= 1 {
        return false;
    }
    match mode {
        AzimuthMode::Nearest => to_half(t) < AZIMUTH_BIN_EPSILON,
        AzimuthMode::Blend => {
            let frac = t - t.floor();
            to_whole(t) < AZIMUTH_BIN_EPSILON
                || to_half(frac * f64::from(AZIMUTH_WEIGHT_STEPS)) < AZIMUTH_BIN_EPSILON
        }
    }
}

/// The trees a frame draws as billboards (every instance of a billboard command the vertex stage
/// keeps), once each, in scene order.
pub fn billboard_trees(prepared: &Prepared, camera: &Camera, params: &Params) -> Vec<usize> {
    let selection = prepared.select(camera, params);
    let res = prepared.resources();
    let uniform = DrawUniform::new(camera, params);
    let mut out = Vec::new();
    for (c, (cmd, data)) in selection.commands.iter().zip(&selection.data).enumerate() {
        if data.billboard == 0 {
            continue;
        }
        for i in cmd.first_instance..cmd.first_instance + cmd.instance_count {
            if tree_stage(&res, &selection, &uniform, c as u32, i).is_some() {
                out.push(prepared.batches.indirection[i as usize] as usize);
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// The billboard trees of a frame whose azimuth decision is ambiguous
/// ([`azimuth_near_boundary`]) under `params`' rule, and how many billboard trees were decided.
pub fn azimuth_boundary_trees(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
) -> (Vec<usize>, usize) {
    let v = BillboardViews::of(params);
    let mode = params.azimuth().expect("valid parameters");
    let trees = billboard_trees(prepared, camera, params);
    let near = trees
        .iter()
        .copied()
        .filter(|&i| {
            let t = prepared.scene.instances[i];
            true_view(t.position, t.yaw, camera.eye, v)
                .is_some_and(|(_, pos)| azimuth_near_boundary(pos, mode, v.azimuth_count))
        })
        .collect();
    (near, trees.len())
}
