//! Celba 2007's test forests (C§5.2) as built-in scenes: `celba-<trees per ha>-<side km>`, e.g.
//! `celba-20-10` (20 trees/ha on 10 km x 10 km).
//!
//! # Contract
//! - **Names**: densities [`CELBA_DENSITIES_PER_HA`] (C§5.2's fifth series: 5, 10, 20, 40 and, for
//!   his poplar forest, 80 trees per 10,000 m²) times sides [`CELBA_SIDES_KM`]: his fourth series'
//!   4x4, 5x5, 10x10 and 20x20 km, and also 1x1 km (the size of every other series: "all tests are
//!   done with forests of size 1x1 km") and 2x2 km (his seventh, nodes-per-node series: "the forest
//!   used is of 2x2 km size"), so that those series can be rerun at his sizes. Every pair is a
//!   scene ([`celba_names`]: 30). [`parse_celba_name`]
//!   accepts exactly the canonical spelling (`celba-20-10`, not `celba-020-10` or `celba-+20-10`);
//!   anything else with the [`CELBA_PREFIX`] is an [`InputError`] naming the value and listing the
//!   valid densities and sides, never a panic. [`super::builtin::by_name`] resolves these names;
//!   [`super::builtin::BUILTIN_NAMES`] is unchanged (its loops would otherwise build 3.2 M trees).
//! - **Scenes**: the generator of [`super::builtin::forest`] (jittered grid of exactly
//!   `round(density · area)` trees, the five species in stands, uniform yaw, scale 0.7-1.3), a
//!   square centred on the origin, seed [`CELBA_SEED`] for every scene (so the 20 trees/ha forests of
//!   all four sizes share one stand map), on the built-in [`HILLS`] (±31 m, 1500 m wavelength). The
//!   hills suit a 20 km forest: their slopes stay under 18 % (10°: a walker's eye 1.7 m above them
//!   looking level sees ahead, not into the ground), while a 20 km scene still crosses 13 of their wavelengths, so the
//!   far plane's horizon varies. Celba's forests were one species each (poplar for series 1);
//!   ours mix five, which only changes what the trees look like, not how many there are.
//! - **Counts**: `density_per_ha · 100 · side_km²` trees exactly (the area is in km²; 1 km² =
//!   100 ha): from 500 (`celba-5-1`) to 3,200,000 (`celba-80-20`). C§5.2 says his 20x20 km forest
//!   "contains almost 400 000 trees": that is `celba-10-20` (10 trees/ha x 40,000 ha = 400,000 trees).
//! - **Deterministic**: the same name gives the same instances, bit for bit, for any rayon
//!   thread count (the generator's contract).
//! - **Memory and time** of the largest, `celba-80-20` (3.2 M trees; an [`super::Instance`] is 24
//!   bytes, so 77 MB of instances), measured with a release build on a busy 2-core machine:
//!   `/usr/bin/time -v forestlod render --scene celba-80-20 --width 640 --height 360
//!   --hierarchy quadtree` builds the scene in 0.81 s (peak 125 MB resident), prepares it (bake,
//!   batches, 330,048 quadtree nodes) in 2.2 s (peak 339 MB), draws the reference frame in 0.33 s
//!   (peak 359 MB) and, with the GPU twin's frame (lavapipe) and the image comparisons, peaks at
//!   704 MB max RSS in 6.5 s wall (638 MB with the default grid). It fits in memory with room.

use super::Scene;
use super::builtin::{ForestConfig, HILLS, forest};
use crate::InputError;

/// Prefix of every Celba scene name.
pub const CELBA_PREFIX: &str = "celba-";
/// C§5.2's densities, trees per hectare (10,000 m²).
pub const CELBA_DENSITIES_PER_HA: [u32; 5] = [5, 10, 20, 40, 80];
/// C§5.2's forest sides, kilometres.
pub const CELBA_SIDES_KM: [u32; 6] = [1, 2, 4, 5, 10, 20];
/// Seed of every Celba scene (the year of the seed).
pub const CELBA_SEED: u64 = 2007;
/// Hectares per km².
pub const HA_PER_KM2: f64 = 100.0;

/// Every Celba scene name, densities outer, sides inner (`celba-5-4`, `celba-5-5`, ...).
pub fn celba_names() -> Vec<String> {
    CELBA_DENSITIES_PER_HA
        .iter()
        .flat_map(|d| CELBA_SIDES_KM.iter().map(move |k| celba_name(*d, *k)))
        .collect()
}

/// The name of the scene at `per_ha` trees/ha on a `side_km` square.
pub fn celba_name(per_ha: u32, side_km: u32) -> String {
    format!("{CELBA_PREFIX}{per_ha}-{side_km}")
}

