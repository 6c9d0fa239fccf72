"""RoboVAE as a LightningModule: overfitting Go2, checkpoints that carry the normaliser,
the public API, and the Lightning CLI with its loggers."""

from __future__ import annotations

import csv
import math
import warnings
from pathlib import Path

import lightning as L
import pytest
import torch
from torch_geometric.data import Batch

from robovae.cli import main
from robovae.data.datamodule import RobotDataModule
from robovae.errors import RobovaeError
from robovae.evaluate.callbacks import (
    ReconstructionMetrics,
    score_split,
    split_metrics_from_z,
)
from robovae.model.checkpoint import load_model
from robovae.model.vae import RoboVAE
from tests.conftest import REPO


def _trainer(tmp_path: Path, epochs: int, **kw) -> L.Trainer:
    return L.Trainer(max_epochs=epochs, accelerator="cpu", devices=1, logger=False,
                     enable_checkpointing=False, enable_progress_bar=False,
                     enable_model_summary=False, default_root_dir=tmp_path, **kw)


def test_overfit_go2(tmp_path, menagerie_dir, cache_root):
    """The paper's first check: one robot, RA 100 % and FRE ~ 0 (here < 1e-4; 600 steps reach
    6.7e-5, 400 do not)."""
    L.seed_everything(0)
    dm = RobotDataModule([f"dir:{menagerie_dir}"], root=str(cache_root), train_names=["go2"],
                         test_names=["go2"], val_is_train=True, batch_size=1)
    model = RoboVAE(hidden_dim=128, beta=1e-4, lr=3e-3)
    _trainer(tmp_path, 600, check_val_every_n_epoch=600).fit(model, dm)
    (res,) = score_split(model.eval(), dm.test_set)
    assert res.ra == 1.0 and res.exact
    assert res.fre < 1e-4, res.fre


def test_checkpoint_alone_decodes_the_same_robot(trained):
    model, dm, ckpt = trained
    loaded = RoboVAE.load_from_checkpoint(ckpt).eval()
    assert bool(loaded.normalizer.fitted)
    assert torch.equal(loaded.normalizer.mean, dm.normalizer.mean)
    robot = dm.test_set[0]
    a, b = model.reconstruct(robot)[0], loaded.reconstruct(robot)[0]
    assert torch.equal(a.parent, b.parent) and torch.equal(a.node_type, b.node_type)
    assert torch.allclose(a.x, b.x)


def test_public_api(trained):
    model, dm, _ = trained
    batch = Batch.from_data_list(list(dm.test_set))
    mu, logvar = model.encode(batch)
    assert mu.shape == logvar.shape == (2, 8)
    decoded = model.decode(mu)
    assert len(decoded) == 2 and all(d.num_nodes <= 64 for d in decoded)
    assert [d.name for d in model.reconstruct(batch)] == ["gym_half_cheetah", "gym_hopper"]
    samples = model.sample(5, generator=torch.Generator().manual_seed(0))
    again = model.sample(5, generator=torch.Generator().manual_seed(0))
    assert [s.num_nodes for s in samples] == [s.num_nodes for s in again]
    for s in samples:  # physical units, own columns only, finite
        assert torch.isfinite(s.x).all() and (s.x[~s.x_mask] == 0).all()
    assert model.sample(0) == []
    # tracebacks of torch.stack or NumPy, or accepted (a negative temperature), until 2026-11-29
    for call, message in ((lambda: model.sample(-1), "sample.n must be an integer >= 0"),
                          (lambda: model.sample(2, temperature=-1.0),
                           "sample_prior.temperature must be a number >= 0"),
                          (lambda: model.sample(2, node_temperature=math.nan),
                           "sample_prior.node_temperature must be a number >= 0"),
                          (lambda: model.sample_prior(-1, [0]), "sample_prior seed must be an"),
                          (lambda: model.sample_prior(0, [3, -1]), "indices must be a non-empty "
                                                                   "sequence of integers >= 0, "
                                                                   "got -1")):
        with pytest.raises(ValueError, match=message):
            call()


