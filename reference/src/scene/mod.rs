//! Scenes: tree meshes, tree instances and terrain: only what a forest under these algorithms
//! needs (SPEC §4). No scene graph, no materials beyond one texture per mesh, no lighting.
//!
//! - A [`TreeMesh`] is a low-poly tree (< 20 triangles, E§3.1: a trunk plus crossed alpha-textured
//!   cards) in local coordinates, Z up, standing at the origin, with one sRGB RGBA8 texture.
//! - An [`Instance`] is a position, a yaw about +Z, a uniform scale and a mesh index. Trees are
//!   radially symmetric, which is what lets billboards vary by elevation only (E§3.3.1).
//! - A [`Scene`] keeps an `f64` origin; instance positions are `f32` relative to it (SPEC §3, §7).
//!
//! Built-in scenes are in [`builtin`], user scenes (scene file + CSV + OBJ/glTF) in [`load`].

pub mod builtin;
pub mod celba;
pub mod load;
pub mod patchy;

use forestlod_shared::{MAX_MESH_VERTICES, MeshMeta};
use glam::Vec3;

use crate::InputError;
use crate::texture::Rgba8Image;

/// Most triangles a tree mesh may have (E§3.1: "< 20 triangles").
pub const MAX_TREE_TRIANGLES: usize = 19;

/// A low-poly tree in local coordinates (metres, Z up, base at the origin).
#[derive(Clone, Debug, PartialEq)]
pub struct TreeMesh {
    /// Species name, unique within a scene.
    pub name: String,
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Texture coordinates, one per vertex, `(0, 0)` at the texture's top-left.
    pub uvs: Vec<[f32; 2]>,
    /// Triangle list of mesh-local vertex indices.
    pub indices: Vec<u32>,
    /// The mesh's one texture: sRGB RGBA8, straight alpha, with real transparency.
    pub texture: Rgba8Image,
}

/// One tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Base position relative to the scene origin.
    pub position: [f32; 3],
    /// Rotation about +Z, radians.
    pub yaw: f32,
    /// Uniform scale (> 0).
    pub scale: f32,
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
}

/// Ground under the trees: the draw stage renders it, scenes place trees on it.
#[derive(Clone, Debug, PartialEq)]
pub enum Terrain {
    /// A flat plane at height `z`.
    Flat {
        /// Height of the plane.
        z: f32,
    },
    /// Gentle hills: `amplitude * sin(2πx/wavelength) * cos(2πy/wavelength)` plus a second octave
    /// at a quarter of the amplitude and 0.37 of the wavelength (the "basic terrain" of E§5).
    Hills {
        /// Peak height of the first octave, metres.
        amplitude: f32,
        /// Wavelength of the first octave, metres.
        wavelength: f32,
    },
    /// A grid of heights from an elevation model (issue 34: GeoTIFF or ESRI ASCII grid,
    /// `load::dem`), resampled to its vertex budget, drawn on its own grid lines
    /// ([`Scene::ground_axes`]) and as high everywhere as the drawn surface
    /// ([`forestlod_shared::grid_surface_height`]).
    Grid(std::sync::Arc<HeightGrid>),
}

/// The heights of an elevation model as drawn (issue 34): `nx · ny` samples, row by row from
/// the south-west (`heights[j · nx + i]` at `x = x0 + (x1 - x0) · i / (nx - 1)`, `y` alike),
/// relative to the scene origin.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightGrid {
    /// Samples per row (>= 2).
    pub nx: usize,
    /// Rows (>= 2).
    pub ny: usize,
    /// `[x0, y0, x1, y1]`: the first and the last sample's position, relative to the origin.
    pub extent: [f32; 4],
    /// Heights relative to the origin, finite.
    pub heights: Vec<f32>,
}

impl HeightGrid {
    /// The sample spacing `[dx, dy]`.
    pub fn step(&self) -> [f32; 2] {
        let [x0, y0, x1, y1] = self.extent;
        [
            (x1 - x0) / (self.nx - 1) as f32,
            (y1 - y0) / (self.ny - 1) as f32,
        ]
    }

    /// Height of the drawn surface at `(x, y)` ([`forestlod_shared::grid_surface_height`]).
    pub fn height(&self, x: f32, y: f32) -> f32 {
        forestlod_shared::grid_surface_height(
            &self.heights,
            self.nx,
            self.ny,
            [self.extent[0], self.extent[1]],
            self.step(),
            x,
            y,
        )
    }

