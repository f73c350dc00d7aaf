#!/usr/bin/env python3
"""Independent replay of an excitation design's delivered trajectory against
the vendor's collision meshes (Pinocchio + coal).

idexp checks collisions on convex hulls of the collision meshes (parry,
GJK/EPA). This script checks the same trajectory with other code on other
geometry: Pinocchio loads the design's URDF with its collision meshes as the
vendor ships them (the PyPI package example-robot-data's copies, found through
its cmeel prefix, else the design's `mesh_path`), coal computes the exact
distance between the full, non-convex meshes (BVH), and the mounting plane
z = 0 (the floor of `[collision] floor = true`) is checked against every mesh
vertex (the least height of a polyhedron is at a vertex: exact).

Every 1 kHz sample of `trajectory.csv` (the delivered trajectory that
`idexp excite` writes: lead-in, periods, lead-out) is replayed. Pairs: the same
rule as idexp, derived here from the URDF and the robot file: every pair of
bodies (a moving link with everything fixed to it; the base) except the pairs
joined by one joint and the robot file's `allowed_collision`, and every body
but the base against the floor (the base is mounted on it; the UR5's base
mesh reaches 3 mm below the plane). A pair whose bounding spheres are farther
apart than the cap (margin + band) is not queried (its distance is above the
cap, which is all that is reported). A design with `[collision] enabled =
false` (it imposes no collision constraint) is replayed with margin 0: any
contact is unsafe.

Usage:
    target/python-venv/bin/python scripts/safety-replay.py designs/excite_ur5.toml out/excite_ur5 [--json FILE] [--hulls]

Prints, per pair, the least distance over the trajectory and where, the
samples below the margin, and the verdict: SAFE (no sample below the margin)
or UNSAFE. Exit status 0 for SAFE, 3 for UNSAFE, 2 for bad input. With
`--hulls`, coal's distances between the convex hulls of the same meshes
(qhull) are computed too, and the margin the hulls add (mesh − hull distance)
is reported per pair.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import site
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

try:
    import coal
    import pinocchio as pin
except ImportError as e:  # pragma: no cover - environment
    sys.exit(f"safety-replay: needs Pinocchio and coal (pip install pin): {e}")


class InputError(Exception):
    """Bad input: a message naming the file and the field."""


def vendor_share() -> list[str]:
    """The cmeel prefixes' share folders (example-robot-data's meshes)."""
    out = []
    for sp in site.getsitepackages() + [site.getusersitepackages()]:
        p = Path(sp) / "cmeel.prefix" / "share"
        if (p / "example-robot-data").is_dir():
            out.append(str(p))
    return out


@dataclass
class Geom:
    """One collision geometry of a body: coal objects and its vertices."""

    name: str
    joint: int
    placement: pin.SE3
    mesh: object
    hull: object | None
    verts: np.ndarray  # local vertices (geometry frame)
    centre: np.ndarray
    radius: float


@dataclass
class Pair:
    a: str
    b: str  # body name or "floor"
    world: bool
    ga: list = field(default_factory=list)
    gb: list = field(default_factory=list)

    @property
    def label(self) -> str:
        return f"{'world' if self.world else 'self'}: {self.a} – {self.b}"


def load_design(design_path: Path):
    try:
        design = tomllib.loads(design_path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise InputError(f"{design_path}: cannot read the design file: {e}") from e
    robot_rel = design.get("robot")
    if not isinstance(robot_rel, str):
        raise InputError(f"{design_path}: field `robot`: expected the path of a robot file")
    robot_path = (design_path.parent / robot_rel).resolve()
    try:
        robot = tomllib.loads(robot_path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise InputError(f"{robot_path}: cannot read the robot file: {e}") from e
    coll = design.get("collision", {})
    for key in ("obstacle", "attached"):
        if coll.get(key):
            raise InputError(f"{design_path}: collision.{key}: not supported by the replay (floor and self pairs only)")
    return design, robot, robot_path


def package_tree(urdf: Path, robot_path: Path, mesh_path: list, tmp: Path) -> str:
    """Without example-robot-data: a folder of links `pkg/...` → the robot
    file's `mesh_path` copies (the longest suffix of each package:// path that
    exists below one of them), for Pinocchio's package_dirs."""
    import re

    roots = [robot_path.parent / m for m in mesh_path]
    for name in set(re.findall(r'filename="package://([^"]+)"', urdf.read_text())):
        parts = Path(name).parts
        target = next(
            (r.joinpath(*parts[i:]) for r in roots for i in range(len(parts)) if r.joinpath(*parts[i:]).is_file()),
            None,
        )
        if target is None:
            continue  # visual meshes are not copied; a missing collision mesh fails in Pinocchio
        link = tmp.joinpath(*parts)
        link.parent.mkdir(parents=True, exist_ok=True)
        if not link.exists():
            link.symlink_to(target.resolve())
    return str(tmp)


