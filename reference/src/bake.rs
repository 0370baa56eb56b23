//! The billboard bake (E Alg. 3.1, §4.1; SPEC §5.1): every mesh rendered unlit from `K` elevation
//! angles (and `J` azimuths, E§7) into the layers of an array texture, then mipmapped by the
//! [`crate::mips`] stage.
//!
//! ## Contract
//! - Layer `mesh * K + k` holds mesh `mesh` seen at elevation `e_k = 90° / (K - 1) · k`
//!   ([`forestlod_shared::bake_elevation`]; `K = 1` bakes the level view only), from the fixed
//!   azimuth `h = +X` (trees are radially symmetric, E§3.3.1, so one azimuth stands for all).
//! - With `J > 1` azimuths (issue 30, E§7 "multiple azimuth angles ... in addition to the multiple
//!   elevation angles"; `Params::azimuth_count`), layer `mesh·K·J + k·J + j`
//!   ([`forestlod_shared::view_layer`]) holds the same elevation seen from the mesh-local
//!   azimuth `φ_j = 2π·j/J` ([`forestlod_shared::bake_azimuth`]): every mesh point is first turned
//!   into that view's frame ([`forestlod_shared::azimuth_to_view`], the identity for `j = 0`), then
//!   projected as below. `J = 1` bakes today's layers bit for bit.
//! - The projection is orthographic and fitted to the mesh's bounding box ("Calculate Orthogonal
//!   Projection From BB", E Alg. 3.1): the layer spans `[-W, W]` along the billboard's right vector
//!   and `[bottom, bottom + height]` along its tilted up vector, from
//!   [`forestlod_shared::billboard_extent`]. The draw stage expands its quads with the same extent,
//!   so a texel lands where the mesh point it shows would be.
//! - The layer is `r x r` (r a power of two, validated by [`forestlod_shared::Params::validate`]),
//!   cleared to transparent black; mesh texels are sampled bilinearly from level 0 (the bake's
//!   resolution is close to the texture's, and a fixed level keeps the GPU twin's sampling
//!   identical), fragments of alpha exactly 0 are discarded, the rest replace the colour behind them
//!   under the depth test LESS. Unlit, as the thesis.
//! - Rendered with the reference rasterizer ([`crate::raster`]), so the rules are the GPU's; the
//!   WGSL twin is `gpu/src/shaders/bake.wgsl` (render passes into array layers).

use forestlod_shared::{
    BillboardExtent, BillboardViews, MeshMeta, MipMode, Params, azimuth_to_view, bake_azimuth,
    bake_elevation, billboard_extent, frame_basis, frame_direction, octahedral::is_hemi,
};
use rayon::prelude::*;

use crate::InputError;
use crate::mips::{MipChain, build_mip_array};
use crate::raster::{ClearValues, DrawState, FragmentOutput, RenderTarget, Vertex};
use crate::sampler::Texture;
use crate::scene::{Scene, TreeMesh};
use crate::texture::Rgba8Image;

/// The bake's output: the billboard array texture with mips, and the extent of every layer.
#[derive(Clone, Debug)]
pub struct BakedBillboards {
    /// Angles per mesh, `K`.
    pub angle_count: u32,
    /// Azimuths per angle, `J` (issue 30; 1 is the thesis).
    pub azimuth_count: u32,
    /// [`forestlod_shared::ViewSphere`] as `u32` (issue 32): elevation views or octahedral frames.
    pub sphere: u32,
    /// Octahedral grid side `N` (issue 32; read only under octahedral views).
    pub grid: u32,
    /// Layer side, `r`.
    pub texture_size: u32,
    /// Level 0 of every layer, `mesh·K·J + k·J + j` (`mesh * K + k` at `J = 1`).
    pub layers: Vec<Rgba8Image>,
    /// Full mip chain of every layer, in layer order.
    pub chains: Vec<MipChain>,
    /// The sampled array texture (every layer's chain, 8-bit).
    pub texture: Texture,
    /// Extent of every layer.
    pub extents: Vec<BillboardExtent>,
    /// The octahedral impostors' depth channel (issue 32, `forestlod_shared::octahedral`), when
    /// [`forestlod_shared::depth_channel`] asks for it: one layer per billboard layer.
    pub depth: Option<BakedDepth>,
}

