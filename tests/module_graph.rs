//! The module graph of the library is one-way.
//!
//! Every top-level module of `src/` belongs to a layer; a module may use
//! modules of its own layer or of a lower one, never of a higher one, and two
//! modules of one layer may not import each other (no cycles):
//!
//! | layer | modules                                   | holds                                            |
//! |-------|-------------------------------------------|--------------------------------------------------|
//! | 0     | `error` `linalg` `rng` `io` `optim`       | errors, nalgebra⇄faer, seeded streams, writers, run-control seam |
//! | 1     | `robot`                                   | immutable robot model, workspaces, kernels        |
//! | 2     | `params` `trajectory` `data`              | base parameters, motions and line sets, run formats |
//! | 3     | `sim` `elastic`                           | closed-loop simulation, elastic gray-box model    |
//! | 4     | `excitation` `ident` `frf` `positions`    | the four problems                                |
//! | 5     | `preview` `payload` `plan`                | the 3D preview page; payload identification and exports; campaign planning |
//!
//! The front end (`src/bin/`, `src/main.rs`) sits above everything and is not
//! scanned; `src/lib.rs` only declares the modules.
//!
//! The test reads every `.rs` file under `src/`, strips comments, and
//! collects the top-level module named by every `crate::<module>` path
//! (including `use crate::{a, b::c}` groups). A file `src/<m>.rs` or
//! `src/<m>/…` belongs to module `<m>`.
//!
//! It fails on an upward import. With `use crate::ident::Run;` temporarily
//! added to `src/robot/model.rs` it failed with
//!
//! ```text
//! upward or cyclic module imports:
//!   src/robot/model.rs:3: robot (layer 1) imports ident (layer 4)
//!   cycle: ident imports robot (src/ident/closed_loop.rs:39) and robot imports ident (src/robot/model.rs:3)
//! ```
//!
//! and on the code before the `data`/`trajectory` moves it reported
//! `src/elastic/sim.rs:30: elastic (layer 3) imports frf (layer 4)`,
//! `src/sim/mod.rs:34: sim (layer 3) imports ident (layer 4)` and the two
//! cycles sim↔ident and elastic↔frf.
//!
use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// Layer of each top-level module, lowest first.
const LAYERS: &[(&str, u32)] = &[
    ("error", 0),
    ("linalg", 0),
    ("rng", 0),
    ("io", 0),
    ("optim", 0),
    ("robot", 1),
    ("params", 2),
    ("trajectory", 2),
    ("data", 2),
    ("sim", 3),
    ("elastic", 3),
    ("excitation", 4),
    ("ident", 4),
    ("frf", 4),
    ("positions", 4),
    ("preview", 5),
    ("payload", 5),
    ("plan", 5),
];

/// Names that may follow `crate::` without being a module (re-exports at the
/// crate root of layer-0 items).
const ROOT_ITEMS: &[(&str, &str)] = &[("Error", "error"), ("Result", "error")];

