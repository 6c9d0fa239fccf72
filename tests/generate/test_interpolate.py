"""Latent interpolation: endpoints are the robots' own reconstructions, every step is written
and validated."""

from __future__ import annotations

import pytest
import torch
from torch_geometric.data import Batch

from robovae.generate import interpolate as interpolate_module
from robovae.generate.fixes import decoded_fixes
from robovae.generate.interpolate import interpolate, latent_path, step_name
from robovae.model.checkpoint import own_model
from robovae.model.node_transfer import carried_latents


def test_path_starts_and_ends_at_the_encoded_means(trained):
    model, dm, _ = trained
    a, b = dm.dataset.by_name("gym_ant"), dm.dataset.by_name("dmc_humanoid")
    t, z, ends = latent_path(model, a, b, steps=5)
    mu, _ = model.encode(a)
    assert t.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0] and len(z) == 5
    assert torch.equal(ends[0].mu, z[0]) and torch.equal(ends[1].tree[0], b.parent)
    assert torch.allclose(z[0], mu[0]) and not torch.allclose(z[0], z[-1])
    assert torch.allclose(z[2], (z[0] + z[-1]) / 2, atol=1e-6)
    for steps in (1, 10**9):  # 10**9: 256 GB asked at once and a traceback until 2026-11-29
        with pytest.raises(ValueError, match=r"--steps must be an integer in \[2, 10000\]"):
            latent_path(model, a, b, steps=steps)


def test_node_latents_are_carried_from_the_nodes_each_robot_shares(trained_nodes):
    """Each step's node takes the two robots' latents of the nodes it shares with them,
    weighted 1 - t and t (not the latents at its pre-order index); the ends are the robots'
    reconstructions where their trees come back."""
    model, dm, _ = trained_nodes
    model = own_model(model).to(torch.float64)
    a, b = dm.dataset.by_name("gym_ant"), dm.dataset.by_name("dmc_humanoid")
    t, z, ends = latent_path(model, a, b, steps=3)
    steps = interpolate(model, a, b, steps=3)
    for k in range(3):
        tree = model.decode(z[k:k + 1], clamp=False)[0]
        w = carried_latents((tree.parent, tree.node_type), ends, [1 - t[k], t[k]])
        want = model.decode(z[k:k + 1], node_latents=[w], clamp=False)[0]
        want, _ = decoded_fixes(want, model.feature_set, mirror=False)
        assert torch.equal(steps[k].graph.parent, want.parent)
        assert torch.equal(steps[k].graph.x, want.x)
    _, (wa, _) = model.encode_nodes(Batch.from_data_list([a, b]))
    first = model.decode(z[:1], clamp=False)[0]
    if torch.equal(first.parent, a.parent) and torch.equal(first.node_type, a.node_type):
        assert torch.equal(carried_latents((a.parent, a.node_type), ends, [1.0, 0.0]), wa)


@pytest.mark.parametrize("fixture", ["trained", "trained_nodes"])
def test_every_step_is_written_and_validated(fixture, request, tmp_path):
    model, dm, _ = request.getfixturevalue(fixture)
    a, b = dm.dataset.by_name("gym_ant"), dm.dataset.by_name("dmc_humanoid")
    steps = interpolate(model, a, b, steps=3, out=tmp_path)
    assert [s.t for s in steps] == [0.0, 0.5, 1.0]
    assert [s.path.parent.name for s in steps] == ["step_00", "step_01", "step_02"]
    assert all(s.path.is_file() and s.validation is not None for s in steps)
    assert all(s.validation.valid or s.validation.reason for s in steps)
    # endpoints: the greedy reconstructions of the two robots
    assert steps[0].graph.num_nodes == model.reconstruct(a)[0].num_nodes
    assert steps[-1].graph.num_nodes == model.reconstruct(b)[0].num_nodes
    no_files = interpolate(model, a, b, steps=2)
    assert no_files[0].path is None and no_files[0].validation is None


def test_long_paths_decode_in_batches_alike(trained_nodes, monkeypatch):
    """A path decodes DECODE_BATCH steps at a time (``--steps 100000`` in one batch was killed
    for want of memory); batches of 2 give the same robots as one batch."""
    model, dm, _ = trained_nodes
    model = own_model(model).to(torch.float64)  # a copy, as interpolate_files decodes
    a, b = dm.dataset.by_name("gym_ant"), dm.dataset.by_name("dmc_humanoid")
    whole = interpolate(model, a, b, steps=5)
    monkeypatch.setattr(interpolate_module, "DECODE_BATCH", 2)
    batched = interpolate(model, a, b, steps=5)
    for s, r in zip(whole, batched, strict=True):
        assert torch.equal(s.graph.parent, r.graph.parent)
        assert torch.equal(s.graph.node_type, r.graph.node_type)
        assert torch.equal(s.graph.x, r.graph.x)


def test_step_names_sort_in_path_order():
    assert [step_name(k, 3) for k in (0, 2)] == ["step_00", "step_02"]
    names = [step_name(k, 1001) for k in (0, 9, 99, 1000)]
    assert names == ["step_0000", "step_0009", "step_0099", "step_1000"] == sorted(names)
