"""The sampling mixture: fitted by EM to training latents at the end of training, drawn from
per robot, stored in the checkpoint, and switched off by ``prior="standard"``."""

from __future__ import annotations

import json

import lightning as L
import numpy as np
import pytest
import torch
from lightning.pytorch.callbacks import ModelCheckpoint

from robovae.data.datamodule import RobotDataModule
from robovae.generate.pipeline import generate
from robovae.model.checkpoint import load_model
from robovae.model.latent_mixture import LatentMixture, principal_basis
from robovae.model.prior import latent, latent_rng
from robovae.model.vae import RoboVAE


def test_em_recovers_two_clusters():
    g = torch.Generator().manual_seed(0)
    a = torch.randn(300, 4, generator=g) * 0.5 - 5.0
    b = torch.randn(700, 4, generator=g) * 1.0 + 5.0
    mix = LatentMixture(4, 2).fit(torch.cat([a, b]))
    order = mix.means[:, 0].argsort()
    assert torch.allclose(mix.weights[order], torch.tensor([0.3, 0.7]), atol=1e-3)
    assert torch.allclose(mix.means[order], torch.tensor([[-5.0] * 4, [5.0] * 4]), atol=0.15)
    assert torch.allclose(mix.stds[order], torch.tensor([[0.5] * 4, [1.0] * 4]), atol=0.1)
    # the fitted density prefers the clusters to the gap between them
    assert bool((mix.log_prob(torch.tensor([[5.0] * 4, [-5.0] * 4]))
                 > mix.log_prob(torch.zeros(1, 4))).all())


def test_draws_are_per_generator_and_temperature_scales_the_spread():
    mix = LatentMixture(3, 2)
    mix.means.copy_(torch.tensor([[1.0, 2.0, 3.0], [-1.0, -2.0, -3.0]]))
    mix.stds.fill_(0.5)
    one = mix.draw(np.random.default_rng([4, 2]))
    assert torch.equal(one, mix.draw(np.random.default_rng([4, 2])))
    cold = mix.draw(np.random.default_rng([4, 2]), temperature=0.0)
    assert any(torch.equal(cold, m) for m in mix.means)
    hot = mix.draw(np.random.default_rng([4, 2]), temperature=2.0)
    assert not torch.equal(one, cold)
    assert torch.allclose(hot - cold, 2.0 * (one - cold))


def test_moments_are_those_of_the_draws():
    mix = LatentMixture(3, 2)
    mix.weights.copy_(torch.tensor([0.25, 0.75]))
    mix.means.copy_(torch.tensor([[1.0, 2.0, 3.0], [-1.0, 0.0, 1.0]]))
    mix.stds.copy_(torch.tensor([[0.5, 0.2, 1.0], [0.3, 0.3, 0.3]]))
    mean, cov = mix.moments()
    rng = np.random.default_rng(0)
    z = torch.stack([mix.draw(rng) for _ in range(20000)]).double().numpy()
    assert np.allclose(mean, z.mean(0), atol=0.03)
    assert np.allclose(cov, np.cov(z.T), atol=0.05)
    assert cov[0, 2] > 0.5  # the components' means correlate the coordinates


def test_principal_basis_refuses_a_variance_out_of_range():
    """0 kept one direction, 2 and NaN every direction, without a word."""
    from robovae.errors import SettingsError

    assert principal_basis(np.diag([4.0, 1.0]), 0.8).shape == (2, 1)
    for bad in (0.0, 2.0, float("nan"), -0.5):
        with pytest.raises(SettingsError, match=r"principal_basis.variance must be a number in"):
            principal_basis(np.diag([4.0, 1.0]), bad)


def test_fewer_latents_than_components_is_refused():
    with pytest.raises(ValueError, match="at least 5 latents"):
        LatentMixture(2, 5).fit(torch.zeros(3, 2))


def test_latents_that_are_not_finite_or_of_another_size_are_refused():
    """A NaN latent (a diverged model) fitted a NaN mixture, and a latent_dim of -1 was a
    torch error, until 2026-11-29."""
    mix = LatentMixture(2, 2)
    x = torch.randn(10, 2)
    x[3, 1] = float("nan")
    with pytest.raises(ValueError, match="1 of 10 latents to fit the mixture to are not finite"):
        mix.fit(x)
    assert not bool(mix.fitted)
    with pytest.raises(ValueError, match=r"fitted to latents \[N, 2\], got \[10, 3\]"):
        mix.fit(torch.randn(10, 3))
    with pytest.raises(ValueError, match="LatentMixture.latent_dim must be an integer >= 1"):
        LatentMixture(-1, 2)


@pytest.fixture(scope="module")
def mixture_model(tmp_path_factory):
    """A small model trained 2 epochs on the zoo with a 3-component sampling mixture."""
    tmp = tmp_path_factory.mktemp("mixture")
    L.seed_everything(0)
    dm = RobotDataModule(["zoo"], root=str(tmp / "cache"), test_names=["gym_hopper"],
                         batch_size=8)
    model = RoboVAE(hidden_dim=32, latent_dim=8, max_nodes=64, prior_components=3)
    # the checkpoint the run itself writes after its last validation
    saver = ModelCheckpoint(dirpath=tmp / "ckpt", save_last=True)
    trainer = L.Trainer(max_epochs=2, accelerator="cpu", devices=1, logger=False,
                        callbacks=[saver], enable_progress_bar=False,
                        enable_model_summary=False, default_root_dir=tmp,
                        limit_train_batches=2, limit_val_batches=1)
    trainer.fit(model, dm)
    return model.eval(), dm, tmp / "ckpt" / "last.ckpt"


