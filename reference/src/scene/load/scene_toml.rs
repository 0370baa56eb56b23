//! Scene files (module docs, "Scene file (TOML)"): parsed with `serde` into spanned fields
//! (unknown keys are errors), every field checked and its errors placed by line, column and
//! field name; then the files it names are loaded (instances, meshes, textures), each through
//! its naming field ([`InputError::within`]) and confined to the scene's folder, and the scene
//! assembled. Every species texture must have species 0's square size (module docs, "One
//! texture size").
//!
//! Depends on every other loader file but `mod.rs`; none depends on it.

use std::path::Path;

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use super::assemble::{DemReport, TerrainSpec, build_scene_trees, validated};
use super::coords::{MAX_WORLD_COORDINATE, UpAxis};
use super::dem::{DEFAULT_DEM_VERTICES, MAX_DEM_VERTICES, load_dem};
use super::diagnostics::{cut_quoted, line_col, utf8_error_line};
use super::gltf_mesh::{GltfBuffers, parse_gltf_mesh};
use super::instances_csv::load_instances_csv;
use super::inventory::{
    ColumnMap, MAX_GEOJSON_BYTES, SpeciesLookup, TreeRow, TreeSize, parse_geojson, parse_named_csv,
};
use super::obj_mesh::parse_obj_mesh;
use super::paths::{
    LoadOptions, MAX_MESH_FILE_BYTES, MAX_SCENE_FILE_BYTES, label, read_limited, resolve_named,
    scene_folder,
};
use super::png_texture::load_png_texture;
use crate::InputError;
use crate::error::excerpt;
use crate::scene::builtin::{Species, species_meshes};
use crate::scene::{Scene, Terrain, TreeMesh};

