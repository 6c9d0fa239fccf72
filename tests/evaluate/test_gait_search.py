"""CMA-ES over a robot's open-loop gait (robovae.evaluate.quality.gait_search)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from robovae.data.procedural import procedural_spec
from robovae.evaluate.quality.gait_search import budget_gait, searched_gait
from robovae.evaluate.quality.locomotion import GaitTrials, gait

FAST = {"rollouts": 8, "seconds": 2.0}


def test_the_search_starts_from_the_random_gaits_and_goes_faster() -> None:
    """The same seed gives the same first rollouts as the random search, so the searched
    speed is never lower; tuning the gait to the body makes a quadruped faster."""
    drawn = gait(procedural_spec(2, "quadruped"), **FAST)
    searched = searched_gait(procedural_spec(2, "quadruped"), refine=32, **FAST)
    again = searched_gait(procedural_spec(2, "quadruped"), refine=32, **FAST)
    none = searched_gait(procedural_spec(2, "quadruped"), refine=0, **FAST)
    assert searched.speed > 1.2 * drawn.speed and searched.rollouts == 8 + 32
    assert again.speed == searched.speed and np.array_equal(again.phase, searched.phase)
    assert none.speed == drawn.speed and none.frequency == drawn.frequency
    assert 0.5 <= searched.frequency <= 3.0 and np.all((searched.amplitude >= 0)
                                                       & (searched.amplitude <= 1))
    assert np.all((searched.phase >= 0) & (searched.phase < 2 * math.pi))
    assert searched.power > 0 and searched.speed == pytest.approx(searched.speed_m_s
                                                                  / searched.extent)


def test_the_searched_gait_replays_at_its_speed() -> None:
    """The gait returned is a gait: rolled out again, it covers the reported distance."""
    r = searched_gait(procedural_spec(5, "quadruped"), refine=32, **FAST)
    trials = GaitTrials(procedural_spec(5, "quadruped"), seconds=2.0)
    speeds, _, _ = trials.run(r.amplitude[None], r.phase[None], np.array([r.frequency]),
                              r.offset[None])
    assert speeds[0] == pytest.approx(r.speed_m_s, rel=1e-9)


def test_a_robot_without_actuators_has_no_gait_to_search() -> None:
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="box", pos=[0, 0, 0.2])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.1, 0.1])
    r = searched_gait(spec, refine=32, **FAST)
    assert r.speed == 0.0 and math.isnan(r.frequency) and r.rollouts == 40


@pytest.mark.parametrize("bad", [{"rollouts": 0}, {"refine": -1}, {"population": 1},
                                 {"step": 0.0}, {"frequency": (1.0, 1.0)},
                                 {"frequency": (0.0, 2.0)}, {"frequency": (1.0, math.inf)},
                                 {"seed": -1}])
def test_bad_search_settings_are_refused(bad: dict) -> None:
    with pytest.raises(ValueError, match="searched_gait|gait seed"):
        searched_gait(procedural_spec(2, "quadruped"), **{**FAST, **bad})


@pytest.mark.parametrize("bad, message", [
    # each scored 0.0 without a word, or a NumPy traceback, until 2026-11-29
    ({"rollouts": 0}, "gait.rollouts must be an integer >= 1, got 0"),
    ({"seconds": 0.0}, "GaitTrials.seconds must be a number > 0, got 0.0"),
    ({"seconds": math.nan}, "GaitTrials.seconds must be a number > 0, got nan"),
    ({"seed": -1}, r"gait seed must be an integer in \[0, 2147483647\], not -1"),
    ({"frequency": (3.0, 0.5)}, "gait.frequency must be a range"),
    ({"settle": 1.0}, r"GaitTrials.settle must be a number in \[0, 1\)"),
    ({"max_tilt": -5.0}, "GaitTrials.max_tilt must be a number in"),
])
def test_bad_gait_settings_are_refused(bad: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message) as e:
        gait(procedural_spec(2, "quadruped"), **{"rollouts": 2, "seconds": 0.5, **bad})
    assert "\n" not in str(e.value)


def test_a_budget_is_spent_by_random_gaits_or_by_a_quarter_of_them_tuned() -> None:
    """``budget_gait``: ``random`` is the random search; ``cma`` draws a quarter of the
    budget at random (the random search's first gaits) and tunes in generations of 16, never
    past the budget."""
    quad = procedural_spec(2, "quadruped")
    drawn = gait(quad, rollouts=40, seconds=2.0)
    same = budget_gait(quad, "random", rollouts=40, seconds=2.0)
    assert same.speed == drawn.speed and same.rollouts == 40
    tuned = budget_gait(quad, "cma", rollouts=40, seconds=2.0)
    assert tuned.rollouts == 10 + 16 * 1  # 30 left: one generation, 14 unspent
    assert tuned.speed >= gait(quad, rollouts=10, seconds=2.0).speed
    assert tuned.speed == searched_gait(quad, rollouts=10, refine=30, seconds=2.0).speed
    few = budget_gait(quad, "cma", rollouts=3, seconds=2.0)
    assert few.rollouts == 1 and few.speed == gait(quad, rollouts=1, seconds=2.0).speed
    for bad in ({"search": "grid"}, {"rollouts": 0}):
        with pytest.raises(ValueError, match="budget_gait"):
            budget_gait(quad, **{"seconds": 2.0, **bad})


def test_gaits_held_and_from_noisy_starts_score_the_median_over_the_starts() -> None:
    """``hold`` holds each control for that many physics steps; after ``perturb`` a gait's
    speed is the median of its speeds from each start, the first start the rest state and
    the others it with noise on the given coordinates only; the search judges every gait so."""
    robot = procedural_spec(2, "quadruped")
    plain, held = GaitTrials(robot, seconds=2.0), GaitTrials(robot, seconds=2.0, hold=5)
    nu = held.model.nu
    amp, phase, freq, offset = (np.random.default_rng(4).uniform(0, 1, (3, nu)),
                                np.random.default_rng(5).uniform(0, 6, (3, nu)),
                                np.array([1.0, 1.5, 2.0]), np.zeros((3, nu)))
    assert held.run(amp, phase, freq, offset)[0].tolist() != \
        plain.run(amp, phase, freq, offset)[0].tolist()
    qpos, qvel = np.arange(7, held.model.nq), np.arange(6, held.model.nv)  # the legs' joints
    held.perturb(qpos, qvel, 3, 0.05, seed=0)
    s0 = held.state0
    assert held.starts.shape == (3, len(s0)) and np.array_equal(held.starts[0], s0)
    changed = np.flatnonzero(held.starts[1] != s0)  # state: time, qpos, qvel, ...
    assert set(changed) <= {1 + i for i in qpos} | {1 + held.model.nq + i for i in qvel}
    assert len(changed) == len(qpos) + len(qvel)
    speeds, _, (states, _, _) = held.run(amp, phase, freq, offset)
    each = []
    for start in held.starts:
        one = GaitTrials(robot, seconds=2.0, hold=5)
        one.starts = start[None]
        each.append(one.run(amp, phase, freq, offset)[0])
    assert speeds == pytest.approx(np.median(each, axis=0), rel=1e-12)
    b = int(np.argmax(speeds))  # its rollout reported for the power: from the rest state
    first = GaitTrials(robot, seconds=2.0, hold=5)
    assert np.array_equal(states, first.run(amp[b:b + 1], phase[b:b + 1], freq[b:b + 1],
                                            offset[b:b + 1])[2][0])
    again = GaitTrials(robot, seconds=2.0, hold=5)
    again.perturb(qpos, qvel, 3, 0.05, seed=0)
    assert np.array_equal(again.starts, held.starts)
    with pytest.raises(ValueError, match="hold must be an integer >= 1"):
        GaitTrials(robot, hold=0)
    with pytest.raises(ValueError, match="count must be at least 1"):
        held.perturb(qpos, qvel, 0, 0.05, seed=0)
