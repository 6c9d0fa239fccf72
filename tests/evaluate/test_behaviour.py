"""Tests for the MuJoCo behaviour measures (robovae.evaluate.behaviour) on real robots."""

from __future__ import annotations

import math

import mujoco
import pytest

from robovae.data.procedural import ProceduralConfig, procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.behaviour import (
    behaviour,
    behaviour_many,
    prepare,
    standing_test,
    state_entropy,
    summarize_behaviour,
)

ZOO = dict(zoo_files()[0])
#: motors a thousand times too weak to move the robot or hold it up
WEAK = ProceduralConfig(gear=(0.001, 0.002))
FAST = {"seconds": 1.0, "rollouts": 4}


def quadruped(weak: bool = False) -> mujoco.MjSpec:
    # seed 3: without torque its legs fold (seed 2's rest on their joint limits at 0.57 height)
    return procedural_spec(3, "quadruped", WEAK if weak else None)


def test_prepare_adds_a_floor_under_a_robot_without_one() -> None:
    spec, scene = prepare(quadruped())
    assert scene.free
    assert any(g.name == "robovae_floor" for g in spec.worldbody.geoms)
    # the procedural robot starts `clearance` (0.02 m) above z = 0: the floor goes under it
    assert scene.floor_z == pytest.approx(0.02, abs=1e-6)
    spec, scene = prepare(ZOO["gym_ant"])  # has its own floor at z = 0
    assert not any(g.name == "robovae_floor" for g in spec.worldbody.geoms)
    assert scene.floor_z == 0.0 and scene.free
    assert not prepare(ZOO["gym_half_cheetah"])[1].free  # planar: slide/hinge root


def test_state_entropy_of_a_robot_that_cannot_move_is_lower() -> None:
    strong = state_entropy(quadruped(), **FAST)
    weak = state_entropy(quadruped(weak=True), **FAST)
    for r in (strong, weak):
        assert r["actuators"] == r["joints"] > 0
        assert r["points"] == 4 * 20 and r["unstable"] == 0 and r["root_dims"] == 3
        assert r["seconds"] == pytest.approx(1.0)
    assert weak["root_entropy"] < strong["root_entropy"] - 5
    assert weak["joint_entropy"] < strong["joint_entropy"] - 2
    assert weak["displacement"] < strong["displacement"]
    assert strong["root_entropy_scaled"] == pytest.approx(
        strong["root_entropy"] - 3 * math.log(strong["size"]))


def test_state_entropy_is_deterministic_per_seed() -> None:
    a = state_entropy(ZOO["gym_ant"], seconds=0.5, rollouts=2, seed=0)
    b = state_entropy(ZOO["gym_ant"], seconds=0.5, rollouts=2, seed=0)
    c = state_entropy(ZOO["gym_ant"], seconds=0.5, rollouts=2, seed=1)
    assert a == b
    assert a["root_entropy"] != c["root_entropy"]


def test_state_entropy_of_a_planar_robot_drops_fixed_coordinates() -> None:
    r = state_entropy(ZOO["gym_half_cheetah"], **FAST)
    assert r["root_dims"] == 2  # the root moves in x and z, never in y
    assert math.isfinite(r["root_entropy"])


def test_state_entropy_without_actuators_is_nan() -> None:
    r = state_entropy(procedural_spec(0, "quadruped", ProceduralConfig(actuators=False)), **FAST)
    assert r["actuators"] == 0 and r["points"] == 0
    assert math.isnan(r["root_entropy"]) and math.isnan(r["joint_entropy"])


def test_max_steps_shortens_episodes() -> None:
    r = state_entropy(ZOO["gym_ant"], seconds=3.0, rollouts=2, max_steps=100)  # dt 0.01
    assert r["seconds"] == pytest.approx(0.5)
    assert r["points"] == 2 * 10