/// The depth channel of octahedral impostors (issue 32, `forestlod_shared::octahedral` module
/// docs): per frame, red = the orthographic bake's depth `z` of the visible surface, alpha = the
/// colour layer's alpha, mipmapped like the colour layers (alpha-weighted, so red stays a depth).
#[derive(Clone, Debug)]
pub struct BakedDepth {
    /// Level 0 of every layer, in the colour layers' order.
    pub layers: Vec<Rgba8Image>,
    /// Full mip chain of every layer.
    pub chains: Vec<MipChain>,
    /// The sampled array texture.
    pub texture: Texture,
}

impl BakedBillboards {
    /// The views baked per mesh.
    pub fn views(&self) -> BillboardViews {
        BillboardViews {
            angle_count: self.angle_count,
            azimuth_count: self.azimuth_count,
            sphere: self.sphere,
            grid: self.grid,
        }
    }
}

/// Orthographic clip-space position of mesh-local point `p` in layer `k`'s bake view (module docs)
/// from the azimuth `+X`.
pub fn bake_clip(p: [f32; 3], meta: &MeshMeta, elevation: f32) -> [f32; 4] {
    let (sin_a, cos_a) = 0.0f32.sin_cos();
    bake_clip_view(p, meta, elevation, sin_a, cos_a)
}

/// [`bake_clip`] from the mesh-local azimuth whose sine and cosine are `sin_a`, `cos_a` (module
/// docs): `p` and the bounding box's centre turned into the view's frame first.
pub fn bake_clip_view(
    p: [f32; 3],
    meta: &MeshMeta,
    elevation: f32,
    sin_a: f32,
    cos_a: f32,
) -> [f32; 4] {
    let p = azimuth_to_view(p, sin_a, cos_a);
    let e = billboard_extent(meta, elevation);
    let (s, c) = elevation.sin_cos();
    // h = +X, R = Z × h = +Y, U = Z cos e - h sin e, V = h cos e + Z sin e (toward the viewer).
    let right = p[1];
    let up = p[2] * c - p[0] * s;
    let toward_viewer = p[0] * c + p[2] * s;
    let half_width = e.half_width.max(f32::MIN_POSITIVE);
    let height = e.height.max(f32::MIN_POSITIVE);
    // Depth 0 at the nearest point of the bounding sphere, 1 at the farthest.
    let center = azimuth_to_view(
        [
            (meta.bbox_min[0] + meta.bbox_max[0]) * 0.5,
            (meta.bbox_min[1] + meta.bbox_max[1]) * 0.5,
            (meta.bbox_min[2] + meta.bbox_max[2]) * 0.5,
        ],
        sin_a,
        cos_a,
    );
    let center_toward = center[0] * c + center[2] * s;
    let radius = meta.sphere_radius.max(f32::MIN_POSITIVE);
    let depth = (center_toward + radius - toward_viewer) / (2.0 * radius);
    [
        right / half_width,
        (up - e.bottom) / height * 2.0 - 1.0,
        depth,
        1.0,
    ]
}

/// Bakes layer `k` of `k_count` for one mesh at `r x r`: level 0 only, from the azimuth `+X`.
pub fn bake_layer(
    mesh: &TreeMesh,
    meta: &MeshMeta,
    mesh_texture: &Texture,
    k: u32,
    k_count: u32,
    r: u32,
) -> Rgba8Image {
    let views = BillboardViews::elevations(k_count);
    bake_view(mesh, meta, mesh_texture, views, k, 0, r)
}

