//! Bad input through the `forestlod` command line (SPEC §4 "every loader validates"; brief "Bad
//! input"): truncated, empty, enormous, NaN-filled and wrongly typed scene files, CSVs, OBJ meshes
//! and PNG textures, and impossible parameter flags. Each must
//! - exit with status **1**;
//! - print exactly **one line** to stderr, starting with `error:`, naming the file (or flag), the
//!   position and the value;
//! - never panic (`panicked` absent);
//! - leave the output folder as it was: absent stays absent, an existing one keeps exactly its
//!   files and their contents (the render computes everything before it writes anything).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

#[path = "../../reference/tests/common/mod.rs"]
mod common;
use common::{HEADER, crc32, gltf_card, write};

/// A fresh directory for one case.
fn case_dir(name: &str) -> PathBuf {
    common::fresh_dir("cli-bad-input", name)
}

/// Every file under `dir` with its contents (empty when `dir` is absent).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in entries {
        let path = e.unwrap().path();
        if path.is_dir() {
            out.extend(snapshot(&path));
        } else {
            out.insert(path.clone(), std::fs::read(&path).unwrap());
        }
    }
    out
}

/// Runs `forestlod` in `dir` with `args` (plus `--out <out>` for `render`, at a small viewport)
/// and checks the contract of the module docs, twice: once with the output folder absent and once
/// with it holding a file from an earlier run. `expect` are substrings of the error line.
fn assert_rejected(dir: &Path, args: &[&str], expect: &[&str]) {
    for existing in [false, true] {
        let out = dir.join(if existing {
            "out-existing"
        } else {
            "out-absent"
        });
        let _ = std::fs::remove_dir_all(&out);
        if existing {
            std::fs::create_dir_all(&out).unwrap();
            std::fs::write(out.join("color.png"), b"an earlier run").unwrap();
        }
        let before = snapshot(&out);
        let mut all: Vec<&str> = args.to_vec();
        let out_str = out.to_str().unwrap().to_string();
        if args.first() == Some(&"render") {
            all.extend(["--width", "32", "--height", "32", "--out", &out_str]);
        }
        let output = Command::new(env!("CARGO_BIN_EXE_forestlod"))
            .args(&all)
            .current_dir(dir)
            .env("RUST_BACKTRACE", "0")
            .output()
            .expect("run forestlod");
        let stderr = String::from_utf8_lossy(&output.stderr);
        let what = format!("forestlod {}", all.join(" "));
        assert_eq!(output.status.code(), Some(1), "{what}: stderr {stderr:?}");
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(
            lines.len(),
            1,
            "{what}: stderr must be one line: {stderr:?}"
        );
        assert!(lines[0].starts_with("error:"), "{what}: {stderr:?}");
        for e in expect {
            assert!(
                lines[0].contains(e),
                "{what}: error {:?} should mention {e:?}",
                lines[0]
            );
        }
        assert_eq!(
            out.exists(),
            existing,
            "{what}: output folder created or removed"
        );
        assert_eq!(snapshot(&out), before, "{what}: output folder changed");
    }
}

/// A crossed-card tree in OBJ (4 triangles, Z up).
/// Writes `contents` to the CSV file that the error must name first (`expect[0]`) and checks that
/// `render --instances` with it is rejected.
fn reject_csv(dir: &Path, contents: impl AsRef<[u8]>, expect: &[&str]) {
    let name = expect[0];
    write(dir, name, contents);
    assert_rejected(dir, &["render", "--instances", name], expect);
}

/// Writes `contents` to `dir/name` and checks that `render --scene name` is rejected.
fn reject_toml(dir: &Path, name: &str, contents: impl AsRef<[u8]>, expect: &[&str]) {
    write(dir, name, contents);
    reject_scene(dir, name, expect);
}

/// Checks that `render --scene scene` is rejected.
fn reject_scene(dir: &Path, scene: &str, expect: &[&str]) {
    assert_rejected(dir, &["render", "--scene", scene], expect);
}

/// Writes `mesh` (the file `mesh_name`) and a scene file `scene` naming it with `texture`
/// (see `species_scene`), and checks that rendering it is rejected.
fn reject_mesh(
    dir: &Path,
    scene: &str,
    (mesh_name, mesh): (&str, impl AsRef<[u8]>),
    texture: &str,
    expect: &[&str],
) {
    write(dir, mesh_name, mesh);
    let scene = species_scene(dir, scene, &[(mesh_name, texture)]);
    reject_scene(dir, &scene, expect);
}

