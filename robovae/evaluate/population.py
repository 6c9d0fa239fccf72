"""Statistics of robot populations (paper §6.2): how two populations' descriptors differ, and
how spread out a population's latent codes are.

A *population* is a list of robot graphs — the training robots of a checkpoint, a folder of
generated robots, any dataset — summarised by the descriptor records of
:mod:`robovae.evaluate.descriptors`.

Comparing two populations (:func:`compare`):

- **KL** per descriptor: ``KL(train ‖ samples)`` (nats) between histograms on shared bins (unit
  bins for counts, 10 equal bins of the transformed value otherwise) with 0.5 added to every bin
  (Jeffreys prior) so that empty bins stay finite. The sum over descriptors is a sum of
  marginal KLs, not a joint KL.
- **MMD²** (unbiased) with an RBF kernel on descriptor vectors standardised by the training
  mean and std (mass and lengths log-transformed first; NaN → training median), bandwidth
  the median pairwise distance of the pooled vectors, and a permutation p-value.
- **coverage**: share of training robots that have a sample within distance ``t`` in that
  standardised space; ``t`` defaults to the median nearest-neighbour distance among the
  training robots (a sample "covers" a robot when it is as close as a typical training
  neighbour). ``precision`` is the reverse: share of samples within ``t`` of a training robot.

Latent statistics (:func:`latent_stats`) of a population's encoded means ``mu``:

- **Gaussian entropy** ``½ log det(2πe Σ)`` (nats) of the Ledoit–Wolf shrunk covariance (full
  rank even with fewer robots than latent dimensions, so populations of any size compare);
- **k-NN entropy** (Kozachenko–Leonenko, :func:`knn_entropy`);
- **effective dimensionality**: participation ratio ``(Σλ)² / Σλ²`` of the PCA eigenvalues
  (1 when one direction holds all the variance, ``d`` when all are equal).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from robovae.errors import check_seed
from robovae.evaluate.descriptors import (
    COUNT_DESCRIPTORS,
    DESCRIPTORS,
    LOG_DESCRIPTORS,
    VECTOR_DESCRIPTORS,
    descriptor_table,
)
from robovae.evaluate.distances import kth_nearest, sqdist
from robovae.settings import check_settings, integer, number

__all__ = ["compare", "coverage", "gaussian_entropy", "histogram_kl", "knn_entropy",
           "latent_stats", "ledoit_wolf", "mmd_rbf", "participation_ratio", "pca", "standardize",
           "summary"]


def _transform(values: np.ndarray, names: Sequence[str]) -> np.ndarray:
    out = values.astype(float).copy()
    for j, n in enumerate(names):
        if n in LOG_DESCRIPTORS:
            out[:, j] = np.log10(np.maximum(out[:, j], 0.0) + 1e-6)
    return out


def standardize(train: np.ndarray, *others: np.ndarray, names: Sequence[str]
                ) -> list[np.ndarray]:
    """Log-transform (:data:`LOG_DESCRIPTORS`), fill NaN with the training median, standardise
    with the training mean/std (std 0 → 1). Returns ``[train, *others]`` transformed."""
    t = _transform(train, names)
    med = np.zeros(t.shape[1])
    for j in range(t.shape[1]):
        col = t[:, j][~np.isnan(t[:, j])]
        med[j] = float(np.median(col)) if col.size else 0.0

    def fill(a: np.ndarray) -> np.ndarray:
        a = _transform(a, names)
        return np.where(np.isnan(a), med, a)

    t = fill(train)
    mean, std = t.mean(0), t.std(0)
    std = np.where(std > 1e-12, std, 1.0)
    return [(a - mean) / std for a in (t, *[fill(o) for o in others])]


def summary(records: Sequence[dict], names: Sequence[str] = DESCRIPTORS) -> dict:
    """Per-descriptor ``mean``, ``std``, ``median``, ``min``, ``max`` and count of defined
    values (NaN ignored)."""
    x = descriptor_table(records, names)
    out = {}
    for j, n in enumerate(names):
        v = x[:, j][~np.isnan(x[:, j])]
        out[n] = ({"mean": float(v.mean()), "std": float(v.std()), "median": float(np.median(v)),
                   "min": float(v.min()), "max": float(v.max()), "n": int(v.size)} if v.size
                  else {"mean": math.nan, "std": math.nan, "median": math.nan, "min": math.nan,
                        "max": math.nan, "n": 0})
    return out


# ----------------------------------------------------------------------------------------------
# divergences between populations


#: rules of :func:`histogram_kl`'s settings (its ``integer`` argument hides the rule's name)
_BINS, _POSITIVE = integer(1), number(0, low_open=True)


def histogram_kl(p: Sequence[float], q: Sequence[float], bins: int | np.ndarray = 10,
                 integer: bool = False, log: bool = False, pseudo: float = 0.5) -> float:
    """``KL(P ‖ Q)`` (nats) of two samples of one scalar, from histograms on shared bins.

    Bins: unit bins centred on the integers (``integer``, at most 50, wider beyond), else
    ``bins`` equal-width bins over the pooled range (of ``log10`` values with ``log``). NaNs are
    dropped; ``pseudo`` is added to every bin count (0.5: Jeffreys prior). NaN when either
    sample is empty.

    Raises:
        SettingsError: ``bins`` (an integer) below 1, ``pseudo`` not a number > 0.
    """
    check_settings("histogram_kl", pseudo=(pseudo, _POSITIVE),
                   **({} if isinstance(bins, np.ndarray) else {"bins": (bins, _BINS)}))
    a = np.asarray(p, dtype=float)
    b = np.asarray(q, dtype=float)
    a, b = a[~np.isnan(a)], b[~np.isnan(b)]
    if not a.size or not b.size:
        return math.nan
    if log:
        a, b = np.log10(np.maximum(a, 0) + 1e-6), np.log10(np.maximum(b, 0) + 1e-6)
    lo, hi = min(a.min(), b.min()), max(a.max(), b.max())
    if isinstance(bins, np.ndarray):
        edges = bins
    elif integer:
        step = max(1.0, math.ceil((hi - lo + 1) / 50))
        edges = np.arange(math.floor(lo) - 0.5, math.ceil(hi) + 0.5 + step, step)
    else:
        edges = np.linspace(lo, hi if hi > lo else lo + 1.0, int(bins) + 1)
    ha = np.histogram(np.clip(a, edges[0], edges[-1]), edges)[0] + pseudo
    hb = np.histogram(np.clip(b, edges[0], edges[-1]), edges)[0] + pseudo
    pa, pb = ha / ha.sum(), hb / hb.sum()
    return float(np.sum(pa * np.log(pa / pb)))


def _median_distance(d2: np.ndarray) -> float:
    """Median of the distances above the diagonal of a square matrix of squared distances,
    gathered row by row into one buffer (half the matrix) instead of through index arrays."""
    n = len(d2)
    buf = np.empty(n * (n - 1) // 2)
    pos = 0
    for i in range(n - 1):
        buf[pos:pos + n - 1 - i] = d2[i, i + 1:]
        pos += n - 1 - i
    np.sqrt(buf, out=buf)
    return float(np.median(buf, overwrite_input=True))


#: Permutations of the MMD test evaluated per matrix product (memory ``N × BATCH`` floats).
BATCH = 64


def mmd_rbf(x: np.ndarray, y: np.ndarray, bandwidth: float | None = None,
            permutations: int = 200, seed: int = 0) -> dict:
    """Unbiased ``MMD²`` between samples ``x`` ``[n, d]`` and ``y`` ``[m, d]`` with the RBF
    kernel ``exp(-|a-b|² / (2 h²))``.

    ``h`` defaults to the median pairwise distance of the pooled points. The p-value is the
    share of ``permutations`` random relabellings of the pooled points whose MMD² is at least
    the observed one (``(1 + count) / (1 + permutations)``; NaN with 0 permutations).
    Each statistic comes from the block sums of the kernel matrix ``K`` (zero diagonal):
    ``S_XX = 1_Xᵀ K 1_X``, ``S_XY = 1_Yᵀ K 1_X``, ``S_YY = ΣK − S_XX − 2 S_XY``, and
    ``MMD² = S_XX / n(n−1) + S_YY / m(m−1) − 2 S_XY / nm``: the permutations cost one product
    ``K V`` per :data:`BATCH` of them, and memory stays at the one ``(n + m)²`` matrix.

    Returns ``{"mmd2", "bandwidth", "p_value"}``.

    Raises:
        SettingsError: ``bandwidth`` not a number > 0 (or None), ``permutations`` negative,
            ``seed`` outside ``[0, 2**31 - 1]``.
    """
    check_settings("mmd_rbf", bandwidth=(bandwidth, number(0, low_open=True).or_none()),
                   permutations=(permutations, integer(0)))
    check_seed(seed, "mmd_rbf seed")
    x, y = np.asarray(x, float), np.asarray(y, float)
    n, m = len(x), len(y)
    if n < 2 or m < 2:
        return {"mmd2": math.nan, "bandwidth": math.nan, "p_value": math.nan}
    z = np.concatenate([x, y])
    k = sqdist(z, z)  # the one [n + m]² matrix: squared distances, then the kernel in place
    if bandwidth is None:
        med = _median_distance(k)
        bandwidth = med if med > 0 else 1.0
    k /= -(2.0 * bandwidth ** 2)
    np.exp(k, out=k)
    np.fill_diagonal(k, 0.0)
    total = k.sum()

    def stats(in_x: np.ndarray) -> np.ndarray:
        """MMD² of each column's split (``in_x`` ``[n + m, P]``: 1 for the x side) from the
        kernel's sums over the blocks: ``1_Xᵀ K 1_X``, ``1_Yᵀ K 1_X`` and the rest."""
        kx = k @ in_x
        sxx = np.einsum("ip,ip->p", in_x, kx)
        sxy = kx.sum(0) - sxx
        syy = total - sxx - 2.0 * sxy
        return sxx / (n * (n - 1)) + syy / (m * (m - 1)) - 2.0 * sxy / (n * m)

    split = np.zeros((n + m, 1))
    split[:n] = 1.0
    observed = float(stats(split)[0])
    p = math.nan
    if permutations > 0:
        rng = np.random.default_rng(seed)
        hits = 0
        for start in range(0, permutations, BATCH):
            cols = np.zeros((n + m, min(BATCH, permutations - start)))
            for c in range(cols.shape[1]):
                cols[rng.permutation(n + m)[:n], c] = 1.0
            hits += int(np.sum(stats(cols) >= observed))
        p = (1 + hits) / (1 + permutations)
    return {"mmd2": observed, "bandwidth": float(bandwidth), "p_value": p}