fn layer(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|(_, l)| *l)
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).expect("read src/") {
        let path = entry.expect("dir entry").path();
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n == "bin") {
                continue;
            }
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Removes `//` and `/* */` comments, keeping line breaks so line numbers
/// stay right. String literals are kept as they are (`//` inside a string
/// would be mistaken for a comment; the crate has no `crate::` in strings).
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let bytes = text.as_bytes();
    let mut i = 0;
    let mut in_string = false;
    while i < bytes.len() {
        let c = bytes[i];
        if in_string {
            out.push(c as char);
            if c == b'\\' && i + 1 < bytes.len() {
                out.push(bytes[i + 1] as char);
                i += 2;
                continue;
            }
            if c == b'"' {
                in_string = false;
            }
            i += 1;
        } else if c == b'"' {
            in_string = true;
            out.push('"');
            i += 1;
        } else if c == b'/' && bytes.get(i + 1) == Some(&b'/') {
            while i < bytes.len() && bytes[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && bytes.get(i + 1) == Some(&b'*') {
            i += 2;
            while i + 1 < bytes.len() && !(bytes[i] == b'*' && bytes[i + 1] == b'/') {
                if bytes[i] == b'\n' {
                    out.push('\n');
                }
                i += 1;
            }
            i += 2;
        } else {
            // keep non-ASCII bytes intact by copying whole chars
            let ch_len = utf8_len(c);
            out.push_str(&text[i..i + ch_len]);
            i += ch_len;
        }
    }
    out
}

fn utf8_len(first: u8) -> usize {
    match first {
        0x00..=0x7f => 1,
        0xc0..=0xdf => 2,
        0xe0..=0xef => 3,
        _ => 4,
    }
}

fn ident_at(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// Top-level names inside a `{ … }` group starting at `s[0] == '{'`.
fn group_heads(s: &str) -> Vec<String> {
    let mut heads = Vec::new();
    let mut depth = 0;
    let mut expect_head = true;
    for (i, c) in s.char_indices() {
        match c {
            '{' => {
                depth += 1;
                expect_head = depth == 1;
            }
            '}' => {
                depth -= 1;
                if depth == 0 {
                    break;
                }
            }
            ',' if depth == 1 => expect_head = true,
            c if expect_head && depth == 1 && (c.is_ascii_alphabetic() || c == '_') => {
                heads.push(ident_at(&s[i..]).to_string());
                expect_head = false;
            }
            _ => {}
        }
    }
    heads
}

/// `(line, imported top-level module)` for every `crate::` path in `code`.
fn crate_imports(code: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    let mut rest = code;
    let mut offset = 0;
    while let Some(pos) = rest.find("crate::") {
        let at = offset + pos;
        let preceded_by_ident = code[..at]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == '$');
        let after = &code[at + "crate::".len()..];
        let line = code[..at].matches('\n').count() + 1;
        if !preceded_by_ident {
            let names = if after.starts_with('{') {
                group_heads(after)
            } else {
                vec![ident_at(after).to_string()]
            };
            for name in names {
                let module = ROOT_ITEMS.iter().find(|(item, _)| *item == name).map_or(name.clone(), |(_, m)| m.to_string());
                found.push((line, module));
            }
        }
        offset = at + "crate::".len();
        rest = &code[offset..];
    }
    found
}

fn owning_module(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?;
    let module = first.strip_suffix(".rs").unwrap_or(first);
    match module {
        "lib" | "main" => None,
        m => Some(m.to_string()),
    }
}

#[test]
fn no_module_imports_a_higher_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    assert!(files.len() > 20, "found only {} files under src/", files.len());

    let mut violations = Vec::new();
    let mut edges: BTreeMap<(String, String), String> = BTreeMap::new();
    let mut seen_modules = BTreeSet::new();
    for file in &files {
        let Some(module) = owning_module(&src, file) else {
            continue;
        };
        let rel = file.strip_prefix(src.parent().unwrap()).unwrap().display();
        let Some(own) = layer(&module) else {
            violations.push(format!("{rel}: module `{module}` has no layer in LAYERS"));
            continue;
        };
        seen_modules.insert(module.clone());
        let code = strip_comments(&fs::read_to_string(file).expect("read source"));
        for (line, target) in crate_imports(&code) {
            if target == module {
                continue;
            }
            let Some(theirs) = layer(&target) else {
                violations.push(format!("{rel}:{line}: `crate::{target}` is not a module with a layer"));
                continue;
            };
            if theirs > own {
                violations.push(format!("{rel}:{line}: {module} (layer {own}) imports {target} (layer {theirs})"));
            }
            edges.entry((module.clone(), target.clone())).or_insert_with(|| format!("{rel}:{line}"));
        }
    }
    for ((from, to), at) in &edges {
        if from < to {
            if let Some(back) = edges.get(&(to.clone(), from.clone())) {
                violations.push(format!("cycle: {from} imports {to} ({at}) and {to} imports {from} ({back})"));
            }
        }
    }
    assert!(
        seen_modules.contains("robot") && seen_modules.contains("ident"),
        "the scan missed the main modules: {seen_modules:?}"
    );
    assert!(violations.is_empty(), "upward or cyclic module imports:\n  {}", violations.join("\n  "));
}

#[test]
fn the_scanner_sees_grouped_and_plain_imports() {
    let code = "use crate::robot::Robot;\n// use crate::frf::Run;\nuse crate::{ident::Run, sim::{a, b}, Error};\nlet x = crate::data::f();\n";
    let found = crate_imports(&strip_comments(code));
    let names: Vec<_> = found.iter().map(|(l, m)| format!("{l}:{m}")).collect();
    assert_eq!(names, ["1:robot", "3:ident", "3:sim", "3:error", "4:data"]);
}

/// The external solver crates whose paths only `src/optim/` may name.
const SOLVER_CRATES: &[&str] = &["nlopt", "clarabel"];

/// True for `nlopt`, `clarabel` and `nlopt_…`/`clarabel_…` (their -sys crates).
fn is_solver_crate(name: &str) -> bool {
    SOLVER_CRATES
        .iter()
        .any(|c| name == *c || name.strip_prefix(c).is_some_and(|rest| rest.starts_with('_')))
}

/// Whether the identifier starting at byte `at` of `code` begins a path (is
/// its first segment) rather than continuing one (`crate::optim::nlopt::…`,
/// or `nlopt::…` inside a use group `optim::{nlopt::…}`). A leading `::`
/// (`::clarabel::…`) still begins a path.
fn begins_path(code: &str, at: usize) -> bool {
    let before = code[..at].trim_end();
    if let Some(head) = before.strip_suffix("::") {
        // `a::nlopt` continues a path; `::nlopt` at the start of one does not
        return !head.trim_end().ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_' || c == '>');
    }
    if !(before.ends_with('{') || before.ends_with(',')) {
        return true;
    }
    // inside a bracket: find the one that encloses the identifier
    let mut depth = 0i32;
    for (i, c) in before.char_indices().rev() {
        match c {
            '}' | ')' | ']' => depth += 1,
            '(' | '[' if depth == 0 => return true,
            '{' if depth == 0 => return !before[..i].trim_end().ends_with("::"),
            '{' | '(' | '[' => depth -= 1,
            _ => {}
        }
    }
    true
}

