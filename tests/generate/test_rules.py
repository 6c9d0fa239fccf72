"""Physical-constraint rules (paper §6.1, SPEC §7): each fires on a crafted violation, leaves
valid data unchanged, never fires on real robots, and turns garbage into compilable robots."""

from __future__ import annotations

import math
import os
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import torch

from robovae.data.features import GEOM, JOINT, JOINT_TYPES, LINK, get_feature_set
from robovae.data.graph import RobotData, tree_data
from robovae.data.mjcf import mjcf_to_graph, model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.data.zoo import zoo_files
from robovae.generate.bodies import joint_types, link_structure
from robovae.generate.rules import (
    RULES,
    apply_rules,
    check_rules,
    floating_base,
    slide_limited,
)
from robovae.generate.rules_geometry import DEFAULT_GEOM_RADIUS, GEOM_SIZE_COMPONENTS, MIN_SIZE
from robovae.generate.rules_joints import HINGE_LIMIT, MIN_RANGE_WIDTH, SLIDE_STROKE
from robovae.generate.rules_mass import MIN_INERTIA, MIN_MASS
from robovae.generate.writer import graph_to_spec
from tests.conftest import random_tree

SETS = ("paper34", "full")
REPO = Path(__file__).resolve().parents[2]
MENAGERIE = Path(os.environ.get("ROBOVAE_SHARED_MENAGERIE", REPO.parent / "shared" / "menagerie"))


# --- data ------------------------------------------------------------------------------------


@cache
def _quadruped(fs: str) -> RobotData:
    """A valid procedural quadruped (free joint, 4 limbs, 1-2 hinges per segment, geoms)."""
    return model_to_graph(procedural_spec(0, "quadruped").compile(), fs, name="quadruped")


def quadruped(fs: str) -> RobotData:
    return _quadruped(fs).clone()


@cache
def real_graph(path: str, fs: str) -> RobotData:
    return mjcf_to_graph(path, fs)


def real_robots() -> list[tuple[str, str]]:
    files = [(name, str(path)) for name, path in zoo_files()[0]]
    files += [(p.parent.name, str(p)) for p in sorted(MENAGERIE.glob("*/*.xml"))]
    return files


def feat(d: RobotData, fs: str, key: str, i: int) -> np.ndarray:
    return d.x[i, get_feature_set(fs).slice(key)].double().numpy()


def put(d: RobotData, fs: str, key: str, i: int, value) -> None:
    d.x[i, get_feature_set(fs).slice(key)] = torch.as_tensor(value, dtype=torch.float32)


def nodes(d: RobotData, t: int) -> list[int]:
    return [i for i, nt in enumerate(d.node_type.tolist()) if nt == t]


def moving_links(d: RobotData) -> list[int]:
    _, chain = link_structure(d.parent.tolist(), d.node_type.tolist())
    return [i for i in nodes(d, LINK) if chain[i]]


def welded_links(d: RobotData) -> list[int]:
    _, chain = link_structure(d.parent.tolist(), d.node_type.tolist())
    return [i for i in nodes(d, LINK) if not chain[i]]


# --- valid data stays valid ------------------------------------------------------------------


@pytest.mark.parametrize("fs", SETS)
@pytest.mark.parametrize("name", list(RULES))
def test_rule_leaves_valid_data_unchanged(name, fs):
    d = quadruped(fs)
    out, fired = RULES[name](d, fs)
    assert not fired
    assert torch.equal(out.x, d.x)
    assert out is not d


@pytest.mark.parametrize("fs", SETS)
def test_real_robots_pass_all_rules_unchanged(fs):
    """Every zoo and Menagerie robot MuJoCo compiles satisfies every rule as is."""
    robots = real_robots()
    if not robots:
        pytest.skip("no zoo or Menagerie robots installed")
    problems = []
    for name, path in robots:
        d = real_graph(path, fs)
        out, fired = apply_rules(d, fs)
        if fired or not torch.equal(out.x, d.x):
            problems.append(f"{name}: {fired}")
    assert not problems, problems


def test_rules_order_and_names():
    assert list(RULES)[0] == "finite" and list(RULES)[-1] == "subtreemass_consistent"
    for key in ("mass_positive", "inertia_positive", "inertia_triangle", "unit_quat",
                "axis_unit", "range_ordered", "nonnegative_dynamics", "size_positive",
                "limb_length", "subtreemass_consistent", "finite"):
        assert key in RULES and RULES[key].__name__ == key


