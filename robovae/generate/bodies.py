"""How a robot graph maps onto MuJoCo bodies and joints (shared by the rules and the writer).

Nodes are in pre-order. Every link node becomes a body, a child of its nearest ancestor link's
body; the joint nodes on the path from that ancestor down to the link are the joints of the
link's body, top-down (:func:`link_structure`; geom nodes are transparent). A link with at
least one joint in its body is *moving*; the *trunk* is the first link reached from the root
through root joints.

Joint types (:func:`joint_types`). In sets with ``joint.type`` the type is the arg-max of its
one-hot. ``paper34`` has no joint type: the root joint is ``free`` when it is the only joint
above the root link, unlimited (``max(|lo|, |hi|) <`` :data:`RANGE_ZERO`) and its axis points
along +z within 25° (``axis_z / |axis| ≥`` :data:`FREE_AXIS_COS`) — MuJoCo compiles every free
joint to axis ``(0, 0, 1)``, position 0 and no range — and every other joint is a ``hinge``
(``paper34`` features cannot tell slides or balls from hinges).
"""

from __future__ import annotations

import math

import numpy as np

from robovae.data.features import GEOM, JOINT, JOINT_TYPES, LINK, FeatureSet
from robovae.data.tree_arrays import RobotTree
from robovae.generate.graph_view import GraphView, as_feature_set

__all__ = ["FREE_AXIS_COS", "RANGE_ZERO", "free_root_allowed", "joint_types", "link_structure",
           "moving_links", "subtree", "trunk", "view_joint_types"]

#: ``max(|lo|, |hi|)`` below this is an unlimited range (rad or m) where no ``limited`` flag
#: exists; every real limited joint or control range reaches at least 5e-3.
RANGE_ZERO = 1e-3
#: Cosine of the largest angle between a ``paper34`` root joint axis and +z for a free joint.
FREE_AXIS_COS = math.cos(math.radians(25.0))


def link_structure(parent: list[int], types: list[int]) -> tuple[list[int], list[list[int]]]:
    """For every node, its nearest ancestor link (``-1`` if none) and, for links, the joint nodes
    on the path from that ancestor (top-down): the joints MuJoCo puts in the link's body.

    Geom nodes are transparent (a joint below a geom still belongs to the path).
    """
    n = len(parent)
    anc = [-1] * n
    chain: list[list[int]] = [[] for _ in range(n)]
    pending: list[list[int]] = [[] for _ in range(n)]  # joints above node i, since its anc link
    for i in range(n):  # pre-order: parents come first
        p = parent[i]
        if p >= 0:
            anc[i] = p if types[p] == LINK else anc[p]
            above = [] if types[p] == LINK else pending[p]
        else:
            above = []
        if types[i] == LINK:
            chain[i] = list(above)
        elif types[i] == JOINT:
            pending[i] = [*above, i]
        else:
            pending[i] = list(above)
    return anc, chain


def subtree(kids: list[list[int]], i: int) -> list[int]:
    """Node ``i`` and its descendants, in pre-order."""
    out, stack = [], [i]
    while stack:
        n = stack.pop()
        out.append(n)
        stack.extend(reversed(kids[n]))
    return out


def moving_links(parent: list[int], types: list[int]) -> list[int]:
    """The link nodes with at least one joint in their body, in pre-order."""
    _, chain = link_structure(parent, types)
    return [i for i, t in enumerate(types) if t == LINK and chain[i]]


def free_root_allowed(parent: list[int], types: list[int]) -> bool:
    """Node 0 is a joint and the only joint of every link body it leads to (where MuJoCo
    accepts a free joint)."""
    if types[0] != JOINT:
        return False
    _, chain = link_structure(parent, types)
    return all(len(c) == 1 for c in chain if c and c[0] == 0)


def trunk(types: list[int], kids: list[list[int]]) -> int:
    """The first link reached from the root through joints (the first non-geom child at each
    step), or ``-1`` when there is none."""
    i = 0
    while types[i] != LINK:
        nxt = [c for c in kids[i] if types[c] != GEOM]
        if not nxt:
            return -1
        i = nxt[0]
    return i


def joint_types(data: RobotTree, feature_set: str | FeatureSet) -> list[str]:
    """MuJoCo joint type name (``free``/``ball``/``slide``/``hinge``) of every node, ``""`` for
    non-joint nodes: from the ``joint.type`` one-hot when the set has it, else inferred
    (module docstring)."""
    return view_joint_types(GraphView(data, as_feature_set(feature_set)))


def view_joint_types(v: GraphView) -> list[str]:
    """:func:`joint_types` of a :class:`~robovae.generate.graph_view.GraphView`."""
    out = [""] * len(v.types)
    if v.has("joint.type"):
        joints = v.nodes(JOINT)
        if joints:  # one arg-max over every joint's one-hot
            onehot = v.x[joints, v.fs.slice("joint.type")]
            best = np.argmax(np.nan_to_num(onehot, nan=-np.inf), axis=1)
            for i, k in zip(joints, best.tolist()):
                out[i] = JOINT_TYPES[k]
        return out
    for i in v.nodes(JOINT):
        out[i] = "hinge"
    if free_root_allowed(v.parent, v.types):
        rng = v.get(0, "joint.range")
        axis = v.get(0, "joint.axis")
        norm = float(np.linalg.norm(axis))
        unlimited = bool(np.all(np.abs(rng) < RANGE_ZERO))  # decoded zeros are not exact
        if unlimited and norm > 0 and axis[2] / norm >= FREE_AXIS_COS:
            out[0] = "free"
    return out
