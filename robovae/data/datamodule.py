"""``RobotDataModule``: a :class:`RobotDataset` split into train/val/test for Lightning."""

from __future__ import annotations

import fnmatch
from collections.abc import Callable, Sequence
from typing import Any

import lightning as L
import torch
from torch.utils.data import DataLoader as TorchDataLoader
from torch_geometric.data import Batch
from torch_geometric.loader import DataLoader

from robovae.data.augment import Augmentation, FeatureJitter, TreeSurgery
from robovae.data.dataset import RobotDataset
from robovae.data.latents import LatentIndices
from robovae.data.normalizer import Normalizer
from robovae.data.sources import check_sources
from robovae.settings import FEATURE_SET, check_settings, integer, number


def select_names(names: Sequence[str], wanted: Sequence[str]) -> list[int]:
    """Indices of the robots ``wanted`` in ``names``, in the order asked, without repeats.

    An entry with a shell wildcard (``*``, ``?``, ``[``) selects every matching name
    (:func:`fnmatch.fnmatchcase`, in dataset order); other entries must be names.

    Raises:
        KeyError: a name not in the dataset, or a pattern matching none.
    """
    index = {n: i for i, n in enumerate(names)}
    out: dict[int, None] = {}
    for w in wanted:
        if any(c in w for c in "*?["):
            hits = [i for i, n in enumerate(names) if fnmatch.fnmatchcase(n, w)]
        else:
            hits = [index[w]] if w in index else []
        if not hits:
            shown = ", ".join(names[:20]) + (f", … ({len(names)} robots)" if len(names) > 20
                                              else "")
            raise KeyError(f"robovae: no robot named {w!r} in the dataset (have: {shown})")
        out.update(dict.fromkeys(hits))
    return list(out)


