//! `forestlod check` through the binary (issue 15, part 7): a handful of random selection parity
//! cases pass on this adapter (exit 0, cases per minute printed); with the test hook
//! `FORESTLOD_CHECK_BREAK=drop-last-command` (the GPU's last command dropped before the
//! comparison: a deliberately broken comparison) the first case that draws fails, is shrunk
//! until no tree can go (every case with one tree fewer draws nothing) and written as
//! `trees.csv` + `case.toml`, and the printed command replays it: failing with the hook, passing
//! without it.
//!
//! Needs a GPU adapter (lavapipe in CI), like the parity tests.

use std::process::{Command, Output};

#[path = "../../reference/tests/common/mod.rs"]
mod common;

fn forestlod(args: &[&str], broken: bool) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_forestlod"));
    c.args(args).env("RUST_BACKTRACE", "0");
    if broken {
        c.env("FORESTLOD_CHECK_BREAK", "drop-last-command");
    } else {
        c.env_remove("FORESTLOD_CHECK_BREAK");
    }
    c.output().expect("run forestlod")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

#[test]
fn random_cases_pass_and_report_their_rate() {
    let dir = common::fresh_dir("cli-check", "pass");
    let o = forestlod(
        &["check", "--cases", "8", "--out", dir.to_str().unwrap()],
        false,
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert!(t.contains("check (select, seed 1): 8 cases in"), "{t}");
    assert!(
        t.contains("cases/min") && t.contains("every case passed"),
        "{t}"
    );
}

#[test]
fn a_broken_comparison_writes_a_shrunk_case_that_replays() {
    let dir = common::fresh_dir("cli-check", "broken");
    let o = forestlod(
        &["check", "--cases", "50", "--out", dir.to_str().unwrap()],
        true,
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    let command = t
        .lines()
        .find_map(|l| l.strip_prefix("reproduce: forestlod "))
        .unwrap_or_else(|| panic!("no reproduce line: {t}"));
    let args: Vec<&str> = command.split(' ').collect();
    assert_eq!(args[..2], ["check", "--replay"], "{t}");
    let case = std::path::Path::new(args[2]);
    assert!(case.starts_with(&dir), "{t}");
    let trees = std::fs::read_to_string(case.join("trees.csv")).expect("trees.csv");
    // A dropped command fails any case with a command: shrunk until every case with one tree
    // fewer draws nothing (one tree; or more where a hierarchy's node over them is visible
    // though no tree alone is), so each of those passes even with the hook.
    let rows: Vec<&str> = trees.lines().skip(1).collect();
    let failed: usize = t
        .lines()
        .find_map(|l| l.split_once(" FAILED (")?.1.split_once(" trees)"))
        .and_then(|(n, _)| n.parse().ok())
        .unwrap_or_else(|| panic!("no failing case line: {t}"));
    assert!(
        !rows.is_empty() && (rows.len() < failed || failed == 1),
        "shrunk from {failed} trees: {trees}"
    );
    assert!(case.join("case.toml").is_file());
    for skip in (0..rows.len()).filter(|_| rows.len() > 1) {
        let fewer = dir.join(format!("without-{skip}"));
        std::fs::create_dir_all(&fewer).unwrap();
        std::fs::copy(case.join("case.toml"), fewer.join("case.toml")).unwrap();
        let kept: Vec<&str> = std::iter::once(trees.lines().next().unwrap())
            .chain(
                rows.iter()
                    .enumerate()
                    .filter(|&(i, _)| i != skip)
                    .map(|(_, r)| *r),
            )
            .collect();
        std::fs::write(fewer.join("trees.csv"), kept.join("\n") + "\n").unwrap();
        let o = forestlod(&["check", "--replay", fewer.to_str().unwrap()], true);
        assert_eq!(
            o.status.code(),
            Some(0),
            "not shrunk to the end: {}",
            text(&o)
        );
    }
    let again = forestlod(&args, true);
    assert_eq!(again.status.code(), Some(2), "{}", text(&again));
    assert!(text(&again).contains("FAILED"), "{}", text(&again));
    let fixed = forestlod(&args, false);
    assert_eq!(fixed.status.code(), Some(0), "{}", text(&fixed));
}

#[test]
fn bad_check_input_is_named() {
    let dir = common::fresh_dir("cli-check", "bad");
    let o = forestlod(
        &["check", "--replay", dir.join("missing").to_str().unwrap()],
        false,
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("case.toml"), "{}", text(&o));
    let o = forestlod(&["check", "--cases", "0"], false);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("--cases 0"), "{}", text(&o));
}
