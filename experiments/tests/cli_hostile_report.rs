//! `forestlod report --run DIR` on hostile run folders (issue 28: special files, unbounded reads,
//! manifests validated where read, errors naming the flag; README "Bad input"). One table, one
//! case per row: each builds a run folder (a copy of the committed `results/mip_mode` sweep,
//! edited), runs the real binary under a deadline with `TMPDIR` set to a fresh empty folder, and
//! requires exit status 1, exactly one stderr line matching the case's pattern (`*` matches any
//! text), no `report.md` or `report.html` written, and nothing left in `TMPDIR`.
//!
//! The file-disclosure cases (paths leading out of the run) are in `cli_report_hostile.rs`.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[path = "../../reference/tests/common/mod.rs"]
mod common;

/// How long one case may run: a report of the small copied sweep takes well under a second, so
/// only a hang (a FIFO opened, `/dev/zero` read) comes near this.
const DEADLINE: Duration = Duration::from_secs(30);

/// A case's folders: the run folder handed to `--run` and the copied sweep inside it.
struct Case {
    run: PathBuf,
    sweep: PathBuf,
}

impl Case {
    fn manifest(&self) -> PathBuf {
        self.sweep.join("sweep.json")
    }

    /// Edits the copied `sweep.json` as a JSON tree.
    fn edit(&self, f: impl FnOnce(&mut serde_json::Value)) {
        let mut m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(self.manifest()).unwrap()).unwrap();
        f(&mut m);
        std::fs::write(self.manifest(), serde_json::to_string_pretty(&m).unwrap()).unwrap();
    }

    /// Replaces `name` in the sweep folder with a FIFO.
    fn fifo(&self, name: &str) {
        let path = self.sweep.join(name);
        let _ = std::fs::remove_file(&path);
        let made = Command::new("mkfifo")
            .arg(&path)
            .status()
            .expect("mkfifo runs");
        assert!(made.success(), "mkfifo {}", path.display());
    }

    /// Replaces `name` in the sweep folder with a link to `target`.
    fn link(&self, name: &str, target: &str) {
        let path = self.sweep.join(name);
        let _ = std::fs::remove_file(&path);
        std::os::unix::fs::symlink(target, path).unwrap();
    }

    /// Replaces `name` in the sweep folder with a sparse file of `bytes` (no disk used).
    fn sparse(&self, name: &str, bytes: u64) {
        let f = std::fs::File::create(self.sweep.join(name)).unwrap();
        f.set_len(bytes).unwrap();
    }
}

/// A fresh run folder holding a copy of the committed `mip_mode` sweep (its manifest, CSV and
/// plots), and an empty `TMPDIR` for the child.
fn fresh(name: &str) -> (Case, PathBuf) {
    let base = common::fresh_dir("hostile-report", name);
    let run = base.join("run");
    let sweep = run.join("mip_mode");
    std::fs::create_dir_all(&sweep).unwrap();
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/mip_mode");
    for entry in std::fs::read_dir(&committed).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(&path, sweep.join(path.file_name().unwrap())).unwrap();
        }
    }
    let tmp = base.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    (Case { run, sweep }, tmp)
}

