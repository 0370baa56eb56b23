//! `sweep.json`, read back by `forestlod report` (issue 28, "validated where read"): one pure
//! parser, [`parse_manifest`], that the report, `--replot` and the fuzz target
//! (`fuzz/fuzz_targets/sweep_json.rs`) share.
//!
//! Contract: a manifest is accepted only when every field has its type and a value a sweep could
//! have written; anything else is one [`InputError`] naming the file, the position (`line L,
//! column C` where the JSON parser knows it) and the key as a path into the manifest
//! (`images[0].width`, the form the report's path errors use), the value (cut to a short excerpt)
//! and what was expected. So a report over a nonsense manifest fails; it never shows garbage.
//!
//! - **Types.** Every field has its Rust type; an integer is a JSON integer in the type's range
//!   (`128.9` or `-1` for a width is an error, never 128 or 0; serde_json refuses both).
//! - **Duplicate keys** are an error at any depth, naming the key (serde's derived structs refuse
//!   them, but maps such as a setting's parameters would keep the last silently, and a row
//!   labelled with one value could then have been drawn at another).
//! - **Unknown keys** are an error naming the key: a manifest is written by `forestlod sweep`,
//!   never by hand, so an unknown key means another program or a corrupt file, and its values
//!   could not be shown. (Decided for issue 28; every committed manifest has only known keys,
//!   which `committed_manifests_parse` checks.)
//! - **Values.** Sizes `1..=MAX_TARGET_SIZE`, at least one ground-truth sample and one frame,
//!   finite non-negative times and distances, finite yaws, accuracy figures in `[0, 1]` (the
//!   figures a sweep may leave unmeasured are `null`), a non-empty name, CSV, scene and variant
//!   list and image paths (the paths themselves are confined to the run by `report.rs`), a shard
//!   of the form `I/N`, and no control character in any text but line breaks and tabs.
//!
//! The file's size is limited before it is read ([`MAX_MANIFEST_BYTES`]).

use std::collections::BTreeSet;
use std::fmt;

use forestlod_reference::InputError;
use forestlod_reference::error::cut;
use forestlod_reference::raster::MAX_TARGET_SIZE;
use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};

use crate::metrics::Accuracy;
use crate::sweep::Manifest;

/// Largest `sweep.json` read, bytes: the limit `sweep merge` reads a shard's manifest with
/// ([`crate::sweep::shard::MAX_SHARD_MANIFEST_BYTES`], 16 MiB), so a report opens whatever a merge
/// accepted. The committed manifests are under 100 KB; a saved frame's entry (fifteen image paths
/// and its figures) is about 2 KB, so this holds thousands of saved frames, far more than a
/// report can show, while a huge or endless file is refused before it is read.
pub const MAX_MANIFEST_BYTES: u64 = crate::sweep::shard::MAX_SHARD_MANIFEST_BYTES;

/// Parses and validates the text of a `sweep.json` (module docs); `file` names it in errors.
pub fn parse_manifest(text: &str, file: &str) -> Result<Manifest, InputError> {
    // Syntax and duplicate keys, on the generic JSON tree.
    let mut de = serde_json::Deserializer::from_str(text);
    NoDuplicates(String::new())
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|e| json_error(text, file, &e, None))?;
    // Types, with the key where one is wrong.
    let mut de = serde_json::Deserializer::from_str(text);
    let m: Manifest = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let key = e.path().to_string();
        json_error(text, file, e.inner(), Some(&key))
    })?;
    // Unknown keys: those the manifest would not write back.
    let given: serde_json::Value =
        serde_json::from_str(text).map_err(|e| json_error(text, file, &e, None))?;
    let known = serde_json::to_value(&m).map_err(|e| {
        InputError::new(file, "manifest", "", format!("cannot be represented: {e}"))
    })?;
    if let Some(key) = unknown_key(&given, &known, &mut String::new()) {
        return Err(InputError::new(
            file,
            format!("key {key}"),
            value_at(&given, &key),
            "unknown key: a sweep writes no such key (another program's or a corrupt file?)",
        ));
    }
    control_characters(&given, &mut String::new()).map_or(Ok(()), |(key, text)| {
        Err(InputError::new(
            file,
            format!("key {key}"),
            text,
            "expected text without control characters (other than line breaks and tabs)",
        ))
    })?;
    validate(&m).map_err(|(key, value, reason)| {
        InputError::new(file, format!("key {key}"), value, reason)
    })?;
    Ok(m)
}

