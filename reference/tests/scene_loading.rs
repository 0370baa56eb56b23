//! File-based tests of the user-scene loaders (SPEC §4): scene files, CSV instance tables, OBJ meshes
//! and PNG textures, good and bad, plus property tests that no input bytes make a loader panic.

use std::path::{Path, PathBuf};

use forestlod_reference::scene::Terrain;
use forestlod_reference::scene::builtin::{self, Species};
use forestlod_reference::scene::load::{
    LoadOptions, UpAxis, decode_png_texture, load_instances_csv,
    load_instances_with_builtin_species, load_obj_mesh, load_path, load_path_with, load_scene_file,
    load_scene_file_with, parse_instances_csv, parse_obj_mesh, parse_scene_file,
};
use forestlod_reference::texture::Rgba8Image;
use proptest::prelude::*;

mod common;
use common::{CARD_POSITIONS, CARD_UVS, HEADER, crc32, gltf_json, write};

/// A fresh directory under the system temp dir, unique to this process and test.
fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir("scene-loading", test)
}

fn png(color: image::ExtendedColorType, channels: usize, w: u32, h: u32) -> Vec<u8> {
    use image::ImageEncoder;
    let mut data = vec![0u8; (w * h) as usize * channels];
    for (i, b) in data.iter_mut().enumerate() {
        *b = (i * 37 % 256) as u8;
    }
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&data, w, h, color)
        .unwrap();
    out
}

fn rgba_png(w: u32, h: u32) -> Vec<u8> {
    png(image::ExtendedColorType::Rgba8, 4, w, h)
}

/// A crossed-card tree: 2 quads = 4 triangles, Y up (as most exporters write).
const CARD_TREE_Y_UP: &str = "\
# crossed cards, Y up
o tree
v -2 0 0
v 2 0 0
v 2 8 0
v -2 8 0
v 0 0 -2
v 0 0 2
v 0 8 2
v 0 8 -2
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3 4/4
f 5/1 6/2 7/3 8/4
";

fn assert_mentions(e: &str, parts: &[&str]) {
    for p in parts {
        assert!(e.contains(p), "error {e:?} should mention {p:?}");
    }
}

#[test]
fn scene_file_with_builtin_and_obj_species_loads() {
    let dir = temp_dir("good");
    write(&dir, "card.obj", CARD_TREE_Y_UP);
    // Every species texture has species 0's size: the built-in spruce's.
    write(
        &dir,
        "card.png",
        rgba_png(builtin::TEXTURE_SIZE, builtin::TEXTURE_SIZE),
    );
    write(
        &dir,
        "trees.csv",
        format!(
            "{HEADER}500000.0,5300000.0,200.0,0.0,1.0,spruce\n\
             500100.0,5300050.0,210.0,1.5,0.8,card\n\
             500050.5,5300020.25,205.0,3.0,1.2,0\n"
        ),
    );
    let scene_path = write(
        &dir,
        "wachau.toml",
        "# a user scene\n\
         instances = \"trees.csv\"\n\
         [terrain]\n\
         kind = \"flat\"\n\
         z = 195.0\n\
         [[species]]\n\
         name = \"spruce\"\n\
         builtin = \"spruce\"\n\
         [[species]]\n\
         name = \"card\"\n\
         mesh = \"card.obj\"\n\
         texture = \"card.png\"\n\
         up = \"y\"\n",
    );
    let scene = load_scene_file(&scene_path).unwrap();
    assert_eq!(scene.name, "wachau");
    assert_eq!(scene.meshes.len(), 2);
    assert_eq!(scene.meshes[1].name, "card");
    assert_eq!(scene.meshes[1].indices.len(), 12);
    // Y-up OBJ: the card's top (OBJ y = 8) becomes z = 8.
    assert!(scene.meshes[1].positions.iter().any(|p| p[2] == 8.0));
    assert_eq!(scene.meshes[1].texture.width, builtin::TEXTURE_SIZE);
    // Default origin: centre of the bounding box, rounded to whole metres.
    assert_eq!(scene.origin, [500050.0, 5300025.0, 205.0]);
    assert_eq!(scene.instances.len(), 3);
    assert_eq!(scene.instances[0].position, [-50.0, -25.0, -5.0]);
    assert_eq!(scene.instances[2].position, [0.5, -4.75, 0.0]);
    assert_eq!(scene.instances[1].mesh, 1);
    assert_eq!(scene.instances[2].mesh, 0);
    assert_eq!(scene.terrain, Terrain::Flat { z: -10.0 });
    assert_eq!(scene.bounds, [-50.0, -25.0, 50.0, 25.0]);
    scene.validate("x").unwrap();
    assert_eq!(load_path(&scene_path).unwrap(), scene);
}

#[test]
fn scene_file_defaults_origin_hills_and_builtin_species() {
    let dir = temp_dir("defaults");
    write(&dir, "t.csv", format!("{HEADER}10,20,3,0,1,birch\n"));
    let path = write(
        &dir,
        "s.toml",
        "name = \"hilly\"\ninstances = \"t.csv\"\norigin = [0.0, 0.0, 0.0]\n\
         [terrain]\nkind = \"hills\"\namplitude = 25.0\nwavelength = 1500.0\n",
    );
    let scene = load_scene_file(&path).unwrap();
    assert_eq!(scene.name, "hilly");
    assert_eq!(scene.origin, [0.0; 3]);
    assert_eq!(scene.meshes.len(), 5);
    assert_eq!(scene.instances[0].mesh, Species::Birch as u32);
    assert_eq!(scene.instances[0].position, [10.0, 20.0, 3.0]);
    assert_eq!(scene.terrain, builtin::HILLS);
}

