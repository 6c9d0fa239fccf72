"""What a ``robovae optimize`` run leaves besides its log: each method's best robots, their
held-out scores and walking gaits, and the convergence plot.

Everything here is rebuilt from the run's ``log.json`` (:mod:`robovae.design.optimize`), so a
continued or finished run rewrites it the same way:

- ``best/<method>/rank_<k>/robot.xml`` (+ ``scene.xml``): the ``top`` best robots of each
  method, best first (ties: the lower index), no two latent designs nearer than the run's
  ``distinct`` (:func:`top_records`), written as the run wrote them for scoring;
- the log's ``heldout``: each of those robots re-scored with the score seeds
  :data:`HELDOUT_SEEDS` (1–8; the run selects with seed 0), the eight scores and their median.
  A method's best is the maximum of many scores under one seed and so is biased upwards (for
  walk one seed is one set of 8 random gaits: a robot can top the run on one lucky gait); the
  held-out median measures it with seeds that played no part in selecting it. Kept by robot
  index, so a continued run re-scores only robots new to the top;
- for walk, ``best/<method>/rank_<k>/gait.json``: the gait that gave the robot its score
  (:func:`robovae.design.score.walk_gait` under the score seed of :func:`gait_seed`: the run's
  seed 0, or with several score sets the set whose best is the median; kept in ``heldout`` as
  ``gait``), to replay as a ``robovae/Walk-v0`` policy (:mod:`robovae.envs.gait`);
- ``convergence.png``: the best score so far against evaluations, one line per method.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from robovae.design.score import GAIT_TASKS, Wheeled, score_robot, walk_gait

if TYPE_CHECKING:  # the model stack stays out of the worker processes that import this module
    from robovae.data.procedural.robots import ProceduralConfig
    from robovae.model.vae import RoboVAE

__all__ = ["HELDOUT_SEEDS", "METHODS", "best_so_far", "gait_seed", "heldout", "heldout_todo",
           "plot", "procedural_config", "search_point", "top_records", "write_best"]

METHODS = ("cma", "prior", "procedural")
#: Score seeds of the held-out re-scoring of each method's best robots (module docstring).
HELDOUT_SEEDS = tuple(range(1, 9))


class Run(Protocol):
    """The state of an optimisation these functions read (:class:`robovae.design.optimize`)."""

    log: dict
    out: Path
    task: str
    seed: int
    top: int
    distinct: float
    origin: np.ndarray
    basis: np.ndarray
    floating: bool
    seeds: list[int]
    model: RoboVAE
    self_collision: bool

    def decode(self, zs: list[np.ndarray]) -> list:
        """The graphs decoded from latents ``zs`` as the run decodes its candidates."""

    def save(self) -> None:
        """Write the log."""


def best_so_far(scores: Sequence[float]) -> np.ndarray:
    """Running maximum of ``scores`` (the convergence curve)."""
    return np.maximum.accumulate(np.asarray(scores, dtype=float)) if len(scores) else \
        np.zeros(0)


def search_point(run: Run, z: Sequence[float]) -> np.ndarray:
    """The point ``y`` of the run's search space (the whitened prior subspace) nearest to the
    latent ``z``: ``y = B⁺ (z − m_0)`` with ``B = U_k diag(λ_k)^{1/2}`` (``run.basis``), so
    that ``|y − y'|`` is the distance of two designs in prior standard deviations."""
    return np.linalg.lstsq(run.basis, np.asarray(z, float) - run.origin, rcond=None)[0]


def top_records(run: Run, method: str) -> list[dict]:
    """The ``top`` best records of ``method``, best first (ties: lower index), taken greedily
    so that no two latent designs lie within ``run.distinct`` of each other in the search
    space (:func:`search_point`; 0: the plain top; a procedural robot, without a latent, is a
    design of its own): a run's best are otherwise one design and its near copies, the
    neighbourhood a local restart climbed."""
    ranked = sorted(run.log["evaluations"][method], key=lambda r: (-r["score"], r["index"]))
    if run.distinct <= 0:
        return ranked[:run.top]
    out: list[dict] = []
    taken: list[np.ndarray] = []
    for r in ranked:
        if len(out) == run.top:
            break
        if "z" in r:
            y = search_point(run, r["z"])
            if any(np.linalg.norm(y - t) < run.distinct for t in taken):
                continue
            taken.append(y)
        out.append(r)
    return out