/// Orthographic clip-space position of mesh-local point `p` in the octahedral frame looking
/// along `-d` (issue 32, `forestlod_shared::octahedral`): the square `[-S, S]²` about the
/// bounding-box centre on the frame's basis, depth 0 at the sphere's point nearest the viewer.
pub fn octahedral_clip(p: [f32; 3], meta: &MeshMeta, d: [f32; 3]) -> [f32; 4] {
    let (r, u) = frame_basis(d);
    let c = mesh_center(meta);
    let o = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    let s = meta.sphere_radius.max(f32::MIN_POSITIVE);
    let dot = |a: [f32; 3]| o[0] * a[0] + o[1] * a[1] + o[2] * a[2];
    [dot(r) / s, dot(u) / s, (s - dot(d)) / (2.0 * s), 1.0]
}

/// The centre of a mesh's bounding box (its sphere's centre, mesh units).
pub fn mesh_center(meta: &MeshMeta) -> [f32; 3] {
    [
        (meta.bbox_min[0] + meta.bbox_max[0]) * 0.5,
        (meta.bbox_min[1] + meta.bbox_max[1]) * 0.5,
        (meta.bbox_min[2] + meta.bbox_max[2]) * 0.5,
    ]
}

/// Bakes view `(k, j)` of `views` for one mesh at `r x r` (module docs): level 0 only. Under
/// octahedral views (issue 32) `k` is the frame `f` and `j` is 0.
pub fn bake_view(
    mesh: &TreeMesh,
    meta: &MeshMeta,
    mesh_texture: &Texture,
    views: BillboardViews,
    k: u32,
    j: u32,
    r: u32,
) -> Rgba8Image {
    if views.octahedral() {
        let d = frame_direction(k, views.grid, is_hemi(views.sphere));
        return bake_with(mesh, mesh_texture, r, false, |p| {
            octahedral_clip(p, meta, d)
        });
    }
    let elevation = bake_elevation(k, views.angle_count);
    let (sin_a, cos_a) = bake_azimuth(j, views.azimuth_count).sin_cos();
    bake_with(mesh, mesh_texture, r, false, |p| {
        bake_clip_view(p, meta, elevation, sin_a, cos_a)
    })
}

/// The depth layer of octahedral frame `f` (issue 32, [`BakedDepth`]): the same render as
/// [`bake_view`]'s, writing `[z, 0, 0, α]` (linear) for the kept fragment of depth `z`.
pub fn bake_depth_view(
    mesh: &TreeMesh,
    meta: &MeshMeta,
    mesh_texture: &Texture,
    views: BillboardViews,
    f: u32,
    r: u32,
) -> Rgba8Image {
    let d = frame_direction(f, views.grid, is_hemi(views.sphere));
    bake_with(mesh, mesh_texture, r, true, |p| octahedral_clip(p, meta, d))
}

/// Renders `mesh` at `r x r` with the clip positions of `clip` (module docs' rules); `depth`
/// writes the fragment's depth in red instead of its colour ([`bake_depth_view`]).
fn bake_with(
    mesh: &TreeMesh,
    mesh_texture: &Texture,
    r: u32,
    depth: bool,
    clip: impl Fn([f32; 3]) -> [f32; 4],
) -> Rgba8Image {
    let triangles: Vec<[Vertex<2>; 3]> = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            core::array::from_fn(|i| {
                let v = t[i] as usize;
                Vertex::new(clip(mesh.positions[v]), mesh.uvs[v])
            })
        })
        .collect();
    let shader = |f: &crate::raster::Fragment<2>| {
        let texel = mesh_texture.bilinear(0, 0, f.varyings);
        (texel[3] > 0.0).then_some(FragmentOutput {
            color: if depth {
                [f.depth, 0.0, 0.0, texel[3]]
            } else {
                texel
            },
            id: 1,
            depth: None,
        })
    };
    let mut target = RenderTarget::new(r, r, ClearValues::default());
    target.draw(&triangles, &shader, &DrawState::OPAQUE);
    target.color_image()
}

