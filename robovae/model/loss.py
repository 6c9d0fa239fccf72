"""VAE loss (paper eq. 8, 12, 13) with per-graph totals.

Reduction: every term is **summed over the graph's decisions / nodes** (eq. 12 sums over ``t``
and ``j``), then **averaged over the graphs** of the batch. So the batch loss is exactly the mean
of the per-graph losses, and a batch of one gives that graph's loss. Per node, the feature error
is the mean squared error over the node's own columns (``batch.x_mask``).

- ``topo``: binary cross-entropy with logits of the expand/backtrack decisions (eq. 9);
- ``feat``: masked MSE of the features (eq. 10), normalised units;
- ``type``: cross-entropy of the node types (eq. 11; identically 0 with a single type);
- ``kl``: eq. 8, ``-1/(2B) sum_i sum_j (1 + logvar - mu^2 - exp(logvar))``; ``kl_tree`` its
  part over the tree latent ``z_T`` (the first ``tree_dim`` columns; reported, not added);
- ``kl_nodes`` (node latents only): the KL of every node's posterior ``q(w_i | G)`` from its
  conditional prior ``p(w_i | z, h_{p->i}, w_p)`` (:mod:`robovae.model.decoder`), summed over the
  graph's nodes: ``1/2 sum_j (lambda^p - lambda^q + (e^{lambda^q} + (mu^q - mu^p)^2)
  e^{-lambda^p} - 1)``;
- ``loss = topo + feat + type + beta * kl + beta_nodes * kl_nodes`` (eq. 13);
- ``per_graph_nelbo``: the negative ELBO of each graph in nats, every term at weight 1 and the
  features scored as a unit-variance Gaussian in normalised units:
  ``topo + type + sum_{i, c own} ((f_ic - f^_ic)^2 + log 2 pi) / 2 + kl + kl_nodes`` (at the
  ``z`` and ``w`` the caller decoded, e.g. the posterior means: a one-sample estimate), so that
  models with and without node latents compare on one scale.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor
from torch_geometric.data import Data

from robovae.model.decoder import DecoderOutput
from robovae.model.tree import graph_index


def vae_loss(out: DecoderOutput, batch: Data, mu: Tensor, logvar: Tensor,
             beta: float = 1.0, node_mu: Tensor | None = None,
             node_logvar: Tensor | None = None, beta_nodes: float | None = None,
             tree_dim: int = 0) -> dict[str, Tensor]:
    """Loss terms of a batch (module docstring for the reduction).

    Args:
        node_mu: ``[N, node_latent_dim]`` node posterior means (node latents only; ``out``
            then carries their prior).
        node_logvar: ``[N, node_latent_dim]`` node posterior log-variances.
        beta_nodes: weight of ``kl_nodes`` (default: ``beta``).
        tree_dim: width of the tree latent ``z_T`` (the first columns of ``mu``) for ``kl_tree``.

    Returns:
        ``loss``, ``topo``, ``feat``, ``type``, ``kl``, ``kl_tree``, ``kl_nodes`` (scalars, batch
        means of per-graph sums; ``kl_nodes`` is 0 without node latents), ``per_graph_loss``
        ``[B]``, ``per_graph_kl``, ``per_graph_kl_tree``, ``per_graph_kl_nodes`` and
        ``per_graph_nelbo`` ``[B]`` (detached, nats; module docstring), and
        detached metrics ``topo_acc`` (share of correct decisions) and ``type_acc`` (share of
        correct node types).
    """
    graph, b = graph_index(batch)

    def per_graph(values: Tensor, index: Tensor) -> Tensor:
        return values.new_zeros(b).index_add(0, index, values)

    topo_t = F.binary_cross_entropy_with_logits(out.topo_logits, out.topo_target,
                                                reduction="none")
    mask = batch.x_mask.to(out.feat_pred.dtype)
    sq = (out.feat_pred - batch.x) ** 2 * mask
    feat_n = sq.sum(1) / mask.sum(1).clamp_min(1.0)
    type_n = F.cross_entropy(out.type_logits, batch.node_type, reduction="none")
    kl_dims = -0.5 * (1 + logvar - mu**2 - logvar.exp())
    kl_g = kl_dims.sum(1)
    topo_g = per_graph(topo_t, out.topo_graph)
    feat_g, type_g = per_graph(feat_n, graph), per_graph(type_n, graph)
    per_graph_loss = topo_g + feat_g + type_g + beta * kl_g
    kl_nodes_g = kl_g.new_zeros(b)
    if node_mu is not None:
        pm, plv = out.prior_mu, out.prior_logvar
        if pm is None or plv is None or node_logvar is None:
            raise ValueError("node latents need their posterior and the decoder's prior")
        kl_n = 0.5 * (plv - node_logvar + (node_logvar.exp() + (node_mu - pm) ** 2)
                      * torch.exp(-plv) - 1.0).sum(1)
        kl_nodes_g = per_graph(kl_n, graph)
        per_graph_loss = per_graph_loss + (beta if beta_nodes is None else beta_nodes) \
            * kl_nodes_g
    with torch.no_grad():
        # the negative ELBO per graph, in nats: topology BCE + type CE + unit-variance Gaussian
        # NLL of the own feature columns (normalised units) + both KL terms at weight 1
        cols = per_graph(mask.sum(1), graph)
        nll = per_graph(sq.sum(1), graph) * 0.5 + 0.5 * math.log(2 * math.pi) * cols
        nelbo_g = topo_g + type_g + nll + kl_g + kl_nodes_g
        topo_acc = ((out.topo_logits > 0).float() == out.topo_target).float().mean()
        type_acc = (out.type_logits.argmax(-1) == batch.node_type).float().mean()
    return {
        "loss": per_graph_loss.mean(),
        "topo": topo_g.mean(),
        "feat": feat_g.mean(),
        "type": type_g.mean(),
        "kl": kl_g.mean(),
        "kl_tree": kl_dims[:, :tree_dim].sum(1).mean().detach(),
        "kl_nodes": kl_nodes_g.mean(),
        "per_graph_loss": per_graph_loss,
        "per_graph_kl": kl_g.detach(),
        "per_graph_kl_tree": kl_dims[:, :tree_dim].sum(1).detach(),
        "per_graph_kl_nodes": kl_nodes_g.detach(),
        "per_graph_nelbo": nelbo_g,
        "topo_acc": topo_acc,
        "type_acc": type_acc,
    }
