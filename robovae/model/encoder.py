"""Tree message-passing encoder (paper §4.2, eq. 4–8), level-scheduled over a batch."""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.model.tree import TreeGRUCell, TreeSchedule, tree_schedule, upward


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

    def messages(self, xp: Tensor, sched: TreeSchedule) -> tuple[Tensor, Tensor]:
        """``(up, down)``, ``[N, H]`` each, node order: ``up[c] = m_{c->parent}``,
        ``down[c] = m_{parent->c}`` (zeros at the roots)."""
        cell, levels = self.cell, sched.levels
        px = cell.project(xp)
        ups = upward(cell, px, sched)
        down = [xp.new_zeros(levels[0].numel(), xp.shape[1])]
        for lv in range(1, len(levels)):
            par = sched.parent[levels[lv]]
            at = sched.pos[par]
            pxp, dp = px[par], down[lv - 1][at]
            # incoming into p except from c: (parent -> p) + all children of p - c
            s = dp + ups.child_sum[lv - 1][at] - ups.up[lv]
            g = cell.gate_p(pxp, dp) + ups.child_gated[lv - 1][at] - ups.gated_up[lv]
            down.append(cell.step(pxp, s, g))
        return sched.gather(ups.up), sched.gather(down)

    def forward(self, batch: Data, sched: TreeSchedule | None = None) -> tuple[Tensor, Tensor]:
        """``(mu, logvar)``, ``[B, latent]`` each, for a ``Batch`` (or one ``Data``)."""
        sched = tree_schedule(batch) if sched is None else sched
        xp = self.proj(batch.x)
        up, down = self.messages(xp, sched)
        nonroot = sched.parent >= 0
        inward = down + torch.zeros_like(up).index_add(0, sched.parent[nonroot], up[nonroot])
        h = torch.relu(self.W_e(xp) + self.U_e(inward))
        leaf = sched.num_children == 0
        h_g = h.new_zeros(sched.num_graphs, h.shape[1]).index_add(0, sched.graph[leaf], h[leaf])
        return self.mu(h_g), self.logvar(h_g)
