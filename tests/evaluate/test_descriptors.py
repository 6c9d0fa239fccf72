"""Descriptors of one robot (robovae.evaluate.descriptors) on real and procedural robots."""

from __future__ import annotations

import math

import mujoco
import pytest

from robovae.data.mjcf import mjcf_to_graph, model_to_graph
from robovae.data.procedural import procedural_plan, procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.descriptors import descriptors, limb_lengths, robot_category

ZOO = dict(zoo_files()[0])


def proc_graph(seed: int, kind: str):
    """The ``paper34`` graph of procedural robot ``seed`` of ``kind``."""
    spec = procedural_spec(seed, kind)
    return model_to_graph(spec.compile(), "paper34", name=spec.modelname)


# ----------------------------------------------------------------------------------------------
# descriptors


@pytest.mark.parametrize("fs", ["paper34", "full"])
def test_ant_descriptors_by_hand(fs: str) -> None:
    """gymnasium ant: torso + 4 legs x (leg, aux, foot) bodies; free joint + 8 hinges."""
    d = descriptors(mjcf_to_graph(ZOO["gym_ant"], fs))
    model = mujoco.MjModel.from_xml_path(str(ZOO["gym_ant"]))
    assert d["name"] == "ant"
    assert d["links"] == 13 == model.nbody - 1
    assert d["joints"] == 9 == model.njnt
    assert d["limbs"] == 4
    assert d["dof"] == 14 == model.nv
    if fs == "paper34":  # free joint -> torso -> leg -> hip -> aux -> ankle -> foot
        assert d["depth"] == 6
    assert d["mass"] == pytest.approx(mujoco.mj_getTotalmass(model), rel=1e-6)
    assert d["mass"] == pytest.approx(model.body_subtreemass[1], rel=1e-6)
    # a limb: aux offset 0.2·√2 + foot offset 0.2·√2 + foot capsule length 0.4·√2
    limb = 0.8 * math.sqrt(2.0)
    assert limb_lengths(mjcf_to_graph(ZOO["gym_ant"], fs)) == pytest.approx([limb] * 4, rel=1e-5)
    assert d["limb_length"] == pytest.approx(limb, rel=1e-5)
    assert d["limb_ratio"] == pytest.approx(1.0)
    assert d["leg_body_ratio"] == pytest.approx(limb / 0.5, rel=1e-5)  # torso sphere r = 0.25


def test_descriptors_of_procedural_robots_follow_the_plan() -> None:
    for seed in range(5):
        plan = procedural_plan(seed, "quadruped")
        spec = procedural_spec(seed, "quadruped")
        model = spec.compile()
        d = descriptors(model_to_graph(model, "paper34"))
        assert d["links"] == 1 + plan.num_segments
        assert d["joints"] == 1 + plan.num_hinges
        assert d["dof"] == 6 + plan.num_hinges == model.nv
        assert d["limbs"] == 4
        assert d["mass"] == pytest.approx(mujoco.mj_getTotalmass(model), rel=1e-5)
        assert 0 < d["limb_ratio"] <= 1.0


def test_planar_robot_has_no_free_dof_and_one_limb_has_nan_ratio() -> None:
    d = descriptors(mjcf_to_graph(ZOO["gym_hopper"]))
    model = mujoco.MjModel.from_xml_path(str(ZOO["gym_hopper"]))
    assert d["dof"] == model.nv  # 3 root slides/hinge + 3 hinges, no free joint
    assert d["limbs"] == 1
    assert math.isnan(d["limb_ratio"])


def test_robot_category() -> None:
    assert robot_category("gym_ant") == "quadruped"
    assert robot_category("dmc_humanoid") == "humanoid"
    assert robot_category("gym_half_cheetah") == "other"  # zoo planar robot
    assert robot_category("unitree_go2") == "quadruped"
    assert robot_category("unitree_h1") == "humanoid"
    assert robot_category("franka_panda") == "arm"
    # from the structure alone (no name)
    assert robot_category("", mjcf_to_graph(ZOO["gym_ant"])) == "quadruped"
    # a procedural humanoid whose arms and neck hang on the pelvis (no waist): 4-5 limbs
    def arms_on_pelvis(seed: int) -> bool:
        root = procedural_plan(seed, "humanoid").root
        names = [c.name for c in root.children]
        return root.name == "pelvis" and "left_arm0" in names and not any(
            "sensor" in n for n in names)

    seed = next(s for s in range(100) if arms_on_pelvis(s))
    assert robot_category("", proc_graph(seed, "humanoid")) == "humanoid"
