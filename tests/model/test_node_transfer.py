"""Node latents carried by correspondence: a decoded tree's node takes the latent of the node it
shares with the encoded robot (the same place from the root, the same type), not of the node at
the same pre-order index; nodes no robot shares take their conditional prior mean."""

from __future__ import annotations

import math

import numpy as np
import torch
from torch_geometric.data import Batch

from robovae.data.tree_arrays import shared_nodes
from robovae.model.checkpoint import own_model
from robovae.model.node_transfer import EncodedRobot, carried_latents, decode_near

#  source:  0 (t0)                 target:     0 (t0)
#          /      \                           /   |    \
#       1 (t1)   3 (t1)                  1 (t1) 2 (t2)  4 (t1)
#         |        |                              |       |
#       2 (t0)   4 (t0)                         3 (t0)  5 (t0)
SOURCE = ([-1, 0, 1, 0, 3], [0, 1, 0, 1, 0])
TARGET = ([-1, 0, 0, 2, 0, 4], [0, 1, 2, 0, 1, 0])


def test_shared_nodes_are_the_same_place_and_type():
    assert shared_nodes(SOURCE, SOURCE).tolist() == [0, 1, 2, 3, 4]
    # target 2 sits where source 3 does, of another type: not shared; its child 3 sits where
    # source 4 does, of the same type: shared (the metrics' correct pairs ignore the parent's
    # type too); the root's third child (4) and its child have no place in the source
    assert shared_nodes(SOURCE, TARGET).tolist() == [0, 1, -1, 4, -1, -1]
    # a limb appended after the source's nodes leaves every earlier node shared
    longer = (SOURCE[0] + [0, 5], SOURCE[1] + [1, 0])
    assert shared_nodes(SOURCE, longer).tolist() == [0, 1, 2, 3, 4, -1, -1]
    # a limb inserted before others moves them in pre-order, not in place
    inserted = ([-1, 0, 1, 1, 0, 4], [0, 1, 0, 2, 1, 0])
    assert shared_nodes(SOURCE, inserted).tolist() == [0, 1, 2, -1, 3, 4]
    # tensors and arrays are taken as lists are
    assert shared_nodes((torch.tensor(SOURCE[0]), np.array(SOURCE[1])), SOURCE).tolist() == \
        [0, 1, 2, 3, 4]


def _robot(tree, nodes):
    return EncodedRobot(torch.zeros(3), torch.as_tensor(nodes, dtype=torch.float64), tree)


def test_carried_latents_average_the_robots_sharing_a_node():
    a = _robot(SOURCE, [[float(i), 0.0] for i in range(5)])
    b = _robot(TARGET, [[0.0, 10.0 + i] for i in range(6)])
    alone = [0, 1, 3]  # the target's nodes a shares (with a's nodes 0, 1, 4)
    w = carried_latents(TARGET, [a], [1.0])
    assert w[alone].tolist() == [[0.0, 0.0], [1.0, 0.0], [4.0, 0.0]]
    assert torch.isnan(w[[2, 4, 5]]).all()
    w = carried_latents(TARGET, [a, b], [0.75, 0.25])
    # nodes both robots have: weighted; the others only b: b's own
    want = 0.75 * a.nodes[[0, 1, 4]] + 0.25 * b.nodes[alone]
    assert torch.allclose(w[alone], want)
    assert torch.equal(w[[2, 4, 5]], b.nodes[[2, 4, 5]])
    # a robot of weight 0 carries nothing
    assert torch.isnan(carried_latents(TARGET, [a, b], [1.0, 0.0])[[2, 4, 5]]).all()


def test_nan_node_latents_take_the_conditional_prior_mean(trained_nodes):
    model, dm, _ = trained_nodes
    model = own_model(model).to(torch.float64)
    mu, (w,) = model.encode_nodes(Batch.from_data_list([dm.dataset.by_name("gym_ant")]))
    from_z = model.decode(mu, clamp=False)[0]
    nan = model.decode(mu, node_latents=[torch.full_like(w, math.nan)], clamp=False)[0]
    assert torch.equal(nan.x, from_z.x)
    # NaN rows among given ones: those nodes as from z, the others as given
    part = w.clone()
    part[1:] = math.nan
    mixed = model.decode(mu, node_latents=[part], clamp=False)[0]
    full = model.decode(mu, node_latents=[w], clamp=False)[0]
    assert torch.equal(mixed.x[0], full.x[0]) and torch.equal(mixed.x[1:], from_z.x[1:])


def _variant(parent: list[int], types: list[int]) -> tuple[list[int], list[int]] | None:
    """A tree that shares all but the last node of ``(parent, types)``, most of them under
    other pre-order indices: a leaf added as the last child of the first node ``a`` whose
    subtree at least two nodes follow (they move one place on), and the last node's type
    changed; None when no node has such a subtree."""
    n = len(parent)
    for a in range(1, n):
        end = a + 1
        while end < n and _under(parent, end, a):
            end += 1
        if n - end >= 2:
            new_parent = parent[:end] + [a] + [p + (p >= end) for p in parent[end:]]
            new_types = types[:end] + [types[a]] + types[end:]
            new_types[-1] = max(types) + 1
            return new_parent, new_types
    return None


def _under(parent: list[int], i: int, a: int) -> bool:
    """Node ``i`` lies in the subtree of node ``a`` (pre-order)."""
    while i > a:
        i = parent[i]
    return i == a


def test_decode_near_carries_a_robots_latents_onto_another_tree(trained_nodes):
    """A latent's tree differs from the robot's: each node takes the robot's latent of the node
    it shares, which sits at another pre-order index, and the node the robot lacks its prior
    mean (pre-order pairing would hand each node its neighbour's latent)."""
    model, dm, _ = trained_nodes
    model = own_model(model).to(torch.float64)
    for name in dm.dataset.names:
        mu, _ = model.encode_nodes(Batch.from_data_list([dm.dataset.by_name(name)]))
        tree = model.decode(mu, clamp=False)[0]
        variant = _variant(tree.parent.tolist(), tree.node_type.tolist())
        if variant is not None:
            break
    assert variant is not None, "no decoded tree with two nodes after a subtree"
    w = torch.randn(len(variant[0]), model.hparams.node_latent_dim, dtype=torch.float64,
                    generator=torch.Generator().manual_seed(0))
    robot = EncodedRobot(mu[0], w, tuple(torch.tensor(v) for v in variant))
    near = decode_near(model, mu, [robot])[0]
    assert torch.equal(near.parent, tree.parent) and torch.equal(near.node_type, tree.node_type)
    shared = shared_nodes(robot.tree, (tree.parent, tree.node_type))
    n = len(shared)
    assert shared[-1] == -1 and (shared[:-1] >= 0).all()
    assert (shared[:-1] != np.arange(n - 1)).any()  # not the pre-order pairing
    rows = torch.full((n, w.shape[1]), math.nan, dtype=w.dtype)
    rows[:-1] = w[torch.from_numpy(shared[:-1])]
    assert torch.equal(near.x, model.decode(mu, node_latents=[rows], clamp=False)[0].x)
    assert not torch.equal(near.x, model.decode(mu, node_latents=[w[:n]], clamp=False)[0].x)