/// Runs `forestlod args` in `dir` and asserts it succeeds.
fn run_ok(dir: &Path, args: &[&str]) -> Output {
    let output = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

const GOOD_OBJ: &str = "v -1 0 0\nv 1 0 0\nv 1 0 2\nv -1 0 2\nv 0 -1 0\nv 0 1 0\nv 0 1 2\nv 0 -1 2\n\
                        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\nf 5/1 6/2 7/3 8/4\n";

/// A valid `side`² RGBA8 PNG, written by the reference's own encoder.
fn good_png(dir: &Path, side: u32) -> Vec<u8> {
    let path = dir.join("tmp-good.png");
    let image = forestlod_reference::texture::Rgba8Image::new(side, side, [60, 140, 60, 255]);
    forestlod_reference::output::write_png(&path, &image).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    bytes
}

/// A valid PNG whose IHDR is patched (width, height, colour type) and its CRC fixed; the image
/// data stays that of a 4x4 RGBA8 image.
fn patched_png(dir: &Path, width: u32, height: u32, colour_type: u8) -> Vec<u8> {
    let mut png = good_png(dir, 4);
    png[16..20].copy_from_slice(&width.to_be_bytes());
    png[20..24].copy_from_slice(&height.to_be_bytes());
    png[25] = colour_type;
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    png
}

/// A scene file naming `good.csv` and one OBJ/glTF species per `(mesh, texture)`.
fn species_scene(dir: &Path, name: &str, species: &[(&str, &str)]) -> String {
    write(
        dir,
        "good.csv",
        format!("{HEADER}1,2,3,0,1,0\n4,5,6,0.5,1.2,0\n"),
    );
    let mut text = String::from("instances = \"good.csv\"\n");
    for (i, (mesh, texture)) in species.iter().enumerate() {
        text.push_str(&format!(
            "[[species]]\nname = \"s{i}\"\nmesh = \"{mesh}\"\ntexture = \"{texture}\"\n"
        ));
    }
    write(dir, name, text);
    name.to_string()
}

// ---------------------------------------------------------------------------------------------
// Instance tables
// ---------------------------------------------------------------------------------------------

#[test]
fn nan_in_csv() {
    let dir = case_dir("nan-csv");
    let nan = format!("{HEADER}1,2,3,0,1,oak\n1,2,NaN,0,1,oak\n");
    reject_csv(&dir, nan, &["nan.csv", "line 3", "column z", "NaN"]);
    let inf = format!("{HEADER}1,2,3,inf,1,oak\n");
    reject_csv(&dir, inf, &["inf.csv", "line 2", "column yaw", "inf"]);
}

#[test]
fn negative_scale() {
    let dir = case_dir("neg-scale");
    let neg = format!("{HEADER}1,2,3,0,-1.5,pine\n");
    reject_csv(&dir, neg, &["neg.csv", "line 2", "column scale", "-1.5"]);
}

#[test]
fn unknown_species() {
    let dir = case_dir("unknown-species");
    let unk = format!("{HEADER}1,2,3,0,1,baobab\n");
    reject_csv(
        &dir,
        unk,
        &["unk.csv", "line 2", "column species", "baobab"],
    );
    let idx = format!("{HEADER}1,2,3,0,1,7\n");
    reject_csv(&dir, idx, &["idx.csv", "line 2", "column species", "7"]);
}

#[test]
fn empty_instance_list() {
    let dir = case_dir("empty");
    let header_only = ["header_only.csv", "line 2", "empty table"];
    reject_csv(&dir, HEADER, &header_only);
    reject_csv(&dir, "", &["zero_bytes.csv", "line 1", "empty file"]);
    let scene = "instances = \"header_only.csv\"\n";
    reject_toml(
        &dir,
        "scene.toml",
        scene,
        &["header_only.csv", "empty table"],
    );
}

#[test]
fn truncated_and_enormous_csv() {
    let dir = case_dir("truncated-csv");
    let cut = format!("{HEADER}1,2,3,0,1,oak\n4,5,6");
    reject_csv(&dir, cut, &["cut.csv", "line 3", "column count"]);
    let quote = format!("{HEADER}1,2,3,0,1,\"oak");
    reject_csv(&dir, quote, &["quote.csv", "line 2", "never closed"]);
    // One record longer than the 64 KiB limit: rejected without reading the rest.
    let long = format!("{HEADER}{}\n", "1".repeat(100_000));
    reject_csv(&dir, long, &["long.csv", "line 2", "at most"]);
    // Wrongly typed values.
    let text = format!("{HEADER}1,2,three,0,1,oak\n");
    reject_csv(&dir, text, &["text.csv", "line 2", "column z", "three"]);
    // Invalid UTF-8.
    let mut bytes = format!("{HEADER}1,2,3,0,1,").into_bytes();
    bytes.extend_from_slice(&[0xff, 0xfe, b'\n']);
    reject_csv(&dir, bytes, &["binary.csv", "line 2"]);
}

// ---------------------------------------------------------------------------------------------
// Parameters and files
// ---------------------------------------------------------------------------------------------

#[test]
fn invalid_params_flags() {
    let dir = case_dir("params");
    for (flag, value, field) in [
        ("--texture-size", "100", "texture_size"),
        ("--texture-size", "8192", "texture_size"),
        ("--grid-size", "nan", "grid_size"),
        ("--grid-size", "0", "grid_size"),
        ("--angles", "0", "angle_count"),
        ("--lod-levels", "4", "lod_levels"),
        ("--transition", "-5", "lod1_transition"),
        ("--fade-width", "inf", "fade_width"),
        ("--draw-distance", "1e9", "draw_distance"),
    ] {
        // How the error prints the value: `f32`'s Display.
        let shown = match value {
            "nan" => "NaN",
            "1e9" => "1000000000",
            other => other,
        };
        assert_rejected(
            &dir,
            &["render", "--scene", "single", flag, value],
            &[field, shown],
        );
    }
    for (flag, value) in [("--fade-mode", "blend"), ("--camera", "sideways")] {
        assert_rejected(
            &dir,
            &["render", "--scene", "single", flag, value],
            &[flag, value],
        );
    }
    reject_scene(&dir, "nowhere", &["scene name", "nowhere"]);
    // Other subcommands validate the same way.
    assert_rejected(
        &dir,
        &["scene", "info", "--scene", "single", "--grid-size", "nan"],
        &["grid_size", "NaN"],
    );
}

#[test]
fn missing_files() {
    let dir = case_dir("missing");
    reject_scene(&dir, "missing.toml", &["missing.toml", "cannot be read"]);
    assert_rejected(
        &dir,
        &["render", "--instances", "missing.csv"],
        &["missing.csv", "cannot be read"],
    );
    let no_csv = "instances = \"gone.csv\"\n";
    reject_toml(&dir, "no_csv.toml", no_csv, &["gone.csv", "cannot be read"]);
    let no_png = ["gone.png", "cannot be read"];
    reject_mesh(
        &dir,
        "no_png.toml",
        ("card.obj", GOOD_OBJ),
        "gone.png",
        &no_png,
    );
}

#[test]
fn bad_scene_files() {
    let dir = case_dir("toml");
    write(&dir, "good.csv", format!("{HEADER}1,2,3,0,1,oak\n"));
    let wrong_type = "instances = \"good.csv\"\norigin = \"abc\"\n";
    let expect = ["wrong_type.toml", "line 2", "abc"];
    reject_toml(&dir, "wrong_type.toml", wrong_type, &expect);
    let nan_origin = "instances = \"good.csv\"\norigin = [nan, 0.0, 0.0]\n";
    let expect = ["nan_origin.toml", "line 2", "origin", "NaN"];
    reject_toml(&dir, "nan_origin.toml", nan_origin, &expect);
    reject_toml(&dir, "empty.toml", "", &["empty.toml", "instances"]);
    let truncated = "instances = \"good.c";
    reject_toml(
        &dir,
        "truncated.toml",
        truncated,
        &["truncated.toml", "line 1"],
    );
    let binary = [0x89u8, b'P', b'N', b'G', 0xff, 0x00];
    reject_toml(
        &dir,
        "binary.toml",
        binary,
        &["binary.toml", "line 1", "UTF-8"],
    );
    let builtin = "instances = \"good.csv\"\n[[species]]\nname = \"oak\"\nbuiltin = \"baobab\"\n";
    let expect = ["unknown_builtin.toml", "line 4", "baobab"];
    reject_toml(&dir, "unknown_builtin.toml", builtin, &expect);
}

// ---------------------------------------------------------------------------------------------
// Meshes and textures
// ---------------------------------------------------------------------------------------------

#[test]
fn out_of_range_obj_index() {
    let dir = case_dir("obj-index");
    write(&dir, "t.png", good_png(&dir, 8));
    let bad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 9/1\n";
    let expect = ["bad.obj", "line 5", "9/1", "out of range"];
    reject_mesh(&dir, "s.toml", ("bad.obj", bad), "t.png", &expect);
    let bad_uv = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/4\n";
    let expect = ["bad_uv.obj", "line 5", "3/4", "out of range"];
    reject_mesh(&dir, "s2.toml", ("bad_uv.obj", bad_uv), "t.png", &expect);
}

#[test]
fn nan_filled_and_truncated_obj() {
    let dir = case_dir("obj-nan");
    write(&dir, "t.png", good_png(&dir, 8));
    let nan = ("nan.obj", "v nan nan nan\nv 1 0 0\nv 1 1 0\n");
    reject_mesh(&dir, "s.toml", nan, "t.png", &["nan.obj", "line 1", "nan"]);
    let cut = ("cut.obj", &GOOD_OBJ[..GOOD_OBJ.len() - 30]);
    reject_mesh(&dir, "s2.toml", cut, "t.png", &["cut.obj"]);
    let empty = ("empty.obj", "");
    reject_mesh(&dir, "s3.toml", empty, "t.png", &["empty.obj", "geometry"]);
}

#[test]
fn truncated_png() {
    let dir = case_dir("png-truncated");
    write(&dir, "card.obj", GOOD_OBJ);
    let png = good_png(&dir, 16);
    write(&dir, "cut.png", &png[..png.len() / 2]);
    let scene = species_scene(&dir, "s.toml", &[("card.obj", "cut.png")]);
    reject_scene(&dir, &scene, &["cut.png", "invalid PNG", "bytes"]);
    write(&dir, "empty.png", "");
    let scene = species_scene(&dir, "s2.toml", &[("card.obj", "empty.png")]);
    reject_scene(&dir, &scene, &["empty.png", "invalid PNG", "0 bytes"]);
}

#[test]
fn png_with_huge_or_wrong_dimensions_or_type() {
    let dir = case_dir("png-size");
    write(&dir, "card.obj", GOOD_OBJ);
    // (name, IHDR width, height, colour type, expected error parts).
    let cases: [(&str, u32, u32, u8, &[&str]); 5] = [
        // Enormous declared size: rejected from the header, nothing allocated.
        ("huge.png", 65536, 65536, 6, &["huge.png", "width", "65536"]),
        // Allowed declared size, but only 4x4 texels of data.
        ("lying.png", 4096, 4096, 6, &["lying.png", "invalid PNG"]),
        ("odd.png", 12, 12, 6, &["odd.png", "width", "12"]),
        (
            "nonsquare.png",
            16,
            8,
            6,
            &["nonsquare.png", "16x8", "square"],
        ),
        // Colour type 2 (RGB): not RGBA.
        ("rgb.png", 4, 4, 2, &["rgb.png", "colour type"]),
    ];
    for (i, (name, width, height, colour_type, expect)) in cases.into_iter().enumerate() {
        write(&dir, name, patched_png(&dir, width, height, colour_type));
        let scene = species_scene(&dir, &format!("s{i}.toml"), &[("card.obj", name)]);
        reject_scene(&dir, &scene, expect);
    }
}

/// The contract's positive side: a good user scene renders, exit 0, and writes its files.
#[test]
fn a_good_obj_scene_renders() {
    let dir = case_dir("good");
    write(&dir, "card.obj", GOOD_OBJ);
    write(&dir, "t.png", good_png(&dir, 8));
    let scene = species_scene(&dir, "s.toml", &[("card.obj", "t.png")]);
    let out = dir.join("out");
    run_ok(&dir, &render_small(&scene, &out));
    assert!(out.join("color.png").is_file() && out.join("metrics.json").is_file());
}

/// `render --scene scene` at the close camera, 32x32 and 16² textures, into `out`.
fn render_small<'a>(scene: &'a str, out: &'a Path) -> Vec<&'a str> {
    let out = out.to_str().unwrap();
    vec![
        "render",
        "--scene",
        scene,
        "--camera",
        "close",
        "--width",
        "32",
        "--height",
        "32",
        "--texture-size",
        "16",
        "--out",
        out,
    ]
}

// ---------------------------------------------------------------------------------------------
// Issue 10 ("failures that fail"): texture sizes, error chains, path confinement, mesh files
// given as --scene, PNG colour types, polygons, glTF, long content
// ---------------------------------------------------------------------------------------------

#[test]
fn species_textures_of_different_sizes() {
    let dir = case_dir("texture-sizes");
    write(&dir, "card.obj", GOOD_OBJ);
    write(&dir, "t8.png", good_png(&dir, 8));
    write(&dir, "t16.png", good_png(&dir, 16));
    let scene = species_scene(
        &dir,
        "s.toml",
        &[("card.obj", "t8.png"), ("card.obj", "t16.png")],
    );
    reject_scene(
        &dir,
        &scene,
        &[
            "error: s.toml: line 9, column 11, field species[1].texture: value \"16x16\"",
            "texture \"t16.png\" is 16x16",
            "species[0] texture \"t8.png\" is 8x8",
            "square size",
        ],
    );
}

#[test]
fn errors_in_named_files_show_the_chain() {
    let dir = case_dir("chain");
    write(&dir, "t.png", good_png(&dir, 8));
    let oak = (
        "oak.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 99/1\n",
    );
    reject_mesh(
        &dir,
        "forest.toml",
        oak,
        "t.png",
        &[
            "error: forest.toml: line 4, column 8, field species[0].mesh = \"oak.obj\": oak.obj: line 5, face: value \"99/1\": vertex index out of range",
        ],
    );
    write(&dir, "bad.csv", format!("{HEADER}1,2,3,0,-2,0\n"));
    write(&dir, "csv.toml", "instances = \"bad.csv\"\n");
    assert_rejected(
        &dir,
        &["scene", "info", "--scene", "csv.toml"],
        &[
            "error: csv.toml: line 1, column 13, field instances = \"bad.csv\": bad.csv: line 2, column scale: value \"-2\"",
        ],
    );
}

#[test]
fn scene_files_naming_files_outside_their_folder() {
    let dir = case_dir("outside");
    let sub = dir.join("scene");
    std::fs::create_dir_all(&sub).unwrap();
    write(&dir, "card.obj", GOOD_OBJ);
    write(&sub, "t.png", good_png(&dir, 8));
    write(&sub, "good.csv", format!("{HEADER}1,2,3,0,1,0\n"));
    write(
        &sub,
        "up.toml",
        "instances = \"good.csv\"\n[[species]]\nname = \"a\"\nmesh = \"../card.obj\"\ntexture = \"t.png\"\n",
    );
    reject_scene(
        &dir,
        "scene/up.toml",
        &[
            "scene/up.toml: line 4, column 8, field species[0].mesh: value \"../card.obj\": resolves to",
            "outside the scene file's folder",
            "--allow-outside-paths",
        ],
    );
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(dir.join("card.obj"), sub.join("link.obj")).unwrap();
        write(
            &sub,
            "link.toml",
            "instances = \"good.csv\"\n[[species]]\nname = \"a\"\nmesh = \"link.obj\"\ntexture = \"t.png\"\n",
        );
        reject_scene(
            &dir,
            "scene/link.toml",
            &[
                "link.toml",
                "species[0].mesh",
                "\"link.obj\"",
                "outside the scene file's folder",
            ],
        );
    }
    // With the flag, the same scene loads.
    let args = [
        "scene",
        "info",
        "--scene",
        "scene/up.toml",
        "--allow-outside-paths",
    ];
    run_ok(&dir, &args);
}

