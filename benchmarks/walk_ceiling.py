"""Diagnostic: how fast can the best robots of walk runs go with a gait tuned to the body? Table.

``robovae optimize --task walk`` scores each robot by the best of 8 random open-loop gaits
(:func:`robovae.design.score.walk_score`). For finished runs (their ``--out`` folders) this
re-scores each method's ``--top`` best robots (``best/<method>/rank_<k>/robot.xml``) with
:func:`robovae.evaluate.quality.gait_search.searched_gait` in the walk score's scene and
settings (3 s, the first 1 s not counted, falls at 60°), starting from the walk score's own 8
gaits (score seed 0) and tuning them with CMA-ES for ``--refine`` more rollouts: so each
searched speed is at least the robot's in-run score. Per run and method it prints the in-run
best, the best searched speed among the top robots (with its rank) and CMA-ES's ratio to the
prior's and the procedural generator's under each score.

    PYTHONPATH=. python benchmarks/walk_ceiling.py /tmp/opt_s0 /tmp/opt_s1 --top 10 --jobs 2
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from robovae.data.workers import process_pool
from robovae.evaluate.tables import format_table

METHODS = ("cma", "prior", "procedural")


def searched(task: tuple[str, int]) -> tuple[float, int]:
    """Searched walk speed (body lengths per second) of one robot file and the rollouts used:
    ``robovae.design.score.walk_gait`` with ``refine`` (the walk score's scene, settings and
    score seed 0, then CMA-ES; what ``robovae gait`` writes)."""
    from robovae.design.score import walk_gait

    path, refine = task
    g = walk_gait(path, refine=refine)
    return g["score"], g["rollouts"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="--out folders of walk runs")
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--refine", type=int, default=496)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    tasks, keys, inrun = [], [], {}
    for run in args.runs:
        log = json.loads((run / "log.json").read_text())
        for m in METHODS:
            scores = [e["score"] for e in log["evaluations"].get(m, [])]
            inrun[run, m] = max(scores, default=0.0)
            for k in range(args.top):
                path = run / "best" / m / f"rank_{k}" / "robot.xml"
                if path.exists():
                    tasks.append((str(path), args.refine))
                    keys.append((run, m, k))
    with process_pool(args.jobs) as pool:
        results = list(pool.map(searched, tasks, chunksize=1))
    best: dict = {}
    for (run, m, k), (speed, _) in zip(keys, results):
        if speed > best.get((run, m), (-1.0, -1))[0]:
            best[run, m] = (speed, k)
    rows = []
    for run in args.runs:
        row = {"run": run.name}
        for m in METHODS:
            s, k = best.get((run, m), (0.0, -1))
            row[f"{m} in-run"], row[f"{m} searched (rank)"] = f"{inrun[run, m]:.3f}", \
                f"{s:.3f} ({k})"
        for ref in ("prior", "procedural"):
            a, b = inrun[run, "cma"], inrun[run, ref]
            sa, sb = best.get((run, "cma"), (0.0,))[0], best.get((run, ref), (0.0,))[0]
            row[f"CMA/{ref} in-run / searched"] = f"{a / b:.2f} / {sa / sb:.2f}" \
                if b > 0 and sb > 0 else "-"
        rows.append(row)
    columns = ["run"] + [f"{m} {c}" for m in METHODS for c in ("in-run", "searched (rank)")] \
        + [f"CMA/{ref} in-run / searched" for ref in ("prior", "procedural")]
    rollouts = results[0][1] if results else 0
    print(f"walk speed (body lengths/s) of the {args.top} best robots per method, gaits "
          f"searched with {rollouts} rollouts in the walk score's scene and settings")
    print(format_table(rows, columns))

if __name__ == "__main__":
    main()
