"""What a robot can do in MuJoCo without a task: random-actuation state entropy and a standing
test (paper §2.3 and §6.3).

**State entropy** (:func:`state_entropy`), after TAME (Hejna et al., 2021), which scores a
morphology by how much of the state space random actions reach. The robot is put on a floor
(a plane at its lowest point when the file has none) and driven by ``rollouts`` independent
episodes of ``seconds`` seconds from its initial pose ``qpos0``. Each episode draws a control
vector uniformly from the actuators' ``ctrlrange`` (``[-1, 1]`` when unlimited) every ``hold``
seconds and keeps it in between (zero-order hold: white noise at the physics rate would average
out before the body moves). Every ``sample_dt`` seconds (``t > 0``) the state is recorded;
states of all episodes are pooled and their differential entropy is estimated with the
Kozachenko–Leonenko k-nearest-neighbour estimator (:func:`robovae.evaluate.population.knn_entropy`,
``k = 3``):

- ``root_entropy``: entropy (nats) of the root body's world position (metres); coordinates that
  never change (planar robots) are left out and ``root_dims`` says how many remain;
- ``root_entropy_scaled``: the same for positions divided by the robot's size ``L`` (the
  diagonal of its bounding box at ``qpos0``), ``root_entropy - root_dims · log L``: robots of
  different sizes compare;
- ``joint_entropy``: the mean over hinge and slide joints of the 1-D entropy of the joint
  position (nats per joint; radians or metres): how widely each joint is swept.

The estimates are biased for small samples (``rollouts · seconds / sample_dt`` points), in the
same way for every robot measured with the same settings; compare robots, not absolute values.

**Standing test** (:func:`standing_test`), for floating-base robots (root body with a free
joint). The robot's actuators are replaced (through ``mujoco.MjSpec``) by one position actuator
per hinge/slide joint holding the joint at its ``qpos0`` value, with stiffness
``kp = stiffness · m g L`` (total mass ``m``, size ``L``: the base sags about ``1/stiffness``
rad under its full weight on a lever of its own size), capped at ``0.1 I / dt²`` (``I`` the
joint's inertia at ``qpos0``, ``dt`` the time step: the explicit spring stays stable), critical
damping (``dampratio = 1``) and, with ``torque_limits``, the torque limit of the robot's own
actuator on that joint (``|gear · gain| · max|ctrlrange|`` for a motor-like actuator whose
force is ``gain · ctrl``, and ``|gear| · max|forcerange|``; unlimited when the joint has
neither, e.g. a position servo without ``forcerange``). The integrator is ``implicitfast`` so
the damping is implicit. After
``seconds`` (2 s) on the floor the robot **stands** when, at every sample, its base stayed
**up** — base height above the floor at least ``min_height`` (0.6) of its height above its own
lowest point at ``qpos0`` — and **upright** — the base's up axis (the local direction that
points up at ``qpos0``) within ``max_tilt`` (30°) of vertical.
"""

from __future__ import annotations

import math
import multiprocessing
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings, load_robot
from robovae.data.mjcf import robot_root
from robovae.evaluate.population import knn_entropy

# plain ints: MjModel arrays hold ints, which do not compare equal to the pybind enums
_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
_HFIELD = int(mujoco.mjtGeom.mjGEOM_HFIELD)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_TRN_JOINT = int(mujoco.mjtTrn.mjTRN_JOINT)
_GAIN_FIXED = int(mujoco.mjtGain.mjGAIN_FIXED)
_BIAS_NONE = int(mujoco.mjtBias.mjBIAS_NONE)
_DYN_INTEGRATOR = int(mujoco.mjtDyn.mjDYN_INTEGRATOR)
_BAD = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
        mujoco.mjtWarning.mjWARN_BADQVEL)

Robot = str | os.PathLike | mujoco.MjSpec


@dataclass
class _Scene:
    model: mujoco.MjModel
    root: int  # root body id
    floor_z: float
    size: float  # bounding-box diagonal at qpos0
    free: bool  # the root body has a free joint


