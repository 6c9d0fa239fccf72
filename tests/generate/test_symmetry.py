"""Paired limbs: the symmetry measure and the mirror of a decoded side (issue 21 item 2)."""

from __future__ import annotations

from functools import cache

import mujoco
import numpy as np
import pytest
import torch

from robovae.data.features import LINK, get_feature_set
from robovae.data.loading import load_robot
from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.data.tree_arrays import TreeArrays
from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.symmetry import anatomy
from robovae.generate.fixes import decoded_fixes
from robovae.generate.graph_view import GraphView
from robovae.generate.symmetry import (
    ATTACH_TOL,
    CLEAR_TOL,
    RING_TOL,
    STRAY_TOL,
    complete_pairs,
    is_symmetric,
    limbs,
    mirror_limbs,
    mirrored_pairs,
    twin_limbs,
)
from robovae.generate.writer import graph_to_spec

FS = get_feature_set("paper34")
ZOO = dict(zoo_files()[0])


@cache
def _hexapod():
    """Procedural hexapod (six legs at (x, ±y, 0)) whose legs are all made unequal, as a
    decoder would give them: leg ``j``'s links ``1.25^j`` times heavier (near-mirror
    pairs, no mirror images; every leg differs from every other by more than 10 %)."""
    g = model_to_graph(procedural_spec(1, "hexapod").compile(), "paper34", name="hexapod")
    v = GraphView(g, FS)
    mass = FS.columns.index("link.mass")
    for j, root in enumerate(limbs(v)[1]):
        for n in _subtree_links(v, root):
            g.x[n, mass] *= 1.25 ** j
    return g


def _subtree_links(v: GraphView, root: int) -> list[int]:
    out, stack = [], [root]
    while stack:
        n = stack.pop()
        out.append(n)
        stack.extend(reversed(v.kids[n]))
    return [n for n in out if v.types[n] == LINK]


@pytest.mark.parametrize(("name", "symmetric"), [("gym_ant", True), ("gym_humanoid", True),
                                                 ("dmc_quadruped", True), ("gym_hopper", False),
                                                 ("gym_half_cheetah", False)])
def test_symmetry_of_zoo_robots(name, symmetric):
    g = model_to_graph(load_robot(ZOO[name]).model, "paper34")
    assert is_symmetric(g) is symmetric


def test_mirror_makes_left_and_right_legs_mirror_images():
    g = _hexapod()
    assert mirrored_pairs(g) == (0, 6)
    out, changed = mirror_limbs(g)
    assert changed and mirrored_pairs(out) == (3, 6) and is_symmetric(out)
    v0, v1 = GraphView(g, FS), GraphView(out, FS)
    for k in range(0, 6, 2):  # the first (left) legs are kept as decoded
        a, b = _subtree_links(v0, limbs(v0)[1][k]), _subtree_links(v1, limbs(v1)[1][k])
        assert torch.equal(g.x[a], out.x[b])
    # in the written robot, each right body sits at the mirror image (y → -y) of its left one,
    # also when the joints move by the same angle
    model = graph_to_spec(out, "paper34", clearance=None)[0].compile()
    v = GraphView(out, FS)
    links = [i for i, t in enumerate(v.types) if t == LINK]
    body = {i: b for b, i in enumerate(links, start=1)}
    _, roots = limbs(v)
    data = mujoco.MjData(model)
    data.qpos[7:] = np.linspace(-0.3, 0.4, model.nq - 7)
    for k in range(0, 6, 2):
        left, right = _subtree_links(v, roots[k]), _subtree_links(v, roots[k + 1])
        for a, b in zip(left, right):  # the same hinge angles on both sides
            ja, jb = model.body_jntadr[body[a]], model.body_jntadr[body[b]]
            for j in range(model.body_jntnum[body[a]]):
                data.qpos[model.jnt_qposadr[jb + j]] = data.qpos[model.jnt_qposadr[ja + j]]
    mujoco.mj_forward(model, data)
    for k in range(0, 6, 2):
        for a, b in zip(_subtree_links(v, roots[k]), _subtree_links(v, roots[k + 1])):
            pa, pb = data.xpos[body[a]], data.xpos[body[b]]
            assert np.allclose(pa * [1, -1, 1], pb, atol=1e-5), (a, b)


