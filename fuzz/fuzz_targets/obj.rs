//! Fuzzes the OBJ mesh parser (`parse_obj_mesh`, which prescans and then calls `tobj`): no input
//! may panic, and an accepted mesh must pass `TreeMesh::validate` (< 20 triangles, at most 256
//! vertices, finite values, indices in range).
#![no_main]

use forestlod_reference::scene::load::{UpAxis, parse_obj_mesh};
use forestlod_reference::texture::Rgba8Image;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let up = if data.first().is_some_and(|b| b & 1 == 1) {
        UpAxis::Y
    } else {
        UpAxis::Z
    };
    let texture = Rgba8Image::new(4, 4, [1, 2, 3, 4]);
    if let Ok(mesh) = parse_obj_mesh("fuzz", data, "fuzz.obj", up, texture) {
        mesh.validate("fuzz.obj")
            .expect("an accepted mesh validates");
    }
});
