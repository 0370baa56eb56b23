//! Hostile glTF/GLB tree meshes (issue 28, "glTF/GLB headers"; README "Bad input"): a GLB whose
//! header (magic, version, length) or chunk headers (type, length) are wrong gets one error naming
//! the file, the field, the value found and the value expected; buffer URIs are percent-decoded
//! as glTF requires, a bad encoding is an error naming the field, and the decoded path is
//! confined to the scene's folder like every named file.
//!
//! One table: each case writes a mesh (and the files it names) into a fresh scene folder, loads
//! the scene on a thread with a deadline, and matches the one error line against a pattern (`*`
//! matches any text). The good cases beside them load, so the refusals are the cases' doing.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use forestlod_reference::scene::load::load_scene_file;

mod common;
use common::{CARD_POSITIONS, CARD_UVS, HEADER, base64, gltf_json, write};

/// The card's buffer as `common::gltf_json` lays it out: positions, UVs, then `u16` indices,
/// padded to 4 bytes.
fn card_buffer(indices: &[u16]) -> Vec<u8> {
    let mut buf: Vec<u8> = Vec::new();
    for c in CARD_POSITIONS.iter().flatten() {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    for c in CARD_UVS.iter().flatten() {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    for i in indices {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    while !buf.len().is_multiple_of(4) {
        buf.push(0);
    }
    buf
}

const INDICES: [u16; 6] = [0, 1, 2, 0, 2, 3];

/// The card's glTF JSON with its buffer's `uri` replaced: `Some(uri)` names an external file,
/// `None` leaves no uri (the GLB's binary chunk).
fn card_json(uri: Option<&str>) -> String {
    let json = gltf_json(&CARD_POSITIONS, &CARD_UVS, &INDICES, 4);
    let data = format!(
        ",\"uri\":\"data:application/octet-stream;base64,{}\"",
        base64(&card_buffer(&INDICES))
    );
    assert!(json.contains(&data), "the data URI is where expected");
    json.replace(
        &data,
        &uri.map(|u| format!(",\"uri\":{u:?}")).unwrap_or_default(),
    )
}

/// A GLB of `json` and, when given, a binary chunk `bin`, both padded to 4 bytes.
fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |bytes: &[u8], with: u8| {
        let mut b = bytes.to_vec();
        while !b.len().is_multiple_of(4) {
            b.push(with);
        }
        b
    };
    let mut chunks = Vec::new();
    let json = pad(json, b' ');
    chunks.extend_from_slice(&(json.len() as u32).to_le_bytes());
    chunks.extend_from_slice(b"JSON");
    chunks.extend_from_slice(&json);
    if let Some(bin) = bin {
        let bin = pad(bin, 0);
        chunks.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        chunks.extend_from_slice(b"BIN\0");
        chunks.extend_from_slice(&bin);
    }
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + chunks.len()) as u32).to_le_bytes());
    out.extend_from_slice(&chunks);
    out
}

/// The good GLB: the card's JSON and its buffer in the binary chunk.
fn good_glb() -> Vec<u8> {
    glb(card_json(None).as_bytes(), Some(&card_buffer(&INDICES)))
}

/// Offset of the binary chunk's header in [`good_glb`].
fn bin_at() -> usize {
    let json = card_json(None).len().next_multiple_of(4);
    12 + 8 + json
}