def test_mirror_copies_the_topology_of_the_first_side():
    g = _hexapod().clone()
    v = GraphView(g, FS)
    _, roots = limbs(v)
    # cut the last link off the second (right) leg: a decoded pair of unequal topology
    right = _subtree_links(v, roots[1])
    keep = [i for i in range(g.num_nodes) if i != right[-1]]
    index = {old: new for new, old in enumerate(keep)}
    parent = [index[p] if p >= 0 else -1 for p in g.parent[keep].tolist()]
    from robovae.data.graph import tree_data

    cut = tree_data(parent, g.node_type[keep], g.x[keep], FS)
    out, changed = mirror_limbs(cut)
    assert changed and out.num_nodes == g.num_nodes and mirrored_pairs(out)[0] == 3


def test_front_and_back_legs_are_not_mirrored():
    for name in ("gym_half_cheetah", "gym_hopper", "gym_walker2d"):
        g = model_to_graph(load_robot(ZOO[name]).model, "paper34")
        out, changed = mirror_limbs(g)
        assert out is g and not changed, name


def test_a_decoded_pair_off_its_mirror_place_is_mirrored():
    """Ant with one leg moved and made heavier (as a decoder might): the pair is restored."""
    g = model_to_graph(load_robot(ZOO["gym_ant"]).model, "paper34")
    assert is_symmetric(g)
    v = GraphView(g, FS)
    _, roots = limbs(v)
    leg = _subtree_links(v, roots[1])
    x = g.x.clone()
    x[leg[0], FS.slice("link.pos")] += torch.tensor([0.05, 0.03, 0.02])
    x[leg, FS.slice("link.mass")] *= 1.3
    from robovae.data.graph import tree_data

    bent = tree_data(g.parent, g.node_type, x, FS)
    assert not is_symmetric(bent)
    out, changed = mirror_limbs(bent)
    assert changed and is_symmetric(out) and out.num_nodes == g.num_nodes


def _without(g, nodes: set[int]):
    """``g`` with the subtrees rooted at ``nodes`` cut off."""
    from robovae.data.graph import tree_data

    v = GraphView(g, FS)
    cut = set()
    for n in nodes:
        cut |= set(_subtree_nodes(v, n))
    keep = [i for i in range(g.num_nodes) if i not in cut]
    index = {old: new for new, old in enumerate(keep)}
    parent = [index[p] if p >= 0 else -1 for p in g.parent[keep].tolist()]
    return tree_data(parent, g.node_type[keep], g.x[keep], FS)


def _subtree_nodes(v: GraphView, root: int) -> list[int]:
    out, stack = [], [root]
    while stack:
        n = stack.pop()
        out.append(n)
        stack.extend(v.kids[n])
    return out


def test_a_stray_leg_gets_its_mirror_image():
    """A hexapod that lost its last (right) leg: two pairs and a stray left leg; the stray
    leg's mirror image is added where the lost leg was."""
    g = mirror_limbs(_hexapod())[0]
    v = GraphView(g, FS)
    lost = limbs(v)[1][5]
    five = _without(g, {lost})
    assert mirrored_pairs(five) == (2, 5) and is_symmetric(five)  # one unpaired limb is allowed
    out, changed = complete_pairs(five)
    assert changed and mirrored_pairs(out) == (3, 6) and out.num_nodes == g.num_nodes
    vo = GraphView(out, FS)
    new = limbs(vo)[1][5]
    assert np.allclose(vo.get(new, "link.pos"), v.get(lost, "link.pos"), atol=1e-6)
    assert torch.equal(out.x, g.x)  # the whole hexapod back, to the last feature


def _lone_caster(p: list[float]):
    """A procedural mobile base (two wheels, two caster pairs, a mast) with one rear caster cut
    off and the other attached at ``p``; its front casters' ``|p_y|`` and ring ``|p|``."""
    g = mirror_limbs(model_to_graph(procedural_spec(0, "mobile_manipulator").compile(), FS))[0]
    v = GraphView(g, FS)
    roots = limbs(v)[1]
    pos = FS.slice("link.pos")
    ys = {r: float(g.x[_subtree_links(v, r)[0], pos][1]) for r in roots}
    casters = [r for r in roots if len(_subtree_links(v, r)) == 2 and abs(ys[r]) > 0.1]
    assert len(casters) == 4
    front = [r for r in casters if g.x[_subtree_links(v, r)[0], pos][0] > 0]
    rear_left, rear_right = sorted((r for r in casters if r not in front), key=lambda r: -ys[r])
    lone = _without(g, {rear_right})
    vl = GraphView(lone, FS)
    moved = [r for r in limbs(vl)[1] if len(_subtree_links(vl, r)) == 2
             and float(lone.x[_subtree_links(vl, r)[0], pos][0]) < 0][0]
    links = _subtree_links(vl, moved)
    lone.x[links[0], pos] = torch.tensor(p, dtype=lone.x.dtype)
    length = float(sum(lone.x[n, pos].norm() for n in links))
    return lone, abs(ys[front[0]]), float(g.x[_subtree_links(v, front[0])[0], pos].norm()), length


