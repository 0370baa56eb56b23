//! `mutate`: the project's own mutation testing (issue 15), not part of CI.
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin mutate -- --list            # every mutant
//! cargo run --release -p forestlod-experiments --bin mutate -- --sample 20 --lang wgsl
//! ```
//!
//! **Mutants** (deterministic: files in sorted order, lines top to bottom, operators in the order
//! below, each match once), by a small operator set applied to one line at a time:
//! - `cmp`: flip a comparison (`<` ↔ `<=`, `>` ↔ `>=`, `==` → `!=`);
//! - `const`: an integer literal +1 (WGSL `3u` → `4u`, Rust `3` → `4`) or a float `0.5` → `1.5`;
//! - `swap`: `min(` ↔ `max(`, `+` → `-` between two operands;
//! - `round`: `floor` → `ceil`, `ceil` → `floor`, `round` → `floor`;
//! - `drop`: a WGSL assignment statement commented out.
//!
//! Rust mutants target `shared/src`, the reference stages (`reference/src/{select,refine,
//! hier_select,coalesce,command_order,hierarchy,mips,bake,draw,raster,sampler,batches,baselines}.rs`),
//! the ground truth (`reference/src/ground_truth.rs`), the harness's judges
//! (`harness/src/{stats,image_compare,texel_compare,judge}.rs`) and the GPU drivers
//! (`gpu/src/*.rs`), code before the
//! first `#[cfg(test)]` and outside comments; each needs a rebuild of the test binary. WGSL
//! mutants target every `gpu/src/shaders/*.wgsl` and need no rebuild: the mutated text is passed
//! through `FORESTLOD_MUTANT_WGSL` (`gpu/src/shaders.rs`, `mutant_or`).
//!
//! **Run**: each mutant against the tests that target its file (`targets`: the parity module of
//! the stage, plus `properties` for Rust mutants of `shared` and the reference) with a timeout;
//! a mutant is *killed* when a test fails (the first failing test is recorded), *timeout* when a
//! test binary outlives the timeout (not a kill: issue 36), *survived* when all pass, *invalid* when it does not compile (Rust) or its module does not validate (counted
//! apart: not a behaviour). Rust mutants are applied in place and always restored; their test
//! binaries are rebuilt before the timeout starts (the timeout bounds the tests only).
//! `--sample N` runs every `M/N`-th mutant of the list (a deterministic stride), so a slow machine
//! can run a representative slice; `--stratified N` about `N` mutants spread over every file
//! (at least one each, the rest in proportion to each file's count: issue 36); `--only ID,ID` runs those ids of the list (a re-run after a
//! survivor got a sharper test); `--csv NAME` names the table. Writes `experiments/results/mutation/mutants.csv` (mutant,
//! file, line, operator, before, after, verdict, killed by, seconds) and prints the kill rate,
//! Rust and WGSL apart.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// One mutant: a line of a file with one replacement.
#[derive(Clone, Debug)]
struct Mutant {
    file: PathBuf,
    line: usize,
    operator: &'static str,
    before: String,
    after: String,
}

impl Mutant {
    fn wgsl(&self) -> bool {
        self.file.extension().is_some_and(|e| e == "wgsl")
    }
}

/// `(operator, from, to)` textual replacements, tried at every occurrence.
const REPLACEMENTS: &[(&str, &str, &str)] = &[
    ("cmp", " < ", " <= "),
    ("cmp", " <= ", " < "),
    ("cmp", " > ", " >= "),
    ("cmp", " >= ", " > "),
    ("cmp", " == ", " != "),
    ("const", "0.5", "1.5"),
    ("swap", "min(", "max("),
    ("swap", "max(", "min("),
    ("swap", " + ", " - "),
    ("round", "floor(", "ceil("),
    ("round", "ceil(", "floor("),
    ("round", "round(", "floor("),
];

fn rust_files(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for dir in ["shared/src", "gpu/src"] {
        if let Ok(rd) = std::fs::read_dir(root.join(dir)) {
            for e in rd.flatten() {
                let p = e.path();
                if p.extension().is_some_and(|x| x == "rs") {
                    out.push(p.strip_prefix(root).unwrap().to_path_buf());
                }
            }
        }
    }
    for f in [
        "select",
        "refine",
        "hier_select",
        "coalesce",
        "command_order",
        "hierarchy",
        "mips",
        "bake",
        "draw",
        "raster",
        "sampler",
        "batches",
        "baselines",
        "ground_truth",
    ] {
        out.push(PathBuf::from(format!("reference/src/{f}.rs")));
    }
    // The harness's judges (issue 36: the verifiers are code that can be wrong too).
    for f in ["stats", "image_compare", "texel_compare", "judge"] {
        out.push(PathBuf::from(format!("harness/src/{f}.rs")));
    }
    out.sort();
    out
}

