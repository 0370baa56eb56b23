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
//!   flipped to the top-left convention of [`TreeMesh::uvs`] (glTF's already are top-left).
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

use std::collections::HashMap;
use std::io::{BufRead, Cursor, Read};
use std::path::{Path, PathBuf};

use image::ImageDecoder;
use serde::Deserialize;
use toml::Spanned;

use super::builtin::{Species, species_meshes};
use super::{Instance, MAX_TREE_TRIANGLES, Scene, Terrain, TreeMesh, footprint};
use crate::InputError;
use crate::error::{cut, excerpt};
use crate::texture::Rgba8Image;

/// Most rows an instance table may have.
pub const MAX_INSTANCES: usize = 20_000_000;
/// Largest texture side accepted, texels.
pub const MAX_TEXTURE_SIDE: u32 = 4096;
/// Largest scene file accepted, bytes.
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 20;
/// Largest OBJ file accepted, bytes (a < 20-triangle tree needs a few kilobytes).
pub const MAX_MESH_FILE_BYTES: u64 = 4 << 20;
/// Largest PNG file accepted, bytes.
pub const MAX_TEXTURE_FILE_BYTES: u64 = 256 << 20;
/// Most species a scene file may declare.
pub const MAX_SPECIES: usize = 4096;
/// Largest magnitude of a world coordinate (CSV values, origin, flat terrain height), metres.
pub const MAX_WORLD_COORDINATE: f64 = 1.0e8;
/// Largest distance of a tree from the scene origin per axis, metres (as [`Scene::validate`]).
pub const MAX_RELATIVE_COORDINATE: f64 = 1.0e6;
/// The instance table's columns.
pub const CSV_COLUMNS: [&str; 6] = ["x", "y", "z", "yaw", "scale", "species"];

/// One row of an instance table, as parsed: world position in `f64`, before the origin is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceRow {
    /// World position, metres.
    pub position: [f64; 3],
    /// Rotation about +Z, radians (finite).
    pub yaw: f32,
    /// Uniform scale, in (0, 1000].
    pub scale: f32,
    /// Mesh (species) index.
    pub mesh: u32,
    /// 1-based line of the row in its file (the header is line 1).
    pub line: u64,
}

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

// ---------------------------------------------------------------------------------------------
// Files
// ---------------------------------------------------------------------------------------------

fn label(path: &Path) -> String {
    path.display().to_string()
}

/// Reads a whole file of at most `limit` bytes.
fn read_limited(path: &Path, limit: u64) -> Result<Vec<u8>, InputError> {
    let file = label(path);
    let cannot =
        |e: std::io::Error| InputError::new(&file, "file", &file, format!("cannot be read: {e}"));
    let f = std::fs::File::open(path).map_err(cannot)?;
    let mut bytes = Vec::new();
    f.take(limit + 1).read_to_end(&mut bytes).map_err(cannot)?;
    if bytes.len() as u64 > limit {
        return Err(InputError::new(
            &file,
            "file size",
            format!("more than {limit} bytes"),
            format!("expected at most {limit} bytes"),
        ));
    }
    Ok(bytes)
}

