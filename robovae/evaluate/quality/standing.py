"""Standing test: does the robot, joints held at rest, stay up on a floor?

The robot (:func:`~robovae.evaluate.quality.stage.stage`: a floor is added to a file or spec
without one) is simulated for ``seconds`` (3 s) with every hinge and slide joint PD-held at its
rest pose (:func:`~robovae.evaluate.quality.stage.rest_pose`: a ``home`` keyframe, else
``qpos0``, clipped into the joint ranges), from that pose and zero velocity, with
``mujoco.rollout`` (the hold is
part of the model, so no Python runs per step). A copy of the model is changed, never the
caller's:

- **hold**: stiffness ``kp = stiffness · m g L`` (total mass ``m``, extent ``L``: the base
  sags about ``1/stiffness`` rad under its full weight on a lever of its own size), capped at
  ``0.1 I / dt²`` (``I`` the joint's inertia ``dof_M0``, ``dt`` the time step, so
  that the explicit spring stays stable), critical damping ``kv = 2 sqrt(kp I)``, integrator
  ``implicitfast`` (damping implicit);
- a joint driven by a stateless actuator of the robot (joint transmission, no activation) is
  held by that actuator turned into a position servo (gain ``kp``, bias ``-kp q - kv q̇``,
  gear 1) whose force is limited by what the robot's own actuators can give on that joint
  (:func:`robovae.data.actuators.torque_limits`); other joints are held by a passive spring
  and damper (``jnt_stiffness``, ``qpos_spring`` the rest pose, ``dof_damping``), unlimited; the
  robot's other actuators are switched off (zero gain and bias).

Only floating-base robots (root body with a free joint) are tested. The robot **stands** when
at every sample (every ``sample_dt``) its root stayed **up** — root height above the floor at
least ``min_height`` (0.5) of its height above its own lowest point at rest — and
**upright** — the root's up axis (the local direction that points up at rest) within
``max_tilt`` (45°) of vertical — and the simulation stayed stable (finite, no MuJoCo
instability warning: MuJoCo would silently reset the state). The root pose is read from the
free joint's ``qpos`` (position and quaternion) at every sample.

The simulation stops early, without changing the verdict, at the first failing sample (the
robot fell: ``height_ratio`` and ``max_tilt`` then describe the moment it failed) or once the
robot is at rest after at least 1 s (held joints, every velocity below ``rest``: a robot at
rest under a PD hold stays at rest; ``settled``). After the first second (the validation's,
simulated without it) the simulation runs with MuJoCo's sleeping (``mjENBL_SLEEP``,
``sleep_tolerance = rest``): a robot whose velocities, each weighted by MuJoCo's
``dof_length``, stay below ``rest`` for ``mjMINAWAKE`` (10) steps is frozen with zero velocity,
so it costs almost nothing until its segment ends and is then ``settled``; a robot still
creeping or falling is simulated as without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from robovae.data.actuators import torque_limits
from robovae.data.loading import capture_mujoco_warnings, quiet_forward
from robovae.evaluate.quality.stage import (
    MOVING,
    Robot,
    Stage,
    rest_pose,
    robot_points,
    stage,
    unstable,
)
from robovae.settings import check_settings, integer, number

_TRN_JOINT = int(mujoco.mjtTrn.mjTRN_JOINT)
_GAIN_FIXED = int(mujoco.mjtGain.mjGAIN_FIXED)
_BIAS_NONE = int(mujoco.mjtBias.mjBIAS_NONE)
_BIAS_AFFINE = int(mujoco.mjtBias.mjBIAS_AFFINE)
_SLEEP = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
#: Equalities MuJoCo cannot sleep (a fatal error): a model with one is simulated awake.
_NO_SLEEP = [int(mujoco.mjtEq.mjEQ_TENDON), int(mujoco.mjtEq.mjEQ_FLEX),
             int(mujoco.mjtEq.mjEQ_FLEXVERT), int(mujoco.mjtEq.mjEQ_FLEXSTRAIN)]

__all__ = ["FIRST_SECONDS", "HeldRun", "StandResult", "first_steps", "hold_at_rest", "standing"]


@dataclass
class StandResult:
    """Outcome of :func:`standing`. Every field but ``floating`` is None for a robot that was
    not tested (no free root joint)."""

    floating: bool  # root body has a free joint (tested)
    stands: bool | None = None  # up, upright and stable at every sample
    up: bool | None = None  # at the last sample
    upright: bool | None = None  # at the last sample
    fell_at: float | None = None  # s, first failing sample (None when standing)
    height_ratio: float | None = None  # last root height / initial height
    min_height_ratio: float | None = None
    max_tilt: float | None = None  # degrees, worst over the samples
    unstable: bool | None = None
    limited_joints: int | None = None  # joints held with a torque limit
    seconds: float | None = None  # simulated
    settled: bool | None = None  # stopped early: at rest (module docstring)


def hold_at_rest(model: mujoco.MjModel, extent: float, stiffness: float = 10.0,
                 limit_torques: bool = True, pose: np.ndarray | None = None
                 ) -> tuple[np.ndarray, int]:
    """Change ``model`` in place so that every hinge/slide joint is PD-held at ``pose``
    (default ``qpos0``; module docstring). Returns the constant control vector that holds the
    robot (servo targets from ``pose``, zero elsewhere) and the number of torque-limited
    joints."""
    pose = model.qpos0 if pose is None else pose
    limits = torque_limits(model) if limit_torques else {}
    mass = float(model.body_subtreemass[0])
    g = float(np.linalg.norm(model.opt.gravity)) or 9.81
    dt = model.opt.timestep
    servo: dict[int, int] = {}  # joint -> actuator
    for u in range(model.nu):
        j = int(model.actuator_trnid[u, 0])
        if (model.actuator_trntype[u] == _TRN_JOINT and model.actuator_actnum[u] == 0
                and model.jnt_type[j] in MOVING and j not in servo):
            servo[j] = u
    model.actuator_gaintype[:] = _GAIN_FIXED  # every actuator off unless made a servo
    model.actuator_biastype[:] = _BIAS_NONE
    model.actuator_gainprm[:] = 0.0
    model.actuator_biasprm[:] = 0.0
    ctrl = np.zeros(model.nu)
    limited = 0
    for j in range(model.njnt):
        if model.jnt_type[j] not in MOVING:
            continue
        dof, qadr = model.jnt_dofadr[j], model.jnt_qposadr[j]
        inertia = float(model.dof_M0[dof])
        kp = min(stiffness * mass * g * extent, 0.1 * inertia / dt ** 2)
        kv = 2.0 * math.sqrt(kp * inertia)
        a = servo.get(j)
        if a is None:
            model.jnt_stiffness[j] = kp
            model.qpos_spring[qadr] = pose[qadr]
            model.dof_damping[dof] += kv
            continue
        model.actuator_biastype[a] = _BIAS_AFFINE
        model.actuator_gainprm[a, 0] = kp
        model.actuator_biasprm[a, :3] = (0.0, -kp, -kv)
        model.actuator_gear[a] = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        model.actuator_ctrllimited[a] = 0
        lim = limits.get(j, math.inf)
        model.actuator_forcelimited[a] = int(math.isfinite(lim) and lim > 0)
        if model.actuator_forcelimited[a]:
            model.actuator_forcerange[a] = (-lim, lim)
            limited += 1
        ctrl[a] = pose[qadr]
    return ctrl, limited


class HeldRun:
    """The standing test's simulation of one staged robot, run in segments: a copy of the
    stage's model with integrator ``implicitfast`` and every hinge/slide joint PD-held at the
    rest pose (:func:`hold_at_rest`), started at rest, continued by :meth:`run`.

    The validator (:func:`robovae.generate.validate.check_robot`) runs the first second and
    :func:`standing` continues from where it stopped: the robot is simulated once. Segments
    run but not yet judged by :func:`standing` wait in ``pending``.

    Attributes:
        stage: the robot on its floor (its ``data`` serves as the rollouts' scratch data).
        model: the held copy of ``stage.model``.
        pose: the rest pose (:func:`~robovae.evaluate.quality.stage.rest_pose`).
        ctrl: the constant control that holds the robot.
        limited: joints held with a torque limit.
        state: full physics state after ``done`` steps.
        warmstart: the solver's warm start after ``done`` steps (with ``state``, what makes a
            run in segments the same trajectory, to the bit, as a run in one piece).
        start, start_warmstart: the state and warm start at rest, before the first step.
        done: steps simulated.
        can_sleep: MuJoCo can sleep the model (no flex, no tendon or flex equality).
        pending: ``[steps, state]`` arrays of the segments :func:`standing` has not judged.
        h0: the root's height above the robot's lowest point at rest (m).
        up_local: the root's local axis that points up at rest.
    """

    STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS

    def __init__(self, st: Stage, stiffness: float = 10.0, limit_torques: bool = True) -> None:
        self.stage = st
        self.model = stage(st, integrator=mujoco.mjtIntegrator.mjINT_IMPLICITFAST).model
        # MuJoCo keeps actuated trees awake by default; the hold is a constant control
        self.model.tree_sleep_policy[:] = int(mujoco.mjtSleepPolicy.mjSLEEP_ALLOWED)
        self.can_sleep = not (self.model.nflex or np.isin(self.model.eq_type, _NO_SLEEP).any())
        self.pose = rest_pose(self.model)
        self.ctrl, self.limited = hold_at_rest(self.model, st.extent, stiffness, limit_torques,
                                               self.pose)
        model, data, root = self.model, st.data, st.root
        mujoco.mj_resetData(model, data)
        data.qpos[:] = self.pose
        quiet_forward(model, data)
        self.h0 = float(data.xpos[root, 2] - robot_points(model, data, root)[:, 2].min())
        self.up_local = data.xmat[root].reshape(3, 3).T @ np.array([0.0, 0.0, 1.0])
        self.state = np.empty(mujoco.mj_stateSize(model, self.STATE))
        mujoco.mj_getState(model, data, self.state, self.STATE)
        self.t0 = float(self.state[0])
        self.warmstart = data.qacc_warmstart.copy()
        self.start, self.start_warmstart = self.state.copy(), self.warmstart.copy()
        self.done = 0
        self.pending: list[np.ndarray] = []

    def run(self, nstep: int, sleep: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Simulate ``nstep`` more steps in one ``mujoco.rollout`` call: the ``[nstep, state]``
        states and ``[nstep, sensordata]`` sensor values (the segment is also queued in
        ``pending``). MuJoCo's warnings accumulate in ``stage.data`` (reset when the run
        started, and when a segment sleeps).

        ``sleep > 0``: MuJoCo's sleeping on for this segment, at that tolerance (module
        docstring), when the model allows it (``can_sleep``); the segment starts awake (the
        stage's data is reset with the flag on, which initialises MuJoCo's sleep state: the
        rollout then sets the whole state)."""
        if sleep > 0 and self.can_sleep:
            self.model.opt.enableflags |= _SLEEP
            self.model.opt.sleep_tolerance = sleep
            mujoco.mj_resetData(self.model, self.stage.data)
        else:
            self.model.opt.enableflags &= ~_SLEEP
        with capture_mujoco_warnings():
            states, sensors = rollout.rollout(self.model, self.stage.data, self.state[None],
                                              self.ctrl[None, None], nstep=nstep,
                                              initial_warmstart=self.warmstart[None])
        self.state = states[0, -1].copy()
        self.warmstart = self.stage.data.qacc_warmstart.copy()
        self.done += nstep
        self.pending.append(states[0])
        return states[0], sensors[0]

    def rest(self) -> None:
        """Leave the stage's data at rest (``qpos0``, ``mj_forward`` on the stage's model), for
        the measures at rest; the run continues from ``state``."""
        mujoco.mj_resetData(self.stage.model, self.stage.data)
        quiet_forward(self.stage.model, self.stage.data)


