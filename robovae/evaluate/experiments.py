"""The paper's experiments (§5, SPEC §6), one command each, and the tables of ``docs/results.md``.

Every experiment is a Lightning CLI config under ``configs/`` (``robovae fit --config ...`` runs it
alone); this module runs them for several seeds, scores the greedy reconstructions of the test
robots (RA, RA_true, exact, FRE; :mod:`robovae.evaluate.metrics`), stores one ``result.json`` per
run, and renders the result tables and loss curves::

    python -m robovae.evaluate.experiments run menagerie4 --seeds 0,1,2
    python -m robovae.evaluate.experiments loo --seeds 0,1,2      # leave-one-out over the 17
    python -m robovae.evaluate.experiments ablation --seeds 0,1,2 --loo   # + LOO per variant
    python -m robovae.evaluate.experiments report                 # docs/results.md + docs/img
    python -m robovae.evaluate.experiments all                    # everything (``--all`` too)

Runs live in ``runs/experiments/<experiment>/<variant>/seed<k>/`` (``metrics.csv`` of the CSV
logger, ``result.json``, ``checkpoints/last.ckpt``). ``report`` only reads those folders: every
number in the tables comes from a run that was done, with its seed, epochs, wall time and the
machine load measured around it.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import lightning as L

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
    "default": ("the configs: node latents with local heads (the node posterior reads the "
                "node's type and child count), type-input decoder, feature augmentation "
                "(shift 1.0, noise 0.5), tree surgery 0.5", ()),
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

    from robovae.evaluate.callbacks import score_split
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
            '--trainer.callbacks+={"class_path": "robovae.evaluate.experiments.FitTimer"}',
            *spec.overrides]
    if spec.epochs:
        argv.append(f"--trainer.max_epochs={spec.epochs}")
    load0, t0 = _loadavg(), time.perf_counter()
    cli = run_lightning_cli(argv)
    command_s = time.perf_counter() - t0
    # (by name: under ``python -m`` this module is ``__main__``, the callback's class is not)
    timer = next(c for c in cli.trainer.callbacks if type(c).__name__ == "FitTimer")
    model, dm = cli.model.eval(), cli.datamodule
    results = score_split(model, dm.test_set)
    summary = summarize(results)
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
        "hparams": {k: v for k, v in dict(model.hparams).items()
                    if isinstance(v, (int, float, str, bool)) or v is None},
        "metrics_csv": str(out / "metrics.csv"),
        "commit": _commit(),
    }
    (out / "result.json").write_text(json.dumps(result, indent=1))
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


def _run_all(specs: list[RunSpec], jobs: int, skip_done: bool) -> list[dict]:
    todo = [s for s in specs if not (skip_done and (s.out / "result.json").is_file())]
    done = [json.loads((s.out / "result.json").read_text()) for s in specs if s not in todo]
    if jobs <= 1:
        for s in todo:
            done.append(_announce(run_one(s)))
        return done
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(jobs, mp_context=ctx) as pool:
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


# --- report ----------------------------------------------------------------------------------


def load_results(root: Path = RUNS) -> list[dict]:
    """Every ``result.json`` below ``root``."""
    return [json.loads(p.read_text()) for p in sorted(root.rglob("result.json"))]


def _ms(values: list[float], fmt: str = "{:.3f}") -> str:
    vals = [v for v in values if not (isinstance(v, float) and math.isnan(v))]
    if not vals:
        return "n/a"
    if len(vals) == 1:
        return fmt.format(vals[0])
    return f"{fmt.format(statistics.mean(vals))} ± {fmt.format(statistics.stdev(vals))}"


def _pct(values: list[float]) -> str:
    vals = [100 * v for v in values if not math.isnan(v)]
    if not vals:
        return "n/a"
    if len(vals) == 1:
        return f"{vals[0]:.1f} %"
    return f"{statistics.mean(vals):.1f} ± {statistics.stdev(vals):.1f} %"


def loss_curve_png(metrics_csv: str | Path, out: str | Path, title: str) -> Path:
    """Training loss terms (log scale) and the validation RA over the epochs of one run."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    with open(metrics_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    fig, ax = plt.subplots(figsize=(7.6, 3.6))
    for key, label in (("train/loss", "total"), ("train/topo", "topology BCE"),
                       ("train/feat", "feature MSE"), ("train/type", "type CE"),
                       ("train/kl", "KL"), ("train/kl_nodes", "node KL")):
        pts = [(int(r["epoch"]), float(r[key])) for r in rows if r.get(key)]
        if pts:
            ax.plot(*zip(*pts), label=label, lw=1)
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel("per-robot loss (train)")
    handles = ax.get_legend_handles_labels()[0]
    ra = [(int(r["epoch"]), float(r["val/RA"])) for r in rows if r.get("val/RA")]
    if ra:
        ax2 = ax.twinx()
        handles += ax2.plot(*zip(*ra), "k.--", label="val RA", lw=0.8)
        ax2.set_ylim(0, 1.05)
        ax2.set_ylabel("val RA")
    # one legend, outside the axes: it never hides a curve
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.1, 1.0), fontsize=7)
    ax.set_title(title, fontsize=9)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out


