//! The mesh sizes the screen-space LOD metrics scale (issue 29; `shared/src/metric.rs`), measured
//! on a bake of the mesh's level view, not guessed from its bounding box.
//!
//! ## Contract
//! [`measure_mesh`] renders the mesh as the billboard bake renders layer 0 of `K = 1` (E Alg. 3.1:
//! elevation 0, azimuth `+X`, the orthographic projection fitted to the mesh's billboard extent,
//! texels sampled bilinearly from level 0, fragments of alpha 0 discarded, depth test LESS), at
//! [`METRIC_BAKE_SIDE`]² texels, whatever the frame's billboard resolution, so that the sizes are a
//! property of the mesh alone ([`forestlod_shared::MeshMeta`] carries them). Then:
//! - **opaque area** `A`: the texels whose stored alpha is at least one half (the coverage of the
//!   alpha test at its default cutoff), times the texel's world area `(2W/n)·(H/n)`; the
//!   pixel-area metrics scale `√A` (C Eq. 4.3 takes an area);
//! - **geometric error** `e`: the largest distance, over those texels, of the mesh surface the
//!   texel shows (its depth) from the billboard's plane (which holds the trunk axis and faces the
//!   viewer): how far the flat card puts a visible point from where the mesh has it. The
//!   `screen-error` metric scales it (3D Tiles' geometric error of the billboard level).
//!
//! Both are at unit scale; a tree of scale `s` has `s²·A` and `s·e`. The measurement error is the
//! bake's: one texel along each edge of the silhouette (`(2W + H)·max(2W, H)/n` of area) and
//! half a texel's depth step (`r/n`) of error.
//!
//! **Memoized.** The measurement is a pure function of the mesh's geometry and texture (its name
//! aside), and it is not cheap: [`METRIC_AZIMUTHS`] renders of [`METRIC_BAKE_SIDE`]² texels.
//! Every `TreeMesh::meta` call pays it, and a property test builds the same few meshes once per
//! case: `perf` on `select_properties::selection_is_conservative` (256 cases of 300 trees) put
//! 87 % of its 27 s in these renders. [`measure_mesh`] therefore keeps the sizes of the last
//! [`MEASURED_KEPT`] distinct meshes, keyed by their **exact** content (positions' and uvs' bits,
//! indices, texture size and texels; compared in full on a hit, so two meshes never share an
//! entry), and forgets them all when full (bounded memory). A hit returns the very value a
//! measurement would, so outputs stay bit-identical whatever the order or thread count.

use std::collections::HashMap;
use std::sync::Mutex;

use forestlod_shared::MeshMeta;

use crate::bake::bake_clip;
use crate::raster::{ClearValues, DrawState, FragmentOutput, RenderTarget, Vertex};
use crate::sampler::Texture;
use crate::scene::TreeMesh;

/// Texels along each side of the metric's level-view bake (module docs).
pub const METRIC_BAKE_SIDE: u32 = 256;

/// A mesh's sizes at unit scale (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshSizes {
    /// Opaque area of the level-view billboard, m².
    pub opaque_area: f32,
    /// Largest distance of a visible surface point from the billboard's plane, m.
    pub geometric_error: f32,
}

/// The sizes of `mesh` (with its bounds `meta`) from its level-view bake (module docs). A mesh
/// whose texture cannot be sampled measures 0 (its load has refused it already).
pub fn measure_mesh(mesh: &TreeMesh, meta: &MeshMeta) -> MeshSizes {
    let _ = meta;
    let key = MeshKey::of(mesh);
    let kept = MEASURED.get_or_init(Default::default);
    if let Some(&sizes) = lock(kept).get(&key) {
        return sizes;
    }
    let sizes = measure_uncached(mesh);
    let mut kept = lock(kept);
    if kept.len() >= MEASURED_KEPT {
        kept.clear();
    }
    kept.insert(key, sizes);
    sizes
}

