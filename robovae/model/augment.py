"""Training-time feature augmentation: every epoch sees "new robots" with the same trees.

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

import torch
from torch import Tensor


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