/// Mip chains of every mesh texture, as sampled textures (the draw stage's LOD0 textures).
pub fn mesh_textures(
    scene: &Scene,
    mode: MipMode,
    alpha_ref: f32,
) -> Result<Vec<Texture>, InputError> {
    scene
        .meshes
        .iter()
        .map(|m| {
            let chain = crate::mips::build_mips(&m.texture, mode, alpha_ref).map_err(|e| {
                InputError::new(
                    scene.name.clone(),
                    format!("mesh {:?}, texture", m.name),
                    format!("{}x{}", m.texture.width, m.texture.height),
                    e.to_string(),
                )
            })?;
            Texture::new(chain.levels.into_iter().map(|l| l.rgba8).collect()).map_err(|e| {
                InputError::new(
                    scene.name.clone(),
                    format!("mesh {:?}, texture", m.name),
                    "mip chain",
                    e.to_string(),
                )
            })
        })
        .collect()
}

/// Most memory the bake may hold at once, bytes (issue 28, "work and memory refused up front").
/// The project's machines have 24 GiB; the default bake (10 angles, 128², synthetic's meshes)
/// needs about 30 MB, and the largest built-in sweep's a few hundred MB. A request past this is a
/// typo or an experiment no machine we run on could finish (`--texture-size 4096 --angles 91`
/// asked for over 100 GB and was killed after 48 s): refused before anything is built.
pub const MAX_BAKE_BYTES: u64 = 16 << 30;

/// The memory [`bake`] holds for `meshes` meshes with `params`, bytes, counted from the structures
/// it keeps per layer (`meshes × K × J` layers of side `r`): level 0 as RGBA8 (`layers`), every mip
/// level in linear `f32` RGBA and RGBA8 (`chains`), and the sampled array texture's levels, again
/// RGBA8 and linear `f32` RGBA (`texture`, [`Texture::heap_bytes`]); plus one `r × r` render target (colour, depth, id: 12 bytes a texel) per layer in
/// flight, counted once. Saturating, so absurd inputs cannot wrap. Exact to within the vectors'
/// headers; it does not count the GPU twin's copy, which wgpu's limits bound.
pub fn bake_memory_bytes(meshes: usize, params: &Params) -> u64 {
    let r = u64::from(params.texture_size.max(1));
    let mut per_layer: u64 = 4 * r * r; // level 0 kept as `layers`
    let mut side = r;
    loop {
        // chains and texture: each linear f32 RGBA (16 B) + RGBA8 (4 B)
        per_layer = per_layer.saturating_add(40 * side * side);
        if side == 1 {
            break;
        }
        side /= 2;
    }
    let mut layers = BillboardViews::of(params).layers(meshes);
    if forestlod_shared::depth_channel(params) {
        layers = layers.saturating_mul(2); // the depth channel: one more layer per frame
    }
    layers.saturating_mul(per_layer).saturating_add(12 * r * r)
}

/// Refuses parameters whose bake would hold more than [`MAX_BAKE_BYTES`] for `meshes` meshes,
/// naming the flags that set it and printing the estimate ([`bake_memory_bytes`]).
pub fn check_bake_memory(meshes: usize, params: &Params) -> Result<(), InputError> {
    let need = bake_memory_bytes(meshes, params);
    if need <= MAX_BAKE_BYTES {
        return Ok(());
    }
    Err(InputError::new(
        "<params>",
        "--texture-size x --angles x --azimuths",
        format!(
            "{} x {} angles x {} azimuths x {meshes} meshes",
            params.texture_size, params.angle_count, params.azimuth_count
        ),
        format!(
            "the billboard bake would need about {}, over the limit of {} (MAX_BAKE_BYTES): lower --texture-size, --angles or --azimuths",
            crate::files::size_text(need),
            crate::files::size_text(MAX_BAKE_BYTES)
        ),
    ))
}

