"""VAE loss: reduction, exact batching, training decreases it, a single tree can be overfitted."""

from __future__ import annotations

import math
import random

import torch
from torch_geometric.data import Batch

from robovae.data.features import get_feature_set
from robovae.data.graph import tree_data
from robovae.model.decoder import TreeDecoder
from robovae.model.encoder import TreeEncoder, reparametrize
from robovae.model.loss import vae_loss
from robovae.model.tree import tree_schedule
from robovae.model.vae import RoboVAE
from tests.conftest import random_parent
from tests.conftest import random_shape as random_tree

FULL = get_feature_set("full")
DW = 8  # node latent width


def model(fs: str = "full", hidden: int = 32, latent: int = 8, seed: int = 0):
    torch.manual_seed(seed)
    f = get_feature_set(fs)
    return (TreeEncoder(f.dim, hidden, latent, DW),
            TreeDecoder(f.dim, f.num_node_types, hidden, latent, DW, type_mask=f.type_mask()))


def losses(enc, dec, batch, beta=1.0, sample=False):
    """Loss terms of the encoder then the decoder (``z``, ``w`` drawn with ``sample``, else
    the posterior means)."""
    sched = tree_schedule(batch)
    x, inward = enc.messages(batch, sched)
    mu, logvar = enc.readout(x, inward, sched)
    wm, wlv = enc.node_readout(x, inward, sched)
    z, w = (reparametrize(mu, logvar), reparametrize(wm, wlv)) if sample else (mu, wm)
    return vae_loss(dec.teacher_forcing(z, batch, w, sched), batch, mu, logvar, beta, wm, wlv)


def test_batching_is_exact() -> None:
    rng = random.Random(0)
    trees = [random_tree(1, rng), random_tree(50, rng, 0.0), random_tree(15, rng, 1.0)]
    trees += [random_tree(rng.randint(2, 45), rng, rng.random()) for _ in range(61)]
    enc, dec = model()
    enc.eval(), dec.eval()
    with torch.no_grad():
        out = losses(enc, dec, Batch.from_data_list(trees), beta=0.5)
        single = torch.cat([losses(enc, dec, Batch.from_data_list([t]), beta=0.5)
                            ["per_graph_loss"] for t in trees])
    assert out["per_graph_loss"].shape == (64,)
    torch.testing.assert_close(out["per_graph_loss"], single, atol=1e-5, rtol=1e-6)
    torch.testing.assert_close(out["loss"], out["per_graph_loss"].mean())
    total = out["topo"] + out["feat"] + out["type"] + 0.5 * (out["kl"] + out["kl_nodes"])
    torch.testing.assert_close(out["loss"], total)
    assert float(out["type"]) > 0 and float(out["topo"]) > 0 and float(out["feat"]) > 0


def test_terms_by_hand() -> None:
    rng = random.Random(1)
    t = random_tree(6, rng, fs="random5")
    enc, dec = model("random5")
    mu, logvar = torch.randn(1, 8), torch.randn(1, 8)
    out = dec.teacher_forcing(mu, t, torch.randn(t.num_nodes, DW))
    res = vae_loss(out, t, mu, logvar, beta=2.0)  # (no node posterior: kl_nodes = 0)
    kl = -0.5 * (1 + logvar - mu**2 - logvar.exp()).sum()  # eq. 8 with B = 1
    torch.testing.assert_close(res["kl"], kl)
    assert float(res["type"]) == 0.0  # one node type
    feat = ((out.feat_pred - t.x) ** 2).mean(1).sum()
    torch.testing.assert_close(res["feat"], feat)
    bce = torch.nn.functional.binary_cross_entropy_with_logits(
        out.topo_logits, out.topo_target, reduction="sum")
    torch.testing.assert_close(res["topo"], bce)
    torch.testing.assert_close(res["loss"], bce + feat + 2.0 * kl)
    # the negative ELBO: every term at weight 1, features as a unit-variance Gaussian (nats)
    nll = 0.5 * ((out.feat_pred - t.x) ** 2).sum() + 0.5 * math.log(2 * math.pi) * t.x.numel()
    torch.testing.assert_close(res["per_graph_nelbo"], (bce + nll + kl)[None])


def test_loss_decreases() -> None:
    rng = random.Random(2)
    batch = Batch.from_data_list([random_tree(rng.randint(1, 30), rng, rng.random())
                                  for _ in range(16)])
    enc, dec = model()
    opt = torch.optim.Adam([*enc.parameters(), *dec.parameters()], lr=3e-3)
    first = None
    for _ in range(100):
        loss = losses(enc, dec, batch, beta=0.1, sample=True)["loss"]
        first = float(loss) if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        final = float(losses(enc, dec, batch, beta=0.1)["loss"])
    assert final < 0.6 * first


def test_overfit_single_tree() -> None:
    """A 15-node tree is reconstructed exactly by greedy decoding of its mean latent."""
    rng = random.Random(3)
    torch.manual_seed(3)
    t = tree_data(random_parent(15, rng, 0.4), [0] * 15, torch.rand(15, 5), "random5")
    t.x = (t.x - 0.5) / 0.29  # roughly standardised, as the Normalizer would
    enc, dec = model("random5", hidden=64, latent=16)
    opt = torch.optim.Adam([*enc.parameters(), *dec.parameters()], lr=3e-3)
    for _ in range(300):
        loss = losses(enc, dec, t, beta=1e-3, sample=True)["loss"]
        opt.zero_grad()
        loss.backward()
        opt.step()
    enc.eval(), dec.eval()
    with torch.no_grad():
        sched = tree_schedule(t)
        h = enc.messages(t, sched)
        mu, _ = enc.readout(*h, sched)
        wm, _ = enc.node_readout(*h, sched)
        parent, types, x = dec.decode(mu, max_nodes=64, max_depth=32, node_latents=[wm])[0]
    assert parent.tolist() == t.parent.tolist()
    assert types.tolist() == [0] * 15
    assert float(((x - t.x) ** 2).mean()) < 0.05


def test_vae_forward_is_encoder_then_decoder() -> None:
    """RoboVAE.forward (the tree encoder's and the feature encoder's level passes stacked, then
    the decoder) gives the loss of the two encoders and the decoder called one after the
    other, with z = [z_T, z_G]."""
    rng = random.Random(3)
    trees = [random_tree(rng.randint(1, 30), rng, rng.random(), fs="paper34") for _ in range(6)]
    batch = Batch.from_data_list(trees)
    torch.manual_seed(0)
    vae = RoboVAE(hidden_dim=16, latent_dim=6, tree_latent_dim=2, node_latent_dim=3).eval()
    vae.normalizer.fit(batch.x, batch.node_type)
    nb = vae.normalized(batch)
    with torch.no_grad():
        out = vae(batch, sample=False)
        sched = tree_schedule(nb)
        mt, lt = vae.tree_encoder(nb, sched)
        x, inward = vae.encoder.messages(nb, sched)
        mg, lg = vae.encoder.readout(x, inward, sched)
        wm, wlv = vae.encoder.node_readout(x, inward, sched)
        mu, logvar = torch.cat([mt, mg], 1), torch.cat([lt, lg], 1)
        ref = vae_loss(vae.decoder.teacher_forcing(mu, nb, wm, sched), nb, mu, logvar,
                       vae.beta_at(0), wm, wlv, tree_dim=2)
    for k in ("loss", "topo", "feat", "type", "kl", "kl_tree", "kl_nodes"):
        torch.testing.assert_close(out[k], ref[k], atol=1e-5, rtol=1e-5)
    assert float(ref["kl_tree"]) < float(ref["kl"])
