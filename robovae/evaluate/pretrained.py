"""The 17 Menagerie robots as the unseen test set of a pretrained model (issue 20).

- **zero-shot** (:func:`zeroshot`): a checkpoint trained without them (``configs/default.yaml``,
  ``configs/large.yaml``) encodes and decodes each of the 17; the result holds every robot's
  reconstruction from ``z`` alone and with the node latents (full channel), and what its
  latents cost in nats (:func:`~robovae.evaluate.callbacks.latent_costs`);
- **fine-tuned** (:func:`finetune_specs`): the pretrained weights (and the pretrained
  normaliser) are trained further on 16 of the 17 (``configs/finetune17.yaml``) and the 17th
  is reconstructed, one run per held-out robot and seed, through the same runner as the
  paper's experiments (:func:`~robovae.evaluate.experiment_runner.run_one`).

Results go to ``runs/experiments/zeroshot/<name>/result.json`` and
``runs/experiments/finetune/<name>/<robot>/seed<k>/result.json``; the tables are
:func:`robovae.evaluate.experiment_tables.zeroshot_table` and ``finetune_table``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import lightning as L

from robovae.evaluate.experiment_runner import (
    MENAGERIE17,
    REPO,
    RUNS,
    RunSpec,
    _commit,
    _loadavg,
    _names_arg,
)
from robovae.files import atomic_json

if TYPE_CHECKING:
    from robovae.evaluate.metrics import Reconstruction

__all__ = ["PretrainedWeights", "finetune_specs", "zeroshot"]

#: The model hyperparameters a fine-tuning run takes from the pretrained checkpoint.
_ARCH = ("feature_set", "hidden_dim", "latent_dim", "tree_latent_dim", "node_latent_dim",
         "max_nodes", "max_depth", "support_margin")


class PretrainedWeights(L.Callback):
    """Start a fit from a checkpoint's weights and normaliser (not its optimiser or epoch).

    Runs in ``setup``, before the LightningModule's own ``setup``, which then keeps the
    loaded (fitted) normaliser instead of fitting one on the new training robots.

    Args:
        path: the pretrained checkpoint.
    """

    def __init__(self, path: str) -> None:
        self.path = path

    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        """Load the weights (strictly: the architectures must match)."""
        from robovae.model.checkpoint import check_current_model, read_checkpoint

        ckpt = read_checkpoint(self.path)
        check_current_model(ckpt, self.path)
        pl_module.load_state_dict(ckpt["state_dict"])
        pl_module.on_load_checkpoint(ckpt)


def _robot_rows(results: Sequence[Reconstruction], costs: Sequence[dict[str, float]]
                ) -> list[dict]:
    return [{"name": r.name, "ra": r.ra, "ra_true": r.ra_true, "exact": r.exact, "fre": r.fre,
             "n_true": r.n_true, "n_pred": r.n_pred, "n_correct": r.n_correct, **c}
            for r, c in zip(results, costs)]


def zeroshot(ckpt: str | Path, name: str, menagerie: str | Path = REPO.parent / "shared" /
             "menagerie", root: Path = RUNS, cache: str | Path = "data_cache") -> dict:
    """Score a pretrained checkpoint on the 17 robots of ``menagerie`` (never trained on):
    from ``z`` and full channel, per robot with its latent costs; writes and returns
    ``<root>/zeroshot/<name>/result.json``."""
    from robovae.data.dataset import RobotDataset
    from robovae.evaluate.callbacks import latent_costs, score_split
    from robovae.evaluate.metrics import summarize
    from robovae.model.checkpoint import load_model

    t0 = time.perf_counter()
    model = load_model(ckpt)
    trained = {str(r.get("name")) for r in model.training_robots}
    data = RobotDataset(cache, [f"dir:{menagerie}"], model.feature_set.name, progress=False)
    robots = [data.by_name(n) for n in MENAGERIE17]
    leaked = sorted(trained & set(MENAGERIE17))
    if leaked:  # the test set must be unseen
        raise ValueError(f"robovae: {ckpt} was trained on {leaked}: not a zero-shot test")
    full, from_z = score_split(model, robots), score_split(model, robots, from_z=True)
    costs = latent_costs(model, robots)
    out = Path(root) / "zeroshot" / name
    out.mkdir(parents=True, exist_ok=True)
    result = {
        "experiment": "zeroshot", "name": name, "ckpt": str(ckpt), "seconds":
            time.perf_counter() - t0, "load": _loadavg(), "commit": _commit(),
        "training_robots": len(trained),
        "hparams": {k: v for k, v in dict(model.hparams).items()
                    if isinstance(v, (int, float, str, bool)) or v is None},
        "test": _robot_rows(full, costs), "test_z": _robot_rows(from_z, costs),
        "summary": {k: summarize(full)[k] for k in ("ra", "ra_true", "exact", "fre")},
        "summary_z": {k: summarize(from_z)[k] for k in ("ra", "ra_true", "exact", "fre")},
    }
    atomic_json(out / "result.json", result)
    return result


def finetune_specs(ckpt: str | Path, name: str, seeds: Sequence[int],
                   robots: Sequence[str] = MENAGERIE17, extra: Sequence[str] = (),
                   epochs: int | None = None, threads: int = 0,
                   root: Path = RUNS) -> list[RunSpec]:
    """Runs that fine-tune ``ckpt`` on 16 of the 17 robots (``configs/finetune17.yaml``, the
    checkpoint's architecture) and test the 17th, one per held-out robot and seed."""
    from robovae.model.checkpoint import read_checkpoint

    hp = read_checkpoint(ckpt).get("hyper_parameters", {})
    arch = [f"--model.{k}={hp[k]}" for k in _ARCH if k in hp and k != "feature_set"]
    if "feature_set" in hp:
        arch.append(f"--data.feature_set={hp['feature_set']}")
    weights = json.dumps({"class_path": "robovae.evaluate.pretrained.PretrainedWeights",
                          "init_args": {"path": str(Path(ckpt).resolve())}})
    specs = []
    for robot in robots:
        train = [n for n in MENAGERIE17 if n != robot]
        ov = [*arch, _names_arg("train_names", train), _names_arg("val_names", [robot]),
              _names_arg("test_names", [robot]), f"--trainer.callbacks+={weights}", *extra]
        slug = robot.replace(" ", "_")
        specs += [RunSpec("finetune", "configs/finetune17.yaml", s,
                          Path(root) / "finetune" / name / slug / f"seed{s}", ov, name, epochs,
                          threads) for s in seeds]
    return specs
