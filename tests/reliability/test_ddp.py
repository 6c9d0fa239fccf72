"""Lightning DDP on CPU (gloo, 2 processes): training, and generation through ``robovae predict``.

- Training: 2 ranks × batch 2 against 1 process × batch 4 on the 12 training robots of
  ``configs/tiny.yaml``. The effective batch (4 robots), the optimizer steps per epoch (3) and the
  robots seen per epoch (each training robot exactly once: ranks are disjoint) are the same. The
  numbers are not bit-identical and are not expected to be: the shuffle orders come from
  different samplers (``DistributedSampler`` vs ``RandomSampler``), each rank draws its own
  reparametrisation noise, and gradients are summed in another order. The epoch losses are the
  mean over all ranks' robots (``sync_dist``), finite, and within 10 % of the 1-process run.
- Generation: robot ``i`` depends only on ``(checkpoint, seed, i)``, so 2 ranks write exactly the
  robots of 1 process and of ``robovae generate``, byte for byte, each index by one rank only.
"""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import lightning as L
import pytest
import torch

from robovae.cli import main
from robovae.generate.pipeline import MANIFEST, read_manifest
from robovae.model.checkpoint import load_model
from tests.conftest import REPO

ENV = {**os.environ, "PYTHONPATH": str(REPO), "MUJOCO_GL": "egl", "PYTHONWARNINGS": "ignore"}
TINY, GENERATE = str(REPO / "configs" / "tiny.yaml"), str(REPO / "configs" / "generate.yaml")
DDP = ["--trainer.devices=2", "--trainer.strategy=ddp"]


class SeenRobots(L.Callback):
    """Used inside the ``robovae fit`` runs: the robots each rank trained on, per epoch
    (``<out>/seen-rank<r>.json``)."""

    def __init__(self, out: str) -> None:
        self.out, self.seen = Path(out), {}

    def on_train_batch_start(self, trainer, pl_module, batch, batch_idx) -> None:
        self.seen.setdefault(str(trainer.current_epoch), []).extend(batch.name)

    def on_train_end(self, trainer, pl_module) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        (self.out / f"seen-rank{trainer.global_rank}.json").write_text(json.dumps(self.seen))


def _run(args: list[str], cwd: Path, timeout: float = 240,
         env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "robovae.cli", *args], env=env or ENV, cwd=cwd,
                          capture_output=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr.decode()[-4000:]
    return proc


def _last_epoch(logs: Path) -> tuple[int, dict[str, float]]:
    (path,) = logs.glob("robovae/version_*/metrics.csv")
    rows: dict[int, dict[str, float]] = {}
    for row in csv.DictReader(path.open()):
        rows.setdefault(int(row["epoch"]), {}).update(
            {k: float(v) for k, v in row.items() if v and k not in ("epoch", "step")})
    for values in rows.values():
        assert all(math.isfinite(v) for v in values.values()), values
    first, last = min(rows), max(rows)
    assert rows[last]["train/loss"] < rows[first]["train/loss"]  # it learns
    return last, rows[last]


def _fit_args(tmp: Path, run: str) -> list[str]:
    seen = json.dumps({"class_path": "tests.reliability.test_ddp.SeenRobots",
                       "init_args": {"out": str(tmp / run)}})
    return ["fit", "--config", TINY, f"--data.root={tmp / 'cache'}",
            f"--checkpoint.dirpath={tmp / run / 'ckpt'}",
            f"--trainer.logger.init_args.save_dir={tmp / run / 'logs'}",
            f"--trainer.callbacks+={seen}"]