    /// The sample lines, each computed as the uniform grid computes its lines
    /// (`forestlod_shared::uniform_axes`): `x0 + (x1 - x0) · i / (nx - 1)`.
    pub fn axes(&self) -> forestlod_shared::GridAxes {
        let [x0, y0, x1, y1] = self.extent;
        let (nx, ny) = (self.nx as u32 - 1, self.ny as u32 - 1);
        forestlod_shared::GridAxes {
            xs: (0..=nx)
                .map(|i| x0 + (x1 - x0) * i as f32 / nx as f32)
                .collect(),
            ys: (0..=ny)
                .map(|j| y0 + (y1 - y0) * j as f32 / ny as f32)
                .collect(),
        }
    }
}

impl Terrain {
    /// Ground height at `(x, y)` relative to the scene origin.
    pub fn height(&self, x: f32, y: f32) -> f32 {
        match *self {
            Terrain::Flat { z } => z,
            Terrain::Hills {
                amplitude,
                wavelength,
            } => {
                let k = core::f32::consts::TAU / wavelength;
                let k2 = k / 0.37;
                amplitude
                    * ((k * x).sin() * (k * y).cos()
                        + 0.25 * (k2 * x + 1.3).sin() * (k2 * y + 0.7).cos())
            }
            Terrain::Grid(ref g) => g.height(x, y),
        }
    }
}

/// A forest: meshes, instances, terrain, and where it lies.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Name (built-in name or the scene file's stem).
    pub name: String,
    /// World position of the local origin, `f64` (UTM-scale coordinates stay exact here).
    pub origin: [f64; 3],
    /// Tree meshes (species).
    pub meshes: Vec<TreeMesh>,
    /// Trees.
    pub instances: Vec<Instance>,
    /// Ground.
    pub terrain: Terrain,
    /// Footprint `[min_x, min_y, max_x, max_y]` relative to the origin.
    pub bounds: [f32; 4],
}

/// Footprint `[min_x, min_y, max_x, max_y]` of trees standing at `positions` (what
/// [`Scene::bounds`] holds).
pub fn footprint(positions: impl IntoIterator<Item = [f32; 3]>) -> [f32; 4] {
    let mut bounds = [
        f32::INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
    ];
    for p in positions {
        bounds = [
            bounds[0].min(p[0]),
            bounds[1].min(p[1]),
            bounds[2].max(p[0]),
            bounds[3].max(p[1]),
        ];
    }
    bounds
}

impl TreeMesh {
    /// A mesh named `name` with `texture` and no geometry yet (the builders and loaders push
    /// vertices and triangles onto it).
    pub fn new(name: &str, texture: Rgba8Image) -> Self {
        TreeMesh {
            name: name.to_string(),
            positions: Vec::new(),
            uvs: Vec::new(),
            indices: Vec::new(),
            texture,
        }
    }

    /// Per-mesh metadata (E§4.1): bounding box, sphere and billboard size. Index and vertex offsets
    /// are filled in when meshes are packed into shared buffers; here they are 0.
    pub fn meta(&self) -> MeshMeta {
        let mut meta = self.bounds_meta();
        let sizes = crate::metric::measure_mesh(self, &meta);
        meta.area_size = sizes.opaque_area.sqrt();
        meta.error_size = sizes.geometric_error;
        meta
    }

    /// [`TreeMesh::meta`] without the metric sizes (0): the bounds alone.
    pub fn bounds_meta(&self) -> MeshMeta {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.positions {
            lo = lo.min(Vec3::from(*p));
            hi = hi.max(Vec3::from(*p));
        }
        let half = (hi - lo) * 0.5;
        // Horizontal circumradius around the trunk axis (x = y = 0): covers every yaw.
        let half_width = self
            .positions
            .iter()
            .map(|p| (p[0] * p[0] + p[1] * p[1]).sqrt())
            .fold(0.0f32, f32::max);
        MeshMeta {
            first_index: 0,
            index_count: self.indices.len() as u32,
            first_vertex: 0,
            vertex_count: self.positions.len() as u32,
            bbox_min: lo.to_array(),
            billboard_half_width: half_width,
            bbox_max: hi.to_array(),
            sphere_radius: round_up(half.length()),
            area_size: 0.0,
            error_size: 0.0,
            _pad0: 0,
            _pad1: 0,
        }
    }