def gait_seed(record: dict, seeds: Sequence[int]) -> int:
    """The score seed whose gait search gave ``record`` (an evaluation of a run with score
    seeds ``seeds``) its score: the first seed, or with ``K > 1`` seeds (the record's
    ``scores``, in ``seeds``' order) the seed whose score is the median, ``sorted(scores)[K //
    2]`` (for even ``K`` the upper of the two middle scores, which the median averages; equal
    scores: the earlier seed)."""
    scores = record.get("scores")
    if not scores or len(seeds) < 2:
        return int(seeds[0])
    order = sorted(range(len(scores)), key=lambda i: (scores[i], i))
    return int(seeds[order[len(scores) // 2]])


def _best_path(run: Run, method: str, rank: int) -> Path:
    return run.out / "best" / method / f"rank_{rank}"


def _cache(run: Run) -> dict[tuple[str, int], dict]:
    """Held-out entries already in the log, by (method, index), if of :data:`HELDOUT_SEEDS`."""
    old = run.log.get("heldout", {})
    if old.get("seeds") != list(HELDOUT_SEEDS):
        return {}
    return {(m, r["index"]): r for m in METHODS for r in old.get(m, [])}


def heldout_todo(run: Run) -> list[tuple[str, int, int, bool]]:
    """(method, rank, index, whether its scores are missing) of the best robots whose
    held-out scores, or for walk whose gait (under :func:`gait_seed`), are not in the log
    yet."""
    cache = _cache(run)
    todo = []
    for m in METHODS:
        for k, r in enumerate(top_records(run, m)):
            entry = cache.get((m, r["index"]), {})
            found = entry.get("gait", {})  # logs before 2026-11-28 lack the seed or "wheeled"
            gait = found.get("score_seed") == gait_seed(r, run.seeds) and "wheeled" in found
            if "scores" not in entry or (run.task in GAIT_TASKS and not gait):
                todo.append((m, k, r["index"], "scores" not in entry))
    return todo


def _score_seed(item: tuple[str, str, int, bool]) -> float | dict:
    """The score of one robot file under one score seed, or (``gait``) its walking gait under
    that seed (worker)."""
    path, task, seed, gait = item
    if gait:
        try:
            return {**walk_gait(path, seed=seed, step=task == "step"), "error": None}
        except Exception as e:  # as score_robot: a robot that cannot walk scores 0, no gait
            wheeled = True if isinstance(e, Wheeled) else None  # task step refuses wheels
            return {"score": 0.0, "score_seed": seed, "wheeled": wheeled, "frequency": None,
                    "actuators": [], "amplitude": [], "phase": [], "offset": [], "power": 0.0,
                    "mass": None,
                    "error": " ".join(f"{type(e).__name__}: {e}".split())[:300]}
    return float(score_robot(path, task, seed=seed)["score"])


def heldout(run: Run, pool: Executor | None) -> dict:
    """Score the robots of ``best/`` with :data:`HELDOUT_SEEDS` and, for walk, find their
    gaits (module docstring); store both in the log, write each ``gait.json``, and return the
    entries per method, best first."""
    seeds = list(HELDOUT_SEEDS)
    cache, todo = _cache(run), heldout_todo(run)
    tops = {m: top_records(run, m) for m in METHODS}
    items: list[tuple] = []
    for m, k, _, scores in todo:
        path = str(_best_path(run, m, k) / "robot.xml")
        items += [(path, run.task, s, False) for s in seeds] if scores else []
        if run.task in GAIT_TASKS:
            items.append((path, run.task, gait_seed(tops[m][k], run.seeds), True))
    done = iter(list(pool.map(_score_seed, items)) if pool else [_score_seed(x) for x in items])
    for m, _, i, scores in todo:
        entry = dict(cache.get((m, i), {}))
        if scores:
            entry["scores"] = [next(done) for _ in seeds]
        if run.task in GAIT_TASKS:
            entry["gait"] = next(done)
        cache[(m, i)] = entry
    out: dict = {"seeds": seeds}
    for m in METHODS:
        out[m] = []
        for k, r in enumerate(tops[m]):
            entry = cache[(m, r["index"])]
            out[m].append({"rank": k, "index": r["index"], "score": r["score"],
                           "scores": entry["scores"], "median": float(np.median(entry["scores"])),
                           **({"gait": entry["gait"]} if "gait" in entry else {})})
            if "gait" in entry:
                (_best_path(run, m, k) / "gait.json").write_text(
                    json.dumps(entry["gait"], indent=1) + "\n")
    run.log["heldout"] = out
    run.save()
    return out


def procedural_config(run: Run) -> ProceduralConfig | None:
    """The procedural generator's settings of the run's baseline robots: its defaults
    (None), or with bodies that collide with each other when the run has ``self_collision``."""
    from robovae.data.procedural.robots import ProceduralConfig

    return ProceduralConfig(self_collision=True) if run.self_collision else None


def write_best(run: Run) -> dict:
    """Rewrite ``best/<method>/rank_<k>/`` from the log; returns the summary per method."""
    from robovae.data.procedural import procedural_spec
    from robovae.generate.fixes import decoded_fixes
    from robovae.generate.writer import scene_xml, write_robot

    tmp = Path(tempfile.mkdtemp(prefix=".best.", dir=run.out))
    summary = {}
    for m in METHODS:
        top = top_records(run, m)
        summary[m] = {"evaluations": len(run.log["evaluations"][m]),
                      "best": top[0]["score"] if top else 0.0,
                      "best_index": top[0]["index"] if top else None}
        for k, rec in enumerate(top):
            folder = tmp / m / f"rank_{k}"
            if m == "procedural":
                folder.mkdir(parents=True)
                (folder / "robot.xml").write_text(
                    procedural_spec(rec["seed"], config=procedural_config(run)).to_xml())
                (folder / "scene.xml").write_text(scene_xml("robot.xml", f"{m}_{k}_scene"))
            else:
                g = run.decode([np.array(rec["z"])])[0]
                g = decoded_fixes(g, run.model.feature_set, floating=run.floating)[0]
                write_robot(g, folder, run.model.feature_set, name=f"{m}_rank{k}", stance=True,
                            self_collision=run.self_collision)
    shutil.rmtree(run.out / "best", ignore_errors=True)
    os.replace(tmp, run.out / "best")
    return summary


def plot(run: Run, path: Path) -> Path:
    """``convergence.png``: best score so far against evaluations, one line per method."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4), dpi=100)
    ax = fig.add_subplot()
    for m in METHODS:
        scores = [r["score"] for r in run.log["evaluations"][m]]
        ax.plot(np.arange(1, len(scores) + 1), best_so_far(scores), label=m)
    ax.set_xlabel("evaluations")
    ax.set_ylabel(f"best {run.task} score so far")
    ax.set_title(f"robovae optimize: {run.task}, seed {run.seed}")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path
