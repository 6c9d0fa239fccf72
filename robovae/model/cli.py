"""``robovae fit|validate|test|predict``: the Lightning CLI over :class:`RoboVAE` and
:class:`RobotDataModule`.

Defaults: CSV logger under ``runs/``, a :class:`ModelCheckpoint` writing ``last.ckpt`` (and
``epoch=E-step=S.ckpt``, the newest only) at the end of every epoch (``checkpoint.*`` options),
the :class:`ReconstructionMetrics` callback (``metrics.*``), seed 0. ``data.feature_set`` is
linked to ``model.feature_set``. Switch to Weights & Biases (offline by default) with
``--config configs/loggers/wandb.yaml``.

Checkpoints are never unpickled: an explicit ``--ckpt_path FILE`` is checked with
:func:`~robovae.model.checkpoint.read_checkpoint` (``torch.load(weights_only=True)``) before
Lightning touches it, the trainer gets ``weights_only=True`` unless ``--weights_only`` says
otherwise, and a refused checkpoint is one line on stderr (exit code 2), not a traceback.
Resume a killed run with ``robovae fit --config X.yaml --ckpt_path last`` (Lightning picks the
newest ``last*.ckpt`` of the checkpoint folder; the run continues exactly, see
:mod:`robovae.model.vae`).
"""

from __future__ import annotations

import pickle
import sys
import warnings
from argparse import ArgumentError
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import lightning as L
from lightning.pytorch.callbacks import ModelCheckpoint
from lightning.pytorch.cli import ArgsType, LightningArgumentParser, LightningCLI
from lightning.pytorch.plugins.io import TorchCheckpointIO

from robovae.data.datamodule import RobotDataModule
from robovae.errors import RobovaeError
from robovae.evaluate.callbacks import ReconstructionMetrics
from robovae.files import FolderLock
from robovae.model.checkpoint import check_current_model, read_checkpoint, refusal
from robovae.model.checkpoint_io import AtomicCheckpointIO
from robovae.model.vae import RoboVAE

# ``ckpt_path`` values that Lightning resolves itself (the file is checked when it is read)
_CKPT_KEYWORDS = ("last", "best", "hpc", "registry")


def _holds_files(folder: str | Path) -> bool:
    """``folder`` exists and is not empty."""
    path = Path(folder)
    return path.is_dir() and any(path.iterdir())


