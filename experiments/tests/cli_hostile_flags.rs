//! Hostile command-line flags of `render`, `export-case` and `check` (issue 28, "errors name the flag" and "work and memory refused up
//! front"), one table: each case runs the real `forestlod` binary under a deadline with a fresh
//! `TMPDIR`, and must
//! - exit with the expected code (1: bad input) within [`DEADLINE`] (no hang, no abort);
//! - print exactly one line to stderr, `error: ...`, containing every expected fragment (the flag
//!   and the value; for memory, the estimate and the limit);
//! - leave `--out` as it was (absent stays absent, a file or link stays what it was) and `TMPDIR`
//!   empty.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

#[path = "../../reference/tests/common/mod.rs"]
mod common;

/// Longest a refusal may take: every case here is refused before a scene is prepared, so a
/// case that runs this long is doing the work it should have refused (or hangs).
const DEADLINE: Duration = Duration::from_secs(60);

/// What `--out` is before the run.
#[derive(Clone, Copy, Debug)]
enum Out {
    /// Absent (must stay absent).
    Absent,
    /// A regular file (must keep its bytes).
    File,
    /// A link to a path that does not exist (must stay a dangling link).
    DanglingLink,
    /// A folder under a dangling link (`link/sub`).
    UnderDanglingLink,
}

struct Case {
    name: &'static str,
    /// The command before `args`: [`RENDER`], [`EXPORT`] or [`CHECK`].
    tool: &'static [&'static str],
    args: &'static [&'static str],
    out: Out,
    /// Fragments the one error line must contain.
    expect: &'static [&'static str],
}

const RENDER: &[&str] = &["render", "--scene", "tiny", "--no-gpu"];
const EXPORT: &[&str] = &["export-case", "--scene", "tiny"];
const CHECK: &[&str] = &["check", "--cases", "1"];

const CASES: &[Case] = &[
    Case {
        name: "unknown preset",
        tool: RENDER,
        args: &["--preset", "celba-ultra"],
        out: Out::Absent,
        expect: &["--preset", "celba-ultra", "celba-extra-high"],
    },
    Case {
        name: "subsets with a hierarchy",
        tool: RENDER,
        args: &["--subset", "thin", "--hierarchy", "octree"],
        out: Out::Absent,
        expect: &["--subset", "subset_mode", "thin", "hierarchy = grid"],
    },
    Case {
        name: "azimuths out of range",
        tool: RENDER,
        args: &["--azimuths", "65"],
        out: Out::Absent,
        expect: &["--azimuths (field azimuth_count)", "\"65\"", "1..=64"],
    },
    Case {
        name: "azimuth views over the layer limit",
        tool: RENDER,
        args: &["--azimuths", "64"],
        out: Out::Absent,
        expect: &["azimuth_count", "\"64\"", "3200 billboard layers", "2048"],
    },
    Case {
        name: "yaw inf",
        tool: RENDER,
        args: &["--yaw", "inf"],
        out: Out::Absent,
        expect: &["--yaw", "inf", "finite"],
    },
    Case {
        name: "yaw nan",
        tool: RENDER,
        args: &["--yaw", "NaN"],
        out: Out::Absent,
        expect: &["--yaw", "NaN", "finite"],
    },
    Case {
        name: "yaw -inf",
        tool: RENDER,
        args: &["--yaw=-inf"],
        out: Out::Absent,
        expect: &["--yaw", "-inf"],
    },
    Case {
        name: "width 0",
        tool: RENDER,
        args: &["--width", "0"],
        out: Out::Absent,
        expect: &["--width", "\"0\"", "pixels"],
    },
    Case {
        name: "height too large",
        tool: RENDER,
        args: &["--height", "16385"],
        out: Out::Absent,
        expect: &["--height", "16385", "1..=16384"],
    },
    Case {
        name: "lod levels out of range",
        tool: RENDER,
        args: &["--lod-levels", "9"],
        out: Out::Absent,
        expect: &["<command line>", "--lod-levels (field lod_levels)", "\"9\""],
    },
    Case {
        name: "out is a file",
        tool: RENDER,
        args: &[],
        out: Out::File,
        expect: &["--out", "cannot be used as the output folder"],
    },
    Case {
        name: "out is a dangling link",
        tool: RENDER,
        args: &[],
        out: Out::DanglingLink,
        expect: &["--out", "does not resolve", "nowhere"],
    },
    Case {
        name: "out is under a dangling link",
        tool: RENDER,
        args: &[],
        out: Out::UnderDanglingLink,
        expect: &["--out", "does not resolve", "nowhere"],
    },
    Case {
        name: "bake memory: 4096 x 91 angles",
        tool: RENDER,
        args: &["--texture-size", "4096", "--angles", "91"],
        out: Out::Absent,
        expect: &[
            "--texture-size x --angles",
            "4096 x 91 angles",
            "GiB",
            "MAX_BAKE_BYTES",
        ],
    },
    Case {
        name: "bake memory: 4096 x 10 angles",
        tool: RENDER,
        args: &["--texture-size", "4096", "--angles", "10"],
        out: Out::Absent,
        expect: &["4096 x 10 angles", "over the limit of"],
    },
    Case {
        name: "export-case out is a dangling link",
        tool: EXPORT,
        args: &[],
        out: Out::DanglingLink,
        expect: &["--out", "does not resolve", "nowhere"],
    },
    Case {
        name: "export-case out is a file",
        tool: EXPORT,
        args: &[],
        out: Out::File,
        expect: &["--out", "cannot be used as the output folder"],
    },
    Case {
        name: "export-case bake memory",
        tool: EXPORT,
        args: &["--texture-size", "4096", "--angles", "91"],
        out: Out::Absent,
        expect: &["4096 x 91 angles", "MAX_BAKE_BYTES"],
    },
    Case {
        name: "check out under a dangling link",
        tool: CHECK,
        args: &[],
        out: Out::UnderDanglingLink,
        expect: &["--out", "does not resolve", "nowhere"],
    },
];

