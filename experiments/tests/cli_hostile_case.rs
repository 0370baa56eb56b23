//! Hostile input at `forestlod verify --case CASE --outputs DIR` and `forestlod check --replay DIR`
//! (issue 28), through the binary: one table per entry point, each row a hostile variant of a
//! real case (a `tiny` case exported at 48², and a replay folder built from it), run under a
//! deadline with `TMPDIR` a fresh folder. Each row states the exit code and a pattern the one
//! error line must match (stderr's `error: ...` for bad input, stdout's verdict line for a
//! parity failure); after each run the child's `TMPDIR` must be empty (a replay used to leave
//! its scratch copy there, and name it in errors).
//!
//! `verify` needs no GPU (it compares files); the replay's positive row needs an adapter
//! (lavapipe in CI), like `cli_check.rs`. Every hostile replay row is refused before an adapter
//! is looked for.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use forestlod_reference::output::{read_depth_exr, read_png, write_depth_exr, write_png};

#[path = "../../reference/tests/common/mod.rs"]
mod common;

/// The deadline of one run (a hang is a failure, not a stuck test).
const DEADLINE: Duration = Duration::from_secs(30);

/// What one run left: exit code, stdout, stderr.
struct Run {
    /// The exit code (`None` when killed at the deadline).
    code: Option<i32>,
    /// What went wrong beside the code and line: a hang, files left in `TMPDIR`.
    problems: Vec<String>,
    /// The child's `TMPDIR`.
    tmp: PathBuf,
    stdout: String,
    stderr: String,
}

impl Run {
    /// The line a row's pattern is matched against: the `error: ` line for bad input, else the
    /// verdict (stdout's last line).
    fn line(&self) -> String {
        if self.code == Some(1) {
            let errors: Vec<&str> = self
                .stderr
                .lines()
                .filter(|l| l.starts_with("error: "))
                .collect();
            match errors[..] {
                [line] => line.to_string(),
                _ => format!("<{} error lines>", errors.len()),
            }
        } else {
            self.stdout.lines().last().unwrap_or("").to_string()
        }
    }
}

/// Runs `forestlod args` with `TMPDIR` = a fresh folder under `work`, under [`DEADLINE`]; asserts
/// that folder is empty afterwards.
fn forestlod(work: &Path, name: &str, args: &[&str]) -> Run {
    let tmp = work.join(format!("tmpdir-{name}"));
    std::fs::create_dir_all(&tmp).unwrap();
    let out = work.join(format!("stdout-{name}"));
    let err = work.join(format!("stderr-{name}"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .env("TMPDIR", &tmp)
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("FORESTLOD_CHECK_BREAK")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .expect("run forestlod");
    let started = Instant::now();
    let mut problems = Vec::new();
    let code = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status.code();
        }
        if started.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            problems.push(format!("no answer within {DEADLINE:?} (killed)"));
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let left: Vec<_> = std::fs::read_dir(&tmp)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    if !left.is_empty() {
        problems.push(format!("left in TMPDIR: {left:?}"));
    }
    Run {
        code,
        problems,
        tmp,
        stdout: std::fs::read_to_string(&out).unwrap(),
        stderr: std::fs::read_to_string(&err).unwrap(),
    }
}

/// Copies a folder tree (regular files and folders only).
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).unwrap();
        }
    }
}

#[cfg(unix)]
fn fifo(path: &Path) {
    let _ = std::fs::remove_file(path);
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
}

#[cfg(unix)]
fn link(target: &str, path: &Path) {
    let _ = std::fs::remove_file(path);
    std::os::unix::fs::symlink(target, path).unwrap();
}

/// Edits a text file in place.
fn edit(path: &Path, f: impl FnOnce(String) -> String) {
    let text = std::fs::read_to_string(path).unwrap();
    let new = f(text.clone());
    assert_ne!(new, text, "{}: the edit changed nothing", path.display());
    std::fs::write(path, new).unwrap();
}

