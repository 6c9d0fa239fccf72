"""Euclidean distances between descriptor (or latent) vectors, in bounded memory.

The population statistics (:mod:`robovae.evaluate.population`: MMD², coverage, k-NN entropy)
and the quality report's precision and recall (:mod:`robovae.evaluate.quality.distribution`)
share these. Nothing here imports torch.
"""

from __future__ import annotations

import numpy as np

from robovae.errors import SettingsError, is_integer

__all__ = ["ROWS", "kth_nearest", "sqdist"]

#: Rows of a pairwise block held at once by :func:`kth_nearest` (memory ``ROWS × N`` floats).
ROWS = 512


def sqdist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances ``|a_i|² + |b_j|² − 2 a_i·b_j`` (floored at 0), built in
    place: one ``[len(a), len(b)]`` matrix of memory, no temporaries of its size."""
    d = a @ b.T
    d *= -2.0
    d += (a * a).sum(1)[:, None]
    d += (b * b).sum(1)[None, :]
    return np.maximum(d, 0.0, out=d)


def _neighbour_rank(k: object, n: int) -> bool:
    """Whether ``k`` is a neighbour rank among ``n`` points: an integer in ``[1, n - 1]``."""
    return is_integer(k) and 1 <= int(k) < n


def kth_nearest(x: np.ndarray, k: int) -> np.ndarray:
    """Distance from each row of ``x`` to its ``k``-th nearest other row (``1 <= k < len(x)``),
    in blocks of :data:`ROWS` rows.

    Raises:
        SettingsError: ``k`` outside ``[1, len(x) - 1]``.
    """
    if not _neighbour_rank(k, len(x)):
        raise SettingsError(f"robovae: kth_nearest.k must be an integer in [1, {len(x) - 1}] "
                            f"for {len(x)} points, got {k!r}")
    out = np.empty(len(x))
    for start in range(0, len(x), ROWS):
        block = sqdist(x[start:start + ROWS], x)
        rows = np.arange(block.shape[0])
        block[rows, start + rows] = np.inf  # a point is not its own neighbour
        out[start:start + block.shape[0]] = np.partition(block, k - 1, axis=1)[:, k - 1]
    return np.sqrt(out)  # the square root is monotone: the k-th of the squares is the k-th
