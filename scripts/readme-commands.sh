#!/usr/bin/env bash
# Runs the README's fast shell commands on a clean clone, in README order:
# every line of a ```sh block that starts with `cargo run` or `./scripts/`,
# except the documented long ones — lines whose comment says "min" (minutes)
# or "about N s" with N > 60, lines marked `# long`, the test-suite line and
# the Slurm recipe (run by scripts/slurm-test.sh). Each must exit 0 (or 3 for
# a documented infeasible/unusable outcome) within 5 minutes.
#   scripts/readme-commands.sh            # all fast commands
#   scripts/readme-commands.sh --list     # print them only
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
cmds=$(awk '
  /^```sh$/ {inb=1; slurm=0; next}
  /^```/ {inb=0; next}
  inb && /^# Slurm job array/ {slurm=1}
  inb && cont != "" {cont = cont " " $0; if ($0 !~ /\\$/) {print cont; cont = ""}; next}
  inb && !slurm && (/^cargo run/ || /^\.\/scripts\//) {if ($0 ~ /\\$/) cont = $0; else print}
' README.md | grep -v -E '# long|cargo test|[0-9] ?min|[(]about ([6-9][0-9]|[0-9]{3,}) s' || true)
if [ "${1:-}" = "--list" ]; then
  printf '%s\n' "$cmds"
  exit 0
fi
work=$(mktemp -d /tmp/idexp-readme.XXXXXX)
trap 'rm -rf "$work"' EXIT
git clone -q --local "$repo" "$work/clone"
cd "$work/clone"
# the clone builds into the repository's target/ (no second 5-minute build)
export CARGO_TARGET_DIR="$repo/target" IDEXP_NO_PROGRESS=1
n=0
fail=0
while IFS= read -r c; do
  [ -z "$c" ] && continue
  c=${c//\\ / }
  n=$((n + 1))
  start=$(date +%s)
  set +e
  timeout 300 bash -c "$c" >"$work/out.txt" 2>&1
  rc=$?
  set -e
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 3 ]; then
    echo "readme-commands: FAILED (exit $rc): $c" >&2
    tail -5 "$work/out.txt" >&2
    fail=$((fail + 1))
  else
    echo "readme-commands: ok ($(($(date +%s) - start)) s): $c" >&2
  fi
done <<<"$cmds"
echo "readme-commands: $n commands, $fail failed" >&2
[ "$fail" -eq 0 ]
