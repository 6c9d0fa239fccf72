"""Diagnostic: why robots fall — standing by limb count, and the support at rest. Tables.

For a folder of ``robovae generate`` (its manifest's quality records) it prints standing per
number of limbs on the root (floating robots). Then, for the first ``--n`` floating robots of
the folder and of ``--written`` procedural training graphs written by the same writer
(:func:`robovae.evaluate.quality.populations.written_files`), the robot on its floor at rest
(:func:`robovae.evaluate.quality.stage.stage`, contacts reported within 1 % of the robot's
extent): whether the centre of mass lies above the convex hull of the floor contacts (the
support polygon), and, for the two-limb robots, how they touch the floor (feet only: leaf
bodies; level: every touching capsule within 15° of horizontal, box face within 15°).

    PYTHONPATH=. python benchmarks/rest_support.py runs/default/samples10k --n 400 --written 400
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from robovae.evaluate.quality.populations import written_files
from robovae.evaluate.quality.stage import stage
from robovae.evaluate.tables import format_table

_CAPSULE, _BOX = int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_BOX)


def at_rest(path: Path) -> dict | None:
    """Support of one floating robot at rest (None for a fixed base)."""
    st = stage(path)
    m = st.model
    if not (m.jnt_type == mujoco.mjtJoint.mjJNT_FREE).any():
        return None
    m.geom_margin[:] = 0.01 * st.extent
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    kids = np.bincount(m.body_parentid[1:], minlength=m.nbody)
    points, leaf, level = [], [], []
    for c in d.contact[:d.ncon]:
        g = int(c.geom[1] if m.geom_bodyid[c.geom[0]] == 0 else c.geom[0])
        points.append(c.pos[:2].copy())
        leaf.append(kids[m.geom_bodyid[g]] == 0)
        z = d.geom_xmat[g].reshape(3, 3)[2]
        if m.geom_type[g] == _CAPSULE:
            level.append(abs(z[2]) < np.sin(np.radians(15)))
        elif m.geom_type[g] == _BOX:
            level.append(np.abs(z).max() > np.cos(np.radians(15)))
    inside = False
    if len(points) >= 3:
        try:
            h = ConvexHull(np.array(points))
            com = d.subtree_com[st.root][:2]
            inside = bool((h.equations[:, :2] @ com + h.equations[:, 2]).max() < 0)
        except QhullError:  # collinear contacts: no polygon
            pass
    return {"inside": inside, "feet_only": bool(points) and all(leaf),
            "level": bool(level) and all(level)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("samples", type=Path)
    ap.add_argument("--n", type=int, default=400)
    ap.add_argument("--written", type=int, default=400)
    ap.add_argument("--root", default="data_cache")
    args = ap.parse_args()
    recs = [json.loads(line) for line in (args.samples / "manifest.jsonl").open()]
    recs = [r for r in recs if (r.get("quality") or {}).get("floating")]
    by = collections.defaultdict(lambda: [0, 0])
    for r in recs:
        by[r["quality"]["limbs"]][0] += 1
        by[r["quality"]["limbs"]][1] += r["quality"]["stands"]
    print(format_table([{"limbs": k, "robots": n, "standing": f"{s / n:.0%}"}
                        for k, (n, s) in sorted(by.items())], ["limbs", "robots", "standing"]))
    rows = []
    two = collections.Counter()
    for r in recs[:args.n]:
        a = at_rest(args.samples / r["path"])
        if r["quality"]["limbs"] == 2 and a is not None:
            key = "stands" if r["quality"]["stands"] else "falls"
            two[key] += 1
            two[key + ", feet only"] += a["feet_only"]
            two[key + ", level"] += a["level"]
        rows.append(a)
    def share(xs: list[dict | None]) -> str:  # floating robots only (None: fixed base)
        done = [x["inside"] for x in xs if x]
        return f"{np.mean(done):.1%} of {len(done)}"

    table = [{"robots": f"samples (first {args.n} floating)", "CoM above support": share(rows)}]
    if args.written > 0:
        written = [at_rest(p) for p in written_files(args.written, args.root, zoo=False)]
        table.append({"robots": f"{args.written} training graphs, written",
                      "CoM above support": share(written)})
    print(format_table(table, ["robots", "CoM above support"]))
    print("two-limb samples:", dict(two))


if __name__ == "__main__":
    main()
