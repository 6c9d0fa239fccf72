"""Benchmark: MJCF → ``Data`` throughput and dataset cache load time.

Writes N procedural robots (real MJCF), builds a ``RobotDataset`` from them (cold, no cache),
then loads the cached dataset again. Prints one table.

    python benchmarks/data_build.py --n 10000 --jobs 2
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from robovae.data.dataset import RobotDataset
from robovae.data.procedural import write_procedural
from robovae.evaluate.tables import format_table


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--n", type=int, default=10_000)
    p.add_argument("--jobs", type=int, default=0, help="loader processes (0: all cores)")
    p.add_argument("--feature-set", default="paper34")
    p.add_argument("--root", default=None, help="work folder (default: a temp folder)")
    args = p.parse_args()
    root = Path(args.root or tempfile.mkdtemp(prefix="robovae_bench_"))
    files = root / "mjcf"
    rows = []
    t = time.perf_counter()
    paths = write_procedural(files, args.n, seed=0)
    dt = time.perf_counter() - t
    rows.append({"step": "write MJCF (procedural)", "files": len(paths), "seconds": f"{dt:.2f}",
                 "files/s": f"{len(paths) / dt:.0f}"})
    cache = root / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    t = time.perf_counter()
    ds = RobotDataset(cache, [f"dir:{files}"], args.feature_set, jobs=args.jobs, progress=False)
    dt = time.perf_counter() - t
    rows.append({"step": f"MJCF → Data, cold build ({ds.jobs} jobs)", "files": len(ds),
                 "seconds": f"{dt:.2f}", "files/s": f"{len(ds) / dt:.0f}"})
    t = time.perf_counter()
    ds2 = RobotDataset(cache, [f"dir:{files}"], args.feature_set, progress=False)
    dt = time.perf_counter() - t
    rows.append({"step": "load cached dataset", "files": len(ds2), "seconds": f"{dt:.2f}",
                 "files/s": f"{len(ds2) / dt:.0f}"})
    print(format_table(rows, ["step", "files", "seconds", "files/s"]))
    nodes = sum(r["nodes"] for r in ds.report["robots"])
    print(f"skipped: {len(ds.report['skipped'])}, nodes: {nodes}")
    if args.root is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
