"""Files written whole or not at all.

:func:`atomic_write` puts text into a temporary file beside its destination and moves it into
place with ``os.replace``: a reader (or a run continued after a crash) sees the old file or the
new one, never half of one. Robot files, scene files, procedural robots, reports and
optimisation logs are written with it.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write"]


def atomic_write(path: str | os.PathLike, text: str, durable: bool = True) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns ``path``.

    The temporary file is ``.<name>.<pid>.tmp`` in ``path``'s folder, created exclusively with
    mode 0600 (as ``tempfile.mkstemp`` would, at a third of its CPU cost; if that name is taken,
    by a crashed writer of the same pid, ``mkstemp`` picks another), fsync'ed when ``durable``
    (callers that sync a whole batch at once, e.g. with ``os.sync``, may skip it), then moved
    onto ``path``. On any error the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    tmp = str(path.parent / f".{path.name}.{os.getpid()}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        try:
            data = text.encode("utf-8")
            while data:
                data = data[os.write(fd, data):]
            if durable:
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