#[test]
fn scene_flag_given_a_csv_or_a_mesh_says_what_to_use() {
    let dir = case_dir("scene-kind");
    write(&dir, "trees.csv", format!("{HEADER}1,2,3,0,1,oak\n"));
    write(&dir, "tree.obj", GOOD_OBJ);
    let expect = ["--scene: value \"trees.csv\"", "use --instances trees.csv"];
    reject_scene(&dir, "trees.csv", &expect);
    for mesh in ["tree.obj", "tree.gltf", "tree.glb"] {
        reject_scene(
            &dir,
            mesh,
            &[
                &format!("--scene: value \"{mesh}\""),
                "scene TOML file",
                "instances = \"trees.csv\" | [[species]] | name = \"tree\"",
                &format!("mesh = \"{mesh}\" | texture = \"tree.png\""),
            ],
        );
    }
}

#[test]
fn png_colour_types_are_named() {
    let dir = case_dir("png-colour");
    write(&dir, "card.obj", GOOD_OBJ);
    for (i, (colour_type, shown)) in [
        (2u8, "RGB, 8-bit, no transparency"),
        (0, "grey, 8-bit, no transparency"),
        (4, "grey+alpha, 8-bit"),
    ]
    .into_iter()
    .enumerate()
    {
        let name = format!("c{colour_type}.png");
        write(&dir, &name, patched_png(&dir, 4, 4, colour_type));
        let scene = species_scene(&dir, &format!("s{i}.toml"), &[("card.obj", &name)]);
        let expect = format!("{name}: colour type: value \"{shown}\"");
        reject_scene(&dir, &scene, &[&expect, "expected RGBA, 8-bit"]);
    }
}

