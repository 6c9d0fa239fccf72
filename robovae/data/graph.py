"""Robot graphs as PyG ``Data`` trees, and their networkx twins.

A robot graph (SPEC §1) is a rooted tree whose nodes are stored in **canonical depth-first
pre-order**: node 0 is the root, ``parent[i] < i`` for every other node, and the children of a
node appear in the order they were declared in the file. Every ``Data`` carries:

========== ============ ======================================================
field      shape        meaning
========== ============ ======================================================
x          [N, d]       physical feature values (zero outside the node's columns)
x_mask     [N, d] bool  which columns belong to the node's type
edge_index [2, 2(N-1)]  undirected tree edges, both directions (paper §4.1)
parent     [N] long     parent index, root = -1
node_type  [N] long     0 link, 1 joint, 2 geom (``random<d>`` sets: 0 only)
depth      [N] long     distance from the root
name       str          robot name
source     str          file (or generator) it came from
========== ============ ======================================================

``parent`` holds per-graph indices and is **not** shifted when PyG batches graphs (the root's
-1 must stay -1): use :func:`global_parent` on a ``Batch``.
"""

from __future__ import annotations

from collections.abc import Sequence

import networkx as nx
import torch
from torch import Tensor
from torch_geometric.data import Data

from robovae.data.features import FeatureSet, get_feature_set
from robovae.data.tree_arrays import children


class RobotData(Data):
    """A PyG ``Data`` holding one robot graph (fields in the module docstring)."""


# cached datasets and checkpoints load with ``weights_only=True``: allow-list our Data class
torch.serialization.add_safe_globals([RobotData])


def global_parent(batch: Data) -> Tensor:
    """Parent indices into a ``Batch``'s node range (roots stay -1)."""
    parent = batch.parent
    if getattr(batch, "ptr", None) is None:
        return parent
    offset = batch.ptr[:-1][batch.batch]
    return torch.where(parent >= 0, parent + offset, parent)


def tree_data(
    parent: Sequence[int] | Tensor,
    node_type: Sequence[int] | Tensor,
    x: Tensor,
    feature_set: str | FeatureSet,
    name: str = "",
    source: str = "",
    **extra: object,
) -> RobotData:
    """Build a robot graph from a pre-order parent vector.

    Args:
        parent: ``parent[i]`` for each node, ``-1`` for the root (node 0 only), ``parent[i] < i``.
        node_type: node type id per node.
        x: ``[N, d]`` physical feature values.
        feature_set: the registry set the columns follow.
        name: robot name.
        source: where the robot came from (file or generator).
        **extra: further attributes to store (e.g. ``warnings``).

    Raises:
        ValueError: when ``parent`` is not a pre-order tree or shapes disagree.
    """
    fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
    parent_t = torch.as_tensor(parent, dtype=torch.long).view(-1)
    types = torch.as_tensor(node_type, dtype=torch.long).view(-1)
    n = parent_t.numel()
    if n == 0:
        raise ValueError("a robot graph needs at least one node")
    if x.shape != (n, fs.dim) or types.numel() != n:
        raise ValueError(f"shapes disagree: x {tuple(x.shape)}, {n} parents, {types.numel()} "
                         f"types, {fs.dim} columns in {fs.name}")
    idx = torch.arange(n)
    if parent_t[0] != -1 or (n > 1 and not bool((parent_t[1:] >= 0).all()
                                                 and (parent_t[1:] < idx[1:]).all())):
        raise ValueError("parent vector is not in depth-first pre-order")
    if not _is_preorder(parent_t.tolist()):
        raise ValueError("parent vector is not in depth-first pre-order")
    if bool(((types < 0) | (types >= fs.num_node_types)).any()):
        raise ValueError(f"node types must be in [0, {fs.num_node_types})")
    par_list, depth_list = parent_t.tolist(), [0] * n
    for i in range(1, n):
        depth_list[i] = depth_list[par_list[i]] + 1
    depth = torch.tensor(depth_list, dtype=torch.long)
    child, par = idx[1:], parent_t[1:]
    edge_index = torch.stack([torch.cat([par, child]), torch.cat([child, par])])
    mask = fs.mask(types)
    x = torch.where(mask, x.float(), torch.zeros((), dtype=torch.float32))
    return RobotData(x=x, x_mask=mask, edge_index=edge_index, parent=parent_t, node_type=types,
                     depth=depth, name=name, source=source, num_nodes=n, **extra)


