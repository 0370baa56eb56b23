//! Camera paths defined by the scene (issue 12: "cameras that look at trees"): placed from the
//! scene's footprint `[x0, y0, x1, y1]` (centre `c`, half-size `R`, the larger half side) and,
//! for the dolly, from the parameter set's fade band, so that every frame looks at trees
//! whatever the scene's size. A sweep file names them as cameras with a frame count:
//!
//! ```toml
//! [[cameras]]
//! name = "orbit"     # any of PATH_NAMES
//! steps = 8
//! ```
//!
//! - **orbit**: around the forest looking in. The eye circles the centre at `1.5 R` (half a
//!   footprint outside it), [`ORBIT_HEIGHT`]` · R` above the ground, looking at the ground at the
//!   centre; `steps` equal angles over 360° from the west (row column `yaw_deg`).
//! - **dolly**: through the fade band `[T - W, T]` (`T` = `lod1_transition`, `W` = `fade_width`,
//!   E§4.4). The eye moves east on the centre line, [`DOLLY_HEIGHT`]` · T` above the ground (12 m
//!   at popping's `T` = 80 m), looking at the ground `3.75 T` ahead; its distance before the
//!   footprint's west edge goes from `T + W` to `max(0, T - 2W)` (row column `distance_m`), so the
//!   front trees enter the band, cross it and leave it, and the trees behind them follow.
//! - **flyover**: at 3D-GIS heights. The eye crosses the footprint west to east on the centre
//!   line at [`FLYOVER_HEIGHT`]` · (x1 - x0)` above the ground (600 m over `synthetic`), pitched
//!   down [`FLYOVER_PITCH_DEGREES`], from `x0 - h` to `x1 - h` (it sees the forest ahead of it);
//!   `distance_m` is the distance flown.
//! - **pan**: a 360° pan from inside the forest: the eye at the centre, [`PAN_HEIGHT_M`] above the
//!   ground (above the built-in canopies), pitched down [`PAN_PITCH_DEGREES`]; `steps` yaws.
//! - **slow-yaw** (issue 30): a slow turn with the forest's front in the fade band. The eye
//!   stands still where the dolly passes `T - W` before the west edge (so the front `W` metres of
//!   forest are in the band `[T - W, T]`), at the dolly's height, pitched down to the dolly's
//!   ground point `3.75 T` ahead, and turns about the vertical by [`SLOW_YAW_DEGREES`] in all,
//!   from `-½` to `+½` of it (row column `yaw_deg`; `distance_m` is `T - W`): trees slide
//!   sideways by a few pixels a step at 1280x720 (0.25° a step at 9 steps, 2.7 px at the image
//!   centre), the motion under which a screen-space dither stays put while the trees move.
//! - **walkthrough** (issue 33, C§5.2's 50 s walk "through the forest as someone walks or runs"):
//!   the eye [`WALK_EYE_HEIGHT_M`] (1.7 m) above the terrain at every step, walking
//!   [`WALK_SECONDS`]` · `[`WALK_SPEED_M_S`] (75 m) east through the footprint's centre along a
//!   sine sway of [`WALK_SWAY_M`] over [`WALK_SWAY_WAVELENGTH_M`], looking level (pitch 0, as
//!   Celba avoided looking into the ground) along the walk: the yaw wanders by `± atan(2π · 4 /
//!   50)` = ±26.7°, a pure function of the distance walked. `steps = 51` is one step a second,
//!   1.5-1.7 m apart (the sway lengthens the diagonal steps); fewer steps sample the same walk.
//!   Row columns: `yaw_deg` the heading, `distance_m` the distance walked along the x axis.
//! - **flight** (issue 33, C§5.2's 55 s flight that "starts with low altitude flight upon the
//!   forest while at the end ... the flight upon the forest is in much higher altitude"): east
//!   through the footprint's centre at [`FLIGHT_SPEED_M_S`] for [`FLIGHT_SECONDS`] (1650 m; at most
//!   [`FLIGHT_MAX_FOOTPRINT`] of the footprint's width, so it stays over small scenes too), the eye's
//!   height above the terrain rising linearly from [`FLIGHT_START_HEIGHT_M`] (20 m, among the
//!   crowns) to [`FLIGHT_END_HEIGHT_M`] (300 m), pitched down to the ground
//!   [`FLIGHT_LOOK_AHEAD_M`] ahead (-2.3° at 20 m, -31° at 300 m; at most `R` ahead in a small
//!   scene). Row columns: `yaw_deg` 0, `distance_m` the height above the terrain (what the
//!   flight's cost follows).
//! - **range** (issue 33, C§5.4's "points suffice to 2000-3500 m"): the forest seen from afar, one
//!   distance band a pose. The eye stands west of the footprint on its centre line, `d` before the
//!   west edge, [`RANGE_HEIGHT`]` · (x1 - x0)` above the terrain (300 m over a 1 km Celba forest,
//!   the flight's top), looking at the ground at the footprint's centre. `d` goes from
//!   [`RANGE_FAR_WIDTHS`] to [`RANGE_NEAR_WIDTHS`] footprint widths (4 → 1 km for a 1 km forest:
//!   an approach, so consecutive poses carry a temporal error); every tree then lies between `d`
//!   and about `d + 1.1 w` from the eye, so on a small forest a pose is a distance band. Row
//!   columns: `yaw_deg` 0, `distance_m` = `d`.
//!
//! Every frame records its tree fraction (the truth's and the frame's, `gt_tree_fraction`,
//! `tree_fraction`), and the report leaves frames whose truth shows no tree out of the means.

