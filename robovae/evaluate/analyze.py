"""``robovae analyze``: the statistical view of a checkpoint's design space (paper §6.2).

:func:`analyze` compares two populations of robots:

- **training**: the robots the checkpoint was trained on — the dataset of its data sources
  (or ``sources``) restricted to the names stored in the checkpoint (every robot of the
  sources when none of those names is found);
- **samples** (optional): a folder of generated robots (``robovae generate --out DIR``; the
  valid robots of its manifest, loaded back from their ``robot.xml``).

(loaded by :func:`training_graphs`, :func:`sample_files` and :func:`load_graphs`). It reports,
for each population, descriptor statistics (:mod:`robovae.evaluate.descriptors`,
:mod:`robovae.evaluate.population`), latent statistics of the encoded means (Gaussian and
k-NN entropy, the latter also at equal size: the larger population's on random subsets of the
smaller one's size, effective dimensionality), MuJoCo behaviour (random-actuation state entropy and
the standing test, :mod:`robovae.evaluate.behaviour`) on up to ``behaviour`` robots, and
between the populations the KL per descriptor, MMD² and coverage.

With ``quality`` > 0 it also measures robot quality (:mod:`robovae.evaluate.quality`: attached
bodies, self-penetration, symmetry, standing, optionally locomotion, count distances and
descriptor precision/recall) on up to ``quality`` robots of each of four populations —
samples, training corpus (spread over it, procedural training robots rebuilt from their
seeds: :func:`~robovae.evaluate.quality.populations.corpus_files`), ``procedural`` robots of
the generator at seeds no config trains on
(:data:`~robovae.evaluate.quality.populations.HOLDOUT_SEED`) and the real robots of the
``real`` folder (Menagerie) — printed side by side in one table
(:func:`~robovae.evaluate.quality.report.quality_table`), with contact sheets when ``sheets``
names a folder.
:func:`format_report` prints the tables; the result is JSON-ready (NaN → ``null``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path

import numpy as np
import torch
from torch_geometric.data import Batch

from robovae.data.dataset import RobotDataset
from robovae.data.graph import RobotData
from robovae.data.mjcf import mjcf_to_graph
from robovae.data.workers import process_pool
from robovae.errors import RobovaeError
from robovae.evaluate.behaviour import behaviour_many, summarize_behaviour
from robovae.evaluate.descriptors import DESCRIPTORS, descriptors, robot_category
from robovae.evaluate.population import compare, latent_stats, summary
from robovae.evaluate.quality.measure import measure_many
from robovae.evaluate.quality.populations import (
    HOLDOUT_SEED,
    corpus_files,
    procedural_files,
    real_robot_files,
    source_file,
)
from robovae.evaluate.quality.report import contact_sheets, quality_table
from robovae.evaluate.tables import format_table
from robovae.files import atomic_json, writable
from robovae.generate.pipeline import read_manifest
from robovae.model.checkpoint import load_model, read_checkpoint
from robovae.model.vae import RoboVAE
from robovae.options import check_analyze


@torch.no_grad()
def encode_means(model: RoboVAE, graphs: Sequence[RobotData], batch_size: int = 128
                 ) -> np.ndarray:
    """Encoded means ``mu`` ``[N, latent_dim]`` (float64) of robot graphs (physical units), in
    batches of ``batch_size``.

    On CPU the encoder runs with one torch thread (``torch.set_num_threads(1)``, restored
    afterwards): its per-level matrix products are small (docs/generation.md, "Implementation
    notes").
    """
    out = []
    threads = torch.get_num_threads()
    if model.device.type == "cpu":
        torch.set_num_threads(1)
    try:
        for k in range(0, len(graphs), batch_size):
            mu, _ = model.encode(Batch.from_data_list(list(graphs[k:k + batch_size])))
            out.append(mu.double().cpu().numpy())
    finally:
        torch.set_num_threads(threads)
    return np.concatenate(out) if out else np.zeros((0, model.hparams.latent_dim))


def training_graphs(model: RoboVAE, ckpt: str | Path | None = None,
                    sources: Sequence[str] | None = None, root: str | Path = "data_cache"
                    ) -> tuple[list[RobotData], str]:
    """The checkpoint's training robots and a one-line description of where they came from.

    The dataset of ``sources`` (default: the checkpoint's data sources, else ``zoo``) in the
    model's feature set, restricted to the robot names stored in the checkpoint (every robot of
    the sources when none of those names is found).
    """
    if not sources:
        dm = read_checkpoint(ckpt).get("datamodule_hyper_parameters", {}) if ckpt else {}
        sources = list(dm.get("sources") or ["zoo"])
    ds = RobotDataset(root, list(sources), model.feature_set.name, progress=False)
    names = {r.get("name") for r in model.training_robots}
    graphs = [d for d in ds if d.name in names]
    what = f"{len(graphs)} training robots of {', '.join(sources)}"
    if not graphs:
        graphs = list(ds)
        what = f"all {len(graphs)} robots of {', '.join(sources)} (no training names matched)"
    return graphs, what


def load_graphs(paths: Sequence[str | Path], feature_set: str = "paper34",
                names: Sequence[str] | None = None) -> tuple[list[RobotData], list[str]]:
    """Robot graphs of files in ``feature_set`` (named ``names[k]``, else by file) and the
    one-line messages of the files that failed (:class:`~robovae.errors.RobovaeError` or
    ``ValueError``: collected, never raised)."""
    graphs, errors = [], []
    for k, p in enumerate(paths):
        try:
            graphs.append(mjcf_to_graph(p, feature_set,
                                        name=names[k] if names is not None else None))
        except (RobovaeError, ValueError) as e:
            errors.append(str(e))
    return graphs, errors


def sample_files(folder: str | Path, valid_only: bool = True) -> list[tuple[str, Path]]:
    """``[(name, robot.xml)]`` of a folder written by ``robovae generate``.

    With a ``manifest.jsonl`` and ``valid_only``, only the robots it calls valid; without a
    manifest, every ``robot_*/robot.xml`` (else every ``*.xml`` below the folder but
    ``scene.xml``).

    Raises:
        RobovaeError: ``folder`` is not a folder.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise RobovaeError(f"robovae: {folder}: no such folder of samples")
    records = read_manifest(folder)
    if records:
        out = []
        for i, rec in sorted(records.items()):
            if valid_only and rec.get("valid") is False:
                continue
            path = folder / rec.get("path", f"robot_{i:06d}/robot.xml")
            if path.is_file():
                out.append((rec.get("name") or f"robot_{i:06d}", path))
        return out
    files = sorted(folder.glob("robot_*/robot.xml")) or sorted(
        p for p in folder.rglob("*.xml") if p.name != "scene.xml")
    return [(p.parent.name if p.name == "robot.xml" else p.stem, p) for p in files]


def _population(model: RoboVAE, graphs: Sequence[RobotData], files: Sequence[str | None],
                behaviour: int, jobs: int, match: int | None = None,
                entropy_kw: dict | None = None) -> dict:
    records = []
    for g in graphs:
        rec = descriptors(g, model.feature_set)
        rec["category"] = robot_category(rec["name"], g)
        records.append(rec)
    mu = encode_means(model, graphs)
    out = {"robots": len(graphs), "records": records, "summary": summary(records),
           "latent": latent_stats(mu, match=match)}
    chosen = [(r, f) for r, f in zip(records, files) if f][: max(behaviour, 0)]
    if chosen:
        rows = behaviour_many([f for _, f in chosen], jobs=jobs, entropy=entropy_kw)
        for (rec, _), row in zip(chosen, rows):
            row["name"], row["category"] = rec["name"], rec["category"]
        out["behaviour"] = rows
        out["behaviour_summary"] = summarize_behaviour(rows)
    return out


def analyze(ckpt: str | Path, samples: str | Path | None = None,
            sources: Sequence[str] | None = None, root: str | Path = "data_cache",
            behaviour: int = 100, jobs: int = 1, permutations: int = 200, seed: int = 0,
            max_samples: int | None = None, entropy_seconds: float = 3.0, quality: int = 0,
            procedural: int = 200, real: str | Path | None = None, locomotion: bool = False,
            sheets: str | Path | None = None, progress: bool = True,
            gait_search: str = "random", gait_rollouts: int = 64) -> dict:
    """The statistical view of a checkpoint and (optionally) a folder of its samples.

    Args:
        ckpt: Lightning checkpoint.
        samples: folder written by ``robovae generate`` (valid robots only), or None.
        sources: data sources of the training robots (default: the checkpoint's).
        root: dataset cache folder.
        behaviour: MuJoCo measures on at most this many robots per population (0: none).
        jobs: worker processes for the MuJoCo measures (0: all cores).
        permutations: permutations of the MMD test.
        seed: seed of the MMD permutations and subsets.
        max_samples: use at most this many sample robots (the first ones).
        entropy_seconds: length of each random-actuation episode.
        quality: quality measures on at most this many robots per population (0: none).
        procedural: procedural robots in the quality table (0: none).
        real: folder of real robots (default ``../shared/menagerie``; absent: none; ``robovae
            analyze --real`` refuses a folder that does not exist).
        locomotion: also the gait-speed measure (``gait_rollouts`` rollouts of 4 s per robot).
        gait_search: the gait-speed measure's search, ``"random"`` gaits or ``"cma"`` (random
            gaits tuned by CMA-ES at the same budget:
            :func:`~robovae.evaluate.quality.gait_search.budget_gait`).
        gait_rollouts: the gait-speed measure's budget, rollouts per robot.
        sheets: folder for the quality contact sheets (None: none).
        progress: progress bars of the quality measures.

    Returns:
        A JSON-ready dict (:func:`to_json`): ``training`` and ``samples`` populations (robot
        records, descriptor ``summary``, ``latent`` statistics, ``behaviour`` rows and
        ``behaviour_summary``), ``comparison`` (KL, MMD, coverage) and, with ``quality``,
        ``quality`` (per-population records, table rows and numbers).
    """
    start = time.perf_counter()
    check_analyze(behaviour=behaviour, jobs=jobs, permutations=permutations, quality=quality,
                  procedural=procedural, max_samples=max_samples,
                  entropy_seconds=entropy_seconds, gait_rollouts=gait_rollouts,
                  gait_search=gait_search, seed=seed)
    if sheets is not None:  # before minutes of work, not after
        writable(sheets, "contact sheets", make=False)  # contact_sheets makes it
    files = sample_files(samples) if samples is not None else []  # checked first
    if samples is not None and not files:
        raise RobovaeError(f"robovae: {samples}: no robot to analyse (no robot_*/robot.xml or "
                           "*.xml, or none that its manifest calls valid)")
    model = load_model(ckpt)
    graphs: list[RobotData] = []
    errors: list[str] = []
    if samples is not None:  # loaded before the training corpus is built (minutes)
        if max_samples is not None:
            files = files[:max_samples]
        names = [n for n, _ in files]
        graphs, errors = load_graphs([p for _, p in files], model.feature_set.name, names)
        if not graphs:
            first = f": {errors[0].removeprefix('robovae: ')}" if errors else ""
            raise RobovaeError(f"robovae: {samples}: no robot loaded "
                               f"({len(errors)} files failed{first})")
    train, what = training_graphs(model, ckpt, sources, root)
    entropy_kw = {"seconds": entropy_seconds}
    result: dict = {"checkpoint": str(ckpt), "feature_set": model.feature_set.name,
                    "latent_dim": int(model.hparams.latent_dim)}
    # the robots measured: the first `behaviour` with a source, procedural ones written from
    # their seeds (source_file)
    train_sources = [getattr(g, "source", None) for g in train]
    with_source = [(i, src) for i, src in enumerate(train_sources) if src][: max(behaviour, 0)]
    train_files: list[str | None] = [None] * len(train)
    for i, src in with_source:
        train_files[i] = source_file(src, root)
    # the k-NN entropy of the larger population also on subsets of the smaller one's size
    result["training"] = {"what": what, **_population(
        model, train, train_files, behaviour, jobs, entropy_kw=entropy_kw,
        match=len(graphs) if graphs and len(graphs) < len(train) else None)}
    sample_paths: list[str] = []
    if graphs:
        sample_paths = [g.source for g in graphs]
        pop = _population(model, graphs, sample_paths, behaviour, jobs,
                          match=len(train), entropy_kw=entropy_kw)
        assert samples is not None  # graphs are only loaded from samples
        manifest = _manifest_counts(Path(samples))
        result["samples"] = {"what": f"{len(graphs)} valid robots of {samples}"
                             + (f" ({manifest['total']} generated)" if manifest else ""),
                             "folder": str(samples), "load_errors": errors, **manifest, **pop}
        result["comparison"] = compare(result["training"]["records"], pop["records"],
                                       permutations=permutations, seed=seed)
    if quality > 0:
        corpus = corpus_files([getattr(g, "source", None) for g in train],
                              [g.name for g in train], quality, root)
        groups: dict[str, tuple[Sequence[str | Path], Sequence[str] | None]] = {
            "samples": (sample_paths[:quality], None),
            "training corpus": corpus,
            "procedural": (procedural_files(min(procedural, quality), root,
                                            HOLDOUT_SEED + seed), None),
            "real robots": (real_robot_files(real)[:quality], None)}
        workers = jobs or 2
        # one pool for the four populations: a worker spends seconds on its imports
        with process_pool(workers) if workers > 1 else nullcontext() as pool:
            pops = {k: measure_many(files, jobs=workers, progress=progress, desc=k, names=names,
                                    pool=pool, locomotion=locomotion, gait_search=gait_search,
                                    gait_kw={"rollouts": gait_rollouts})
                    for k, (files, names) in groups.items() if files}
        rows, cols, numbers = quality_table(pops, seed=seed)
        result["quality"] = {"populations": pops, "table": rows, "columns": cols,
                             "numbers": numbers}
        if locomotion:
            result["quality"]["gait"] = {"search": gait_search, "rollouts": gait_rollouts}
        if sheets is not None:
            result["quality"]["sheets"] = [str(p) for p in contact_sheets(pops, sheets)]
    result["seconds"] = time.perf_counter() - start
    return result


def _manifest_counts(folder: Path) -> dict:
    recs = read_manifest(folder)
    if not recs:
        return {}
    return {"total": len(recs), "valid": sum(1 for r in recs.values() if r.get("valid"))}


# ----------------------------------------------------------------------------------------------
# output


def to_json(obj: object) -> object:
    """``obj`` with NaN/inf floats as ``None`` and numpy scalars as Python numbers."""
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def save_json(result: dict, path: str | Path) -> Path:
    """Write :func:`to_json` of ``result`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_json(path, to_json(result), durable=False)


def _f(v: float | None, fmt: str = "{:.3g}") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    return fmt.format(v)


def _ms(s: dict) -> str:
    return "-" if not s.get("n") else f"{_f(s['mean'])} ± {_f(s['std'])}"


def format_report(result: dict) -> str:
    """The tables :func:`analyze` results print as (plain text)."""
    tr, sa, cmp_ = result["training"], result.get("samples"), result.get("comparison")
    lines = [f"training: {tr['what']}"]
    if sa:
        lines.append(f"samples:  {sa['what']}")
    rows = []
    for n in DESCRIPTORS:
        row = {"descriptor": n, "training": _ms(tr["summary"][n])}
        if sa:
            assert cmp_ is not None  # analyze writes "comparison" with "samples"
            row["samples"] = _ms(sa["summary"][n])
            row["KL(train||samples)"] = _f(cmp_["kl"][n], "{:.3f}")
        rows.append(row)
    cols = ["descriptor", "training"] + (["samples", "KL(train||samples)"] if sa else [])
    lines += ["", format_table(rows, cols)]
    if sa:
        assert cmp_ is not None  # analyze writes "comparison" with "samples"
        m, c = cmp_["mmd"], cmp_["coverage"]
        lines += ["", f"KL summed over descriptors {_f(cmp_['kl_total'], '{:.3f}')} nats; "
                  f"MMD² {_f(m['mmd2'], '{:.4f}')} (RBF, bandwidth {_f(m['bandwidth'])}, "
                  f"permutation p = {_f(m['p_value'], '{:.3f}')}); coverage "
                  f"{_f(c['coverage'], '{:.1%}')} of training robots have a sample within "
                  f"{_f(c['threshold'])} (standardised descriptors), precision "
                  f"{_f(c['precision'], '{:.1%}')} of samples near a training robot"]
    pops = [("training", tr)] + ([("samples", sa)] if sa else [])
    rows = []
    for label, p in pops:
        lat = p["latent"]
        row = {"population": label, "robots": p["robots"],
               "H_gauss": _f(lat.get("gaussian_entropy"), "{:.2f}"),
               "H_knn": _f(lat.get("knn_entropy"), "{:.2f}"),
               "H_knn@n": _f(lat.get("knn_entropy_matched", lat.get("knn_entropy")),
                             "{:.2f}"),
               "eff_dim": _f(lat.get("effective_dim"), "{:.2f}"),
               "variance": _f(lat.get("total_variance"), "{:.3g}"),
               "median|mu|": _f(lat.get("median_norm"), "{:.2f}")}
        rows.append(row)
    prior = tr["latent"]["prior_entropy"]
    n_eq = min(p["robots"] for _, p in pops)
    lines += ["", f"latent space (encoded means, {result['latent_dim']} dims; the prior "
              f"N(0, I) has entropy {prior:.2f} nats; H_knn@n: k-NN entropy at n = {n_eq} "
              "robots, the larger population's on random subsets of that size)",
              format_table(rows, ["population", "robots", "H_gauss", "H_knn", "H_knn@n",
                                  "eff_dim", "variance", "median|mu|"])]
    rows = []
    for label, p in pops:
        b = p.get("behaviour_summary")
        if not b:
            continue
        rows.append({"population": label, "measured": b["robots"],
                     "root_H": _f(b["root_entropy"], "{:.2f}"),
                     "root_H/size": _f(b["root_entropy_scaled"], "{:.2f}"),
                     "joint_H": _f(b["joint_entropy"], "{:.2f}"),
                     "displacement": _f(b["displacement"], "{:.2f}"),
                     "stand": f"{b['standing']}/{b['floating']}", "errors": b["errors"]})
    if rows:
        lines += ["", "MuJoCo behaviour (random actuation: k-NN state entropy in nats; "
                  "standing test: floating-base robots that stand)",
                  format_table(rows, ["population", "measured", "root_H", "root_H/size",
                                      "joint_H", "displacement", "stand", "errors"])]
    if tr.get("behaviour"):
        rows = [{"robot": r["name"], "category": r["category"],
                 "root_H": _f(r.get("root_entropy"), "{:.2f}"),
                 "root_H/size": _f(r.get("root_entropy_scaled"), "{:.2f}"),
                 "joint_H": _f(r.get("joint_entropy"), "{:.2f}"),
                 "displacement": _f(r.get("displacement"), "{:.2f}"),
                 "stands": ("-" if not r.get("floating") else _f(r.get("stands"))),
                 "fell_at": _f(r.get("fell_at"), "{:.2f}"),
                 "max_tilt": _f(r.get("max_tilt"), "{:.0f}"),
                 "note": (r.get("error", "")[:60] if "error" in r else
                          "no free joint" if r.get("floating") is False else "")}
                for r in tr["behaviour"]]
        lines += ["", "training robots",
                  format_table(rows, ["robot", "category", "root_H", "root_H/size", "joint_H",
                                      "displacement", "stands", "fell_at", "max_tilt", "note"])]
    q = result.get("quality")
    if q:
        lines += ["", "robot quality (attached: every body within 5 % of the extent of its "
                  "parent; symmetric: limbs in mirrored pairs within 10 %; standing: 3 s "
                  "joints held at rest; W1 to the training corpus)",
                  format_table(q["table"], q["columns"])]
        if "gait" in q:
            how = "random gaits" if q["gait"]["search"] == "random" else \
                "random gaits tuned by CMA-ES"
            lines.append(f"gait speed: best of {q['gait']['rollouts']} open-loop rollouts of 4 s "
                         f"({how}), forward speed over the extent")
        lines += [f"contact sheet: {p}" for p in q.get("sheets", [])]
    lines.append(f"\n({result['seconds']:.1f} s)")
    return "\n".join(lines)


__all__ = ["analyze", "encode_means", "format_report", "load_graphs", "sample_files",
           "save_json", "to_json", "training_graphs"]