def _is_preorder(parent: list[int]) -> bool:
    """True when nodes 0..N-1 are a depth-first pre-order of the tree ``parent`` describes."""
    stack = [0]
    for i in range(1, len(parent)):
        while stack and stack[-1] != parent[i]:
            stack.pop()
        if not stack:
            return False
        stack.append(i)
    return True


def to_networkx(data: Data) -> nx.DiGraph:
    """The tree as a ``networkx.DiGraph`` (parent → child edges, node attributes kept).

    Node attributes: ``node_type`` (int), ``x`` (list of floats), ``order`` (rank among
    siblings). Graph attributes: ``name``, ``source``.
    """
    g = nx.DiGraph(name=getattr(data, "name", ""), source=getattr(data, "source", ""))
    parent = data.parent.tolist()
    rank: dict[int, int] = {}
    for i, p in enumerate(parent):
        rank[p] = rank.get(p, -1) + 1
        g.add_node(i, node_type=int(data.node_type[i]), x=data.x[i].tolist(),
                   order=rank[p] if p >= 0 else 0)
        if p >= 0:
            g.add_edge(p, i)
    return g


def from_networkx(g: nx.DiGraph, feature_set: str | FeatureSet) -> RobotData:
    """Inverse of :func:`to_networkx`: re-index nodes in canonical pre-order."""
    roots = [n for n in g.nodes if g.in_degree(n) == 0]
    if len(roots) != 1 or not nx.is_arborescence(g):
        raise ValueError("graph is not a rooted tree")
    order: list = []
    stack = [roots[0]]
    while stack:
        n = stack.pop()
        order.append(n)
        kids = sorted(g.successors(n), key=lambda c: g.nodes[c].get("order", 0))
        stack.extend(reversed(kids))
    index = {n: i for i, n in enumerate(order)}
    parent = [-1] + [index[next(iter(g.predecessors(n)))] for n in order[1:]]
    types = [g.nodes[n]["node_type"] for n in order]
    x = torch.tensor([g.nodes[n]["x"] for n in order], dtype=torch.float32)
    return tree_data(parent, types, x, feature_set, name=g.graph.get("name", ""),
                     source=g.graph.get("source", ""))


def limbs(data: Data) -> int:
    """Number of limbs: subtrees leaving the root's link that contain at least one joint.

    For a floating-base robot the root is the free joint, so the trunk is its first link.
    """
    kids = children(data.parent)
    types = data.node_type.tolist()
    trunk = 0
    while types[trunk] != 0 and len(kids[trunk]) == 1:  # walk down root joints to the trunk
        trunk = kids[trunk][0]

    def has_joint(i: int) -> bool:
        return types[i] == 1 or any(has_joint(c) for c in kids[i])

    return sum(has_joint(c) for c in kids[trunk])


def describe(data: Data, feature_set: str | FeatureSet | None = None) -> str:
    """A short multi-line description: counts per node type, depth, limbs, features."""
    n_types = int(data.node_type.max()) + 1 if data.num_nodes else 0
    names = (get_feature_set(feature_set).node_types if isinstance(feature_set, str)
             else feature_set.node_types if feature_set is not None
             else ("link", "joint", "geom")[: max(n_types, 1)])
    counts = torch.bincount(data.node_type, minlength=len(names)).tolist()
    parts = ", ".join(f"{c} {t}s" for t, c in zip(names, counts))
    return (f"{getattr(data, 'name', '') or '<robot>'}: {data.num_nodes} nodes ({parts}), "
            f"depth {int(data.depth.max())}, {limbs(data)} limbs, {data.x.shape[1]} features")
