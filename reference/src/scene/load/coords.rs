//! Coordinate conventions of loaded scenes (SPEC §3, §7; module docs, "Large coordinates"):
//! mesh files are converted to the Z-up world ([`UpAxis`]); world coordinates stay within
//! ±[`MAX_WORLD_COORDINATE`] and tree positions within ±[`MAX_RELATIVE_COORDINATE`] of the
//! scene origin; the default origin is the centre of the trees' bounding box rounded to whole
//! metres ([`default_origin`]).
//!
//! Imports none of the other loader files.

use serde::Deserialize;

/// Largest magnitude of a world coordinate (CSV values, origin, flat terrain height), metres.
pub const MAX_WORLD_COORDINATE: f64 = 1.0e8;
/// Largest distance of a tree from the scene origin per axis, metres (as [`Scene::validate`]).
pub const MAX_RELATIVE_COORDINATE: f64 = 1.0e6;

/// Up axis of an OBJ file; meshes are converted to the Z-up world (SPEC §3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Z up (GIS, Blender's world): taken as is.
    #[default]
    Z,
    /// Y up (most modelling exports): `(x, y, z)` becomes `(x, -z, y)`.
    Y,
}

impl UpAxis {
    /// A mesh-file position in the Z-up world (OBJ and glTF alike).
    pub fn to_z_up(self, p: [f32; 3]) -> [f32; 3] {
        match self {
            UpAxis::Z => p,
            UpAxis::Y => [p[0], -p[2], p[1]],
        }
    }
}

/// The origin the loaders choose for trees at world `positions` (SPEC §3): the centre of their
/// bounding box rounded to whole metres.
pub fn default_origin(positions: impl IntoIterator<Item = [f64; 3]>) -> [f64; 3] {
    let (lo, hi) = bounding_box(positions);
    [0, 1, 2].map(|k| ((lo[k] + hi[k]) * 0.5).round())
}

/// Componentwise `(min, max)` of `points`.
pub(super) fn bounding_box(points: impl IntoIterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}