def test_a_lone_caster_off_its_pairs_ring_gets_its_mirror_image():
    """A mobile base whose rear casters the decoder gave as one caster nearer the plane and
    the centre than its front pair: too near the plane for ``STRAY_TOL``, off the pair's ring,
    so it is mirrored."""
    p = [-0.12, 0.06, -0.076]
    lone, pair_y, ring, length = _lone_caster(p)
    assert abs(p[1]) < STRAY_TOL * pair_y  # not a stray by the pairs' distance to the plane
    assert abs(float(np.linalg.norm(p)) - ring) > RING_TOL * ring  # off the pair's ring
    assert 2 * abs(p[1]) >= CLEAR_TOL * length  # room for its mirror image
    pos = FS.slice("link.pos")
    before = mirrored_pairs(lone)
    out, changed = complete_pairs(lone)
    assert changed and mirrored_pairs(out) == (before[0] + 1, before[1] + 1)
    vo = GraphView(out, FS)
    added = [r for r in limbs(vo)[1] if len(_subtree_links(vo, r)) == 2
             and float(out.x[_subtree_links(vo, r)[0], pos][0]) < 0]
    assert len(added) == 2
    got = sorted(out.x[_subtree_links(vo, r)[0], pos].tolist() for r in added)
    assert np.allclose(got, [[-0.12, -0.06, -0.076], [-0.12, 0.06, -0.076]], atol=1e-6)


def test_a_lone_caster_without_room_for_its_mirror_image_is_left_single():
    """The same caster next to the plane: its mirror image would sit through it."""
    p = [-0.03, 0.009, -0.015]
    lone, pair_y, ring, length = _lone_caster(p)
    vl = GraphView(lone, FS)
    assert any(len(_subtree_links(vl, r)) == 2 and np.allclose(
        lone.x[_subtree_links(vl, r)[0], FS.slice("link.pos")].numpy(), p) for r in limbs(vl)[1])
    assert abs(p[1]) > ATTACH_TOL * np.linalg.norm(p)  # off the plane ...
    assert abs(float(np.linalg.norm(p)) - ring) > RING_TOL * ring  # ... and off the ring ...
    assert 2 * abs(p[1]) < CLEAR_TOL * length  # ... without room
    assert complete_pairs(lone) == (lone, False)


@pytest.mark.parametrize("seed", [1, 15, 36, 42])
def test_a_radial_robots_odd_leg_on_the_ring_is_left_single(seed):
    """Radial robots with an odd leg count whose odd leg sits off the plane but nearer it than
    the pairs: it shares their ring, so no sixth (or fourth) leg is added."""
    g = mirror_limbs(model_to_graph(procedural_spec(seed, "radial").compile(), FS))[0]
    assert complete_pairs(g) == (g, False)


def test_complete_pairs_leaves_other_limbs_alone():
    # real robots: nothing to complete
    for name in ("gym_ant", "gym_humanoid", "dmc_quadruped", "gym_half_cheetah"):
        g = model_to_graph(load_robot(ZOO[name]).model, "paper34")
        assert complete_pairs(g)[0] is g, name
    g = mirror_limbs(_hexapod())[0]
    v = GraphView(g, FS)
    roots = limbs(v)[1]
    # a stray limb of another topology than the pairs' (a torso, an arm) stays single
    other = _without(g, {roots[5], _subtree_links(v, roots[4])[-1]})
    assert mirrored_pairs(other) == (2, 5)
    assert complete_pairs(other) == (other, False)
    # a robot without a pair (one leg off the plane) is not given a second one
    lone = _without(g, set(roots[1:]))
    assert complete_pairs(lone) == (lone, False)


def _casters(g) -> tuple[GraphView, list[int]]:
    """The graph's view and the roots of its two caster limbs (on the sagittal plane, two links:
    a swivel and a wheel)."""
    v = GraphView(g, FS)
    roots = [r for r in limbs(v)[1] if len(_subtree_links(v, r)) == 2
             and abs(v.get(_subtree_links(v, r)[0], "link.pos")[1]) < 1e-9]
    return v, roots


