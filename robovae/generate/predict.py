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
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import lightning as L
import torch
from lightning.pytorch.callbacks import BasePredictionWriter

from robovae.data.latents import LatentIndices  # noqa: F401  (re-exported)
from robovae.generate.pipeline import append_records, read_manifest, summarize, write_records


class RobotWriter(BasePredictionWriter):
    """Write each predicted batch of robots to ``output_dir`` (one folder per robot).

    Args:
        output_dir: the generation folder (re-running resumes: done robots are skipped).
        validate: simulate and classify each robot (:mod:`robovae.generate.validate`).
        scene: also write ``scene.xml``.
        jobs: validation worker processes per rank (0: all cores / world size).
    """

    def __init__(self, output_dir: str = "runs/samples", validate: bool = True,
                 scene: bool = True, jobs: int = 0) -> None:
        super().__init__(write_interval="batch")
        self.out = Path(output_dir)
        self.validate, self.scene, self.jobs = validate, scene, jobs
        self.report = None

    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        if stage != "predict":
            return
        self.out.mkdir(parents=True, exist_ok=True)
        dm = trainer.datamodule
        if dm is not None and hasattr(dm, "predict_skip"):
            dm.predict_skip = sorted(read_manifest(self.out))

    def write_on_batch_end(self, trainer: L.Trainer, pl_module: L.LightningModule,
                           prediction: Any, batch_indices: Sequence[int] | None, batch: Any,
                           batch_idx: int, dataloader_idx: int = 0) -> None:
        if not isinstance(prediction, dict) or "graphs" not in prediction:
            raise TypeError("robovae: RobotWriter needs latent batches (set "
                            "data.predict_samples > 0)")
        jobs = self.jobs or max(1, (torch.get_num_threads() or 1) // trainer.world_size)
        records = write_records(pl_module, prediction["index"].tolist(), prediction["z"],
                                prediction["graphs"], self.out, seed=prediction["seed"],
                                temperature=prediction["temperature"], validate=self.validate,
                                jobs=jobs, scene=self.scene)
        with (self.out / f"manifest-rank{trainer.global_rank}.jsonl").open("a") as manifest:
            append_records(manifest, records)

    def on_predict_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        trainer.strategy.barrier()
        if trainer.is_global_zero:
            dm = trainer.datamodule
            n = dm.hparams.predict_samples
            new = len(dm.predict_set) if getattr(dm, "predict_set", None) is not None else 0
            self.report = summarize(pl_module, self.out, n, new, self.validate, 0.0)
            print(self.report.format())
        trainer.strategy.barrier()