/// E Alg. 3.1 for every mesh, angle and azimuth (E§7), then the mips stage on every layer.
pub fn bake(
    scene: &Scene,
    metas: &[MeshMeta],
    mesh_textures: &[Texture],
    params: &Params,
) -> Result<BakedBillboards, InputError> {
    let (views, r) = (BillboardViews::of(params), params.texture_size);
    let k_count = views.angle_count;
    let jobs: Vec<(usize, u32, u32)> = views.views(scene.meshes.len()).collect();
    let layers: Vec<Rgba8Image> = jobs
        .par_iter()
        .map(|&(m, k, j)| {
            bake_view(
                &scene.meshes[m],
                &metas[m],
                &mesh_textures[m],
                views,
                k,
                j,
                r,
            )
        })
        .collect();
    let extents = jobs
        .iter()
        .map(|&(m, k, _)| views.extent(&metas[m], k))
        .collect();
    let mode = params.mips().map_err(InputError::from)?;
    let (chains, texture) = mip_array(&layers, mode, params.alpha_cutoff, r, "billboard")?;
    let depth = if forestlod_shared::depth_channel(params) {
        let layers: Vec<Rgba8Image> = jobs
            .par_iter()
            .map(|&(m, f, _)| {
                bake_depth_view(&scene.meshes[m], &metas[m], &mesh_textures[m], views, f, r)
            })
            .collect();
        let (chains, texture) = mip_array(&layers, mode, params.alpha_cutoff, r, "depth")?;
        Some(BakedDepth {
            layers,
            chains,
            texture,
        })
    } else {
        None
    };
    Ok(BakedBillboards {
        angle_count: k_count,
        azimuth_count: views.azimuth_count,
        sphere: views.sphere,
        grid: views.grid,
        texture_size: r,
        layers,
        chains,
        texture,
        extents,
        depth,
    })
}

/// The mips stage on a set of layers and the sampled array of their chains; errors name `what`.
fn mip_array(
    layers: &[Rgba8Image],
    mode: MipMode,
    alpha_ref: f32,
    r: u32,
    what: &str,
) -> Result<(Vec<MipChain>, Texture), InputError> {
    let chains = build_mip_array(layers, mode, alpha_ref).map_err(|e| {
        InputError::new(
            "<bake>",
            format!("{what} layers"),
            format!("{r}x{r}"),
            e.to_string(),
        )
    })?;
    let texture = Texture::new_array(
        chains
            .iter()
            .map(|c| c.levels.iter().map(|l| l.rgba8.clone()).collect())
            .collect(),
    )
    .map_err(|e| {
        InputError::new(
            "<bake>",
            format!("{what} array"),
            format!("{r}x{r}"),
            e.to_string(),
        )
    })?;
    Ok((chains, texture))
}

