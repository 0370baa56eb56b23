//! Fails when a string literal or comment of a tracked `.rs` file of the workspace spells out a
//! list of one mode's choice names by hand (`"grid, grid-aabb, quadtree"`, `none, lod0, all`,
//! `"expected 0 (off) or 1 (on)"`): such a list goes stale when a mode is added. Names come from
//! the parameter table ([`forestlod_shared::PARAMS`]), so a new mode is covered with no edit here.
//!
//! A hand list is a run of choice names of one mode inside one literal or comment, consecutive
//! names separated by a comma or `|`, or by `or`/`and` between coded names (`0 (off) or 1 (on)`)
//! or at the end of a comma list (`a, b and c`),
//! with optional quotes, backticks, parentheses and codes (a parenthesized citation may follow a
//! name), naming at least three distinct
//! choices, or every choice of a mode that has only two. Two names of a larger mode (a chosen
//! pair, `octree,kmeans`) and prose without a comma (`lod0 and all`) are not lists. A list that
//! spans lines is not seen.
//!
//! Exempt: the enum declarations themselves (one name a line, so nothing to find today), the pin
//! of the generated texts (`shared/tests/param_texts.rs`, whose hand lists are the point).

use std::path::Path;
use std::process::Command;

use forestlod_shared::PARAMS;

/// Files that spell their lists out on purpose (module docs).
const EXEMPT: &[&str] = &[
    "shared/src/fade.rs",
    "shared/src/params.rs",
    "shared/tests/param_texts.rs",
    // This test's own examples of what it finds.
    "shared/tests/no_hand_lists.rs",
];

/// The string literals and comments of Rust source `src`: `(line, text)`, each a piece of one
/// line (a literal or block comment over several lines gives one piece per line).
fn texts(src: &str) -> Vec<(usize, String)> {
    let b: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            let start = i;
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
            out.push((line, b[start..i].iter().collect()));
            continue;
        }
        if c == '/' && next == Some('*') {
            i += 2;
            let mut piece = String::new();
            while i < b.len() && !(b[i] == '*' && b.get(i + 1) == Some(&'/')) {
                if b[i] == '\n' {
                    out.push((line, std::mem::take(&mut piece)));
                    line += 1;
                } else {
                    piece.push(b[i]);
                }
                i += 1;
            }
            out.push((line, piece));
            i += 2;
            continue;
        }
        // Character literals that hold a quote: not the start of a string.
        if c == '\'' && (next == Some('"') || (next == Some('\\') && b.get(i + 2) == Some(&'"'))) {
            i += if next == Some('"') { 3 } else { 4 };
            continue;
        }
        let raw_hashes = if c == 'r' && matches!(next, Some('"' | '#')) {
            let mut j = i + 1;
            while b.get(j) == Some(&'#') {
                j += 1;
            }
            (b.get(j) == Some(&'"')).then_some(j - i - 1)
        } else {
            None
        };
        if c == '"' || raw_hashes.is_some() {
            let hashes = raw_hashes.unwrap_or(0);
            i += if raw_hashes.is_some() { hashes + 2 } else { 1 };
            let mut piece = String::new();
            while let Some(&ch) = b.get(i) {
                if raw_hashes.is_none() && ch == '\\' {
                    piece.push(' ');
                    if b.get(i + 1) == Some(&'\n') {
                        out.push((line, std::mem::take(&mut piece)));
                        line += 1;
                    }
                    i += 2;
                    continue;
                }
                if ch == '"' && (0..hashes).all(|k| b.get(i + 1 + k) == Some(&'#')) {
                    i += 1 + hashes;
                    break;
                }
                if ch == '\n' {
                    out.push((line, std::mem::take(&mut piece)));
                    line += 1;
                } else {
                    piece.push(ch);
                }
                i += 1;
            }
            out.push((line, piece));
            continue;
        }
        if c == '\n' {
            line += 1;
        }
        i += 1;
    }
    out
}

fn is_word(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == '-'
}