def test_rules_need_a_robot_feature_set():
    d = tree_data([-1, 0], [0, 0], torch.rand(2, 5), "random5")
    with pytest.raises(ValueError, match="robot feature set"):
        apply_rules(d, "random5")
    with pytest.raises(ValueError, match="columns"):
        apply_rules(quadruped("paper34"), "full")


def test_apply_rules_does_not_modify_input():
    d = quadruped("full")
    put(d, "full", "link.mass", 1, -5.0)
    before = d.x.clone()
    out, fired = apply_rules(d, "full")
    assert "mass_positive" in fired
    assert torch.equal(d.x, before) and not torch.equal(out.x, before)


# --- each rule fires on a crafted violation --------------------------------------------------


@pytest.mark.parametrize("fs", SETS)
def test_finite(fs):
    d = quadruped(fs)
    link, joint = nodes(d, LINK)[0], nodes(d, JOINT)[1]
    put(d, fs, "link.mass", link, float("nan"))
    put(d, fs, "link.quat", link, [float("inf"), 0, 0, 0])
    put(d, fs, "joint.axis", joint, [float("nan"), 1, 0])
    out, fired = RULES["finite"](d, fs)
    assert fired and torch.isfinite(out.x).all()
    assert feat(out, fs, "link.quat", link).tolist() == [1, 0, 0, 0]
    assert feat(out, fs, "joint.axis", joint).tolist() == [0, 0, 1]
    assert feat(out, fs, "link.mass", link)[0] == 0
    full, fired_all = apply_rules(d, fs)
    assert fired_all[0] == "finite" and torch.isfinite(full.x).all()


def test_one_hot():
    d = quadruped("full")
    j, g = nodes(d, JOINT)[2], nodes(d, GEOM)[0]
    put(d, "full", "joint.type", j, [0.2, 0.1, 0.7, 0.3])
    put(d, "full", "joint.limited", j, 0.6)
    put(d, "full", "geom.type", g, [0.1, 0.0, 0.0, 0.0, 0.4])
    put(d, "full", "geom.collides", g, 0.2)
    out, fired = RULES["one_hot"](d, "full")
    assert fired
    assert feat(out, "full", "joint.type", j).tolist() == [0, 0, 1, 0]
    assert feat(out, "full", "joint.limited", j).tolist() == [1]
    assert feat(out, "full", "geom.type", g).tolist() == [0, 0, 0, 0, 1]
    assert feat(out, "full", "geom.collides", g).tolist() == [0]


def test_joint_type_valid():
    # dm_control's humanoid: free root, bodies with two and three hinges
    d = real_graph(str(dict(zoo_files()[0])["dmc_humanoid"]), "full").clone()
    free = np.eye(4)[JOINT_TYPES.index("free")]
    ball = np.eye(4)[JOINT_TYPES.index("ball")]
    j = nodes(d, JOINT)[1]
    put(d, "full", "joint.type", j, free)  # a free joint inside a limb
    # a ball joint followed by a hinge in the same body (a two-hinge segment)
    _, chain = link_structure(d.parent.tolist(), d.node_type.tolist())
    two = next(c for c in chain if len(c) == 2)
    put(d, "full", "joint.type", two[0], ball)
    out, fired = RULES["joint_type_valid"](d, "full")
    assert fired
    types = joint_types(out, "full")
    assert types[0] == "free" and types[j] == "hinge" and types[two[0]] == "hinge"
    graph_to_spec(out, "full")  # compiles


def test_in_range():
    d = quadruped("paper34")
    link, joint = nodes(d, LINK)[1], nodes(d, JOINT)[1]
    put(d, "paper34", "link.pos", link, [100.0, -50.0, 0.1])
    put(d, "paper34", "joint.damping", joint, 1e9)
    out, fired = RULES["in_range"](d, "paper34")
    assert fired
    assert feat(out, "paper34", "link.pos", link).tolist() == pytest.approx([10.0, -10.0, 0.1])
    assert feat(out, "paper34", "joint.damping", joint)[0] == 1e4


