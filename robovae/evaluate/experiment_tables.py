"""The tables of ``docs/results.md`` and the loss-curve figures, from the ``result.json`` files
the experiment runner (:mod:`robovae.evaluate.experiment_runner`) leaves: every number in a
table comes from a run that was done, with its seed, epochs, wall time and the machine load
measured around it. Percentages are "mean ± standard deviation over seeds" (one value: no
spread); FRE is in normalised feature units squared.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Callable
from pathlib import Path

from robovae.errors import RobovaeError
from robovae.evaluate.experiment_runner import DOCS, EXPERIMENTS, MENAGERIE17, RUNS


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


def _group(results: list[dict], **match: object) -> list[dict]:
    return [r for r in results if all(r.get(k) == v for k, v in match.items())]


def experiments_table(results: list[dict], variant: str = "default") -> str:
    """Markdown table: one row per experiment, the paper's number beside ours (mean ±
    spread over seeds), from ``z`` alone first (node latents at their conditional-prior mean;
    ``n/a`` for runs made before it was recorded), then with every node's posterior latent."""
    lines = ["| experiment | paper | RA from z | exact from z | FRE from z | RA | RA_true | exact "
             "| FRE | seeds | epochs | fit wall (s) | load | command |", "|---" * 14 + "|"]
    for name, e in EXPERIMENTS.items():
        rs = sorted(_group(results, experiment=name, variant=variant), key=lambda r: r["seed"])
        if not rs:
            continue
        s = [r["summary"] for r in rs]
        z = [r["summary_z"] for r in rs if "summary_z" in r]
        seeds = ",".join(str(r["seed"]) for r in rs)
        lines.append(
            f"| {e.title} | {e.paper} | {_pct([x['ra'] for x in z])} | "
            f"{_pct([x['exact'] for x in z])} | {_ms([x['fre'] for x in z], '{:.2g}')} | "
            f"{_pct([x['ra'] for x in s])} | "
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


def pretrained_table(results: list[dict], experiment: str, name: str) -> str:
    """Markdown table of a pretrained model on the 17 Menagerie robots (``zeroshot`` or
    ``finetune`` runs of model ``name``, :mod:`robovae.evaluate.pretrained`): per held-out robot,
    from ``z`` alone — decoded node count, min(RA, RA_true), exact, FRE — then the full
    channel's min(RA, RA_true) and what the latents cost (nats: ``KL_z`` and its tree part per
    robot, ``KL_nodes`` per node); the last row the means over robots (± over seeds)."""
    rs = [r for r in results if r.get("experiment") == experiment
          and r.get("variant", r.get("name")) == name]
    by: dict[str, list[tuple[dict, dict]]] = {}
    for r in rs:
        for z, f in zip(r["test_z"], r["test"]):
            by.setdefault(z["name"], []).append((z, f))
    lines = ["| robot | nodes | decoded nodes from z | min(RA, RA_true) from z | exact from z | "
             "FRE from z | min(RA, RA_true) full | KL_z | KL_tree | KL_nodes per node |",
             "|---" * 10 + "|"]

    def mra(t: dict) -> float:
        return min(t["ra"], t["ra_true"])

    for n in MENAGERIE17:
        ts = by.get(n, [])
        if not ts:
            continue
        z, f = [t[0] for t in ts], [t[1] for t in ts]
        lines.append(f"| {n} | {z[0]['n_true']} | {', '.join(str(t['n_pred']) for t in z)} | "
                     f"{_ms([mra(t) for t in z])} | {_pct([float(t['exact']) for t in z])} | "
                     f"{_ms([t['fre'] for t in z], '{:.2g}')} | {_ms([mra(t) for t in f])} | "
                     f"{_ms([t['kl_z'] for t in z], '{:.0f}')} | "
                     f"{_ms([t.get('kl_tree', math.nan) for t in z], '{:.0f}')} | "
                     f"{_ms([t['kl_nodes'] / t['nodes'] for t in z], '{:.1f}')} |")
    seeds = sorted({r.get("seed", 0) for r in rs})
    groups = [[t for r in rs if r.get("seed", 0) == s for t in zip(r["test_z"], r["test"])]
              for s in seeds]
    if groups and groups[0]:
        def mean(fn: Callable[[dict], float], side: int = 0) -> list[float]:
            return [statistics.mean(fn(t[side]) for t in g) for g in groups]

        exact = [sum(float(t[0]["exact"]) for t in g) for g in groups]
        per_node = [sum(t[0]["kl_nodes"] for t in g) / sum(t[0]["nodes"] for t in g)
                    for g in groups]
        lines.append(
            f"| **mean over robots** | | | {_ms(mean(mra))} | "
            f"{_ms(exact, '{:.0f}')} of {len(groups[0])} | "
            f"{_ms(mean(lambda t: t['fre']), '{:.2g}')} | {_ms(mean(mra, 1))} | "
            f"{_ms(mean(lambda t: t['kl_z']), '{:.0f}')} | "
            f"{_ms(mean(lambda t: t.get('kl_tree', math.nan)), '{:.0f}')} | "
            f"{_ms(per_node, '{:.1f}')} |")
    return "\n".join(lines)


def _replace_block(text: str, key: str, body: str) -> str:
    """``text`` with the block ``key`` holding ``body``; a ``body`` of no row (a header and
    its separator: no run of that table under the root) leaves the block as it was, so that
    a report over some of the runs keeps the measured tables of the others."""
    start, end = f"<!-- auto:{key} -->", f"<!-- /auto:{key} -->"
    if start not in text or len(body.strip().splitlines()) <= 2:
        return text
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n{body}\n{end}{tail}"


def report(doc: Path = DOCS / "results.md", root: Path = RUNS) -> None:
    """Fill the ``<!-- auto:... -->`` blocks of ``docs/results.md`` from the runs under ``root``
    and draw one loss-curve PNG per experiment (its lowest seed) into ``docs/img``; a table
    without runs under ``root`` keeps its block.

    Raises:
        RobovaeError: no ``result.json`` under ``root`` (``doc`` is left as it is; until
            2026-11-29 every table was emptied).
    """
    results = load_results(root)
    if not results:
        raise RobovaeError(f"robovae: {root}: no result.json of any run; {doc} left as it is")
    for name, e in EXPERIMENTS.items():
        rs = sorted(_group(results, experiment=name, variant="default"), key=lambda r: r["seed"])
        if rs and Path(rs[0]["metrics_csv"]).is_file():
            loss_curve_png(rs[0]["metrics_csv"], DOCS / "img" / f"loss_{name}.png",
                           f"{e.title}, seed {rs[0]['seed']}")
    text = doc.read_text()
    text = _replace_block(text, "experiments", experiments_table(results))
    text = _replace_block(text, "menagerie17", per_robot_table(results, "menagerie17"))
    text = _replace_block(text, "loo", loo_table(results))
    for experiment in ("zeroshot", "finetune"):
        for name in ("default", "large"):
            text = _replace_block(text, f"{experiment}_{name}",
                                  pretrained_table(results, experiment, name))
    doc.write_text(text)
    print(f"wrote {doc}")
