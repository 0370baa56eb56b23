//! `forestlod report --run DIR` reads only its run (issue 28, the file-disclosure hole; README
//! "Bad input"). A report is a file people mail around, so a crafted `sweep.json` must not copy a
//! file from outside the run into `report.html` or `report.md`.
//!
//! Each case copies a real run (the committed `results/mip_mode` sweep: its CSV, plots and
//! manifest) into a fresh run folder, edits its `sweep.json` the way an attacker would, and runs
//! the `forestlod` binary on it. A secret file (a random 32-byte hex string) lies outside the run.
//! The report must either fail with exit status 1 and one `error:` line naming the manifest, the
//! key and the value, writing no report; or be written and contain no byte sequence of the
//! secret, neither the secret's text nor the base64 of the file (what an embedded image holds).

use std::hash::{BuildHasher, Hasher};
use std::path::{Path, PathBuf};
use std::process::Command;

use forestlod_experiments::html::base64;

#[path = "../../reference/tests/common/mod.rs"]
mod common;

/// A random 32-byte secret as 64 hex digits (std's randomly seeded hasher, no extra crate).
fn random_hex() -> String {
    (0..4)
        .map(|i| {
            let mut h = std::collections::hash_map::RandomState::new().build_hasher();
            h.write_u64(i);
            format!("{:016x}", h.finish())
        })
        .collect()
}

/// A run folder holding a copy of the committed `mip_mode` sweep, with a secret file beside
/// the run (outside it): `(run, sweep folder, secret file, secret text)`.
fn crafted_run(name: &str) -> (PathBuf, PathBuf, PathBuf, String) {
    let base = common::fresh_dir("report-hostile", name);
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
    let text = random_hex();
    let secret = common::write(&base, "secret.txt", format!("{text}\n"));
    (run, sweep, secret, text)
}

