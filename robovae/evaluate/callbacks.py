"""Lightning callback that scores autoregressive reconstructions (RA, RA_true, exact, FRE).

Teacher-forced losses say little about what the decoder does on its own, so every
``every_n_epochs`` validation epochs, and at test time, the robots of the split are encoded
(z = μ) and decoded greedily, and the metrics of :mod:`robovae.evaluate.metrics` are logged as
``<stage>/RA``, ``<stage>/RA_true``, ``<stage>/exact``, ``<stage>/FRE`` (means) and
``<stage>/RA/<robot>``, ``<stage>/FRE/<robot>`` (per robot).
"""

from __future__ import annotations

import math

import lightning as L
from torch_geometric.data import Batch

from robovae.evaluate.metrics import Reconstruction, reconstruction_metrics, summarize


def score_split(pl_module, robots, batch_size: int = 64) -> list[Reconstruction]:
    """Reconstruct ``robots`` (a dataset or list of ``Data``) and score each one."""
    robots = list(robots)
    results = []
    for start in range(0, len(robots), batch_size):
        chunk = robots[start:start + batch_size]
        decoded = pl_module.reconstruct(Batch.from_data_list(chunk))
        results += [reconstruction_metrics(t, p, pl_module.normalizer, pl_module.feature_set)
                    for t, p in zip(chunk, decoded)]
    return results


class ReconstructionMetrics(L.Callback):
    """Log RA / RA_true / exact / FRE of greedy reconstructions.

    Args:
        every_n_epochs: validation epochs between two scorings (the last epoch always counts).
        per_robot: also log one value per robot (at most ``max_per_robot`` robots).
        max_per_robot: cap on per-robot keys.
    """

    def __init__(self, every_n_epochs: int = 10, per_robot: bool = True,
                 max_per_robot: int = 64) -> None:
        self.every_n_epochs = max(1, every_n_epochs)
        self.per_robot = per_robot
        self.max_per_robot = max_per_robot
        self.last: dict[str, list[Reconstruction]] = {}

    def _log(self, pl_module, stage: str, results: list[Reconstruction]) -> None:
        self.last[stage] = results
        summary = summarize(results)
        for key in ("ra", "ra_true", "exact", "fre"):
            value = summary[key]
            name = {"ra": "RA", "ra_true": "RA_true", "exact": "exact", "fre": "FRE"}[key]
            if not math.isnan(value):
                pl_module.log(f"{stage}/{name}", value, batch_size=len(results))
        if self.per_robot and len(results) <= self.max_per_robot:
            for r in results:
                pl_module.log(f"{stage}/RA/{r.name}", r.ra, batch_size=1)
                if not math.isnan(r.fre):
                    pl_module.log(f"{stage}/FRE/{r.name}", r.fre, batch_size=1)

    def on_validation_epoch_end(self, trainer: L.Trainer, pl_module) -> None:
        """Every ``every_n_epochs`` (and at the last epoch): decode the validation robots and
        log ``val/RA``, ``val/RA_true``, ``val/exact``, ``val/FRE``."""
        if trainer.sanity_checking:
            return
        epoch = trainer.current_epoch + 1
        last = trainer.max_epochs is not None and epoch >= trainer.max_epochs
        if epoch % self.every_n_epochs and not last:
            return
        self._log(pl_module, "val", score_split(pl_module, trainer.datamodule.val_set))

    def on_test_epoch_end(self, trainer: L.Trainer, pl_module) -> None:
        """Decode the test robots and log the ``test/*`` metrics (also per robot)."""
        self._log(pl_module, "test", score_split(pl_module, trainer.datamodule.test_set))
