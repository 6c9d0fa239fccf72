"""A statistical view of robot populations (paper §6.2): descriptors, divergences, latent
entropy, effective dimensionality and coverage.

A *population* is a list of robot graphs — the training robots of a checkpoint, a folder of
generated robots, any dataset. Each robot is summarised by a dict of **descriptors**
(:func:`descriptors`):

=================== =================================================================
``links``           link (body) nodes
``joints``          joint nodes
``depth``           depth of the tree (node levels below the root)
``limbs``           subtrees of the trunk that contain a joint (:func:`~robovae.data.graph.limbs`)
``mass``            total mass, kg (sum of ``link.mass``)
``dof``             degrees of freedom: free 6, ball 3, hinge/slide 1 (joint types from
                    :func:`~robovae.generate.bodies.joint_types`: inferred in ``paper34``)
``limb_length``     mean limb length, m: per limb, the longest chain of link offsets
                    ``|link.pos|`` from the trunk to a leaf link plus the leaf's extent
                    (twice its largest ``link.size``)
``limb_ratio``      shortest / longest limb length (1: all limbs alike; NaN below 2 limbs)
``leg_body_ratio``  longest limb / trunk extent (twice the trunk's largest ``link.size``;
                    NaN when the trunk has no geom)
=================== =================================================================

Population statistics (:func:`compare`):

- **KL** per descriptor: ``KL(train ‖ samples)`` between histograms on shared bins (unit bins
  for counts, 10 equal bins of the transformed value otherwise) with 0.5 added to every bin
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

- **Gaussian entropy** ``½ log det(2πe Σ)`` of the Ledoit–Wolf shrunk covariance (full rank
  even with fewer robots than latent dimensions, so populations of any size compare);
- **k-NN entropy** (Kozachenko–Leonenko, :func:`knn_entropy`);
- **effective dimensionality**: participation ratio ``(Σλ)² / Σλ²`` of the PCA eigenvalues
  (1 when one direction holds all the variance, ``d`` when all are equal).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from robovae.data.features import JOINT, LINK, FeatureSet, get_feature_set
from robovae.data.graph import RobotData, children, limbs

#: Descriptor names in table order.
DESCRIPTORS = ("links", "joints", "depth", "limbs", "mass", "dof", "limb_length", "limb_ratio",
               "leg_body_ratio")
#: Integer-valued descriptors (histograms with unit bins).
COUNT_DESCRIPTORS = ("links", "joints", "depth", "limbs", "dof")
#: Descriptors log-transformed before standardising / binning (heavy-tailed, positive).
LOG_DESCRIPTORS = ("mass", "limb_length", "leg_body_ratio")
#: The descriptor vector of MMD and coverage.
VECTOR_DESCRIPTORS = ("links", "joints", "depth", "limbs", "mass", "dof", "limb_length",
                      "limb_ratio")
_DOF = {"free": 6, "ball": 3, "slide": 1, "hinge": 1}


# ----------------------------------------------------------------------------------------------
# descriptors of one robot


def _fs(data: RobotData, feature_set: str | FeatureSet | None) -> FeatureSet:
    if isinstance(feature_set, FeatureSet):
        return feature_set
    if feature_set is not None:
        return get_feature_set(feature_set)
    return get_feature_set("full" if data.x.shape[1] == get_feature_set("full").dim
                           else "paper34")


def _trunk(types: list[int], kids: list[list[int]]) -> int:
    i = 0
    while types[i] != LINK:  # root joints (a free base) down to the first link
        nxt = [c for c in kids[i] if types[c] in (LINK, JOINT)]
        if not nxt:
            return -1
        i = nxt[0]
    return i


def limb_lengths(data: RobotData, feature_set: str | FeatureSet | None = None) -> list[float]:
    """Length (m) of each limb of the trunk: the longest chain of link offsets ``|link.pos|``
    from the trunk to a leaf link, plus the leaf's extent (twice its largest ``link.size``)."""
    fs = _fs(data, feature_set)
    types = data.node_type.tolist()
    kids = children(data.parent)
    trunk = _trunk(types, kids)
    if trunk < 0 or "link" not in fs.node_types:
        return []
    pos = data.x[:, fs.slice("link.pos")].double().norm(dim=1).tolist()
    size = data.x[:, fs.slice("link.size")].double().amax(dim=1).tolist()

    def longest(i: int) -> tuple[float, bool]:
        """Longest link chain below node ``i`` (inclusive) and whether it holds a joint."""
        own = pos[i] if types[i] == LINK else 0.0
        best, has_joint = None, types[i] == JOINT
        for c in kids[i]:
            length, j = longest(c)
            has_joint |= j
            if types[c] in (LINK, JOINT):
                best = length if best is None else max(best, length)
        if best is None:  # a leaf (or a node whose children are geoms)
            best = 2.0 * size[i] if types[i] == LINK else 0.0
        return own + best, has_joint

    out = []
    for c in kids[trunk]:
        length, has_joint = longest(c)
        if has_joint:
            out.append(float(length))
    return out


