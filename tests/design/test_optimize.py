"""robovae optimize and the task scores: outputs, resume, baselines, one-line refusals."""

from __future__ import annotations

import copy
import json

import gymnasium
import mujoco
import numpy as np
import pytest
import torch

import robovae.design.optimize as optimize_module
from robovae.cli import main
from robovae.data.procedural import procedural_spec
from robovae.design.optimize import (
    CMA_RESAMPLES,
    HELDOUT_SEEDS,
    METHODS,
    PRIOR_REDRAWS,
    UNFINISHED,
    WRITER,
    best_so_far,
    optimize,
    score_seeds,
)
from robovae.design.results import gait_seed, search_point, top_records
from robovae.design.score import Wheeled, reach_score, score_robot, walk_gait, walk_score
from robovae.envs import WALK_ID
from robovae.envs.gait import SinusoidGait, replay
from robovae.envs.walk import walk_scene
from robovae.errors import RobovaeError, SettingsError
from robovae.evaluate.quality.locomotion import continuous_actuators, gait
from robovae.generate.fixes import decoded_fixes
from robovae.generate.writer import write_robot
from robovae.model.prior import unfinished


@pytest.fixture(scope="module")
def quadruped(tmp_path_factory):
    path = tmp_path_factory.mktemp("q") / "q.xml"
    path.write_text(procedural_spec(3, kind="quadruped").to_xml())
    return path


def test_walk_score_is_deterministic_and_normalised(quadruped):
    a = walk_score(quadruped, trials=2, seconds=1.5, settle=0.5)
    b = walk_score(quadruped, trials=2, seconds=1.5, settle=0.5)
    assert a == b and a["score"] > 0
    assert a["score"] == pytest.approx(a["speed"] / a["extent"])
    # a robot that counts as fallen from the first sample has walked nothing
    assert walk_score(quadruped, trials=2, seconds=1.5, settle=0.5, max_tilt=0.0)["score"] == 0
    # one gait scorer: the quality measure's search with the optimiser's budget
    scene = walk_scene(quadruped)[1]
    assert a["score"] == gait(scene.model, rollouts=2, seconds=1.5, settle=1 / 3,
                              max_tilt=60.0).speed


def test_step_scores_walkers_and_refuses_wheels(quadruped, tmp_path):
    """Task step is walk for a robot without a motor on a hinge without limits; a wheeled
    robot, which could roll, scores 0 with the reason, and its gait is none."""
    kw = {"seed": 0}
    assert score_robot(quadruped, "step", **kw) == score_robot(quadruped, "walk", **kw)
    mobile = tmp_path / "mobile.xml"
    mobile.write_text(procedural_spec(0, "mobile_manipulator").to_xml())
    assert score_robot(mobile, "walk")["score"] > 0  # it rolls
    res = score_robot(mobile, "step")
    assert res["score"] == 0.0 and res["error"].startswith("Wheeled: wheeled: a motor drives")
    with pytest.raises(Wheeled):
        walk_gait(mobile, step=True)
    assert walk_gait(mobile)["wheeled"] is True and walk_gait(quadruped)["wheeled"] is False


def test_scores_of_robots_that_cannot_do_the_task(tmp_path):
    spec = procedural_spec(0)
    for act in list(spec.actuators):
        spec.delete(act)
    passive = tmp_path / "passive.xml"
    passive.write_text(spec.to_xml())
    res = score_robot(passive, "walk")
    assert res["score"] == 0.0 and "no actuators" in res["error"]
    gantry = mujoco.MjSpec()  # a box moved by motors on its slides to the world
    body = gantry.worldbody.add_body(name="cart", pos=[0, 0, 0.1])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1])
    for name, axis in (("x", [1, 0, 0]), ("z", [0, 0, 1])):
        body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
        gantry.add_actuator(target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT).gear[0] = 20.0
    (tmp_path / "gantry.xml").write_text(gantry.to_xml())
    res = score_robot(tmp_path / "gantry.xml", "walk")
    assert res["score"] == 0.0 and "(actuated base)" in res["error"]
    junk = tmp_path / "junk.xml"
    junk.write_text("junk")
    assert score_robot(junk, "stand")["score"] == 0.0
    with pytest.raises(RobovaeError, match="unknown task 'fly' .choose from walk"):
        score_robot(passive, "fly")
    with pytest.raises(RobovaeError, match="score seed must be an integer in"):  # an error
        score_robot(passive, "walk", seed=-1)  # record, as for a bad robot, until 2026-11-29


