"""Worker processes of the package (datasets, generation, validation, measures, experiments),
started with ``spawn``.

``fork`` is unsafe here: once the parent has run torch (a dataset already built, a model
loaded), its thread pools hold locks that forked children inherit locked, and the workers
hang for ever in ``futex_wait`` (seen on a 100,000-robot build followed by a second dataset).
``spawn`` starts clean interpreters; they import the worker function's module, so worker
functions live in :mod:`robovae` modules, and a script that starts workers must guard its
entry point with ``if __name__ == "__main__":`` (as every multiprocessing program on macOS and
Windows must).
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context


def process_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` spawned processes."""
    return ProcessPoolExecutor(workers, mp_context=get_context("spawn"))
