"""Numbers as MJCF output writes them, so a spec and its written file hold the same values.

``MjSpec.to_xml`` writes every number with 6 significant digits (``%g``) and drops vector
components 12 decades below the vector's largest one. The writer rounds values this way
**before** they enter the spec (:func:`mjcf_round`, :func:`mjcf_round_vector`); constraints that
rounding can break are re-established on the rounded values (:func:`rounded_inertia` for the
triangle inequality of principal inertias).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = ["mjcf_round", "mjcf_round_groups", "mjcf_round_rows", "mjcf_round_up",
           "mjcf_round_vector", "mjcf_round_vectors", "rounded_inertia"]


def mjcf_round(v: float) -> float:
    """``v`` at the 6 significant digits ``MjSpec.to_xml`` writes; ``|v| < 1e-16`` → 0;
    NaN/±Inf unchanged."""
    v = float(v)
    if not math.isfinite(v) or abs(v) < 1e-16:
        return v if not math.isfinite(v) else 0.0
    return float(f"{v:.6g}")


def mjcf_round_vector(vec: npt.ArrayLike) -> list[float]:
    """A vector as written: each component :func:`mjcf_round`-ed, components with
    ``|a| ≤ 1e-12 · max |a|`` set to 0."""
    if isinstance(vec, np.ndarray):
        arr = vec.astype(float, copy=False).ravel().tolist()
    elif isinstance(vec, list | tuple):
        arr = [float(a) for a in vec]
    else:
        arr = [float(a) for a in np.asarray(vec, dtype=float).ravel()]
    if arr and math.isfinite(sum(arr)):  # every component finite (the usual case)
        tiny = 1e-12 * max(map(abs, arr))
        return [0.0 if abs(a) <= tiny or abs(a) < 1e-16 else float(f"{a:.6g}") for a in arr]
    big = max((abs(a) for a in arr if math.isfinite(a)), default=0.0)
    return [0.0 if math.isfinite(a) and abs(a) <= 1e-12 * big else mjcf_round(a) for a in arr]


def mjcf_round_vectors(a: np.ndarray, starts: np.ndarray) -> list[list[float]]:
    """:func:`mjcf_round_vector` of every group of columns ``a[r, starts[k]:starts[k + 1]]`` of
    every row (the last group to the end; ``starts[0] == 0``), the very same values, with one
    pass over the numbers instead of a call per vector: rows of concatenated vectors (e.g.
    a geom's size, pos and quat) in, rows of rounded numbers out."""
    a = np.asarray(a, dtype=float)
    if not np.isfinite(a).all():  # NaN/Inf: the per-vector rules
        return [sum((mjcf_round_vector(g) for g in np.split(row, starts[1:])), [])
                for row in a]
    zero = _negligible(a, starts).tolist()
    return [[0.0 if z else float(f"{v:.6g}") for v, z in zip(row, zrow)]
            for row, zrow in zip(a.tolist(), zero)]


def _negligible(a: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Boolean ``a.shape``: the finite components that MJCF output writes as 0, those with
    ``|a| <= 1e-12 · max |a|`` over their group of columns (``starts``, as in
    :func:`mjcf_round_groups`) or ``|a| < 1e-16``."""
    fin = np.isfinite(a)
    mag = np.where(fin, np.abs(a), 0.0)
    width = np.diff(np.append(starts, a.shape[1]))
    big = np.repeat(np.maximum.reduceat(mag, starts, axis=1), width, axis=1)
    return fin & ((mag <= 1e-12 * big) | (mag < 1e-16))


def mjcf_round_rows(a: np.ndarray) -> np.ndarray:
    """Every row of a 2-D array rounded as :func:`mjcf_round_vector` rounds a vector, in one
    vectorised pass (for a whole feature matrix at once).

    A component ``a`` with decimal exponent ``e`` becomes ``round(a · 10^(5-e)) / 10^(5-e)``,
    the double nearest to a 6-digit decimal, which MJCF output writes and reads back exactly (in
    rare ties it may pick the other neighbour than ``%.6g``: both are written exactly).
    """
    a = np.asarray(a, dtype=float)
    fin = np.isfinite(a)
    big = np.where(fin, np.abs(a), 0.0).max(axis=1, initial=0.0)[:, None]
    out = a.copy()
    zero = fin & ((np.abs(a) <= 1e-12 * big) | (np.abs(a) < 1e-16))
    out[zero] = 0.0
    live = fin & ~zero
    if live.any():
        out[live] = _round6(a[live])
    return out


def mjcf_round_groups(a: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """:func:`mjcf_round_rows` of every group of columns ``a[:, starts[k]:starts[k + 1]]``
    (the last to the end; ``starts[0] == 0``), in one vectorised pass: a feature matrix rounded
    feature by feature, each feature's row a vector. The same values as one
    :func:`mjcf_round_rows` call per group."""
    a = np.asarray(a, dtype=float)
    if a.size == 0:
        return a.copy()
    fin = np.isfinite(a)
    out = a.copy()
    zero = _negligible(a, starts)
    out[zero] = 0.0
    live = fin & ~zero
    if live.any():
        out[live] = _round6(a[live])
    return out


def _round6(x: np.ndarray) -> np.ndarray:
    """Non-zero finite values to 6 significant digits (see :func:`mjcf_round_rows`)."""
    m = 5 - np.floor(np.log10(np.abs(x))).astype(np.int64)
    for _ in range(2):  # log10 can be one off next to a power of ten
        k = np.abs(x * 10.0 ** m.astype(float))
        m = np.where(k >= 999999.5, m - 1, np.where(k < 99999.5, m + 1, m))
    up = m >= 0
    out = np.empty_like(x)
    p = 10.0 ** np.abs(m).astype(float)
    out[up] = np.round(x[up] * p[up]) / p[up]
    out[~up] = np.round(x[~up] / p[~up]) * p[~up]
    return out


def mjcf_round_up(v: float) -> float:
    """The smallest 6-significant-digit number ≥ ``v``."""
    q = mjcf_round(v)
    step = 1e-6
    while q < v:
        q = mjcf_round(v * (1.0 + step) if v > 0 else v * (1.0 - step))
        step *= 2.0
    return q


def rounded_inertia(inertia: npt.ArrayLike) -> tuple[list[float], bool]:
    """A diagonal inertia as written that still satisfies ``a + b ≥ c`` for every permutation.

    The vector is :func:`mjcf_round_vector`-ed; while the two smaller components ``a ≤ b`` fall
    short of the largest ``c``, each is raised by half the deficit plus ``1e-6 c`` and rounded
    up (:func:`mjcf_round_up`), at most 20 times.

    Returns:
        The written components and whether they had to move for the inequality.
    """
    out = mjcf_round_vector(inertia)
    moved = False
    for _ in range(20):
        a, b, c = sorted(out)
        if a + b >= c:
            break
        order = np.argsort(out, kind="stable")
        deficit = c - a - b
        for k in order[:2]:
            out[k] = mjcf_round_up(out[k] + 0.5 * deficit + 1e-6 * c)
        moved = True
    return out, moved
