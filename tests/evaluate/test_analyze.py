"""Tests for ``robovae analyze`` (robovae.evaluate.analyze) on the small zoo checkpoint."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robovae.cli import main
from robovae.data.procedural import procedural_spec
from robovae.data.zoo import zoo_files
from robovae.errors import RobovaeError
from robovae.evaluate.analyze import (
    analyze,
    encode_means,
    format_report,
    load_graphs,
    sample_files,
    to_json,
    training_graphs,
)
from robovae.evaluate.descriptors import DESCRIPTORS
from robovae.evaluate.quality.gait_search import budget_gait
from robovae.evaluate.quality.symmetry import anatomy

ZOO = dict(zoo_files()[0])


def _strict(text: str):
    """``json.loads`` that refuses NaN/Infinity."""
    def bad(c):
        raise ValueError(f"non-standard JSON constant {c}")
    return json.loads(text, parse_constant=bad)


@pytest.fixture(scope="module")
def proc_samples(tmp_path_factory):
    """A folder laid out like ``robovae generate --out`` with 6 procedural robots."""
    out = tmp_path_factory.mktemp("samples")
    with open(out / "manifest.jsonl", "w") as f:
        for i in range(6):
            d = out / f"robot_{i:06d}"
            d.mkdir()
            (d / "robot.xml").write_text(procedural_spec(i, "quadruped").to_xml())
            f.write(json.dumps({"index": i, "valid": i != 5,
                                "path": f"robot_{i:06d}/robot.xml"}) + "\n")
    return out


def test_training_graphs_are_the_checkpoint_training_robots(trained) -> None:
    model, dm, ckpt = trained
    graphs, what = training_graphs(model, ckpt, root=ckpt.parent / "cache")
    names = {g.name for g in graphs}
    assert names == {r["name"] for r in model.training_robots}
    assert "gym_hopper" not in names and "gym_half_cheetah" not in names  # held out
    assert what.startswith(f"{len(graphs)} training robots of zoo")
    mu = encode_means(model, graphs[:3])
    assert mu.shape == (3, 8) and np.isfinite(mu).all()
    assert encode_means(model, []).shape == (0, 8)


def test_cli_analyze_prints_the_report_and_writes_json(trained, tmp_path, capsys,
                                                       menagerie_dir) -> None:
    _, _, ckpt = trained
    out = tmp_path / "analysis.json"
    rc = main(["analyze", "--ckpt", str(ckpt), "--behaviour", "2", "--permutations", "20",
               "--root", str(ckpt.parent / "cache"), "--jobs", "1", "--entropy-seconds", "0.5",
               "--json", str(out), "--quality", "2", "--procedural", "2", "--real",
               str(menagerie_dir)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "Traceback" not in captured.out + captured.err
    text = captured.out
    assert text.startswith("training: ")
    for word in ("descriptor", *DESCRIPTORS, "latent space", "H_gauss", "eff_dim",
                 "MuJoCo behaviour", "training robots", f"json: {out}", "robot quality",
                 "all bodies attached", "W1 limbs"):
        assert word in text, word
    res = _strict(out.read_text())
    q = res["quality"]
    assert q["columns"] == ["measure", "training corpus", "procedural", "real robots"]
    assert [len(q["populations"][k]) for k in q["columns"][1:]] == [2, 2, 2]
    assert q["numbers"]["procedural"]["all_attached"] == 1.0
    tr = res["training"]
    assert res["latent_dim"] == 8 and res["feature_set"] == "paper34"
    assert tr["robots"] == len(tr["records"]) > 10
    assert len(tr["behaviour"]) == 2
    assert tr["behaviour_summary"]["robots"] == 2
    assert "samples" not in res and "comparison" not in res
    lat = tr["latent"]
    assert lat["n"] == tr["robots"] and lat["dim"] == 8 and len(lat["eigenvalues"]) == 8
    assert 1.0 <= lat["effective_dim"] <= 8.0
    ant = next(r for r in tr["records"] if r["name"] == "gym_ant")
    assert (ant["links"], ant["joints"], ant["limbs"], ant["dof"]) == (13, 9, 4, 14)
    assert ant["category"] == "quadruped"


def test_analyze_with_samples(trained, proc_samples) -> None:
    _, _, ckpt = trained
    res = analyze(ckpt, samples=proc_samples, root=ckpt.parent / "cache", behaviour=1,
                  permutations=20, entropy_seconds=0.5, quality=3, procedural=0,
                  real=proc_samples / "none", jobs=1, progress=False)
    q = res["quality"]
    assert q["columns"] == ["measure", "samples", "training corpus"]
    assert [r["name"] for r in q["populations"]["samples"]] == [
        "robot_000000", "robot_000001", "robot_000002"]
    paired = [anatomy(procedural_spec(i, "quadruped")).symmetric for i in range(3)]
    assert q["numbers"]["samples"]["symmetric"] == pytest.approx(np.mean(paired))
    sa, cmp_ = res["samples"], res["comparison"]
    assert sa["robots"] == 5 and sa["total"] == 6 and sa["valid"] == 5  # invalid one left out
    assert sa["load_errors"] == []
    assert sa["what"] == f"5 valid robots of {proc_samples} (6 generated)"
    assert all(r["limbs"] == 4 for r in sa["records"])
    # unnamed robots are categorised by structure (robot_category's documented rule): four
    # limbs of at most 3 joints make a quadruped, longer legs count as a humanoid
    assert [r["category"] for r in sa["records"]] == [
        "quadruped" if (r["joints"] - 1) / 4 <= 3 else "humanoid" for r in sa["records"]]
    # 5 samples < training robots: the training robots' k-NN entropy also at n = 5
    assert "knn_entropy_matched" not in sa["latent"]
    assert res["training"]["latent"]["matched_n"] == 5
    assert math.isfinite(res["training"]["latent"]["knn_entropy_matched"])
    assert set(cmp_["kl"]) == set(DESCRIPTORS)
    assert cmp_["kl"]["limbs"] > 0.1  # zoo limbs 0..12 vs always 4
    assert 0.0 <= cmp_["coverage"]["coverage"] <= 1.0
    assert cmp_["mmd"]["mmd2"] > 0
    assert len(sa["behaviour"]) == 1 and sa["behaviour"][0]["name"] == "robot_000000"
    text = format_report(res)
    assert "samples:  5 valid robots" in text and "KL(train||samples)" in text
    assert "MMD²" in text and "coverage" in text and "k-NN entropy at n = 5 robots" in text
    _strict(json.dumps(to_json(res)))
    capped = analyze(ckpt, samples=proc_samples, root=ckpt.parent / "cache", behaviour=0,
                     permutations=0, max_samples=2)
    assert capped["samples"]["robots"] == 2 and "behaviour" not in capped["samples"]


def test_analyze_locomotion_with_tuned_gaits(trained, proc_samples) -> None:
    """``--locomotion --gait-search cma --gait-rollouts N``: every population's gait speed is
    the CMA-ES search at that budget, and the report says which search it was."""
    _, _, ckpt = trained
    res = analyze(ckpt, samples=proc_samples, root=ckpt.parent / "cache", behaviour=0,
                  permutations=0, quality=1, procedural=0, real=proc_samples / "none", jobs=1,
                  progress=False, locomotion=True, gait_search="cma", gait_rollouts=24)
    q = res["quality"]
    assert q["gait"] == {"search": "cma", "rollouts": 24}
    sample = q["populations"]["samples"][0]
    path = proc_samples / "robot_000000" / "robot.xml"
    assert sample["gait_speed"] == budget_gait(str(path), "cma", rollouts=24).speed > 0
    assert all("gait_speed" in r for pop in q["populations"].values() for r in pop)
    assert "best of 24 open-loop rollouts of 4 s (random gaits tuned by CMA-ES)" in \
        format_report(res)


def test_analyze_of_a_folder_without_robots_is_a_one_line_error(trained, tmp_path,
                                                                capsys) -> None:
    _, _, ckpt = trained
    (tmp_path / "robot_000000").mkdir()
    (tmp_path / "robot_000000" / "robot.xml").write_text("<mujoco><worldbody><body></mujoco>")
    cache = tmp_path.parent / f"{tmp_path.name}_cache"
    rc = main(["analyze", "--ckpt", str(ckpt), "--samples", str(tmp_path), "--behaviour", "0",
               "--root", str(cache)])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("robovae: ") and "no robot loaded" in err
    assert "robot.xml: malformed XML" in err and len(err.strip().splitlines()) == 1
    assert not cache.exists()  # refused before the training corpus is built


def test_to_json() -> None:
    obj = {"a": math.nan, "b": [np.float32(1.5), np.int64(3), np.bool_(True), math.inf],
           1: (np.float64("nan"),)}
    assert to_json(obj) == {"a": None, "b": [1.5, 3, True, None], "1": [None]}


def test_load_graphs_collects_errors(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    graphs, errors = load_graphs([ZOO["gym_ant"], bad, tmp_path / "missing.xml"],
                                 names=["a", "b", "c"])
    assert [g.name for g in graphs] == ["a"]
    assert len(errors) == 2 and all(e.startswith("robovae: ") for e in errors)


def test_sample_files_with_and_without_manifest(tmp_path) -> None:
    for i in range(3):
        (tmp_path / f"robot_{i:06d}").mkdir()
        (tmp_path / f"robot_{i:06d}" / "robot.xml").write_text(ZOO["gym_ant"].read_text())
    assert [n for n, _ in sample_files(tmp_path)] == [f"robot_{i:06d}" for i in range(3)]
    with open(tmp_path / "manifest.jsonl", "w") as f:
        for i, valid in enumerate([True, False, True]):
            f.write(json.dumps({"index": i, "valid": valid,
                                "path": f"robot_{i:06d}/robot.xml"}) + "\n")
    # the manifest's invalid robot 1 is left out
    assert [n for n, _ in sample_files(tmp_path)] == ["robot_000000", "robot_000002"]
    assert len(sample_files(tmp_path, valid_only=False)) == 3
    with pytest.raises(RobovaeError):
        sample_files(tmp_path / "nope")


def test_analyze_measures_procedural_training_robots(trained, tmp_path) -> None:
    """Training robots built in memory from ``procedural:<class>:<seed>`` have no file: the
    behaviour rows measure the robot written from its seed (``source_file``), not an error."""
    _, _, ckpt = trained
    res = analyze(ckpt, sources=["procedural:n=2,seed=0"], root=tmp_path, behaviour=2,
                  permutations=0, entropy_seconds=0.5, jobs=1, progress=False)
    rows = res["training"]["behaviour"]
    assert len(rows) == 2 and not any("error" in r for r in rows)
    assert all(Path(r["robot"]).is_file() for r in rows)


def test_analyze_refuses_an_unwritable_json_or_sheets_before_any_work(trained, tmp_path,
                                                                      capsys) -> None:
    """--json and --sheets are checked first: a report lost after minutes of measures would
    be the other outcome."""
    _, _, ckpt = trained
    (tmp_path / "file").write_text("")
    cache = tmp_path / "cache"
    for flag, value, message in (("--json", tmp_path, "a folder, not a file name for the report"),
                                 ("--json", tmp_path / "file" / "r.json",
                                  "file: cannot write report there"),
                                 ("--sheets", tmp_path / "file" / "sheets",
                                  "file: cannot write contact sheets there")):
        rc = main(["analyze", "--ckpt", str(ckpt), "--behaviour", "0", "--root", str(cache),
                   flag, str(value)])
        err = capsys.readouterr().err
        assert rc == 2 and message in err and len(err.strip().splitlines()) == 1, err
        assert not cache.exists()
    # a run refused after the check (no robot in --samples) leaves no empty --sheets folder
    (tmp_path / "empty").mkdir()
    rc = main(["analyze", "--ckpt", str(ckpt), "--behaviour", "0", "--root", str(cache),
               "--samples", str(tmp_path / "empty"), "--sheets", str(tmp_path / "new" / "s")])
    err = capsys.readouterr().err
    assert rc == 2 and "no robot" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "new").exists()