/// A serde_json error as an [`InputError`]: the line and column, the key path where known, and
/// the value there.
fn json_error(text: &str, file: &str, e: &serde_json::Error, key: Option<&str>) -> InputError {
    let mut position = if e.line() > 0 {
        format!("line {}, column {}", e.line(), e.column())
    } else {
        "manifest".to_string()
    };
    let mut value = String::new();
    if let Some(key) = key.filter(|k| !k.is_empty() && *k != ".") {
        position.push_str(&format!(", key {key}"));
        if let Ok(tree) = serde_json::from_str::<serde_json::Value>(text) {
            value = value_at(&tree, key);
        }
    }
    // serde_json appends " at line L column C", which the position already says.
    let message = e.to_string();
    let reason = match message.rfind(" at line ") {
        Some(i) => message[..i].to_string(),
        None => message,
    };
    let reason = if e.is_syntax() || e.is_eof() {
        format!("is not JSON: {reason}")
    } else {
        reason
    };
    InputError::new(file, position, value, reason)
}

/// The JSON text of the value at `key` (a path as [`unknown_key`] and serde_path_to_error write
/// it: `a.b[0].c`), or empty when there is none.
fn value_at(tree: &serde_json::Value, key: &str) -> String {
    let mut at = tree;
    for part in key.split('.') {
        let (name, rest) = part.split_once('[').unwrap_or((part, ""));
        if !name.is_empty() {
            match at.get(name) {
                Some(v) => at = v,
                None => return String::new(),
            }
        }
        for index in rest.split('[') {
            let Some(i) = index.trim_end_matches(']').parse::<usize>().ok() else {
                continue;
            };
            match at.get(i) {
                Some(v) => at = v,
                None => return String::new(),
            }
        }
    }
    cut(&at.to_string())
}

/// The first key of `given` (at `path`) that `known` (the parsed manifest written back) lacks.
fn unknown_key(
    given: &serde_json::Value,
    known: &serde_json::Value,
    path: &mut String,
) -> Option<String> {
    use serde_json::Value;
    match (given, known) {
        (Value::Object(g), Value::Object(k)) => {
            for (key, v) in g {
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                let found = match k.get(key) {
                    None => Some(path.clone()),
                    Some(kv) => unknown_key(v, kv, path),
                };
                path.truncate(len);
                if found.is_some() {
                    return found;
                }
            }
            None
        }
        (Value::Array(g), Value::Array(k)) => {
            for (i, (v, kv)) in g.iter().zip(k).enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                let found = unknown_key(v, kv, path);
                path.truncate(len);
                if found.is_some() {
                    return found;
                }
            }
            None
        }
        _ => None,
    }
}

/// The first string of `tree` (at `path`) holding a control character other than a line break
/// or a tab, with its key.
fn control_characters(tree: &serde_json::Value, path: &mut String) -> Option<(String, String)> {
    use serde_json::Value;
    match tree {
        Value::String(s) => s
            .chars()
            .any(|c| c.is_control() && !matches!(c, '\n' | '\r' | '\t'))
            .then(|| (path.clone(), s.clone())),
        Value::Object(map) => map.iter().find_map(|(key, v)| {
            let len = path.len();
            if !path.is_empty() {
                path.push('.');
            }
            path.push_str(key);
            let found = control_characters(v, path);
            path.truncate(len);
            found
        }),
        Value::Array(items) => items.iter().enumerate().find_map(|(i, v)| {
            let len = path.len();
            path.push_str(&format!("[{i}]"));
            let found = control_characters(v, path);
            path.truncate(len);
            found
        }),
        _ => None,
    }
}

/// Walks a JSON value and refuses an object that repeats a key (module docs); the `String` is
/// the path so far, for the error.
struct NoDuplicates(String);

impl<'de> DeserializeSeed<'de> for NoDuplicates {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for NoDuplicates {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_i128<E>(self, _: i128) -> Result<(), E> {
        Ok(())
    }
    fn visit_u128<E>(self, _: u128) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E>(self) -> Result<(), E> {
        Ok(())
    }
    fn visit_none<E>(self) -> Result<(), E> {
        Ok(())
    }
    fn visit_some<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        self.deserialize(d)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0usize;
        while seq
            .next_element_seed(NoDuplicates(format!("{}[{i}]", self.0)))?
            .is_some()
        {
            i += 1;
        }
        Ok(())
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = BTreeSet::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = if self.0.is_empty() {
                key.clone()
            } else {
                format!("{}.{key}", self.0)
            };
            if !seen.insert(key) {
                return Err(de::Error::custom(format_args!(
                    "duplicate key {path}: each key may appear once"
                )));
            }
            map.next_value_seed(NoDuplicates(path))?;
        }
        Ok(())
    }
}

