"""Two-legged stance: ankles strong enough for their soles and the centre of mass over them.

Two named rules that the writer runs after the rules of :mod:`robovae.generate.stance`, on the
same compiled robot at ``qpos0`` (``stance=True``), ``strong_ankles`` first (it changes only
motor gears), then ``balance_home``; both reported per robot when they change something, both
from the robot's geometry, masses and motors at rest, never a simulation. Their *two legs*
(:func:`two_legs`): the robot's support points (:func:`~robovae.generate.stance.support_points`)
belong to exactly two limbs of the root body, each with a hinge at or above its foot whose axis
lies within 45° of the *lateral* axis (from one foot's support points to the other's): its
*ankle*.

``balance_home``
    A robot on two legs gets a ``home`` keyframe in which its centre of mass lies over the
    middle of its soles: the *ankle strategy*. Both ankles turn by ``θ`` (each signed by its
    axis' direction along the lateral axis) and the whole robot turns back about the first
    foot, so that the feet keep their place on the floor and the body leans over them; ``θ``
    is found by bisection in ``[-MAX_ANKLE, MAX_ANKLE]`` (and the ankles' joint ranges) so
    that the centre of mass projects, along the sagittal axis (the
    horizontal normal of the lateral one), onto the middle ``m`` of the support points'
    sagittal extent ``[s_lo, s_hi]``. It fires only when, at ``qpos0``, the centre of mass lies
    outside the middle :data:`BALANCED` share of that extent (``|s_com - m| > BALANCED ·
    (s_hi - s_lo) / 2``) and a ``θ`` that centres it exists; the keyframe's lowest point is
    kept at ``qpos0``'s. A robot that already has a ``home`` keyframe is left alone.

``strong_ankles``
    On the two legs, an ankle motor weaker than ``(m g / 2) · h`` (half the
    robot's weight ``m g`` at ``h``, half the sagittal extent of its leg's support points: the
    torque that puts the centre of pressure on the sole's edge, the most a foot can use) gets
    that strength, its gear scaled up (a DC motor keeps its no-load speed). A decoded biped's
    ankle can be far weaker than its other joints, and held by its own motors the robot then
    falls on its face. The procedural bipeds' ankles all pass (1.7 to 3.3 times the bound, 5th
    percentile to median); an ankle without a motor is left.

The quality measures and ``robovae/Walk-v0`` start a robot at its ``home`` keyframe
(:func:`robovae.evaluate.quality.stage.rest_pose`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numpy as np

from robovae.data.actuators import joint_strength, speed_limited
from robovae.generate.mjcf_numbers import mjcf_round, mjcf_round_vector
from robovae.generate.stance import (
    Points,
    at_qpos0,
    candidate_points,
    root_limb,
    support_points,
)

__all__ = ["BALANCED", "MAX_ANKLE", "TwoLegs", "balance_home", "strong_ankles", "two_legs"]

#: ``balance_home`` leaves a centre of mass inside this middle share of the soles' extent.
BALANCED = 0.5
#: Largest ankle turn (rad) of ``balance_home``.
MAX_ANKLE = 0.6
#: A hinge is an ankle when its axis is within 45° of the lateral axis.
_ANKLE_COS = math.cos(math.radians(45.0))
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)


def _depth(model: mujoco.MjModel, body: int) -> int:
    k = 0
    while body:
        body, k = int(model.body_parentid[body]), k + 1
    return k


def _ankle(model: mujoco.MjModel, data: mujoco.MjData, foot: int, root: int,
           lateral: np.ndarray) -> int | None:
    """The first hinge at or above ``foot`` (below ``root``) whose axis lies within 45° of
    ``lateral``."""
    body = foot
    while body not in (root, 0):
        first = model.body_jntadr[body]
        for j in range(first, first + model.body_jntnum[body]):
            if model.jnt_type[j] == _HINGE and abs(float(data.xaxis[j] @ lateral)) >= _ANKLE_COS:
                return j
        body = int(model.body_parentid[body])
    return None


class TwoLegs(NamedTuple):
    """The two legs of a two-legged robot at rest (:func:`two_legs`)."""

    points: np.ndarray  # support points [P, 3]
    leg_of: np.ndarray  # [P]: the root's child (leg) each point belongs to
    legs: list[int]
    lateral: np.ndarray  # unit, horizontal, from the first foot to the second
    sagittal: np.ndarray  # unit, horizontal, normal to lateral
    ankles: list[int]  # per leg, its ankle hinge (:func:`_ankle`)
    feet: list[int]  # per leg, its deepest support body


def two_legs(model: mujoco.MjModel, data: mujoco.MjData, root: int,
             points: Points | None = None) -> TwoLegs | None:
    """The two legs of ``balance_home`` and ``strong_ankles`` (module docstring), at ``data``'s
    pose; None when the support points do not lie on exactly two limbs of ``root`` each with an
    ankle."""
    pts, owner, _ = support_points(model, data, points=points)
    limbs = np.array([root_limb(model, int(model.geom_bodyid[g]), root) for g in owner])
    legs = sorted(set(limbs.tolist()))
    if len(legs) != 2 or root in legs:
        return None
    centres = [pts[limbs == leg, :2].mean(0) for leg in legs]
    lateral = np.array([*(centres[1] - centres[0]), 0.0])
    if np.linalg.norm(lateral) < 1e-9:
        return None
    lateral /= np.linalg.norm(lateral)
    ankles, feet = [], []
    for leg in legs:
        on_leg = [int(model.geom_bodyid[g]) for g in owner[limbs == leg]]
        foot = max(on_leg, key=lambda b: (_depth(model, b), b))
        j = _ankle(model, data, foot, root, lateral)
        if j is None:
            return None
        ankles.append(j)
        feet.append(foot)
    return TwoLegs(pts, limbs, legs, lateral, np.array([-lateral[1], lateral[0], 0.0]), ankles,
                   feet)


def strong_ankles(spec: mujoco.MjSpec, model: mujoco.MjModel, root: int,
                  data: mujoco.MjData | None = None, points: Points | None = None,
                  legs: TwoLegs | None = None) -> bool:
    """Give each ankle of a two-legged free-floating robot at least the strength that holds half
    the robot's weight at its sole's edge (``strong_ankles``, module docstring): the gear of
    its motor in ``spec`` is scaled up (a DC motor stays one). ``model``: ``spec`` compiled;
    ``data``: its kinematics at ``qpos0`` (made here when not given); ``points``:
    :func:`candidate_points` at that pose; ``legs``: :func:`two_legs` at it. Returns whether an
    ankle was made stronger."""
    if model.body_jntnum[root] < 1 or model.jnt_type[model.body_jntadr[root]] != _FREE:
        return False
    data = at_qpos0(model, data)
    two = legs or two_legs(model, data, root, points)
    if two is None:
        return False
    strength = joint_strength(model)
    weight = float(model.body_subtreemass[root]) * float(np.linalg.norm(model.opt.gravity))
    fired = False
    for leg, j in zip(two.legs, two.ankles):
        s = two.points[two.leg_of == leg] @ two.sagittal
        need = 0.5 * weight * 0.5 * float(s.max() - s.min())
        if not 0.0 < strength[j] < need:  # no motor to strengthen, or strong enough
            continue
        name = model.joint(j).name
        for act in spec.actuators:
            if act.trntype == mujoco.mjtTrn.mjTRN_JOINT and act.target == name:
                gear = mjcf_round(float(act.gear[0]) * need / strength[j])
                act.gear = [gear] + [0.0] * 5
                if act.biastype == mujoco.mjtBias.mjBIAS_AFFINE:  # a DC motor's speed line
                    speed_limited(act, gear)
                fired = True
    return fired


def balance_home(spec: mujoco.MjSpec, model: mujoco.MjModel, root: int, lift: float = 0.0,
                 data: mujoco.MjData | None = None, points: Points | None = None,
                 legs: TwoLegs | None = None) -> bool:
    """Add the ``home`` keyframe of the ankle strategy to ``spec`` (``balance_home``, module
    docstring; ``model``: ``spec`` compiled, ``root``: the free-floating root body). ``lift``:
    added to the root's height in the keyframe (the floor placement's shift of the root, which
    ``model`` does not have yet); ``data``: ``model``'s kinematics at ``qpos0`` (made here when
    not given; its pose is changed; ``points``: :func:`candidate_points` at ``qpos0``). Returns
    whether a keyframe was added."""
    if any(k.name == "home" for k in spec.keys) or model.body_jntnum[root] < 1:
        return False
    free = int(model.body_jntadr[root])
    if model.jnt_type[free] != _FREE:
        return False
    data = at_qpos0(model, data)
    two = legs or two_legs(model, data, root, points)
    if two is None:
        return False
    pts, lateral, sagittal = two.points, two.lateral, two.sagittal
    s = pts @ sagittal
    mid, half = 0.5 * (s.max() + s.min()), 0.5 * (s.max() - s.min())
    ankles = [(int(model.jnt_qposadr[j]), float(np.sign(data.xaxis[j] @ lateral)), j)
              for j in two.ankles]
    feet = two.feet
    lo, hi = -MAX_ANKLE, MAX_ANKLE
    for adr, sign, j in ankles:  # keep every ankle inside its range
        if model.jnt_limited[j]:
            a, b = sorted(((model.jnt_range[j] - model.qpos0[adr]) / sign).tolist())
            lo, hi = max(lo, a), min(hi, b)
    qadr = int(model.jnt_qposadr[free])
    q0 = model.qpos0.copy()
    foot = feet[0]
    foot_pos, foot_rot = data.xpos[foot].copy(), data.xmat[foot].reshape(3, 3).copy()
    low0 = float(pts[:, 2].min())  # the support points hold the lowest point

    def pose(theta: float, placed: bool = False) -> tuple[np.ndarray, float]:
        """The keyframe at ankle turn ``theta`` (``placed``: its lowest point put back at the
        height it had at rest) and its centre of mass' sagittal offset, which a vertical shift
        does not change (the bisection leaves the placement to the last pose)."""
        q = q0.copy()
        for adr, sign, _ in ankles:
            q[adr] += sign * theta
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        turn = foot_rot @ data.xmat[foot].reshape(3, 3).T  # puts the first foot back
        q[qadr:qadr + 3] = turn @ (data.xpos[root] - data.xpos[foot]) + foot_pos
        mujoco.mju_mat2Quat(q[qadr + 3:qadr + 7], (turn @ data.xmat[root].reshape(3, 3)).ravel())
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        if placed:
            q[qadr + 2] += low0 - float(candidate_points(model, data)[0][:, 2].min())
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        return q, float(data.subtree_com[root] @ sagittal) - mid

    _, off = pose(0.0)
    if abs(off) <= BALANCED * half or lo >= hi:
        return False
    f_lo, f_hi = pose(lo)[1], pose(hi)[1]
    if f_lo * f_hi > 0:
        return False
    for _ in range(30):
        c = 0.5 * (lo + hi)
        f_c = pose(c)[1]
        if f_lo * f_c <= 0:
            hi, f_hi = c, f_c
        else:
            lo, f_lo = c, f_c
    q, _ = pose(0.5 * (lo + hi), placed=True)
    q[qadr + 2] += lift
    spec.add_key(name="home", qpos=mjcf_round_vector(q))
    return True