def test_node_latent_api(trained_nodes):
    """encode_nodes gives each robot's latent and its nodes' latents in pre-order;
    reconstruct decodes exactly those (without support clipping); sample draws the nodes'
    latents from their prior, reproducibly."""
    model, dm, ckpt = trained_nodes
    robots = list(dm.test_set)
    batch = Batch.from_data_list(robots)
    mu, nodes = model.encode_nodes(batch)
    assert torch.equal(mu, model.encode(batch)[0])
    assert [n.shape for n in nodes] == [(r.num_nodes, 6) for r in robots]
    direct = model.decode(mu, node_latents=nodes, clamp=False)
    for a, b in zip(model.reconstruct(batch), direct):
        assert torch.equal(a.parent, b.parent) and torch.equal(a.x, b.x)
    loaded = RoboVAE.load_from_checkpoint(ckpt).eval()
    assert torch.equal(loaded.reconstruct(robots[0])[0].x, model.reconstruct(robots[0])[0].x)
    g = [[(s.num_nodes, float(s.x.sum())) for s in
          model.sample(4, generator=torch.Generator().manual_seed(k))] for k in (0, 0, 1)]
    assert g[0] == g[1] and g[0] != g[2]


@pytest.mark.parametrize("seed", [0, 1])
def test_node_latents_reconstruct_an_unseen_robot(tmp_path, menagerie_dir, cache_root, seed):
    """Trained on Go1 and A1 only, the model rebuilds Go2's tree, and its features closer
    than half the FRE of a one-latent model (0.48 in the 2-robot experiment of
    docs/results.md, which scores Go1's own features as 0.55)."""
    dm = RobotDataModule([f"dir:{menagerie_dir}"], root=str(cache_root),
                         train_names=["go1", "a1"], val_names=["go2"], test_names=["go2"],
                         batch_size=2, feature_shift=1.0, feature_noise=0.5)
    L.seed_everything(seed)
    model = RoboVAE(hidden_dim=32, latent_dim=16, beta=1e-4, lr=3e-3, node_latent_dim=32)
    _trainer(tmp_path, 300, check_val_every_n_epoch=10**6, gradient_clip_val=10).fit(model, dm)
    (res,) = score_split(model.eval(), dm.test_set)
    assert res.exact
    assert res.fre < 0.24, res.fre


def test_beta_annealing():
    model = RoboVAE(beta=0.1, beta_start=0.0, beta_warmup_epochs=10)
    assert model.beta_at(0) == 0.0 and model.beta_at(5) == pytest.approx(0.05)
    assert model.beta_at(50) == pytest.approx(0.1)


def test_feature_set_mismatch_is_refused(cache_root, tmp_path):
    dm = RobotDataModule(["synthetic:n=4,nodes=5,dim=5"], feature_set="random5",
                         root=str(cache_root))
    with pytest.raises(ValueError, match="feature set 'paper34'"):
        _trainer(tmp_path, 1).fit(RoboVAE(feature_set="paper34"), dm)


def _cli_args(tmp_path: Path, *extra: str) -> list[str]:
    return ["--config", str(REPO / "configs" / "zoo.yaml"),
            "--trainer.max_epochs=2", "--trainer.enable_progress_bar=false",
            "--trainer.limit_train_batches=2", f"--data.root={tmp_path / 'cache'}",
            "--model.hidden_dim=32", "--model.latent_dim=8", "--model.tree_latent_dim=4",
            "--model.max_nodes=64",
            "--metrics.every_n_epochs=1", "--trainer.check_val_every_n_epoch=1",
            f"--checkpoint.dirpath={tmp_path / 'ckpt'}", *extra]