/// Distinct meshes whose sizes [`measure_mesh`] keeps (module docs): the built-in scenes have
/// five species, a property test three; random-texture tests make a new mesh per case, hence the
/// bound.
pub const MEASURED_KEPT: usize = 64;

/// The kept sizes (module docs).
static MEASURED: std::sync::OnceLock<Mutex<HashMap<MeshKey, MeshSizes>>> =
    std::sync::OnceLock::new();

/// The kept sizes, locked; a panic elsewhere while holding the lock leaves a map that is still
/// valid (entries are inserted whole), so a poisoned lock is taken as is.
fn lock(
    m: &Mutex<HashMap<MeshKey, MeshSizes>>,
) -> std::sync::MutexGuard<'_, HashMap<MeshKey, MeshSizes>> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Everything [`measure_uncached`] reads of a mesh, exactly (floats by their bits).
#[derive(PartialEq, Eq, Hash)]
struct MeshKey {
    positions: Vec<[u32; 3]>,
    uvs: Vec<[u32; 2]>,
    indices: Vec<u32>,
    size: (u32, u32),
    texels: Vec<[u8; 4]>,
}

impl MeshKey {
    fn of(mesh: &TreeMesh) -> Self {
        Self {
            positions: mesh.positions.iter().map(|p| p.map(f32::to_bits)).collect(),
            uvs: mesh.uvs.iter().map(|p| p.map(f32::to_bits)).collect(),
            indices: mesh.indices.clone(),
            size: (mesh.texture.width, mesh.texture.height),
            texels: mesh.texture.texels.clone(),
        }
    }
}

/// [`measure_mesh`] without the memo.
fn measure_uncached(mesh: &TreeMesh) -> MeshSizes {
    // The billboard stands for every azimuth (E§3.3.1): the mesh is measured from
    // METRIC_AZIMUTHS directions (rotated about its trunk axis), area averaged, error the largest.
    let mut area = 0.0f64;
    let mut error = 0.0f32;
    for k in 0..METRIC_AZIMUTHS {
        let (s, c) = (core::f32::consts::TAU * k as f32 / METRIC_AZIMUTHS as f32).sin_cos();
        let rotated = TreeMesh {
            positions: mesh
                .positions
                .iter()
                .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])
                .collect(),
            ..mesh.clone()
        };
        let m = measure_view(&rotated, &rotated.bounds_meta());
        area += m.opaque_area as f64;
        error = error.max(m.geometric_error);
    }
    MeshSizes {
        opaque_area: (area / METRIC_AZIMUTHS as f64) as f32,
        geometric_error: error,
    }
}

/// Azimuths the sizes are measured from ([`measure_mesh`]). Eight: crossed cards seen at 0°
/// and 45° bound their depth error; at +X alone a crossed-card tree measures about a tenth of it.
pub const METRIC_AZIMUTHS: u32 = 8;

