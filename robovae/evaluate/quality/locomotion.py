"""Locomotion: how fast can an open-loop sinusoidal gait move the robot?

The robot (on a floor, :func:`~robovae.evaluate.quality.stage.stage`) is driven by its own
actuators with one open-loop gait per rollout,

    ctrl_a(t) = clip(c_a + h_a (B_a + A_a sin(2π f t + φ_a)), lo_a, hi_a),

``c_a`` and ``h_a`` the middle and half-width of actuator ``a``'s ``ctrlrange`` ``[lo_a, hi_a]``
(``[-1, 1]`` when unlimited), amplitude ``A_a ~ U[0, 1]`` and phase ``φ_a ~ U[0, 2π)`` per
actuator and one frequency ``f ~ U[f_lo, f_hi]`` (0.5–3 Hz) per rollout. The **offset**
``B_a ~ U[-1, 1]`` is drawn for the actuators that drive an unlimited hinge
(:func:`continuous_actuators`: a wheel, a rotor) and is 0 for all others: a wheel is turned,
not only rocked about its rest angle (a motor's constant term is a constant torque). The
offsets are drawn after every other number, so a robot without such actuators runs the same
gaits as without offsets. A fixed budget of ``rollouts`` (64) random gaits of ``seconds``
(4 s) each, drawn from ``numpy.random.default_rng(seed)``, runs in one ``mujoco.rollout`` call
from the robot's rest pose (:func:`~robovae.evaluate.quality.stage.rest_pose`) at rest (random
search).

The **speed** of a gait is the horizontal distance (m) the root body covers between
``settle · seconds`` (a quarter of the rollout: falling over or dropping onto the floor at the
start is not locomotion) and the end, divided by the time in between and by the robot's extent
``L`` (the diagonal of its bounding box at ``qpos0``): extents per second; any direction counts
as forward (a generated robot has no designated front). Rollouts that go unstable (non-finite
state, or MuJoCo resetting it) or fall through the floor (root ending more than ``L`` below
it: a robot without collision geoms) score 0 and count in ``GaitResult.unstable``, and so do
rollouts that **fly**: the robot's centre of mass rises more than :data:`MAX_RISE` (half) of
its extent above its height at rest at some 10 ms sample. Walking does not do that; leaping
does (Menagerie's Spot, driven open loop by its strong position servos, leaves the ground in
about half of the 64 gaits), and so does the simulator's numerical energy: a 77-body robot
with motor gears up to 11,000 that CMA-ES over ``z`` found rose 98 m in 3 s without touching
the floor, at 26 m/s.
:func:`gait_speed` is the best speed over the budget. ``GaitResult.power`` is what that gait
spends: the mean over its counted 10 ms samples of the mechanical power its actuators deliver,
``Σ_a |τ_a q̇_a|`` (W; MuJoCo's motors give their torque at any speed, so a motor on an unlimited
hinge can spin up to where its joint damping stops it). A robot without actuators scores 0, and
so does a robot with an **actuated base** (:func:`actuated_base`): a motor on a joint between
its root body and the world moves the root by itself — a gantry, not locomotion (CMA-ES over
``z`` found a 15-tonne blob whose six actuated root slides carried it 65 m/s). Unactuated root
joints (the planar slides and hinge of dm_control's cheetah, walker, hopper) count. It
is a random search: the number is a lower bound on what the body can do with such gaits,
comparable between robots measured with the same budget and seed.

With ``max_tilt`` (degrees; off by default), a gait **falls** at the first 10 ms sample where
the root's up axis (the local direction that points up at rest) tilts more than ``max_tilt``
from vertical: the displacement stops counting there (tumbling is not walking; nothing counts
when it falls before the settling time) while the time still runs to the end, so falling early
costs. The design optimiser's walk score is this search with its own budget (8 gaits of 3 s,
falls at 60°: :func:`robovae.design.score.walk_score`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from robovae.data.loading import capture_mujoco_warnings, quiet_forward
from robovae.errors import check_seed
from robovae.evaluate.quality.stage import Robot, rest_pose, stage
from robovae.settings import check_settings, integer, number, span

__all__ = ["FALL_SAMPLE_DT", "MAX_RISE", "GaitResult", "GaitTrials", "actuated_base",
           "continuous_actuators", "gait", "gait_speed", "random_gaits", "sinusoid_controls"]

#: Seconds between the samples that look for a fall (``max_tilt``) or a flight.
FALL_SAMPLE_DT = 0.01
#: A rollout whose centre of mass rises more than this share of the extent above its rest
#: height flies (module docstring).
MAX_RISE = 0.5


@dataclass
class GaitResult:
    """Outcome of :func:`gait`."""

    speed: float  # best horizontal speed / extent, 1/s
    speed_m_s: float  # the same gait's speed, m/s
    extent: float  # m
    frequency: float  # Hz of the best gait (NaN without actuators)
    amplitude: np.ndarray  # [nu] of the best gait
    phase: np.ndarray  # [nu] rad
    unstable: int  # rollouts that went unstable
    rollouts: int
    seconds: float  # simulated per rollout
    actuated_base: bool = False  # scored 0: a motor drives the root relative to the world
    offset: np.ndarray | None = None  # [nu] of the best gait (0 but on continuous actuators)
    power: float = 0.0  # W: the best gait's mean mechanical power while its distance counts
    mass: float = 0.0  # kg: the robot's


_JOINT_TRANSMISSIONS = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))


def actuated_base(model: mujoco.MjModel, root: int) -> bool:
    """Whether an actuator with a joint transmission drives a joint of body ``root`` (the
    robot's root, whose joints connect it to the world): the root then moves by its own motor,
    which is not locomotion (module docstring)."""
    on_joint = np.isin(model.actuator_trntype, _JOINT_TRANSMISSIONS)
    joints = model.actuator_trnid[on_joint, 0]
    return bool(np.any(model.jnt_bodyid[joints] == root))


def continuous_actuators(model: mujoco.MjModel) -> np.ndarray:
    """``[nu]`` bool: the actuators whose joint transmission drives a hinge without limits
    (a wheel, a rotor): the gaits give them a constant offset (module docstring)."""
    on_joint = np.isin(model.actuator_trntype, _JOINT_TRANSMISSIONS)
    if model.njnt == 0:  # tendon or site transmissions only
        return np.zeros(model.nu, dtype=bool)
    joint = np.where(on_joint, model.actuator_trnid[:, 0], 0)
    hinge = model.jnt_type[joint] == int(mujoco.mjtJoint.mjJNT_HINGE)
    return on_joint & hinge & ~model.jnt_limited[joint].astype(bool)


def sinusoid_controls(model: mujoco.MjModel, amplitude: np.ndarray, phase: np.ndarray,
                      frequency: np.ndarray, steps: int, offset: np.ndarray | None = None
                      ) -> np.ndarray:
    """``[R, steps, nu]`` controls of ``R`` gaits (module docstring) at the model's time
    step: ``amplitude``, ``phase`` and ``offset`` (None: 0) ``[R, nu]``, ``frequency``
    ``[R]`` (Hz)."""
    limited = model.actuator_ctrllimited.astype(bool)
    lo = np.where(limited, model.actuator_ctrlrange[:, 0], -1.0)
    hi = np.where(limited, model.actuator_ctrlrange[:, 1], 1.0)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    t = np.arange(steps) * model.opt.timestep
    arg = 2 * np.pi * frequency[:, None, None] * t[None, :, None] + phase[:, None, :]
    ctrl = mid + amplitude[:, None, :] * half * np.sin(arg)
    if offset is None or not np.any(offset):
        return ctrl
    return np.clip(ctrl + (offset * half)[:, None, :], lo, hi)


def _root_pos(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray, root: int
              ) -> np.ndarray:
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data.xpos[root].copy()


def _com_z(model: mujoco.MjModel, data: mujoco.MjData, bodies: np.ndarray) -> float:
    mass = model.body_mass[bodies]
    return float(mass @ data.xipos[bodies, 2] / max(float(mass.sum()), 1e-12))


def _scan(model: mujoco.MjModel, data: mujoco.MjData, states: np.ndarray, root: int,
          bodies: np.ndarray, up_local: np.ndarray, cos_tilt: float | None, com_limit: float
          ) -> tuple[int | None, bool]:
    """Every 10 ms sample of a rollout: the state index of the first fall (root up axis tilted
    below ``cos_tilt``; None: never, or not checked) and whether the centre of mass of the
    robot's ``bodies`` rose above ``com_limit`` before it (module docstring)."""
    every = max(1, round(FALL_SAMPLE_DT / model.opt.timestep))
    for k in range(every - 1, len(states), every):
        data.qpos[:] = states[k, 1:1 + model.nq]
        mujoco.mj_kinematics(model, data)
        if _com_z(model, data, bodies) > com_limit:
            return None, True
        if cos_tilt is not None and (data.xmat[root].reshape(3, 3) @ up_local)[2] < cos_tilt:
            return k, False
    return None, False


def _mean_power(model: mujoco.MjModel, data: mujoco.MjData, states: np.ndarray,
                ctrl: np.ndarray, first: int, last: int) -> float:
    """Mean over the 10 ms samples of states ``first … last`` of one rollout of the mechanical
    power its actuators deliver, ``Σ_a |f_a v_a|`` (W: actuator force times actuator velocity,
    i.e. joint torque times joint speed), each state with the control applied next."""
    every = max(1, round(FALL_SAMPLE_DT / model.opt.timestep))
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    total, n = 0.0, 0
    for k in range(first, last + 1, every):
        mujoco.mj_setState(model, data, states[k], spec)
        data.ctrl[:] = ctrl[min(k + 1, len(ctrl) - 1)]
        quiet_forward(model, data)
        total += float(np.abs(data.actuator_force * data.actuator_velocity).sum())
        n += 1
    return total / max(n, 1)


class GaitTrials:
    """A robot staged once (:func:`~robovae.evaluate.quality.stage.stage`) to score open-loop
    sinusoidal gaits in batches (module docstring): every rollout of :meth:`run` starts from
    the same rest state and lasts ``steps`` physics steps; :func:`gait` runs its random gaits
    through one, :func:`~robovae.evaluate.quality.gait_search.searched_gait` its CMA-ES
    generations. ``settle``: the share of each rollout before the distance counts;
    ``max_tilt``: degrees past which a gait has fallen (None: falls are not checked);
    ``max_steps`` caps the steps per rollout; ``hold``: each control is held for this many
    physics steps (the gait's value at the first step of each block: as an environment with
    ``frame_skip = hold`` applies a policy's actions; 1: a control at every step).
    :meth:`perturb` makes every gait start from several states and score the median speed.

    Raises:
        RobovaeError: a model without a floor; RobotFileError: a file that does not load.
    """

    def __init__(self, robot: Robot, seconds: float = 4.0, settle: float = 0.25,
                 max_steps: int = 2_000, max_tilt: float | None = None, hold: int = 1) -> None:
        check_settings("GaitTrials", seconds=(seconds, number(0, low_open=True)),
                       settle=(settle, number(0, 1, high_open=True)),
                       max_steps=(max_steps, integer(1)),
                       max_tilt=(max_tilt, number(0, 180).or_none()), hold=(hold, integer(1)))
        self.hold = int(hold)
        st = stage(robot)
        self.model, self.root, self.extent, self.floor_z = st.model, st.root, st.extent, \
            st.floor_z
        model, root = self.model, self.root
        dt = model.opt.timestep
        self.steps = min(max(1, round(seconds / dt)), max_steps)
        self.mass = float(model.body_subtreemass[root])
        #: a motor drives the root relative to the world: nothing this robot does is walking
        self.actuated_base = model.nu > 0 and actuated_base(model, root)
        #: ``[nu]``: the actuators that get an offset (:func:`continuous_actuators`)
        self.continuous = continuous_actuators(model)
        self.data = data = mujoco.MjData(model)
        data.qpos[:] = rest_pose(model)
        quiet_forward(model, data)
        self.up_local = data.xmat[root].reshape(3, 3).T @ np.array([0.0, 0.0, 1.0])
        self.bodies = np.flatnonzero(model.body_rootid == model.body_rootid[root])
        self.com_limit = _com_z(model, data, self.bodies) + MAX_RISE * self.extent
        self.cos_tilt = math.cos(math.radians(max_tilt)) if max_tilt is not None else None
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.state0 = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, self.state0, spec)
        #: ``[K, state]``: the states every gait starts from (:meth:`perturb`)
        self.starts = self.state0[None]
        steps = self.steps
        self.first = min(int(settle * steps), steps - 1)  # state index where distance starts
        self.span = (steps - 1 - self.first) * dt if self.first < steps - 1 else steps * dt

    @property
    def seconds(self) -> float:
        """Simulated seconds per rollout."""
        return self.steps * self.model.opt.timestep

    def perturb(self, qpos: np.ndarray, qvel: np.ndarray, count: int, scale: float,
                seed: int) -> None:
        """Start every gait of :meth:`run` from ``count`` states: the rest state and ``count -
        1`` copies of it with the noise of ``robovae/Walk-v0``'s reset (:class:`~robovae.envs.
        walk.WalkEnv`: ``U(-scale, scale)`` added to the positions ``qpos`` (indices into
        ``qpos``), ``scale · N(0, 1)`` to the velocities ``qvel``), drawn from
        ``numpy.random.default_rng([seed, 1])`` (a stream apart from :func:`random_gaits`'
        of the same seed); a gait's speed is then its median over them."""
        if count < 1:
            raise ValueError(f"GaitTrials.perturb: count must be at least 1, not {count}")
        model, data = self.model, self.data
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        rng = np.random.default_rng([seed, 1])
        starts = [self.state0]
        for _ in range(count - 1):
            mujoco.mj_setState(model, data, self.state0, spec)
            data.qpos[qpos] += rng.uniform(-scale, scale, len(qpos))
            data.qvel[qvel] += scale * rng.standard_normal(len(qvel))
            starts.append(np.empty_like(self.state0))
            mujoco.mj_getState(model, data, starts[-1], spec)
        mujoco.mj_setState(model, data, self.state0, spec)
        quiet_forward(model, data)
        self.starts = np.array(starts)

    def run(self, amplitude: np.ndarray, phase: np.ndarray, frequency: np.ndarray,
            offset: np.ndarray) -> tuple[np.ndarray, int, tuple[np.ndarray, np.ndarray, int]]:
        """Roll out ``R`` gaits (``amplitude``, ``phase``, ``offset`` ``[R, nu]``,
        ``frequency`` ``[R]`` Hz) from each start (``K``: one unless :meth:`perturb`) in one
        ``mujoco.rollout`` call: their horizontal root speeds (m/s) ``[R]``, the median over
        the starts, a rollout scoring 0 when it went unstable, fell through the floor, flew or
        fell before the distance counts; the number of unstable, sunk or flying rollouts; and
        the best gait's rollout from the first start ``(states, controls, last counted
        state)``, for its power."""
        model, data = self.model, self.data
        ctrl = sinusoid_controls(model, amplitude, phase, frequency, self.steps, offset)
        if self.hold > 1:
            ctrl = ctrl[:, np.arange(self.steps) // self.hold * self.hold]
        k = len(self.starts)
        if k > 1:  # gait-major: rollout r * k + j is gait r from start j
            ctrl = np.repeat(ctrl, k, axis=0)
        init = np.tile(self.starts, (len(frequency), 1)) if k > 1 else self.starts
        with capture_mujoco_warnings():
            states, _ = rollout.rollout(model, data, init, ctrl, nstep=self.steps)
        speeds = np.zeros(len(ctrl))
        lasts = np.zeros(len(ctrl), dtype=int)
        bad = 0
        for r in range(len(ctrl)):
            speeds[r], lasts[r], failed = self._speed(states[r])
            bad += failed
        median = np.median(speeds.reshape(-1, k), axis=1)
        best = int(np.argmax(median)) * k
        return median, bad, (states[best], ctrl[best], int(lasts[best]))

    def _speed(self, s: np.ndarray) -> tuple[float, int, bool]:
        """One rollout's states ``s``: its speed (m/s), last counted state and whether it went
        unstable, sank or flew (:meth:`run`)."""
        model, data, root = self.model, self.data, self.root
        if not np.isfinite(s).all() or np.any(np.diff(s[:, 0]) <= 0):
            return 0.0, 0, True
        if _root_pos(model, data, s[-1, 1:1 + model.nq], root)[2] < self.floor_z - self.extent:
            return 0.0, 0, True  # fell through the floor (no collision geoms)
        fell, flew = _scan(model, data, s, root, self.bodies, self.up_local, self.cos_tilt,
                           self.com_limit)
        if flew:
            return 0.0, 0, True  # a leap or numerical energy: not walking
        last = len(s) - 1 if fell is None else fell
        if last <= self.first:  # fell before the distance counts
            return 0.0, 0, False
        start = _root_pos(model, data, s[self.first, 1:1 + model.nq], root)
        end = _root_pos(model, data, s[last, 1:1 + model.nq], root)
        return float(np.linalg.norm((end - start)[:2])) / self.span, last, False

    def power(self, best: tuple[np.ndarray, np.ndarray, int]) -> float:
        """Mean mechanical power (W) of a rollout ``(states, controls, last counted state)``
        while its distance counts (:func:`_mean_power`)."""
        states, ctrl, last = best
        return _mean_power(self.model, self.data, states, ctrl, self.first, last)

    def result(self, speed: float, frequency: float, amplitude: np.ndarray, phase: np.ndarray,
               offset: np.ndarray, unstable: int, rollouts: int, power: float) -> GaitResult:
        """A :class:`GaitResult` of this robot for its best gait (``speed`` in m/s)."""
        return GaitResult(speed / self.extent, speed, self.extent, frequency, amplitude, phase,
                          unstable, rollouts, self.seconds, offset=offset, power=power,
                          mass=self.mass)

    def nothing(self, rollouts: int) -> GaitResult:
        """The result of a robot that cannot walk (no actuators, or an actuated base)."""
        nu = self.model.nu
        return GaitResult(0.0, 0.0, self.extent, math.nan, np.zeros(nu), np.zeros(nu), 0,
                          max(rollouts, 0), self.seconds, self.actuated_base, np.zeros(nu),
                          mass=self.mass)


def gait(robot: Robot, rollouts: int = 64, seconds: float = 4.0, seed: int = 0,
         frequency: tuple[float, float] = (0.5, 3.0), settle: float = 0.25,
         max_steps: int = 2_000, max_tilt: float | None = None) -> GaitResult:
    """Random search over ``rollouts`` open-loop sinusoidal gaits of ``seconds`` each (module
    docstring): the budget. ``settle``: the share of each rollout before the distance counts;
    ``max_tilt``: degrees past which a gait has fallen (None: falls are not checked).

    ``max_steps`` caps the steps per rollout (a robot with a tiny time step is driven for less
    than ``seconds``; ``GaitResult.seconds`` says how long and the speed uses it).

    Raises:
        RobovaeError: a model without a floor; RobotFileError: a file that does not load.
        SettingsError: ``rollouts`` below 1, a ``seed`` out of ``[0, 2**31 - 1]``, a
            ``frequency`` range that is not ``0 < low <= high`` (finite), or a setting of
            :class:`GaitTrials` out of range (``seconds`` not > 0, ``settle`` outside
            ``[0, 1)``).
    """
    check_gait_settings(rollouts, seed, frequency)
    trials = GaitTrials(robot, seconds, settle, max_steps, max_tilt)
    nu = trials.model.nu
    if nu == 0 or trials.actuated_base:
        return trials.nothing(rollouts)
    amp, phase, freq, offset = random_gaits(np.random.default_rng(seed), rollouts, nu,
                                            frequency, trials.continuous)
    speeds, bad, best_run = trials.run(amp, phase, freq, offset)
    best = int(np.argmax(speeds))
    power = trials.power(best_run) if speeds[best] > 0 else 0.0
    return trials.result(float(speeds[best]), float(freq[best]), amp[best], phase[best],
                         offset[best], bad, rollouts, power)


def check_gait_settings(rollouts: object, seed: object,
                        frequency: tuple[float, float]) -> None:
    """Refuse a gait search's ``rollouts`` below 1, a ``seed`` out of range or a ``frequency``
    range that is not ``0 < low <= high`` (finite), in one line (``SettingsError``)."""
    check_settings("gait", rollouts=(rollouts, integer(1)), frequency=(frequency, span()))
    check_seed(seed, "gait seed")


def random_gaits(rng: np.random.Generator, rollouts: int, nu: int,
                 frequency: tuple[float, float], continuous: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``rollouts`` random gaits (module docstring) for ``nu`` actuators, ``continuous``
    ``[nu]`` those that get an offset: ``(amplitude, phase, frequency, offset)``, drawn in
    that order (the offsets last)."""
    amp = rng.uniform(0.0, 1.0, (rollouts, nu))
    phase = rng.uniform(0.0, 2 * np.pi, (rollouts, nu))
    freq = rng.uniform(frequency[0], frequency[1], rollouts)
    offset = rng.uniform(-1.0, 1.0, (rollouts, nu)) * continuous
    return amp, phase, freq, offset


def gait_speed(robot: Robot, rollouts: int = 64, seconds: float = 4.0, seed: int = 0) -> float:
    """Best horizontal speed over the robot's extent (1/s) of ``rollouts`` seeded random
    sinusoidal gaits of ``seconds`` (:func:`gait`)."""
    return gait(robot, rollouts, seconds, seed).speed
