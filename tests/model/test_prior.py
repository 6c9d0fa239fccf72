"""Prior draws: an unfinished decoding (cut off by the decoder's limits) redraws its latent."""

from __future__ import annotations

import copy

import torch

from robovae.model.prior import draw_robots, latent, tree_depth, unfinished


def test_tree_depth():
    assert tree_depth(torch.tensor([-1])) == 0
    assert tree_depth(torch.tensor([-1, 0, 1, 0, 3, 4])) == 3


def test_redraws_replace_unfinished_trees_only(trained):
    model, _, _ = trained
    model = copy.deepcopy(model).eval()
    # this barely trained model runs away (to its 64-node limit) from most latents
    z0, g0, d0 = draw_robots(model, 0, range(40))
    assert d0 == [0] * 40
    cut = [unfinished(model, g) for g in g0]
    assert any(cut) and not all(cut)
    z, graphs, draws = draw_robots(model, 0, range(40), redraws=6)
    for b in range(40):
        if not cut[b]:  # a finished robot keeps its first draw
            assert draws[b] == 0 and torch.equal(z[b], z0[b])
        else:  # an unfinished one moved on to its own next streams, at most 6 times
            assert 1 <= draws[b] <= 6
            assert torch.equal(z[b], latent(0, b, z.shape[1], draw=draws[b]))
            assert draws[b] == 6 or not unfinished(model, graphs[b])
    assert sum(not unfinished(model, g) for g in graphs) > sum(not c for c in cut)
    # the same robots whatever the batch
    _, again, d2 = draw_robots(model, 0, [5, 3])
    assert d2 == [0, 0] and torch.equal(again[0].parent, draw_robots(model, 0, [5])[1][0].parent)
    z_b, _, d_b = draw_robots(model, 0, [7, 2], redraws=6)
    assert d_b == [draws[7], draws[2]] and torch.equal(z_b[0], z[7])


def test_robot_streams_refuse_arguments_out_of_range() -> None:
    """A negative seed was NumPy's "expected non-negative integer" traceback, a negative
    temperature a latent of the opposite sign: refused, naming the setting."""
    import pytest

    from robovae.errors import SettingsError
    from robovae.model.prior import node_noise

    for kw, bad in (({"seed": -1}, "latent seed"), ({"temperature": -1.0}, "latent.temperature"),
                    ({"temperature": float("nan")}, "latent.temperature"),
                    ({"index": -3}, "latent.index"), ({"draw": -1}, "latent.draw")):
        with pytest.raises(SettingsError, match=bad):
            latent(**{"seed": 0, "index": 0, "dim": 4, **kw})
    with pytest.raises(SettingsError, match="node_noise.max_nodes"):
        node_noise(0, 0, -1, 4)
    assert latent(0, 0, 4, temperature=0.0).abs().sum() == 0  # temperature 0: the prior's mean
