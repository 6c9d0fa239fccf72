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

**Standing test** (:func:`standing_test`): :func:`robovae.evaluate.quality.standing.standing`
as a flat dict (``seconds`` renamed ``stand_seconds``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any, TypeAlias

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings
from robovae.data.workers import process_pool
from robovae.errors import SettingsError, check_seed
from robovae.evaluate.population import knn_entropy
from robovae.evaluate.quality.stage import MOVING, prepare
from robovae.evaluate.quality.stage import unstable as is_unstable
from robovae.evaluate.quality.standing import standing
from robovae.settings import check_settings, integer, number

Robot: TypeAlias = str | os.PathLike | mujoco.MjSpec


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

    Raises:
        SettingsError: ``seconds``, ``hold`` or ``sample_dt`` not > 0, ``rollouts``, ``k`` or
            ``max_steps`` below 1, ``seed`` outside ``[0, 2**31 - 1]``.
    """
    positive = number(0, low_open=True)
    check_settings("state_entropy", seconds=(seconds, positive), rollouts=(rollouts, integer(1)),
                   hold=(hold, positive), sample_dt=(sample_dt, positive), k=(k, integer(1)),
                   max_steps=(max_steps, integer(1)))
    check_seed(seed, "state_entropy seed")
    spec, scene = prepare(robot)
    model = scene.model
    data = mujoco.MjData(model)
    dt = model.opt.timestep
    seconds = min(seconds, max_steps * dt / rollouts)
    steps = max(1, round(seconds / dt))
    every_ctrl = max(1, round(hold / dt))
    every_rec = max(1, round(sample_dt / dt))
    lo = np.where(model.actuator_ctrllimited.astype(bool), model.actuator_ctrlrange[:, 0], -1.0)
    hi = np.where(model.actuator_ctrllimited.astype(bool), model.actuator_ctrlrange[:, 1], 1.0)
    joints = [j for j in range(model.njnt) if model.jnt_type[j] in MOVING]
    qadr = np.array([model.jnt_qposadr[j] for j in joints], dtype=int)
    roots, qs, disp, unstable = [], [], [], 0
    out = {"actuators": int(model.nu), "joints": len(joints), "size": scene.extent,
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
                if is_unstable(data):
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
            "root_entropy_scaled": h_root - dims * math.log(scene.extent),
            "root_dims": dims, "joint_entropy": h_joint, "points": len(pos),
            "displacement": float(np.mean(disp)) if disp else math.nan, "unstable": unstable}


def standing_test(robot: Robot, **kwargs: Any) -> dict:
    """:func:`~robovae.evaluate.quality.standing.standing` (keyword arguments passed on) as a
    dict; its ``seconds`` is called ``stand_seconds``."""
    out = asdict(standing(robot, **kwargs))
    out["stand_seconds"] = out.pop("seconds")
    return out


def behaviour(robot: Robot, entropy: dict | None = None, standing: dict | None = None) -> dict:
    """:func:`state_entropy` and :func:`standing_test` of one robot (keyword arguments in
    ``entropy``/``standing``), as one flat dict; ``error`` holds a one-line message when the
    robot could not be measured.

    Raises:
        SettingsError: a setting out of range (:func:`state_entropy`, :func:`standing_test`):
            the settings' fault, not the robot's.
    """
    out: dict = {"robot": str(robot) if not isinstance(robot, mujoco.MjSpec) else
                 robot.modelname}
    try:
        out.update(state_entropy(robot, **(entropy or {})))
        out.update(standing_test(robot, **(standing or {})))
    except SettingsError:
        raise
    except Exception as e:  # a bad robot must not stop a population
        out["error"] = " ".join(f"{type(e).__name__}: {e}".split())
    return out


def _behaviour_item(item: tuple) -> dict:
    path, entropy, standing = item
    return behaviour(path, entropy, standing)


def behaviour_many(paths: Sequence[str | Path], jobs: int = 1, entropy: dict | None = None,
                   standing: dict | None = None) -> list[dict]:
    """:func:`behaviour` of many robot files, in ``jobs`` worker processes (``0``: all cores;
    started with ``spawn``, like generation's workers).

    Raises:
        SettingsError: ``jobs`` negative, or a setting of :func:`behaviour` out of range.
    """
    check_settings("behaviour_many", jobs=(jobs, integer(0)))
    items = [(str(p), entropy, standing) for p in paths]
    jobs = jobs or (os.cpu_count() or 1)
    if jobs <= 1 or len(items) < 2:
        return [_behaviour_item(it) for it in items]
    with process_pool(min(jobs, len(items))) as pool:
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
