//! Mutation fuzzing of every input reader, in the default suite: every
//! shipped design (designs/*.toml, the information JSON), every shipped robot
//! file (designs/robots/*.toml, *.urdf, the test robots) and the CSV readers
//! (states, repetitions, generic tables) are mutated — lines deleted or
//! duplicated, numbers turned into NaN, 1e308, −1 or 0, the text truncated,
//! keys dropped — and handed to the library's parse/validate entry points
//! (not the solvers). Each must return, without panicking, either a value or
//! an error whose message is not empty and names the file it read (or the
//! file that one refers to, e.g. a robot file's URDF).
//!
//! Seeded (the sequence of mutants is fixed) and bounded: at most
//! `MUTANTS_PER_FILE` mutants per file and `BUDGET` of wall time overall, so
//! a loaded machine runs a prefix of the same sequence. Longer, coverage-
//! guided runs: the `cargo fuzz` target in fuzz/ (docs/testing.md).

mod common;
use common::root;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const MUTANTS_PER_FILE: usize = 100;
const BUDGET: Duration = Duration::from_secs(45);
const SEED: u64 = 0x1d_e7_f0_22;

/// One mutation of `text`: a line deleted or duplicated, a number replaced
/// by a hostile value, a truncation, or a `key = value` line dropped.
fn mutate(text: &str, rng: &mut ChaCha8Rng) -> (String, String) {
    let lines: Vec<&str> = text.lines().collect();
    let n = lines.len().max(1);
    match rng.random_range(0..5u32) {
        0 => {
            let k = rng.random_range(0..n);
            let out: Vec<&str> = lines.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, l)| *l).collect();
            (out.join("\n"), format!("delete line {}", k + 1))
        }
        1 => {
            let k = rng.random_range(0..n);
            let mut out: Vec<&str> = lines.clone();
            if k < out.len() {
                out.insert(k, lines[k]);
            }
            (out.join("\n"), format!("duplicate line {}", k + 1))
        }
        2 => {
            // the byte ranges of number-like tokens
            let b = text.as_bytes();
            let mut spans = Vec::new();
            let mut i = 0;
            while i < b.len() {
                if b[i].is_ascii_digit() && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) {
                    let s = if i > 0 && (b[i - 1] == b'-' || b[i - 1] == b'.') { i - 1 } else { i };
                    let mut e = i;
                    while e < b.len() && (b[e].is_ascii_digit() || matches!(b[e], b'.' | b'e' | b'E' | b'-' | b'+')) {
                        e += 1;
                    }
                    spans.push((s, e));
                    i = e;
                } else {
                    i += 1;
                }
            }
            if spans.is_empty() {
                return (text.to_string(), "unchanged (no number)".into());
            }
            let (s, e) = spans[rng.random_range(0..spans.len())];
            let v = ["nan", "NaN", "1e308", "-1", "0", "-0.0", "inf", "1e-300", "-1e308"][rng.random_range(0..9usize)];
            (
                format!("{}{v}{}", &text[..s], &text[e..]),
                format!("number `{}` at byte {s} → {v}", &text[s..e]),
            )
        }
        3 => {
            let mut cut = rng.random_range(0..text.len().max(1));
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            (text[..cut].to_string(), format!("truncate at byte {cut}"))
        }
        _ => {
            let keys: Vec<usize> = lines
                .iter()
                .enumerate()
                .filter(|(_, l)| l.contains('=') && !l.trim_start().starts_with('#'))
                .map(|(i, _)| i)
                .collect();
            if keys.is_empty() {
                return (text.to_string(), "unchanged (no key)".into());
            }
            let k = keys[rng.random_range(0..keys.len())];
            let out: Vec<&str> = lines.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, l)| *l).collect();
            (out.join("\n"), format!("drop key on line {}", k + 1))
        }
    }
}

/// A library entry point on a file.
type Reader = fn(&Path) -> Result<(), String>;

fn err(e: idexp::Error) -> Result<(), String> {
    Err(e.to_string())
}

fn robot(p: &Path) -> Result<(), String> {
    idexp::robot::load(p).map(|_| ()).or_else(err)
}
fn excite(p: &Path) -> Result<(), String> {
    idexp::excitation::Problem::from_file(p).map(|_| ()).or_else(err)
}
fn positions(p: &Path) -> Result<(), String> {
    idexp::positions::PositionsDesign::read(p).map(|_| ()).or_else(err)
}
fn elastic(p: &Path) -> Result<(), String> {
    idexp::frf::Design::load(p).map(|_| ()).or_else(err)
}
fn simulate(p: &Path) -> Result<(), String> {
    idexp::sim::SimDesign::read(p).map(|_| ()).or_else(err)
}
fn information(p: &Path) -> Result<(), String> {
    idexp::positions::InformationFile::read(p).map(|_| ()).or_else(err)
}
fn states6(p: &Path) -> Result<(), String> {
    idexp::io::States::read(p, 6).map(|_| ()).or_else(err)
}
fn repetition3(p: &Path) -> Result<(), String> {
    idexp::data::Repetition::read(p, 3).map(|_| ()).or_else(err)
}
fn table(p: &Path) -> Result<(), String> {
    idexp::io::Table::read(p).map(|_| ()).or_else(err)
}

