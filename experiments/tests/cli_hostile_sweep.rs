//! Hostile input at the sweep entry points (issue 28): `forestlod sweep FILE --out DIR` and
//! `forestlod sweep merge --out DIR SHARD...`, through the real binary. One table of cases, each
//! for a class of the issue (special files and unbounded reads, settings validated where read and
//! named where written, nothing given twice, work and memory refused up front, `--out`), run with
//! `--out` absent and with `--out` holding an earlier run's file. Every case must, within
//! [`DEADLINE`]:
//! - exit with status 1, with exactly one line on stderr, starting `error:`, matching the case's
//!   pattern (fragments that must appear in this order);
//! - leave `--out` as it was (absent stays absent, an existing one keeps exactly its files);
//! - leave nothing in the child's `$TMPDIR`.
//!
//! Beside it, a stable property test over the pure parser `parse_sweep_toml` (arbitrary text and
//! TOML-shaped token soups: no panic, a refusal names the file on one line, an acceptance is within
//! the limits), the little brother of `fuzz/fuzz_targets/sweep_toml.rs`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

#[path = "../../reference/tests/common/mod.rs"]
mod common;

use forestlod_experiments::sweep::{BUILTIN_SWEEPS, MAX_SWEEP_FRAMES, parse_sweep_toml};

/// Longest a refused case may take (a FIFO read would block forever).
const DEADLINE: Duration = Duration::from_secs(30);

/// A valid small sweep: the cases change one thing of it.
const GOOD: &str = "name = 'hostile'\ntitle = 't'\nscenes = ['tiny']\nwidth = 64\nheight = 48\nsamples = 1\n\n[[cameras]]\nname = 'far'\n\n[[axes]]\nparam = 'grid_size'\nvalues = [50.0, 100.0]\n";

/// Every file under `dir` with its contents (empty when `dir` is absent).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in entries {
        let path = e.unwrap().path();
        let meta = std::fs::symlink_metadata(&path).unwrap();
        if meta.is_dir() {
            out.extend(snapshot(&path));
        } else if meta.is_file() {
            out.insert(path.clone(), std::fs::read(&path).unwrap());
        } else {
            out.insert(path.clone(), b"<special>".to_vec());
        }
    }
    out
}

fn fresh(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("cli-hostile-sweep")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn mkfifo(path: &Path) {
    let made = Command::new("mkfifo").arg(path).status().expect("mkfifo");
    assert!(made.success(), "mkfifo {}", path.display());
}

/// A shard manifest (`sweep.json`) for `sweep merge`, with `edit` applied to its JSON.
fn manifest(edit: impl Fn(&mut serde_json::Value)) -> String {
    let mut m = serde_json::json!({
        "name": "hostile", "title": "t", "description": "", "quick": true, "x_axis": "yaw",
        "scenes": ["tiny"], "variants": ["ours"], "backends": ["reference"],
        "width": 64, "height": 48, "ground_truth_spp": 1, "frames": 0,
        "csv": "hostile.csv", "plots": [], "images": [], "wall_seconds": 0.0,
        "ground_truth_bvh": [], "ground_truth_rays": 0, "shard": "0/1",
    });
    edit(&mut m);
    m.to_string()
}

/// A shard folder `dir/shard` holding sweep `hostile` with manifest `json` and an empty CSV.
fn shard(dir: &Path, json: &str) -> String {
    let sub = dir.join("shard").join("hostile");
    std::fs::create_dir_all(sub.join("img")).unwrap();
    std::fs::write(sub.join("sweep.json"), json).unwrap();
    std::fs::write(sub.join("hostile.csv"), "frame,sweep\n").unwrap();
    dir.join("shard").display().to_string()
}

/// One hostile case: `setup` writes its files into the case folder and returns the arguments
/// after `forestlod sweep` (without `--out`); the error line must contain `pattern`'s fragments
/// in order.
struct Case {
    name: &'static str,
    setup: fn(&Path) -> Vec<String>,
    pattern: &'static [&'static str],
}