/// A stratified sample of about `n` mutants (issue 36): every file gets at least one, the rest
/// shared in proportion to each file's count, evenly spaced within the file; ids of the full list.
fn stratified(mutants: &[Mutant], n: usize) -> Vec<usize> {
    let mut files: Vec<&Path> = mutants.iter().map(|m| m.file.as_path()).collect();
    files.dedup();
    let total = mutants.len().max(1);
    let spare = n.saturating_sub(files.len());
    let mut out = Vec::new();
    for f in files {
        let ids: Vec<usize> = (0..mutants.len())
            .filter(|&i| mutants[i].file == f)
            .collect();
        let quota = (1 + spare * ids.len() / total).min(ids.len());
        for k in 0..quota {
            out.push(ids[k * ids.len() / quota + ids.len() / (2 * quota)]);
        }
    }
    out
}

fn wgsl_files(root: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(root.join("gpu/src/shaders"))
        .map(|rd| {
            rd.flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "wgsl"))
                .map(|p| p.strip_prefix(root).unwrap().to_path_buf())
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

/// Integer literal +1 on a line: the first standalone integer (`3u`, `3`), skipping ones inside
/// identifiers and floats.
fn const_mutant(line: &str, wgsl: bool) -> Option<String> {
    let b = line.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit()
            && (i == 0
                || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_' || b[i - 1] == b'.'))
        {
            let mut j = i;
            while j < b.len() && b[j].is_ascii_digit() {
                j += 1;
            }
            let next = b.get(j).copied();
            let ok = if wgsl {
                next == Some(b'u') || next == Some(b'i')
            } else {
                !matches!(next, Some(b'.') | Some(b'e') | Some(b'x') | Some(b'_'))
                    && !next.is_some_and(|c| c.is_ascii_alphabetic())
            };
            if ok {
                let n: u64 = line[i..j].parse().ok()?;
                return Some(format!("{}{}{}", &line[..i], n + 1, &line[j..]));
            }
            i = j;
        } else {
            i += 1;
        }
    }
    None
}

/// Every mutant of `file`, deterministic.
fn mutants_of(root: &Path, file: &Path) -> Vec<Mutant> {
    let text = std::fs::read_to_string(root.join(file)).unwrap_or_default();
    let wgsl = file.extension().is_some_and(|e| e == "wgsl");
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if !wgsl && line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let t = line.trim_start();
        if t.starts_with("//") || t.starts_with("#[") || t.starts_with("///") || t.is_empty() {
            continue;
        }
        let code = line.split("//").next().unwrap_or(line);
        let mut push = |operator: &'static str, after: String| {
            if after != line {
                out.push(Mutant {
                    file: file.to_path_buf(),
                    line: n + 1,
                    operator,
                    before: line.to_string(),
                    after,
                });
            }
        };
        for &(op, from, to) in REPLACEMENTS {
            for (pos, _) in code.match_indices(from) {
                if from == " < " && code[pos..].starts_with(" <= ") {
                    continue;
                }
                if from == " > " && code[pos..].starts_with(" >= ") {
                    continue;
                }
                push(
                    op,
                    format!("{}{}{}", &line[..pos], to, &line[pos + from.len()..]),
                );
            }
        }
        if let Some(m) = const_mutant(code, wgsl) {
            let rest = &line[code.len()..];
            push("const", format!("{m}{rest}"));
        }
        if wgsl
            && t.ends_with(';')
            && !t.starts_with("let ")
            && !t.starts_with("var ")
            && !t.starts_with("const ")
            && !t.starts_with("override ")
            && !t.starts_with("return")
            && t.contains(" = ")
        {
            let indent = &line[..line.len() - t.len()];
            push("drop", format!("{indent}// {t}"));
        }
    }
    out
}

