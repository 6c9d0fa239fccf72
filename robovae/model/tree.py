"""Batched tree utilities: level schedules, the tree GRU cell and the upward message pass.

Every message-passing computation of the encoder and the decoder is scheduled by tree **level**
(depth): all nodes of one depth, across the whole batch, are updated in one call. A batch of
pre-order trees (``robovae.data.graph``) is turned once into a :class:`TreeSchedule`, which the
encoder and the decoder share.

The GRU is the JT-VAE "GraphGRU" (Jin et al., 2018) that implements eq. 4,
``m_ij = GRU(x_i^p, {m_ki}_{k in N(i)\\j})``:

.. math::
    s_{ij} = \\sum_k m_{ki}, \\quad z = \\sigma(W_z [x_i, s_{ij}]), \\quad
    r_{ki} = \\sigma(W_r x_i + U_r m_{ki}), \\\\
    \\tilde m = \\tanh(W_h [x_i, \\sum_k r_{ki} \\odot m_{ki}]), \\quad
    m_{ij} = (1 - z) \\odot s_{ij} + z \\odot \\tilde m.

Because ``r_ki`` depends only on the sender ``i`` and the incoming message ``m_ki`` (not on the
target ``j``), the cell only needs two sums, ``s = sum_k m_ki`` and ``g = sum_k r_ki * m_ki``,
which are scatter sums over tree edges. The cell is shared by the encoder and (with its own
weights) the decoder.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.data.graph import global_parent

if TYPE_CHECKING:  # pragma: no cover
    from robovae.model.encoder import TreeEncoder


def graph_index(batch: Data) -> tuple[Tensor, int]:
    """Graph index per node and number of graphs, for a ``Batch`` or a single ``Data``."""
    g = getattr(batch, "batch", None)
    if g is None:
        return torch.zeros(batch.num_nodes, dtype=torch.long, device=batch.x.device), 1
    return g, int(batch.num_graphs)


@dataclass
class TreeSchedule:
    """Level schedule of a batch of pre-order trees (all indices are batch-global).

    Attributes:
        parent: ``[N]`` parent index, ``-1`` for roots.
        graph: ``[N]`` graph index; ``num_graphs`` the number of graphs ``B``.
        depth: ``[N]`` depth; ``rank``: ``[N]`` position among its siblings (roots 0).
        num_children: ``[N]``; ``size``: ``[N]`` subtree size (the node included).
        levels: node ids of each depth, ascending (siblings are contiguous and in order).
        pos: ``[N]`` position of a node inside its level.
        inv: ``[N]`` maps ``torch.cat(per_level_rows)`` back to node order.
        groups: per level ``L >= 1``, sibling-group id of each node inside that level
            (``levels[L]``-aligned); ``num_groups[L]`` / ``max_rank[L]`` plain ints.
    """

    parent: Tensor
    graph: Tensor
    num_graphs: int
    depth: Tensor
    rank: Tensor
    num_children: Tensor
    size: Tensor
    levels: list[Tensor]
    pos: Tensor
    inv: Tensor
    groups: list[Tensor]
    num_groups: list[int]
    max_rank: list[int]

    @property
    def num_nodes(self) -> int:
        return self.parent.numel()

    def gather(self, per_level: list[Tensor]) -> Tensor:
        """Concatenate per-level rows (``levels`` order) into node order."""
        return torch.cat(per_level)[self.inv]


def tree_schedule(batch: Data) -> TreeSchedule:
    """Build the :class:`TreeSchedule` of a ``Batch`` (or one ``Data``) of pre-order trees.

    The trees are assumed to be in pre-order (``tree_data`` validates it); the cheap checks
    ``parent[i] < i`` and ``depth = depth[parent] + 1`` are repeated here.

    Raises:
        ValueError: when ``parent``/``depth`` are inconsistent.
    """
    parent = global_parent(batch)
    n, dev = parent.numel(), parent.device
    graph, num_graphs = graph_index(batch)
    depth = batch.depth
    idx = torch.arange(n, device=dev)
    nonroot = parent >= 0
    if bool((parent[nonroot] >= idx[nonroot]).any()) or bool(
        (depth[nonroot] != depth[parent[nonroot]] + 1).any() or (depth[~nonroot] != 0).any()
    ):
        raise ValueError("batch is not a set of pre-order trees with consistent depth")
    # rank among siblings: a stable sort by parent keeps siblings in index (= canonical) order
    order = torch.argsort(parent, stable=True)
    counts = torch.bincount(parent + 1, minlength=n + 1)
    start = torch.cumsum(counts, 0) - counts
    rank = torch.empty_like(parent)
    rank[order] = idx - start[parent[order] + 1]
    rank = torch.where(nonroot, rank, torch.zeros_like(rank))
    num_children = counts[1:]
    # levels
    by_depth = torch.argsort(depth, stable=True)
    level_sizes = torch.bincount(depth).tolist()
    levels = list(torch.split(by_depth, level_sizes))
    level_start = torch.cumsum(torch.tensor([0] + level_sizes[:-1], device=dev), 0)
    pos = torch.empty_like(parent)
    pos[by_depth] = idx - level_start[depth[by_depth]]
    inv = torch.empty_like(parent)
    inv[by_depth] = idx
    # subtree sizes, deepest level first
    size = torch.ones(n, dtype=torch.long, device=dev)
    for nodes in reversed(levels[1:]):
        size.index_add_(0, parent[nodes], size[nodes])
    # sibling groups per level: siblings are contiguous inside a level
    groups = [torch.empty(0, dtype=torch.long, device=dev)]
    for nodes in levels[1:]:
        groups.append(torch.cumsum((rank[nodes] == 0).long(), 0) - 1)
    first = [(rank[lv] == 0).sum() for lv in levels[1:]]
    maxr = [rank[lv].max() for lv in levels[1:]]
    ints = torch.stack(first + maxr).tolist() if first else []
    k = len(first)
    return TreeSchedule(parent, graph, num_graphs, depth, rank, num_children, size, levels, pos,
                        inv, groups, [0] + ints[:k], [0] + ints[k:])


def exclusive_sibling_prefix(values: Tensor, groups: Tensor, rank: Tensor, num_groups: int,
                             max_rank: int) -> Tensor:
    """For each node of a level, the sum of ``values`` over its *earlier* siblings.

    Exact (no subtraction): the level is scattered into a dense ``[groups, max_rank + 2, H]``
    array shifted by one slot and cumulated, so the result does not depend on the batch.
    """
    dense = values.new_zeros(num_groups, max_rank + 2, values.shape[-1])
    dense = dense.index_put((groups, rank + 1), values)
    return dense.cumsum(1)[groups, rank]


class TreeGRUCell(nn.Module):
    """JT-VAE GraphGRU (eq. 4), fed with pre-summed incoming messages (module docstring).

    The terms that depend only on the sender's features (``W_z``/``W_h`` on ``x`` and
    ``W_r x``) are computed once per node by :meth:`project` (``px``, ``[M, 3H]``); the batched
    passes then only multiply the message sums level by level (:meth:`step`, :meth:`gate_p`).
    """

    def __init__(self, hidden_dim: int) -> None:
        super().__init__()
        self.hidden_dim = hidden_dim
        self.W_z = nn.Linear(2 * hidden_dim, hidden_dim)
        self.W_r = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.U_r = nn.Linear(hidden_dim, hidden_dim)
        self.W_h = nn.Linear(2 * hidden_dim, hidden_dim)

    def project(self, x: Tensor) -> Tensor:
        """``px = [W_z^x x + b_z, W_h^x x + b_h, W_r x]``, ``[M, 3H]``."""
        h = self.hidden_dim
        weight = torch.cat([self.W_z.weight[:, :h], self.W_h.weight[:, :h], self.W_r.weight])
        bias = torch.cat([self.W_z.bias, self.W_h.bias, self.W_z.bias.new_zeros(h)])
        return F.linear(x, weight, bias)

    def gate_p(self, px: Tensor, m: Tensor) -> Tensor:
        """``r_ki * m_ki`` with ``r_ki = sigma(W_r x_i + U_r m_ki)``; ``px`` projects the node
        ``i`` that receives ``m_ki`` (and sends the message being computed)."""
        return torch.sigmoid(px[:, 2 * self.hidden_dim:] + self.U_r(m)) * m

    def step(self, px: Tensor, s: Tensor, g: Tensor) -> Tensor:
        """``m = (1 - z) s + z tanh(W_h [x, g])``, ``z = sigma(W_z [x, s])``.

        Args:
            px: ``[M, 3H]`` :meth:`project` of the sending nodes' ``x^p``.
            s: ``[M, H]`` sum of the incoming messages.
            g: ``[M, H]`` sum of the gated incoming messages (:meth:`gate_p`).
        """
        h = self.hidden_dim
        z = torch.sigmoid(px[:, :h] + F.linear(s, self.W_z.weight[:, h:]))
        cand = torch.tanh(px[:, h:2 * h] + F.linear(g, self.W_h.weight[:, h:]))
        return (1.0 - z) * s + z * cand

    def forward(self, x: Tensor, s: Tensor, g: Tensor) -> Tensor:
        """:meth:`step` from unprojected ``x`` ``[M, H]``."""
        return self.step(self.project(x), s, g)

    def forward_set(self, x: Tensor, msgs: Tensor) -> Tensor:
        """Reference form for one edge, written out literally with the concatenations:
        ``x`` ``[H]``, ``msgs`` ``[K, H]`` (``K`` may be 0)."""
        s = msgs.sum(0)
        z = torch.sigmoid(self.W_z(torch.cat([x, s])))
        r = torch.sigmoid(self.W_r(x)[None] + self.U_r(msgs))
        cand = torch.tanh(self.W_h(torch.cat([x, (r * msgs).sum(0)])))
        return (1.0 - z) * s + z * cand


@dataclass
class UpPass:
    """Upward messages, per level (``levels``-aligned rows).

    ``up[L]``: message from each node of level ``L`` to its parent (zeros at the roots);
    ``gated_up[L]``: the same, gated by the parent (``cell.gate_p(px_parent, up)``);
    ``child_sum[L]`` / ``child_gated[L]``: per node, the sums of those over its children.
    """

    up: list[Tensor]
    gated_up: list[Tensor]
    child_sum: list[Tensor]
    child_gated: list[Tensor]


def upward(cell: TreeGRUCell, px: Tensor, sched: TreeSchedule) -> UpPass:
    """Child → parent messages ``m_cp = GRU(x_c^p, {m_kc}_{k child of c})``, deepest level first.

    ``px`` is ``cell.project(x^p)`` of every node. One GRU step per level for the whole batch.
    """
    levels, depth_max, hid = sched.levels, len(sched.levels) - 1, cell.hidden_dim
    empty = px.new_zeros(0)
    up, gated = [empty] * (depth_max + 1), [empty] * (depth_max + 1)
    csum, cgated = [empty] * (depth_max + 1), [empty] * (depth_max + 1)
    gated[0] = px.new_zeros(levels[0].numel(), hid)
    for lv in range(depth_max, -1, -1):
        nodes = levels[lv]
        s = g = px.new_zeros(nodes.numel(), hid)
        if lv < depth_max:
            par = sched.parent[levels[lv + 1]]
            gated[lv + 1] = cell.gate_p(px[par], up[lv + 1])
            at = sched.pos[par]
            s = s.index_add(0, at, up[lv + 1])
            g = g.index_add(0, at, gated[lv + 1])
        csum[lv], cgated[lv] = s, g
        up[lv] = cell.step(px[nodes], s, g) if lv > 0 else torch.zeros_like(s)
    return UpPass(up, gated, csum, cgated)


def encode_reference(encoder: TreeEncoder, data: Data) -> tuple[Tensor, Tensor]:
    """Naive per-tree encoder (a Python loop over directed edges), for tests/benchmarks.

    Computes eq. 4–7 literally: every message ``m_ij`` from the list of ``m_ki``,
    ``k in N(i)\\j``, with :meth:`TreeGRUCell.forward_set`. Returns ``(mu, logvar)``, ``[1, z]``.
    """
    parent = data.parent.tolist()
    n = len(parent)
    nbrs: list[list[int]] = [[] for _ in range(n)]
    for i, p in enumerate(parent):
        if p >= 0:
            nbrs[i].append(p)
            nbrs[p].append(i)
    xp = encoder.proj(data.x)
    memo: dict[tuple[int, int], Tensor] = {}

    def msg(i: int, j: int) -> Tensor:
        inc = [memo[(k, i)] for k in nbrs[i] if k != j]
        stack = torch.stack(inc) if inc else xp.new_zeros(0, xp.shape[1])
        return encoder.cell.forward_set(xp[i], stack)

    for i in reversed(range(1, n)):  # upward: children are done before their parent
        memo[(i, parent[i])] = msg(i, parent[i])
    for i in range(1, n):  # downward: the parent's own down message is done first
        memo[(parent[i], i)] = msg(parent[i], i)
    h_g = xp.new_zeros(xp.shape[1])
    for i in range(n):
        if any(parent[k] == i for k in nbrs[i]):
            continue  # not a leaf
        inc = sum((memo[(k, i)] for k in nbrs[i]), xp.new_zeros(xp.shape[1]))
        h_g = h_g + torch.relu(encoder.W_e(xp[i]) + encoder.U_e(inc))
    return encoder.mu(h_g[None]), encoder.logvar(h_g[None])