def coverage(train: np.ndarray, samples: np.ndarray, threshold: float | None = None) -> dict:
    """Share of training points with a sample within ``threshold`` (Euclidean), and of samples
    with a training point within it (``precision``).

    ``threshold`` defaults to the median nearest-neighbour distance among the training points.
    Returns ``{"coverage", "precision", "threshold", "mean_nearest_sample"}``.

    Raises:
        SettingsError: ``threshold`` not a number >= 0 (or None).
    """
    check_settings("coverage", threshold=(threshold, number(0).or_none()))
    train, samples = np.asarray(train, float), np.asarray(samples, float)
    if len(train) == 0 or len(samples) == 0:
        return {"coverage": math.nan, "precision": math.nan, "threshold": math.nan,
                "mean_nearest_sample": math.nan}
    if threshold is None:
        threshold = (float(np.median(kth_nearest(train, 1)))
                     if len(train) >= 2 else 1.0)
    d = np.sqrt(sqdist(train, samples))
    nearest_sample = d.min(1)
    nearest_train = d.min(0)
    return {"coverage": float((nearest_sample <= threshold).mean()),
            "precision": float((nearest_train <= threshold).mean()),
            "threshold": float(threshold),
            "mean_nearest_sample": float(nearest_sample.mean())}


#: Most training robots :func:`compare` puts into MMD² and coverage: their pairwise matrices
#: grow with the square (40,000 robots: 13 GB per matrix of float64).
MAX_REFERENCE = 10_000


