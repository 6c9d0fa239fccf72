"""Is a robot simulatable? Load it with MuJoCo, put it on a floor, simulate, classify.

A robot is ``valid`` when all of these hold (SPEC §4, validity):

1. ``compile``: the file compiles with MuJoCo (a floor plane is added when the file has none);
   ``degenerate``: it has at least one joint besides a free base (a rigid body is not a
   robot);
2. ``self_penetration``: at rest (``mj_forward`` of the initial pose) no two robot geoms
   penetrate deeper than ``penetration_tol`` metres (contacts with the floor do not count);
3. ``nan_inf``: qpos/qvel stay finite during ``duration`` seconds (1 s) of simulation;
4. ``mujoco_warning``: MuJoCo raises none of its instability warnings (bad qacc/qpos/qvel,
   inertia, contact/constraint buffer full);
5. ``energy_blowup``: the kinetic energy stays below ``energy_factor`` times the energy scale
   ``m g max(h, 1 m) + 1 J`` (total mass ``m``, robot height ``h``, at ``qpos0``): a robot that
   only falls or collapses stays far below it, a numerically exploding one does not.

The first failing check gives the reason. Which simulation (``controls``):

- ``"held"`` (default): the robot powered on and holding its pose, i.e. the first second of the
  standing test (:mod:`robovae.evaluate.quality.standing`), for floating and fixed-base robots
  alike: the floor is moved to the robot's lowest point at ``qpos0``
  (:func:`~robovae.evaluate.quality.stage.stage_compiled`), the integrator is
  ``implicitfast``, every hinge and slide joint is PD-held at the rest pose
  (:func:`~robovae.evaluate.quality.standing.hold_at_rest`) and the robot starts there. The
  standing test then continues this simulation instead of starting another
  (:class:`~robovae.evaluate.quality.standing.HeldRun`);
- ``"zero"``: zero controls, the model's own integrator and time step, from ``qpos0``, floor
  plane at ``z = 0`` (the definition until 2026-11-25).

The simulation runs in one ``mujoco.rollout`` call (no Python per step; the kinetic energy of
each step comes from an ``e_kinetic`` sensor added to the model); a robot that fails is
replayed one ``mj_step`` at a time, the same trajectory, for the exact step and reason.
:func:`check_robot` also returns the spec, compiled model, stage and held run, so that the
quality measures need not load the file again. :func:`validate_many` runs robots in worker
processes.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np
from mujoco import rollout

from robovae.data.loading import (
    capture_mujoco_warnings,
    drop_missing_assets,
    mujoco_error_line,
)
from robovae.data.robot_file import scan_robot_file
from robovae.data.workers import process_pool
from robovae.errors import RobotFileError
from robovae.evaluate.quality.stage import FLOOR, Stage, stage_compiled
from robovae.evaluate.quality.standing import HeldRun, first_steps
from robovae.settings import check_settings, choice, number

_BAD_WARNINGS = {
    mujoco.mjtWarning.mjWARN_BADQACC: "bad qacc",
    mujoco.mjtWarning.mjWARN_BADQPOS: "bad qpos",
    mujoco.mjtWarning.mjWARN_BADQVEL: "bad qvel",
    mujoco.mjtWarning.mjWARN_INERTIA: "inertia",
    mujoco.mjtWarning.mjWARN_CONTACTFULL: "contact buffer full",
    mujoco.mjtWarning.mjWARN_CNSTRFULL: "constraint buffer full",
}
_KINETIC = "robovae_kinetic_energy"
_NO_SENSORS = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
REASONS = ("valid", "compile", "degenerate", "self_penetration", "nan_inf", "mujoco_warning",
           "energy_blowup")
#: The simulations a robot can be validated with (module docstring).
CONTROLS = ("held", "zero")
_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass
class Validation:
    """Outcome of :func:`validate_robot`.

    Attributes:
        path: the file validated.
        valid: all checks passed.
        reason: ``valid`` or the first failed check (see :data:`REASONS`).
        detail: a one-line explanation.
        steps: simulation steps done.
        max_kinetic: largest kinetic energy seen (J).
        energy_scale: ``m g h + 1`` (J).
    """

    path: str
    valid: bool
    reason: str
    detail: str = ""
    steps: int = 0
    max_kinetic: float = 0.0
    energy_scale: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready dictionary of the validation result."""
        return asdict(self)


