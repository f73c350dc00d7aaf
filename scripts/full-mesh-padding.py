#!/usr/bin/env python3
"""How far the vendor's full (visual) meshes reach beyond a robot's collision
geometry, per link, against the robot file's `collision_padding`.

idexp checks distances between the convex hulls of the URDF's collision
meshes (and its primitives), each grown by the link's `collision_padding`.
The vendors' visual meshes are more detailed and reach up to about 2 mm
beyond those hulls. A visual mesh lies inside the grown hull exactly when
each of its vertices lies within `pad` of the hull (the grown hull is convex
and so holds the convex hull of the vertices, hence every triangle). This
script computes, independently of idexp (Pinocchio loads the URDF and both
geometry models, coal the hulls and the point distances), for each link the
largest distance of a visual vertex from the link's collision shapes, and
says whether the robot file's padding covers it.

  target/python-venv/bin/python scripts/full-mesh-padding.py designs/robots/ur5.toml

Exit status: 0 every link covered, 3 a link's visual mesh reaches beyond its
padding, 2 bad input. Needs pin (Pinocchio, with coal) and the PyPI package
example-robot-data (the vendors' visual meshes).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tomllib
from pathlib import Path

import numpy as np
import coal
import pinocchio as pin


class InputError(Exception):
    pass


def vendor_share() -> list[str]:
    """The cmeel prefixes' share folders holding example-robot-data."""
    out = []
    for p in sys.path:
        share = Path(p) / "cmeel.prefix" / "share"
        if (share / "example-robot-data").is_dir():
            out.append(str(share))
    return out


def protrusion(robot_path: Path) -> list[dict]:
    """Per link with collision geometry: visual vertex count, the largest
    distance of a visual vertex outside the link's collision shapes (m) and
    the robot file's padding of the link (m, 0 if none)."""
    try:
        robot = tomllib.loads(robot_path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise InputError(f"{robot_path}: {e}") from e
    urdf_rel = robot.get("urdf")
    if not isinstance(urdf_rel, str):
        raise InputError(f"{robot_path}: field `urdf`: a URDF robot is needed (its visual meshes)")
    pads = robot.get("collision_padding", {})
    if not isinstance(pads, dict) or not all(isinstance(v, (int, float)) for v in pads.values()):
        raise InputError(f"{robot_path}: field `collision_padding`: expected a table of link = metres")
    dirs = vendor_share()
    if not dirs:
        raise InputError("the PyPI package example-robot-data (the vendors' visual meshes) is not installed")
    urdf = str(robot_path.parent / urdf_rel)
    model = pin.buildModelFromUrdf(urdf)
    vis = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.VISUAL, package_dirs=dirs)
    col = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION, package_dirs=dirs)
    point = coal.Sphere(1e-12)
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    out = []
    for f in sorted({go.parentFrame for go in col.geometryObjects}):
        shapes = []
        for go in col.geometryObjects:
            if go.parentFrame != f:
                continue
            g = go.geometry
            if isinstance(g, coal.BVHModelBase):
                g.buildConvexHull(True, "Qt")
                g = g.convex
            shapes.append((go.placement, g))
        worst, n = 0.0, 0
        for v in vis.geometryObjects:
            if v.parentFrame != f:
                continue
            if not isinstance(v.geometry, coal.BVHModelBase):
                raise InputError(f"{urdf}: visual `{v.name}`: only meshes are compared")
            verts = np.asarray(v.geometry.vertices(), dtype=float).reshape(-1, 3)
            n += len(verts)
            for p in verts:
                pf = v.placement.act(p)
                d = math.inf
                for m, g in shapes:
                    res.clear()
                    d = min(d, coal.distance(g, coal.Transform3s(), point, coal.Transform3s(np.eye(3), m.actInv(pf)), req, res))
                worst = max(worst, d)
        name = model.frames[f].name
        out.append({"link": name, "visual_vertices": n, "protrusion": worst, "padding": float(pads.get(name, 0.0))})
    return out


def covered(rows: list[dict], robot_path: Path) -> list[dict]:
    """`rows` with `body_padding`: the padding idexp applies to the link's
    body (the largest over the links merged into it by fixed joints: idexp
    grows every shape of a body by its body's padding) — computed here from
    the URDF tree, as idexp merges fixed children into their parent."""
    robot = tomllib.loads(robot_path.read_text())
    model = pin.buildModelFromUrdf(str(robot_path.parent / robot["urdf"]))
    body = {fr.name: fr.parentJoint for fr in model.frames}
    best: dict[int, float] = {}
    for r in rows:
        j = body[r["link"]]
        best[j] = max(best.get(j, 0.0), r["padding"])
    for r in rows:
        r["body_padding"] = best[body[r["link"]]]
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("robot", type=Path, help="robot file (TOML) with a URDF")
    ap.add_argument("--json", type=Path, help="write the table as JSON here")
    a = ap.parse_args(argv)
    try:
        rows = covered(protrusion(a.robot), a.robot)
    except InputError as e:
        print(f"full-mesh-padding: {e}", file=sys.stderr)
        return 2
    bad = 0
    print(f"{a.robot}: the vendor's visual meshes beyond the collision shapes, per link")
    for r in rows:
        ok = r["protrusion"] <= r["body_padding"]
        bad += not ok
        print(
            f"  {r['link']:<20} {r['visual_vertices']:>6} vertices  reach {r['protrusion'] * 1e3:6.3f} mm  "
            f"padding {r['padding'] * 1e3:4.1f} mm (body {r['body_padding'] * 1e3:4.1f} mm)  {'ok' if ok else 'NOT COVERED'}"
        )
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    return 3 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
