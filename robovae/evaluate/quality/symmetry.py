"""Body plan of a compiled robot: counts, limbs, and whether the limbs come in mirrored pairs.

The robot is the subtree of its root body (:func:`~robovae.data.loading.robot_root`). A **limb**
is a child subtree of the root body that holds at least one joint. At ``qpos0``:

- a limb's **topology** is its canonical tree signature: each body is written as its number of
  hinge/slide/ball joints followed by the sorted signatures of its children, so two limbs have
  the same signature exactly when their body trees with joint counts are isomorphic;
- its **length** is the largest distance from the limb's first body origin to a point of one of
  its geoms (geom centre distance plus ``geom_rbound``) or body origins, in m;
- its **mass** is the limb's subtree mass, kg.

Two limbs are **mirrored** when they share the topology and their lengths and masses differ by
at most ``tolerance`` (10 %) of the larger one. Limbs are paired greedily (each limb, in body
order, with the closest unpaired mirror: smallest summed relative length and mass difference).
A robot is **symmetric** when it has at least two limbs and at most one limb is left unpaired
(a head, tail or the waist of a humanoid whose arms pair); **one limb** when exactly one limb
hangs on the root (a chain).

:func:`anatomy` also gives the counts compared with a training corpus: ``bodies`` (robot
bodies), ``dof`` (``nv`` of the robot's joints, a free joint counts 6) and ``mass`` (kg).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from robovae.data.loading import robot_root
from robovae.evaluate.quality.stage import HFIELD, PLANE, Robot, Stage, compiled
from robovae.settings import check_settings, number

__all__ = ["Anatomy", "anatomy", "mirrored"]

_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)


@dataclass
class Anatomy:
    """Counts and limb symmetry of one robot (:func:`anatomy`)."""

    bodies: int
    dof: int
    mass: float  # kg
    limbs: int
    pairs: int  # mirrored limb pairs
    unpaired: int
    limb_lengths: list[float] = field(default_factory=list)  # m, in body order
    limb_masses: list[float] = field(default_factory=list)  # kg

    @property
    def symmetric(self) -> bool:
        """At least two limbs and at most one unpaired."""
        return self.limbs >= 2 and self.unpaired <= 1

    @property
    def one_limb(self) -> bool:
        """Exactly one limb on the root."""
        return self.limbs == 1


def mirrored(len_a: float, len_b: float, mass_a: float, mass_b: float,
             tolerance: float = 0.1) -> bool:
    """Lengths and masses each within ``tolerance`` of the larger value."""
    def close(a: float, b: float) -> bool:
        return abs(a - b) <= tolerance * max(abs(a), abs(b))
    return close(len_a, len_b) and close(mass_a, mass_b)


def _signature(model: mujoco.MjModel, kids: dict[int, list[int]], b: int) -> str:
    adr, n = model.body_jntadr[b], model.body_jntnum[b]
    types = model.jnt_type[adr:adr + n] if n > 0 else np.zeros(0, int)
    own = f"{int(np.sum(types == _HINGE))}{int(np.sum(types == _SLIDE))}" \
          f"{int(np.sum(types == _BALL))}"
    return own + "(" + ",".join(sorted(_signature(model, kids, c) for c in kids.get(b, []))) + ")"


def _subtree(kids: dict[int, list[int]], b: int) -> list[int]:
    out, stack = [], [b]
    while stack:
        x = stack.pop()
        out.append(x)
        stack += kids.get(x, [])
    return out


def anatomy(robot: Robot, tolerance: float = 0.1) -> Anatomy:
    """Counts, limbs and mirrored limb pairs of a robot file, spec, model or stage (module
    docstring).

    Raises:
        RobotFileError: a file that does not load; SettingsError: ``tolerance`` not a finite
            number ``>= 0``.
    """
    check_settings("anatomy", tolerance=(tolerance, number(0)))
    model = compiled(robot)
    if isinstance(robot, Stage):
        data = robot.data
    else:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
    root, _ = robot_root(model)
    kids: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        if model.body_rootid[b] == root and b != root:
            kids.setdefault(int(model.body_parentid[b]), []).append(b)
    bodies = _subtree(kids, root)
    dof = int(sum(model.body_dofnum[b] for b in bodies))
    limbs, lengths, masses, sigs = [], [], [], []
    for c in kids.get(root, []):
        sub = _subtree(kids, c)
        if not any(model.body_jntnum[b] for b in sub):
            continue
        origin = data.xpos[c]
        reach = max(float(np.linalg.norm(data.xpos[b] - origin)) for b in sub)
        for g in range(model.ngeom):
            if model.geom_bodyid[g] in sub and model.geom_type[g] not in (PLANE, HFIELD):
                reach = max(reach, float(np.linalg.norm(data.geom_xpos[g] - origin)
                                         + model.geom_rbound[g]))
        limbs.append(c)
        lengths.append(reach)
        masses.append(float(model.body_subtreemass[c]))
        sigs.append(_signature(model, kids, c))
    free = set(range(len(limbs)))
    pairs = 0
    for i in range(len(limbs)):
        if i not in free:
            continue
        free.discard(i)
        best, cost = None, np.inf
        for j in sorted(free):
            if sigs[j] != sigs[i] or not mirrored(lengths[i], lengths[j], masses[i], masses[j],
                                                  tolerance):
                continue
            d = (abs(lengths[i] - lengths[j]) / max(lengths[i], lengths[j], 1e-12)
                 + abs(masses[i] - masses[j]) / max(masses[i], masses[j], 1e-12))
            if d < cost:
                best, cost = j, d
        if best is not None:
            free.discard(best)
            pairs += 1
    return Anatomy(len(bodies), dof, float(model.body_subtreemass[root]), len(limbs), pairs,
                   len(limbs) - 2 * pairs, lengths, masses)
