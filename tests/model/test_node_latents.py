"""Node latents: decoding agrees with teacher forcing whether the nodes'
latents are given (reconstruction) or drawn from the conditional prior (generation); the node
KL is the Gaussian KL; every parameter learns; the tree and the node types come from the tree
latent alone."""

from __future__ import annotations

import random

import pytest
import torch
from torch_geometric.data import Batch

from robovae.data.graph import tree_data
from robovae.model.decoder import TreeDecoder
from robovae.model.encoder import TreeEncoder, reparametrize
from robovae.model.loss import vae_loss
from robovae.model.tree import soft_clamp, tree_schedule
from tests.model.test_decoder import FULL, assert_decoded_as_scored, random_batch, random_tree

DW = 6


#: (seed, expansion bias) of a random decoder that makes trees of many sizes (asserted below)
VARIED = (2, 0.0)


def make_decoder(feature_layers: int = 1) -> TreeDecoder:
    seed, bias = VARIED
    torch.manual_seed(seed)
    dec = TreeDecoder(FULL.dim, 3, 32, 8, DW, type_mask=FULL.type_mask(),
                      feature_layers=feature_layers).eval()
    with torch.no_grad():
        dec.topo.u.bias.add_(bias)
    return dec


def check_agrees(dec: TreeDecoder, z: torch.Tensor, trees: list, w: torch.Tensor,
                 max_nodes: int, max_depth: int) -> None:
    """Teacher forcing with node latents ``w`` makes the decoded trees' decisions, types and
    features."""
    with torch.no_grad():
        out = dec.teacher_forcing(z, Batch.from_data_list(trees), w)
    assert_decoded_as_scored(out, trees, max_nodes, max_depth)


def decoded_trees(dec: TreeDecoder, z: torch.Tensor, max_nodes: int, max_depth: int,
                  **kw) -> list:
    trees = [tree_data(p, t, x, FULL)
             for p, t, x in dec.decode(z, max_nodes=max_nodes, max_depth=max_depth, **kw)]
    sizes = [t.num_nodes for t in trees]
    assert len(set(sizes)) > 3, sizes  # the check below needs trees of several shapes
    return trees


def test_decode_with_given_node_latents_matches_teacher_forcing() -> None:
    """Reconstruction: node ``t`` of robot ``b`` takes ``node_latents[b][t]``; beyond the given
    rows it takes the prior mean (here every robot gives 150 rows, more than it uses)."""
    dec = make_decoder()
    torch.manual_seed(100)
    z = torch.randn(12, 8) * 2
    given = [torch.randn(150, DW) * 2 for _ in range(12)]
    max_nodes, max_depth = 120, 25
    trees = decoded_trees(dec, z, max_nodes, max_depth, node_latents=given)
    w = torch.cat([g[:t.num_nodes] for g, t in zip(given, trees)])
    check_agrees(dec, z, trees, w, max_nodes, max_depth)


@pytest.mark.parametrize(("noise", "feature_layers"), [(False, 1), (True, 1), (True, 3)])
def test_prior_decoding_matches_teacher_forcing(noise: bool, feature_layers: int) -> None:
    """Generation: every node's latent is ``mu^p + sigma^p eps_t`` of the prior that teacher
    forcing computes from the decoded tree, i.e. a fixed point of ``w -> prior(w)`` (reached
    after one sweep per tree level, since a node's prior reads its parent's latent)."""
    dec = make_decoder(feature_layers)
    torch.manual_seed(100)
    z = torch.randn(12, 8) * 2
    max_nodes, max_depth = 120, 25
    eps = torch.randn(12, max_nodes, DW) if noise else None
    trees = decoded_trees(dec, z, max_nodes, max_depth, node_noise=eps)
    batch = Batch.from_data_list(trees)
    sched = tree_schedule(batch)
    local_index = torch.arange(batch.num_nodes) - batch.ptr[batch.batch]
    w = torch.zeros(batch.num_nodes, DW)
    with torch.no_grad():
        for _ in range(int(sched.depth.max()) + 1):
            out = dec.teacher_forcing(z, batch, w, sched)
            w = out.prior_mu
            if eps is not None:
                w = w + torch.exp(0.5 * out.prior_logvar) * eps[batch.batch, local_index]
    check_agrees(dec, z, trees, w, max_nodes, max_depth)


def test_node_latent_inputs_are_checked() -> None:
    dec = make_decoder()
    z = torch.randn(2, 8)
    with pytest.raises(ValueError, match="node_noise must be"):
        dec.decode(z, max_nodes=10, node_noise=torch.randn(2, 5, DW))
    with pytest.raises(ValueError, match="2 robots for 1"):
        dec.decode(z[:1], node_latents=[torch.zeros(3, DW)] * 2)
    with pytest.raises(ValueError, match=r"must be \[n, 6\]"):
        dec.decode(z, node_latents=[torch.zeros(3, DW), torch.zeros(3, DW + 1)])
    with pytest.raises(ValueError, match="needs node latents"):
        TreeDecoder(FULL.dim, 3, 32, 8, 0)
    with pytest.raises(ValueError, match="feature_layers >= 1"):
        TreeDecoder(FULL.dim, 3, 32, 8, DW, feature_layers=0)


