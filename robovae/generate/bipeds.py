"""Two-legged stance: soles under point feet, ankles strong enough for their soles and the
centre of mass over them.

Three named rules that the writer runs after the rules of :mod:`robovae.generate.stance`, on
the compiled robot at ``qpos0`` (``stance=True``): ``foot_soles`` first (it adds geoms; the
robot is compiled again), then ``strong_ankles`` (it changes only motor gears), then
``balance_home``; each reported per robot when it changes something, all from the robot's
geometry, masses and motors at rest, never a simulation. Their *two legs*
(:func:`two_legs`): the robot's support points (:func:`~robovae.generate.stance.support_points`)
belong to exactly two limbs of the root body, each with a hinge at or above its foot whose axis
lies within 45° of the *lateral* axis (from one foot's support points to the other's): its
*ankle*.

``foot_soles``
    A decoded biped often ends its legs in points or edges: rods, toes standing on end. Its
    support then has almost no sagittal extent and, held at rest, it topples forwards or
    backwards: of the first 80 fallen two-limbed robots of 10,000 samples, 71 fell even with
    their joints held at unlimited torque, their support's sagittal extent a median 0.05 of
    their centre of mass' height (standing ones: 0.19 at the 10th percentile). When that
    extent is below :data:`MIN_SOLE` times the height ``h`` of the centre of mass above the
    support, the centre of mass projects outside it (sagittally, at ``qpos0``; the
    procedural bipeds with such short feet, 19 of 80 bipeds and humanoids, have it inside by
    0.02 to 0.07 ``h``), and the robot is a biped (:func:`~robovae.generate.stance.biped` within
    :data:`SOLE_BIPED_TOL`: no third limb near the floor), each foot (its leg's deepest support
    body) gets a thin flat box under it at the level of the lowest point: sagittally from its
    own support points to ``a = SOLE_MARGIN · h`` beyond the centre of mass' projection ``s_c``
    on both sides (``[min(s_lo, s_c - a), max(s_hi, s_c + a)]``), laterally as wide as the
    foot's support points (at least ``SOLE_WIDTH · h``), ``SOLE_THICKNESS · h`` thick, with the
    contact settings, friction and colour of the foot's lowest geom. Inertials are explicit,
    so the masses do not change. The procedural bipeds and humanoids stand on soles and do not
    fire it (written from the ``kinematic`` or ``full`` features; ``paper34`` has no foot
    geometry, and every procedural biped written from it fires it).

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
    biped,
    candidate_points,
    root_limb,
    support_points,
)

__all__ = ["BALANCED", "MAX_ANKLE", "MIN_SOLE", "SOLE_BIPED_TOL", "SOLE_MARGIN", "SOLE_THICKNESS",
           "SOLE_WIDTH", "TwoLegs", "balance_home", "foot_soles", "strong_ankles", "two_legs"]

#: ``balance_home`` leaves a centre of mass inside this middle share of the soles' extent.
BALANCED = 0.5
#: ``foot_soles`` fires when the support's sagittal extent is below this share of the centre
#: of mass' height (the standing samples' 10th percentile is 0.19, the fallen's median 0.05).
MIN_SOLE = 0.15
#: ``foot_soles``: no third limb within this share of the robot's size of its lowest point
#: (of 2,000 samples, 0.05 gave soles to 152 robots, 62 of them fallen and then standing, 81
#: standing already; :data:`~robovae.generate.stance.BIPED_TOL`, 0.10: 86, 32 and 46).
SOLE_BIPED_TOL = 0.05
#: A sole reaches this share of the centre of mass' height beyond its projection, both ways.
SOLE_MARGIN = 0.1
#: A sole's least width and its thickness, as shares of the centre of mass' height.
SOLE_WIDTH = 0.05
SOLE_THICKNESS = 0.02
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
    geoms: np.ndarray  # [P]: the geom of each support point


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
                   feet, owner)


def _floating_legs(model: mujoco.MjModel, root: int, data: mujoco.MjData | None,
                   points: Points | None, legs: TwoLegs | None
                   ) -> tuple[mujoco.MjData, TwoLegs] | None:
    """``(data, legs)`` of a free-floating ``root`` on two legs (``data`` at ``qpos0``, made
    when not given; ``legs`` :func:`two_legs`, computed when not given), else None: what
    :func:`foot_soles` and :func:`strong_ankles` start from."""
    if model.body_jntnum[root] < 1 or model.jnt_type[model.body_jntadr[root]] != _FREE:
        return None
    data = at_qpos0(model, data)
    two = legs or two_legs(model, data, root, points)
    return None if two is None else (data, two)


def foot_soles(spec: mujoco.MjSpec, model: mujoco.MjModel, root: int,
               data: mujoco.MjData | None = None, points: Points | None = None,
               legs: TwoLegs | None = None) -> bool:
    """Add a sole under each foot of a two-legged free-floating robot whose support is a
    point or an edge (``foot_soles``, module docstring) to ``spec``. ``model``: ``spec``
    compiled; ``data``: its kinematics at ``qpos0`` (made here when not given; its
    ``subtree_com`` is computed); ``points``: :func:`candidate_points` at that pose;
    ``legs``: :func:`two_legs` at it. Returns whether soles were added (``model`` is then out
    of date)."""
    found = _floating_legs(model, root, data, points, legs)
    if found is None:
        return False
    data, two = found
    mujoco.mj_comPos(model, data)
    pts, sag, lat = two.points, two.sagittal, two.lateral
    low = float(pts[:, 2].min())
    h = float(data.subtree_com[root][2]) - low
    s, s_com = pts @ sag, float(data.subtree_com[root] @ sag)
    if h <= 0 or float(s.max() - s.min()) >= MIN_SOLE * h or s.min() <= s_com <= s.max():
        return False
    points = candidate_points(model, data) if points is None else points
    if not biped(model, data, root, points, SOLE_BIPED_TOL):  # last: the dearest test
        return False
    a, t = SOLE_MARGIN * h, SOLE_THICKNESS * h
    frame = np.stack([sag, lat, [0.0, 0.0, 1.0]], axis=1)  # sole axes in the world
    for leg, foot in zip(two.legs, two.feet):
        mine = two.leg_of == leg
        sl, ll = pts[mine] @ sag, pts[mine] @ lat
        lo, hi = min(float(sl.min()), s_com - a), max(float(sl.max()), s_com + a)
        width = max(float(ll.max() - ll.min()), SOLE_WIDTH * h)
        centre = 0.5 * (lo + hi) * sag + float(ll.mean()) * lat
        centre[2] = low + 0.5 * t
        rot = data.xmat[foot].reshape(3, 3)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (rot.T @ frame).ravel())
        like = spec.geom(model.geom(int(two.geoms[mine][np.argmin(pts[mine, 2])])).name)
        sole = spec.body(model.body(foot).name).add_geom(
            name=f"{model.body(foot).name}_sole", type=mujoco.mjtGeom.mjGEOM_BOX,
            size=mjcf_round_vector(np.array([0.5 * (hi - lo), 0.5 * width, 0.5 * t])),
            pos=mjcf_round_vector(rot.T @ (centre - data.xpos[foot])),
            quat=mjcf_round_vector(quat), rgba=like.rgba, friction=like.friction)
        sole.contype, sole.conaffinity = like.contype, like.conaffinity
        sole.condim, sole.group = like.condim, like.group
    return True


def strong_ankles(spec: mujoco.MjSpec, model: mujoco.MjModel, root: int,
                  data: mujoco.MjData | None = None, points: Points | None = None,
                  legs: TwoLegs | None = None) -> bool:
    """Give each ankle of a two-legged free-floating robot at least the strength that holds half
    the robot's weight at its sole's edge (``strong_ankles``, module docstring): the gear of
    its motor in ``spec`` is scaled up (a DC motor stays one). ``model``: ``spec`` compiled;
    ``data``: its kinematics at ``qpos0`` (made here when not given); ``points``:
    :func:`candidate_points` at that pose; ``legs``: :func:`two_legs` at it. Returns whether an
    ankle was made stronger."""
    found = _floating_legs(model, root, data, points, legs)
    if found is None:
        return False
    data, two = found
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
