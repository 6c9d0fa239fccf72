"""Descriptors of one robot graph: sizes, mass, degrees of freedom, limb proportions (paper
§6.2), and its category.

:func:`descriptors` summarises a robot graph (physical units) by a dict:

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

The trunk is :func:`~robovae.generate.bodies.trunk`. :func:`descriptor_table` stacks the
records of a population into an array; :mod:`robovae.evaluate.population` compares them.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np

from robovae.data.features import JOINT, LINK, FeatureSet, get_feature_set
from robovae.data.graph import RobotData, children, limbs
from robovae.data.zoo import zoo_category
from robovae.generate.bodies import joint_types, trunk

__all__ = ["COUNT_DESCRIPTORS", "DESCRIPTORS", "LOG_DESCRIPTORS", "VECTOR_DESCRIPTORS",
           "descriptor_table", "descriptors", "dof", "limb_lengths", "robot_category"]

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


def _fs(data: RobotData, feature_set: str | FeatureSet | None) -> FeatureSet:
    if isinstance(feature_set, FeatureSet):
        return feature_set
    if feature_set is not None:
        return get_feature_set(feature_set)
    return get_feature_set("full" if data.x.shape[1] == get_feature_set("full").dim
                           else "paper34")


def limb_lengths(data: RobotData, feature_set: str | FeatureSet | None = None) -> list[float]:
    """Length (m) of each limb of the trunk: the longest chain of link offsets ``|link.pos|``
    from the trunk to a leaf link, plus the leaf's extent (twice its largest ``link.size``)."""
    fs = _fs(data, feature_set)
    types = data.node_type.tolist()
    kids = children(data.parent)
    root_link = trunk(types, kids)
    if root_link < 0 or "link" not in fs.node_types:
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
    for c in kids[root_link]:
        length, has_joint = longest(c)
        if has_joint:
            out.append(float(length))
    return out


def dof(data: RobotData, feature_set: str | FeatureSet | None = None) -> int:
    """Degrees of freedom: free 6, ball 3, hinge and slide 1 (types as the writer infers them)."""
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
        root_link = trunk(types.tolist(), children(data.parent))
        if root_link >= 0:
            ext = 2.0 * float(data.x[root_link, fs.slice("link.size")].max())
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
    floating = (data.node_type[0] == JOINT and joint_types(data, _fs(data, None))[0] == "free")
    per_limb = (d["joints"] - (1 if floating else 0)) / max(d["limbs"], 1)
    if floating and d["limbs"] == 4 and per_limb <= 3.0:
        return "quadruped"
    if floating and d["limbs"] in (4, 5):
        return "humanoid"
    if not floating and d["limbs"] <= 1 and d["joints"] >= 2:
        return "arm"
    return "other"


def descriptor_table(records: Sequence[dict], names: Sequence[str] = DESCRIPTORS) -> np.ndarray:
    """``[N, len(names)]`` float array of descriptor values (NaN where undefined)."""
    return np.array([[float(r.get(n, math.nan)) for n in names] for r in records],
                    dtype=float).reshape(len(records), len(names))
