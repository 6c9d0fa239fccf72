"""``robovae fit|validate|test|predict``: the Lightning CLI over :class:`RoboVAE` and
:class:`RobotDataModule`.

Defaults: CSV logger under ``runs/``, a :class:`ModelCheckpoint` keeping ``last.ckpt``
(``checkpoint.*`` options), the :class:`ReconstructionMetrics` callback (``metrics.*``), seed 0.
``data.feature_set`` is linked to ``model.feature_set``. Switch to Weights & Biases (offline by
default) with ``--config configs/loggers/wandb.yaml``.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

from lightning.pytorch.callbacks import ModelCheckpoint
from lightning.pytorch.cli import LightningArgumentParser, LightningCLI

from robovae.data.datamodule import RobotDataModule
from robovae.evaluate.callbacks import ReconstructionMetrics
from robovae.model.vae import RoboVAE


class RoboVAECLI(LightningCLI):
    """LightningCLI with robovae's linked arguments and always-on callbacks."""

    def add_arguments_to_parser(self, parser: LightningArgumentParser) -> None:
        parser.link_arguments("data.feature_set", "model.feature_set")
        parser.add_lightning_class_args(ModelCheckpoint, "checkpoint")
        parser.set_defaults({"checkpoint.save_last": True, "checkpoint.save_top_k": 0})
        parser.add_lightning_class_args(ReconstructionMetrics, "metrics")


def run_lightning_cli(argv: Sequence[str] | None = None) -> RoboVAECLI:
    """Run the Lightning CLI on ``argv`` (``["fit", "--config", ...]``; ``None``: sys.argv)."""
    warnings.filterwarnings("ignore", ".*does not have many workers.*")
    warnings.filterwarnings("ignore", ".*smaller than the logging interval.*")
    return RoboVAECLI(
        RoboVAE,
        RobotDataModule,
        args=list(argv) if argv is not None else None,
        seed_everything_default=0,
        save_config_kwargs={"overwrite": True},
        trainer_defaults={
            "logger": {"class_path": "lightning.pytorch.loggers.CSVLogger",
                       "init_args": {"save_dir": "runs", "name": "robovae"}},
            "log_every_n_steps": 1,
        },
    )
