r"""``robovae optimize``: CMA-ES over the latent space for a task, against two baselines.

For a checkpoint with latent dimension ``d``, task ``T`` (:data:`robovae.design.score.TASKS`)
and a budget of ``N`` evaluations per method, three methods run side by side in one run:

- ``cma``: CMA-ES (the ``cmaes`` package) in the sampling prior's principal subspace. With
  the prior's mean ``m_0`` and covariance ``C_0 = U diag(lambda) U^T`` (the fitted latent
  mixture's :meth:`~robovae.model.latent_mixture.LatentMixture.moments`, or ``0`` and ``I`` for
  ``N(0, I)``; eigenvalues in decreasing order), the search keeps the ``k`` leading directions
  that hold the share ``variance`` (default 0.9) of the prior's variance (``sum_{i<=k}
  lambda_i >= variance sum_i lambda_i``) and whitens them:

  .. math::  z = m_0 + U_k \mathrm{diag}(\lambda_k)^{1/2} y, \qquad y \in R^k,

  CMA-ES over ``y`` starts at ``0`` with covariance ``I`` and step size ``sigma_0 = 1``, so that
  its first generation is spread like the prior samples it competes with (``variance = 1``:
  the whole space, ``k = d``); population ``population`` (default ``4 + floor(3 ln k)``, the
  ``cmaes`` default), seeded with ``seed``; it minimises ``-score``. After ``restart_after``
  (default :data:`RESTART_AFTER`) generations without a better robot (or when ``cmaes`` says it
  has converged) it restarts, alternately *locally* — from the best point ``y*`` found so far,
  step size ``local_step`` (default :data:`LOCAL_SIGMA`), the first population: the
  neighbourhood of a walker holds better walkers than the prior does (docs/design.md) — and
  *globally*, from the same start as the first run with twice the population of the last
  global run (IPOP-CMA-ES, Auger and Hansen 2005; the alternation of a large-population regime
  with a small-step one as in BIPOP-CMA-ES, Hansen 2009). The directions left out hold the
  posterior's collapsed latents, where a d-dimensional CMA-ES spends most of its
  budget learning nothing (docs/design.md);
- ``prior``: random samples of the model's sampling prior, what ``robovae generate`` draws
  (:meth:`robovae.model.vae.RoboVAE.prior_latent`: the fitted latent mixture, or
  ``N(0, I)``; generator seeded by ``(seed, i)``);
- ``procedural``: random robots of :func:`robovae.data.procedural.procedural_spec` (seed drawn
  from ``(seed, i, 2)``, any kind).

Latent candidates are decoded from ``z`` alone (greedy; with node latents, every node's latent
at its conditional prior mean), written as ``robovae generate`` writes a robot
(:data:`WRITER`: for walk and stand a root joint becomes a floating base, for reach the base
stays fixed; mirrored limbs; the writer's stance rules; with ``self_collision`` bodies that
collide with each other, as the procedural baseline robots then do too), and scored by
:func:`robovae.design.score.score_robot` with the run's score seeds (:func:`score_seeds`: seed
0, and with ``score_sets = K > 1`` seeds 9 … K + 7 too; every robot gets the same gait
searches): the score is the median of the ``K`` scores (for walk, the median over ``K`` sets of
8 gaits of each set's best: a robot tops a run with ``K = 1`` on one lucky gait more often
than on its walking, docs/design.md). The held-out seeds 1–8 that re-score the best robots
are never among them. A decoding that did not finish its tree (it reached the decoder's node
or depth limit: a chain cut off, :func:`robovae.model.prior.unfinished`) is not a robot of the model
and costs no evaluation: a prior sample redraws its ``z`` as ``robovae generate`` does (up to
:data:`PRIOR_REDRAWS` times, ``draw`` in its record); CMA-ES asks a new candidate in its place
(up to :data:`CMA_RESAMPLES` times, ``rejected`` in the record: the resampling ``cmaes`` does
for candidates out of bounds), so a generation is ranked on robots. A latent still unfinished
after that scores 0 with ``error`` :data:`UNFINISHED`, without simulation. Evaluation
runs in ``jobs`` worker processes (``spawn``), one round at a time: a CMA generation and as
many prior and procedural robots, with a progress bar. This process decodes and prepares each
candidate (:meth:`_Run.prepare`: generate's fixes, or the procedural robot's MJCF); the workers
(:func:`robovae.design.candidates.evaluate`) write and score them without importing torch.

Output folder ``out``:

- ``log.json``: the settings and every evaluation per method (index, score, details, ``z`` or
  procedural seed), rewritten atomically after each round. Re-running with the same ``out``
  continues from it: CMA-ES is replayed from the logged scores, resampling and restarts
  included (its candidates are deterministic for the seed; the resamples are taken from the
  logged counts, not decoded again; a latent that differs from the log is refused), the
  baselines skip logged indices. A log of other settings (model, task, seed, score version,
  score seeds, search space, population, the rules for unfinished decodings and restarts, the
  writer) is refused; a larger ``--budget`` extends the run.
- ``best/<method>/rank_<k>/`` (the ``top`` best robots per method; for walk with the gait
  that scored them, ``gait.json``), the held-out re-scoring of those robots (the log's
  ``heldout``) and ``convergence.png``, rebuilt from the log at the end of every run
  (:mod:`robovae.design.results`).

Bad input is refused with one line before anything is written: an unknown task, a budget
``<= 0``, a ``variance`` outside ``(0, 1]``, a population below 2, ``score_sets`` below 1, a
checkpoint that is not one, an ``out`` that is a file or holds a log of another run.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Sequence
from concurrent.futures import Executor
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from robovae.data.tree_arrays import TreeArrays
from robovae.design.candidates import evaluate, failed
from robovae.design.results import (
    HELDOUT_SEEDS,
    METHODS,
    best_so_far,
    heldout,
    heldout_todo,
    plot,
    procedural_config,
    write_best,
)
from robovae.design.score import SCORE_VERSION
from robovae.errors import RobovaeError
from robovae.files import FolderLock, atomic_json
from robovae.generate.pipeline import model_fingerprint, worker_pool
from robovae.generate.writer import WRITER as WRITTEN
from robovae.model.checkpoint import own_model
from robovae.model.prior import draw_robots, unfinished
from robovae.model.vae import RoboVAE
from robovae.options import check_optimize

if TYPE_CHECKING:
    from robovae.data.graph import RobotData

__all__ = ["HELDOUT_SEEDS", "METHODS", "best_so_far", "optimize", "procedural_seed",
           "score_seeds"]

LOG = "log.json"
#: Redraws of a prior sample whose decoding did not finish its tree (as ``robovae generate``).
PRIOR_REDRAWS = 4
#: New CMA-ES candidates asked, at most, in place of one whose decoding did not finish its tree.
CMA_RESAMPLES = 20
#: Default CMA-ES generations without a better robot after which it restarts (locally, then
#: globally): ``optimize(restart_after=...)``, ``robovae optimize --restart-after``.
RESTART_AFTER = 10
#: Default step size of a local restart, around the best point so far (whitened prior units):
#: ``optimize(local_step=...)``, ``robovae optimize --local-step``.
LOCAL_SIGMA = 0.15
#: Default least distance between two latent designs among a method's best robots (whitened
#: prior units: :func:`robovae.design.results.top_records`): ``optimize(distinct=...)``,
#: ``robovae optimize --distinct``.
DISTINCT = 1.0
#: The error of a latent whose decoding did not finish its tree (scored 0, not simulated).
UNFINISHED = "unfinished decoding: the tree reached the decoder's node or depth limit"
#: How a decoded candidate is written (as ``robovae generate``): generation fixes
#: (:func:`robovae.generate.fixes.decoded_fixes`), then the writer with its stance rules.
WRITER = "floating base (walk, stand), mirrored limbs, stance rules, " + WRITTEN


def procedural_seed(seed: int, index: int) -> int:
    """Seed of procedural baseline robot ``index`` of a run with ``seed``."""
    return int(np.random.SeedSequence([seed, index, 2]).generate_state(1)[0])


def score_seeds(sets: int) -> list[int]:
    """The score seeds of a run with ``sets`` score sets: 0, then 9, 10, … (never one of the
    held-out seeds :data:`HELDOUT_SEEDS`, 1–8)."""
    return [0] + list(range(max(HELDOUT_SEEDS) + 1, max(HELDOUT_SEEDS) + sets))


class _Run:
    """State of one optimisation folder: settings, log, model, CMA-ES."""

    def __init__(self, model: RoboVAE, task: str, budget: int, out: Path, seed: int,
                 jobs: int, top: int, variance: float, population: int | None = None,
                 score_sets: int = 1, restart_after: int = RESTART_AFTER,
                 local_step: float = LOCAL_SIGMA, distinct: float = DISTINCT,
                 self_collision: bool = False) -> None:
        from cmaes import CMA

        self.model, self.task, self.budget, self.out = model, task, budget, out
        self.seed, self.jobs, self.top, self.distinct = seed, jobs, top, distinct
        self.restart_after, self.local_step = restart_after, local_step
        self.self_collision = self_collision
        self.seeds = score_seeds(score_sets)
        self.dim = int(model.hparams.latent_dim)
        self.floating = task != "reach"
        self.origin, self.basis = model.prior_directions(variance)
        k = self.basis.shape[1]
        self.cma = CMA(mean=np.zeros(k), sigma=1.0, seed=seed, population_size=population)
        self.restarts, self._best, self._stall = 0, -math.inf, 0
        self.local = False  # the running CMA-ES is a local restart
        self._global_population = self.cma.population_size
        self._top: tuple[float, np.ndarray] = (-math.inf, np.zeros(k))  # best score, its y
        self.settings = {"model": model_fingerprint(model), "task": task, "seed": seed,
                         "latent_dim": self.dim, "score_seeds": self.seeds,
                         "score_version": SCORE_VERSION, "cma_start": "prior moments",
                         "cma_variance": variance, "cma_dim": k,
                         "cma_population": self.cma.population_size,
                         "unfinished": f"cma resamples {CMA_RESAMPLES}, prior redraws "
                                       f"{PRIOR_REDRAWS}, then 0",
                         "cma_restarts": f"after {restart_after} generations, local (step "
                                         f"{local_step:g} from the best) and IPOP alternately",
                         "writer": WRITER}
        if self_collision:  # logs of robots that do not collide with themselves continue
            self.settings["self_collision"] = True
        # logs written before the population was a setting ran the cmaes default
        self._default_population = CMA(mean=np.zeros(k), sigma=1.0).population_size
        self.log: dict[str, Any] = {"settings": self.settings, "budget": budget,
                    "evaluations": {m: [] for m in METHODS}}
        self.pending: list[dict] = []  # evaluated part of the CMA-ES generation being asked

    def ask(self) -> tuple[list[np.ndarray], list[np.ndarray], list, list[int]]:
        """One CMA-ES generation: its search points ``y``, their latents ``z``, their decoded
        graphs and, per point, how many candidates asked before it in its place decoded to an
        unfinished tree (each replaced by a new ``cma.ask()``, at most :data:`CMA_RESAMPLES`
        times: the module docstring). Deterministic for the CMA-ES state (a resumed run
        replays it)."""
        ys = [self.cma.ask() for _ in range(self.cma.population_size)]
        graphs: list = [None] * len(ys)
        rejected = [0] * len(ys)
        todo = list(range(len(ys)))
        while todo:
            for k, g in zip(todo, self.decode([self.origin + self.basis @ ys[k] for k in todo])):
                graphs[k] = g
            todo = [k for k in todo
                    if unfinished(self.model, graphs[k]) and rejected[k] < CMA_RESAMPLES]
            for k in todo:
                ys[k] = self.cma.ask()
                rejected[k] += 1
        return ys, [self.origin + self.basis @ y for y in ys], graphs, rejected

    def _replay_ask(self, recs: Sequence[dict]) -> list[np.ndarray]:
        """The search points of a logged generation: the ``cma.ask()`` calls of :meth:`ask`
        in their order, the resamples taken from the records' ``rejected`` counts instead of
        from decoding again (the latents are then checked against the log)."""
        ys = [self.cma.ask() for _ in range(self.cma.population_size)]
        rejected = [r.get("rejected", 0) for r in recs]
        for round_ in range(1, max(rejected, default=0) + 1):
            for k, n in enumerate(rejected):
                if n >= round_:
                    ys[k] = self.cma.ask()
        return ys

    def load(self) -> None:
        """Continue from ``log.json`` (module docstring); refuses another run's log, and a file
        that is not a log (damaged, or another program's) in one line."""
        path = self.out / LOG
        if not path.is_file():
            return
        try:
            old = json.loads(path.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise RobovaeError(f"robovae: {path}: not an optimisation log ({e}); use another "
                               "--out") from None
        evaluations = old.get("evaluations") if isinstance(old, dict) else None
        if not (isinstance(evaluations, dict) and isinstance(old.get("settings", {}), dict)
                and all(isinstance(evaluations.get(m), list) for m in METHODS)):
            raise RobovaeError(f"robovae: {path}: not an optimisation log (no settings and "
                               f"evaluations of {', '.join(METHODS)}); use another --out")
        settings = dict(old.get("settings", {}))
        settings.setdefault("cma_population", self._default_population)
        if "score_seed" in settings:  # logs before score sets: one seed
            settings["score_seeds"] = [settings.pop("score_seed")]
        if settings != self.settings:
            keys = list(self.settings) + [k for k in settings if k not in self.settings]
            diff = ", ".join(k for k in keys if settings.get(k) != self.settings.get(k))
            raise RobovaeError(f"robovae: {path}: log of another run ({diff} differ); use "
                               "another --out")
        self.log["evaluations"] = old["evaluations"]  # written back with the new settings
        if "heldout" in old:
            self.log["heldout"] = old["heldout"]
        done = self.log["evaluations"]["cma"]
        g = 0
        while len(done) - g >= self.cma.population_size:
            pop = self.cma.population_size
            ys = self._replay_ask(done[g:g + pop])
            self._check_replay([self.origin + self.basis @ y for y in ys], done[g:g + pop])
            self._tell(ys, done[g:g + pop])
            g += pop
        self.pending = done[g:]  # a generation cut by the budget

    def _tell(self, ys: Sequence[np.ndarray], recs: Sequence[dict]) -> None:
        """Tell CMA-ES a generation's scores; after ``restart_after`` generations without a
        better robot since it started, restart it, seeded by ``(seed, restart)``: after a
        global run locally (from the best point so far, step size ``local_step``, the first
        run's population), after a local run globally (IPOP:
        from the prior's moments, step size 1, twice the last global run's population)."""
        from cmaes import CMA

        self.cma.tell([(y, -r["score"]) for y, r in zip(ys, recs)])
        k = max(range(len(recs)), key=lambda i: recs[i]["score"])
        best = recs[k]["score"]
        if best > self._top[0]:
            self._top = (best, np.array(ys[k]))
        self._best, self._stall = (best, 0) if best > self._best else (self._best,
                                                                        self._stall + 1)
        if self._stall >= self.restart_after or self.cma.should_stop():
            self.restarts += 1
            seed = int(np.random.SeedSequence([self.seed, self.restarts, 3]).generate_state(1)[0])
            self.local = not self.local
            if self.local:
                self.cma = CMA(mean=self._top[1], sigma=self.local_step, seed=seed,
                               population_size=self.settings["cma_population"])
            else:
                self._global_population *= 2
                self.cma = CMA(mean=np.zeros(self.basis.shape[1]), sigma=1.0, seed=seed,
                               population_size=self._global_population)
            self._best, self._stall = -math.inf, 0

    def _check_replay(self, zs: Sequence[np.ndarray], recs: Sequence[dict]) -> None:
        for z, rec in zip(zs, recs):
            if not np.allclose(z, rec["z"], atol=1e-6):
                raise RobovaeError(f"robovae: {self.out / LOG}: CMA-ES replay differs from the "
                                   f"log at evaluation {rec['index']}; use another --out")

    def save(self) -> None:
        """Write ``log.json`` (atomically)."""
        atomic_json(self.out / LOG, self.log)

    @torch.no_grad()
    def decode(self, zs: list[np.ndarray]) -> list:
        z = torch.as_tensor(np.stack(zs), dtype=torch.float64)
        return self.model.decode(z)

    def prepare(self, method: str, payload: int | RobotData) -> TreeArrays | str | dict:
        """What a worker writes for a candidate (:func:`robovae.design.candidates.evaluate`):
        a decoded graph with ``robovae generate``'s fixes (floating base for walk and stand,
        mirrored limbs) as :class:`TreeArrays`, a procedural robot's MJCF text; or, when that
        fails, the candidate's record (score 0)."""
        try:
            if method == "procedural":
                from robovae.data.procedural import procedural_spec

                return procedural_spec(payload, config=procedural_config(self)).to_xml()
            from robovae.generate.fixes import decoded_fixes

            assert not isinstance(payload, int)  # a latent method's decoded graph
            graph = decoded_fixes(payload, self.model.feature_set, floating=self.floating)[0]
            return TreeArrays.of(graph)
        except Exception as e:  # an unwritable candidate scores 0
            return failed(e)

    def round(self, pool: Executor | None) -> int:
        """One CMA-ES generation plus as many baseline robots; returns evaluations done."""
        ev = self.log["evaluations"]
        pop = self.cma.population_size
        left = {m: self.budget - len(ev[m]) for m in METHODS}
        jobs: list[tuple[str, int, Any]] = []  # (method, index, latent or procedural seed)
        start = len(ev["cma"]) - len(self.pending)  # index of this generation's first
        graphs: dict[int, RobotData] = {}  # job -> decoded graph (latent methods)
        rejected: dict[int, int] = {}  # job -> unfinished CMA-ES candidates resampled
        draws: dict[int, int] = {}  # job -> prior draw kept
        if left["cma"] > 0:
            ys, zs, decoded, asked = self.ask()
            self._check_replay(zs, self.pending)
            for k, z in enumerate(zs):
                if k >= len(self.pending) and start + k < self.budget:
                    graphs[len(jobs)], rejected[len(jobs)] = decoded[k], asked[k]
                    jobs.append(("cma", start + k, z))
        prior = [len(ev["prior"]) + k for k in range(min(pop, left["prior"]))]
        if prior:  # unfinished decodings redrawn as robovae generate redraws them
            zp, gp, dp = draw_robots(self.model, self.seed, prior, redraws=PRIOR_REDRAWS,
                                     noise=False)
            for i, z, g, d in zip(prior, zp, gp, dp):
                graphs[len(jobs)], draws[len(jobs)] = g, d
                jobs.append(("prior", i, z.numpy()))
        for k in range(min(pop, left["procedural"])):
            i = len(ev["procedural"]) + k
            jobs.append(("procedural", i, procedural_seed(self.seed, i)))
        if not jobs:
            return 0
        work = self.out / ".work"
        done: dict[int, dict] = {k: {"score": 0.0, "error": UNFINISHED} for k, g in graphs.items()
                                 if unfinished(self.model, g)}
        items: dict[int, tuple] = {}
        for k, (m, i, p) in enumerate(jobs):
            if k not in done:
                robot = self.prepare(m, graphs.get(k, p))
                if isinstance(robot, dict):
                    done[k] = robot
                else:
                    items[k] = (robot, str(work / f"{m}_{i:06d}"), self.model.feature_set.name,
                                self.task, self.seeds, self.self_collision)
        todo = list(items.values())
        done.update(zip(items, pool.map(evaluate, todo) if pool else map(evaluate, todo)))
        for k, (m, i, p) in enumerate(jobs):
            res = done[k]
            rec = {"index": i, **res}
            rec.update({"seed": p} if m == "procedural" else
                       {"z": [float(v) for v in p]})
            if k in draws:
                rec["draw"] = draws[k]
            if k in rejected:
                rec.update(rejected=rejected[k], restart=self.restarts, local=self.local)
            ev[m].append(rec)
        if left["cma"] > 0:
            gen = ev["cma"][start:start + pop]
            if len(gen) == pop:
                self._tell(ys, gen)
                self.pending = []
            else:
                self.pending = gen
        self.save()
        return len(jobs)


def optimize(ckpt: str | os.PathLike | RoboVAE, task: str, budget: int, out: str | os.PathLike,
             seed: int = 0, jobs: int = 0, top: int = 10, progress: bool = True,
             variance: float = 0.9, population: int | None = None,
             score_sets: int = 1, restart_after: int = RESTART_AFTER,
             local_step: float = LOCAL_SIGMA, distinct: float = DISTINCT,
             self_collision: bool = False) -> dict:
    """Run (or continue) an optimisation (module docstring). ``population``: CMA-ES candidates
    per generation (None: ``4 + floor(3 ln k)``); each round scores as many baseline robots.
    ``score_sets``: score seeds per robot (:func:`score_seeds`), each evaluation then costs
    that many scorings for every method. ``restart_after``: CMA-ES generations without a
    better robot before a restart; ``local_step``: the step size of a local restart (whitened
    prior units); both are settings of the run (module docstring). ``distinct``: the least
    distance between two latent designs among a method's ``top`` best robots (whitened prior
    units; 0: the plain top), a choice of what to write, not of the search.
    ``self_collision``: every robot of every method is written with bodies that collide with
    each other, but for the pairs in contact at rest (:mod:`robovae.data.self_collision`), a
    setting of the run.

    Returns:
        per method ``evaluations``, ``best`` score, ``best_index``, ``heldout`` (the best
        robot's median score under :data:`HELDOUT_SEEDS`), and ``heldout_best`` and
        ``heldout_best_rank`` (the largest such median among the ``top`` best robots, and that
        robot's rank: the pick of a user who wants the robot that does the task best, not the
        one whose gaits were luckiest), for walk and step ``power_per_kg`` (the best robot's scoring
        gait: mean mechanical power over its mass, W/kg; else None) and ``top_wheeled`` (how
        many of the ``top`` best robots have a motor on a hinge without limits, and so may roll
        rather than step; else None) of ``top_robots``; plus ``out``, ``log``, ``plot``.

    Raises:
        RobovaeError: unknown task, ``budget`` or ``top`` not a positive integer,
            ``variance`` outside ``(0, 1]``, ``population`` not an integer in [2, 10,000],
            ``score_sets`` or ``restart_after`` not an integer >= 1, ``local_step`` not > 0,
            ``distinct`` < 0, ``jobs`` negative, bad checkpoint, ``out`` not usable or being
            written by another run (:class:`~robovae.files.FolderLock`).
    """
    check_optimize(task, budget, top, variance, population, score_sets, restart_after,
                   local_step, distinct, seed, jobs)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RobovaeError(f"robovae: {out}: exists and is not a folder")
    model = own_model(ckpt)  # decoded in float64: never the caller's object
    run = _Run(model.to(torch.float64), task, budget, out, seed, jobs, top, variance, population,
               score_sets, restart_after, local_step, distinct, self_collision)
    # one run at a time: a second would rewrite log.json under this one and delete its .work
    with FolderLock(out, "the run's files"):
        run.load()
        from tqdm.auto import tqdm

        done = sum(min(len(v), budget) for v in run.log["evaluations"].values())
        bar = tqdm(total=3 * budget, initial=done, desc=f"optimize {task}", unit="robot",
                   disable=not progress)
        jobs = jobs or (os.cpu_count() or 1)
        # started warm (their imports overlap the first decoding), and only with robots to score
        busy = done < 3 * budget or heldout_todo(run)
        pool = worker_pool(jobs, warm=True) if jobs > 1 and busy else None
        try:  # on an error or Ctrl-C the pool cancels its queued robots (WorkerPool)
            with pool if pool is not None else nullcontext():
                while True:
                    k = run.round(pool)
                    if k == 0:
                        break
                    bar.update(k)
                bar.close()
                summary = write_best(run)
                held = heldout(run, pool)
        finally:
            bar.close()
            shutil.rmtree(out / ".work", ignore_errors=True)
        for m in METHODS:
            summary[m]["heldout"] = held[m][0]["median"] if held[m] else None
            # the robot that walks (stands, reaches) best on the held-out seeds may not be rank 0
            pick = max(held[m], key=lambda h: (h["median"], -h["rank"]), default=None)
            summary[m]["heldout_best"] = pick["median"] if pick else None
            summary[m]["heldout_best_rank"] = pick["rank"] if pick else None
            gait = (held[m][0].get("gait") or {}) if held[m] else {}  # walk: the best's gait
            summary[m]["power_per_kg"] = gait["power"] / gait["mass"] \
                if gait.get("power") is not None and gait.get("mass") else None
            # walk, step: how many top robots have a motor on a hinge without limits (may roll)
            wheels = [h["gait"].get("wheeled") for h in held[m] if "gait" in h]
            summary[m]["top_wheeled"] = sum(w is True for w in wheels) if wheels else None
            summary[m]["top_robots"] = len(held[m])
        png = plot(run, out / "convergence.png")
        return {**summary, "out": str(out), "log": str(out / LOG), "plot": str(png)}
