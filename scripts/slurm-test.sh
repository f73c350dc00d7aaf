#!/usr/bin/env bash
# The README's Slurm batch recipe on a real scheduler: runs the README's
# ```sh block that starts with "# Slurm job array" exactly as written (only
# its SHARED/N/CPUS/STARTS line is replaced by values for this machine),
# waits for the job array and the dependent merge job, and checks that the
# merged fit folder holds every file a single run writes, byte-identical:
# run.json names the data file by its absolute path (the recipe's
# $SHARED/frf, the single run's copy in its own folder), so it is compared
# with each run's folder replaced by ROOT; status.json is compared without its
# two times (`started`, `finished`: when each run began and ended).
#   scripts/slurm-up.sh && scripts/slurm-test.sh
# Needs the release binary (cargo build --release) and a running Slurm.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
command -v sbatch >/dev/null || { echo "slurm-test: no sbatch (run scripts/slurm-up.sh)" >&2; exit 1; }
export PATH="$repo/target/release:$PATH"
export IDEXP_NO_PROGRESS=1
work=$(mktemp -d /tmp/idexp-slurm.XXXXXX)
trap 'rm -rf "$work"' EXIT
# the recipe, as written in the README
recipe=$(awk '/^```sh$/{inb=1; buf=""; next} /^```$/{if (inb && buf ~ /^# Slurm job array/) {printf "%s", buf; exit} inb=0; next} inb{buf = buf $0 "\n"}' README.md)
[ -n "$recipe" ] || { echo "slurm-test: no Slurm block in README.md" >&2; exit 1; }
grep -q '^SHARED=' <<<"$recipe" || { echo "slurm-test: the recipe has no SHARED= line" >&2; exit 1; }
cpus=$(nproc)
params="SHARED=$work/shared N=3 CPUS=1 STARTS=6"
script=$(sed "s|^SHARED=.*|$params|" <<<"$recipe")
echo "slurm-test: running the README recipe with $params" >&2
# the recipe as written, plus one line reporting the array's job id
out=$(bash -euo pipefail -c "$script"$'\n''echo "$jid"')
# sbatch --parsable prints the job ids, one a line
ids=$(grep -E '^[0-9]+(;.*)?$' <<<"$out" | cut -d';' -f1 | paste -sd, -)
[ "$(tr ',' '\n' <<<"$ids" | wc -l)" -eq 2 ] || { echo "slurm-test: expected two job ids, got '$ids' from: $out" >&2; exit 1; }
echo "slurm-test: submitted jobs $ids" >&2
# wait for both jobs (at most 20 min); a dependency that can never be met is a failure
left=1
for _ in $(seq 1200); do
  q=$(squeue -h -j "$ids" -o "%i %T %r" 2>/dev/null || true)
  if grep -q DependencyNeverSatisfied <<<"$q"; then
    echo "slurm-test: the array failed, the merge can never run:" >&2
    cat "$work"/shared/slurm-*.out >&2 || true
    scancel ${ids//,/ } || true
    exit 1
  fi
  left=$(grep -c . <<<"$q" || true)
  [ "$left" -eq 0 ] && break
  sleep 1
done
[ "$left" -eq 0 ] || { echo "slurm-test: jobs still queued after 20 min" >&2; squeue >&2; scancel ${ids//,/ } || true; exit 1; }
merged="$work/shared/fit_lls_user"
[ -s "$merged/fit.json" ] || { echo "slurm-test: merge wrote no fit.json" >&2; cat "$work"/shared/slurm-*.out >&2 || true; exit 1; }
grep -q '"status": "complete"' "$merged/status.json" || { echo "slurm-test: merged status is not complete" >&2; cat "$merged/status.json" >&2; exit 1; }
# a single run on the same FRF data
mkdir -p "$work/single"
cp -r "$work/shared/frf" "$work/single/frf"
idexp --threads "$cpus" fit designs/elastic_industrial6.toml --starts 6 --out "$work/single" >/dev/null
single="$work/single/fit_lls_user"
fail=0
n=0
norm() { # file, folder prefix to replace by ROOT
  case "$(basename "$1")" in
    status.json) grep -v -E '^  "(started|finished)": ' "$1" ;;
    run.json) sed "s|$2|ROOT|g" "$1" ;;
    *) cat "$1" ;;
  esac
}
[ "$(cd "$single" && find . -type f | sort)" = "$(cd "$merged" && find . -type f ! -name 'starts.shard-*' | sort)" ] || {
  echo "slurm-test: the merged folder does not hold the single run's files" >&2
  diff <(cd "$single" && find . -type f | sort) <(cd "$merged" && find . -type f ! -name 'starts.shard-*' | sort) >&2 || true
  exit 1
}
for f in $(cd "$single" && find . -type f | sort); do
  n=$((n + 1))
  if ! cmp -s <(norm "$single/$f" "$work/single") <(norm "$merged/$f" "$work/shared"); then
    echo "slurm-test: $f differs between the merged and the single run" >&2
    fail=1
  fi
done
[ "$n" -gt 3 ] || { echo "slurm-test: only $n files compared" >&2; exit 1; }
[ "$fail" -eq 0 ] || exit 1
echo "slurm-test: ok, all $n files of the merged fit identical to a single run's (run.json up to its folder, status.json up to its times)" >&2