/// A contact sheet of level 0 of every layer: one row per mesh, one column per view (angle-major:
/// the `J` azimuths of angle `k` in columns `k·J..(k + 1)·J`), over a
/// checkerboard (grey 200 and 150 in 8-texel squares) so transparency shows. `meshes` rows
/// (at least the bake's meshes); the pixels no layer covers (rows past the bake's meshes) are
/// opaque black `[0, 0, 0, 255]`.
pub fn contact_sheet(baked: &BakedBillboards, meshes: usize) -> Rgba8Image {
    let (k, r) = (baked.views().per_mesh(), baked.texture_size);
    let (w, h) = (k * r, meshes as u32 * r);
    let mut sheet = Rgba8Image::new(w, h, [0, 0, 0, 255]);
    for (layer, image) in baked.layers.iter().enumerate() {
        let (row, col) = (layer as u32 / k, layer as u32 % k);
        for y in 0..r {
            for x in 0..r {
                let check = if ((x / 8) + (y / 8)) % 2 == 0 {
                    200.0
                } else {
                    150.0
                };
                let t = image.get(x, y);
                let a = t[3] as f32 / 255.0;
                let px: [u8; 4] = core::array::from_fn(|c| {
                    if c == 3 {
                        255
                    } else {
                        (t[c] as f32 * a + check * (1.0 - a)).round() as u8
                    }
                });
                sheet.texels[((row * r + y) * w + col * r + x) as usize] = px;
            }
        }
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The contact sheet against its doc, on a hand-made bake of one mesh at two angles drawn
    /// with two rows: each layer in its cell, composited over the checkerboard (opaque texels as
    /// they are, a transparent one the checker's grey, a half-transparent one the mix), and
    /// every pixel of the row no layer covers opaque black. Added for issue 36's Rust mutant 845
    /// (the sheet's background `[0, 0, 0, 255]` -> `[1, 0, 0, 255]`).
    #[test]
    fn the_contact_sheet_shows_each_layer_over_the_checkerboard_on_black() {
        let r = 16;
        let mut opaque = Rgba8Image::new(r, r, [200, 30, 30, 255]);
        opaque.texels[0] = [0, 0, 0, 0];
        let half = Rgba8Image::new(r, r, [100, 100, 100, 128]);
        let baked = BakedBillboards {
            angle_count: 2,
            azimuth_count: 1,
            sphere: 0,
            grid: 0,
            texture_size: r,
            layers: vec![opaque.clone(), half],
            chains: Vec::new(),
            texture: Texture::new(vec![opaque]).unwrap(),
            extents: Vec::new(),
            depth: None,
        };
        let sheet = contact_sheet(&baked, 2);
        assert_eq!((sheet.width, sheet.height), (2 * r, 2 * r));
        // Layer 0 at column 0: opaque texels, and the transparent (0, 0) on the light checker.
        assert_eq!(sheet.get(5, 3), [200, 30, 30, 255]);
        assert_eq!(sheet.get(0, 0), [200, 200, 200, 255]);
        // Layer 1 at column 1, texel (8, 0) on the dark checker: 100 · a + 150 · (1 - a),
        // a = 128 / 255.
        assert_eq!(sheet.get(r + 8, 0), [125, 125, 125, 255]);
        // Row 1: no layer; every pixel the background.
        for y in r..2 * r {
            for x in 0..2 * r {
                assert_eq!(
                    sheet.get(x, y),
                    [0, 0, 0, 255],
                    "pixel ({x}, {y}) outside every layer"
                );
            }
        }
    }

    /// The estimate that refuses a bake up front is what a real bake holds: exact for the
    /// structures it keeps (a mutant dropping the `texture`'s linear copy, or counting one level,
    /// fails here), plus the one render target.
    #[test]
    fn bake_memory_estimate_is_what_the_bake_holds() {
        let scene = crate::scene::builtin::tiny();
        let params = Params {
            texture_size: 16,
            angle_count: 3,
            ..Default::default()
        };
        let prepared = crate::pipeline::prepare(scene, &params).unwrap();
        let b = &prepared.billboards;
        let texels = |n: usize| n as u64;
        let layers: u64 = b.layers.iter().map(|l| 4 * texels(l.texels.len())).sum();
        let chains: u64 = b
            .chains
            .iter()
            .flat_map(|c| &c.levels)
            .map(|l| 16 * texels(l.linear.texels.len()) + 4 * texels(l.rgba8.texels.len()))
            .sum();
        let held = layers + chains + b.texture.heap_bytes();
        let meshes = prepared.scene.meshes.len();
        let estimate = bake_memory_bytes(meshes, &params);
        assert_eq!(
            estimate,
            held + 12 * 16 * 16,
            "estimate {estimate}, held {held}"
        );
        // Saturates rather than wraps, and the refusal states the estimate and the limit.
        let huge = Params {
            texture_size: 4096,
            angle_count: 91,
            ..Default::default()
        };
        assert!(bake_memory_bytes(usize::MAX, &huge) == u64::MAX);
        let e = check_bake_memory(meshes, &huge).unwrap_err().to_string();
        assert!(e.contains("4096 x 91 angles") && e.contains("GiB"), "{e}");
        check_bake_memory(meshes, &Params::default()).unwrap();
    }
}