def arm(hinges: int) -> mujoco.MjSpec:
    spec = mujoco.MjSpec()
    spec.compiler.degree = False  # ranges below in radians
    body = spec.worldbody.add_body(name="base")
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 0.05, 0.05])
    axes = [[0, 0, 1], [0, 1, 0], [0, 1, 0]]
    for k in range(hinges):
        body = body.add_body(name=f"l{k}", pos=[0, 0, 0.1] if k == 0 else [0.2, 0, 0])
        body.add_joint(name=f"j{k}", axis=axes[k], range=[-1.5, 1.5],
                       limited=mujoco.mjtLimited.mjLIMITED_TRUE)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0, 0.2, 0, 0],
                      size=[0.02, 0, 0])
    return spec


def test_reach_volume_grows_with_the_arms_freedom(tmp_path):
    vols = []
    for n in (1, 2, 3):
        path = tmp_path / f"arm{n}.xml"
        path.write_text(arm(n).to_xml())
        vols.append(reach_score(path, samples=256)["volume"])
    assert vols[0] == 0.0  # one hinge sweeps an arc: a flat hull, no volume
    assert 1e-3 < vols[1] < vols[2]
    # samples=0 scored 0.0 as if measured, -3 was a NumPy traceback: refused in one line
    for samples in (0, 3, -3):
        with pytest.raises(SettingsError, match=r"reach_score\.samples must be an integer >= 4"):
            reach_score(path, samples=samples)


def test_best_so_far():
    assert best_so_far([1, 0, 3, 2]).tolist() == [1, 1, 3, 3]


def test_optimize_writes_log_plot_best_and_resumes(trained_nodes, tmp_path):
    model, _, ckpt = trained_nodes
    out = tmp_path / "opt"
    res = optimize(ckpt, "stand", 3, out, seed=1, jobs=1, top=2, progress=False, variance=0.5)
    log = json.loads((out / "log.json").read_text())
    for m in METHODS:
        recs = log["evaluations"][m]
        assert [r["index"] for r in recs] == [0, 1, 2]
        assert res[m]["best"] == max(r["score"] for r in recs)
        assert (out / "best" / m / "rank_0" / "robot.xml").is_file()
        assert (out / "best" / m / "rank_1" / "robot.xml").is_file()
    assert all(len(r["z"]) == model.hparams.latent_dim for r in log["evaluations"]["cma"])
    # CMA-ES searches the prior's leading directions: its latents lie in that affine subspace
    mean, basis = model.prior_directions(0.5)
    assert log["settings"]["cma_dim"] == basis.shape[1] < model.hparams.latent_dim
    z = np.array([r["z"] for r in log["evaluations"]["cma"]]) - mean
    assert np.allclose(z, z @ basis @ np.linalg.pinv(basis), atol=1e-8)
    assert (out / "convergence.png").stat().st_size > 1000
    assert not (out / ".work").exists()
    # the best robots are written as robovae generate writes a robot (fixes, then stance)
    best = max(log["evaluations"]["prior"], key=lambda r: (r["score"], -r["index"]))
    m64 = copy.deepcopy(model).to(torch.float64)
    g = decoded_fixes(m64.decode(torch.tensor([best["z"]], dtype=torch.float64))[0],
                      model.feature_set)[0]
    ref = write_robot(g, tmp_path / "ref", model.feature_set, name="prior_rank0", stance=True)
    assert ref.robot_path.read_bytes() == \
        (out / "best" / "prior" / "rank_0" / "robot.xml").read_bytes()
    assert log["settings"]["writer"] == WRITER
    # a larger budget continues: the logged evaluations are kept, CMA-ES is replayed
    optimize(ckpt, "stand", 5, out, seed=1, jobs=1, top=2, progress=False, variance=0.5)
    log2 = json.loads((out / "log.json").read_text())
    for m in METHODS:
        assert log2["evaluations"][m][:3] == log["evaluations"][m]
        assert len(log2["evaluations"][m]) == 5
    # the same run from scratch reaches the same log
    fresh = tmp_path / "fresh"
    optimize(ckpt, "stand", 5, fresh, seed=1, jobs=1, top=2, progress=False, variance=0.5)
    assert json.loads((fresh / "log.json").read_text()) == log2


