//! docs/library.md names the files one touches to add a criterion, a
//! trajectory shape, a robot or log format, an estimator…: every path it
//! names must exist, so that a move or a split (as `excitation/objective.rs`
//! into `excitation/objective/`) shows up here and not in a reader's hands.
//!
//! A path is a backticked span with a `/` that ends in `.rs` or `/`, or that
//! starts with a folder of the repository (`src/`, `tests/`, `python/`, …),
//! and the first word of the layout block's lines. Spans that start with
//! `src/`, `tests/`, … are relative to the repository, the others (`optim/ga.rs`)
//! to `src/`; `{a,b}` expands to both; spans with a placeholder (`<shape>`) or
//! a wildcard are skipped.

use std::path::Path;

const ROOTS: [&str; 10] = [
    "src/",
    "tests/",
    "python/",
    "designs/",
    "scripts/",
    "benches/",
    "examples/",
    "docs/",
    ".ci/",
    "fuzz/",
];

/// `a/{b,c}.rs` → `a/b.rs`, `a/c.rs` (one group; nested groups are not used).
fn expand(s: &str) -> Vec<String> {
    match (s.find('{'), s.find('}')) {
        (Some(i), Some(j)) if i < j => s[i + 1..j]
            .split(',')
            .flat_map(|alt| expand(&format!("{}{}{}", &s[..i], alt.trim(), &s[j + 1..])))
            .collect(),
        _ => vec![s.to_string()],
    }
}

/// The paths named on one line: backticked spans and, inside the layout
/// block, the line's first word.
fn paths_of(line: &str, in_layout: bool) -> Vec<String> {
    let mut out = Vec::new();
    for (k, span) in line.split('`').enumerate() {
        if k % 2 == 0 {
            continue;
        }
        let span = span.trim();
        let rooted = ROOTS.iter().any(|r| span.starts_with(r));
        let looks = span.contains('/') && (span.ends_with(".rs") || span.ends_with('/') || rooted);
        if !looks || span.contains(char::is_whitespace) || span.contains(['<', '*', ':', '(']) {
            continue;
        }
        out.push(span.to_string());
    }
    if in_layout {
        if let Some(w) = line.split_whitespace().next() {
            if ROOTS.iter().any(|r| w.starts_with(r)) {
                out.push(w.to_string());
            }
        }
    }
    out
}

#[test]
fn every_path_named_in_library_md_exists() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("docs/library.md")).expect("docs/library.md");
    let (mut checked, mut missing) = (0, Vec::new());
    let mut fence = false;
    let mut in_layout = false;
    let mut section = "";
    for (i, line) in doc.lines().enumerate() {
        if let Some(h) = line.strip_prefix("## ") {
            section = h;
        }
        if line.starts_with("```") {
            fence = !fence;
            in_layout = fence && section == "Layout";
            continue;
        }
        for p in paths_of(line, in_layout) {
            for q in expand(&p) {
                let rooted = ROOTS.iter().any(|r| q.starts_with(r));
                let full = if rooted { root.join(&q) } else { root.join("src").join(&q) };
                checked += 1;
                if !full.exists() {
                    missing.push(format!(
                        "docs/library.md:{}: `{q}` ({} does not exist)",
                        i + 1,
                        full.strip_prefix(root).unwrap().display()
                    ));
                }
            }
        }
    }
    assert!(
        checked >= 40,
        "only {checked} paths found in docs/library.md: has the page's form changed under this test?"
    );
    assert!(missing.is_empty(), "paths named in docs/library.md that do not exist:\n{}", missing.join("\n"));
}

#[test]
fn expansion_and_span_rules() {
    assert_eq!(expand("objective/{mod,gradient}.rs"), ["objective/mod.rs", "objective/gradient.rs"]);
    assert_eq!(
        paths_of("a `src/ident/` and `optim/ga.rs`, not `Method::Wls` or `<x>/y.rs`", false),
        ["src/ident/", "optim/ga.rs"]
    );
    assert_eq!(paths_of("src/sim/         closed-loop simulator", true), ["src/sim/"]);
    assert!(paths_of("src/sim/         closed-loop simulator", false).is_empty());
}
