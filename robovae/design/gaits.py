"""Gaits tuned to a robot's body, as ``robovae/Walk-v0`` policies: ``robovae gait``.

``robovae optimize --task walk`` scores a robot by the best of 8 random open-loop sinusoidal
gaits and writes that gait beside each of its best robots (``gait.json``): a measure of the
body under a fixed, small budget, and a gait tuned to one exact start with a control at every
physics step, which an environment that holds each action for 5 steps and starts from a noisy
pose does not give it. :func:`tune_gaits` finds, for any robot files (samples, optimised
robots, real robots), a gait for the environment: the walk score's search continued by CMA-ES
(:func:`robovae.design.score.walk_gait` with ``refine``: the same 8 random gaits first, then
``refine // 16`` generations of 16, in the same scene and rules: 3 s, the first second not
counted, falls at 60°) with every gait judged as ``robovae/Walk-v0`` would run it by default:
each control held for ``hold`` (5) physics steps, and its median speed from ``starts`` (4)
states, the rest state and three with the environment's reset noise (``noise``, 0.05).
``starts = hold = 1`` tunes for the exact start instead (a replay with ``frame_skip=1`` and no
reset noise reproduces its score, and the score is never below the walk score). The gait is
written in the format of ``gait.json`` (:meth:`robovae.envs.gait.SinusoidGait.from_json` reads
it; the file adds ``walk_score``, the robot's walk score, and ``robot``, the file it was tuned
for).

Where the files go: ``<robot's folder>/gait_tuned.json`` by default; with ``out``, one file per
robot in that folder, named after the robot (its folder's name for a ``robot.xml`` or
``scene.xml``, else the file's stem), prefixed by as many enclosing folders as set it apart
from the other robots' (``cma_rank_0.json`` and ``prior_rank_0.json`` for an optimisation
run's ``best/*/rank_0``); each written as soon as its robot is done. Every robot
is loaded, and every destination folder made and tried, before any gait is tuned: a file that
does not load, a robot that ``robovae/Walk-v0`` refuses (no actuators, an actuated base), two
robots that would write the same file, a file already there that holds another robot's gait (an
earlier run into the same folder; ``overwrite`` replaces it), or a folder that cannot be
written is refused with one line. A robot's own earlier gait is replaced.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path

from tqdm.auto import tqdm

from robovae.data.workers import process_pool
from robovae.errors import RobovaeError, check_count, check_seed
from robovae.files import atomic_json, writable

__all__ = ["GAIT_FILE", "tune_gaits"]

#: The name of a tuned gait's file beside its robot.
GAIT_FILE = "gait_tuned.json"


def _names(path: Path) -> list[str]:
    """The names a robot file's gait can take in ``out``, shortest first: the robot's name (its
    folder's for a ``robot.xml`` or ``scene.xml``, else the file's stem), then that name
    prefixed by one more enclosing folder at a time (``prior_rank_0``, ``best_prior_rank_0``)."""
    path = Path(os.path.abspath(path))  # a/../a/robot.xml is a/robot.xml; links kept
    folders = [p.name for p in path.parents if p.name]
    if path.name not in ("robot.xml", "scene.xml") or not folders:
        folders.insert(0, path.stem)
    return ["_".join(reversed(folders[:k])) for k in range(1, len(folders) + 1)]


def _destinations(files: Sequence[Path], out: Path | None) -> list[Path]:
    """Each robot's gait file: ``gait_tuned.json`` beside it, or with ``out`` the shortest of
    its :func:`_names` that no other robot file's takes (robots of one name in different
    folders: ``best/cma/rank_0`` and ``best/prior/rank_0`` give ``cma_rank_0.json`` and
    ``prior_rank_0.json``). One file given twice keeps one name (refused by the caller)."""
    if out is None:
        return [f.parent / GAIT_FILE for f in files]
    names, same = [_names(f) for f in files], [f.resolve() for f in files]
    depth = [0] * len(files)
    while True:
        takers: dict[str, set[Path]] = {}
        for f, n, d in zip(same, names, depth):
            takers.setdefault(n[d], set()).add(f)
        longer = [i for i, (n, d) in enumerate(zip(names, depth))
                  if len(takers[n[d]]) > 1 and d + 1 < len(n)]
        if not longer:
            return [out / f"{n[d]}.json" for n, d in zip(names, depth)]
        for i in longer:
            depth[i] += 1


def _kept(target: Path, robot: Path) -> None:
    """Refuse (one line) to replace ``target`` when it exists and is not a gait of ``robot``
    (its ``robot`` field, written by :func:`_tune`, names another file, or it is no gait)."""
    if not target.exists():
        return
    try:
        owner = json.loads(target.read_text()).get("robot")
    except (OSError, ValueError, AttributeError):
        owner = None
    if owner != str(robot.resolve()):
        held = f"the gait of {owner}" if isinstance(owner, str) else "no gait of robovae gait"
        raise RobovaeError(f"robovae: {target} holds {held}: give another --out, or --overwrite "
                           "to replace it")


def _check(path: Path, step: bool) -> None:
    """Refuse (one line) a robot file that ``robovae/Walk-v0`` refuses (it does not load, has
    no actuators or an actuated base: :func:`robovae.envs.walk.walk_scene`) or, with ``step``,
    one with a motor on a hinge without limits."""
    from robovae.envs.walk import walk_scene
    from robovae.evaluate.quality.locomotion import continuous_actuators

    _, scene = walk_scene(path)
    if step and continuous_actuators(scene.model).any():
        raise RobovaeError(f"robovae: {path}: wheeled (a motor drives a hinge without limits): "
                           "--step tunes robots that step, not roll")


def _tune(item: tuple[str, int, int, bool, dict]) -> dict:
    """The tuned gait of one robot file, with its walk score (worker)."""
    from robovae.design.score import walk_gait

    path, refine, seed, step, kw = item
    plain = walk_gait(path, seed=seed, step=step)["score"]
    return {**walk_gait(path, seed=seed, step=step, refine=refine, **kw), "walk_score": plain,
            "robot": str(Path(path).resolve())}


def tune_gaits(paths: Sequence[str | os.PathLike], refine: int = 496, seed: int = 0,
               step: bool = False, out: str | os.PathLike | None = None, jobs: int = 1,
               progress: bool = True, starts: int = 4, hold: int = 5, noise: float = 0.05,
               overwrite: bool = False) -> list[tuple[Path, dict]]:
    """Tune the gait of each robot file and write it (module docstring); returns each gait
    file and its contents, in input order.

    ``refine``: CMA-ES gaits after the 8 random ones (in generations of 16); ``starts``,
    ``hold``, ``noise``: how every gait is judged (module docstring; each gait is simulated
    ``starts`` times); ``seed``: the walk score's seed (its 8 gaits, CMA-ES's and the noisy
    starts'); ``step``: a robot with a motor on a hinge without limits is refused instead (it
    could roll: task step); ``jobs``: worker processes (0: all cores); ``progress``: a tqdm
    progress bar; ``overwrite``: replace gait files of other robots found at the destinations.

    Raises:
        RobovaeError: one line, before any gait is tuned: ``refine`` below 16, ``starts`` or
            ``hold`` below 1, ``jobs`` or ``noise`` negative, no robot, a missing or broken
            file, a robot without actuators or with an actuated base (with ``step``: wheeled),
            two robots with one destination, a destination holding another robot's gait (unless
            ``overwrite``), or a destination folder that cannot be written.
    """
    check_count("--refine", refine, 16)
    check_count("--starts", starts, 1)
    check_count("--hold", hold, 1)
    check_count("--jobs", jobs, 0)
    check_seed(seed)
    if not 0 <= noise < math.inf:
        raise RobovaeError(f"robovae: --noise must be a finite number >= 0, not {noise!r}")
    files = [Path(p) for p in paths]
    if not files:
        raise RobovaeError("robovae: no robot files given")
    folder = None if out is None else Path(out)
    targets = _destinations(files, folder)
    seen: dict[Path, Path] = {}
    for f, t in zip(files, targets):
        if not f.is_file():
            raise RobovaeError(f"robovae: {f}: no such robot file")
        if t.resolve() in seen:
            raise RobovaeError(f"robovae: {seen[t.resolve()]} and {f} would both write {t}")
        seen[t.resolve()] = f
        if not overwrite:
            _kept(t, f)
    for f in files:
        _check(f, step)
    for parent in dict.fromkeys(t.parent for t in targets):
        writable(parent, "gaits")
    kw = {"starts": starts, "hold": hold, "noise": noise}
    items = [(str(f), refine, seed, step, kw) for f in files]
    jobs = jobs or (os.cpu_count() or 1)
    bar = tqdm(total=len(items), desc="gaits", unit="robot", disable=not progress)
    done: list[tuple[Path, dict]] = []
    try:  # each gait is written as soon as it is tuned (a file whole or not at all)
        with nullcontext() if jobs == 1 or len(items) == 1 else \
                process_pool(min(jobs, len(items))) as pool:
            tuned = pool.map(_tune, items, chunksize=1) if pool else map(_tune, items)
            for target, g in zip(targets, tuned):
                done.append((atomic_json(target, g), g))
                bar.update()
    finally:
        bar.close()
    return done
