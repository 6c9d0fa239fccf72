"""robovae gait: gaits tuned to the body, written for robovae/Walk-v0, and its refusals."""

from __future__ import annotations

import json

import gymnasium
import mujoco
import numpy as np
import pytest

import robovae.envs
from robovae.cli import main
from robovae.data.procedural import procedural_spec
from robovae.design.gaits import GAIT_FILE, tune_gaits
from robovae.design.score import walk_gait
from robovae.envs.gait import SinusoidGait, replay
from robovae.envs.walk import walk_scene
from robovae.errors import RobovaeError
from robovae.evaluate.quality.locomotion import GaitTrials


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    """A quadruped and a mobile manipulator, each in a folder of its own as robot.xml."""
    root = tmp_path_factory.mktemp("gaits")
    paths = {}
    for name, kind in (("quadruped", "quadruped"), ("mobile", "mobile_manipulator")):
        (root / name).mkdir()
        paths[name] = root / name / "robot.xml"
        paths[name].write_text(procedural_spec(3, kind=kind).to_xml())
    return paths


def test_a_gait_tuned_for_the_exact_start_beats_the_walk_score_and_replays_to_it(robots):
    q = robots["quadruped"]
    [(path, g)] = tune_gaits([q], refine=32, starts=1, hold=1, progress=False)
    assert path == q.parent / GAIT_FILE and json.loads(path.read_text()) == g
    plain = walk_gait(q)
    # the same 8 random gaits first: never below the walk score; here CMA-ES found better
    assert g["walk_score"] == plain["score"] and g["score"] > plain["score"] > 0
    assert g["rollouts"] == 8 + 32 and g["refine"] == 32 and g["robot"] == str(q.resolve())
    assert (g["starts"], g["hold"], g["noise"]) == (1, 1, 0.0)
    assert g == {**walk_gait(q, refine=32), "walk_score": plain["score"],
                 "robot": str(q.resolve())}  # deterministic
    env = gymnasium.make(robovae.envs.WALK_ID, robot=str(q), frame_skip=1, reset_noise_scale=0.0)
    r = replay(env, SinusoidGait.from_json(path), g["seconds"])
    assert r.speed(g["settle"], g["max_tilt"]) / g["extent"] == pytest.approx(g["score"],
                                                                              rel=1e-9)


def test_a_gait_tuned_for_the_environment_is_judged_as_the_environment_runs_it(robots):
    """By default every gait is judged with each control held for 5 physics steps (the
    environment's frame_skip) by its median speed from 4 starts. Held so, a gait moves the
    robot as the environment with frame_skip 5 (and no reset noise) moves it."""
    q = robots["quadruped"]
    [(_, g)] = tune_gaits([q], refine=16, starts=1, hold=5, progress=False)
    gait = SinusoidGait(g["frequency"], *map(np.asarray, (g["amplitude"], g["phase"],
                                                        g["offset"])))
    env = gymnasium.make(robovae.envs.WALK_ID, robot=str(q), reset_noise_scale=0.0)
    assert env.unwrapped.frame_skip == 5
    r = replay(env, gait, g["seconds"])
    scene = walk_scene(q)[1]
    trials = GaitTrials(scene.model, g["seconds"], 1 / 3, max_tilt=60.0, hold=5)
    speeds, _, (states, _, _) = trials.run(gait.amplitude[None], gait.phase[None],
                                           np.array([gait.frequency]), gait.offset[None])
    assert speeds[0] / trials.extent == pytest.approx(g["score"], rel=1e-12)
    data = mujoco.MjData(scene.model)
    data.qpos[:] = states[-1, 1:1 + scene.model.nq]
    mujoco.mj_kinematics(scene.model, data)
    assert len(states) == 5 * len(r.time)
    assert r.root[-1] == pytest.approx(data.xpos[scene.root], abs=1e-9)
    [(_, noisy)] = tune_gaits([q], refine=16, progress=False)
    assert (noisy["starts"], noisy["hold"], noisy["noise"]) == (4, 5, 0.05)
    assert noisy == walk_gait(q, refine=16, starts=4, hold=5) | {
        "walk_score": noisy["walk_score"], "robot": noisy["robot"]}
    assert noisy["score"] != g["score"] and noisy["walk_score"] == walk_gait(q)["score"]


def test_cli_tunes_a_folder_of_robots_into_out(robots, tmp_path, capsys):
    out = tmp_path / "gaits"
    assert main(["gait", str(robots["quadruped"].parent), str(robots["mobile"]), "--refine",
                 "16", "--starts", "2", "--out", str(out), "--jobs", "2"]) == 0
    text = capsys.readouterr().out
    assert "walk score" in text and "tuned" in text and "1 CMA-ES generations of 16" in text
    assert "the median from 2 starts, 1 with noise 0.05" in text
    assert sorted(p.name for p in out.iterdir()) == ["mobile.json", "quadruped.json"]
    mobile = json.loads((out / "mobile.json").read_text())
    assert mobile["wheeled"] is True and any(mobile["offset"])  # its wheels turn
    assert mobile["score"] > 0 and mobile["walk_score"] > 0
    assert not (robots["mobile"].parent / GAIT_FILE).exists()  # only --out was written


