//! Tree inventories as GIS tools write them (issue 34): GeoJSON points and CSV tables with named
//! columns, read through a column map into [`TreeRow`]s.
//!
//! # Contract
//! - **Column map** ([`ColumnMap`], the scene file's `[columns]` table): the file's own names for
//!   `x`, `y`, `z`, `height`, `crown_diameter`, `species`, `yaw`. A CSV needs `x`, `y` and
//!   `species` mapped; GeoJSON takes `x`, `y` (and `z` when the point has three coordinates and
//!   no `z` property is mapped) from each `Point` geometry and the rest from its `properties`,
//!   by the mapped names or, unmapped, by the canonical ones. Columns the map does not name are
//!   ignored; a mapped column missing from the header (or a property missing from a feature) is
//!   an error naming the file, the row and the name.
//! - **Species**: the value is looked up in the scene file's `[species_names]` table (inventory
//!   name to scene species), then among the scene's species names; anything else is an error
//!   naming the file, the row and the value.
//! - **Size**: `height` (metres) gives the scale from the mesh's own height (its top above its
//!   base, `bbox_max.z`): `scale = height / top`, so the drawn top is the given height within a
//!   few ULPs; without a height, `crown_diameter` gives it from the mesh's crown width (twice its
//!   horizontal radius); with neither, scale 1.
//! - **z** is optional: a tree without one stands on the terrain (`assemble`).
//! - **yaw** in degrees, counter-clockwise about +Z; without one, a fixed function of the row
//!   (golden-ratio sequence), so the same file gives the same scene.
//! - At most [`super::MAX_INSTANCES`] trees; a GeoJSON file of at most [`MAX_GEOJSON_BYTES`].

use std::collections::BTreeMap;
use std::io::Read;

use super::coords::MAX_WORLD_COORDINATE;
use super::instances_csv::{CsvRecords, MAX_INSTANCES};
use crate::InputError;
use crate::error::cut;

/// Largest GeoJSON inventory read, bytes.
pub const MAX_GEOJSON_BYTES: u64 = 512 << 20;

/// The canonical names of an inventory's columns, in the order of [`ColumnMap::names`].
pub const INVENTORY_COLUMNS: [&str; 7] =
    ["x", "y", "z", "height", "crown_diameter", "species", "yaw"];

/// The file's own column names for the canonical ones (module docs).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColumnMap {
    /// Easting, metres.
    pub x: Option<String>,
    /// Northing, metres.
    pub y: Option<String>,
    /// Height of the tree's base, metres (optional).
    pub z: Option<String>,
    /// Tree height, metres.
    pub height: Option<String>,
    /// Crown diameter, metres.
    pub crown_diameter: Option<String>,
    /// Species name.
    pub species: Option<String>,
    /// Yaw, degrees.
    pub yaw: Option<String>,
}

impl ColumnMap {
    /// The mapped names in [`INVENTORY_COLUMNS`] order.
    pub fn names(&self) -> [Option<&str>; 7] {
        [
            &self.x,
            &self.y,
            &self.z,
            &self.height,
            &self.crown_diameter,
            &self.species,
            &self.yaw,
        ]
        .map(|n| n.as_deref())
    }
}

/// How big a tree is, as the inventory says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TreeSize {
    /// A scale factor of the mesh.
    Scale(f32),
    /// Height of the top above the base, metres.
    Height(f64),
    /// Crown diameter, metres.
    Crown(f64),
}

/// One tree of an inventory, as read: world `x, y`, optional `z`.
#[derive(Clone, Debug, PartialEq)]
pub struct TreeRow {
    /// World easting and northing, metres.
    pub xy: [f64; 2],
    /// World height of the base, when given.
    pub z: Option<f64>,
    /// Yaw, radians.
    pub yaw: f32,
    /// Size.
    pub size: TreeSize,
    /// Mesh (species) index.
    pub mesh: u32,
    /// Where the row is, for errors (`line 5`, `feature 3`).
    pub at: String,
}

/// Inventory species name to mesh index: `[species_names]` first, then the scene's own names.
pub struct SpeciesLookup<'a> {
    /// The scene's species names, in mesh order.
    pub names: &'a [String],
    /// Inventory name to scene species name.
    pub aliases: &'a BTreeMap<String, String>,
}

