#!/usr/bin/env python3
"""Two idexp binaries on one excitation design, seed by seed (docs/performance.md).

    scripts/compare-seeds.py --before OLD_IDEXP --after NEW_IDEXP DESIGN \\
        [--seeds 1-30] [--threads N] [--out DIR]

A kernel change that moves results in the last bits can send a non-convex
design to another local optimum. The rule for accepting it: over seeds 1-5
the design's criterion is no worse on average. This script runs
`idexp excite DESIGN --seed s` with both binaries for every seed, reads
`criterion` and `criterion_value` (every criterion is minimised) from each
run's coefficients.json, and prints the paired table, the means over seeds
1-5 and over all seeds, how many seeds moved (relative change above 1e-4)
and in which direction, and the verdict of the rule. The runs are kept in
DIR (default: a new temporary folder), one folder per binary and seed, and
the table is written to DIR/seeds.csv.

Exit codes: 0 the comparison ran (whatever the verdict), 1 bad input (a
binary or the design missing, bad seed list), 3 a run failed or wrote no
criterion (its stderr is printed).
"""
import argparse, csv, json, os, statistics, subprocess, sys, tempfile

MOVED = 1e-4  # relative change below which a seed "landed on the same point"


def parse_seeds(text):
    seeds = []
    for part in text.split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = (int(x) for x in part.split("-", 1))
                if b < a:
                    raise ValueError
                seeds.extend(range(a, b + 1))
            else:
                seeds.append(int(part))
        except ValueError:
            raise SystemExit(f"compare-seeds: --seeds: '{part}' is not a seed or a range a-b with a <= b (e.g. 1-30 or 1,2,5)")
    if not seeds or min(seeds) < 0 or len(seeds) > 10000:
        raise SystemExit(f"compare-seeds: --seeds: {len(seeds)} seeds, min {min(seeds, default=None)}; allowed 1 to 10000 non-negative seeds")
    return seeds


def run(binary, design, seed, out, threads):
    cmd = [binary, "excite", design, "--seed", str(seed), "--out", out]
    if threads:
        cmd += ["--threads", str(threads)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    path = os.path.join(out, "coefficients.json")
    if p.returncode not in (0, 3) or not os.path.exists(path):
        sys.stderr.write(f"compare-seeds: {' '.join(cmd)} exited {p.returncode}:\n{p.stderr}")
        sys.exit(3)
    with open(path) as f:
        c = json.load(f)
    if not isinstance(c.get("criterion_value"), (int, float)):
        sys.stderr.write(f"compare-seeds: {path}: no numeric criterion_value\n")
        sys.exit(3)
    return c["criterion"], float(c["criterion_value"]), c.get("status", "?")


def mean_of(rows, key, seeds):
    vals = [r[key] for r in rows if r["seed"] in seeds]
    return statistics.fmean(vals) if vals else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", required=True, help="idexp binary before the change")
    ap.add_argument("--after", required=True, help="idexp binary after the change")
    ap.add_argument("design", help="excitation design file (TOML)")
    ap.add_argument("--seeds", default="1-5", help="seeds: a range a-b and/or a comma list (default 1-5)")
    ap.add_argument("--threads", type=int, default=0, help="worker threads of each run (default: idexp's)")
    ap.add_argument("--out", help="folder for the runs and seeds.csv (default: a new temporary folder)")
    a = ap.parse_args()
    for what, b in (("--before", a.before), ("--after", a.after)):
        if not (os.path.isfile(b) and os.access(b, os.X_OK)):
            raise SystemExit(f"compare-seeds: {what} {b}: not an executable file")
    if not os.path.isfile(a.design):
        raise SystemExit(f"compare-seeds: design {a.design}: no such file")
    if a.threads < 0:
        raise SystemExit(f"compare-seeds: --threads {a.threads}: allowed 0 (idexp's default) or more")
    seeds = parse_seeds(a.seeds)
    out = a.out or tempfile.mkdtemp(prefix="compare-seeds-")
    os.makedirs(out, exist_ok=True)
    rows = []
    for s in seeds:
        crit, before, st_b = run(a.before, a.design, s, os.path.join(out, "before", f"seed-{s}"), a.threads)
        _, after, st_a = run(a.after, a.design, s, os.path.join(out, "after", f"seed-{s}"), a.threads)
        rel = (after - before) / abs(before) if before != 0 else (0.0 if after == before else float("inf"))
        rows.append({"seed": s, "criterion": crit, "before": before, "after": after, "relative": rel, "status_before": st_b, "status_after": st_a})
        print(f"seed {s:>4}: {crit} {before:.6g} -> {after:.6g} ({100 * rel:+.3f} %)", flush=True)
    with open(os.path.join(out, "seeds.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    moved = [r["relative"] for r in rows if abs(r["relative"]) > MOVED]
    print(f"\n{len(rows)} seeds of {a.design}; runs and seeds.csv in {out}")
    print(f"moved (|relative change| > {MOVED:g}): {len(moved)}; worse {sum(x > 0 for x in moved)}, better {sum(x < 0 for x in moved)}")
    print(f"median relative change {100 * statistics.median(r['relative'] for r in rows):+.3f} %")
    all_seeds, first = set(seeds), set(range(1, 6))
    means = {}
    for label, ss in (("seeds 1-5", first & all_seeds), ("all seeds", all_seeds)):
        mb, ma = mean_of(rows, "before", ss), mean_of(rows, "after", ss)
        means[label] = (mb, ma)
        if mb is not None:
            print(f"mean over {label} ({len(ss)}): before {mb:.6g}, after {ma:.6g} ({100 * (ma / mb - 1):+.3f} %)")
    if first <= all_seeds:
        mb, ma = means["seeds 1-5"]
        print("rule (seeds 1-5 no worse on average): " + ("met" if ma <= mb else "NOT met"))
    else:
        print("rule (seeds 1-5 no worse on average): not judged (seeds 1-5 not all run)")


if __name__ == "__main__":
    main()
