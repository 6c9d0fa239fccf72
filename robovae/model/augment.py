"""Training-time augmentation: feature jitter (new robots with the same trees) and tree
surgery (new trees from the limbs of the batch's robots).

The paper's 4-robot failure (§5: the unseen Go2 decoded with an extra limb) and our 2-robot one
(Go2 decoded with a limb missing) have one cause: with a handful of training robots, each
robot's latent is a point, and the decoder's topology decisions are only trained at those
points. An unseen robot of a known shape (Go2 is Go1's tree with other masses, lengths and
inertias) encodes elsewhere, and the decisions there are arbitrary.

:func:`jitter_features` perturbs the normalised features of a batch, as if the robot were
redesigned: a per-robot offset on every column (all link masses of a robot scaled by one factor
through the log transform, all joint dampings by another, ...), plus small per-node noise. The
encoder input, the decoder's teacher-forced inputs and the reconstruction targets all get the
same perturbed values, so the model learns to (1) keep the tree when only the features change,
and (2) carry feature values through ``z`` instead of memorising them per robot.
Categorical (one-hot) columns are left alone; a node's foreign columns stay zero.
"""

from __future__ import annotations

import random
from collections.abc import Sequence

import torch
from torch import Tensor

from robovae.data.features import FeatureSet
from robovae.data.graph import RobotData, tree_data


def jitter_features(x: Tensor, own: Tensor, graph: Tensor, num_graphs: int, shift: float,
                    noise: float, keep: Tensor | None = None,
                    generator: torch.Generator | None = None) -> Tensor:
    """``x + own * (offset[graph] + noise * eps)`` in normalised units.

    Args:
        x: ``[N, d]`` normalised features.
        own: ``[N, d]`` bool, the node's own columns (``batch.x_mask``).
        graph: ``[N]`` graph index; ``num_graphs`` the number of graphs ``B``.
        shift: std of the per-graph, per-column offsets (``[B, d]``).
        noise: std of the per-node noise.
        keep: ``[d]`` bool, columns never perturbed (categorical one-hots).
        generator: random source (default: the global one).
    """
    if shift <= 0 and noise <= 0:
        return x
    mask = own.to(x.dtype)
    if keep is not None:
        mask = mask * (~keep).to(x.dtype)
    dev = generator.device if generator is not None else x.device
    delta = x.new_zeros(x.shape)
    if shift > 0:
        off = torch.randn(num_graphs, x.shape[1], generator=generator, dtype=x.dtype, device=dev)
        delta = delta + shift * off.to(x.device).index_select(0, graph)
    if noise > 0:
        eps = torch.randn(x.shape, generator=generator, dtype=x.dtype, device=dev)
        delta = delta + noise * eps.to(x.device)
    return x + mask * delta


# --- topology augmentation -------------------------------------------------------------------
#
# Feature jitter keeps every tree; with 16 training robots the decoder then learns 16 shapes and
# decodes an unseen robot as the nearest of them (leave-one-out, docs/results.md). Tree surgery
# gives every training step robots with other trees, built from the limbs of the batch's own
# robots, so that the code in z has to describe a tree rather than name a training robot.

#: the fields of a graph built by :func:`~robovae.data.graph.tree_data`
_FIELDS = ("x", "x_mask", "edge_index", "parent", "node_type", "depth", "name", "source")
#: the edits of :func:`tree_surgery`
SURGERY_OPS = ("drop", "duplicate", "graft", "swap")


def _subtree_end(parent: list[int], i: int) -> int:
    """One past the last node of the pre-order subtree rooted at ``i``: the first later node
    whose parent lies before ``i``."""
    end = i + 1
    while end < len(parent) and parent[end] >= i:
        end += 1
    return end


def _relative(parent: list[int], i: int, j: int) -> list[int]:
    """The parent vector of the subtree ``[i, j)`` on its own: -1 at its root ``i``."""
    return [-1] + [p - i for p in parent[i + 1:j]]


def _splice(parent: list[int], nodes: list, at: int, sub_parent: list[int], sub_nodes: list,
            new_parent: int) -> tuple[list[int], list]:
    """Insert a pre-order subtree (``sub_parent``: relative indices, -1 at its root) at
    position ``at``, its root under ``new_parent``; ``nodes`` travel with the parents."""
    k = len(sub_parent)
    shifted = [p + k if p >= at else p for p in parent]
    ins = [new_parent if p < 0 else p + at for p in sub_parent]
    return shifted[:at] + ins + shifted[at:], nodes[:at] + list(sub_nodes) + nodes[at:]


def _cut(parent: list[int], nodes: list, lo: int, hi: int) -> tuple[list[int], list]:
    """Remove the pre-order subtree occupying ``[lo, hi)``."""
    k = hi - lo
    keep = [p - k if p >= hi else p for p in parent[:lo] + parent[hi:]]
    return keep, nodes[:lo] + nodes[hi:]


