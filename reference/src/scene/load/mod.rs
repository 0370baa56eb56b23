//! User scenes: a small TOML scene file, a CSV instance table, and OBJ meshes with RGBA PNG
//! textures (SPEC §4 "User scenes").
//!
//! # Contract
//! - **Every input is validated** and every failure is an [`InputError`] naming the file, the
//!   position (line and column name for CSV, line/column or field for TOML, line for OBJ), the
//!   offending value and what was expected: NaN/inf, negative or zero scale, unknown species, wrong
//!   type, missing or unknown column, wrong column count, empty table, too many rows, index out of
//!   range, texture not 8-bit RGBA / zero / non-power-of-two / non-square / too large, missing or unreadable
//!   file. No input bytes make these functions panic (property-tested). Every successful load ends
//!   with [`Scene::validate`].
//! - **Large coordinates** (SPEC §3, §7): CSV coordinates are parsed as `f64` (UTM scale,
//!   x ~ 5e5, y ~ 5.3e6), the scene keeps an `f64` origin, and instance positions are the `f32`
//!   differences to it, so every `f32` stays small. Default origin: the centre of the instances'
//!   bounding box rounded to whole metres.
//! - **Meshes** are < 20-triangle trees (E§3.1) with one texture: a built-in procedural species
//!   ([`super::builtin::Species`]), an OBJ file (loaded by `tobj`, polygons triangulated in their
//!   plane by [`triangulate_polygon`], all objects merged) or a glTF 2.0 file (`.gltf`/`.glb`,
//!   [`parse_gltf_mesh`]), with an 8-bit RGBA PNG. OBJ texture coordinates have `v` up; they are
//!   flipped to the top-left convention of [`TreeMesh::uvs`](super::TreeMesh::uvs) (glTF's already are top-left).
//! - **One texture size**: every species texture must have species 0's square size (the GPU draw
//!   stage samples all mesh textures from one array texture, `gpu/src/draw.rs`
//!   `upload_texture_array`); built-in species are [`super::builtin::TEXTURE_SIZE`]².
//! - **Files under the scene's folder**: a scene file may only name files under its own folder
//!   (after resolving `..` and symbolic links) unless [`LoadOptions::allow_outside_paths`].
//! - **Error chains**: an error in a file named by the scene file is reported through the naming
//!   field ([`InputError::within`]): `forest.toml: line 4, column 8, field species[0].mesh =
//!   "oak.obj": oak.obj: line 5, face: value "99/1": ...`.
//!
//! # Scene file (TOML)
//! ```toml
//! name = "wachau"                        # optional; default: the file stem
//! instances = "trees.csv"                # required; relative to the scene file
//! origin = [500000.0, 5300000.0, 0.0]    # optional world origin (f64)
//!
//! [terrain]                              # optional; default: flat at the lowest tree
//! kind = "flat"                          # "flat" with z (world height, metres) ...
//! z = 210.0
//! # kind = "hills", amplitude = 25.0, wavelength = 1500.0   # ... or hills around the origin
//! # kind = "dem", file = "dem.tif", vertices = 66049, z_tolerance = 1.0
//! #                                      # ... or an elevation model (issue 34, [`dem`])
//!
//! [columns]                              # optional (issue 34, [`inventory`]): an inventory's own
//! x = "East"                             # column names; `instances` may then be a CSV with
//! y = "North"                            # named columns or GeoJSON points
//! height = "H_m"
//! species = "Baumart"
//! [species_names]                        # optional: inventory species name -> scene species
//! Fichte = "spruce"
//!
//! [[species]]                            # optional; default: the five built-in species
//! name = "spruce"
//! builtin = "spruce"                     # a built-in procedural mesh ...
//!
//! [[species]]
//! name = "oak"
//! mesh = "oak.obj"                       # ... or an OBJ/glTF file and an RGBA PNG,
//! texture = "oak.png"                    # relative to the scene file
//! up = "y"                               # optional: the mesh's up axis, "z" or "y"
//!                                        # (default: "z" for OBJ, "y" for glTF)
//! ```
//! Unknown keys are errors. Species order gives the mesh indices.
//!
//! # Instance table (CSV)
//! A header naming the six columns `x,y,z,yaw,scale,species` (any order, each once, nothing else),
//! then one tree per row: world position in metres (`f64`), yaw about +Z in **radians**, scale
//! (finite, in (0, 1000]), and species by name or by 0-based index. Fields are trimmed; empty lines
//! are skipped. At least one and at most [`MAX_INSTANCES`] rows.

