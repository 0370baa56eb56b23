//! Helpers shared by the file-based loader tests (`reference/tests/scene_loading.rs`) and the
//! command-line tests of `experiments/tests/cli_*.rs` (which include this file by `#[path]`):
//! temporary case folders, files written into them, and the PNG/glTF byte builders. Standard
//! library only, so that every test binary can include it. Not every binary uses every helper.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A fresh directory under the system temp dir, unique to this process: `forestlod-{tag}-{pid}-{name}`.
pub fn fresh_dir(tag: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("forestlod-{tag}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `bytes` to `dir/name` and returns that path.
pub fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The instance-table header line.
pub const HEADER: &str = "x,y,z,yaw,scale,species\n";

/// CRC-32 (ISO 3309, as PNG chunks use), bit by bit.
pub fn crc32(bytes: &[u8]) -> u32 {
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

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
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

/// A glTF 2.0 JSON file with one embedded base64 buffer: `positions` (float VEC3), `uvs` (float
/// VEC2), `indices` (unsigned short), primitive `mode`.
pub fn gltf_json(positions: &[[f32; 3]], uvs: &[[f32; 2]], indices: &[u16], mode: u32) -> String {
    let mut buf: Vec<u8> = Vec::new();
    for c in positions.iter().flatten() {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    let uv_at = buf.len();
    for c in uvs.iter().flatten() {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    let index_at = buf.len();
    for i in indices {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    while !buf.len().is_multiple_of(4) {
        buf.push(0);
    }
    format!(
        r#"{{"asset":{{"version":"2.0"}},
"buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pl}}},{{"buffer":0,"byteOffset":{uv_at},"byteLength":{tl}}},{{"buffer":0,"byteOffset":{index_at},"byteLength":{il}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}},{{"bufferView":1,"componentType":5126,"count":{nt},"type":"VEC2"}},{{"bufferView":2,"componentType":5123,"count":{ni},"type":"SCALAR"}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"mode":{mode}}}]}}],
"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        len = buf.len(),
        b64 = base64(&buf),
        pl = uv_at,
        tl = index_at - uv_at,
        il = indices.len() * 2,
        n = positions.len(),
        nt = uvs.len(),
        ni = indices.len(),
    )
}

/// A card, Y up as glTF has it: 2 m tall.
pub const CARD_POSITIONS: [[f32; 3]; 4] = [
    [-1.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 2.0, 0.0],
    [-1.0, 2.0, 0.0],
];
/// The card's texture coordinates (glTF's top-left origin).
pub const CARD_UVS: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];

/// The glTF card (`CARD_POSITIONS`, `CARD_UVS`) with `indices` and primitive `mode`.
pub fn gltf_card(indices: &[u16], mode: u32) -> String {
    gltf_json(&CARD_POSITIONS, &CARD_UVS, indices, mode)
}

/// Runs `command` (its stdin closed, stdout dropped, stderr captured) until it exits or
/// `deadline` passes, when it is killed: `(exit code, stderr)`, or `(None, "<no answer within
/// …>")` past the deadline. The hostile-input tables of issue 28 run every case through it, so a
/// hang fails the case that hangs instead of the whole suite. Stderr is read after exit: the
/// commands under test print one line, far below a pipe's buffer.
pub fn run_with_deadline(
    command: &mut std::process::Command,
    deadline: std::time::Duration,
) -> (Option<i32>, String) {
    use std::process::Stdio;
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run the command");
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
            return (status.code(), err);
        }
        if start.elapsed() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return (None, format!("<no answer within {deadline:?}>"));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}