/// A PNG whose header declares `width`x`height` (8-bit RGBA) with a token of image data.
fn png_declaring(width: u32, height: u32) -> Vec<u8> {
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        c.extend_from_slice(&body);
        c.extend_from_slice(&common::crc32(&body).to_be_bytes());
        c
    };
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00]));
    png.extend(chunk(b"IEND", &[]));
    png
}

/// `depth.exr` whose header declares `side`x`side` (its data window patched).
fn exr_declaring(from: &Path, side: i32) -> Vec<u8> {
    let mut bytes = std::fs::read(from).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("dataWindow")
        + key.len()
        + 4;
    bytes[at + 8..at + 12].copy_from_slice(&(side - 1).to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&(side - 1).to_le_bytes());
    bytes
}

/// Exports the `tiny` case at 48² (no GPU needed), once.
fn export_case(work: &Path) -> PathBuf {
    let dir = work.join("case");
    let o = forestlod(
        work,
        "export",
        &[
            "export-case",
            "--scene",
            "tiny",
            "--camera",
            "medium",
            "--grid-size",
            "50",
            "--angles",
            "8",
            "--texture-size",
            "32",
            "--width",
            "48",
            "--height",
            "48",
            "--out",
            dir.to_str().unwrap(),
        ],
    );
    assert_eq!(
        (o.code, &o.problems[..]),
        (Some(0), &[][..]),
        "export-case: {}{}",
        o.stdout,
        o.stderr
    );
    dir
}

/// One hostile row: its name, how it breaks a fresh copy of the case (`CASE`) and outputs
/// (`OUT`, a copy of the reference frame with its commands), the exit code, the pattern.
type Row = (&'static str, Breaks, i32, &'static str);

/// How a row breaks its copies of the case (or replay) and outputs folders.
type Breaks = Box<dyn Fn(&Path, &Path)>;

fn regex(pattern: &str) -> regex::Regex {
    regex::Regex::new(pattern).unwrap()
}

