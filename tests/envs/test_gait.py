"""Sinusoidal gaits as robovae/Walk-v0 policies: the walk score's gait replayed to its score."""

from __future__ import annotations

import json

import gymnasium
import numpy as np
import pytest

import robovae.envs
from robovae.data.procedural import procedural_spec
from robovae.design.score import walk_gait, walk_score
from robovae.envs.gait import SinusoidGait, replay
from robovae.errors import RobovaeError


@pytest.fixture(scope="module")
def quadruped(tmp_path_factory):
    path = tmp_path_factory.mktemp("gait") / "quadruped.xml"
    path.write_text(procedural_spec(3, kind="quadruped").to_xml())
    return path


def test_replay_with_frame_skip_one_is_the_walk_score(quadruped, tmp_path):
    g = walk_gait(quadruped)
    assert g["score"] == walk_score(quadruped)["score"] > 0
    assert len(g["amplitude"]) == len(g["phase"]) == len(g["actuators"]) > 0
    (tmp_path / "gait.json").write_text(json.dumps(g))
    gait = SinusoidGait.from_json(tmp_path / "gait.json")
    env = gymnasium.make(robovae.envs.WALK_ID, robot=str(quadruped), frame_skip=1,
                         reset_noise_scale=0.0)
    r = replay(env, gait, g["seconds"])
    assert len(r.time) == round(g["seconds"] / env.unwrapped.dt)
    # this gait tips the quadruped past 60 degrees after about 1.1 s: the replay finds the
    # score's fall at its 10 ms sample (root poses of the states, not the lagging xpos)
    assert r.upright.min() < 0.5
    assert r.speed(g["settle"], g["max_tilt"]) / g["extent"] == pytest.approx(g["score"],
                                                                              rel=1e-9)
    assert r.speed(g["settle"], max_tilt=0.0) == 0.0  # fallen from the first sample
    # a policy's view: actions held for 5 steps, noise on the start; still deterministic
    env5 = gymnasium.make(robovae.envs.WALK_ID, robot=str(quadruped))
    a, b = replay(env5, gait, 1.0, seed=3), replay(env5, gait, 1.0, seed=3)
    assert np.array_equal(a.root, b.root) and a.episode_return == b.episode_return
    assert gait(0.0) == pytest.approx(gait.amplitude * np.sin(gait.phase))
    assert g["offset"] == [0.0] * len(g["amplitude"])  # no wheels


def test_a_wheeled_robots_gait_replays_to_its_score(tmp_path) -> None:
    """A mobile manipulator's drive wheels get offsets; its gait.json replayed in Walk-v0
    moves it as the score measured (up to rounding: the environment scales the clipped action
    rather than clipping the scaled one)."""
    path = tmp_path / "mobile.xml"
    path.write_text(procedural_spec(0, kind="mobile_manipulator").to_xml())
    g = walk_gait(path)
    assert g["score"] > 0 and any(g["offset"]) and g["power"] > 0 and g["mass"] > 0
    (tmp_path / "gait.json").write_text(json.dumps(g))
    env = gymnasium.make(robovae.envs.WALK_ID, robot=str(path), frame_skip=1,
                         reset_noise_scale=0.0)
    r = replay(env, SinusoidGait.from_json(tmp_path / "gait.json"), g["seconds"])
    assert r.speed(g["settle"], g["max_tilt"]) / g["extent"] == pytest.approx(g["score"],
                                                                              rel=1e-6)


def test_a_gait_with_an_offset_is_clipped_and_read_back(tmp_path) -> None:
    wheel = SinusoidGait(0.5, np.array([0.5, 1.0]), np.zeros(2), np.array([0.8, 0.0]))
    assert wheel(1.0).tolist() == pytest.approx([0.8, 0.0], abs=1e-12)  # sin(pi) = 0
    assert wheel(0.5).tolist() == pytest.approx([1.0, 1.0])  # 0.8 + 0.5 clipped
    (tmp_path / "g.json").write_text(json.dumps(
        {"frequency": 0.5, "amplitude": [0.5, 1.0], "phase": [0, 0], "offset": [0.8, 0]}))
    assert SinusoidGait.from_json(tmp_path / "g.json")(0.5).tolist() == pytest.approx([1, 1])
    # a gait file of an earlier score version (no offsets) replays with none
    (tmp_path / "old.json").write_text(json.dumps(
        {"frequency": 0.5, "amplitude": [0.5, 1.0], "phase": [0, 0]}))
    assert not SinusoidGait.from_json(tmp_path / "old.json").offset.any()
    (tmp_path / "bad.json").write_text(json.dumps(
        {"frequency": 0.5, "amplitude": [0.5, 1.0], "phase": [0, 0], "offset": [1]}))
    with pytest.raises(RobovaeError, match="bad.json: no gait"):
        SinusoidGait.from_json(tmp_path / "bad.json")


def test_bad_gaits_are_refused_in_one_line(quadruped, tmp_path):
    junk = tmp_path / "junk.json"
    junk.write_text("{not json")
    with pytest.raises(RobovaeError, match="junk.json: not a gait file") as e:
        SinusoidGait.from_json(junk)
    assert "\n" not in str(e.value)
    still = tmp_path / "still.json"
    still.write_text(json.dumps({"frequency": None, "amplitude": [], "phase": []}))
    with pytest.raises(RobovaeError, match="still.json: no gait"):
        SinusoidGait.from_json(still)
    env = gymnasium.make(robovae.envs.WALK_ID, robot=str(quadruped))
    with pytest.raises(RobovaeError, match="the gait drives 2 actuators, the robot has"):
        replay(env, SinusoidGait(1.0, np.ones(2), np.zeros(2)), 1.0)
    # accepted until 2026-11-29: NaN controls (MuJoCo's instability warning), one step for a
    # negative duration, a traceback for NaN
    nan = tmp_path / "nan.json"
    nan.write_text('{"frequency": NaN, "amplitude": [1.0], "phase": [0.0]}')
    with pytest.raises(RobovaeError, match="nan.json: not a gait file .robovae: SinusoidGait."
                                           "frequency must be a number >= 0, got nan"):
        SinusoidGait.from_json(nan)
    with pytest.raises(ValueError, match="must be finite vectors of one length"):
        SinusoidGait(1.0, np.array([1.0, np.inf]), np.zeros(2))
    nu = env.unwrapped.model.nu
    for seconds in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="replay.seconds must be a number > 0"):
            replay(env, SinusoidGait(1.0, np.ones(nu), np.zeros(nu)), seconds)
