"""Benchmark: generation throughput — decode, write MJCF, validate (1 s of MuJoCo) — and RAM.

Decodes N prior samples of a checkpoint (float64, as ``robovae generate`` does), writes each robot
with the physical rules (in this process, as the pipeline's workers do: no load check, no
per-file fsync, one ``os.sync`` at the end), validates them with 1 and with ``--jobs`` worker
processes (MuJoCo only: the files exist), then runs the whole ``generate()`` pipeline (decode,
write and validate in the workers). Prints one table (robots/s per stage), the end-to-end
throughput as a share of the MuJoCo-only validation throughput on ``--jobs`` processes (target
>= 80 %), and the peak RSS.

    python benchmarks/generate.py --ckpt runs/zoo/checkpoints/last.ckpt --n 1000 --jobs 2
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

from robovae.evaluate.tables import format_table
from robovae.generate.pipeline import generate, latent
from robovae.generate.validate import validate_many
from robovae.generate.writer import write_robot
from robovae.model.checkpoint import load_model


def _row(step: str, n: int, seconds: float) -> dict:
    return {"step": step, "robots": n, "seconds": f"{seconds:.2f}",
            "robots/s": f"{n / seconds:.1f}"}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--ckpt", required=True)
    p.add_argument("--n", type=int, default=1000)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--root", default=None, help="work folder (default: a temp folder)")
    args = p.parse_args()
    root = Path(args.root or tempfile.mkdtemp(prefix="robovae_genbench_"))
    model = load_model(args.ckpt).to(torch.float64)
    dim = model.hparams.latent_dim
    rows = []

    t = time.perf_counter()
    graphs = []
    for k in range(0, args.n, args.batch_size):
        idx = range(k, min(args.n, k + args.batch_size))
        graphs += model.decode(torch.stack([latent(0, i, dim) for i in idx]).double())
    rows.append(_row(f"decode (batch {args.batch_size})", args.n, time.perf_counter() - t))

    t = time.perf_counter()
    paths = [write_robot(g, root / "w" / f"robot_{i:06d}", model.feature_set, check=False,
                         durable=False).robot_path for i, g in enumerate(graphs)]
    os.sync()
    rows.append(_row("writer (rules + MjSpec + files), 1 process", args.n,
                     time.perf_counter() - t))

    sub = paths[: max(1, args.n // 4)]
    t = time.perf_counter()
    validate_many(sub, jobs=1)
    rows.append(_row("validate, 1 process", len(sub), time.perf_counter() - t))
    t = time.perf_counter()
    checks = validate_many(paths, jobs=args.jobs)
    validation = time.perf_counter() - t
    rows.append(_row(f"validate (MuJoCo only), {args.jobs} processes", args.n, validation))

    t = time.perf_counter()
    report = generate(model, args.n, root / "g", jobs=args.jobs, progress=False,
                      batch_size=args.batch_size)
    end_to_end = time.perf_counter() - t
    rows.append(_row(f"generate() end to end, {args.jobs} processes", args.n, end_to_end))

    print(format_table(rows, ["step", "robots", "seconds", "robots/s"]))
    print(f"end to end / MuJoCo-only validation throughput: {validation / end_to_end:.0%}")
    valid = sum(c.valid for c in checks)
    mean_nodes = sum(g.num_nodes for g in graphs) / len(graphs)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"valid {valid}/{args.n} ({valid / args.n:.1%}), mean nodes {mean_nodes:.1f}, "
          f"peak RSS (main process) {peak:.0f} MiB")
    print(report.format())
    if args.root is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