#[test]
fn verify_refuses_hostile_cases_and_outputs_naming_the_file() {
    let work = common::fresh_dir("cli-hostile-case", "verify");
    let case = export_case(&work);
    let json = |f: &'static str, to: &'static str| -> Breaks {
        Box::new(move |c: &Path, _: &Path| edit(&c.join("case.json"), |t| t.replacen(f, to, 1)))
    };
    let set = |pointer: &'static str, value: serde_json::Value| -> Breaks {
        Box::new(move |c: &Path, _: &Path| {
            edit(&c.join("case.json"), |t| {
                let mut v: serde_json::Value = serde_json::from_str(&t).unwrap();
                *v.pointer_mut(pointer).unwrap() = value.clone();
                v.to_string()
            })
        })
    };
    let rows: Vec<Row> = vec![
        (
            "valid",
            Box::new(|_: &Path, _: &Path| {}),
            0,
            r"^parity passed$",
        ),
        // Folders given as flags.
        (
            "case-missing",
            Box::new(|c: &Path, _: &Path| std::fs::remove_dir_all(c).unwrap()),
            1,
            r"<command line>: --case: value .*: expected a case folder .*: no such folder$",
        ),
        (
            "case-is-file",
            Box::new(|c: &Path, _: &Path| {
                std::fs::remove_dir_all(c).unwrap();
                std::fs::write(c, "x").unwrap();
            }),
            1,
            r"--case: value .*case.*: it is a file, not a folder$",
        ),
        (
            "case-is-fifo",
            Box::new(|c: &Path, _: &Path| {
                std::fs::remove_dir_all(c).unwrap();
                fifo(c);
            }),
            1,
            r"--case: value .*: it is a special file",
        ),
        (
            "case-dangling-link",
            Box::new(|c: &Path, _: &Path| {
                std::fs::remove_dir_all(c).unwrap();
                link("/nonexistent/forestlod-case", c);
            }),
            1,
            r"--case: value .*: it is a link that does not resolve",
        ),
        (
            "outputs-is-fifo",
            Box::new(|_: &Path, o: &Path| {
                std::fs::remove_dir_all(o).unwrap();
                fifo(o);
            }),
            1,
            r"--outputs: value .*: it is a special file",
        ),
        (
            "outputs-is-file",
            Box::new(|_: &Path, o: &Path| {
                std::fs::remove_dir_all(o).unwrap();
                std::fs::write(o, "x").unwrap();
            }),
            1,
            r"--outputs: value .*: it is a file, not a folder$",
        ),
        // Special files and sizes.
        (
            "case-json-fifo",
            Box::new(|c: &Path, _: &Path| fifo(&c.join("case.json"))),
            1,
            r"case\.json: file: .*special file",
        ),
        (
            "case-json-dev-zero",
            Box::new(|c: &Path, _: &Path| link("/dev/zero", &c.join("case.json"))),
            1,
            r"case\.json: file: .*special file",
        ),
        (
            "case-json-huge",
            Box::new(|c: &Path, _: &Path| {
                std::fs::write(c.join("case.json"), vec![b' '; (1 << 20) + 1]).unwrap()
            }),
            1,
            r"case\.json: file size: value .1048577 bytes \(1\.0 MiB\).: is over the limit of 1048576 bytes",
        ),
        (
            "case-json-not-utf8",
            Box::new(|c: &Path, _: &Path| std::fs::write(c.join("case.json"), b"{\xff}").unwrap()),
            1,
            r"case\.json: byte 1: value .0xff.: is not UTF-8",
        ),
        (
            "case-json-not-json",
            json("{", "["),
            1,
            r"case\.json: line 2, column \d+: .*not a case file \(JSON\)",
        ),
        // Lossy casts.
        (
            "width-fraction",
            json("\"width\": 48", "\"width\": 48.9"),
            1,
            r#"case\.json: field camera\.width: value "48\.9": expected an integer in 1\.\.=16384$"#,
        ),
        (
            "width-negative",
            json("\"width\": 48", "\"width\": -48"),
            1,
            r#"case\.json: field camera\.width: value "-48": expected an integer"#,
        ),
        (
            "width-float-whole",
            json("\"width\": 48", "\"width\": 48.0"),
            1,
            r#"field camera\.width: value "48\.0": expected an integer"#,
        ),
        (
            "near-beyond-f32",
            set("/camera/near", serde_json::json!(1e39)),
            1,
            r"field camera\.near: value .1e\+?39.: expected a finite number within the range of f32",
        ),
        (
            "trees-fraction",
            set("/scene/trees", serde_json::json!(0.5)),
            1,
            r"field scene\.trees: value .0\.5.: expected an integer",
        ),
        (
            "angles-fraction",
            json("\"angles\": 8", "\"angles\": 8.5"),
            1,
            r#"field params\.angles: value "8\.5": expected a non-negative integer"#,
        ),
        (
            "commands-negative",
            set("/commands", serde_json::json!(-1)),
            1,
            r#"field commands: value "-1": expected an integer"#,
        ),
        // Unknown, missing, twice.
        (
            "unknown-param",
            json("\"params\": {", "\"params\": {\"bogus\": 1,"),
            1,
            r"field params\.bogus: value .1.: not a parameter of this version",
        ),
        (
            "param-twice-by-two-names",
            json("\"params\": {", "\"params\": {\"angle_count\": 8,"),
            1,
            r"field params\.angles: .*parameter angle_count given twice: as angle_count and as angles$",
        ),
        (
            "duplicate-key",
            json("\"width\": 48", "\"width\": 48, \"width\": 96"),
            1,
            r#"case\.json: line \d+, column \d+: .*key \\?"width\\?" given twice"#,
        ),
        (
            "unknown-field",
            json("\"camera\": {", "\"camera\": {\"roll\": 3,"),
            1,
            r"field camera\.roll: value .3.: not a field of the case format forestlod-case/1",
        ),
        (
            "missing-field",
            Box::new(|c: &Path, _: &Path| {
                edit(&c.join("case.json"), |t| {
                    let mut v: serde_json::Value = serde_json::from_str(&t).unwrap();
                    v["camera"].as_object_mut().unwrap().remove("near");
                    v.to_string()
                })
            }),
            1,
            r"field camera\.near: value \x22\x22: missing$",
        ),
        (
            "wrong-format",
            json("forestlod-case/1", "forestlod-case/2"),
            1,
            r#"field format: value "\\"forestlod-case/2\\"": expected "forestlod-case/1""#,
        ),
        (
            "invalid-param",
            set("/params/grid_size", serde_json::json!(-3)),
            1,
            r#"field params\.grid_size: value "-3": -3: expected a finite size"#,
        ),
        (
            "too-many-shifts",
            Box::new(|c: &Path, _: &Path| {
                edit(&c.join("case.json"), |t| {
                    let mut v: serde_json::Value = serde_json::from_str(&t).unwrap();
                    v["alpha_cutoff_shifts"] = serde_json::json!(vec![0.01; 65]);
                    v.to_string()
                })
            }),
            1,
            r"field alpha_cutoff_shifts: .*expected a list of at most 64 numbers",
        ),
        // Values the oracle never writes: a bad case (1), not the implementation's failure.
        (
            "reference-depth-nan",
            Box::new(|c: &Path, _: &Path| {
                let p = c.join("reference/depth.exr");
                let (w, h, mut d) = read_depth_exr(&p).unwrap();
                d[100] = f32::NAN;
                d[101] = f32::NAN;
                write_depth_exr(&p, w, h, &d).unwrap();
            }),
            1,
            r#"reference/depth\.exr: pixel \(4, 2\): value "NaN": 2 depths are NaN, infinite or outside \[0, 1\]: not what export-case writes: a bad case"#,
        ),
        (
            "reference-depth-above-one",
            Box::new(|c: &Path, _: &Path| {
                let p = c.join("reference/depth.exr");
                let (w, h, mut d) = read_depth_exr(&p).unwrap();
                d[0] = 1.5;
                write_depth_exr(&p, w, h, &d).unwrap();
            }),
            1,
            r#"reference/depth\.exr: pixel \(0, 0\): value "1\.5": .*a bad case"#,
        ),
        (
            "alternative-depth-inf",
            Box::new(|c: &Path, _: &Path| {
                let p = c.join("alternatives/1/depth.exr");
                let (w, h, mut d) = read_depth_exr(&p).unwrap();
                d[47] = f32::INFINITY;
                write_depth_exr(&p, w, h, &d).unwrap();
            }),
            1,
            r#"alternatives/1/depth\.exr: pixel \(47, 0\): value "inf": .*a bad case"#,
        ),
        (
            "reference-lod-id-7",
            Box::new(|c: &Path, _: &Path| {
                let p = c.join("reference/lod_id.png");
                let mut img = read_png(&p).unwrap();
                img.texels[49] = [7, 7, 7, 255];
                write_png(&p, &img).unwrap();
            }),
            1,
            r#"reference/lod_id\.png: pixel \(1, 1\): value "\[7, 7, 7, 255\]": expected an opaque grey LOD id in 0\.\.=4"#,
        ),
        (
            "reference-colour-rgb",
            Box::new(|c: &Path, _: &Path| {
                let p = c.join("reference/color.png");
                let img = read_png(&p).unwrap();
                let rgb: Vec<u8> = img.texels.iter().flat_map(|t| [t[0], t[1], t[2]]).collect();
                image::save_buffer(&p, &rgb, 48, 48, image::ColorType::Rgb8).unwrap();
            }),
            1,
            r#"reference/color\.png: colour type: value "Rgb8": not what export-case writes"#,
        ),
        (
            "reference-colour-declares-100000",
            Box::new(|c: &Path, _: &Path| {
                std::fs::write(
                    c.join("reference/color.png"),
                    png_declaring(100_000, 100_000),
                )
                .unwrap()
            }),
            1,
            r#"reference/color\.png: declared size: value "100000x100000": expected the case's 48x48"#,
        ),
        (
            "commands-count-not-the-cases",
            set("/commands", serde_json::json!(100000)),
            1,
            r"reference/commands\.csv: rows: value .\d+.: expected the 100000 commands case\.json names: not what export-case writes",
        ),
        (
            "reference-commands-fifo",
            Box::new(|c: &Path, _: &Path| fifo(&c.join("reference/commands.csv"))),
            1,
            r"reference/commands\.csv: file: .*special file",
        ),
        (
            "alternative-folder-missing",
            Box::new(|c: &Path, _: &Path| {
                std::fs::remove_dir_all(c.join("alternatives/2")).unwrap()
            }),
            1,
            r"alternatives/2/color\.png: file: .*cannot be read",
        ),
        // The implementation's files.
        (
            "outputs-colour-declares-100000",
            Box::new(|_: &Path, o: &Path| {
                std::fs::write(o.join("color.png"), png_declaring(100_000, 100_000)).unwrap()
            }),
            1,
            r#"out/color\.png: declared size: value "100000x100000": expected the case's 48x48"#,
        ),
        (
            "outputs-depth-declares-100000",
            Box::new(|_: &Path, o: &Path| {
                let bytes = exr_declaring(&o.join("depth.exr"), 100_000);
                std::fs::write(o.join("depth.exr"), bytes).unwrap()
            }),
            1,
            r#"out/depth\.exr: declared size: value "100000x100000": expected the case's 48x48"#,
        ),
        (
            "outputs-colour-other-size",
            Box::new(|_: &Path, o: &Path| {
                write_png(
                    &o.join("color.png"),
                    &forestlod_reference::texture::Rgba8Image {
                        width: 49,
                        height: 48,
                        texels: vec![[0; 4]; 49 * 48],
                    },
                )
                .unwrap()
            }),
            1,
            r#"out/color\.png: declared size: value "49x48": expected the case's 48x48"#,
        ),
        (
            "outputs-depth-dev-zero",
            Box::new(|_: &Path, o: &Path| link("/dev/zero", &o.join("depth.exr"))),
            1,
            r"out/depth\.exr: file: .*special file",
        ),
        (
            "outputs-lod-id-fifo",
            Box::new(|_: &Path, o: &Path| fifo(&o.join("lod_id.png"))),
            1,
            r"out/lod_id\.png: file: .*special file",
        ),
        (
            "outputs-commands-dangling",
            Box::new(|_: &Path, o: &Path| {
                link("/nonexistent/commands.csv", &o.join("commands.csv"))
            }),
            1,
            r"out/commands\.csv: file: .*cannot be read",
        ),
        (
            "outputs-commands-negative",
            Box::new(|_: &Path, o: &Path| {
                edit(&o.join("commands.csv"), |t| {
                    let mut lines: Vec<String> = t.lines().map(String::from).collect();
                    lines[1] = format!("-{}", lines[1]);
                    lines.join("\n")
                })
            }),
            1,
            r#"out/commands\.csv: line 2, column index_count: value "-\d+": expected an integer in 0\.\.=4294967295 \(u32\)"#,
        ),
        (
            "outputs-commands-no-header",
            Box::new(|_: &Path, o: &Path| {
                edit(&o.join("commands.csv"), |t| {
                    t.lines().skip(1).collect::<Vec<_>>().join("\n")
                })
            }),
            1,
            r"out/commands\.csv: line 1: .*expected the header index_count,",
        ),
        (
            "outputs-commands-huge",
            Box::new(|_: &Path, o: &Path| {
                let f = std::fs::File::create(o.join("commands.csv")).unwrap();
                f.set_len((128 << 20) + 1).unwrap();
            }),
            1,
            r"out/commands\.csv: file size: .*over the limit of 134217728 bytes",
        ),
        // NaN in the implementation's depth fails (2), at silhouette pixels too.
        (
            "outputs-depth-nan",
            Box::new(|_: &Path, o: &Path| {
                let p = o.join("depth.exr");
                let (w, h, mut d) = read_depth_exr(&p).unwrap();
                // Silhouette pixels: drawn, with a background neighbour.
                let edges: Vec<usize> = (1..d.len() - 1)
                    .filter(|&i| d[i] < 1.0 && (d[i - 1] == 1.0 || d[i + 1] == 1.0))
                    .take(5)
                    .collect();
                assert_eq!(edges.len(), 5, "the case has silhouettes");
                for i in edges {
                    d[i] = f32::NAN;
                }
                write_depth_exr(&p, w, h, &d).unwrap();
            }),
            2,
            r"^parity FAILED: depth: 5 NaN or infinite pixels \(expected depths in \[0, 1\]\)",
        ),
    ];
    let mut failures = Vec::new();
    for (name, break_it, code, pattern) in &rows {
        let dir = work.join(name);
        let (c, o) = (dir.join("case"), dir.join("out"));
        copy_tree(&case, &c);
        copy_tree(&case.join("reference"), &o);
        break_it(&c, &o);
        let run = forestlod(
            &dir,
            "run",
            &[
                "verify",
                "--case",
                c.to_str().unwrap(),
                "--outputs",
                o.to_str().unwrap(),
            ],
        );
        let line = if run.code == Some(*code) {
            run.line()
        } else {
            String::new()
        };
        if run.code != Some(*code) || !regex(pattern).is_match(&line) || !run.problems.is_empty() {
            failures.push(format!(
                "{name}: exit {:?} (expected {code}), line {line:?} !~ {pattern} {:?}\n{}{}",
                run.code,
                run.problems,
                run.stdout.lines().last().unwrap_or(""),
                run.stderr
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} rows failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn check_replay_refuses_hostile_folders_naming_the_cases_file() {
    let work = common::fresh_dir("cli-hostile-case", "replay");
    let case = export_case(&work);
    // A replay of the case's trees and camera, written as check writes it.
    let replay = work.join("replay");
    std::fs::create_dir_all(&replay).unwrap();
    std::fs::copy(case.join("instances.csv"), replay.join("trees.csv")).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(case.join("case.json")).unwrap()).unwrap();
    let c = &json["camera"];
    let origin = &json["scene"]["origin"];
    let v3 = |v: &serde_json::Value, o: Option<&serde_json::Value>| {
        let k = |i: usize| v[i].as_f64().unwrap() + o.map_or(0.0, |o| o[i].as_f64().unwrap());
        format!("[{}, {}, {}]", k(0), k(1), k(2))
    };
    std::fs::write(
        replay.join("case.toml"),
        format!(
            "[camera]\neye = {}\nforward = {}\nup = {}\nfov_y = {}\nnear = {}\nfar = {}\nwidth = 64\nheight = 64\n\n[params]\ngrid_size = 50\nangle_count = 8\nlod_levels = 2\nhierarchy = \"grid\"\n",
            v3(&c["eye"], Some(origin)),
            v3(&c["forward"], None),
            v3(&c["up"], None),
            c["fov_y_degrees"].as_f64().unwrap().to_radians(),
            c["near"],
            c["far"],
        ),
    )
    .unwrap();
    let toml = |f: &'static str, to: &'static str| -> Breaks {
        Box::new(move |r: &Path, _: &Path| edit(&r.join("case.toml"), |t| t.replacen(f, to, 1)))
    };
    let trees = |f: fn(String) -> String| -> Breaks {
        Box::new(move |r: &Path, _: &Path| edit(&r.join("trees.csv"), f))
    };
    let rows: Vec<Row> = vec![
        (
            "valid",
            Box::new(|_: &Path, _: &Path| {}),
            0,
            r"^case .*replay \(select over grid\): passed$",
        ),
        (
            "missing",
            Box::new(|r: &Path, _: &Path| std::fs::remove_dir_all(r).unwrap()),
            1,
            r"<command line>: --replay: value .*: expected a replay folder holding case\.toml and trees\.csv: no such folder$",
        ),
        (
            "is-file",
            Box::new(|r: &Path, _: &Path| {
                std::fs::remove_dir_all(r).unwrap();
                std::fs::write(r, "x").unwrap();
            }),
            1,
            r"--replay: value .*: it is a file, not a folder$",
        ),
        (
            "is-fifo",
            Box::new(|r: &Path, _: &Path| {
                std::fs::remove_dir_all(r).unwrap();
                fifo(r);
            }),
            1,
            r"--replay: value .*: it is a special file",
        ),
        (
            "dangling-link",
            Box::new(|r: &Path, _: &Path| {
                std::fs::remove_dir_all(r).unwrap();
                link("/nonexistent/forestlod-replay", r);
            }),
            1,
            r"--replay: value .*: it is a link that does not resolve",
        ),
        (
            "toml-fifo",
            Box::new(|r: &Path, _: &Path| fifo(&r.join("case.toml"))),
            1,
            r"replay/case\.toml: file: .*special file",
        ),
        (
            "toml-dev-zero",
            Box::new(|r: &Path, _: &Path| link("/dev/zero", &r.join("case.toml"))),
            1,
            r"replay/case\.toml: file: .*special file",
        ),
        (
            "toml-huge",
            Box::new(|r: &Path, _: &Path| {
                std::fs::write(r.join("case.toml"), vec![b'#'; (64 << 10) + 1]).unwrap()
            }),
            1,
            r"replay/case\.toml: file size: value .65537 bytes.: is over the limit of 65536 bytes",
        ),
        (
            "width-fraction",
            toml("width = 64", "width = 64.9"),
            1,
            r#"replay/case\.toml: line 8, column 9: value "64\.9": invalid replay case .*expected u32"#,
        ),
        (
            "width-negative",
            toml("width = 64", "width = -64"),
            1,
            r#"replay/case\.toml: line 8, column 9: value "-64": invalid replay case"#,
        ),
        (
            "width-zero",
            toml("width = 64", "width = 0"),
            1,
            r#"replay/case\.toml: line 8, column 9, field camera\.viewport: value "0": 0x64: expected 1\.\.=16384"#,
        ),
        (
            "fov-nan",
            toml("fov_y = ", "fov_y = nan\n#"),
            1,
            r#"replay/case\.toml: line 5, column 9, field camera\.fov_y: value "nan": expected a finite number"#,
        ),
        (
            "eye-inf",
            Box::new(|r: &Path, _: &Path| {
                edit(&r.join("case.toml"), |t| {
                    let eye = t
                        .lines()
                        .find(|l| l.starts_with("eye"))
                        .unwrap()
                        .to_string();
                    t.replacen(&eye, "eye = [inf, 0, 0]", 1)
                })
            }),
            1,
            r#"replay/case\.toml: line 2, column 7, field camera\.eye: value "\[inf, 0, 0\]": expected finite coordinates"#,
        ),
        (
            "eye-four-numbers",
            toml("eye = [", "eye = [1, "),
            1,
            r#"replay/case\.toml: line 2, column 7, field camera\.eye: value "\[1, .*": expected three numbers$"#,
        ),
        (
            "missing-near",
            Box::new(|r: &Path, _: &Path| {
                edit(&r.join("case.toml"), |t| {
                    t.lines()
                        .filter(|l| !l.starts_with("near"))
                        .collect::<Vec<_>>()
                        .join("\n")
                })
            }),
            1,
            r"replay/case\.toml: line 1, column 1: .*missing field `near`",
        ),
        (
            "unknown-camera-field",
            toml("width = 64", "roll = 3\nwidth = 64"),
            1,
            r"replay/case\.toml: line 8, column 1: value .roll.: .*unknown field `roll`",
        ),
        (
            "unknown-table",
            toml("[params]", "[extra]\nx = 1\n[params]"),
            1,
            r"replay/case\.toml: line 11, column 2: value .extra.: .*unknown field `extra`",
        ),
        (
            "unknown-param",
            toml("[params]", "[params]\nbogus = 1"),
            1,
            r#"replay/case\.toml: line 12, column 1, field params\.bogus: value "bogus = 1": not a parameter"#,
        ),
        (
            "duplicate-key",
            toml("grid_size = 50", "grid_size = 50\ngrid_size = 60"),
            1,
            r"replay/case\.toml: line 13, column 1: .*duplicate key",
        ),
        (
            "param-twice-by-two-names",
            toml("angle_count = 8", "angle_count = 8\nangles = 8"),
            1,
            r"field params\.angles: .*parameter angle_count given twice: as angle_count and as angles$",
        ),
        (
            "param-fraction",
            toml("lod_levels = 2", "lod_levels = 1.5"),
            1,
            r#"field params\.lod_levels: value "1\.5": expected a non-negative integer"#,
        ),
        (
            "tree-cull",
            toml("[params]", "[params]\ntree_cull = \"lod0\""),
            1,
            r#"line 12, column 1, field params\.tree_cull: value "tree_cull = \\"lod0\\"": lod0 runs refine: check compares"#,
        ),
        (
            "trees-fifo",
            Box::new(|r: &Path, _: &Path| fifo(&r.join("trees.csv"))),
            1,
            r"replay/trees\.csv: file: .*special file",
        ),
        (
            "trees-missing",
            Box::new(|r: &Path, _: &Path| std::fs::remove_file(r.join("trees.csv")).unwrap()),
            1,
            r"replay/trees\.csv: file: .*cannot be read",
        ),
        (
            "trees-huge",
            Box::new(|r: &Path, _: &Path| {
                let f = std::fs::OpenOptions::new()
                    .append(true)
                    .open(r.join("trees.csv"))
                    .unwrap();
                f.set_len((16 << 20) + 1).unwrap();
            }),
            1,
            r"replay/trees\.csv: file size: .*over the limit of 16777216 bytes",
        ),
        // The case's own file is named, with its line: never a scratch copy under TMPDIR.
        (
            "trees-bad-row",
            trees(|t| t.replacen('\n', "\n1,2,nan,0,1,0\n", 1)),
            1,
            r"replay/trees\.csv: line 2, column z",
        ),
        (
            "trees-bad-species",
            trees(|t| t + "1,2,3,0,1,larch\n"),
            1,
            r"replay/trees\.csv: line \d+, column species",
        ),
    ];
    let mut failures = Vec::new();
    for (name, break_it, code, pattern) in &rows {
        let dir = work.join(name);
        let r = dir.join("replay");
        copy_tree(&replay, &r);
        break_it(&r, &dir);
        let run = forestlod(&dir, "run", &["check", "--replay", r.to_str().unwrap()]);
        let line = if run.code == Some(*code) {
            run.line()
        } else {
            String::new()
        };
        // Never a scratch copy under the child's TMPDIR named.
        if run.code != Some(*code)
            || !regex(pattern).is_match(&line)
            || line.contains(&run.tmp.display().to_string())
            || !run.problems.is_empty()
        {
            failures.push(format!(
                "{name}: exit {:?} (expected {code}), line {line:?} !~ {pattern} {:?}\n{}{}",
                run.code, run.problems, run.stdout, run.stderr
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} rows failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
