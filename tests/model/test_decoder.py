"""Tree decoder: DFS-trace labels, greedy decoding limits (decode == teacher forcing and the
gradients: tests/model/test_node_latents.py)."""

from __future__ import annotations

import random

import pytest
import torch
from torch_geometric.data import Batch

from robovae.data.features import get_feature_set
from robovae.data.graph import _is_preorder, children, tree_data
from robovae.model.decoder import TreeDecoder
from tests.conftest import random_shape as random_tree

FULL = get_feature_set("full")


def random_batch(count: int = 8, max_nodes: int = 25, seed: int = 0) -> Batch:
    """``count`` random trees of 1..``max_nodes`` nodes and random shapes, batched."""
    rng = random.Random(seed)
    return Batch.from_data_list([random_tree(rng.randint(1, max_nodes), rng, rng.random())
                                 for _ in range(count)])


def dfs_trace(parent: list[int]) -> list[tuple[int, int]]:
    """(deciding node, label) of the true depth-first expand/backtrack sequence."""
    kids, out = children(parent), []

    def visit(i: int) -> None:
        for c in kids[i]:
            out.append((i, 1))
            visit(c)
        out.append((i, 0))

    visit(0)
    return out


def make_decoder(seed: int = 0, **kw) -> TreeDecoder:
    torch.manual_seed(seed)
    return TreeDecoder(FULL.dim, 3, 32, 8, 6, type_mask=FULL.type_mask(), **kw).eval()


def test_teacher_forcing_labels_follow_dfs() -> None:
    rng = random.Random(0)
    trees = [random_tree(1, rng), random_tree(20, rng, 0.0), random_tree(9, rng, 1.0)]
    trees += [random_tree(rng.randint(2, 30), rng, rng.random()) for _ in range(10)]
    batch = Batch.from_data_list(trees)
    dec = make_decoder()
    out = dec.teacher_forcing(torch.randn(len(trees), 8), batch, torch.randn(batch.num_nodes, 6))
    n = batch.num_nodes
    assert out.topo_logits.shape == out.topo_target.shape == (2 * n - len(trees),)
    assert out.feat_pred.shape == (n, FULL.dim) and out.type_logits.shape == (n, 3)
    for g, t in enumerate(trees):
        sel = out.topo_graph == g
        node = (out.topo_node[sel] - batch.ptr[g]).tolist()
        assert list(zip(node, out.topo_target[sel].long().tolist())) == dfs_trace(
            t.parent.tolist())
    assert bool((out.topo_graph.diff() >= 0).all())


def check_tree(parent: torch.Tensor, types: torch.Tensor, x: torch.Tensor, max_nodes: int,
               max_depth: int) -> int:
    """Assert a decoded tree is a valid pre-order tree within the limits; return its depth."""
    n = parent.numel()
    assert 1 <= n <= max_nodes and types.shape == (n,) and x.shape == (n, FULL.dim)
    assert parent[0] == -1 and _is_preorder(parent.tolist())
    assert bool((types >= 0).all() and (types < 3).all())
    t = tree_data(parent, types, torch.nan_to_num(x), FULL)
    depth = int(t.depth.max())
    assert depth <= max_depth
    return depth


@pytest.mark.parametrize("bias", [50.0, 0.0, -50.0])
def test_decode_respects_limits(bias: float) -> None:
    dec = make_decoder()
    with torch.no_grad():
        dec.topo.u.bias.add_(bias)
    scale = torch.tensor([1.0, 3.0, 1e6, 1e30] * 3)
    z = torch.randn(12, 8) * scale[:, None]
    out = dec.decode(z, max_nodes=40, max_depth=5)
    assert len(out) == 12
    for (p, t, x), s in zip(out, scale.tolist()):
        depth = check_tree(p, t, x, 40, 5)
        if bias > 0 and s < 10:  # always expands: fills the budget, never deeper than allowed
            assert p.numel() == 40 and depth == 5
        if bias < 0 and s < 10:  # never expands (huge latents overwhelm any bias)
            assert p.numel() == 1
    assert len(dec.decode(z[0])) == 1  # a single latent vector
    assert dec.decode(z[:2], max_nodes=1)[0][0].tolist() == [-1]


def test_decode_in_a_batch_is_decoding_alone() -> None:
    """Trees that outgrow the node buffer (64 nodes a latent at first, then doubled), decoded
    in a batch and one at a time after other work (the buffer's memory is not cleared: each
    node's child sums must start at zero as it is added): the same trees, the same features
    but for the last bits of float64 sums (a batch's matrix products)."""
    dec = make_decoder().double()
    with torch.no_grad():
        dec.topo.u.bias.add_(2.0)
    z = torch.randn(6, 8, dtype=torch.float64) * torch.tensor([0.5, 1, 2, 4, 8, 16])[:, None]
    together = dec.decode(z, max_nodes=150, max_depth=6)
    assert max(p.numel() for p, _, _ in together) > 64  # some trees grew the buffer
    for k in range(len(z)):
        dec.decode(torch.randn(3, 8, dtype=torch.float64), max_nodes=30)  # memory to reuse
        (p, t, x), = dec.decode(z[k], max_nodes=150, max_depth=6)
        assert torch.equal(p, together[k][0]) and torch.equal(t, together[k][1])
        torch.testing.assert_close(x, together[k][2], rtol=0.0, atol=1e-9)


def test_decode_rejects_nonfinite() -> None:
    dec = make_decoder()
    z = torch.zeros(3, 8)
    z[1, 2] = float("nan")
    with pytest.raises(ValueError, match="rows \\[1\\]"):
        dec.decode(z)
    z[1, 2] = float("inf")
    with pytest.raises(ValueError, match="finite"):
        dec.decode(z)


def assert_decoded_as_scored(out, trees: list, max_nodes: int, max_depth: int) -> None:
    """Teacher forcing on decoded ``trees`` (``out``) predicts their features and types and
    makes their decisions: every expansion a "yes", every backtrack of an untruncated tree a
    "no"."""
    mask = FULL.type_mask()[torch.cat([t.node_type for t in trees])]
    torch.testing.assert_close(torch.where(mask, out.feat_pred, 0.0),
                               torch.cat([t.x for t in trees]), atol=1e-5, rtol=1e-5)
    assert torch.equal(out.type_logits.argmax(-1), torch.cat([t.node_type for t in trees]))
    expand = out.topo_target == 1
    assert bool((out.topo_logits[expand] > 0).all())
    for g, t in enumerate(trees):
        if t.num_nodes < max_nodes and int(t.depth.max()) < max_depth:
            sel = (out.topo_graph == g) & ~expand
            assert bool((out.topo_logits[sel] <= 0).all())
