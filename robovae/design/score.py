"""Task scores of a robot file in MuJoCo: the objective of :mod:`robovae.design.optimize`.

One interface, :func:`score_robot` ``(path, task, seed) -> dict`` with at least ``score`` (a
finite float, higher is better, 0 for a robot that cannot do the task) and ``error`` (None or a
one-line reason). Every measure is deterministic for a file and ``seed``. (The sample-quality
measures being written in :mod:`robovae.evaluate` can replace these behind the same interface.)

- **walk** (:func:`walk_score`): the best open-loop sinusoidal gait found by a fixed, seeded
  random search of ``trials`` gaits (8). The robot is put in the ``robovae/Walk-v0`` scene
  (:func:`robovae.envs.walk.walk_scene`: floor, free base). A gait drives actuator ``j`` with
  the normalised action ``a_j(t) = A_j sin(2 pi f t + phi_j)`` (scaled to the control range as
  in the environment), with ``f ~ U[0.5, 3] Hz``, ``A_j = A u_j`` (a gait amplitude ``A``
  log-uniform in ``[0.1, 1]``, ``u_j ~ U[0.5, 1]``) and ``phi_j ~ U[0, 2 pi)``.
  It runs ``seconds`` (3 s); its speed is the root's horizontal displacement between
  ``settle`` (1 s) and the end, divided by that time and by the robot's **extent** ``L`` (the
  diagonal of its bounding box at ``qpos0``, m): body lengths per second, so that size alone
  does not win. When the robot **falls** — its root's up axis (the local direction that points
  up at ``qpos0``) tilts more than ``max_tilt`` (60°) from vertical at a 10 ms sample, the
  bound of ``robovae/Walk-v0``'s health — the displacement stops counting there (tumbling is
  not walking) but the time still runs to the end: falling early costs. A rollout that
  diverges (non-finite state or a MuJoCo instability warning) scores 0. ``score`` is the best
  gait's speed; ``speed`` is the same in m/s.
- **stand** (:func:`stand_score`): :func:`robovae.evaluate.behaviour.standing_test` for 3 s
  (joints PD-held at ``qpos0`` with the robot's own torque limits); ``score`` is the lowest
  root height over the test as a fraction of its height at ``qpos0`` (``min_height_ratio``),
  0 when unstable or not floating.
- **reach** (:func:`reach_score`): for a fixed-base arm, the volume of the convex hull of the
  end-effector positions over ``samples`` (512) joint configurations drawn uniformly within
  the joint ranges (unlimited hinges: ``[-pi, pi]``; free joints stay at ``qpos0``), divided by
  ``L^3``. The end effector is the centre of mass of the deepest body of the robot's tree
  (first in depth-first order on ties; its frame origin sits on its own joint, which would
  not move it). Forward kinematics only (no dynamics).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings

__all__ = ["SCORE_VERSION", "TASKS", "reach_score", "score_robot", "stand_score", "walk_score"]

#: Changes whenever a measure changes: an optimisation log of another version is not continued.
SCORE_VERSION = 2

_BAD = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
        mujoco.mjtWarning.mjWARN_BADQVEL)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_BALL = int(mujoco.mjtJoint.mjJNT_BALL)


def _rollout(model: mujoco.MjModel, lo: np.ndarray, hi: np.ndarray, root: int, freq: float,
             amp: np.ndarray, phase: np.ndarray, seconds: float, settle: float,
             cos_tilt: float) -> float:
    """Horizontal root displacement (m) between ``settle`` and ``seconds`` of one gait, or
    until the root tilts more than ``acos(cos_tilt)`` from its initial up axis (checked every
    10 ms; 0 when that happens before ``settle``); NaN when the simulation diverges."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    up_local = data.xmat[root].reshape(3, 3).T @ np.array([0.0, 0.0, 1.0])
    dt = model.opt.timestep
    steps, start = int(round(seconds / dt)), int(round(settle / dt))
    every = max(1, int(round(0.01 / dt)))
    p0 = data.xpos[root, :2].copy()
    for t in range(steps):
        a = amp * np.sin(2.0 * math.pi * freq * t * dt + phase)
        data.ctrl[:] = lo + 0.5 * (a + 1.0) * (hi - lo)
        mujoco.mj_step(model, data)
        if t + 1 == start:
            p0 = data.xpos[root, :2].copy()
        if (t + 1) % every == 0 and (data.xmat[root].reshape(3, 3) @ up_local)[2] < cos_tilt:
            break  # fallen: what it walked before counts, the tumbling after does not
    if t + 1 <= start:
        p0 = data.xpos[root, :2].copy()
    if any(data.warning[w].number for w in _BAD) or not np.isfinite(data.qpos).all():
        return math.nan
    return float(np.linalg.norm(data.xpos[root, :2] - p0))


