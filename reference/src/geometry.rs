//! Packing tree meshes into the shared vertex and index buffers the draw stage pulls from (E§4.1).
//!
//! All meshes live in one vertex array and one index array, so one multi-draw-indirect call can draw
//! every command without rebinding (E§4.4). Index values are **mesh-local** vertex ids: the draw
//! stage adds the mesh's `first_vertex` (see [`forestlod_shared::DrawCommand`] for why
//! `base_vertex` is taken by the command index). The billboard quad (the thesis appends "a single
//! dummy triangle" as origin and scale reference, E§4.1; without a geometry stage we append a unit
//! quad, two triangles) comes last.

use forestlod_shared::MeshMeta;

use crate::scene::Scene;

/// One vertex of the shared vertex buffer. Keep in sync with `gpu/src/shaders/draw.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackedVertex {
    /// Mesh-local position (unit scale, zero yaw).
    pub position: [f32; 3],
    /// Texture coordinate.
    pub uv: [f32; 2],
}
const _: () = assert!(core::mem::size_of::<PackedVertex>() == 20);

/// The billboard quad's corners as `(u, v)` texture coordinates; the vertex stage expands them
/// around the tree (E§3.3.1). Triangles `0 1 2` and `0 2 3`, counter-clockwise seen from the eye.
pub const BILLBOARD_CORNERS: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
/// Index list of the billboard quad, mesh-local.
pub const BILLBOARD_INDICES: [u32; 6] = [0, 1, 2, 0, 2, 3];

/// Every mesh packed into shared buffers, plus the billboard quad.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedGeometry {
    /// Shared vertex buffer.
    pub vertices: Vec<PackedVertex>,
    /// Shared index buffer of mesh-local ids.
    pub indices: Vec<u32>,
    /// Per-mesh metadata with offsets filled in, in mesh order.
    pub meshes: Vec<MeshMeta>,
    /// The billboard quad's range (only the offset and count fields are meaningful).
    pub billboard: MeshMeta,
    /// The far level's iota range (issue 32, `forestlod_shared::far`): local vertex ids
    /// `0..3·MAX_HULL_TRIANGLES`, after the billboard quad; far commands index its start. No
    /// vertices: the far primitives pull theirs from the cells and the hull.
    pub far: MeshMeta,
}

/// Packs the scene's meshes in mesh order and appends the billboard quad.
pub fn pack_geometry(scene: &Scene) -> PackedGeometry {
    pack_geometry_with(scene, crate::scene::TreeMesh::meta)
}

/// [`pack_geometry`] with each mesh's metadata from `meta` (offsets are filled in here). A
/// caller that never selects by a screen-space metric may pass `TreeMesh::bounds_meta` and skip
/// the metric's measurement (`crate::metric`, several renders per mesh); the metric sizes are
/// then 0.
pub fn pack_geometry_with(
    scene: &Scene,
    meta: impl Fn(&crate::scene::TreeMesh) -> MeshMeta,
) -> PackedGeometry {
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    let mut meshes = Vec::with_capacity(scene.meshes.len());
    for mesh in &scene.meshes {
        let mut meta = meta(mesh);
        meta.first_vertex = vertices.len() as u32;
        meta.first_index = indices.len() as u32;
        vertices.extend(
            mesh.positions
                .iter()
                .zip(&mesh.uvs)
                .map(|(p, uv)| PackedVertex {
                    position: *p,
                    uv: *uv,
                }),
        );
        indices.extend_from_slice(&mesh.indices);
        meshes.push(meta);
    }
    let billboard = MeshMeta {
        first_index: indices.len() as u32,
        index_count: BILLBOARD_INDICES.len() as u32,
        first_vertex: vertices.len() as u32,
        vertex_count: BILLBOARD_CORNERS.len() as u32,
        ..bytemuck::Zeroable::zeroed()
    };
    vertices.extend(BILLBOARD_CORNERS.iter().map(|c| PackedVertex {
        position: [c[0], 0.0, c[1]],
        uv: *c,
    }));
    indices.extend_from_slice(&BILLBOARD_INDICES);
    let far_len = 3 * forestlod_shared::MAX_HULL_TRIANGLES;
    let far = MeshMeta {
        first_index: indices.len() as u32,
        index_count: far_len,
        ..bytemuck::Zeroable::zeroed()
    };
    indices.extend(0..far_len);
    PackedGeometry {
        vertices,
        indices,
        meshes,
        billboard,
        far,
    }
}