def _compile(path: Path) -> tuple[mujoco.MjSpec, mujoco.MjsGeom | None, mujoco.MjModel]:
    """The robot's spec with a floor plane (:data:`FLOOR` added at ``z = 0`` when the world has
    no plane; that geom, else None) and a kinetic-energy sensor (mujoco.rollout gives every
    step's sensor data), and its compiled model."""
    spec = mujoco.MjSpec.from_file(str(path))
    drop_missing_assets(spec)
    spec.add_sensor(name=_KINETIC, type=mujoco.mjtSensor.mjSENS_E_KINETIC)
    floor = None
    if not any(g.type == mujoco.mjtGeom.mjGEOM_PLANE for g in spec.worldbody.geoms):
        floor = spec.worldbody.add_geom(name=FLOOR, type=mujoco.mjtGeom.mjGEOM_PLANE,
                                        size=[0, 0, 0.05])
    return spec, floor, spec.compile()


def _why_not(path: Path, e: Exception) -> str:
    """What is wrong with a file MuJoCo did not load, in one line: the robot-file check's
    finding (a folder, a missing or empty file, ...), else MuJoCo's message as the loader words
    it (``malformed XML (XML_ERROR_...) (line N)``). Run only after a failure: a valid robot's
    path stays as lean as it was."""
    try:
        scan_robot_file(path)
    except RobotFileError as found:
        return found.line().removeprefix(f"robovae: {found.path}: ")
    return mujoco_error_line(str(e)) if str(e).strip() else type(e).__name__


def _step_by_step(path: Path, model: mujoco.MjModel, data: mujoco.MjData, start: np.ndarray,
                  warmstart: np.ndarray, ctrl: np.ndarray, steps: int, scale: float,
                  energy_factor: float) -> Validation:
    """Checks 3-5, one ``mj_step`` at a time from the full physics state ``start`` (with the
    solver's ``warmstart`` and the constant control ``ctrl``, as the rollout ran them):
    the exact step and reason of a failure. ``data`` is reset first."""
    fail = lambda reason, detail, **kw: Validation(str(path), False, reason,  # noqa: E731
                                                    detail, **kw)
    mujoco.mj_resetData(model, data)
    mujoco.mj_setState(model, data, start, _STATE)
    data.qacc_warmstart[:] = warmstart
    data.ctrl[:] = ctrl
    max_kin = 0.0
    for k in range(steps):
        mujoco.mj_step(model, data)
        for w, name in _BAD_WARNINGS.items():
            if data.warning[w].number:
                return fail("mujoco_warning", f"MuJoCo warning '{name}' at step {k}",
                            steps=k + 1, max_kinetic=max_kin, energy_scale=scale)
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            return fail("nan_inf", f"non-finite state at step {k}", steps=k + 1,
                        max_kinetic=max_kin, energy_scale=scale)
        max_kin = max(max_kin, float(data.energy[1]))
        if max_kin > energy_factor * scale:
            return fail("energy_blowup", f"kinetic energy {max_kin:.3g} J > "
                        f"{energy_factor:g} x {scale:.3g} J at step {k}", steps=k + 1,
                        max_kinetic=max_kin, energy_scale=scale)
    return Validation(str(path), True, "valid", "", steps, max_kin, scale)