def walk_score(path: str | os.PathLike, seed: int = 0, trials: int = 8, seconds: float = 3.0,
               settle: float = 1.0, max_tilt: float = 60.0) -> dict:
    """Best open-loop gait speed in body lengths per second (module docstring)."""
    from robovae.envs.walk import walk_scene

    _, scene = walk_scene(path)
    model = scene.model
    lo, hi = model.actuator_ctrlrange.T.copy()
    unlimited = model.actuator_ctrllimited == 0
    lo[unlimited], hi[unlimited] = -1.0, 1.0
    rng = np.random.default_rng(seed)
    best, best_gait = 0.0, None
    with capture_mujoco_warnings():
        for _ in range(trials):
            freq = float(rng.uniform(0.5, 3.0))
            amp = math.exp(rng.uniform(math.log(0.1), 0.0)) * rng.uniform(0.5, 1.0, model.nu)
            phase = rng.uniform(0.0, 2.0 * math.pi, model.nu)
            d = _rollout(model, lo, hi, scene.root, freq, amp, phase, seconds, settle,
                         math.cos(math.radians(max_tilt)))
            speed = d / (seconds - settle) if math.isfinite(d) else 0.0
            if speed > best:
                best, best_gait = speed, freq
    return {"score": best / scene.size, "speed": best, "extent": scene.size,
            "frequency": best_gait}


def stand_score(path: str | os.PathLike, seed: int = 0, seconds: float = 3.0) -> dict:
    """Lowest root height kept over a 3 s PD-held standing test (module docstring)."""
    from robovae.evaluate.behaviour import standing_test

    res = standing_test(path, seconds=seconds)
    ratio = res.get("min_height_ratio")
    ok = res["floating"] and not res["unstable"] and ratio is not None and math.isfinite(ratio)
    return {"score": max(0.0, float(ratio)) if ok else 0.0, "stands": res["stands"],
            "floating": res["floating"]}


def _deepest_body(model: mujoco.MjModel) -> int:
    depth = np.zeros(model.nbody, dtype=int)
    for b in range(1, model.nbody):
        depth[b] = depth[model.body_parentid[b]] + 1
    return int(np.argmax(depth))


def reach_score(path: str | os.PathLike, seed: int = 0, samples: int = 512) -> dict:
    """End-effector workspace volume over ``L^3`` of a fixed-base arm (module docstring)."""
    from scipy.spatial import ConvexHull, QhullError

    from robovae.data.loading import load_robot
    from robovae.evaluate.camera import robot_bounds

    model = load_robot(path).model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    lo_b, hi_b = robot_bounds(model, data)
    size = max(float(np.linalg.norm(hi_b - lo_b)), 1e-6)
    joints = [j for j in range(model.njnt) if model.jnt_type[j] not in (_FREE, _BALL)]
    if not joints:
        return {"score": 0.0, "volume": 0.0, "extent": size, "error": "no joints to reach with"}
    rng = np.random.default_rng(seed)
    ee = _deepest_body(model)
    points = np.empty((samples, 3))
    for k in range(samples):
        data.qpos[:] = model.qpos0
        for j in joints:
            lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-math.pi, math.pi)
            data.qpos[model.jnt_qposadr[j]] = rng.uniform(lo, hi)
        mujoco.mj_kinematics(model, data)
        points[k] = data.xipos[ee]
    try:
        volume = float(ConvexHull(points).volume)
    except (QhullError, ValueError):  # planar or degenerate workspace
        volume = 0.0
    return {"score": volume / size ** 3, "volume": volume, "extent": size}


#: Task name → scorer ``(path, seed) -> dict``.
TASKS: dict[str, Callable[..., dict]] = {"walk": walk_score, "stand": stand_score,
                                         "reach": reach_score}


def score_robot(path: str | os.PathLike, task: str, seed: int = 0) -> dict:
    """``TASKS[task](path, seed)``; a robot the task cannot use (a file that does not load, no
    actuators, a failing measure) scores 0 with ``error`` set to one line. Never raises for a
    bad robot; raises ``KeyError`` for an unknown task."""
    fn = TASKS[task]
    try:
        out = fn(Path(path), seed=seed)
    except Exception as e:  # a bad candidate is a zero, not a crash of the optimisation
        return {"score": 0.0, "error": " ".join(f"{type(e).__name__}: {e}".split())[:300]}
    out.setdefault("error", None)
    if not math.isfinite(out["score"]):
        out.update(score=0.0, error="non-finite score")
    return out