#[test]
fn bad_obj_polygons() {
    let dir = case_dir("polygons");
    write(&dir, "t.png", good_png(&dir, 8));
    let bow = "v 0 0 0\nv 1 0 1\nv 1 0 0\nv 0 0 1\nvt 0 0\nf 1/1 2/1 3/1 4/1\n";
    reject_mesh(
        &dir,
        "bow.toml",
        ("bow.obj", bow),
        "t.png",
        &[
            "field species[0].mesh = \"bow.obj\": bow.obj: line 6, face: value \"4 vertices: 1 2 3 4\"",
            "self-intersecting",
        ],
    );
    let bent = "v 0 0 0\nv 1 0 0\nv 1 1 1\nv 0 0 1\nvt 0 0\nf 1/1 2/1 3/1 4/1\n";
    let expect = ["bent.obj: line 6, face", "non-planar"];
    reject_mesh(&dir, "bent.toml", ("bent.obj", bent), "t.png", &expect);
}

#[test]
fn bad_gltf_meshes() {
    let dir = case_dir("gltf");
    write(&dir, "t.png", good_png(&dir, 8));
    let range = ("range.gltf", gltf_card(&[0, 1, 2, 0, 2, 9], 4));
    reject_mesh(
        &dir,
        "range.toml",
        range,
        "t.png",
        &[
            "error: range.toml: line 4, column 8, field species[0].mesh = \"range.gltf\": range.gltf: mesh 0, primitive 0, indices element 5: value \"9\": index out of range (4 vertices)",
        ],
    );
    let strip = ("strip.gltf", gltf_card(&[0, 1, 2, 3], 5));
    reject_mesh(
        &dir,
        "strip.toml",
        strip,
        "t.png",
        &[
            "strip.gltf: mesh 0, primitive 0, mode: value \"TRIANGLE_STRIP (5)\": expected a triangle list",
        ],
    );
    let card = gltf_card(&[0, 1, 2], 4);
    let cut = ("cut.gltf", &card[..200]);
    let expect = ["cut.gltf: file", "invalid glTF 2.0"];
    reject_mesh(&dir, "cut.toml", cut, "t.png", &expect);
}