#: Seconds of the first segment of the standing test: the validation's simulated second
#: (:func:`robovae.generate.validate.check_robot`), after which a robot at rest may stop.
FIRST_SECONDS = 1.0


def first_steps(model: mujoco.MjModel, seconds: float = FIRST_SECONDS) -> int:
    """Steps of a segment of ``seconds`` at the model's time step (at least 1)."""
    return max(1, math.ceil(seconds / model.opt.timestep))


def standing(robot: Robot, seconds: float = 3.0, stiffness: float = 10.0,
             limit_torques: bool = True, min_height: float = 0.5, max_tilt: float = 45.0,
             sample_dt: float = 0.02, max_steps: int = 10_000, chunk_seconds: float = 0.5,
             rest: float = 1e-3, held: HeldRun | None = None) -> StandResult:
    """The standing test of a robot file, spec, model with a floor or stage (module docstring).

    ``max_steps`` caps the physics steps: a robot with a tiny time step is tested for less than
    ``seconds`` (``StandResult.seconds`` says how long). The simulation runs in rollouts, the
    first of :data:`FIRST_SECONDS`, then of ``chunk_seconds``, and stops early at the first
    failing sample or when the robot is at rest (after at least 1 s, every ``|qvel|`` below
    ``rest``, m/s or rad/s; after the first second MuJoCo's sleeping, at tolerance ``rest``,
    freezes a robot at rest: module docstring; ``rest = 0``: neither). ``held``: the
    simulation of ``robot`` (a stage) already begun, by the validator, with the same
    ``stiffness`` and ``limit_torques``: its segments are judged first, then it is continued
    (the same result as starting afresh).

    Raises:
        RobovaeError: a model without a floor; RobotFileError: a file that does not load;
        SettingsError: a setting out of range (``seconds``, ``sample_dt`` and ``chunk_seconds``
            not > 0, ``stiffness``, ``min_height`` or ``rest`` negative, ``max_tilt`` outside
            ``[0, 180]``, ``max_steps`` below 1).
    """
    check_settings("standing", seconds=(seconds, number(0, low_open=True)),
                   stiffness=(stiffness, number(0)), min_height=(min_height, number(0)),
                   max_tilt=(max_tilt, number(0, 180)),
                   sample_dt=(sample_dt, number(0, low_open=True)),
                   max_steps=(max_steps, integer(1)),
                   chunk_seconds=(chunk_seconds, number(0, low_open=True)),
                   rest=(rest, number(0)))
    if held is None:
        st = stage(robot)
        if not st.free:
            return StandResult(floating=False)
        held = HeldRun(st, stiffness, limit_torques)
    elif not held.stage.free:
        return StandResult(floating=False)
    try:
        return _judge(held, seconds, min_height, max_tilt, sample_dt, max_steps,
                      chunk_seconds, rest)
    finally:
        if isinstance(robot, Stage):  # the caller's stage is left at rest
            held.rest()