/// Edits the copied `sweep.json` with `edit`.
fn edit_manifest(sweep: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let path = sweep.join("sweep.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    edit(&mut m);
    std::fs::write(&path, serde_json::to_string_pretty(&m).unwrap()).unwrap();
}

/// What `forestlod report --run run` did.
enum Outcome {
    /// It failed with this error line.
    Refused(String),
    /// It wrote a report.
    Written,
}

/// Runs the report on `run`, asserting the contract of the module docs: no panic; either exit 1
/// with one `error:` line and no report, or exit 0 with a report that holds no byte sequence of
/// `secret`.
fn report(run: &Path, secret: &Path, text: &str) -> Outcome {
    let out = Command::new(env!("CARGO_BIN_EXE_forestlod"))
        .args(["report", "--run", run.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "{stderr}");
    let bytes = std::fs::read(secret).unwrap();
    let leaks = [text.to_string(), base64(&bytes), base64(text.as_bytes())];
    for name in ["report.md", "report.html"] {
        if let Ok(written) = std::fs::read_to_string(run.join(name)) {
            for leak in &leaks {
                assert!(
                    !written.contains(leak.as_str()),
                    "{name} holds the secret file's content ({leak})"
                );
            }
        }
    }
    if out.status.success() {
        assert!(run.join("report.html").is_file(), "{stderr}");
        Outcome::Written
    } else {
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "one error line: {stderr}");
        assert!(lines[0].starts_with("error:"), "{stderr}");
        assert!(
            !run.join("report.html").exists() && !run.join("report.md").exists(),
            "a refused report writes nothing"
        );
        Outcome::Refused(lines[0].to_string())
    }
}

/// The refusal names the run folder, the manifest, the key and the value (cut as every error
/// cuts a file's content).
fn assert_names(line: &str, run: &Path, key: &str, value: &str) {
    let manifest = run.join("mip_mode").join("sweep.json");
    let shown = forestlod_reference::InputError::new("", "", value, "").value;
    for part in [
        format!("run folder {}", run.display()),
        format!("{}: key {key}: value {shown:?}", manifest.display()),
        "reports read only their run".to_string(),
    ] {
        assert!(line.contains(&part), "{line:?} lacks {part:?}");
    }
}

#[test]
fn the_unedited_copy_reports_and_embeds_its_plots() {
    // The control: the copy is a run the report accepts, and it does embed files of the run, so
    // the cases below test the guard and not a report that embeds nothing.
    let (run, _, secret, text) = crafted_run("control");
    assert!(matches!(report(&run, &secret, &text), Outcome::Written));
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    // Issue 35: a plot with an SVG twin beside it is embedded as that SVG.
    let plot = std::fs::read(run.join("mip_mode/runtime.svg")).unwrap();
    assert!(
        html.contains(&base64(&plot)),
        "the run's own plot is embedded"
    );
}

#[cfg(unix)]
#[test]
fn a_plot_twin_that_leaves_the_run_is_not_read() {
    // The SVG twin of a plot is not named by the manifest; a twin that is a link to a file
    // outside the run (or a special file) is skipped unread, and the PNG is embedded instead.
    let (run, sweep, secret, text) = crafted_run("twin");
    let twin = sweep.join("runtime.svg");
    std::fs::remove_file(&twin).unwrap();
    std::os::unix::fs::symlink(&secret, &twin).unwrap();
    let fifo = sweep.join("accuracy.svg");
    std::fs::remove_file(&fifo).unwrap();
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    assert!(made, "mkfifo");
    assert!(matches!(report(&run, &secret, &text), Outcome::Written));
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    for png in ["runtime.png", "accuracy.png"] {
        let plot = std::fs::read(sweep.join(png)).unwrap();
        assert!(html.contains(&base64(&plot)), "{png} embedded instead");
    }
}

#[test]
fn manifest_text_holding_markdown_images_and_links_embeds_nothing() {
    let (run, sweep, secret, text) = crafted_run("text");
    let s = secret.display().to_string();
    let image = format!("![x]({s})");
    edit_manifest(&sweep, |m| {
        m["title"] = format!("{image} and [a link]({s})").into();
        m["description"] = format!("*{image}* `x`{image}` \\{image}").into();
        m["scenes"][0] = image.clone().into();
        m["plots"][0][1] = format!("caption {image}").into();
        m["images"][0]["setting"] = image.clone().into();
        m["images"][0]["camera"] = image.clone().into();
        m["images"][0]["per_lod"][0][0] = image.clone().into();
    });
    assert!(matches!(report(&run, &secret, &text), Outcome::Written));
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(!html.contains("<img alt=\"x\""), "a title became an image");
    assert!(
        !html.contains(&format!("href=\"{s}\"")),
        "a title became a link"
    );
    assert!(
        !html.contains("not embedded"),
        "no image outside the report's own was even asked for"
    );
}

#[test]
fn a_plot_path_with_dotdot_is_refused_naming_the_key() {
    let (run, sweep, secret, text) = crafted_run("dotdot");
    let value = "../../secret.txt";
    assert!(sweep.join(value).is_file(), "the path reaches the secret");
    edit_manifest(&sweep, |m| m["plots"][0][0] = value.into());
    let Outcome::Refused(line) = report(&run, &secret, &text) else {
        panic!("a plot outside the run was accepted");
    };
    assert_names(&line, &run, "plots[0][0]", value);
}

#[test]
fn an_absolute_image_path_is_refused_naming_the_key() {
    let (run, sweep, secret, text) = crafted_run("absolute");
    let value = secret.display().to_string();
    edit_manifest(&sweep, |m| m["images"][0]["color"] = value.clone().into());
    let Outcome::Refused(line) = report(&run, &secret, &text) else {
        panic!("an absolute image path was accepted");
    };
    assert_names(&line, &run, "images[0].color", &value);
}

#[test]
fn a_plot_that_links_outside_the_run_is_refused_naming_the_key() {
    let (run, sweep, secret, text) = crafted_run("symlink");
    std::os::unix::fs::symlink(&secret, sweep.join("evil.png")).unwrap();
    edit_manifest(&sweep, |m| m["plots"][1][0] = "evil.png".into());
    let Outcome::Refused(line) = report(&run, &secret, &text) else {
        panic!("a plot linking outside the run was accepted");
    };
    assert_names(&line, &run, "plots[1][0]", "evil.png");
    assert!(line.contains("outside the run folder"), "{line}");
}

#[test]
fn a_per_lod_map_in_a_linked_folder_outside_the_run_is_refused() {
    // A folder link inside the run that leads out of it: the path has no `..`, only its
    // resolution shows where it goes.
    let (run, sweep, secret, text) = crafted_run("folder-link");
    std::os::unix::fs::symlink(secret.parent().unwrap(), sweep.join("out")).unwrap();
    edit_manifest(&sweep, |m| {
        m["images"][0]["per_lod"][2][1] = "out/secret.txt".into()
    });
    let Outcome::Refused(line) = report(&run, &secret, &text) else {
        panic!("a map through a folder link out of the run was accepted");
    };
    assert_names(&line, &run, "images[0].per_lod[2][1]", "out/secret.txt");
}

#[test]
fn a_csv_outside_the_run_is_refused_naming_the_key() {
    let (run, sweep, secret, text) = crafted_run("csv");
    edit_manifest(&sweep, |m| m["csv"] = "../../secret.txt".into());
    let Outcome::Refused(line) = report(&run, &secret, &text) else {
        panic!("a CSV outside the run was accepted");
    };
    assert_names(&line, &run, "csv", "../../secret.txt");
    assert!(!line.contains(&text), "the error echoes the secret");
}

#[test]
fn a_manifest_that_links_outside_the_run_is_refused() {
    let (run, sweep, secret, text) = crafted_run("manifest-link");
    let outside = secret.parent().unwrap().join("sweep.json");
    std::fs::rename(sweep.join("sweep.json"), &outside).unwrap();
    std::os::unix::fs::symlink(&outside, sweep.join("sweep.json")).unwrap();
    let Outcome::Refused(line) = report(&run, &secret, &text) else {
        panic!("a manifest outside the run was read");
    };
    assert!(
        line.contains("sweep.json: manifest") && line.contains("outside the run folder"),
        "{line}"
    );
}