class RobotDataModule(L.LightningDataModule):
    """Robot graphs for training, with splits by robot name or by fraction.

    Args:
        sources: source strings (``zoo``, ``menagerie:go2``, ``dir:PATH``, ``synthetic:...``).
        feature_set: ``paper34``, ``kinematic`` or ``full`` (synthetic sources force
            ``random<d>``).
        root: cache folder of the processed dataset.
        train_names: robots to train on (default: all not in val/test). Names may be shell
            patterns (``proc_*``, :func:`fnmatch.fnmatchcase`), in all three name lists.
        val_names: robots held out for validation, by name. When ``val_names`` and
            ``test_names`` are both empty the split is by fraction (seeded shuffle).
        test_names: robots held out for testing, by name.
        val_fraction: share of the robots for validation when no names are given.
        test_fraction: share of the robots for testing when no names are given.
        val_is_train: validate on the training robots (for overfitting experiments and tiny
            sets where a held-out robot is the test robot).
        batch_size: graphs per batch.
        seed: seed of the fraction split.
        num_workers: DataLoader workers.
        predict_samples: when > 0, ``predict`` decodes this many prior samples (robot indices
            ``0 … n-1``, see :mod:`robovae.generate.predict`) instead of the test robots.
        predict_seed: seed of those samples.
        predict_temperature: prior temperature of those samples.
        predict_redraws: an unfinished decoding (at the decoder's node or depth limit) redraws
            its latent up to this many times (:func:`robovae.model.prior.draw_robots`).
        feature_shift: training-batch augmentation (:class:`~robovae.data.augment.FeatureJitter`):
            std of a per-robot offset on every feature column, normalised units (0: off).
        feature_noise: std of per-node feature noise, normalised units (0: off).
        tree_surgery: probability that a training robot is rebuilt by random limb edits in a
            step (:class:`~robovae.data.augment.TreeSurgery`; 0: off).
        surgery_ops: at most this many edits per rebuilt robot.
        surgery_max_nodes: tree surgery never makes a robot larger than this (the model's
            ``max_nodes``).

    Training batches are augmented on the device (:meth:`on_after_batch_transfer`), tree
    surgery first, with generators seeded by ``(seed_everything's seed, epoch, batch index,
    rank)`` (:func:`~robovae.data.augment.run_seed`): a run resumed from an end-of-epoch
    checkpoint augments exactly like an uninterrupted one.
    """

    def __init__(
        self,
        sources: Sequence[str] = ("zoo",),
        feature_set: str = "paper34",
        root: str = "data_cache",
        train_names: Sequence[str] = (),
        val_names: Sequence[str] = (),
        test_names: Sequence[str] = (),
        val_fraction: float = 0.1,
        test_fraction: float = 0.1,
        val_is_train: bool = False,
        batch_size: int = 32,
        seed: int = 0,
        num_workers: int = 0,
        predict_samples: int = 0,
        predict_seed: int = 0,
        predict_temperature: float = 1.0,
        predict_redraws: int = 4,
        feature_shift: float = 0.0,
        feature_noise: float = 0.0,
        tree_surgery: float = 0.0,
        surgery_ops: int = 3,
        surgery_max_nodes: int = 256,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()
        share = number(0, 1, high_open=True)
        check_settings(
            "data", feature_set=(feature_set, FEATURE_SET), val_fraction=(val_fraction, share),
            test_fraction=(test_fraction, share), batch_size=(batch_size, integer(1)),
            num_workers=(num_workers, integer(0)), predict_samples=(predict_samples, integer(0)),
            predict_temperature=(predict_temperature, number(0)),
            predict_redraws=(predict_redraws, integer(0)),
            feature_shift=(feature_shift, number(0)), feature_noise=(feature_noise, number(0)),
            tree_surgery=(tree_surgery, number(0, 1)), surgery_ops=(surgery_ops, integer(1)),
            surgery_max_nodes=(surgery_max_nodes, integer(1)))
        check_sources(sources, feature_set)  # refused now, not when the data is built
        if val_fraction + test_fraction >= 1:
            raise ValueError(f"robovae: data.val_fraction + data.test_fraction must be below 1 "
                             f"(no robot left to train on), got {val_fraction + test_fraction:g}")
        self.dataset: RobotDataset | None = None
        self.normalizer: Normalizer | None = None
        # robots already written: a list, or a function asked when the predict set is built
        # (RobotWriter sets one that also ties the output folder to the run)
        self.predict_skip: Sequence[int] | Callable[[], Sequence[int]] = []
        self.predict_set: LatentIndices | None = None
        self.augmentation: Augmentation | None = None

    @property
    def feature_set(self) -> str:
        """The feature set in use (after synthetic sources forced theirs)."""
        return self.dataset.feature_set if self.dataset is not None else \
            self.hparams["feature_set"]

    def _split(self, names: list[str]) -> tuple[list[int], list[int], list[int]]:
        hp = self.hparams
        if hp["val_names"] or hp["test_names"] or hp["train_names"]:
            val, test = select_names(names, hp["val_names"]), select_names(names, hp["test_names"])
            held = set(val) | set(test)
            train = (select_names(names, hp["train_names"]) if hp["train_names"]
                     else [i for i in range(len(names)) if i not in held])
        else:
            g = torch.Generator().manual_seed(hp["seed"])
            perm = torch.randperm(len(names), generator=g).tolist()
            n_test = round(hp["test_fraction"] * len(names))
            n_val = round(hp["val_fraction"] * len(names))
            test, val, train = perm[:n_test], perm[n_test:n_test + n_val], perm[n_test + n_val:]
        if hp["val_is_train"] or not val:
            val = list(train)
        return train, val, test

    def _predicts_latents(self) -> bool:
        """``predict`` of prior samples: no robot files are needed (the model brings its
        normaliser from the checkpoint)."""
        trainer = getattr(self, "trainer", None)
        return (self.hparams["predict_samples"] > 0 and trainer is not None
                and trainer.state.fn == "predict")

    def prepare_data(self) -> None:
        """Build (or load from the cache) the dataset once, on rank 0."""
        if self._predicts_latents():
            return
        RobotDataset(self.hparams["root"], self.hparams["sources"], self.hparams["feature_set"])

    def setup(self, stage: str | None = None) -> None:
        """Load the dataset, split it into train/val/test and fit the normaliser on train."""
        hp = self.hparams
        if stage == "predict" and hp["predict_samples"] > 0:
            return  # latents only: the model brings its normaliser from the checkpoint
        if self.dataset is not None:
            return
        self.dataset = RobotDataset(hp["root"], hp["sources"], hp["feature_set"], progress=False)
        train, val, test = self._split(self.dataset.names)
        if not train:
            raise ValueError("robovae: the training split is empty")
        self.train_set = self.dataset[train]
        self.val_set = self.dataset[val]
        self.test_set = self.dataset[test] if test else self.dataset[val]
        x, t, rows = self.dataset.node_rows(train)
        self.normalizer = Normalizer(self.dataset.feature_set).fit(x, t, rows)
        self.augmentation = self.train_augmentation()

    def train_augmentation(self) -> Augmentation | None:
        """The transforms of the training batches (``None`` when every knob is off)."""
        hp, fs = self.hparams, self.feature_set
        surgery = TreeSurgery(fs, hp["tree_surgery"], hp["surgery_ops"], hp["surgery_max_nodes"]) \
            if hp["tree_surgery"] > 0 else None
        jitter = FeatureJitter(fs, hp["feature_shift"], hp["feature_noise"]) \
            if hp["feature_shift"] > 0 or hp["feature_noise"] > 0 else None
        return Augmentation(surgery, jitter) if surgery or jitter else None

    def transfer_batch_to_device(self, batch: Any, device: torch.device,
                                 dataloader_idx: int) -> Any:
        """Robot batches move with PyG's own ``Batch.to`` (nothing to do when they are already
        there); Lightning's default walks every attribute of the batch (names, sources, ...)
        through ``apply_to_collection``, milliseconds per step on the CPU."""
        if isinstance(batch, Batch):
            return batch if batch.x.device == device else batch.to(device)
        return super().transfer_batch_to_device(batch, device, dataloader_idx)

    def on_after_batch_transfer(self, batch: Any, dataloader_idx: int) -> Any:
        """Augment a training batch (:attr:`augmentation`), seeded by ``(epoch, batch index,
        rank)`` of the trainer; other batches pass unchanged."""
        trainer = self.trainer
        if (self.augmentation is None or trainer is None or not trainer.training
                or not isinstance(batch, Batch)):
            return batch
        # the loop increments its batch counter right after this hook: +1 is the batch_idx
        # that training_step receives
        index = trainer.fit_loop.epoch_loop.batch_idx + 1
        self.augmentation.seed(trainer.current_epoch, index, trainer.global_rank)
        return self.augmentation(batch)

    def train_dataloader(self) -> DataLoader:
        """Shuffled PyG loader over the training robots."""
        return DataLoader(self.train_set, batch_size=self.hparams["batch_size"], shuffle=True,
                          num_workers=self.hparams["num_workers"])

    def val_dataloader(self) -> DataLoader:
        """Loader over the validation robots (the training robots when ``val_is_train``)."""
        return DataLoader(self.val_set, batch_size=self.hparams["batch_size"],
                          num_workers=self.hparams["num_workers"])

    def test_dataloader(self) -> DataLoader:
        """Loader over the test robots."""
        return DataLoader(self.test_set, batch_size=self.hparams["batch_size"],
                          num_workers=self.hparams["num_workers"])


    def predict_dataloader(self) -> DataLoader | TorchDataLoader:
        """Loader over the latent requests of ``robovae predict``."""
        hp = self.hparams
        if hp["predict_samples"] <= 0:
            return self.test_dataloader()
        skip = self.predict_skip() if callable(self.predict_skip) else self.predict_skip
        self.predict_set = LatentIndices(hp["predict_samples"], hp["predict_seed"],
                                         hp["predict_temperature"], skip=skip,
                                         redraws=hp["predict_redraws"])
        return TorchDataLoader(self.predict_set, batch_size=max(hp["batch_size"], 1))
