"""Tree building blocks shared by the encoder and the decoder: the level schedule of a batch
of pre-order trees, the tree GRU cell and the soft clamp of log-variances.

Every message-passing computation of the encoder and the decoder is scheduled by tree **level**
(depth): all nodes of one depth, across the whole batch, are updated in one call. A batch of
pre-order trees (``robovae.data.graph``) is turned once into a :class:`TreeSchedule`, which the
encoder and the decoder share. The passes (:mod:`robovae.model.messages`) work in **level
order** (the nodes sorted by depth, then index), so that every level is a contiguous block of
rows.

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

from dataclasses import dataclass, field

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.data.graph import global_parent


def graph_index(batch: Data) -> tuple[Tensor, int]:
    """Graph index per node and number of graphs, for a ``Batch`` or a single ``Data``."""
    g = getattr(batch, "batch", None)
    if g is None:
        return torch.zeros(batch.num_nodes, dtype=torch.long, device=batch.x.device), 1
    return g, int(batch.num_graphs)


@dataclass
class TreeSchedule:
    """Level schedule of a batch of pre-order trees (all indices are batch-global).

    Node-order attributes:
        parent: ``[N]`` parent index, ``-1`` for roots.
        graph: ``[N]`` graph index; ``num_graphs`` the number of graphs ``B``.
        depth: ``[N]`` depth; ``rank``: ``[N]`` position among its siblings (roots 0).
        num_children: ``[N]``; ``size``: ``[N]`` subtree size (the node included).
        levels: node ids of each depth, ascending (siblings are contiguous and in order).
        pos: ``[N]`` position of a node inside its level.
        inv: ``[N]`` row of each node in level order (maps ``torch.cat(per_level_rows)`` back
            to node order: ``cat(...)[inv]``).

    Level-order attributes (rows of ``torch.cat(levels)``):
        order: ``[N]`` node id of each row (``torch.cat(levels)``).
        sizes, offsets: plain ints, number of nodes and first row of each level.
        at: per level ``L >= 1``, the position of each node's parent inside level ``L - 1``
            (``at[0]`` is empty).
        groups: per level ``L >= 1``, sibling-group id of each node inside that level;
            ``num_groups[L]`` / ``max_rank[L]`` plain ints (0 at level 0).
        prefix_dst, prefix_src: per level ``L >= 1``, flat slots of each node in a dense
            ``[num_groups, max_rank + 2]`` sibling table (``dst = src + 1``), for exact
            sibling prefix sums.
        parent_row: ``[N]`` row of each row's parent (0 for the roots).
        leaf_rows: rows of the leaves; ``leaf_graph``: their graph index.
        cache: derived index tensors (e.g. the decoder's DFS-trace order), built on first use.
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
    order: Tensor
    sizes: list[int]
    offsets: list[int]
    at: list[Tensor]
    prefix_dst: list[Tensor]
    prefix_src: list[Tensor]
    parent_row: Tensor
    leaf_rows: Tensor
    leaf_graph: Tensor
    cache: dict = field(default_factory=dict, repr=False)

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
    by_parent = torch.argsort(parent, stable=True)
    counts = torch.bincount(parent + 1, minlength=n + 1)
    start = torch.cumsum(counts, 0) - counts
    rank = torch.empty_like(parent)
    rank[by_parent] = idx - start[parent[by_parent] + 1]
    rank = torch.where(nonroot, rank, torch.zeros_like(rank))
    num_children = counts[1:]
    # levels
    order = torch.argsort(depth, stable=True)
    sizes = torch.bincount(depth).tolist()
    levels = list(torch.split(order, sizes))
    level_start = torch.cumsum(torch.tensor([0] + sizes[:-1], device=dev), 0)
    depth_l = depth[order]
    pos = torch.empty_like(parent)
    pos[order] = idx - level_start[depth_l]
    inv = torch.empty_like(parent)
    inv[order] = idx
    # level order: the parents' positions in the level above
    rank_l = rank[order]
    at = pos[parent[order].clamp_min(0)]
    # subtree sizes, deepest level first (level order, per-level views)
    size_l = torch.ones(n, dtype=torch.long, device=dev)
    size_lv, at_lv = torch.split(size_l, sizes), torch.split(at, sizes)
    for lv in range(len(sizes) - 1, 0, -1):
        size_lv[lv - 1].index_add_(0, at_lv[lv], size_lv[lv])
    size = size_l[inv]
    # sibling groups (siblings are contiguous inside a level) and their dense tables
    gid = torch.cumsum((rank_l == 0).long(), 0) - 1
    gid = gid - gid[level_start][depth_l]
    num_levels = len(sizes)
    zeros = torch.zeros(num_levels, dtype=torch.long, device=dev)
    max_rank = zeros.scatter_reduce(0, depth_l, rank_l, "amax")
    num_groups = zeros.scatter_reduce(0, depth_l, gid, "amax") + 1
    dst = gid * (max_rank + 2)[depth_l] + rank_l + 1
    ints = torch.stack([num_groups, max_rank]).tolist() if num_levels else [[], []]
    empty = torch.empty(0, dtype=torch.long, device=dev)

    def per_level(t: Tensor) -> list[Tensor]:
        return [empty, *torch.split(t, sizes)[1:]]

    leaf_rows = (num_children[order] == 0).nonzero().flatten()
    offsets = [0]
    for s in sizes[:-1]:
        offsets.append(offsets[-1] + s)
    return TreeSchedule(
        parent, graph, num_graphs, depth, rank, num_children, size, levels, pos, inv,
        groups=per_level(gid), num_groups=[0] + ints[0][1:], max_rank=[0] + ints[1][1:],
        order=order, sizes=sizes, offsets=offsets, at=per_level(at),
        prefix_dst=per_level(dst), prefix_src=per_level(dst - 1),
        parent_row=inv[parent[order].clamp_min(0)], leaf_rows=leaf_rows,
        leaf_graph=graph[order[leaf_rows]])


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

    def project(self, x: Tensor, in_weight: Tensor | None = None) -> Tensor:
        """``px = [W_z^x x + b_z, W_h^x x + b_h, W_r x]``, ``[M, 3H]``.

        With ``in_weight`` (``[H, d]``), ``x`` (``[M, d]``) is first mapped by it: the product
        of the two weights is taken first (``[3H, d]``), which is several times cheaper than
        projecting ``M`` rows twice when ``d < H``, forward and backward.
        """
        h = self.hidden_dim
        weight = torch.cat([self.W_z.weight[:, :h], self.W_h.weight[:, :h], self.W_r.weight])
        if in_weight is not None:
            weight = weight @ in_weight
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


def soft_clamp(logvar: Tensor, bound: float = 10.0) -> Tensor:
    """``bound * tanh(logvar / bound)``: a log-variance kept inside ``(-bound, bound)``
    smoothly (identity near 0, slope 1 at 0), so that neither ``e^{lambda^q}`` nor
    ``e^{-lambda^p}`` in a Gaussian KL can overflow."""
    return bound * torch.tanh(logvar / bound)