def tree_surgery(graphs: Sequence[RobotData], feature_set: FeatureSet, prob: float,
                 max_ops: int, max_nodes: int, rng: random.Random,
                 attach_types: Sequence[int] = (0,),
                 ops: Sequence[str] = SURGERY_OPS) -> list[RobotData]:
    """Edit the trees of a batch of robots (physical-unit graphs): each robot, with probability
    ``prob``, gets 1..``max_ops`` random edits of :data:`SURGERY_OPS` on its *limbs* (the
    subtrees below a node whose type is in ``attach_types``; default: the links):

    - ``drop``: remove a limb;
    - ``duplicate``: insert a copy of a limb as its next sibling;
    - ``graft``: attach a limb of a robot of the batch (possibly itself) under one of the
      robot's attachment nodes, as its last child;
    - ``swap``: exchange two adjacent sibling limbs (sibling order is part of the tree).

    Nodes keep their own feature rows and types; depths follow from the new tree. Edits that
    would exceed ``max_nodes`` are skipped; ``ops`` restricts the edits drawn. Every returned
    graph has the fields of :func:`~robovae.data.graph.tree_data` only (other per-node fields,
    e.g. ``mj_id``, would not describe a rebuilt robot), so the list batches.
    """
    if unknown := set(ops) - set(SURGERY_OPS):
        raise ValueError(f"unknown tree surgery ops {sorted(unknown)} (known: {SURGERY_OPS})")
    pool = [(g.parent.tolist(), g.node_type.tolist()) for g in graphs]
    attach = set(attach_types)
    all_x = torch.cat([g.x for g in graphs])
    offset = [0]
    for g in graphs:
        offset.append(offset[-1] + g.num_nodes)
    out = []
    for gi, g in enumerate(graphs):
        if rng.random() >= prob:  # the same robot, with the fields a rebuilt one has
            out.append(RobotData(**{k: g[k] for k in _FIELDS}, num_nodes=g.num_nodes))
            continue
        # every node is (source graph, source row): features and type come from there
        parent = list(pool[gi][0])
        nodes = [(gi, r) for r in range(len(parent))]
        for _ in range(rng.randint(1, max_ops)):
            kind = [pool[s][1][r] for s, r in nodes]
            limbs = [i for i in range(1, len(parent)) if kind[parent[i]] in attach]
            op = rng.choice(ops)
            if op == "drop" and limbs:
                i = rng.choice(limbs)
                parent, nodes = _cut(parent, nodes, i, _subtree_end(parent, i))
            elif op == "duplicate" and limbs:
                i = rng.choice(limbs)
                j = _subtree_end(parent, i)
                if len(parent) + j - i <= max_nodes:
                    parent, nodes = _splice(parent, nodes, j, _relative(parent, i, j),
                                            nodes[i:j], parent[i])
            elif op == "graft":
                di = rng.randrange(len(graphs))
                dpar, dtypes = pool[di]
                donor = [i for i in range(1, len(dpar)) if dtypes[dpar[i]] in attach]
                hosts = [i for i in range(len(parent)) if kind[i] in attach]
                if donor and hosts:
                    i = rng.choice(donor)
                    j = _subtree_end(dpar, i)
                    if len(parent) + j - i <= max_nodes:
                        host = rng.choice(hosts)
                        parent, nodes = _splice(parent, nodes, _subtree_end(parent, host),
                                                _relative(dpar, i, j),
                                                [(di, r) for r in range(i, j)], host)
            elif op == "swap":
                ends = [(a, _subtree_end(parent, a)) for a in limbs]
                pairs = [(a, b) for a, b in ends if b < len(parent) and parent[b] == parent[a]]
                if pairs:
                    parent, nodes = _swap(parent, nodes, *rng.choice(pairs))
        x = all_x.index_select(0, torch.tensor([offset[s] + r for s, r in nodes]))
        out.append(tree_data(parent, [pool[s][1][r] for s, r in nodes], x, feature_set,
                             name=g.name, source=g.source))
    return out


def _swap(parent: list[int], nodes: list, a: int, b: int) -> tuple[list[int], list]:
    """Exchange the adjacent sibling subtrees starting at ``a`` and ``b`` (``a < b``)."""
    e = _subtree_end(parent, b)
    order = list(range(b, e)) + list(range(a, b))
    new_pos = {old: a + k for k, old in enumerate(order)}
    mid = [new_pos.get(parent[o], parent[o]) for o in order]
    return parent[:a] + mid + parent[e:], nodes[:a] + [nodes[o] for o in order] + nodes[e:]