/// The hand lists of `modes` (each a mode's choice names) in `text`, as the matched text.
fn hand_lists(text: &str, modes: &[Vec<&'static str>]) -> Vec<String> {
    let chars: Vec<char> = text.chars().collect();
    // Words: `(start, end, word)`, character offsets.
    let mut words = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        if is_word(chars[i]) {
            let s = i;
            while i < chars.len() && is_word(chars[i]) {
                i += 1;
            }
            words.push((s, i, chars[s..i].iter().collect::<String>()));
        } else {
            i += 1;
        }
    }
    let gap_ok = |from: usize, to: usize, continuing: bool| {
        // Between two names: separators, quotes, parentheses, codes, `or`/`and`; a comma or `|`.
        let mut gap: String = chars[from..to].iter().collect();
        // A citation right after the first name, `alpha (E§4.4), dither`.
        let trimmed = gap.trim_start();
        if let Some(close) = trimmed.find(')').filter(|_| trimmed.starts_with('(')) {
            gap = trimmed[close + 1..].to_string();
        }
        let rest: Vec<&str> = gap
            .split(|c: char| !is_word(c))
            .filter(|w| !w.is_empty())
            .collect();
        rest.iter()
            .all(|w| *w == "or" || *w == "and" || w.chars().all(|c| c.is_ascii_digit()))
            && (gap.contains([',', '|'])
                || rest.iter().any(|w| w != &"or" && w != &"and")
                || (continuing && rest.len() == 1))
            && gap
                .chars()
                .all(|c| is_word(c) || c.is_whitespace() || ",|`\"'()".contains(c))
    };
    let mut found = Vec::new();
    for names in modes {
        let need = names.len().min(3);
        let hits: Vec<_> = words
            .iter()
            .filter(|(_, _, w)| names.contains(&w.as_str()))
            .collect();
        let mut k = 0;
        while k < hits.len() {
            let mut run = vec![hits[k]];
            while k + 1 < hits.len() && gap_ok(run.last().unwrap().1, hits[k + 1].0, run.len() >= 2)
            {
                run.push(hits[k + 1]);
                k += 1;
            }
            let mut distinct: Vec<&str> = run.iter().map(|h| h.2.as_str()).collect();
            distinct.sort_unstable();
            distinct.dedup();
            if distinct.len() >= need {
                let (s, e) = (run[0].0, run.last().unwrap().1);
                found.push(chars[s..e].iter().collect());
            }
            k += 1;
        }
    }
    found
}

#[test]
fn no_hand_list_of_choices() {
    let modes: Vec<Vec<&'static str>> = PARAMS
        .iter()
        .map(|spec| spec.choice_names())
        .filter(|names| names.len() >= 2)
        .collect();
    assert!(modes.len() >= 7, "the table's choice parameters");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let listed = Command::new("git")
        .args(["ls-files", "-z", "*.rs"])
        .current_dir(&root)
        .output()
        .expect("git ls-files runs");
    assert!(listed.status.success(), "git ls-files failed");
    let files: Vec<String> = String::from_utf8(listed.stdout)
        .expect("UTF-8 paths")
        .split('\0')
        .filter(|f| !f.is_empty())
        .map(str::to_string)
        .collect();
    assert!(files.len() > 50, "only {} files listed", files.len());
    let mut hits = Vec::new();
    for file in &files {
        if EXEMPT.contains(&file.as_str()) {
            continue;
        }
        let Ok(src) = std::fs::read_to_string(root.join(file)) else {
            continue; // deleted in the work tree
        };
        for (line, text) in texts(&src) {
            for list in hand_lists(&text, &modes) {
                hits.push(format!("{file}:{line}: {list:?}"));
            }
        }
    }
    assert!(
        hits.is_empty(),
        "hand lists of choice names (generate them from the mode's choices):\n{}",
        hits.join("\n")
    );
}

#[test]
fn finds_the_lists_it_should() {
    let modes = vec![
        vec!["none", "alpha", "dither", "dither-sequential"],
        vec!["off", "on"],
        vec!["grid", "grid-aabb", "quadtree", "octree"],
    ];
    for (text, n) in [
        (
            "Fade mode: none, alpha (E§4.4), dither, dither-sequential (G§4)",
            1,
        ),
        (
            "expected 0 (none), 1 (alpha), 2 (dither) or 3 (dither-sequential)",
            1,
        ),
        ("expected 0 (off) or 1 (on)", 1),
        ("off or on", 0), // no comma, no codes: prose
        ("off, on", 1),
        ("`none`, `alpha` and `dither`", 1),
        ("[\"none\", \"alpha\", \"dither\"]", 1),
        ("grid,grid-aabb,quadtree", 1),
        ("octree, grid", 0),   // a pair of a larger mode
        ("none and alpha", 0), // prose
        ("quadtree, octree and grid", 1),
        ("the quadtree, the octree and grid", 0),
        ("dither-sequential", 0),
        ("none of them, alpha", 0), // not a list of names
    ] {
        assert_eq!(hand_lists(text, &modes).len(), n, "{text}");
    }
    let t = texts("let a = \"x, y\"; // c\n/* d\ne */ let c = '\"'; r#\"f\"#");
    let got: Vec<_> = t.iter().map(|(l, s)| (*l, s.as_str())).collect();
    assert_eq!(
        got,
        [(1, "x, y"), (1, "// c"), (2, " d"), (3, "e "), (3, "f")]
    );
}
