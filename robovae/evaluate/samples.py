"""Metrics of generated robot populations (SPEC §4, generation).

Each robot is summarised by a *record* (:func:`robot_record`): its duplicate key, topology key
and descriptors. Metrics are computed from records, so a manifest of 10,000 robots (or the
training set stored in a checkpoint) is enough — no graph has to be kept in memory.

- **validity**: share of samples that :mod:`robovae.generate.validate` calls ``valid``;
- **uniqueness**: distinct keys among valid samples / valid samples. Two robots are duplicates
  when they have the same topology and node types and their normalised features agree on a grid
  of step ``tol`` (features snapped to ``round(x / tol)``);
- **novelty**: share of valid samples whose key matches no training robot;
- **diversity**: distinct topologies, limb-count and total-mass histograms (samples against the
  training set) and the mean pairwise Euclidean distance of descriptor vectors
  ``(nodes, depth, limbs, log(1 + mass))``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np
import torch

from robovae.data.features import JOINT, LINK
from robovae.data.graph import RobotData, limbs
from robovae.data.normalizer import Normalizer

DUPLICATE_TOL = 0.05


def topology_key(data: RobotData) -> str:
    """Hash of the tree shape and node types (child order included)."""
    h = hashlib.sha1(data.parent.numpy().astype(np.int64).tobytes())
    h.update(data.node_type.numpy().astype(np.int64).tobytes())
    return h.hexdigest()[:16]


def robot_key(data: RobotData, normalizer: Normalizer, tol: float = DUPLICATE_TOL) -> str:
    """Topology + normalised features snapped to a ``tol`` grid: equal keys = duplicates."""
    y = normalizer(data.x, data.node_type)
    snapped = torch.round(y / tol).to(torch.int64).numpy()
    return topology_key(data) + hashlib.sha1(snapped.tobytes()).hexdigest()[:16]


def robot_record(data: RobotData, normalizer: Normalizer, tol: float = DUPLICATE_TOL) -> dict:
    """Key, topology and descriptors (nodes, links, joints, depth, limbs, total mass)."""
    fs = normalizer.feature_set
    links = data.node_type == LINK
    mass = (float(data.x[links, fs.slice("link.mass")].sum()) if "link" in fs.node_types
            else 0.0)
    return {"name": getattr(data, "name", ""), "key": robot_key(data, normalizer, tol),
            "topology": topology_key(data), "nodes": int(data.num_nodes),
            "links": int(links.sum()), "joints": int((data.node_type == JOINT).sum()),
            "depth": int(data.depth.max()), "limbs": limbs(data), "mass": mass}


def _histogram(values: Sequence[float], bins: np.ndarray) -> list[int]:
    return np.histogram(np.asarray(values, dtype=float), bins=bins)[0].tolist()


def _mean_pairwise(vec: np.ndarray, max_points: int = 2000) -> float:
    if len(vec) < 2:
        return 0.0
    vec = vec[:max_points]  # O(n^2): a deterministic prefix is plenty for a mean
    diff = vec[:, None, :] - vec[None, :, :]
    return float(np.sqrt((diff ** 2).sum(-1)).sum() / (len(vec) * (len(vec) - 1)))


def sample_metrics(samples: Sequence[dict], training: Sequence[dict]) -> dict:
    """Validity, uniqueness, novelty and diversity of sample records against training records.

    Each sample record needs ``valid`` besides the :func:`robot_record` fields.
    """
    n = len(samples)
    good = [s for s in samples if s.get("valid")]
    keys = [s["key"] for s in good]
    train_keys = {t["key"] for t in training}
    all_desc = good + list(training)
    limb_bins = np.arange(0, max([d["limbs"] for d in all_desc] + [1]) + 2) - 0.5
    masses = [d["mass"] for d in all_desc if d["mass"] > 0]
    mass_bins = (np.geomspace(min(masses), max(masses) * 1.0001, 11) if masses
                 else np.linspace(0, 1, 11))
    vec = np.array([[d["nodes"], d["depth"], d["limbs"], np.log1p(d["mass"])] for d in good])
    tvec = np.array([[d["nodes"], d["depth"], d["limbs"], np.log1p(d["mass"])]
                     for d in training])
    nan = float("nan")
    return {
        "samples": n,
        "valid": len(good),
        "validity": len(good) / n if n else nan,
        "uniqueness": len(set(keys)) / len(good) if good else nan,
        "novelty": sum(k not in train_keys for k in keys) / len(good) if good else nan,
        "distinct_topologies": len({s["topology"] for s in good}),
        "training_topologies": len({t["topology"] for t in training}),
        "mean_descriptor_distance": _mean_pairwise(vec),
        "training_descriptor_distance": _mean_pairwise(tvec),
        "limb_histogram": {"bins": limb_bins.tolist(),
                           "samples": _histogram([d["limbs"] for d in good], limb_bins),
                           "training": _histogram([d["limbs"] for d in training], limb_bins)},
        "mass_histogram": {"bins": mass_bins.tolist(),
                           "samples": _histogram([d["mass"] for d in good], mass_bins),
                           "training": _histogram([d["mass"] for d in training], mass_bins)},
    }