@pytest.mark.parametrize("fs", SETS)
def test_unit_quat(fs):
    d = quadruped(fs)
    a, b = nodes(d, LINK)[:2]
    put(d, fs, "link.quat", a, [2.0, 0.0, 0.0, 0.0])
    put(d, fs, "link.iquat", b, [0.0, 0.0, 0.0, 0.0])
    if fs == "full":
        put(d, fs, "geom.quat", nodes(d, GEOM)[0], [0.0, 3.0, 4.0, 0.0])
    out, fired = RULES["unit_quat"](d, fs)
    assert fired
    assert feat(out, fs, "link.quat", a).tolist() == [1, 0, 0, 0]
    assert feat(out, fs, "link.iquat", b).tolist() == [1, 0, 0, 0]
    if fs == "full":
        assert feat(out, fs, "geom.quat", nodes(d, GEOM)[0]) == pytest.approx([0, 0.6, 0.8, 0])


def test_axis_unit():
    d = quadruped("paper34")
    a, b = nodes(d, JOINT)[1:3]
    put(d, "paper34", "joint.axis", a, [0.0, 0.0, 0.0])
    put(d, "paper34", "joint.axis", b, [0.0, 3.0, 4.0])
    out, fired = RULES["axis_unit"](d, "paper34")
    assert fired
    assert feat(out, "paper34", "joint.axis", a).tolist() == [0, 0, 1]
    assert feat(out, "paper34", "joint.axis", b) == pytest.approx([0, 0.6, 0.8])


def test_range_ordered_paper34():
    fs = "paper34"
    d = quadruped(fs)
    j = nodes(d, JOINT)[1:6]
    put(d, fs, "joint.range", j[0], [1.0, -0.5])  # swapped
    put(d, fs, "joint.range", j[1], [-20.0, 30.0])  # beyond 2π
    put(d, fs, "joint.range", j[2], [0.4, 0.4])  # empty
    put(d, fs, "joint.range", j[3], [2e-4, -1e-4])  # noise around zero: unlimited
    out, fired = RULES["range_ordered"](d, fs)
    assert fired
    r = [feat(out, fs, "joint.range", i) for i in j]
    assert r[0].tolist() == [-0.5, 1.0]
    assert r[1] == pytest.approx([-HINGE_LIMIT, HINGE_LIMIT])
    assert r[2][1] - r[2][0] >= 0.99 * MIN_RANGE_WIDTH and r[2].mean() == pytest.approx(0.4)
    assert r[3].tolist() == [0.0, 0.0]
    assert feat(out, fs, "joint.range", j[4]).tolist() == feat(d, fs, "joint.range", j[4]).tolist()


def test_range_ordered_full():
    fs = "full"
    d = quadruped(fs)
    j = nodes(d, JOINT)
    put(d, fs, "joint.type", j[1], np.eye(4)[JOINT_TYPES.index("ball")])
    put(d, fs, "joint.range", j[1], [-0.5, 0.3])  # ball: range[0] must be 0
    put(d, fs, "joint.limited", j[2], 0.0)  # unlimited joint keeps no range
    put(d, fs, "joint.range", j[0], [-1.0, 1.0])  # the free joint has no range
    put(d, fs, "joint.limited", j[0], 1.0)
    put(d, fs, "joint.ctrlrange", j[3], [1.0, -1.0])
    out, fired = RULES["range_ordered"](d, fs)
    assert fired
    assert feat(out, fs, "joint.range", j[1]).tolist() == [0.0, 0.5]
    assert feat(out, fs, "joint.range", j[2]).tolist() == [0.0, 0.0]
    assert feat(out, fs, "joint.range", j[0]).tolist() == [0.0, 0.0]
    assert feat(out, fs, "joint.limited", j[0]).tolist() == [0.0]
    assert feat(out, fs, "joint.ctrlrange", j[3]).tolist() == [-1.0, 1.0]


