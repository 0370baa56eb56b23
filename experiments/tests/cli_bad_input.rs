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
use std::process::Command;

/// A fresh directory for one case.
fn case_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "forestlod-cli-bad-input-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
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

const HEADER: &str = "x,y,z,yaw,scale,species\n";

/// A crossed-card tree in OBJ (4 triangles, Z up).
const GOOD_OBJ: &str = "v -1 0 0\nv 1 0 0\nv 1 0 2\nv -1 0 2\nv 0 -1 0\nv 0 1 0\nv 0 1 2\nv 0 -1 2\n\
                        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\nf 5/1 6/2 7/3 8/4\n";

/// CRC-32 as PNG chunks use it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

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

/// A scene file naming `good.csv` and one OBJ species.
fn obj_scene(dir: &Path, name: &str, obj: &str, texture: &str) -> String {
    write(
        dir,
        "good.csv",
        format!("{HEADER}1,2,3,0,1,0\n4,5,6,0.5,1.2,0\n"),
    );
    write(
        dir,
        name,
        format!(
            "instances = \"good.csv\"\n[[species]]\nname = \"card\"\nmesh = \"{obj}\"\ntexture = \"{texture}\"\n"
        ),
    );
    name.to_string()
}

// ---------------------------------------------------------------------------------------------
// Instance tables
// ---------------------------------------------------------------------------------------------

#[test]
fn nan_in_csv() {
    let dir = case_dir("nan-csv");
    write(
        &dir,
        "nan.csv",
        format!("{HEADER}1,2,3,0,1,oak\n1,2,NaN,0,1,oak\n"),
    );
    assert_rejected(
        &dir,
        &["render", "--instances", "nan.csv"],
        &["nan.csv", "line 3", "column z", "NaN"],
    );
    write(&dir, "inf.csv", format!("{HEADER}1,2,3,inf,1,oak\n"));
    assert_rejected(
        &dir,
        &["render", "--instances", "inf.csv"],
        &["inf.csv", "line 2", "column yaw", "inf"],
    );
}

#[test]
fn negative_scale() {
    let dir = case_dir("neg-scale");
    write(&dir, "neg.csv", format!("{HEADER}1,2,3,0,-1.5,pine\n"));
    assert_rejected(
        &dir,
        &["render", "--instances", "neg.csv"],
        &["neg.csv", "line 2", "column scale", "-1.5"],
    );
}

#[test]
fn unknown_species() {
    let dir = case_dir("unknown-species");
    write(&dir, "unk.csv", format!("{HEADER}1,2,3,0,1,baobab\n"));
    assert_rejected(
        &dir,
        &["render", "--instances", "unk.csv"],
        &["unk.csv", "line 2", "column species", "baobab"],
    );
    write(&dir, "idx.csv", format!("{HEADER}1,2,3,0,1,7\n"));
    assert_rejected(
        &dir,
        &["render", "--instances", "idx.csv"],
        &["idx.csv", "line 2", "column species", "7"],
    );
}

#[test]
fn empty_instance_list() {
    let dir = case_dir("empty");
    write(&dir, "header_only.csv", HEADER);
    assert_rejected(
        &dir,
        &["render", "--instances", "header_only.csv"],
        &["header_only.csv", "line 2", "empty table"],
    );
    write(&dir, "zero_bytes.csv", "");
    assert_rejected(
        &dir,
        &["render", "--instances", "zero_bytes.csv"],
        &["zero_bytes.csv", "line 1", "empty file"],
    );
    write(&dir, "scene.toml", "instances = \"header_only.csv\"\n");
    assert_rejected(
        &dir,
        &["render", "--scene", "scene.toml"],
        &["header_only.csv", "empty table"],
    );
}

