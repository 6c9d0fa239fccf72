"""Benchmark: one training epoch over a procedural dataset through ``robovae fit`` (issue 20's
scale target: 100,000 robots in <= 3 min on 2 CPU cores, peak RSS <= 4 GB).

Each row runs the Lightning CLI in a subprocess on ``--config`` (its model and data blocks),
with ``procedural:n=N`` as the only source, one epoch, no validation, no checkpoint: once with
one process and ``--threads`` torch threads, once with Lightning's DDP over ``--devices``
processes (one thread each). The dataset is built first (and cached), so the rows time training
alone. Columns: wall time of the whole command (start-up, data loading, the epoch, the final
checkpoint), wall time of the training epoch alone (:class:`EpochClock`, a callback the command
is given, on rank 0: from the epoch's start to the end of its last training step) and, apart,
what the model does once after that last step (the sampling mixture's fit over the training
robots, :class:`~robovae.model.latent_mixture.LatentMixture`), CPU time of the processes the
command waited for, peak RSS (the largest of the processes, and their sum for DDP, from
``ps``), the peak of the processes' summed PSS (``/proc/PID/smaps_rollup``: the memory-mapped
dataset the DDP processes share counted once, the machine's memory the command holds), robots
per second of the epoch.

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

import lightning as L

from robovae.data.dataset import RobotDataset
from robovae.evaluate.tables import format_table

REPO = Path(__file__).resolve().parents[1]
#: The lines :class:`EpochClock` prints to stderr.
EPOCH_TAG = "epoch_seconds="
AFTER_TAG = "after_last_step_seconds="


class EpochClock(L.Callback):
    """Prints ``epoch_seconds=<wall s>`` of each training epoch (start to the end of its last
    training step) and ``after_last_step_seconds=<wall s>`` (the rest of the epoch: the
    module's own end-of-batch work on the last step, which Lightning calls after the
    callbacks', e.g. the mixture fit) to stderr (rank 0)."""

    def on_train_epoch_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        self.start = self.last = time.perf_counter()

    def on_train_batch_end(self, trainer: L.Trainer, pl_module: L.LightningModule, outputs,
                           batch, batch_idx: int) -> None:
        self.last = time.perf_counter()

    def on_train_epoch_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        if trainer.is_global_zero:
            now = time.perf_counter()
            print(f"{EPOCH_TAG}{self.last - self.start:.1f}\n{AFTER_TAG}{now - self.last:.1f}",
                  file=sys.stderr, flush=True)


def _pss(pid: int) -> int:
    """Proportional set size in bytes (shared pages divided among their users), 0 if gone."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _tree_rss(pid: int) -> tuple[int, int, int]:
    """(largest RSS, summed RSS, summed PSS) in bytes of ``pid`` and its descendants: the
    summed PSS counts pages the processes share (the memory-mapped dataset) once."""
    sizes, pss = [], 0
    try:
        out = subprocess.run(["ps", "-o", "pid=,ppid=,rss=", "-A"], capture_output=True,
                             text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return 0, 0, 0
    kids: dict[int, list[int]] = {}
    own: dict[int, int] = {}
    for line in out.splitlines():
        p, pp, rss = (int(v) for v in line.split())
        kids.setdefault(pp, []).append(p)
        own[p] = rss
    stack = [pid]
    while stack:
        p = stack.pop()
        if p in own:
            sizes.append(own[p] * 1024)
            pss += _pss(p)
        stack.extend(kids.get(p, []))
    return (max(sizes), sum(sizes), pss) if sizes else (0, 0, 0)


def _run(args: list[str], env: dict) -> tuple[float, float, float, float, list[int]]:
    """Wall, epoch wall, wall after the last step, CPU (children) and the peaks of
    :func:`_tree_rss` of one CLI run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "robovae.cli", *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    peak = [0, 0, 0]

    def watch() -> None:
        while proc.poll() is None:
            peak[:] = [max(a, b) for a, b in zip(peak, _tree_rss(proc.pid))]
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
    def last(tag: str) -> float:
        vals = [float(line[len(tag):]) for line in err.splitlines() if line.startswith(tag)]
        return vals[-1] if vals else float("nan")

    return wall, last(EPOCH_TAG), last(AFTER_TAG), cpu, peak


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
                  "--trainer.logger=false", f"--checkpoint.dirpath={tmp}/ckpt",
                  f"--trainer.default_root_dir={tmp}",
                  "--trainer.callbacks+=benchmarks.epoch_speed.EpochClock"]
        if args.batch_size:
            common.append(f"--data.batch_size={args.batch_size}")
        modes = {"single": (["--trainer.devices=1"], args.threads),
                 "ddp": ([f"--trainer.devices={args.devices}", "--trainer.strategy=ddp"], 1)}
        for name, (extra, threads) in modes.items():
            if args.only and name != args.only:
                continue
            env = {**os.environ, "OMP_NUM_THREADS": str(threads), "PYTHONPATH": str(REPO),
                   "PYTHONWARNINGS": "ignore"}
            wall, epoch, after, cpu, (big, total, pss) = _run([*common, *extra], env)
            procs = 1 if name == "single" else args.devices
            rows.append([f"{name} ({procs} x {threads} thread)", len(ds), f"{wall:.0f}",
                         f"{epoch:.0f}", f"{after:.0f}", f"{cpu:.0f}", f"{big / 2**30:.2f}",
                         f"{total / 2**30:.2f}", f"{pss / 2**30:.2f}",
                         f"{len(ds) / epoch:.0f}"])
    print(f"dataset {source}: {len(ds)} robots, loaded/built in {build:.1f} s; "
          f"load average {os.getloadavg()[0]:.1f}")
    cols = ["run", "robots", "wall s (whole command)", "epoch s", "after last step s", "CPU s",
            "peak RSS GB", "summed RSS GB", "summed PSS GB", "robots/s (epoch)"]
    print(format_table([dict(zip(cols, r)) for r in rows], cols))


if __name__ == "__main__":
    main()
