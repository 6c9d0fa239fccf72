"""Benchmark: are generated robots in one piece and paired? One table over folders of robots.

For every folder of ``robovae generate`` (its ``robot_*/robot.xml``) and, as references, the zoo
(the README model's training robots) and the procedural generator: share of robots with all
bodies attached and mean share of detached bodies
(:mod:`robovae.evaluate.quality.attachment`), share
with self-penetration at rest above 1 cm, share with a single limb on the trunk, and symmetry
share (:func:`robovae.generate.symmetry.is_symmetric`, on the graph read back from the file).

    PYTHONPATH=. python benchmarks/writer_samples.py runs/zoo/samples_a runs/zoo/samples_b
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from robovae.data.loading import load_robot
from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.tables import format_table
from robovae.generate.symmetry import mirrored_pairs

PENETRATION_TOL = 0.01  # m


def _row(label: str, models: list) -> dict:
    rows = []
    for model in models:
        a = attachment(model)
        pairs, n = mirrored_pairs(model_to_graph(model, "paper34"))
        rows.append((a.all_attached, a.detached_share, a.penetration > PENETRATION_TOL,
                     n == 1, pairs >= 1 and n - 2 * pairs <= 1))
    arr = np.array(rows, dtype=float)
    return {"robots": label, "n": len(rows), "all attached": f"{arr[:, 0].mean():.1%}",
            "bodies detached": f"{arr[:, 1].mean():.1%}",
            "penetration > 1 cm": f"{arr[:, 2].mean():.1%}",
            "one limb": f"{arr[:, 3].mean():.1%}", "symmetric": f"{arr[:, 4].mean():.1%}"}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("folders", nargs="*", type=Path)
    p.add_argument("--procedural", type=int, default=100)
    p.add_argument("--first", type=int, default=0, help="robots per folder (0: all)")
    args = p.parse_args()
    table = [_row("zoo (training)", [load_robot(f).model for _, f in zoo_files()[0]])]
    if args.procedural:
        table.append(_row("procedural", [procedural_spec(s).compile()
                                         for s in range(args.procedural)]))
    for folder in args.folders:
        files = sorted(folder.glob("robot_*/robot.xml"))
        files = files[: args.first] if args.first else files
        table.append(_row(str(folder), [load_robot(f).model for f in files]))
    print(format_table(table, ["robots", "n", "all attached", "bodies detached",
                               "penetration > 1 cm", "one limb", "symmetric"]))


if __name__ == "__main__":
    main()