def _verdict(path: Path, model: mujoco.MjModel, data: mujoco.MjData, states: np.ndarray,
             sensors: np.ndarray, steps: int, scale: float, energy_factor: float
             ) -> Validation | None:
    """Checks 3-5 on the ``[steps, state]`` states and ``[steps, sensordata]`` sensor values of
    one rollout (``data``: its data after it): the valid result, or None when anything looks
    wrong (the caller then replays the steps one by one for the exact failure)."""
    # the sensor reads data.energy before the step's forward pass renews it (with any
    # integrator): the sensor of step k holds the energy of step k - 1, the data the last one
    kinetic = sensors[1:, model.sensor_adr[model.sensor(_KINETIC).id]]
    max_kin = max(float(kinetic.max(initial=0.0)), float(data.energy[1]), 0.0)
    if (data.warning.number.any() or not np.isfinite(states).all()
            or not np.isfinite(max_kin) or max_kin > energy_factor * scale):
        return None
    return Validation(str(path), True, "valid", "", steps, max_kin, scale)


def _zero(path: Path, model: mujoco.MjModel, data: mujoco.MjData, steps: int, scale: float,
          energy_factor: float) -> Validation:
    """Checks 3-5 with zero controls from ``data``'s state (``mj_forward`` at ``qpos0``, energy
    flag on), in one ``mujoco.rollout`` call, replayed step by step when anything looks wrong
    (the same trajectory)."""
    start = np.empty(mujoco.mj_stateSize(model, _STATE))
    mujoco.mj_getState(model, data, start, _STATE)
    warmstart = data.qacc_warmstart.copy()
    if not (data.warning.number.any() or model.opt.disableflags & _NO_SENSORS):
        states, sensors = rollout.rollout(model, data, start[None], nstep=steps,
                                          initial_warmstart=warmstart[None])
        v = _verdict(path, model, data, states[0], sensors[0], steps, scale, energy_factor)
        if v is not None:
            return v
    return _step_by_step(path, model, data, start, warmstart, np.zeros(model.nu), steps, scale,
                         energy_factor)


def _held(path: Path, held: HeldRun, steps: int, scale: float, energy_factor: float
          ) -> Validation:
    """Checks 3-5 on the first ``steps`` of the held simulation (energy flag on while it runs),
    replayed step by step from the rest pose when anything looks wrong."""
    model, data = held.model, held.stage.data
    flags = model.opt.enableflags
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    try:
        if not (data.warning.number.any() or model.opt.disableflags & _NO_SENSORS):
            states, sensors = held.run(steps)
            v = _verdict(path, model, data, states, sensors, steps, scale, energy_factor)
            if v is not None:
                return v
        return _step_by_step(path, model, data, held.start, held.start_warmstart, held.ctrl,
                             steps, scale, energy_factor)
    finally:
        model.opt.enableflags = flags


class Checked(NamedTuple):
    """Outcome of :func:`check_robot`: the validation, and the robot as it was checked (None
    when the file did not compile)."""

    validation: Validation
    model: mujoco.MjModel | None  # compiled from spec (floor at z = 0)
    spec: mujoco.MjSpec | None  # the file's, with a floor and a kinetic-energy sensor
    floor: mujoco.MjsGeom | None  # the floor plane added (None: the file's own)
    data: mujoco.MjData | None = None  # model's, mj_forward at qpos0 (None: not simulated)
    stage: Stage | None = None  # held: the robot on its floor at its lowest point, data at rest
    held: HeldRun | None = None  # held: the simulation, its first second run (valid robots)


