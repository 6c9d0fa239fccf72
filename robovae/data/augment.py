"""Training-time augmentation as PyG transforms, applied to training batches by
:class:`~robovae.data.datamodule.RobotDataModule` (``data.feature_shift``, ``data.feature_noise``,
``data.tree_surgery``, ``data.surgery_ops`` in the YAML configs).

- :class:`TreeSurgery`: each robot of a batch, with probability ``prob``, is rebuilt by
  1..``max_ops`` random edits of its limbs (:func:`tree_surgery`): new trees from the limbs of
  the batch's own robots, so the latent has to describe a tree rather than name a training robot.
- :class:`FeatureJitter`: a redesign of every robot's features, a per-robot offset on every
  column plus per-node noise, in the model's normalised units (the feature normaliser's units:
  ``(T(x) - mu) / sigma``; all link masses of a robot scaled by one factor through the log
  transform, all joint dampings by another, ...). It is drawn here and stored as the batch's
  ``x_jitter`` (``[N, d]``); :meth:`RoboVAE.normalized <robovae.model.vae.RoboVAE.normalized>`
  adds it after normalising, so the encoder input, the decoder's teacher-forced inputs and the
  reconstruction targets all see the same perturbed values. (Applying it in physical units
  would not be exact: the inverse of a log column clips at zero.)

Randomness: every transform draws from its own generator, re-seeded for each training batch by
:meth:`Augmentation.seed` with :func:`run_seed` of ``(stream, epoch, batch, rank)`` (the
datamodule does it), so a run resumed from an end-of-epoch checkpoint draws the same edits and
offsets as an uninterrupted one.
"""

from __future__ import annotations

import os
import random
from collections.abc import Sequence

import numpy as np
import torch
from torch_geometric.data import Batch, Data
from torch_geometric.transforms import BaseTransform

from robovae.data.features import FeatureSet, get_feature_set
from robovae.data.graph import RobotData, tree_data
from robovae.settings import check_settings, integer, number

#: streams of :func:`run_seed`: the training loader's shuffle, the model's reparametrisation
#: noise (and the tree surgery, which has always shared its seed), the feature jitter
SHUFFLE, NOISE, JITTER = 1, 2, 3


def run_seed(*keys: int) -> int:
    """A 63-bit seed from the run's seed and ``keys`` (e.g. stream, epoch, batch, rank).

    The run's seed is ``seed_everything``'s ``PL_GLOBAL_SEED`` environment variable when set,
    else ``torch.initial_seed()``; the seed is NumPy's ``SeedSequence`` of their absolute
    values, so different keys give independent streams.
    """
    env = os.environ.get("PL_GLOBAL_SEED")
    base = int(env) if env is not None and env.lstrip("-").isdigit() \
        else torch.initial_seed()
    entropy = [abs(int(k)) for k in (base, *keys)]
    return int(np.random.SeedSequence(entropy).generate_state(2, np.uint64)[0] >> 1)


