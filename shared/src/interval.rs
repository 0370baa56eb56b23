//! The batch projection interval and the LOD decision on it (E§3.5, Fig. 3.8; E§4.3).
//!
//! A bounding sphere `(c, r)` projected onto the view direction `f` from the eye `e` becomes the
//! interval `[d - r, d + r]` with `d = (c - e) · f` (E§3.5). Every point of the sphere has its view
//! depth inside it, so deciding LODs on the interval is conservative for every fragment of every
//! tree in the sphere (SPEC §6).
//!
//! **Rounding.** `d` is computed in `f32`; its error is at most a few ulp of
//! `|c - e|₁ = |cx - ex| + |cy - ey| + |cz - ez|`. The interval is widened by
//! [`selection_margin`] = `4 ε (|c - e|₁ + r)` on both sides, which bounds that error, so
//! containment of a tree's sphere in its batch's sphere carries over to their computed intervals.
//! The per-tree oracle widens the same way, so a batch of one tree decides exactly as the oracle.
//!
//! Keep in sync with `gpu/src/shaders/common.wgsl` (`selection_margin`, `view_interval`, `lod_needs`),
//! used by `gpu/src/shaders/select.wgsl`.

/// A view-depth interval `[lo, hi]` around the projected centre `d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewInterval {
    /// Projected distance of the centre, `(c - e) · f`.
    pub d: f32,
    /// Lower end, `d - r - margin`.
    pub lo: f32,
    /// Upper end, `d + r + margin`.
    pub hi: f32,
}

/// Widening that absorbs the `f32` rounding of the projection; see the module docs.
pub fn selection_margin(rel: [f32; 3], radius: f32) -> f32 {
    4.0 * f32::EPSILON * (rel[0].abs() + rel[1].abs() + rel[2].abs() + radius)
}

/// Projects the sphere `(center, radius)` onto the view direction (E§3.5).
pub fn view_interval(
    center: [f32; 3],
    radius: f32,
    eye: [f32; 3],
    forward: [f32; 3],
) -> ViewInterval {
    let rel = [center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]];
    let d = rel[0] * forward[0] + rel[1] * forward[1] + rel[2] * forward[2];
    let m = selection_margin(rel, radius);
    ViewInterval {
        d,
        lo: d - radius - m,
        hi: d + radius + m,
    }
}

/// Widening of an axis-aligned box's interval and plane test (the box twin of
/// [`selection_margin`]): `16 ε (|c - e|₁ + e_x + e_y + e_z)`. Four times the sphere's, so that a box
/// that contains a tree's sphere also contains the tree's *computed* interval (the tree's own
/// margin, `4 ε (|c_t - e|₁ + r_t) <= 4 ε (|c - e|₁ + Σ e_k)`, plus both evaluations' rounding):
/// the per-tree oracle decides on those computed intervals.
pub fn aabb_margin(rel: [f32; 3], extent: [f32; 3]) -> f32 {
    16.0 * f32::EPSILON
        * (rel[0].abs() + rel[1].abs() + rel[2].abs() + extent[0] + extent[1] + extent[2])
}

/// Projects the axis-aligned box `center ± extent` onto the view direction (E§7 "tighter bounding
/// volumes", C§4.5's effective radius): `d ± (|f_x| e_x + |f_y| e_y + |f_z| e_z)`, widened by
/// [`aabb_margin`]. Every point of the box has its view depth inside it.
pub fn aabb_view_interval(
    center: [f32; 3],
    extent: [f32; 3],
    eye: [f32; 3],
    forward: [f32; 3],
) -> ViewInterval {
    let rel = [center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]];
    let d = rel[0] * forward[0] + rel[1] * forward[1] + rel[2] * forward[2];
    let r =
        forward[0].abs() * extent[0] + forward[1].abs() * extent[1] + forward[2].abs() * extent[2];
    let m = aabb_margin(rel, extent);
    ViewInterval {
        d,
        lo: d - r - m,
        hi: d + r + m,
    }
}

/// Which LODs an interval needs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LodNeeds {
    /// Some point is closer than `fade_end`: LOD0 has weight there.
    pub lod0: bool,
    /// Some point is at or past `fade_start`: LOD1 has weight there.
    pub lod1: bool,
}

impl LodNeeds {
    /// Whether the interval overlaps the fade band, i.e. needs both.
    pub fn both(self) -> bool {
        self.lod0 && self.lod1
    }
    /// `self` asks for at least everything `other` does.
    pub fn covers(self, other: LodNeeds) -> bool {
        (self.lod0 || !other.lod0) && (self.lod1 || !other.lod1)
    }
}

/// The LODs an interval `[lo, hi]` needs, for a band `[fade_start, fade_end]` and `lod_levels`
/// (E§4.3: "for every LOD the batch is checked against the transition distance of the LOD, and
/// whether or not it overlaps the transition distance of the next LOD").
///
/// LOD0 has weight exactly where `d < fade_end`, LOD1 where `d > fade_start` (or `d >= fade_end` for
/// an empty band); `hi >= fade_start` covers both cases for LOD1. With one LOD level everything is
/// LOD0.
pub fn lod_needs(lo: f32, hi: f32, fade_start: f32, fade_end: f32, lod_levels: u32) -> LodNeeds {
    if lod_levels < 2 {
        return LodNeeds {
            lod0: true,
            lod1: false,
        };
    }
    LodNeeds {
        lod0: lo < fade_end,
        lod1: hi >= fade_start,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_is_centre_projection_plus_minus_radius() {
        let i = view_interval([10.0, 0.0, 0.0], 2.0, [0.0; 3], [1.0, 0.0, 0.0]);
        assert_eq!(i.d, 10.0);
        assert!(i.lo < 8.0 && i.lo > 7.9999);
        assert!(i.hi > 12.0 && i.hi < 12.0001);
    }

    #[test]
    fn aabb_interval_uses_the_effective_radius() {
        let f = [0.6f32, 0.8, 0.0];
        let i = aabb_view_interval([10.0, 0.0, 0.0], [1.0, 2.0, 3.0], [0.0; 3], f);
        assert_eq!(i.d, 6.0);
        // |f| · e = 0.6 + 1.6 = 2.2 (the z extent does not count: f_z = 0).
        assert!(i.lo < 3.8 && i.lo > 3.7999, "{i:?}");
        assert!(i.hi > 8.2 && i.hi < 8.2001, "{i:?}");
    }

    #[test]
    fn needs_follow_the_band() {
        let n = |lo, hi| lod_needs(lo, hi, 750.0, 1000.0, 2);
        assert_eq!(
            n(0.0, 700.0),
            LodNeeds {
                lod0: true,
                lod1: false
            }
        );
        assert_eq!(
            n(0.0, 800.0),
            LodNeeds {
                lod0: true,
                lod1: true
            }
        );
        assert_eq!(
            n(1000.0, 1200.0),
            LodNeeds {
                lod0: false,
                lod1: true
            }
        );
        assert_eq!(
            n(999.0, 1200.0),
            LodNeeds {
                lod0: true,
                lod1: true
            }
        );
        // One LOD level: meshes everywhere.
        assert_eq!(
            lod_needs(5000.0, 6000.0, 750.0, 1000.0, 1),
            LodNeeds {
                lod0: true,
                lod1: false
            }
        );
        // "No LOD0" (transition 0, E Fig. 5.7): nothing in front of the eye needs LOD0.
        assert_eq!(
            lod_needs(0.5, 10.0, -250.0, 0.0, 2),
            LodNeeds {
                lod0: false,
                lod1: true
            }
        );
    }
}
