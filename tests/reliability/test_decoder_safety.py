"""Decoder safety: any latent decodes within the node and depth limits, or is refused with a
one-line :class:`~robovae.errors.RobovaeError` that says why.

- finite latents of any magnitude (1, 1e6, 1e30, 3e38 — about the float32 maximum — and 1e300
  for a float64 model) decode into trees of at most ``max_nodes`` nodes and depth at most
  ``max_depth``, with finite physical features (the support margin clips them);
- NaN / ±inf rows, wrong shapes and non-numbers are refused (rows named); so are finite values
  that overflow the model's dtype, and — for a model without a support margin — latents whose
  decoded features overflow;
- the same through ``predict_step`` (prior samples at a huge temperature) and ``robovae
  generate --temperature``.
"""

from __future__ import annotations

import copy

import pytest
import torch

from robovae.cli import main
from robovae.data.graph import RobotData
from robovae.errors import RobovaeError
from robovae.generate.pipeline import read_manifest

SCALES = [1.0, 1e6, 1e30, 3e38]


def _z(n: int, dim: int, scale: float, seed: int = 0, dtype=torch.float32) -> torch.Tensor:
    """``n`` latents with entries of magnitude up to ``scale`` (uniform in ±scale, a few at
    exactly ±scale)."""
    g = torch.Generator().manual_seed(seed)
    z = (torch.rand(n, dim, generator=g, dtype=torch.float64) * 2 - 1) * scale
    z[0] = scale
    z[1] = -scale
    return z.to(dtype)


def _check_tree(d: RobotData, max_nodes: int, max_depth: int) -> None:
    n = d.num_nodes
    assert 1 <= n <= max_nodes
    parent = d.parent.tolist()
    assert parent[0] == -1 and all(0 <= p < i for i, p in enumerate(parent) if i)  # pre-order
    assert int(d.depth.max()) <= max_depth
    assert torch.isfinite(d.x).all()
    assert d.x.shape == (n, d.x_mask.shape[1])


@pytest.fixture(scope="module")
def models(trained):
    """The trained model, and a copy whose topology head always says "expand" (so every latent
    runs into the limits)."""
    model = copy.deepcopy(trained[0]).float().eval()  # (other tests may leave it float64)
    greedy = copy.deepcopy(model)
    with torch.no_grad():
        greedy.decoder.topo.u.bias.add_(50.0)
    return model, greedy


@pytest.mark.parametrize("scale", SCALES)
def test_any_finite_latent_decodes_within_the_limits(models, scale):
    model, greedy = models
    z = _z(8, model.hparams.latent_dim, scale)
    cases = [(model, None, None), (greedy, 40, 3), (greedy, 1, 5), (greedy, 10, 0)]
    for m, max_nodes, max_depth in cases:
        out = m.decode(z, max_nodes=max_nodes, max_depth=max_depth)
        assert len(out) == 8
        for d in out:
            _check_tree(d, max_nodes or m.hparams.max_nodes,
                        m.hparams.max_depth if max_depth is None else max_depth)
    if scale == 1.0:  # always expanding: the node budget is what stops it
        assert all(d.num_nodes == 40 for d in greedy.decode(z, max_nodes=40, max_depth=3))


def test_1e6_latents_terminate_within_max_nodes_and_max_depth(models):
    """The case the issue names: 1e6-magnitude latents, at RoboVAE's default limits (256 nodes,
    depth 64) and at a tight depth, decoded by a model that always wants to expand."""
    _, greedy = models
    z = _z(8, greedy.hparams.latent_dim, 1e6, seed=3)
    for max_nodes, max_depth in [(256, 64), (100, 4)]:
        out = greedy.decode(z, max_nodes=max_nodes, max_depth=max_depth)
        assert len(out) == 8
        for d in out:
            _check_tree(d, max_nodes, max_depth)
        assert max(d.num_nodes for d in out) == max_nodes or \
            max(int(d.depth.max()) for d in out) == max_depth  # some tree hit a limit


def test_float64_model_takes_float64_magnitudes(models):
    model = copy.deepcopy(models[1]).double()
    out = model.decode(_z(8, model.hparams.latent_dim, 1e300, dtype=torch.float64),
                       max_nodes=30, max_depth=5)
    for d in out:
        _check_tree(d, 30, 5)