def test_robots_of_one_name_get_their_folders_in_the_file_name(robots, tmp_path):
    """An optimisation run's best/cma/rank_0 and best/prior/rank_0 into one --out folder."""
    files = []
    for method in ("cma", "prior"):
        (tmp_path / "best" / method / "rank_0").mkdir(parents=True)
        files.append(tmp_path / "best" / method / "rank_0" / "robot.xml")
        files[-1].write_text(robots["quadruped"].read_text())
    done = tune_gaits([*files, robots["mobile"]], refine=16, starts=1, hold=1,
                      out=tmp_path / "gaits", progress=False)
    assert [p.name for p, _ in done] == ["cma_rank_0.json", "prior_rank_0.json", "mobile.json"]
    assert [g["robot"] for _, g in done] == [str(f.resolve()) for f in
                                            (*files, robots["mobile"])]
    assert done[0][1]["score"] == done[1][1]["score"]  # the same body, the same seed


def test_a_gait_file_of_another_robot_is_kept_unless_overwrite(robots, tmp_path, capsys):
    """Two runs into one --out: the second refuses to replace the first's gait of another robot
    with its own (both robots are some run's rank_0), unless --overwrite."""
    one, two = (tmp_path / run / "rank_0" / "robot.xml" for run in ("walk1", "walk2"))
    for f in (one, two):
        f.parent.mkdir(parents=True)
        f.write_text(robots["quadruped"].read_text())
    out, fast = tmp_path / "gaits", {"refine": 16, "starts": 1, "hold": 1, "progress": False}
    tune_gaits([one], out=out, **fast)
    first = (out / "rank_0.json").read_text()
    assert main(["gait", str(two), "--refine", "16", "--starts", "1", "--hold", "1", "--out",
                 str(out), "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert f"rank_0.json holds the gait of {one.resolve()}: give another --out" in err
    assert len(err.strip().splitlines()) == 1 and (out / "rank_0.json").read_text() == first
    tune_gaits([one], out=out, **fast)  # a robot's own gait is replaced
    (path, gait), = tune_gaits([two], out=out, overwrite=True, **fast)
    assert json.loads(path.read_text())["robot"] == gait["robot"] == str(two.resolve())
    (out / "rank_0.json").write_text("[1, 2]")  # not a gait file
    with pytest.raises(RobovaeError, match="holds no gait of robovae gait"):
        tune_gaits([two], out=out, **fast)


def test_bad_input_is_refused_in_one_line_before_anything_is_written(robots, tmp_path, capsys):
    passive = procedural_spec(0)
    for a in list(passive.actuators):
        passive.delete(a)
    (tmp_path / "passive.xml").write_text(passive.to_xml())
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body>")
    out = tmp_path / "out"
    q, mobile = str(robots["quadruped"]), str(robots["mobile"])
    cases = [([q, "--refine", "8"], "--refine must be an integer of at least 16, not 8"),
             ([q, "--starts", "0"], "--starts must be an integer of at least 1, not 0"),
             ([q, "--hold", "0"], "--hold must be an integer of at least 1, not 0"),
             ([q, "--noise", "-1"], "--noise must be a finite number >= 0, not -1.0"),
             # a NumPy OverflowError traceback until 2026-11-29
             ([q, "--noise", "inf"], "--noise must be a finite number >= 0, not inf"),
             ([q, str(tmp_path / "passive.xml")], "passive.xml: no actuators to walk with"),
             ([q, str(tmp_path / "broken.xml")], "broken.xml"),
             ([q, str(tmp_path / "nope.xml")], "nope.xml: no such file or folder"),
             ([q, mobile, "--step"], "mobile/robot.xml: wheeled"),
             ([q, str(robots["quadruped"].parent)], "would both write"),
             ([str(tmp_path / "empty")], "empty: no robot files")]
    (tmp_path / "empty").mkdir()
    for argv, message in cases:
        assert main(["gait", *argv, "--out", str(out), "--jobs", "1"]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
        assert not out.exists()
    (tmp_path / "file").write_text("")
    with pytest.raises(RobovaeError, match="file: cannot write gaits there"):
        tune_gaits([q], out=tmp_path / "file")
    with pytest.raises(RobovaeError, match="--jobs must be an integer of at least 0, not -1"):
        tune_gaits([q], out=out, jobs=-1)  # ran in this process until 2026-11-29
    assert not out.exists()
    assert main(["gait", q, "--out", str(tmp_path / "file" / "gaits"), "--jobs", "1"]) == 2
    assert "file/gaits: cannot write gaits there" in capsys.readouterr().err
    again = robots["quadruped"].parent / ".." / "quadruped" / "robot.xml"  # the same file
    with pytest.raises(RobovaeError, match=f"would both write {again.parent / GAIT_FILE}"):
        tune_gaits([q, again])
    with pytest.raises(RobovaeError, match="no robot files given"):
        tune_gaits([])
    for bad in ({"refine": -1}, {"starts": 2}, {"hold": 0, "refine": 16}):
        with pytest.raises(ValueError, match="walk_gait: refine must be 0 or more"):
            walk_gait(q, **bad)