/// 1-based line and column (in characters) of byte `offset` in `text`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// 1-based line of the first invalid UTF-8 byte.
fn utf8_error_line(bytes: &[u8], e: &std::str::Utf8Error) -> usize {
    bytes[..e.valid_up_to()]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

// ---------------------------------------------------------------------------------------------
// Scene files
// ---------------------------------------------------------------------------------------------

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<Spanned<String>>,
    instances: Spanned<String>,
    origin: Option<Spanned<[f64; 3]>>,
    terrain: Option<Spanned<TerrainFile>>,
    species: Option<Vec<Spanned<SpeciesFile>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TerrainFile {
    kind: Spanned<String>,
    z: Option<Spanned<f64>>,
    amplitude: Option<Spanned<f64>>,
    wavelength: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SpeciesFile {
    name: Spanned<String>,
    builtin: Option<Spanned<String>>,
    mesh: Option<Spanned<String>>,
    texture: Option<Spanned<String>>,
    up: Option<UpAxis>,
}

/// How a scene file may name other files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Allow the files a scene file names (instances, meshes, textures, glTF buffers) to lie
    /// outside the scene file's folder (after resolving `..` and symbolic links). Off by default:
    /// a scene file from elsewhere cannot make the loader read arbitrary files (the CLI's
    /// `--allow-outside-paths`).
    pub allow_outside_paths: bool,
}

/// Loads a scene file (module docs: TOML scene file, CSV instances, meshes) and everything it
/// names, validated, with the default [`LoadOptions`] (every named file under the scene's folder).
pub fn load_scene_file(path: &Path) -> Result<Scene, InputError> {
    load_scene_file_with(path, &LoadOptions::default())
}

/// [`load_scene_file`] with `options`.
pub fn load_scene_file_with(path: &Path, options: &LoadOptions) -> Result<Scene, InputError> {
    let bytes = read_limited(path, MAX_SCENE_FILE_BYTES)?;
    parse_scene_file_with(&bytes, path, options)
}

/// Parses `bytes` as the contents of the scene file at `path`; `path` gives the error label, the
/// default name (its stem) and the directory that relative paths start from. Loads the files it
/// names, with the default [`LoadOptions`].
pub fn parse_scene_file(bytes: &[u8], path: &Path) -> Result<Scene, InputError> {
    parse_scene_file_with(bytes, path, &LoadOptions::default())
}

/// The scene file's folder as relative paths start from it (empty for a bare file name, so that
/// named files keep the names they were given in errors).
fn scene_folder(path: &Path) -> &Path {
    path.parent().unwrap_or(Path::new(""))
}

/// Where a path named in a scene file points: `base.join(named)`, checked to lie under `base`
/// (after resolving `..` and symbolic links) unless `options` allow otherwise. A path that does
/// not resolve (a missing file) is returned as is: reading it reports it. `link` is the naming
/// field (`scene.toml: line 2, column 13, field instances`).
fn resolve_named(
    base: &Path,
    named: &str,
    options: &LoadOptions,
    file: &str,
    position: &str,
) -> Result<PathBuf, InputError> {
    confine(base, base.join(named), named, options, file, position)
}

/// `path` (written `named` in `file` at `position`) if it lies under `root` after resolving `..`
/// and symbolic links, or `options` allow files outside; a path that does not resolve is
/// returned as is (reading it reports it).
fn confine(
    root: &Path,
    path: PathBuf,
    named: &str,
    options: &LoadOptions,
    file: &str,
    position: &str,
) -> Result<PathBuf, InputError> {
    if options.allow_outside_paths {
        return Ok(path);
    }
    let root = if root.as_os_str().is_empty() {
        Path::new(".")
    } else {
        root
    };
    if let (Ok(root), Ok(target)) = (root.canonicalize(), path.canonicalize())
        && !target.starts_with(&root)
    {
        return Err(InputError::new(
            file,
            position,
            named,
            format!(
                "resolves to {}, outside the scene file's folder {}: move the file under that folder, or allow it (--allow-outside-paths)",
                target.display(),
                root.display()
            ),
        ));
    }
    Ok(path)
}

/// Shortens every double-quoted part of a parser's message to [`crate::error::MAX_EXCERPT_CHARS`]
/// characters (marked `…`) and puts it on one line: messages such as TOML's `invalid type: string
/// "..."` quote the file's content.
fn cut_quoted(message: &str) -> String {
    let mut out = String::new();
    let mut inside = false;
    let mut escaped = false;
    let mut count = 0;
    for c in message.trim().chars() {
        let c = if c == '\n' || c == '\r' { ' ' } else { c };
        if !inside {
            out.push(c);
            if c == '"' {
                inside = true;
                count = 0;
            }
            continue;
        }
        if !escaped && c == '"' {
            if count > crate::error::MAX_EXCERPT_CHARS {
                out.push('…');
            }
            out.push(c);
            inside = false;
            continue;
        }
        escaped = !escaped && c == '\\';
        count += 1;
        if count <= crate::error::MAX_EXCERPT_CHARS {
            out.push(c);
        }
    }
    if inside && count > crate::error::MAX_EXCERPT_CHARS {
        out.push('…');
    }
    out
}

/// [`parse_scene_file`] with `options`.
pub fn parse_scene_file_with(
    bytes: &[u8],
    path: &Path,
    options: &LoadOptions,
) -> Result<Scene, InputError> {
    let file = label(path);
    let text = std::str::from_utf8(bytes).map_err(|e| {
        InputError::new(
            &file,
            format!("line {}", utf8_error_line(bytes, &e)),
            format!("byte {}", e.valid_up_to()),
            "expected UTF-8 text (TOML)",
        )
    })?;
    let at = |span: std::ops::Range<usize>, field: &str| {
        let (line, col) = line_col(text, span.start);
        format!("line {line}, column {col}, field {field}")
    };
    let parsed: SceneFile = toml::from_str(text).map_err(|e| {
        let (position, value) = match e.span() {
            Some(span) => {
                let (line, col) = line_col(text, span.start);
                let end = span.end.min(text.len());
                let snippet = text
                    .get(span.start.min(end)..end)
                    .unwrap_or("")
                    .lines()
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_string();
                (format!("line {line}, column {col}"), snippet)
            }
            None => ("file".to_string(), String::new()),
        };
        InputError::new(
            &file,
            position,
            value,
            format!("invalid scene file: {}", cut_quoted(e.message())),
        )
    })?;
    let base = scene_folder(path);

    let name = match &parsed.name {
        Some(n) => {
            if n.get_ref().trim().is_empty() {
                return Err(InputError::new(
                    &file,
                    at(n.span(), "name"),
                    n.get_ref(),
                    "expected a non-empty name",
                ));
            }
            n.get_ref().clone()
        }
        None => path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".to_string()),
    };

    let origin = match &parsed.origin {
        Some(o) => {
            let v = *o.get_ref();
            if v.iter()
                .any(|c| !c.is_finite() || c.abs() > MAX_WORLD_COORDINATE)
            {
                return Err(InputError::new(
                    &file,
                    at(o.span(), "origin"),
                    format!("{v:?}"),
                    format!("expected three finite coordinates within ±{MAX_WORLD_COORDINATE:e} m"),
                ));
            }
            Some(v)
        }
        None => None,
    };

    let terrain = match &parsed.terrain {
        Some(t) => Some(terrain_spec(t, &file, text)?),
        None => None,
    };

    let meshes = match &parsed.species {
        None => species_meshes(),
        Some(list) => load_species(list, &file, text, base, options)?,
    };
    let names: Vec<String> = meshes.iter().map(|m| m.name.clone()).collect();

    let instances_at = at(parsed.instances.span(), "instances");
    if parsed.instances.get_ref().trim().is_empty() {
        return Err(InputError::new(
            &file,
            instances_at,
            parsed.instances.get_ref(),
            "expected the path of a CSV instance table",
        ));
    }
    let instances_path = resolve_named(
        base,
        parsed.instances.get_ref(),
        options,
        &file,
        &instances_at,
    )?;
    let link = format!(
        "{file}: {instances_at} = {}",
        excerpt(parsed.instances.get_ref())
    );
    let rows = load_instances_csv(&instances_path, &names).map_err(|e| e.within(&link))?;
    validated(
        build_scene(
            name,
            meshes,
            &rows,
            origin,
            terrain,
            &label(&instances_path),
        )
        .map_err(|e| e.within(&link))?,
        &file,
    )
}

/// Checks a `[terrain]` table: `kind = "flat"` with `z`, or `kind = "hills"` with `amplitude` and
/// `wavelength`, nothing else.
fn terrain_spec(
    t: &Spanned<TerrainFile>,
    file: &str,
    text: &str,
) -> Result<TerrainSpec, InputError> {
    let at = |span: std::ops::Range<usize>, field: &str| {
        let (line, col) = line_col(text, span.start);
        format!("line {line}, column {col}, field terrain.{field}")
    };
    let t_ref = t.get_ref();
    let kind = t_ref.kind.get_ref().as_str();
    let (needed, unwanted): (&[&str], &[&str]) = match kind {
        "flat" => (&["z"], &["amplitude", "wavelength"]),
        "hills" => (&["amplitude", "wavelength"], &["z"]),
        _ => {
            return Err(InputError::new(
                file,
                at(t_ref.kind.span(), "kind"),
                kind,
                "expected \"flat\" or \"hills\"",
            ));
        }
    };
    let field = |name: &str| match name {
        "z" => &t_ref.z,
        "amplitude" => &t_ref.amplitude,
        _ => &t_ref.wavelength,
    };
    for name in needed {
        if field(name).is_none() {
            return Err(InputError::new(
                file,
                at(t.span(), name),
                "",
                format!("missing: kind = \"{kind}\" needs {}", needed.join(" and ")),
            ));
        }
    }
    for name in unwanted {
        if let Some(v) = field(name) {
            return Err(InputError::new(
                file,
                at(v.span(), name),
                v.get_ref(),
                format!("not allowed with kind = \"{kind}\""),
            ));
        }
    }
    let check = |name: &str, ok: fn(f64) -> bool, reason: &str| -> Result<f64, InputError> {
        match field(name) {
            Some(v) if ok(*v.get_ref()) => Ok(*v.get_ref()),
            Some(v) => Err(InputError::new(
                file,
                at(v.span(), name),
                v.get_ref(),
                reason,
            )),
            None => Ok(0.0),
        }
    };
    if kind == "flat" {
        let z = check(
            "z",
            |z| z.is_finite() && z.abs() <= MAX_WORLD_COORDINATE,
            "expected a finite world height within ±1e8 m",
        )?;
        return Ok(TerrainSpec::FlatWorld(z));
    }
    let amplitude = check(
        "amplitude",
        |a| a.is_finite() && a.abs() <= 1.0e4,
        "expected a finite amplitude within ±10 km",
    )?;
    let wavelength = check(
        "wavelength",
        |w| w.is_finite() && (1.0..=1.0e7).contains(&w),
        "expected a finite wavelength in [1 m, 10000 km]",
    )?;
    Ok(TerrainSpec::Relative(Terrain::Hills {
        amplitude: amplitude as f32,
        wavelength: wavelength as f32,
    }))
}

fn load_species(
    list: &[Spanned<SpeciesFile>],
    file: &str,
    text: &str,
    base: &Path,
    options: &LoadOptions,
) -> Result<Vec<TreeMesh>, InputError> {
    let at = |span: std::ops::Range<usize>, field: String| {
        let (line, col) = line_col(text, span.start);
        format!("line {line}, column {col}, field {field}")
    };
    if list.is_empty() {
        return Err(InputError::new(
            file,
            "field species",
            "[]",
            "expected at least one species",
        ));
    }
    if list.len() > MAX_SPECIES {
        return Err(InputError::new(
            file,
            "field species",
            list.len(),
            format!("expected at most {MAX_SPECIES} species"),
        ));
    }
    let mut meshes: Vec<TreeMesh> = Vec::with_capacity(list.len());
    // Where each mesh's texture came from, for the texture-size rule: (position of the naming
    // field, description such as `texture "a.png"` or `built-in "spruce"`).
    let mut texture_sources: Vec<(String, String)> = Vec::with_capacity(list.len());
    for (i, entry) in list.iter().enumerate() {
        let s = entry.get_ref();
        let name = s.name.get_ref();
        if name.trim().is_empty() || name.trim() != name {
            return Err(InputError::new(
                file,
                at(s.name.span(), format!("species[{i}].name")),
                name,
                "expected a non-empty name without surrounding spaces",
            ));
        }
        if meshes.iter().any(|m| &m.name == name) {
            return Err(InputError::new(
                file,
                at(s.name.span(), format!("species[{i}].name")),
                name,
                "duplicate species name",
            ));
        }
        let (mesh, source) = match (&s.builtin, &s.mesh, &s.texture) {
            (Some(b), None, None) => {
                let species = Species::from_name(b.get_ref()).ok_or_else(|| {
                    InputError::new(
                        file,
                        at(b.span(), format!("species[{i}].builtin")),
                        b.get_ref(),
                        format!(
                            "unknown built-in species; expected one of: {}",
                            Species::ALL.map(Species::name).join(", ")
                        ),
                    )
                })?;
                let mut mesh = species.mesh();
                mesh.name = name.clone();
                let source = (
                    at(b.span(), format!("species[{i}].builtin")),
                    format!("built-in {}", excerpt(b.get_ref())),
                );
                (mesh, source)
            }
            (None, Some(m), Some(t)) => {
                let mesh_at = at(m.span(), format!("species[{i}].mesh"));
                let texture_at = at(t.span(), format!("species[{i}].texture"));
                let kind = MeshKind::of(Path::new(m.get_ref())).ok_or_else(|| {
                    InputError::new(
                        file,
                        &mesh_at,
                        m.get_ref(),
                        "expected a mesh file ending in .obj, .gltf or .glb",
                    )
                })?;
                let mesh_path = resolve_named(base, m.get_ref(), options, file, &mesh_at)?;
                let texture_path = resolve_named(base, t.get_ref(), options, file, &texture_at)?;
                let mesh_link = format!("{file}: {mesh_at} = {}", excerpt(m.get_ref()));
                let texture_link = format!("{file}: {texture_at} = {}", excerpt(t.get_ref()));
                let bytes = read_limited(&mesh_path, MAX_MESH_FILE_BYTES)
                    .map_err(|e| e.within(&mesh_link))?;
                let image = load_png_texture(&texture_path).map_err(|e| e.within(&texture_link))?;
                let mesh_file = label(&mesh_path);
                let mesh = match kind {
                    MeshKind::Obj => {
                        parse_obj_mesh(name, &bytes, &mesh_file, s.up.unwrap_or(UpAxis::Z), image)
                    }
                    MeshKind::Gltf => {
                        let buffers = GltfBuffers {
                            folder: scene_folder(&mesh_path),
                            root: base,
                            options,
                        };
                        parse_gltf_mesh(
                            name,
                            &bytes,
                            &mesh_file,
                            s.up.unwrap_or(UpAxis::Y),
                            image,
                            &buffers,
                        )
                    }
                }
                .map_err(|e| e.within(&mesh_link))?;
                (
                    mesh,
                    (texture_at, format!("texture {}", excerpt(t.get_ref()))),
                )
            }
            (None, Some(m), None) => {
                return Err(InputError::new(
                    file,
                    at(m.span(), format!("species[{i}].texture")),
                    "",
                    "missing: a mesh needs an RGBA PNG texture",
                ));
            }
            (None, None, _) => {
                return Err(InputError::new(
                    file,
                    at(entry.span(), format!("species[{i}]")),
                    name,
                    "expected either builtin = \"...\" or mesh = \"...\" with texture = \"...\"",
                ));
            }
            (Some(b), _, _) => {
                return Err(InputError::new(
                    file,
                    at(b.span(), format!("species[{i}].builtin")),
                    b.get_ref(),
                    "a built-in species takes no mesh or texture: give either builtin or mesh + texture",
                ));
            }
        };
        // The GPU draw stage samples every mesh texture from one array texture, so all must have
        // species 0's (square) size (`gpu/src/draw.rs`, `upload_texture_array`).
        if let Some(first) = meshes.first() {
            let (w0, h0) = (first.texture.width, first.texture.height);
            let (w, h) = (mesh.texture.width, mesh.texture.height);
            if (w, h) != (w0, h0) {
                return Err(InputError::new(
                    file,
                    &source.0,
                    format!("{w}x{h}"),
                    format!(
                        "species[{i}] {} is {w}x{h} but species[0] {} is {w0}x{h0}: every species texture must have species 0's square size (the GPU draws all mesh textures from one texture array; built-in species are {}x{})",
                        source.1,
                        texture_sources[0].1,
                        super::builtin::TEXTURE_SIZE,
                        super::builtin::TEXTURE_SIZE
                    ),
                ));
            }
        }
        meshes.push(mesh);
        texture_sources.push(source);
    }
    Ok(meshes)
}

/// The mesh file formats a scene file may name, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MeshKind {
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// glTF 2.0, JSON (`.gltf`) or binary (`.glb`).
    Gltf,
}