def test_cli_fit_then_test_with_csv_logger(tmp_path, capsys):
    logs = tmp_path / "runs"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["fit", *_cli_args(tmp_path,
                                       f"--trainer.logger.init_args.save_dir={logs}")]) == 0
    # the libraries' deprecations inside Lightning and its warning about main([...]) are not
    # the user's business: none reaches the output
    said = [str(w.message) for w in caught]
    assert not [m for m in said if "LeafSpec" in m or "skip_none" in m or "args parameter" in m]
    ckpt = tmp_path / "ckpt" / "last.ckpt"
    assert ckpt.is_file()
    (metrics,) = logs.glob("robovae/version_*/metrics.csv")
    header = next(csv.reader(metrics.open()))
    for key in ["train/loss", "train/topo", "train/feat", "train/type", "train/kl",
                "val/loss", "val/RA", "val/RA_true", "val/exact", "val/FRE"]:
        assert key in header, key
    assert main(["test", *_cli_args(tmp_path, f"--trainer.logger.init_args.save_dir={logs}"),
                 f"--ckpt_path={ckpt}"]) == 0
    out = capsys.readouterr().out
    assert "test/RA" in out and "test/FRE" in out


def test_cli_fit_with_wandb_offline(tmp_path, monkeypatch):
    pytest.importorskip("wandb")
    monkeypatch.setenv("WANDB_SILENT", "true")
    monkeypatch.setenv("WANDB_DIR", str(tmp_path))
    args = _cli_args(tmp_path, "--config", str(REPO / "configs" / "loggers" / "wandb.yaml"),
                     f"--trainer.logger.init_args.save_dir={tmp_path / 'wb'}")
    assert main(["fit", *args]) == 0
    runs = list((tmp_path / "wb").glob("wandb/offline-run-*"))
    assert runs, "no offline wandb run folder"
    assert any(p.suffix == ".wandb" for p in runs[0].iterdir())