def test_slide_limited_gives_a_decoded_rail_its_ends_but_not_a_root_slide():
    """A fix of decoded graphs, not a rule: an unlimited slide below the trunk (flag 0, or a
    range of zeros) gets ±SLIDE_STROKE, a limited one keeps its range, the trunk's own slides
    (dm_control's cheetah: rootx, rootz) stay unlimited; apply_rules leaves rails alone (a
    slide without limits is valid)."""
    fs = "full"
    d = quadruped(fs)
    j = nodes(d, JOINT)
    slide = np.eye(4)[JOINT_TYPES.index("slide")]
    for i in (j[1], j[2], j[3]):
        put(d, fs, "joint.type", i, slide)
    put(d, fs, "joint.limited", j[1], 0.0)  # a rail without ends, decoded range left over
    put(d, fs, "joint.range", j[2], [-0.02, 0.03])
    put(d, fs, "joint.range", j[3], [0.0, 0.0])  # a rail without ends, flag left over
    assert "slide_limited" not in apply_rules(d, fs)[1] and "slide_limited" not in RULES
    out, changed = slide_limited(d, fs)
    assert changed
    for i in (j[1], j[3]):
        assert feat(out, fs, "joint.range", i) == pytest.approx([-SLIDE_STROKE, SLIDE_STROKE])
        assert feat(out, fs, "joint.limited", i).tolist() == [1.0]
    assert feat(out, fs, "joint.range", j[2]) == pytest.approx([-0.02, 0.03])
    assert not slide_limited(out, fs)[1]  # once is enough
    out, fired = apply_rules(out, fs)
    assert "range_ordered" not in fired  # the fix leaves valid ranges
    model = graph_to_spec(out, fs)[0].compile()
    slides = [k for k in range(model.njnt) if model.jnt_type[k] == 2]
    assert len(slides) == 3 and all(model.jnt_limited[k] for k in slides)
    cheetah = dict(zoo_files()[0]).get("dmc_cheetah")
    if cheetah is not None:  # root slides to the world: left alone
        g = real_graph(str(cheetah), fs)
        assert "slide" in joint_types(g, fs)
        assert not slide_limited(g, fs)[1]


@pytest.mark.parametrize("fs", SETS)
def test_nonnegative_dynamics(fs):
    d = quadruped(fs)
    j = nodes(d, JOINT)[1]
    for key in ("joint.damping", "joint.armature", "joint.frictionloss", "joint.stiffness"):
        put(d, fs, key, j, -2.0)
    if fs == "full":
        put(d, fs, "geom.friction", nodes(d, GEOM)[0], [-1.0, 0.1, -0.1])
    out, fired = RULES["nonnegative_dynamics"](d, fs)
    assert fired
    for key in ("joint.damping", "joint.armature", "joint.frictionloss", "joint.stiffness"):
        assert feat(out, fs, key, j)[0] == 0.0
    if fs == "full":
        assert feat(out, fs, "geom.friction", nodes(d, GEOM)[0]) == pytest.approx([0, 0.1, 0])


def test_mass_positive():
    fs = "paper34"
    d = quadruped(fs)
    moving = moving_links(d)
    put(d, fs, "link.mass", moving[0], -3.0)
    put(d, fs, "link.mass", moving[1], 0.0)
    out, fired = RULES["mass_positive"](d, fs)
    assert fired
    for i in moving[:2]:
        assert feat(out, fs, "link.mass", i)[0] >= MIN_MASS
    # a welded link may be massless, but not negative
    d = tree_data([-1, 0, 1], [LINK, LINK, LINK], torch.zeros(3, 34), fs)
    put(d, fs, "link.mass", 1, -1.0)
    out, fired = RULES["mass_positive"](d, fs)
    assert fired and feat(out, fs, "link.mass", 1)[0] == 0.0


def test_inertia_positive():
    fs = "paper34"
    d = quadruped(fs)
    a, b = moving_links(d)[:2]
    put(d, fs, "link.inertia", a, [0.0, 0.0, 0.0])
    put(d, fs, "link.inertia", b, [-1.0, 0.01, 0.01])
    out, fired = RULES["inertia_positive"](d, fs)
    assert fired
    ia, ib = feat(out, fs, "link.inertia", a), feat(out, fs, "link.inertia", b)
    mass, size = feat(out, fs, "link.mass", a)[0], feat(out, fs, "link.size", a).max()
    assert ia == pytest.approx([0.4 * mass * size**2] * 3, rel=1e-6)  # a solid sphere
    assert ib.min() >= MIN_INERTIA and ib[1:].tolist() == pytest.approx([0.01, 0.01])


@pytest.mark.parametrize("inertia", [[1.0, 1.0, 3.0], [0.0, 0.0, 1.0], [2.0, 0.1, 0.1],
                                     [1e-6, 5.0, 5.1]])
def test_inertia_triangle(inertia):
    fs = "paper34"
    d = quadruped(fs)
    i = moving_links(d)[0]
    put(d, fs, "link.inertia", i, inertia)
    out, fired = RULES["inertia_triangle"](d, fs)
    assert fired
    new, old = feat(out, fs, "link.inertia", i), feat(d, fs, "link.inertia", i)
    a, b, c = sorted(new)
    assert a + b >= c
    assert new.max() == old.max()  # the largest is kept
    assert (new >= old).all()  # the others only grow


