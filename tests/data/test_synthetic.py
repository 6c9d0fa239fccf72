"""Tests of the paper's synthetic random-tree dataset."""

from __future__ import annotations

import itertools
import random

import networkx as nx
import pytest
import torch

from robovae.data.graph import RobotData, _is_preorder, tree_data
from robovae.data.synthetic import (
    SOURCE,
    canonical_form,
    is_isomorphic,
    prufer_to_parent,
    random_tree,
    random_trees,
    unseen_random_tree,
)


def undirected(parent: list[int] | torch.Tensor) -> nx.Graph:
    par = parent.tolist() if isinstance(parent, torch.Tensor) else list(parent)
    g = nx.Graph()
    g.add_nodes_from(range(len(par)))
    g.add_edges_from((i, p) for i, p in enumerate(par) if p >= 0)
    return g


def shuffled_preorder(g: nx.Graph, root: int, rnd: random.Random) -> list[int]:
    """Pre-order parent vector of ``g`` rooted at ``root``, children in random order."""
    parent: list[int] = []
    index: dict[int, int] = {}
    stack = [(root, None)]
    while stack:
        u, p = stack.pop()
        index[u] = len(parent)
        parent.append(-1 if p is None else index[p])
        kids = [v for v in g[u] if v != p]
        rnd.shuffle(kids)
        stack.extend((v, u) for v in kids)
    return parent


def test_random_tree_contract() -> None:
    t = random_tree(15, 5, 7)
    assert t.num_nodes == 15
    assert t.x.shape == (15, 5) and t.x.dtype == torch.float32
    assert bool(((t.x >= 0) & (t.x <= 1)).all())
    assert t.node_type.tolist() == [0] * 15
    assert bool(t.x_mask.all())
    assert t.parent[0] == -1 and _is_preorder(t.parent.tolist())
    assert t.edge_index.shape == (2, 28)
    assert nx.is_tree(undirected(t.parent))
    assert t.source == SOURCE == "synthetic:random"
    assert t.name == "random_tree_7"


def test_random_tree_determinism() -> None:
    a, b = random_tree(12, 3, 5), random_tree(12, 3, 5)
    assert torch.equal(a.parent, b.parent) and torch.equal(a.x, b.x)
    g1, g2 = torch.Generator().manual_seed(5), torch.Generator().manual_seed(5)
    c, d = random_tree(12, 3, g1), random_tree(12, 3, g2)
    assert torch.equal(c.parent, d.parent) and torch.equal(c.x, d.x)
    assert not torch.equal(random_tree(12, 3, g1).x, c.x)  # the generator advanced


@pytest.mark.parametrize("n", [1, 2, 3])
def test_tiny_trees(n: int) -> None:
    t = random_tree(n, 2, 0)
    assert t.num_nodes == n and t.parent.tolist() == list(range(-1, n - 1))


def test_random_trees_paper_dataset() -> None:
    trees = random_trees(20)
    assert len(trees) == 20
    assert all(t.num_nodes == 15 and t.x.shape == (15, 5) for t in trees)
    assert [t.name for t in trees[:2]] == ["random_tree_0_0", "random_tree_0_1"]
    again = random_trees(20)
    assert all(torch.equal(a.parent, b.parent) and torch.equal(a.x, b.x)
               for a, b in zip(trees, again))
    other = random_trees(20, seed=1)
    assert any(not torch.equal(a.parent, b.parent) for a, b in zip(trees, other))
    prefix = random_trees(5)  # prefix-stable stream
    assert all(torch.equal(a.x, b.x) for a, b in zip(prefix, trees))
    assert len({canonical_form(t) for t in trees}) > 15  # 7741 shapes: collisions are rare


def test_prufer_decoding_matches_networkx() -> None:
    rnd = random.Random(0)
    for n in range(3, 12):
        for _ in range(20):
            seq = [rnd.randrange(n) for _ in range(n - 2)]
            parent = prufer_to_parent(seq, n)
            assert _is_preorder(parent)
            assert nx.is_isomorphic(undirected(parent), nx.from_prufer_sequence(seq))
    assert prufer_to_parent([0, 0, 0], 5) == [-1, 0, 0, 0, 0]  # star
    assert prufer_to_parent([1, 2, 3], 5) == [-1, 0, 1, 2, 3]  # path 0-1-2-3-4
    with pytest.raises(ValueError):
        prufer_to_parent([5], 3)


def test_shapes_are_uniform_over_labelled_trees() -> None:
    # 16 labelled trees on 4 nodes: 4 stars, 12 paths
    g = torch.Generator().manual_seed(0)
    trees = [random_tree(4, 1, g) for _ in range(2000)]
    star = canonical_form([-1, 0, 0, 0])
    stars = sum(canonical_form(t) == star for t in trees)
    assert 0.2 < stars / 2000 < 0.3


