"""Checkpoints written whole or not at all.

Lightning's ``TorchCheckpointIO`` writes a checkpoint through an fsspec transaction whose
temporary file lies in the system's temporary folder; where that is another file system than
the run's (``/tmp`` on tmpfs, runs on a network disk) the commit *copies* the file onto its
destination, truncating the old ``last.ckpt`` first: a run killed or out of disk space in that
copy leaves a torn ``last.ckpt``, and ``--ckpt_path last`` cannot resume from it.
:class:`AtomicCheckpointIO` writes a local checkpoint to a temporary file in the checkpoint's own
folder and renames it onto the destination (:func:`robovae.files.atomic_write`): the old file
stays whole until the new one is. Remote paths (``s3://`` …) go to Lightning's own writer.

Reading, a local file that is not a checkpoint (torn, or another kind of file) is refused in
one line naming it, for every path Lightning resolves itself (``--ckpt_path last`` or ``best``,
which :mod:`robovae.model.cli` cannot check before the trainer runs), where ``torch.load``
ended in a traceback.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from lightning.pytorch.plugins.io import TorchCheckpointIO

from robovae.files import atomic_write
from robovae.model.checkpoint import check_archive, refusal

__all__ = ["AtomicCheckpointIO"]


def _as_read(storage: Any, location: str) -> Any:
    """``torch.load``'s ``map_location`` that leaves a storage where it was read."""
    return storage


class AtomicCheckpointIO(TorchCheckpointIO):
    """``TorchCheckpointIO`` whose local checkpoints are renamed into place (module docstring);
    the same bytes as Lightning's (``torch.save`` of the same dictionary)."""

    def save_checkpoint(self, checkpoint: dict[str, Any], path: str | Path,
                        storage_options: Any | None = None) -> None:
        """Write ``checkpoint`` to ``path``: a local file atomically and durably (fsync'ed).

        Raises:
            OSError: naming ``path``, when it cannot be written (a full disk); the file that
                was there is left as it was.
        """
        if storage_options is not None or "://" in str(path):  # a URL: Lightning's writer
            return super().save_checkpoint(checkpoint, path, storage_options)
        buffer = io.BytesIO()
        torch.save(checkpoint, buffer)
        target = Path(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(target, buffer.getbuffer())

    def load_checkpoint(self, path: str | Path, map_location: Callable | None = _as_read,
                        weights_only: bool | None = None) -> dict[str, Any]:
        """Lightning's read of ``path``, a local file first checked to be a checkpoint
        (``map_location``'s default keeps every tensor where ``torch.load`` reads it: on the
        CPU, as Lightning's default).

        Raises:
            RobovaeError: one line naming ``path``: missing, not a checkpoint, or refused by
                ``torch.load`` (:func:`robovae.model.checkpoint.refusal`).
        """
        if "://" in str(path):
            return super().load_checkpoint(path, map_location, weights_only)
        check_archive(path)
        try:
            return super().load_checkpoint(path, map_location, weights_only)
        except Exception as e:  # a damaged archive: RuntimeError, OSError or an unpickling error
            raise refusal(path, e) from None