/// A value error: the key, the value as shown, and what was expected.
type Bad = (String, String, String);

fn bad(key: impl Into<String>, value: impl fmt::Display, reason: impl Into<String>) -> Bad {
    (key.into(), value.to_string(), reason.into())
}

/// `v` finite and at least 0 (seconds, metres).
fn non_negative(key: &str, v: f64) -> Result<(), Bad> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(bad(key, v, "expected a finite number of at least 0"))
    }
}

/// `v` non-empty.
fn filled(key: &str, v: &str, what: &str) -> Result<(), Bad> {
    if v.trim().is_empty() {
        Err(bad(key, v, format!("expected {what}, not empty")))
    } else {
        Ok(())
    }
}

/// Every figure of `a` in `[0, 1]`; those a sweep may leave unmeasured may be NaN (`null`).
fn accuracy(key: &str, a: &Accuracy) -> Result<(), Bad> {
    let required = [
        ("flip_mean", a.flip_mean),
        ("flip_p95", a.flip_p95),
        ("flip_p99", a.flip_p99),
        ("coverage_error", a.coverage_error),
        ("gt_tree_fraction", a.gt_tree_fraction),
        ("tree_fraction", a.tree_fraction),
    ];
    let optional = [
        ("lod_flip_mean", a.lod_flip_mean),
        ("lod_flip_p99", a.lod_flip_p99),
        ("lod_changed", a.lod_changed),
        ("total_flip_mean", a.total_flip_mean),
        ("total_flip_p99", a.total_flip_p99),
        ("total_coverage_error", a.total_coverage_error),
        ("lod_flip_billboard", a.lod_flip_billboard),
    ];
    for (name, v) in required
        .iter()
        .chain(optional.iter().filter(|(_, v)| !v.is_nan()))
    {
        if !(0.0..=1.0).contains(v) {
            return Err(bad(
                format!("{key}.{name}"),
                v,
                "expected a figure between 0 and 1",
            ));
        }
    }
    Ok(())
}