impl SpeciesLookup<'_> {
    fn find(&self, value: &str) -> Option<u32> {
        let name = self.aliases.get(value).map_or(value, String::as_str);
        self.names.iter().position(|n| n == name).map(|i| i as u32)
    }

    fn unknown(&self) -> String {
        let mut known: Vec<String> = self.aliases.keys().take(6).map(|n| cut(n)).collect();
        known.extend(self.names.iter().take(6).map(|n| cut(n)));
        format!(
            "unknown species: expected a name of [species_names] or a scene species ({}{})",
            known.join(", "),
            if self.aliases.len() + self.names.len() > known.len() {
                ", ..."
            } else {
                ""
            }
        )
    }
}

/// The default yaw of row `k` (module docs): the golden-ratio sequence, radians.
pub fn default_yaw(k: usize) -> f32 {
    let f = (k as f64 * 0.618_033_988_749_894_9).fract();
    (f * core::f64::consts::TAU) as f32
}

/// A number of an inventory: finite; `what` says what it is in errors.
fn number(
    file: &str,
    at: &str,
    column: &str,
    text: &str,
    check: fn(f64) -> bool,
    expected: &str,
) -> Result<f64, InputError> {
    let v: f64 = text.trim().parse().map_err(|_| {
        InputError::new(
            file,
            format!("{at}, column {}", cut(column)),
            text,
            format!("expected a number ({expected})"),
        )
    })?;
    if !(v.is_finite() && check(v)) {
        return Err(InputError::new(
            file,
            format!("{at}, column {}", cut(column)),
            text,
            format!("expected {expected}"),
        ));
    }
    Ok(v)
}

const COORD: &str = "a finite coordinate within ±1e8 m";
fn coord_ok(v: f64) -> bool {
    v.abs() <= MAX_WORLD_COORDINATE
}
fn size_ok(v: f64) -> bool {
    v > 0.0 && v <= 1000.0
}
fn any(_: f64) -> bool {
    true
}

/// Builds one row from its fields by canonical name (`get(k)`: the text of
/// `INVENTORY_COLUMNS[k]`, `None` when the row has none), `k` its 0-based index.
fn row_from(
    file: &str,
    at: String,
    k: usize,
    names: [&str; 7],
    get: impl Fn(usize) -> Option<String>,
    species: &SpeciesLookup,
) -> Result<TreeRow, InputError> {
    let need = |c: usize| {
        get(c).ok_or_else(|| {
            InputError::new(
                file,
                format!("{at}, column {}", cut(names[c])),
                "",
                format!(
                    "missing: the column map names {} for {}",
                    cut(names[c]),
                    INVENTORY_COLUMNS[c]
                ),
            )
        })
    };
    let x = number(file, &at, names[0], &need(0)?, coord_ok, COORD)?;
    let y = number(file, &at, names[1], &need(1)?, coord_ok, COORD)?;
    let z = match get(2) {
        Some(t) if !t.trim().is_empty() => Some(number(file, &at, names[2], &t, coord_ok, COORD)?),
        _ => None,
    };
    let size = match (get(3), get(4)) {
        (Some(h), _) => TreeSize::Height(number(
            file,
            &at,
            names[3],
            &h,
            size_ok,
            "a height in (0, 1000] m",
        )?),
        (None, Some(c)) => TreeSize::Crown(number(
            file,
            &at,
            names[4],
            &c,
            size_ok,
            "a crown diameter in (0, 1000] m",
        )?),
        (None, None) => TreeSize::Scale(1.0),
    };
    let name = need(5)?;
    let mesh = species.find(name.trim()).ok_or_else(|| {
        InputError::new(
            file,
            format!("{at}, column {}", cut(names[5])),
            &name,
            species.unknown(),
        )
    })?;
    let yaw = match get(6) {
        Some(t) => (number(file, &at, names[6], &t, any, "degrees")?.to_radians()) as f32,
        None => default_yaw(k),
    };
    Ok(TreeRow {
        xy: [x, y],
        z,
        yaw,
        size,
        mesh,
        at,
    })
}

