"""Lightning callback that scores autoregressive reconstructions (RA, RA_true, exact, FRE), in
full (z and every node's posterior latent) and from the robot latent alone.

Teacher-forced losses say little about what the decoder does on its own, so every
``every_n_epochs`` validation epochs, and at test time, the robots of the split are encoded
(z = μ) and decoded greedily, and the metrics of :mod:`robovae.evaluate.metrics` are logged as
``<stage>/RA``, ``<stage>/RA_true``, ``<stage>/exact``, ``<stage>/FRE`` (means) and
``<stage>/RA/<robot>``, ``<stage>/FRE/<robot>`` (per robot); from ``z`` alone (node latents at
their conditional-prior mean) ``<stage>/RA_z``, ``RA_true_z``, ``exact_z``, ``FRE_z``; and the
cost of the latents, ``<stage>/KL_z``, its tree part ``<stage>/KL_tree`` and
``<stage>/KL_nodes`` (nats per robot), and
``<stage>/NELBO_node`` (negative ELBO, nats per node, :func:`~robovae.model.loss.vae_loss`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from functools import partial
from typing import TYPE_CHECKING, cast

import lightning as L
from torch_geometric.data import Batch, Data

from robovae.evaluate.metrics import Reconstruction, reconstruction_metrics, summarize
from robovae.settings import check_settings, integer

if TYPE_CHECKING:
    from robovae.model.vae import RoboVAE


def score_split(pl_module: RoboVAE, robots: Iterable[Data], batch_size: int = 64,
                from_z: bool = False) -> list[Reconstruction]:
    """Reconstruct ``robots`` (a dataset or list of ``Data``) and score each one; ``from_z``:
    from the robot latent alone (:meth:`RoboVAE.reconstruct
    <robovae.model.vae.RoboVAE.reconstruct>`)."""
    robots = list(robots)
    results = []
    for start in range(0, len(robots), batch_size):
        chunk = robots[start:start + batch_size]
        decoded = pl_module.reconstruct(Batch.from_data_list(chunk), from_z=from_z)
        results += [reconstruction_metrics(t, p, pl_module.normalizer, pl_module.feature_set)
                    for t, p in zip(chunk, decoded)]
    return results


def latent_costs(pl_module: RoboVAE, robots: Iterable[Data],
                 batch_size: int = 64) -> list[dict[str, float]]:
    """Per robot: ``kl_z``, ``kl_tree``, ``kl_nodes`` (nats per robot) and ``nelbo_per_node``
    (nats) of :meth:`RoboVAE.latent_costs <robovae.model.vae.RoboVAE.latent_costs>`, and
    ``nodes``."""
    robots = list(robots)
    out: list[dict[str, float]] = []
    for start in range(0, len(robots), batch_size):
        costs = pl_module.latent_costs(Batch.from_data_list(robots[start:start + batch_size]))
        out += [{k: float(v[i]) for k, v in costs.items()} for i in range(len(costs["nodes"]))]
    return out


def split_metrics_from_z(pl_module: RoboVAE, robots: Sequence[Data]) -> dict[str, float]:
    """The from-z part of :func:`split_metrics` (``RA_z`` ... ``FRE_z``, ``KL_z``, ``KL_tree``,
    ``KL_nodes``, ``NELBO_node``)."""
    names = {"ra": "RA_z", "ra_true": "RA_true_z", "exact": "exact_z", "fre": "FRE_z"}
    s = summarize(score_split(pl_module, robots, from_z=True))
    out = {names[k]: s[k] for k in names}
    costs = latent_costs(pl_module, robots)
    if costs:
        out["KL_z"] = sum(c["kl_z"] for c in costs) / len(costs)
        out["KL_tree"] = sum(c["kl_tree"] for c in costs) / len(costs)
        out["KL_nodes"] = sum(c["kl_nodes"] for c in costs) / len(costs)
        out["NELBO_node"] = sum(c["nelbo_per_node"] * c["nodes"] for c in costs) / \
            sum(c["nodes"] for c in costs)
    return out


class ReconstructionMetrics(L.Callback):
    """Log RA / RA_true / exact / FRE of greedy reconstructions.

    Args:
        every_n_epochs: validation epochs between two scorings (the last epoch always counts).
        per_robot: also log one value per robot (at most ``max_per_robot`` robots).
        max_per_robot: cap on per-robot keys.

    Raises:
        SettingsError: ``every_n_epochs`` below 1, ``max_per_robot`` negative.
    """

    def __init__(self, every_n_epochs: int = 10, per_robot: bool = True,
                 max_per_robot: int = 64) -> None:
        check_settings("ReconstructionMetrics", every_n_epochs=(every_n_epochs, integer(1)),
                       max_per_robot=(max_per_robot, integer(0)))
        self.every_n_epochs = every_n_epochs
        self.per_robot = per_robot
        self.max_per_robot = max_per_robot
        self.last: dict[str, list[Reconstruction]] = {}

    def _log(self, module: L.LightningModule, stage: str, robots: Sequence[Data]) -> None:
        # Lightning passes the hooks a LightningModule: this callback scores a RoboVAE
        pl_module = cast("RoboVAE", module)
        results = score_split(pl_module, robots)
        self.last[stage] = results
        summary = summarize(results)
        from_z = split_metrics_from_z(pl_module, robots)
        # every rank scores the whole split with the same weights: the ranks' values agree, and
        # sync_dist (their mean) logs that value under DDP without Lightning's warning per key
        log = partial(pl_module.log, sync_dist=True)
        for name, value in from_z.items():
            if not math.isnan(value):
                log(f"{stage}/{name}", value, batch_size=len(results))
        for key in ("ra", "ra_true", "exact", "fre"):
            value = summary[key]
            name = {"ra": "RA", "ra_true": "RA_true", "exact": "exact", "fre": "FRE"}[key]
            if not math.isnan(value):
                log(f"{stage}/{name}", value, batch_size=len(results))
        if self.per_robot and len(results) <= self.max_per_robot:
            for r in results:
                log(f"{stage}/RA/{r.name}", r.ra, batch_size=1)
                if not math.isnan(r.fre):
                    log(f"{stage}/FRE/{r.name}", r.fre, batch_size=1)

    def on_validation_epoch_end(self, trainer: L.Trainer,
                                pl_module: L.LightningModule) -> None:
        """Every ``every_n_epochs`` (and at the last epoch): decode the validation robots and
        log ``val/RA``, ``val/RA_true``, ``val/exact``, ``val/FRE``."""
        if trainer.sanity_checking:
            return
        epoch = trainer.current_epoch + 1
        last = trainer.max_epochs is not None and epoch >= trainer.max_epochs
        if epoch % self.every_n_epochs and not last:
            return
        # Lightning sets Trainer.datamodule at run time without declaring it on the class
        self._log(pl_module, "val", trainer.datamodule.val_set)  # type: ignore[attr-defined]

    def on_test_epoch_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        """Decode the test robots and log the ``test/*`` metrics (also per robot)."""
        # Lightning sets Trainer.datamodule at run time without declaring it on the class
        self._log(pl_module, "test", trainer.datamodule.test_set)  # type: ignore[attr-defined]