#[test]
fn bare_csv_uses_builtin_species() {
    let dir = temp_dir("bare");
    let path = write(
        &dir,
        "stand.csv",
        format!("{HEADER}1,1,0,0,1,oak\n3,1,0,0,1,poplar\n2,5,1,0,1,2\n"),
    );
    let scene = load_instances_with_builtin_species(&path).unwrap();
    assert_eq!(scene.name, "stand");
    assert_eq!(scene.meshes.len(), 5);
    assert_eq!(scene.origin, [2.0, 3.0, 1.0]);
    assert_eq!(scene.instances[1].mesh, Species::Poplar as u32);
    assert_eq!(scene.terrain, Terrain::Flat { z: -1.0 });
    assert_eq!(load_path(&path).unwrap(), scene);
}

#[test]
fn utm_coordinates_keep_decimetres_relative_to_the_origin() {
    let dir = temp_dir("utm");
    // 0.1 m steps at UTM northing: f32 world coordinates would lose them (spacing 0.5 m at 5.3e6).
    let mut csv = HEADER.to_string();
    for i in 0..10 {
        csv.push_str(&format!("512345.1,{}.{i},250,0,1,pine\n", 5_312_345));
    }
    let path = write(&dir, "utm.csv", csv);
    let scene = load_instances_with_builtin_species(&path).unwrap();
    let ys: Vec<f32> = scene.instances.iter().map(|t| t.position[1]).collect();
    for w in ys.windows(2) {
        assert!((w[1] - w[0] - 0.1).abs() < 1e-4, "{ys:?}");
    }
}

#[test]
fn bad_csv_files_give_errors_naming_file_line_column_and_value() {
    let dir = temp_dir("badcsv");
    let names: Vec<String> = vec!["spruce".into(), "oak".into()];
    let cases: &[(&str, String, &[&str])] = &[
        (
            "nan.csv",
            format!("{HEADER}1,2,3,0,1,oak\n1,NaN,3,0,1,oak\n"),
            &["nan.csv", "line 3", "column y", "NaN"],
        ),
        (
            "negscale.csv",
            format!("{HEADER}1,2,3,0,-0.5,oak\n"),
            &["negscale.csv", "line 2", "column scale", "-0.5"],
        ),
        (
            "species.csv",
            format!("{HEADER}1,2,3,0,1,maple\n"),
            &[
                "species.csv",
                "line 2",
                "column species",
                "maple",
                "spruce, oak",
            ],
        ),
        (
            "index.csv",
            format!("{HEADER}1,2,3,0,1,2\n"),
            &["index.csv", "line 2", "column species", "\"2\""],
        ),
        (
            "type.csv",
            format!("{HEADER}1,2,3,0,1,oak\n\n1,2,3,zero,1,oak\n"),
            &["type.csv", "line 4", "column yaw", "zero"],
        ),
        (
            "empty.csv",
            HEADER.to_string(),
            &["empty.csv", "line 2", "empty table"],
        ),
        ("nothing.csv", String::new(), &["nothing.csv", "empty file"]),
        (
            "count.csv",
            format!("{HEADER}1,2,3,0,1,oak,extra\n"),
            &["count.csv", "line 2", "column count", "extra"],
        ),
        (
            "missing.csv",
            "x,y,yaw,scale,species\n1,2,0,1,oak\n".to_string(),
            &["missing.csv", "line 1", "column z", "missing column"],
        ),
        (
            "inf.csv",
            format!("{HEADER}inf,2,3,0,1,oak\n"),
            &["inf.csv", "line 2", "column x", "inf"],
        ),
    ];
    for (name, text, expect) in cases {
        let path = write(&dir, name, text);
        let e = load_instances_csv(&path, &names).unwrap_err().to_string();
        assert_mentions(&e, expect);
    }
    let e = load_instances_csv(&dir.join("absent.csv"), &names)
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &["absent.csv", "cannot be read"]);
}

