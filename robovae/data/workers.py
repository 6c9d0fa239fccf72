"""Worker processes of the package (datasets, generation, validation, measures, experiments),
started with ``spawn``.

``fork`` is unsafe here: once the parent has run torch (a dataset already built, a model
loaded), its thread pools hold locks that forked children inherit locked, and the workers
hang for ever in ``futex_wait`` (seen on a 100,000-robot build followed by a second dataset).
``spawn`` starts clean interpreters; they import the worker function's module, so worker
functions live in :mod:`robovae` modules, and a script that starts workers must guard its
entry point with ``if __name__ == "__main__":`` (as every multiprocessing program on macOS and
Windows must).

Used as a context manager, a pool waits for its work when the block ends normally, and stops
at once when it ends with an exception (an error, Ctrl-C, a notebook's interrupt): the work not
yet started is cancelled and the workers busy with the rest are ended (``SIGTERM``, as
Python 3.14's ``ProcessPoolExecutor.terminate_workers``). ``concurrent.futures`` would
otherwise run every queued item first (``robovae gait`` on 30 robots: up to 45 minutes after
the interrupt), and then the items already running, whose results nobody reads (a script's
exit waits for them; in a notebook they hold the cores). The files a worker leaves (robots,
scenes, reports) are written atomically (:func:`robovae.files.atomic_write`), and its scratch
files go with their folder (``robovae optimize``'s ``.work``), so an ended worker leaves no
half-written file.

A worker ends with its parent: killed (``SIGTERM``, ``SIGKILL``, a closed terminal), the
parent runs no clean-up, and its workers would otherwise go on with the robots already sent
to them, orphaned, for as long as those take (minutes for ``robovae gait``).
"""

from __future__ import annotations

import os
import signal
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context, parent_process
from threading import Thread
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from multiprocessing.process import BaseProcess
    from types import TracebackType


class WorkerPool(ProcessPoolExecutor):
    """A :class:`~concurrent.futures.ProcessPoolExecutor` whose ``with`` block, ended by an
    exception, cancels its queued work and ends its busy workers instead of waiting for them
    (:meth:`terminate`; module docstring)."""

    #: How many processes the pool runs (:func:`process_pool`'s, after its cap).
    workers: int = 1

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.shutdown(wait=True)
        else:
            self.terminate()

    def terminate(self) -> None:
        """Stop now: cancel the work not started, send ``SIGTERM`` to every living worker and
        shut the pool down without waiting. The futures of the ended work fail
        (:class:`~concurrent.futures.process.BrokenProcessPool`)."""
        stop = getattr(super(), "terminate_workers", None)  # Python 3.14+: the same
        if stop is not None:
            stop()
            return
        workers = list((self._processes or {}).values())  # shutdown() forgets them
        # the queue's feeder thread may be blocked writing into the pipe to the workers, which
        # will read no more: joined at exit (the queue's finalizer), it hung the process for
        # ever (Ctrl-C in robovae generate: 2 runs of 20); dropped with the process instead
        queue = getattr(self, "_call_queue", None)
        if queue is not None:
            queue.cancel_join_thread()
        self.shutdown(wait=False, cancel_futures=True)
        for process in workers:
            try:
                if process.is_alive():
                    process.terminate()
            except (ValueError, ProcessLookupError):  # closed, or ended meanwhile
                pass


def process_pool(workers: int) -> WorkerPool:
    """A pool of ``workers`` spawned processes, at most one per core (:func:`os.cpu_count`:
    more only share the cores, each with its own imports and memory: ``--jobs 1000`` could
    start a thousand interpreters), each ending as soon as this process ends
    (:func:`exit_with_parent`)."""
    workers = max(1, min(int(workers), os.cpu_count() or 1))
    pool = WorkerPool(workers, mp_context=get_context("spawn"), initializer=exit_with_parent)
    pool.workers = workers
    return pool


def exit_with_parent() -> None:
    """In a worker process: a daemon thread that waits for the parent process's end (its
    sentinel, :meth:`multiprocessing.process.BaseProcess.join`) and then ends this process at
    once (``os._exit(1)``: the work in hand is lost with the parent that asked for it).
    Nothing in a process without a ``multiprocessing`` parent. Ctrl-C is the parent's to
    handle (it ends its workers, :meth:`WorkerPool.terminate`): a worker ignores ``SIGINT``,
    which a terminal sends to every process of the command, instead of printing its own
    ``KeyboardInterrupt`` traceback."""
    parent = parent_process()
    if parent is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        Thread(target=_end_after, args=(parent,), name="robovae-exit-with-parent",
               daemon=True).start()


def _end_after(parent: BaseProcess) -> None:
    parent.join()
    os._exit(1)