/// Most species a scene file may declare.
pub const MAX_SPECIES: usize = 4096;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<Spanned<String>>,
    instances: Spanned<String>,
    origin: Option<Spanned<[f64; 3]>>,
    terrain: Option<Spanned<TerrainFile>>,
    species: Option<Vec<Spanned<SpeciesFile>>>,
    /// Issue 34: the inventory's own column names (module `inventory`).
    columns: Option<Spanned<ColumnMap>>,
    /// Issue 34: inventory species names to scene species names.
    species_names: Option<Spanned<BTreeMap<String, String>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TerrainFile {
    kind: Spanned<String>,
    z: Option<Spanned<f64>>,
    amplitude: Option<Spanned<f64>>,
    wavelength: Option<Spanned<f64>>,
    /// `kind = "dem"`: the elevation model (GeoTIFF or ESRI ASCII grid).
    file: Option<Spanned<String>>,
    /// `kind = "dem"`: the drawn grid's vertex budget.
    vertices: Option<Spanned<i64>>,
    /// `kind = "dem"`: the `z` mismatch tolerance, metres.
    z_tolerance: Option<Spanned<f64>>,
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

/// [`parse_scene_file`] with `options`.
pub fn parse_scene_file_with(
    bytes: &[u8],
    path: &Path,
    options: &LoadOptions,
) -> Result<Scene, InputError> {
    parse_scene_file_reported(bytes, path, options).map(|(s, _)| s)
}

/// [`load_scene_file_with`] and what loading an elevation model found (issue 34; `None` without
/// one): the CLI prints it.
pub fn load_scene_file_reported(
    path: &Path,
    options: &LoadOptions,
) -> Result<(Scene, Option<DemReport>), InputError> {
    let bytes = read_limited(path, MAX_SCENE_FILE_BYTES)?;
    parse_scene_file_reported(&bytes, path, options)
}

/// [`parse_scene_file_with`] and the [`DemReport`].
pub fn parse_scene_file_reported(
    bytes: &[u8],
    path: &Path,
    options: &LoadOptions,
) -> Result<(Scene, Option<DemReport>), InputError> {
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
        let (position, value) = crate::error::span_position(text, e.span());
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
        Some(t) if t.get_ref().kind.get_ref() == "dem" => {
            Some(dem_spec(t, &file, text, base, options)?)
        }
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
    let aliases = parsed
        .species_names
        .as_ref()
        .map(|m| m.get_ref().clone())
        .unwrap_or_default();
    for (from, to) in &aliases {
        if !names.contains(to) {
            let span = parsed.species_names.as_ref().map_or(0..0, |m| m.span());
            return Err(InputError::new(
                &file,
                at(span, &format!("species_names.{}", excerpt(from))),
                to,
                format!("not a species of this scene ({})", names.join(", ")),
            ));
        }
    }
    let lookup = SpeciesLookup {
        names: &names,
        aliases: &aliases,
    };
    let kind = instances_path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let columns = parsed.columns.as_ref().map(|c| c.get_ref().clone());
    let rows: Vec<TreeRow> = match (kind.as_deref(), &columns) {
        (Some("geojson" | "json"), map) => {
            let bytes =
                read_limited(&instances_path, MAX_GEOJSON_BYTES).map_err(|e| e.within(&link))?;
            parse_geojson(
                &bytes,
                &label(&instances_path),
                map.as_ref().unwrap_or(&ColumnMap::default()),
                &lookup,
            )
            .map_err(|e| e.within(&link))?
        }
        (_, Some(map)) => {
            let f = super::paths::open_file(&instances_path).map_err(|e| e.within(&link))?;
            parse_named_csv(
                std::io::BufReader::new(f),
                &label(&instances_path),
                map,
                &lookup,
            )
            .map_err(|e| e.within(&link))?
        }
        (_, None) => load_instances_csv(&instances_path, &names)
            .map_err(|e| e.within(&link))?
            .into_iter()
            .map(|r| TreeRow {
                xy: [r.position[0], r.position[1]],
                z: Some(r.position[2]),
                yaw: r.yaw,
                size: TreeSize::Scale(r.scale),
                mesh: r.mesh,
                at: format!("line {}", r.line),
            })
            .collect(),
    };
    let (scene, report) = build_scene_trees(
        name,
        meshes,
        &rows,
        origin,
        terrain,
        &label(&instances_path),
    )
    .map_err(|e| e.within(&link))?;
    Ok((validated(scene, &file)?, report))
}

/// Checks a `[terrain]` table of `kind = "dem"` (issue 34): `file` (required, under the scene's
/// folder), `vertices` (the drawn grid's budget, default [`DEFAULT_DEM_VERTICES`]), `z_tolerance`
/// (metres, default 1), nothing else; reads the elevation model.
fn dem_spec(
    t: &Spanned<TerrainFile>,
    file: &str,
    text: &str,
    base: &Path,
    options: &LoadOptions,
) -> Result<TerrainSpec, InputError> {
    let at = |span: std::ops::Range<usize>, field: &str| {
        let (line, col) = line_col(text, span.start);
        format!("line {line}, column {col}, field terrain.{field}")
    };
    let r = t.get_ref();
    for (name, v) in [
        ("z", &r.z),
        ("amplitude", &r.amplitude),
        ("wavelength", &r.wavelength),
    ] {
        if let Some(v) = v {
            return Err(InputError::new(
                file,
                at(v.span(), name),
                v.get_ref(),
                "not allowed with kind = \"dem\"",
            ));
        }
    }
    let Some(dem) = &r.file else {
        return Err(InputError::new(
            file,
            at(t.span(), "file"),
            "",
            "missing: kind = \"dem\" needs file (a GeoTIFF .tif or an ESRI ASCII grid .asc)",
        ));
    };
    let budget = match &r.vertices {
        None => DEFAULT_DEM_VERTICES,
        Some(v) if (4..=i64::from(MAX_DEM_VERTICES)).contains(v.get_ref()) => *v.get_ref() as u32,
        Some(v) => {
            return Err(InputError::new(
                file,
                at(v.span(), "vertices"),
                v.get_ref(),
                format!("expected a vertex budget in [4, {MAX_DEM_VERTICES}]"),
            ));
        }
    };
    let tolerance = match &r.z_tolerance {
        None => 1.0,
        Some(v) if v.get_ref().is_finite() && *v.get_ref() >= 0.0 => *v.get_ref(),
        Some(v) => {
            return Err(InputError::new(
                file,
                at(v.span(), "z_tolerance"),
                v.get_ref(),
                "expected a finite tolerance >= 0 m",
            ));
        }
    };
    let dem_at = at(dem.span(), "file");
    let path = resolve_named(base, dem.get_ref(), options, file, &dem_at)?;
    let link = format!("{file}: {dem_at} = {}", excerpt(dem.get_ref()));
    let raster = load_dem(&path).map_err(|e| e.within(&link))?;
    Ok(TerrainSpec::Dem {
        raster,
        budget,
        tolerance,
        file: label(&path),
    })
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
                "expected \"flat\", \"hills\" or \"dem\"",
            ));
        }
    };
    let dem_only = [
        (
            "file",
            t_ref.file.as_ref().map(|v| (v.span(), v.get_ref().clone())),
        ),
        (
            "vertices",
            t_ref
                .vertices
                .as_ref()
                .map(|v| (v.span(), v.get_ref().to_string())),
        ),
        (
            "z_tolerance",
            t_ref
                .z_tolerance
                .as_ref()
                .map(|v| (v.span(), v.get_ref().to_string())),
        ),
    ];
    for (name, v) in dem_only {
        if let Some((span, value)) = v {
            return Err(InputError::new(
                file,
                at(span, name),
                value,
                format!("not allowed with kind = \"{kind}\" (only with kind = \"dem\")"),
            ));
        }
    }
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
                        crate::scene::builtin::TEXTURE_SIZE,
                        crate::scene::builtin::TEXTURE_SIZE
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
