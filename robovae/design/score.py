"""Task scores of a robot file in MuJoCo: the objective of :mod:`robovae.design.optimize`.

One interface, :func:`score_robot` ``(path, task, seed) -> dict`` with at least ``score`` (a
finite float, higher is better, 0 for a robot that cannot do the task) and ``error`` (None or a
one-line reason). Every measure is deterministic for a file and ``seed``. (The sample-quality
measures being written in :mod:`robovae.evaluate` can replace these behind the same interface.)

- **walk** (:func:`walk_score`): the quality measure's gait search
  (:func:`robovae.evaluate.quality.locomotion.gait`, one sinusoidal-gait scorer for the
  project) with the optimiser's budget: ``trials`` (8) seeded random open-loop gaits of
  ``seconds`` (3 s) each, in the ``robovae/Walk-v0`` scene (:func:`robovae.envs.walk.walk_scene`:
  floor, free base). Gait ``j`` drives actuator ``a`` with ``c_a + h_a (B_a + A_a sin(2 pi f t
  + phi_a))`` clipped to its control range (``c_a``, ``h_a`` the middle and half-width of that
  range), ``A_a ~ U[0, 1]``, ``phi_a ~ U[0, 2 pi)``, ``f ~ U[0.5, 3] Hz``, the offset ``B_a ~
  U[-1, 1]`` on the actuators of unlimited hinges (wheels turn) and 0 on the others, from the
  robot's rest pose. Its speed is the
  root's horizontal displacement from ``settle`` (1 s) to the end, divided by that time and by
  the robot's **extent** ``L`` (the diagonal of its bounding box at ``qpos0``, m): body lengths
  per second, so that size alone does not win. When the robot **falls** — its root's up axis
  tilts more than ``max_tilt`` (60°, the bound of ``robovae/Walk-v0``'s health) from vertical
  at a 10 ms sample — the displacement stops counting there (tumbling is not walking) but the
  time still runs to the end: falling early costs. A rollout that diverges scores 0, and so
  does a robot whose root body is moved by its own motor (an actuated base). ``score``
  is the best gait's speed; ``speed`` is the same in m/s; ``power`` (W) the mean mechanical
  power that gait's actuators deliver while its distance counts, ``mass`` the robot's (kg).
  (The quality table's locomotion measure searches 64 gaits of 4 s and does not stop at
  falls.)
- **step** (:func:`step_score`): walk for a robot that must step: one with a motor on a hinge
  without limits (a wheel or a rotor:
  :func:`robovae.evaluate.quality.locomotion.continuous_actuators`), which could roll, scores
  0 (``error`` names it) without simulation; any other robot scores as for walk.
- **stand** (:func:`stand_score`): the standing test
  (:func:`robovae.evaluate.quality.standing.standing`) for 3 s (joints PD-held at their rest
  pose with the robot's own torque limits); ``score`` is the lowest root height over the test
  as a fraction of its height at rest (``min_height_ratio``), 0 when unstable or not floating.
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

from robovae.data.loading import quiet_forward
from robovae.errors import RobovaeError, check_seed
from robovae.evaluate.quality.locomotion import (
    GaitResult,
    GaitTrials,
    continuous_actuators,
    gait,
)
from robovae.settings import check_settings, integer

__all__ = ["GAIT_TASKS", "SCORE_VERSION", "TASKS", "reach_score", "score_robot", "stand_score",
           "step_score", "walk_gait", "walk_score", "Wheeled"]

#: Changes whenever a measure changes: an optimisation log of another version is not continued.
#: 3: the walk score is the quality measure's gait search (issue 22); 4: rollouts that fly
#: (centre of mass above half the extent over rest, ``locomotion.MAX_RISE``) score 0;
#: 5: robots with an actuated base (``locomotion.actuated_base``) score 0; 6: the actuators of
#: unlimited hinges get a constant offset in each gait (``locomotion.continuous_actuators``);
#: 7: the standing test (task stand) sleeps a robot at rest after its first second.
SCORE_VERSION = 7

_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_BALL = int(mujoco.mjtJoint.mjJNT_BALL)


#: The tasks scored by a gait (their best robots get a ``gait.json``).
GAIT_TASKS = ("walk", "step")


class Wheeled(ValueError):
    """A robot that could roll (a motor on a hinge without limits) given to task step."""


def _walk(path: str | os.PathLike, seed: int, trials: int, seconds: float, settle: float,
          max_tilt: float, step: bool = False, refine: int = 0, starts: int = 1,
          hold: int = 1, noise: float = 0.0) -> tuple[GaitResult, mujoco.MjModel]:
    from robovae.envs.walk import walk_scene

    _, scene = walk_scene(path)
    if step and continuous_actuators(scene.model).any():
        raise Wheeled("wheeled: a motor drives a hinge without limits (task step scores "
                      "robots that step, not roll)")
    if not refine:
        return gait(scene.model, rollouts=trials, seconds=seconds, seed=seed,
                    settle=settle / seconds, max_tilt=max_tilt), scene.model
    from robovae.evaluate.quality.gait_search import trials_search

    runs = GaitTrials(scene.model, seconds, settle / seconds, max_tilt=max_tilt, hold=hold)
    if starts > 1:
        runs.perturb(scene.qpos_idx, scene.qvel_idx, starts, noise, seed)
    return trials_search(runs, rollouts=trials, refine=refine, seed=seed), scene.model


def _record(g: GaitResult) -> dict:
    return {"score": g.speed, "speed": g.speed_m_s, "extent": g.extent,
            "frequency": g.frequency, "power": g.power, "mass": g.mass}


def walk_score(path: str | os.PathLike, seed: int = 0, trials: int = 8, seconds: float = 3.0,
               settle: float = 1.0, max_tilt: float = 60.0) -> dict:
    """Best open-loop gait speed in body lengths per second (module docstring): ``trials``
    gaits of ``seconds``, the first ``settle`` seconds not counted."""
    return _record(_walk(path, seed, trials, seconds, settle, max_tilt)[0])


def step_score(path: str | os.PathLike, seed: int = 0, trials: int = 8, seconds: float = 3.0,
               settle: float = 1.0, max_tilt: float = 60.0) -> dict:
    """:func:`walk_score` of a robot without a motor on a hinge without limits (module
    docstring).

    Raises:
        Wheeled: a wheeled robot (:func:`score_robot` makes it a 0 with that error).
    """
    return _record(_walk(path, seed, trials, seconds, settle, max_tilt, step=True)[0])


def walk_gait(path: str | os.PathLike, seed: int = 0, trials: int = 8, seconds: float = 3.0,
              settle: float = 1.0, max_tilt: float = 60.0, step: bool = False,
              refine: int = 0, starts: int = 1, hold: int = 1, noise: float = 0.05) -> dict:
    """The gait that gives :func:`walk_score` (same arguments) its score, as JSON-ready
    numbers: ``score``, ``speed``, ``extent``, ``power``, ``mass``, ``seconds``, ``settle``,
    ``max_tilt``, the ``score_seed``, ``wheeled`` (a motor drives a hinge without limits: the
    robot may roll rather than step), and the gait itself, ``frequency`` (Hz), ``amplitude``,
    ``phase`` and ``offset`` per actuator in the model's order (``actuators``: their names). In
    ``robovae/Walk-v0``'s normalised actions it is ``a(t) = clip(B + A sin(2 pi f t + phi), -1,
    1)`` (:class:`robovae.envs.gait.SinusoidGait`); a robot that scores 0 has no gait (``frequency``
    None, empty lists). ``step``: :func:`step_score`'s gait (a wheeled robot raises
    :class:`Wheeled`). ``refine > 0``: the gait tuned to the body, the ``trials`` random gaits
    followed by ``refine // 16`` CMA-ES generations of 16 from the best of them
    (:func:`robovae.evaluate.quality.gait_search.trials_search`, the same scene and rules);
    with ``starts = hold = 1`` its ``score`` is never below :func:`walk_score`'s. Tuned for a
    policy's use: each control held for ``hold`` physics steps (``robovae/Walk-v0``'s
    ``frame_skip``) and every gait judged by its median speed from ``starts`` states, the
    rest state and ``starts - 1`` with the environment's reset noise of scale ``noise``
    (:meth:`~robovae.evaluate.quality.locomotion.GaitTrials.perturb`); ``score`` is then that
    median. ``rollouts`` counts the gaits tried, each simulated ``starts`` times.

    Raises:
        ValueError: ``refine``, ``starts`` or ``hold`` out of range (``refine >= 0``, the
            others ``>= 1``; ``starts`` and ``hold`` other than 1 only with ``refine``)."""
    if refine < 0 or starts < 1 or hold < 1 or (not refine and (starts, hold) != (1, 1)):
        raise ValueError(f"walk_gait: refine must be 0 or more, starts and hold 1 or more (and "
                         f"1 without refine), not {refine}, {starts}, {hold}")
    g, model = _walk(path, seed, trials, seconds, settle, max_tilt, step, refine, starts, hold,
                     noise)
    moves = g.speed > 0
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(model.nu)]
    return {"score": g.speed, "speed": g.speed_m_s, "extent": g.extent, "score_seed": seed,
            "power": g.power, "mass": g.mass,
            "wheeled": bool(continuous_actuators(model).any()),
            "trials": trials, "refine": refine, "rollouts": g.rollouts, "starts": starts,
            "hold": hold, "noise": noise if starts > 1 else 0.0, "seconds": seconds,
            "settle": settle, "max_tilt": max_tilt,
            "frequency": g.frequency if moves else None,
            "actuators": names if moves else [],
            "amplitude": [float(v) for v in g.amplitude] if moves else [],
            "phase": [float(v) for v in g.phase] if moves else [],
            # offset None is 0 (a gait file without offsets reads as zeros)
            "offset": [float(v) for v in g.offset] if moves and g.offset is not None else []}


def stand_score(path: str | os.PathLike, seed: int = 0, seconds: float = 3.0) -> dict:
    """Lowest root height kept over a 3 s PD-held standing test (module docstring)."""
    from robovae.evaluate.quality.standing import standing

    res = standing(path, seconds=seconds)
    ratio = res.min_height_ratio
    score = 0.0
    if res.floating and not res.unstable and ratio is not None and math.isfinite(ratio):
        score = max(0.0, float(ratio))
    return {"score": score, "stands": res.stands, "floating": res.floating}


def _deepest_body(model: mujoco.MjModel) -> int:
    depth = np.zeros(model.nbody, dtype=int)
    for b in range(1, model.nbody):
        depth[b] = depth[model.body_parentid[b]] + 1
    return int(np.argmax(depth))


def reach_score(path: str | os.PathLike, seed: int = 0, samples: int = 512) -> dict:
    """End-effector workspace volume over ``L^3`` of a fixed-base arm (module docstring).

    Raises:
        SettingsError: ``samples`` below 4 (a hull has volume only from 4 points on), ``seed``
            outside ``[0, 2**31 - 1]``.
    """
    check_settings("reach_score", samples=(samples, integer(4)))
    check_seed(seed, "reach_score seed")
    from scipy.spatial import ConvexHull, QhullError

    from robovae.data.loading import load_robot
    from robovae.evaluate.camera import robot_bounds

    model = load_robot(path).model
    data = mujoco.MjData(model)
    quiet_forward(model, data)
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
TASKS: dict[str, Callable[..., dict]] = {"walk": walk_score, "step": step_score,
                                         "stand": stand_score, "reach": reach_score}


def score_robot(path: str | os.PathLike, task: str, seed: int = 0) -> dict:
    """``TASKS[task](path, seed)``; a robot the task cannot use (a file that does not load, no
    actuators, a failing measure) scores 0 with ``error`` set to one line. Never raises for a
    bad robot; raises ``RobovaeError`` (one line) for an unknown task or a ``seed`` out of
    ``[0, 2**31 - 1]``."""
    if task not in TASKS:
        raise RobovaeError(f"robovae: unknown task {task!r} (choose from {', '.join(TASKS)})")
    check_seed(seed, "score seed")
    fn = TASKS[task]
    try:
        out = fn(Path(path), seed=seed)
    except Exception as e:  # a bad candidate is a zero, not a crash of the optimisation
        return {"score": 0.0, "error": " ".join(f"{type(e).__name__}: {e}".split())[:300]}
    out.setdefault("error", None)
    if not math.isfinite(out["score"]):
        out.update(score=0.0, error="non-finite score")
    return out
