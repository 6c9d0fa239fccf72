"""Is a compiled robot in one piece? Attachment of bodies and self-penetration at rest.

Both are measured at the initial pose (``mj_forward`` at ``qpos0``) with MuJoCo's own signed
geom distance (``mujoco.mj_geomDistance``: the gap between two geoms, negative when they
overlap), over every non-plane geom whatever its collision flags.

**Attached** (issue 21): a non-root body (a body whose parent is not the world) is *detached*
when none of its geoms comes within ``tol · stat.extent`` (default ``tol`` = 5 %, MuJoCo's
``model.stat.extent`` is the model's size in m) of a geom of its parent body. A body without
geoms is neither attached nor detached (not counted); a parent without geoms is replaced by its
nearest ancestor with geoms (a body that only carries a joint is not a gap).

**Self-penetration**: the deepest overlap (m) between two geoms of different bodies that are
neither the same body nor parent and child (MuJoCo's own contact filter excludes those pairs:
geoms that meet at a joint may overlap). Its bounding-box pre-test skips pairs whose spheres
``geom_rbound`` cannot touch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings

__all__ = ["ATTACH_TOL", "Attachment", "attachment"]

#: Largest gap (fraction of ``stat.extent``) between a body's geoms and its parent's.
ATTACH_TOL = 0.05

_PLANE = mujoco.mjtGeom.mjGEOM_PLANE


@dataclass
class Attachment:
    """What :func:`attachment` measured on one robot.

    Attributes:
        bodies: non-root bodies with geoms whose attachment was checked.
        detached: ids of the detached bodies (``model.body`` ids).
        gaps: for each checked body id, its smallest gap to the parent's geoms (m).
        extent: ``model.stat.extent`` (m).
        penetration: deepest overlap between geoms of non-adjacent bodies (m, 0 when none).
    """

    bodies: int
    detached: list[int] = field(default_factory=list)
    gaps: dict[int, float] = field(default_factory=dict)
    extent: float = 0.0
    penetration: float = 0.0

    @property
    def all_attached(self) -> bool:
        """No body is detached."""
        return not self.detached

    @property
    def detached_share(self) -> float:
        """Detached bodies / checked bodies (0 when none was checked)."""
        return len(self.detached) / self.bodies if self.bodies else 0.0


def _geoms_by_body(model: mujoco.MjModel) -> list[list[int]]:
    out: list[list[int]] = [[] for _ in range(model.nbody)]
    for g in range(model.ngeom):
        if model.geom_type[g] != _PLANE:
            out[int(model.geom_bodyid[g])].append(g)
    return out


def _distance(model: mujoco.MjModel, data: mujoco.MjData, g1: int, g2: int,
              cap: float) -> float:
    """Signed distance between two geoms, at most ``cap`` (m)."""
    return float(mujoco.mj_geomDistance(model, data, g1, g2, cap, None))


def attachment(model: mujoco.MjModel, tol: float = ATTACH_TOL,
               penetration: bool = True) -> Attachment:
    """Attachment of every non-root body and self-penetration at rest (module docstring).

    Args:
        model: a compiled robot (a floor plane, if any, is ignored).
        tol: largest gap as a fraction of ``model.stat.extent``.
        penetration: also measure the self-penetration (O(geoms²) distance queries).
    """
    data = mujoco.MjData(model)
    with capture_mujoco_warnings():
        mujoco.mj_forward(model, data)
    extent = float(model.stat.extent)
    reach = tol * extent
    geoms = _geoms_by_body(model)
    parent = model.body_parentid
    out = Attachment(0, extent=extent)
    for b in range(1, model.nbody):
        if parent[b] == 0 or not geoms[b]:
            continue
        p = int(parent[b])
        while p > 0 and not geoms[p]:
            p = int(parent[p])
        if p == 0:
            continue
        out.bodies += 1
        cap = max(reach, 1e-9) * 4
        gap = min(_distance(model, data, g1, g2, cap) for g1 in geoms[b] for g2 in geoms[p])
        out.gaps[b] = gap
        if gap > reach:
            out.detached.append(b)
    if penetration:
        out.penetration = _deepest_overlap(model, data, geoms)
    return out


def _deepest_overlap(model: mujoco.MjModel, data: mujoco.MjData,
                     geoms: list[list[int]]) -> float:
    parent = model.body_parentid
    flat = [g for gs in geoms for g in gs]
    body = model.geom_bodyid
    pos, rb = data.geom_xpos, model.geom_rbound
    deepest = 0.0
    for a, g1 in enumerate(flat):
        b1 = int(body[g1])
        for g2 in flat[a + 1:]:
            b2 = int(body[g2])
            if b1 == b2 or parent[b1] == b2 or parent[b2] == b1:
                continue
            if np.linalg.norm(pos[g1] - pos[g2]) > rb[g1] + rb[g2]:
                continue
            deepest = max(deepest, -_distance(model, data, g1, g2, 0.0))
    return deepest