/// The value checks of the module docs, on the typed manifest.
fn validate(m: &Manifest) -> Result<(), Bad> {
    filled("name", &m.name, "the sweep's name")?;
    filled("csv", &m.csv, "the CSV's path")?;
    filled("x_axis", &m.x_axis, "the plots' x axis")?;
    if m.scenes.is_empty() {
        return Err(bad("scenes", "[]", "expected the sweep's scenes"));
    }
    if m.variants.is_empty() {
        return Err(bad("variants", "[]", "expected the sweep's variants"));
    }
    for (key, v) in [("width", m.width), ("height", m.height)] {
        if !(1..=MAX_TARGET_SIZE).contains(&v) {
            return Err(bad(
                key,
                v,
                format!("expected a frame size between 1 and {MAX_TARGET_SIZE} pixels"),
            ));
        }
    }
    if m.ground_truth_spp == 0 {
        return Err(bad(
            "ground_truth_spp",
            0,
            "expected at least 1 sample per pixel",
        ));
    }
    if m.frames == 0 {
        return Err(bad(
            "frames",
            0,
            "expected at least 1 frame (a sweep that rendered nothing writes no manifest)",
        ));
    }
    non_negative("wall_seconds", m.wall_seconds)?;
    if let Some(s) = m.ground_truth_seconds {
        non_negative("ground_truth_seconds", s)?;
    }
    for (i, (_, _, secs)) in m.ground_truth_bvh.iter().enumerate() {
        non_negative(&format!("ground_truth_bvh[{i}][2]"), *secs)?;
    }
    if let Some(shard) = &m.shard {
        shard
            .parse::<crate::sweep::shard::Shard>()
            .map_err(|e| bad("shard", shard, format!("expected I/N ({e})")))?;
    }
    for (i, (path, _)) in m.plots.iter().enumerate() {
        filled(&format!("plots[{i}][0]"), path, "the plot's path")?;
    }
    for (i, im) in m.images.iter().enumerate() {
        let key = |field: &str| format!("images[{i}].{field}");
        for (field, path) in [
            ("color", &im.color),
            ("lod", &im.lod),
            ("flip", &im.flip),
            ("ground_truth", &im.ground_truth),
            ("ground_truth_class", &im.ground_truth_class),
        ] {
            filled(&key(field), path, "the image's path")?;
        }
        if !im.yaw_deg.is_finite() {
            return Err(bad(key("yaw_deg"), im.yaw_deg, "expected a finite yaw"));
        }
        non_negative(&key("distance_m"), f64::from(im.distance_m))?;
        accuracy(&key("accuracy"), &im.accuracy)?;
        for (field, maps) in [
            ("per_lod", &im.per_lod),
            ("per_lod_lod_error", &im.per_lod_lod_error),
            ("per_lod_total", &im.per_lod_total),
        ] {
            for (j, (_, path, mean, _)) in maps.iter().enumerate() {
                filled(&key(&format!("{field}[{j}][1]")), path, "the map's path")?;
                if !(0.0..=1.0).contains(mean) {
                    return Err(bad(
                        key(&format!("{field}[{j}][2]")),
                        mean,
                        "expected a mean FLIP between 0 and 1",
                    ));
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// The `sweep_json` fuzz target's finding (crash-e2cc1337…): a key holding an escaped newline
    /// came back raw in serde's "unknown field" message, a two-line error. Control characters are
    /// escaped by `InputError`'s display, at every depth.
    #[test]
    fn a_key_holding_a_newline_gives_a_one_line_error() {
        for text in [
            "{\"na\\nme\": 1}",
            "{\"spec\": {\"back\\nds\": [\"reference\"]}}",
            "{\"x\\u001b[2J\\r\": 1}",
        ] {
            let e = parse_manifest(text, "run/s/sweep.json")
                .unwrap_err()
                .to_string();
            assert_eq!(e.lines().count(), 1, "{text}: {e:?}");
            assert!(!e.contains('\r') && !e.contains('\u{1b}'), "{text}: {e:?}");
        }
    }

    fn committed() -> Vec<std::path::PathBuf> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("results");
        let mut found = Vec::new();
        let mut stack = vec![root];
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).unwrap() {
                let p = entry.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else if p.file_name().is_some_and(|n| n == "sweep.json") {
                    found.push(p);
                }
            }
        }
        assert!(found.len() > 5, "the committed sweeps are found");
        found
    }

    #[test]
    fn committed_manifests_parse() {
        for p in committed() {
            let text = std::fs::read_to_string(&p).unwrap();
            parse_manifest(&text, &p.display().to_string()).unwrap_or_else(|e| panic!("{e}"));
        }
    }

    /// The committed `mip_mode` manifest as a JSON tree.
    fn good() -> serde_json::Value {
        committed_tree("mip_mode")
    }

    /// The committed manifest of sweep `name` as a JSON tree.
    fn committed_tree(name: &str) -> serde_json::Value {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("results/{name}/sweep.json"));
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    }

    /// Committed manifests for the mutation properties: one without `spec`, one with (a
    /// setting added, so its flattened parameters are there to mutate).
    fn seeds() -> [serde_json::Value; 2] {
        let mut with_spec = committed_tree("angles_texture");
        with_spec["spec"]["settings"] = serde_json::json!([{"label": "a", "lod0_distance": 30.0}]);
        [good(), with_spec]
    }

    fn error_of(text: &str) -> String {
        parse_manifest(text, "run/s/sweep.json")
            .map(|_| "accepted".to_string())
            .unwrap_or_else(|e| e.to_string())
    }

    #[test]
    fn nonsense_is_refused_naming_the_key_and_value() {
        let edit = |f: &dyn Fn(&mut serde_json::Value)| {
            let mut v = good();
            f(&mut v);
            error_of(&serde_json::to_string_pretty(&v).unwrap())
        };
        type Edit = fn(&mut serde_json::Value);
        let cases: Vec<(Edit, &[&str])> = vec![
            (
                (|v| v["width"] = 128.9.into()),
                &["key width: value \"128.9\"", "expected u32"],
            ),
            (
                (|v| v["height"] = (-1).into()),
                &["key height: value \"-1\"", "expected u32"],
            ),
            (
                (|v| v["width"] = 0.into()),
                &["key width: value \"0\"", "between 1 and 16384"],
            ),
            (
                (|v| v["frames"] = 1e30.into()),
                &["key frames", "expected usize"],
            ),
            (
                (|v| v["images"][0]["yaw_deg"] = 1e300.into()),
                &["key images[0].yaw_deg", "finite"],
            ),
            (
                (|v| v["images"][0]["accuracy"]["flip_mean"] = 7.into()),
                &[
                    "key images[0].accuracy.flip_mean: value \"7\"",
                    "between 0 and 1",
                ],
            ),
            (
                (|v| v["title"] = 5.into()),
                &["key title: value \"5\"", "expected a string"],
            ),
            (
                (|v| v["colour"] = "red".into()),
                &["key colour: value \"\\\"red\\\"\"", "unknown key"],
            ),
            (
                (|v| v["images"][0]["colour"] = "red".into()),
                &["key images[0].colour", "unknown key"],
            ),
            (
                (|v| v["wall_seconds"] = (-3.0).into()),
                &["key wall_seconds: value \"-3\"", "at least 0"],
            ),
            (
                (|v| v["shard"] = "3/2".into()),
                &["key shard: value \"3/2\"", "I/N"],
            ),
            ((|v| v["csv"] = "".into()), &["key csv", "not empty"]),
            (
                (|v| v["scenes"] = serde_json::json!([])),
                &["key scenes: value \"[]\""],
            ),
            (
                (|v| v["title"] = "a\u{1b}[31mred".into()),
                &["key title", "control characters"],
            ),
            (
                (|v| {
                    v.as_object_mut().unwrap().remove("name");
                }),
                &["missing field `name`"],
            ),
        ];
        for (f, want) in cases {
            let e = edit(&f);
            assert!(e.starts_with("run/s/sweep.json: "), "{e}");
            for w in want {
                assert!(e.contains(w), "{e:?} lacks {w:?}");
            }
        }
    }

    #[test]
    fn duplicate_keys_and_bad_syntax_are_refused_naming_line_and_key() {
        let text = serde_json::to_string_pretty(&good()).unwrap();
        // A duplicate top-level key (serde's struct check) and one inside a map (ours).
        let dup = format!("{{\n\"width\": 64,{}", &text[1..]);
        let e = error_of(&dup);
        assert!(
            e.contains(": line ") && e.contains("duplicate key width"),
            "{e}"
        );
        let mut v = good();
        v["spec"] = serde_json::json!({"settings": [{"label": "a", "lod0_distance": 1}]});
        let text = serde_json::to_string(&v).unwrap().replace(
            "\"lod0_distance\":1",
            "\"lod0_distance\":1,\"lod0_distance\":2",
        );
        let e = error_of(&text);
        assert!(
            e.contains("duplicate key spec.settings[0].lod0_distance"),
            "{e}"
        );
        let e = error_of("{\"name\": ");
        assert!(
            e.contains("line 1, column 9") && e.contains("is not JSON"),
            "{e}"
        );
        let e = error_of(&format!("{} x", serde_json::to_string(&good()).unwrap()));
        assert!(e.contains("trailing characters"), "{e}");
    }

    // -----------------------------------------------------------------------------------------
    // A little fuzzing on stable (the libFuzzer target is fuzz/fuzz_targets/sweep_json.rs, with
    // the same checks): no input panics; a refusal is one line naming the file; an accepted
    // manifest keeps the promises of the module docs and, written back, parses to itself.
    // -----------------------------------------------------------------------------------------

    use proptest::prelude::*;

    const FILE: &str = "run/s/sweep.json";

    fn check(text: &str) -> Result<(), TestCaseError> {
        match parse_manifest(text, FILE) {
            Ok(m) => {
                prop_assert!((1..=MAX_TARGET_SIZE).contains(&m.width));
                prop_assert!((1..=MAX_TARGET_SIZE).contains(&m.height));
                prop_assert!(!m.name.trim().is_empty() && !m.csv.trim().is_empty());
                prop_assert!(m.images.iter().all(|i| i.yaw_deg.is_finite()));
                let back = serde_json::to_string_pretty(&m).unwrap();
                let again = parse_manifest(&back, FILE);
                prop_assert!(again.is_ok(), "written back, refused: {:?}", again.err());
                prop_assert_eq!(
                    serde_json::to_value(again.unwrap()).unwrap(),
                    serde_json::to_value(&m).unwrap()
                );
            }
            Err(e) => {
                let shown = e.to_string();
                prop_assert!(shown.starts_with(FILE), "{}", shown);
                prop_assert_eq!(shown.lines().count(), 1, "{}", shown);
            }
        }
        Ok(())
    }

    /// JSON tokens and the manifest's own keys, more likely than raw text to reach the checks.
    fn token_soup() -> impl Strategy<Value = String> {
        let token = prop::sample::select(
            "{|}|[|]|,|:|\"name\"|\"title\"|\"width\"|\"height\"|\"csv\"|\"plots\"|\"images\"|\"accuracy\"|\"spec\"|\"settings\"|\"flip_mean\"|\"yaw_deg\"|\"shard\"|0|1|-1|128.9|1e300|1e400|-0|4294967296|18446744073709551616|null|true|false|\"\"|\"x\"|\"\\u0000\"|\"\\ud800\"|\"0/2\"| |\n"
                .split('|')
                .collect::<Vec<_>>(),
        );
        prop::collection::vec(token, 0..40).prop_map(|t| t.concat())
    }

    /// A JSON value to put somewhere in a good manifest.
    fn json_value() -> impl Strategy<Value = serde_json::Value> {
        prop::sample::select(vec![
            serde_json::json!(null),
            serde_json::json!(true),
            serde_json::json!(0),
            serde_json::json!(-1),
            serde_json::json!(0.5),
            serde_json::json!(128.9),
            serde_json::json!(1e300),
            serde_json::json!(4294967296u64),
            serde_json::json!(""),
            serde_json::json!("x"),
            serde_json::json!("../../etc/passwd"),
            serde_json::json!("a\u{7}b"),
            serde_json::json!([]),
            serde_json::json!(["a", "b"]),
            serde_json::json!({}),
            serde_json::json!({"k": 1}),
        ])
    }

    /// Every path (`a.b[0].c`) of a JSON tree, objects and arrays included.
    fn paths(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(map) => {
                for (k, x) in map {
                    let p = if at.is_empty() {
                        k.clone()
                    } else {
                        format!("{at}.{k}")
                    };
                    paths(x, p.clone(), out);
                    out.push(p);
                }
            }
            serde_json::Value::Array(items) => {
                for (i, x) in items.iter().enumerate() {
                    let p = format!("{at}[{i}]");
                    paths(x, p.clone(), out);
                    out.push(p);
                }
            }
            _ => {}
        }
    }

    /// The value at `path` of `v`, made if missing.
    fn at_path<'a>(v: &'a mut serde_json::Value, path: &str) -> &'a mut serde_json::Value {
        let mut cur = v;
        for part in path.split('.') {
            let (name, rest) = part.split_once('[').unwrap_or((part, ""));
            if !name.is_empty() {
                cur = &mut cur[name];
            }
            for index in rest.split('[').filter(|s| !s.is_empty()) {
                cur = &mut cur[index.trim_end_matches(']').parse::<usize>().unwrap()];
            }
        }
        cur
    }

    fn fuzz_cases() -> u32 {
        std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(256)
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: fuzz_cases(),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        #[test]
        fn arbitrary_text_never_panics(text in ".*") {
            check(&text)?;
        }

        #[test]
        fn token_soups_never_panic(text in token_soup()) {
            check(&text)?;
        }

        #[test]
        fn a_good_manifest_with_one_value_replaced_is_checked(
            seed in 0usize..2,
            pick in any::<prop::sample::Index>(),
            value in json_value(),
        ) {
            let mut tree = seeds()[seed].clone();
            let mut all = Vec::new();
            paths(&tree, String::new(), &mut all);
            let path = pick.get(&all).clone();
            *at_path(&mut tree, &path) = value;
            check(&serde_json::to_string_pretty(&tree).unwrap())?;
        }

        #[test]
        fn a_good_manifest_cut_or_spliced_is_checked(
            seed in 0usize..2,
            at in any::<prop::sample::Index>(),
            len in 0usize..20,
            insert in token_soup(),
        ) {
            let text = serde_json::to_string_pretty(&seeds()[seed]).unwrap();
            let start = at.index(text.len());
            let end = (start + len).min(text.len());
            if text.is_char_boundary(start) && text.is_char_boundary(end) {
                check(&format!("{}{insert}{}", &text[..start], &text[end..]))?;
            }
        }
    }
}