fn prepare_out(dir: &Path, out: Out) -> PathBuf {
    match out {
        Out::Absent => dir.join("out"),
        Out::File => {
            let p = dir.join("out-file");
            std::fs::write(&p, b"not a folder").unwrap();
            p
        }
        Out::DanglingLink | Out::UnderDanglingLink => {
            let link = dir.join("out-link");
            std::os::unix::fs::symlink(dir.join("nowhere"), &link).unwrap();
            if matches!(out, Out::UnderDanglingLink) {
                link.join("sub")
            } else {
                link
            }
        }
    }
}

fn out_unchanged(dir: &Path, out: Out, path: &Path) -> bool {
    match out {
        Out::Absent => !path.exists() && std::fs::symlink_metadata(path).is_err(),
        Out::File => std::fs::read(path).is_ok_and(|b| b == b"not a folder"),
        Out::DanglingLink | Out::UnderDanglingLink => {
            let link = dir.join("out-link");
            std::fs::symlink_metadata(&link).is_ok_and(|m| m.file_type().is_symlink())
                && !dir.join("nowhere").exists()
        }
    }
}

/// Runs `forestlod TOOL ARGS --out OUT` (tiny scene, small viewport, no GPU for render) under
/// [`DEADLINE`]; returns (exit code, stderr). A run past the deadline is killed and fails.
fn run(
    dir: &Path,
    tool: &[&str],
    args: &[&str],
    out: &Path,
    tmp: &Path,
    what: &str,
) -> (Option<i32>, String) {
    let mut all = tool.to_vec();
    for flag in ["--width", "--height"] {
        if tool != CHECK && !args.contains(&flag) {
            all.extend([flag, "32"]);
        }
    }
    all.extend(args);
    let out_s = out.to_str().unwrap().to_string();
    all.extend(["--out", &out_s]);
    let (code, stderr) = common::run_with_deadline(
        Command::new(env!("CARGO_BIN_EXE_forestlod"))
            .args(&all)
            .current_dir(dir)
            .env("TMPDIR", tmp)
            .env("RUST_BACKTRACE", "0"),
        DEADLINE,
    );
    if code.is_none() {
        panic!("{what}: {stderr} (a hang, or work not refused up front)");
    }
    (code, stderr)
}

#[test]
fn hostile_flags_are_refused_naming_the_flag() {
    let mut failures = Vec::new();
    for case in CASES {
        let dir = common::fresh_dir("cli-hostile-flags", &case.name.replace([' ', ':'], "-"));
        let tmp = dir.join("tmp");
        std::fs::create_dir_all(&tmp).unwrap();
        let out = prepare_out(&dir, case.out);
        let what = format!(
            "{}: forestlod {} {}",
            case.name,
            case.tool.join(" "),
            case.args.join(" ")
        );
        let (code, stderr) = run(&dir, case.tool, case.args, &out, &tmp, &what);
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        let mut problems = Vec::new();
        if code != Some(1) {
            problems.push(format!("exit {code:?}, expected 1"));
        }
        if stderr.contains("panicked") {
            problems.push("panicked".into());
        }
        if lines.len() != 1 || !lines[0].starts_with("error:") {
            problems.push(format!("stderr is not one `error:` line: {stderr:?}"));
        }
        for e in case.expect {
            if !stderr.contains(e) {
                problems.push(format!("error lacks {e:?}: {stderr:?}"));
            }
        }
        if !out_unchanged(&dir, case.out, &out) {
            problems.push(format!("--out {} was changed", out.display()));
        }
        let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
        if !left.is_empty() {
            problems.push(format!("{} entries left in TMPDIR", left.len()));
        }
        if !problems.is_empty() {
            failures.push(format!("{what}: {}", problems.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
