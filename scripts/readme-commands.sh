#!/usr/bin/env bash
# Runs the documented fast shell commands on a clean clone: those of README.md,
# then of the pages in docs/ in the order of DOCS below (each page may use
# what an earlier one wrote under out/):
# every line of a ```sh block that starts with `cargo run` or `./scripts/`,
# except the documented long ones — lines whose comment says "min" (minutes)
# or "about N s" with N > 60, lines marked `# long`, the test-suite line and
# the Slurm recipe (run by scripts/slurm-test.sh). Each must exit 0 (or 3 for
# a documented infeasible/unusable outcome) within 5 minutes.
# A `pip install` line ("into the active Python") runs with the venv
# target/python-venv active when it exists (made by scripts/python-test.sh):
# Debian's system Python refuses pip installs (PEP 668).
#   scripts/readme-commands.sh            # all fast commands
#   scripts/readme-commands.sh --list     # print them only
#   scripts/readme-commands.sh --ci       # in this checkout (CI's clean clone, already built;
#                                         # a clone elsewhere rebuilds the crate), and without
#                                         # the Python lines (.ci/run has just run python-test.sh,
#                                         # which does the same `pip install ./python` in its venv)
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
DOCS="README.md docs/robots.md docs/excitation.md docs/collision.md docs/identification.md docs/payload.md docs/elastic.md docs/positions.md docs/plan.md docs/library.md docs/testing.md docs/performance.md docs/python.md"
for f in docs/*.md; do
  case " $DOCS " in *" $f "*) ;; *) echo "readme-commands: $f is not in DOCS: add it" >&2; exit 1 ;; esac
done
cmds=$(awk '
  /^```sh$/ {inb=1; slurm=0; next}
  /^```/ {inb=0; next}
  inb && /^# Slurm job array/ {slurm=1}
  inb && cont != "" {cont = cont " " $0; if ($0 !~ /\\$/) {print cont; cont = ""}; next}
  inb && !slurm && (/^cargo run/ || /^\.\/scripts\//) {if ($0 ~ /\\$/) cont = $0; else print}
' $DOCS | grep -v -E '# long|cargo test|[0-9] ?min|[(]about ([6-9][0-9]|[0-9]{3,}) s' || true)
ci=0 list=0
for a in "$@"; do
  case $a in
    --ci) ci=1 ;;
    --list) list=1 ;;
    *) echo "readme-commands: unknown option $a (allowed: --ci, --list)" >&2; exit 2 ;;
  esac
done
if [ $ci = 1 ]; then
  # .ci/run has just run scripts/python-test.sh, which builds and installs
  # the package with the same `pip install ./python` into target/python-venv
  cmds=$(printf '%s\n' "$cmds" | grep -v -e '^\./scripts/python-test\.sh$' -e 'pip install \./python' || true)
fi
if [ $list = 1 ]; then
  printf '%s\n' "$cmds"
  exit 0
fi
work=$(mktemp -d /tmp/idexp-readme.XXXXXX)
trap 'rm -rf "$work"' EXIT
if [ $ci = 1 ]; then
  if [ -n "$(git status --porcelain --untracked-files=normal)" ] || [ -e out ]; then
    echo "readme-commands --ci: this checkout is not clean (or has out/): run it on a clean clone" >&2
    exit 1
  fi
else
  git clone -q --local "$repo" "$work/clone"
  cd "$work/clone"
  # the clone's path differs from the repository's: cargo rebuilds the crate
  # once, before the timed commands
  CARGO_TARGET_DIR="$repo/target" cargo build -q --release --bins --examples
fi
# the repository's target/ (dependencies built once)
export CARGO_TARGET_DIR="$repo/target" IDEXP_NO_PROGRESS=1
n=0
fail=0
while IFS= read -r c; do
  [ -z "$c" ] && continue
  c=${c//\\ / }
  n=$((n + 1))
  start=$(date +%s)
  set +e
  if [[ "$c" == *"pip install"* ]] && [ -x "$repo/target/python-venv/bin/python" ]; then
    timeout 900 env VIRTUAL_ENV="$repo/target/python-venv" PATH="$repo/target/python-venv/bin:$PATH" bash -c "$c" >"$work/out.txt" 2>&1
  else
    timeout 300 bash -c "$c" >"$work/out.txt" 2>&1
  fi
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