def test_optimize_walk_with_workers(trained_nodes, tmp_path, capsys, monkeypatch):
    _, _, ckpt = trained_nodes
    out = tmp_path / "walk"
    assert main(["optimize", "--ckpt", str(ckpt), "--task", "walk", "--budget", "2",
                 "--out", str(out), "--jobs", "2"]) == 0
    text = capsys.readouterr().out
    assert "procedural" in text and "convergence" in text
    log = json.loads((out / "log.json").read_text())
    # the two procedural baseline robots of seed 0 are a fixed-base arm (walk score 0) and a
    # humanoid; test_walk_score_is_deterministic_and_normalised checks that a quadruped walks
    assert [len(log["evaluations"][m]) for m in METHODS] == [2, 2, 2]
    assert np.isfinite([r["score"] for m in METHODS for r in log["evaluations"][m]]).all()
    # each method's best robots are re-scored with the held-out score seeds 1-8
    assert "held-out median" in text and "held-out best (rank)" in text
    held = log["heldout"]
    assert held["seeds"] == list(HELDOUT_SEEDS) == list(range(1, 9))
    for m in METHODS:
        top = sorted(log["evaluations"][m], key=lambda r: (-r["score"], r["index"]))
        assert [h["index"] for h in held[m]] == [r["index"] for r in top]
        for h in held[m]:
            assert len(h["scores"]) == 8 and h["median"] == np.median(h["scores"])
        # the table names the top robot with the largest held-out median, and its rank
        best = max(held[m], key=lambda h: (h["median"], -h["rank"]))
        cells = next(line for line in text.splitlines() if line.startswith(m)).split()
        k = cells.index(f"({best['rank']})")
        assert cells[k - 1] == f"{best['median']:.4f}"
        # and what the best robot's scoring gait spends: mechanical power per kg (W/kg)
        g0 = held[m][0]["gait"]
        assert (g0["power"] > 0) == (g0["score"] > 0)
        if g0["error"] is None:  # a robot that cannot walk (no actuators) has no mass logged
            assert g0["mass"] > 0 and cells[k + 1] == f"{g0['power'] / g0['mass']:.0f}"
        # and how many of the top robots may roll: a motor on a hinge without limits
        for h in held[m]:
            robot = mujoco.MjModel.from_xml_path(
                str(out / "best" / m / f"rank_{h['rank']}" / "robot.xml"))
            assert h["gait"]["wheeled"] == (bool(continuous_actuators(robot).any())
                                            if h["gait"]["error"] is None else None)
        wheeled = sum(h["gait"]["wheeled"] is True for h in held[m])
        assert cells[-1] == f"{wheeled}/{len(held[m])}"
    walker = held["procedural"][0]  # the humanoid: its score depends on the gaits drawn
    path = out / "best" / "procedural" / "rank_0" / "robot.xml"
    assert walker["scores"][:2] == [score_robot(path, "walk", seed=s)["score"] for s in (1, 2)]
    assert walker["score"] == score_robot(path, "walk", seed=0)["score"]
    # with each best robot, the gait that scored it; replayed in robovae/Walk-v0, it walks at
    # the logged score (a robot that scored 0 has no gait to replay)
    assert "gait.json" in text
    for m in METHODS:
        for h in held[m]:
            g = json.loads((out / "best" / m / f"rank_{h['rank']}" / "gait.json").read_text())
            assert g == h["gait"] and g["score"] == h["score"]
            assert (g["frequency"] is None) == (h["score"] == 0)
    assert walker["score"] > 0
    env = gymnasium.make(WALK_ID, robot=str(path), frame_skip=1, reset_noise_scale=0.0)
    r = replay(env, SinusoidGait.from_json(path.parent / "gait.json"), walker["gait"]["seconds"])
    assert r.speed() / walker["gait"]["extent"] == pytest.approx(walker["score"], rel=1e-9)
    # a finished run (held-out scores kept in the log) starts no worker processes
    started = []
    monkeypatch.setattr(optimize_module, "worker_pool", lambda *a, **k: started.append(a))
    assert main(["optimize", "--ckpt", str(ckpt), "--task", "walk", "--budget", "2",
                 "--out", str(out), "--jobs", "2"]) == 0
    assert started == []


