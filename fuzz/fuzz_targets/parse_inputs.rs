//! Fuzz target: the text readers and validators of idexp's inputs. The first
//! byte picks the reader, the rest is the file's text. Every reader must
//! return `Ok` or an `Err` with a message; a panic, an abort or a hang is a
//! finding. The seeded mutation test (tests/mutation_fuzz.rs) covers the same
//! readers in the default test suite; this target is for long runs.
#![no_main]

use idexp::io::parse_toml;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fn check(r: idexp::Result<()>) {
    if let Err(e) = r {
        assert!(!e.to_string().trim().is_empty(), "an error without a message");
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(rest) else { return };
    let p = Path::new("fuzz-input");
    match pick % 7 {
        0 => check(idexp::robot::file::parse_robot_toml(Path::new("fuzz-input.toml"), text).map(|_| ())),
        1 => check(idexp::robot::urdf::parse_urdf(Path::new("fuzz-input.urdf"), text, None, None).map(|_| ())),
        2 => check(idexp::io::Table::parse(p, text).map(|_| ())),
        3 => check(idexp::positions::InformationFile::parse(p, text).map(|_| ())),
        4 => check(parse_toml::<idexp::excitation::design::ExciteDesign>(p, text).and_then(|d| d.validate("fuzz-input"))),
        5 => check(parse_toml::<idexp::sim::SimDesign>(p, text).and_then(|d| d.validate("fuzz-input"))),
        _ => check(parse_toml::<idexp::positions::PositionsDesign>(p, text).and_then(|d| d.validate("fuzz-input"))),
    }
});
