"""Which checkpoints a model can load: the settings that shape its weights, and a one-line
refusal of a checkpoint of another model (:func:`check_architecture`, called by
:meth:`RoboVAE.on_load_checkpoint <robovae.model.vae.RoboVAE.on_load_checkpoint>` whenever
Lightning restores one: ``--ckpt_path FILE``, ``--ckpt_path last``, ``Trainer.fit(...,
ckpt_path=...)``)."""

from __future__ import annotations

import os

import torch

from robovae.errors import RobovaeError

__all__ = ["ARCHITECTURE", "check_architecture"]


#: The settings that shape a model's weights: a checkpoint loads only into a model built with
#: its values of these.
ARCHITECTURE = ("feature_set", "hidden_dim", "latent_dim", "tree_latent_dim", "node_latent_dim",
                "feature_layers", "prior_components")


def check_architecture(ckpt: dict, model: torch.nn.Module, path: str | os.PathLike | None = None
                       ) -> None:
    """Refuse to load ``ckpt`` into ``model`` when their weights differ in name or shape (a
    checkpoint given with another config's model settings: ``robovae fit --config
    configs/tiny.yaml --ckpt_path <default model>`` was a traceback listing every mismatched
    tensor).

    Raises:
        RobovaeError: one line naming the checkpoint and the :data:`ARCHITECTURE` settings
            whose values differ (or how many weights do, when none of those).
    """
    state, own = ckpt.get("state_dict") or {}, model.state_dict()
    differ = sorted(k for k in state.keys() | own.keys() if k not in state or k not in own
                    or tuple(state[k].shape) != tuple(own[k].shape))
    if not state or not differ:
        return
    theirs, ours = ckpt.get("hyper_parameters") or {}, getattr(model, "hparams", {})
    what = ", ".join(f"{k} {theirs.get(k)!r} in the checkpoint, {ours.get(k)!r} here"
                     for k in ARCHITECTURE if theirs.get(k) != ours.get(k))
    where = f" {path}:" if path is not None else ""
    raise RobovaeError(f"robovae:{where} a checkpoint of another model "
                       f"({what or f'{len(differ)} weights of other names or shapes'}); build "
                       "the model with the settings it was trained with (its config, or "
                       "robovae.model.checkpoint.load_model)")
