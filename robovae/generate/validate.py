"""Is a robot simulatable? Load it with MuJoCo, put it on a floor, simulate, classify.

A robot is ``valid`` when all of these hold (SPEC §4, validity):

1. ``compile``: the file compiles with MuJoCo (a floor plane is added when the file has none);
   ``degenerate``: it has at least one joint besides a free base (a rigid body is not a
   robot);
2. ``self_penetration``: at rest (``mj_forward`` of the initial pose) no two robot geoms
   penetrate deeper than ``penetration_tol`` metres (contacts with the floor do not count);
3. ``nan_inf``: qpos/qvel stay finite during ``duration`` seconds of simulation at the model's
   own timestep with zero controls;
4. ``mujoco_warning``: MuJoCo raises none of its instability warnings (bad qacc/qpos/qvel,
   inertia, contact/constraint buffer full);
5. ``energy_blowup``: the kinetic energy stays below ``energy_factor`` times the energy scale
   ``m g max(h, 1 m) + 1 J`` (total mass ``m``, robot height ``h``): a robot that only falls
   or collapses stays far below it, a numerically exploding one does not.

The first failing check gives the reason. :func:`validate_many` runs robots in worker
processes.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings, drop_missing_assets

_BAD_WARNINGS = {
    mujoco.mjtWarning.mjWARN_BADQACC: "bad qacc",
    mujoco.mjtWarning.mjWARN_BADQPOS: "bad qpos",
    mujoco.mjtWarning.mjWARN_BADQVEL: "bad qvel",
    mujoco.mjtWarning.mjWARN_INERTIA: "inertia",
    mujoco.mjtWarning.mjWARN_CONTACTFULL: "contact buffer full",
    mujoco.mjtWarning.mjWARN_CNSTRFULL: "constraint buffer full",
}
REASONS = ("valid", "compile", "degenerate", "self_penetration", "nan_inf", "mujoco_warning",
           "energy_blowup")


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


def _with_floor(spec: mujoco.MjSpec) -> mujoco.MjSpec:
    world = spec.worldbody
    if not any(g.type == mujoco.mjtGeom.mjGEOM_PLANE for g in world.geoms):
        floor = world.add_geom()
        floor.name = "robovae_floor"
        floor.type = mujoco.mjtGeom.mjGEOM_PLANE
        floor.size = [0, 0, 0.05]
    return spec


def _compile(path: Path) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(path))
    drop_missing_assets(spec)
    return _with_floor(spec).compile()


def validate_robot(path: str | Path, duration: float = 1.0, penetration_tol: float = 0.01,
                   energy_factor: float = 100.0) -> Validation:
    """Validate one robot file (``robot.xml`` or a ``scene.xml`` including it) with the checks
    of the module docstring: ``duration`` in s, ``penetration_tol`` in m, ``energy_factor``
    times the energy scale. A robot that fails (also one whose file does not load) is not an
    error: the first failed check is the result's ``reason``."""
    path = Path(path)
    fail = lambda reason, detail, **kw: Validation(str(path), False, reason,  # noqa: E731
                                                    " ".join(str(detail).split()), **kw)
    with capture_mujoco_warnings():
        try:
            model = _compile(path)
        except Exception as e:
            return fail("compile", str(e).strip().splitlines()[0] if str(e).strip() else e)
        if not (model.jnt_type != mujoco.mjtJoint.mjJNT_FREE).any():
            return fail("degenerate", f"{model.nbody - 1} bodies and no joint besides a free "
                        "base: nothing moves")
        model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        robot_geom = model.geom_bodyid != 0
        for c in data.contact[: data.ncon]:
            if robot_geom[c.geom1] and robot_geom[c.geom2] and c.dist < -penetration_tol:
                return fail("self_penetration", f"geoms {c.geom1} and {c.geom2} overlap by "
                            f"{-c.dist:.3f} m at rest")
        mass = float(model.body_subtreemass[0])
        height = float(np.ptp(data.geom_xpos[robot_geom, 2])) if robot_geom.any() else 0.0
        scale = mass * 9.81 * max(height, 1.0) + 1.0
        steps = max(1, math.ceil(duration / model.opt.timestep))
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


def _validate_kw(args: tuple[str, dict]) -> dict:
    path, kw = args
    try:
        return validate_robot(path, **kw).to_dict()
    except Exception as e:  # a validator bug must not kill a 10,000-robot run
        return Validation(path, False, "compile", f"validator error: {e}").to_dict()


def validate_many(paths: Sequence[str | Path], jobs: int = 0, chunksize: int = 16,
                  **kw) -> list[Validation]:
    """Validate many robots in ``jobs`` worker processes (0: all cores), in input order."""
    jobs = jobs or (os.cpu_count() or 1)
    items = [(str(p), kw) for p in paths]
    if jobs == 1 or len(items) < 8:
        return [Validation(**_validate_kw(i)) for i in items]
    with ProcessPoolExecutor(jobs) as pool:
        return [Validation(**r) for r in pool.map(_validate_kw, items, chunksize=chunksize)]