def test_a_worker_scores_candidates_without_torch(tmp_path):
    """What a worker process of ``robovae optimize`` does (:func:`robovae.design.candidates.
    evaluate`), in a fresh interpreter given pickled items: a decoded-and-fixed graph as
    :class:`TreeArrays` and a procedural robot's MJCF text are written, scored as in this
    process and deleted, and neither torch, PyG nor ``cmaes`` is ever imported; a graph the
    writer cannot take scores 0 with a one-line error."""
    import pickle
    import subprocess
    import sys

    from robovae.data.mjcf import model_to_graph
    from robovae.data.tree_arrays import TreeArrays
    from robovae.design.candidates import evaluate

    graph = model_to_graph(procedural_spec(3, kind="quadruped").compile(), "kinematic")
    arrays = TreeArrays.of(decoded_fixes(graph, "kinematic")[0])
    broken = arrays.with_x(arrays.x[:, :3])  # fewer feature columns than the set has
    items = [(arrays, str(tmp_path / "a"), "kinematic", "walk", [0], False),
             (procedural_spec(3, kind="quadruped").to_xml(), str(tmp_path / "b"), "kinematic",
              "stand", [0], False),
             (broken, str(tmp_path / "c"), "kinematic", "stand", [0], False)]
    (tmp_path / "items.pkl").write_bytes(pickle.dumps(items))
    script = (
        "import pickle, sys, json\n"
        "from robovae.design.candidates import evaluate\n"
        f"items = pickle.loads(open({str(tmp_path / 'items.pkl')!r}, 'rb').read())\n"
        "print(json.dumps({'results': [evaluate(x) for x in items],\n"
        "  'loaded': [m for m in ('torch', 'torch_geometric', 'cmaes', 'scipy.stats')\n"
        "             if m in sys.modules]}))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["loaded"] == []
    here = json.loads(json.dumps([evaluate(x) for x in items]))
    assert got["results"] == here
    assert here[0]["score"] > 0 and here[0]["error"] is None and here[0]["frequency"]
    assert here[1]["score"] > 0.5 and here[1]["stands"]
    assert here[2]["score"] == 0 and here[2]["error"].startswith("writer: ")
    assert "\n" not in here[2]["error"]
    assert not any((tmp_path / k).exists() for k in "abc")  # scratch folders deleted


@pytest.mark.parametrize("kw, message", [
    ({"budget": float("nan")}, "--budget must be an integer"),  # NaN and 2.5 ran
    ({"budget": 2.5}, "--budget must be an integer"),
    ({"top": 0.5}, "--top must be an integer"), ({"score_sets": float("nan")}, "--score-sets"),
    ({"population": 3.5}, "--population must be an integer"),
    ({"restart_after": 0.5}, "--restart-after must be an integer"),
    ({"jobs": -1}, "--jobs must be an integer of at least 0"),
])
def test_optimize_library_refuses_numbers_the_command_line_cannot_give(tmp_path, kw, message):
    """A caller of :func:`optimize` (not argparse's integers) is refused before the checkpoint
    is read or anything is written."""
    with pytest.raises(RobovaeError, match=message):
        optimize(tmp_path / "none.ckpt", "walk", **{"budget": 4, **kw}, out=tmp_path / "o")
    assert not (tmp_path / "o").exists()


W2 = ["--task", "walk", "--budget", "2"]


@pytest.mark.parametrize("argv, message", [
    (["--task", "fly", "--budget", "2"], "unknown task 'fly'"),
    (["--task", "walk", "--budget", "0"], "--budget must be an integer of at least 1, not"),
    (["--task", "walk", "--budget", "-3"], "--budget must be an integer of at least 1, not"),
    ([*W2, "--variance", "0"], "--variance must be a number in (0, 1]"),
    ([*W2, "--population", "1"], "--population must be an integer of at least 2"),
    # --population 100000000 ran minutes before anything was scored, until 2026-11-29
    (["--task", "walk", "--budget", "8", "--population", "100000000"],
     "--population must be at most 10,000"),
    ([*W2, "--score-sets", "0"], "--score-sets must be an integer of at least 1"),
    ([*W2, "--restart-after", "0"], "--restart-after must be an integer of at least 1"),
    ([*W2, "--local-step", "0"], "--local-step must be a finite number > 0"),
    ([*W2, "--local-step", "nan"], "--local-step must be a finite number > 0"),
    ([*W2, "--distinct", "-1"], "--distinct must be a finite number >= 0"),
])
def test_optimize_refuses_bad_input(trained_nodes, tmp_path, capsys, argv, message):
    _, _, ckpt = trained_nodes
    out = tmp_path / "o"
    assert main(["optimize", "--ckpt", str(ckpt), "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not out.exists()


def test_optimize_refuses_a_folder_another_run_is_writing(trained_nodes, tmp_path, capsys):
    """A second run would rewrite log.json under the first and delete its scratch folder."""
    from robovae.files import LOCK, FolderLock

    _, _, ckpt = trained_nodes
    out = tmp_path / "o"
    with FolderLock(out):
        assert main(["optimize", "--ckpt", str(ckpt), "--task", "stand", "--budget", "2",
                     "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "another run is writing there" in err and err.count("\n") == 1
        assert sorted(p.name for p in out.iterdir()) == [LOCK]


def test_optimize_refuses_an_out_inside_a_file(trained_nodes, tmp_path, capsys):
    _, _, ckpt = trained_nodes
    (tmp_path / "file").write_text("keep")
    out = tmp_path / "file" / "o"
    assert main(["optimize", "--ckpt", str(ckpt), "--task", "stand", "--budget", "2",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "file/o: cannot write the run's files there" in err and err.count("\n") == 1
    assert (tmp_path / "file").read_text() == "keep"


def test_optimize_refuses_a_bad_checkpoint_and_another_runs_log(trained_nodes, tmp_path,
                                                                 capsys):
    bad = tmp_path / "bad.ckpt"
    bad.write_text("not a checkpoint")
    out = tmp_path / "o"
    assert main(["optimize", "--ckpt", str(bad), "--task", "walk", "--budget", "2",
                 "--out", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1 and not out.exists()
    _, _, ckpt = trained_nodes
    optimize(ckpt, "reach", 1, out, seed=0, jobs=1, top=1, progress=False)
    before = (out / "log.json").read_text()
    assert main(["optimize", "--ckpt", str(ckpt), "--task", "stand", "--budget", "2",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "log of another run (task differ)" in err and err.count("\n") == 1
    assert (out / "log.json").read_text() == before
    # a damaged log or another program's file: tracebacks until 2026-11-29
    for text, reason in ((before[:200], "Expecting"), ("", "Expecting value"),
                         ("[1, 2]", "no settings and evaluations of cma, prior, procedural")):
        (out / "log.json").write_text(text)
        assert main(["optimize", "--ckpt", str(ckpt), "--task", "reach", "--budget", "2",
                     "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"robovae: {out / 'log.json'}: not an optimisation log (")
        assert reason in err and err.count("\n") == 1
        assert (out / "log.json").read_text() == text


def test_optimize_population_is_a_setting_of_the_run(trained_nodes, tmp_path, capsys):
    _, _, ckpt = trained_nodes
    out = tmp_path / "pop"
    optimize(ckpt, "stand", 3, out, seed=2, jobs=1, top=1, progress=False, variance=0.5,
             population=4)
    log = json.loads((out / "log.json").read_text())
    assert log["settings"]["cma_population"] == 4
    assert [len(log["evaluations"][m]) for m in METHODS] == [3, 3, 3]  # a round cut at 3
    # without --population: the cmaes default, 4 + floor(3 ln k) for k searched directions
    default = tmp_path / "default"
    optimize(ckpt, "stand", 3, default, seed=2, jobs=1, top=1, progress=False, variance=0.5)
    dlog = json.loads((default / "log.json").read_text())
    k = dlog["settings"]["cma_dim"]
    assert dlog["settings"]["cma_population"] == 4 + int(np.floor(3 * np.log(k)))
    # resuming with another population is refused before anything changes
    before = (out / "log.json").read_text()
    assert main(["optimize", "--ckpt", str(ckpt), "--task", "stand", "--budget", "4",
                 "--out", str(out), "--seed", "2", "--variance", "0.5"]) == 2
    err = capsys.readouterr().err
    assert "log of another run (cma_population differ)" in err and err.count("\n") == 1
    assert (out / "log.json").read_text() == before
    # a log written before the population was recorded ran the default: it resumes
    old = json.loads((default / "log.json").read_text())
    del old["settings"]["cma_population"]
    (default / "log.json").write_text(json.dumps(old))
    optimize(ckpt, "stand", 4, default, seed=2, jobs=1, top=1, progress=False, variance=0.5)
    resumed = json.loads((default / "log.json").read_text())
    assert resumed["evaluations"]["cma"][:3] == dlog["evaluations"]["cma"]
    assert resumed["settings"]["cma_population"] == dlog["settings"]["cma_population"]


def test_score_sets_score_each_robot_by_the_median_over_seeds(trained_nodes, tmp_path,
                                                              capsys):
    _, _, ckpt = trained_nodes
    assert score_seeds(1) == [0] and score_seeds(3) == [0, 9, 10]
    assert not set(score_seeds(20)) & set(HELDOUT_SEEDS)
    out = tmp_path / "sets"
    optimize(ckpt, "reach", 2, out, seed=0, jobs=1, top=1, progress=False, score_sets=3)
    log = json.loads((out / "log.json").read_text())
    assert log["settings"]["score_seeds"] == [0, 9, 10]
    varied = 0
    for m in METHODS:
        for r in log["evaluations"][m]:
            if r.get("error") is not None:  # e.g. not a fixed-base arm: 0, not scored again
                assert r["score"] == 0.0 and r["scores"] == [0.0, 0.0, 0.0]
                continue
            path = out / "best" / m / "rank_0" / "robot.xml"
            if r["index"] == log["heldout"][m][0]["index"]:  # the written best: re-score it
                assert r["scores"] == [score_robot(path, "reach", seed=s)["score"]
                                       for s in (0, 9, 10)]
            assert r["score"] == np.median(r["scores"])
            varied += len(set(r["scores"])) > 1
    assert varied  # the seeds draw other configurations: the scores differ
    # another number of score sets is another run: refused before anything changes
    before = (out / "log.json").read_text()
    assert main(["optimize", "--ckpt", str(ckpt), "--task", "reach", "--budget", "2",
                 "--out", str(out), "--top", "1"]) == 2
    err = capsys.readouterr().err
    assert "log of another run (score_seeds differ)" in err and err.count("\n") == 1
    assert (out / "log.json").read_text() == before
    # a log written before score sets (one score seed, "score_seed": 0) resumes with one set
    one = tmp_path / "one"
    optimize(ckpt, "reach", 1, one, seed=0, jobs=1, top=1, progress=False)
    old = json.loads((one / "log.json").read_text())
    assert old["settings"].pop("score_seeds") == [0]
    old["settings"]["score_seed"] = 0
    (one / "log.json").write_text(json.dumps(old))
    optimize(ckpt, "reach", 2, one, seed=0, jobs=1, top=1, progress=False)
    resumed = json.loads((one / "log.json").read_text())
    assert resumed["settings"]["score_seeds"] == [0]
    assert [resumed["evaluations"][m][:1] for m in METHODS] == \
        [old["evaluations"][m] for m in METHODS]


def test_gait_seed_is_the_set_that_gives_the_median():
    assert gait_seed({"score": 0.4}, [0]) == 0
    assert gait_seed({"score": 0.5, "scores": [0.9, 0.5, 0.1]}, [0, 9, 10]) == 9
    assert gait_seed({"score": 0.2, "scores": [0.2, 0.2, 0.7]}, [0, 9, 10]) == 9
    # even K: the median averages the middle two; the gait is the upper one's
    assert gait_seed({"score": 0.35, "scores": [0.1, 0.3, 0.4, 0.9]}, [0, 9, 10, 11]) == 10


def test_walk_gait_with_score_sets_is_the_median_sets(trained_nodes, tmp_path):
    """With three score sets a robot's walk score is the median of three searches; its
    gait.json is the search that scored the median (a gait that walks at the logged score), and
    a finished run keeps it."""
    _, _, ckpt = trained_nodes
    out = tmp_path / "sets"
    optimize(ckpt, "walk", 1, out, seed=0, jobs=1, top=1, progress=False, score_sets=3)
    log = json.loads((out / "log.json").read_text())
    moved = 0
    for m in METHODS:
        h, r = log["heldout"][m][0], log["evaluations"][m][0]
        g = json.loads((out / "best" / m / "rank_0" / "gait.json").read_text())
        assert g == h["gait"] and g["score_seed"] == gait_seed(r, [0, 9, 10])
        assert g["score"] == r["score"] == np.median(r["scores"])
        moved += g["score_seed"] != 0
    assert moved  # seed 0's search is not the median's for every robot
    before = (out / "log.json").read_text()
    optimize(ckpt, "walk", 1, out, seed=0, jobs=1, top=1, progress=False, score_sets=3)
    assert (out / "log.json").read_text() == before


def test_unfinished_decodings_score_zero_and_prior_samples_redraw(trained_nodes, tmp_path):
    """A decoding cut off by the node limit is not a robot: CMA-ES asks another candidate in
    its place, prior samples redraw their latent as robovae generate does; what is still
    unfinished scores 0 without simulation."""
    model = copy.deepcopy(trained_nodes[0]).to(torch.float64)
    model.hparams.max_nodes = 3  # most of this model's trees are larger: cut off
    # top=1 throughout: the best robots re-scored at the end are not what this test checks
    optimize(model, "stand", 6, tmp_path / "opt", seed=0, jobs=1, progress=False, top=1)
    ev = json.loads((tmp_path / "opt" / "log.json").read_text())["evaluations"]

    def decode(z):
        return model.decode(torch.tensor(np.asarray(z), dtype=torch.float64)[None])[0]

    cut = [unfinished(model, decode(r["z"])) for r in ev["cma"]]
    assert any(r["rejected"] > 0 for r in ev["cma"])
    for r, c in zip(ev["cma"], cut):
        assert (r["error"] == UNFINISHED and r["score"] == 0.0) == c
        assert not c or r["rejected"] == CMA_RESAMPLES
    for r in ev["prior"]:
        k = r["draw"]
        assert np.allclose(r["z"], model.prior_latent(0, r["index"], draw=k).double().numpy())
        assert (k == 0 or unfinished(model, decode(
            model.prior_latent(0, r["index"], draw=k - 1).double().numpy())))
        assert (r.get("error") == UNFINISHED) == unfinished(model, decode(r["z"]))
        assert r.get("error") != UNFINISHED or k == PRIOR_REDRAWS
    assert any(r["draw"] > 0 for r in ev["prior"])
    # a continued run replays CMA-ES with its resamples and reaches the log of a fresh run
    # (population 2: the 6 logged evaluations are 3 whole generations, replayed on loading)
    optimize(model, "stand", 6, tmp_path / "opt2", seed=0, jobs=1, progress=False, population=2,
             top=1)
    log6 = json.loads((tmp_path / "opt2" / "log.json").read_text())
    assert any(r["rejected"] > 0 for r in log6["evaluations"]["cma"])
    optimize(model, "stand", 8, tmp_path / "opt2", seed=0, jobs=1, progress=False, population=2,
             top=1)
    optimize(model, "stand", 8, tmp_path / "fresh", seed=0, jobs=1, progress=False, population=2,
             top=1)
    longer = json.loads((tmp_path / "opt2" / "log.json").read_text())
    assert longer["evaluations"]["cma"][:6] == log6["evaluations"]["cma"]
    assert longer == json.loads((tmp_path / "fresh" / "log.json").read_text())


def test_cma_es_restarts_locally_and_globally_in_turn_and_resumes(trained_nodes, tmp_path,
                                                                  capsys):
    """A CMA-ES that finds nothing better for ``restart_after`` generations (here 1) restarts,
    in turn, around the best point so far (step ``local_step``, the first population) and from
    the prior with twice the last global population (IPOP); a resumed run replays both, a run
    with other restart settings is refused."""
    _, _, ckpt = trained_nodes
    out = tmp_path / "opt"
    # top=1: the best robots re-scored at the end are not what this test checks
    optimize(ckpt, "reach", 10, out, seed=0, jobs=1, progress=False, population=2,
             restart_after=1, top=1)
    log = json.loads((out / "log.json").read_text())
    cma = log["evaluations"]["cma"]
    restarts = [r["restart"] for r in cma]
    assert restarts == sorted(restarts) and restarts[-1] >= 2
    assert [r["local"] for r in cma] == [k % 2 == 1 for k in restarts]
    sizes = [restarts.count(k) for k in range(restarts[-1])]  # whole generations
    assert all(n % 2 == 0 for n in sizes[1::2])  # local: the first population
    assert all(n % (2 * 2 ** k) == 0 for k, n in enumerate(sizes[::2]))  # global: doubling
    # a local run searches around the best latent before it, a global one the whole prior
    from robovae.model.checkpoint import load_model

    run = optimize_module._Run(load_model(ckpt), "reach", 10, out, 0, 1, 1, 0.95, 2)
    whiten = np.linalg.pinv(run.basis)
    first = restarts.index(1)
    best = max(cma[:first], key=lambda r: r["score"])
    y_best = whiten @ (np.array(best["z"]) - run.origin)
    near = [np.linalg.norm(whiten @ (np.array(r["z"]) - run.origin) - y_best)
            for r in cma if r["restart"] == 1]
    far = [np.linalg.norm(whiten @ (np.array(r["z"]) - run.origin)) for r in cma[:first]]
    assert max(near) < 0.5 * np.median(far)
    optimize(ckpt, "reach", 12, out, seed=0, jobs=1, progress=False, population=2,
             restart_after=1, top=1)
    again = json.loads((out / "log.json").read_text())["evaluations"]["cma"]
    assert again[:10] == cma and len(again) == 12
    before = (out / "log.json").read_text()
    for flags in (["--restart-after", "2"], ["--restart-after", "1", "--local-step", "0.3"]):
        assert main(["optimize", "--ckpt", str(ckpt), "--task", "reach", "--budget", "14",
                     "--out", str(out), "--population", "2", *flags]) == 2
        err = capsys.readouterr().err
        assert "log of another run (cma_restarts differ)" in err and err.count("\n") == 1
    assert (out / "log.json").read_text() == before


def test_a_given_model_is_not_changed(trained_nodes, tmp_path):
    """optimize decodes in float64 on a copy: the caller's model keeps its dtype."""
    from robovae.model.checkpoint import load_model

    model = load_model(trained_nodes[2])
    optimize(model, "reach", 1, tmp_path / "opt", seed=0, jobs=1, top=1, progress=False)
    assert all(p.dtype == torch.float32 for p in model.parameters())


def test_optimize_help_gives_the_restart_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["optimize", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"default {optimize_module.RESTART_AFTER}" in text
    assert f"default {optimize_module.LOCAL_SIGMA:g}" in text
    assert f"default {optimize_module.DISTINCT:g}" in text


def test_top_records_are_distinct_designs():
    """A method's best robots skip latent designs within ``distinct`` (whitened prior units)
    of a better one; procedural robots have no latent and are each their own design."""
    rng = np.random.default_rng(0)
    basis = np.linalg.qr(rng.normal(size=(6, 2)))[0] * np.array([2.0, 0.5])  # U diag(λ)^½
    origin = rng.normal(size=6)
    ys = [np.array(y) for y in ([0, 0], [0.3, 0], [0, 0.5], [2, 0], [2.2, 0.1], [0, 3])]
    scores = [0.9, 0.8, 0.7, 0.6, 0.5, 0.1]
    cma = [{"index": i, "score": s, "z": list(origin + basis @ y)}
           for i, (y, s) in enumerate(zip(ys, scores))]
    proc = [{"index": i, "score": 0.5, "seed": i} for i in range(4)]
    run = type("Run", (), {"log": {"evaluations": {"cma": cma, "procedural": proc}}, "top": 3,
                           "distinct": 1.0, "origin": origin, "basis": basis})()
    assert np.allclose(search_point(run, cma[4]["z"]), ys[4])
    assert [r["index"] for r in top_records(run, "cma")] == [0, 3, 5]
    assert [r["index"] for r in top_records(run, "procedural")] == [0, 1, 2]
    run.distinct = 0.4  # only the nearest copy (0.3 away) is skipped
    assert [r["index"] for r in top_records(run, "cma")] == [0, 2, 3]
    run.distinct, run.top = 0.0, 4
    assert [r["index"] for r in top_records(run, "cma")] == [0, 1, 2, 3]


def test_optimize_self_collision_is_a_setting_of_the_run(trained_nodes, tmp_path, capsys):
    """--self-collision: every method's robots collide with themselves (the written best ones
    too), the log says so, and a log of the other kind is not continued either way."""
    import mujoco

    _, _, ckpt = trained_nodes
    out, plain = tmp_path / "sc", tmp_path / "plain"
    argv = ["optimize", "--ckpt", str(ckpt), "--task", "stand", "--budget", "2", "--top", "1",
            "--seed", "2", "--variance", "0.5", "--jobs", "1"]
    assert main([*argv, "--out", str(out), "--self-collision"]) == 0
    log = json.loads((out / "log.json").read_text())
    assert log["settings"]["self_collision"] is True
    for m in METHODS:
        model = mujoco.MjModel.from_xml_path(str(out / "best" / m / "rank_0" / "robot.xml"))
        assert (model.geom_conaffinity[model.geom_bodyid != 0] == 1).all(), m
    del log["settings"]["self_collision"]  # the log of the same run without self-collision
    plain.mkdir()
    (plain / "log.json").write_text(json.dumps(log))
    capsys.readouterr()
    for folder, extra in ((out, []), (plain, ["--self-collision"])):
        before = (folder / "log.json").read_text()
        assert main([*argv, "--out", str(folder), *extra]) == 2
        err = capsys.readouterr().err
        assert "log of another run (self_collision differ)" in err and err.count("\n") == 1
        assert (folder / "log.json").read_text() == before