/// A sweep file `s.toml` holding `text`, run as `forestlod sweep s.toml`.
fn sweep_file(dir: &Path, text: &str) -> Vec<String> {
    let p = dir.join("s.toml");
    std::fs::write(&p, text).unwrap();
    vec![p.display().to_string()]
}

/// [`GOOD`] with `old` replaced by `new` (which must occur).
fn good_with(old: &str, new: &str) -> String {
    assert!(GOOD.contains(old), "{old}");
    GOOD.replacen(old, new, 1)
}

fn cases() -> Vec<Case> {
    vec![
        // Special files and unbounded reads.
        Case {
            name: "fifo as sweep file",
            setup: |d| {
                let p = d.join("s.toml");
                mkfifo(&p);
                vec![p.display().to_string()]
            },
            pattern: &["s.toml", "special file", "not a regular file"],
        },
        Case {
            name: "link to /dev/zero as sweep file",
            setup: |d| {
                let p = d.join("zero.toml");
                std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
                vec![p.display().to_string()]
            },
            pattern: &["zero.toml", "special file"],
        },
        Case {
            name: "folder as sweep file",
            setup: |d| {
                let p = d.join("dir.toml");
                std::fs::create_dir_all(&p).unwrap();
                vec![p.display().to_string()]
            },
            pattern: &["dir.toml", "a folder"],
        },
        Case {
            name: "oversized sweep file",
            setup: |d| sweep_file(d, &format!("{GOOD}#{}\n", "x".repeat(1 << 20))),
            pattern: &["s.toml", "file size", "limit of 1048576 bytes"],
        },
        Case {
            name: "sweep file not UTF-8",
            setup: |d| {
                let p = d.join("s.toml");
                std::fs::write(&p, b"name = '\xff'\n").unwrap();
                vec![p.display().to_string()]
            },
            pattern: &["s.toml", "byte 8", "not UTF-8"],
        },
        Case {
            name: "missing sweep file",
            setup: |d| vec![d.join("absent.toml").display().to_string()],
            pattern: &["absent.toml", "does not exist", "built-in sweep name"],
        },
        Case {
            name: "fifo as a scene of the sweep",
            setup: |d| {
                let scene = d.join("fifo.toml");
                mkfifo(&scene);
                let text = good_with("'tiny'", &format!("'{}'", scene.display()));
                sweep_file(d, &text)
            },
            pattern: &["fifo.toml", "not a regular file"],
        },
        // Validated where read, named where written: file, line, column, key, value.
        Case {
            name: "TOML syntax",
            setup: |d| sweep_file(d, &good_with("width = 64", "width = = 64")),
            pattern: &["s.toml: line 4, column", "invalid sweep file"],
        },
        Case {
            name: "duplicate TOML key",
            setup: |d| sweep_file(d, &good_with("height = 48", "height = 48\nheight = 96")),
            pattern: &["s.toml: line 6, column 1", "duplicate key"],
        },
        Case {
            name: "unknown field",
            setup: |d| sweep_file(d, &format!("colour = 3\n{GOOD}")),
            pattern: &["s.toml: line 1", "unknown field `colour`"],
        },
        Case {
            name: "axis value out of range",
            setup: |d| sweep_file(d, &good_with("[50.0, 100.0]", "[50.0, -1.0]")),
            pattern: &[
                "s.toml: line 13, column 17, key axes[0].values[1]",
                "value \"-1.0\"",
                "parameter grid_size",
            ],
        },
        Case {
            name: "NaN in [params]",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("samples = 1", "samples = 1\nparams = { fade_width = nan }"),
                )
            },
            pattern: &[
                "s.toml: line 7, column",
                "key params.fade_width",
                "\"nan\"",
                "parameter fade_width",
            ],
        },
        Case {
            name: "setting with a bad value",
            setup: |d| {
                sweep_file(
                    d,
                    &format!("{GOOD}\n[[settings]]\nlabel = 'a'\ntexture_size = 100\n"),
                )
            },
            pattern: &[
                "s.toml: line 17, column 16, key settings[0].texture_size",
                "\"100\"",
                "power of two",
            ],
        },
        Case {
            name: "width as a float",
            setup: |d| sweep_file(d, &good_with("width = 64", "width = 64.5")),
            pattern: &["s.toml: line 4, column", "invalid type: floating point"],
        },
        Case {
            name: "negative yaw steps",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("name = 'far'", "name = 'far'\nyaw_steps = -2"),
                )
            },
            pattern: &[
                "s.toml: line 10, column 13, key cameras[0].yaw_steps",
                "\"-2\"",
                "expected u32",
            ],
        },
        Case {
            name: "name leaving --out",
            setup: |d| sweep_file(d, &good_with("name = 'hostile'", "name = '../escape'")),
            pattern: &[
                "s.toml: line 1, column 8, key name",
                "\"../escape\"",
                "output folder",
            ],
        },
        Case {
            name: "distance not finite",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("name = 'far'", "name = 'distance'\ndistances = [0.0, inf]"),
                )
            },
            pattern: &[
                "s.toml: line 10, column",
                "key cameras[0].distances[1]",
                "inf",
                "finite distance",
            ],
        },
        Case {
            name: "yaw steps on the distance camera",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with(
                        "name = 'far'",
                        "name = 'distance'\ndistances = [0.0]\nyaw_steps = 4",
                    ),
                )
            },
            pattern: &[
                "s.toml: line 11, column 1, key cameras[0].yaw_steps",
                "would ignore it",
            ],
        },
        Case {
            name: "x_axis names nothing",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("samples = 1", "samples = 1\nx_axis = 'texture_size'"),
                )
            },
            pattern: &[
                "s.toml: line 7, column 10, key x_axis",
                "\"texture_size\"",
                "axis",
            ],
        },
        Case {
            name: "[quick] axis names no axis",
            setup: |d| {
                sweep_file(
                    d,
                    &format!("{GOOD}\n[quick]\naxes = {{ angle_count = [2] }}\n"),
                )
            },
            pattern: &[
                "s.toml: line 16, column 10, key quick.axes.angle_count",
                "names no axis",
            ],
        },
        Case {
            name: "[quick] value refused",
            setup: |d| sweep_file(d, &format!("{GOOD}\n[quick]\nwidth = 0\n")),
            pattern: &["s.toml: line 16, column 9, key quick.width", "positive"],
        },
        // Nothing given twice.
        Case {
            name: "axis given twice by another spelling",
            setup: |d| {
                sweep_file(
                    d,
                    &format!("{GOOD}\n[[axes]]\nparam = 'grid-size'\nvalues = [10.0]\n"),
                )
            },
            pattern: &[
                "s.toml: line 16, column 9, key axes[1].param",
                "\"grid-size\"",
                "given twice",
            ],
        },
        Case {
            name: "parameter given twice in [params]",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with(
                        "samples = 1",
                        "samples = 1\nparams = { fade_width = 10.0, fade-width = 20.0 }",
                    ),
                )
            },
            pattern: &["s.toml: line 7", "key params.", "fade_width given twice"],
        },
        Case {
            name: "setting sets an axis",
            setup: |d| {
                sweep_file(
                    d,
                    &format!("{GOOD}\n[[settings]]\nlabel = 'a'\ngrid_size = 7.0\n"),
                )
            },
            pattern: &[
                "s.toml: line 17, column 1, key settings[0].grid_size",
                "also axes[0]",
            ],
        },
        Case {
            name: "[params] sets an axis",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("samples = 1", "samples = 1\nparams = { grid_size = 7.0 }"),
                )
            },
            pattern: &[
                "s.toml: line 7, column 12, key params.grid_size",
                "also axes[0]",
            ],
        },
        Case {
            name: "axis value given twice",
            setup: |d| sweep_file(d, &good_with("[50.0, 100.0]", "[50, 100.0, 50.0]")),
            pattern: &[
                "s.toml: line 13, column 22, key axes[0].values[2]",
                "given twice (also values[0])",
            ],
        },
        Case {
            name: "setting label given twice",
            setup: |d| {
                sweep_file(
                    d,
                    &format!("{GOOD}\n[[settings]]\nlabel = 'a'\n[[settings]]\nlabel = 'a'\n"),
                )
            },
            pattern: &[
                "s.toml: line 18, column 9, key settings[1].label",
                "given twice",
            ],
        },
        Case {
            name: "resolutions beside width",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("samples = 1", "samples = 1\nresolutions = [[64, 48]]"),
                )
            },
            pattern: &["s.toml: line 4, column 1, key width", "size given twice"],
        },
        Case {
            name: "camera given twice",
            setup: |d| sweep_file(d, &format!("{GOOD}\n[[cameras]]\nname = 'far'\n")),
            pattern: &[
                "s.toml: line 16, column 8, key cameras[1].name",
                "given twice",
            ],
        },
        // Work and memory refused up front, with the estimate and the limit.
        Case {
            name: "too many frames",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("name = 'far'", "name = 'far'\nyaw_steps = 4000000000"),
                )
            },
            pattern: &[
                "s.toml: sweep size",
                "8000000000 frames",
                "limit of 100000",
                "MAX_SWEEP_FRAMES",
            ],
        },
        Case {
            name: "sizes whose product overflows",
            setup: |d| {
                let mut t = "name = 'o'\ntitle = 't'\nscenes = ['tiny']\nwidth = 8192\nheight = 8192\nsamples = 4000000000\nrepeats = 4000000000\ntotal_error = false\n".to_string();
                for c in ["far", "medium", "close"] {
                    t += &format!("[[cameras]]\nname = '{c}'\nyaw_steps = 4000000000\n");
                }
                for i in 0..40 {
                    t += &format!("[[settings]]\nlabel = 's{i}'\n");
                }
                sweep_file(d, &t)
            },
            pattern: &["s.toml: sweep size", "overflows 128 bits"],
        },
        Case {
            name: "too many pixels",
            setup: |d| {
                let t = good_with(
                    "width = 64\nheight = 48",
                    "width = 8192\nheight = 8192\ntotal_error = false",
                );
                sweep_file(
                    d,
                    &t.replace("name = 'far'", "name = 'far'\nyaw_steps = 10000"),
                )
            },
            pattern: &["s.toml: sweep size", "pixels", "MAX_SWEEP_PIXEL_WORK"],
        },
        Case {
            name: "frame memory",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with("width = 64\nheight = 48", "width = 8192\nheight = 8192"),
                )
            },
            pattern: &[
                "s.toml: sweep size",
                "GiB",
                "one frame's memory",
                "MAX_FRAME_BYTES",
            ],
        },
        Case {
            name: "billboard memory",
            setup: |d| {
                sweep_file(
                    d,
                    &good_with(
                        "samples = 1",
                        "samples = 1\nparams = { texture_size = 4096, angle_count = 91 }",
                    ),
                )
            },
            pattern: &[
                "s.toml: sweep size",
                "GiB",
                "angle_count = 91, texture_size = 4096",
                "MAX_BILLBOARD_BYTES = MAX_BAKE_BYTES",
            ],
        },
        Case {
            name: "ground-truth memory",
            setup: |d| {
                let t = good_with(
                    "width = 64\nheight = 48",
                    "width = 1280\nheight = 720\ntotal_error = false",
                );
                sweep_file(
                    d,
                    &t.replace("name = 'far'", "name = 'far'\nyaw_steps = 40000")
                        .replace("[50.0, 100.0]", "[50.0]"),
                )
            },
            pattern: &[
                "s.toml: sweep size",
                "ground-truth images",
                "MAX_TRUTH_BYTES",
            ],
        },
        Case {
            name: "frame side",
            setup: |d| sweep_file(d, &good_with("width = 64", "width = 100000")),
            pattern: &[
                "s.toml: line 4, column 9, key width",
                "100000x48",
                "MAX_FRAME_SIDE",
            ],
        },
        // Errors name the flag.
        Case {
            name: "--width too large for the total error",
            setup: |d| {
                let mut a = sweep_file(d, GOOD);
                a.extend([
                    "--width".into(),
                    "8000".into(),
                    "--samples".into(),
                    "2".into(),
                ]);
                a
            },
            pattern: &[
                "<command line>: --width --samples",
                "16000",
                "<sweep hostile>",
            ],
        },
        Case {
            name: "--yaw-steps too many frames",
            setup: |d| {
                let mut a = sweep_file(d, GOOD);
                a.extend(["--yaw-steps".into(), "4000000000".into()]);
                a
            },
            pattern: &["<command line>: --yaw-steps", "frames", "MAX_SWEEP_FRAMES"],
        },
        // --out.
        Case {
            name: "--out is a file",
            setup: |d| {
                let mut a = sweep_file(d, GOOD);
                let f = d.join("file-out");
                std::fs::write(&f, "x").unwrap();
                a.extend(["--out".into(), f.display().to_string()]);
                a
            },
            pattern: &["<command line>: --out", "file-out", "not a folder"],
        },
        Case {
            name: "--out is a dangling link",
            setup: |d| {
                let mut a = sweep_file(d, GOOD);
                let l = d.join("dangling-out");
                std::os::unix::fs::symlink(d.join("nowhere"), &l).unwrap();
                a.extend(["--out".into(), l.display().to_string()]);
                a
            },
            pattern: &["<command line>: --out", "dangling-out", "dangling link"],
        },
        // sweep merge: what it reads from the shards.
        Case {
            name: "merge: sweep.json a FIFO",
            setup: |d| {
                let sub = d.join("shard").join("hostile");
                std::fs::create_dir_all(&sub).unwrap();
                mkfifo(&sub.join("sweep.json"));
                vec!["merge".into(), d.join("shard").display().to_string()]
            },
            pattern: &["sweep.json", "not a regular file"],
        },
        Case {
            name: "merge: sweep.json oversized",
            setup: |d| {
                let json = manifest(|m| m["description"] = "x".repeat(17 << 20).into());
                vec!["merge".into(), shard(d, &json)]
            },
            pattern: &["sweep.json", "file size", "limit of"],
        },
        Case {
            name: "merge: name leaving --out",
            setup: |d| {
                vec![
                    "merge".into(),
                    shard(d, &manifest(|m| m["name"] = "../../x".into())),
                ]
            },
            pattern: &["sweep.json: key name", "\"../../x\"", "output folder"],
        },
        Case {
            name: "merge: csv outside the shard",
            setup: |d| {
                vec![
                    "merge".into(),
                    shard(d, &manifest(|m| m["csv"] = "../../etc/passwd.csv".into())),
                ]
            },
            pattern: &["sweep.json: key csv", "NAME.csv"],
        },
        Case {
            name: "merge: image outside the shard",
            setup: |d| {
                let json = manifest(|m| {
                    m["images"] = serde_json::json!([{
                        "camera": "far", "yaw_deg": 0.0, "distance_m": 0.0, "variant": "ours",
                        "setting": "default", "color": format!("img/{}etc/passwd", "../".repeat(40)), "lod": "",
                        "flip": "", "per_lod": [], "ground_truth": "", "ground_truth_class": "",
                        "accuracy": forestlod_experiments::metrics::Accuracy::default(),
                    }])
                });
                vec!["merge".into(), shard(d, &json)]
            },
            pattern: &[
                "sweep.json: key images[0].color",
                "without `..`",
                "reads only its shards",
            ],
        },
        Case {
            name: "merge: an absurd shard count",
            setup: |d| {
                vec![
                    "merge".into(),
                    shard(d, &manifest(|m| m["shard"] = "0/1000000000000".into())),
                ]
            },
            pattern: &[
                "sweep merge",
                "hostile 1/1000000000000",
                "999999999999 shards are missing",
            ],
        },
        Case {
            name: "merge: a bad sweep definition",
            setup: |d| {
                let spec = parse_sweep_toml(GOOD, "g").unwrap();
                let mut spec = serde_json::to_value(&spec).unwrap();
                spec["samples"] = 0.into();
                vec![
                    "merge".into(),
                    shard(d, &manifest(|m| m["spec"] = spec.clone())),
                ]
            },
            pattern: &["sweep.json: key spec", "key samples", "positive"],
        },
    ]
}

