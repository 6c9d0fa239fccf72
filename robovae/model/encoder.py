"""Tree message-passing encoder (paper §4.2, eq. 4–8), level-scheduled over a batch."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.model.messages import level_messages
from robovae.model.tree import TreeGRUCell, TreeSchedule, soft_clamp, tree_schedule


def reparametrize(mu: Tensor, logvar: Tensor) -> Tensor:
    """``z = mu + eps * exp(logvar / 2)``, ``eps ~ N(0, I)`` (Kingma & Welling, 2014)."""
    return mu + torch.randn_like(mu) * torch.exp(0.5 * logvar)


class TreeEncoder(nn.Module):
    """Encode a batch of robot trees into ``q(z | G)`` and the node posteriors ``q(w_i | G)``.

    - eq. 5: ``x_i^p = W^p x_i`` (``proj``), ``x_i`` the node's (normalised) features, or with
      ``reads_types`` its one-hot type: such an encoder sees the tree and its node types only
      (the robot's *tree latent*, :class:`~robovae.model.vae.RoboVAE`);
    - eq. 4: GRU messages ``m_ij`` along every tree edge in both directions (:class:`TreeGRUCell`):
      upward level by level from the deepest depth, then downward from the roots, where the
      message ``p -> c`` sums the message into ``p`` from its parent and the upward messages of
      all the *other* children of ``p``;
    - eq. 6: ``h_i = ReLU(W^e x_i^p + sum_k U^e m_ki)``;
    - eq. 7, as a mean: ``h_G = mean of h_i over the leaves`` (a one-node tree's root is its
      leaf). The paper sums; a sum grows with the leaf count, and a zoo robot of 200 leaves
      got ``|mu|`` near 900, whose draws sent the node KL and the features to 1e9 and a run
      to NaN;
    - ``mu = Linear(h_G)``, ``logvar = Linear(h_G)`` (``log sigma^2``, soft-clamped to
      ``(-10, 10)``: an unbounded head once drew a latent of ``e^15`` standard deviations and
      took a whole run to NaN).

    **Node latents** (``node_latent_dim > 0``): every node also gets a posterior
    ``q(w_i | G) = N(mu^w(h_i), diag exp(logvar^w(h_i)))`` (log-variance soft-clamped to
    ``(-10, 10)``) from its readout ``h_i`` (eq. 6, for every node). The decoder reads these
    latents for the features only (:mod:`robovae.model.decoder`).

    Args:
        in_dim: feature width ``d`` (``batch.x`` must already be normalised), or the number of
            node types with ``reads_types``.
        hidden_dim: message / hidden width ``H``.
        latent_dim: width of ``z``.
        node_latent_dim: width of the node latents ``w_i`` (0: none).
        reads_types: read each node's one-hot type instead of its features.
    """

    def __init__(self, in_dim: int, hidden_dim: int, latent_dim: int,
                 node_latent_dim: int = 0, reads_types: bool = False) -> None:
        super().__init__()
        self.reads_types = reads_types
        self.proj = nn.Linear(in_dim, hidden_dim, bias=False)
        self.cell = TreeGRUCell(hidden_dim)
        self.W_e = nn.Linear(hidden_dim, hidden_dim)
        self.U_e = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.mu = nn.Linear(hidden_dim, latent_dim)
        self.logvar = nn.Linear(hidden_dim, latent_dim)
        self.node_latent_dim = node_latent_dim
        if node_latent_dim > 0:
            self.node_mu = nn.Linear(hidden_dim, node_latent_dim)
            self.node_logvar = nn.Linear(hidden_dim, node_latent_dim)

    def forward(self, batch: Data, sched: TreeSchedule | None = None) -> tuple[Tensor, Tensor]:
        """``(mu, logvar)``, ``[B, latent]`` each, for a ``Batch`` (or one ``Data``)."""
        sched = tree_schedule(batch) if sched is None else sched
        return self.readout(*self.messages(batch, sched), sched)

    def inputs(self, batch: Data, sched: TreeSchedule) -> Tensor:
        """What the encoder reads of every node, rows in level order: ``[N, in_dim]``."""
        if self.reads_types:
            return F.one_hot(batch.node_type.index_select(0, sched.order),
                             self.proj.in_features).to(self.proj.weight.dtype)
        return batch.x.index_select(0, sched.order)

    def project(self, x: Tensor) -> Tensor:
        """``cell.project(W^p x)`` of level-order inputs (the level passes' ``px``)."""
        return self.cell.project(x, self.proj.weight)

    def messages(self, batch: Data, sched: TreeSchedule) -> tuple[Tensor, Tensor]:
        """eq. 4–5 alone: ``(x, inward)`` in level order, the inputs ``[N, in_dim]``
        (:meth:`inputs`) and the sum of every message a node receives ``[N, H]`` (the inputs
        of :meth:`readout` and :meth:`node_readout`)."""
        x = self.inputs(batch, sched)
        px = self.project(x)
        _, total, _ = level_messages([self.cell], px[None], sched, 1)
        return x, total[0]

    def readout(self, x: Tensor, inward: Tensor, sched: TreeSchedule) -> tuple[Tensor, Tensor]:
        """eq. 5–7 and the heads from level-order ``x`` (``[N, d]``) and ``inward`` (``[N, H]``:
        the sum of every message a node receives, ``level_messages(...)[1]``)."""
        leaf = sched.leaf_rows
        h = self.node_states(x.index_select(0, leaf), inward.index_select(0, leaf))
        h_g = h.new_zeros(sched.num_graphs, h.shape[1]).index_add(0, sched.leaf_graph, h)
        leaves = torch.bincount(sched.leaf_graph, minlength=sched.num_graphs).clamp_min(1)
        h_g = h_g / leaves[:, None].to(h_g.dtype)
        mu, logvar = _heads(h_g, self.mu, self.logvar)
        return mu, soft_clamp(logvar)

    def node_states(self, x: Tensor, inward: Tensor) -> Tensor:
        """eq. 6, ``h_i = ReLU(W^e x_i^p + U^e sum_k m_ki)``, for the rows given."""
        return torch.relu(self.W_e(self.proj(x)) + self.U_e(inward))

    def node_readout(self, x: Tensor, inward: Tensor,
                     sched: TreeSchedule) -> tuple[Tensor, Tensor]:
        """``(mu^w, logvar^w)`` of every node's latent, ``[N, node_latent_dim]`` each, **node
        order**, from the same level-order inputs as :meth:`readout`."""
        g = self.node_states(x, inward).index_select(0, sched.inv)
        mu, logvar = _heads(g, self.node_mu, self.node_logvar)
        return mu, soft_clamp(logvar)


def _heads(h: Tensor, mu: nn.Linear, logvar: nn.Linear) -> tuple[Tensor, Tensor]:
    """``(mu(h), logvar(h))``, computed in float64 and rounded back.

    A float32 matmul rounds differently with the number of rows (BLAS kernels), and the KL term
    exponentiates logvar, which turns those last-bit differences into a visibly batch-dependent
    loss. Rounded back to float32, a robot's latents no longer depend on the other robots of
    its batch. ``[B, H] x [H, z]``: free.
    """
    hd = h.double()
    mu_h, logvar_h = (F.linear(hd, head.weight.double(), head.bias.double()).to(h.dtype)
                      for head in (mu, logvar))
    return mu_h, logvar_h


def encode_reference(encoder: TreeEncoder, data: Data) -> tuple[Tensor, Tensor]:
    """Naive per-tree encoder (a Python loop over directed edges), for tests/benchmarks.

    Computes eq. 4–7 (the leaf mean) literally: every message ``m_ij`` from the list of ``m_ki``,
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
    h_g, leaves = xp.new_zeros(xp.shape[1]), 0
    for i in range(n):
        if any(parent[k] == i for k in nbrs[i]):
            continue  # not a leaf
        inc = sum((memo[(k, i)] for k in nbrs[i]), xp.new_zeros(xp.shape[1]))
        h_g = h_g + torch.relu(encoder.W_e(xp[i]) + encoder.U_e(inc))
        leaves += 1
    h_g = h_g / leaves
    return encoder.mu(h_g[None]), soft_clamp(encoder.logvar(h_g[None]))