#[test]
fn bad_scene_files_give_errors_naming_file_line_field_and_value() {
    let dir = temp_dir("badtoml");
    write(&dir, "t.csv", format!("{HEADER}1,2,3,0,1,a\n"));
    write(&dir, "empty.csv", HEADER);
    write(&dir, "card.obj", CARD_TREE_Y_UP);
    write(&dir, "rgba.png", rgba_png(8, 8));
    write(
        &dir,
        "rgb.png",
        png(image::ExtendedColorType::Rgb8, 3, 8, 8),
    );
    write(&dir, "odd.png", rgba_png(12, 8));
    write(
        &dir,
        "bad_index.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 9/1\n",
    );
    let species_a = "[[species]]\nname = \"a\"\nbuiltin = \"oak\"\n";
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "unknown_key.toml",
            format!("instances = \"t.csv\"\ncolour = \"red\"\n{species_a}"),
            vec!["unknown_key.toml", "line 2", "colour"],
        ),
        (
            "wrong_type.toml",
            format!("instances = \"t.csv\"\norigin = \"abc\"\n{species_a}"),
            vec!["wrong_type.toml", "line 2", "abc"],
        ),
        (
            "nan_origin.toml",
            format!("instances = \"t.csv\"\norigin = [nan, 0.0, 0.0]\n{species_a}"),
            vec!["nan_origin.toml", "line 2", "field origin", "NaN"],
        ),
        (
            "no_instances.toml",
            species_a.to_string(),
            vec!["no_instances.toml", "instances"],
        ),
        (
            "bad_builtin.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nbuiltin = \"baobab\"\n".into(),
            vec![
                "bad_builtin.toml",
                "line 4",
                "species[0].builtin",
                "baobab",
                "spruce",
            ],
        ),
        (
            "dup.toml",
            format!("instances = \"t.csv\"\n{species_a}{species_a}"),
            vec!["dup.toml", "line 6", "species[1].name", "duplicate"],
        ),
        (
            "no_mesh.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\n".into(),
            vec!["no_mesh.toml", "species[0]", "builtin"],
        ),
        (
            "bad_terrain.toml",
            format!("instances = \"t.csv\"\n[terrain]\nkind = \"flat\"\nz = inf\n{species_a}"),
            vec!["bad_terrain.toml", "line 4", "terrain.z", "inf"],
        ),
        (
            "bad_kind.toml",
            format!("instances = \"t.csv\"\n[terrain]\nkind = \"mountains\"\n{species_a}"),
            vec!["bad_kind.toml", "line 3", "terrain.kind", "mountains"],
        ),
        (
            "flat_no_z.toml",
            format!("instances = \"t.csv\"\n[terrain]\nkind = \"flat\"\n{species_a}"),
            vec!["flat_no_z.toml", "line 2", "terrain.z", "missing"],
        ),
        (
            "flat_amplitude.toml",
            format!(
                "instances = \"t.csv\"\n[terrain]\nkind = \"flat\"\nz = 1.0\namplitude = 3.0\n{species_a}"
            ),
            vec!["flat_amplitude.toml", "line 5", "terrain.amplitude", "3", "not allowed"],
        ),
        (
            "bad_wavelength.toml",
            format!(
                "instances = \"t.csv\"\n[terrain]\nkind = \"hills\"\namplitude = 5.0\nwavelength = 0.0\n{species_a}"
            ),
            vec!["bad_wavelength.toml", "terrain.wavelength", "0"],
        ),
        (
            "missing_csv.toml",
            format!("instances = \"nope.csv\"\n{species_a}"),
            vec!["nope.csv", "cannot be read"],
        ),
        (
            "empty_instances.toml",
            format!("instances = \"empty.csv\"\n{species_a}"),
            vec!["empty.csv", "empty table"],
        ),
        (
            "csv_species.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"b\"\nbuiltin = \"oak\"\n".into(),
            vec!["t.csv", "line 2", "column species", "\"a\""],
        ),
        (
            "rgb.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"card.obj\"\ntexture = \"rgb.png\"\n".into(),
            vec!["rgb.png", "colour type", "value \"RGB, 8-bit, no transparency\"", "expected RGBA, 8-bit"],
        ),
        (
            "odd.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"card.obj\"\ntexture = \"odd.png\"\n".into(),
            vec!["odd.png", "width", "12", "power of two"],
        ),
        (
            "no_texture.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"card.obj\"\n".into(),
            vec!["no_texture.toml", "species[0].texture", "missing"],
        ),
        (
            "missing_png.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"card.obj\"\ntexture = \"gone.png\"\n".into(),
            vec!["gone.png", "cannot be read"],
        ),
        (
            "obj_index.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"bad_index.obj\"\ntexture = \"rgba.png\"\n".into(),
            vec![
                "obj_index.toml: line 4, column 8, field species[0].mesh = \"bad_index.obj\": ",
                "bad_index.obj",
                "line 5",
                "9/1",
                "out of range",
            ],
        ),
        (
            "both.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nbuiltin = \"oak\"\nmesh = \"card.obj\"\ntexture = \"rgba.png\"\n".into(),
            vec!["both.toml", "species[0].builtin", "either"],
        ),
        (
            "truncated.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nbuiltin = \"oa".into(),
            vec!["truncated.toml", "line 4"],
        ),
    ];
    for (name, text, expect) in &cases {
        let path = write(&dir, name, text);
        let e = load_scene_file(&path).unwrap_err().to_string();
        assert_mentions(&e, expect);
    }
    let e = load_scene_file(&dir.join("absent.toml"))
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &["absent.toml", "cannot be read"]);
    let garbage = write(&dir, "garbage.toml", [0xffu8, 0xfe, 0x00, 0x41]);
    let e = load_scene_file(&garbage).unwrap_err().to_string();
    assert_mentions(&e, &["garbage.toml", "line 1", "UTF-8"]);
    let e = load_path(&dir.join("scene.json")).unwrap_err().to_string();
    assert_mentions(&e, &["scene.json", "extension", "json"]);
}

#[test]
fn obj_files_are_checked() {
    let dir = temp_dir("obj");
    let tex = write(&dir, "t.png", rgba_png(4, 4));
    let good = write(&dir, "good.obj", CARD_TREE_Y_UP);
    let m = load_obj_mesh("card", &good, &tex, UpAxis::Z).unwrap();
    assert_eq!(m.indices.len() / 3, 4);
    let nan = write(&dir, "nan.obj", "v 0 0 0\nv 1 NaN 0\n");
    let e = load_obj_mesh("t", &nan, &tex, UpAxis::Z)
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &["nan.obj", "line 2", "NaN"]);
    let neg = write(
        &dir,
        "neg.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf -1/1 -2/1 -4/1\n",
    );
    let e = load_obj_mesh("t", &neg, &tex, UpAxis::Z)
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &["neg.obj", "line 5", "-4/1", "out of range"]);
    let e = load_obj_mesh("t", &dir.join("none.obj"), &tex, UpAxis::Z)
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &["none.obj", "cannot be read"]);
    // Relative indices that are in range work.
    let rel = write(
        &dir,
        "rel.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf -3/-3 -2/-2 -1/-1\n",
    );
    assert_eq!(
        load_obj_mesh("t", &rel, &tex, UpAxis::Z)
            .unwrap()
            .indices
            .len(),
        3
    );
}