#[test]
fn a_good_gltf_scene_renders() {
    let dir = case_dir("good-gltf");
    write(&dir, "card.gltf", gltf_card(&[0, 1, 2, 0, 2, 3], 4));
    write(&dir, "t.png", good_png(&dir, 8));
    let scene = species_scene(&dir, "s.toml", &[("card.gltf", "t.png")]);
    let out = dir.join("out");
    run_ok(&dir, &render_small(&scene, &out));
    assert!(out.join("color.png").is_file());
}

#[test]
fn long_file_content_is_echoed_as_a_short_marked_excerpt() {
    let dir = case_dir("excerpt");
    let long = "q".repeat(10_000);
    let excerpt = format!("value \"{}…\"", "q".repeat(40));
    write(&dir, "long.csv", format!("{HEADER}1,2,3,0,1,{long}\n"));
    let expect = ["long.csv: line 2, column species", &excerpt];
    assert_rejected(&dir, &["render", "--instances", "long.csv"], &expect);
    write(&dir, "t.png", good_png(&dir, 8));
    let obj = format!("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1 {long}\n");
    let expect = ["long.obj: line 5, face", &excerpt];
    reject_mesh(&dir, "s.toml", ("long.obj", obj), "t.png", &expect);
}

// ---------------------------------------------------------------------------------------------
// Sweep flags that would be clamped, and the free camera
// ---------------------------------------------------------------------------------------------