def test_quadruped_stands_and_weak_quadruped_falls() -> None:
    st = standing_test(quadruped())
    assert st["floating"] and st["stands"] and st["up"] and st["upright"]
    assert st["fell_at"] is None and not st["unstable"]
    assert st["height_ratio"] >= 0.5 and st["max_tilt"] <= 45
    assert st["limited_joints"] == 12 and 1.0 <= st["stand_seconds"] <= 3.0
    weak = standing_test(quadruped(weak=True))
    assert weak["floating"] and weak["stands"] is False
    assert weak["fell_at"] is not None and 0 < weak["fell_at"] <= 3.0
    assert weak["min_height_ratio"] < 0.5  # the legs fold under the torso
    # without the robot's own torque limits the same weak robot is held up
    held = standing_test(quadruped(weak=True), limit_torques=False)
    assert held["stands"] and held["limited_joints"] == 0


def test_dm_control_quadruped_stands_and_gym_humanoid_falls() -> None:
    assert standing_test(ZOO["dmc_quadruped"])["stands"]
    hum = standing_test(ZOO["gym_humanoid"])  # a stiff statue on small feet topples
    assert hum["stands"] is False and hum["upright"] is False and hum["max_tilt"] > 45


def test_fixed_base_robot_is_not_tested() -> None:
    st = standing_test(ZOO["gym_half_cheetah"])
    assert st["floating"] is False
    assert all(v is None for k, v in st.items() if k != "floating")


def test_behaviour_rows_and_summary(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    kw = {"seconds": 0.5, "rollouts": 2}
    rows = behaviour_many([ZOO["gym_ant"], ZOO["gym_half_cheetah"], bad], jobs=1, entropy=kw)
    assert [r["robot"] for r in rows] == [str(ZOO["gym_ant"]), str(ZOO["gym_half_cheetah"]),
                                         str(bad)]
    ant, cheetah, broken = rows
    assert "error" not in ant and ant["floating"] and ant["stands"]
    assert "error" not in cheetah and cheetah["floating"] is False
    assert "error" in broken and "\n" not in broken["error"]
    s = summarize_behaviour(rows)
    assert s["robots"] == 3 and s["errors"] == 1
    assert s["floating"] == 1 and s["standing"] == 1 and s["standing_rate"] == 1.0
    assert s["root_entropy"] == pytest.approx(
        (ant["root_entropy"] + cheetah["root_entropy"]) / 2)
    one = behaviour(quadruped(weak=True), entropy=kw)
    assert one["robot"] == "proc_quadruped_00003" and one["stands"] is False
    assert math.isnan(summarize_behaviour([])["standing_rate"])


@pytest.mark.parametrize("kw, bad", [
    ({"seconds": -1.0}, "state_entropy.seconds"), ({"rollouts": 0}, "state_entropy.rollouts"),
    ({"hold": float("nan")}, "state_entropy.hold"), ({"sample_dt": 0.0}, "state_entropy.sample_dt"),
    ({"k": 0}, "state_entropy.k"), ({"seed": -1}, "state_entropy seed"),
    ({"max_steps": 0}, "state_entropy.max_steps"),
])
def test_state_entropy_refuses_settings_out_of_range(kw, bad) -> None:
    """Negative seconds measured one step, zero rollouts NaN entropies, a NaN hold a
    traceback: refused in one line, before the robot is loaded."""
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match=bad):
        state_entropy(ZOO["gym_ant"], **kw)


def test_bad_settings_stop_a_population_instead_of_failing_every_robot(tmp_path) -> None:
    """A robot that cannot be measured is a row with ``error``; settings out of range are the
    caller's mistake, the same for every robot, and raise (they were an error row per robot)."""
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match="state_entropy.rollouts"):
        behaviour(ZOO["gym_ant"], entropy={"rollouts": 0})
    with pytest.raises(SettingsError, match="standing.seconds"):
        behaviour_many([ZOO["gym_ant"]], jobs=1, entropy=FAST, standing={"seconds": -1.0})
    with pytest.raises(SettingsError, match="behaviour_many.jobs"):
        behaviour_many([ZOO["gym_ant"]], jobs=-1)