def compare(train: Sequence[dict], samples: Sequence[dict], permutations: int = 200,
            threshold: float | None = None, seed: int = 0,
            max_reference: int = MAX_REFERENCE) -> dict:
    """KL per descriptor, MMD² and coverage of ``samples`` against ``train`` descriptor
    records (module docstring). Returns ``{"kl": {name: nats}, "kl_total", "mmd", "coverage",
    "vector"}``, and ``"reference"`` when both sides have records.

    The KLs use every training record; MMD² and coverage use at most ``max_reference`` of
    them, drawn without replacement with ``seed`` (an unbiased MMD² estimate of the same
    distribution; ``"reference"`` says how many).

    Raises:
        SettingsError: as :func:`mmd_rbf` and :func:`coverage`, or ``max_reference`` below 2.
    """
    check_settings("compare", permutations=(permutations, integer(0)),
                   threshold=(threshold, number(0).or_none()),
                   max_reference=(max_reference, integer(2)))
    check_seed(seed, "compare seed")
    kl = {}
    for n in DESCRIPTORS:
        kl[n] = histogram_kl([r[n] for r in train], [r[n] for r in samples],
                             integer=n in COUNT_DESCRIPTORS, log=n in LOG_DESCRIPTORS)
    names = VECTOR_DESCRIPTORS
    out: dict = {"kl": kl, "kl_total": float(np.nansum(list(kl.values())))}
    if train and samples:
        t, s = standardize(descriptor_table(train, names), descriptor_table(samples, names),
                           names=names)
        if len(t) > max_reference:
            t = t[np.sort(np.random.default_rng(seed).choice(len(t), max_reference,
                                                             replace=False))]
        out["reference"] = len(t)
        out["mmd"] = mmd_rbf(t, s, permutations=permutations, seed=seed)
        out["coverage"] = coverage(t, s, threshold)
    else:
        out["mmd"] = {"mmd2": math.nan, "bandwidth": math.nan, "p_value": math.nan}
        out["coverage"] = coverage(np.zeros((0, len(names))), np.zeros((0, len(names))))
    out["vector"] = list(names)
    return out