/// The test filters that target `file`: `(test binary, filter)`. The reference stages that
/// record threshold coverage (`select`, `refine`, `hier_select`, `draw`) are also targeted by the
/// `coverage` binary, which checks what those counters count.
fn targets(file: &Path) -> Vec<(&'static str, String)> {
    let stem = file.file_stem().unwrap().to_string_lossy().to_string();
    // The truth and the judges: their unit tests (`lib` runs `cargo test --workspace --lib`
    // with the module as filter), then the tests that use them.
    if file.starts_with("harness") {
        return vec![
            ("lib", format!("{stem}::")),
            ("gate_sensitivity", String::new()),
            ("parity", "every_stage::".into()),
        ];
    }
    if stem == "ground_truth" {
        return vec![
            ("lib", "ground_truth::".into()),
            ("truth_oracle", String::new()),
            ("reference", String::new()),
        ];
    }
    if matches!(stem.as_str(), "hierarchy" | "coalesce" | "command_order") {
        return vec![
            ("properties", String::new()),
            ("parity", "hier_select::".into()),
        ];
    }
    let mut t = targets_of_stage(file);
    // A Rust mutant also meets its module's unit tests.
    if file.extension().is_some_and(|e| e == "rs") {
        t.insert(0, ("lib", format!("{stem}::")));
    }
    // Every GPU-side mutant also meets the walk of every mode and parameter extreme (issue 36),
    // and `common.wgsl` holds the cut's rules too.
    if file.starts_with("gpu") {
        if stem == "common" {
            t.insert(1, ("parity", "hier_select::".into()));
        }
        // A stage's own walk; `common.wgsl` and the shared drivers every walk.
        let walk = if forestlod_shared::StageId::from_name(&stem).is_some() {
            format!("every_stage::walk_{stem}")
        } else {
            "every_stage::walk_".into()
        };
        t.push(("parity", walk));
    }
    if file.starts_with("reference")
        && matches!(stem.as_ref(), "select" | "refine" | "hier_select" | "draw")
    {
        t.push(("coverage", String::new()));
    }
    t
}

fn targets_of_stage(file: &Path) -> Vec<(&'static str, String)> {
    let stem = file.file_stem().unwrap().to_string_lossy().to_string();
    let parity = |m: &str| ("parity", format!("{m}::"));
    match stem.as_str() {
        "common" | "shaders" | "lib" | "types" | "view" | "interval" | "camera" | "params" => vec![
            parity("select"),
            parity("draw"),
            parity("metamorphic"),
            ("properties", String::new()),
        ],
        "select" | "refine" | "mips" | "bake" | "draw" => {
            let mut t = vec![parity(&stem)];
            if file.starts_with("reference") || file.starts_with("shared") {
                t.push(("properties", String::new()));
            }
            t
        }
        // The hierarchical cut: its parity module, plus `properties` (`hierarchy_properties`)
        // for the reference; a GPU-driver or WGSL mutant needs only the parity side.
        "hier_select" => {
            let mut t = vec![parity("hier_select")];
            if file.starts_with("reference") {
                t.push(("properties", String::new()));
            }
            t
        }
        "primitive" | "cull" | "baselines" => vec![parity("baselines")],
        "raster" | "sampler" => vec![parity("draw"), parity("bake"), parity("sampler_lod")],
        "batches" => vec![parity("metamorphic"), ("properties", String::new())],
        "depth_copy" => vec![parity("draw")],
        // The layout checker: the naga layout tests read it.
        "wgsl_layout" => vec![("layout", String::new()), parity("draw")],
        // The threshold counters: the coverage test recounts them.
        "coverage" => vec![("coverage", String::new())],
        _ => vec![
            parity("draw"),
            parity("metamorphic"),
            ("properties", String::new()),
        ],
    }
}