/// A scratch copy of `dir`: every entry linked, so relative paths inside a
/// mutant (robots, URDFs, meshes, information files) still resolve.
fn mirror(dir: &Path, into: &Path) {
    std::fs::create_dir_all(into).unwrap();
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        std::os::unix::fs::symlink(e.path(), into.join(e.file_name())).unwrap();
    }
}

/// The files to mutate, each with its reader and the directory it is read from.
fn corpus(tmp: &Path) -> Vec<(PathBuf, Reader, PathBuf)> {
    let mut out: Vec<(PathBuf, Reader, PathBuf)> = Vec::new();
    // designs/ (and ../tests for the relative robot path of the rpr designs)
    let designs = tmp.join("designs");
    mirror(&root("designs"), &designs);
    std::os::unix::fs::symlink(root("tests"), tmp.join("tests")).unwrap();
    let mut files: Vec<PathBuf> = std::fs::read_dir(root("designs")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let reader: Option<Reader> = match () {
            _ if name.ends_with(".json") => Some(information),
            _ if !name.ends_with(".toml") => None,
            _ if name.starts_with("excite_") => Some(excite),
            _ if name.starts_with("positions_") => Some(positions),
            _ if name.starts_with("elastic_") => Some(elastic),
            _ if name.starts_with("sim_") => Some(simulate),
            _ => None,
        };
        if let Some(r) = reader {
            out.push((f, r, designs.clone()));
        }
    }
    // robots: designs/robots and the test robots
    let robots = tmp.join("robots");
    mirror(&root("designs/robots"), &robots);
    let mut files: Vec<PathBuf> = std::fs::read_dir(root("designs/robots"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml" || e == "urdf"))
        .collect();
    files.sort();
    for f in files {
        out.push((f, robot as Reader, robots.clone()));
    }
    let data = tmp.join("data");
    mirror(&root("tests/data"), &data);
    for f in [
        "tests/data/rpr_standard.toml",
        "tests/data/coupled6_modified.toml",
        "tests/data/tree.urdf",
        "tests/data/ident/rpr_drives.toml",
    ] {
        out.push((root(f), robot as Reader, data.clone()));
    }
    // CSV readers: a states file, a repetition written here (t, q, tau for 3
    // joints), and the generic table reader on both
    out.push((root("tests/data/ur5_states.csv"), states6 as Reader, data.clone()));
    out.push((root("tests/data/ur5_states.csv"), table as Reader, data.clone()));
    let rep = tmp.join("repetition.csv");
    let mut text = String::from("t,q1,q2,q3,tau1,tau2,tau3\n");
    for k in 0..20 {
        let t = k as f64 * 0.01;
        text += &format!("{t},{},{},{},{},{},{}\n", t.sin(), 0.1 + 0.2 * t, t.cos(), 3.0 * t, -1.5, 0.25 * t);
    }
    std::fs::write(&rep, text).unwrap();
    assert!(repetition3(&rep).is_ok(), "{:?}", repetition3(&rep));
    out.push((rep.clone(), repetition3 as Reader, data.clone()));
    out.push((rep, table as Reader, data));
    out
}

#[test]
fn mutated_inputs_never_panic_and_errors_name_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let corpus = corpus(tmp.path());
    let t0 = Instant::now();
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let (mut tried, mut refused) = (0usize, 0usize);
    let mut failures = Vec::new();
    // the originals are accepted
    for (src, read, dir) in &corpus {
        let ext = src.extension().unwrap().to_string_lossy().into_owned();
        let p = dir.join(format!("original.{ext}"));
        std::fs::write(&p, std::fs::read(src).unwrap()).unwrap();
        if let Err(e) = read(&p) {
            failures.push(format!("{}: the unmutated file is refused: {e}", src.display()));
        }
    }
    'files: for round in 0..MUTANTS_PER_FILE {
        for (i, (src, read, dir)) in corpus.iter().enumerate() {
            if t0.elapsed() > BUDGET {
                break 'files;
            }
            let text = std::fs::read_to_string(src).unwrap();
            let (mutant, what) = mutate(&text, &mut rng);
            let ext = src.extension().unwrap().to_string_lossy().into_owned();
            let name = format!("mutant_{i}_{round}.{ext}");
            let p = dir.join(&name);
            std::fs::write(&p, &mutant).unwrap();
            let got = catch_unwind(AssertUnwindSafe(|| read(&p)));
            tried += 1;
            match got {
                Err(_) => failures.push(format!("{} ({what}): panicked", src.display())),
                Ok(Err(msg)) => {
                    refused += 1;
                    if msg.trim().is_empty() || !(msg.contains(&name) || msg.contains(&*tmp.path().to_string_lossy())) {
                        failures.push(format!("{} ({what}): the error does not name the file: {msg}", src.display()));
                    }
                }
                Ok(Ok(())) => {}
            }
            let _ = std::fs::remove_file(&p);
        }
    }
    eprintln!(
        "{tried} mutants over {} files, {refused} refused, {:.1} s",
        corpus.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(tried >= corpus.len(), "the time budget ran out before one round");
    assert!(failures.is_empty(), "{} of {tried} mutants:\n{}", failures.len(), failures.join("\n"));
}
