//! Scene assembly: parsed instance rows plus meshes and terrain become a [`Scene`]. Picks the
//! origin (given, or [`default_origin`](super::default_origin)), stores each tree as its `f32`
//! offset from it (each within ±`MAX_RELATIVE_COORDINATE`), sets the terrain (given, or flat at
//! the lowest tree) and the footprint; every load ends with `Scene::validate` (`validated`).
//! Also the bare-CSV scene with the built-in species.
//!
//! Depends on `paths`, `coords` and `instances_csv`.

use std::path::Path;

use super::coords::{MAX_RELATIVE_COORDINATE, default_origin};
use super::instances_csv::InstanceRow;
use super::paths::label;
use crate::InputError;
use crate::scene::builtin::{Species, species_meshes};
use crate::scene::{Instance, Scene, Terrain, TreeMesh, footprint};

/// Terrain as declared, before the origin is known.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum TerrainSpec {
    /// Flat at a world height.
    FlatWorld(f64),
    /// Already relative to the origin.
    Relative(Terrain),
}

/// `scene` if it passes [`Scene::validate`] (every load ends here).
pub(super) fn validated(scene: Scene, file: &str) -> Result<Scene, InputError> {
    scene.validate(file)?;
    Ok(scene)
}

/// Turns parsed rows into a scene: picks the origin (given, or the bounding-box centre rounded to
/// whole metres), converts positions to `f32` relative to it (each within
/// ±[`MAX_RELATIVE_COORDINATE`]), sets the terrain (given, or flat at the lowest tree) and the
/// footprint. `csv_file` names the rows' file in errors.
pub(super) fn build_scene(
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

/// Loads a bare instance table with the five built-in species (`spruce`, `pine`, `oak`, `birch`,
/// `poplar`, or indices 0–4): origin at the bounding-box centre rounded to whole metres, flat
/// terrain at the lowest tree, name = file stem. What the CLI's `--instances trees.csv` uses.
pub fn load_instances_with_builtin_species(csv: &Path) -> Result<Scene, InputError> {
    let file = label(csv);
    let f = super::paths::open_file(csv)?;
    let name = csv
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "instances".to_string());
    parse_instances_with_builtin_species(std::io::BufReader::new(f), &file, name)
}

/// [`load_instances_with_builtin_species`] from a reader (text already read, or built in memory):
/// `file` names it in errors, `name` is the scene's name. No file is touched (issue 28: `check`
/// materializes its cases through this, never through a scratch file).
pub fn parse_instances_with_builtin_species(
    reader: impl std::io::Read,
    file: &str,
    name: String,
) -> Result<Scene, InputError> {
    let names: Vec<String> = Species::ALL.iter().map(|s| s.name().to_string()).collect();
    let rows = super::instances_csv::parse_instances_csv(reader, file, &names)?;
    validated(
        build_scene(name, species_meshes(), &rows, None, None, file)?,
        file,
    )
}

#[cfg(test)]
mod tests {
    use super::super::instances_csv::parse_instances_csv;
    use super::super::test_util::{assert_mentions, names};
    use super::*;

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
}
