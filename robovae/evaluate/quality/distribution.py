"""Population-level comparisons: 1-D Wasserstein distances with a split-half reference, and
k-NN precision and recall.

**Wasserstein-1** between two samples of one scalar (equal weights per point),

    W1(a, b) = ∫ |F_a(x) − F_b(x)| dx,

computed exactly from the two empirical CDFs on the sorted union of the values (same units as
the values). :func:`split_half` is the distance a corpus has *to itself*: the mean W1 between
two random halves over ``repeats`` seeded splits; a sample population whose distance to the
corpus is near this reference is as close as the corpus's own sampling noise allows.

**Precision and recall** (Kynkäänniemi et al., 2019, "Improved precision and recall metric for
assessing generative models"): with ``r_k(x)`` the distance from a point of a set to its k-th
nearest neighbour in that set (itself excluded), a set's manifold is the union of the balls
``B(x, r_k(x))``. Precision is the share of samples that fall in the reference's manifold
(samples look like reference robots), recall the share of reference points in the samples'
manifold (the reference is covered). Points are descriptor vectors (Euclidean distance); the
caller standardises them (:func:`robovae.evaluate.population.standardize`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robovae.errors import check_seed
from robovae.evaluate.distances import kth_nearest, sqdist
from robovae.settings import check_settings, integer

__all__ = ["knn_radii", "precision_recall", "split_half", "wasserstein_1d"]


def wasserstein_1d(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> float:
    """W1 between two samples (module docstring); NaNs are dropped.

    Raises:
        ValueError: a sample is empty (after dropping NaNs).
    """
    sa = np.sort(np.asarray(a, dtype=float).ravel())
    sb = np.sort(np.asarray(b, dtype=float).ravel())
    sa, sb = sa[~np.isnan(sa)], sb[~np.isnan(sb)]
    if not sa.size or not sb.size:
        raise ValueError("wasserstein_1d: empty sample")
    x = np.concatenate([sa, sb])
    x.sort()
    fa = np.searchsorted(sa, x[:-1], side="right") / sa.size
    fb = np.searchsorted(sb, x[:-1], side="right") / sb.size
    return float(np.sum(np.abs(fa - fb) * np.diff(x)))


def split_half(x: Sequence[float] | np.ndarray, repeats: int = 20, seed: int = 0) -> float:
    """Mean W1 between two random halves of ``x`` over ``repeats`` splits (seeded); NaN below
    two values.

    Raises:
        SettingsError: ``repeats`` below 1, ``seed`` outside ``[0, 2**31 - 1]``.
    """
    check_settings("split_half", repeats=(repeats, integer(1)))
    check_seed(seed, "split_half seed")
    v = np.asarray(x, dtype=float).ravel()
    v = v[~np.isnan(v)]
    if v.size < 2:
        return float("nan")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(repeats):
        p = rng.permutation(v.size)
        h = v.size // 2
        out.append(wasserstein_1d(v[p[:h]], v[p[h:]]))
    return float(np.mean(out))


def knn_radii(x: np.ndarray, k: int = 3) -> np.ndarray:
    """Distance from each row of ``x`` to its k-th nearest other row (``k`` capped at
    ``len(x) - 1``; a single point gets radius 0).

    Raises:
        SettingsError: ``k`` below 1.
    """
    check_settings("knn_radii", k=(k, integer(1)))
    n = len(x)
    if n < 2:
        return np.zeros(n)
    return kth_nearest(np.asarray(x, dtype=float), min(k, n - 1))


def precision_recall(reference: np.ndarray, samples: np.ndarray, k: int = 3
                     ) -> tuple[float, float]:
    """``(precision, recall)`` of ``samples`` ``[m, d]`` against ``reference`` ``[n, d]``
    (module docstring); NaN for an empty set.

    Raises:
        ValueError: the two sets have different widths.
        SettingsError: ``k`` below 1.
    """
    check_settings("precision_recall", k=(k, integer(1)))
    reference, samples = np.atleast_2d(reference), np.atleast_2d(samples)
    if reference.shape[1] != samples.shape[1]:
        raise ValueError(f"precision_recall: {reference.shape[1]} and {samples.shape[1]} "
                         "descriptor columns")
    if not len(reference) or not len(samples):
        return float("nan"), float("nan")
    d = np.sqrt(sqdist(samples, reference))  # [m, n]
    r_ref, r_samples = knn_radii(reference, k), knn_radii(samples, k)
    precision = float(np.mean((d <= r_ref[None]).any(1)))  # sample in a reference ball
    recall = float(np.mean((d <= r_samples[:, None]).any(0)))  # reference in a sample ball
    return precision, recall
