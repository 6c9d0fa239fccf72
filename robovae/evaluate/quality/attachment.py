"""Is the robot in one piece? Detached bodies and self-penetration at its initial pose.

At ``qpos0`` (``mj_forward``), with ``L`` the robot's extent (diagonal of its bounding box,
:func:`~robovae.evaluate.quality.stage.extent`):

- a non-root body of the robot (the subtree of :func:`~robovae.data.mjcf.robot_root`) that has
  geoms is **detached** when none of its geoms comes within ``gap · L`` (5 %) of a geom of its
  parent body (``mujoco.mj_geomDistance``, signed, so touching or overlapping geoms are
  attached). A body without geoms, or whose parent has none, is not judged. Planes and height
  fields are left out; every other geom counts (visual ones too: a link drawn away from its
  joint looks detached). Menagerie files without their mesh files keep only their primitive
  collision geoms, so they can look detached where the meshes would join them;
- **self-penetration**: the deepest overlap (m) among the contacts MuJoCo finds at ``qpos0``
  between two geoms of the robot (``data.contact`` with ``dist < 0``: MuJoCo's own filters
  apply, so parent-child pairs, ``contype``/``conaffinity``-filtered pairs and ``<exclude>``
  pairs do not count, exactly the pairs that would push each other apart in simulation); a
  contact deeper than ``tolerance · L`` (1 %) is penetrating.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco

from robovae.data.mjcf import robot_root
from robovae.evaluate.quality.stage import HFIELD, PLANE, Robot, compiled, extent

__all__ = ["AttachResult", "attachment"]


@dataclass
class AttachResult:
    """Outcome of :func:`attachment`."""

    bodies: int  # non-root bodies judged
    detached: int
    detached_bodies: list[str] = field(default_factory=list)
    penetration: float = 0.0  # deepest overlap between non-adjacent bodies, m
    penetrating_pairs: int = 0  # contacts deeper than tolerance · extent
    extent: float = 0.0  # m

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


def _penetration(model: mujoco.MjModel, data: mujoco.MjData, root: int, threshold: float
                 ) -> tuple[float, int]:
    """Deepest robot-robot contact overlap (m) and the contacts deeper than ``threshold``."""
    c = data.contact[:data.ncon]
    if data.ncon == 0:
        return 0.0, 0
    b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
    own = (b1 > 0) & (b2 > 0) & (model.body_rootid[b1] == root) & (model.body_rootid[b2] == root)
    depth = -c.dist[own]
    if not depth.size:
        return 0.0, 0
    return max(float(depth.max()), 0.0), int((depth > threshold).sum())


def attachment(robot: Robot, gap: float = 0.05, tolerance: float = 0.01) -> AttachResult:
    """Detached bodies and self-penetration of a robot file, spec or model at ``qpos0``
    (module docstring; ``gap`` and ``tolerance`` are fractions of the extent).

    Raises:
        RobotFileError: a file that does not load.
    """
    model = compiled(robot)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    root, _ = robot_root(model)
    size = extent(model, data, root)
    geoms = _geoms_by_body(model, root)
    limit = gap * size
    judged, detached = 0, []
    for b in range(1, model.nbody):
        if b == root or model.body_rootid[b] != root or b not in geoms:
            continue
        p = int(model.body_parentid[b])
        if p not in geoms:
            continue
        judged += 1
        if _min_distance(model, data, geoms[b], geoms[p], 2.0 * limit) > limit:
            detached.append(model.body(b).name or f"body{b}")
    deepest, pairs = _penetration(model, data, root, tolerance * size)
    return AttachResult(judged, len(detached), detached, deepest, pairs, size)
