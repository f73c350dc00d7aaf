#!/bin/sh
# Seed inputs for the parse_inputs fuzz target from the shipped files: the
# first byte picks the reader (see fuzz_targets/parse_inputs.rs), the rest is
# the file's text. Writes fuzz/corpus/parse_inputs/ (idempotent).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
out="$here/corpus/parse_inputs"
mkdir -p "$out"
seed() { # selector-byte (octal) file
    name=$(basename "$2")
    { printf "\\$1"; cat "$2"; } > "$out/$1-$name"
}
for f in "$root"/designs/robots/*.toml "$root"/tests/data/*.toml "$root"/tests/data/ident/*.toml; do seed 000 "$f"; done
for f in "$root"/designs/robots/*.urdf "$root"/tests/data/*.urdf; do seed 001 "$f"; done
for f in "$root"/tests/data/*.csv; do seed 002 "$f"; done
for f in "$root"/designs/*.json; do seed 003 "$f"; done
for f in "$root"/designs/excite_*.toml; do seed 004 "$f"; done
for f in "$root"/designs/sim_*.toml; do seed 005 "$f"; done
for f in "$root"/designs/positions_*.toml; do seed 006 "$f"; done
echo "$(ls "$out" | wc -l) seeds in $out"
