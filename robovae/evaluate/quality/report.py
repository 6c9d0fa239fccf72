"""Quality of robot populations side by side: summaries, one table, contact sheets.

A population is a list of :func:`~robovae.evaluate.quality.measure.measure` records.
:func:`summarize` reduces one population to shares and medians; :func:`quality_table` puts
several populations in columns (``samples``, ``training corpus``, ``procedural``, ``real
robots`` ...) with one row per measure, comparing each with the training corpus:

- shares: all bodies attached, mean detached share, self-penetrating (and of those, away
  from joints: bodies passing through each other), symmetric, one limb on
  the root, wheeled (a motor on a hinge without limits), standing (of the floating-base
  robots), median gait speed (extents/s) of all robots and of those not wheeled (stepping, not
  rolling);
- ``W1 <count>``: 1-D Wasserstein distance (:mod:`~robovae.evaluate.quality.distribution`)
  of limbs, bodies, DoF and total mass (kg) to the training corpus; the corpus column holds
  its own split-half distance, the reference a population near the corpus should approach;
- precision / recall of the graph descriptors (``d_*``, standardised with the reference's
  mean and std after log-transforming heavy-tailed ones,
  :func:`robovae.evaluate.population.standardize`) against the training corpus and against
  the real robots (k-NN manifolds, ``k = 3``).

Records with ``error`` are counted and left out of every measure.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from robovae.evaluate.descriptors import VECTOR_DESCRIPTORS
from robovae.evaluate.population import standardize
from robovae.evaluate.quality.distribution import precision_recall, split_half, wasserstein_1d
from robovae.evaluate.tables import format_table

__all__ = ["COUNTS", "contact_sheets", "format_quality", "quality_table", "summarize"]

#: Counts compared with the training corpus by 1-D Wasserstein distance.
COUNTS = ("limbs", "bodies", "dof", "mass")


def _ok(rows: Sequence[dict]) -> list[dict]:
    return [r for r in rows if "error" not in r]


def _share(rows: Sequence[dict], key: str) -> float:
    v = [bool(r[key]) for r in rows if r.get(key) is not None]
    return float(np.mean(v)) if v else math.nan


def _values(rows: Sequence[dict], key: str) -> np.ndarray:
    return np.array([float(r[key]) for r in rows if r.get(key) is not None], dtype=float)


def summarize(rows: Sequence[dict]) -> dict:
    """Shares and medians of one population (module docstring)."""
    ok = _ok(rows)
    floating = [r for r in ok if r.get("floating")]
    speeds = _values(ok, "gait_speed")
    legged = _values([r for r in ok if r.get("wheeled") is False], "gait_speed")
    detached = _values(ok, "detached_share")
    return {"robots": len(rows), "errors": len(rows) - len(ok),
            "all_attached": _share(ok, "all_attached"),
            "detached_share": float(detached.mean()) if detached.size else math.nan,
            "self_penetrating": _share(ok, "self_penetrating"),
            "penetrating_off_joint": _share(ok, "penetrating_off_joint"),
            "symmetric": _share(ok, "symmetric"), "one_limb": _share(ok, "one_limb"),
            "wheeled": _share(ok, "wheeled"),
            "floating": len(floating), "standing": _share(floating, "stands"),
            "gait_speed": float(np.median(speeds)) if speeds.size else math.nan,
            "gait_speed_legged": float(np.median(legged)) if legged.size else math.nan,
            **{f"mean_{k}": (float(_values(ok, k).mean()) if _values(ok, k).size else math.nan)
               for k in COUNTS}}


def _descriptor_matrix(rows: Sequence[dict]) -> np.ndarray:
    return np.array([[float(r.get(f"d_{k}", math.nan)) for k in VECTOR_DESCRIPTORS]
                     for r in _ok(rows) if f"d_{VECTOR_DESCRIPTORS[0]}" in r],
                    dtype=float).reshape(-1, len(VECTOR_DESCRIPTORS))


def _pr(reference: Sequence[dict], samples: Sequence[dict], k: int = 3) -> tuple[float, float]:
    ref, smp = _descriptor_matrix(reference), _descriptor_matrix(samples)
    if not len(ref) or not len(smp):
        return math.nan, math.nan
    ref, smp = standardize(ref, smp, names=VECTOR_DESCRIPTORS)
    return precision_recall(ref, smp, k)


def _fmt(v: float | None, fmt: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return fmt.format(v)


def quality_table(populations: Mapping[str, Sequence[dict]], corpus: str = "training corpus",
                  real: str | None = "real robots", seed: int = 0
                  ) -> tuple[list[dict], list[str], dict]:
    """Rows (one per measure), columns (``measure`` + population names) and the numbers
    behind them (``{population: {measure: value}}``) of the side-by-side table (module
    docstring). ``corpus`` and ``real`` name the reference populations (absent ones give
    ``-``)."""
    names = list(populations)
    numbers: dict[str, dict] = {}
    ref = _ok(populations.get(corpus, []))
    real_rows = _ok(populations.get(real, [])) if real else []
    for name in names:
        rows = populations[name]
        s = summarize(rows)
        ok = _ok(rows)
        for k in COUNTS:
            own, base = _values(ok, k), _values(ref, k)
            if name == corpus:
                s[f"w1_{k}"] = split_half(base, seed=seed)
            else:
                s[f"w1_{k}"] = (wasserstein_1d(own, base) if own.size and base.size
                                else math.nan)
        s["precision_corpus"], s["recall_corpus"] = (
            (math.nan, math.nan) if name == corpus else _pr(ref, ok))
        s["precision_real"], s["recall_real"] = (
            (math.nan, math.nan) if name == real or not real_rows else _pr(real_rows, ok))
        numbers[name] = s
    spec = [("robots measured (errors)", None, None),
            ("all bodies attached", "all_attached", "{:.0%}"),
            ("bodies detached (mean)", "detached_share", "{:.1%}"),
            ("self-penetrating at rest", "self_penetrating", "{:.0%}"),
            ("  of which away from joints", "penetrating_off_joint", "{:.0%}"),
            ("symmetric (mirrored limb pairs)", "symmetric", "{:.0%}"),
            ("one limb on the root", "one_limb", "{:.0%}"),
            ("wheeled (motor on a hinge without limits)", "wheeled", "{:.0%}"),
            ("standing (of floating base)", "standing", "{:.0%}"),
            ("gait speed median (extents/s)", "gait_speed", "{:.3f}"),
            ("gait speed median, not wheeled", "gait_speed_legged", "{:.3f}"),
            *[(f"W1 {k} (corpus: split-half)", f"w1_{k}", "{:.3g}") for k in COUNTS],
            ("precision vs corpus", "precision_corpus", "{:.0%}"),
            ("recall vs corpus", "recall_corpus", "{:.0%}"),
            ("precision vs real robots", "precision_real", "{:.0%}"),
            ("recall vs real robots", "recall_real", "{:.0%}")]
    table = []
    for label, key, fmt in spec:
        row = {"measure": label}
        for name in names:
            s = numbers[name]
            if key is None:
                row[name] = f"{s['robots'] - s['errors']} ({s['errors']})"
                continue
            assert fmt is not None  # only the row without a key has no format
            if key == "standing":
                row[name] = (f"{_fmt(s[key], fmt)} of {s['floating']}" if s["floating"]
                             else "-")
            else:
                row[name] = _fmt(s[key], fmt)
        table.append(row)
    return table, ["measure", *names], numbers


def format_quality(populations: Mapping[str, Sequence[dict]],
                   **kw: Any) -> str:
    """:func:`quality_table` as plain text."""
    rows, cols, _ = quality_table(populations, **kw)
    return format_table(rows, cols)


def _label(r: dict) -> str:
    flags = [("attached" if r.get("all_attached") else "DETACHED"),
             ("sym" if r.get("symmetric") else "asym")]
    if r.get("floating"):
        flags.append("stands" if r.get("stands") else "falls")
    return f"{r['name'][:22]} {' '.join(flags)}" if "error" not in r else r["name"][:30]


def contact_sheets(populations: Mapping[str, Sequence[dict]], out: str | os.PathLike,
                   first: int = 20, columns: int = 5) -> list[Path]:
    """One PNG contact sheet per population (``out/quality_<population>.png``) of its first
    ``first`` measured robot files, each labelled with its attached / symmetric / standing
    flags."""
    from robovae.evaluate.render import contact_sheet

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, rows in populations.items():
        rows = [r for r in rows if r.get("path")][:first]
        if not rows:
            continue
        target = out / f"quality_{name.replace(' ', '_')}.png"
        paths.append(contact_sheet([r["path"] for r in rows], target, columns=columns,
                                   labels=[_label(r) for r in rows]))
    return paths