impl MeshKind {
    fn of(path: &Path) -> Option<Self> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("obj") => Some(Self::Obj),
            Some("gltf" | "glb") => Some(Self::Gltf),
            _ => None,
        }
    }
}

/// Terrain as declared, before the origin is known.
#[derive(Clone, Copy, Debug, PartialEq)]
enum TerrainSpec {
    /// Flat at a world height.
    FlatWorld(f64),
    /// Already relative to the origin.
    Relative(Terrain),
}

/// `scene` if it passes [`Scene::validate`] (every load ends here).
fn validated(scene: Scene, file: &str) -> Result<Scene, InputError> {
    scene.validate(file)?;
    Ok(scene)
}

/// The origin the loaders choose for trees at world `positions` (SPEC §3): the centre of their
/// bounding box rounded to whole metres.
pub fn default_origin(positions: impl IntoIterator<Item = [f64; 3]>) -> [f64; 3] {
    let (lo, hi) = bounding_box(positions);
    [0, 1, 2].map(|k| ((lo[k] + hi[k]) * 0.5).round())
}

/// Componentwise `(min, max)` of `points`.
fn bounding_box(points: impl IntoIterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
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

/// Turns parsed rows into a scene: picks the origin (given, or the bounding-box centre rounded to
/// whole metres), converts positions to `f32` relative to it (each within
/// ±[`MAX_RELATIVE_COORDINATE`]), sets the terrain (given, or flat at the lowest tree) and the
/// footprint. `csv_file` names the rows' file in errors.
fn build_scene(
    name: String,
    meshes: Vec<TreeMesh>,
    rows: &[InstanceRow],
    origin: Option<[f64; 3]>,
    terrain: Option<TerrainSpec>,
    csv_file: &str,
) -> Result<Scene, InputError> {
    if rows.is_empty() {
        return Err(InputError::new(
            csv_file,
            "rows",
            "none",
            "expected at least one tree: the scene is empty",
        ));
    }
    let origin = origin.unwrap_or_else(|| default_origin(rows.iter().map(|r| r.position)));
    let mut instances = Vec::with_capacity(rows.len());
    let mut min_z = f32::INFINITY;
    for r in rows {
        let rel = [0, 1, 2].map(|k| r.position[k] - origin[k]);
        if rel.iter().any(|c| c.abs() > MAX_RELATIVE_COORDINATE) {
            return Err(InputError::new(
                csv_file,
                format!("line {}, columns x,y,z", r.line),
                format!("{:?}", r.position),
                format!(
                    "more than {} km from the scene origin {origin:?}: split the scene or set its origin",
                    MAX_RELATIVE_COORDINATE / 1000.0
                ),
            ));
        }
        let p = rel.map(|c| c as f32);
        min_z = min_z.min(p[2]);
        instances.push(Instance {
            position: p,
            yaw: r.yaw,
            scale: r.scale,
            mesh: r.mesh,
        });
    }
    let bounds = footprint(instances.iter().map(|i| i.position));
    let terrain = match terrain {
        Some(TerrainSpec::FlatWorld(z)) => Terrain::Flat {
            z: (z - origin[2]) as f32,
        },
        Some(TerrainSpec::Relative(t)) => t,
        None => Terrain::Flat { z: min_z },
    };
    Ok(Scene {
        name,
        origin,
        meshes,
        instances,
        terrain,
        bounds,
    })
}

// ---------------------------------------------------------------------------------------------
// Instance tables
// ---------------------------------------------------------------------------------------------

/// Loads an instance table (module docs: CSV) whose `species` column names one of
/// `species_names` or gives its 0-based index.
pub fn load_instances_csv(
    path: &Path,
    species_names: &[String],
) -> Result<Vec<InstanceRow>, InputError> {
    let file = label(path);
    let f = std::fs::File::open(path)
        .map_err(|e| InputError::new(&file, "file", &file, format!("cannot be read: {e}")))?;
    parse_instances_csv(std::io::BufReader::new(f), &file, species_names)
}

/// Parses an instance table from `reader`; `file` names it in errors.
pub fn parse_instances_csv<R: Read>(
    reader: R,
    file: &str,
    species_names: &[String],
) -> Result<Vec<InstanceRow>, InputError> {
    parse_instances_csv_limited(reader, file, species_names, MAX_INSTANCES)
}

/// [`parse_instances_csv`] with a row limit (tests use a small one).
fn parse_instances_csv_limited<R: Read>(
    reader: R,
    file: &str,
    species_names: &[String],
    max_rows: usize,
) -> Result<Vec<InstanceRow>, InputError> {
    let mut csv = CsvRecords::new(std::io::BufReader::new(reader), file);
    let mut record: Vec<String> = Vec::new();
    let Some(header_line) = csv.next_record(&mut record)? else {
        return Err(InputError::new(
            file,
            "line 1",
            "",
            format!("empty file: expected the header {}", CSV_COLUMNS.join(",")),
        ));
    };
    // column[k] = index in the record of CSV_COLUMNS[k]
    let mut column = [usize::MAX; 6];
    for (i, name) in record.iter().enumerate() {
        let name = name.as_str();
        match CSV_COLUMNS.iter().position(|c| *c == name) {
            Some(k) if column[k] == usize::MAX => column[k] = i,
            Some(_) => {
                return Err(InputError::new(
                    file,
                    format!("line {header_line}, column {}", i + 1),
                    name,
                    "duplicate column",
                ));
            }
            None => {
                return Err(InputError::new(
                    file,
                    format!("line {header_line}, column {}", i + 1),
                    name,
                    format!(
                        "unknown column; expected the header {}",
                        CSV_COLUMNS.join(",")
                    ),
                ));
            }
        }
    }
    if let Some(k) = column.iter().position(|&c| c == usize::MAX) {
        return Err(InputError::new(
            file,
            format!("line {header_line}, column {}", CSV_COLUMNS[k]),
            record.join(","),
            format!(
                "missing column; expected the header {}",
                CSV_COLUMNS.join(",")
            ),
        ));
    }
    let width = record.len();
    let by_name: HashMap<&str, u32> = species_names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i as u32))
        .collect();

    let mut rows = Vec::new();
    while let Some(line) = csv.next_record(&mut record)? {
        if record.len() != width {
            return Err(InputError::new(
                file,
                format!("line {line}"),
                record.join(","),
                format!(
                    "wrong column count: expected {width} fields, found {}",
                    record.len()
                ),
            ));
        }
        if rows.len() >= max_rows {
            return Err(InputError::new(
                file,
                format!("line {line}"),
                format!("row {}", rows.len() + 1),
                format!("too many rows: at most {max_rows} trees per table"),
            ));
        }
        let field = |k: usize| record.get(column[k]).map_or("", String::as_str);
        let err = |k: usize, reason: String| {
            InputError::new(
                file,
                format!("line {line}, column {}", CSV_COLUMNS[k]),
                field(k),
                reason,
            )
        };
        let mut position = [0.0f64; 3];
        for (k, p) in position.iter_mut().enumerate() {
            let v: f64 = field(k)
                .parse()
                .map_err(|_| err(k, "expected a number (metres)".into()))?;
            if !v.is_finite() || v.abs() > MAX_WORLD_COORDINATE {
                return Err(err(
                    k,
                    format!("expected a finite coordinate within ±{MAX_WORLD_COORDINATE:e} m"),
                ));
            }
            *p = v;
        }
        let yaw: f32 = field(3)
            .parse()
            .map_err(|_| err(3, "expected a number (radians)".into()))?;
        if !yaw.is_finite() {
            return Err(err(3, "expected a finite angle (radians)".into()));
        }
        let scale: f32 = field(4)
            .parse()
            .map_err(|_| err(4, "expected a number".into()))?;
        if !(scale.is_finite() && scale > 0.0 && scale <= 1.0e3) {
            return Err(err(4, "expected a finite scale in (0, 1000]".into()));
        }
        let species = field(5);
        let mesh = match by_name.get(species) {
            Some(&m) => m,
            None => match species.parse::<u32>() {
                Ok(i) if (i as usize) < species_names.len() => i,
                _ => {
                    let mut known = species_names
                        .iter()
                        .take(8)
                        .map(|n| cut(n))
                        .collect::<Vec<_>>()
                        .join(", ");
                    if species_names.len() > 8 {
                        known.push_str(", ...");
                    }
                    return Err(err(
                        5,
                        format!(
                            "unknown species: expected one of [{known}] or an index below {}",
                            species_names.len()
                        ),
                    ));
                }
            },
        };
        rows.push(InstanceRow {
            position,
            yaw,
            scale,
            mesh,
            line,
        });
    }
    if rows.is_empty() {
        return Err(InputError::new(
            file,
            format!("line {}", header_line + 1),
            "no rows",
            "empty table: expected at least one tree after the header",
        ));
    }
    Ok(rows)
}

/// Longest record accepted in an instance table, bytes.
pub const MAX_CSV_RECORD_BYTES: usize = 1 << 16;

