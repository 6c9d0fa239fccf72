"""Training-time augmentation: feature jitter (``feature_shift`` / ``feature_noise``) and tree
surgery (``tree_surgery``): what they change and what not."""

from __future__ import annotations

import random

import pytest
import torch
from torch_geometric.data import Batch

from robovae.data.features import get_feature_set
from robovae.data.graph import children, tree_data
from robovae.model.augment import SURGERY_OPS, jitter_features, tree_surgery
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


# --- tree surgery ----------------------------------------------------------------------------


def _robots() -> list:
    """Two robots with distinct feature rows: J(L(J(L(J(L))) J(L))) and J(L(J(L) J(L) J(L)))."""
    specs = [([-1, 0, 1, 2, 3, 4, 1, 6], [1, 0, 1, 0, 1, 0, 1, 0]),
             ([-1, 0, 1, 2, 1, 4, 1, 6], [1, 0, 1, 0, 1, 0, 1, 0])]
    out = []
    for g, (parent, types) in enumerate(specs):
        x = torch.arange(len(parent) * FS.dim, dtype=torch.float32).view(len(parent), FS.dim)
        out.append(tree_data(parent, types, x + 1000 * g, FS, name=f"r{g}"))
    return out


def _shape(d) -> str:
    ch, t = children(d.parent), d.node_type.tolist()

    def rec(i: int) -> str:
        return "LJ"[t[i]] + ("(" + "".join(rec(k) for k in ch[i]) + ")" if ch[i] else "")

    return rec(0)


def _rows(d) -> set[tuple]:
    return {(int(t), tuple(r.tolist())) for t, r in zip(d.node_type, d.x, strict=True)}


def _edges(d) -> set[tuple]:
    """(parent type, parent row, child type, child row) of every edge: limbs move whole."""
    kid = (d.parent >= 0).nonzero().flatten()
    return {(int(d.node_type[p]), tuple(d.x[p].tolist()), int(d.node_type[c]),
             tuple(d.x[c].tolist())) for p, c in zip(d.parent[kid], kid, strict=True)
            if c != 0}


def test_surgery_off_keeps_every_robot():
    robots = _robots()
    out = tree_surgery(robots, FS, 0.0, 3, 64, random.Random(0))
    for a, b in zip(robots, out, strict=True):
        assert torch.equal(a.parent, b.parent) and torch.equal(a.x, b.x)


@pytest.mark.parametrize("op", SURGERY_OPS)
def test_each_edit_gives_a_valid_tree_of_known_limbs(op):
    robots = _robots()
    known = set().union(*(_rows(d) for d in robots))
    changed = 0
    for seed in range(20):
        out = tree_surgery(robots, FS, 1.0, 1, 64, random.Random(seed), ops=(op,))
        for before, after in zip(robots, out, strict=True):
            # tree_data validated the pre-order; features travel with their node and type
            assert _rows(after) <= known
            assert torch.equal(after.x_mask, FS.mask(after.node_type))
            assert after.node_type[0] == before.node_type[0]  # the root is never edited
            edges = set().union(*(_edges(d) for d in robots))
            if op == "graft":  # a new edge, host link -> donor limb: compare the types only
                edges, new = {(e[0], e[2]) for e in edges}, {(e[0], e[2]) for e in _edges(after)}
            else:
                new = _edges(after)
            assert new <= edges
            n0, n1 = before.num_nodes, after.num_nodes
            assert {"drop": n1 < n0, "duplicate": n1 > n0, "graft": n1 > n0,
                    "swap": n1 == n0}[op]
            changed += _shape(after) != _shape(before)
    assert changed > 0


def test_swap_exchanges_adjacent_siblings():
    robot = _robots()[0]  # J(L(J(L(J(L))) J(L))): the base link's two limbs
    (out,) = tree_surgery([robot], FS, 1.0, 1, 64, random.Random(0), ops=("swap",))
    assert _shape(robot) == "J(L(J(L(J(L)))J(L)))"
    assert _shape(out) == "J(L(J(L)J(L(J(L)))))"
    assert torch.equal(out.x[2], robot.x[6]) and torch.equal(out.x[4], robot.x[2])


def test_duplicate_and_graft_respect_max_nodes():
    for seed in range(20):
        for d in tree_surgery(_robots(), FS, 1.0, 5, 9, random.Random(seed),
                              ops=("duplicate", "graft")):
            assert d.num_nodes <= 9


def test_unknown_op_is_refused():
    with pytest.raises(ValueError, match="unknown tree surgery ops"):
        tree_surgery(_robots(), FS, 1.0, 1, 64, random.Random(0), ops=("mirror",))


def test_model_rebuilds_trees_in_training_only():
    robots = _robots()
    b = Batch.from_data_list(robots)
    model = RoboVAE(hidden_dim=16, latent_dim=4, tree_surgery=1.0, surgery_ops=2)
    model.normalizer.fit(b.x, b.node_type)
    model.eval()
    assert torch.equal(model(b, sample=False)["loss"], model(b, sample=False)["loss"])
    model.train()
    losses = [model(b, generator=torch.Generator().manual_seed(k))["loss"] for k in (1, 1, 2)]
    assert torch.equal(losses[0], losses[1])  # the batch generator drives the surgery
    assert not torch.equal(losses[0], losses[2])
    assert all(torch.isfinite(t) for t in losses)
