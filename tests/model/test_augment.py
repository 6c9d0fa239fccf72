"""Feature augmentation (``feature_shift`` / ``feature_noise``): what it perturbs and what not."""

from __future__ import annotations

import torch
from torch_geometric.data import Batch

from robovae.data.features import get_feature_set
from robovae.data.graph import tree_data
from robovae.model.augment import jitter_features
from robovae.model.vae import RoboVAE

FS = get_feature_set("paper34")


def _batch(n_graphs: int = 3) -> Batch:
    graphs = []
    for g in range(n_graphs):
        parent = [-1, 0, 1, 2, 1, 4]
        types = [1, 0, 1, 0, 1, 0]
        x = torch.rand(6, FS.dim) + g
        graphs.append(tree_data(parent, types, x, FS, name=f"r{g}"))
    return Batch.from_data_list(graphs)


def test_zero_std_is_identity():
    b = _batch()
    assert jitter_features(b.x, b.x_mask, b.batch, 3, 0.0, 0.0) is b.x


def test_shift_is_per_robot_and_column_and_keeps_foreign_columns():
    b = _batch()
    x = torch.zeros_like(b.x)
    out = jitter_features(x, b.x_mask, b.batch, 3, shift=1.0, noise=0.0,
                          generator=torch.Generator().manual_seed(0))
    assert (out[~b.x_mask] == 0).all()  # foreign columns stay zero
    for g in range(3):
        rows = out[b.batch == g]
        own = b.x_mask[b.batch == g]
        for t in (0, 1):  # every node of a type gets the same offset per column
            sel = rows[b.node_type[b.batch == g] == t]
            assert torch.allclose(sel, sel[:1].expand_as(sel))
        assert rows[own].abs().sum() > 0
    assert not torch.allclose(out[b.batch == 0], out[b.batch == 1])


def test_categorical_columns_are_kept():
    b = _batch(1)
    keep = torch.zeros(FS.dim, dtype=torch.bool)
    keep[:5] = True
    out = jitter_features(b.x, b.x_mask, b.batch, 1, 1.0, 1.0, keep=keep)
    assert torch.equal(out[:, :5], b.x[:, :5])
    assert not torch.equal(out[:, 5:], b.x[:, 5:])


def test_model_jitters_in_training_only():
    b = _batch(2)
    model = RoboVAE(hidden_dim=16, latent_dim=4, feature_shift=0.5, feature_noise=0.1)
    x = torch.cat([d.x for d in b.to_data_list()])
    model.normalizer.fit(x, b.node_type)
    model.eval()
    a = model(b, sample=False)["loss"]
    assert torch.equal(a, model(b, sample=False)["loss"])  # eval: deterministic, no jitter
    model.train()
    g1, g2 = (torch.Generator().manual_seed(1) for _ in range(2))
    t1, t2 = model(b, generator=g1)["loss"], model(b, generator=g2)["loss"]
    assert torch.equal(t1, t2)  # the batch generator drives the jitter: reproducible
    assert not torch.equal(t1, model(b, generator=torch.Generator().manual_seed(2))["loss"])


def test_augmentation_stops_after_augment_until():
    """``augment_until=0.5`` of 4 epochs: epochs 0-1 perturb the features, epochs 2-3 train on
    the true ones."""
    import lightning as L
    from torch_geometric.loader import DataLoader

    b = _batch(2)
    model = RoboVAE(hidden_dim=16, latent_dim=4, feature_shift=0.5, augment_until=0.5)
    model.normalizer.fit(torch.cat([d.x for d in b.to_data_list()]), b.node_type)
    flags = []

    class Record(L.Callback):
        def on_train_epoch_start(self, trainer, pl_module):
            flags.append(pl_module.augmenting())

    trainer = L.Trainer(max_epochs=4, logger=False, enable_checkpointing=False,
                        enable_progress_bar=False, enable_model_summary=False,
                        callbacks=[Record()])
    trainer.fit(model, DataLoader(b.to_data_list(), batch_size=2))
    assert flags == [True, True, False, False]
    assert not RoboVAE(hidden_dim=16, latent_dim=4).augmenting()  # nothing to augment
    assert RoboVAE(hidden_dim=16, latent_dim=4, feature_noise=0.1).augmenting()  # no trainer