#[test]
fn every_builtin_loads_valid_and_deterministic() {
    for name in builtin::BUILTIN_NAMES {
        if *name == "stress" || *name == "patchy" {
            continue; // covered by the library's own tests (1.47M trees; patchy thins stress)
        }
        let a = builtin::by_name(name).unwrap();
        a.validate(name).unwrap();
        assert_eq!(a, builtin::by_name(name).unwrap(), "{name}");
        for m in &a.meshes {
            assert!(m.indices.len() / 3 < 20);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Property tests: no bytes make a loader panic.
// ---------------------------------------------------------------------------------------------

fn names() -> Vec<String> {
    Species::ALL.iter().map(|s| s.name().to_string()).collect()
}

/// `|`-separated tokens, in order (the empty string included), for `prop::sample::select`.
fn tokens(list: &'static str) -> Vec<&'static str> {
    list.split('|').collect()
}

/// Lines of CSV-ish tokens: more likely than raw bytes to reach the row checks.
fn csv_like() -> impl Strategy<Value = String> {
    let token = prop::sample::select(tokens(
        "x|y|z|yaw|scale|species|0|1|-1|1e308|1e39|NaN|inf|-inf|oak|4|5|abc||\"|\"a,b\"| |0.5|4294967296|\u{feff}x",
    ));
    let row = prop::collection::vec(token, 0..8).prop_map(|t| t.join(","));
    prop::collection::vec(row, 0..6).prop_map(|rows| rows.join("\n"))
}

/// Lines of OBJ-ish tokens.
fn obj_like() -> impl Strategy<Value = String> {
    let token = prop::sample::select(tokens(
        "v|vt|vn|f|l|p|o|g|s|usemtl|mtllib|#|0|1|2|3|-1|-9|1/1|2/2|3/3|1//1|1/1/1|1/0|0/1|-1/-1|9223372036854775807|-9223372036854775808|nan|inf|1e40|0.5|x|/|//|1/2/3/4|\u{3000}",
    ));
    let line = prop::collection::vec(token, 0..7).prop_map(|t| t.join(" "));
    prop::collection::vec(line, 0..24).prop_map(|lines| lines.join("\n"))
}

/// Scene files built from plausible and implausible pieces.
fn toml_like() -> impl Strategy<Value = String> {
    let piece = prop::sample::select(vec![
        "instances = \"t.csv\"\n",
        "instances = \"missing.csv\"\n",
        "instances = 3\n",
        "name = \"n\"\n",
        "name = \"\"\n",
        "origin = [0.0, 0.0, 0.0]\n",
        "origin = [nan, 1.0, 2.0]\n",
        "origin = [1.0]\n",
        "[terrain]\nkind = \"flat\"\nz = 1.0\n",
        "[terrain]\nkind = \"hills\"\namplitude = 1e300\nwavelength = -1.0\n",
        "[terrain]\nkind = \"cliff\"\n",
        "[[species]]\nname = \"a\"\nbuiltin = \"oak\"\n",
        "[[species]]\nname = \"b\"\nbuiltin = \"none\"\n",
        "[[species]]\nname = \"c\"\nmesh = \"m.obj\"\ntexture = \"t.png\"\n",
        "[[species]]\nname = \"d\"\nmesh = \"m.obj\"\n",
        "[[species]]\n",
        "up = \"x\"\n",
        "extra = 1\n",
        "[",
        "\"",
    ]);
    prop::collection::vec(piece, 0..8).prop_map(|p| p.concat())
}

fn tex() -> Rgba8Image {
    Rgba8Image::new(4, 4, [1, 2, 3, 4])
}

/// Cases per byte-fuzzing property: 256, or `PROPTEST_CASES` when set (a long fuzzing run:
/// `PROPTEST_CASES=20000 cargo test --release -p forestlod-reference --test scene_loading`).
fn fuzz_cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(256)
}

/// The byte-fuzzing properties' configuration: `fuzz_cases()` cases, no persisted failures.
fn fuzz_config() -> ProptestConfig {
    ProptestConfig {
        cases: fuzz_cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(fuzz_config())]

    #[test]
    fn csv_loader_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_instances_csv(&bytes[..], "fuzz.csv", &names());
    }

    #[test]
    fn csv_loader_never_panics_on_csv_like_text(text in csv_like()) {
        match parse_instances_csv(text.as_bytes(), "fuzz.csv", &names()) {
            Ok(rows) => {
                prop_assert!(!rows.is_empty());
                for r in rows {
                    prop_assert!(r.scale > 0.0 && r.scale.is_finite() && r.yaw.is_finite());
                    prop_assert!(r.position.iter().all(|c| c.is_finite()));
                    prop_assert!(r.mesh < 5);
                }
            }
            Err(e) => prop_assert!(e.to_string().contains("fuzz.csv")),
        }
    }

    #[test]
    fn obj_loader_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_obj_mesh("fuzz", &bytes, "fuzz.obj", UpAxis::Z, tex());
    }

    #[test]
    fn obj_loader_never_panics_on_obj_like_text(text in obj_like()) {
        if let Ok(mesh) = parse_obj_mesh("fuzz", text.as_bytes(), "fuzz.obj", UpAxis::Y, tex()) {
            prop_assert!(mesh.validate("fuzz.obj").is_ok());
        }
    }

    #[test]
    fn toml_loader_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let dir = std::env::temp_dir().join("forestlod-scene-loading-fuzz-nonexistent");
        let _ = parse_scene_file(&bytes, &dir.join("fuzz.toml"));
    }

    #[test]
    fn png_decoder_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = decode_png_texture(&bytes, "fuzz.png");
    }
}

#[test]
fn toml_loader_never_panics_on_scene_like_text() {
    // A fixed directory with a good CSV, OBJ and PNG so that generated scene files reach the loaders.
    let dir = fuzz_dir("toml-fuzz");
    let path = dir.join("fuzz.toml");
    let mut runner = proptest::test_runner::TestRunner::new(fuzz_config());
    runner
        .run(&toml_like(), |text| {
            match parse_scene_file(text.as_bytes(), &path) {
                Ok(scene) => prop_assert!(scene.validate("fuzz").is_ok()),
                Err(e) => prop_assert!(!e.to_string().is_empty()),
            }
            Ok(())
        })
        .unwrap();
}

