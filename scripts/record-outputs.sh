#!/usr/bin/env bash
# Runs every shipped design and the README's commands into one folder, so two
# builds of idexp can be compared file by file (scripts/compare-outputs.py).
#   scripts/record-outputs.sh <idexp binary> <output folder>
# Long studies are run with smaller budgets (fit: 4 starts) so the record takes
# a few minutes; excite_ur5_bench (time-limited, machine-dependent) and
# positions_industrial6_random (minutes) are left out.
set -uo pipefail
BIN=$(realpath "$1"); OUT=$(realpath -m "$2")
cd "$(dirname "$0")/.."
mkdir -p "$OUT"
export IDEXP_NO_PROGRESS=1
log="$OUT/commands.log"; : > "$log"
run() { # name, args... (the exit code goes to the log: 0 ok, 1 input, 2 usage, 3 not usable, 130 interrupted)
  local name=$1; shift
  echo "== $name: idexp $*" >> "$log"
  "$BIN" "$@" > "$OUT/$name.stdout" 2> "$OUT/$name.stderr"; echo "exit $?" >> "$log"
}
O=$OUT/out
run robot_info robot info designs/robots/puma560.toml
run robot_info_json robot info designs/robots/puma560.toml --json
run robot_torques robot torques designs/robots/ur5.toml --states tests/data/ur5_states.csv
run robot_regressor robot regressor designs/robots/ur5.toml --states tests/data/ur5_states.csv --base --out "$O/robot_regressor"
for d in excite_ur5 excite_industrial6_full excite_industrial6_restrained excite_panda_table payload_ur5_excite; do
  run "$d" excite designs/$d.toml --out "$O/$d"
done
run assess_ur5 assess designs/robots/ur5.toml "$O/excite_ur5/trajectory.csv" --every 100 --out "$O/assess_ur5"
run assess_ur5_json assess designs/robots/ur5.toml "$O/excite_ur5/trajectory.csv" --every 10 --noise 0.5 --json
for d in sim_rpr_fourier sim_rpr_fourier_validate sim_rpr_pick_place sim_rpr_pick_place_validate sim_rpr_square sim_rpr_closed_loop sim_puma_gravity sim_puma_friction sim_puma_fourier; do
  run "$d" simulate designs/$d.toml --out "$O/$d"
done
R=tests/data/ident/rpr_drives.toml
run ident_fourier identify $R "$O/sim_rpr_fourier" --validate "$O/sim_rpr_fourier_validate" --harmonics 20 --truth "$O/sim_rpr_fourier/truth.json" --out "$O/ident_fourier"
run ident_pick identify $R "$O/sim_rpr_pick_place" --validate "$O/sim_rpr_pick_place_validate" --reduce --out "$O/ident_pick"
run ident_pick_tanh identify tests/data/ident/rpr_drives_tanh.toml "$O/sim_rpr_pick_place" --validate "$O/sim_rpr_pick_place_validate" --reduce --out "$O/ident_pick_tanh"
run ident_square identify $R "$O/sim_rpr_square" --reduce --out "$O/ident_square"
run ident_proj identify $R "$O/sim_rpr_closed_loop" --method projection --harmonics 20 --truth "$O/sim_rpr_closed_loop/truth.json" --out "$O/ident_proj"
run ident_ml identify $R "$O/sim_rpr_closed_loop" --method ml --harmonics 20 --truth "$O/sim_rpr_closed_loop/truth.json" --out "$O/ident_ml"
run ident_gravity identify designs/robots/puma560.toml "$O/sim_puma_gravity" --experiment gravity --joint 2 --out "$O/puma_gravity"
run ident_friction identify designs/robots/puma560.toml "$O/sim_puma_friction" --experiment friction --joint 2 --gravity-fit "$O/puma_gravity/gravity.json" --out "$O/puma_friction"
run multisine multisine designs/elastic_industrial6.toml --out "$O/elastic"
run frf frf designs/elastic_industrial6.toml --out "$O/elastic"
run fit_lls fit designs/elastic_industrial6.toml --starts 4 --out "$O/elastic"
run frf_time frf designs/elastic_industrial6_time.toml --out "$O/elastic_time"
run fit_time fit designs/elastic_industrial6_time.toml --starts 2 --out "$O/elastic_time"
for d in positions_industrial6_rigid positions_file_d positions_file_a positions_file_e positions_elastic6 positions_elastic6_small; do
  run "$d" positions designs/$d.toml --out "$O/$d"
done
# the README's study and payload chains: their designs read ../out/… beside designs/,
# so they run in a copy of designs/ and tests/data/ whose out/ is inside the record
T=$OUT/tree; rm -rf "$T"; mkdir -p "$T/tests"; cp -r designs "$T/"; cp -r tests/data "$T/tests/"
run_in_tree() { local name=$1; shift; echo "== $name: (in $T) idexp $*" >> "$log"
  (cd "$T" && "$BIN" "$@" > "$OUT/$name.stdout" 2> "$OUT/$name.stderr"); echo "exit $?" >> "$log"; }
for d in sim_rpr_fourier sim_rpr_study_b sim_rpr_study_gravity sim_rpr_fourier_validate sim_rpr_study_validate; do
  run_in_tree "tree_$d" simulate designs/$d.toml
done
run_in_tree study_rpr identify designs/study_rpr.toml
run_in_tree tree_payload_excite payload excite designs/payload_ur5_excite.toml
run_in_tree tree_sim_ur5_payload simulate designs/sim_ur5_payload.toml
run_in_tree tree_sim_ur5_payload_unloaded simulate designs/sim_ur5_payload_unloaded.toml
run_in_tree payload_ur5 payload identify designs/payload_ur5.toml
rm -rf "$T/designs" "$T/tests"
echo "recorded into $OUT"
