"""Tree message-passing encoder (paper §4.2, eq. 4–8), level-scheduled over a batch."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.model.tree import TreeGRUCell, TreeSchedule, level_messages, tree_schedule


def reparametrize(mu: Tensor, logvar: Tensor) -> Tensor:
    """``z = mu + eps * exp(logvar / 2)``, ``eps ~ N(0, I)`` (Kingma & Welling, 2014)."""
    return mu + torch.randn_like(mu) * torch.exp(0.5 * logvar)


class TreeEncoder(nn.Module):
    """Encode a batch of robot trees into ``(mu, logvar)`` of ``q(z | G)``.

    - eq. 5: ``x_i^p = W^p x_i`` (``proj``);
    - eq. 4: GRU messages ``m_ij`` along every tree edge in both directions (:class:`TreeGRUCell`):
      upward level by level from the deepest depth, then downward from the roots, where the
      message ``p -> c`` sums the message into ``p`` from its parent and the upward messages of
      all the *other* children of ``p``;
    - eq. 6: ``h_i = ReLU(W^e x_i^p + sum_k U^e m_ki)``;
    - eq. 7: ``h_G = sum of h_i over the leaves`` (a one-node tree's root is its leaf);
    - ``mu = Linear(h_G)``, ``logvar = Linear(h_G)`` (``log sigma^2``, unclamped).

    Args:
        in_dim: feature width ``d``; ``batch.x`` must already be normalised.
        hidden_dim: message / hidden width ``H``.
        latent_dim: latent width.
    """

    def __init__(self, in_dim: int, hidden_dim: int, latent_dim: int) -> None:
        super().__init__()
        self.proj = nn.Linear(in_dim, hidden_dim, bias=False)
        self.cell = TreeGRUCell(hidden_dim)
        self.W_e = nn.Linear(hidden_dim, hidden_dim)
        self.U_e = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.mu = nn.Linear(hidden_dim, latent_dim)
        self.logvar = nn.Linear(hidden_dim, latent_dim)

    def forward(self, batch: Data, sched: TreeSchedule | None = None) -> tuple[Tensor, Tensor]:
        """``(mu, logvar)``, ``[B, latent]`` each, for a ``Batch`` (or one ``Data``)."""
        sched = tree_schedule(batch) if sched is None else sched
        x = batch.x.index_select(0, sched.order)  # level order
        px = self.cell.project(x, self.proj.weight)
        _, total, _ = level_messages([self.cell], px[None], sched, 1)
        return self.readout(x, total[0], sched)

    def readout(self, x: Tensor, inward: Tensor, sched: TreeSchedule) -> tuple[Tensor, Tensor]:
        """eq. 5–7 and the heads from level-order ``x`` (``[N, d]``) and ``inward`` (``[N, H]``:
        the sum of every message a node receives, ``level_messages(...)[1]``)."""
        leaf = sched.leaf_rows
        xp = self.proj(x.index_select(0, leaf))
        h = torch.relu(self.W_e(xp) + self.U_e(inward.index_select(0, leaf)))
        h_g = h.new_zeros(sched.num_graphs, h.shape[1]).index_add(0, sched.leaf_graph, h)
        # The heads run in float64: a float32 matmul rounds differently with the number of rows
        # (BLAS kernels), and the KL term exponentiates logvar, which turns those last-bit
        # differences into a visibly batch-dependent loss. Rounded back to float32, a robot's
        # (mu, logvar) no longer depend on the other robots of its batch. [B, H] x [H, z]: free.
        hd = h_g.double()
        return tuple(F.linear(hd, head.weight.double(), head.bias.double()).to(h_g.dtype)
                     for head in (self.mu, self.logvar))