@pytest.mark.slow
@pytest.mark.timeout(400)  # (a hung DDP run fails instead of blocking the suite)
def test_ddp_fit_matches_one_process(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # the 2 cores are for the 2 ranks below; be fair to this one too
    try:
        assert main([*_fit_args(tmp_path, "one"), "--data.batch_size=4"]) == 0
    finally:
        torch.set_num_threads(threads)
    # with warnings shown, as a user sees them: the reconstruction metrics that every rank
    # computes alike are synchronised, so Lightning does not ask for sync_dist key by key
    loud = {k: v for k, v in ENV.items() if k != "PYTHONWARNINGS"}
    ddp = _run([*_fit_args(tmp_path, "ddp"), "--data.batch_size=2", *DDP], tmp_path, env=loud)
    assert "sync_dist" not in ddp.stderr.decode() + ddp.stdout.decode()

    one = json.loads((tmp_path / "one" / "seen-rank0.json").read_text())
    r0, r1 = (json.loads((tmp_path / "ddp" / f"seen-rank{r}.json").read_text()) for r in (0, 1))
    train = sorted(one["0"])
    assert len(train) == len(set(train)) == 12
    for epoch in one:  # every robot once per epoch, split between the ranks
        assert sorted(one[epoch]) == train
        assert not set(r0[epoch]) & set(r1[epoch]) and sorted(r0[epoch] + r1[epoch]) == train
        assert len(r0[epoch]) == len(r1[epoch]) == 6

    a = torch.load(tmp_path / "one" / "ckpt" / "last.ckpt", weights_only=True)
    b = torch.load(tmp_path / "ddp" / "ckpt" / "last.ckpt", weights_only=True)
    assert (a["epoch"], a["global_step"]) == (b["epoch"], b["global_step"]) == (3, 12)
    epoch_a, last_a = _last_epoch(tmp_path / "one" / "logs")
    epoch_b, last_b = _last_epoch(tmp_path / "ddp" / "logs")
    assert epoch_a == epoch_b == 3
    for key in ("train/loss", "val/loss"):
        assert last_b[key] == pytest.approx(last_a[key], rel=0.1), key
    model = load_model(tmp_path / "ddp" / "ckpt" / "last.ckpt")  # a usable checkpoint
    assert len(model.decode(torch.zeros(2, model.hparams.latent_dim))) == 2


def _robot_files(out: Path) -> dict[str, bytes]:
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.glob("robot_*/*.xml"))}


def _same_record(rec: dict) -> dict:
    return {k: v for k, v in rec.items() if k not in ("seconds",)}


@pytest.mark.slow
def test_ddp_predict_writes_the_robots_of_one_process_and_of_generate(trained, tmp_path,
                                                                       monkeypatch):
    _, _, ckpt = trained
    monkeypatch.chdir(tmp_path)
    n, seed = 10, 5

    def predict(out: str) -> list[str]:
        return ["predict", "--config", TINY, "--config", GENERATE, f"--ckpt_path={ckpt}",
                f"--data.predict_samples={n}", f"--data.predict_seed={seed}",
                "--data.batch_size=3", f"--trainer.callbacks.output_dir={tmp_path / out}",
                "--trainer.callbacks.jobs=1"]

    ddp = _run([*predict("ddp"), *DDP], tmp_path)
    assert f"{n} robots in" in ddp.stdout.decode()  # rank 0's summary of both ranks' robots
    assert main(predict("one")) == 0
    assert main(["generate", "--ckpt", str(ckpt), "-n", str(n), "--seed", str(seed),
                 "--out", str(tmp_path / "gen"), "--jobs", "1", "--batch-size", "4"]) == 0

    ranks = [[json.loads(ln)["index"] for ln in
              (tmp_path / "ddp" / f"manifest-rank{r}.jsonl").read_text().splitlines()]
             for r in (0, 1)]
    assert ranks[0] and ranks[1] and not set(ranks[0]) & set(ranks[1])  # no robot twice
    assert sorted(ranks[0] + ranks[1]) == list(range(n))  # none missing
    assert (tmp_path / "gen" / MANIFEST).is_file()
    files = {run: _robot_files(tmp_path / run) for run in ("ddp", "one", "gen")}
    assert len(files["ddp"]) == 2 * n  # robot.xml + scene.xml
    assert files["ddp"] == files["one"] == files["gen"]  # byte-identical
    recs = {run: read_manifest(tmp_path / run) for run in ("ddp", "one", "gen")}
    for i in range(n):  # same latents, validation results, rules, counts
        assert _same_record(recs["ddp"][i]) == _same_record(recs["one"][i]) \
            == _same_record(recs["gen"][i]), i
