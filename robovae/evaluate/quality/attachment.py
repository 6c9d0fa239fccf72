"""Is the robot in one piece? Detached bodies and self-penetration at its initial pose.

At ``qpos0`` (``mj_forward``), with ``L`` the robot's extent (diagonal of its bounding box,
:func:`~robovae.evaluate.quality.stage.extent`; MuJoCo's ``stat.extent`` would count floors and
``<statistic>`` overrides: 85 m for dm_control's quadruped):

- a non-root body of the robot (the subtree of :func:`~robovae.data.loading.robot_root`) that has
  geoms is **detached** when none of its geoms comes within ``gap · L`` (5 %) of a geom of its
  parent body, or of its nearest ancestor with geoms when the parent has none (a body that
  only carries a joint is not a gap). Distances are ``mujoco.mj_geomDistance`` (signed:
  touching or overlapping geoms are attached). Planes and height fields are left out; every
  other geom counts (visual ones too: a link drawn away from its joint looks detached).
  Menagerie files without their mesh files keep only their primitive geoms, so they can look
  detached where the meshes would join them;
- **self-penetration**: the deepest overlap (m) between two geoms of bodies that are neither
  the same body nor parent and child (geoms that meet at a joint may overlap), whatever their
  collision flags (generated robots do not collide with themselves, yet an overlap is still
  visible); a pair deeper than ``tolerance · L`` (1 %) is penetrating.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from robovae.data.loading import quiet_forward, robot_root
from robovae.evaluate.quality.stage import HFIELD, PLANE, Robot, Stage, compiled, extent
from robovae.settings import check_settings, number

__all__ = ["AttachResult", "attachment"]


@dataclass
class AttachResult:
    """Outcome of :func:`attachment`."""

    bodies: int  # non-root bodies judged
    detached: int
    detached_bodies: list[str] = field(default_factory=list)
    penetration: float = 0.0  # deepest overlap between non-adjacent bodies, m
    penetrating_pairs: int = 0  # geom pairs overlapping deeper than tolerance · extent
    extent: float = 0.0  # m
    gaps: dict[int, float] = field(default_factory=dict)  # body id -> gap to its parent, m

    @property
    def all_attached(self) -> bool:
        """No judged body is detached."""
        return self.detached == 0

    @property
    def detached_share(self) -> float:
        """Detached / judged bodies (0 when none is judged)."""
        return self.detached / self.bodies if self.bodies else 0.0


def _geoms_by_body(model: mujoco.MjModel, root: int) -> dict[int, list[int]]:
    out: dict[int, list[int]] = {}
    for g in range(model.ngeom):
        b = int(model.geom_bodyid[g])
        if b and model.body_rootid[b] == root and model.geom_type[g] not in (PLANE, HFIELD):
            out.setdefault(b, []).append(g)
    return out


def _min_distance(model: mujoco.MjModel, data: mujoco.MjData, a: list[int], b: list[int],
                  distmax: float) -> float:
    return min(mujoco.mj_geomDistance(model, data, g1, g2, distmax, None)
               for g1 in a for g2 in b)


def _penetration(model: mujoco.MjModel, data: mujoco.MjData, geoms: dict[int, list[int]],
                 threshold: float) -> tuple[float, int]:
    """Deepest overlap (m) between geoms of non-adjacent bodies and the pairs deeper than
    ``threshold``; a bounding-sphere pre-test skips pairs that cannot touch."""
    flat = np.array([g for gs in geoms.values() for g in gs], dtype=int)
    body = model.geom_bodyid[flat]
    parent = model.body_parentid[body]
    pos, rb = data.geom_xpos[flat], model.geom_rbound[flat]
    gap = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - (rb[:, None] + rb[None])
    apart = ((body[:, None] == body[None]) | (parent[:, None] == body[None])
             | (body[:, None] == parent[None]) | (gap > 0))
    deepest, pairs = 0.0, 0
    for i, j in zip(*np.nonzero(np.triu(~apart, 1))):
        depth = -float(mujoco.mj_geomDistance(model, data, int(flat[i]), int(flat[j]), 0.0,
                                              None))
        deepest = max(deepest, depth)
        pairs += depth > threshold
    return deepest, pairs


def attachment(robot: Robot, gap: float = 0.05, tolerance: float = 0.01,
               penetration: bool = True) -> AttachResult:
    """Detached bodies and self-penetration of a robot file, spec, model or stage at ``qpos0``
    (module docstring; ``gap`` and ``tolerance`` are fractions of the extent; ``penetration``
    False skips the O(geoms²) overlap search).

    Raises:
        RobotFileError: a file that does not load; SettingsError: ``gap`` or ``tolerance``
            not a finite number ``>= 0``.
    """
    check_settings("attachment", gap=(gap, number(0)), tolerance=(tolerance, number(0)))
    model = compiled(robot)
    if isinstance(robot, Stage):
        data, root, size = robot.data, robot.root, robot.extent
    else:
        data = mujoco.MjData(model)
        quiet_forward(model, data)
        root = robot_root(model)[0]
        size = extent(model, data, root)
    geoms = _geoms_by_body(model, root)
    limit = gap * size
    out = AttachResult(0, 0, extent=size)
    for b in range(1, model.nbody):
        if b == root or model.body_rootid[b] != root or b not in geoms:
            continue
        p = int(model.body_parentid[b])
        while p != root and p > 0 and p not in geoms:
            p = int(model.body_parentid[p])
        if p not in geoms:
            continue
        out.bodies += 1
        out.gaps[b] = _min_distance(model, data, geoms[b], geoms[p], 2.0 * limit)
        if out.gaps[b] > limit:
            out.detached += 1
            out.detached_bodies.append(model.body(b).name or f"body{b}")
    if penetration:
        out.penetration, out.penetrating_pairs = _penetration(model, data, geoms, tolerance * size)
    return out