fn set_u32(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// Loads the scene `scene` on a thread, failing the test past a 10 s deadline.
fn load(scene: &Path) -> Result<usize, String> {
    let (tx, rx) = mpsc::channel();
    let p = scene.to_path_buf();
    std::thread::spawn(move || {
        let _ = tx.send(
            load_scene_file(&p)
                .map(|s| s.meshes[0].indices.len())
                .map_err(|e| e.to_string()),
        );
    });
    rx.recv_timeout(Duration::from_secs(10))
        .unwrap_or_else(|_| panic!("loading {}: no answer in 10 s", scene.display()))
}

/// A scene folder `dir/scene` with a texture, an instance table and a scene file naming the mesh
/// `mesh`; returns the scene file.
fn scene_naming(dir: &Path, mesh: &str) -> PathBuf {
    let folder = dir.join("scene");
    std::fs::create_dir_all(&folder).unwrap();
    write(&folder, "t.png", common_png());
    write(&folder, "t.csv", format!("{HEADER}1,2,3,0,1,0\n"));
    write(
        &folder,
        "s.toml",
        format!(
            "instances = \"t.csv\"\n[[species]]\nname = \"s0\"\nmesh = {mesh:?}\ntexture = \"t.png\"\n"
        ),
    )
}

/// An 8x8 RGBA PNG.
fn common_png() -> Vec<u8> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&[200u8; 8 * 8 * 4], 8, 8, image::ExtendedColorType::Rgba8)
        .unwrap();
    out
}