def dof(data: RobotData, feature_set: str | FeatureSet | None = None) -> int:
    """Degrees of freedom: free 6, ball 3, hinge and slide 1 (types as the writer infers them)."""
    from robovae.generate.bodies import joint_types

    fs = _fs(data, feature_set)
    if "joint" not in fs.node_types:
        return 0
    return sum(_DOF.get(t, 0) for t in joint_types(data, fs))


def descriptors(data: RobotData, feature_set: str | FeatureSet | None = None) -> dict:
    """The descriptors of one robot graph (module docstring), plus its ``name``.

    ``feature_set`` defaults to the set whose width matches ``data.x`` (``paper34``/``full``).
    """
    fs = _fs(data, feature_set)
    types = data.node_type
    is_link = types == LINK
    robot = fs.node_types[:2] == ("link", "joint")
    mass = float(data.x[is_link, fs.slice("link.mass")].double().sum()) if robot else 0.0
    lengths = limb_lengths(data, fs) if robot else []
    nan = float("nan")
    trunk_extent = nan
    if robot:
        trunk = _trunk(types.tolist(), children(data.parent))
        if trunk >= 0:
            ext = 2.0 * float(data.x[trunk, fs.slice("link.size")].max())
            trunk_extent = ext if ext > 0 else nan
    return {
        "name": getattr(data, "name", "") or "",
        "links": int(is_link.sum()),
        "joints": int((types == JOINT).sum()),
        "depth": int(data.depth.max()) if data.num_nodes else 0,
        "limbs": limbs(data) if robot else 0,
        "mass": mass,
        "dof": dof(data, fs) if robot else 0,
        "limb_length": float(np.mean(lengths)) if lengths else nan,
        "limb_ratio": (min(lengths) / max(lengths) if len(lengths) >= 2 and max(lengths) > 0
                       else nan),
        "leg_body_ratio": (max(lengths) / trunk_extent
                           if lengths and not math.isnan(trunk_extent) else nan),
    }


_CATEGORY_WORDS = (
    ("arm", r"(^|_)(z1|piper|panda|arm|ur\d+e?|kinova|gen3|iiwa|xarm\d*|so_?arm\d*|reacher|"
            r"pusher|tiago|fr3|sawyer|viper|widow|lite6|vx300s?)($|_)"),
    ("humanoid", r"humanoid|(^|_)(h1|g1|t1|n1|talos|op3|berkeley|cassie|apollo)($|_)"),
    ("quadruped", r"quadruped|(^|_)(ant|go1|go2|a1|spot|barkour|anymal|dog|dog_v2|rodent|"
                  r"aliengo|b1|b2)($|_)|barkour"),
)


def robot_category(name: str = "", data: RobotData | None = None) -> str:
    """``quadruped``, ``humanoid``, ``arm`` or ``other``.

    Zoo robots take their zoo category (planar, swimmer, hexapod → ``other``); other names are
    matched against common robot names (``unitree_go2``, ``unitree_h1``, ``unitree_z1``, ...);
    else the category comes from its structure: a
    floating base with four limbs of at most three joints is a quadruped, one with four or five
    limbs and more joints a humanoid, a fixed base with one limb an arm.
    """
    from robovae.data.zoo import zoo_category

    zoo = zoo_category(name)
    if zoo != "unknown":
        return zoo if zoo in ("quadruped", "humanoid") else "other"
    low = name.lower()
    for cat, pattern in _CATEGORY_WORDS:
        if re.search(pattern, low):
            return cat
    if data is None or data.num_nodes == 0:
        return "other"
    d = descriptors(data)
    from robovae.generate.bodies import joint_types

    floating = (data.node_type[0] == JOINT and joint_types(data, _fs(data, None))[0] == "free")
    per_limb = (d["joints"] - (1 if floating else 0)) / max(d["limbs"], 1)
    if floating and d["limbs"] == 4 and per_limb <= 3.0:
        return "quadruped"
    if floating and d["limbs"] in (4, 5):
        return "humanoid"
    if not floating and d["limbs"] <= 1 and d["joints"] >= 2:
        return "arm"
    return "other"