#[test]
fn sweep_zero_flags_are_rejected_not_clamped() {
    let dir = case_dir("sweep-zero");
    let sweep_out = dir.join("sweep-out");
    let sweep_out = sweep_out.to_str().unwrap();
    for flag in ["--repeats", "--yaw-steps", "--width", "--height"] {
        assert_rejected(
            &dir,
            &[
                "sweep",
                "camera360",
                "--quick",
                "--out",
                sweep_out,
                flag,
                "0",
            ],
            &[flag, "\"0\"", "expected at least 1"],
        );
        assert!(
            !Path::new(sweep_out).exists(),
            "{flag} 0: the sweep output folder was created"
        );
    }
    // A sweep file's `yaw_steps = 0` too.
    write(
        &dir,
        "zero.toml",
        "name = 'zero'\ntitle = 't'\nscenes = ['tiny']\n[[cameras]]\nname = 'far'\nyaw_steps = 0\n",
    );
    assert_rejected(
        &dir,
        &["sweep", "zero.toml", "--out", sweep_out],
        &["zero.toml", "cameras[0].yaw_steps", "\"0\""],
    );
}

#[test]
fn bad_free_cameras() {
    let dir = case_dir("free-camera");
    for (eye, look, fov, flag, value) in [
        ("1,2", "0,0,0", None, "--eye", "1,2"),
        ("1,2,nan", "0,0,0", None, "--eye", "1,2,nan"),
        ("1,2,inf", "0,0,0", None, "--eye", "1,2,inf"),
        ("1,2,3", "a,b,c", None, "--look-at", "a,b,c"),
        ("1,2,3", "1,2,3", None, "--look-at", "1,2,3"),
        ("0,0,100", "0,0,0", None, "--look-at", "0,0,0"),
        ("0,0,100", "0,0,200", None, "--look-at", "0,0,200"),
        ("0,0,100", "50,0,0", Some("0"), "--fov", "0"),
        ("0,0,100", "50,0,0", Some("180"), "--fov", "180"),
        ("0,0,100", "50,0,0", Some("-10"), "--fov", "-10"),
        ("0,0,100", "50,0,0", Some("nan"), "--fov", "NaN"),
    ] {
        let eye = format!("--eye={eye}");
        let look = format!("--look-at={look}");
        for sub in ["render", "select"] {
            let mut args = vec![sub, "--scene", "single", &eye, &look];
            if let Some(f) = fov {
                args.extend(["--fov", f]);
            }
            assert_rejected(&dir, &args, &[flag, &format!("{value:?}")]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Issue 33: Celba's built-in forests (`celba-<trees per ha>-<side km>`, C§5.2)
// ---------------------------------------------------------------------------------------------

/// A Celba scene renders from the command line; a name outside his densities or sizes, or not of
/// the form, exits 1 naming the value and the valid densities and sizes.
#[test]
fn celba_scenes_render_and_bad_celba_names_are_rejected() {
    let dir = case_dir("celba");
    let out = dir.join("out");
    run_ok(&dir, &render_small("celba-20-4", &out));
    let metrics = std::fs::read_to_string(out.join("metrics.json")).unwrap();
    assert!(metrics.contains("celba-20-4"), "{metrics}");
    reject_scene(&dir, "celba-30-4", &["30 trees/ha", "5, 10, 20, 40, 80"]);
    reject_scene(&dir, "celba-20-3", &["3 km", "1, 2, 4, 5, 10, 20"]);
    reject_scene(
        &dir,
        "celba-20",
        &["celba-20", "celba-<trees per ha>-<side km>"],
    );
}