use forestlod_reference::cameras::NAMED_FOV_Y_DEGREES;
use forestlod_reference::scene::Scene;
use forestlod_shared::{Camera, Params};

/// Names of the scene-defined paths.
pub const PATH_NAMES: [&str; 8] = [
    "orbit",
    "dolly",
    "flyover",
    "pan",
    "slow-yaw",
    "walkthrough",
    "flight",
    "range",
];

/// Frames of a path when the sweep file gives no `steps`.
pub const DEFAULT_PATH_STEPS: u32 = 8;

/// The orbit's eye height above the ground, times `R`.
pub const ORBIT_HEIGHT: f32 = 0.25;
/// The dolly's eye height above the ground, times `T`.
pub const DOLLY_HEIGHT: f32 = 0.15;
/// The fly-over's height above the ground, times the footprint's width.
pub const FLYOVER_HEIGHT: f32 = 0.3;
/// The fly-over's pitch below the horizon, degrees.
pub const FLYOVER_PITCH_DEGREES: f32 = 30.0;
/// The pan's eye height above the ground, metres.
pub const PAN_HEIGHT_M: f32 = 40.0;
/// The pan's pitch below the horizon, degrees.
pub const PAN_PITCH_DEGREES: f32 = 5.0;

/// The slow yaw's whole turn, degrees (module docs).
pub const SLOW_YAW_DEGREES: f32 = 2.0;

/// The walkthrough's eye height above the terrain, metres (C§5.2: a person walking).
pub const WALK_EYE_HEIGHT_M: f32 = 1.7;
/// The walkthrough's speed, metres per second of the seed's animation (a walk: 1-2 m/s).
pub const WALK_SPEED_M_S: f32 = 1.5;
/// The walkthrough's length, seconds (C§5.2: 50 s).
pub const WALK_SECONDS: f32 = 50.0;
/// Amplitude of the walkthrough's sideways sway, metres.
pub const WALK_SWAY_M: f32 = 4.0;
/// Wavelength of the walkthrough's sway along its course, metres.
pub const WALK_SWAY_WAVELENGTH_M: f32 = 50.0;
/// The flight's height above the terrain at its start, metres (C§5.2: "low altitude").
pub const FLIGHT_START_HEIGHT_M: f32 = 20.0;
/// The flight's height above the terrain at its end, metres (C§5.2: "much higher altitude").
pub const FLIGHT_END_HEIGHT_M: f32 = 300.0;
/// The flight's ground speed, metres per second.
pub const FLIGHT_SPEED_M_S: f32 = 30.0;
/// The flight's length, seconds (C§5.2: 55 s).
pub const FLIGHT_SECONDS: f32 = 55.0;
/// The most of the footprint's width the flight covers (small scenes).
pub const FLIGHT_MAX_FOOTPRINT: f32 = 0.8;
/// The flight looks at the ground this far ahead, metres.
pub const FLIGHT_LOOK_AHEAD_M: f32 = 500.0;

