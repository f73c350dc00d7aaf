#!/usr/bin/env python3
"""Compares two folders made by scripts/record-outputs.sh, numeric results only.

    scripts/compare-outputs.py <before> <after>

CSV files must be byte-identical; JSON files must hold the same values after
dropping timing fields (seconds, *_time, started, finished, elapsed) and the
keys named in IGNORE; status.json, options.json (run metadata) and the
human-readable files (.txt, .svg, .stdout) are not compared. Prints every
difference with the first differing path and exits 1 if there is any.
"""
import json, os, re, sys

IGNORE = {"seconds", "started", "finished", "elapsed", "idexp_version", "design_fingerprint", "out", "output", "dir"}
TIMING = re.compile(r"(_time|_seconds|time_s)$")
SKIP_FILES = {"status.json", "options.json", "inputs.json", "design.json"}


def clean(v, root):
    if isinstance(v, dict):
        return {k: clean(x, root) for k, x in v.items() if k not in IGNORE and not TIMING.search(k)}
    if isinstance(v, list):
        return [clean(x, root) for x in v]
    if isinstance(v, str):
        return v.replace(root, "ROOT")
    return v


def first_diff(a, b, path="$"):
    if type(a) != type(b):
        return f"{path}: {a!r} vs {b!r}"
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{path}.{k}: only in {'after' if k not in a else 'before'}"
            d = first_diff(a[k], b[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{path}: length {len(a)} vs {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            d = first_diff(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{path}: {a!r} vs {b!r}"


def main(before, after):
    bad = 0
    checked = 0
    walks = [os.walk(os.path.join(before, sub)) for sub in ("out", os.path.join("tree", "out"))]
    for d, _, files in (w for walk in walks for w in walk):
        for f in sorted(files):
            pa = os.path.join(d, f)
            rel = os.path.relpath(pa, before)
            pb = os.path.join(after, rel)
            if f in SKIP_FILES or not (f.endswith(".csv") or f.endswith(".json") or f.endswith(".jsonl")):
                continue
            checked += 1
            if not os.path.exists(pb):
                print(f"missing in after: {rel}")
                bad += 1
                continue
            if f.endswith(".json"):
                try:
                    ja = clean(json.load(open(pa)), before)
                    jb = clean(json.load(open(pb)), after)
                except json.JSONDecodeError as e:
                    print(f"{rel}: not JSON: {e}")
                    bad += 1
                    continue
                diff = first_diff(ja, jb)
            else:
                diff = None if open(pa, "rb").read() == open(pb, "rb").read() else "bytes differ"
            if diff:
                print(f"DIFF {rel}: {diff}")
                bad += 1
    print(f"{checked} numeric files compared, {bad} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])))