class FeatureJitter(BaseTransform):
    """Store a feature perturbation ``x_jitter = m * (shift * o[graph] + noise * eps)`` in a
    batch (normalised units; module docstring).

    ``o`` is ``[B, d]`` and ``eps`` ``[N, d]`` standard normals from this transform's generator
    (``o`` drawn first), ``m`` the node's own columns (``x_mask``) minus the categorical ones.

    Args:
        feature_set: the registry set of the batch's columns (its categorical columns are kept).
        shift: std of the per-robot, per-column offsets (0: none).
        noise: std of the per-node noise (0: none).

    Raises:
        SettingsError: ``shift`` or ``noise`` negative or not finite (one line).
    """

    def __init__(self, feature_set: str | FeatureSet, shift: float, noise: float) -> None:
        check_settings("FeatureJitter", shift=(shift, number(0)), noise=(noise, number(0)))
        fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
        self.keep = fs.column_transform("categorical")
        self.shift, self.noise = float(shift), float(noise)
        self.generator = torch.Generator()

    def seed(self, seed: int) -> None:
        """Re-seed the generator (the datamodule does, per batch)."""
        self.generator.manual_seed(seed)

    def forward(self, data: Data) -> Data:
        """``data`` (a ``Batch`` or one graph) with ``x_jitter`` set, ``x`` unchanged."""
        x = data.x
        graph = getattr(data, "batch", None)
        if graph is None:
            graph = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
        b = int(getattr(data, "num_graphs", 1) or 1)
        gen = self.generator
        delta = torch.zeros(x.shape, dtype=torch.float32)
        if self.shift > 0:
            off = torch.randn(b, x.shape[1], generator=gen)
            delta += self.shift * off.index_select(0, graph.cpu())
        if self.noise > 0:
            delta += self.noise * torch.randn(x.shape, generator=gen)
        mask = data.x_mask.cpu() & ~self.keep
        data.x_jitter = (delta * mask).to(x.device)
        return data

    def __repr__(self) -> str:
        return f"{type(self).__name__}(shift={self.shift}, noise={self.noise})"


class TreeSurgery(BaseTransform):
    """Rebuild robots of a batch by random limb edits (:func:`tree_surgery`).

    Args:
        feature_set: the registry set of the batch's columns.
        prob: probability that a robot is rebuilt (0: none).
        max_ops: at most this many edits per rebuilt robot.
        max_nodes: edits that would make a robot larger are skipped.

    Raises:
        SettingsError: ``prob`` outside ``[0, 1]``, ``max_ops`` or ``max_nodes`` below 1.
    """

    def __init__(self, feature_set: str | FeatureSet, prob: float, max_ops: int = 3,
                 max_nodes: int = 256) -> None:
        check_settings("TreeSurgery", prob=(prob, number(0, 1)), max_ops=(max_ops, integer(1)),
                       max_nodes=(max_nodes, integer(1)))
        self.feature_set = get_feature_set(feature_set) if isinstance(feature_set, str) \
            else feature_set
        self.prob, self.max_ops, self.max_nodes = float(prob), int(max_ops), int(max_nodes)
        self.rng = random.Random(0)

    def seed(self, seed: int) -> None:
        """Re-seed the edits (the datamodule does, per batch)."""
        self.rng = random.Random(seed)

    def forward(self, data: Data) -> Batch:
        """A new ``Batch`` of the edited robots (the fields of
        :func:`~robovae.data.graph.tree_data` only)."""
        graphs = data.to_data_list() if isinstance(data, Batch) else [data]
        out = tree_surgery(graphs, self.feature_set, self.prob, self.max_ops, self.max_nodes,
                           self.rng)
        return Batch.from_data_list(out).to(data.x.device)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(prob={self.prob}, max_ops={self.max_ops}, "
                f"max_nodes={self.max_nodes})")


class Augmentation(BaseTransform):
    """Tree surgery then feature jitter (either may be absent), seeded per batch."""

    def __init__(self, surgery: TreeSurgery | None, jitter: FeatureJitter | None) -> None:
        self.surgery, self.jitter = surgery, jitter

    def seed(self, epoch: int, batch: int, rank: int = 0) -> None:
        """Seed both transforms from ``(stream, epoch, batch, rank)`` (:func:`run_seed`)."""
        if self.surgery is not None:
            self.surgery.seed(run_seed(NOISE, epoch, batch, rank))
        if self.jitter is not None:
            self.jitter.seed(run_seed(JITTER, epoch, batch, rank))

    def forward(self, data: Data) -> Data:
        """The augmented batch."""
        if self.surgery is not None:
            data = self.surgery(data)
        if self.jitter is not None:
            data = self.jitter(data)
        return data

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.surgery!r}, {self.jitter!r})"


# --- tree surgery ----------------------------------------------------------------------------

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
