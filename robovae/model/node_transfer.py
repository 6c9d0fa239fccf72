"""Node latents carried from encoded robots to the trees decoded near them.

A robot's node latents ``w_1 … w_m`` (the encoder's means, pre-order) describe its own nodes. A
latent ``z`` near the robot's (a variation of it, a step of a path from it) may decode to
another tree, whose ``t``-th node in pre-order is then not the robot's ``t``-th node. Node
``t`` of a decoded tree instead takes the latent of the node it **shares** with each robot
``r`` (:func:`~robovae.data.tree_arrays.shared_nodes`: the node at the same place, reached from
the root by the same child ranks, when it has the same type — the *correct* pairs of the
reconstruction metrics; ``s_r(t)``), averaged with the robots' weights ``a_r``:

.. math::
    w'_t = \\frac{\\sum_r a_r [t \\in r] \\, w^r_{s_r(t)}}{\\sum_r a_r [t \\in r]}

and, where no robot of positive weight shares the node, its conditional prior mean (the
decoder's rows of NaN: :meth:`~robovae.model.decoder.TreeDecoder.decode`), as sampled robots
get at node temperature 0. The tree and its node types depend on ``z`` alone
(:mod:`robovae.model.decoder`), so :func:`decode_near` decodes each tree first, then its
features with the carried latents. When the decoded tree is the robot's own tree, every node
keeps its latent: the reconstruction.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import torch
from torch import Tensor

from robovae.data.graph import RobotData
from robovae.data.tree_arrays import shared_nodes

if TYPE_CHECKING:
    from robovae.model.vae import RoboVAE

__all__ = ["EncodedRobot", "carried_latents", "decode_near"]


class EncodedRobot(NamedTuple):
    """A robot encoded: its latent mean ``mu`` ``[latent_dim]``, its nodes' latent means
    ``nodes`` ``[n_nodes, node_latent_dim]`` (pre-order) and its ``tree``, ``(parent,
    node_type)`` in pre-order."""

    mu: Tensor
    nodes: Tensor
    tree: tuple[Tensor, Tensor]


def carried_latents(tree: tuple[Tensor, Tensor], robots: Sequence[EncodedRobot],
                    weights: Sequence[float]) -> Tensor:
    """The node latents ``[n, node_latent_dim]`` of a decoded ``tree`` ``(parent,
    node_type)`` carried from ``robots`` with ``weights`` (module docstring); NaN rows for
    the nodes no robot of positive weight shares."""
    n, ref = len(tree[0]), robots[0].nodes
    total = ref.new_zeros(n, ref.shape[1])
    mass = ref.new_zeros(n)
    for robot, a in zip(robots, weights):
        if a <= 0:
            continue
        shared = torch.from_numpy(shared_nodes(robot.tree, tree)).to(ref.device)
        has = shared >= 0
        total[has] += a * robot.nodes[shared[has]].to(ref)
        mass[has] += a
    out = torch.full_like(total, float("nan"))
    has = mass > 0
    out[has] = total[has] / mass[has, None]
    return out


@torch.no_grad()
def decode_near(model: RoboVAE, z: Tensor, robots: Sequence[EncodedRobot],
                weights: Tensor | None = None) -> list[RobotData]:
    """Decode latents ``z`` ``[B, latent_dim]`` near ``robots``: each tree from its ``z``, then
    its features with the node latents carried from the robots with ``weights[b]``
    (``[B, len(robots)]``; default every robot weight 1). Features are not clipped to the
    training support (a robot may lie outside it)."""
    if weights is None:
        weights = z.new_ones(z.shape[0], len(robots))
    trees = model.decode(z, clamp=False)  # for the trees only: they depend on z alone
    nodes = [carried_latents((g.parent, g.node_type), robots, a.tolist())
             for g, a in zip(trees, weights)]
    return model.decode(z, node_latents=nodes, clamp=False)
