"""Tree encoder: level schedule, equality with the naive per-edge encoder, batching invariance."""

from __future__ import annotations

import gc
import random
import weakref

import pytest
import torch
from torch_geometric.data import Batch

from robovae.data.graph import children
from robovae.model.encoder import TreeEncoder, encode_reference, reparametrize
from robovae.model.messages import level_messages, level_messages_reference
from robovae.model.tree import TreeGRUCell, exclusive_sibling_prefix, tree_schedule
from tests.conftest import random_shape as random_tree


def varied_trees(count: int, seed: int = 0, fs: str = "full") -> list:
    rng = random.Random(seed)
    trees = [random_tree(1, rng, fs=fs), random_tree(40, rng, pop=0.0, fs=fs),
             random_tree(12, rng, pop=1.0, fs=fs)]
    while len(trees) < count:
        trees.append(random_tree(rng.randint(2, 40), rng, pop=rng.random(), fs=fs))
    return trees


def test_schedule_matches_naive() -> None:
    trees = varied_trees(10, seed=1)
    batch = Batch.from_data_list(trees)
    s = tree_schedule(batch)
    off = 0
    for t in trees:
        kids = children(t.parent)
        n = t.num_nodes
        assert s.num_children[off:off + n].tolist() == [len(k) for k in kids]
        for ks in kids:
            for r, c in enumerate(ks):
                assert int(s.rank[off + c]) == r
        size = [1] * n
        for i in reversed(range(1, n)):
            size[t.parent[i]] += size[i]
        assert s.size[off:off + n].tolist() == size
        off += n
    for lv, nodes in enumerate(s.levels):
        assert bool((s.depth[nodes] == lv).all()) and bool((nodes.diff() > 0).all())
        assert torch.equal(s.pos[nodes], torch.arange(nodes.numel()))
    assert torch.equal(s.gather([s.depth[lv] for lv in s.levels]), s.depth)


def test_exclusive_sibling_prefix() -> None:
    vals = torch.arange(1.0, 7.0)[:, None]
    groups, rank = torch.tensor([0, 0, 0, 1, 2, 2]), torch.tensor([0, 1, 2, 0, 0, 1])
    out = exclusive_sibling_prefix(vals, groups, rank, 3, 2)
    assert out.flatten().tolist() == [0.0, 1.0, 3.0, 0.0, 0.0, 5.0]


@pytest.mark.parametrize("seed", [0, 1])
def test_matches_reference(seed: int) -> None:
    torch.manual_seed(seed)
    enc = TreeEncoder(62, 32, 8, 4)
    for t in varied_trees(8, seed=seed):
        mu, logvar = enc(t)
        mu_r, logvar_r = encode_reference(enc, t)
        torch.testing.assert_close(mu, mu_r, atol=1e-5, rtol=1e-5)
        torch.testing.assert_close(logvar, logvar_r, atol=1e-5, rtol=1e-5)


def test_batching_invariance() -> None:
    torch.manual_seed(0)
    enc = TreeEncoder(62, 32, 8, 4).eval()
    trees = varied_trees(64, seed=3)
    mu, logvar = enc(Batch.from_data_list(trees))
    assert mu.shape == (64, 8) == logvar.shape
    for i, t in enumerate(trees):
        m1, l1 = enc(Batch.from_data_list([t]))
        torch.testing.assert_close(mu[i:i + 1], m1, atol=1e-5, rtol=0)
        torch.testing.assert_close(logvar[i:i + 1], l1, atol=1e-5, rtol=0)


def test_single_data_and_leaf_readout() -> None:
    torch.manual_seed(0)
    enc = TreeEncoder(5, 16, 4, 4)
    t = random_tree(1, random.Random(0), fs="random5")
    mu, _ = enc(t)  # a plain Data (no batch vector) works
    xp = enc.proj(t.x)
    h = torch.relu(enc.W_e(xp) + enc.U_e(torch.zeros_like(xp)))  # the root is the only leaf
    torch.testing.assert_close(mu, enc.mu(h))


def test_reparametrize() -> None:
    mu, logvar = torch.randn(4, 3), torch.full((4, 3), -60.0)
    torch.testing.assert_close(reparametrize(mu, logvar), mu)
    assert not torch.equal(reparametrize(mu, torch.zeros(4, 3)), mu)


def test_bad_depth_raises() -> None:
    t = random_tree(5, random.Random(0))
    t.depth = t.depth.clone()
    t.depth[3] += 1
    with pytest.raises(ValueError, match="pre-order"):
        tree_schedule(t)


@pytest.mark.parametrize("num_cells,num_encoder", [(2, 1), (1, 1), (1, 0), (2, 2), (3, 1)])
@pytest.mark.parametrize("kind", ["varied", "single_node", "stars"])
def test_level_messages_match_autograd_reference(num_cells: int, num_encoder: int,
                                                 kind: str) -> None:
    """The hand-written backward of the stacked level passes equals autograd through the plain
    per-cell implementation (float64: values and the gradients of every input and weight)."""
    rng = random.Random(7)
    trees = {"varied": varied_trees(12, seed=5),
             "single_node": [random_tree(1, rng), random_tree(1, rng)],
             "stars": [random_tree(6, rng, pop=1.0), random_tree(1, rng),
                       random_tree(9, rng, pop=1.0)]}[kind]
    sched = tree_schedule(Batch.from_data_list(trees))
    torch.manual_seed(0)
    hid = 6
    cells = [TreeGRUCell(hid).double() for _ in range(num_cells)]
    px = torch.randn(num_cells, sched.num_nodes, 3 * hid, dtype=torch.double,
                     requires_grad=True)
    weights = [torch.randn(num_cells, sched.num_nodes, hid, dtype=torch.double)
               for _ in range(3)]
    params = [px, *(p for cell in cells for p in cell.parameters())]
    results = []
    for fn in (level_messages, level_messages_reference):
        outs = fn(cells, px, sched, num_encoder)
        loss = sum((o * w).sum() for o, w in zip(outs, weights)) + 0.0 * px.sum()
        grads = torch.autograd.grad(loss, params, allow_unused=True)
        results.append((outs, [torch.zeros_like(p) if g is None else g
                               for g, p in zip(grads, params)]))
    (outs, grads), (outs_ref, grads_ref) = results
    for a, b in zip(outs, outs_ref):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)
    for a, b in zip(grads, grads_ref):
        torch.testing.assert_close(a, b, atol=1e-9, rtol=1e-9)


def test_level_messages_free_their_outputs_without_the_cycle_collector() -> None:
    """A training step's message tensors are freed by reference counting alone: nothing of the
    pass keeps its own outputs alive through a reference cycle (which piled up megabytes per
    step until Python's rare full garbage collection)."""
    sched = tree_schedule(Batch.from_data_list(varied_trees(6, seed=1)))
    cells = [TreeGRUCell(8), TreeGRUCell(8)]
    px = torch.randn(2, sched.num_nodes, 24, requires_grad=True)
    gc.collect()
    gc.disable()
    try:
        outs = level_messages(cells, px, sched, 1)
        refs = [weakref.ref(o) for o in outs]
        sum(o.sum() for o in outs).backward()
        del outs
        assert all(r() is None for r in refs)
        outs = level_messages(cells, px, sched, 1)  # also when backward never runs
        refs = [weakref.ref(o) for o in outs]
        del outs
        assert all(r() is None for r in refs)
    finally:
        gc.enable()