use std::path::Path;

use crate::InputError;
use crate::error::{cut, excerpt};
use crate::scene::Scene;

mod assemble;
mod coords;
pub mod dem;
mod diagnostics;
pub mod geotiff_writer;
mod gltf_mesh;
mod instances_csv;
pub mod inventory;
mod obj_mesh;
mod paths;
mod png_texture;
mod scene_toml;
#[cfg(test)]
mod test_util;

use paths::label;

pub use assemble::{
    DemReport, load_instances_with_builtin_species, parse_instances_with_builtin_species, scale_for,
};
pub use coords::{MAX_RELATIVE_COORDINATE, MAX_WORLD_COORDINATE, UpAxis, default_origin};
pub use gltf_mesh::{GltfBuffers, load_gltf_mesh, parse_gltf_mesh};
pub use instances_csv::{
    CSV_COLUMNS, InstanceRow, MAX_CSV_RECORD_BYTES, MAX_INSTANCES, load_instances_csv,
    parse_instances_csv,
};
pub use obj_mesh::{load_obj_mesh, parse_obj_mesh, triangulate_polygon};
pub use paths::{LoadOptions, MAX_MESH_FILE_BYTES, MAX_SCENE_FILE_BYTES, MAX_TEXTURE_FILE_BYTES};
pub use png_texture::{MAX_TEXTURE_SIDE, decode_png_texture, load_png_texture};
pub use scene_toml::{
    MAX_SPECIES, load_scene_file, load_scene_file_reported, load_scene_file_with, parse_scene_file,
    parse_scene_file_reported, parse_scene_file_with,
};

/// A scene file naming one mesh, as a one-line hint: what to write when someone hands a mesh file
/// where a scene is expected.
pub fn minimal_scene_hint(mesh: &str) -> String {
    let stem = Path::new(mesh)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "tree".into());
    format!(
        "a mesh is named from a scene TOML file; write e.g. scene.toml with the lines: instances = \"trees.csv\" | [[species]] | name = {} | mesh = {} | texture = \"{}.png\" (see the README, \"Scene files\")",
        excerpt(&stem),
        excerpt(mesh),
        cut(&stem)
    )
}

/// Loads `path` by its extension: `.toml` as a scene file ([`load_scene_file`]), `.csv` as a bare
/// instance table with the built-in species ([`load_instances_with_builtin_species`]); a mesh
/// file (`.obj`, `.gltf`, `.glb`) is an error showing the minimal scene file that names it.
pub fn load_path(path: &Path) -> Result<Scene, InputError> {
    load_path_with(path, &LoadOptions::default())
}

/// [`load_path`] with `options`.
pub fn load_path_with(path: &Path, options: &LoadOptions) -> Result<Scene, InputError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("toml") => load_scene_file_with(path, options),
        Some("csv") => load_instances_with_builtin_species(path),
        Some("obj" | "gltf" | "glb") => Err(InputError::new(
            label(path),
            "file extension",
            path.extension()
                .map(|e| e.to_string_lossy().into_owned())
                .unwrap_or_default(),
            minimal_scene_hint(&label(path)),
        )),
        _ => Err(InputError::new(
            label(path),
            "file extension",
            path.extension()
                .map(|e| e.to_string_lossy().into_owned())
                .unwrap_or_default(),
            "expected .toml (scene file) or .csv (instance table)",
        )),
    }
}