/// Parses a CSV inventory with named columns (module docs).
pub fn parse_named_csv(
    reader: impl Read,
    file: &str,
    map: &ColumnMap,
    species: &SpeciesLookup,
) -> Result<Vec<TreeRow>, InputError> {
    let mut csv = CsvRecords::new(std::io::BufReader::new(reader), file);
    let mut record = Vec::new();
    let Some(header_line) = csv.next_record(&mut record)? else {
        return Err(InputError::new(
            file,
            "line 1",
            "",
            "empty file: expected a header",
        ));
    };
    let mapped = map.names();
    for (k, need) in [(0, "x"), (1, "y"), (5, "species")] {
        if mapped[k].is_none() {
            return Err(InputError::new(
                file,
                "column map",
                need,
                format!("[columns] must name the column of {need} for a CSV inventory"),
            ));
        }
    }
    // column[k]: index in the record of the mapped column of INVENTORY_COLUMNS[k].
    let mut column = [None; 7];
    for (k, name) in mapped.iter().enumerate() {
        if let Some(name) = name {
            let i = record.iter().position(|h| h == name).ok_or_else(|| {
                InputError::new(
                    file,
                    format!("line {header_line}, header"),
                    *name,
                    format!(
                        "missing column (mapped for {}); the header has: {}",
                        INVENTORY_COLUMNS[k],
                        cut(&record.join(","))
                    ),
                )
            })?;
            column[k] = Some(i);
        }
    }
    let names = std::array::from_fn(|k| mapped[k].unwrap_or(INVENTORY_COLUMNS[k]));
    let width = record.len();
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
        if rows.len() >= MAX_INSTANCES {
            return Err(InputError::new(
                file,
                format!("line {line}"),
                rows.len() + 1,
                format!("too many rows: at most {MAX_INSTANCES} trees"),
            ));
        }
        let k = rows.len();
        let get = |c: usize| column[c].map(|i| record[i].clone());
        rows.push(row_from(
            file,
            format!("line {line}"),
            k,
            names,
            get,
            species,
        )?);
    }
    if rows.is_empty() {
        return Err(InputError::new(
            file,
            "rows",
            "none",
            "expected at least one tree",
        ));
    }
    Ok(rows)
}

/// Parses a GeoJSON inventory: a `FeatureCollection` of `Point` features (module docs).
pub fn parse_geojson(
    bytes: &[u8],
    file: &str,
    map: &ColumnMap,
    species: &SpeciesLookup,
) -> Result<Vec<TreeRow>, InputError> {
    use serde_json::Value;
    let doc: Value = serde_json::from_slice(bytes).map_err(|e| {
        InputError::new(
            file,
            format!("line {}, column {}", e.line(), e.column()),
            "",
            format!("invalid JSON: {e}"),
        )
    })?;
    if doc.get("type").and_then(Value::as_str) != Some("FeatureCollection") {
        return Err(InputError::new(
            file,
            "type",
            doc.get("type").map(Value::to_string).unwrap_or_default(),
            "expected a GeoJSON FeatureCollection",
        ));
    }
    let features = doc
        .get("features")
        .and_then(Value::as_array)
        .ok_or_else(|| InputError::new(file, "features", "", "expected an array of features"))?;
    if features.len() > MAX_INSTANCES {
        return Err(InputError::new(
            file,
            "features",
            features.len(),
            format!("too many features: at most {MAX_INSTANCES} trees"),
        ));
    }
    let mapped = map.names();
    let names: [&str; 7] = std::array::from_fn(|k| mapped[k].unwrap_or(INVENTORY_COLUMNS[k]));
    let mut rows = Vec::with_capacity(features.len());
    for (k, f) in features.iter().enumerate() {
        let at = format!("feature {k}");
        let geometry = f.get("geometry").unwrap_or(&Value::Null);
        let point = (geometry.get("type").and_then(Value::as_str) == Some("Point"))
            .then(|| geometry.get("coordinates").and_then(Value::as_array))
            .flatten()
            .filter(|c| (2..=3).contains(&c.len()) && c.iter().all(Value::is_number));
        let props = f.get("properties").and_then(Value::as_object);
        let prop = |name: &str| -> Option<String> {
            match props?.get(name)? {
                Value::Null => None,
                Value::String(s) => Some(s.clone()),
                v => Some(v.to_string()),
            }
        };
        let get = |c: usize| -> Option<String> {
            let from_point = |i: usize| point.and_then(|p| p.get(i)).map(Value::to_string);
            match c {
                0 | 1 if mapped[c].is_none() => from_point(c),
                2 if mapped[2].is_none() => from_point(2),
                _ => prop(names[c]),
            }
        };
        if point.is_none() && (mapped[0].is_none() || mapped[1].is_none()) {
            return Err(InputError::new(
                file,
                format!("{at}, geometry"),
                cut(&geometry.to_string()),
                "expected a Point with 2 or 3 numeric coordinates",
            ));
        }
        rows.push(row_from(file, at, k, names, get, species)?);
    }
    if rows.is_empty() {
        return Err(InputError::new(
            file,
            "features",
            "[]",
            "expected at least one tree",
        ));
    }
    Ok(rows)
}