/// Whether `text` matches `pattern`, where `*` matches any text (possibly empty) and every other
/// character itself.
fn matches(pattern: &str, text: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if parts.len() == 1 {
        return text == pattern;
    }
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

/// Runs `forestlod report --run run` with `TMPDIR=tmp` under [`DEADLINE`]: exit status and stderr.
fn report(run: &Path, tmp: &Path) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args(["report", "--run"])
        .arg(run)
        .env("TMPDIR", tmp)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > DEADLINE {
            child.kill().unwrap();
            let _ = child.wait();
            panic!(
                "report --run {} did not finish within {DEADLINE:?}",
                run.display()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

type Setup = fn(&Case) -> PathBuf;

/// `--run` is the run folder itself.
fn the_run(c: &Case) -> PathBuf {
    c.run.clone()
}

#[cfg(unix)]
#[test]
fn hostile_run_folders_get_one_error_line_and_no_report() {
    // The control: the unedited copy reports (so every refusal below is the case's doing).
    let (c, tmp) = fresh("control");
    let (code, stderr) = report(&c.run, &tmp);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(c.run.join("report.html").is_file());
    assert_eq!(std::fs::read_dir(&tmp).unwrap().count(), 0, "TMPDIR left");

    const MANIFEST: &str = "error: run folder */run: */run/mip_mode/sweep.json: ";
    const CSV: &str = "error: run folder */run: */run/mip_mode/sweep.json: key csv = \"mip_mode.csv\": */mip_mode.csv: ";
    let cases: Vec<(&str, Setup, String)> = vec![
        // Special files and unbounded reads: the manifest.
        (
            "manifest-fifo",
            |c| {
                c.fifo("sweep.json");
                the_run(c)
            },
            format!("{MANIFEST}manifest: value \"\": resolves to */sweep.json, not a regular file*"),
        ),
        (
            "manifest-dev-zero",
            |c| {
                c.link("sweep.json", "/dev/zero");
                the_run(c)
            },
            format!("{MANIFEST}manifest: value \"\": resolves to /dev/zero, outside the run folder*"),
        ),
        (
            "manifest-folder",
            |c| {
                std::fs::remove_file(c.manifest()).unwrap();
                std::fs::create_dir(c.manifest()).unwrap();
                the_run(c)
            },
            format!("{MANIFEST}manifest: value \"\": *not a regular file*"),
        ),
        (
            "manifest-huge",
            |c| {
                c.sparse("sweep.json", 17 << 20);
                the_run(c)
            },
            format!(
                "{MANIFEST}file size: value \"17825792 bytes (17.0 MiB)\": is over the limit of 16777216 bytes (16.0 MiB)*"
            ),
        ),
        (
            "manifest-not-utf8",
            |c| {
                std::fs::write(c.manifest(), b"{\"name\": \"\xff\"}").unwrap();
                the_run(c)
            },
            format!("{MANIFEST}byte 10: value \"0xff\": is not UTF-8 text"),
        ),
        // Validated where read: the manifest's syntax, types, keys and values.
        (
            "manifest-syntax",
            |c| {
                std::fs::write(c.manifest(), "{\"name\": \"mip_mode\",").unwrap();
                the_run(c)
            },
            format!("{MANIFEST}line 1, column 20: value \"\": is not JSON: EOF while parsing*"),
        ),
        (
            "manifest-lossy-width",
            |c| {
                c.edit(|m| m["width"] = 128.9.into());
                the_run(c)
            },
            format!("{MANIFEST}line *, column *, key width: value \"128.9\": invalid type: floating point `128.9`, expected u32"),
        ),
        (
            "manifest-negative-height",
            |c| {
                c.edit(|m| m["height"] = (-720).into());
                the_run(c)
            },
            format!("{MANIFEST}line *, key height: value \"-720\": invalid value: integer `-720`, expected u32"),
        ),
        (
            "manifest-zero-width",
            |c| {
                c.edit(|m| m["width"] = 0.into());
                the_run(c)
            },
            format!("{MANIFEST}key width: value \"0\": expected a frame size between 1 and 16384 pixels"),
        ),
        (
            "manifest-infinite-yaw",
            |c| {
                c.edit(|m| m["images"][0]["yaw_deg"] = 1e300.into());
                the_run(c)
            },
            format!("{MANIFEST}key images[0].yaw_deg: value \"inf\": expected a finite yaw"),
        ),
        (
            "manifest-flip-out-of-range",
            |c| {
                c.edit(|m| m["images"][0]["accuracy"]["flip_mean"] = (-0.5).into());
                the_run(c)
            },
            format!("{MANIFEST}key images[0].accuracy.flip_mean: value \"-0.5\": expected a figure between 0 and 1"),
        ),
        (
            "manifest-unknown-key",
            |c| {
                c.edit(|m| m["plots_extra"] = "x".into());
                the_run(c)
            },
            format!("{MANIFEST}key plots_extra: value \"\\\"x\\\"\": unknown key*"),
        ),
        (
            "manifest-duplicate-key",
            |c| {
                let text = std::fs::read_to_string(c.manifest()).unwrap();
                let text = text.replacen("{", "{\n  \"width\": 64,", 1);
                std::fs::write(c.manifest(), text).unwrap();
                the_run(c)
            },
            format!("{MANIFEST}line *, column *: value \"\": duplicate key width: each key may appear once"),
        ),
        (
            "manifest-wrong-type",
            |c| {
                c.edit(|m| m["plots"] = "runtime.png".into());
                the_run(c)
            },
            format!("{MANIFEST}line *, key plots: value \"\\\"runtime.png\\\"\": invalid type: string *, expected a sequence"),
        ),
        // Special files and unbounded reads: the CSV.
        (
            "csv-fifo",
            |c| {
                c.fifo("mip_mode.csv");
                the_run(c)
            },
            format!("{MANIFEST}key csv: value \"mip_mode.csv\": resolves to */mip_mode.csv, not a regular file*"),
        ),
        (
            "csv-dev-zero",
            |c| {
                c.link("mip_mode.csv", "/dev/zero");
                the_run(c)
            },
            format!("{MANIFEST}key csv: value \"mip_mode.csv\": resolves to /dev/zero, outside the run folder*"),
        ),
        (
            "csv-huge",
            |c| {
                c.sparse("mip_mode.csv", 257 << 20);
                the_run(c)
            },
            format!("{CSV}file size: value \"269484032 bytes (257.0 MiB)\": is over the limit of 268435456 bytes (256.0 MiB)*"),
        ),
        (
            "csv-missing",
            |c| {
                std::fs::remove_file(c.sweep.join("mip_mode.csv")).unwrap();
                the_run(c)
            },
            format!("{MANIFEST}key csv: value \"mip_mode.csv\": names no file in */run/mip_mode"),
        ),
        (
            "csv-no-rows",
            |c| {
                let text = std::fs::read_to_string(c.sweep.join("mip_mode.csv")).unwrap();
                let header = text.lines().next().unwrap();
                std::fs::write(c.sweep.join("mip_mode.csv"), format!("{header}\n")).unwrap();
                the_run(c)
            },
            format!("{CSV}rows: value \"0 rows\": expected the sweep's frames, one row each"),
        ),
        (
            "csv-bad-cell",
            |c| {
                let text = std::fs::read_to_string(c.sweep.join("mip_mode.csv")).unwrap();
                let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
                let header: Vec<&str> = lines[0].split(',').collect();
                let col = header.iter().position(|h| *h == "width").unwrap();
                let mut cells: Vec<String> = lines[1].split(',').map(str::to_string).collect();
                cells[col] = "128.9".into();
                lines[1] = cells.join(",");
                std::fs::write(c.sweep.join("mip_mode.csv"), lines.join("\n") + "\n").unwrap();
                the_run(c)
            },
            format!("{CSV}row 2, column width: value \"128.9\": invalid digit found in string"),
        ),
        // Special files and unbounded reads: the plots the report embeds.
        (
            "plot-fifo",
            |c| {
                c.fifo("runtime.png");
                the_run(c)
            },
            format!("{MANIFEST}key plots[*][0]: value \"runtime.png\": resolves to */runtime.png, not a regular file*"),
        ),
        (
            "plot-dev-zero",
            |c| {
                c.link("runtime.png", "/dev/zero");
                the_run(c)
            },
            format!("{MANIFEST}key plots[*][0]: value \"runtime.png\": resolves to /dev/zero, outside the run folder*"),
        ),
        (
            "plot-huge",
            |c| {
                c.sparse("runtime.png", (32 << 20) + 1);
                the_run(c)
            },
            format!("{MANIFEST}key plots[*][0]: value \"runtime.png\": names an image of 33554433 bytes (32.0 MiB), over the limit of 33554432 bytes (32.0 MiB) for an image a report embeds"),
        ),
        (
            "plots-too-many-in-all",
            |c| {
                // Each within the per-image limit; nine of them pass the report's 256 MiB.
                c.sparse("runtime.png", 30 << 20);
                c.edit(|m| {
                    let plot = serde_json::json!(["runtime.png", "runtime"]);
                    m["plots"] = serde_json::Value::Array(vec![plot; 9]);
                });
                the_run(c)
            },
            format!("{MANIFEST}key plots[8][0]: value \"runtime.png\": brings the report's embedded images to * (270.0 MiB), over the limit of 268435456 bytes (256.0 MiB) for one report"),
        ),
        // Errors name the flag: `--run` itself.
        (
            "run-is-a-file",
            |c| c.manifest(),
            "error: <command line>: --run: value \"*/run/mip_mode/sweep.json\": is a file, not a folder; expected the folder `forestlod sweep --out` wrote".into(),
        ),
        (
            "run-missing",
            |c| c.run.join("nowhere"),
            "error: <command line>: --run: value \"*/run/nowhere\": cannot be read (No such file or directory*); expected the folder *".into(),
        ),
        (
            "run-dangling-link",
            |c| {
                let link = c.run.join("dangling");
                std::os::unix::fs::symlink(c.run.join("nowhere"), &link).unwrap();
                link
            },
            "error: <command line>: --run: value \"*/run/dangling\": is a link that does not resolve (No such file or directory*); expected the folder *".into(),
        ),
        (
            "run-is-a-fifo",
            |c| {
                let fifo = c.run.join("pipe");
                let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
                assert!(made.success());
                fifo
            },
            "error: <command line>: --run: value \"*/run/pipe\": is a special file (a FIFO, socket or device), not a folder; *".into(),
        ),
        (
            "run-without-sweeps",
            |c| {
                std::fs::remove_dir_all(&c.sweep).unwrap();
                the_run(c)
            },
            "error: */run: sweeps: value \"\": no */sweep.json found: run `forestlod sweep --out DIR` first".into(),
        ),
    ];
    let mut failures = Vec::new();
    for (name, setup, pattern) in &cases {
        let (c, tmp) = fresh(name);
        let run = setup(&c);
        let (code, stderr) = report(&run, &tmp);
        let lines: Vec<&str> = stderr.lines().collect();
        let left: Vec<_> = std::fs::read_dir(&tmp)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        let written = ["report.md", "report.html"]
            .iter()
            .any(|f| c.run.join(f).exists());
        if code != Some(1)
            || lines.len() != 1
            || !matches(pattern, lines[0])
            || !left.is_empty()
            || written
        {
            failures.push(format!(
                "{name}: exit {code:?}, report written {written}, TMPDIR left {left:?}, stderr:\n{stderr}\n  expected one line matching:\n{pattern}"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn the_pattern_matcher_matches_only_what_it_should() {
    assert!(matches("a*c", "abc") && matches("a*c", "ac") && matches("*", "x"));
    assert!(matches("a*b*c", "a1b2c") && !matches("a*b*c", "a1c"));
    assert!(!matches("a*c", "abcd") && !matches("abc", "abcd") && !matches("x*", "abc"));
    assert!(!matches("ab*ba", "aba"), "the two ends do not share text");
}