def test_unequal_casters_are_made_equal_where_they_are():
    """A mobile manipulator on two drive wheels and two casters on the sagittal plane (front
    and back, equal, as every such training robot has them), its back caster made 30 % longer
    and heavier, as a decoder might: the back caster becomes a copy of the front one, attached
    where it was; the equal casters of the procedural robot are left alone."""
    g = model_to_graph(procedural_spec(3, "mobile_manipulator").compile(), "paper34", name="mm")
    v, (front, back) = _casters(g)
    assert twin_limbs(g) == (g, False)  # already equal
    pos, mass = FS.slice("link.pos"), FS.columns.index("link.mass")
    odd = g.clone()
    for k, n in enumerate(_subtree_links(v, back)):
        odd.x[n, pos] *= 1.3 if k else 1.1  # its place moved too
        odd.x[n, mass] *= 1.3
    out, changed = twin_limbs(odd)
    assert changed
    assert torch.equal(out.parent, odd.parent) and torch.equal(out.node_type, odd.node_type)
    w, (f2, b2) = _casters(out)
    src, dst = _subtree_links(w, f2), _subtree_links(w, b2)
    assert torch.equal(out.x[dst[0], pos], odd.x[_subtree_links(v, back)[0], pos])  # its place
    assert torch.equal(out.x[dst[1:]], out.x[src[1:]])  # the rest of it: the front caster's
    keep = [c for c in range(FS.dim) if c not in range(pos.start, pos.stop)]
    assert torch.equal(out.x[dst[0], keep], out.x[src[0], keep])
    # written and measured as the quality table does: the casters pair again
    pairs = [anatomy(graph_to_spec(x, FS)[0]).pairs for x in (g, odd, out)]
    assert pairs[0] == pairs[2] == pairs[1] + 1


def test_twin_limbs_leaves_robots_with_equal_or_paired_limbs_alone():
    """Real robots whose limbs on the plane are equal (walker2d's legs) or who have none are
    not changed; the half-cheetah's front and back legs (same topology, unequal) are made
    equal: one of three zoo robots that differ from the training corpus's rule
    (docs/generation.md)."""
    for name in ("gym_ant", "gym_humanoid", "dmc_quadruped", "gym_walker2d", "gym_hopper"):
        g = model_to_graph(load_robot(ZOO[name]).model, "paper34")
        assert twin_limbs(g) == (g, False), name
    cheetah = model_to_graph(load_robot(ZOO["gym_half_cheetah"]).model, "paper34")
    assert twin_limbs(cheetah)[1]
    assert twin_limbs(_hexapod())[0] is _hexapod()  # legs off the plane: mirror_limbs' work


def test_decoded_fixes_give_the_same_robot_from_a_graph_and_from_its_arrays():
    """The fixes run on NumPy arrays: a PyG graph and its ``TreeArrays`` get the same fixes and
    features, each back in its own kind (a hexapod with a stray leg and near-mirror pairs: the
    tree changes; the ant: a floating base only, the tree kept; a PyG graph keeps its other
    fields then)."""
    g = mirror_limbs(_hexapod())[0]
    roots = limbs(GraphView(g, FS))[1]
    unequal = _hexapod()
    stray = _without(unequal, {limbs(GraphView(unequal, FS))[1][5]})
    ant = model_to_graph(load_robot(ZOO["gym_ant"]).model, "paper34", name="ant")
    assert len(roots) == 6
    for graph, want in ((stray, ["mirror_limbs", "complete_pairs"]), (ant, None)):
        out, fixes = decoded_fixes(graph, FS)
        arrays, afixes = decoded_fixes(TreeArrays.of(graph), FS)
        assert fixes == afixes and (want is None or fixes == want), fixes
        assert isinstance(arrays, TreeArrays) and not isinstance(out, TreeArrays)
        assert np.array_equal(out.x.numpy(), arrays.x)
        assert np.array_equal(out.parent.numpy(), arrays.parent)
        assert np.array_equal(out.node_type.numpy(), arrays.node_type)
        assert out.name == arrays.name == graph.name
        assert set(out.keys()) == set(graph.keys())
    assert decoded_fixes(g, FS, floating=False) == (g, [])  # nothing to fix: the graph itself