fn join(values: &[u32]) -> String {
    values
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// What a valid name looks like, for error messages.
pub fn celba_name_hint() -> String {
    format!(
        "{CELBA_PREFIX}<trees per ha>-<side km> with trees per ha in {{{}}} and side in {{{}}} km (e.g. {})",
        join(&CELBA_DENSITIES_PER_HA),
        join(&CELBA_SIDES_KM),
        celba_name(20, 10),
    )
}

/// `(trees per ha, side km)` of a Celba scene name; `Ok(None)` for a name without the
/// [`CELBA_PREFIX`]; an error naming the value for a prefixed name that is not one of
/// [`celba_names`].
pub fn parse_celba_name(name: &str) -> Result<Option<(u32, u32)>, InputError> {
    let Some(rest) = name.strip_prefix(CELBA_PREFIX) else {
        return Ok(None);
    };
    let err = |what: &str, value: &str, why: String| {
        Err(InputError::new(
            "<built-in scenes>",
            format!("Celba scene {what}"),
            value,
            format!("{why}; expected {}", celba_name_hint()),
        ))
    };
    let parsed = rest.split_once('-').and_then(|(d, k)| {
        let (d, k) = (d.parse::<u32>().ok()?, k.parse::<u32>().ok()?);
        (celba_name(d, k) == name).then_some((d, k))
    });
    let Some((per_ha, side_km)) = parsed else {
        return err(
            "name",
            name,
            "not of the form celba-<trees per ha>-<side km>".into(),
        );
    };
    if !CELBA_DENSITIES_PER_HA.contains(&per_ha) {
        return err(
            "density",
            &format!("{per_ha} trees/ha (in {name})"),
            "not one of C§5.2's densities".into(),
        );
    }
    if !CELBA_SIDES_KM.contains(&side_km) {
        return err(
            "side",
            &format!("{side_km} km (in {name})"),
            "not one of C§5.2's forest sizes".into(),
        );
    }
    Ok(Some((per_ha, side_km)))
}

/// Whether `name` is a valid Celba scene name.
pub fn is_celba_name(name: &str) -> bool {
    matches!(parse_celba_name(name), Ok(Some(_)))
}

/// The generator's configuration of the scene at `per_ha` trees/ha on a `side_km` square (any
/// values: [`celba`] checks the name first).
pub fn celba_config(per_ha: u32, side_km: u32) -> ForestConfig {
    ForestConfig {
        name: celba_name(per_ha, side_km),
        side_m: f64::from(side_km) * 1000.0,
        density_per_km2: f64::from(per_ha) * HA_PER_KM2,
        seed: CELBA_SEED,
        terrain: HILLS,
    }
}

/// The Celba scene called `name` (one of [`celba_names`]); an error naming the value otherwise.
pub fn celba(name: &str) -> Result<Scene, InputError> {
    match parse_celba_name(name)? {
        Some((per_ha, side_km)) => forest(&celba_config(per_ha, side_km)),
        None => Err(InputError::new(
            "<built-in scenes>",
            "Celba scene name",
            name,
            format!("expected {}", celba_name_hint()),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_parses_to_its_pair_and_counts_density_times_area() {
        let names = celba_names();
        assert_eq!(names.len(), 30);
        assert!(names.iter().all(|n| is_celba_name(n)));
        for d in CELBA_DENSITIES_PER_HA {
            for k in CELBA_SIDES_KM {
                let name = celba_name(d, k);
                assert_eq!(parse_celba_name(&name).unwrap(), Some((d, k)));
                // trees = trees/ha x ha; exact in f64 (integers far below 2^53).
                let expected = u64::from(d) * 100 * u64::from(k) * u64::from(k);
                assert_eq!(celba_config(d, k).tree_count() as u64, expected, "{name}");
            }
        }
        assert_eq!(celba_config(80, 20).tree_count(), 3_200_000);
        assert_eq!(celba_config(10, 20).tree_count(), 400_000); // C§5.2's "almost 400 000"
        assert_eq!(parse_celba_name("synthetic").unwrap(), None);
    }

    #[test]
    fn bad_names_are_errors_naming_the_value_and_the_valid_ones() {
        for (bad, names) in [
            ("celba-30-4", "30 trees/ha"),
            ("celba-20-3", "3 km"),
            ("celba-20-0", "0 km"),
            ("celba-20", "celba-20"),
            ("celba-", "celba-"),
            ("celba-020-4", "celba-020-4"),
            ("celba-+20-4", "celba-+20-4"),
            ("celba-20-4-x", "celba-20-4-x"),
            ("celba-20-4.0", "celba-20-4.0"),
            ("celba-99999999999-4", "celba-99999999999-4"),
        ] {
            let e = parse_celba_name(bad).unwrap_err().to_string();
            assert!(e.contains(names), "{bad}: {e}");
            for v in CELBA_DENSITIES_PER_HA
                .iter()
                .chain(&CELBA_SIDES_KM)
                .map(u32::to_string)
            {
                assert!(e.contains(&v), "{bad}: {e} lacks {v}");
            }
            assert!(celba(bad).is_err());
            assert!(!is_celba_name(bad));
        }
        assert!(celba("tiny").unwrap_err().to_string().contains("tiny"));
    }

    #[test]
    fn the_smallest_scene_is_deterministic_exact_and_inside_its_square() {
        let a = celba("celba-5-4").unwrap();
        let b = celba("celba-5-4").unwrap();
        assert_eq!(a, b, "same name, same instances");
        assert_eq!(a.name, "celba-5-4");
        assert_eq!(a.instances.len(), 8_000);
        assert_eq!(a.bounds, [-2000.0, -2000.0, 2000.0, 2000.0]);
        let per_ha = a.instances.len() as f64 / (a.area_km2() * HA_PER_KM2);
        assert!((per_ha - 5.0).abs() < 1e-9, "{per_ha}");
        for t in &a.instances {
            let [x, y, z] = t.position;
            assert!(x.abs() < 2000.0 && y.abs() < 2000.0);
            assert_eq!(z, a.terrain.height(x, y));
        }
        // Another density is another forest on the same stand map and terrain.
        let c = celba("celba-10-4").unwrap();
        assert_eq!(c.instances.len(), 16_000);
        assert_eq!(c.terrain, a.terrain);
    }
}
