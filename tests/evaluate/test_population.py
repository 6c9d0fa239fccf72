"""Population statistics (robovae.evaluate.population) on procedural robot populations and
known distributions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robovae.evaluate.descriptors import DESCRIPTORS, descriptor_table, descriptors
from robovae.evaluate.population import (
    compare,
    coverage,
    gaussian_entropy,
    histogram_kl,
    knn_entropy,
    latent_stats,
    ledoit_wolf,
    mmd_rbf,
    participation_ratio,
    pca,
    standardize,
    summary,
)
from tests.evaluate.test_descriptors import proc_graph


@pytest.fixture(scope="module")
def quadrupeds() -> list[dict]:
    return [descriptors(proc_graph(s, "quadruped")) for s in range(30)]


@pytest.fixture(scope="module")
def humanoids() -> list[dict]:
    return [descriptors(proc_graph(s, "humanoid")) for s in range(30)]


# ----------------------------------------------------------------------------------------------
# tables


def test_descriptor_table_summary_and_standardize(quadrupeds: list[dict]) -> None:
    t = descriptor_table(quadrupeds)
    assert t.shape == (30, len(DESCRIPTORS))
    s = summary(quadrupeds)
    links = [r["links"] for r in quadrupeds]
    assert s["links"]["mean"] == pytest.approx(np.mean(links))
    assert s["links"]["min"] == min(links) and s["links"]["max"] == max(links)
    assert s["limbs"] == {"mean": 4.0, "std": 0.0, "median": 4.0, "min": 4.0, "max": 4.0,
                          "n": 30}
    empty = summary([{"links": math.nan}], ["links"])
    assert empty["links"]["n"] == 0 and math.isnan(empty["links"]["mean"])
    z, z2 = standardize(t, t[:5], names=DESCRIPTORS)
    assert np.isfinite(z).all()
    varying = t.std(0) > 0
    assert np.allclose(z.mean(0), 0.0, atol=1e-9)
    assert np.allclose(z.std(0)[varying], 1.0)
    assert np.allclose(z2, z[:5])
    # mass is log-transformed: a 10x heavier robot moves one log10 unit / std
    heavy = t.copy()
    j = DESCRIPTORS.index("mass")
    heavy[:, j] *= 10
    zh = standardize(t, heavy, names=DESCRIPTORS)[1]
    std = np.log10(t[:, j] + 1e-6).std()
    assert np.allclose(zh[:, j] - z[:, j], 1.0 / std, rtol=1e-4)


# ----------------------------------------------------------------------------------------------
# divergences


def test_histogram_kl_identity_and_symmetric_case() -> None:
    p = [0] * 30 + [1] * 10
    q = [0] * 10 + [1] * 30
    assert histogram_kl(p, p, integer=True) == pytest.approx(0.0, abs=1e-12)
    kl_pq, kl_qp = histogram_kl(p, q, integer=True), histogram_kl(q, p, integer=True)
    assert kl_pq == pytest.approx(kl_qp)  # mirrored histograms
    a, b = np.array([30.5, 10.5]) / 41, np.array([10.5, 30.5]) / 41  # + 0.5 per bin
    assert kl_pq == pytest.approx(float(np.sum(a * np.log(a / b))))
    # an unrelated bin empty in both samples changes nothing; NaNs are dropped
    assert histogram_kl(p + [math.nan], q, integer=True) == pytest.approx(kl_pq)
    assert math.isnan(histogram_kl([], q))
    # more different -> larger
    r = [1] * 40
    assert histogram_kl(p, r, integer=True) > kl_pq
    rng = np.random.default_rng(0)
    x, y = rng.normal(0, 1, 500), rng.normal(3, 1, 500)
    assert histogram_kl(x, x) == pytest.approx(0.0, abs=1e-12)
    assert histogram_kl(x, y) > 1.0


def test_mmd_identity_vs_shift() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(60, 3))
    same = mmd_rbf(x, x, permutations=50)
    other = mmd_rbf(x, rng.normal(size=(60, 3)) + 2.0, permutations=50)
    fresh = mmd_rbf(x, rng.normal(size=(60, 3)), permutations=50)
    assert abs(same["mmd2"]) < 0.02
    assert other["mmd2"] > 0.3 > abs(fresh["mmd2"])
    assert other["p_value"] == pytest.approx(1 / 51)
    assert same["p_value"] > 0.5 and fresh["p_value"] > 0.05
    assert math.isnan(mmd_rbf(x[:1], x)["mmd2"])
    assert math.isnan(mmd_rbf(x, x, permutations=0)["p_value"])


def test_mmd_block_sums_match_the_kernel_blocks() -> None:
    """The statistic and every permutation's, from ``K V`` products, equal the mean kernel
    values over the blocks of the kernel matrix, computed directly (the definition)."""
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(37, 4)), rng.normal(size=(23, 4)) + 0.4
    z = np.concatenate([x, y])
    d = np.sqrt(((z[:, None] - z[None]) ** 2).sum(-1))
    h = float(np.median(d[np.triu_indices(len(z), 1)]))
    k = np.exp(-d ** 2 / (2 * h * h))
    np.fill_diagonal(k, 0.0)

    def direct(ix: np.ndarray, iy: np.ndarray) -> float:
        return (k[np.ix_(ix, ix)].sum() / (37 * 36) + k[np.ix_(iy, iy)].sum() / (23 * 22)
                - 2 * k[np.ix_(ix, iy)].sum() / (37 * 23))

    observed = direct(np.arange(37), np.arange(37, 60))
    rng5 = np.random.default_rng(5)
    perms = [rng5.permutation(60) for _ in range(150)]
    hits = sum(direct(p[:37], p[37:]) >= observed for p in perms)
    got = mmd_rbf(x, y, permutations=150, seed=5)  # 150: more than one batch of permutations
    assert got["bandwidth"] == pytest.approx(h, rel=1e-12)
    assert got["mmd2"] == pytest.approx(observed, rel=1e-9)
    assert got["p_value"] == (1 + hits) / 151


def test_coverage_of_a_set_by_itself_and_by_a_far_set() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(40, 4))
    c = coverage(x, x)
    assert c["coverage"] == 1.0 and c["precision"] == 1.0
    assert c["mean_nearest_sample"] == pytest.approx(0.0, abs=1e-6)
    far = coverage(x, x + 100.0)
    assert far["coverage"] == 0.0 and far["precision"] == 0.0
    half = coverage(x, x[:20], threshold=1e-6)
    assert half["coverage"] == 0.5 and half["precision"] == 1.0


def test_compare_populations(quadrupeds: list[dict], humanoids: list[dict]) -> None:
    same = compare(quadrupeds, quadrupeds, permutations=20)
    assert same["kl_total"] == pytest.approx(0.0, abs=1e-9)
    assert abs(same["mmd"]["mmd2"]) < 0.05
    assert same["coverage"]["coverage"] == 1.0 and same["coverage"]["precision"] == 1.0
    diff = compare(quadrupeds, humanoids, permutations=20)
    assert diff["kl"]["limbs"] > 1.0  # 4 limbs vs 5
    assert diff["kl_total"] > 1.0
    assert diff["mmd"]["mmd2"] > 10 * abs(same["mmd"]["mmd2"])
    assert diff["mmd"]["p_value"] == pytest.approx(1 / 21)
    assert diff["coverage"]["coverage"] < 0.5
    # a subset covers less of the training set than the whole
    part = compare(quadrupeds, quadrupeds[:10], permutations=0)
    assert 0.0 < part["coverage"]["coverage"] < 1.0 and part["coverage"]["precision"] == 1.0
    empty = compare(quadrupeds, [], permutations=0)
    assert math.isnan(empty["mmd"]["mmd2"]) and math.isnan(empty["coverage"]["coverage"])


def test_compare_caps_the_reference_for_mmd_and_coverage(quadrupeds: list[dict],
                                                         humanoids: list[dict]) -> None:
    """A training set larger than ``max_reference`` enters MMD² and coverage as a seeded
    subsample (pairwise matrices are quadratic), the KLs whole."""
    train = quadrupeds + humanoids
    full = compare(train, humanoids, permutations=0)
    capped = compare(train, humanoids, permutations=0, max_reference=len(quadrupeds))
    assert full["reference"] == len(train) and capped["reference"] == len(quadrupeds)
    assert capped["kl"] == full["kl"]
    assert capped["mmd"]["mmd2"] != full["mmd"]["mmd2"]
    again = compare(train, humanoids, permutations=0, max_reference=len(quadrupeds))
    assert again["mmd"] == capped["mmd"] and again["coverage"] == capped["coverage"]


# ----------------------------------------------------------------------------------------------
# entropy and dimensionality


def test_knn_entropy_of_known_distributions() -> None:
    rng = np.random.default_rng(0)
    assert knn_entropy(rng.normal(size=2000)) == pytest.approx(
        0.5 * math.log(2 * math.pi * math.e), abs=0.05)
    assert knn_entropy(rng.uniform(size=(2000, 2))) == pytest.approx(0.0, abs=0.08)
    cov = np.diag([1.0, 4.0, 0.25])
    x = rng.multivariate_normal(np.zeros(3), cov, size=2000)
    assert knn_entropy(x) == pytest.approx(gaussian_entropy(cov), abs=0.1)
    # scaling by s adds d·log s
    assert knn_entropy(3 * x) - knn_entropy(x) == pytest.approx(3 * math.log(3), abs=1e-9)
    assert math.isnan(knn_entropy(x[:1]))
    assert math.isfinite(knn_entropy(np.zeros((10, 2))))  # repeated points: floor, not -inf


def test_gaussian_entropy_and_participation_ratio() -> None:
    assert gaussian_entropy(np.eye(3)) == pytest.approx(1.5 * math.log(2 * math.pi * math.e))
    assert gaussian_entropy(np.diag([1.0, 0.0])) == -math.inf
    assert participation_ratio([1, 1, 1, 1]) == pytest.approx(4.0)
    assert participation_ratio([5, 0, 0]) == pytest.approx(1.0)
    assert participation_ratio([0, 0]) == 0.0


def test_latent_stats_of_known_gaussians() -> None:
    rng = np.random.default_rng(0)
    d = 6
    iso = rng.normal(size=(3000, d))
    s = latent_stats(iso)
    assert s["n"] == 3000 and s["dim"] == d
    assert s["prior_entropy"] == pytest.approx(0.5 * d * math.log(2 * math.pi * math.e))
    assert s["gaussian_entropy"] == pytest.approx(s["prior_entropy"], abs=0.1)
    assert s["knn_entropy"] == pytest.approx(s["prior_entropy"], abs=0.4)
    assert s["effective_dim"] == pytest.approx(d, rel=0.05)
    assert s["total_variance"] == pytest.approx(d, rel=0.05)
    assert 0.0 <= s["shrinkage"] <= 1.0  # isotropic: shrinking towards mu·I costs nothing
    # one direction holds the variance
    flat = iso * np.array([10.0] + [0.01] * (d - 1))
    f = latent_stats(flat)
    assert f["effective_dim"] == pytest.approx(1.0, abs=0.01)
    # shrinkage towards mu·I lifts the tiny eigenvalues: lower, though far above the exact
    # 0.5·log det(2πe Σ) = prior - 20·ln 10 / 2
    exact = s["prior_entropy"] + 0.5 * math.log(100.0 * 1e-4 ** (d - 1))
    assert exact < f["gaussian_entropy"] < s["gaussian_entropy"] - 5
    # fewer points than dimensions: shrinkage keeps the entropy finite
    few = latent_stats(rng.normal(size=(5, 20)), match=None)
    assert math.isfinite(few["gaussian_entropy"]) and few["shrinkage"] > 0
    m = latent_stats(iso[:500], match=100, repeats=3)
    assert m["matched_n"] == 100 and math.isfinite(m["knn_entropy_matched"])
    one = latent_stats(iso[:1])
    assert math.isnan(one["gaussian_entropy"]) and one["eigenvalues"] == []


def test_ledoit_wolf_and_pca() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2000, 3)) * np.array([3.0, 1.0, 0.1])
    cov, s = ledoit_wolf(x)
    assert 0.0 <= s < 0.01  # strongly anisotropic, many points: hardly shrunk
    assert np.allclose(np.diag(cov), [9.0, 1.0, 0.01], rtol=0.1, atol=0.02)
    proj, ratio = pca(x, 2)
    assert proj.shape == (2000, 2)
    assert ratio[0] == pytest.approx(9.0 / 10.01, abs=0.02)
    assert abs(proj[:, 0].std()) == pytest.approx(3.0, rel=0.05)
    # few points in many dimensions: shrunk towards mu·I, full rank
    cov, s = ledoit_wolf(x[:4] @ rng.normal(size=(3, 10)))
    assert 0.0 < s <= 1.0 and np.linalg.matrix_rank(cov) == 10


@pytest.mark.parametrize("call, bad", [
    (lambda x, y: mmd_rbf(x, y, permutations=-1), "mmd_rbf.permutations"),
    (lambda x, y: mmd_rbf(x, y, bandwidth=0.0), "mmd_rbf.bandwidth"),
    (lambda x, y: mmd_rbf(x, y, bandwidth=float("nan")), "mmd_rbf.bandwidth"),
    (lambda x, y: mmd_rbf(x, y, seed=-1), "mmd_rbf seed"),
    (lambda x, y: coverage(x, y, threshold=-1.0), "coverage.threshold"),
    (lambda x, y: knn_entropy(x, k=0), "knn_entropy.k"),
    (lambda x, y: knn_entropy(x, min_distance=0.0), "knn_entropy.min_distance"),
    (lambda x, y: histogram_kl(x[:, 0], y[:, 0], bins=0), "histogram_kl.bins"),
    (lambda x, y: histogram_kl(x[:, 0], y[:, 0], pseudo=0.0), "histogram_kl.pseudo"),
    (lambda x, y: compare([], [], permutations=-1), "compare.permutations"),
    (lambda x, y: compare([], [], max_reference=1), "compare.max_reference"),
])
def test_statistics_refuse_settings_out_of_range(call, bad) -> None:
    """A bandwidth of 0 gave MMD² 0 with p = 1 (the populations "the same"), a NaN one a NaN
    MMD² with p = 0.005, a negative threshold coverage 0, ``k = 0`` an entropy (the
    estimator is undefined there), ``bins = 0`` a KL of 0: refused in one line instead."""
    from robovae.errors import SettingsError

    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(20, 3)), rng.normal(size=(20, 3)) + 0.1
    with pytest.raises(SettingsError, match=bad):
        call(x, y)
    assert math.isnan(mmd_rbf(x, y, permutations=0)["p_value"])  # 0 permutations: documented