#[test]
fn truncated_and_enormous_csv() {
    let dir = case_dir("truncated-csv");
    write(&dir, "cut.csv", format!("{HEADER}1,2,3,0,1,oak\n4,5,6"));
    assert_rejected(
        &dir,
        &["render", "--instances", "cut.csv"],
        &["cut.csv", "line 3", "column count"],
    );
    write(&dir, "quote.csv", format!("{HEADER}1,2,3,0,1,\"oak"));
    assert_rejected(
        &dir,
        &["render", "--instances", "quote.csv"],
        &["quote.csv", "line 2", "never closed"],
    );
    // One record longer than the 64 KiB limit: rejected without reading the rest.
    write(
        &dir,
        "long.csv",
        format!("{HEADER}{}\n", "1".repeat(100_000)),
    );
    assert_rejected(
        &dir,
        &["render", "--instances", "long.csv"],
        &["long.csv", "line 2", "at most"],
    );
    // Wrongly typed values.
    write(&dir, "text.csv", format!("{HEADER}1,2,three,0,1,oak\n"));
    assert_rejected(
        &dir,
        &["render", "--instances", "text.csv"],
        &["text.csv", "line 2", "column z", "three"],
    );
    // Invalid UTF-8.
    let mut bytes = format!("{HEADER}1,2,3,0,1,").into_bytes();
    bytes.extend_from_slice(&[0xff, 0xfe, b'\n']);
    write(&dir, "binary.csv", bytes);
    assert_rejected(
        &dir,
        &["render", "--instances", "binary.csv"],
        &["binary.csv", "line 2"],
    );
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
        ("--lod-levels", "3", "lod_levels"),
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
    assert_rejected(
        &dir,
        &["render", "--scene", "single", "--fade-mode", "blend"],
        &["--fade-mode", "blend"],
    );
    assert_rejected(
        &dir,
        &["render", "--scene", "single", "--camera", "sideways"],
        &["--camera", "sideways"],
    );
    assert_rejected(
        &dir,
        &["render", "--scene", "nowhere"],
        &["scene name", "nowhere"],
    );
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
    assert_rejected(
        &dir,
        &["render", "--scene", "missing.toml"],
        &["missing.toml", "cannot be read"],
    );
    assert_rejected(
        &dir,
        &["render", "--instances", "missing.csv"],
        &["missing.csv", "cannot be read"],
    );
    write(&dir, "no_csv.toml", "instances = \"gone.csv\"\n");
    assert_rejected(
        &dir,
        &["render", "--scene", "no_csv.toml"],
        &["gone.csv", "cannot be read"],
    );
    let scene = obj_scene(&dir, "no_png.toml", "card.obj", "gone.png");
    write(&dir, "card.obj", GOOD_OBJ);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["gone.png", "cannot be read"],
    );
}

#[test]
fn bad_scene_files() {
    let dir = case_dir("toml");
    write(&dir, "good.csv", format!("{HEADER}1,2,3,0,1,oak\n"));
    write(
        &dir,
        "wrong_type.toml",
        "instances = \"good.csv\"\norigin = \"abc\"\n",
    );
    assert_rejected(
        &dir,
        &["render", "--scene", "wrong_type.toml"],
        &["wrong_type.toml", "line 2", "abc"],
    );
    write(
        &dir,
        "nan_origin.toml",
        "instances = \"good.csv\"\norigin = [nan, 0.0, 0.0]\n",
    );
    assert_rejected(
        &dir,
        &["render", "--scene", "nan_origin.toml"],
        &["nan_origin.toml", "line 2", "origin", "NaN"],
    );
    write(&dir, "empty.toml", "");
    assert_rejected(
        &dir,
        &["render", "--scene", "empty.toml"],
        &["empty.toml", "instances"],
    );
    write(&dir, "truncated.toml", "instances = \"good.c");
    assert_rejected(
        &dir,
        &["render", "--scene", "truncated.toml"],
        &["truncated.toml", "line 1"],
    );
    write(&dir, "binary.toml", [0x89u8, b'P', b'N', b'G', 0xff, 0x00]);
    assert_rejected(
        &dir,
        &["render", "--scene", "binary.toml"],
        &["binary.toml", "line 1", "UTF-8"],
    );
    write(
        &dir,
        "unknown_builtin.toml",
        "instances = \"good.csv\"\n[[species]]\nname = \"oak\"\nbuiltin = \"baobab\"\n",
    );
    assert_rejected(
        &dir,
        &["render", "--scene", "unknown_builtin.toml"],
        &["unknown_builtin.toml", "line 4", "baobab"],
    );
}

// ---------------------------------------------------------------------------------------------
// Meshes and textures
// ---------------------------------------------------------------------------------------------

#[test]
fn out_of_range_obj_index() {
    let dir = case_dir("obj-index");
    write(&dir, "t.png", good_png(&dir, 8));
    write(
        &dir,
        "bad.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 9/1\n",
    );
    let scene = obj_scene(&dir, "s.toml", "bad.obj", "t.png");
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["bad.obj", "line 5", "9/1", "out of range"],
    );
    write(
        &dir,
        "bad_uv.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/4\n",
    );
    let scene = obj_scene(&dir, "s2.toml", "bad_uv.obj", "t.png");
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["bad_uv.obj", "line 5", "3/4", "out of range"],
    );
}

#[test]
fn nan_filled_and_truncated_obj() {
    let dir = case_dir("obj-nan");
    write(&dir, "t.png", good_png(&dir, 8));
    write(&dir, "nan.obj", "v nan nan nan\nv 1 0 0\nv 1 1 0\n");
    let scene = obj_scene(&dir, "s.toml", "nan.obj", "t.png");
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["nan.obj", "line 1", "nan"],
    );
    write(&dir, "cut.obj", &GOOD_OBJ[..GOOD_OBJ.len() - 30]);
    let scene = obj_scene(&dir, "s2.toml", "cut.obj", "t.png");
    assert_rejected(&dir, &["render", "--scene", &scene], &["cut.obj"]);
    write(&dir, "empty.obj", "");
    let scene = obj_scene(&dir, "s3.toml", "empty.obj", "t.png");
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["empty.obj", "geometry"],
    );
}