/// The range's eye height above the terrain, times the footprint's width (module docs).
pub const RANGE_HEIGHT: f32 = 0.3;
/// The range's first distance before the footprint's west edge, in footprint widths.
pub const RANGE_FAR_WIDTHS: f32 = 4.0;
/// The range's last distance before the footprint's west edge, in footprint widths.
pub const RANGE_NEAR_WIDTHS: f32 = 1.0;

/// Where the walkthrough is after `walked` metres along x: `(x offset, y offset, heading in
/// degrees)` from its start (module docs).
fn walk_at(walked: f32) -> (f32, f32, f32) {
    let k = core::f32::consts::TAU / WALK_SWAY_WAVELENGTH_M;
    let y = WALK_SWAY_M * (k * walked).sin();
    let slope = WALK_SWAY_M * k * (k * walked).cos();
    (walked, y, slope.atan().to_degrees())
}

/// Whether `name` is a scene-defined path.
pub fn is_path(name: &str) -> bool {
    PATH_NAMES.contains(&name)
}

/// Where along its path frame `step` of `steps` is: `step / steps` for the closed paths (orbit,
/// pan: 360° is the start again), `step / (steps - 1)` for the open ones (0 for one frame).
pub fn path_fraction(name: &str, step: u32, steps: u32) -> f32 {
    if matches!(name, "orbit" | "pan") {
        step as f32 / steps.max(1) as f32
    } else if steps <= 1 {
        0.0
    } else {
        step as f32 / (steps - 1) as f32
    }
}

/// A camera from `eye`, yawed `yaw` degrees from +X and pitched `pitch` degrees (negative: down).
fn aimed(eye: [f32; 3], yaw: f32, pitch: f32, width: u32, height: u32) -> Camera {
    let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
    let f = [
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    ];
    let target = [eye[0] + f[0], eye[1] + f[1], eye[2] + f[2]];
    let mut c = Camera::look_at(eye, target, NAMED_FOV_Y_DEGREES, width, height);
    c.forward = f;
    c
}