// ---------------------------------------------------------------------------------------------
// Structure-aware PNG fuzzing and the whole file path (brief "Bad input and fuzzing").
// ---------------------------------------------------------------------------------------------

/// Recomputes the CRC of every chunk whose length field fits the data, so that mutations reach
/// the decoder's parsing instead of stopping at its checksum test.
fn fix_crcs(png: &mut [u8]) {
    let mut at = 8; // signature
    while at + 12 <= png.len() {
        let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        let Some(end) = (at + 8).checked_add(len) else {
            return;
        };
        if end + 4 > png.len() {
            return;
        }
        let crc = crc32(&png[at + 4..end]);
        png[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
}

/// A valid RGBA8 PNG of side `side` (IHDR width at bytes 16..20, height at 20..24).
fn valid_png(side: u32) -> Vec<u8> {
    rgba_png(side, side)
}

/// A valid PNG whose IHDR declares `width` x `height` (CRC fixed), its data unchanged.
fn png_declaring(width: u32, height: u32) -> Vec<u8> {
    let mut png = valid_png(4);
    png[16..20].copy_from_slice(&width.to_be_bytes());
    png[20..24].copy_from_slice(&height.to_be_bytes());
    fix_crcs(&mut png);
    png
}

#[test]
fn png_with_huge_or_lying_dimensions_is_rejected_cleanly() {
    // Declared larger than allowed: rejected from the header, before any allocation.
    for (w, h, what) in [
        (1 << 30, 1 << 30, "width"),
        (u32::MAX, 4, "width"),
        (4, 8192, "height"),
        (0, 4, "file"),
    ] {
        let e = decode_png_texture(&png_declaring(w, h), "huge.png")
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["huge.png", what]);
    }
    // Declared within limits but the data holds 4x4 texels: the decoder runs out of data.
    for side in [8u32, 4096] {
        let e = decode_png_texture(&png_declaring(side, side), "lying.png")
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["lying.png", "invalid PNG"]);
    }
    // Every truncation of a valid PNG is an error naming the file, or (cut inside the trailing
    // IEND chunk, after all image data) the complete image: never a partial one.
    let full = valid_png(8);
    let whole = decode_png_texture(&full, "cut.png").unwrap();
    let mut accepted = 0;
    for cut in 0..full.len() {
        match decode_png_texture(&full[..cut], "cut.png") {
            Ok(t) => {
                assert!(
                    cut >= full.len() - 12,
                    "cut at {cut} of {} accepted",
                    full.len()
                );
                assert_eq!(t, whole, "cut at {cut}");
                accepted += 1;
            }
            Err(e) => assert!(e.to_string().starts_with("cut.png"), "cut at {cut}: {e}"),
        }
    }
    assert!(accepted <= 12);
}

/// A directory with a good CSV, OBJ and PNG beside the generated scene files.
fn fuzz_dir(test: &str) -> PathBuf {
    let dir = temp_dir(test);
    write(&dir, "t.csv", format!("{HEADER}1,2,3,0,1,0\n"));
    write(&dir, "m.obj", CARD_TREE_Y_UP);
    write(&dir, "t.png", rgba_png(4, 4));
    dir
}