def _judge(held: HeldRun, seconds: float, min_height: float, max_tilt: float,
           sample_dt: float, max_steps: int, chunk_seconds: float, rest: float) -> StandResult:
    """The verdict of :func:`standing` over ``held``'s segments, run as needed.

    Samples are taken every ``sample_dt`` of simulated time and at the end of every segment;
    the values reported for a fallen robot are those up to its failing sample, so that they do
    not depend on how the simulation was cut into segments."""
    model, st = held.model, held.stage
    dt = model.opt.timestep
    steps = min(max(1, round(seconds / dt)), max_steps)
    every = max(1, round(sample_dt / dt))
    chunk = max(every, round(chunk_seconds / dt) // every * every)
    qadr = model.jnt_qposadr[model.body_jntadr[st.root]]
    fell_at, min_ratio, worst, ratio, tilt = None, math.inf, 0.0, math.nan, 0.0
    if held.done != sum(len(p) for p in held.pending):
        raise ValueError("standing: the held run was judged already (start a new HeldRun)")
    bad, settled, done, t_prev = False, False, 0, held.t0
    while done < steps and fell_at is None and not bad and not settled:
        if held.pending:
            s = held.pending.pop(0)
        else:
            s = (held.run(chunk, sleep=rest) if done else held.run(first_steps(model)))[0]
            held.pending.pop()
        n = min(len(s), steps - done)
        s = s[:n]
        # MuJoCo resets the state (time jumps back) on a bad acceleration
        bad = (unstable(st.data) or not np.isfinite(s).all()
               or bool(np.any(np.diff(s[:, 0]) <= 0)) or s[0, 0] <= t_prev)
        t_prev = float(s[-1, 0])
        picks = np.flatnonzero((done + np.arange(1, n + 1)) % every == 0)
        if not len(picks) or picks[-1] != n - 1:
            picks = np.append(picks, n - 1)
        q = s[picks, 1 + qadr:1 + qadr + 7]  # the free joint: position, quaternion
        z = q[:, 2]
        w, x, y, qz = q[:, 3], q[:, 4], q[:, 5], q[:, 6]
        norm = np.maximum(w * w + x * x + y * y + qz * qz, 1e-12)
        row = np.stack([2 * (x * qz - w * y), 2 * (y * qz + w * x),
                        w * w - x * x - y * y + qz * qz], axis=1) / norm[:, None]
        up_z = np.clip(row @ held.up_local, -1.0, 1.0)  # world z of the local up axis
        ratios = (z - st.floor_z) / max(held.h0, 1e-9)
        tilts = np.degrees(np.arccos(up_z))
        ok = np.isfinite(ratios) & np.isfinite(tilts)
        failed = np.flatnonzero(~ok | (ratios < min_height) | (tilts > max_tilt))
        if failed.size:  # up to the failing sample only
            fell_at = (done + picks[failed[0]] + 1) * dt
            ok[failed[0] + 1:] = False
        if ok.any():
            ratio, tilt = float(ratios[ok][-1]), float(tilts[ok][-1])
            min_ratio = min(min_ratio, float(ratios[ok].min()))
            worst = max(worst, float(tilts[ok].max()))
        done += n
        qvel = s[-1, 1 + model.nq:1 + model.nq + model.nv]
        settled = done * dt >= FIRST_SECONDS and bool(np.abs(qvel).max(initial=0.0) < rest)
    held.pending.clear()
    if bad and fell_at is None:
        fell_at = done * dt
    return StandResult(
        floating=True, stands=fell_at is None and not bad,
        up=bool(ratio >= min_height) and not bad, upright=bool(tilt <= max_tilt) and not bad,
        fell_at=fell_at, height_ratio=ratio,
        min_height_ratio=min_ratio if math.isfinite(min_ratio) else math.nan,
        max_tilt=worst, unstable=bool(bad), limited_joints=held.limited, seconds=done * dt,
        settled=settled)