/// A minimal RFC 4180 reader that knows its line numbers exactly (the `csv` crate's positions skip
/// blank lines and mis-count CRLF). Fields are separated by `,`; a field may be quoted with `"`
/// (`""` inside is a quote) and then may span lines; unquoted fields and quoted contents are
/// trimmed of spaces and tabs; empty lines are skipped; a leading UTF-8 byte-order mark is dropped;
/// line ends are `\n` or `\r\n`.
struct CsvRecords<'a, R> {
    reader: R,
    file: &'a str,
    /// Lines read so far.
    line: u64,
    buf: Vec<u8>,
}

impl<'a, R: std::io::BufRead> CsvRecords<'a, R> {
    fn new(reader: R, file: &'a str) -> Self {
        Self {
            reader,
            file,
            line: 0,
            buf: Vec::new(),
        }
    }

    /// Reads one physical line into `self.buf` without its line end; `false` at the end of input.
    fn read_line(&mut self) -> Result<bool, InputError> {
        self.buf.clear();
        let limit = MAX_CSV_RECORD_BYTES as u64 + 2;
        let n = (&mut self.reader)
            .take(limit)
            .read_until(b'\n', &mut self.buf)
            .map_err(|e| {
                InputError::new(
                    self.file,
                    format!("line {}", self.line + 1),
                    "",
                    format!("cannot be read: {e}"),
                )
            })?;
        if n == 0 {
            return Ok(false);
        }
        self.line += 1;
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
            if self.buf.last() == Some(&b'\r') {
                self.buf.pop();
            }
        } else if n as u64 >= limit {
            return Err(self.too_long());
        }
        if self.line == 1 && self.buf.starts_with(&[0xef, 0xbb, 0xbf]) {
            self.buf.drain(..3);
        }
        Ok(true)
    }

    fn too_long(&self) -> InputError {
        InputError::new(
            self.file,
            format!("line {}", self.line.max(1)),
            format!("more than {MAX_CSV_RECORD_BYTES} bytes"),
            format!("expected records of at most {MAX_CSV_RECORD_BYTES} bytes"),
        )
    }

    /// Reads the next non-empty record into `fields`; returns the line it starts on, or `None` at
    /// the end of input.
    fn next_record(&mut self, fields: &mut Vec<String>) -> Result<Option<u64>, InputError> {
        fields.clear();
        // Skip empty lines.
        loop {
            if !self.read_line()? {
                return Ok(None);
            }
            if !self.buf.iter().all(|b| *b == b' ' || *b == b'\t') {
                break;
            }
        }
        let start = self.line;
        let mut record: Vec<u8> = Vec::new();
        let mut field: Vec<u8> = Vec::new();
        let mut quoted = false; // inside quotes
        let mut after_quote = false; // a quoted field has closed
        let mut raw: Vec<Vec<u8>> = Vec::new();
        loop {
            let mut i = 0;
            while i < self.buf.len() {
                let b = self.buf[i];
                if quoted {
                    if b == b'"' {
                        if self.buf.get(i + 1) == Some(&b'"') {
                            field.push(b'"');
                            i += 1;
                        } else {
                            quoted = false;
                            after_quote = true;
                        }
                    } else {
                        field.push(b);
                    }
                } else if b == b',' {
                    raw.push(std::mem::take(&mut field));
                    after_quote = false;
                } else if after_quote {
                    if b != b' ' && b != b'\t' {
                        return Err(InputError::new(
                            self.file,
                            format!("line {}", self.line),
                            String::from_utf8_lossy(&self.buf).into_owned(),
                            "invalid CSV: unexpected character after a closing quote",
                        ));
                    }
                } else if b == b'"' && field.iter().all(|c| *c == b' ' || *c == b'\t') {
                    field.clear();
                    quoted = true;
                } else {
                    field.push(b);
                }
                i += 1;
            }
            record.extend_from_slice(&self.buf);
            if record.len() > MAX_CSV_RECORD_BYTES {
                return Err(self.too_long());
            }
            if !quoted {
                break;
            }
            // The quoted field goes on on the next line.
            field.push(b'\n');
            if !self.read_line()? {
                return Err(InputError::new(
                    self.file,
                    format!("line {start}"),
                    String::from_utf8_lossy(&record).into_owned(),
                    "invalid CSV: a quoted field is never closed",
                ));
            }
        }
        raw.push(field);
        for bytes in raw {
            let text = String::from_utf8(bytes).map_err(|e| {
                InputError::new(
                    self.file,
                    format!("line {start}, column {}", fields.len() + 1),
                    format!("byte {}", e.utf8_error().valid_up_to()),
                    "expected UTF-8 text",
                )
            })?;
            fields.push(text.trim_matches(|c| c == ' ' || c == '\t').to_string());
        }
        Ok(Some(start))
    }
}

/// Loads a bare instance table with the five built-in species (`spruce`, `pine`, `oak`, `birch`,
/// `poplar`, or indices 0–4): origin at the bounding-box centre rounded to whole metres, flat
/// terrain at the lowest tree, name = file stem. What the CLI's `--instances trees.csv` uses.
pub fn load_instances_with_builtin_species(csv: &Path) -> Result<Scene, InputError> {
    let file = label(csv);
    let names: Vec<String> = Species::ALL.iter().map(|s| s.name().to_string()).collect();
    let rows = load_instances_csv(csv, &names)?;
    let name = csv
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "instances".to_string());
    validated(
        build_scene(name, species_meshes(), &rows, None, None, &file)?,
        &file,
    )
}

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

// ---------------------------------------------------------------------------------------------
// Meshes and textures
// ---------------------------------------------------------------------------------------------

/// Loads an OBJ tree mesh named `name` with the RGBA PNG `texture`; `up` is the OBJ's up axis.
/// Validated with [`TreeMesh::validate`] (at most 19 triangles, 256 vertices, finite values,
/// indices in range).
pub fn load_obj_mesh(
    name: &str,
    obj: &Path,
    texture: &Path,
    up: UpAxis,
) -> Result<TreeMesh, InputError> {
    let bytes = read_limited(obj, MAX_MESH_FILE_BYTES)?;
    let image = load_png_texture(texture)?;
    parse_obj_mesh(name, &bytes, &label(obj), up, image)
}

/// Parses OBJ `bytes` (`file` names them in errors) into a tree mesh with `texture`. Every object
/// and group is merged; points and lines are ignored; materials are ignored. Every vertex needs a
/// texture coordinate (`f v/vt`). Faces with more than three vertices are triangulated in their
/// plane ([`triangulate_polygon`]): convex ones as fans from their first vertex (as before),
/// concave ones by ear clipping; non-planar, self-intersecting and zero-area polygons are errors
/// naming the face's line.
pub fn parse_obj_mesh(
    name: &str,
    bytes: &[u8],
    file: &str,
    up: UpAxis,
    texture: Rgba8Image,
) -> Result<TreeMesh, InputError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        InputError::new(
            file,
            format!("line {}", utf8_error_line(bytes, &e)),
            format!("byte {}", e.valid_up_to()),
            "expected UTF-8 text (OBJ)",
        )
    })?;
    let face_lines = prescan_obj(text, file)?;
    // tobj's optional `merging`/`reordering` features add fields: keep the struct update.
    // Faces are kept whole (`triangulate: false`): tobj would fan-triangulate concave polygons
    // wrongly. Vertices come out in the same order either way.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, _materials) =
        tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| InputError::new(file, "file", "", format!("invalid OBJ: {e}")))?;
    let mut mesh = TreeMesh::new(name, texture);
    // Faces (of 3 or more vertices) seen so far, over all models: indexes `face_lines`.
    let mut face_number = 0usize;
    for model in &models {
        let m = &model.mesh;
        let count = m.positions.len() / 3;
        if m.texcoords.len() != 2 * count {
            return Err(InputError::new(
                file,
                format!("object {}", excerpt(&model.name)),
                format!(
                    "{} texture coordinates for {count} vertices",
                    m.texcoords.len() / 2
                ),
                "expected a texture coordinate for every vertex (faces as f v/vt)",
            ));
        }
        let base = mesh.positions.len();
        if base + count > forestlod_shared::MAX_MESH_VERTICES as usize {
            return Err(InputError::new(
                file,
                "vertex count",
                base + count,
                format!(
                    "expected at most {} vertices per tree mesh",
                    forestlod_shared::MAX_MESH_VERTICES
                ),
            ));
        }
        for (p, t) in m.positions.chunks_exact(3).zip(m.texcoords.chunks_exact(2)) {
            mesh.positions.push(up.to_z_up([p[0], p[1], p[2]]));
            mesh.uvs.push([t[0], 1.0 - t[1]]);
        }
        let mut next = 0usize;
        let mut face_in_model = 0usize;
        while next < m.indices.len() {
            let arity = if m.face_arities.is_empty() {
                3
            } else {
                match m.face_arities.get(face_in_model) {
                    Some(&a) => a as usize,
                    None => break,
                }
            };
            face_in_model += 1;
            let Some(face) = m.indices.get(next..next + arity) else {
                break;
            };
            next += arity;
            face_number += 1;
            let at = || match face_lines.get(face_number - 1) {
                Some(line) => format!("line {line}, face"),
                None => format!("face {face_number}"),
            };
            // base + index < MAX_MESH_VERTICES (checked above) fits in u32.
            let global = |k: usize| base as u32 + face[k];
            if arity == 3 {
                mesh.indices.extend([global(0), global(1), global(2)]);
                continue;
            }
            if arity > MAX_TREE_TRIANGLES + 2 {
                return Err(InputError::new(
                    file,
                    at(),
                    format!("{arity} vertices"),
                    format!(
                        "a polygon of {arity} vertices makes {} triangles: expected at most {MAX_TREE_TRIANGLES} triangles per tree (E§3.1)",
                        arity - 2
                    ),
                ));
            }
            let points: Vec<[f64; 3]> = face
                .iter()
                .map(|&i| {
                    let p = &m.positions[3 * i as usize..3 * i as usize + 3];
                    [p[0] as f64, p[1] as f64, p[2] as f64]
                })
                .collect();
            let triangles = triangulate_polygon(&points).map_err(|reason| {
                let tokens = face
                    .iter()
                    .map(|i| (i + 1).to_string())
                    .collect::<Vec<_>>()
                    .join(" ");
                InputError::new(
                    file,
                    at(),
                    format!("{arity} vertices: {tokens}"),
                    format!("{reason}: split the polygon into triangles or convex polygons"),
                )
            })?;
            for t in triangles {
                mesh.indices.extend(t.map(global));
            }
        }
    }
    mesh.validate(file)?;
    Ok(mesh)
}

