"""Loading checkpoints safely.

Checkpoints are read with ``torch.load(weights_only=True)``: tensors, numbers, strings and
containers only, never arbitrary pickled objects, so a checkpoint cannot run code when it is
loaded. A file that needs more than that is refused with one line.
"""

from __future__ import annotations

from pathlib import Path

import torch

from robovae.errors import RobovaeError
from robovae.model.vae import RoboVAE


def load_model(path: str | Path, map_location: str | torch.device = "cpu") -> RoboVAE:
    """A :class:`RoboVAE` in eval mode from a Lightning checkpoint (``weights_only`` loading).

    Raises:
        RobovaeError: missing file, or a checkpoint that is not plain weights + settings.
    """
    path = Path(path)
    if not path.is_file():
        raise RobovaeError(f"robovae: {path}: no such checkpoint")
    try:
        model = RoboVAE.load_from_checkpoint(path, map_location=map_location, weights_only=True)
    except Exception as e:  # UnpicklingError for planted objects, RuntimeError for bad zips
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise RobovaeError(f"robovae: {path}: refused to load checkpoint ({first})") from None
    return model.eval()