def test_node_kl_is_the_gaussian_kl() -> None:
    """``kl_nodes`` = sum over a graph's nodes of KL(N(mu^q, e^{lambda^q}) || N(mu^p, e^{lambda^p}))
    (torch.distributions), averaged over graphs, and weighted by ``beta_nodes`` in the loss."""
    rng = random.Random(1)
    trees = [random_tree(n, rng) for n in (1, 7, 12)]
    batch = Batch.from_data_list(trees)
    dec = make_decoder()
    n = batch.num_nodes
    qm, qlv = torch.randn(n, DW), torch.randn(n, DW)
    z = torch.randn(3, 8)
    out = dec.teacher_forcing(z, batch, qm)
    mu, logvar = torch.randn(3, 8), torch.randn(3, 8)
    base = vae_loss(out, batch, mu, logvar, beta=0.5)
    terms = vae_loss(out, batch, mu, logvar, beta=0.5, node_mu=qm, node_logvar=qlv,
                     beta_nodes=0.25)
    q = torch.distributions.Normal(qm, torch.exp(0.5 * qlv))
    p = torch.distributions.Normal(out.prior_mu, torch.exp(0.5 * out.prior_logvar))
    per_node = torch.distributions.kl_divergence(q, p).sum(1)
    per_graph = torch.zeros(3).index_add(0, batch.batch, per_node)
    torch.testing.assert_close(terms["kl_nodes"], per_graph.mean())
    torch.testing.assert_close(terms["loss"], base["loss"] + 0.25 * per_graph.mean())
    assert float(base["kl_nodes"]) == 0.0


def test_soft_clamp_bounds_log_variances() -> None:
    x = torch.tensor([-1e6, -30.0, -1.0, 0.0, 1.0, 30.0, 1e6])
    y = soft_clamp(x)
    assert bool((y.abs() <= 10).all()) and bool((y.diff() >= 0).all())
    torch.testing.assert_close(soft_clamp(torch.tensor([0.5])), torch.tensor([0.5]),
                               atol=1e-3, rtol=0)


@pytest.mark.parametrize("feature_layers", [1, 3])
def test_every_parameter_gets_a_gradient_with_node_latents(feature_layers: int) -> None:
    torch.manual_seed(0)
    batch = random_batch()
    enc = TreeEncoder(FULL.dim, 32, 8, node_latent_dim=DW)
    dec = TreeDecoder(FULL.dim, 3, 32, 8, DW, type_mask=FULL.type_mask(),
                      feature_layers=feature_layers)
    sched = tree_schedule(batch)
    mu, logvar = enc(batch, sched)
    wm, wlv = enc.node_readout(*enc.messages(batch, sched), sched)
    out = dec.teacher_forcing(reparametrize(mu, logvar), batch, reparametrize(wm, wlv), sched)
    vae_loss(out, batch, mu, logvar, 1.0, wm, wlv)["loss"].backward()
    for name, p in [*enc.named_parameters(), *dec.named_parameters()]:
        assert p.grad is not None and bool(p.grad.abs().sum() > 0), name


def test_tree_and_types_come_from_the_tree_latent_alone() -> None:
    """The decoded tree and node types are a function of z_T (the first ``tree_latent_dim``
    columns of z) alone: the rest of z and the node latents (given, drawn or at their prior
    mean) change the features only."""
    torch.manual_seed(2)
    dec = TreeDecoder(FULL.dim, 3, 32, 8, DW, tree_latent_dim=3,
                      type_mask=FULL.type_mask()).eval()
    with torch.no_grad():
        dec.topo.u.bias.add_(VARIED[1])
    z = torch.randn(12, 8) * 2
    other = z.clone()
    other[:, 3:] = torch.randn(12, 5) * 3
    runs = [dec.decode(z, max_nodes=80, max_depth=20),
            dec.decode(other, max_nodes=80, max_depth=20),
            dec.decode(z, max_nodes=80, max_depth=20,
                       node_noise=torch.randn(12, 80, DW) * 2),
            dec.decode(z, max_nodes=80, max_depth=20,
                       node_latents=[torch.randn(200, DW) for _ in range(12)])]
    assert len({p.numel() for p, _, _ in runs[0]}) > 3  # trees of several sizes
    for run in runs[1:]:
        for (p0, t0, x0), (p1, t1, x1) in zip(runs[0], run):
            assert torch.equal(p0, p1) and torch.equal(t0, t1)
            assert not torch.allclose(x0, x1)
    with pytest.raises(ValueError, match="tree_latent_dim"):
        TreeDecoder(FULL.dim, 3, 32, 8, DW, tree_latent_dim=9)
