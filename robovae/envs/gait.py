"""Open-loop sinusoidal gaits as ``robovae/Walk-v0`` policies.

The walk score (:func:`robovae.design.score.walk_score`) drives actuator ``a`` with
``ctrl_a(t) = c_a + h_a (B_a + A_a sin(2 pi f t + phi_a))`` clipped to its control range
(``c_a``, ``h_a``: the middle and half-width of that range; the offset ``B_a`` is 0 but on the
actuators of unlimited hinges, :func:`~robovae.evaluate.quality.locomotion.continuous_actuators`).
:class:`~robovae.envs.walk.WalkEnv` maps a normalised action to ``ctrl = c + a h``, so the same
gait as a policy is

    a_a(t) = clip(B_a + A_a sin(2 pi f t + phi_a), -1, 1),      t = the simulation time,

:class:`SinusoidGait`. ``robovae optimize --task walk`` writes each best robot's gait beside
it (``gait.json``, :func:`robovae.design.score.walk_gait`), and :func:`replay` drives a
``WalkEnv`` with it. With ``frame_skip=1`` and ``reset_noise_scale=0`` the replay is the
score's own rollout (the same scene, start and controls at every physics step):
:meth:`GaitReplay.speed` gives the score's speed (up to floating-point rounding while no fall
ends the count); with the environment's defaults (each action held for 5 physics steps, noise
on the start) it measures how much of that speed the gait keeps when the robot is used as a
policy would use it.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

import mujoco
import numpy as np

from robovae.errors import RobovaeError, SettingsError
from robovae.evaluate.quality.locomotion import FALL_SAMPLE_DT
from robovae.settings import check_settings, number

if TYPE_CHECKING:
    import gymnasium

    from robovae.envs.walk import WalkEnv

__all__ = ["GaitReplay", "SinusoidGait", "replay"]


@dataclass(frozen=True)
class SinusoidGait:
    """``a(t) = clip(offset + amplitude * sin(2 pi frequency t + phase), -1, 1)`` in normalised
    actions (module docstring): ``frequency`` in Hz, ``amplitude``, ``phase`` (rad) and
    ``offset`` (None: 0) ``[nu]``.

    Raises:
        SettingsError: a ``frequency`` that is not a finite number ``>= 0``, or amplitudes,
            phases and offsets that are not finite vectors of one length.
    """

    frequency: float
    amplitude: np.ndarray
    phase: np.ndarray
    offset: np.ndarray | None = None

    def __post_init__(self) -> None:
        check_settings("SinusoidGait", frequency=(self.frequency, number(0)))
        parts = [self.amplitude, self.phase] + ([] if self.offset is None else [self.offset])
        arrays = [np.asarray(a, dtype=float) for a in parts]
        if not (all(a.ndim == 1 and len(a) == len(arrays[0]) for a in arrays)
                and all(np.isfinite(a).all() for a in arrays)):
            raise SettingsError("robovae: SinusoidGait: amplitude, phase and offset must be "
                                "finite vectors of one length, got shapes "
                                f"{', '.join(str(a.shape) for a in arrays)}")

    def __call__(self, t: float) -> np.ndarray:
        """The action at time ``t`` (s), ``[nu]`` in ``[-1, 1]``."""
        wave = self.amplitude * np.sin(2.0 * math.pi * self.frequency * t + self.phase)
        return wave if self.offset is None else np.clip(self.offset + wave, -1.0, 1.0)

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> SinusoidGait:
        """The gait of a ``gait.json`` written by ``robovae optimize`` (or any JSON object
        with ``frequency``, ``amplitude`` and ``phase``, and optionally ``offset``: 0 when
        absent).

        Raises:
            RobovaeError: one line naming the file: unreadable, not such an object, or a
                robot that scored 0 (no gait).
        """
        path = Path(path)
        try:
            obj = json.loads(path.read_text())
            freq, amp, phase = obj["frequency"], obj["amplitude"], obj["phase"]
            offset = obj.get("offset") or [0.0] * len(amp or [])
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
            raise RobovaeError(f"robovae: {path}: not a gait file ({type(e).__name__}: "
                               f"{' '.join(str(e).split())})") from None
        if freq is None or not amp or not len(amp) == len(phase) == len(offset):
            raise RobovaeError(f"robovae: {path}: no gait (the robot scored 0, or amplitude, "
                               "phase and offset differ in length)")
        try:
            return cls(float(freq), np.asarray(amp, dtype=float),
                       np.asarray(phase, dtype=float), np.asarray(offset, dtype=float))
        except (SettingsError, TypeError, ValueError) as e:  # NaN, nested lists, text
            raise RobovaeError(f"robovae: {path}: not a gait file ({e})") from None


@dataclass
class GaitReplay:
    """What :func:`replay` recorded after each environment step of ``dt`` seconds, for a replay
    of ``seconds``: ``time`` (s) ``[T]``, the root body's world position ``root`` ``[T, 3]``,
    ``upright`` (cosine of the root's tilt from its rest orientation) ``[T]``, and the
    environment's ``healthy`` and ``reward`` ``[T]``."""

    seconds: float
    dt: float
    time: np.ndarray
    root: np.ndarray
    upright: np.ndarray
    healthy: np.ndarray
    reward: np.ndarray

    def speed(self, settle: float = 1.0, max_tilt: float = 60.0) -> float:
        """Horizontal root speed (m/s) as the walk score measures it
        (:func:`robovae.evaluate.quality.locomotion.gait`): the distance from the step at
        ``settle`` seconds (index ``int(settle / seconds * T)``) to the last step, or to the
        first 10 ms sample where the root tilts more than ``max_tilt`` degrees (a fall:
        walking stops counting, time runs on), over the time from that step to the end; 0
        when it falls before ``settle``."""
        steps = len(self.time)
        first = min(int(settle / self.seconds * steps), steps - 1)
        every = max(1, round(FALL_SAMPLE_DT / self.dt))
        samples = np.arange(every - 1, steps, every)
        fallen = samples[self.upright[samples] < math.cos(math.radians(max_tilt))]
        last = int(fallen[0]) if len(fallen) else steps - 1
        span = float(self.time[-1] - self.time[first])
        if last <= first or span <= 0:
            return 0.0
        return float(np.linalg.norm(self.root[last, :2] - self.root[first, :2])) / span

    @property
    def episode_return(self) -> float:
        """The sum of the rewards."""
        return float(self.reward.sum())


def replay(env: gymnasium.Env, gait: SinusoidGait, seconds: float, seed: int | None = None
           ) -> GaitReplay:
    """Run ``gait`` in a :class:`~robovae.envs.walk.WalkEnv` (or a wrapper of one) for
    ``seconds`` of simulated time from ``env.reset(seed=seed)``, never ending early (an
    unhealthy step is recorded, not a reason to stop).

    Raises:
        RobovaeError: the gait's actuators do not match the environment's; SettingsError:
            ``seconds`` not a finite number > 0.
    """
    check_settings("replay", seconds=(seconds, number(0, low_open=True)))
    walk = cast("WalkEnv", env.unwrapped)  # Env.unwrapped is typed as a plain Env
    if len(gait.amplitude) != walk.model.nu:
        raise RobovaeError(f"robovae: {walk.robot_path}: the gait drives {len(gait.amplitude)} "
                           f"actuators, the robot has {walk.model.nu} (actuator)")
    env.reset(seed=seed)
    steps = max(1, round(seconds / walk.dt))
    time, qpos = np.empty(steps), np.empty((steps, walk.model.nq))
    healthy, reward = np.empty(steps, dtype=bool), np.empty(steps)
    for k in range(steps):
        _, reward[k], _, _, info = walk.step(gait(walk.data.time))
        time[k], qpos[k], healthy[k] = walk.data.time, walk.data.qpos, info["healthy"]
    # after mj_step, data.xpos is still that of the state before the step: the root's pose of
    # each recorded state is computed from its qpos
    data, root = mujoco.MjData(walk.model), walk.scene.root
    pos, upright = np.empty((steps, 3)), np.empty(steps)
    for k in range(steps):
        data.qpos[:] = qpos[k]
        mujoco.mj_kinematics(walk.model, data)
        pos[k] = data.xpos[root]
        upright[k] = (data.xmat[root].reshape(3, 3) @ walk.up_local)[2]
    return GaitReplay(float(seconds), float(walk.dt), time, pos, upright, healthy, reward)