    /// Checks the mesh's own invariants, naming the first violation.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        let at = |what: String| format!("mesh {}, {what}", crate::error::excerpt(&self.name));
        if self.positions.is_empty() || self.indices.is_empty() {
            return Err(InputError::new(
                file,
                at("geometry".into()),
                format!(
                    "{} vertices, {} indices",
                    self.positions.len(),
                    self.indices.len()
                ),
                "expected at least one triangle",
            ));
        }
        if self.positions.len() > MAX_MESH_VERTICES as usize {
            return Err(InputError::new(
                file,
                at("vertex count".into()),
                self.positions.len(),
                format!("expected at most {MAX_MESH_VERTICES} vertices per tree mesh"),
            ));
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(InputError::new(
                file,
                at("index count".into()),
                self.indices.len(),
                "expected a multiple of 3 (a triangle list)",
            ));
        }
        if self.indices.len() / 3 > MAX_TREE_TRIANGLES {
            return Err(InputError::new(
                file,
                at("triangle count".into()),
                self.indices.len() / 3,
                format!("expected at most {MAX_TREE_TRIANGLES} triangles per tree (E§3.1)"),
            ));
        }
        if self.uvs.len() != self.positions.len() {
            return Err(InputError::new(
                file,
                at("uv count".into()),
                self.uvs.len(),
                format!("expected one uv per vertex ({})", self.positions.len()),
            ));
        }
        for (i, p) in self.positions.iter().enumerate() {
            if p.iter().any(|c| !c.is_finite() || c.abs() > 1.0e4) {
                return Err(InputError::new(
                    file,
                    at(format!("vertex {i}")),
                    format!("{p:?}"),
                    "expected finite coordinates within 10 km of the tree's base",
                ));
            }
        }
        for (i, uv) in self.uvs.iter().enumerate() {
            if uv.iter().any(|c| !c.is_finite()) {
                return Err(InputError::new(
                    file,
                    at(format!("uv {i}")),
                    format!("{uv:?}"),
                    "expected finite texture coordinates",
                ));
            }
        }
        for (i, &ix) in self.indices.iter().enumerate() {
            if ix as usize >= self.positions.len() {
                return Err(InputError::new(
                    file,
                    at(format!("index {i}")),
                    ix,
                    format!(
                        "out of range: the mesh has {} vertices",
                        self.positions.len()
                    ),
                ));
            }
        }
        let t = &self.texture;
        if t.width == 0
            || t.height == 0
            || t.texels.len() != (t.width as usize) * (t.height as usize)
        {
            return Err(InputError::new(
                file,
                at("texture".into()),
                format!("{}x{} with {} texels", t.width, t.height, t.texels.len()),
                "expected a non-empty RGBA image",
            ));
        }
        Ok(())
    }
}

/// Smallest `f32` strictly above `x` for `x > 0` (0 stays 0): radii are rounded up so that sphere
/// containment survives rounding.
pub fn round_up(x: f32) -> f32 {
    if x > 0.0 && x.is_finite() {
        f32::from_bits(x.to_bits() + 1)
    } else {
        x
    }
}

/// Bounding sphere of one tree in scene coordinates: the mesh's local sphere (centred on its box
/// centre) scaled, rotated by yaw about +Z and translated. Tree heights are included by construction.
pub fn tree_sphere(instance: &Instance, mesh: &MeshMeta) -> ([f32; 3], f32) {
    let local = (Vec3::from(mesh.bbox_min) + Vec3::from(mesh.bbox_max)) * 0.5 * instance.scale;
    let (s, c) = instance.yaw.sin_cos();
    let rotated = Vec3::new(
        c * local.x - s * local.y,
        s * local.x + c * local.y,
        local.z,
    );
    let center = Vec3::from(instance.position) + rotated;
    (
        center.to_array(),
        round_up(mesh.sphere_radius * instance.scale),
    )
}

impl Scene {
    /// Per-mesh metadata for every mesh, in mesh order.
    pub fn mesh_metas(&self) -> Vec<MeshMeta> {
        self.meshes.iter().map(TreeMesh::meta).collect()
    }