# ----------------------------------------------------------------------------------------------
# populations


def load_graphs(paths: Sequence[str | Path], feature_set: str = "paper34",
                names: Sequence[str] | None = None) -> tuple[list[RobotData], list[str]]:
    """Robot graphs of files (errors are collected as one-line messages, never raised)."""
    from robovae.data.mjcf import mjcf_to_graph
    from robovae.errors import RobovaeError

    graphs, errors = [], []
    for k, p in enumerate(paths):
        try:
            graphs.append(mjcf_to_graph(p, feature_set,
                                        name=names[k] if names is not None else None))
        except (RobovaeError, ValueError) as e:
            errors.append(str(e))
    return graphs, errors


def sample_files(folder: str | Path, valid_only: bool = True) -> list[tuple[str, Path]]:
    """``[(name, robot.xml)]`` of a folder written by ``robovae generate``.

    With a ``manifest.jsonl`` and ``valid_only``, only the robots it calls valid; without a
    manifest, every ``robot_*/robot.xml`` (else every ``*.xml`` below the folder).
    """
    from robovae.generate.pipeline import read_manifest

    folder = Path(folder)
    if not folder.is_dir():
        from robovae.errors import RobovaeError

        raise RobovaeError(f"robovae: {folder}: no such folder of samples")
    records = read_manifest(folder)
    if records:
        out = []
        for i, rec in sorted(records.items()):
            if valid_only and rec.get("valid") is False:
                continue
            path = folder / rec.get("path", f"robot_{i:06d}/robot.xml")
            if path.is_file():
                out.append((rec.get("name") or f"robot_{i:06d}", path))
        return out
    files = sorted(folder.glob("robot_*/robot.xml")) or sorted(
        p for p in folder.rglob("*.xml") if p.name != "scene.xml")
    return [(p.parent.name if p.name == "robot.xml" else p.stem, p) for p in files]


def descriptor_table(records: Sequence[dict], names: Sequence[str] = DESCRIPTORS) -> np.ndarray:
    """``[N, len(names)]`` float array of descriptor values (NaN where undefined)."""
    return np.array([[float(r.get(n, math.nan)) for n in names] for r in records],
                    dtype=float).reshape(len(records), len(names))


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


def histogram_kl(p: Sequence[float], q: Sequence[float], bins: int | np.ndarray = 10,
                 integer: bool = False, log: bool = False, pseudo: float = 0.5) -> float:
    """``KL(P ‖ Q)`` (nats) of two samples of one scalar, from histograms on shared bins.

    Bins: unit bins centred on the integers (``integer``, at most 50, wider beyond), else
    ``bins`` equal-width bins over the pooled range (of ``log10`` values with ``log``). NaNs are
    dropped; ``pseudo`` is added to every bin count (0.5: Jeffreys prior). NaN when either
    sample is empty.
    """
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


def _sqdist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d, 0.0)


