"""Every quality measure of one robot as one flat record, and of many robots in worker
processes with a progress bar.

:func:`measure` loads and compiles the robot once (a floor is added when it has none,
:func:`~robovae.evaluate.quality.stage.prepare`), or takes it compiled (a model with a floor, or
a :class:`~robovae.evaluate.quality.stage.Stage`: ``robovae generate`` reuses the validator's
model, :func:`~robovae.evaluate.quality.stage.stage_compiled`), and runs on that model:

- ``bodies``, ``dof``, ``mass``, ``limbs``: counts
  (:func:`~robovae.evaluate.quality.symmetry.anatomy`); ``pairs``, ``symmetric``,
  ``one_limb``: mirrored limb pairs; ``wheeled``: an actuator drives a hinge without limits
  (a wheel or rotor: :func:`~robovae.evaluate.quality.locomotion.continuous_actuators`), so
  that a gait speed can be told rolling from stepping;
- ``judged``, ``detached``, ``all_attached``, ``detached_share``: bodies judged / detached
  (:mod:`~robovae.evaluate.quality.attachment`); ``penetration``: deepest self-penetration at
  rest over the extent; ``self_penetrating``: a contact deeper than 1 % of the extent;
  ``penetrating_off_joint``: such a contact between bodies whose tree path is longer than
  their geoms are thick together (bodies passing through each other, not links meeting at a
  cluster of joints: the attachment module's docstring);
- ``floating``, ``stands``, ``fell_at``, ``stand_tilt``: the standing test
  (:mod:`~robovae.evaluate.quality.standing`; ``stands`` None when not floating);
- ``gait_speed`` (extents/s), ``gait_speed_m_s``: with ``locomotion``, the best gait
  (:mod:`~robovae.evaluate.quality.locomotion`; random gaits, or with ``gait_search="cma"``
  tuned by CMA-ES at the same budget:
  :func:`~robovae.evaluate.quality.gait_search.budget_gait`);
- ``d_<descriptor>``: graph descriptors (``VECTOR_DESCRIPTORS`` of
  :mod:`robovae.evaluate.descriptors`, ``paper34`` graph of the model);
- ``t_<measure>``: seconds each measure took.

A robot that cannot be loaded or measured gets ``error`` (one line) instead: a bad robot never
stops a population.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from contextlib import nullcontext
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import mujoco

from robovae.data.workers import process_pool
from robovae.errors import SettingsError
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.quality.gait_search import budget_gait
from robovae.evaluate.quality.locomotion import continuous_actuators
from robovae.evaluate.quality.stage import Robot, Stage, prepare, stage
from robovae.evaluate.quality.standing import HeldRun, standing
from robovae.evaluate.quality.symmetry import anatomy
from robovae.settings import check_settings, integer

__all__ = ["QUALITY_KEYS", "measure", "measure_many", "robot_quality"]

#: The fields of :func:`robot_quality` (generation's manifest and summary).
QUALITY_KEYS = ("all_attached", "detached_share", "self_penetrating", "penetrating_off_joint",
                "symmetric", "one_limb", "floating", "stands", "limbs", "bodies", "dof", "mass")


_P = ParamSpec("_P")
_T = TypeVar("_T")


def _timed(out: dict, key: str, fn: Callable[_P, _T], *args: _P.args,
           **kwargs: _P.kwargs) -> _T:
    t = time.perf_counter()
    try:
        return fn(*args, **kwargs)
    finally:
        out[f"t_{key}"] = time.perf_counter() - t


def measure(robot: Robot, locomotion: bool = False, describe: bool = True,
            gait_kw: dict | None = None, stand_kw: dict | None = None,
            name: str | None = None, held: HeldRun | None = None,
            gait_search: str = "random") -> dict:
    """The quality record of one robot file, spec, model with a floor or stage (module
    docstring). ``gait_kw`` and ``stand_kw`` are passed to
    :func:`~robovae.evaluate.quality.gait_search.budget_gait` (with ``gait_search``) and
    :func:`~robovae.evaluate.quality.standing.standing`; ``name`` defaults to the spec's model
    name or the file stem (the folder for ``robot_<i>/robot.xml``), ``""`` for a model.
    ``held``: the standing test's simulation of ``robot`` (a stage) already begun by the
    validator (:func:`robovae.generate.validate.check_robot`), continued instead of run again
    (ignored when ``stand_kw`` changes the hold).

    A robot that cannot be measured gets ``error`` (one line) in its record.

    Raises:
        SettingsError: a setting of ``gait_kw``, ``stand_kw`` or ``gait_search`` out of range
            (every robot would fail alike).
    """
    compiled = isinstance(robot, (Stage, mujoco.MjModel))
    if name is None:
        if isinstance(robot, (Stage, mujoco.MjModel)):  # compiled, spelled out to narrow robot
            name = ""
        elif isinstance(robot, mujoco.MjSpec):
            name = robot.modelname
        else:
            name = Path(robot).stem
            if name == "robot":  # robovae generate's robot_<i>/robot.xml
                name = Path(robot).parent.name
    path = None if compiled or isinstance(robot, mujoco.MjSpec) else str(robot)
    out: dict = {"name": name, "path": path}
    try:
        st = _timed(out, "load", stage if compiled else lambda r: prepare(r)[1], robot)
        model = st.model
        a = _timed(out, "anatomy", anatomy, st)
        out.update(bodies=a.bodies, dof=a.dof, mass=a.mass, limbs=a.limbs, pairs=a.pairs,
                   symmetric=a.symmetric, one_limb=a.one_limb, extent=st.extent,
                   wheeled=bool(continuous_actuators(model).any()))
        at = _timed(out, "attachment", attachment, st)
        out.update(judged=at.bodies, detached=at.detached, all_attached=at.all_attached,
                   detached_share=at.detached_share, penetration=at.penetration / at.extent,
                   self_penetrating=at.penetrating_pairs > 0,
                   penetrating_off_joint=at.off_joint_pairs > 0)
        kw = dict(stand_kw or {})
        if held is not None and held.stage is st and not {"stiffness", "limit_torques"} & set(kw):
            kw["held"] = held
        s = _timed(out, "standing", standing, st, **kw)
        out.update(floating=s.floating, stands=s.stands, fell_at=s.fell_at,
                   stand_tilt=s.max_tilt)
        if describe:  # graph descriptors need the PyG graph (torch): imported only here, so
            # that generation's workers (robot_quality) never load torch
            from robovae.data.mjcf import model_to_graph
            from robovae.evaluate.descriptors import VECTOR_DESCRIPTORS, descriptors

            d = _timed(out, "descriptors", lambda: descriptors(model_to_graph(model)))
            out.update({f"d_{k}": d[k] for k in VECTOR_DESCRIPTORS})
        if locomotion:
            g = _timed(out, "gait", budget_gait, st, gait_search, **(gait_kw or {}))
            out.update(gait_speed=g.speed, gait_speed_m_s=g.speed_m_s)
    except SettingsError:  # the settings' fault, not the robot's: every robot would fail
        raise
    except Exception as e:  # noqa: BLE001 - one bad robot must not stop a population
        out["error"] = " ".join(f"{type(e).__name__}: {e}".split())
    return out


def robot_quality(robot: Robot, held: HeldRun | None = None) -> dict:
    """The compact quality record of one robot (:data:`QUALITY_KEYS` of :func:`measure`
    without descriptors or locomotion; ``error`` when it could not be measured); ``held`` as in
    :func:`measure`."""
    rec = measure(robot, describe=False, held=held)
    return {k: rec[k] for k in (*QUALITY_KEYS, "error") if k in rec}


def _measure_item(item: tuple) -> dict:
    robot, name, kw = item
    return measure(robot, name=name, **kw)


def measure_many(robots: Sequence[str | os.PathLike | mujoco.MjSpec], jobs: int = 2,
                 progress: bool = True, desc: str = "quality",
                 names: Sequence[str] | None = None, pool: Executor | None = None,
                 **kw: Any) -> list[dict]:
    """:func:`measure` (keyword arguments ``kw``) of many robots, in order, in ``jobs`` worker
    processes (``spawn``; ``0``: all cores, ``1``: in this process), with a tqdm progress bar
    labelled ``desc``; robot ``k`` is called ``names[k]`` when given. ``pool``: worker
    processes already started (:func:`~robovae.data.workers.process_pool`, left running), for
    callers that measure several populations: each new worker spends seconds importing torch
    and PyG (for the graph descriptors) before its first robot.

    Raises:
        SettingsError: ``jobs`` negative, or a setting of :func:`measure` out of range.
    """
    check_settings("measure_many", jobs=(jobs, integer(0)))
    from tqdm.auto import tqdm

    items = [(r, names[k] if names is not None else None, kw) for k, r in enumerate(robots)]
    jobs = jobs or (os.cpu_count() or 1)
    bar = tqdm(total=len(items), desc=desc, unit="robot", disable=not progress)
    out: list[dict] = []
    try:
        if jobs <= 1 or len(items) < 2:
            for it in items:
                out.append(_measure_item(it))
                bar.update()
            return out
        chunk = max(1, min(16, len(items) // (4 * jobs)))
        with nullcontext(pool) if pool is not None else process_pool(min(jobs, len(items))) \
                as workers:
            for rec in workers.map(_measure_item, items, chunksize=chunk):
                out.append(rec)
                bar.update()
        return out
    finally:
        bar.close()
