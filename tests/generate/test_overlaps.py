"""``clear_limbs`` (:mod:`robovae.generate.overlaps`): branches through each other slide apart."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robovae.data.features import get_feature_set
from robovae.data.loading import robot_root
from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.evaluate.quality.attachment import attachment
from robovae.generate import writer
from robovae.generate.overlaps import PASSES, clear_limbs
from robovae.generate.stance import at_qpos0
from robovae.generate.writer import graph_to_spec

FS = get_feature_set("kinematic")


def _high_hips(seed: int, dz: float = 0.09):
    """A procedural humanoid's graph with its legs' mounts ``dz`` m higher on the root (the
    decoder's error of docs/generation.md: hips inside the waist), and the legs' names."""
    graph = model_to_graph(procedural_spec(seed, "humanoid").compile(), FS)
    model = graph_to_spec(graph, FS, stance=True)[0].compile()
    data = at_qpos0(model)
    root = robot_root(model)[0]
    legs = []
    for b in np.flatnonzero(model.body_parentid == root).tolist():
        sub = [b] + [c for c in range(b + 1, model.nbody) if model.body_rootid[c] == root
                     and _below(model, c, b)]
        if data.xpos[sub].mean(0)[2] < data.xpos[b][2] - 0.05:
            legs.append(model.body(b).name)
    x = graph.x.clone()
    for name in legs:
        x[int(name.removeprefix("link")), FS.slice("link.pos").start + 2] += dz
    high = graph.clone()
    high.x = x
    return high, legs


def _below(model: mujoco.MjModel, body: int, top: int) -> bool:
    while body > top:
        body = int(model.body_parentid[body])
    return body == top


@pytest.mark.parametrize("seed", [900000, 900007])
def test_legs_mounted_inside_the_waist_slide_down_and_out_of_it(seed):
    high, legs = _high_hips(seed)
    assert len(legs) == 2
    spec, rules = graph_to_spec(high, FS, stance=True)
    before = graph_to_spec(high, FS)[0].compile()  # no stance rules
    assert attachment(before).off_joint_pairs > 0
    slides = clear_limbs(before, robot_root(before)[0])
    assert set(slides) == set(legs)  # the legs move, not the waist
    a, b = (slides[name] for name in legs)
    assert a[2] < 0 and np.allclose(a * [1, -1, 1], b, atol=1e-9)  # down, mirrored
    assert "clear_limbs" in rules
    after = attachment(spec.compile())
    assert after.off_joint_pairs == 0 and after.all_attached


def _narrow_arms(seed: int, dy: float):
    """A procedural humanoid's graph with its arms mounted ``dy`` m nearer the sagittal plane
    on its chest (the arms hang through the torso's other parts), the arms' names and the
    sides (signs of their mounts' y on the chest) they were on."""
    graph = model_to_graph(procedural_spec(seed, "humanoid").compile(), FS)
    model = graph_to_spec(graph, FS, stance=True)[0].compile()
    data = at_qpos0(model)
    root = robot_root(model)[0]
    y = np.abs(data.xpos[:, 1] - data.xpos[root, 1])
    arms = [model.body(b).name for b in range(1, model.nbody)
            if model.body_parentid[b] not in (0, root) and y[model.body_parentid[b]] < 0.02
            and y[b] > 0.02]
    x = graph.x.clone()
    col = FS.slice("link.pos").start + 1
    for name in arms:
        i = int(name.removeprefix("link"))
        x[i, col] -= float(np.sign(x[i, col])) * dy
    narrow = graph.clone()
    narrow.x = x
    return narrow, arms, [float(np.sign(graph.x[int(n.removeprefix("link")), col])) for n in arms]


def test_arms_hung_through_the_chest_slide_back_out_mirrored():
    """Inside one limb: the arms, not the spine or legs, slide back out, mirrored."""
    narrow, arms, sides = _narrow_arms(900003, 0.08)
    assert len(arms) == 2
    before = graph_to_spec(narrow, FS)[0].compile()
    assert attachment(before).off_joint_pairs > 0
    slides = clear_limbs(before, robot_root(before)[0])
    assert set(slides) == set(arms)
    a, b = (slides[name] for name in arms)
    assert np.allclose(a * [1, -1, 1], b, atol=1e-9)  # mirrored ...
    assert a[1] * sides[0] > 0.02  # ... and back out
    spec, rules = graph_to_spec(narrow, FS, stance=True)
    assert "clear_limbs" in rules
    after = attachment(spec.compile())
    assert after.off_joint_pairs == 0 and after.all_attached


def test_a_second_pass_clears_what_the_robot_built_again_still_overlaps(monkeypatch):
    """Arms 10 cm too near the plane: one pass of the rule leaves two overlaps in the robot
    built again, the writer's further passes (on that robot) none."""
    narrow, arms, _ = _narrow_arms(900001, 0.10)
    assert len(arms) == 2
    left = []
    for passes in (1, PASSES):
        monkeypatch.setattr(writer, "PASSES", passes)
        spec, rules = graph_to_spec(narrow, FS, stance=True)
        assert "clear_limbs" in rules
        result = attachment(spec.compile())
        assert result.all_attached
        left.append(result.off_joint_pairs)
    assert left[0] > 0 and left[1] == 0


@pytest.mark.parametrize("kind", ["humanoid", "hexapod", "biped"])
def test_robots_without_overlaps_are_left_as_they_are(kind):
    model = procedural_spec(3, kind).compile()
    assert attachment(model).off_joint_pairs == 0
    data = at_qpos0(model)
    xpos = data.geom_xpos.copy()
    assert clear_limbs(model, robot_root(model)[0], data) == {}
    assert np.array_equal(data.geom_xpos, xpos)


@pytest.mark.parametrize("seed", [900005, 900021])
def test_a_fixed_base_arms_gripper_fingers_through_each_other_slide_apart(seed):
    """Fixed bases get the rule too, though no stance rule: the two fingers a procedural arm's
    graph is written with through each other slide apart, mirrored."""
    graph = model_to_graph(procedural_spec(seed, "arm").compile(), FS)
    before = graph_to_spec(graph, FS)[0].compile()
    root = robot_root(before)[0]
    assert before.body_jntnum[root] == 0 and before.body_parentid[root] == 0  # welded
    assert attachment(before).off_joint_pairs > 0
    slides = clear_limbs(before, root)
    assert len(slides) == 2
    a, b = slides.values()
    assert np.allclose(a * [1, -1, 1], b, atol=1e-9)
    parents = {int(before.body_parentid[before.body(name).id]) for name in slides}
    assert len(parents) == 1  # the fingers: two branches of the gripper's body
    spec, rules = graph_to_spec(graph, FS, stance=True)
    assert "clear_limbs" in rules
    after = spec.compile()
    assert after.body_jntnum[robot_root(after)[0]] == 0  # still welded: no free joint added
    result = attachment(after)
    assert result.off_joint_pairs == 0 and result.all_attached
