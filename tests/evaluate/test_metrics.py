"""Tests for the reconstruction metrics (SPEC §4)."""

from __future__ import annotations

import math

import pytest
import torch

from robovae.data.features import JOINT, LINK, get_feature_set
from robovae.data.graph import RobotData, tree_data
from robovae.data.normalizer import Normalizer
from robovae.evaluate.metrics import (
    Reconstruction,
    match_trees,
    reconstruction_metrics,
    summarize,
)

FS = get_feature_set("paper34")


def go2_shape(legs: int = 4) -> tuple[list[int], list[int]]:
    """Go2-like tree: free joint -> base link -> ``legs`` x [hip j, hip l, thigh j/l, calf j/l]."""
    parent, types = [-1, 0], [JOINT, LINK]
    for _ in range(legs):
        prev = 1
        for t in (JOINT, LINK) * 3:
            parent.append(prev)
            types.append(t)
            prev = len(parent) - 1
    return parent, types


def physical_x(types: list[int], seed: int = 0) -> torch.Tensor:
    """Random physical features inside the columns' ranges (positive where log-transformed)."""
    g = torch.Generator().manual_seed(seed)
    return torch.rand(len(types), FS.dim, generator=g) * 2.0 + 0.1


def make(parent: list[int], types: list[int], x: torch.Tensor | None = None,
         name: str = "go2") -> RobotData:
    if x is None:
        x = physical_x(types)
    return tree_data(parent, types, x, "paper34", name=name)


@pytest.fixture
def go2() -> RobotData:
    return make(*go2_shape())


@pytest.fixture
def normalizer(go2: RobotData) -> Normalizer:
    xs = torch.cat([go2.x, physical_x(go2.node_type.tolist(), seed=1)])
    ts = torch.cat([go2.node_type, go2.node_type])
    return Normalizer("paper34").fit(xs, ts)


def test_go2_shape_has_26_nodes(go2: RobotData) -> None:
    assert go2.num_nodes == 26
    assert int((go2.node_type == JOINT).sum()) == 13


def test_identical_trees(go2: RobotData, normalizer: Normalizer) -> None:
    r = reconstruction_metrics(go2, go2.clone(), normalizer)
    assert r.ra == 1.0 and r.ra_true == 1.0 and r.exact
    assert r.n_true == r.n_pred == r.n_correct == 26
    assert r.fre == 0.0
    assert all(v == 0.0 for v in r.feature_mae.values())
    assert set(r.feature_mae) == {f.key for f in FS.features}
    assert r.name == "go2"


def test_match_trees_root_first_preorder(go2: RobotData) -> None:
    pairs = match_trees(go2.parent, go2.node_type, go2.parent, go2.node_type)
    assert pairs == [(i, i) for i in range(26)]


def test_go2_extra_limb_is_26_of_32(go2: RobotData, normalizer: Normalizer) -> None:
    parent, types = go2_shape(legs=5)
    x = torch.cat([go2.x, physical_x(types[26:], seed=7) * 100.0])
    pred = make(parent, types, x)
    r = reconstruction_metrics(go2, pred, normalizer)
    assert (r.n_true, r.n_pred, r.n_correct) == (26, 32, 26)
    assert r.ra == 26 / 32 == 0.8125
    assert r.ra_true == 1.0
    assert not r.exact
    assert r.fre == 0.0  # the extra limb has no ground truth: not scored
    assert all(v == 0.0 for v in r.feature_mae.values())


def test_missing_subtree(go2: RobotData) -> None:
    parent, types = go2_shape(legs=3)
    pred = make(parent, types, go2.x[:20].clone())
    r = reconstruction_metrics(go2, pred, feature_set="paper34")
    assert r.ra == 1.0
    assert r.ra_true == pytest.approx(20 / 26)
    assert not r.exact


def test_wrong_type_at_root_still_matches_children(go2: RobotData) -> None:
    parent, types = go2_shape()
    types[0] = LINK
    pred = make(parent, types, go2.x.clone())
    pairs = match_trees(go2.parent, go2.node_type, pred.parent, pred.node_type)
    assert len(pairs) == 26  # matching is structural
    r = reconstruction_metrics(go2, pred, feature_set="paper34")
    assert r.n_correct == 25
    assert r.ra == r.ra_true == pytest.approx(25 / 26)
    assert not r.exact


def test_single_node_wrong_type() -> None:
    true = make([-1], [JOINT])
    pred = make([-1], [LINK])
    r = reconstruction_metrics(true, pred, feature_set="paper34")
    assert r.n_correct == 0 and r.ra == 0.0 and r.ra_true == 0.0 and not r.exact
    assert math.isnan(r.fre)
    assert all(math.isnan(v) for v in r.feature_mae.values())


