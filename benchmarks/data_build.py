"""Benchmark: building procedural datasets, in memory (fast path) and through MJCF files.

Rows (one table, wall and CPU time; on a shared machine the CPU time divided by the jobs is
the wall time an idle machine with that many cores would need):

- with ``--stages``, ``procedural graphs only``: :func:`robovae.data.procedural.procedural_graphs`
  on ``--n`` robots in ``--jobs`` processes: plan → ``MjSpec`` → compile → graph, no XML;
- ``dataset cold build``: ``RobotDataset(["procedural:n=N"])`` from nothing, i.e. the graphs
  plus de-duplication, the build report and the saved cache (what ``robovae data`` does);
- ``load cached dataset``: the same dataset again, read from its cache;
- baseline, on ``--files`` robots: ``write MJCF`` then ``MJCF → Data`` (the file path).

Then the class mix and node counts of the built dataset.

    PYTHONPATH=. python benchmarks/data_build.py --n 100000 --jobs 2 --files 2000
"""

from __future__ import annotations

import argparse
import collections
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

from robovae.data.dataset import RobotDataset
from robovae.data.procedural import parse_procedural, procedural_graphs, write_procedural
from robovae.data.procedural.coverage import MENAGERIE_CLASSES, coverage_rows
from robovae.evaluate.tables import format_table


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the worker processes)."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


class _Clock:
    def __enter__(self) -> _Clock:
        self.wall, self.cpu = time.perf_counter(), _cpu()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall, self.cpu = time.perf_counter() - self.wall, _cpu() - self.cpu


def _row(step: str, n: int, c: _Clock, jobs: int) -> dict:
    """Wall and CPU time; ``2-core min per 100k``: CPU time / jobs scaled to 100,000 robots,
    the wall time an otherwise idle machine with ``jobs`` cores would need. Printed at once
    (a long run keeps the rows it finished)."""
    row = {"step": step, "robots": n, "wall s": f"{c.wall:.1f}", "cpu s": f"{c.cpu:.1f}",
            "cpu ms/robot": f"{1e3 * c.cpu / n:.2f}",
            f"{jobs}-core min per 100k": f"{c.cpu / jobs / n * 100_000 / 60:.1f}"}
    print(" | ".join(f"{k}: {v}" for k, v in row.items()), flush=True)
    return row


def coverage(n: int, seed: int, jobs: int) -> str:
    """The coverage table of the Menagerie robots (``ROBOVAE_SHARED_MENAGERIE`` or
    ``../shared/menagerie``): their statistics and, in brackets, the range of their class."""
    folder = Path(os.environ.get("ROBOVAE_SHARED_MENAGERIE", "../shared/menagerie"))
    robots = {}
    for name, kind in MENAGERIE_CLASSES.items():
        files = sorted(f for f in (folder / name).glob("*.xml") if "scene" not in f.name)
        if files:
            robots[name] = (kind, files[0])
    rows = coverage_rows(robots, n=n, seed=seed, jobs=jobs)
    return format_table(rows, list(rows[0]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--n", type=int, default=10_000)
    p.add_argument("--files", type=int, default=1000, help="robots for the MJCF-file baseline")
    p.add_argument("--jobs", type=int, default=2, help="worker processes")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--feature-set", default="paper34")
    p.add_argument("--stages", action="store_true", help="also time the graphs alone")
    p.add_argument("--coverage", type=int, default=0, metavar="N",
                   help="also: do N robots per class cover the trees of ../shared/menagerie?")
    p.add_argument("--root", default=None, help="work folder (default: a temp folder)")
    args = p.parse_args()
    root = Path(args.root or tempfile.mkdtemp(prefix="robovae_bench_"))
    src = f"procedural:n={args.n},seed={args.seed}"
    rows: list[dict] = []
    load = " ".join(f"{v:.1f}" for v in os.getloadavg())

    if args.stages:
        with _Clock() as c:
            graphs = procedural_graphs(parse_procedural(f"n={args.n},seed={args.seed}"),
                                       args.feature_set, args.jobs)
        rows.append(_row("procedural graphs only (in memory)", len(graphs), c, args.jobs))
        del graphs

    cache = root / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    with _Clock() as c:
        ds = RobotDataset(cache, [src], args.feature_set, jobs=args.jobs, progress=False)
    rows.append(_row("dataset cold build (robovae data)", len(ds), c, args.jobs))
    with _Clock() as c:
        again = RobotDataset(cache, [src], args.feature_set, progress=False)
    rows.append(_row("load cached dataset", len(again), c, 1))

    files = root / "mjcf"
    with _Clock() as c:
        paths = write_procedural(files, args.files, seed=args.seed, workers=args.jobs)
    rows.append(_row("baseline: write MJCF files", len(paths), c, args.jobs))
    with _Clock() as c:
        fds = RobotDataset(root / "cache_files", [f"dir:{files}"], args.feature_set,
                           jobs=args.jobs, progress=False)
    rows.append(_row("baseline: MJCF files → Data", len(fds), c, args.jobs))
    print(format_table(rows, list(rows[0])))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    print(f"peak RSS of the main process: {peak:.2f} GB; load average before: {load}")

    report = ds.report["robots"]
    kinds = collections.Counter(r["name"].split("_", 1)[1].rsplit("_", 1)[0] for r in report)
    mix = []
    for kind, count in sorted(kinds.items()):
        nodes = [r["nodes"] for r in report if f"_{kind}_" in r["name"]]
        mix.append({"class": kind, "robots": count, "share": f"{count / len(report):.3f}",
                    "nodes min": min(nodes), "nodes mean": f"{sum(nodes) / len(nodes):.1f}",
                    "nodes max": max(nodes)})
    print()
    print(format_table(mix, ["class", "robots", "share", "nodes min", "nodes mean",
                             "nodes max"]))
    print(f"skipped: {len(ds.report['skipped'])}, duplicates: {len(ds.report['duplicates'])}")
    if args.coverage:
        print()
        print(coverage(args.coverage, args.seed, args.jobs))
    if args.root is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