/// Triangulates a polygon of `points` (4 or more, in order) in its own plane. Returns triangles
/// as indices into `points`, in the polygon's winding:
/// - a convex polygon gives the fan from vertex 0, `(0, k, k + 1)` (what fan triangulation, and
///   this loader before, always gave);
/// - a concave simple polygon is ear-clipped;
/// - a zero-area, non-planar (a vertex off the best plane by more than 1e-3 of the polygon's
///   size) or self-intersecting polygon is an error (the reason is returned).
pub fn triangulate_polygon(points: &[[f64; 3]]) -> Result<Vec<[usize; 3]>, String> {
    let n = points.len();
    let fan = || (1..n - 1).map(|k| [0, k, k + 1]).collect::<Vec<_>>();
    // Newell's normal: twice the vector area, robust for concave polygons.
    let mut normal = [0.0f64; 3];
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let (lo, hi) = bounding_box(points.iter().copied());
    let size = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross3 = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    // The plane: through vertex 0, the vertex farthest from it and the vertex farthest from that
    // line (robust even where the vector area vanishes, as for a symmetric bow tie).
    let a = points[0];
    let far = points
        .iter()
        .copied()
        .max_by(|p, q| dot(sub(*p, a), sub(*p, a)).total_cmp(&dot(sub(*q, a), sub(*q, a))))
        .unwrap_or(a);
    let spread = points
        .iter()
        .map(|p| cross3(sub(far, a), sub(*p, a)))
        .max_by(|p, q| dot(*p, *p).total_cmp(&dot(*q, *q)))
        .unwrap_or([0.0; 3]);
    let spread_length = dot(spread, spread).sqrt();
    if size == 0.0 || spread_length <= 1.0e-9 * size * size {
        return Err("zero-area polygon (its vertices are on one line)".into());
    }
    // Oriented with the polygon's winding (the vector area) where it has one.
    let sign = if dot(spread, normal) < 0.0 { -1.0 } else { 1.0 };
    let nrm = spread.map(|c| sign * c / spread_length);
    let centroid = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).sum::<f64>() / n as f64);
    for p in points {
        let off = dot(sub(*p, centroid), nrm).abs();
        if off > 1.0e-3 * size {
            return Err(format!(
                "non-planar polygon (a vertex is {off:.3e} off its plane, size {size:.3e})"
            ));
        }
    }
    // A 2D frame (u, v) in the plane with u x v = normal: the polygon winds counter-clockwise.
    let helper = if nrm[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = cross3(helper, nrm);
    let ul = dot(u, u).sqrt();
    let u = u.map(|c| c / ul);
    let v = cross3(nrm, u);
    let flat: Vec<[f64; 2]> = points
        .iter()
        .map(|p| {
            let d = sub(*p, centroid);
            [dot(d, u), dot(d, v)]
        })
        .collect();
    let eps = 1.0e-12 * size * size;
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    // Simple: no two non-adjacent edges meet (touching counts).
    let on_segment = |a: [f64; 2], b: [f64; 2], p: [f64; 2]| {
        p[0] >= a[0].min(b[0]) - 1e-12 * size
            && p[0] <= a[0].max(b[0]) + 1e-12 * size
            && p[1] >= a[1].min(b[1]) - 1e-12 * size
            && p[1] <= a[1].max(b[1]) + 1e-12 * size
    };
    let segments_meet = |a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]| {
        let (o1, o2) = (orient(a, b, c), orient(a, b, d));
        let (o3, o4) = (orient(c, d, a), orient(c, d, b));
        let side = |o: f64| {
            if o > eps {
                1
            } else if o < -eps {
                -1
            } else {
                0
            }
        };
        let (s1, s2, s3, s4) = (side(o1), side(o2), side(o3), side(o4));
        if s1 * s2 < 0 && s3 * s4 < 0 {
            return true;
        }
        (s1 == 0 && on_segment(a, b, c))
            || (s2 == 0 && on_segment(a, b, d))
            || (s3 == 0 && on_segment(c, d, a))
            || (s4 == 0 && on_segment(c, d, b))
    };
    for i in 0..n {
        for j in i + 1..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            if adjacent {
                continue;
            }
            if segments_meet(flat[i], flat[(i + 1) % n], flat[j], flat[(j + 1) % n]) {
                return Err(format!(
                    "self-intersecting polygon (edges {}-{} and {}-{} meet)",
                    i + 1,
                    (i + 1) % n + 1,
                    j + 1,
                    (j + 1) % n + 1
                ));
            }
        }
    }
    let area = dot(normal, nrm);
    if area <= 1.0e-9 * size * size {
        return Err("zero-area polygon".into());
    }
    let convex = (0..n).all(|i| orient(flat[i], flat[(i + 1) % n], flat[(i + 2) % n]) >= -eps);
    if convex {
        return Ok(fan());
    }
    // Ear clipping: cut off a convex corner whose triangle holds no other vertex, until three are
    // left.
    let mut left: Vec<usize> = (0..n).collect();
    let mut triangles = Vec::with_capacity(n - 2);
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&k| {
            let (a, b, c) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
            if orient(flat[a], flat[b], flat[c]) <= eps {
                return false;
            }
            left.iter().all(|&q| {
                q == a
                    || q == b
                    || q == c
                    || orient(flat[a], flat[b], flat[q]) < -eps
                    || orient(flat[b], flat[c], flat[q]) < -eps
                    || orient(flat[c], flat[a], flat[q]) < -eps
            })
        });
        let Some(k) = ear else {
            return Err("polygon cannot be triangulated (no ear found)".into());
        };
        triangles.push([left[(k + m - 1) % m], left[k], left[(k + 1) % m]]);
        left.remove(k);
    }
    triangles.push([left[0], left[1], left[2]]);
    Ok(triangles)
}

