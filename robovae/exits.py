"""How a ``robovae`` command ends when it does not end well: one line, never a traceback.

- a usage error or bad input: a :class:`~robovae.errors.RobovaeError`, exit status 2;
- a disk that fills up or turns read-only while the run writes (:data:`DISK_ERRORS`): exit
  status 1, the file named;
- Ctrl-C (:func:`interrupted`): exit status :data:`INTERRUPTED`;
- robovae's own warnings print as their one line (:func:`one_line_warnings`).
"""

from __future__ import annotations

import contextlib
import errno
import threading
import warnings
from collections.abc import Iterator
from concurrent.futures import InvalidStateError

__all__ = ["DISK_ERRORS", "INTERRUPTED", "interrupted", "one_line_warnings",
           "quiet_after_interrupt"]


#: Errors of the disk a run writes to, not of the run: said in one line, exit status 1.
DISK_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG})


@contextlib.contextmanager
def one_line_warnings() -> Iterator[None]:
    """robovae's own warnings (``robovae: ...``) print as their one line, not with Python's
    second line of source; other warnings as Python prints them."""
    python_format = warnings.formatwarning

    def fmt(message: Warning | str, category: type[Warning], filename: str, lineno: int,
            line: str | None = None) -> str:
        if str(message).startswith("robovae"):
            return f"{message}\n"
        return python_format(message, category, filename, lineno, line)

    warnings.formatwarning = fmt
    try:
        yield
    finally:
        warnings.formatwarning = python_format


def interrupted(e: BaseException | None) -> bool:
    """``e`` is Ctrl-C's ``KeyboardInterrupt``, or an error it caused: an extension module
    interrupted in its import raises ``ImportError: initialization failed`` from it."""
    seen: set[int] = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def quiet_after_interrupt(args: threading.ExceptHookArgs) -> None:
    """After Ctrl-C, a worker pool's manager thread may still fail on the futures the
    interrupt cancelled (Python 3.11's ``ProcessPoolExecutor`` sets an error on a cancelled
    future: ``InvalidStateError``); the run is over, so that is not printed. Other errors of
    threads are, as Python prints them."""
    if not issubclass(args.exc_type, InvalidStateError):
        threading.__excepthook__(args)


#: Exit status of a run ended by Ctrl-C (the shells' 128 + SIGINT).
INTERRUPTED = 130