/// Runs `forestlod sweep ARGS` under [`DEADLINE`] with a fresh `$TMPDIR`, returning its exit
/// code and stderr; the child is killed at the deadline.
fn run_child(args: &[String], tmp: &Path) -> (Option<i32>, String) {
    common::run_with_deadline(
        Command::new(env!("CARGO_BIN_EXE_forestlod"))
            .arg("sweep")
            .args(args)
            .env("TMPDIR", tmp)
            .env("RUST_BACKTRACE", "0"),
        DEADLINE,
    )
}

/// Whether `line` contains every fragment of `pattern`, in order.
fn matches(line: &str, pattern: &[&str]) -> bool {
    let mut rest = line;
    for f in pattern {
        match rest.find(f) {
            Some(i) => rest = &rest[i + f.len()..],
            None => return false,
        }
    }
    true
}

#[test]
fn hostile_sweep_input_is_refused_with_one_line_and_nothing_left() {
    let mut failures = Vec::new();
    for (i, case) in cases().into_iter().enumerate() {
        // A case that gives its own `--out` runs once; the checks of that path are its own.
        let own_out = (case.setup)(&fresh("probe")).iter().any(|a| a == "--out");
        for existing in [false, true] {
            if own_out && existing {
                continue;
            }
            let dir = fresh(&format!("{i}-{existing}"));
            let tmp = dir.join("tmp");
            std::fs::create_dir_all(&tmp).unwrap();
            let mut args = (case.setup)(&dir);
            let out = match args.iter().position(|a| a == "--out") {
                Some(i) => PathBuf::from(&args[i + 1]),
                None => dir.join("out"),
            };
            let out_meta = |p: &Path| {
                std::fs::symlink_metadata(p)
                    .map(|m| (m.file_type(), m.len()))
                    .ok()
            };
            let given = out_meta(&out);
            if !own_out {
                if existing {
                    std::fs::create_dir_all(&out).unwrap();
                    std::fs::write(out.join("earlier.csv"), "an earlier run").unwrap();
                }
                args.extend(["--out".into(), out.display().to_string()]);
            }
            let before = snapshot(&out);
            let (code, stderr) = run_child(&args, &tmp);
            let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
            let what = format!(
                "{} (out {}): {stderr:?}",
                case.name,
                if existing { "existing" } else { "absent" }
            );
            if code != Some(1) {
                failures.push(format!("{what}: exit {code:?}, expected 1"));
            } else if lines.len() != 1 || !lines[0].starts_with("error: ") {
                failures.push(format!("{what}: expected one line starting `error: `"));
            } else if !matches(lines[0], case.pattern) {
                failures.push(format!("{what}: does not match {:?}", case.pattern));
            }
            if own_out {
                if out_meta(&out).map(|m| format!("{m:?}")) != given.map(|m| format!("{m:?}")) {
                    failures.push(format!("{what}: the given --out changed"));
                }
            } else if out.exists() != existing || snapshot(&out) != before {
                failures.push(format!("{what}: --out changed"));
            }
            let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
            if !left.is_empty() {
                failures.push(format!("{what}: {} entries left in TMPDIR", left.len()));
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Every built-in sweep passes the load-time checks, in full and in quick mode (the parser checks
/// both), and the checks measure what the runner will do: the frames are within the limit.
#[test]
fn every_builtin_sweep_passes_the_load_checks() {
    for (name, text) in BUILTIN_SWEEPS {
        let spec = parse_sweep_toml(text, name).unwrap_or_else(|e| panic!("{name}: {e}"));
        for s in [spec.clone(), spec.quick()] {
            let frames = s.param_sets(name).unwrap().len()
                * s.poses().len()
                * s.scenes.len()
                * s.variants.len()
                * s.backends.len();
            assert!(frames as u128 <= MAX_SWEEP_FRAMES, "{name}: {frames}");
        }
    }
}

mod properties {
    use proptest::prelude::*;

    use super::*;

    /// Pieces of sweep files: keys, values (good, out of range, non-finite, huge), brackets,
    /// table headers and line breaks.
    const TOKENS: &[&str] = &[
        "name",
        "title",
        "scenes",
        "cameras",
        "axes",
        "param",
        "values",
        "settings",
        "label",
        "quick",
        "width",
        "height",
        "samples",
        "repeats",
        "yaw_steps",
        "steps",
        "distances",
        "resolutions",
        "x_axis",
        "params",
        "grid_size",
        "grid-size",
        "texture_size",
        "angle_count",
        "fade_mode",
        "total_error",
        "truth_tiles",
        "backends",
        "variants",
        " = ",
        "=",
        "'tiny'",
        "'far'",
        "'distance'",
        "'orbit'",
        "'x'",
        "'../x'",
        "'gpu'",
        "'ours'",
        "0",
        "1",
        "-1",
        "4096",
        "91",
        "4000000000",
        "1e300",
        "nan",
        "inf",
        "-0.0",
        "2.5",
        "true",
        "[",
        "]",
        "[[",
        "]]",
        "{",
        "}",
        ",",
        "\n",
        "[[cameras]]\n",
        "[[axes]]\n",
        "[[settings]]\n",
        "[quick]\n",
        "[params]\n",
        "\"",
        "'",
        "#",
        ".",
    ];

    fn soup() -> impl Strategy<Value = String> {
        prop::collection::vec(prop::sample::select(TOKENS), 0..80).prop_map(|t| t.join(" "))
    }

    fn check(text: &str) {
        match parse_sweep_toml(text, "p.toml") {
            Ok(spec) => {
                spec.validate("p.toml")
                    .expect("accepted sweeps validate again");
                let sets = spec.param_sets("p.toml").unwrap();
                assert!(!sets.is_empty() && !spec.poses().is_empty());
                assert!((sets.len() * spec.poses().len()) as u128 <= MAX_SWEEP_FRAMES);
            }
            Err(e) => {
                let line = e.to_string();
                assert!(line.starts_with("p.toml: "), "{line}");
                assert!(!line.contains('\n'), "{line}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn arbitrary_text_never_panics(text in ".{0,300}") {
            check(&text);
        }

        #[test]
        fn token_soups_never_panic(text in soup()) {
            check(&text);
        }

        /// A valid sweep with a soup appended (reaching the checks past the syntax).
        #[test]
        fn a_good_sweep_with_a_soup_appended(tail in soup()) {
            check(&format!("{GOOD}{tail}"));
        }

        /// A valid sweep with one line replaced by a soup.
        #[test]
        fn a_good_sweep_with_a_line_replaced(line in 0usize..14, soup in soup()) {
            let mut lines: Vec<&str> = GOOD.lines().collect();
            let at = line.min(lines.len() - 1);
            lines[at] = &soup;
            check(&lines.join("\n"));
        }
    }
}
