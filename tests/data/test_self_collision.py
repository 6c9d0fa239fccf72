"""Robots that collide with themselves: valid at rest, colliding elsewhere
(robovae.data.self_collision), from the writer and from the procedural generator."""

import mujoco
import numpy as np
import pytest

from robovae.data.procedural import parse_procedural, procedural_graphs
from robovae.data.procedural.robots import ProceduralConfig, procedural_spec
from robovae.data.self_collision import resting_pairs
from robovae.generate.validate import validate_robot
from robovae.generate.writer import write_robot


@pytest.fixture(scope="module")
def humanoid():
    """A procedural humanoid (seed 1): its hips' geometry overlaps the trunk at rest."""
    (graph,) = procedural_graphs(parse_procedural("n=1,seed=1"), "kinematic", jobs=1)
    assert "humanoid" in graph.name
    return graph


def _robot_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> int:
    bodies = model.geom_bodyid[data.contact.geom[:data.ncon]]
    return int((bodies != 0).all(axis=1).sum())


def test_self_collision_excludes_exactly_the_pairs_touching_at_rest(humanoid, tmp_path):
    res = write_robot(humanoid, tmp_path / "sc", "kinematic", stance=True, self_collision=True)
    assert "self_collision_excludes" in res.rules
    model = mujoco.MjModel.from_xml_path(str(res.robot_path))
    robot = model.geom_bodyid != 0
    assert (model.geom_contype[robot] == 1).all() and (model.geom_conaffinity[robot] == 1).all()
    assert model.nexclude > 0 and resting_pairs(model) == []  # no contact left at rest
    assert validate_robot(res.robot_path).valid
    # the same file without its excludes: the pairs touch at rest, deeper than the validator
    # allows (what self_collision wrote before the excludes)
    spec = mujoco.MjSpec.from_file(str(res.robot_path))
    for e in list(spec.excludes):
        spec.delete(e)
    bare = tmp_path / "bare.xml"
    bare.write_text(spec.to_xml())
    v = validate_robot(bare)
    assert not v.valid and v.reason == "self_penetration"
    assert len(resting_pairs(mujoco.MjModel.from_xml_path(str(bare)))) == model.nexclude


def test_self_colliding_robot_collides_away_from_rest(humanoid, tmp_path):
    """Every pair but the excluded ones collides: posed at random within its joint ranges, the
    robot's limbs meet each other or its trunk."""
    path = write_robot(humanoid, tmp_path / "sc", "kinematic", stance=True,
                       self_collision=True).robot_path
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    hinges = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
    lo, hi = model.jnt_range[hinges].T
    hits = 0
    for _ in range(50):
        data.qpos[:] = model.qpos0
        data.qpos[model.jnt_qposadr[hinges]] = rng.uniform(lo, hi)
        mujoco.mj_fwdPosition(model, data)
        hits += _robot_contacts(model, data) > 0
    assert hits > 0


def test_default_robots_do_not_collide_with_themselves(humanoid, tmp_path):
    res = write_robot(humanoid, tmp_path / "plain", "kinematic", stance=True)
    model = mujoco.MjModel.from_xml_path(str(res.robot_path))
    assert "self_collision_excludes" not in res.rules and model.nexclude == 0
    assert (model.geom_conaffinity[model.geom_bodyid != 0] == 0).all()


@pytest.mark.parametrize("seed", [1, 8, 9])  # two humanoids and a mobile manipulator
def test_procedural_robots_with_self_collision_are_valid(seed, tmp_path):
    path = tmp_path / "robot.xml"
    path.write_text(procedural_spec(seed, config=ProceduralConfig(self_collision=True)).to_xml())
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nexclude > 0 and resting_pairs(model) == []
    assert (model.geom_conaffinity[model.geom_bodyid != 0] == 1).all()
    assert validate_robot(path).valid
    plain = mujoco.MjModel.from_xml_string(procedural_spec(seed).to_xml())
    assert plain.nexclude == 0  # without self-collision nothing is excluded (nothing collides)