/// [`measure_mesh`] from the bake's own azimuth `+X` only.
fn measure_view(mesh: &TreeMesh, meta: &MeshMeta) -> MeshSizes {
    let zero = MeshSizes {
        opaque_area: 0.0,
        geometric_error: 0.0,
    };
    let Ok(texture) = Texture::new(vec![mesh.texture.clone()]) else {
        return zero;
    };
    let n = METRIC_BAKE_SIDE;
    let triangles: Vec<[Vertex<2>; 3]> = mesh
        .indices
        .chunks_exact(3)
        .filter_map(|t| {
            let ok = t
                .iter()
                .all(|&v| (v as usize) < mesh.positions.len().min(mesh.uvs.len()));
            ok.then(|| {
                core::array::from_fn(|i| {
                    let v = t[i] as usize;
                    Vertex::new(bake_clip(mesh.positions[v], meta, 0.0), mesh.uvs[v])
                })
            })
        })
        .collect();
    let shader = |f: &crate::raster::Fragment<2>| {
        let texel = texture.bilinear(0, 0, f.varyings);
        (texel[3] > 0.0).then_some(FragmentOutput {
            color: texel,
            id: 1,
            depth: None,
        })
    };
    let mut target = RenderTarget::new(n, n, ClearValues::default());
    target.draw(&triangles, &shader, &DrawState::OPAQUE);
    let image = target.color_image();
    let depth = target.depth();
    // bake_clip at elevation 0: depth = (c_x + r - x) / 2r, x the distance toward the viewer
    // from the plane through the trunk axis.
    let center_x = (meta.bbox_min[0] + meta.bbox_max[0]) * 0.5;
    let radius = meta.sphere_radius.max(f32::MIN_POSITIVE);
    let extent = forestlod_shared::billboard_extent(meta, 0.0);
    let texel_area =
        (2.0 * extent.half_width as f64 / n as f64) * (extent.height as f64 / n as f64);
    let mut count = 0u64;
    let mut error = 0.0f32;
    for (texel, &z) in image.texels.iter().zip(depth) {
        if texel[3] >= 128 {
            count += 1;
            let x = center_x + radius - z * 2.0 * radius;
            error = error.max(x.abs());
        }
    }
    MeshSizes {
        opaque_area: (count as f64 * texel_area) as f32,
        geometric_error: error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::Rgba8Image;

    /// A square card of side 2 m in the plane x = `depth`, facing +X, fully opaque.
    fn card(depth: f32, alpha: u8) -> TreeMesh {
        TreeMesh {
            name: "card".into(),
            positions: vec![
                [depth, -1.0, 0.0],
                [depth, 1.0, 0.0],
                [depth, 1.0, 2.0],
                [depth, -1.0, 2.0],
            ],
            uvs: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
            indices: vec![0, 1, 2, 0, 2, 3],
            texture: Rgba8Image::new(4, 4, [90, 140, 60, alpha]),
        }
    }

    /// The memo returns what a measurement gives, and tells apart meshes that differ in one
    /// texel or one vertex's bits (module docs). Mutation-checked: a key without the texels
    /// hands the half-transparent card the opaque card's area and fails.
    #[test]
    fn the_memo_returns_each_meshs_own_measurement() {
        let opaque = card(0.5, 255);
        let faint = card(0.5, 0);
        let moved = TreeMesh {
            positions: opaque
                .positions
                .iter()
                .map(|p| [f32::from_bits(p[0].to_bits() + 1), p[1], p[2]])
                .collect(),
            ..opaque.clone()
        };
        for mesh in [&opaque, &faint, &moved, &opaque] {
            let m = mesh.bounds_meta();
            assert_eq!(
                measure_mesh(mesh, &m),
                measure_uncached(mesh),
                "{}",
                mesh.name
            );
        }
        assert_ne!(
            measure_mesh(&opaque, &opaque.bounds_meta()),
            measure_mesh(&faint, &faint.bounds_meta())
        );
    }

    #[test]
    fn an_opaque_card_measures_its_area_and_its_offset() {
        // Offset 0.5 m toward the viewer: the billboard extent's half-width is the horizontal
        // circumradius √(0.5² + 1²), so the card covers 1 / 1.118 of the layer's width.
        let mesh = card(0.5, 255);
        let meta = mesh.meta();
        let s = measure_view(&mesh, &mesh.bounds_meta());
        let texel = 2.0 * meta.billboard_half_width / METRIC_BAKE_SIDE as f32;
        // One texel column at each silhouette edge (module docs): 2 texels × 2 m tall.
        let edge = 2.0 * texel * 2.0;
        assert!(
            (s.opaque_area - 4.0).abs() <= edge,
            "area {} vs 4 ± {edge}",
            s.opaque_area
        );
        // Depth quantization: the raster keeps depth in f32, so the error is nearly exact.
        assert!(
            (s.geometric_error - 0.5).abs() < 1e-3,
            "error {}",
            s.geometric_error
        );
        // Over the azimuths the card is seen edge-on too: less area on average, and an error
        // of at least the +X view's (its far corners, 1.118 m from the axis).
        let all = measure_mesh(&mesh, &meta);
        assert!(
            all.opaque_area < s.opaque_area && all.opaque_area > 0.0,
            "{all:?}"
        );
        assert!(
            all.geometric_error >= s.geometric_error && all.geometric_error <= 1.12,
            "{all:?}"
        );
        assert_eq!(meta.area_size, all.opaque_area.sqrt());
        assert_eq!(meta.error_size, all.geometric_error);
    }

    #[test]
    fn translucent_texels_do_not_count() {
        let s = measure_mesh(&card(0.0, 100), &card(0.0, 100).bounds_meta());
        assert_eq!(s.opaque_area, 0.0);
        assert_eq!(s.geometric_error, 0.0);
    }
}

/// The calibration of C Eq. 4.3 (issue 29): an opaque square facing the eye at the centre of the
/// view, drawn by the reference rasterizer, covers `C·A/D²` pixels with the corrected constant,
/// within the pixels its edges cross; the seed's constant is 4x off.
#[cfg(test)]
mod calibration {
    use forestlod_shared::metric::{metric_constant, pixel_area};
    use forestlod_shared::{Camera, StageId};
    use glam::{Vec3, Vec4};

    use crate::raster::{ClearValues, DrawState, FragmentOutput, RenderTarget, Vertex};

    /// Pixels of a square of side `side` at view depth `depth`, centred in the view of `camera`.
    fn covered(camera: &Camera, side: f32, depth: f32) -> u64 {
        let b = camera.basis();
        let c = Vec3::from(camera.eye) + b.forward * depth;
        let h = side * 0.5;
        let m = camera.view_projection();
        let corner = |sx: f32, sy: f32| {
            let p = c + b.right * (sx * h) + b.up * (sy * h);
            let clip: Vec4 = m * p.extend(1.0);
            Vertex::new(clip.to_array(), [0.0f32; 1])
        };
        let (a, bb, cc, d) = (
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        );
        let triangles = vec![[a, bb, cc], [a, cc, d]];
        let shader = |_: &crate::raster::Fragment<1>| {
            Some(FragmentOutput {
                color: [1.0; 4],
                id: 1,
                depth: None,
            })
        };
        let mut target = RenderTarget::new(camera.width, camera.height, ClearValues::default());
        target.draw(&triangles, &shader, &DrawState::OPAQUE);
        let _ = StageId::Draw;
        target.aux().iter().filter(|&&id| id == 1).count() as u64
    }

    #[test]
    fn a_square_covers_c_a_over_d_squared_pixels_and_the_seed_constant_is_4x_off() {
        let mut worst = 0.0f64;
        for (w, h, fov) in [
            (640, 360, 60.0),
            (1280, 720, 45.0),
            (1920, 1080, 90.0),
            (300, 500, 30.0),
        ] {
            let cam = Camera::look_at([0.0, 0.0, 10.0], [0.0, 100.0, 10.0], fov, w, h);
            for (side, depth) in [(2.0f32, 20.0f32), (10.0, 300.0), (1.0, 7.0)] {
                let got = covered(&cam, side, depth) as f64;
                let area = (side * side) as f64;
                let want = pixel_area(metric_constant(&cam, false), area, depth as f64);
                // Edge ambiguity: the pixels the square's four edges cross, each edge
                // `√want` pixels long.
                let edges = 4.0 * want.sqrt() + 4.0;
                assert!(
                    (got - want).abs() <= edges,
                    "{w}x{h} {fov}°: side {side} at {depth}: {got} pixels, C·A/D² = {want:.1} ± {edges:.1}"
                );
                worst = worst.max((got - want).abs() / edges);
                let seed = pixel_area(metric_constant(&cam, true), area, depth as f64);
                if want > 50.0 {
                    assert!(
                        (got - seed).abs() > edges,
                        "the seed's constant passes at {w}x{h}: {got} vs {seed:.1}"
                    );
                    let ratio = seed / got;
                    assert!((ratio - 4.0).abs() < 0.5, "seed over covered {ratio}");
                }
            }
        }
        eprintln!("calibration: worst |covered - C·A/D²| = {worst:.2} of the edge allowance");
    }
}