# ----------------------------------------------------------------------------------------------
# entropy and dimensionality


def knn_entropy(x: np.ndarray, k: int = 3, min_distance: float = 1e-9) -> float:
    """Kozachenko–Leonenko k-nearest-neighbour estimate of the differential entropy (nats) of
    the distribution the rows of ``x`` ``[N, d]`` were drawn from:

    ``H ≈ ψ(N) − ψ(k) + log V_d + (d / N) Σ_i log ε_i``,

    with ``ε_i`` the Euclidean distance from point ``i`` to its ``k``-th nearest neighbour and
    ``V_d = π^{d/2} / Γ(d/2 + 1)`` the volume of the unit ball. Distances below
    ``min_distance`` are raised to it (repeated points would give ``-inf``). Consistent as
    ``N → ∞``; biased for small ``N`` in high ``d`` (compare populations of equal size).
    ``k`` is lowered to ``N - 1`` for tiny samples; NaN below 2 points.

    Raises:
        SettingsError: ``k`` below 1, ``min_distance`` not a number > 0.
    """
    check_settings("knn_entropy", k=(k, integer(1)),
                   min_distance=(min_distance, number(0, low_open=True)))
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    n, d = x.shape
    if n < 2 or d == 0:
        return math.nan
    k = min(k, n - 1)
    eps = np.maximum(kth_nearest(x, k), min_distance)
    log_vd = 0.5 * d * math.log(math.pi) - math.lgamma(0.5 * d + 1.0)
    return float(_digamma(n) - _digamma(k) + log_vd + d * np.mean(np.log(eps)))


def _digamma(n: int) -> float:
    """ψ(n) for a positive integer: −γ + Σ_{j<n} 1/j."""
    return -0.5772156649015329 + float(np.sum(1.0 / np.arange(1, n)))


def ledoit_wolf(x: np.ndarray) -> tuple[np.ndarray, float]:
    """Ledoit–Wolf shrunk covariance of the rows of ``x`` and the shrinkage in ``[0, 1]``."""
    x = np.asarray(x, float)
    n, d = x.shape
    xc = x - x.mean(0)
    emp = xc.T @ xc / n
    if n < 2:
        return emp, 1.0
    mu = np.trace(emp) / d
    x2 = xc ** 2
    beta_ = float(np.sum(x2.T @ x2)) / n
    delta_ = float(np.sum((xc.T @ xc) ** 2)) / n ** 2
    beta = (beta_ - delta_) / (d * n)
    delta = (delta_ - 2.0 * mu * np.trace(emp) + d * mu ** 2) / d
    beta = min(beta, delta)
    s = 0.0 if delta <= 0 else beta / delta
    s = float(min(max(s, 0.0), 1.0))
    return (1.0 - s) * emp + s * mu * np.eye(d), s