def _refused(model, z, match: str, **kw) -> str:
    with pytest.raises(RobovaeError, match=match) as e:
        model.decode(z, **kw)
    msg = str(e.value)
    assert msg.startswith("robovae: ") and "\n" not in msg
    return msg


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_non_finite_latents_are_refused(models, value):
    model = models[0]
    z = torch.zeros(5, model.hparams.latent_dim)
    z[1, 0] = value
    z[3, -1] = value
    assert _refused(model, z, r"rows \[1, 3\] hold NaN or inf")
    z = torch.full((30, model.hparams.latent_dim), value)
    assert "and 20 more" in _refused(model, z, "finite")


def test_values_beyond_the_model_dtype_are_refused(models):
    model = models[0]  # float32: 1e300 would become inf
    z = _z(3, model.hparams.latent_dim, 1e300, dtype=torch.float64)
    _refused(model, z, "finite float32 values")


@pytest.mark.parametrize("shape", [(2, 7), (2, 9), (7,), (2, 8, 1), (), (8, 2)])
def test_wrong_shapes_are_refused(models, shape):
    model = models[0]
    assert model.hparams.latent_dim == 8
    _refused(model, torch.zeros(shape), r"shape \[B, 8\] or \[8\]")


def test_other_inputs(models):
    model = models[0]
    _refused(model, [["a"] * 8], "must be numbers")
    _refused(model, torch.zeros(2, 8, dtype=torch.complex64), "real numbers")
    _refused(model, torch.zeros(2, 8, dtype=torch.bool), "real numbers")
    _refused(model, torch.zeros(2, 8), "max_nodes >= 1", max_nodes=0)
    _refused(model, torch.zeros(2, 8), "max_depth >= 0", max_depth=-1)
    assert model.decode(torch.zeros(0, 8)) == []
    assert len(model.decode([0.0] * 8)) == 1  # a list, a single latent
    assert len(model.decode(torch.zeros(3, 8, dtype=torch.long))) == 3  # integers


def test_without_support_margin_overflowing_features_are_refused(models):
    """Without the margin nothing clips decoded features: rows whose features overflow are
    named in the error, and the other rows decode on their own."""
    model = copy.deepcopy(models[1])
    model.hparams.support_margin = None
    g = torch.Generator().manual_seed(1)
    signs = torch.randint(0, 2, (10, 8), generator=g).float() * 2 - 1
    z = torch.cat([signs * 3e38, _z(4, 8, 1.0)])  # huge rows, then ordinary ones
    try:
        out = model.decode(z, max_nodes=5, max_depth=2)
    except RobovaeError as e:
        msg = str(e)
        assert msg.startswith("robovae: latents too large: rows [") and "\n" not in msg
        named = [int(r) for r in msg.split("[")[1].split("]")[0].split(",")]
        assert named and max(named) < 10  # only huge rows
        ok = [i for i in range(z.shape[0]) if i not in named]
        out = model.decode(z[ok], max_nodes=5, max_depth=2)
    for d in out:
        _check_tree(d, 5, 2)
    with torch.no_grad():  # a decoder whose features always overflow: every row is named
        model.decoder.U_l.bias.fill_(float("inf"))
    assert "rows [0, 1, 2]" in _refused(model, _z(3, 8, 1.0), "latents too large")
    assert "and 2 more" in _refused(model, _z(12, 8, 1.0), "latents too large")


def test_predict_step_at_a_huge_temperature(models):
    model = models[0]
    batch = {"index": torch.arange(6), "seed": torch.zeros(6, dtype=torch.long),
             "temperature": torch.full((6,), 1e30, dtype=torch.float64)}
    out = model.predict_step(batch, 0)
    assert out["index"].tolist() == list(range(6))
    for d in out["graphs"]:
        _check_tree(d, model.hparams.max_nodes, model.hparams.max_depth)
    batch["temperature"] = torch.full((6,), float("inf"), dtype=torch.float64)
    with pytest.raises(RobovaeError, match="temperature must be a number >= 0, got inf"):
        model.predict_step(batch, 0)


def test_cli_generate_with_absurd_temperatures(trained, tmp_path, capsys):
    _, _, ckpt = trained
    args = ["generate", "--ckpt", str(ckpt), "-n", "3", "--jobs", "1", "--no-validate"]
    assert main([*args, "--temperature", "1e30", "--out", str(tmp_path / "huge")]) == 0
    assert sorted(read_manifest(tmp_path / "huge")) == [0, 1, 2]  # written, within limits
    capsys.readouterr()
    assert main([*args, "--temperature", "nan", "--out", str(tmp_path / "nan")]) == 2
    err = capsys.readouterr().err  # (the progress bar shares stderr)
    assert "Traceback" not in err
    assert "robovae: --temperature must be a finite number >= 0, got nan" in err
    assert not (tmp_path / "nan").exists()  # refused before anything is written