def build(design_path: Path, mesh_dirs: list[str] | None = None, hulls: bool = False, meshes: str = "collision"):
    design, robot, robot_path = load_design(design_path)
    urdf_rel = robot.get("urdf")
    if not isinstance(urdf_rel, str):
        raise InputError(f"{robot_path}: field `urdf`: the replay needs a URDF robot")
    urdf = robot_path.parent / urdf_rel
    dirs = list(mesh_dirs or []) or vendor_share()
    if meshes not in ("collision", "visual"):
        raise InputError(f"--meshes {meshes}: expected collision or visual")
    if meshes == "visual" and not dirs:
        raise InputError("--meshes visual: the vendor's visual meshes come from the PyPI package example-robot-data (pip install example-robot-data), not found")
    if not dirs:
        import tempfile

        # the shipped copies (byte for byte the vendor's, see designs/robots/meshes/README.md)
        dirs = [package_tree(urdf, robot_path, robot.get("mesh_path", []), Path(tempfile.mkdtemp(prefix="replay-meshes-")))]
    model = pin.buildModelFromUrdf(str(urdf))
    gtype = pin.GeometryType.VISUAL if meshes == "visual" else pin.GeometryType.COLLISION
    gmodel = pin.buildGeomFromUrdf(model, str(urdf), gtype, package_dirs=dirs)
    tip = robot.get("tip_link")
    if tip:
        # the robot file cuts the URDF at tip_link (e.g. before the Panda's
        # finger joints): as in idexp, the joints off the root-to-tip chain
        # and the links they move are left out (locked at 0, no geometry)
        if not model.existFrame(tip):
            raise InputError(f"{robot_path}: field `tip_link`: no link `{tip}` in {urdf}")
        j = model.frames[model.getFrameId(tip)].parentJoint
        chain = set()
        while j > 0:
            chain.add(j)
            j = model.parents[j]
        lock = [j for j in range(1, model.njoints) if j not in chain]
        # links moved by a locked joint are outside idexp's model: no geometry
        for name in [go.name for go in gmodel.geometryObjects if go.parentJoint in lock]:
            gmodel.removeGeometryObject(name)
        if lock:
            model, (gmodel,) = pin.buildReducedModel(model, [gmodel], lock, pin.neutral(model))
    # bodies: the base (joint 0) and one per moving joint, named by the link the joint moves
    base = robot.get("base_link")
    names = {}
    for f in model.frames:
        if f.type == pin.FrameType.BODY:
            # the first body frame of a joint is the link it moves (fixed children come later)
            names.setdefault(f.parentJoint, f.name)
    if base:
        names[0] = base
    geoms: dict[int, list[Geom]] = {}
    for go in gmodel.geometryObjects:
        g = go.geometry
        if isinstance(g, coal.BVHModelBase):
            verts = np.array(g.vertices(), dtype=float).reshape(-1, 3)
            hull = None
            if hulls:
                g.buildConvexHull(False, "Qt")
                hull = g.convex
        elif isinstance(g, coal.Box):
            h = np.asarray(g.halfSide, dtype=float)
            verts = np.array([[sx * h[0], sy * h[1], sz * h[2]] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            hull = g
        else:
            raise InputError(f"{urdf}: geometry `{go.name}`: shape {type(g).__name__} not supported by the replay")
        c = 0.5 * (verts.min(axis=0) + verts.max(axis=0))
        r = float(np.max(np.linalg.norm(verts - c, axis=1)))
        geoms.setdefault(go.parentJoint, []).append(
            Geom(go.name, go.parentJoint, go.placement, g, hull, verts, c, r)
        )
    allowed = robot.get("allowed_collision", [])
    coll = design.get("collision", {})
    pairs = []
    excluded = []
    njoints = model.njoints
    if coll.get("self", True):
        for a in range(njoints):
            for b in range(a + 1, njoints):
                if not geoms.get(a) or not geoms.get(b):
                    continue
                if model.parents[b] == a or model.parents[a] == b:
                    excluded.append((names[a], names[b], "adjacent: joined by one joint"))
                    continue
                la, lb = names[a], names[b]
                if any({al.get("a"), al.get("b")} == {la, lb} for al in allowed):
                    excluded.append((la, lb, "allowed by the robot file"))
                    continue
                pairs.append(Pair(la, lb, False, geoms[a], geoms[b]))
    if coll.get("floor", True):
        if geoms.get(0):
            # as idexp: the base is mounted on the plane (a vendor mesh may reach below it)
            excluded.append((names[0], "floor", "the base is mounted on it"))
        for j in range(1, njoints):
            if geoms.get(j):
                pairs.append(Pair(names[j], "floor", True, geoms[j], []))
    # a design that imposes no collision constraint ([collision] enabled =
    # false, the benchmark designs) is replayed all the same: without a
    # margin, any contact is unsafe (idexp checks it afterwards the same way)
    margin = 0.0 if coll.get("enabled", True) is False else float(coll.get("margin", 0.02))
    band = float(coll.get("band", 0.1))
    return model, gmodel, pairs, excluded, margin, band


def read_trajectory(path: Path, dof: int):
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        raise InputError(f"{path}: cannot read the trajectory: {e}") from e
    if not rows:
        raise InputError(f"{path}: empty")
    head = rows[0]
    cols = [f"q{j + 1}" for j in range(dof)]
    missing = [c for c in ["t"] + cols if c not in head]
    if missing:
        raise InputError(f"{path}: header lacks columns {missing} (robot with {dof} joints)")
    idx = [head.index(c) for c in ["t"] + cols]
    seg = head.index("segment") if "segment" in head else None
    data = np.array([[float(r[i]) for i in idx] for r in rows[1:]])
    segs = np.array([int(float(r[seg])) for r in rows[1:]]) if seg is not None else np.zeros(len(data), dtype=int)
    if not np.all(np.isfinite(data)):
        raise InputError(f"{path}: a value is not finite")
    return data[:, 0], data[:, 1:], segs


def pair_distance(p: Pair, oMg: dict, cap: float, use_hull: bool, req, res) -> float:
    """Least distance of pair p (meshes or hulls), capped at `cap`."""
    best = cap
    if p.world:
        for g in p.ga:
            M = oMg[id(g)]
            z = (g.verts @ M.rotation.T + M.translation)[:, 2]
            best = min(best, float(z.min()))
        return best
    for ga in p.ga:
        Ma = oMg[id(ga)]
        ca = Ma.act(ga.centre)
        for gb in p.gb:
            Mb = oMg[id(gb)]
            cb = Mb.act(gb.centre)
            if np.linalg.norm(ca - cb) - ga.radius - gb.radius > best:
                continue
            sa = ga.hull if use_hull else ga.mesh
            sb = gb.hull if use_hull else gb.mesh
            res.clear()
            d = coal.distance(sa, coal.Transform3s(Ma.rotation, Ma.translation), sb, coal.Transform3s(Mb.rotation, Mb.translation), req, res)
            best = min(best, d)
    return best


def replay(design_path: Path, out_dir: Path, hulls: bool = False, mesh_dirs=None, stride: int = 1, trajectory: str = "trajectory.csv", cap: float | None = None, meshes: str = "collision"):
    """Replays `out_dir/trajectory`; distances are capped at `cap` (default
    the design's margin + band): a pair farther apart reports the cap."""
    model, gmodel, pairs, excluded, margin, band = build(design_path, mesh_dirs, hulls, meshes)
    if cap is None:
        cap = margin + band
    if not (math.isfinite(cap) and cap >= margin):
        raise InputError(f"cap {cap} must be finite and at least the margin {margin} m")
    t, q, segs = read_trajectory(out_dir / trajectory, model.nq)
    data = model.createData()
    gdata = gmodel.createData()
    req = coal.DistanceRequest()
    res = coal.DistanceResult()
    allg = [g for p in pairs for g in p.ga + p.gb]
    dist = np.full((len(t), len(pairs)), cap)
    hdist = np.full((len(t), len(pairs)), cap) if hulls else None
    for k in range(0, len(t), stride):
        pin.forwardKinematics(model, data, q[k])
        oMg = {}
        for g in allg:
            oMg[id(g)] = data.oMi[g.joint] * g.placement
        for i, p in enumerate(pairs):
            dist[k, i] = pair_distance(p, oMg, cap, False, req, res)
            if hulls:
                hdist[k, i] = pair_distance(p, oMg, cap, True, req, res)
    rows = range(0, len(t), stride)
    summary = []
    for i, p in enumerate(pairs):
        col = dist[list(rows), i]
        kmin = int(np.argmin(col)) * stride
        below = int(np.sum(col < margin))
        entry = {
            "pair": p.label,
            "min": float(dist[kmin, i]),
            "t": float(t[kmin]),
            "segment": int(segs[kmin]),
            "below_margin": below,
        }
        if below:
            kb = int(np.argmax(col < margin)) * stride
            entry["first_below_t"] = float(t[kb])
            entry["first_below_q"] = [float(v) for v in q[kb]]
        if hulls:
            hcol = hdist[list(rows), i]
            both = (col < cap) & (hcol < cap)
            gap = col[both] - hcol[both]
            entry["hull_min"] = float(hcol.min())
            if gap.size:
                entry["hull_gap_min"] = float(gap.min())
                entry["hull_gap_median"] = float(np.median(gap))
                kh = int(np.argmin(hcol))
                entry["hull_gap_at_hull_min"] = float(col[kh] - hcol[kh]) if hcol[kh] < cap and col[kh] < cap else None
                entry["hull_gap_max"] = float(gap.max())
        summary.append(entry)
    unsafe = any(e["below_margin"] for e in summary)
    return {
        "design": str(design_path),
        "trajectory": str(out_dir / trajectory),
        "samples": len(rows),
        "meshes": meshes,
        "margin": margin,
        "cap": cap,
        "excluded": [{"a": a, "b": b, "reason": r} for a, b, r in excluded],
        "pairs": summary,
        "verdict": "UNSAFE" if unsafe else "SAFE",
    }, (t, q, dist, hdist, pairs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("design", type=Path, help="design file (TOML)")
    ap.add_argument("out", type=Path, help="output folder of `idexp excite` (holds trajectory.csv)")
    ap.add_argument("--json", type=Path, help="write the summary as JSON here")
    ap.add_argument("--meshes", choices=["collision", "visual"], default="collision", help="the vendor's collision meshes (default) or its full visual meshes (from example-robot-data)")
    ap.add_argument("--hulls", action="store_true", help="also coal's convex-hull distances: the margin the hulls add")
    ap.add_argument("--mesh-dir", action="append", help="package folder for package:// meshes (default: example-robot-data's)")
    ap.add_argument("--stride", type=int, default=1, help="replay every n-th sample (default 1: all)")
    ap.add_argument("--trajectory", default="trajectory.csv", help="file in OUT (default trajectory.csv; periodic.csv: one period)")
    ap.add_argument("--cap", type=float, help="report distances up to this (m; default margin + band); smaller is faster")
    a = ap.parse_args(argv)
    if a.stride < 1:
        print("safety-replay: --stride must be ≥ 1", file=sys.stderr)
        return 2
    try:
        s, _ = replay(a.design, a.out, a.hulls, a.mesh_dir, a.stride, a.trajectory, a.cap, a.meshes)
    except InputError as e:
        print(f"safety-replay: {e}", file=sys.stderr)
        return 2
    print(f"{s['design']}: {s['samples']} samples of {s['trajectory']}, the vendor's {s['meshes']} meshes, margin {s['margin']} m")
    for e in s["excluded"]:
        print(f"  not checked: {e['a']} – {e['b']}: {e['reason']}")
    for e in sorted(s["pairs"], key=lambda e: e["min"]):
        extra = ""
        if "hull_min" in e:
            extra = f"  hull {e['hull_min']:.4f}"
            if "hull_gap_min" in e:
                extra += f", mesh−hull {e['hull_gap_min']:.4f} … {e['hull_gap_max']:.4f} (median {e['hull_gap_median']:.4f})"
                if e.get("hull_gap_at_hull_min") is not None:
                    extra += f", {e['hull_gap_at_hull_min']:.4f} where the hull is closest"
        flag = f"  BELOW MARGIN at {e['below_margin']} samples (first t = {e['first_below_t']:.3f} s)" if e["below_margin"] else ""
        print(f"  {e['pair']:<40} min {e['min']:.4f} m at t = {e['t']:.3f} s (segment {e['segment']}){extra}{flag}")
    print(f"verdict: {s['verdict']}")
    if a.json:
        a.json.write_text(json.dumps(s, indent=1))
    return 3 if s["verdict"] == "UNSAFE" else 0


if __name__ == "__main__":
    sys.exit(main())