def mmd_rbf(x: np.ndarray, y: np.ndarray, bandwidth: float | None = None,
            permutations: int = 200, seed: int = 0) -> dict:
    """Unbiased ``MMD²`` between samples ``x`` ``[n, d]`` and ``y`` ``[m, d]`` with the RBF
    kernel ``exp(-|a-b|² / (2 h²))``.

    ``h`` defaults to the median pairwise distance of the pooled points. The p-value is the
    share of ``permutations`` random relabellings of the pooled points whose MMD² is at least
    the observed one (``(1 + count) / (1 + permutations)``; NaN with 0 permutations).

    Returns ``{"mmd2", "bandwidth", "p_value"}``.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    n, m = len(x), len(y)
    if n < 2 or m < 2:
        return {"mmd2": math.nan, "bandwidth": math.nan, "p_value": math.nan}
    z = np.concatenate([x, y])
    d2 = _sqdist(z, z)
    if bandwidth is None:
        iu = np.triu_indices(len(z), 1)
        med = float(np.median(np.sqrt(d2[iu])))
        bandwidth = med if med > 0 else 1.0
    k = np.exp(-d2 / (2.0 * bandwidth ** 2))
    np.fill_diagonal(k, 0.0)

    def stat(ix: np.ndarray, iy: np.ndarray) -> float:
        kxx = k[np.ix_(ix, ix)].sum() / (n * (n - 1))
        kyy = k[np.ix_(iy, iy)].sum() / (m * (m - 1))
        kxy = k[np.ix_(ix, iy)].sum() / (n * m)
        return float(kxx + kyy - 2.0 * kxy)

    idx = np.arange(n + m)
    observed = stat(idx[:n], idx[n:])
    p = math.nan
    if permutations > 0:
        rng = np.random.default_rng(seed)
        hits = 0
        for _ in range(permutations):
            perm = rng.permutation(n + m)
            hits += stat(perm[:n], perm[n:]) >= observed
        p = (1 + hits) / (1 + permutations)
    return {"mmd2": observed, "bandwidth": float(bandwidth), "p_value": p}


def coverage(train: np.ndarray, samples: np.ndarray, threshold: float | None = None) -> dict:
    """Share of training points with a sample within ``threshold`` (Euclidean), and of samples
    with a training point within it (``precision``).

    ``threshold`` defaults to the median nearest-neighbour distance among the training points.
    Returns ``{"coverage", "precision", "threshold", "mean_nearest_sample"}``.
    """
    train, samples = np.asarray(train, float), np.asarray(samples, float)
    if len(train) == 0 or len(samples) == 0:
        return {"coverage": math.nan, "precision": math.nan, "threshold": math.nan,
                "mean_nearest_sample": math.nan}
    if threshold is None:
        if len(train) >= 2:
            d = np.sqrt(_sqdist(train, train))
            np.fill_diagonal(d, np.inf)
            threshold = float(np.median(d.min(1)))
        else:
            threshold = 1.0
    d = np.sqrt(_sqdist(train, samples))
    nearest_sample = d.min(1)
    nearest_train = d.min(0)
    return {"coverage": float((nearest_sample <= threshold).mean()),
            "precision": float((nearest_train <= threshold).mean()),
            "threshold": float(threshold),
            "mean_nearest_sample": float(nearest_sample.mean())}


def compare(train: Sequence[dict], samples: Sequence[dict], permutations: int = 200,
            threshold: float | None = None, seed: int = 0) -> dict:
    """KL per descriptor, MMD² and coverage of ``samples`` against ``train`` descriptor
    records (module docstring). Returns ``{"kl": {name: nats}, "kl_total", "mmd", "coverage"}``.
    """
    kl = {}
    for n in DESCRIPTORS:
        kl[n] = histogram_kl([r[n] for r in train], [r[n] for r in samples],
                             integer=n in COUNT_DESCRIPTORS, log=n in LOG_DESCRIPTORS)
    names = VECTOR_DESCRIPTORS
    out: dict = {"kl": kl, "kl_total": float(np.nansum(list(kl.values())))}
    if train and samples:
        t, s = standardize(descriptor_table(train, names), descriptor_table(samples, names),
                           names=names)
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
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    n, d = x.shape
    if n < 2 or d == 0:
        return math.nan
    k = max(1, min(k, n - 1))
    eps = np.empty(n)
    for start in range(0, n, 1024):  # chunks keep memory at 1024 × N
        block = np.sqrt(_sqdist(x[start:start + 1024], x))
        for r in range(block.shape[0]):
            block[r, start + r] = np.inf
        eps[start:start + block.shape[0]] = np.partition(block, k - 1, axis=1)[:, k - 1]
    eps = np.maximum(eps, min_distance)
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


def participation_ratio(eigenvalues: Sequence[float]) -> float:
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


__all__ = ["COUNT_DESCRIPTORS", "DESCRIPTORS", "LOG_DESCRIPTORS", "VECTOR_DESCRIPTORS",
           "compare", "coverage", "descriptor_table", "descriptors", "dof", "gaussian_entropy",
           "histogram_kl", "knn_entropy", "latent_stats", "ledoit_wolf", "limb_lengths",
           "load_graphs", "mmd_rbf", "participation_ratio", "pca", "robot_category",
           "sample_files", "standardize", "summary"]