class CheckpointLock(L.Callback):
    """Hold the checkpoint folder of a ``fit`` run (:class:`~robovae.files.FolderLock`, rank 0,
    from ``setup`` to the end of the run): a second ``robovae fit`` writing the same
    folder — the same config started twice, or another config's run given the same
    ``checkpoint.dirpath`` — is refused in one line, on every rank, before it trains. Until
    2026-11-29 both trained and overwrote each other's ``last.ckpt`` and deleted each other's
    epoch checkpoints. ``validate``/``test``/``predict`` only read checkpoints: not held.

    A ``checkpoint.dirpath`` that is set and holds files (a run's, or its lock) is taken in
    ``setup``, before the checkpoint callback's own ``setup`` (Lightning runs checkpoint
    callbacks last), so a refused run does not first warn that the folder "exists and is not
    empty"; an empty or new folder is taken at ``on_fit_start``, after that callback looked at
    it (taken earlier, the lock file itself would set off the warning), and so is a folder the
    checkpoint callback derives from the logger, known only then."""

    def __init__(self) -> None:
        self._lock: FolderLock | None = None
        self._taken = False  # the folder was asked for in this run (on every rank)

    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        """Take a set ``dirpath`` that holds files, for ``fit`` (rank 0 looks, every rank
        follows its answer: a file made meanwhile by another run must not split the ranks)."""
        self._taken = False
        ckpt = trainer.checkpoint_callback
        folder = ckpt.dirpath if isinstance(ckpt, ModelCheckpoint) else None
        if stage != "fit" or folder is None:
            return
        full = _holds_files(folder) if trainer.is_global_zero else None
        if trainer.strategy.broadcast(full, src=0):
            self._take(trainer, folder)

    def on_fit_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        """Take the folder the checkpoint callback resolved, when ``setup`` could not."""
        ckpt = trainer.checkpoint_callback  # typed as the base Checkpoint: ours has a dirpath
        if not self._taken and isinstance(ckpt, ModelCheckpoint) and ckpt.dirpath is not None:
            self._take(trainer, ckpt.dirpath)

    def _take(self, trainer: L.Trainer, folder: str | Path) -> None:
        """Take ``folder`` on rank 0; every rank raises the refusal together."""
        refused = None
        if trainer.is_global_zero:
            try:
                self._lock = FolderLock(folder, "checkpoints").acquire()
            except RobovaeError as e:
                refused = str(e)
        self._taken = True
        refused = trainer.strategy.broadcast(refused, src=0)
        if refused is not None:
            raise RobovaeError(refused)

    def _release(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def teardown(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        """Release the folder at the end of the run."""
        self._release()

    def on_exception(self, trainer: L.Trainer, pl_module: L.LightningModule,
                     exception: BaseException) -> None:
        """Release the folder when the run fails or is interrupted."""
        self._release()


class RoboVAECLI(LightningCLI):
    """LightningCLI with robovae's linked arguments and always-on callbacks (the checkpoint,
    the RA/FRE metrics, :class:`CheckpointLock`)."""

    def add_arguments_to_parser(self, parser: LightningArgumentParser) -> None:
        """Link ``data.feature_set`` to the model and add the ``checkpoint`` and ``metrics``
        (RA/FRE callback) groups."""
        parser.link_arguments("data.feature_set", "model.feature_set")
        parser.add_lightning_class_args(ModelCheckpoint, "checkpoint")
        # save_top_k=1 without a monitor keeps the newest epoch's checkpoint; Lightning 2.6 writes
        # last.ckpt only together with such a save, so with save_top_k=0 a killed run had none
        parser.set_defaults({"checkpoint.save_last": True, "checkpoint.save_top_k": 1})
        parser.add_lightning_class_args(ReconstructionMetrics, "metrics")

    def parse_arguments(self, parser: LightningArgumentParser, args: ArgsType) -> None:
        """Parse, then refuse an unsafe ``ckpt_path`` before anything reads it (LightningCLI
        itself loads its hyperparameters right after parsing)."""
        super().parse_arguments(parser, args)
        sub = self.config.get("subcommand")
        ckpt = self.config[sub].get("ckpt_path") if sub else None
        if ckpt and not (str(ckpt) in _CKPT_KEYWORDS or str(ckpt).startswith("registry:")
                         or "://" in str(ckpt)):
            check_current_model(read_checkpoint(Path(ckpt)), ckpt)  # one-line RobovaeErrors

    def instantiate_trainer(self, **kwargs: Any) -> L.Trainer:
        """The trainer, with :class:`CheckpointLock` first among its callbacks (its ``setup``
        before the checkpoint callback's), and checkpoints written whole
        (:class:`~robovae.model.checkpoint_io.AtomicCheckpointIO`, unless a checkpoint plugin
        was given)."""
        trainer = super().instantiate_trainer(**kwargs)
        # Trainer.callbacks is set by Lightning's callback connector, undeclared on the class
        trainer.callbacks.insert(0, CheckpointLock())  # type: ignore[attr-defined]
        if type(trainer.strategy.checkpoint_io) is TorchCheckpointIO:  # not a plugin of the user's
            trainer.strategy.checkpoint_io = AtomicCheckpointIO()
        return trainer

    def _weights_only(self) -> None:
        """``before_fit/validate/test/predict``: load checkpoints weights-only unless asked."""
        kwargs = self.config_init[self.subcommand]
        if "weights_only" in kwargs and kwargs["weights_only"] is None:
            kwargs["weights_only"] = True

    before_fit = before_validate = before_test = before_predict = _weights_only

    def instantiate_classes(self) -> None:
        """Build the model, data module and trainer; a setting a constructor refuses (its
        ``ValueError``) is one line naming the config files, not a traceback."""
        try:
            super().instantiate_classes()
        except ValueError as e:
            files = self.config[self.subcommand].get("config") or ["command line"]
            where = ", ".join(str(getattr(f, "relative", f)) for f in files)
            msg = " ".join(str(e).split()).removeprefix("robovae: ")
            raise RobovaeError(f"robovae: {where}: invalid setting: {msg}") from None


def run_lightning_cli(argv: Sequence[str] | None = None) -> RoboVAECLI:
    """Run the Lightning CLI on ``argv`` (``["fit", "--config", ...]``; ``None``: sys.argv)."""
    warnings.filterwarnings("ignore", ".*does not have many workers.*")
    warnings.filterwarnings("ignore", ".*smaller than the logging interval.*")
    # Lightning's own calls into newer libraries, nothing a user can change: torch's
    # pytree (Lightning's ``_pytree.py``) and jsonargparse (Lightning's ``cli.py``)
    warnings.filterwarnings("ignore", r"`isinstance\(treespec, LeafSpec\)` is deprecated")
    warnings.filterwarnings("ignore", r"\s*skip_none parameter was deprecated")
    if argv is not None:  # given on purpose (main([...]) in a notebook or a test), whatever
        # the host program's own sys.argv holds
        warnings.filterwarnings("ignore", "LightningCLI's args parameter is intended.*")
    args = list(sys.argv[1:] if argv is None else argv)
    for config in _configs(args):  # jsonargparse's reader raises UnicodeDecodeError
        try:
            Path(config).read_text(encoding="utf-8")
        except UnicodeDecodeError as e:
            raise RobovaeError(f"robovae {args[0] if args else 'COMMAND'} ({config}): not a "
                               f"YAML config (not UTF-8 text, byte {e.start})") from None
        except OSError:  # missing or unreadable: jsonargparse says so in one line
            pass
    try:
        return _cli(argv)
    except pickle.UnpicklingError as e:  # a checkpoint Lightning found itself (``last``)
        raise refusal(None, e) from None
    except ArgumentError as e:  # jsonargparse's, instead of its usage text and exit
        raise RobovaeError(_parse_error(list(sys.argv[1:] if argv is None else argv), e)) \
            from None


def _configs(argv: list[str]) -> list[str]:
    """The config files named on a command line (``--config F``, ``-c F``, ``--config=F``)."""
    return ([b for a, b in zip(argv, argv[1:]) if a in ("-c", "--config")]
            + [a.split("=", 1)[1] for a in argv if a.startswith("--config=")])


def _parse_error(argv: list[str], e: ArgumentError) -> str:
    """One line for a parse error: the sub-command, its config files, the message."""
    sub = argv[0] if argv else "COMMAND"
    configs = _configs(argv)
    where = f" ({', '.join(configs)})" if configs else ""
    return (f"robovae {sub}{where}: {' '.join(str(e).split())} (robovae {sub} --help lists the "
            "options)")


def _cli(argv: Sequence[str] | None) -> RoboVAECLI:
    one_line = {"exit_on_error": False}  # a parse error raises (run_lightning_cli: one line)
    return RoboVAECLI(
        RoboVAE,
        RobotDataModule,
        args=list(argv) if argv is not None else None,
        parser_kwargs={**one_line, **{sub: dict(one_line) for sub in RoboVAECLI.subcommands()}},
        seed_everything_default=0,
        save_config_kwargs={"overwrite": True},
        trainer_defaults={
            "logger": {"class_path": "lightning.pytorch.loggers.CSVLogger",
                       "init_args": {"save_dir": "runs", "name": "robovae"}},
            "log_every_n_steps": 1,
        },
    )