/// Frame `t` in `[0, 1]` ([`path_fraction`]) of path `name`, with the row's `yaw_deg` and
/// `distance_m` (module docs). `None` for a name that is no path.
pub fn path_camera(
    name: &str,
    scene: &Scene,
    params: &Params,
    t: f32,
    width: u32,
    height: u32,
) -> Option<(Camera, f32, f32)> {
    let [x0, y0, x1, y1] = scene.bounds;
    let (cx, cy) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
    let r = ((x1 - x0).max(y1 - y0) * 0.5).max(1.0);
    let ground = |x: f32, y: f32| scene.terrain.height(x, y);
    Some(match name {
        "orbit" => {
            let yaw = 360.0 * t;
            let a = (180.0 + yaw).to_radians();
            let (ex, ey) = (cx + 1.5 * r * a.cos(), cy + 1.5 * r * a.sin());
            let eye = [ex, ey, ground(ex, ey) + ORBIT_HEIGHT * r];
            let target = [cx, cy, ground(cx, cy)];
            let c = Camera::look_at(eye, target, NAMED_FOV_Y_DEGREES, width, height);
            (c, yaw, 0.0)
        }
        "dolly" => {
            let (big_t, w) = (params.lod1_transition, params.fade_width);
            let (from, to) = (big_t + w, (big_t - 2.0 * w).max(0.0));
            let d = from + (to - from) * t;
            let ex = x0 - d;
            let h = (DOLLY_HEIGHT * big_t).max(1.0);
            let eye = [ex, cy, ground(ex, cy) + h];
            let tx = ex + 3.75 * big_t.max(1.0);
            let target = [tx, cy, ground(tx, cy)];
            let c = Camera::look_at(eye, target, NAMED_FOV_Y_DEGREES, width, height);
            (c, 0.0, d)
        }
        "flyover" => {
            let h = FLYOVER_HEIGHT * (x1 - x0).max(1.0);
            let flown = (x1 - x0) * t;
            let ex = x0 - h + flown;
            let eye = [ex, cy, ground(ex, cy) + h];
            (
                aimed(eye, 0.0, -FLYOVER_PITCH_DEGREES, width, height),
                0.0,
                flown,
            )
        }
        "pan" => {
            let yaw = 360.0 * t;
            let eye = [cx, cy, ground(cx, cy) + PAN_HEIGHT_M];
            (aimed(eye, yaw, -PAN_PITCH_DEGREES, width, height), yaw, 0.0)
        }
        "slow-yaw" => {
            let big_t = params.lod1_transition;
            let d = (big_t - params.fade_width).max(0.0);
            let ex = x0 - d;
            let eye = [ex, cy, ground(ex, cy) + (DOLLY_HEIGHT * big_t).max(1.0)];
            let ahead = 3.75 * big_t.max(1.0);
            let pitch = (ground(ex + ahead, cy) - eye[2]).atan2(ahead).to_degrees();
            let yaw = SLOW_YAW_DEGREES * (t - 0.5);
            (aimed(eye, yaw, pitch, width, height), yaw, d)
        }
        "walkthrough" => {
            let length = WALK_SPEED_M_S * WALK_SECONDS;
            let (dx, dy, yaw) = walk_at(length * t);
            let (ex, ey) = (cx - 0.5 * length + dx, cy + dy);
            let eye = [ex, ey, ground(ex, ey) + WALK_EYE_HEIGHT_M];
            (aimed(eye, yaw, 0.0, width, height), yaw, dx)
        }
        "flight" => {
            let length = (FLIGHT_SPEED_M_S * FLIGHT_SECONDS).min(FLIGHT_MAX_FOOTPRINT * (x1 - x0));
            let ex = cx - 0.5 * length + length * t;
            let h = FLIGHT_START_HEIGHT_M + (FLIGHT_END_HEIGHT_M - FLIGHT_START_HEIGHT_M) * t;
            let eye = [ex, cy, ground(ex, cy) + h];
            let pitch = -h.atan2(FLIGHT_LOOK_AHEAD_M.min(r)).to_degrees();
            (aimed(eye, 0.0, pitch, width, height), 0.0, h)
        }
        "range" => {
            let w = (x1 - x0).max(1.0);
            let d = w * (RANGE_FAR_WIDTHS + (RANGE_NEAR_WIDTHS - RANGE_FAR_WIDTHS) * t);
            let ex = x0 - d;
            let eye = [ex, cy, ground(ex, cy) + RANGE_HEIGHT * w];
            let target = [cx, cy, ground(cx, cy)];
            let c = Camera::look_at(eye, target, NAMED_FOV_Y_DEGREES, width, height);
            (c, 0.0, d)
        }
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use forestlod_reference::scene::builtin;

    /// Every path keeps the forest in view: the footprint's centre (orbit, pan: some tree) is in
    /// front of the eye and, for orbit and fly-over, inside the frustum, on `tiny` and `synthetic`.
    #[test]
    fn every_path_looks_at_the_forest() {
        for scene in [builtin::tiny(), builtin::synthetic()] {
            let params = Params::default();
            let [x0, y0, x1, y1] = scene.bounds;
            let centre = glam::Vec3::new((x0 + x1) * 0.5, (y0 + y1) * 0.5, 0.0);
            for name in PATH_NAMES {
                for step in 0..8 {
                    let t = path_fraction(name, step, 8);
                    let (c, ..) = path_camera(name, &scene, &params, t, 320, 180).unwrap();
                    c.validate().unwrap();
                    // Some tree lies inside the frustum.
                    let planes = c.frustum().planes;
                    let eye = glam::Vec3::from(c.eye);
                    let sees = |p: glam::Vec3| {
                        planes
                            .iter()
                            .all(|q| glam::Vec3::new(q[0], q[1], q[2]).dot(p - eye) + q[3] >= 0.0)
                    };
                    let any = scene
                        .instances
                        .iter()
                        .any(|i| sees(glam::Vec3::from(i.position)));
                    assert!(any, "{} {name} step {step}: no tree in view", scene.name);
                    if matches!(name, "orbit" | "flyover") && step == 4 {
                        // Half-way: the orbit looks at the centre, the fly-over is over it.
                        let z = scene.terrain.height(centre.x, centre.y);
                        assert!(sees(centre.with_z(z)), "{} {name}", scene.name);
                    }
                }
            }
        }
        assert!(path_camera("medium", &builtin::tiny(), &Params::default(), 0.0, 8, 8).is_none());
    }

    /// Trees of `scene` inside `c`'s frustum and within `reach` metres of the eye.
    fn trees_in_view(scene: &Scene, c: &Camera, reach: f32) -> usize {
        let planes = c.frustum().planes;
        let eye = glam::Vec3::from(c.eye);
        scene
            .instances
            .iter()
            .filter(|i| {
                let p = glam::Vec3::from(i.position);
                p.distance(eye) <= reach
                    && planes
                        .iter()
                        .all(|q| glam::Vec3::new(q[0], q[1], q[2]).dot(p - eye) + q[3] >= 0.0)
            })
            .count()
    }

    /// The walkthrough (C§5.2): the eye 1.7 m above the terrain at every step, steps of 1-2 m
    /// at one a second, a yaw that wanders both ways, level, inside the forest, deterministic,
    /// with trees in view within the default draw distance in a Celba scene.
    #[test]
    fn the_walkthrough_walks_at_eye_height_through_a_celba_forest() {
        let scene = forestlod_reference::scene::celba::celba("celba-20-4").unwrap();
        let params = Params::default();
        let steps = (WALK_SECONDS + 1.0) as u32; // one a second
        let poses: Vec<_> = (0..steps)
            .map(|i| {
                let t = path_fraction("walkthrough", i, steps);
                path_camera("walkthrough", &scene, &params, t, 320, 180).unwrap()
            })
            .collect();
        let [x0, y0, x1, y1] = scene.bounds;
        let (mut yaw_min, mut yaw_max) = (f32::INFINITY, f32::NEG_INFINITY);
        for (i, (c, yaw, walked)) in poses.iter().enumerate() {
            c.validate().unwrap();
            let [x, y, z] = c.eye;
            let above = z - scene.terrain.height(x, y);
            assert!(
                (above - WALK_EYE_HEIGHT_M).abs() < 1e-3,
                "step {i}: eye {above} m above the terrain"
            );
            assert!(x > x0 && x < x1 && y > y0 && y < y1, "step {i}: outside");
            assert!(c.forward[2].abs() < 1e-6, "step {i}: level");
            let seen = trees_in_view(&scene, c, params.draw_distance);
            assert!(seen > 10, "step {i}: {seen} trees in view");
            if i > 0 {
                let (p, ..) = &poses[i - 1];
                let step = glam::Vec3::from(c.eye).distance(glam::Vec3::from(p.eye));
                assert!((1.0..=2.0).contains(&step), "step {i}: {step} m");
                assert!(*walked > poses[i - 1].2, "step {i}: walks on");
            }
            yaw_min = yaw_min.min(*yaw);
            yaw_max = yaw_max.max(*yaw);
        }
        assert!(
            yaw_min < -20.0 && yaw_max > 20.0,
            "wander {yaw_min}..{yaw_max}"
        );
        let again = path_camera("walkthrough", &scene, &params, 0.37, 320, 180).unwrap();
        let once = path_camera("walkthrough", &scene, &params, 0.37, 320, 180).unwrap();
        assert_eq!(again, once, "deterministic");
    }

    /// The flight (C§5.2): its height above the terrain rises strictly from 20 m to 300 m, it
    /// looks down more as it climbs, stays over the forest, sees trees at every step in a Celba
    /// scene, and is deterministic.
    #[test]
    fn the_flight_rises_from_20_to_300_m_over_a_celba_forest() {
        let scene = forestlod_reference::scene::celba::celba("celba-5-4").unwrap();
        let params = Params::default();
        let steps = 12;
        let poses: Vec<_> = (0..steps)
            .map(|i| {
                let t = path_fraction("flight", i, steps);
                path_camera("flight", &scene, &params, t, 320, 180).unwrap()
            })
            .collect();
        let above = |c: &Camera| c.eye[2] - scene.terrain.height(c.eye[0], c.eye[1]);
        assert!((above(&poses[0].0) - FLIGHT_START_HEIGHT_M).abs() < 1e-3);
        assert!((above(&poses[steps as usize - 1].0) - FLIGHT_END_HEIGHT_M).abs() < 1e-3);
        let [x0, y0, x1, y1] = scene.bounds;
        for (i, (c, _, h)) in poses.iter().enumerate() {
            c.validate().unwrap();
            assert!((above(c) - h).abs() < 1e-3, "step {i}: row height {h}");
            let [x, y, _] = c.eye;
            assert!(x > x0 && x < x1 && y > y0 && y < y1, "step {i}: outside");
            let seen = trees_in_view(&scene, c, params.draw_distance);
            assert!(seen > 10, "step {i}: {seen} trees in view");
            if i > 0 {
                let (p, _, ph) = &poses[i - 1];
                assert!(h > ph && above(c) > above(p), "step {i}: rises");
                assert!(c.forward[2] < p.forward[2], "step {i}: looks further down");
                assert!(c.eye[0] > p.eye[0], "step {i}: flies on");
            }
        }
        let flown = poses[steps as usize - 1].0.eye[0] - poses[0].0.eye[0];
        assert!(
            (flown - FLIGHT_SPEED_M_S * FLIGHT_SECONDS).abs() < 0.5,
            "{flown}"
        );
        let a = path_camera("flight", &scene, &params, 0.61, 64, 48).unwrap();
        let b = path_camera("flight", &scene, &params, 0.61, 64, 48).unwrap();
        assert_eq!(a, b, "deterministic");
    }

    /// The range (issue 33): an approach from 4 to 1 footprint widths before the west edge, at
    /// 0.3 widths above the terrain, with the whole forest in view and no tree nearer than `d`.
    #[test]
    fn the_range_approaches_a_celba_forest_from_4_to_1_km() {
        let scene = forestlod_reference::scene::celba::celba("celba-20-1").unwrap();
        let params = Params::default();
        let steps = 7;
        let mut last = f32::INFINITY;
        for i in 0..steps {
            let t = path_fraction("range", i, steps);
            let (c, yaw, d) = path_camera("range", &scene, &params, t, 320, 180).unwrap();
            c.validate().unwrap();
            assert_eq!(yaw, 0.0);
            assert!(
                (1000.0..=4000.0).contains(&d) && d < last,
                "step {i}: {d} m"
            );
            last = d;
            let above = c.eye[2] - scene.terrain.height(c.eye[0], c.eye[1]);
            assert!((above - 300.0).abs() < 1e-2, "step {i}: {above} m up");
            let eye = glam::Vec3::from(c.eye);
            let nearest = scene
                .instances
                .iter()
                .map(|t| glam::Vec3::from(t.position).distance(eye))
                .fold(f32::INFINITY, f32::min);
            assert!(
                nearest >= d,
                "step {i}: a tree at {nearest} m, nearer than {d}"
            );
            let seen = trees_in_view(&scene, &c, f32::INFINITY);
            assert_eq!(
                seen,
                scene.instances.len(),
                "step {i}: the whole forest in view"
            );
        }
        assert_eq!(path_fraction("range", 0, steps), 0.0);
        assert_eq!(last, 1000.0);
    }

    #[test]
    fn the_slow_yaw_turns_slowly_with_the_front_in_the_band() {
        let scene = builtin::tiny();
        let params = Params {
            lod1_transition: 80.0,
            fade_width: 30.0,
            ..Params::default()
        };
        let pose = |t| path_camera("slow-yaw", &scene, &params, t, 64, 48).unwrap();
        let (first, yaw0, d) = pose(0.0);
        let (last, yaw1, _) = pose(1.0);
        assert_eq!((yaw0, yaw1, d), (-1.0, 1.0, 50.0));
        assert_eq!(first.eye, last.eye, "the eye stands still");
        let f0 = glam::Vec3::from(first.forward);
        let f1 = glam::Vec3::from(last.forward);
        // The turn about the vertical: the forward vectors' azimuths.
        let turned = (f1.y.atan2(f1.x) - f0.y.atan2(f0.x)).to_degrees();
        assert!((turned - SLOW_YAW_DEGREES).abs() < 1e-3, "{turned}");
        assert!(
            (f0.z - f1.z).abs() < 1e-6,
            "a pure yaw: the pitch is the same"
        );
        assert_eq!(path_fraction("slow-yaw", 8, 9), 1.0);
    }

    #[test]
    fn the_dolly_crosses_the_fade_band() {
        let scene = builtin::tiny();
        let params = Params {
            lod1_transition: 80.0,
            fade_width: 30.0,
            ..Params::default()
        };
        let d = |t| path_camera("dolly", &scene, &params, t, 64, 48).unwrap().2;
        // The front trees start beyond the band's far end T and end nearer than its start T - W.
        assert_eq!(d(0.0), 110.0);
        assert_eq!(d(1.0), 20.0);
        assert_eq!(path_fraction("dolly", 7, 8), 1.0);
        assert_eq!(path_fraction("orbit", 4, 8), 0.5);
        assert_eq!(path_fraction("flyover", 0, 1), 0.0);
    }
}
