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
  visible); a pair deeper than ``tolerance · L`` (1 %) is penetrating. A penetrating pair
  is **off joint** when the tree path between its two bodies (the polyline through the
  origins of the bodies below their nearest common ancestor) is longer than the two geoms are
  thick together (the radii of the largest balls they hold; a mesh's bounding box). Links
  shorter than that must overlap whichever way they turn: that is how geoms meet where several
  joints sit at (nearly) one point (a hip of three hinges: the thigh reaches into the pelvis
  through a short link). Off-joint overlaps are bodies passing through each other: legs
  crossing, an arm through the hips, a sensor box through a hip.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from robovae.data.loading import quiet_forward, robot_root
from robovae.evaluate.quality.stage import HFIELD, PLANE, Robot, Stage, compiled, extent
from robovae.settings import check_settings, number

__all__ = ["AttachResult", "attachment", "near_pairs", "off_joint", "robot_geoms"]

_G = mujoco.mjtGeom
SPHERE, CAPSULE, CYLINDER, ELLIPSOID, BOX = (int(t) for t in (
    _G.mjGEOM_SPHERE, _G.mjGEOM_CAPSULE, _G.mjGEOM_CYLINDER, _G.mjGEOM_ELLIPSOID, _G.mjGEOM_BOX))


@dataclass
class AttachResult:
    """Outcome of :func:`attachment`."""

    bodies: int  # non-root bodies judged
    detached: int
    detached_bodies: list[str] = field(default_factory=list)
    penetration: float = 0.0  # deepest overlap between non-adjacent bodies, m
    penetrating_pairs: int = 0  # geom pairs overlapping deeper than tolerance · extent
    off_joint_pairs: int = 0  # of those, pairs whose tree path is longer than they are thick
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


def robot_geoms(model: mujoco.MjModel, root: int) -> dict[int, list[int]]:
    """The geoms of each body of the robot below ``root`` (``root`` included), planes and
    height fields left out."""
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


def _thickness(model: mujoco.MjModel, g: int) -> float:
    """Radius (m) of the largest ball geom ``g`` holds (a mesh: of its bounding box)."""
    size, kind = model.geom_size[g], int(model.geom_type[g])
    if kind in (SPHERE, CAPSULE):
        return float(size[0])
    if kind == CYLINDER:
        return float(min(size[0], size[1]))
    if kind in (ELLIPSOID, BOX):
        return float(size.min())
    return float(model.geom_aabb[g, 3:].min())


def _path_length(model: mujoco.MjModel, data: mujoco.MjData, a: int, b: int) -> float:
    """Length (m) of the tree path between bodies ``a`` and ``b``: the polyline through the
    origins of the bodies below their nearest common ancestor, ``a``'s side then ``b``'s."""
    up_a, up_b = [a], [b]
    while up_a[-1] > 0:
        up_a.append(int(model.body_parentid[up_a[-1]]))
    while up_b[-1] > 0:
        up_b.append(int(model.body_parentid[up_b[-1]]))
    common = next(x for x in up_a if x in up_b)
    bodies = up_a[:up_a.index(common)] + up_b[:up_b.index(common)][::-1]
    points = data.xpos[bodies]
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def off_joint(model: mujoco.MjModel, data: mujoco.MjData, g1: int, g2: int) -> bool:
    """Whether an overlap of geoms ``g1`` and ``g2`` (of different bodies) is *off joint*: the
    tree path between their bodies is longer than the two are thick together (module
    docstring)."""
    return (_path_length(model, data, int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2]))
            > _thickness(model, g1) + _thickness(model, g2))


def near_pairs(model: mujoco.MjModel, data: mujoco.MjData, flat: np.ndarray,
               margins: tuple[float, ...] = (0.0,)) -> list[list[tuple[int, int]]]:
    """Per margin ``m`` (m), the index pairs ``i < j`` into ``flat`` (geom ids) of geoms of
    bodies that are neither the same nor parent and child whose bounding spheres come within
    ``m`` of each other: the pairs that can overlap (``m = 0``), or meet when moved by ``m``."""
    body = model.geom_bodyid[flat]
    parent = model.body_parentid[body]
    pos, rb = data.geom_xpos[flat], model.geom_rbound[flat]
    gap = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - (rb[:, None] + rb[None])
    other = np.triu((body[:, None] != body[None]) & (parent[:, None] != body[None])
                    & (body[:, None] != parent[None]), 1)
    return [[(int(i), int(j)) for i, j in zip(*np.nonzero(other & (gap <= m)))]
            for m in margins]


def _penetration(model: mujoco.MjModel, data: mujoco.MjData, geoms: dict[int, list[int]],
                 threshold: float) -> tuple[float, int, int]:
    """Deepest overlap (m) between geoms of non-adjacent bodies, the pairs deeper than
    ``threshold`` and those of them off joint (module docstring); a bounding-sphere pre-test
    (:func:`near_pairs`) skips pairs that cannot touch."""
    flat = np.array([g for gs in geoms.values() for g in gs], dtype=int)
    deepest, pairs, off = 0.0, 0, 0
    for i, j in near_pairs(model, data, flat)[0]:
        g1, g2 = int(flat[i]), int(flat[j])
        depth = -float(mujoco.mj_geomDistance(model, data, g1, g2, 0.0, None))
        deepest = max(deepest, depth)
        if depth > threshold:
            pairs += 1
            off += off_joint(model, data, g1, g2)
    return deepest, pairs, off


def attachment(robot: Robot, gap: float = 0.05, tolerance: float = 0.01,
               penetration: bool = True, data: mujoco.MjData | None = None) -> AttachResult:
    """Detached bodies and self-penetration of a robot file, spec, model or stage at ``qpos0``
    (module docstring; ``gap`` and ``tolerance`` are fractions of the extent; ``penetration``
    False skips the O(geoms²) overlap search). ``data``: a model's kinematics at ``qpos0``
    (``mj_kinematics``), used instead of a new ``MjData`` (the same result; left as given).

    Raises:
        RobotFileError: a file that does not load; SettingsError: ``gap`` or ``tolerance``
            not a finite number ``>= 0``.
    """
    check_settings("attachment", gap=(gap, number(0)), tolerance=(tolerance, number(0)))
    model = compiled(robot)
    if isinstance(robot, Stage):
        data, root, size = robot.data, robot.root, robot.extent
    else:
        if data is None:
            data = mujoco.MjData(model)
            quiet_forward(model, data)
        root = robot_root(model)[0]
        size = extent(model, data, root)
    geoms = robot_geoms(model, root)
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
        out.penetration, out.penetrating_pairs, out.off_joint_pairs = _penetration(
            model, data, geoms, tolerance * size)
    return out
