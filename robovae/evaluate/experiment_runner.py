"""The paper's experiments (§5, SPEC §6) as runs: the registry of experiments and runner
variants, and the runner that trains a config through the Lightning CLI for a seed, scores the
greedy reconstructions of its test robots (RA, RA_true, exact, FRE;
:mod:`robovae.evaluate.metrics`) and writes one ``result.json`` per run into
``runs/experiments/<experiment>/<variant>/seed<k>/`` (with the CSV log ``metrics.csv`` and
``checkpoints/last.ckpt``). The command line is :mod:`robovae.evaluate.experiments`, the tables
:mod:`robovae.evaluate.experiment_tables`.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import lightning as L

from robovae.files import atomic_json

REPO = Path(__file__).resolve().parents[2]
RUNS = Path("runs/experiments")
DOCS = REPO / "docs"

#: the 17 robots of the paper's appendix A, by their names in the dataset
MENAGERIE17 = ("piper_description", "cassie", "berkeley_humanoid", "T1", "spot", "N1",
               "barkour v0", "barkour_vb", "talos", "tiago", "tiago_dual", "a1", "g1", "go1",
               "go2", "h1", "z1")


@dataclass(frozen=True)
class Experiment:
    """One row of SPEC §6: a config, what the paper reports, and extra CLI overrides."""

    name: str
    config: str
    paper: str
    title: str
    overrides: tuple[str, ...] = ()


EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment("overfit_go2", "configs/overfit_go2.yaml", "RA 100 %, FRE ~0",
               "overfit: Go2 -> Go2"),
    Experiment("synthetic", "configs/synthetic.yaml", "structure exact, small FRE",
               "synthetic: 20 random trees -> unseen tree"),
    Experiment("menagerie2", "configs/menagerie2.yaml", "RA 100 %, FRE ~1e-3",
               "2 robots (Go1, A1) -> Go2"),
    Experiment("menagerie4", "configs/menagerie4.yaml", "RA 81 % (extra limb), FRE ~1e-3",
               "4 robots (Go1, G1, A1, H1) -> Go2"),
    Experiment("menagerie17", "configs/menagerie17.yaml",
               "RA 100 %, FRE 'relatively high' (not converged)",
               "17 robots (appendix A) -> Go2 (in training)"),
)}

#: Runner variants: name -> (description, CLI overrides on top of the configs). The 2- and
#: 4-robot configs and ``configs/loo17.yaml`` share one model block, so a variant means the same
#: change in every experiment; runs go to ``runs/experiments/<experiment>/<variant>/``. (The
#: model variants of the ablation in ``docs/results.md`` were measured at commit ``b6c3bdf``;
#: their code is in git history.)
ABLATIONS: dict[str, tuple[str, tuple[str, ...]]] = {
    "default": ("the configs: the tree from the tree latent z_T, node latents for the "
                "features, feature augmentation (shift 1.0, noise 0.5), tree surgery 0.5", ()),
    "no_surgery": ("the configs without tree surgery", ("--data.tree_surgery=0",)),
    "no_augment": ("the configs without feature augmentation",
                   ("--data.feature_shift=0", "--data.feature_noise=0")),
}


def _loadavg() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # pragma: no cover
        return math.nan


class FitTimer(L.Callback):
    """Wall time of ``trainer.fit`` (first to last training batch hooks) and the load average."""

    def __init__(self) -> None:
        self.start = self.end = 0.0
        self.load_start = self.load_end = math.nan

    def on_fit_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        """Start the wall clock."""
        self.start, self.load_start = time.perf_counter(), _loadavg()

    def on_fit_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        """Stop the wall clock (the fit took ``end - start`` seconds)."""
        self.end, self.load_end = time.perf_counter(), _loadavg()


@dataclass
class RunSpec:
    """One training run: a config, a seed, extra overrides and where it goes."""

    experiment: str
    config: str
    seed: int
    out: Path
    overrides: list[str] = field(default_factory=list)
    variant: str = "default"
    epochs: int | None = None
    threads: int = 0


def _names_arg(key: str, names: Sequence[str]) -> str:
    return f"--data.{key}={json.dumps(list(names))}"


def run_one(spec: RunSpec) -> dict:
    """Train ``spec`` through the Lightning CLI (``robovae fit``), score its test robots and
    write ``<out>/result.json``; returns the result."""
    import torch

    from robovae.evaluate.callbacks import latent_costs, score_split
    from robovae.evaluate.metrics import summarize
    from robovae.model.cli import run_lightning_cli

    if spec.threads:
        torch.set_num_threads(spec.threads)
    out = spec.out
    out.mkdir(parents=True, exist_ok=True)
    argv = ["fit", "--config", str(spec.config), f"--seed_everything={spec.seed}",
            "--trainer.logger.class_path=lightning.pytorch.loggers.CSVLogger",
            f"--trainer.logger.init_args.save_dir={out.parent}",
            "--trainer.logger.init_args.name=",
            f"--trainer.logger.init_args.version={out.name}",
            f"--checkpoint.dirpath={out / 'checkpoints'}",
            '--trainer.callbacks+={"class_path": "robovae.evaluate.experiment_runner.FitTimer"}',
            *spec.overrides]
    if spec.epochs:
        argv.append(f"--trainer.max_epochs={spec.epochs}")
    load0, t0 = _loadavg(), time.perf_counter()
    cli = run_lightning_cli(argv)
    command_s = time.perf_counter() - t0
    # (by name: under ``python -m`` this module is ``__main__``, the callback's class is not;
    # Lightning sets Trainer.callbacks at run time without declaring it on the class)
    timer = next(c for c in cli.trainer.callbacks  # type: ignore[attr-defined]
                 if type(c).__name__ == "FitTimer")
    model, dm = cli.model.eval(), cli.datamodule
    results = score_split(model, dm.test_set)
    summary = summarize(results)
    results_z = score_split(model, dm.test_set, from_z=True)
    summary_z = summarize(results_z)
    costs = latent_costs(model, dm.test_set)
    result = {
        "experiment": spec.experiment, "variant": spec.variant, "seed": spec.seed,
        "config": str(spec.config), "overrides": spec.overrides,
        "epochs": int(cli.trainer.current_epoch),
        "fit_s": timer.end - timer.start, "command_s": command_s,
        "load_start": load0, "load_fit_start": timer.load_start, "load_end": timer.load_end,
        "threads": torch.get_num_threads(),
        "train_names": [str(d.name) for d in dm.train_set],
        "test": [{"name": r.name, "ra": r.ra, "ra_true": r.ra_true, "exact": r.exact,
                  "fre": r.fre, "n_true": r.n_true, "n_pred": r.n_pred,
                  "n_correct": r.n_correct} for r in results],
        "summary": {k: summary[k] for k in ("ra", "ra_true", "exact", "fre", "count")},
        # from z alone (node latents at their conditional-prior mean) and what the latents cost
        "test_z": [{"name": r.name, "ra": r.ra, "ra_true": r.ra_true, "exact": r.exact,
                    "fre": r.fre, "n_true": r.n_true, "n_pred": r.n_pred, **c}
                   for r, c in zip(results_z, costs)],
        "summary_z": {k: summary_z[k] for k in ("ra", "ra_true", "exact", "fre", "count")},
        "hparams": {k: v for k, v in dict(model.hparams).items()
                    if isinstance(v, (int, float, str, bool)) or v is None},
        "metrics_csv": str(out / "metrics.csv"),
        "commit": _commit(),
    }
    atomic_json(out / "result.json", result)  # whole or absent: run_all skips it when present
    del cli
    return result


def _commit() -> str:
    try:
        head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "--", "robovae",
                                "configs"], capture_output=True, text=True).stdout.strip()
        return head + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run_all(specs: list[RunSpec], jobs: int, skip_done: bool) -> list[dict]:
    """Run ``specs`` (``jobs`` processes at a time, spawned), skipping those that have a
    ``result.json`` when ``skip_done``; the results of all of them, done and new."""
    todo = [s for s in specs if not (skip_done and (s.out / "result.json").is_file())]
    done = [json.loads((s.out / "result.json").read_text()) for s in specs if s not in todo]
    if jobs <= 1:
        for s in todo:
            done.append(_announce(run_one(s)))
        return done
    from robovae.data.workers import process_pool

    with process_pool(jobs) as pool:
        for r in pool.map(run_one, todo):
            done.append(_announce(r))
    return done


def _announce(r: dict) -> dict:
    s = r["summary"]
    print(f"[{r['experiment']}/{r['variant']}/seed{r['seed']}] RA {s['ra']:.4f} RA_true "
          f"{s['ra_true']:.4f} exact {s['exact']:.3f} FRE {s['fre']:.3g}  ({r['epochs']} "
          f"epochs, fit {r['fit_s']:.1f} s, load {r['load_fit_start']:.1f})", flush=True)
    return r


def experiment_specs(name: str, seeds: Sequence[int], variant: str = "default",
                     extra: Sequence[str] = (), epochs: int | None = None,
                     threads: int = 0, root: Path = RUNS) -> list[RunSpec]:
    """Runs of experiment ``name`` (:data:`EXPERIMENTS`), one per seed."""
    e = EXPERIMENTS[name]
    return [RunSpec(name, e.config, s, Path(root) / name / variant / f"seed{s}",
                    [*e.overrides, *extra], variant, epochs, threads) for s in seeds]


def loo_specs(seeds: Sequence[int], robots: Sequence[str] = MENAGERIE17, variant: str = "default",
              extra: Sequence[str] = (), epochs: int | None = None,
              threads: int = 0, root: Path = RUNS) -> list[RunSpec]:
    """Leave-one-out over the 17 robots: train on 16 (``configs/loo17.yaml``), test the 17th."""
    specs = []
    for robot in robots:
        train = [n for n in MENAGERIE17 if n != robot]
        ov = [_names_arg("train_names", train), _names_arg("val_names", [robot]),
              _names_arg("test_names", [robot]), *extra]
        slug = robot.replace(" ", "_")
        specs += [RunSpec("loo", "configs/loo17.yaml", s,
                          Path(root) / "loo" / variant / slug / f"seed{s}", ov, variant, epochs,
                          threads) for s in seeds]
    return specs