def test_child_order_matters() -> None:
    # true: root -> [A0 -> A1 -> A2, B0]; pred: root -> [B0, A0 -> A1 -> A2]
    x = torch.rand(5, 5)
    true = tree_data([-1, 0, 1, 2, 0], [0] * 5, x, "random5")
    pred = tree_data([-1, 0, 0, 2, 3], [0] * 5, x, "random5")
    assert reconstruction_metrics(true, true, feature_set="random5").ra == 1.0
    assert match_trees(true.parent, true.node_type, pred.parent, pred.node_type) == [
        (0, 0), (1, 1), (4, 2)]
    r = reconstruction_metrics(true, pred, feature_set="random5")
    assert r.n_correct == 3
    assert r.ra == r.ra_true == pytest.approx(3 / 5)
    assert not r.exact


def test_fre_perturbed_feature(go2: RobotData, normalizer: Normalizer) -> None:
    node = 3  # hip link of the first leg
    assert int(go2.node_type[node]) == LINK
    col = FS.slice("link.mass").start
    x = go2.x.clone()
    x[node, col] *= 1.7
    pred = make(go2.parent.tolist(), go2.node_type.tolist(), x)
    r = reconstruction_metrics(go2, pred, normalizer)

    nt = normalizer(go2.x, go2.node_type)
    npred = normalizer(x, go2.node_type)
    diff = (npred[node, col].double() - nt[node, col].double()) ** 2
    n_link = int((go2.node_type == LINK).sum())
    n_joint = int((go2.node_type == JOINT).sum())
    entries = (n_link * sum(f.width for f in FS.features_of("link"))
               + n_joint * sum(f.width for f in FS.features_of("joint")))
    assert entries == 13 * 22 + 13 * 12
    assert r.fre == pytest.approx(float(diff) / entries, rel=1e-5)
    assert r.fre > 0

    # without a normaliser FRE is on raw values
    raw = reconstruction_metrics(go2, pred, feature_set="paper34")
    expected_raw = float((x[node, col].double() - go2.x[node, col].double()) ** 2) / entries
    assert raw.fre == pytest.approx(expected_raw, rel=1e-5)


def test_fre_ignores_other_type_columns(go2: RobotData, normalizer: Normalizer) -> None:
    pred = go2.clone()
    other = ~go2.x_mask
    pred.x = torch.where(other, torch.full_like(go2.x, 123.0), go2.x)
    assert bool((pred.x != go2.x).any())
    assert reconstruction_metrics(go2, pred, normalizer).fre == 0.0
    raw = reconstruction_metrics(go2, pred, feature_set="paper34")
    assert raw.fre == 0.0
    assert all(v == 0.0 for v in raw.feature_mae.values())
    # and with only the data's own mask (no feature set, no normaliser)
    assert reconstruction_metrics(go2, pred).fre == 0.0


def test_feature_mae_physical_units(go2: RobotData, normalizer: Normalizer) -> None:
    x = go2.x.clone()
    links = (go2.node_type == LINK).nonzero().view(-1)
    joints = (go2.node_type == JOINT).nonzero().view(-1)
    x[links[0], FS.slice("link.mass")] += 0.5  # kg
    x[joints[2], FS.slice("joint.pos")] += torch.tensor([0.3, -0.3, 0.0])  # m
    pred = make(go2.parent.tolist(), go2.node_type.tolist(), x)
    r = reconstruction_metrics(go2, pred, normalizer)
    assert r.feature_mae["link.mass"] == pytest.approx(0.5 / len(links), rel=1e-5)
    assert r.feature_mae["joint.pos"] == pytest.approx(0.6 / (3 * len(joints)), rel=1e-5)
    others = {k: v for k, v in r.feature_mae.items() if k not in ("link.mass", "joint.pos")}
    assert all(v == 0.0 for v in others.values())


def test_deep_chain() -> None:
    n = 5000
    x = torch.rand(n, 5)
    true = tree_data([-1] + list(range(n - 1)), [0] * n, x, "random5")
    r = reconstruction_metrics(true, true, feature_set="random5")
    assert r.exact and r.n_correct == n and r.fre == 0.0
    short = tree_data([-1] + list(range(3999)), [0] * 4000, x[:4000], "random5")
    r = reconstruction_metrics(true, short, feature_set="random5")
    assert r.ra == 1.0 and r.ra_true == pytest.approx(0.8)


def test_summarize_nan_safe() -> None:
    a = Reconstruction("a", 1.0, 1.0, True, 0.2, 3, 3, 3, {"node.f0": 0.1})
    b = Reconstruction("b", 0.5, 0.25, False, math.nan, 4, 2, 1, {"node.f0": math.nan})
    s = summarize([a, b])
    assert s["ra"] == pytest.approx(0.75)
    assert s["ra_true"] == pytest.approx(0.625)
    assert s["exact"] == pytest.approx(0.5)
    assert s["fre"] == pytest.approx(0.2)
    assert s["count"] == 2
    assert s["mae/node.f0"] == pytest.approx(0.1)
    empty = summarize([])
    assert empty["count"] == 0 and math.isnan(empty["ra"]) and math.isnan(empty["fre"])