proptest! {
    #![proptest_config(fuzz_config())]

    /// Mutated valid PNGs (bytes overwritten, then every chunk CRC fixed, then optionally cut)
    /// never panic the decoder, and what it accepts is a square power-of-two RGBA8 texture.
    #[test]
    fn png_decoder_never_panics_on_mutated_pngs(
        side in prop::sample::select(vec![1u32, 2, 4, 8, 16]),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in prop::option::of(any::<prop::sample::Index>()),
    ) {
        let mut png = valid_png(side);
        for (at, byte) in &edits {
            let i = 8 + at.index(png.len() - 8);
            png[i] = *byte;
        }
        fix_crcs(&mut png);
        if let Some(cut) = cut {
            png.truncate(cut.index(png.len() + 1));
        }
        match decode_png_texture(&png, "mutated.png") {
            Ok(t) => {
                prop_assert!(t.width == t.height && t.width.is_power_of_two() && t.width <= 4096);
                prop_assert_eq!(t.texels.len(), (t.width * t.height) as usize);
            }
            Err(e) => prop_assert!(e.to_string().starts_with("mutated.png")),
        }
    }

    /// The whole file path: arbitrary bytes as a scene file on disk, as an instance table on disk
    /// and as an OBJ/PNG pair named by a good scene file never panic `load_scene_file`,
    /// `load_path` or `load_instances_with_builtin_species`; what they accept validates.
    #[test]
    fn file_loaders_never_panic_on_bytes(
        bytes in prop::collection::vec(any::<u8>(), 0..1024),
        which in 0u8..4,
    ) {
        let dir = fuzz_dir("file-fuzz");
        let result = match which {
            0 => load_scene_file(&write(&dir, "fuzz.toml", &bytes)),
            1 => load_path(&write(&dir, "fuzz.csv", &bytes)),
            2 => {
                write(&dir, "fuzz.obj", &bytes);
                load_scene_file(&write(&dir, "s.toml", "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"fuzz.obj\"\ntexture = \"t.png\"\n"))
            }
            _ => {
                write(&dir, "fuzz.png", &bytes);
                load_scene_file(&write(&dir, "s.toml", "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"m.obj\"\ntexture = \"fuzz.png\"\n"))
            }
        };
        match result {
            Ok(scene) => prop_assert!(scene.validate("fuzz").is_ok()),
            Err(e) => prop_assert!(!e.to_string().contains('\n'), "one-line error: {e}"),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Issue 10 ("failures that fail"): texture sizes, error chains, path confinement, PNG colour
// types, concave polygons, glTF meshes.
// ---------------------------------------------------------------------------------------------

/// A scene file with one OBJ species per `(mesh, texture)`, instances in `t.csv`.
fn species_scene(dir: &Path, name: &str, species: &[(&str, &str)]) -> PathBuf {
    let mut text = String::from("instances = \"t.csv\"\n");
    for (i, (mesh, texture)) in species.iter().enumerate() {
        text.push_str(&format!(
            "[[species]]\nname = \"s{i}\"\nmesh = \"{mesh}\"\ntexture = \"{texture}\"\n"
        ));
    }
    write(dir, "t.csv", format!("{HEADER}1,2,3,0,1,0\n"));
    write(dir, name, text)
}

#[test]
fn species_textures_must_share_species_0s_size() {
    let dir = temp_dir("texsize");
    write(&dir, "card.obj", CARD_TREE_Y_UP);
    write(&dir, "small.png", rgba_png(8, 8));
    write(&dir, "big.png", rgba_png(16, 16));
    let ok = species_scene(
        &dir,
        "ok.toml",
        &[("card.obj", "small.png"), ("card.obj", "small.png")],
    );
    assert_eq!(load_scene_file(&ok).unwrap().meshes.len(), 2);
    let bad = species_scene(
        &dir,
        "bad.toml",
        &[("card.obj", "small.png"), ("card.obj", "big.png")],
    );
    let e = load_scene_file(&bad).unwrap_err().to_string();
    assert_mentions(
        &e,
        &[
            "bad.toml",
            "line 9",
            "species[1].texture",
            "\"big.png\" is 16x16",
            "species[0] texture \"small.png\" is 8x8",
            "square size",
        ],
    );
    // A built-in species (128²) beside a smaller user texture.
    write(
        &dir,
        "mixed.toml",
        "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nbuiltin = \"oak\"\n[[species]]\nname = \"b\"\nmesh = \"card.obj\"\ntexture = \"small.png\"\n",
    );
    let e = load_scene_file(&dir.join("mixed.toml"))
        .unwrap_err()
        .to_string();
    assert_mentions(
        &e,
        &[
            "mixed.toml",
            "species[1].texture",
            "8x8",
            "built-in \"oak\" is 128x128",
        ],
    );
}

#[test]
fn errors_in_named_files_print_the_chain_from_the_scene_file() {
    let dir = temp_dir("chain");
    write(&dir, "t.png", rgba_png(8, 8));
    write(
        &dir,
        "bad.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 99/1\n",
    );
    let scene = species_scene(&dir, "forest.toml", &[("bad.obj", "t.png")]);
    let e = load_scene_file(&scene).unwrap_err();
    assert_eq!(e.chain.len(), 1, "{e}");
    let shown = e.to_string();
    let scene_label = scene.display().to_string();
    assert!(
        shown.starts_with(&format!(
            "{scene_label}: line 4, column 8, field species[0].mesh = \"bad.obj\": "
        )),
        "{shown}"
    );
    assert_mentions(
        &shown,
        &["bad.obj: line 5, face: value \"99/1\"", "out of range"],
    );
    // The texture's chain, the CSV's chain.
    write(
        &dir,
        "rgb.png",
        png(image::ExtendedColorType::Rgb8, 3, 8, 8),
    );
    write(&dir, "card.obj", CARD_TREE_Y_UP);
    let scene = species_scene(&dir, "tex.toml", &[("card.obj", "rgb.png")]);
    let e = load_scene_file(&scene).unwrap_err().to_string();
    assert_mentions(
        &e,
        &[
            "field species[0].texture = \"rgb.png\": ",
            "rgb.png: colour type",
        ],
    );
    write(&dir, "nan.csv", format!("{HEADER}1,2,nan,0,1,0\n"));
    write(&dir, "csv.toml", "instances = \"nan.csv\"\n");
    let e = load_scene_file(&dir.join("csv.toml"))
        .unwrap_err()
        .to_string();
    assert_mentions(
        &e,
        &[
            "csv.toml: line 1, column 13, field instances = \"nan.csv\": ",
            "nan.csv: line 2, column z",
        ],
    );
}

#[test]
fn scene_files_may_name_only_files_under_their_folder_unless_allowed() {
    let dir = temp_dir("confine");
    let sub = dir.join("scene");
    std::fs::create_dir_all(&sub).unwrap();
    write(&dir, "card.obj", CARD_TREE_Y_UP);
    write(&dir, "t.png", rgba_png(8, 8));
    write(&sub, "t.png", rgba_png(8, 8));
    write(&dir, "outside.csv", format!("{HEADER}1,2,3,0,1,0\n"));
    write(&sub, "t.csv", format!("{HEADER}1,2,3,0,1,0\n"));
    let allow = LoadOptions {
        allow_outside_paths: true,
    };
    // `..` out of the folder.
    let scene = write(
        &sub,
        "up.toml",
        "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"../card.obj\"\ntexture = \"t.png\"\n",
    );
    let e = load_scene_file(&scene).unwrap_err().to_string();
    assert_mentions(
        &e,
        &[
            "up.toml",
            "line 4",
            "species[0].mesh",
            "\"../card.obj\"",
            "outside the scene file's folder",
            "--allow-outside-paths",
        ],
    );
    assert!(load_scene_file_with(&scene, &allow).is_ok());
    assert!(load_path_with(&scene, &allow).is_ok());
    // An absolute path, and the instance table.
    let abs = dir.join("outside.csv").display().to_string();
    let scene = write(&sub, "abs.toml", format!("instances = {abs:?}\n"));
    let e = load_scene_file(&scene).unwrap_err().to_string();
    assert_mentions(
        &e,
        &[
            "abs.toml",
            "field instances",
            "outside the scene file's folder",
        ],
    );
    assert!(load_scene_file_with(&scene, &allow).is_ok());
    // A symbolic link inside the folder that points out of it.
    #[cfg(unix)]
    {
        let _ = std::fs::remove_file(sub.join("link.obj"));
        std::os::unix::fs::symlink(dir.join("card.obj"), sub.join("link.obj")).unwrap();
        let scene = write(
            &sub,
            "link.toml",
            "instances = \"t.csv\"\n[[species]]\nname = \"a\"\nmesh = \"link.obj\"\ntexture = \"t.png\"\n",
        );
        let e = load_scene_file(&scene).unwrap_err().to_string();
        assert_mentions(
            &e,
            &[
                "link.toml",
                "\"link.obj\"",
                "outside the scene file's folder",
            ],
        );
        assert!(load_scene_file_with(&scene, &allow).is_ok());
    }
    // Inside, through `..` that comes back: fine.
    let scene = write(&sub, "back.toml", "instances = \"../scene/t.csv\"\n");
    assert!(load_scene_file(&scene).is_ok());
}

#[test]
fn png_colour_types_are_named_as_the_file_has_them() {
    for (color, channels, shown) in [
        (
            image::ExtendedColorType::Rgb8,
            3,
            "RGB, 8-bit, no transparency",
        ),
        (
            image::ExtendedColorType::L8,
            1,
            "grey, 8-bit, no transparency",
        ),
        (image::ExtendedColorType::La8, 2, "grey+alpha, 8-bit"),
        (image::ExtendedColorType::Rgba16, 8, "RGBA, 16-bit"),
        (
            image::ExtendedColorType::L16,
            2,
            "grey, 16-bit, no transparency",
        ),
    ] {
        let e = decode_png_texture(&png(color, channels, 4, 4), "t.png")
            .unwrap_err()
            .to_string();
        assert_mentions(
            &e,
            &[
                "t.png: colour type",
                &format!("value \"{shown}\""),
                "expected RGBA, 8-bit",
            ],
        );
        assert!(!e.contains("Rgb") && !e.contains("L8"), "{e}");
    }
}

#[test]
fn concave_polygons_are_ear_clipped_and_bad_ones_rejected() {
    let tex = || Rgba8Image::new(4, 4, [1, 2, 3, 255]);
    // An L-shaped hexagon (area 3) in the x/z plane, starting beside its reflex corner: the fan
    // from vertex 0 would cover the missing square.
    let l_shape =
        "v 2 0 1\nv 1 0 1\nv 1 0 2\nv 0 0 2\nv 0 0 0\nv 2 0 0\nvt 0 0\nf 1/1 2/1 3/1 4/1 5/1 6/1\n";
    let m = parse_obj_mesh("l", l_shape.as_bytes(), "l.obj", UpAxis::Z, tex()).unwrap();
    assert_eq!(m.indices.len(), 12);
    let area: f32 = m
        .indices
        .chunks(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
            // Signed area in the x/z plane: the polygon's winding is kept.
            0.5 * ((b[0] - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (b[2] - a[2]))
        })
        .sum();
    assert!((area - 3.0).abs() < 1e-5, "area {area}");
    // Every triangle lies inside the L: its centroid is not in the missing square (1,2)x(1,2).
    for t in m.indices.chunks(3) {
        let c = [0, 2].map(|k| t.iter().map(|&i| m.positions[i as usize][k]).sum::<f32>() / 3.0);
        assert!(
            !(c[0] > 1.0 && c[1] > 1.0),
            "triangle {t:?} outside the polygon"
        );
    }
    // A convex quad keeps the fan (0,1,2),(0,2,3), exactly as before.
    let quad = "v -1 0 0\nv 1 0 0\nv 1 0 2\nv -1 0 2\nvt 0 0\nf 1/1 2/1 3/1 4/1\n";
    let m = parse_obj_mesh("q", quad.as_bytes(), "q.obj", UpAxis::Z, tex()).unwrap();
    assert_eq!(m.indices, [0, 1, 2, 0, 2, 3]);
    let bad = |text: &str| {
        parse_obj_mesh("b", text.as_bytes(), "b.obj", UpAxis::Z, tex())
            .unwrap_err()
            .to_string()
    };
    let e = bad("v 0 0 0\nv 1 0 1\nv 1 0 0\nv 0 0 1\nvt 0 0\nf 1/1 2/1 3/1 4/1\n");
    assert_mentions(&e, &["b.obj", "line 6, face", "self-intersecting"]);
    let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 1\nv 0 0 1\nvt 0 0\n# c\nf 1/1 2/1 3/1 4/1\n");
    assert_mentions(&e, &["line 7, face", "non-planar"]);
    let e = bad("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\n");
    assert_mentions(&e, &["line 6, face", "zero-area"]);
}

#[test]
fn gltf_meshes_load_and_bad_ones_are_rejected() {
    let dir = temp_dir("gltf");
    write(&dir, "t.png", rgba_png(8, 8));
    write(
        &dir,
        "card.gltf",
        gltf_json(&CARD_POSITIONS, &CARD_UVS, &[0, 1, 2, 0, 2, 3], 4),
    );
    let scene = species_scene(&dir, "s.toml", &[("card.gltf", "t.png")]);
    let s = load_scene_file(&scene).unwrap();
    let m = &s.meshes[0];
    assert_eq!(m.indices, [0, 1, 2, 0, 2, 3]);
    // glTF is Y up: (1, 2, 0) becomes (1, 0, 2); UVs are top-left already.
    assert_eq!(m.positions[2], [1.0, 0.0, 2.0]);
    assert_eq!(m.uvs[2], [1.0, 0.0]);
    // The same mesh through a .glb holding the JSON and a binary chunk.
    let json = gltf_json(&CARD_POSITIONS, &CARD_UVS, &[0, 1, 2, 0, 2, 3], 4);
    let mut json_bytes = json.into_bytes();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut glb = b"glTF".to_vec();
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&((12 + 8 + json_bytes.len()) as u32).to_le_bytes());
    glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json_bytes);
    write(&dir, "card.glb", glb);
    let scene = species_scene(&dir, "glb.toml", &[("card.glb", "t.png")]);
    assert_eq!(
        load_scene_file(&scene).unwrap().meshes[0].positions,
        m.positions
    );

    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "range.gltf",
            gltf_json(&CARD_POSITIONS, &CARD_UVS, &[0, 1, 9], 4),
            vec![
                "range.gltf: mesh 0, primitive 0, indices element 2: value \"9\"",
                "out of range (4 vertices)",
            ],
        ),
        (
            "lines.gltf",
            gltf_json(&CARD_POSITIONS, &CARD_UVS, &[0, 1, 2], 1),
            vec![
                "lines.gltf: mesh 0, primitive 0, mode: value \"LINES (1)\"",
                "triangle list",
            ],
        ),
        (
            "nan.gltf",
            gltf_json(
                &[[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]],
                &CARD_UVS[..3],
                &[0, 1, 2],
                4,
            ),
            vec![
                "nan.gltf: mesh 0, primitive 0, POSITION element 0",
                "NaN",
                "finite",
            ],
        ),
        (
            "uvs.gltf",
            gltf_json(&CARD_POSITIONS, &CARD_UVS[..3], &[0, 1, 2], 4),
            vec![
                "uvs.gltf",
                "TEXCOORD_0",
                "3 texture coordinates for 4 vertices",
            ],
        ),
        (
            "json.gltf",
            "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [".into(),
            vec!["json.gltf: file", "invalid glTF 2.0"],
        ),
        (
            "nomesh.gltf",
            "{\"asset\": {\"version\": \"2.0\"}}".into(),
            vec![
                "nomesh.gltf: meshes: value \"0 meshes\"",
                "exactly one mesh",
            ],
        ),
    ];
    for (name, text, expect) in &cases {
        write(&dir, name, text);
        let scene = species_scene(&dir, &format!("{name}.toml"), &[(name, "t.png")]);
        let e = load_scene_file(&scene).unwrap_err().to_string();
        assert_mentions(&e, &[&format!("field species[0].mesh = \"{name}\": ")]);
        assert_mentions(&e, expect);
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    // A mesh file where a scene is expected says what to write.
    let e = load_path(&dir.join("card.gltf")).unwrap_err().to_string();
    assert_mentions(&e, &["card.gltf", "[[species]]", "mesh = "]);
}

