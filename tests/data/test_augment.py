"""Training-batch augmentation (robovae.data.augment): feature jitter and tree surgery, what
they change and what not, and how the datamodule applies them."""

from __future__ import annotations

import random

import pytest
import torch
from torch_geometric.data import Batch

from robovae.data.augment import SURGERY_OPS, FeatureJitter, TreeSurgery, tree_surgery
from robovae.data.features import get_feature_set
from robovae.data.graph import children, tree_data
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


def _jitter(b: Batch, shift: float, noise: float, seed: int = 0) -> torch.Tensor:
    j = FeatureJitter(FS, shift, noise)
    j.seed(seed)
    return j(b.clone()).x_jitter


def test_zero_std_is_no_jitter():
    b = _batch()
    assert not _jitter(b, 0.0, 0.0).any()
    assert torch.equal(FeatureJitter(FS, 1.0, 1.0)(b.clone()).x, b.x)  # x itself is kept


def test_shift_is_per_robot_and_column_and_keeps_foreign_columns():
    b = _batch()
    out = _jitter(b, shift=1.0, noise=0.0)
    assert (out[~b.x_mask] == 0).all()  # foreign columns stay zero
    for g in range(3):
        rows = out[b.batch == g]
        own = b.x_mask[b.batch == g]
        for t in (0, 1):  # every node of a type gets the same offset per column
            sel = rows[b.node_type[b.batch == g] == t]
            assert torch.allclose(sel, sel[:1].expand_as(sel))
        assert rows[own].abs().sum() > 0
    assert not torch.allclose(out[b.batch == 0], out[b.batch == 1])
    assert torch.equal(out, _jitter(b, 1.0, 0.0))  # the seed fixes the draw
    assert not torch.equal(out, _jitter(b, 1.0, 0.0, seed=1))


def test_categorical_columns_are_kept():
    fs = get_feature_set("full")
    cat = fs.column_transform("categorical")
    assert cat.any()
    parent, types = [-1, 0, 1, 1], [1, 0, 2, 2]
    b = Batch.from_data_list([tree_data(parent, types, torch.rand(4, fs.dim), fs)])
    j = FeatureJitter(fs, 1.0, 1.0)
    out = j(b).x_jitter
    assert not out[:, cat].any() and out[:, ~cat].any()


def test_model_adds_the_jitter_after_normalising():
    b = _batch(2)
    model = RoboVAE(hidden_dim=16, latent_dim=4, node_latent_dim=4)
    model.normalizer.fit(b.x, b.node_type)
    plain = model.normalized(b).x
    jittered = FeatureJitter(FS, 0.5, 0.1)(b.clone())
    torch.testing.assert_close(model.normalized(jittered).x, plain + jittered.x_jitter)


def test_datamodule_augments_training_batches_only_and_by_epoch_and_batch(tmp_path):
    """Training batches carry a jitter drawn from (seed, epoch, batch); validation batches
    none; the same seed draws the same jitter in a second run."""
    import lightning as L

    from robovae.data.datamodule import RobotDataModule

    def run(seed: int) -> tuple[list, list]:
        train, val = [], []

        class Record(L.Callback):
            def on_train_batch_start(self, trainer, pl_module, batch, batch_idx):
                train.append((trainer.current_epoch, batch_idx, batch.num_nodes,
                              batch.x_jitter.clone()))

            def on_validation_batch_start(self, trainer, pl_module, batch, batch_idx,
                                          dataloader_idx=0):
                val.append(getattr(batch, "x_jitter", None))

        L.seed_everything(seed)
        dm = RobotDataModule(["synthetic:n=6,nodes=5,dim=5,seed=0"], root=str(tmp_path),
                             val_fraction=0.2, test_fraction=0.0, batch_size=2,
                             feature_shift=1.0, feature_noise=0.5, tree_surgery=0.5)
        model = RoboVAE(feature_set="random5", hidden_dim=8, latent_dim=4, node_latent_dim=2)
        L.Trainer(max_epochs=2, logger=False, enable_checkpointing=False,
                  enable_progress_bar=False, enable_model_summary=False,
                  num_sanity_val_steps=0, callbacks=[Record()]).fit(model, dm)
        return train, val

    a, val = run(0)
    per_epoch = [[i for e, i, _, _ in a if e == epoch] for epoch in (0, 1)]
    assert per_epoch[0] == per_epoch[1] == list(range(len(per_epoch[0]))) and per_epoch[0]
    assert val and all(v is None for v in val)
    b, _ = run(0)
    assert all(x[2] == y[2] and torch.equal(x[3], y[3]) for x, y in zip(a, b, strict=True))
    c, _ = run(1)
    assert not all(x[2] == y[2] and torch.equal(x[3], y[3]) for x, y in zip(a, c, strict=True))


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


def test_surgery_transform_rebuilds_a_batch_by_its_seed():
    b = Batch.from_data_list(_robots())
    s = TreeSurgery(FS, 1.0, 2, 64)
    shapes = []
    for seed in (1, 1, 2):
        s.seed(seed)
        shapes.append([_shape(d) for d in s(b).to_data_list()])
    assert shapes[0] == shapes[1] and shapes[0] != shapes[2]


@pytest.mark.parametrize("build, bad", [
    (lambda: FeatureJitter("paper34", float("nan"), 0.1), "FeatureJitter.shift"),
    (lambda: FeatureJitter("paper34", 0.1, -0.5), "FeatureJitter.noise"),
    (lambda: TreeSurgery("paper34", 2.0), "TreeSurgery.prob"),
    (lambda: TreeSurgery("paper34", float("nan")), "TreeSurgery.prob"),
    (lambda: TreeSurgery("paper34", 0.5, max_ops=0), "TreeSurgery.max_ops"),
    (lambda: TreeSurgery("paper34", 0.5, max_nodes=0), "TreeSurgery.max_nodes"),
])
def test_transforms_refuse_settings_out_of_range(build, bad) -> None:
    """Used directly (not through the datamodule's checked config), a NaN shift would train on
    NaN inputs and a probability of 2 would edit every robot: refused in one line."""
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match=bad):
        build()
