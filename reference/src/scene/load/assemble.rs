//! Scene assembly: parsed instance rows plus meshes and terrain become a [`Scene`]. Picks the
//! origin (given, or [`default_origin`](super::default_origin)), stores each tree as its `f32`
//! offset from it (each within ±`MAX_RELATIVE_COORDINATE`), sets the terrain (given, or flat at
//! the lowest tree) and the footprint; every load ends with `Scene::validate` (`validated`).
//! Also the bare-CSV scene with the built-in species.
//!
//! Depends on `paths`, `coords` and `instances_csv`.

use std::path::Path;

use super::coords::{MAX_RELATIVE_COORDINATE, default_origin};
use super::dem::{Raster, resample};
use super::instances_csv::InstanceRow;
use super::inventory::{TreeRow, TreeSize};
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
    /// An elevation model (issue 34), drawn within `budget` vertices; trees whose given `z`
    /// differs from it by more than `tolerance` metres are reported.
    Dem {
        /// The model as read.
        raster: Raster,
        /// Vertex budget of the drawn grid.
        budget: u32,
        /// The `z` mismatch tolerance, metres.
        tolerance: f64,
        /// The DEM file, for the report and errors.
        file: String,
    },
}

/// What loading a scene with an elevation model found (issue 34): printed by the CLI, not an
/// error. Trees whose given `z` disagrees with the DEM are reported, never moved.
#[derive(Clone, Debug, PartialEq)]
pub struct DemReport {
    /// The DEM file.
    pub file: String,
    /// Its CRS, when it names one.
    pub crs: Option<String>,
    /// Native samples `(columns, rows)` and spacing, metres.
    pub native: (usize, usize, f64, f64),
    /// Drawn grid `(columns, rows)` (the vertex budget's resampling).
    pub drawn: (usize, usize),
    /// Nodata samples.
    pub nodata: usize,
    /// Trees with a given `z`, and trees placed on the terrain.
    pub trees_given_z: usize,
    /// Trees without `z`, placed on the drawn terrain.
    pub trees_placed: usize,
    /// The tolerance, metres.
    pub tolerance: f64,
    /// Trees whose `|z - DEM| > tolerance`.
    pub mismatches: usize,
    /// The worst `(row, given z, DEM z)`, when any tree has a given `z`.
    pub worst: Option<(String, f64, f64)>,
}

impl std::fmt::Display for DemReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h, dx, dy) = self.native;
        write!(
            f,
            "terrain {}: {w}x{h} samples at {dx} x {dy} m{}, {} nodata, drawn {}x{}; {} trees on it, {} with a given z: {} differ from the DEM by more than {} m",
            self.file,
            self.crs
                .as_deref()
                .map(|c| format!(" ({c})"))
                .unwrap_or_default(),
            self.nodata,
            self.drawn.0,
            self.drawn.1,
            self.trees_placed,
            self.trees_given_z,
            self.mismatches,
            self.tolerance
        )?;
        if let Some((at, z, d)) = &self.worst {
            write!(f, " (worst: {at}, z {z} vs DEM {d:.3}, {:+.3} m)", z - d)?;
        }
        Ok(())
    }
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
    let trees: Vec<TreeRow> = rows
        .iter()
        .map(|r| TreeRow {
            xy: [r.position[0], r.position[1]],
            z: Some(r.position[2]),
            yaw: r.yaw,
            size: TreeSize::Scale(r.scale),
            mesh: r.mesh,
            at: format!("line {}", r.line),
        })
        .collect();
    build_scene_trees(name, meshes, &trees, origin, terrain, csv_file).map(|(s, _)| s)
}

