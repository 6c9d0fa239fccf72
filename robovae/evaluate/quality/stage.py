"""A robot on a floor, ready for the quality measures: its compiled model, root body, floor
height and size.

:func:`stage` accepts a robot file, a ``mujoco.MjSpec`` or a compiled ``mujoco.MjModel``:

- a file or spec gets a floor (a plane at the robot's lowest point in its :func:`rest_pose`:
  its rest keyframe or ``qpos0``, joints clipped into their ranges) when it has none
  (:func:`prepare`, which also returns the spec with the floor);
- a model is used as it is: it must already have a floor (an upward world plane or height
  field), else :class:`~robovae.errors.RobovaeError` is raised;
- a :class:`Stage` is used as it is (its model copied when an integrator is asked for).

:func:`stage_compiled` gives what :func:`prepare` would from the spec and model the validator
compiled (:func:`robovae.generate.validate.check_robot`: floor at ``z = 0``), without loading the
file again.

**Size.** ``Stage.extent`` is the diagonal (m) of the axis-aligned box around the robot's geoms
(world-frame corners of their bounding boxes) and body origins in the rest pose. MuJoCo's
``stat.extent`` would be the natural choice but it includes world geoms and ``<statistic>``
overrides (the dm_control quadruped's floor makes it 85 m, gymnasium's ant sets 8 m), so the
robot's own box is used.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass
from typing import TypeAlias

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings, load_robot, quiet_forward, robot_root
from robovae.errors import RobovaeError

# plain ints: MjModel arrays hold ints, which do not compare equal to the pybind enums
PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
HFIELD = int(mujoco.mjtGeom.mjGEOM_HFIELD)
FREE = int(mujoco.mjtJoint.mjJNT_FREE)
MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
BAD_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
                mujoco.mjtWarning.mjWARN_BADQVEL)
_BAD = [int(w) for w in BAD_WARNINGS]

__all__ = ["FLOOR", "REST_KEYFRAMES", "Robot", "Stage", "compiled", "extent", "prepare",
           "rest_key", "rest_pose", "robot_points", "stage", "stage_compiled", "unstable"]

#: Keyframe names taken as a robot's rest pose (Menagerie's robots define ``home``).
REST_KEYFRAMES = ("home", "stand", "standing")
#: Name of the floor plane added to a robot without one.
FLOOR = "robovae_floor"


@dataclass
class Stage:
    """A compiled robot on a floor (module docstring)."""

    model: mujoco.MjModel
    root: int  # root body id (robovae.data.loading.robot_root)
    floor_z: float  # height of the floor under the robot, m
    extent: float  # diagonal of the robot's bounding box at qpos0, m
    free: bool  # the root body has a free joint
    data: mujoco.MjData  # model's, mj_forward at qpos0 (a measure that steps it restores it)


Robot: TypeAlias = str | os.PathLike | mujoco.MjSpec | mujoco.MjModel | Stage


def robot_points(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> np.ndarray:
    """``[P, 3]`` world corners of the geom AABBs of the robot (the subtree of ``root``, planes
    and height fields left out) and its body origins, at ``data``'s pose."""
    bodies = np.flatnonzero(model.body_rootid == root)
    bodies = bodies[bodies > 0]
    pts = [data.xpos[bodies]]
    g = np.flatnonzero((model.body_rootid[model.geom_bodyid] == root)
                       & (model.geom_bodyid > 0)
                       & ~np.isin(model.geom_type, (PLANE, HFIELD)))
    if len(g):
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        local = center[:, None, :] + half[:, None, :] * signs[None]  # [G, 8, 3]
        rot = data.geom_xmat[g].reshape(-1, 3, 3)
        pts.append((np.einsum("gij,gkj->gki", rot, local) + data.geom_xpos[g][:, None]
                    ).reshape(-1, 3))
    return np.concatenate(pts)