def _group(results: list[dict], **match) -> list[dict]:
    return [r for r in results if all(r.get(k) == v for k, v in match.items())]


def experiments_table(results: list[dict], variant: str = "default") -> str:
    """Markdown table: one row per experiment, the paper's number beside ours (mean ±
    spread over seeds)."""
    lines = ["| experiment | paper | RA | RA_true | exact | FRE | seeds | epochs | fit wall (s) "
             "| load | command |", "|---" * 11 + "|"]
    for name, e in EXPERIMENTS.items():
        rs = sorted(_group(results, experiment=name, variant=variant), key=lambda r: r["seed"])
        if not rs:
            continue
        s = [r["summary"] for r in rs]
        seeds = ",".join(str(r["seed"]) for r in rs)
        lines.append(
            f"| {e.title} | {e.paper} | {_pct([x['ra'] for x in s])} | "
            f"{_pct([x['ra_true'] for x in s])} | {_pct([x['exact'] for x in s])} | "
            f"{_ms([x['fre'] for x in s], '{:.2g}')} | {seeds} | {rs[0]['epochs']} | "
            f"{_ms([r['fit_s'] for r in rs], '{:.0f}')} | "
            f"{_ms([r['load_fit_start'] for r in rs], '{:.1f}')} | "
            f"`python -m robovae.evaluate.experiments run {name} --seeds {seeds}` |")
    return "\n".join(lines)


def per_robot_table(results: list[dict], experiment: str, variant: str = "default") -> str:
    """Markdown table: RA / RA_true / exact / FRE of every test robot of one experiment."""
    rs = _group(results, experiment=experiment, variant=variant)
    names: dict[str, list[dict]] = {}
    for r in rs:
        for t in r["test"]:
            names.setdefault(t["name"], []).append(t)
    lines = ["| robot | nodes | RA | RA_true | exact | FRE |", "|---" * 6 + "|"]
    for n, ts in names.items():
        lines.append(f"| {n} | {ts[0]['n_true']} | {_pct([t['ra'] for t in ts])} | "
                     f"{_pct([t['ra_true'] for t in ts])} | "
                     f"{_pct([float(t['exact']) for t in ts])} | "
                     f"{_ms([t['fre'] for t in ts], '{:.2g}')} |")
    return "\n".join(lines)


def loo_table(results: list[dict], variant: str = "default") -> str:
    """Markdown table of the leave-one-out runs: one row per held-out robot."""
    rs = _group(results, experiment="loo", variant=variant)
    by: dict[str, list[dict]] = {}
    for r in rs:
        t = r["test"][0]
        by.setdefault(t["name"], []).append({**t, "seed": r["seed"], "fit_s": r["fit_s"]})
    lines = ["| held-out robot | nodes | RA | RA_true | exact | FRE | decoded nodes (per seed) |",
             "|---" * 7 + "|"]
    for n in MENAGERIE17:
        ts = sorted(by.get(n, []), key=lambda t: t["seed"])
        if not ts:
            continue
        lines.append(f"| {n} | {ts[0]['n_true']} | {_pct([t['ra'] for t in ts])} | "
                     f"{_pct([t['ra_true'] for t in ts])} | "
                     f"{_pct([float(t['exact']) for t in ts])} | "
                     f"{_ms([t['fre'] for t in ts], '{:.2g}')} | "
                     f"{', '.join(str(t['n_pred']) for t in ts)} |")
    seeds = sorted({r["seed"] for r in rs})
    per_seed = [[r["test"][0] for r in rs if r["seed"] == s] for s in seeds]
    if per_seed:
        lines.append(f"| **mean over robots** | | "
                     f"{_pct([statistics.mean(t['ra'] for t in p) for p in per_seed])} | "
                     f"{_pct([statistics.mean(t['ra_true'] for t in p) for p in per_seed])} | "
                     f"{_pct([statistics.mean(float(t['exact']) for t in p) for p in per_seed])}"
                     f" | {_ms([statistics.mean(t['fre'] for t in p) for p in per_seed], '{:.2g}')}"
                     f" | seeds {','.join(map(str, seeds))} (± over seeds) |")
    return "\n".join(lines)


def _replace_block(text: str, key: str, body: str) -> str:
    start, end = f"<!-- auto:{key} -->", f"<!-- /auto:{key} -->"
    if start not in text:
        return text
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n{body}\n{end}{tail}"