/// Runs the targeted tests with a timeout: `Ok(None)` all passed, `Ok(Some(test))` the first
/// failure, `Err(why)` the mutant did not build or validate.
fn run_tests(
    root: &Path,
    m: &Mutant,
    mutant_file: Option<&Path>,
    timeout: Duration,
) -> Result<Option<String>, String> {
    // A WGSL mutant that does not parse or validate is not a behaviour: the `forestlod-gpu` unit
    // and layout tests validate every module with naga (through the same hook) and say so.
    if let Some(f) = mutant_file {
        let name = m.file.file_name().unwrap().to_string_lossy();
        let out = Command::new("cargo")
            .current_dir(root)
            .args(["test", "-q", "--workspace", "--test", "layout"])
            .args(["--", "--test-threads", "1"])
            .env("FORESTLOD_MUTANT_WGSL", format!("{name}={}", f.display()))
            .output()
            .map_err(|e| e.to_string())?;
        let text = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        if text.contains("WGSL parse error") || text.contains("WGSL validation error") {
            return Err("WGSL does not validate (naga)".into());
        }
    }
    // A WGSL mutant changes only the GPU: the CPU-only `properties` binary cannot see it.
    let targets: Vec<_> = targets(&m.file)
        .into_iter()
        .filter(|(binary, _)| !(mutant_file.is_some() && *binary == "properties"))
        .collect();
    // A Rust mutant rebuilds the targeted test binaries first, outside the timeout: the timeout
    // bounds the tests, not the compiler (a slow rebuild on a loaded machine is no kill), and a
    // mutant that does not compile is invalid, not killed.
    if mutant_file.is_none() {
        let mut build = Command::new("cargo");
        build
            .current_dir(root)
            .args(["test", "-q", "--no-run", "--workspace"]);
        for (binary, _) in &targets {
            if *binary == "lib" {
                build.arg("--lib");
            } else {
                build.args(["--test", binary]);
            }
        }
        let out = build.output().map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err("does not compile".into());
        }
    }
    for (binary, filter) in targets {
        let mut cmd = Command::new("cargo");
        cmd.current_dir(root).args(["test", "-q", "--workspace"]);
        if binary == "lib" {
            cmd.arg("--lib");
        } else {
            cmd.args(["--test", binary]);
        }
        // Proptest shrinking is cut short: only the failure is wanted, and a shrinking run
        // that outlasts the timeout would count as a timeout instead of a named failing test.
        cmd.arg("--")
            .arg(&filter)
            .args(["--test-threads", "1"])
            .env("PROPTEST_MAX_SHRINK_ITERS", "0");
        // Output to a file, not a pipe: a failing run prints more than a pipe holds, and a child
        // blocked on a full pipe that nobody reads until it exits would end as a timeout.
        let log = std::env::temp_dir().join(format!("forestlod-mutant-{}.log", std::process::id()));
        let file = std::fs::File::create(&log).map_err(|e| format!("{}: {e}", log.display()))?;
        cmd.stdout(file.try_clone().map_err(|e| e.to_string())?)
            .stderr(file);
        if let Some(f) = mutant_file {
            let name = m.file.file_name().unwrap().to_string_lossy();
            cmd.env("FORESTLOD_MUTANT_WGSL", format!("{name}={}", f.display()));
        }
        // Its own process group, so that a timeout kills the test binary too: killing `cargo`
        // alone left the test binary running, holding the output pipe, and the tool waited on
        // it for as long as the mutant's hang lasted.
        std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
        let mut child = cmd.spawn().map_err(|e| e.to_string())?;
        let start = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
                break Some(s);
            }
            if start.elapsed() > timeout {
                let _ = Command::new("kill")
                    .args(["-KILL", "--", &format!("-{}", child.id())])
                    .status();
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(200));
        };
        let text = String::from_utf8_lossy(&std::fs::read(&log).unwrap_or_default()).to_string();
        match status {
            None => return Ok(Some(format!("{binary} {filter} (timeout)"))),
            Some(s) if s.success() => continue,
            Some(_) => {
                if text.contains("error[E") || text.contains("could not compile") {
                    return Err("does not compile".into());
                }
                // A WGSL mutant that does not validate is no behaviour; a Rust mutant whose
                // shader (a constant it generates) does not validate is caught by the failing
                // test like any other (issue 36: such Rust mutants were counted invalid).
                if mutant_file.is_some()
                    && (text.contains("Shader validation error")
                        || text.contains("Validation Error")
                        || text.contains("parsing error"))
                {
                    return Err("WGSL does not validate".into());
                }
                // `-q` prints no `test NAME ... FAILED` lines: the failure section's
                // `---- NAME stdout ----` header names the first failing test.
                let failed = text
                    .lines()
                    .find_map(|l| {
                        l.strip_prefix("test ")
                            .and_then(|r| r.strip_suffix(" ... FAILED"))
                            .or_else(|| {
                                l.strip_prefix("---- ")
                                    .and_then(|r| r.strip_suffix(" stdout ----"))
                            })
                            .map(str::to_string)
                    })
                    .or_else(|| {
                        text.lines()
                            .find(|l| l.contains("panicked at"))
                            .map(|l| l.chars().take(80).collect())
                    })
                    .unwrap_or_else(|| format!("{binary} {filter}"));
                return Ok(Some(format!("{binary}: {failed}")));
            }
        }
    }
    Ok(None)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let lang = flag("--lang").unwrap_or_else(|| "all".into());
    let mut mutants = Vec::new();
    if lang != "wgsl" {
        for f in rust_files(&root) {
            mutants.extend(mutants_of(&root, &f));
        }
    }
    if lang != "rust" {
        for f in wgsl_files(&root) {
            mutants.extend(mutants_of(&root, &f));
        }
    }
    if args.iter().any(|a| a == "--list") {
        for (i, m) in mutants.iter().enumerate() {
            println!(
                "{i}\t{}:{}\t{}\t{}",
                m.file.display(),
                m.line,
                m.operator,
                m.after.trim()
            );
        }
        eprintln!("{} mutants", mutants.len());
        return;
    }
    let sample: usize = flag("--sample")
        .and_then(|s| s.parse().ok())
        .unwrap_or(mutants.len());
    let timeout = Duration::from_secs(
        flag("--timeout")
            .and_then(|s| s.parse().ok())
            .unwrap_or(600),
    );
    let stride = (mutants.len() / sample.max(1)).max(1);
    let only: Option<Vec<usize>> =
        flag("--only").map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect());
    let strat: Option<usize> = flag("--stratified").and_then(|s| s.parse().ok());
    let chosen: Vec<(usize, Mutant)> = match (&only, strat) {
        // `--stratified N`: every file, in proportion to its count (issue 36).
        (None, Some(n)) => stratified(&mutants, n)
            .into_iter()
            .map(|i| (i, mutants[i].clone()))
            .collect(),
        _ => match &only {
            // `--only 88,110`: these ids of the list (after survivors got a sharper test).
            Some(ids) => ids
                .iter()
                .filter_map(|&i| mutants.get(i).cloned().map(|m| (i, m)))
                .collect(),
            None => mutants
                .iter()
                .cloned()
                .enumerate()
                .step_by(stride)
                .take(sample)
                .collect(),
        },
    };
    let out_dir = root.join("experiments/results/mutation");
    std::fs::create_dir_all(&out_dir).expect("create experiments/results/mutation");
    let csv_path = out_dir.join(flag("--csv").unwrap_or_else(|| "mutants.csv".into()));
    let mut csv = String::from("id,file,line,operator,before,after,verdict,killed_by,seconds\n");
    let (mut killed, mut survived, mut invalid, mut timeouts) =
        ([0u32; 2], [0u32; 2], [0u32; 2], [0u32; 2]);
    eprintln!(
        "{} of {} mutants (every {stride}th)",
        chosen.len(),
        mutants.len()
    );
    for (id, m) in &chosen {
        let start = Instant::now();
        let path = root.join(&m.file);
        let original = std::fs::read_to_string(&path).expect("read");
        let mutated: String = original
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i + 1 == m.line {
                    m.after.clone()
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
            + if original.ends_with('\n') { "\n" } else { "" };
        let result = if m.wgsl() {
            let tmp = std::env::temp_dir().join(format!("forestlod-mutant-{id}.wgsl"));
            std::fs::write(&tmp, &mutated).expect("write mutant");
            let r = run_tests(&root, m, Some(&tmp), timeout);
            let _ = std::fs::remove_file(&tmp);
            r
        } else {
            std::fs::write(&path, &mutated).expect("write mutant");
            let r = run_tests(&root, m, None, timeout);
            std::fs::write(&path, &original).expect("RESTORE the mutated file");
            r
        };
        let k = usize::from(m.wgsl());
        let (verdict, by) = match result {
            // A timeout is not a named failing test (issue 36): counted apart, triaged like a
            // survivor.
            Ok(Some(t)) if t.ends_with("(timeout)") => {
                timeouts[k] += 1;
                ("timeout", t)
            }
            Ok(Some(t)) => {
                killed[k] += 1;
                ("killed", t)
            }
            Ok(None) => {
                survived[k] += 1;
                ("survived", String::new())
            }
            Err(e) => {
                invalid[k] += 1;
                ("invalid", e)
            }
        };
        let q = |s: &str| format!("\"{}\"", s.trim().replace('"', "\"\""));
        csv.push_str(&format!(
            "{id},{},{},{},{},{},{verdict},{},{:.0}\n",
            m.file.display(),
            m.line,
            m.operator,
            q(&m.before),
            q(&m.after),
            q(&by),
            start.elapsed().as_secs_f64()
        ));
        std::fs::write(&csv_path, &csv).expect("write mutants.csv");
        eprintln!(
            "mutant {id} {}:{} {}: {verdict} {by} ({:.0} s)",
            m.file.display(),
            m.line,
            m.operator,
            start.elapsed().as_secs_f64()
        );
    }
    for (k, lang) in ["Rust", "WGSL"].iter().enumerate() {
        let valid = killed[k] + survived[k] + timeouts[k];
        if valid + invalid[k] > 0 {
            println!(
                "{lang}: {} killed by a failing test, {} timed out, {} survived, {} invalid; \
                 kill rate {:.0} % of {valid} valid mutants (timeouts not counted as kills)",
                killed[k],
                timeouts[k],
                survived[k],
                invalid[k],
                100.0 * killed[k] as f64 / valid.max(1) as f64
            );
        }
    }
    println!("table: {}", csv_path.display());
}