def compiled(robot: Robot) -> mujoco.MjModel:
    """The compiled model of a robot file, spec, model or stage (a model, or a stage's model,
    is returned as it is; no floor is added).

    Raises:
        RobotFileError: a file that does not load.
    """
    if isinstance(robot, Stage):
        return robot.model
    if isinstance(robot, mujoco.MjModel):
        return robot
    if isinstance(robot, mujoco.MjSpec):
        with capture_mujoco_warnings():
            return robot.copy().compile()
    return load_robot(robot).model


def extent(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> float:
    """Diagonal (m) of the robot's bounding box at ``data``'s pose (:func:`robot_points`;
    at least 1e-6)."""
    pts = robot_points(model, data, root)
    return max(float(np.linalg.norm(pts.max(0) - pts.min(0))), 1e-6)


def _has_floor(model: mujoco.MjModel) -> bool:
    world = model.geom_bodyid == 0
    return bool(np.any(world & np.isin(model.geom_type, (PLANE, HFIELD))))


def _floor_height(model: mujoco.MjModel, data: mujoco.MjData, lowest: float) -> float:
    """Height of the highest upward-facing world plane not above the robot's lowest point
    (walls and ceilings are planes too); ``lowest`` when there is none (a height field)."""
    z = data.geom_xpos[(model.geom_bodyid == 0) & (model.geom_type == PLANE)
                       & (data.geom_xmat[:, 8] > 0.99) & (data.geom_xpos[:, 2] <= lowest + 1e-3), 2]
    return float(z.max()) if z.size else lowest


_SIZES = ("nq", "nv", "nu", "na", "nbody", "njnt", "ngeom", "nsite", "ncam", "nlight",
          "nmocap", "neq", "ntendon", "nsensordata", "nuserdata", "nplugin", "nbuffer",
          "narena")


def _stage_of(model: mujoco.MjModel, data: mujoco.MjData | None = None) -> Stage:
    """The stage of a model with a floor; ``data``: an MjData to reuse when it was made for a
    model of the same sizes (allocating one costs more than the measures at rest)."""
    if data is None or any(getattr(data.model, k) != getattr(model, k) for k in _SIZES):
        data = mujoco.MjData(model)
    else:
        mujoco.mj_resetData(model, data)
    root, _ = robot_root(model)
    moved = _to_rest_pose(model, data)  # floor and size where the robot starts
    quiet_forward(model, data)
    pts = robot_points(model, data, root)
    if moved:  # the stage's data stays at qpos0
        mujoco.mj_resetData(model, data)
        quiet_forward(model, data)
    floor_z = _floor_height(model, data, float(pts[:, 2].min()))
    size = max(float(np.linalg.norm(pts.max(0) - pts.min(0))), 1e-6)  # extent()
    free = bool(model.body_jntnum[root] >= 1 and model.jnt_type[model.body_jntadr[root]] == FREE)
    return Stage(model, root, floor_z, size, free, data)


def prepare(robot: str | os.PathLike | mujoco.MjSpec, integrator: int | None = None
            ) -> tuple[mujoco.MjSpec, Stage]:
    """The robot's spec (a copy) with a floor (added at its lowest point, named :data:`FLOOR`,
    when it has none) and its :class:`Stage`.

    Raises:
        RobotFileError: the file does not load (one line).
    """
    if isinstance(robot, mujoco.MjSpec):
        spec = robot.copy()
        with capture_mujoco_warnings():
            model = spec.compile()
    else:
        loaded = load_robot(robot)
        spec, model = loaded.spec, loaded.model
    if not _has_floor(model):
        data = mujoco.MjData(model)
        _to_rest_pose(model, data)
        quiet_forward(model, data)
        lowest = float(robot_points(model, data, robot_root(model)[0])[:, 2].min())
        spec.worldbody.add_geom(name=FLOOR, type=mujoco.mjtGeom.mjGEOM_PLANE,
                                size=[0, 0, 0.05], pos=[0.0, 0.0, lowest], condim=3)
    if integrator is not None:
        spec.option.integrator = integrator
    with capture_mujoco_warnings():
        model = spec.compile()
    return spec, _stage_of(model)


def stage(robot: Robot, integrator: int | None = None) -> Stage:
    """The :class:`Stage` of a robot file, spec, model or stage (module docstring); a model is
    copied, never changed; a stage is returned as it is, or with a copy of its model using
    ``integrator``.

    Raises:
        RobovaeError: a model without a floor.
        RobotFileError: a file that does not load.
    """
    if isinstance(robot, Stage):
        if integrator is None:
            return robot
        model = copy.copy(robot.model)
        model.opt.integrator = integrator
        return Stage(model, robot.root, robot.floor_z, robot.extent, robot.free, robot.data)
    if isinstance(robot, mujoco.MjModel):
        if not _has_floor(robot):
            raise RobovaeError("robovae: model has no floor (pass the robot's file or MjSpec, "
                               "or compile it with a floor plane)")
        model = copy.copy(robot)
        if integrator is not None:
            model.opt.integrator = integrator
        return _stage_of(model)
    return prepare(robot, integrator)[1]


def stage_compiled(model: mujoco.MjModel, spec: mujoco.MjSpec, floor: mujoco.MjsGeom | None,
                   data: mujoco.MjData | None = None) -> Stage:
    """The :class:`Stage` that :func:`prepare` gives for a robot, from its spec already compiled
    into ``model`` with a floor (the validator's,
    :func:`robovae.generate.validate.check_robot`), without loading it again.

    ``floor``: the plane added to a robot that had no floor, at any height. It is moved to the
    robot's lowest point in its :func:`rest_pose`, where :func:`prepare` adds it,
    and the spec compiled once more (``spec`` is changed; ``model`` is not). ``None``: the
    floor is the robot's own and ``model`` is staged as it is (a copy). When other world geoms
    sit beside the added plane (a height field: :func:`prepare` would add no floor), the plane
    is deleted and the spec prepared from scratch. ``data``: ``model``'s data at ``qpos0``
    (made when None).
    """
    if floor is None:
        return stage(model)
    if np.count_nonzero(model.geom_bodyid == 0) != 1:
        spec.delete(floor)
        return prepare(spec)[1]
    fresh = data is None
    data = mujoco.MjData(model) if fresh else data
    if _to_rest_pose(model, data) or fresh:  # where prepare puts the floor
        mujoco.mj_kinematics(model, data)
    lowest = float(robot_points(model, data, robot_root(model)[0])[:, 2].min())
    floor.pos = [0.0, 0.0, lowest]
    floor.condim = 3  # as prepare adds it, whatever the file's default class says
    with capture_mujoco_warnings():
        return _stage_of(spec.compile(), data)


def rest_key(model: mujoco.MjModel) -> int:
    """Id of the robot's keyframe named in :data:`REST_KEYFRAMES` (the first found), else -1."""
    for name in REST_KEYFRAMES:
        k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, name)
        if k >= 0:
            return k
    return -1