#[test]
fn errors_echo_at_most_a_short_marked_excerpt_of_file_content() {
    let dir = temp_dir("excerpt");
    let long = "z".repeat(5000);
    write(&dir, "long.csv", format!("{HEADER}1,2,3,0,1,{long}\n"));
    let e = load_instances_with_builtin_species(&dir.join("long.csv"))
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &[&format!("\"{}…\"", "z".repeat(40))]);
    assert!(!e.contains(&"z".repeat(41)), "{e}");
    write(
        &dir,
        "long.toml",
        format!("instances = \"t.csv\"\norigin = \"{long}\"\n"),
    );
    let e = load_scene_file(&dir.join("long.toml"))
        .unwrap_err()
        .to_string();
    assert!(!e.contains(&"z".repeat(41)) && e.contains('…'), "{e}");
    write(&dir, "long.obj", format!("v 1 2 {long}\n"));
    let e = parse_obj_mesh(
        "t",
        format!("o {long}\nv 1 2 3\n").as_bytes(),
        "o.obj",
        UpAxis::Z,
        Rgba8Image::new(1, 1, [0; 4]),
    )
    .unwrap_err()
    .to_string();
    assert!(!e.contains(&"z".repeat(41)), "{e}");
}

/// Special files are refused before they are opened, at every file the loaders read (issue 28):
/// a FIFO (opening it would block until a writer came), a link to `/dev/zero` (a read that never
/// ends) and a folder, as a scene file, an instance table, an OBJ mesh and a PNG texture, each
/// with one error naming the file. Each case runs on a thread with a deadline, so a loader that
/// blocks fails the test instead of hanging it.
#[cfg(unix)]
#[test]
fn special_files_are_refused_naming_the_file() {
    use std::sync::mpsc;
    use std::time::Duration;
    let dir = temp_dir("special-files");
    let fifo = dir.join("pipe");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo (coreutils) runs");
    assert!(made.success(), "mkfifo {}", fifo.display());
    let zero = dir.join("zero");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let folder = dir.join("folder");
    std::fs::create_dir_all(&folder).unwrap();
    type Loader = fn(&Path) -> Result<(), String>;
    let loaders: [(&str, Loader); 4] = [
        ("scene", |p| {
            load_scene_file(p).map(|_| ()).map_err(|e| e.to_string())
        }),
        ("instances", |p| {
            load_instances_csv(p, &["oak".to_string()])
                .map(|_| ())
                .map_err(|e| e.to_string())
        }),
        ("obj", |p| {
            load_obj_mesh("oak", p, p, UpAxis::Z)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }),
        ("png", |p| {
            forestlod_reference::scene::load::load_png_texture(p)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }),
    ];
    for (kind, load) in loaders {
        for (path, what) in [
            (&fifo, "special file"),
            (&zero, "special file"),
            (&folder, "folder"),
        ] {
            let (tx, rx) = mpsc::channel();
            let p = path.clone();
            std::thread::spawn(move || {
                let _ = tx.send(load(&p));
            });
            let got = rx
                .recv_timeout(Duration::from_secs(10))
                .unwrap_or_else(|_| {
                    panic!("{kind} loader on {}: no answer in 10 s", path.display())
                });
            let e = got.expect_err(&format!("{kind} loader accepted {}", path.display()));
            assert_mentions(
                &e,
                &[&path.display().to_string(), what, "not a regular file"],
            );
        }
    }
}