/// Checks what `tobj` does not report with a line number: numbers in `v`/`vt` lines, and that every
/// face index is a non-zero integer naming an already-declared `v`/`vt`/`vn` (negative indices count
/// back). Guarantees `tobj` only ever sees in-range indices. Returns the 1-based line of every
/// face of three or more vertices, in order (`tobj` keeps faces in file order).
fn prescan_obj(text: &str, file: &str) -> Result<Vec<usize>, InputError> {
    let mut counts = [0usize; 3]; // v, vt, vn
    let mut face_lines = Vec::new();
    for (n, raw_line) in text.lines().enumerate() {
        let line = n + 1;
        let mut words = raw_line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let err = |what: &str, value: &str, reason: &str| {
            InputError::new(file, format!("line {line}, {what}"), value, reason)
        };
        match keyword {
            "v" | "vt" | "vn" => {
                let (k, need) = match keyword {
                    "v" => (0, 3),
                    "vt" => (1, 2),
                    _ => (2, 3),
                };
                let values: Vec<&str> = words.clone().take(need).collect();
                if values.len() < need {
                    return Err(err(
                        keyword,
                        raw_line.trim(),
                        &format!("expected {need} numbers"),
                    ));
                }
                for v in values {
                    match v.parse::<f32>() {
                        Ok(x) if x.is_finite() => {}
                        _ => return Err(err(keyword, v, "expected a finite number")),
                    }
                }
                counts[k] += 1;
            }
            "f" | "l" => {
                if keyword == "f" && words.clone().count() >= 3 {
                    face_lines.push(line);
                }
                for token in words {
                    let parts: Vec<&str> = token.split('/').collect();
                    if parts.len() > 3 {
                        return Err(err("face", token, "expected v, v/vt, v//vn or v/vt/vn"));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let kind = ["vertex", "texture coordinate", "normal"][k];
                        let index: isize = part.parse().map_err(|_| {
                            err("face", token, &format!("expected an integer {kind} index"))
                        })?;
                        let available = counts[k] as isize;
                        let ok = if index > 0 {
                            index <= available
                        } else {
                            index < 0 && available + index >= 0
                        };
                        if !ok {
                            return Err(err(
                                "face",
                                token,
                                &format!(
                                    "{kind} index out of range: {} declared so far (indices start at 1; negative ones count back)",
                                    counts[k]
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(face_lines)
}

/// Where a glTF file's external buffers (`"uri": "tree.bin"`) are read from: `folder` (the glTF
/// file's), confined to `root` (the scene file's folder) unless `options` allow otherwise.
#[derive(Clone, Copy, Debug)]
pub struct GltfBuffers<'a> {
    /// The glTF file's folder; buffer URIs are relative to it.
    pub folder: &'a Path,
    /// The folder every file must lie under (the scene file's).
    pub root: &'a Path,
    /// Whether files outside `root` are allowed.
    pub options: &'a LoadOptions,
}

/// Loads a glTF 2.0 tree mesh (`.gltf` or `.glb`, [`parse_gltf_mesh`]) named `name` with the RGBA
/// PNG `texture`; `up` is the file's up axis (glTF's own is +Y). External buffers may lie
/// anywhere under the glTF file's folder.
pub fn load_gltf_mesh(
    name: &str,
    gltf: &Path,
    texture: &Path,
    up: UpAxis,
) -> Result<TreeMesh, InputError> {
    let bytes = read_limited(gltf, MAX_MESH_FILE_BYTES)?;
    let image = load_png_texture(texture)?;
    let folder = scene_folder(gltf);
    let options = LoadOptions::default();
    let buffers = GltfBuffers {
        folder,
        root: folder,
        options: &options,
    };
    parse_gltf_mesh(name, &bytes, &label(gltf), up, image, &buffers)
}

/// Decodes standard base64 (RFC 4648, `=` padding optional); `None` on any other character.
fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    let text = text.trim_end_matches('=');
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

/// Parses glTF 2.0 `bytes` (JSON `.gltf` or binary `.glb`; `file` names them in errors) into a
/// tree mesh with `texture`, the way a tree needs it and no further:
/// - exactly one mesh; every primitive of it is merged; each must be a triangle list
///   (`mode` 4) with `POSITION` (float VEC3) and `TEXCOORD_0` (float, or normalized unsigned
///   byte/short VEC2), and optional `indices` (unsigned byte/short/int); sparse accessors are not
///   supported;
/// - a node that uses the mesh must have the identity transform (apply transforms before
///   export): the mesh is taken in its own coordinates, converted from `up` (glTF's +Y by
///   default) to Z up;
/// - buffers come from the GLB's binary chunk, a base64 `data:` URI, or a file relative to
///   the glTF file ([`GltfBuffers`]);
/// - materials and the file's own images are ignored: the scene file's `texture` is the mesh's
///   texture (glTF's UV origin is the top-left, as [`TreeMesh::uvs`]).
///
/// Positions must be finite, indices in range, at most 19 triangles and 256 vertices; every
/// failure names the file, the mesh/primitive/attribute and the value.
pub fn parse_gltf_mesh(
    name: &str,
    bytes: &[u8],
    file: &str,
    up: UpAxis,
    texture: Rgba8Image,
    buffers: &GltfBuffers,
) -> Result<TreeMesh, InputError> {
    let err = |position: String, value: String, reason: String| {
        InputError::new(file, position, value, reason)
    };
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| {
        let message = e.to_string().replace(['\n', '\r'], " ");
        err(
            "file".into(),
            format!("{} bytes", bytes.len()),
            format!("invalid glTF 2.0: {}", cut_quoted(&message)),
        )
    })?;
    let document = &gltf.document;
    let meshes: Vec<gltf::Mesh> = document.meshes().collect();
    if meshes.len() != 1 {
        return Err(err(
            "meshes".into(),
            format!("{} meshes", meshes.len()),
            "expected exactly one mesh (a tree)".into(),
        ));
    }
    let gmesh = &meshes[0];
    for node in document.nodes() {
        if node.mesh().is_some() {
            let m = node.transform().matrix();
            let identity =
                (0..4).all(|c| (0..4).all(|r| m[c][r] == if c == r { 1.0 } else { 0.0 }));
            if !identity {
                let (t, r, sc) = node.transform().decomposed();
                return Err(err(
                    format!("node {}, transform", node.index()),
                    format!(
                        "translation {} {} {}, rotation {} {} {} {}, scale {} {} {}",
                        t[0], t[1], t[2], r[0], r[1], r[2], r[3], sc[0], sc[1], sc[2]
                    ),
                    "expected no transform on the mesh's node (apply transforms before export)"
                        .into(),
                ));
            }
        }
    }
    // Buffer contents, by buffer index.
    let mut data: Vec<Vec<u8>> = Vec::new();
    for buffer in document.buffers() {
        let at = format!("buffer {}", buffer.index());
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                err(
                    at.clone(),
                    "no binary chunk".into(),
                    "expected the GLB's binary chunk (a .gltf file needs a uri)".into(),
                )
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let payload = uri.split_once(";base64,").map(|(_, b)| b).ok_or_else(|| {
                    err(
                        at.clone(),
                        cut(uri),
                        "expected a base64 data URI (data:application/octet-stream;base64,...)"
                            .into(),
                    )
                })?;
                decode_base64(payload).ok_or_else(|| {
                    err(
                        at.clone(),
                        cut(uri),
                        "invalid base64 in the data URI".into(),
                    )
                })?
            }
            gltf::buffer::Source::Uri(uri) => {
                let path = confine(
                    buffers.root,
                    buffers.folder.join(uri),
                    uri,
                    buffers.options,
                    file,
                    &format!("{at}, uri"),
                )?;
                read_limited(&path, MAX_MESH_FILE_BYTES)
                    .map_err(|e| e.within(format!("{file}: {at}, uri = {}", excerpt(uri))))?
            }
        };
        if bytes.len() < buffer.length() {
            return Err(err(
                at,
                format!("{} bytes", bytes.len()),
                format!("expected byteLength {} bytes of data", buffer.length()),
            ));
        }
        data.push(bytes);
    }
    let mut mesh = TreeMesh::new(name, texture);
    let mesh_at = format!("mesh {}", gmesh.index());
    for primitive in gmesh.primitives() {
        let prim_at = format!("{mesh_at}, primitive {}", primitive.index());
        if primitive.mode() != gltf::mesh::Mode::Triangles {
            return Err(err(
                format!("{prim_at}, mode"),
                match primitive.mode() {
                    gltf::mesh::Mode::Points => "POINTS (0)",
                    gltf::mesh::Mode::Lines => "LINES (1)",
                    gltf::mesh::Mode::LineLoop => "LINE_LOOP (2)",
                    gltf::mesh::Mode::LineStrip => "LINE_STRIP (3)",
                    gltf::mesh::Mode::Triangles => "TRIANGLES (4)",
                    gltf::mesh::Mode::TriangleStrip => "TRIANGLE_STRIP (5)",
                    gltf::mesh::Mode::TriangleFan => "TRIANGLE_FAN (6)",
                }
                .to_string(),
                "expected a triangle list (mode 4, TRIANGLES)".into(),
            ));
        }
        let base = mesh.positions.len();
        let positions = primitive.get(&gltf::Semantic::Positions).ok_or_else(|| {
            err(
                format!("{prim_at}, attributes"),
                "no POSITION".into(),
                "expected a POSITION attribute".into(),
            )
        })?;
        let uvs = primitive
            .get(&gltf::Semantic::TexCoords(0))
            .ok_or_else(|| {
                err(
                    format!("{prim_at}, attributes"),
                    "no TEXCOORD_0".into(),
                    "expected texture coordinates (TEXCOORD_0) for every vertex".into(),
                )
            })?;
        let count = positions.count();
        if base + count > forestlod_shared::MAX_MESH_VERTICES as usize {
            return Err(err(
                "vertex count".into(),
                (base + count).to_string(),
                format!(
                    "expected at most {} vertices per tree mesh",
                    forestlod_shared::MAX_MESH_VERTICES
                ),
            ));
        }
        if uvs.count() != count {
            return Err(err(
                format!("{prim_at}, TEXCOORD_0"),
                format!("{} texture coordinates for {count} vertices", uvs.count()),
                "expected one texture coordinate per vertex".into(),
            ));
        }
        // The accessor's values, `width` per element, each element finite.
        let read_finite =
            |accessor: &gltf::Accessor, attribute: &str, usage, width, reason: &str| {
                let values = read_accessor(
                    accessor,
                    &data,
                    file,
                    &format!("{prim_at}, {attribute}"),
                    usage,
                )?;
                if let Some((i, v)) = values
                    .chunks_exact(width)
                    .enumerate()
                    .find(|(_, v)| v.iter().any(|c| !c.is_finite()))
                {
                    let shown: Vec<String> = v.iter().map(f64::to_string).collect();
                    return Err(err(
                        format!("{prim_at}, {attribute} element {i}"),
                        format!("({})", shown.join(", ")),
                        reason.into(),
                    ));
                }
                Ok(values)
            };
        let p = read_finite(
            &positions,
            "POSITION",
            AccessorUse::Position,
            3,
            "expected finite coordinates",
        )?;
        for v in p.chunks_exact(3) {
            mesh.positions
                .push(up.to_z_up([v[0] as f32, v[1] as f32, v[2] as f32]));
        }
        let t = read_finite(
            &uvs,
            "TEXCOORD_0",
            AccessorUse::TexCoord,
            2,
            "expected finite texture coordinates",
        )?;
        for uv in t.chunks_exact(2) {
            mesh.uvs.push([uv[0] as f32, uv[1] as f32]);
        }
        let local: Vec<u32> = match primitive.indices() {
            Some(indices) => {
                if indices.count() > 3 * MAX_TREE_TRIANGLES {
                    return Err(err(
                        format!("{prim_at}, indices"),
                        format!("{} indices", indices.count()),
                        format!("expected at most {MAX_TREE_TRIANGLES} triangles per tree (E§3.1)"),
                    ));
                }
                read_accessor(
                    &indices,
                    &data,
                    file,
                    &format!("{prim_at}, indices"),
                    AccessorUse::Index,
                )?
                .into_iter()
                .map(|i| i as u32)
                .collect()
            }
            None => (0..count as u32).collect(),
        };
        if !local.len().is_multiple_of(3) {
            return Err(err(
                format!("{prim_at}, indices"),
                format!("{} indices", local.len()),
                "expected a multiple of 3 (a triangle list)".into(),
            ));
        }
        for (k, &i) in local.iter().enumerate() {
            if i as usize >= count {
                return Err(err(
                    format!("{prim_at}, indices element {k}"),
                    i.to_string(),
                    format!("index out of range ({count} vertices)"),
                ));
            }
            // base + i < MAX_MESH_VERTICES (checked above) fits in u32.
            mesh.indices.push(base as u32 + i);
        }
    }
    mesh.validate(file)?;
    Ok(mesh)
}

/// What an accessor is read as, which decides the types it may have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AccessorUse {
    /// `POSITION`: float VEC3.
    Position,
    /// `TEXCOORD_0`: VEC2 of float, or normalized unsigned byte or short.
    TexCoord,
    /// `indices`: SCALAR unsigned byte, short or int.
    Index,
}

/// Reads every component of `accessor` as `f64` (bounds-checked against the buffer data; no
/// arithmetic can overflow: counts are limited first).
fn read_accessor(
    accessor: &gltf::Accessor,
    data: &[Vec<u8>],
    file: &str,
    at: &str,
    usage: AccessorUse,
) -> Result<Vec<f64>, InputError> {
    use gltf::accessor::{DataType, Dimensions};
    let err = |value: String, reason: &str| InputError::new(file, at, value, reason);
    let (dims, ty, normalized) = (
        accessor.dimensions(),
        accessor.data_type(),
        accessor.normalized(),
    );
    let ok = match usage {
        AccessorUse::Position => dims == Dimensions::Vec3 && ty == DataType::F32,
        AccessorUse::TexCoord => {
            dims == Dimensions::Vec2
                && (ty == DataType::F32
                    || (normalized && matches!(ty, DataType::U8 | DataType::U16)))
        }
        AccessorUse::Index => {
            dims == Dimensions::Scalar && matches!(ty, DataType::U8 | DataType::U16 | DataType::U32)
        }
    };
    let kind = format!(
        "{}{} {}",
        if normalized { "normalized " } else { "" },
        match ty {
            DataType::I8 => "byte",
            DataType::U8 => "unsigned byte",
            DataType::I16 => "short",
            DataType::U16 => "unsigned short",
            DataType::U32 => "unsigned int",
            DataType::F32 => "float",
        },
        match dims {
            Dimensions::Scalar => "SCALAR",
            Dimensions::Vec2 => "VEC2",
            Dimensions::Vec3 => "VEC3",
            Dimensions::Vec4 => "VEC4",
            Dimensions::Mat2 => "MAT2",
            Dimensions::Mat3 => "MAT3",
            Dimensions::Mat4 => "MAT4",
        }
    );
    if !ok {
        let expected = match usage {
            AccessorUse::Position => "expected float VEC3 positions",
            AccessorUse::TexCoord => {
                "expected VEC2 texture coordinates of float, or normalized unsigned byte/short"
            }
            AccessorUse::Index => "expected unsigned byte, short or int indices",
        };
        return Err(err(kind, expected));
    }
    if accessor.sparse().is_some() {
        return Err(err("sparse".into(), "sparse accessors are not supported"));
    }
    let count = accessor.count();
    if count == 0 || count > 4 * forestlod_shared::MAX_MESH_VERTICES as usize {
        return Err(err(
            format!("count {count}"),
            "expected between 1 and a tree's few hundred elements",
        ));
    }
    let view = accessor.view().ok_or_else(|| {
        err(
            "no bufferView".into(),
            "expected an accessor with data (a bufferView)",
        )
    })?;
    let component = match ty {
        DataType::I8 | DataType::U8 => 1usize,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    };
    let width = dims.multiplicity();
    let element = component * width;
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(err(
            format!("byteStride {stride}"),
            "expected a stride of at least one element",
        ));
    }
    let buffer = data
        .get(view.buffer().index())
        .map_or(&[][..], Vec::as_slice);
    let view_end = view.offset().checked_add(view.length());
    let Some(view_bytes) = view_end.and_then(|end| buffer.get(view.offset()..end)) else {
        return Err(err(
            format!(
                "bufferView {} bytes {}+{}",
                view.index(),
                view.offset(),
                view.length()
            ),
            "bufferView out of its buffer's data",
        ));
    };
    let needed = accessor
        .offset()
        .checked_add(stride * (count - 1) + element)
        .filter(|&end| end <= view_bytes.len());
    if needed.is_none() {
        return Err(err(
            format!(
                "byteOffset {} count {count} stride {stride}",
                accessor.offset()
            ),
            "accessor out of its bufferView",
        ));
    }
    let mut out = Vec::with_capacity(count * width);
    for i in 0..count {
        let start = accessor.offset() + i * stride;
        for c in 0..width {
            let b = &view_bytes[start + c * component..start + (c + 1) * component];
            let v = match ty {
                DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::U16 => {
                    let v = u16::from_le_bytes([b[0], b[1]]) as f64;
                    if normalized { v / 65535.0 } else { v }
                }
                DataType::U8 => {
                    let v = b[0] as f64;
                    if normalized { v / 255.0 } else { v }
                }
                // Excluded above.
                DataType::I8 | DataType::I16 => 0.0,
            };
            out.push(v);
        }
    }
    Ok(out)
}

/// Loads an 8-bit RGBA PNG texture ([`decode_png_texture`]).
pub fn load_png_texture(path: &Path) -> Result<Rgba8Image, InputError> {
    let bytes = read_limited(path, MAX_TEXTURE_FILE_BYTES)?;
    decode_png_texture(&bytes, &label(path))
}

/// The colour type and bit depth a PNG's header declares, in words: `RGB, 8-bit`, `palette,
/// 4-bit, no transparency`, `grey+alpha, 16-bit`... (`bytes` has been accepted by the decoder, so
/// its IHDR chunk is where the PNG standard puts it.)
fn png_colour_type_name(bytes: &[u8]) -> String {
    let (Some(&depth), Some(&colour)) = (bytes.get(24), bytes.get(25)) else {
        return "unknown".into();
    };
    let name = match colour {
        0 => "grey",
        2 => "RGB",
        3 => "palette",
        4 => "grey+alpha",
        6 => "RGBA",
        _ => return format!("colour type {colour}, {depth}-bit"),
    };
    // A palette or grey/RGB image may carry its transparency in a tRNS chunk.
    // (It comes before the first IDAT; walk the chunks up to there.)
    let mut has_trns = false;
    let mut at = 8usize;
    while let Some(header) = bytes.get(at..at + 8) {
        let length = u32::from_be_bytes([header[0], header[1], header[2], header[3]]) as usize;
        match &header[4..8] {
            b"tRNS" => has_trns = true,
            b"IDAT" => break,
            _ => {}
        }
        at = at.saturating_add(length).saturating_add(12);
    }
    let transparency = match (colour, has_trns) {
        (0 | 2 | 3, false) => ", no transparency",
        (0 | 2 | 3, true) => ", with tRNS transparency",
        _ => "",
    };
    format!("{name}, {depth}-bit{transparency}")
}

/// Decodes PNG `bytes` (`file` names them in errors) as a texture: the image must decode to 8-bit
/// RGBA (colour type 6 at bit depth 8, or a palette with transparency), square, with a power-of-two
/// side of at most [`MAX_TEXTURE_SIDE`]. Colour is taken as sRGB, alpha as straight (SPEC §3).
pub fn decode_png_texture(bytes: &[u8], file: &str) -> Result<Rgba8Image, InputError> {
    let size = format!("{} bytes", bytes.len());
    let decoder = image::codecs::png::PngDecoder::new(Cursor::new(bytes))
        .map_err(|e| InputError::new(file, "file", &size, format!("invalid PNG: {e}")))?;
    let (width, height) = decoder.dimensions();
    if decoder.color_type() != image::ColorType::Rgba8 {
        return Err(InputError::new(
            file,
            "colour type",
            png_colour_type_name(bytes),
            "expected RGBA, 8-bit (PNG colour type 6, straight alpha) or a palette with transparency (tRNS): re-export the texture as 8-bit RGBA",
        ));
    }
    for (what, side) in [("width", width), ("height", height)] {
        if side == 0 || !side.is_power_of_two() || side > MAX_TEXTURE_SIDE {
            return Err(InputError::new(
                file,
                what,
                side,
                format!("expected a power of two in 1..={MAX_TEXTURE_SIDE}"),
            ));
        }
    }
    // The mips stage (E Alg. 3.2) builds square chains only; say so here, where the file is known,
    // rather than in `prepare`, which no longer knows it.
    if width != height {
        return Err(InputError::new(
            file,
            "size",
            format!("{width}x{height}"),
            "expected a square texture (the mip chain of every texture is square)",
        ));
    }
    let image = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| InputError::new(file, "image data", &size, format!("invalid PNG: {e}")))?
        .into_rgba8();
    let texels = image.pixels().map(|p| p.0).collect();
    Ok(Rgba8Image {
        width,
        height,
        texels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Asserts that the error text `e` mentions every one of `needles`.
    fn assert_mentions(e: &str, needles: &[&str]) {
        assert!(needles.iter().all(|n| e.contains(n)), "{e}");
    }

    fn names() -> Vec<String> {
        Species::ALL.iter().map(|s| s.name().to_string()).collect()
    }

    fn parse(text: &str) -> Result<Vec<InstanceRow>, InputError> {
        parse_instances_csv(text.as_bytes(), "trees.csv", &names())
    }

    #[test]
    fn csv_parses_utm_coordinates_names_and_indices() {
        let rows = parse("x,y,z,yaw,scale,species\n500000.25,5300000.5,210,0.5,1.2,oak\n500010,5300003,211.5,0,1,4\n")
            .unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].position, [500000.25, 5300000.5, 210.0]);
        assert_eq!(rows[0].mesh, Species::Oak as u32);
        assert_eq!(rows[0].line, 2);
        assert_eq!(rows[1].mesh, 4);
        assert_eq!(rows[1].line, 3);
        let scene =
            build_scene("t".into(), species_meshes(), &rows, None, None, "trees.csv").unwrap();
        assert_eq!(scene.origin, [500005.0, 5300002.0, 211.0]);
        assert_eq!(scene.instances[0].position, [-4.75, -1.5, -1.0]);
        assert_eq!(scene.terrain, Terrain::Flat { z: -1.0 });
        scene.validate("t").unwrap();
    }

    #[test]
    fn csv_columns_may_come_in_any_order_with_spaces_and_a_bom() {
        let rows = parse("\u{feff}species, scale ,yaw,z,y,x\n pine ,2,0,1,2,3\n").unwrap();
        assert_eq!(rows[0].position, [3.0, 2.0, 1.0]);
        assert_eq!(rows[0].scale, 2.0);
        assert_eq!(rows[0].mesh, 1);
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn csv_errors_name_file_line_column_and_value() {
        let h = "x,y,z,yaw,scale,species\n";
        // Rows after the header `h`, and what the error must mention.
        let after_header: [(&str, &[&str]); 10] = [
            (
                "1,2,3,0,1,oak\nabc,2,3,0,1,oak\n",
                &["trees.csv", "line 3", "column x", "abc"],
            ),
            ("1,2,NaN,0,1,oak\n", &["line 2", "column z", "NaN"]),
            ("1,2,3,inf,1,oak\n", &["column yaw", "inf"]),
            ("1,2,3,0,-1,oak\n", &["column scale", "-1"]),
            ("1,2,3,0,0,oak\n", &["column scale", "\"0\""]),
            (
                "1,2,3,0,1,baobab\n",
                &["column species", "baobab", "spruce"],
            ),
            ("1,2,3,0,1,5\n", &["column species", "\"5\""]),
            ("1,2,3,0,1\n", &["line 2", "column count"]),
            ("", &["empty table"]),
            ("1e300,2,3,0,1,oak\n", &["column x", "1e300"]),
        ];
        for (rows, needles) in after_header {
            let e = err(&format!("{h}{rows}"));
            assert_mentions(&e, needles);
        }
        // Whole files: no header, or a bad one.
        let whole: [(&str, &[&str]); 4] = [
            ("", &["empty file"]),
            (
                "x,y,z,yaw,species\n1,2,3,0,oak\n",
                &["missing column", "scale"],
            ),
            (
                "x,y,z,yaw,scale,species,height\n",
                &["unknown column", "height"],
            ),
            ("x,y,z,yaw,scale,species,x\n", &["duplicate column"]),
        ];
        for (text, needles) in whole {
            let e = err(text);
            assert_mentions(&e, needles);
        }
    }

    #[test]
    fn csv_line_numbers_count_blank_lines_crlf_and_quoted_newlines() {
        let h = "x,y,z,yaw,scale,species\r\n";
        // (position, value) of the error for the table `h` + `body`.
        let error_at = |body: &str| {
            let e = parse(&format!("{h}{body}")).unwrap_err();
            (e.position, e.value)
        };
        // The quoted species spans lines 6-7 and is not a species name.
        let (position, value) =
            error_at("\r\n1,2,3,0,1,oak\r\n\n  \n\"1\",2,3,0,1,\"o\nak\"\n4,5,6,0,1,\"pine\"");
        assert_eq!(position, "line 6, column species");
        assert_eq!(value, "o\nak");
        let (position, value) =
            error_at("\r\n1,2,3,0,1,oak\r\n\n  \n\" 1 \",2,3,0,1,\"pi\"\"ne\"\n4,5,6,0,1,\"pine\"");
        assert_eq!(position, "line 6, column species");
        assert_eq!(value, "pi\"ne");
        let rows = parse(&format!(
            "{h}\r\n1,2,3,0,1,oak\r\n\n\n\"1\" ,2,3,0,1,\"pine\"\r\n4,5,6,0,1,birch"
        ))
        .unwrap();
        assert_eq!(rows.iter().map(|r| r.line).collect::<Vec<_>>(), [3, 6, 7]);
        assert_eq!(rows[1].position[0], 1.0);
        let e = err(&format!("{h}1,2,3,0,1,\"oak"));
        assert_mentions(&e, &["line 2", "never closed"]);
        let e = err(&format!("{h}1,2,3,0,1,\"oak\"x"));
        assert_mentions(&e, &["line 2", "closing quote"]);
        let long = format!("{h}{}", "1".repeat(MAX_CSV_RECORD_BYTES + 10));
        let e = err(&long);
        assert_mentions(&e, &["line 2", "at most"]);
    }

    #[test]
    fn csv_rejects_too_many_rows_at_the_first_extra_row() {
        let text = "x,y,z,yaw,scale,species\n1,2,3,0,1,oak\n1,2,3,0,1,oak\n\n1,2,3,0,1,oak\n";
        assert_eq!(
            parse_instances_csv_limited(text.as_bytes(), "big.csv", &names(), 3)
                .unwrap()
                .len(),
            3
        );
        let e = parse_instances_csv_limited(text.as_bytes(), "big.csv", &names(), 2)
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["big.csv", "line 5", "row 3", "too many rows"]);
    }

    #[test]
    fn csv_rejects_invalid_utf8_with_a_line() {
        let mut bytes = b"x,y,z,yaw,scale,species\n1,2,3,0,1,oak\n1,2,3,0,1,".to_vec();
        bytes.extend_from_slice(&[0xff, 0xfe, b'\n']);
        let e = parse_instances_csv(&bytes[..], "trees.csv", &names())
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["trees.csv", "line 3"]);
    }

    #[test]
    fn far_trees_are_rejected_with_their_line() {
        let rows = parse("x,y,z,yaw,scale,species\n0,0,0,0,1,oak\n3000000,0,0,0,1,oak\n").unwrap();
        let e = build_scene(
            "t".into(),
            species_meshes(),
            &rows,
            Some([0.0; 3]),
            None,
            "trees.csv",
        )
        .unwrap_err()
        .to_string();
        assert_mentions(&e, &["line 3", "3000000"]);
    }

    const QUAD_OBJ: &str = "# a card\nv -1 0 0\nv 1 0 0\nv 1 0 2\nv -1 0 2\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";

    fn texture() -> Rgba8Image {
        Rgba8Image::new(4, 4, [10, 20, 30, 255])
    }

    #[test]
    fn obj_quad_is_triangulated_with_flipped_v() {
        let card = |up| parse_obj_mesh("card", QUAD_OBJ.as_bytes(), "card.obj", up, texture());
        let m = card(UpAxis::Z).unwrap();
        assert_eq!(m.indices.len(), 6);
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[2], [1.0, 0.0, 2.0]);
        assert_eq!(m.uvs[0], [0.0, 1.0]);
        assert_eq!(m.uvs[2], [1.0, 0.0]);
        let y = card(UpAxis::Y).unwrap();
        assert_eq!(y.positions[2], [1.0, -2.0, 0.0]);
    }

    #[test]
    fn obj_errors_name_file_line_and_value() {
        let bad = |text: &str| {
            parse_obj_mesh("t", text.as_bytes(), "tree.obj", UpAxis::Z, texture())
                .unwrap_err()
                .to_string()
        };
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 7/1\n");
        assert_mentions(&e, &["tree.obj", "line 5", "7/1", "out of range"]);
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 0/1\n");
        assert_mentions(&e, &["line 5", "0/1"]);
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/0 2/1 3/1\n");
        assert_mentions(&e, &["line 5", "1/0"]);
        let e = bad("v 0 nan 0\n");
        assert_mentions(&e, &["line 1", "nan"]);
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
        assert!(e.contains("texture coordinate"), "{e}");
        let e = bad("# nothing\n");
        assert!(e.contains("geometry") || e.contains("triangle"), "{e}");
        let mut many = String::new();
        for i in 0..25 {
            many.push_str(&format!("v {i} 0 0\nv {i} 1 0\nv {i} 1 1\nvt 0 0\n"));
        }
        for i in 0..25 {
            let b = 3 * i + 1;
            many.push_str(&format!("f {}/1 {}/1 {}/1\n", b, b + 1, b + 2));
        }
        let e = bad(&many);
        assert_mentions(&e, &["triangle count", "25"]);
    }

    fn png(color: image::ExtendedColorType, w: u32, h: u32) -> Vec<u8> {
        use image::ImageEncoder;
        let channels = match color {
            image::ExtendedColorType::Rgba8 => 4,
            image::ExtendedColorType::Rgb8 => 3,
            image::ExtendedColorType::L8 => 1,
            image::ExtendedColorType::Rgba16 => 8,
            _ => unreachable!(),
        };
        let data = vec![7u8; (w * h) as usize * channels];
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&data, w, h, color)
            .unwrap();
        out
    }

    #[test]
    fn png_must_be_rgba8_power_of_two_and_small() {
        use image::ExtendedColorType::{L8, Rgb8, Rgba8, Rgba16};
        let t = decode_png_texture(&png(Rgba8, 8, 8), "t.png").unwrap();
        assert_eq!((t.width, t.height), (8, 8));
        assert_eq!(t.texels[0], [7, 7, 7, 7]);
        let err = |bytes: &[u8]| decode_png_texture(bytes, "t.png").unwrap_err().to_string();
        let e = err(&png(Rgba8, 8, 4));
        assert_mentions(&e, &["t.png", "8x4", "square"]);
        let e = err(&png(Rgb8, 8, 8));
        assert_mentions(&e, &["t.png", "colour type", "RGB, 8-bit"]);
        let e = err(&png(L8, 8, 8));
        assert!(e.contains("colour type"), "{e}");
        let e = err(&png(Rgba16, 8, 8));
        assert!(e.contains("colour type"), "{e}");
        let e = err(&png(Rgba8, 6, 8));
        assert_mentions(&e, &["width", "6"]);
        let e = err(&png(Rgba8, 8192, 1));
        assert_mentions(&e, &["width", "8192"]);
        let e = err(b"not a png");
        assert!(e.contains("invalid PNG"), "{e}");
        let full = png(Rgba8, 8, 8);
        assert!(decode_png_texture(&full[..full.len() / 2], "t.png").is_err());
    }

    #[test]
    fn line_col_counts_characters() {
        assert_eq!(line_col("ab\ncdé\nf", 0), (1, 1));
        assert_eq!(line_col("ab\ncdé\nf", 3), (2, 1));
        assert_eq!(line_col("ab\ncdé\nf", 8), (3, 1));
        assert_eq!(line_col("ab", 100), (1, 3));
    }
}