/// `(line, path root)` for every path in `code` whose first segment is a
/// solver crate (`nlopt::…`, `clarabel::…`, `::clarabel::…`, `use nlopt;`,
/// `extern crate nlopt`), comments already stripped.
fn solver_crate_paths(code: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    let bytes = code.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if !(c.is_ascii_alphabetic() || c == b'_') {
            i += 1;
            continue;
        }
        let name = ident_at(&code[i..]);
        let preceded_by_ident = i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_');
        let after = code[i + name.len()..].trim_start();
        let before = code[..i].trim_end();
        let named = after.starts_with("::")
            || before.ends_with("extern crate")
            || ((before.ends_with("use") || before.ends_with("pub use")) && (after.starts_with(';') || after.starts_with("as ")));
        if !preceded_by_ident && is_solver_crate(name) && named && begins_path(code, i) {
            found.push((code[..i].matches('\n').count() + 1, name.to_string()));
        }
        i += name.len().max(1);
    }
    found
}

fn rust_files_under(dir: &Path, skip: &[PathBuf], out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap_or_else(|e| panic!("read {}: {e}", dir.display())) {
        let path = entry.expect("dir entry").path();
        if skip.contains(&path) {
            continue;
        }
        if path.is_dir() {
            rust_files_under(&path, skip, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The solver room owns its solvers: nlopt's and Clarabel's types (cones,
/// statuses, algorithms) are named only in `src/optim/`; everything else
/// (the library, the command line in `src/bin/`, the Python bindings in
/// `python/src/`) uses idexp's own (`optim::conic::Cone`,
/// `optim::conic::ConicStatus`, `optim::GradientStatus`, ...).
///
/// On the code before the solver vocabulary moved into `src/optim/` it
/// failed with
///
/// ```text
/// solver crate paths outside src/optim/:
///   src/ident/consistent.rs:38: `clarabel`
///   src/ident/consistent.rs:657: `clarabel`
///   src/ident/prior.rs:39: `clarabel`
///   src/positions/conic.rs:44: `clarabel`
/// ```
///
/// (nlopt's status reached ident and excitation as `NloptStatus` through
/// `crate::optim::nlopt`, a path of idexp's own: it is now
/// `optim::GradientStatus`. `crate::optim::nlopt::Problem` stays: the bridge
/// is idexp's module, not the crate.)
#[test]
fn solver_crates_are_named_only_in_optim() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files_under(&root.join("src"), &[root.join("src/optim")], &mut files);
    rust_files_under(&root.join("python/src"), &[], &mut files);
    files.sort();
    assert!(
        files.iter().any(|f| f.ends_with("src/bin/idexp/main.rs")) && files.iter().any(|f| f.ends_with("python/src/lib.rs")),
        "the scan missed the front ends ({} files)",
        files.len()
    );
    let mut violations = Vec::new();
    for file in &files {
        let code = strip_comments(&fs::read_to_string(file).expect("read source"));
        let rel = file.strip_prefix(root).unwrap().display();
        for (line, name) in solver_crate_paths(&code) {
            violations.push(format!("{rel}:{line}: `{name}`"));
        }
    }
    assert!(violations.is_empty(), "solver crate paths outside src/optim/:\n  {}", violations.join("\n  "));
}

#[test]
fn the_solver_scanner_tells_crate_paths_from_idexps_modules() {
    let code = "use crate::optim::nlopt::{Algorithm, Problem};\n\
                use crate::optim::{nlopt::Problem, Control};\n\
                use clarabel::solver::SupportedConeT;\n\
                let s = ::clarabel::solver::SolverStatus::Solved;\n\
                f(nlopt::Algorithm::Lbfgs, nlopt_sys::nlopt_optimize);\n\
                // use nlopt::Nlopt;\n\
                use nlopt;\n\
                extern crate clarabel;\n\
                let x = { clarabel::algebra::CscMatrix::zeros((1, 1)) };\n\
                let nlopt = 1; let t = nlopt_evals + nlopt; my_nlopt::f();\n";
    let found: Vec<_> = solver_crate_paths(&strip_comments(code)).iter().map(|(l, n)| format!("{l}:{n}")).collect();
    assert_eq!(
        found,
        ["3:clarabel", "4:clarabel", "5:nlopt", "5:nlopt_sys", "7:nlopt", "8:clarabel", "9:clarabel"]
    );
}