#[test]
fn truncated_png() {
    let dir = case_dir("png-truncated");
    write(&dir, "card.obj", GOOD_OBJ);
    let png = good_png(&dir, 16);
    write(&dir, "cut.png", &png[..png.len() / 2]);
    let scene = obj_scene(&dir, "s.toml", "card.obj", "cut.png");
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["cut.png", "invalid PNG", "bytes"],
    );
    write(&dir, "empty.png", "");
    let scene = obj_scene(&dir, "s2.toml", "card.obj", "empty.png");
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["empty.png", "invalid PNG", "0 bytes"],
    );
}

#[test]
fn png_with_huge_or_wrong_dimensions_or_type() {
    let dir = case_dir("png-size");
    write(&dir, "card.obj", GOOD_OBJ);
    let cases: [(&str, Vec<u8>, &[&str]); 5] = [
        // Enormous declared size: rejected from the header, nothing allocated.
        (
            "huge.png",
            patched_png(&dir, 65536, 65536, 6),
            &["huge.png", "width", "65536"],
        ),
        // Allowed declared size, but only 4x4 texels of data.
        (
            "lying.png",
            patched_png(&dir, 4096, 4096, 6),
            &["lying.png", "invalid PNG"],
        ),
        (
            "odd.png",
            patched_png(&dir, 12, 12, 6),
            &["odd.png", "width", "12"],
        ),
        (
            "nonsquare.png",
            patched_png(&dir, 16, 8, 6),
            &["nonsquare.png", "16x8", "square"],
        ),
        // Colour type 2 (RGB): not RGBA.
        (
            "rgb.png",
            patched_png(&dir, 4, 4, 2),
            &["rgb.png", "colour type"],
        ),
    ];
    for (i, (name, bytes, expect)) in cases.into_iter().enumerate() {
        write(&dir, name, bytes);
        let scene = obj_scene(&dir, &format!("s{i}.toml"), "card.obj", name);
        assert_rejected(&dir, &["render", "--scene", &scene], expect);
    }
}

