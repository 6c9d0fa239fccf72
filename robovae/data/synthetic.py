"""The paper's synthetic dataset: random trees with random node features.

The paper trains on "20 random graphs of 15 nodes each with five-dimensional feature vectors
with random values between 0 and 1". :func:`random_trees` reproduces it: every tree is a
uniformly random *labelled* tree (a random Prüfer sequence), rooted at label 0, stored in
canonical depth-first pre-order (children visited in increasing original label), with one node
type (``0``) and features drawn uniformly from ``[0, 1)`` under the ``random<d>`` feature set.

Isomorphism (:func:`is_isomorphic`) is **unrooted, undirected** tree isomorphism that ignores
child order, node types and features — the paper's graphs are undirected, so two trees that
differ only in where they are rooted count as the same graph. It is decided by comparing
canonical forms (:func:`canonical_form`): the AHU encoding of the tree rooted at its centre
(the smaller encoding of the two when the tree has two centres). This agrees with
``networkx.is_isomorphic`` on the undirected trees and runs in ``O(N log N)``.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Sequence

import torch
from torch import Tensor

from robovae.data.graph import RobotData, tree_data
from robovae.errors import check_seed
from robovae.settings import check_settings, integer

__all__ = [
    "SOURCE",
    "canonical_form",
    "is_isomorphic",
    "prufer_to_parent",
    "random_tree",
    "random_trees",
    "unseen_random_tree",
]

#: ``source`` of every synthetic tree.
SOURCE = "synthetic:random"


def _as_generator(generator: torch.Generator | int) -> torch.Generator:
    if isinstance(generator, torch.Generator):
        return generator
    g = torch.Generator()
    g.manual_seed(int(generator))
    return g


def _prufer_edges(seq: Sequence[int], n: int) -> list[tuple[int, int]]:
    """Edges of the labelled tree on ``0..n-1`` encoded by the Prüfer sequence ``seq``."""
    if n == 1:
        return []
    degree = [1] * n
    for v in seq:
        degree[v] += 1
    leaves = [u for u in range(n) if degree[u] == 1]
    heapq.heapify(leaves)
    edges = []
    for v in seq:  # join the smallest leaf to the next label of the sequence
        leaf = heapq.heappop(leaves)
        edges.append((leaf, v))
        degree[v] -= 1
        if degree[v] == 1:
            heapq.heappush(leaves, v)
    edges.append((heapq.heappop(leaves), heapq.heappop(leaves)))
    return edges


def prufer_to_parent(seq: Sequence[int], n: int, root: int = 0) -> list[int]:
    """Pre-order parent vector of the Prüfer-encoded labelled tree, rooted at ``root``.

    Nodes are re-indexed in depth-first pre-order from ``root``, visiting children in increasing
    original label, so ``parent[0] == -1`` and ``parent[i] < i``.

    Args:
        seq: Prüfer sequence of length ``n - 2`` with entries in ``[0, n)``.
        n: number of nodes (``>= 1``).
        root: original label of the root.
    """
    if n < 1:
        raise ValueError("a tree needs at least one node")
    if len(seq) != max(n - 2, 0) or any(not 0 <= v < n for v in seq):
        raise ValueError(f"not a Prüfer sequence for {n} nodes: {list(seq)}")
    adj: list[list[int]] = [[] for _ in range(n)]
    for u, v in _prufer_edges(seq, n):
        adj[u].append(v)
        adj[v].append(u)
    parent: list[int] = []
    index: dict[int, int] = {}
    stack: list[tuple[int, int]] = [(root, -1)]  # (label, parent label)
    while stack:
        u, p = stack.pop()
        index[u] = len(parent)
        parent.append(index[p] if p >= 0 else -1)
        stack.extend((c, u) for c in sorted((c for c in adj[u] if c != p), reverse=True))
    return parent


def random_tree(
    num_nodes: int,
    dim: int,
    generator: torch.Generator | int,
    name: str | None = None,
) -> RobotData:
    """A uniformly random labelled tree with uniform ``[0, 1)`` features.

    The tree comes from a uniformly random Prüfer sequence (so every labelled tree on
    ``num_nodes`` nodes is equally likely), is rooted at label 0 and stored in canonical
    pre-order (children in increasing original label). All nodes have type 0.

    Args:
        num_nodes: number of nodes ``N >= 1``.
        dim: feature dimension ``d`` (feature set ``random<d>``).
        generator: a ``torch.Generator`` (advanced in place) or an integer seed.
        name: robot name; defaults to ``random_tree_<seed>`` for an integer seed, else
            ``random_tree``.

    Returns:
        a :class:`RobotData` with ``x`` of shape ``[N, d]`` and ``source="synthetic:random"``.

    Raises:
        SettingsError: ``num_nodes`` or ``dim`` below 1, an integer seed outside
            ``[0, 2**31 - 1]``.
    """
    check_settings("random_tree", num_nodes=(num_nodes, integer(1)), dim=(dim, integer(1)))
    if not isinstance(generator, torch.Generator):
        check_seed(generator, "random_tree seed")
    if name is None:
        name = ("random_tree" if isinstance(generator, torch.Generator)
                else f"random_tree_{generator}")
    return _draw_tree(num_nodes, dim, _as_generator(generator), name)


def _draw_tree(num_nodes: int, dim: int, g: torch.Generator, name: str) -> RobotData:
    """:func:`random_tree` once its arguments are checked (the loops below check them once)."""
    seq = torch.randint(0, num_nodes, (max(num_nodes - 2, 0),), generator=g).tolist()
    x = torch.rand(num_nodes, dim, generator=g)
    parent = prufer_to_parent(seq, num_nodes)
    return tree_data(parent, [0] * num_nodes, x, f"random{dim}", name=name, source=SOURCE)


def random_trees(
    num_graphs: int, num_nodes: int = 15, dim: int = 5, seed: int = 0
) -> list[RobotData]:
    """The synthetic dataset: ``num_graphs`` random trees (defaults: the paper's 15 nodes, d=5).

    Deterministic for a seed, and a prefix-stable stream: the first ``k`` trees of
    ``random_trees(n, seed=s)`` are ``random_trees(k, seed=s)``. Tree ``i`` is named
    ``random_tree_<seed>_<i>``.

    Raises:
        SettingsError: ``num_graphs`` negative, ``num_nodes`` or ``dim`` below 1, ``seed``
            outside ``[0, 2**31 - 1]``.
    """
    check_settings("random_trees", num_graphs=(num_graphs, integer(0)),
                   num_nodes=(num_nodes, integer(1)), dim=(dim, integer(1)))
    check_seed(seed, "random_trees seed")
    g = _as_generator(seed)
    return [_draw_tree(num_nodes, dim, g, f"random_tree_{seed}_{i}") for i in range(num_graphs)]


def _parent_of(tree: RobotData | Tensor | Sequence[int]) -> list[int]:
    par = tree.parent if isinstance(tree, RobotData) or hasattr(tree, "parent") else tree
    return par.tolist() if isinstance(par, Tensor) else [int(p) for p in par]


def _centres(adj: list[list[int]]) -> list[int]:
    """The one or two centres of a tree (repeatedly strip leaves)."""
    n = len(adj)
    if n <= 2:
        return list(range(n))
    degree = [len(a) for a in adj]
    layer = [u for u in range(n) if degree[u] <= 1]
    left = n
    while left > 2:
        left -= len(layer)
        nxt = []
        for u in layer:
            for v in adj[u]:
                degree[v] -= 1
                if degree[v] == 1:
                    nxt.append(v)
        layer = nxt
    return layer


def _ahu(adj: list[list[int]], root: int) -> str:
    """AHU encoding of the tree rooted at ``root`` (children's codes sorted)."""
    order: list[tuple[int, int]] = []
    stack = [(root, -1)]
    while stack:
        u, p = stack.pop()
        order.append((u, p))
        stack.extend((v, u) for v in adj[u] if v != p)
    code: dict[int, str] = {}
    for u, p in reversed(order):  # children before parents
        code[u] = "(" + "".join(sorted(code[v] for v in adj[u] if v != p)) + ")"
    return code[root]


def canonical_form(tree: RobotData | Tensor | Sequence[int]) -> str:
    """A string equal for two trees exactly when they are isomorphic as unrooted trees.

    Child order, the chosen root, node types and features are ignored.

    Args:
        tree: a robot graph, or its parent vector (``-1`` for the root).
    """
    parent = _parent_of(tree)
    adj: list[list[int]] = [[] for _ in parent]
    for i, p in enumerate(parent):
        if p >= 0:
            adj[i].append(p)
            adj[p].append(i)
    return min(_ahu(adj, c) for c in _centres(adj))


def is_isomorphic(a: RobotData | Tensor | Sequence[int], b: RobotData | Tensor | Sequence[int]
                  ) -> bool:
    """Unrooted, undirected tree isomorphism of two trees (features and child order ignored).

    Equivalent to ``networkx.is_isomorphic`` on the undirected trees (see the module docstring).
    """
    return len(_parent_of(a)) == len(_parent_of(b)) and canonical_form(a) == canonical_form(b)


#: Unlabelled unrooted trees of ``n`` nodes, ``n = 0 … 12`` (OEIS A000055): a training set that
#: holds that many shapes of ``n`` nodes leaves none unseen.
TREE_SHAPES = (1, 1, 1, 1, 2, 3, 6, 11, 23, 47, 106, 235, 551)


def unseen_random_tree(
    train: Iterable[RobotData],
    num_nodes: int = 15,
    dim: int = 5,
    seed: int = 0,
    max_tries: int = 100_000,
) -> RobotData:
    """A random tree (as :func:`random_tree`) not isomorphic to any tree in ``train``.

    Trees are drawn from one generator seeded with ``seed`` until one's unrooted shape is not
    among the training shapes. The result is named ``random_tree_unseen_<seed>_<k>``, ``k``
    being the number of rejected draws.

    Raises:
        RuntimeError: when ``train`` holds every shape of ``num_nodes`` nodes
            (:data:`TREE_SHAPES`, at once), or ``max_tries`` draws were all seen.
        SettingsError: ``num_nodes``, ``dim`` or ``max_tries`` below 1, ``seed`` outside
            ``[0, 2**31 - 1]``.
    """
    check_settings("unseen_random_tree", num_nodes=(num_nodes, integer(1)),
                   dim=(dim, integer(1)), max_tries=(max_tries, integer(1)))
    check_seed(seed, "unseen_random_tree seed")
    shapes = {(t.num_nodes, canonical_form(t)) for t in train}
    seen = {form for _, form in shapes}
    if (num_nodes < len(TREE_SHAPES)
            and sum(n == num_nodes for n, _ in shapes) >= TREE_SHAPES[num_nodes]):
        raise RuntimeError(f"every tree shape of {num_nodes} nodes ({TREE_SHAPES[num_nodes]}) "
                           "is in training: none is unseen")
    g = _as_generator(seed)
    for k in range(max_tries):
        tree = _draw_tree(num_nodes, dim, g, f"random_tree_unseen_{seed}_{k}")
        if canonical_form(tree) not in seen:
            return tree
    raise RuntimeError(f"no tree of {num_nodes} nodes unseen in training after {max_tries} draws")