def test_print_config(capsys):
    with pytest.raises(SystemExit) as e:
        main(["fit", "--config", str(REPO / "configs" / "zoo.yaml"), "--print_config"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "hidden_dim: 128" in out and "feature_set: paper34" in out


@pytest.mark.parametrize("name", sorted(p.stem for p in (REPO / "configs").glob("*.yaml")
                                        if p.stem != "generate"))
def test_every_config_parses(name, capsys):
    """Every training config is accepted by the CLI as it is (keys, types, class paths)."""
    with pytest.raises(SystemExit) as e:
        main(["fit", "--config", str(REPO / "configs" / f"{name}.yaml"), "--print_config"])
    assert e.value.code == 0
    assert "seed_everything" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(p.stem for p in (REPO / "configs").glob("*.yaml")))
def test_every_config_passes_the_settings_checks(name, monkeypatch):
    """``--print_config`` builds no class: each config's ``data`` and ``model`` sections are
    built here, so that a settings rule (``robovae.settings``, the source checks) that a
    shipped config breaks fails a test, not a user's run."""
    import yaml

    monkeypatch.chdir(REPO)  # configs name folders relative to the repository
    config = yaml.safe_load((REPO / "configs" / f"{name}.yaml").read_text()) or {}
    sources = (config.get("data") or {}).get("sources", [])
    if any("../shared" in s for s in sources) and not (REPO.parent / "shared").is_dir():
        pytest.skip("the config reads ../shared, which is absent")
    if config.get("data"):
        RobotDataModule(**config["data"])
    if config.get("model"):
        RoboVAE(**config["model"])


def test_reconstruction_callback_logs_per_robot(trained, tmp_path):
    model, dm, _ = trained
    cb = ReconstructionMetrics(every_n_epochs=1)
    trainer = _trainer(tmp_path, 1, callbacks=[cb], limit_train_batches=1)
    trainer.test(model, dm, verbose=False)
    assert {"test/RA", "test/RA_true", "test/exact"} <= set(trainer.callback_metrics)
    assert "test/RA/gym_hopper" in trainer.callback_metrics
    assert len(cb.last["test"]) == 2


def test_checkpoints_of_earlier_versions_load_or_are_refused(trained_nodes, tmp_path):
    """A checkpoint written before the ablation switches and the augmentation knobs left the
    model loads when its model is the current one; a removed variant is refused in one line
    that says how to retrain."""
    model, dm, ckpt = trained_nodes
    data = torch.load(ckpt, weights_only=True)
    data["hyper_parameters"].update(topo_context=True, node_structure=True, local_heads=True,
                                    latent_inputs=False, decoder_inputs="types",
                                    feature_shift=1.0, feature_noise=0.5, tree_surgery=0.5,
                                    surgery_ops=3, augment_until=1.0)
    old = tmp_path / "old.ckpt"
    torch.save(data, old)
    robot = dm.test_set[0]
    assert torch.equal(load_model(old).reconstruct(robot)[0].x, model.reconstruct(robot)[0].x)
    data["hyper_parameters"].update(local_heads=False, decoder_inputs="features")
    torch.save(data, old)
    with pytest.raises(RobovaeError, match="removed.*local_heads=False.*retrain") as e:
        load_model(old)
    assert "\n" not in str(e.value)
    # the model before the tree latent: no tree encoder among its weights
    data = torch.load(ckpt, weights_only=True)
    data["state_dict"] = {k: v for k, v in data["state_dict"].items()
                          if not k.startswith("tree_encoder.")}
    torch.save(data, old)
    with pytest.raises(RobovaeError, match=f"{old}: .*no tree latent.*retrain") as e:
        load_model(old)
    assert "\n" not in str(e.value)


def test_from_z_reconstruction_and_latent_costs(trained_nodes):
    """From z alone: z = mu and every node latent at its conditional-prior mean; the latents'
    costs in nats: KL_z is the Gaussian KL of q(z | G), KL_nodes positive, and the negative
    ELBO per node covers both."""
    model, dm, _ = trained_nodes
    robots = list(dm.test_set)
    batch = Batch.from_data_list(robots)
    mu, logvar = model.encode(batch)
    for a, b in zip(model.reconstruct(batch, from_z=True), model.decode(mu, clamp=False)):
        assert torch.equal(a.parent, b.parent) and torch.equal(a.x, b.x)
    costs = model.latent_costs(batch)
    torch.testing.assert_close(costs["kl_z"], -0.5 * (1 + logvar - mu**2 - logvar.exp()).sum(1))
    assert costs["nodes"].tolist() == [r.num_nodes for r in robots]
    assert bool((costs["kl_nodes"] > 0).all())
    total = costs["nelbo_per_node"] * costs["nodes"]
    assert bool((total > costs["kl_z"] + costs["kl_nodes"]).all())
    m = split_metrics_from_z(model, robots)
    assert set(m) == {"RA_z", "RA_true_z", "exact_z", "FRE_z", "KL_z", "KL_tree", "KL_nodes",
                      "NELBO_node"}
    assert bool((costs["kl_tree"] > 0).all() and (costs["kl_tree"] < costs["kl_z"]).all())
    assert 0 <= m["RA_z"] <= 1 and m["KL_z"] == pytest.approx(float(costs["kl_z"].mean()))


@pytest.mark.parametrize(("setting", "message"), [
    ("--model.feature_layers=0", "model.feature_layers must be an integer >= 1, got 0"),
    ("--model.tree_latent_dim=0", "model.tree_latent_dim must be an integer >= 1, or null, "
                                  "got 0"),
    ("--model.tree_latent_dim=8", "tree_latent_dim must be in [1, latent_dim), got 8"),
    ("--model.node_temperature=-1", "model.node_temperature must be a number >= 0, or null, "
                                    "got -1.0"),
    # accepted before 2026-11-29: a negative KL weight or learning rate trained without a word,
    # an unknown schedule failed after the dataset was built
    ("--model.beta=-1", "model.beta must be a number >= 0, got -1.0"),
    ("--model.lr=0", "model.lr must be a number > 0, got 0.0"),
    ("--model.lr_schedule=step", "model.lr_schedule must be one of cosine, constant, got 'step'"),
    ("--data.feature_set=nope", "model.feature_set must be a feature set: paper34, kinematic, "
                                "full or random<d>, got 'nope'"),
    ("--data.batch_size=0", "data.batch_size must be an integer >= 1, got 0"),
    ("--data.val_fraction=0.9", "data.val_fraction + data.test_fraction must be below 1"),
    ("--data.tree_surgery=1.5", "data.tree_surgery must be a number in [0, 1], got 1.5"),
])
def test_cli_refuses_an_invalid_model_setting_in_one_line(setting, message, tmp_path, capsys,
                                                          monkeypatch):
    """A value a constructor refuses is one line naming the config file, exit code 2, and no
    run folder is written."""
    monkeypatch.chdir(tmp_path)
    tiny = REPO / "configs" / "tiny.yaml"
    code = main(["fit", "--config", str(tiny), setting, f"--data.root={tmp_path / 'cache'}"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    assert err.startswith(f"robovae: {tiny}: invalid setting: {message}"), err
    assert not (tmp_path / "runs").exists()


def test_reconstruction_callback_refuses_settings_out_of_range():
    """``every_n_epochs=0`` was silently read as 1."""
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match=r"ReconstructionMetrics\.every_n_epochs"):
        ReconstructionMetrics(every_n_epochs=0)
    with pytest.raises(SettingsError, match=r"ReconstructionMetrics\.max_per_robot"):
        ReconstructionMetrics(max_per_robot=-1)


def test_a_checkpoint_of_another_model_is_one_line(trained, tmp_path, capsys):
    """Loading a checkpoint into a model of other settings was torch's traceback listing every
    mismatched tensor; now one line naming the file and the settings that differ."""
    import re

    _, dm, ckpt = trained
    other = RoboVAE(hidden_dim=16, latent_dim=8, max_nodes=64)
    with pytest.raises(RobovaeError, match=re.escape(
            f"{ckpt}: a checkpoint of another model (hidden_dim 32 in the checkpoint, 16 here)")):
        _trainer(tmp_path, 1).test(other, dm, ckpt_path=str(ckpt), verbose=False)
    # the command line: LightningCLI takes the model's settings from the checkpoint, but the
    # data's feature set (linked to the model's) comes from the config
    argv = ["test", "--config", str(REPO / "configs" / "tiny.yaml"), "--ckpt_path", str(ckpt),
            "--data.root", str(tmp_path / "cache"), "--data.feature_set", "kinematic",
            "--trainer.default_root_dir", str(tmp_path), "--trainer.logger", "false"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"robovae: {ckpt}: a checkpoint of another model (feature_set 'paper34' "
                       "in the checkpoint, 'kinematic' here); build the model with the settings "
                       "it was trained with (its config, or robovae.model.checkpoint.load_model)")


def test_a_second_fit_into_a_checkpoint_folder_in_use_is_refused(tmp_path, capsys, monkeypatch,
                                                                 recwarn):
    """Two ``robovae fit`` runs writing one checkpoint folder overwrote each other's
    ``last.ckpt`` and deleted each other's epoch checkpoints (measured: two ``tiny.yaml`` runs
    of other learning rates, both exit 0, one ``last.ckpt`` left, until 2026-11-29); the
    second is refused before it trains while the first holds the folder (with no warning that
    the folder is not empty before its line), and a run holds it only while it runs."""
    from robovae.files import LOCK, FolderLock

    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "runs" / "tiny" / "checkpoints"
    argv = ["fit", "--config", str(REPO / "configs" / "tiny.yaml"),
            f"--data.root={tmp_path / 'cache'}", "--trainer.max_epochs=1"]
    with FolderLock(folder):  # the first run, still training
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.startswith(f"robovae: {folder}: another run is writing there")
        # refused before the checkpoint callback's setup warns of the folder in use
        assert not any("exists and is not empty" in str(w.message) for w in recwarn)
        assert sorted(p.name for p in folder.iterdir()) == [LOCK]
    recwarn.clear()
    assert main(argv) == 0  # once the first has ended
    assert (folder / "last.ckpt").is_file() and not (folder / LOCK).exists()
    # an empty folder is taken after the checkpoint callback looked: its own lock file sets off
    # no warning
    assert not any("exists and is not empty" in str(w.message) for w in recwarn)