/// Whether `text` matches `pattern` (`*`: any text, possibly empty).
fn matches(pattern: &str, text: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    if parts.len() == 1 {
        return text == pattern;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !text.starts_with(first) || !text[first.len()..].ends_with(last) {
        return false;
    }
    let mut rest = &text[first.len()..text.len() - last.len()];
    for part in &parts[1..parts.len() - 1] {
        match rest.find(part) {
            Some(i) => rest = &rest[i + part.len()..],
            None => return false,
        }
    }
    true
}

/// A case: the mesh file's name, its bytes, other files to write beside it (in the scene folder;
/// a name starting with `../` lands beside the folder), and the pattern of the error (`None`: it
/// must load).
struct Case {
    mesh: &'static str,
    bytes: Vec<u8>,
    files: Vec<(&'static str, Vec<u8>)>,
    error: Option<&'static str>,
}

fn case(mesh: &'static str, bytes: Vec<u8>, error: &'static str) -> Case {
    Case {
        mesh,
        bytes,
        files: Vec::new(),
        error: Some(error),
    }
}

/// A `.gltf` whose buffer's `uri` is `uri`, beside `files`.
fn with_uri(uri: &str, files: Vec<(&'static str, Vec<u8>)>, error: Option<&'static str>) -> Case {
    Case {
        mesh: "m.gltf",
        bytes: card_json(Some(uri)).into_bytes(),
        files,
        error,
    }
}

#[test]
fn hostile_gltf_and_glb_files_get_one_error_naming_the_field() {
    let buffer = card_buffer(&INDICES);
    let mut cases = vec![
        // Controls: these load.
        Case {
            mesh: "good.glb",
            bytes: good_glb(),
            files: Vec::new(),
            error: None,
        },
        with_uri(
            "my%20buffer.bin",
            vec![("my buffer.bin", buffer.clone())],
            None,
        ),
        with_uri("plain.bin", vec![("plain.bin", buffer.clone())], None),
        with_uri(
            "sub%2Fin%20sub.bin",
            vec![("sub/in sub.bin", buffer.clone())],
            None,
        ),
        // GLB header: magic, version, length.
        case(
            "short.glb",
            b"glTF\x02\0\0\0".to_vec(),
            "*/short.glb: GLB header: value \"8 bytes\": expected the 12-byte GLB header (magic, version, length): the file is truncated",
        ),
        case(
            "magic.glb",
            {
                let mut b = good_glb();
                b[3] = b'X';
                b
            },
            "*/magic.glb: GLB header, magic: value \"glTX (0x58546c67)\": expected glTF (0x46546c67): a .glb file starts with the binary glTF magic*",
        ),
        case(
            "json-named.glb",
            card_json(None).into_bytes(),
            "*/json-named.glb: GLB header, magic: value \"{*(0x*)\": expected glTF (0x46546c67)*",
        ),
        case(
            "version.glb",
            {
                let mut b = good_glb();
                set_u32(&mut b, 4, 1);
                b
            },
            "*/version.glb: GLB header, version: value \"1\": expected 2 (binary glTF 2.0)",
        ),
        case(
            "long.glb",
            {
                let mut b = good_glb();
                let n = b.len() as u32;
                set_u32(&mut b, 8, n + 100);
                b
            },
            "*/long.glb: GLB header, length: value \"* bytes\": expected the file's size, * bytes: the file is truncated",
        ),
        // Below the header's own 12 bytes (the gltf crate would subtract 12 from it unchecked).
        case(
            "tiny-length.glb",
            {
                let mut b = good_glb();
                set_u32(&mut b, 8, 4);
                b
            },
            "*/tiny-length.glb: GLB header, length: value \"4 bytes\": expected the file's size, * bytes: the file is longer than its header says",
        ),
        case(
            "trailing.glb",
            {
                let mut b = good_glb();
                b.extend_from_slice(&[0; 16]);
                b
            },
            "*/trailing.glb: GLB header, length: value \"* bytes\": * the file is longer than its header says",
        ),
        // Chunk headers.
        case(
            "no-chunk.glb",
            {
                let mut b = good_glb();
                b.truncate(12);
                set_u32(&mut b, 8, 12);
                b
            },
            "*/no-chunk.glb: GLB chunk 0 (JSON), header: value \"0 bytes\": expected an 8-byte chunk header (length, type)",
        ),
        case(
            "json-type.glb",
            {
                let mut b = good_glb();
                b[16..20].copy_from_slice(b"BIN\0");
                b
            },
            "*/json-type.glb: GLB chunk 0 (JSON), type: value \"BIN\\\\x00 (0x004e4942)\": expected JSON (0x4e4f534a): chunk 0 holds the glTF JSON",
        ),
        case(
            "json-length.glb",
            {
                let mut b = good_glb();
                set_u32(&mut b, 12, 1 << 30);
                b
            },
            "*/json-length.glb: GLB chunk 0 (JSON), length: value \"1073741824 bytes\": expected at most the * bytes left in the file",
        ),
        case(
            "bin-type.glb",
            {
                let mut b = good_glb();
                let at = bin_at();
                b[at + 4..at + 8].copy_from_slice(b"JSON");
                b
            },
            "*/bin-type.glb: GLB chunk 1 (BIN), type: value \"JSON (0x4e4f534a)\": expected BIN\\x00 (0x004e4942): chunk 1 holds the binary buffer",
        ),
        case(
            "bin-length.glb",
            {
                let mut b = good_glb();
                set_u32(&mut b, bin_at(), u32::MAX);
                b
            },
            "*/bin-length.glb: GLB chunk 1 (BIN), length: value \"4294967295 bytes\": expected at most the * bytes left in the file",
        ),
        case(
            "bin-header.glb",
            {
                let mut b = good_glb();
                b.truncate(bin_at() + 4);
                let n = b.len() as u32;
                set_u32(&mut b, 8, n);
                b
            },
            "*/bin-header.glb: GLB chunk 1 (BIN), header: value \"4 bytes\": expected an 8-byte chunk header (length, type)",
        ),
        case(
            "no-bin.glb",
            glb(card_json(None).as_bytes(), None),
            "*/no-bin.glb: buffer 0: value \"no binary chunk\": expected the GLB's binary chunk*",
        ),
        // Buffer URIs: percent-encoding, schemes, queries, confinement of the decoded path.
        with_uri(
            "bad%zzname.bin",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"bad%zzname.bin\": invalid percent-encoding \"%zz\" at character 3: expected % and two hex digits*",
            ),
        ),
        with_uri(
            "cut%2",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"cut%2\": invalid percent-encoding \"%2\" at character 3*",
            ),
        ),
        with_uri(
            "nul%00.bin",
            vec![],
            Some("*/m.gltf: buffer 0, uri: value \"nul%00.bin\": percent-decodes to a NUL byte*"),
        ),
        with_uri(
            "%ff.bin",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"%ff.bin\": percent-decodes to bytes that are not UTF-8*",
            ),
        ),
        with_uri(
            "http://example.com/b.bin",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"http://example.com/b.bin\": expected a file path relative to the glTF file, or a data: URI; a http: URI is not read",
            ),
        ),
        with_uri(
            "file:///etc/passwd",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"file:///etc/passwd\": * a file: URI is not read",
            ),
        ),
        with_uri(
            "b.bin#part",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"b.bin#part\": expected a file path: \"#\" at character 5 starts a URI query or fragment*",
            ),
        ),
        with_uri(
            "%2e%2e%2fsecret.bin",
            vec![("../secret.bin", buffer.clone())],
            Some(
                "*/m.gltf: buffer 0, uri: value \"%2e%2e%2fsecret.bin\": resolves to */secret.bin, outside the scene file's folder *",
            ),
        ),
        with_uri(
            "%2E%2E/secret.bin",
            vec![("../secret.bin", buffer.clone())],
            Some(
                "*/m.gltf: buffer 0, uri: value \"%2E%2E/secret.bin\": resolves to */secret.bin, outside the scene file's folder *",
            ),
        ),
        with_uri(
            "%2fetc%2fpasswd",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"%2fetc%2fpasswd\": resolves to /etc/passwd, outside the scene file's folder *",
            ),
        ),
        with_uri(
            "missing%20file.bin",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri = \"missing%20file.bin\": */scene/missing file.bin: file: value \"*\": cannot be read: No such file or directory*",
            ),
        ),
        with_uri(
            "dev%2fzero.bin",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri: value \"dev%2fzero.bin\": resolves to /dev/zero, outside the scene file's folder *",
            ),
        ),
        with_uri(
            "pipe%20b.bin",
            vec![],
            Some(
                "*/m.gltf: buffer 0, uri = \"pipe%20b.bin\": */scene/pipe b.bin: file: *: is a special file (a FIFO, socket or device), not a regular file*",
            ),
        ),
    ];
    // A `.glb` that is a FIFO: refused before it is opened.
    cases.push(case(
        "fifo.glb",
        Vec::new(),
        "*/fifo.glb: file: *: is a special file (a FIFO, socket or device), not a regular file*",
    ));
    let mut failures = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        let dir = common::fresh_dir("gltf-hostile", &i.to_string());
        let scene = scene_naming(&dir, c.mesh);
        let folder = dir.join("scene");
        if c.mesh == "fifo.glb" {
            let made = std::process::Command::new("mkfifo")
                .arg(folder.join(c.mesh))
                .status()
                .expect("mkfifo runs");
            assert!(made.success());
        } else {
            write(&folder, c.mesh, &c.bytes);
        }
        for (name, bytes) in &c.files {
            let path = folder.join(name);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, bytes).unwrap();
        }
        if c.error.is_some_and(|e| e.contains("dev%2fzero")) {
            std::fs::create_dir_all(folder.join("dev")).unwrap();
            std::os::unix::fs::symlink("/dev/zero", folder.join("dev/zero.bin")).unwrap();
        }
        if c.error.is_some_and(|e| e.contains("pipe%20b")) {
            let made = std::process::Command::new("mkfifo")
                .arg(folder.join("pipe b.bin"))
                .status()
                .expect("mkfifo runs");
            assert!(made.success());
        }
        let got = load(&scene);
        let chain = format!(
            "*/scene/s.toml: line 4, column *, field species[0].mesh = {:?}: ",
            c.mesh
        );
        match (&got, c.error) {
            (Ok(n), None) => assert_eq!(*n, INDICES.len(), "{}", c.mesh),
            (Err(e), Some(pattern)) => {
                let pattern = format!("{chain}{pattern}");
                if e.lines().count() != 1 || !matches(&pattern, e) {
                    failures.push(format!("{}:\n  got      {e}\n  expected {pattern}", c.mesh));
                }
            }
            (got, want) => failures.push(format!("{}: got {got:?}, expected {want:?}", c.mesh)),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_pattern_matcher_matches_only_what_it_should() {
    assert!(matches("a*c", "abc") && matches("a*c", "ac") && matches("*", "x"));
    assert!(matches("a*b*c", "a1b2c") && !matches("a*b*c", "a1c"));
    assert!(!matches("a*c", "abcd") && !matches("abc", "abcd") && !matches("x*", "abc"));
    assert!(!matches("ab*ba", "aba"), "the two ends do not share text");
}
