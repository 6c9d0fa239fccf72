"""robovae generate --like and robovae interpolate: outputs, determinism, one-line refusals."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import torch

from robovae.cli import main
from robovae.data.procedural import procedural_spec
from robovae.design import variations
from robovae.design.variations import SHEET_STEPS, ball_offsets, encode_file, sheet_steps
from robovae.generate.pipeline import read_manifest
from robovae.model.checkpoint import own_model
from robovae.model.prior import unfinished


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("robots")
    a, b = root / "a.xml", root / "b.xml"
    a.write_text(procedural_spec(0, kind="quadruped").to_xml())
    b.write_text(procedural_spec(1, kind="hexapod").to_xml())
    junk = root / "junk.xml"
    junk.write_text("<mujoco><worldbody></worldbody></mujoco>")
    return a, b, junk


def test_ball_offsets_are_inside_the_ball_and_fill_it():
    rng = np.random.default_rng(0)
    x = ball_offsets(rng, 4000, 3, 2.0)
    r = np.linalg.norm(x, axis=1)
    assert r.max() <= 2.0 + 1e-12
    # uniform in a 3-ball: P(r < R/2) = 1/8
    assert abs(np.mean(r < 1.0) - 0.125) < 0.02
    assert np.allclose(ball_offsets(rng, 5, 3, 0.0), 0)


def test_like_writes_variations_within_radius(trained_nodes, files, tmp_path, capsys):
    model, _, ckpt = trained_nodes
    a, _, _ = files
    out = tmp_path / "like"
    def argv(n: int) -> list[str]:
        return ["generate", "--ckpt", str(ckpt), "--like", str(a), "--radius", "0.3", "-n",
                str(n), "--out", str(out), "--jobs", "1", "--no-validate"]

    assert main(argv(3)) == 0
    assert "3 robots" in capsys.readouterr().out
    recs = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert [r["index"] for r in recs] == [0, 1, 2]
    mu = encode_file(model, a).mu.double().numpy()
    _, basis = model.prior_directions(variations.LIKE_VARIANCE)
    for r in recs:
        assert r["radius"] == 0.3 and r["like"] == str(a)
        assert (out / r["path"]).is_file()
        # within 0.3 prior standard deviations, in the prior's principal subspace
        y, *_ = np.linalg.lstsq(basis, np.array(r["latent"]) - mu, rcond=None)
        assert np.allclose(basis @ y, np.array(r["latent"]) - mu, atol=1e-5)
        assert 0 < np.linalg.norm(y) <= 0.3 + 1e-4
    # resuming with more robots keeps the first ones byte for byte
    before = (out / "robot_000001" / "robot.xml").read_bytes()
    assert main(argv(5)) == 0
    assert (out / "robot_000001" / "robot.xml").read_bytes() == before
    assert (out / "robot_000004" / "robot.xml").is_file()


def test_like_takes_the_writing_options_of_generate(trained_nodes, files, tmp_path, capsys):
    """generate --like with --self-collision, --no-stance, --no-mirror-limbs, --no-quality: the
    variations are written so (the flags were ignored: they are the generate parser's), the
    run records what changes the files; the sampling options of prior draws are refused."""
    import mujoco

    _, _, ckpt = trained_nodes
    out = tmp_path / "like_sc"
    argv = ["generate", "--ckpt", str(ckpt), "--like", str(files[0]), "--radius", "0.3", "-n",
            "2", "--out", str(out), "--jobs", "1"]
    assert main([*argv, "--self-collision", "--no-stance", "--no-mirror-limbs",
                 "--no-quality"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["self_collision"] is True and run["stance"] is False and run["mirror"] is False
    for rec in read_manifest(out).values():
        assert "quality" not in rec and "mirror_limbs" not in rec["rules"]
        model = mujoco.MjModel.from_xml_path(str(out / rec["path"]))
        assert (model.geom_conaffinity[model.geom_bodyid != 0] == 1).all()
    capsys.readouterr()
    assert main([*argv[:-2], "--temperature", "0.5", "--prior", "standard"]) == 2
    err = capsys.readouterr().err
    assert "--temperature, --prior: not used with --like" in err and err.count("\n") == 1


def test_like_in_batches_writes_the_same_robots(trained_nodes, files, tmp_path, monkeypatch):
    """Variations are decoded, written and logged LIKE_BATCH at a time; batches of 2 give
    the same files and records as one batch."""
    _, _, ckpt = trained_nodes
    a, _, _ = files

    def run(out):
        assert main(["generate", "--ckpt", str(ckpt), "--like", str(a), "--radius", "0.3",
                     "-n", "5", "--out", str(out), "--jobs", "1", "--no-validate"]) == 0
        recs = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
        return ([{k: v for k, v in r.items() if k != "seconds"} for r in recs],
                [(out / r["path"]).read_bytes() for r in recs])

    whole = run(tmp_path / "whole")
    monkeypatch.setattr(variations, "LIKE_BATCH", 2)
    assert run(tmp_path / "batched") == whole


def test_radius_zero_gives_the_reconstruction(trained_nodes, files, tmp_path):
    _, _, ckpt = trained_nodes
    a, _, _ = files
    out = tmp_path / "zero"
    assert main(["generate", "--ckpt", str(ckpt), "--like", str(a), "--radius", "0", "-n", "2",
                 "--out", str(out), "--jobs", "1", "--no-validate", "--no-scene"]) == 0
    assert (out / "robot_000000" / "robot.xml").read_text().replace("000000", "") == \
        (out / "robot_000001" / "robot.xml").read_text().replace("000001", "")


def test_radius_zero_keeps_everything_the_report_measures(trained_nodes, files, tmp_path,
                                                          capsys):
    """The report says what a radius bought against the robot's reconstruction: at radius 0
    every variation is the reconstruction (topology, limbs, nodes and mass kept)."""
    model, _, ckpt = trained_nodes
    a, _, _ = files
    out = tmp_path / "zero"
    assert main(["generate", "--ckpt", str(ckpt), "--like", str(a), "--radius", "0", "-n", "3",
                 "--out", str(out), "--jobs", "1", "--no-validate", "--no-scene"]) == 0
    like = json.loads((out / "summary.json").read_text())["metrics"]["like"]
    assert like["same_topology"] == like["same_limbs"] == 1.0
    assert like["nodes_changed"] == 0.0 and like["mass_factor"] == pytest.approx(1.0)
    assert like["prior_spread"] == pytest.approx(variations.prior_spread(model))
    assert like["prior_spread"] > 0
    line = [x for x in capsys.readouterr().out.splitlines() if x.startswith("variations")]
    assert len(line) == 1 and "kept by 100.0%" in line[0]


def test_like_metrics_compare_each_variation_with_the_reconstruction():
    ref = {"topology": "t0", "nodes": 10, "limbs": 4, "mass": 2.0}
    recs = [dict(ref), {"topology": "t1", "nodes": 14, "limbs": 6, "mass": 8.0},
            {"topology": "t0", "nodes": 10, "limbs": 4, "mass": 1.0},
            {"topology": "t2", "nodes": 8, "limbs": 4, "mass": 2.0}]
    m = variations.like_metrics(recs, ref, 2.0, 3.0)
    assert m["same_topology"] == 0.5 and m["same_limbs"] == 0.75
    assert m["nodes_changed"] == 1.5  # (0 + 4 + 0 + 2) / 4
    assert m["mass_factor"] == pytest.approx(2.0 ** 0.5)  # median of |ln| 0, 2 ln2, ln2, 0
    assert m["reconstruction"] == ref and m["radius"] == 2.0 and m["prior_spread"] == 3.0


@pytest.mark.parametrize("extra, message", [
    (["--radius", "-1"], "--radius must be a finite number >= 0"),
    (["-n", "0"], "-n must be an integer of at least 1"),
])
def test_like_refuses_bad_numbers(trained_nodes, files, tmp_path, capsys, extra, message):
    _, _, ckpt = trained_nodes
    out = tmp_path / "bad"
    assert main(["generate", "--ckpt", str(ckpt), "--like", str(files[0]), "--out", str(out),
                 *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not out.exists()


def test_like_refuses_a_file_that_is_not_a_robot(trained_nodes, files, tmp_path, capsys):
    _, _, ckpt = trained_nodes
    out = tmp_path / "bad"
    assert main(["generate", "--ckpt", str(ckpt), "--like", str(files[2]), "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert "junk.xml" in err and err.count("\n") == 1 and not out.exists()


def test_a_long_path_shows_evenly_spaced_steps_on_its_sheet():
    assert sheet_steps(3) == [0, 1, 2] and sheet_steps(SHEET_STEPS) == list(range(SHEET_STEPS))
    shown = sheet_steps(1000)
    assert len(shown) == SHEET_STEPS and shown[0] == 0 and shown[-1] == 999
    gaps = np.diff(shown)
    assert gaps.min() >= 21 and gaps.max() <= 22  # 999 / 47 = 21.3


def test_interpolate_writes_steps_and_sheet(trained_nodes, files, tmp_path, capsys):
    _, _, ckpt = trained_nodes
    a, b, _ = files
    out = tmp_path / "path"
    assert main(["interpolate", str(a), str(b), "--ckpt", str(ckpt), "--steps", "3",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "sheet.png" in text and "0.500" in text
    res = json.loads((out / "path.json").read_text())
    assert [s["t"] for s in res["steps"]] == [0.0, 0.5, 1.0]
    assert all((out / s["path"]).is_file() and s["reason"] for s in res["steps"])
    from PIL import Image

    assert Image.open(out / "sheet.png").size == (3 * 240, 180)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["path"]  # no temporary left


def test_interpolate_self_collision(trained_nodes, files, tmp_path, capsys):
    """--self-collision: every step's robot geoms collide with each other, but for the pairs
    touching at rest, and the path says so; without it they do not (the default files)."""
    import mujoco

    from robovae.data.self_collision import resting_pairs

    _, _, ckpt = trained_nodes
    a, b, _ = files
    argv = ["interpolate", str(a), str(b), "--ckpt", str(ckpt), "--steps", "2", "--no-sheet",
            "--no-validate"]
    for flag, out in ((["--self-collision"], tmp_path / "sc"), ([], tmp_path / "plain")):
        assert main([*argv, "--out", str(out), *flag]) == 0
        res = json.loads((out / "path.json").read_text())
        assert res.get("self_collision", False) is bool(flag)
        for step in res["steps"]:
            model = mujoco.MjModel.from_xml_path(str(out / step["path"]))
            robot = model.geom_bodyid != 0
            assert (model.geom_conaffinity[robot] == (1 if flag else 0)).all()
            if flag:
                assert resting_pairs(model) == []
    capsys.readouterr()


@pytest.mark.parametrize("case", ["steps", "junk", "out"])
def test_interpolate_refuses_bad_input(trained_nodes, files, tmp_path, capsys, case):
    _, _, ckpt = trained_nodes
    a, b, junk = files
    out = tmp_path / "path"
    argv = ["interpolate", str(a), str(b), "--ckpt", str(ckpt), "--steps", "3", "--out", str(out)]
    if case == "steps":
        argv[-3] = "1"
    elif case == "junk":
        argv[2] = str(junk)
    else:
        out.mkdir()
        (out / "mine.txt").write_text("keep")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("robovae: ")
    assert {"steps": "--steps must be an integer in [2, 10000]", "junk": "junk.xml",
            "out": "not empty"}[case] in err
    if case == "out":
        assert [p.name for p in out.iterdir()] == ["mine.txt"]
    else:
        assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == (["path"] if case == "out" else [])


def test_interpolate_refuses_an_out_another_run_is_writing(trained_nodes, files, tmp_path,
                                                          capsys):
    """Two paths into one ``--out``: the second is refused at once, one line naming the first's
    process (until 2026-11-29 both ran; the one that ended second found the folder full and
    ended in a traceback, its path lost)."""
    from robovae.files import FolderLock

    _, _, ckpt = trained_nodes
    a, b, _ = files
    out = tmp_path / "path"
    argv = ["interpolate", str(a), str(b), "--ckpt", str(ckpt), "--steps", "3", "--out", str(out)]
    with FolderLock(out, "the path", beside=True):  # the first run, still decoding
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1
        assert f"path: another run is writing there (process {os.getpid()}, .path.robovae" in err
        assert not out.exists()
    assert main(argv) == 0 and (out / "path.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["path"]  # no lock, no temporary


def test_interpolate_refuses_an_out_inside_a_file(trained_nodes, files, tmp_path, capsys):
    _, _, ckpt = trained_nodes
    a, b, _ = files
    (tmp_path / "file").write_text("keep")
    assert main(["interpolate", str(a), str(b), "--ckpt", str(ckpt), "--steps", "3", "--out",
                 str(tmp_path / "file" / "path")]) == 2
    err = capsys.readouterr().err
    assert "file: cannot write the path there (a file, not a folder)" in err
    assert err.count("\n") == 1 and (tmp_path / "file").read_text() == "keep"


def test_bad_checkpoint_is_refused(files, tmp_path, capsys):
    ck = tmp_path / "not.ckpt"
    ck.write_text("nope")
    out = tmp_path / "o"
    assert main(["generate", "--ckpt", str(ck), "--like", str(files[0]), "--out", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not out.exists()


def test_a_given_model_is_not_changed(trained_nodes, files, tmp_path):
    """generate_like and interpolate_files decode in float64 on a copy: the caller's model
    keeps its dtype and weights."""
    import torch

    from robovae.design.variations import generate_like, interpolate_files
    from robovae.model.checkpoint import load_model

    model = load_model(trained_nodes[2])
    before = {k: v.clone() for k, v in model.state_dict().items()}
    a, b, _ = files
    generate_like(model, a, 0.2, 1, tmp_path / "like", validate=False, jobs=1)
    interpolate_files(model, a, b, 2, tmp_path / "path", validate=False, sheet=False)
    assert all(p.dtype == torch.float32 for p in model.parameters())
    after = model.state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before)


def test_unfinished_variations_are_drawn_again(trained_nodes, files):
    """A variation whose decoding reaches the node limit draws its ``y`` again from its next
    stream, up to ``redraws`` times (the last draw kept); without redraws, the first."""
    model, _, _ = trained_nodes
    model = own_model(model).to(torch.float64)
    encoded = encode_file(model, files[0])
    encoded = encoded._replace(mu=encoded.mu.double(), nodes=encoded.nodes.double())
    _, basis = model.prior_directions(variations.LIKE_VARIANCE)
    model.hparams.max_nodes = 3  # every tree is cut off at 3 nodes
    z, graphs, draws = variations.draw_variations(model, encoded, basis, 1.0, 0, [0, 1], 0)
    assert draws == [0, 0] and all(unfinished(model, g) for g in graphs)
    assert torch.equal(z, variations.variation_latents(encoded, basis, 1.0, 0, [0, 1]))
    z, graphs, draws = variations.draw_variations(model, encoded, basis, 1.0, 0, [0, 1], 3)
    assert draws == [3, 3] and all(g.num_nodes == 3 for g in graphs)
    assert torch.equal(z, variations.variation_latents(encoded, basis, 1.0, 0, [0, 1], draw=3))
    assert not torch.equal(z[0], variations.variation_latents(encoded, basis, 1.0, 0, [0])[0])



@pytest.mark.parametrize("kw, message", [
    ({"variance": 0.0}, r"--variance must be a number in \(0, 1\]"),
    ({"variance": 2.0}, r"--variance must be a number in \(0, 1\]"),
    ({"variance": float("nan")}, r"--variance must be a number in \(0, 1\]"),
    ({"jobs": -3}, "--jobs must be an integer of at least 0"),  # ran in one process
])
def test_like_library_refuses_settings_out_of_range(files, tmp_path, kw, message):
    """``generate_like(variance=0)`` varied one direction, 2 or NaN all of them, after the
    output folder was claimed; refused first, before the checkpoint is read."""
    from robovae.design.variations import generate_like
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match=message):
        generate_like(tmp_path / "none.ckpt", files[0], 0.5, 2, tmp_path / "o", **kw)
    assert not (tmp_path / "o").exists()