def test_size_positive():
    d = quadruped("full")
    link = nodes(d, LINK)[1]
    put(d, "full", "link.size", link, [-0.1, 0.0, 0.2])
    geoms = nodes(d, GEOM)[:2]
    put(d, "full", "geom.type", geoms[0], np.eye(5)[0])  # sphere
    put(d, "full", "geom.size", geoms[0], [0.0, 5.0, -1.0])
    put(d, "full", "geom.type", geoms[1], np.eye(5)[4])  # box
    put(d, "full", "geom.size", geoms[1], [0.1, 1e-9, 0.0])
    out, fired = RULES["size_positive"](d, "full")
    assert fired
    assert feat(out, "full", "link.size", link) == pytest.approx([MIN_SIZE, MIN_SIZE, 0.2])
    assert feat(out, "full", "geom.size", geoms[0]) == pytest.approx([MIN_SIZE, 5.0, 0.0])
    assert feat(out, "full", "geom.size", geoms[1]) == pytest.approx([0.1, MIN_SIZE, MIN_SIZE])
    assert GEOM_SIZE_COMPONENTS["box"] == 3


@pytest.mark.parametrize("size, expect", [
    ([0.0126, 0.038, 0.0003], [0.0126, 0.038, 0.0]),  # decoded "zero" → capsule, not a plate
    ([0.05, 0.0004, 0.0002], [0.05, 0.0, 0.0]),  # → sphere
    ([0.2, 0.1, 0.003], [0.2, 0.1, 0.0]),  # 1.5 % of the largest: absent
    ([0.0003, 0.0, 0.0], [0.0003, 0.0, 0.0]),  # the first component is never dropped
    ([0.02, 0.03, 0.001], [0.02, 0.03, 0.001]),  # a real thin box stays
])
def test_size_positive_drops_decoded_zeros(size, expect):
    d = quadruped("paper34")
    link = nodes(d, LINK)[1]
    put(d, "paper34", "link.size", link, size)
    out, _ = RULES["size_positive"](d, "paper34")
    assert feat(out, "paper34", "link.size", link) == pytest.approx(expect)


@pytest.mark.parametrize("fs", SETS)
def test_limb_length(fs):
    d = quadruped(fs)
    trunk = 1  # node 0 is the free joint
    kids = [i for i, p in enumerate(d.parent.tolist()) if p == trunk and d.node_type[i] != GEOM]
    first, second = kids[0], kids[1]  # the first two limbs
    in_first = [i for i in range(first, second) if d.node_type[i] == LINK]
    for i in in_first:
        put(d, fs, "link.pos", i, [0.0, 0.0, 0.0])
        put(d, fs, "link.ipos", i, [0.0, 0.0, 0.0])
    other = [i for i in range(second, d.num_nodes) if d.node_type[i] == LINK]
    out, fired = RULES["limb_length"](d, fs)
    assert fired
    for i in in_first:
        assert np.linalg.norm(feat(out, fs, "link.pos", i)) > 1e-3
    for i in other:  # other limbs untouched
        assert feat(out, fs, "link.pos", i).tolist() == feat(d, fs, "link.pos", i).tolist()
    # a single link at its parent's origin is fine (URDF dummy links do that), and so is a
    # limb whose bodies sit at the origin but whose masses do not
    d = quadruped(fs)
    put(d, fs, "link.pos", in_first[-1], [0.0, 0.0, 0.0])
    assert not RULES["limb_length"](d, fs)[1]
    for i in in_first:
        put(d, fs, "link.pos", i, [0.0, 0.0, 0.0])
    assert not RULES["limb_length"](d, fs)[1]


def test_subtreemass_consistent():
    fs = "paper34"
    d = quadruped(fs)
    put(d, fs, "link.subtreemass", 1, 123.0)
    out, fired = RULES["subtreemass_consistent"](d, fs)
    assert fired
    masses = sum(feat(d, fs, "link.mass", i)[0] for i in nodes(d, LINK))
    assert feat(out, fs, "link.subtreemass", 1)[0] == pytest.approx(masses, rel=1e-6)
    # changing a mass makes apply_rules recompute the subtree masses
    d = quadruped(fs)
    put(d, fs, "link.mass", nodes(d, LINK)[-1], 50.0)
    assert "subtreemass_consistent" in check_rules(d, fs)