/// The contract's positive side: a good user scene renders, exit 0, and writes its files.
#[test]
fn a_good_obj_scene_renders() {
    let dir = case_dir("good");
    write(&dir, "card.obj", GOOD_OBJ);
    write(&dir, "t.png", good_png(&dir, 8));
    let scene = obj_scene(&dir, "s.toml", "card.obj", "t.png");
    let out = dir.join("out");
    let output = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args([
            "render",
            "--scene",
            &scene,
            "--camera",
            "close",
            "--width",
            "32",
            "--height",
            "32",
            "--texture-size",
            "16",
            "--out",
            out.to_str().unwrap(),
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(out.join("color.png").is_file() && out.join("metrics.json").is_file());
}

// ---------------------------------------------------------------------------------------------
// Issue 10 ("failures that fail"): texture sizes, error chains, path confinement, mesh files
// given as --scene, PNG colour types, polygons, glTF, long content
// ---------------------------------------------------------------------------------------------

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
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
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
    write(
        &dir,
        "oak.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 99/1\n",
    );
    let scene = species_scene(&dir, "forest.toml", &[("oak.obj", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
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
    assert_rejected(
        &dir,
        &["render", "--scene", "scene/up.toml"],
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
        assert_rejected(
            &dir,
            &["render", "--scene", "scene/link.toml"],
            &[
                "link.toml",
                "species[0].mesh",
                "\"link.obj\"",
                "outside the scene file's folder",
            ],
        );
    }
    // With the flag, the same scene loads.
    let output = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args([
            "scene",
            "info",
            "--scene",
            "scene/up.toml",
            "--allow-outside-paths",
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn scene_flag_given_a_csv_or_a_mesh_says_what_to_use() {
    let dir = case_dir("scene-kind");
    write(&dir, "trees.csv", format!("{HEADER}1,2,3,0,1,oak\n"));
    write(&dir, "tree.obj", GOOD_OBJ);
    assert_rejected(
        &dir,
        &["render", "--scene", "trees.csv"],
        &["--scene: value \"trees.csv\"", "use --instances trees.csv"],
    );
    for mesh in ["tree.obj", "tree.gltf", "tree.glb"] {
        assert_rejected(
            &dir,
            &["render", "--scene", mesh],
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
        assert_rejected(
            &dir,
            &["render", "--scene", &scene],
            &[
                &format!("{name}: colour type: value \"{shown}\""),
                "expected RGBA, 8-bit",
            ],
        );
    }
}

#[test]
fn bad_obj_polygons() {
    let dir = case_dir("polygons");
    write(&dir, "t.png", good_png(&dir, 8));
    write(
        &dir,
        "bow.obj",
        "v 0 0 0\nv 1 0 1\nv 1 0 0\nv 0 0 1\nvt 0 0\nf 1/1 2/1 3/1 4/1\n",
    );
    let scene = species_scene(&dir, "bow.toml", &[("bow.obj", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &[
            "field species[0].mesh = \"bow.obj\": bow.obj: line 6, face: value \"4 vertices: 1 2 3 4\"",
            "self-intersecting",
        ],
    );
    write(
        &dir,
        "bent.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 1\nv 0 0 1\nvt 0 0\nf 1/1 2/1 3/1 4/1\n",
    );
    let scene = species_scene(&dir, "bent.toml", &[("bent.obj", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["bent.obj: line 6, face", "non-planar"],
    );
}

/// Standard base64 with padding.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A glTF 2.0 card (Y up, 2 m tall) with an embedded base64 buffer, `indices` and `mode`.
fn gltf_card(indices: &[u16], mode: u32) -> String {
    let positions: [[f32; 3]; 4] = [
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 2.0, 0.0],
        [-1.0, 2.0, 0.0],
    ];
    let uvs: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let mut buf: Vec<u8> = Vec::new();
    for c in positions.iter().flatten().chain(uvs.iter().flatten()) {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    for i in indices {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    while !buf.len().is_multiple_of(4) {
        buf.push(0);
    }
    format!(
        r#"{{"asset":{{"version":"2.0"}},
"buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},{{"buffer":0,"byteOffset":80,"byteLength":{il}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,0],"max":[1,2,0]}},{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},{{"bufferView":2,"componentType":5123,"count":{ni},"type":"SCALAR"}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"mode":{mode}}}]}}],
"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        len = buf.len(),
        b64 = base64(&buf),
        il = indices.len() * 2,
        ni = indices.len(),
    )
}

#[test]
fn bad_gltf_meshes() {
    let dir = case_dir("gltf");
    write(&dir, "t.png", good_png(&dir, 8));
    write(&dir, "range.gltf", gltf_card(&[0, 1, 2, 0, 2, 9], 4));
    let scene = species_scene(&dir, "range.toml", &[("range.gltf", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &[
            "error: range.toml: line 4, column 8, field species[0].mesh = \"range.gltf\": range.gltf: mesh 0, primitive 0, indices element 5: value \"9\": index out of range (4 vertices)",
        ],
    );
    write(&dir, "strip.gltf", gltf_card(&[0, 1, 2, 3], 5));
    let scene = species_scene(&dir, "strip.toml", &[("strip.gltf", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &[
            "strip.gltf: mesh 0, primitive 0, mode: value \"TRIANGLE_STRIP (5)\": expected a triangle list",
        ],
    );
    write(&dir, "cut.gltf", &gltf_card(&[0, 1, 2], 4)[..200]);
    let scene = species_scene(&dir, "cut.toml", &[("cut.gltf", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &["cut.gltf: file", "invalid glTF 2.0"],
    );
}

#[test]
fn a_good_gltf_scene_renders() {
    let dir = case_dir("good-gltf");
    write(&dir, "card.gltf", gltf_card(&[0, 1, 2, 0, 2, 3], 4));
    write(&dir, "t.png", good_png(&dir, 8));
    let scene = species_scene(&dir, "s.toml", &[("card.gltf", "t.png")]);
    let out = dir.join("out");
    let output = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args([
            "render", "--scene", &scene, "--camera", "close", "--width", "32", "--height", "32",
        ])
        .args(["--texture-size", "16", "--out", out.to_str().unwrap()])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(out.join("color.png").is_file());
}

#[test]
fn long_file_content_is_echoed_as_a_short_marked_excerpt() {
    let dir = case_dir("excerpt");
    let long = "q".repeat(10_000);
    write(&dir, "long.csv", format!("{HEADER}1,2,3,0,1,{long}\n"));
    assert_rejected(
        &dir,
        &["render", "--instances", "long.csv"],
        &[
            "long.csv: line 2, column species",
            &format!("value \"{}…\"", "q".repeat(40)),
        ],
    );
    write(&dir, "t.png", good_png(&dir, 8));
    write(
        &dir,
        "long.obj",
        format!("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1 {long}\n"),
    );
    let scene = species_scene(&dir, "s.toml", &[("long.obj", "t.png")]);
    assert_rejected(
        &dir,
        &["render", "--scene", &scene],
        &[
            "long.obj: line 5, face",
            &format!("value \"{}…\"", "q".repeat(40)),
        ],
    );
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
        &["zero.toml", "cameras.yaw_steps", "\"0\""],
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