def test_mixture_is_fitted_after_training_and_travels_in_the_checkpoint(mixture_model):
    model, dm, ckpt = mixture_model
    mix = model.latent_mixture
    assert bool(mix.fitted) and model.sampling_mixture() is mix
    # fitted to the training robots' posterior means: they are likelier under it than under
    # the standard normal
    mu, _ = model.encode(dm.train_set[0])
    standard = torch.distributions.Normal(0.0, 1.0).log_prob(mu).sum(1)
    assert float(mix.log_prob(mu)[0]) > float(standard[0])
    loaded = load_model(ckpt)
    for key, value in mix.state_dict().items():
        assert torch.equal(loaded.latent_mixture.state_dict()[key], value)
    assert torch.equal(loaded.prior_latent(3, 7), mix.draw(latent_rng(3, 7)))
    assert not torch.equal(loaded.prior_latent(3, 7), latent(3, 7, 8))
    loaded.hparams.prior = "standard"
    assert loaded.sampling_mixture() is None
    assert torch.equal(loaded.prior_latent(3, 7), latent(3, 7, 8))


def test_checkpoint_without_a_mixture_loads_unfitted(mixture_model, tmp_path):
    _, _, ckpt = mixture_model
    data = torch.load(ckpt, weights_only=True)
    data["state_dict"] = {k: v for k, v in data["state_dict"].items()
                          if not k.startswith("latent_mixture.")}
    old = tmp_path / "old.ckpt"
    torch.save(data, old)
    model = load_model(old)
    assert model.sampling_mixture() is None
    assert torch.equal(model.prior_latent(0, 1), latent(0, 1, 8))


def test_generate_records_the_prior_it_used(mixture_model, tmp_path):
    model, _, _ = mixture_model
    generate(model, 2, tmp_path / "mix", validate=False, jobs=1, progress=False)
    generate(model, 2, tmp_path / "std", validate=False, jobs=1, progress=False,
             prior="standard")
    runs = {k: json.loads((tmp_path / k / "run.json").read_text())["prior"]
            for k in ("mix", "std")}
    assert runs == {"mix": "mixture", "std": "standard"}
    recs = {k: [json.loads(line)
                for line in (tmp_path / k / "manifest.jsonl").read_text().splitlines()]
            for k in ("mix", "std")}
    assert [r["latent"] for r in recs["mix"]] != [r["latent"] for r in recs["std"]]
    for r in recs["std"]:  # (a draw > 0 redrew an unfinished tree)
        want = latent(0, r["index"], 8, draw=r["draw"])
        assert np.allclose(r["latent"], want.numpy(), atol=1e-6)
    for r in recs["mix"]:
        want = model.latent_mixture.draw(latent_rng(0, r["index"], r["draw"]))
        assert np.allclose(r["latent"], want.numpy(), atol=1e-6)


def test_optimize_starts_cma_with_the_prior_moments(mixture_model, tmp_path):
    """CMA-ES searches where the sampling prior puts robots: ``z = m + B y`` with the mixture's
    mean ``m`` and ``B B^T`` its covariance (the whole space at ``variance=1``), from ``y = 0``
    (N(0, I) without a mixture)."""
    from robovae.design.optimize import _Run

    model, _, _ = mixture_model
    mean, cov = model.sampling_mixture().moments()
    run = _Run(model, "walk", 4, tmp_path, seed=0, jobs=1, top=1, variance=1.0)
    assert np.allclose(run.origin, mean) and np.allclose(run.basis @ run.basis.T, cov)
    assert np.allclose(run.cma.mean, 0) and run.settings["cma_start"] == "prior moments"
    ys, zs, _, _ = run.ask()
    assert np.allclose(zs[1], mean + run.basis @ ys[1])
    model.hparams.prior = "standard"
    try:
        run = _Run(model, "walk", 4, tmp_path, seed=0, jobs=1, top=1, variance=1.0)
        assert np.allclose(run.origin, 0)
        assert np.allclose(run.basis @ run.basis.T, np.eye(len(mean)))
    finally:
        model.hparams.prior = "mixture"


def test_principal_basis_keeps_the_leading_variance():
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    cov = q @ np.diag([4.0, 3.0, 2.0, 0.5, 0.3, 0.2]) @ q.T  # trace 10
    assert np.allclose(principal_basis(cov, 1.0) @ principal_basis(cov, 1.0).T, cov)
    b = principal_basis(cov, 0.9)  # 4 + 3 + 2 = 90 % of the trace
    assert b.shape == (6, 3)
    assert np.allclose(b.T @ b, np.diag([4.0, 3.0, 2.0]))  # whitened: y ~ N(0, I) -> C_k
    assert principal_basis(cov, 0.91).shape == (6, 4)
    assert principal_basis(cov, 0.3).shape == (6, 1)


def test_prior_spread_is_the_root_mean_square_of_the_priors_draws(mixture_model):
    """In the radius' units (whitened principal subspace) the prior's draws lie sqrt(k) from
    its mean, root mean square: measured on draws of the sampling mixture."""
    from robovae.design import variations

    model, _, _ = mixture_model
    mean, basis = model.prior_directions(variations.LIKE_VARIANCE)
    draws = np.stack([model.prior_latent(0, i).double().numpy() for i in range(4000)])
    y = np.linalg.lstsq(basis, (draws - mean).T, rcond=None)[0].T
    assert variations.prior_spread(model) == pytest.approx(np.sqrt(basis.shape[1]))
    assert np.sqrt((y ** 2).sum(1).mean()) == pytest.approx(variations.prior_spread(model),
                                                            rel=0.05)