def check_robot(path: str | Path, duration: float = 1.0, penetration_tol: float = 0.01,
                energy_factor: float = 100.0, controls: str = "held") -> Checked:
    """:func:`validate_robot`, and the robot as it was checked, so that the quality measures
    need not load it again: its spec with a floor plane (its own, or :data:`FLOOR` added at
    ``z = 0``) and a kinetic-energy sensor, the compiled model (flags as in the file) and its
    data at rest; with ``controls="held"`` also the robot staged on its floor
    (:func:`~robovae.evaluate.quality.stage.stage_compiled`, which moves the added floor to the
    robot's lowest point and compiles the spec again) and the held simulation, whose first
    ``duration`` seconds were the validation's (the standing test continues it:
    :func:`~robovae.evaluate.quality.standing.standing` with ``held``)."""
    check_settings("validate_robot", duration=(duration, number(0, low_open=True)),
                   penetration_tol=(penetration_tol, number(0)),
                   energy_factor=(energy_factor, number(0, low_open=True)),
                   controls=(controls, choice(CONTROLS)))
    path = Path(path)
    fail = lambda reason, detail, **kw: Validation(str(path), False, reason,  # noqa: E731
                                                    " ".join(str(detail).split()), **kw)
    with capture_mujoco_warnings():
        try:
            spec, floor, model = _compile(path)
        except Exception as e:
            return Checked(fail("compile", _why_not(path, e)), None, None, None)
        if not (model.jnt_type != mujoco.mjtJoint.mjJNT_FREE).any():
            return Checked(fail("degenerate", f"{model.nbody - 1} bodies and no joint besides a "
                                "free base: nothing moves"), model, spec, floor)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        robot_geom = model.geom_bodyid != 0
        pair, dist = data.contact.geom, data.contact.dist
        deep = np.flatnonzero(robot_geom[pair].all(axis=1) & (dist < -penetration_tol))
        if deep.size:
            (g1, g2), d = pair[deep[0]], dist[deep[0]]
            return Checked(fail("self_penetration", f"geoms {g1} and {g2} overlap by {-d:.3f} m "
                                "at rest"), model, spec, floor)
        mass = float(model.body_subtreemass[0])
        height = float(np.ptp(data.geom_xpos[robot_geom, 2])) if robot_geom.any() else 0.0
        scale = mass * 9.81 * max(height, 1.0) + 1.0
        if controls == "zero":
            steps = max(1, math.ceil(duration / model.opt.timestep))
            flags = model.opt.enableflags
            model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
            try:
                v = _zero(path, model, data, steps, scale, energy_factor)
            finally:
                model.opt.enableflags = flags
            mujoco.mj_resetData(model, data)
            mujoco.mj_forward(model, data)
            return Checked(v, model, spec, floor, data)
        st = stage_compiled(model, spec, floor, data)
        held = HeldRun(st)
        v = _held(path, held, first_steps(held.model, duration), scale, energy_factor)
        held.rest()
    return Checked(v, model, spec, floor, st.data, st, held)


def validate_robot(path: str | Path, duration: float = 1.0, penetration_tol: float = 0.01,
                   energy_factor: float = 100.0, controls: str = "held") -> Validation:
    """Validate one robot file (``robot.xml`` or a ``scene.xml`` including it) with the checks
    of the module docstring: ``duration`` in s, ``penetration_tol`` in m, ``energy_factor``
    times the energy scale, ``controls`` ``"held"`` or ``"zero"``. A robot that fails (also one
    whose file does not load) is not an error: the first failed check is the result's
    ``reason``."""
    return check_robot(path, duration, penetration_tol, energy_factor, controls).validation


def _validate_kw(args: tuple[str, dict]) -> dict:
    path, kw = args
    try:
        return validate_robot(path, **kw).to_dict()
    except Exception as e:  # a validator bug must not kill a 10,000-robot run
        return Validation(path, False, "compile", f"validator error: {e}").to_dict()


def validate_many(paths: Sequence[str | Path], jobs: int = 0, chunksize: int = 16,
                  **kw: Any) -> list[Validation]:
    """Validate many robots in ``jobs`` worker processes (0: all cores; spawned:
    :func:`robovae.data.workers.process_pool`), in input order;
    ``kw`` as in :func:`validate_robot`."""
    jobs = jobs or (os.cpu_count() or 1)
    items = [(str(p), kw) for p in paths]
    if jobs == 1 or len(items) < 8:
        return [Validation(**_validate_kw(i)) for i in items]
    with process_pool(jobs) as pool:
        return [Validation(**r) for r in pool.map(_validate_kw, items, chunksize=chunksize)]
