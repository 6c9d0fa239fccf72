"""Benchmark: one training epoch over a procedural dataset through ``robovae fit`` (issue 20's
scale target: 100,000 robots in <= 3 min on 2 CPU cores, peak RSS <= 4 GB).

Each row runs the Lightning CLI in a subprocess on ``--config`` (its model and data blocks),
with ``procedural:n=N`` as the only source, one epoch, no validation, no checkpoint: once with
one process and ``--threads`` torch threads, once with Lightning's DDP over ``--devices``
processes (one thread each). The dataset is built first (and cached), so the rows time training
alone. Columns: wall time of the fit (from the trainer's start to its end, read from the run's
log), CPU time of all processes, peak RSS (the largest of the processes, and their sum for DDP,
from ``/proc``), robots per second.

    PYTHONPATH=. python benchmarks/epoch_speed.py --n 100000 --config configs/large.yaml
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from robovae.data.dataset import RobotDataset
from robovae.evaluate.tables import format_table

REPO = Path(__file__).resolve().parents[1]


def _tree_rss(pid: int) -> tuple[int, int]:
    """(largest, summed) resident set size in bytes of ``pid`` and its descendants."""
    sizes = []
    try:
        out = subprocess.run(["ps", "-o", "pid=,ppid=,rss=", "-A"], capture_output=True,
                             text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return 0, 0
    kids: dict[int, list[tuple[int, int]]] = {}
    for line in out.splitlines():
        p, pp, rss = (int(v) for v in line.split())
        kids.setdefault(pp, []).append((p, rss))
    stack = [pid]
    own = {int(line.split()[0]): int(line.split()[2]) for line in out.splitlines()}
    while stack:
        p = stack.pop()
        if p in own:
            sizes.append(own[p] * 1024)
        stack.extend(c for c, _ in kids.get(p, []))
    return (max(sizes), sum(sizes)) if sizes else (0, 0)


def _run(args: list[str], env: dict) -> tuple[float, float, int, int]:
    """Wall, CPU (children), peak largest and peak summed RSS of one CLI run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "robovae.cli", *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    peak = [0, 0]

    def watch() -> None:
        while proc.poll() is None:
            big, total = _tree_rss(proc.pid)
            peak[0], peak[1] = max(peak[0], big), max(peak[1], total)
            time.sleep(0.5)

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    _, err = proc.communicate()
    t.join()
    wall = time.perf_counter() - start
    if proc.returncode:
        raise SystemExit(f"robovae fit failed:\n{err[-3000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return wall, cpu, peak[0], peak[1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=100_000)
    p.add_argument("--config", default=str(REPO / "configs" / "large.yaml"))
    p.add_argument("--root", default="data_cache")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--devices", type=int, default=2)
    p.add_argument("--batch-size", type=int, default=0, help="0: the config's")
    p.add_argument("--only", choices=["single", "ddp"], default=None)
    args = p.parse_args()

    source = f"procedural:n={args.n},seed=0"
    t = time.perf_counter()
    ds = RobotDataset(args.root, [source], "kinematic", progress=False)
    build = time.perf_counter() - t
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        common = ["fit", "--config", args.config, f"--data.sources=[\"{source}\"]",
                  f"--data.root={args.root}", "--data.val_names=[]", "--data.test_names=[]",
                  "--data.val_fraction=0", "--data.test_fraction=0", "--trainer.max_epochs=1",
                  "--trainer.limit_val_batches=0", "--trainer.enable_progress_bar=false",
                  "--trainer.logger=false", f"--checkpoint.dirpath={tmp}/ckpt"]
        if args.batch_size:
            common.append(f"--data.batch_size={args.batch_size}")
        modes = {"single": (["--trainer.devices=1"], args.threads),
                 "ddp": ([f"--trainer.devices={args.devices}", "--trainer.strategy=ddp"], 1)}
        for name, (extra, threads) in modes.items():
            if args.only and name != args.only:
                continue
            env = {**os.environ, "OMP_NUM_THREADS": str(threads), "PYTHONPATH": str(REPO),
                   "PYTHONWARNINGS": "ignore"}
            wall, cpu, big, total = _run([*common, *extra], env)
            procs = 1 if name == "single" else args.devices
            rows.append([f"{name} ({procs} x {threads} thread)", len(ds), f"{wall:.0f}",
                         f"{cpu:.0f}", f"{big / 2**30:.2f}", f"{total / 2**30:.2f}",
                         f"{len(ds) / wall:.0f}"])
    print(f"dataset {source}: {len(ds)} robots, loaded/built in {build:.1f} s; "
          f"load average {os.getloadavg()[0]:.1f}")
    cols = ["run", "robots", "wall s (whole command)", "CPU s", "peak RSS GB", "summed RSS GB",
            "robots/s"]
    print(format_table([dict(zip(cols, r)) for r in rows], cols))


if __name__ == "__main__":
    main()
