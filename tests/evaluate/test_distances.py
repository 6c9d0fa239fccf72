"""Distances shared by the population statistics and the quality report's precision/recall."""

from __future__ import annotations

import numpy as np

from robovae.evaluate.distances import ROWS, kth_nearest, sqdist
from robovae.evaluate.quality.distribution import knn_radii


def test_sqdist_is_the_squared_euclidean_distance():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(7, 4)), rng.normal(size=(5, 4))
    want = ((a[:, None] - b[None]) ** 2).sum(-1)
    assert np.allclose(sqdist(a, b), want, atol=1e-12)
    assert (sqdist(a, a) >= 0).all()  # rounding never gives a negative square


def test_kth_nearest_excludes_the_point_itself_across_blocks():
    """More rows than one block holds: the k-th nearest other row, as a full sort gives it;
    the quality report's radii are the same distances."""
    rng = np.random.default_rng(1)
    x = rng.normal(size=(ROWS + 37, 3))
    x[5] = x[ROWS + 20]  # a duplicate: its nearest other row is at distance 0
    full = np.sqrt(((x[:, None] - x[None]) ** 2).sum(-1))
    np.fill_diagonal(full, np.inf)
    for k in (1, 3):
        want = np.sort(full, axis=1)[:, k - 1]
        assert np.allclose(kth_nearest(x, k), want, atol=1e-9)
        assert np.allclose(knn_radii(x, k), want, atol=1e-9)
    assert kth_nearest(x, 1)[5] < 1e-6
    assert knn_radii(x[:1], 3).tolist() == [0.0] and len(knn_radii(x[:2], 3)) == 2


def test_a_neighbour_rank_out_of_range_is_refused():
    """``k = 0`` gave every point an infinite radius (precision and recall then read 1.0), ``k``
    beyond the points a NumPy traceback: refused, naming the function and setting."""
    import pytest

    from robovae.errors import SettingsError
    from robovae.evaluate.quality.distribution import precision_recall

    x = np.eye(4)
    for k in (0, 4, 2.5):
        with pytest.raises(SettingsError, match=r"kth_nearest\.k must be an integer in \[1, 3\]"):
            kth_nearest(x, k)
    with pytest.raises(SettingsError, match=r"knn_radii\.k"):
        knn_radii(x, 0)
    with pytest.raises(SettingsError, match=r"precision_recall\.k"):
        precision_recall(x, x, k=0)
    assert knn_radii(x, 10).shape == (4,)  # above the points: capped, as documented
