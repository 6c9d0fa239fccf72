"""Crash-safe training: ``robovae fit`` killed with SIGKILL in the middle of an epoch and resumed
with ``--ckpt_path last`` ends with exactly the weights, optimizer state and logged metrics of
an uninterrupted run with the same seed (CPU, one thread per process).

Why it is exact: Lightning restores the weights, optimizer, LR schedule and loop counters from
the end-of-epoch ``last.ckpt``, and the randomness of an epoch (shuffle order, reparametrisation
noise) is a function of ``(seed, epoch, batch)`` (:mod:`robovae.model.vae`), not of the global
RNG, which no checkpoint holds. The killed epoch is simply run again.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import lightning as L
import pytest
import torch

from tests.conftest import REPO

# one thread per process: the runs must not depend on how busy the machine is, and the
# reference and the interrupted run share the two cores
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(REPO),
       "MUJOCO_GL": "egl", "PYTHONWARNINGS": "ignore"}
EPOCHS = 4
KILL_EPOCH, KILL_BATCH = 2, 1  # last.ckpt then holds epochs 0-1; the kill is inside epoch 2


class PauseAt(L.Callback):
    """Used inside the ``robovae fit`` subprocess: after batch ``batch`` of epoch ``epoch``,
    write ``marker`` and wait (for the SIGKILL)."""

    def __init__(self, marker: str, epoch: int = KILL_EPOCH, batch: int = KILL_BATCH) -> None:
        self.marker, self.epoch, self.batch = Path(marker), epoch, batch

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if trainer.current_epoch == self.epoch and batch_idx == self.batch:
            # whole or not at all: the test reads it as soon as it exists
            part = self.marker.with_name(self.marker.name + ".part")
            part.write_text(json.dumps({"global_step": trainer.global_step}))
            part.replace(self.marker)
            while True:
                time.sleep(0.5)


def _fit(tmp: Path, run: str, *extra: str) -> list[str]:
    return [sys.executable, "-m", "robovae.cli", "fit",
            "--config", str(REPO / "configs" / "tiny.yaml"),
            f"--trainer.max_epochs={EPOCHS}", f"--data.root={tmp / 'cache'}",
            f"--checkpoint.dirpath={tmp / run / 'ckpt'}",
            f"--trainer.logger.init_args.save_dir={tmp / run / 'logs'}", *extra]


def _epoch_rows(logs: Path) -> dict[tuple[int, str], float]:
    """Logged values by ``(epoch, key)`` over every version folder of a run."""
    out: dict[tuple[int, str], float] = {}
    for path in sorted(logs.glob("robovae/version_*/metrics.csv")):
        for row in csv.DictReader(path.open()):
            for k, v in row.items():
                if v not in ("", None) and k not in ("epoch", "step"):
                    out[(int(row["epoch"]), k)] = float(v)
    return out


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float) -> None:
    end = time.monotonic() + timeout
    while not path.exists():
        if proc.poll() is not None:
            raise AssertionError(f"run ended (code {proc.returncode}) before {path.name}")
        if time.monotonic() > end:
            raise AssertionError(f"no {path} after {timeout} s")
        time.sleep(0.1)


@pytest.mark.slow
@pytest.mark.timeout(400)  # generous: the 2 cores may be shared
def test_killed_fit_resumes_exactly(tmp_path):
    # build the dataset cache once (the two runs below would race for it)
    from robovae.data.dataset import RobotDataset

    RobotDataset(str(tmp_path / "cache"), ["procedural:n=16,seed=0"], "paper34", progress=False)
    marker = tmp_path / "paused.json"
    pause = json.dumps({"class_path": "tests.reliability.test_resume.PauseAt",
                        "init_args": {"marker": str(marker)}})
    logs = {run: (tmp_path / f"{run}.stderr").open("wb") for run in ("ref", "crash")}
    ref = subprocess.Popen(_fit(tmp_path, "ref"), env=ENV, cwd=tmp_path,
                           stdout=subprocess.DEVNULL, stderr=logs["ref"])
    crash = subprocess.Popen(_fit(tmp_path, "crash", f"--trainer.callbacks+={pause}"), env=ENV,
                             cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=logs["crash"])
    try:
        _wait_for(marker, crash, 200)
        crash.send_signal(signal.SIGKILL)
        assert crash.wait(10) == -signal.SIGKILL
        last = tmp_path / "crash" / "ckpt" / "last.ckpt"
        saved = torch.load(last, weights_only=True)
        assert saved["epoch"] == KILL_EPOCH - 1  # the killed epoch's work is lost, not saved
        assert json.loads(marker.read_text())["global_step"] > saved["global_step"]

        resumed = subprocess.run(_fit(tmp_path, "crash", "--ckpt_path", "last"), env=ENV,
                                 cwd=tmp_path, capture_output=True, timeout=200)
        assert resumed.returncode == 0, resumed.stderr.decode()[-3000:]
        assert ref.wait(200) == 0, (tmp_path / "ref.stderr").read_text()[-3000:]
    finally:
        for proc in (ref, crash):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for f in logs.values():
            f.close()

    a = torch.load(tmp_path / "ref" / "ckpt" / "last.ckpt", weights_only=True)
    b = torch.load(last, weights_only=True)
    assert (a["epoch"], a["global_step"]) == (b["epoch"], b["global_step"]) == (
        EPOCHS - 1, EPOCHS * 3)
    assert a["state_dict"].keys() == b["state_dict"].keys()
    for k, v in a["state_dict"].items():  # bit for bit
        assert torch.equal(v, b["state_dict"][k]), k
    for sa, sb in zip(a["optimizer_states"][0]["state"].values(),
                      b["optimizer_states"][0]["state"].values()):
        assert all(torch.equal(sa[k], sb[k]) for k in sa)
    assert a["lr_schedulers"] == b["lr_schedulers"]

    ref_rows, crash_rows = (_epoch_rows(tmp_path / r / "logs") for r in ("ref", "crash"))
    after = {k: v for k, v in ref_rows.items() if k[0] >= KILL_EPOCH}
    assert {k for k in after if k[1] == "train/loss"} == {
        (e, "train/loss") for e in range(KILL_EPOCH, EPOCHS)}
    assert {k: crash_rows.get(k) for k in after} == after  # final metrics, exactly
    before = {k: v for k, v in ref_rows.items() if k[0] < KILL_EPOCH}
    assert {k: crash_rows.get(k) for k in before} == before  # and the epochs before the kill


def _robot_files(out: Path) -> dict[str, bytes]:
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.glob("robot_*/*.xml"))}


def test_predict_resumes_a_killed_generation_and_refuses_another_run(trained, tmp_path):
    """``robovae predict`` (RobotWriter) resumes a folder — here one started by ``robovae
    generate``, whose per-rank manifest a kill left with a torn line — and writes exactly the
    robots of an uninterrupted run; a folder of another seed or checkpoint is refused."""
    import copy

    from robovae.data.datamodule import RobotDataModule
    from robovae.errors import RobovaeError
    from robovae.generate.pipeline import generate, read_manifest
    from robovae.generate.predict import RobotWriter

    model, _, ckpt = trained
    out = tmp_path / "gen"
    generate(ckpt, 4, out, seed=2, validate=False, progress=False, jobs=1)
    (out / "manifest-rank0.jsonl").write_text('{"index": 5, "na')  # killed mid-line

    def predict(module, seed: int = 2) -> RobotWriter:
        dm = RobotDataModule(["zoo"], root=str(tmp_path / "cache"), predict_samples=7,
                             predict_seed=seed, batch_size=2)
        writer = RobotWriter(str(out), validate=False, jobs=1)
        trainer = L.Trainer(accelerator="cpu", devices=1, logger=False, callbacks=[writer],
                            precision="64-true", enable_progress_bar=False,
                            enable_model_summary=False)
        trainer.predict(copy.deepcopy(module), dm, return_predictions=False)
        return writer

    writer = predict(model)
    assert (writer.report.total, writer.report.new) == (7, 3)
    assert sorted(read_manifest(out)) == list(range(7))
    generate(ckpt, 7, tmp_path / "ref", seed=2, validate=False, progress=False, jobs=1)
    assert _robot_files(out) == _robot_files(tmp_path / "ref")
    # and back: generate resumes the folder predict wrote to (same run.json)
    assert generate(ckpt, 8, out, seed=2, validate=False, progress=False, jobs=1).new == 1

    with pytest.raises(RobovaeError, match="seed differ"):
        predict(model, seed=3)
    other = copy.deepcopy(model)
    with torch.no_grad():
        other.decoder.U_l.bias.add_(1.0)
    with pytest.raises(RobovaeError, match="model differ"):
        predict(other)
    from robovae.files import LOCK, FolderLock

    with FolderLock(out), pytest.raises(RobovaeError, match="another run is writing there"):
        predict(model)  # a second run into the folder while a first writes there
    assert sorted(read_manifest(out)) == list(range(8))  # nothing touched
    assert not (out / LOCK).exists()  # every run above released the folder