def _to_rest_pose(model: mujoco.MjModel, data: mujoco.MjData) -> bool:
    """Set ``data.qpos`` to the robot's :func:`rest_pose`, where the standing test and the gait
    search start; returns whether that differs from ``qpos0`` (nothing is computed)."""
    q = rest_pose(model)
    data.qpos[:] = q
    return not np.array_equal(q, model.qpos0)


def rest_pose(model: mujoco.MjModel) -> np.ndarray:
    """The robot's rest ``qpos``: its keyframe named in :data:`REST_KEYFRAMES` when it has one
    (real robots' ``qpos0`` is often outside their joint ranges: Go2's knees), else
    ``qpos0``; hinge and slide positions clipped into their joint ranges."""
    k = rest_key(model)
    q = model.key_qpos[k].copy() if k >= 0 else model.qpos0.copy()
    j = np.flatnonzero(np.isin(model.jnt_type, MOVING) & (model.jnt_limited != 0))
    a = model.jnt_qposadr[j]
    q[a] = np.clip(q[a], model.jnt_range[j, 0], model.jnt_range[j, 1])
    return q


def unstable(data: mujoco.MjData) -> bool:
    """NaN/Inf state or a MuJoCo instability warning (bad qacc/qpos/qvel) since the last reset."""
    finite = np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()
    return not finite or bool(data.warning.number[_BAD].any())
