//! Fuzzes the TOML scene-file parser (`parse_scene_file`) and everything it loads: the scene file
//! sits in a directory holding a good CSV (`t.csv`), OBJ (`m.obj`) and PNG (`t.png`), so inputs
//! that name them reach the CSV, OBJ and PNG loaders too. No input may panic; an accepted scene
//! must pass `Scene::validate`.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use forestlod_reference::scene::load::parse_scene_file;
use libfuzzer_sys::fuzz_target;

fn scene_dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("forestlod-fuzz-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("t.csv"), "x,y,z,yaw,scale,species\n1,2,3,0,1,0\n").expect("csv");
        std::fs::write(
            dir.join("m.obj"),
            "v -1 0 0\nv 1 0 0\nv 1 0 2\nv -1 0 2\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n",
        )
        .expect("obj");
        let mut png = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut png),
            &[90u8; 4 * 4 * 4],
            4,
            4,
            image::ExtendedColorType::Rgba8,
        )
        .expect("png");
        std::fs::write(dir.join("t.png"), png).expect("png");
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let path = scene_dir().join("fuzz.toml");
    if let Ok(scene) = parse_scene_file(data, &path) {
        scene
            .validate("fuzz.toml")
            .expect("an accepted scene validates");
    }
});