def _spec(robot: Robot) -> mujoco.MjSpec:
    if isinstance(robot, mujoco.MjSpec):
        return robot.copy()
    return load_robot(robot).spec  # missing meshes dropped; one-line RobotFileError otherwise


def _robot_points(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> np.ndarray:
    """World corners of the geom AABBs of the robot (the subtree of ``root``) and its bodies."""
    pts = [data.xpos[b] for b in range(1, model.nbody) if model.body_rootid[b] == root]
    for g in range(model.ngeom):
        b = model.geom_bodyid[g]
        if b == 0 or model.body_rootid[b] != root or model.geom_type[g] in (_PLANE, _HFIELD):
            continue
        center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        rot = data.geom_xmat[g].reshape(3, 3)
        for sx in (-1, 1):
            for sy in (-1, 1):
                for sz in (-1, 1):
                    pts.append(data.geom_xpos[g] + rot @ (center + half * [sx, sy, sz]))
    return np.array(pts)


def _has_floor(model: mujoco.MjModel) -> bool:
    world = model.geom_bodyid == 0
    return bool(np.any(world & np.isin(model.geom_type, (_PLANE, _HFIELD))))


def _floor_height(model: mujoco.MjModel, data: mujoco.MjData, lowest: float) -> float:
    """Height of the highest upward-facing world plane not above the robot's lowest point
    (walls and ceilings are planes too); ``lowest`` when there is none (a height field)."""
    z = [float(data.geom_xpos[g, 2]) for g in range(model.ngeom)
         if model.geom_bodyid[g] == 0 and model.geom_type[g] == _PLANE
         and data.geom_xmat[g, 8] > 0.99 and data.geom_xpos[g, 2] <= lowest + 1e-3]
    return max(z) if z else lowest


def prepare(robot: Robot, integrator: int | None = None) -> tuple[mujoco.MjSpec, _Scene]:
    """The robot's spec with a floor (added at its lowest point when it has none) and facts
    about it: root body, floor height, size, whether the root is free."""
    spec = _spec(robot)
    with capture_mujoco_warnings():
        model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    root, _ = robot_root(model)
    pts = _robot_points(model, data, root)
    lo, hi = pts.min(0), pts.max(0)
    if _has_floor(model):
        floor_z = _floor_height(model, data, float(lo[2]))
    else:
        floor_z = float(lo[2])
        spec.worldbody.add_geom(name="robovae_floor", type=_PLANE, size=[0, 0, 0.05],
                                pos=[0.0, 0.0, floor_z], condim=3)
    if integrator is not None:
        spec.option.integrator = integrator
    with capture_mujoco_warnings():
        model = spec.compile()
    free = bool(model.body_jntnum[root] >= 1 and model.jnt_type[model.body_jntadr[root]] == _FREE)
    size = float(np.linalg.norm(hi - lo))
    return spec, _Scene(model, root, floor_z, max(size, 1e-6), free)


def _finite(data: mujoco.MjData) -> bool:
    return bool(np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all())


def _unstable(data: mujoco.MjData) -> bool:
    return not _finite(data) or any(data.warning[w].number for w in _BAD)


def state_entropy(robot: Robot, seconds: float = 3.0, rollouts: int = 8, hold: float = 0.05,
                  sample_dt: float = 0.05, k: int = 3, seed: int = 0,
                  max_steps: int = 30_000) -> dict:
    """Random-actuation state entropy of a robot (module docstring).

    Args:
        robot: a robot file or ``mujoco.MjSpec``.
        seconds: length of each episode.
        rollouts: number of episodes.
        hold: seconds each random control is held.
        sample_dt: seconds between recorded states.
        k: neighbours of the entropy estimator.
        seed: seed of the random controls (episode ``r`` uses ``(seed, r)``).
        max_steps: physics steps allowed over all episodes: robots with tiny time steps
            (the fruit fly's 0.1 ms) get shorter episodes (``seconds`` in the result).

    Returns:
        ``root_entropy``, ``root_entropy_scaled``, ``root_dims``, ``joint_entropy``,
        ``joints``, ``points``, ``size`` (m), ``displacement`` (mean horizontal distance of
        the root from its start at the end of an episode, m), ``seconds`` (simulated per
        episode), ``unstable`` (episodes stopped by NaN or MuJoCo instability warnings),
        ``actuators``. Entropies are NaN for a robot without actuators.
    """
    spec, scene = prepare(robot)
    model = scene.model
    data = mujoco.MjData(model)
    dt = model.opt.timestep
    seconds = min(seconds, max_steps * dt / max(rollouts, 1))
    steps = max(1, round(seconds / dt))
    every_ctrl = max(1, round(hold / dt))
    every_rec = max(1, round(sample_dt / dt))
    lo = np.where(model.actuator_ctrllimited.astype(bool), model.actuator_ctrlrange[:, 0], -1.0)
    hi = np.where(model.actuator_ctrllimited.astype(bool), model.actuator_ctrlrange[:, 1], 1.0)
    joints = [j for j in range(model.njnt) if model.jnt_type[j] in _MOVING]
    qadr = np.array([model.jnt_qposadr[j] for j in joints], dtype=int)
    roots, qs, disp, unstable = [], [], [], 0
    out = {"actuators": int(model.nu), "joints": len(joints), "size": scene.size,
           "seconds": steps * dt}
    if model.nu == 0:
        nan = math.nan
        return {**out, "root_entropy": nan, "root_entropy_scaled": nan, "root_dims": 0,
                "joint_entropy": nan, "points": 0, "displacement": nan, "unstable": 0}
    with capture_mujoco_warnings():
        for r in range(rollouts):
            rng = np.random.default_rng([seed, r])
            mujoco.mj_resetData(model, data)
            mujoco.mj_forward(model, data)
            start = data.xpos[scene.root].copy()
            ep_root, ep_q = [], []
            ok = True
            for t in range(steps):
                if t % every_ctrl == 0:
                    data.ctrl[:] = rng.uniform(lo, hi)
                mujoco.mj_step(model, data)
                if _unstable(data):
                    ok = False
                    break
                if (t + 1) % every_rec == 0:
                    ep_root.append(data.xpos[scene.root].copy())
                    ep_q.append(data.qpos[qadr].copy())
            if not ok:
                unstable += 1
                continue
            roots += ep_root
            qs += ep_q
            disp.append(float(np.linalg.norm((data.xpos[scene.root] - start)[:2])))
    pos = np.array(roots).reshape(-1, 3)
    moving = pos.std(0) > 1e-9 if len(pos) else np.zeros(3, bool)
    dims = int(moving.sum())
    h_root = knn_entropy(pos[:, moving], k) if dims and len(pos) > 1 else math.nan
    q = np.array(qs).reshape(len(qs), len(joints))
    h_joint = (float(np.mean([knn_entropy(q[:, i], k) for i in range(q.shape[1])]))
               if len(q) > 1 and q.shape[1] else math.nan)
    return {**out, "root_entropy": h_root,
            "root_entropy_scaled": h_root - dims * math.log(scene.size),
            "root_dims": dims, "joint_entropy": h_joint, "points": len(pos),
            "displacement": float(np.mean(disp)) if disp else math.nan, "unstable": unstable}


def _torque_limits(model: mujoco.MjModel) -> dict[int, float]:
    """Largest torque the robot's own actuators can put on each joint (joint id → N·m or N)."""
    out: dict[int, float] = {}
    for a in range(model.nu):
        if model.actuator_trntype[a] != _TRN_JOINT:
            continue
        j = int(model.actuator_trnid[a, 0])
        gear = abs(float(model.actuator_gear[a, 0]))
        limit = math.inf
        # force = gain · (ctrl or act) only for a fixed gain without bias (motors); a servo's
        # force (kp · (ctrl - q) ...) is not bounded by its control range
        if model.actuator_gaintype[a] == _GAIN_FIXED and model.actuator_biastype[a] == _BIAS_NONE:
            gain = gear * abs(float(model.actuator_gainprm[a, 0]))
            if model.actuator_dyntype[a] == _DYN_INTEGRATOR:
                if model.actuator_actlimited[a]:
                    limit = gain * float(np.abs(model.actuator_actrange[a]).max())
            elif model.actuator_ctrllimited[a]:
                limit = gain * float(np.abs(model.actuator_ctrlrange[a]).max())
        if model.actuator_forcelimited[a]:  # forcerange clamps the force before the gear
            limit = min(limit, gear * float(np.abs(model.actuator_forcerange[a]).max()))
        out[j] = out.get(j, 0.0) + limit
    return out


def standing_test(robot: Robot, seconds: float = 2.0, stiffness: float = 10.0,
                  torque_limits: bool = True, min_height: float = 0.6, max_tilt: float = 30.0,
                  sample_dt: float = 0.02, max_steps: int = 5_000) -> dict:
    """Hold the joints at ``qpos0`` on a floor and see whether the robot stays up (module
    docstring).

    ``max_steps`` caps the physics steps (robots with tiny time steps are tested for less than
    ``seconds``: ``seconds`` in the result says how long).

    Returns:
        ``floating`` (False: not tested, every other value is None), ``stands``, ``up``,
        ``upright``, ``fell_at`` (s, first sample that failed, None when standing),
        ``height_ratio`` (final base height / height at ``qpos0``), ``min_height_ratio``,
        ``max_tilt`` (degrees), ``unstable`` (NaN or MuJoCo instability warnings),
        ``limited_joints`` (joints held with a torque limit), ``stand_seconds`` (simulated).
    """
    spec, scene = prepare(robot, integrator=mujoco.mjtIntegrator.mjINT_IMPLICITFAST)
    base = {"floating": scene.free, "stands": None, "up": None, "upright": None,
            "fell_at": None, "height_ratio": None, "min_height_ratio": None, "max_tilt": None,
            "unstable": None, "limited_joints": None, "stand_seconds": None}
    if not scene.free:
        return base
    model = scene.model
    limits = _torque_limits(model) if torque_limits else {}
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    mass = float(model.body_subtreemass[scene.root])
    g = float(np.linalg.norm(model.opt.gravity)) or 9.81
    dt = model.opt.timestep
    for a in list(spec.actuators):  # replaced by position actuators holding qpos0
        spec.delete(a)
    targets, limited = [], 0
    for j, js in enumerate(spec.joints):  # spec order is the compiled order
        if model.jnt_type[j] not in _MOVING:
            continue
        if not js.name:
            js.name = f"robovae_joint{j}"
        inertia = float(model.dof_M0[model.jnt_dofadr[j]])
        kp = min(stiffness * mass * g * scene.size, 0.1 * inertia / dt ** 2)
        act = spec.add_actuator(name=f"robovae_hold{j}", target=js.name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        # whatever the file's default class says: unlimited control, gear 1, no dynamics
        act.dyntype = mujoco.mjtDyn.mjDYN_NONE
        act.gear = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.actlimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.set_to_position(kp=kp, dampratio=1.0)
        lim = limits.get(j, math.inf)
        if math.isfinite(lim) and lim > 0:
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-lim, lim]
            limited += 1
        else:
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
        targets.append(float(model.qpos0[model.jnt_qposadr[j]]))
    with capture_mujoco_warnings():
        model = spec.compile()
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        root = scene.root
        pts = _robot_points(model, data, root)
        h0 = float(data.xpos[root, 2] - pts[:, 2].min())
        up_local = data.xmat[root].reshape(3, 3).T @ np.array([0.0, 0.0, 1.0])
        data.ctrl[:] = targets
        steps = min(max(1, round(seconds / dt)), max_steps)
        every = max(1, round(sample_dt / dt))
        fell_at, min_ratio, worst_tilt, ratio, tilt = None, math.inf, 0.0, math.nan, 0.0
        unstable = False
        for t in range(steps):
            mujoco.mj_step(model, data)
            if _unstable(data):
                unstable = True
                fell_at = fell_at if fell_at is not None else (t + 1) * dt
                break
            if (t + 1) % every and t + 1 != steps:
                continue
            ratio = float(data.xpos[root, 2] - scene.floor_z) / max(h0, 1e-9)
            up = data.xmat[root].reshape(3, 3) @ up_local
            tilt = math.degrees(math.acos(float(np.clip(up[2], -1.0, 1.0))))
            min_ratio, worst_tilt = min(min_ratio, ratio), max(worst_tilt, tilt)
            if fell_at is None and (ratio < min_height or tilt > max_tilt):
                fell_at = (t + 1) * dt
    return {**base, "stands": fell_at is None and not unstable,
            "up": bool(ratio >= min_height) and not unstable,
            "upright": bool(tilt <= max_tilt) and not unstable,
            "fell_at": fell_at, "height_ratio": ratio,
            "min_height_ratio": min_ratio if math.isfinite(min_ratio) else math.nan,
            "max_tilt": worst_tilt, "unstable": unstable, "limited_joints": limited,
            "stand_seconds": steps * dt}


def behaviour(robot: Robot, entropy: dict | None = None, standing: dict | None = None) -> dict:
    """:func:`state_entropy` and :func:`standing_test` of one robot (keyword arguments in
    ``entropy``/``standing``), as one flat dict; ``error`` holds a one-line message when the
    robot could not be measured."""
    out: dict = {"robot": str(robot) if not isinstance(robot, mujoco.MjSpec) else
                 robot.modelname}
    try:
        out.update(state_entropy(robot, **(entropy or {})))
        out.update(standing_test(robot, **(standing or {})))
    except Exception as e:  # a bad robot must not stop a population
        out["error"] = " ".join(f"{type(e).__name__}: {e}".split())
    return out


def _behaviour_item(item: tuple) -> dict:
    path, entropy, standing = item
    return behaviour(path, entropy, standing)


def behaviour_many(paths: Sequence[str | Path], jobs: int = 1, entropy: dict | None = None,
                   standing: dict | None = None) -> list[dict]:
    """:func:`behaviour` of many robot files, in ``jobs`` worker processes (``0``: all cores;
    started with ``spawn``, like generation's workers)."""
    items = [(str(p), entropy, standing) for p in paths]
    jobs = jobs or (os.cpu_count() or 1)
    if jobs <= 1 or len(items) < 2:
        return [_behaviour_item(it) for it in items]
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(min(jobs, len(items)), mp_context=ctx) as pool:
        return list(pool.map(_behaviour_item, items))


def summarize_behaviour(rows: Sequence[dict]) -> dict:
    """Population means of the entropies, and the standing rate among floating-base robots."""
    def mean(key: str) -> float:
        v = [r[key] for r in rows if isinstance(r.get(key), (int, float))
             and r.get(key) is not None and math.isfinite(r[key])]
        return float(np.mean(v)) if v else math.nan

    floating = [r for r in rows if r.get("floating")]
    stands = [r for r in floating if r.get("stands")]
    return {"robots": len(rows), "errors": sum(1 for r in rows if "error" in r),
            "root_entropy": mean("root_entropy"),
            "root_entropy_scaled": mean("root_entropy_scaled"),
            "joint_entropy": mean("joint_entropy"), "displacement": mean("displacement"),
            "floating": len(floating), "standing": len(stands),
            "standing_rate": len(stands) / len(floating) if floating else math.nan}


__all__ = ["behaviour", "behaviour_many", "prepare", "standing_test", "state_entropy",
           "summarize_behaviour"]
