#!/usr/bin/env bash
# The preview page of a 300 s delivered trajectory: its size, the time to
# write it (`idexp view`) and the time headless Chromium takes to load and
# draw it: the wall time from the DevTools protocol's Page.navigate until the
# page reports its first frame drawn (scripts/preview-load.mjs; needs Node ≥
# 20.10 for its WebSocket, Debian's `nodejs` package), with the page's own
# marks of where the time goes.
#
# The trajectory: designs/excite_ur5.toml with [execution] periods = 29
# (300.3 s, 300,321 rows at 1 kHz). Usage: scripts/preview-bench.sh [REPEATS]
# Figures and machine state go to docs/performance.md by hand.
set -euo pipefail
cd "$(dirname "$0")/.."
repeats=${1:-3}
export IDEXP_NO_PROGRESS=1
cargo build --release --quiet
bin=target/release/idexp
work=target/preview-bench
mkdir -p "$work"
{ cat designs/excite_ur5.toml; printf '\n[execution]\nperiods = 29\n'; } | sed 's|^robot = "robots/|robot = "../../designs/robots/|' > "$work/excite_ur5_300s.toml"
echo "machine: $(nproc) cores, $(uptime | sed 's/.*load/load/')"
"$bin" excite "$work/excite_ur5_300s.toml" --out "$work/out" > /dev/null
page="$work/out/preview.html"
rows=$(($(wc -l < "$work/out/trajectory.csv") - 1))
echo "trajectory.csv: $rows rows; preview.html: $(stat -c %s "$page") bytes"
for i in $(seq "$repeats"); do
  s=$(date +%s.%N); "$bin" view "$work/out" > /dev/null; e=$(date +%s.%N)
  echo "idexp view (write the page): $(echo "$e - $s" | bc) s"
done
node --experimental-websocket scripts/preview-load.mjs "$page" "$repeats" 2>/dev/null
echo "load: $(uptime | sed 's/.*load/load/')"
