"""Generation through ``trainer.predict``: latent indices in, robot folders out.

The same code as :func:`robovae.generate.pipeline.generate`, run by Lightning so it can be
spread over devices and processes (``robovae predict --config configs/generate.yaml``):

- :class:`~robovae.data.latents.LatentIndices` is the prediction dataset: robot indices
  ``0 … n-1`` (minus the ones a previous run already wrote). Lightning's distributed sampler
  gives each rank its own share without padding, and robot ``i``'s latent depends only on
  ``(seed, i)`` (:func:`~robovae.generate.pipeline.latent`), so the set of robots does not
  depend on the number of processes.
- :meth:`RoboVAE.predict_step <robovae.model.vae.RoboVAE.predict_step>` decodes them.
- :class:`RobotWriter` (a :class:`~lightning.pytorch.callbacks.BasePredictionWriter`) writes the
  folders, validates them and appends to ``manifest-rank<r>.jsonl``; rank 0 writes the summary.
  Like ``generate``, it ties the folder to its run (``run.json``: model fingerprint, seed,
  temperature): resuming a folder of another checkpoint or seed is refused with one line, and a
  folder started by ``robovae generate`` can be resumed by ``robovae predict`` and vice versa.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import lightning as L
import torch
from lightning.pytorch.callbacks import BasePredictionWriter

from robovae.data.latents import LatentIndices  # noqa: F401  (re-exported)
from robovae.data.workers import WorkerPool
from robovae.errors import RobovaeError
from robovae.files import FolderLock
from robovae.generate.pipeline import (
    RUN,
    GenerationReport,
    append_records,
    claim,
    model_fingerprint,
    open_manifest,
    read_manifest,
    read_run,
    run_record,
    summarize,
    worker_pool,
    write_records,
)
from robovae.model.vae import RoboVAE


class _Float32Weights:
    """A model's weights as ``generate`` fingerprints them (float32, as trained), whatever the
    precision of the predict run (``64-true`` turns them into exact float64 copies)."""

    def __init__(self, module: torch.nn.Module) -> None:
        self.module = module

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {k: v.float() if v.is_floating_point() else v
                for k, v in self.module.state_dict().items()}


def _robovae(pl_module: L.LightningModule) -> RoboVAE:
    """The module a :class:`RobotWriter` writes the robots of.

    Raises:
        TypeError: it is not a :class:`~robovae.model.vae.RoboVAE`.
    """
    if not isinstance(pl_module, RoboVAE):
        raise TypeError(f"robovae: RobotWriter writes the robots of a RoboVAE, not of "
                        f"{type(pl_module).__name__}")
    return pl_module


class RobotWriter(BasePredictionWriter):
    """Write each predicted batch of robots to ``output_dir`` (one folder per robot).

    Args:
        output_dir: the generation folder (re-running resumes: done robots are skipped).
        validate: simulate and classify each robot (:mod:`robovae.generate.validate`).
        scene: also write ``scene.xml``.
        jobs: validation worker processes per rank (0: all cores / world size).
        self_collision: the robots' bodies collide with each other, but for the pairs in
            contact at rest (:mod:`robovae.data.self_collision`), as ``robovae generate
            --self-collision``.
    """

    def __init__(self, output_dir: str = "runs/samples", validate: bool = True,
                 scene: bool = True, jobs: int = 0, self_collision: bool = False) -> None:
        super().__init__(write_interval="batch")
        self.out = Path(output_dir)
        self.validate, self.scene, self.jobs = validate, scene, jobs
        self.self_collision = self_collision
        self.report: GenerationReport | None = None
        self._pool: WorkerPool | None = None
        self._lock = FolderLock(self.out)  # taken by rank 0 when the run claims the folder

    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        """Ask for the robots already in the output folder when the predict set is built (rank 0
        makes the folder then, when it claims it: a refused run leaves none)."""
        if stage != "predict":
            return
        # Lightning sets Trainer.datamodule at run time without declaring it on the class
        dm = trainer.datamodule  # type: ignore[attr-defined]
        if dm is not None and hasattr(dm, "predict_skip"):
            # asked for when the datamodule builds the predict set: the weights are restored
            # from the checkpoint by then (they are not yet during setup)
            dm.predict_skip = lambda: self.done(trainer, pl_module)

    def done(self, trainer: L.Trainer, pl_module: L.LightningModule) -> list[int]:
        """Claim the folder for this run and list the robots already in it (every rank).

        Rank 0 claims (``run.json``), then every rank checks ``run.json`` itself, so that all
        ranks stop together on a refusal; all ranks have read the manifests before any writes.

        Raises:
            RobovaeError: an untrained model (no checkpoint given), a folder of another run,
                or one another run is writing.
        """
        hp = trainer.datamodule.hparams  # type: ignore[attr-defined]  # as in setup
        model = _robovae(pl_module)
        if not bool(model.normalizer.fitted):  # no checkpoint: random weights, no feature units
            raise RobovaeError("robovae: the model to sample from is untrained (its feature "
                               "normaliser was never fitted): give --ckpt_path, the checkpoint "
                               "of a trained model")
        # as generate's (held controls when validated): either resumes the other's folder
        run = run_record(model, model_fingerprint(_Float32Weights(model)), int(hp.predict_seed),
                         float(hp.predict_temperature), model.hparams.get("node_temperature"),
                         int(hp.predict_redraws),
                         validation="held" if self.validate else None,
                         self_collision=self.self_collision)
        refused = None
        if trainer.is_global_zero:
            try:  # held by rank 0 until the run ends (teardown): one run writes here at a time
                self._lock = FolderLock(self.out, "robots").acquire()
                claim(self.out, run)
            except RobovaeError as e:
                refused = str(e)
        refused = trainer.strategy.broadcast(refused, src=0)  # every rank stops together
        if refused is not None:
            raise RobovaeError(refused)
        path = self.out / RUN
        if not path.is_file() or read_run(path) != run:
            raise RobovaeError(f"robovae: {self.out}: holds robots of another run; use another "
                               "output_dir")
        skip = sorted(read_manifest(self.out))
        trainer.strategy.barrier()
        return skip

    def write_on_batch_end(self, trainer: L.Trainer, pl_module: L.LightningModule,
                           prediction: Any, batch_indices: Sequence[int] | None, batch: Any,
                           batch_idx: int, dataloader_idx: int = 0) -> None:
        """Write, validate and record the robots decoded in one predict batch."""
        if not isinstance(prediction, dict) or "graphs" not in prediction:
            raise TypeError("robovae: RobotWriter needs latent batches (set "
                            "data.predict_samples > 0)")
        jobs = self.jobs or max(1, (torch.get_num_threads() or 1) // trainer.world_size)
        if jobs > 1 and self._pool is None and len(prediction["graphs"]) >= 4:
            self._pool = worker_pool(jobs)  # one pool for the whole run, not one per batch
        records = write_records(_robovae(pl_module), prediction["index"].tolist(),
                                prediction["z"],
                                prediction["graphs"], self.out, seed=prediction["seed"],
                                temperature=prediction["temperature"], validate=self.validate,
                                jobs=jobs, scene=self.scene, pool=self._pool,
                                draws=prediction.get("draws"),
                                self_collision=self.self_collision)
        # (a torn last line of a killed run is terminated first, as by generate)
        with open_manifest(self.out / f"manifest-rank{trainer.global_rank}.jsonl") as manifest:
            append_records(manifest, records)

    def on_exception(self, trainer: L.Trainer, pl_module: L.LightningModule,
                     exception: BaseException) -> None:
        """After an error or an interrupt, stop the validation workers at once (robots queued
        or in hand are dropped: :meth:`robovae.data.workers.WorkerPool.terminate`)."""
        if self._pool is not None:
            self._pool.terminate()
            self._pool = None
        self._lock.release()

    def teardown(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        """Close the validation worker pool (after finished batches nothing is queued)."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None
        self._lock.release()

    def on_predict_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        """On rank 0, summarise the manifests of all ranks and print the sample report."""
        trainer.strategy.barrier()
        if trainer.is_global_zero:
            dm = trainer.datamodule  # type: ignore[attr-defined]  # as in setup
            n = dm.hparams.predict_samples
            new = len(dm.predict_set) if getattr(dm, "predict_set", None) is not None else 0
            report = summarize(_robovae(pl_module), self.out, n, new, self.validate, 0.0)
            print(report.format())
            self.report = report
        trainer.strategy.barrier()