def _humanoid_with_unequal_arms():
    """A procedural humanoid (arms on a chest below the pelvis's waist) whose right arm is
    moved, made heavier and its hinges turned, and whose chest sits 3 cm to the left and turned
    15° about z: a decoder's arms, which ``mirror_limbs`` (the trunk's limbs) does not reach."""
    from robovae.data.graph import tree_data
    from robovae.data.procedural import procedural_plan
    from robovae.generate.bodies import subtree

    seed = next(s for s in range(100) if procedural_plan(s).kind == "humanoid"
                and len(limbs(GraphView(model_to_graph(procedural_spec(s).compile(),
                                                       "paper34"), FS))[1]) == 3)
    g = model_to_graph(procedural_spec(seed).compile(), "paper34", name="humanoid")
    v = GraphView(g, FS)
    def side(c: int) -> float:  # y of a branch's first link in its link's frame
        return float(v.get(next(k for k in subtree(v.kids, c) if v.types[k] == LINK),
                           "link.pos")[1])

    hub = next(n for n in range(g.num_nodes) if v.types[n] == LINK and n != limbs(v)[0]
               and len(v.kids[n]) >= 2 and side(v.kids[n][-2]) > 0.05 > -0.05 > side(v.kids[n][-1]))
    left, right = v.kids[hub][-2:]
    x = g.x.clone()
    first = next(n for n in subtree(v.kids, right) if v.types[n] == LINK)
    x[first, FS.slice("link.pos")] += torch.tensor([0.03, -0.02, 0.05])
    x[subtree(v.kids, right), FS.slice("link.mass")] *= 1.3
    joints = [n for n in subtree(v.kids, right) if v.types[n] != LINK]
    x[joints[0], FS.slice("joint.axis")] = torch.tensor([0.6, 0.0, 0.8])
    x[hub, FS.slice("link.pos")] += torch.tensor([0.0, 0.03, 0.0])
    c, s = np.cos(np.radians(7.5)), np.sin(np.radians(7.5))
    x[hub, FS.slice("link.quat")] = torch.tensor([c, 0.0, 0.0, s])
    return tree_data(g.parent, g.node_type, x, FS, name="humanoid"), hub, left, right


def test_a_chest_with_unequal_arms_gets_mirrored_arms():
    from robovae.generate.bodies import subtree
    from robovae.generate.symmetry import mirror_branches

    g, hub, left, right = _humanoid_with_unequal_arms()
    g = mirror_limbs(g)[0]  # the trunk's limbs, the legs (the arms are not among them)
    assert mirror_limbs(g)[0] is g
    out, changed = mirror_branches(g, FS)
    assert changed and out.num_nodes == g.num_nodes
    assert torch.equal(out.x[subtree(GraphView(g, FS).kids, left)],
                       g.x[subtree(GraphView(g, FS).kids, left)])  # the first arm as decoded
    assert mirror_branches(out, FS) == (out, False)  # nothing left to mirror
    # written, each right-arm body sits at the mirror image of its left twin across the
    # pelvis's sagittal plane (not the turned chest's), at rest and with equal hinge angles
    model = graph_to_spec(out, "paper34", clearance=None)[0].compile()
    v = GraphView(out, FS)
    links = [i for i, t in enumerate(v.types) if t == LINK]
    body = {i: b for b, i in enumerate(links, start=1)}
    arms = [[n for n in subtree(v.kids, c) if v.types[n] == LINK] for c in v.kids[hub][-2:]]
    data = mujoco.MjData(model)
    for k in range(2):
        for a, b in zip(*arms):
            ja, jb = model.body_jntadr[body[a]], model.body_jntadr[body[b]]
            for j in range(model.body_jntnum[body[a]]):
                data.qpos[model.jnt_qposadr[ja + j]] = 0.3 * k * (j + 1)
                data.qpos[model.jnt_qposadr[jb + j]] = 0.3 * k * (j + 1)
        mujoco.mj_forward(model, data)
        t = body[limbs(v)[0]]
        rot, origin = data.xmat[t].reshape(3, 3), data.xpos[t]
        for a, b in zip(*arms):
            pa, pb = (rot.T @ (data.xpos[body[n]] - origin) for n in (a, b))
            assert np.allclose(pa * [1, -1, 1], pb, atol=1e-5), (k, a, b)


def test_decoded_fixes_mirror_a_chests_arms():
    g = _humanoid_with_unequal_arms()[0]
    out, fixes = decoded_fixes(g, FS, floating=False)
    assert "mirror_branches" in fixes
    assert decoded_fixes(out, FS, floating=False)[1] == []
