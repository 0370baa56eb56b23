//! The stage table (`harness/src/stages.rs`, issue 27) walked: every stage has a row, every row's
//! twins exist under the stage's own name, every stage has a parity case that names it, and no
//! WGSL stage or GPU driver exists without a row. No GPU needed.

use std::path::{Path, PathBuf};

use forestlod_harness::stages::STAGES;
use forestlod_shared::StageId;

/// The workspace root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The file stem of a workspace path.
fn stem(path: &str) -> &str {
    Path::new(path)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("")
}

/// Stages whose CPU twin lives in a module of another name, and why.
const REFERENCE_ELSEWHERE: &[(StageId, &str)] = &[
    (
        StageId::Cull,
        "the baselines' reference is one module, reference/src/baselines.rs",
    ),
    (
        StageId::Primitive,
        "the baselines' reference is one module, reference/src/baselines.rs",
    ),
];

/// WGSL files and GPU driver files that are not stages: shared code, infrastructure, and parts
/// of the draw stage's driver (`gpu/src/draw.rs`: the depth read-back, and the point LOD's
/// command expansion of issue 33, judged by `parity::points` and the draw row's walk).
const NOT_STAGES: &[&str] = &[
    "common",
    "scan",
    "depth_copy",
    "point_commands",
    "lib",
    "context",
    "readback",
    "shaders",
    "wgsl_layout",
];

/// Stages without a generic harness backend: none (issue 27); every row runs in
/// `parity::every_stage`.
const MOST_WITHOUT_BACKEND: usize = 0;

#[test]
fn every_stage_has_a_row_with_its_twins_and_a_parity_case() {
    let ids: Vec<StageId> = STAGES.iter().map(|e| e.id).collect();
    assert_eq!(
        ids,
        StageId::ALL,
        "one row per stage, in StageId::ALL order"
    );
    let mut problems = Vec::new();
    for e in STAGES {
        let name = e.id.name();
        for (what, path) in [
            ("reference", e.reference),
            ("driver", e.driver),
            ("wgsl", e.wgsl),
            ("parity", e.parity),
        ] {
            if !root().join(path).is_file() {
                problems.push(format!("{name}: {what} file {path} does not exist"));
            }
        }
        if stem(e.driver) != name || stem(e.wgsl) != name {
            problems.push(format!(
                "{name}: the GPU twins must share the stage's name ({}, {})",
                e.driver, e.wgsl
            ));
        }
        let elsewhere = REFERENCE_ELSEWHERE.iter().any(|(id, _)| *id == e.id);
        if stem(e.reference) != name && !elsewhere {
            problems.push(format!(
                "{name}: the reference twin {} has another name",
                e.reference
            ));
        }
        match std::fs::read_to_string(root().join(e.parity)) {
            Ok(src) if src.contains(name) => {}
            Ok(_) => problems.push(format!(
                "{name}: its parity file {} never names it",
                e.parity
            )),
            Err(err) => problems.push(format!("{name}: {}: {err}", e.parity)),
        }
    }
    let without: Vec<&str> = STAGES
        .iter()
        .filter(|e| e.backend.is_none())
        .map(|e| e.id.name())
        .collect();
    eprintln!("stages without a generic harness backend: {without:?}");
    // A backend names a stage type of the harness (`stage::Name`, declared in `stage.rs` or
    // `stage_defs.rs`).
    let stage_src = ["harness/src/stage.rs", "harness/src/stage_defs.rs"]
        .map(|f| std::fs::read_to_string(root().join(f)).expect("read the harness stages"))
        .join("\n");
    for e in STAGES {
        if let Some(b) = e.backend {
            let ty = b.strip_prefix("stage::").unwrap_or(b);
            if !stage_src.contains(&format!("pub struct {ty};"))
                || !stage_src.contains(&format!("impl Judged for {ty} "))
            {
                problems.push(format!(
                    "{}: backend {b} is not a judged stage type of harness/src/stage*.rs",
                    e.id.name()
                ));
            }
        }
    }
    if without.len() > MOST_WITHOUT_BACKEND {
        problems.push(format!(
            "{} stages without a harness backend ({without:?}), at most {MOST_WITHOUT_BACKEND}",
            without.len()
        ));
    }
    assert!(problems.is_empty(), "stage table:\n{}", problems.join("\n"));
}

#[test]
fn no_gpu_stage_exists_without_a_row() {
    let mut problems = Vec::new();
    for (dir, ext) in [("gpu/src/shaders", "wgsl"), ("gpu/src", "rs")] {
        for f in std::fs::read_dir(root().join(dir)).expect("read the GPU crate") {
            let path = f.expect("dir entry").path();
            if path.extension().and_then(|e| e.to_str()) != Some(ext) {
                continue;
            }
            let s = path
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("")
                .to_string();
            if NOT_STAGES.contains(&s.as_str()) {
                continue;
            }
            if StageId::from_name(&s).is_none() {
                problems.push(format!(
                    "{}: a GPU stage without a StageId and a row",
                    path.display()
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// Issue 36 (coverage by construction): the modes and numeric parameters a row names are entries
/// of `forestlod_shared::registry::PARAMS` of that kind, and **every** entry of the registry is
/// named by at least one row, so a parameter or mode added to the registry is walked by
/// `parity::every_stage`'s walk (every choice; least and greatest value) once it names the stage
/// that reads it, and this test fails until it does.
#[test]
fn every_parameter_is_walked_by_a_stage_that_reads_it() {
    use forestlod_shared::registry::{PARAMS, ParamKind, param};
    let mut problems = Vec::new();
    for e in STAGES {
        for &m in e.modes {
            match param(m).map(|s| s.kind) {
                Some(ParamKind::Choice(_)) => {}
                Some(_) => problems.push(format!("{}: mode {m} is a number", e.id.name())),
                None => problems.push(format!("{}: mode {m} is no parameter", e.id.name())),
            }
        }
        for &p in e.params {
            match param(p).map(|s| s.kind) {
                Some(ParamKind::Float { .. } | ParamKind::Uint { .. }) => {}
                Some(_) => problems.push(format!("{}: parameter {p} is a choice", e.id.name())),
                None => problems.push(format!("{}: {p} is no parameter", e.id.name())),
            }
        }
    }
    for spec in &PARAMS {
        let named = STAGES
            .iter()
            .any(|e| e.modes.contains(&spec.name) || e.params.contains(&spec.name));
        if !named {
            problems.push(format!(
                "parameter {} is read by no stage row (harness/src/stages.rs `modes`/`params`)",
                spec.name
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