def test_isomorphism_positive_cases() -> None:
    rnd = random.Random(1)
    for _ in range(20):
        n = rnd.randrange(2, 16)
        seq = [rnd.randrange(n) for _ in range(n - 2)]
        a = prufer_to_parent(seq, n, root=0)
        b = prufer_to_parent(seq, n, root=rnd.randrange(n))  # same tree, another root
        assert is_isomorphic(a, b)
        # same undirected tree, random root and random child order
        c = shuffled_preorder(undirected(a), rnd.randrange(n), rnd)
        assert _is_preorder(c) and is_isomorphic(a, c)
    t = random_tree(15, 5, 3)
    assert is_isomorphic(t, t.parent) and is_isomorphic(t, random_tree(15, 5, 3))


def test_isomorphism_negative_cases() -> None:
    star, path = [-1, 0, 0, 0, 0], [-1, 0, 1, 2, 3]
    assert not is_isomorphic(star, path)
    assert not is_isomorphic([-1, 0, 1], [-1, 0, 1, 2])
    # same degree sequence, different trees
    a = [-1, 0, 1, 2, 3, 2, 1]  # path 0-1-2-3-4, extra leaves on 1 and 2 (adjacent)
    b = [-1, 0, 1, 2, 3, 1, 3]  # path 0-1-2-3-4, extra leaves on 1 and 3 (distance 2)
    assert sorted(d for _, d in undirected(a).degree) == sorted(d for _, d in undirected(b).degree)
    assert not is_isomorphic(a, b)


def test_isomorphism_agrees_with_networkx() -> None:
    trees = random_trees(60, num_nodes=7, dim=1, seed=2)
    for a, b in itertools.combinations(trees, 2):
        assert is_isomorphic(a, b) == nx.is_isomorphic(undirected(a.parent), undirected(b.parent))


def test_unseen_random_tree_is_unseen() -> None:
    train = random_trees(20)
    t = unseen_random_tree(train, 15, 5, seed=123)
    assert t.num_nodes == 15 and t.x.shape == (15, 5) and t.source == SOURCE
    assert not any(nx.is_isomorphic(undirected(t.parent), undirected(s.parent)) for s in train)
    again = unseen_random_tree(train, 15, 5, seed=123)
    assert torch.equal(t.parent, again.parent) and torch.equal(t.x, again.x)


def test_unseen_random_tree_finds_the_missing_shape() -> None:
    # 5 nodes have 3 unlabelled trees: path, star, "chair"; train on the first two
    path, star, chair = [-1, 0, 1, 2, 3], [-1, 0, 0, 0, 0], [-1, 0, 1, 2, 1]
    t = unseen_random_tree([_d(path), _d(star)], 5, 2, seed=0)
    assert is_isomorphic(t, chair)
    with pytest.raises(RuntimeError):
        unseen_random_tree([_d(path), _d(star), _d(chair)], 5, 2, seed=0, max_tries=200)


def _d(parent: list[int]) -> RobotData:
    """A ``random2`` tree with the given parent vector and zero features."""
    n = len(parent)
    return tree_data(parent, [0] * n, torch.zeros(n, 2), "random2")


@pytest.mark.parametrize("call, bad", [
    (lambda: random_trees(-1), "random_trees.num_graphs"),
    (lambda: random_trees(2, num_nodes=0), "random_trees.num_nodes"),
    (lambda: random_trees(2, dim=0), "random_trees.dim"),  # was a KeyError of feature sets
    (lambda: random_trees(2, dim=-1), "random_trees.dim"),  # was a torch RuntimeError
    (lambda: random_trees(2, seed=-1), "random_trees seed"),
    (lambda: random_tree(0, 5, 0), "random_tree.num_nodes"),
    (lambda: random_tree(3, 5, -2), "random_tree seed"),
    (lambda: unseen_random_tree([], 5, seed=0, max_tries=0), "unseen_random_tree.max_tries"),
])
def test_random_trees_refuse_bad_arguments_in_one_line(call, bad) -> None:
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match=bad):
        call()


def test_unseen_tree_of_the_largest_seed() -> None:
    """``synthetic:…,seed=2147483647,unseen=1`` draws its unseen tree from seed 0 (the next seed
    wraps round), not from a seed out of range."""
    from robovae.data.sources import resolve_sources

    graphs = resolve_sources(["synthetic:n=3,nodes=6,seed=2147483647,unseen=1"]).graphs
    assert len(graphs) == 4 and graphs[-1].name == "random_unseen"
