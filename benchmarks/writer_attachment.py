"""Benchmark: does the writer keep robots in one piece? Round trip robot file → graph → writer.

For every robot of a group (the zoo: dm_control + gymnasium models; ``--procedural N``
procedural robots; the Menagerie robots of ``--menagerie``), the original and the writer's
round trip (``mjcf_to_graph`` in ``--feature-set``, then ``graph_to_spec`` with the rules) are
measured with :func:`robovae.evaluate.quality.attachment.attachment`: share of robots with
all bodies
attached, mean share of detached bodies, share with self-penetration at rest above 1 cm and the
writer rules that fired. Prints one table.

    PYTHONPATH=. python benchmarks/writer_attachment.py --procedural 200
"""

from __future__ import annotations

import argparse
import os
import time
from collections import Counter
from pathlib import Path

import mujoco
import numpy as np

from robovae.data.loading import load_robot
from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.tables import format_table
from robovae.generate.writer import graph_to_spec

PENETRATION_TOL = 0.01  # m, as robovae.generate.validate


def _groups(n_procedural: int, menagerie: Path) -> dict[str, list[tuple[str, mujoco.MjModel]]]:
    zoo = [(name, load_robot(path).model) for name, path in zoo_files()[0]]
    out = {
        "gymnasium": [(n, m) for n, m in zoo if n.startswith("gym_")],
        "dm_control": [(n, m) for n, m in zoo if n.startswith("dmc_")],
        "procedural": [(f"proc_{s}", procedural_spec(s).compile()) for s in range(n_procedural)],
        "menagerie": [(p.parent.name, load_robot(p).model)
                      for p in sorted(menagerie.glob("*/*.xml"))],
    }
    return {k: v for k, v in out.items() if v}


def _measure(models: list[tuple[str, mujoco.MjModel]], fs: str, roundtrip: bool
             ) -> tuple[dict, Counter, list[str]]:
    rows, rules, bad = [], Counter(), []
    for name, model in models:
        if roundtrip:
            spec, fired = graph_to_spec(model_to_graph(model, fs, name=name), fs, name=name)
            rules.update(fired)
            model = spec.compile()
        a = attachment(model)
        rows.append((a.all_attached, a.detached_share, a.penetration > PENETRATION_TOL))
        if not a.all_attached:
            bad.append(name)
    arr = np.array(rows, dtype=float)
    return {"robots": len(rows), "all attached": f"{arr[:, 0].mean():.1%}",
            "bodies detached": f"{arr[:, 1].mean():.1%}",
            "penetration > 1 cm": f"{arr[:, 2].mean():.1%}"}, rules, bad


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--procedural", type=int, default=200, help="procedural robots (seeds 0..N-1)")
    p.add_argument("--menagerie", type=Path,
                   default=Path(os.environ.get("ROBOVAE_SHARED_MENAGERIE", "../shared/menagerie")))
    p.add_argument("--feature-set", default="paper34")
    p.add_argument("--show", action="store_true", help="list the robots with detached bodies")
    args = p.parse_args()
    table = []
    t = time.perf_counter()
    for group, models in _groups(args.procedural, args.menagerie).items():
        for roundtrip in (False, True):
            row, rules, bad = _measure(models, args.feature_set, roundtrip)
            table.append({"robots of": group, "as": "round trip" if roundtrip else "original",
                          **row, "rules fired": ", ".join(f"{k} {v}" for k, v in
                                                          sorted(rules.items()))})
            if args.show and bad:
                print(f"{group} {'round trip' if roundtrip else 'original'}: detached in "
                      + ", ".join(bad))
    print(format_table(table, ["robots of", "as", "robots", "all attached", "bodies detached",
                               "penetration > 1 cm", "rules fired"]))
    print(f"feature set {args.feature_set}, {time.perf_counter() - t:.1f} s")


if __name__ == "__main__":
    main()
