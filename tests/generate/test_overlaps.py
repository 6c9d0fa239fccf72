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
from robovae.generate.overlaps import clear_limbs
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


def test_arms_hung_through_the_chest_slide_back_out_mirrored():
    """Inside one limb: a procedural humanoid's arms mounted 8 cm nearer the plane on its
    chest pass through the torso's other parts; the arms, not the spine or legs, slide out."""
    graph = model_to_graph(procedural_spec(900003, "humanoid").compile(), FS)
    model = graph_to_spec(graph, FS, stance=True)[0].compile()
    data = at_qpos0(model)
    root = robot_root(model)[0]
    y = np.abs(data.xpos[:, 1] - data.xpos[root, 1])
    arms = [model.body(b).name for b in range(1, model.nbody)
            if model.body_parentid[b] not in (0, root) and y[model.body_parentid[b]] < 0.02
            and y[b] > 0.02]
    assert len(arms) == 2
    x = graph.x.clone()
    col = FS.slice("link.pos").start + 1
    for name in arms:
        i = int(name.removeprefix("link"))
        x[i, col] -= float(np.sign(x[i, col])) * 0.08
    narrow = graph.clone()
    narrow.x = x
    before = graph_to_spec(narrow, FS)[0].compile()
    assert attachment(before).off_joint_pairs > 0
    slides = clear_limbs(before, robot_root(before)[0])
    assert set(slides) == set(arms)
    a, b = (slides[name] for name in arms)
    assert np.allclose(a * [1, -1, 1], b, atol=1e-9)  # mirrored ...
    side = np.sign(graph.x[int(arms[0].removeprefix("link")), col])
    assert a[1] * side > 0.02  # ... and back out
    spec, rules = graph_to_spec(narrow, FS, stance=True)
    assert "clear_limbs" in rules
    after = attachment(spec.compile())
    assert after.off_joint_pairs == 0 and after.all_attached


@pytest.mark.parametrize("kind", ["humanoid", "hexapod", "biped"])
def test_robots_without_overlaps_are_left_as_they_are(kind):
    model = procedural_spec(3, kind).compile()
    assert attachment(model).off_joint_pairs == 0
    data = at_qpos0(model)
    xpos = data.geom_xpos.copy()
    assert clear_limbs(model, robot_root(model)[0], data) == {}
    assert np.array_equal(data.geom_xpos, xpos)
