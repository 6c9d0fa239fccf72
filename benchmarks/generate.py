"""Benchmark: generation throughput — decode, write MJCF, validate (1 s of MuJoCo), measure
quality — and RAM.

Robots: with ``--ckpt``, N prior samples of a checkpoint decoded in float64 (as ``robovae
generate`` does); without, the graphs of N procedural robots
(:func:`robovae.data.procedural.procedural_graphs`, ``paper34``) stand in for decoded ones. Each
graph gets a floating base and mirrored limbs, as the pipeline gives them. Rows (one table; wall
and CPU seconds, the CPU of this process or of the finished worker processes):

- ``decode`` or ``procedural graphs``;
- ``writer``: rules + MjSpec + files in this process (no load check, no per-file fsync, one
  ``os.sync`` at the end, as the pipeline's workers write);
- ``validate``: MuJoCo only (the files exist), in 1 and in ``--jobs`` worker processes;
- ``write + validate + quality``: what the pipeline's workers do for each robot
  (:func:`robovae.generate.build.build_robot`), in ``--jobs`` worker processes, and the
  same less a separate run of the workers' start-up (imports, one robot each);
- with ``--ckpt``, the whole ``generate()`` (decode, write, validate and measure in the
  workers).

Then the end-to-end throughput as a share of the MuJoCo-only validation throughput on
``--jobs`` processes (target >= 80 %) and the peak RSS.

    python benchmarks/generate.py --ckpt runs/zoo/checkpoints/last.ckpt --n 1000 --jobs 2
    PYTHONPATH=. python benchmarks/generate.py --n 1000 --jobs 2    # procedural robots
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

import torch

from robovae.data.procedural import parse_procedural, procedural_graphs
from robovae.evaluate.tables import format_table
from robovae.generate.build import build_robot
from robovae.generate.rules import floating_base
from robovae.generate.symmetry import mirror_limbs
from robovae.generate.validate import validate_many
from robovae.generate.writer import write_robot

# The model stack (robovae.model, Lightning) is imported in main(): the spawned workers import
# this script again and, like robovae generate's, need only the writer, validator and measures.


def _cpu(children: bool = False) -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class _Clock:
    """Wall and CPU seconds of a block: this process's CPU, or the worker processes' that
    finished inside it (``children``)."""

    def __init__(self, children: bool = False) -> None:
        self.children = children

    def __enter__(self) -> _Clock:
        self.wall, self.cpu = time.perf_counter(), _cpu(self.children)
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall = time.perf_counter() - self.wall
        self.cpu = _cpu(self.children) - self.cpu


def _row(step: str, n: int, c: _Clock) -> dict:
    return {"step": step, "robots": n, "wall s": f"{c.wall:.2f}",
            "robots/s (wall)": f"{n / c.wall:.1f}", "CPU s": f"{c.cpu:.2f}",
            "CPU ms/robot": f"{1e3 * c.cpu / n:.1f}"}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--ckpt", help="checkpoint (default: procedural robots, no model)")
    p.add_argument("--n", type=int, default=1000)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--root", default=None, help="work folder (default: a temp folder)")
    args = p.parse_args()
    from robovae.generate.pipeline import generate, latent, worker_pool
    from robovae.model.checkpoint import load_model

    root = Path(args.root or tempfile.mkdtemp(prefix="robovae_genbench_"))
    rows = []

    model = load_model(args.ckpt).to(torch.float64) if args.ckpt else None
    fs = model.feature_set.name if model is not None else "paper34"
    with _Clock() as c:
        if model is not None:
            dim = model.hparams.latent_dim
            graphs = []
            for k in range(0, args.n, args.batch_size):
                idx = range(k, min(args.n, k + args.batch_size))
                graphs += model.decode(torch.stack([latent(0, i, dim) for i in idx]).double())
        else:
            graphs = procedural_graphs(parse_procedural(f"n={args.n}"), fs, jobs=1)
        graphs = [mirror_limbs(floating_base(g, fs)[0], fs)[0] for g in graphs]
    rows.append(_row(f"decode (batch {args.batch_size})" if model is not None
                     else "procedural graphs", args.n, c))

    with _Clock() as c:
        paths = [write_robot(g, root / "w" / f"robot_{i:06d}", fs, check=False,
                             durable=False).robot_path for i, g in enumerate(graphs)]
        os.sync()
    rows.append(_row("writer (rules + MjSpec + files), 1 process", args.n, c))

    sub = paths[: max(1, args.n // 4)]
    with _Clock() as c:
        validate_many(sub, jobs=1)
    rows.append(_row("validate, 1 process", len(sub), c))
    with _Clock(children=True) as c:
        checks = validate_many(paths, jobs=args.jobs)
    validation = c.wall
    rows.append(_row(f"validate (MuJoCo only), {args.jobs} processes", args.n, c))

    items = [(g.cpu(), root / "b" / f"robot_{i:06d}", fs, f"robot_{i:06d}", True, True, True)
             for i, g in enumerate(graphs)]
    with _Clock(children=True) as start, worker_pool(args.jobs) as pool:
        list(pool.map(build_robot, items[:args.jobs]))
    rows.append(_row(f"worker start-up (imports) + 1 robot each, {args.jobs} processes",
                     args.jobs, start))
    with _Clock(children=True) as c, worker_pool(args.jobs) as pool:
        built = list(pool.map(build_robot, items, chunksize=4))
    rows.append(_row(f"write + validate + quality, {args.jobs} processes (incl. start-up)",
                     args.n, c))
    steady = _Clock()
    steady.wall, steady.cpu = c.wall - start.wall, c.cpu - start.cpu
    rows.append(_row("  the same without the start-up", args.n - args.jobs, steady))

    end_to_end = None
    if model is not None:
        with _Clock(children=True) as c:
            report = generate(model, args.n, root / "g", jobs=args.jobs, progress=False,
                              batch_size=args.batch_size)
        end_to_end = c.wall
        rows.append(_row(f"generate() end to end, {args.jobs} processes", args.n, c))

    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(format_table(rows, ["step", "robots", "wall s", "robots/s (wall)", "CPU s",
                              "CPU ms/robot"]))
    per = steady.cpu / (args.n - args.jobs)
    print(f"10,000 robots written, validated and measured on {args.jobs} processes: "
          f"{start.wall + 10_000 * steady.wall / (args.n - args.jobs):.0f} s at this machine's "
          f"wall rate, {10_000 * per / args.jobs:.0f} s from the CPU per robot on idle cores")
    if end_to_end is not None:
        print(f"end to end / MuJoCo-only validation throughput: {validation / end_to_end:.0%}")
        print(report.format())
    valid = sum(cv.valid for cv in checks)
    measured = sum("quality" in b for b in built)
    mean_nodes = sum(g.num_nodes for g in graphs) / len(graphs)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"valid {valid}/{args.n} ({valid / args.n:.1%}), quality measured for {measured}, "
          f"mean nodes {mean_nodes:.1f}, peak RSS (main process) {peak:.0f} MiB")
    if args.root is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
