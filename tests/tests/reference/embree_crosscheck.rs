//! obvhs against Embree (SPEC §10: "embreex cross-checks obvhs hits on the same triangles").
//!
//! The ground truth ([`forestlod_reference::ground_truth`]) traces rays through obvhs's BVH with
//! its own watertight leaf test (Woop, Benthin and Wald 2013). This test dumps
//! the `tiny` scene's triangles (every tree and the ground, as the ground truth places them), a few
//! thousand rays (primary rays of the `medium` and `close` cameras plus seeded random rays inside
//! the forest) and the truth's nearest hits (geometric query: no alpha test) to a file, then runs
//! `experiments/embree_check/check.py FILE`, which casts the same rays with Embree 4 (the `embreex`
//! wheel) and passes when hit/miss and distances agree within its stated tolerances, ambiguous
//! edge hits aside (see the script's docstring).
//!
//! If `embreex` is not importable the test installs it (`python3 -m pip install --quiet embreex
//! numpy`) and fails with the install hint if that fails: it never skips. Set
//! `FORESTLOD_EMBREE_FILE=path` to keep the dump.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use forestlod_reference::cameras::named_camera;
use forestlod_reference::ground_truth::{GroundTruthScene, primary_ray};
use forestlod_reference::scene::builtin;

/// Image size of the primary rays per camera.
const CAMERA_RAYS: (u32, u32) = (64, 48);
/// Random rays from inside the forest.
const RANDOM_RAYS: usize = 2048;
/// The query's far end (every ray starts at t = 0).
const T_MAX: f32 = 1.0e30;

fn python_has_embreex() -> bool {
    Command::new("python3")
        .args(["-c", "import embreex, numpy"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

fn ensure_embreex() {
    if python_has_embreex() {
        return;
    }
    let out = Command::new("python3")
        .args(["-m", "pip", "install", "--quiet", "embreex", "numpy"])
        .output();
    match out {
        Ok(o) if o.status.success() && python_has_embreex() => {}
        Ok(o) => panic!(
            "embreex is not importable and `python3 -m pip install --quiet embreex numpy` failed \
             (exit {:?}):\n{}\n{}\nInstall it by hand (SPEC §8: `pip install embreex numpy`).",
            o.status.code(),
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => panic!(
            "cannot run python3 to install embreex: {e}; install python3 and `pip install embreex numpy`"
        ),
    }
}

/// splitmix64, for seeded random rays without another dependency.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn unit(seed: u64) -> f32 {
    (mix(seed) >> 40) as f32 / (1u64 << 24) as f32
}

fn write_dump(path: &Path) -> (usize, usize) {
    let scene = builtin::tiny();
    let gt = GroundTruthScene::build(&scene, 0.5).expect("tiny builds");
    let mut rays: Vec<([f32; 3], [f32; 3])> = Vec::new();
    for name in ["medium", "close"] {
        let camera = named_camera(name, &scene, 30.0, CAMERA_RAYS.0, CAMERA_RAYS.1).unwrap();
        for y in 0..CAMERA_RAYS.1 {
            for x in 0..CAMERA_RAYS.0 {
                rays.push(primary_ray(&camera, x as f32 + 0.5, y as f32 + 0.5));
            }
        }
    }
    let [x0, y0, x1, y1] = scene.bounds;
    for i in 0..RANDOM_RAYS as u64 {
        let o = [
            x0 + (x1 - x0) * unit(6 * i),
            y0 + (y1 - y0) * unit(6 * i + 1),
            1.0 + 40.0 * unit(6 * i + 2),
        ];
        // Uniform on the sphere.
        let z = 2.0 * unit(6 * i + 3) - 1.0;
        let phi = std::f32::consts::TAU * unit(6 * i + 4);
        let r = (1.0 - z * z).max(0.0).sqrt();
        rays.push((o, [r * phi.cos(), r * phi.sin(), z]));
    }
    let tris = gt.triangles();
    let mut bytes: Vec<u8> = Vec::new();
    bytes.extend_from_slice(b"FLEMBRE1");
    bytes.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&(rays.len() as u32).to_le_bytes());
    for t in &tris {
        for v in t {
            for c in v {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for (o, d) in &rays {
        for c in o.iter().chain(d) {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    for _ in &rays {
        bytes.extend_from_slice(&T_MAX.to_le_bytes());
    }
    let hits: Vec<_> = rays
        .iter()
        .map(|(o, d)| gt.trace(*o, *d, 0.0, T_MAX, false))
        .collect();
    for h in &hits {
        let t = h.map_or(f32::INFINITY, |h| h.t);
        bytes.extend_from_slice(&t.to_le_bytes());
    }
    for h in &hits {
        let id = h.map_or(u32::MAX, |h| h.triangle);
        bytes.extend_from_slice(&id.to_le_bytes());
    }
    let mut f = std::fs::File::create(path).expect("create the dump");
    f.write_all(&bytes).expect("write the dump");
    (tris.len(), rays.len())
}

#[test]
fn obvhs_hits_agree_with_embree_on_the_tiny_forest() {
    ensure_embreex();
    let path: PathBuf = std::env::var_os("FORESTLOD_EMBREE_FILE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            std::env::temp_dir().join(format!("forestlod-embree-{}.bin", std::process::id()))
        });
    let (tris, rays) = write_dump(&path);
    eprintln!(
        "wrote {tris} triangles and {rays} rays to {}",
        path.display()
    );
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../experiments/embree_check/check.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(&path)
        .output()
        .expect("run python3");
    let stdout = String::from_utf8_lossy(&out.stdout);
    eprintln!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    if std::env::var_os("FORESTLOD_EMBREE_FILE").is_none() {
        let _ = std::fs::remove_file(&path);
    }
    assert!(
        out.status.success(),
        "{} failed (exit {:?}):\n{stdout}",
        script.display(),
        out.status.code()
    );
    assert!(stdout.contains("PASS"));
}