def report(doc: Path = DOCS / "results.md", root: Path = RUNS) -> None:
    """Fill the ``<!-- auto:... -->`` blocks of ``docs/results.md`` from the runs under ``root``
    and draw one loss-curve PNG per experiment (its lowest seed) into ``docs/img``."""
    results = load_results(root)
    for name, e in EXPERIMENTS.items():
        rs = sorted(_group(results, experiment=name, variant="default"), key=lambda r: r["seed"])
        if rs and Path(rs[0]["metrics_csv"]).is_file():
            loss_curve_png(rs[0]["metrics_csv"], DOCS / "img" / f"loss_{name}.png",
                           f"{e.title}, seed {rs[0]['seed']}")
    text = doc.read_text()
    text = _replace_block(text, "experiments", experiments_table(results))
    text = _replace_block(text, "menagerie17", per_robot_table(results, "menagerie17"))
    text = _replace_block(text, "loo", loo_table(results))
    doc.write_text(text)
    print(f"wrote {doc}")


# --- command line ----------------------------------------------------------------------------


def _seeds(s: str) -> list[int]:
    return [int(x) for x in s.split(",") if x.strip()]


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m robovae.evaluate.experiments {run,loo,ablation,report,all}``: exit
    code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--all":
        argv[0] = "all"
    # Lightning CLI overrides after ``--`` (``run menagerie2 -- --model.latent_dim=64``)
    passthrough = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    p = argparse.ArgumentParser(prog="python -m robovae.evaluate.experiments",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--seeds", type=_seeds, default=[0, 1, 2])
    common.add_argument("--epochs", type=int, default=None, help="override max_epochs")
    common.add_argument("--threads", type=int, default=0, help="torch threads (0: default)")
    common.add_argument("--jobs", type=int, default=1, help="runs in parallel (processes)")
    common.add_argument("--redo", action="store_true", help="re-run runs that have a result")
    common.add_argument("--variant", default="default", help="ablation variant name")
    common.add_argument("--root", default=str(RUNS), help="where runs are stored")
    r = sub.add_parser("run", parents=[common], help="one experiment of SPEC §6")
    r.add_argument("experiment", choices=list(EXPERIMENTS))
    r.add_argument("overrides", nargs="*", help="extra Lightning CLI arguments (after --)")
    lo = sub.add_parser("loo", parents=[common], help="leave-one-out over the 17 robots")
    lo.add_argument("--robots", default=",".join(MENAGERIE17))
    lo.add_argument("overrides", nargs="*", help="extra Lightning CLI arguments (after --)")
    ab = sub.add_parser("ablation", parents=[common], help="the ablation variants")
    ab.add_argument("--only", default="", help="comma-separated variants")
    ab.add_argument("--loo", action="store_true", help="also the leave-one-out per variant")
    rp = sub.add_parser("report", help="write docs/results.md tables and docs/img loss curves")
    rp.add_argument("--root", default=str(RUNS), help="where runs are stored")
    al = sub.add_parser("all", parents=[common], help="every experiment, LOO, ablation, report")
    al.add_argument("--skip-ablation", action="store_true")
    args = p.parse_args(argv)
    if passthrough:
        if not hasattr(args, "overrides"):
            p.error(f"{args.cmd} takes no Lightning CLI overrides")
        args.overrides = [*args.overrides, *passthrough]
    root = Path(args.root)
    if args.cmd == "report":
        report(root=root)
        return 0
    redo = not args.redo
    ex = {"epochs": args.epochs, "threads": args.threads, "root": root}
    if args.cmd == "run":
        extra = [*ABLATIONS.get(args.variant, ("", ()))[1], *args.overrides]
        _run_all(experiment_specs(args.experiment, args.seeds, args.variant, extra, **ex),
                 args.jobs, redo)
    elif args.cmd == "loo":
        extra = [*ABLATIONS.get(args.variant, ("", ()))[1], *args.overrides]
        _run_all(loo_specs(args.seeds, args.robots.split(","), args.variant, extra, **ex),
                 args.jobs, redo)
    elif args.cmd == "ablation":
        names = args.only.split(",") if args.only else list(ABLATIONS)
        specs = []
        for v in names:
            ov = list(ABLATIONS[v][1])
            for exp in ("menagerie2", "menagerie4"):
                specs += experiment_specs(exp, args.seeds, v, ov, **ex)
            if args.loo:
                specs += loo_specs(args.seeds, variant=v, extra=ov, **ex)
        _run_all(specs, args.jobs, redo)
    elif args.cmd == "all":
        specs = []
        for name in EXPERIMENTS:
            specs += experiment_specs(name, args.seeds, **ex)
        specs += loo_specs(args.seeds, **ex)
        if not args.skip_ablation:  # every seed at 2 and 4 robots, the first for the LOO
            for v, (_, ov) in ABLATIONS.items():
                if v == "default":
                    continue
                for exp in ("menagerie2", "menagerie4"):
                    specs += experiment_specs(exp, args.seeds, v, list(ov), **ex)
                specs += loo_specs(args.seeds[:1], variant=v, extra=list(ov), **ex)
        _run_all(specs, args.jobs, redo)
        report(root=root)
    return 0


if __name__ == "__main__":
    sys.exit(main())