/// [`build_scene`] for inventory rows (issue 34): sizes become scales by the mesh's height or
/// crown; with an elevation model every tree must lie over it (an error naming the row and the
/// point otherwise), trees without `z` stand on the drawn terrain, and trees whose given `z`
/// differs from the DEM (bilinear in its native samples) by more than the tolerance are counted
/// in the [`DemReport`], never moved. Trees without `z` on flat or hills terrain stand on it;
/// without a terrain they are an error.
pub(super) fn build_scene_trees(
    name: String,
    meshes: Vec<TreeMesh>,
    rows: &[TreeRow],
    origin: Option<[f64; 3]>,
    terrain: Option<TerrainSpec>,
    csv_file: &str,
) -> Result<(Scene, Option<DemReport>), InputError> {
    if rows.is_empty() {
        return Err(InputError::new(
            csv_file,
            "rows",
            "none",
            "expected at least one tree: the scene is empty",
        ));
    }
    // World z of every tree: given, or the DEM's (for the origin), or unknown yet.
    let mut report = None;
    let mut dem_z: Vec<Option<f64>> = vec![None; rows.len()];
    if let Some(TerrainSpec::Dem {
        raster,
        tolerance,
        file,
        ..
    }) = &terrain
    {
        let mut r = DemReport {
            file: file.clone(),
            crs: raster.crs.clone(),
            native: (raster.width, raster.height, raster.dx, raster.dy),
            drawn: (0, 0),
            nodata: raster.samples.iter().filter(|v| v.is_nan()).count(),
            trees_given_z: 0,
            trees_placed: 0,
            tolerance: *tolerance,
            mismatches: 0,
            worst: None,
        };
        for (k, t) in rows.iter().enumerate() {
            let h = raster.height_at(t.xy[0], t.xy[1]).ok_or_else(|| {
                let [x0, y0, x1, y1] = raster.extent();
                InputError::new(
                    csv_file,
                    format!("{}, x,y", t.at),
                    format!("({}, {})", t.xy[0], t.xy[1]),
                    format!(
                        "outside the elevation model {file} (samples cover x {x0}..{x1}, y {y0}..{y1}) or over nodata"
                    ),
                )
            })?;
            dem_z[k] = Some(h);
            match t.z {
                Some(z) => {
                    r.trees_given_z += 1;
                    let d = (z - h).abs();
                    if d > *tolerance {
                        r.mismatches += 1;
                    }
                    if r.worst
                        .as_ref()
                        .is_none_or(|(_, wz, wd)| d > (wz - wd).abs())
                    {
                        r.worst = Some((t.at.clone(), z, h));
                    }
                }
                None => r.trees_placed += 1,
            }
        }
        report = Some(r);
    }
    let world_z = |k: usize| -> Option<f64> {
        rows[k].z.or(dem_z[k]).or(match &terrain {
            Some(TerrainSpec::FlatWorld(z)) => Some(*z),
            _ => None,
        })
    };
    let origin = match origin {
        Some(o) => o,
        None => {
            let known: Vec<[f64; 3]> = (0..rows.len())
                .map(|k| [rows[k].xy[0], rows[k].xy[1], world_z(k).unwrap_or(0.0)])
                .collect();
            default_origin(known)
        }
    };
    let placed = match terrain {
        Some(TerrainSpec::FlatWorld(z)) => Some(Terrain::Flat {
            z: (z - origin[2]) as f32,
        }),
        Some(TerrainSpec::Relative(t)) => Some(t),
        Some(TerrainSpec::Dem { raster, budget, .. }) => {
            let grid = resample(&raster, budget, origin);
            if let Some(r) = report.as_mut() {
                r.drawn = (grid.nx, grid.ny);
            }
            Some(Terrain::Grid(std::sync::Arc::new(grid)))
        }
        None => None,
    };
    let mut instances = Vec::with_capacity(rows.len());
    let mut min_z = f32::INFINITY;
    for r in rows {
        let rel_xy = [r.xy[0] - origin[0], r.xy[1] - origin[1]];
        let rel_z = r.z.map(|z| z - origin[2]).unwrap_or(0.0);
        if rel_xy
            .iter()
            .chain([&rel_z])
            .any(|c| c.abs() > MAX_RELATIVE_COORDINATE)
        {
            return Err(InputError::new(
                csv_file,
                format!("{}, columns x,y,z", r.at),
                format!("{:?}", [r.xy[0], r.xy[1], r.z.unwrap_or(f64::NAN)]),
                format!(
                    "more than {} km from the scene origin {origin:?}: split the scene or set its origin",
                    MAX_RELATIVE_COORDINATE / 1000.0
                ),
            ));
        }
        let (x, y) = (rel_xy[0] as f32, rel_xy[1] as f32);
        let z = match (r.z, &placed) {
            (Some(_), _) => rel_z as f32,
            (None, Some(t)) => t.height(x, y),
            (None, None) => {
                return Err(InputError::new(
                    csv_file,
                    format!("{}, z", r.at),
                    "",
                    "missing: a tree without z needs a terrain to stand on ([terrain] in the scene file)",
                ));
            }
        };
        let scale = match r.size {
            TreeSize::Scale(s) => s,
            TreeSize::Height(h) => scale_for(h, meshes[r.mesh as usize].bounds_meta().bbox_max[2]),
            TreeSize::Crown(c) => scale_for(
                c,
                2.0 * meshes[r.mesh as usize].bounds_meta().billboard_half_width,
            ),
        };
        if !(scale.is_finite() && scale > 0.0 && scale <= 1.0e3) {
            return Err(InputError::new(
                csv_file,
                format!("{}, size", r.at),
                format!("{:?}", r.size),
                format!(
                    "gives scale {scale} of mesh {}: expected a scale in (0, 1000]",
                    meshes[r.mesh as usize].name
                ),
            ));
        }
        min_z = min_z.min(z);
        instances.push(Instance {
            position: [x, y, z],
            yaw: r.yaw,
            scale,
            mesh: r.mesh,
        });
    }
    let bounds = footprint(instances.iter().map(|i| i.position));
    let terrain = placed.unwrap_or(Terrain::Flat { z: min_z });
    Ok((
        Scene {
            name,
            origin,
            meshes,
            instances,
            terrain,
            bounds,
        },
        report,
    ))
}

/// The scale that makes a mesh of size `mesh` (its top above its base, or its crown width)
/// `size` metres: `size / mesh` in `f64`, rounded once to `f32` (module `inventory`, "Size").
pub fn scale_for(size: f64, mesh: f32) -> f32 {
    (size / f64::from(mesh)) as f32
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