def gaussian_entropy(cov: np.ndarray) -> float:
    """``½ log det(2πe Σ)`` in nats (``-inf`` for a singular ``Σ``)."""
    d = cov.shape[0]
    sign, logdet = np.linalg.slogdet(cov)
    if sign <= 0:
        return -math.inf
    return float(0.5 * (d * math.log(2 * math.pi * math.e) + logdet))


def participation_ratio(eigenvalues: Sequence[float] | np.ndarray) -> float:
    """``(Σλ)² / Σλ²``: the effective number of dimensions of a spectrum."""
    lam = np.clip(np.asarray(eigenvalues, float), 0.0, None)
    s2 = float((lam ** 2).sum())
    return float(lam.sum() ** 2 / s2) if s2 > 0 else 0.0


def latent_stats(mu: np.ndarray | torch.Tensor, k: int = 3, match: int | None = None,
                 repeats: int = 20, seed: int = 0) -> dict:
    """Entropy and dimensionality of encoded means ``mu`` ``[N, d]`` (module docstring).

    With ``match`` (< N), the k-NN entropy is also estimated on ``repeats`` random subsets of
    ``match`` points (``knn_entropy_matched``: compares with a population of that size).

    Returns ``n``, ``dim``, ``gaussian_entropy`` (nats), ``shrinkage``, ``knn_entropy`` (nats),
    ``effective_dim``, ``total_variance``, ``median_norm`` (median ``|mu|``: the Gaussian
    entropy and the variance follow outliers, the k-NN entropy and this do not),
    ``prior_entropy`` (``N(0, I)`` in ``d``
    dimensions, for reference) and the PCA ``eigenvalues``.
    """
    x = mu.detach().cpu().double().numpy() if isinstance(mu, torch.Tensor) else \
        np.asarray(mu, float)
    n, d = x.shape
    nan = math.nan
    out = {"n": int(n), "dim": int(d),
           "prior_entropy": 0.5 * d * math.log(2 * math.pi * math.e)}
    if n < 2:
        return {**out, "gaussian_entropy": nan, "shrinkage": nan, "knn_entropy": nan,
                "median_norm": float(np.linalg.norm(x, axis=1).mean()) if n else nan,
                "effective_dim": nan, "total_variance": nan, "eigenvalues": []}
    cov, s = ledoit_wolf(x)
    out["median_norm"] = float(np.median(np.linalg.norm(x, axis=1)))
    xc = x - x.mean(0)
    lam = np.sort(np.linalg.eigvalsh(xc.T @ xc / (n - 1)))[::-1]
    out.update(gaussian_entropy=gaussian_entropy(cov), shrinkage=s,
               knn_entropy=knn_entropy(x, k), effective_dim=participation_ratio(lam),
               total_variance=float(lam.sum()),
               eigenvalues=[float(v) for v in np.clip(lam, 0, None)])
    if match is not None and 2 <= match < n:
        rng = np.random.default_rng(seed)
        out["knn_entropy_matched"] = float(np.mean(
            [knn_entropy(x[rng.choice(n, match, replace=False)], k) for _ in range(repeats)]))
        out["matched_n"] = int(match)
    return out


def pca(x: np.ndarray | torch.Tensor, dims: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Project rows of ``x`` on their first ``dims`` principal components.

    Returns ``(projection [N, dims], explained variance ratio [dims])``.
    """
    a = x.detach().cpu().double().numpy() if isinstance(x, torch.Tensor) else \
        np.asarray(x, float)
    ac = a - a.mean(0)
    _, sv, vt = np.linalg.svd(ac, full_matrices=False)
    var = sv ** 2
    ratio = var / var.sum() if var.sum() > 0 else np.zeros_like(var)
    return ac @ vt[:dims].T, ratio[:dims]
