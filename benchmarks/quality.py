"""Benchmark: throughput of each quality measure (robots/s) and of all of them on 2 cores.

Robots: ``--samples DIR`` (a ``robovae generate`` folder, valid robots) or ``--n`` procedural
robots. Measures every robot once in one process (per-measure times from the records'
``t_<measure>`` fields: loading with a floor, anatomy + symmetry, attachment + penetration,
standing, graph descriptors) and then all measures but locomotion in ``--jobs`` worker
processes (wall clock, workers started inside the timing), and locomotion (64 rollouts of 4 s)
on ``--gait`` robots. Prints one table, and the time 10,000 robots would take at the measured
multi-process rate (the issue's target: ≤ 120 s with every measure but locomotion, 2 cores).

    PYTHONPATH=. python benchmarks/quality.py --n 200 --jobs 2 --gait 8
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

from robovae.evaluate.analyze import sample_files
from robovae.evaluate.quality.measure import measure, measure_many
from robovae.evaluate.quality.populations import procedural_files
from robovae.evaluate.tables import format_table

MEASURES = ("load", "anatomy", "attachment", "standing", "descriptors")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--samples", help="robovae generate folder (default: procedural robots)")
    p.add_argument("--n", type=int, default=200, help="robots")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--gait", type=int, default=8, help="robots for the locomotion measure")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        files = ([f for _, f in sample_files(args.samples)][:args.n] if args.samples
                 else procedural_files(args.n, tmp))
        what = args.samples or "procedural"
        rows = [measure(f) for f in files]
        ok = [r for r in rows if "error" not in r]
        table = []
        for k in MEASURES:
            t = np.array([r[f"t_{k}"] for r in ok if f"t_{k}" in r])
            table.append({"measure": k, "robots": len(t), "ms/robot (1 core)":
                          f"{1e3 * t.mean():.1f} ± {1e3 * t.std():.1f}",
                          "robots/s (1 core)": f"{1 / t.mean():.1f}"})
        per_robot = sum(float(np.mean([r[f"t_{k}"] for r in ok])) for k in MEASURES[:4])
        table.append({"measure": "sum: load + anatomy + attachment + standing",
                      "robots": len(ok), "ms/robot (1 core)": f"{1e3 * per_robot:.1f}",
                      "robots/s (1 core)": f"{1 / per_robot:.1f}"})
        start = time.perf_counter()
        measure_many(files[:args.jobs], jobs=args.jobs, progress=False, describe=False)
        startup = time.perf_counter() - start  # spawning workers (imports) + one robot each
        start = time.perf_counter()
        measure_many(files, jobs=args.jobs, progress=False, describe=False)
        wall = time.perf_counter() - start
        table.append({"measure": f"all but locomotion and descriptors, {args.jobs} processes",
                      "robots": len(files), "ms/robot (1 core)": "-",
                      "robots/s (1 core)": f"{len(files) / wall:.1f} (wall, {args.jobs} jobs)"})
        start = time.perf_counter()
        g = measure_many(files[:args.gait], jobs=args.jobs, progress=False, describe=False,
                         locomotion=True)
        gwall = time.perf_counter() - start
        tg = np.array([r["t_gait"] for r in g if "t_gait" in r])
        table.append({"measure": "locomotion (64 x 4 s)", "robots": len(tg),
                      "ms/robot (1 core)": f"{1e3 * tg.mean():.0f} ± {1e3 * tg.std():.0f}",
                      "robots/s (1 core)": f"{1 / tg.mean():.2f}; {len(g) / gwall:.2f} "
                                           f"(wall, {args.jobs} jobs, all measures)"})
    print(f"robots: {len(files)} ({what}), {len(rows) - len(ok)} errors")
    print(format_table(table, ["measure", "robots", "ms/robot (1 core)", "robots/s (1 core)"]))
    steady = max(wall - startup, 1e-9)
    print(f"10,000 robots, every measure but locomotion, {args.jobs} processes: "
          f"{10_000 * wall / len(files):.0f} s at the measured wall rate (worker start-up "
          f"{startup:.1f} s included once per {len(files)} robots), "
          f"{startup + 10_000 * steady / len(files):.0f} s with start-up once, "
          f"{10_000 * per_robot / args.jobs:.0f} s from the 1-core sum on {args.jobs} free "
          "cores (target 120 s)")


if __name__ == "__main__":
    main()