    /// The ground grid's lines: the uniform grid over the footprint plus the margin
    /// ([`forestlod_shared::uniform_axes`]) for flat and hills terrain; for a [`Terrain::Grid`]
    /// its own sample lines, plus one line beyond each side that the footprint plus the margin
    /// reaches past the grid (the edge heights continued, issue 34).
    pub fn ground_axes(&self) -> forestlod_shared::GridAxes {
        let Terrain::Grid(g) = &self.terrain else {
            return forestlod_shared::uniform_axes(self.bounds);
        };
        let mut axes = g.axes();
        let m = forestlod_shared::TERRAIN_MARGIN;
        let [bx0, by0, bx1, by1] = self.bounds;
        let widen = |lines: &mut Vec<f32>, lo: f32, hi: f32| {
            if lo < lines[0] {
                lines.insert(0, lo);
            }
            if hi > lines[lines.len() - 1] {
                lines.push(hi);
            }
        };
        widen(&mut axes.xs, bx0 - m, bx1 + m);
        widen(&mut axes.ys, by0 - m, by1 + m);
        axes
    }

    /// Every vertex of the ground grid once, row by row: [`forestlod_shared::axes_vertices`] on
    /// [`Scene::ground_axes`] and the terrain's height.
    pub fn ground_vertices(&self) -> Vec<([f32; 3], [f32; 3])> {
        forestlod_shared::axes_vertices(&self.ground_axes(), |x, y| self.terrain.height(x, y))
    }

    /// The ground's triangles in draw order, each vertex `(position, linear colour)`: what every
    /// renderer draws and the truth traces ([`forestlod_shared::axes_grid`]).
    pub fn ground_triangles(&self) -> Vec<[([f32; 3], [f32; 3]); 3]> {
        forestlod_shared::axes_grid(&self.ground_axes(), |x, y| self.terrain.height(x, y))
    }

    /// Footprint area in km².
    pub fn area_km2(&self) -> f64 {
        let [x0, y0, x1, y1] = self.bounds;
        ((x1 - x0) as f64 * (y1 - y0) as f64) / 1.0e6
    }

    /// Total triangles over all meshes.
    pub fn mesh_triangles(&self) -> usize {
        self.meshes.iter().map(|m| m.indices.len() / 3).sum()
    }

    /// Checks every mesh and instance, naming the first violation. `file` names the source.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        if self.meshes.is_empty() {
            return Err(InputError::new(
                file,
                "meshes",
                "[]",
                "expected at least one tree mesh",
            ));
        }
        if self.instances.is_empty() {
            return Err(InputError::new(
                file,
                "instances",
                "[]",
                "expected at least one tree: the scene is empty",
            ));
        }
        if self.origin.iter().any(|c| !c.is_finite()) {
            return Err(InputError::new(
                file,
                "origin",
                format!("{:?}", self.origin),
                "expected finite coordinates",
            ));
        }
        for m in &self.meshes {
            m.validate(file)?;
        }
        for (i, t) in self.instances.iter().enumerate() {
            let pos = format!("instance {i}");
            if t.position.iter().any(|c| !c.is_finite()) {
                return Err(InputError::new(
                    file,
                    pos,
                    format!("{:?}", t.position),
                    "expected a finite position",
                ));
            }
            if t.position.iter().any(|c| c.abs() > 1.0e6) {
                return Err(InputError::new(
                    file,
                    pos,
                    format!("{:?}", t.position),
                    "expected a position within 1000 km of the scene origin (store large coordinates in the origin)",
                ));
            }
            if !t.yaw.is_finite() {
                return Err(InputError::new(
                    file,
                    format!("instance {i}, yaw"),
                    t.yaw,
                    "expected a finite angle",
                ));
            }
            if !(t.scale.is_finite() && t.scale > 0.0 && t.scale <= 1.0e3) {
                return Err(InputError::new(
                    file,
                    format!("instance {i}, scale"),
                    t.scale,
                    "expected a finite scale in (0, 1000]",
                ));
            }
            if t.mesh as usize >= self.meshes.len() {
                return Err(InputError::new(
                    file,
                    format!("instance {i}, mesh"),
                    t.mesh,
                    format!(
                        "unknown species: the scene has {} meshes",
                        self.meshes.len()
                    ),
                ));
            }
        }
        Ok(())
    }
}
