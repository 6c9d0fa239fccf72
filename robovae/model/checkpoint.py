"""Loading checkpoints safely.

Checkpoints are read with ``torch.load(weights_only=True)``: tensors, numbers, strings and
containers only, never arbitrary pickled objects, so a checkpoint cannot run code when it is
loaded. A file that needs more than that is refused with one line.

The same rule holds for the Lightning CLI (``robovae fit|validate|test|predict --ckpt_path``):
:mod:`robovae.model.cli` checks the file with :func:`read_checkpoint` before Lightning reads
it, and passes ``weights_only=True`` to the trainer (Lightning's own default, ``None``, defers to
``torch.load``, which an environment variable can turn into full unpickling).
"""

from __future__ import annotations

import copy
import os
import re
import zipfile
from pathlib import Path

import torch

from robovae.errors import RobovaeError
from robovae.model.vae import RoboVAE


def refusal(path: str | Path | None, e: BaseException) -> RobovaeError:
    """The one-line error of a checkpoint ``torch.load(weights_only=True)`` refused with ``e``
    (for a planted object: the global it names, e.g. ``GLOBAL posix.system``)."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(e))
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    found = re.search(r"GLOBAL ([\w.]+)", text)
    if found:  # torch names the global it would have had to import
        reason = f"it holds a pickled object, not plain weights: GLOBAL {found.group(1)}"
    elif "Weights only load failed" in text:
        tail = [ln.strip() for ln in text.partition("WeightsUnpickler error:")[2].splitlines()
                if ln.strip()]
        reason = "not a weights-only checkpoint" + (f": {tail[0].rstrip('.')}" if tail else "")
    else:
        reason = lines[0].split(". ")[0].rstrip(".") if lines else type(e).__name__
    where = f" {path}:" if path is not None else ""
    return RobovaeError(f"robovae:{where} refused to load checkpoint ({reason})")


def check_archive(path: str | os.PathLike[str]) -> Path:
    """``path`` as a ``Path``, when it is a file with the zip archive ``torch.save`` writes.

    Raises:
        RobovaeError: missing file, or another kind of file (a torn checkpoint among them).
    """
    path = Path(path)
    if not path.is_file():
        raise RobovaeError(f"robovae: {path}: no such checkpoint")
    if not zipfile.is_zipfile(path):  # torch.save has written zip archives since torch 1.6
        raise RobovaeError(f"robovae: {path}: not a checkpoint (not a zip archive: another "
                           "kind of file, or one cut short)")
    return path


def read_checkpoint(path: str | os.PathLike[str]) -> dict:
    """The contents of a checkpoint file, read with ``torch.load(weights_only=True)``.

    Raises:
        RobovaeError: missing file, not a checkpoint, or a checkpoint that holds anything but
            tensors, numbers, strings and containers (no pickled object is ever built).
    """
    path = check_archive(path)
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # UnpicklingError for planted objects, RuntimeError for bad zips
        raise refusal(path, e) from None
    if not isinstance(ckpt, dict):
        raise RobovaeError(f"robovae: {path}: not a Lightning checkpoint "
                           f"(a {type(ckpt).__name__})")
    return ckpt


#: hyperparameters of earlier versions: the value the current model has built in (a checkpoint
#: with another value holds a removed model variant), or ``None`` for training-only settings
#: that moved to the datamodule (``data:``) and do not change the weights
RETIRED_HPARAMS: dict[str, object] = {
    "topo_context": True, "node_structure": True, "local_heads": True, "latent_inputs": False,
    "decoder_inputs": "types", "augment_until": None, "feature_shift": None,
    "feature_noise": None, "tree_surgery": None, "surgery_ops": None,
}


def current_hparams(hparams: dict, path: str | Path | None = None) -> dict:
    """The constructor arguments of :class:`RoboVAE` from a checkpoint's hyperparameters,
    written by this version or an earlier one: retired settings (:data:`RETIRED_HPARAMS`) are
    dropped when the model they describe is the current one.

    Raises:
        RobovaeError: (one line) the checkpoint holds a model variant this version no longer
            has (e.g. ``local_heads=False`` or no node latents); it says how to retrain.
    """
    hp = dict(hparams)
    bad = [f"{k}={hp[k]!r}" for k, v in RETIRED_HPARAMS.items()
           if v is not None and k in hp and hp[k] != v]
    if "node_latent_dim" in hp and int(hp["node_latent_dim"]) < 1:
        bad.append(f"node_latent_dim={hp['node_latent_dim']!r}")
    if bad:
        where = f" {path}:" if path is not None else ""
        raise RobovaeError(f"robovae:{where} a checkpoint of a model variant that was removed "
                           f"({', '.join(bad)}); retrain it with the current configs, e.g. "
                           "`robovae fit --config configs/zoo.yaml`")
    # (``_instantiator`` and other ``_`` keys: Lightning CLI bookkeeping, not arguments)
    return {k: v for k, v in hp.items() if k not in RETIRED_HPARAMS and not k.startswith("_")}


def check_current_model(ckpt: dict, path: str | Path | None = None) -> None:
    """Refuse a checkpoint of the model before the tree latent (its node latents carried the
    tree; it has no ``tree_encoder``): its weights cannot be read into the current model.

    Raises:
        RobovaeError: one line that says how to retrain.
    """
    state = ckpt.get("state_dict", {})
    if state and not any(k.startswith("tree_encoder.") for k in state):
        where = f" {path}:" if path is not None else ""
        raise RobovaeError(f"robovae:{where} a checkpoint of the earlier model whose node "
                           "latents carried the tree (no tree latent z_T); retrain it with the "
                           "current configs, e.g. `robovae fit --config configs/default.yaml`")


def load_model(path: str | os.PathLike[str], map_location: str | torch.device = "cpu"
               ) -> RoboVAE:
    """A :class:`RoboVAE` in eval mode from a Lightning checkpoint (``weights_only`` loading),
    also from a checkpoint of an earlier version whose model is the current one
    (:func:`current_hparams`).

    Raises:
        RobovaeError: missing file, a checkpoint that is not plain weights + settings, or one of
            a removed model variant or of the model before the tree latent (one line each).
    """
    path = Path(path)
    ckpt = read_checkpoint(path)  # the same one-line refusals everywhere
    if "state_dict" not in ckpt:
        raise RobovaeError(f"robovae: {path}: not a Lightning checkpoint (no state_dict)")
    hp = current_hparams(ckpt.get("hyper_parameters", {}), path)
    check_current_model(ckpt, path)
    try:
        model = RoboVAE(**hp)
        model.on_load_checkpoint(ckpt)  # first, as Lightning does: it may complete the weights
        model.load_state_dict(ckpt["state_dict"])
    except Exception as e:  # weights of another model (shapes, names), bad hyperparameters
        raise refusal(path, e) from None
    return model.to(map_location).eval()


def own_model(model: RoboVAE | str | os.PathLike[str]) -> RoboVAE:
    """A model the caller may change (e.g. turn into float64): a deep copy of a given
    :class:`RoboVAE`, never the object itself, or :func:`load_model` of a checkpoint path."""
    return copy.deepcopy(model) if isinstance(model, RoboVAE) else load_model(model)