# --- joint types -----------------------------------------------------------------------------


def test_paper34_joint_type_inference():
    d = quadruped("paper34")
    types = joint_types(d, "paper34")
    assert types[0] == "free" and set(types[i] for i in nodes(d, JOINT)[1:]) == {"hinge"}
    d2 = d.clone()
    put(d2, "paper34", "joint.axis", 0, [0.0, 0.0, -1.0])  # a root hinge about -z: no free
    assert joint_types(d2, "paper34")[0] == "hinge"
    d3 = d.clone()
    put(d3, "paper34", "joint.range", 0, [-1.0, 1.0])  # limited: no free
    assert joint_types(d3, "paper34")[0] == "hinge"
    full = joint_types(quadruped("full"), "full")
    assert full[0] == "free" and {full[i] for i in nodes(quadruped("full"), JOINT)[1:]} == {"hinge"}


# --- garbage in, valid robot out -------------------------------------------------------------


@pytest.mark.parametrize("fs", SETS)
def test_random_garbage_becomes_valid(fs):
    """~100 random trees per set: rules make every value physical and are idempotent."""
    rng = np.random.default_rng(7 if fs == "paper34" else 8)
    for _ in range(100):
        d = random_tree(rng, fs, int(rng.integers(1, 30)))
        out, fired = apply_rules(d, fs)
        assert "finite" in fired or torch.isfinite(d.x[d.x_mask]).all()
        assert torch.isfinite(out.x).all()
        assert not check_rules(out, fs), "rules are not idempotent"
        for i in nodes(out, LINK):
            assert feat(out, fs, "link.mass", i)[0] >= 0
            a, b, c = sorted(feat(out, fs, "link.inertia", i))
            assert a >= 0 and a + b >= c
            assert abs(np.linalg.norm(feat(out, fs, "link.quat", i)) - 1) < 1e-4
        for i in moving_links(out):
            assert feat(out, fs, "link.mass", i)[0] >= MIN_MASS
            assert feat(out, fs, "link.inertia", i).min() >= MIN_INERTIA
        for i in nodes(out, JOINT):
            lo, hi = feat(out, fs, "joint.range", i)
            assert lo <= hi and abs(np.linalg.norm(feat(out, fs, "joint.axis", i)) - 1) < 1e-4
            assert max(abs(lo), abs(hi)) <= 1e3
            for key in ("joint.damping", "joint.armature", "joint.frictionloss"):
                assert feat(out, fs, key, i)[0] >= 0


def test_constants_are_consistent():
    assert math.isclose(HINGE_LIMIT, 2 * math.pi)
    assert MIN_SIZE < 1.7e-4 and MIN_MASS < 5e-8 and MIN_INERTIA < 4.9e-14  # below real data
    assert DEFAULT_GEOM_RADIUS > MIN_SIZE


@pytest.mark.parametrize("fs", SETS)
def test_floating_base_frees_a_decoded_root_hinge(fs):
    d = quadruped(fs)
    assert joint_types(d, fs)[0] == "free"
    same, changed = floating_base(d, fs)
    assert not changed and torch.equal(same.x, d.x)  # a real free root is left alone
    put(d, fs, "joint.range", 0, [-0.38, 0.49])  # what a decoder makes of a root joint
    put(d, fs, "joint.axis", 0, [0.3, 0.33, 0.22])
    if fs == "full":
        put(d, fs, "joint.type", 0, np.eye(len(JOINT_TYPES))[JOINT_TYPES.index("hinge")])
    assert joint_types(d, fs)[0] == "hinge"
    out, changed = floating_base(d, fs)
    assert changed and joint_types(out, fs)[0] == "free"
    assert feat(out, fs, "joint.range", 0) == pytest.approx([0.0, 0.0])
    assert torch.equal(out.x[1:], d.x[1:])  # nothing else changes
    spec = graph_to_spec(out, fs)[0]
    assert spec.compile().jnt_type[0] == 0  # mjJNT_FREE


def test_floating_base_leaves_planar_roots_and_welded_bases():
    zoo = dict(zoo_files()[0])
    for name in ["gym_half_cheetah", "gym_hopper"]:  # rootx, rootz, rooty: three root joints
        d = real_graph(str(zoo[name]), "paper34")
        assert floating_base(d, "paper34") == (d, False)
