"""The writer's stance rules (robovae.generate.stance, robovae.generate.bipeds): wheels
grounded, soles laid flat, biped stilts stood on their ends, soles under point feet, strong
ankles, a balanced home pose."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
import torch

import robovae.envs  # noqa: F401  (registers robovae/Walk-v0)
from robovae.data.features import JOINT, LINK, get_feature_set
from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.quality.stage import rest_pose, robot_points, stage
from robovae.evaluate.quality.standing import standing
from robovae.evaluate.scene import prepare
from robovae.generate.pipeline import generate
from robovae.generate.stance import (
    MAX_SOLE_TILT,
    MAX_WHEEL_DROP,
    WHEEL_TOL,
    at_qpos0,
    support_points,
)
from robovae.generate.stance import _floor_boxes as floor_boxes
from robovae.generate.writer import graph_to_spec, write_robot

FS = get_feature_set("kinematic")
_I, _J = (0, 1, 2, 0, 0, 1), (0, 1, 2, 1, 2, 2)


def _biped(tilt_deg: float = 0.0, com_shift: float = 0.0, seed: int = 1):
    """Procedural biped ``seed`` with its feet boxes pitched by ``tilt_deg`` and its pelvis'
    centre of mass moved ``com_shift`` m along x (what a decoder's imprecision does)."""
    model = procedural_spec(seed, "biped").compile()
    g = model_to_graph(model, FS, name="biped")
    names = [model.body(b).name for b in range(model.nbody)]
    x = g.x.numpy().astype(np.float64)
    c, s = math.cos(math.radians(tilt_deg)), math.sin(math.radians(tilt_deg))
    pitch = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    axes, ipos = FS.slice("link.box_axes"), FS.slice("link.ipos")
    for i, (t, b) in enumerate(zip(g.node_type.tolist(), g.mj_id.tolist())):
        if t != LINK:
            continue
        if names[b].endswith("_foot"):
            a = np.zeros((3, 3))
            a[_I, _J] = x[i, axes]
            a[_J, _I] = x[i, axes]
            x[i, axes] = (pitch @ a @ pitch.T)[_I, _J]
        if names[b] == "pelvis":
            x[i, ipos.start] += com_shift
    out = g.clone()
    out.x = torch.from_numpy(x).to(g.x.dtype)
    return out


def _leaves(model: mujoco.MjModel) -> set[int]:
    """Bodies without child bodies (the biped's two feet)."""
    return set(range(1, model.nbody)) - set(model.body_parentid[1:].tolist())


def _write(graph, folder, stance: bool):
    return write_robot(graph, folder, FS, stance=stance)


def _rule_stands_it(graph, folder, rule: str):
    """The robot written without and with the stance rules: only ``rule`` fires, and the robot
    falls without it and stands with it. Returns both writes."""
    off = _write(graph, folder / "off", stance=False)
    on = _write(graph, folder / "on", stance=True)
    assert on.rules == [rule] and off.rules == []
    assert not standing(off.robot_path).stands
    assert standing(on.robot_path).stands
    return off, on


def test_level_soles_lays_tilted_feet_flat_and_the_biped_stands(tmp_path):
    before, after = _rule_stands_it(_biped(tilt_deg=10.0), tmp_path, "level_soles")
    model = mujoco.MjModel.from_xml_path(str(after.robot_path))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    feet = [g for g in range(model.ngeom) if model.geom_bodyid[g] in _leaves(model)
            and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX]
    assert len(feet) == 2
    for f in feet:  # one face of each sole is horizontal
        assert np.abs(data.geom_xmat[f].reshape(3, 3)[2]).max() == pytest.approx(1.0, abs=1e-5)
    pts, _, _ = support_points(model, data, tol=1e-4)
    assert len(pts) >= 8  # two flat soles: four corners each on the floor


def test_a_sole_tilted_beyond_the_limit_is_left(tmp_path):
    g = _biped(tilt_deg=MAX_SOLE_TILT + 10.0)
    assert "level_soles" not in _write(g, tmp_path / "on", stance=True).rules


@pytest.mark.parametrize("seed,tilt", [(1, 10.0), (3, 20.0)])
def test_level_stilts_stands_a_bipeds_slanted_stilts_on_their_ends(seed, tilt, tmp_path):
    """Feet boxes pitched until their long axis is ``tilt`` degrees from vertical (stilts, what
    decoded bipeds often stand on): on their edges the biped falls; stood on their end faces,
    it stands."""
    g = _biped(tilt_deg=90.0 - tilt, seed=seed)
    before = _write(g, tmp_path / "off", stance=False)
    after = _write(g, tmp_path / "on", stance=True)
    model = mujoco.MjModel.from_xml_path(str(before.robot_path))
    slanted = floor_boxes(model, at_qpos0(model), on_end=True)
    assert [t for _, _, t in slanted] == [pytest.approx(tilt, abs=0.5)] * 2
    names = [model.geom(g).name for g, _, _ in slanted]
    assert "level_stilts" in after.rules and "level_soles" not in after.rules
    assert not standing(before.robot_path).stands
    assert standing(after.robot_path).stands
    model = mujoco.MjModel.from_xml_path(str(after.robot_path))
    data = at_qpos0(model)
    for f in (model.geom(n).id for n in names):  # the longest axis vertical: on its end face
        up = np.abs(data.geom_xmat[f].reshape(3, 3)[2])
        assert up.max() == pytest.approx(1.0, abs=1e-5)
        assert model.geom_size[f, int(np.argmax(up))] == model.geom_size[f].max()
    assert len(support_points(model, data, tol=1e-4)[0]) >= 8  # two end faces on the floor
    assert attachment(str(after.robot_path)).all_attached


@pytest.mark.parametrize("seed,kind", [(0, "hexapod"), (6, "quadruped")])
def test_stilts_of_a_robot_on_more_legs_keep_their_slant(seed, kind, tmp_path):
    """The procedural hexapods and quadrupeds stand on leg boxes slanted by 18-25 degrees:
    ``level_stilts`` leaves them (only a biped falls off its edges)."""
    g = model_to_graph(procedural_spec(seed, kind).compile(), FS, name=kind)
    off = _write(g, tmp_path / "off", stance=False)
    model = mujoco.MjModel.from_xml_path(str(off.robot_path))
    assert len(floor_boxes(model, at_qpos0(model), on_end=True)) >= 4
    on = _write(g, tmp_path / "on", stance=True)
    assert "level_stilts" not in on.rules
    assert on.robot_path.read_bytes() == off.robot_path.read_bytes()


def _weak_ankles(graph, factor: float):
    """The graph with its ankle motors (``*_foot_j0``) ``factor`` times as strong."""
    model = procedural_spec(1, "biped").compile()
    x, torque = graph.x.clone(), FS.slice("joint.torque").start
    for i, (t, j) in enumerate(zip(graph.node_type.tolist(), graph.mj_id.tolist())):
        if t == JOINT and model.joint(j).name.endswith("_foot_j0"):
            x[i, torque] *= factor
    out = graph.clone()
    out.x = x
    return out


def test_strong_ankles_give_weak_ankles_their_soles_strength(tmp_path):
    """Ankle motors decoded 50 times too weak: held by its own motors the biped falls on its
    face. ``strong_ankles`` gives each ankle the torque of half the robot's weight at its
    sole's edge (its other motors and its geometry unchanged), and it stands. The procedural
    biped's own ankles are that strong already: the rule leaves it."""
    g = _biped()
    assert "strong_ankles" not in _write(g, tmp_path / "own", stance=True).rules
    off, on = _rule_stands_it(_weak_ankles(g, 1 / 50), tmp_path, "strong_ankles")
    m_off = mujoco.MjModel.from_xml_path(str(off.robot_path))
    m_on = mujoco.MjModel.from_xml_path(str(on.robot_path))
    data = at_qpos0(m_on)
    pts, owner, _ = support_points(m_on, data)
    weight = m_on.body_subtreemass[1] * 9.81
    parents = set(m_on.body_parentid.tolist())
    ankles = 0
    for a in range(m_on.nu):
        foot = int(m_on.jnt_bodyid[m_on.actuator_trnid[a, 0]])
        if foot in parents:  # not an ankle (the feet are the leaves)
            assert m_on.actuator_gear[a, 0] == m_off.actuator_gear[a, 0]
            continue
        ankles += 1
        x = pts[m_on.geom_bodyid[owner] == foot, 0]  # the feet point along x
        need = 0.5 * weight * 0.5 * np.ptp(x)
        assert m_on.actuator_gear[a, 0] == pytest.approx(need, rel=1e-4)
        assert m_on.actuator_gear[a, 0] > 10 * m_off.actuator_gear[a, 0]
    assert ankles == 2 and m_on.geom_size.tolist() == m_off.geom_size.tolist()


def test_strong_ankles_keep_a_dc_motor_one(tmp_path):
    """An ankle driven by a DC motor (a continuous joint's: ``speed_limited``) keeps its
    no-load speed when its gear is raised: the bias follows the new gear."""
    from robovae.data.actuators import NO_LOAD_SPEED, speed_limited
    from robovae.generate.bipeds import strong_ankles

    path = _write(_weak_ankles(_biped(), 1 / 50), tmp_path / "off", stance=False).robot_path
    spec = mujoco.MjSpec.from_file(str(path))
    model = spec.compile()
    leaves = set(range(model.nbody)) - set(model.body_parentid.tolist())
    ankles = [a for a in spec.actuators if int(model.joint(a.target).bodyid[0]) in leaves]
    for act in ankles:
        speed_limited(act, float(act.gear[0]))
    model = spec.compile()
    assert strong_ankles(spec, model, 1)
    for act in ankles:
        assert act.biasprm[2] == pytest.approx(-1.0 / (act.gear[0] * NO_LOAD_SPEED))
        assert act.gear[0] > 10.0 and list(act.forcerange) == [-1.0, 1.0]
    assert not strong_ankles(spec, spec.compile(), 1)  # strong enough now


def _point_feet(graph, half: float = 0.01):
    """The graph with the biped's feet boxes shrunk to cubes of ``half`` (m): legs on points."""
    model = procedural_spec(1, "biped").compile()
    x, box = graph.x.clone(), FS.slice("link.box_half")
    for i, (t, b) in enumerate(zip(graph.node_type.tolist(), graph.mj_id.tolist())):
        if t == LINK and model.body(b).name.endswith("_foot"):
            x[i, box] = half
    out = graph.clone()
    out.x = x
    return out


def test_foot_soles_stand_a_biped_on_points(tmp_path):
    """Feet decoded as 2 cm cubes and the centre of mass 10 cm behind them: the biped falls
    backwards. ``foot_soles`` puts a flat box under each foot, level with the lowest point,
    reaching past the centre of mass' projection, and it stands; masses unchanged."""
    g = _point_feet(_biped(com_shift=-0.1))
    off = _write(g, tmp_path / "off", stance=False)
    on = _write(g, tmp_path / "on", stance=True)
    assert on.rules == off.rules + ["foot_soles"]
    assert not standing(off.robot_path).stands and standing(on.robot_path).stands
    m_off = mujoco.MjModel.from_xml_path(str(off.robot_path))
    m_on = mujoco.MjModel.from_xml_path(str(on.robot_path))
    assert m_on.body_mass.tolist() == m_off.body_mass.tolist()
    soles = [k for k in range(m_on.ngeom) if m_on.geom(k).name.endswith("_sole")]
    assert m_on.ngeom == m_off.ngeom + 2 and len(soles) == 2
    assert sorted(int(m_on.geom_bodyid[k]) for k in soles) == sorted(_leaves(m_on))
    data = at_qpos0(m_on)
    mujoco.mj_comPos(m_on, data)
    com_x = data.subtree_com[1, 0]
    lowest = robot_points(m_on, data, 1)[:, 2].min()
    for k in soles:
        assert m_on.geom_type[k] == mujoco.mjtGeom.mjGEOM_BOX
        assert m_on.geom_contype[k] == 1 and m_on.geom_conaffinity[k] == 0
        corners = data.geom_xpos[k] + np.abs(data.geom_xmat[k].reshape(3, 3)) @ m_on.geom_size[k]
        assert corners[2] - 2 * m_on.geom_size[k, 2] == pytest.approx(lowest, abs=1e-4)
        low_x = data.geom_xpos[k, 0] - m_on.geom_size[k, 0]
        assert low_x < com_x < data.geom_xpos[k, 0] + m_on.geom_size[k, 0]  # under the feet


@pytest.mark.parametrize("kind", ["biped", "humanoid"])
def test_procedural_feet_get_no_soles(kind):
    """The procedural bipeds and humanoids stand on their own feet: ``foot_soles`` leaves all
    of them (some have short soles, their centre of mass over them)."""
    for seed in range(40):
        g = model_to_graph(procedural_spec(seed, kind).compile(), FS, name=kind)
        assert "foot_soles" not in graph_to_spec(g, FS, stance=True, clearance=0.0)[1], seed


def test_balance_home_leans_the_biped_over_its_feet(tmp_path):
    g = _biped(com_shift=-0.25)
    before, after = _rule_stands_it(g, tmp_path, "balance_home")
    model = mujoco.MjModel.from_xml_path(str(after.robot_path))
    home = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
    assert home >= 0 and model.nkey == 1
    rest, key = mujoco.MjData(model), mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, key, home)
    for d in (rest, key):
        mujoco.mj_kinematics(model, d)
        mujoco.mj_comPos(model, d)
    root = 1
    feet = sorted(_leaves(model))
    assert len(feet) == 2
    # the feet keep their place on the floor, the lowest point its height
    assert np.abs(key.xpos[feet] - rest.xpos[feet]).max() < 2e-3
    assert robot_points(model, key, root)[:, 2].min() == pytest.approx(
        robot_points(model, rest, root)[:, 2].min(), abs=1e-4)
    # the centre of mass moved over the soles (x: the sagittal axis of this biped)
    pts, _, _ = support_points(model, key)
    lo, hi = pts[:, 0].min(), pts[:, 0].max()
    assert not lo <= rest.subtree_com[root, 0] <= hi
    assert lo + 0.25 * (hi - lo) <= key.subtree_com[root, 0] <= hi - 0.25 * (hi - lo)
    # what starts the robot sees its home pose: the standing test, the stage's floor, the
    # renderer and robovae/Walk-v0
    np.testing.assert_allclose(rest_pose(model), model.key_qpos[home])
    st = stage(after.robot_path)
    mujoco.mj_resetDataKeyframe(st.model, st.data, home)
    mujoco.mj_kinematics(st.model, st.data)
    assert robot_points(st.model, st.data, st.root)[:, 2].min() == pytest.approx(st.floor_z,
                                                                                 abs=1e-6)
    np.testing.assert_allclose(prepare(after.robot_path, 64, 64).data.qpos,
                               model.key_qpos[home])
    env = gym.make("robovae/Walk-v0", robot=str(after.robot_path), reset_noise_scale=0.0)
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped.data.qpos, model.key_qpos[home], atol=1e-12)
    env.close()


def _raised_wheel(share: float, seed: int = 5, wheel: str = "wheel0l", mount: str = "wheel0l"):
    """A procedural mobile manipulator whose ``wheel`` is mounted ``share`` of its radius
    higher (``mount``, the root's child that carries it, moved: a decoder's imprecision), and
    that wheel's radius."""
    model = procedural_spec(seed, "mobile_manipulator").compile()
    w, m = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in (wheel, mount))
    radius = float(model.geom_size[model.body_geomadr[w], 0])
    g = model_to_graph(model, FS, name="mm")
    i = [k for k, (t, b) in enumerate(zip(g.node_type.tolist(), g.mj_id.tolist()))
         if t == LINK and b == m][0]
    x = g.x.clone()
    x[i, FS.slice("link.pos").start + 2] += share * radius
    out = g.clone()
    out.x = x
    return out, radius


def _wheel_bottoms(path) -> tuple[np.ndarray, float, float]:
    """The lowest points of the robot's wheels (bodies with a cylinder or sphere on hinges
    without limits), the robot's lowest point and its size, at ``qpos0``."""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    pts, owner, size = support_points(model, data, tol=10.0)  # every candidate point
    round_ = (int(mujoco.mjtGeom.mjGEOM_CYLINDER), int(mujoco.mjtGeom.mjGEOM_SPHERE))
    wheels = {int(model.jnt_bodyid[j]) for j in range(model.njnt)
              if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and not model.jnt_limited[j]
              and model.geom_type[model.body_geomadr[model.jnt_bodyid[j]]] in round_}
    bottoms = [pts[model.geom_bodyid[owner] == b, 2].min() for b in sorted(wheels)]
    return np.array(bottoms), float(pts[:, 2].min()), size


@pytest.mark.parametrize("seed,wheel,mount,wheels,share", [
    (5, "wheel0l", "wheel0l", 4, 0.6), (0, "caster1_wheel", "caster1", 6, 2.5)])
def test_ground_wheels_lowers_a_hanging_wheel_onto_the_floor(seed, wheel, mount, wheels, share,
                                                             tmp_path):
    g, radius = _raised_wheel(share, seed, wheel, mount)
    off = _write(g, tmp_path / "off", stance=False)
    on = _write(g, tmp_path / "on", stance=True)
    assert "ground_wheels" in on.rules and "ground_wheels" not in off.rules
    bottoms, low, _ = _wheel_bottoms(off.robot_path)
    assert len(bottoms) == wheels
    assert bottoms.max() - low == pytest.approx(share * radius, rel=0.05)  # one wheel hangs
    assert np.sort(bottoms)[-2] - low < WHEEL_TOL * radius
    bottoms, low, _ = _wheel_bottoms(on.robot_path)
    np.testing.assert_allclose(bottoms, low, atol=1e-5)  # every wheel on the floor
    assert standing(on.robot_path).stands
    # built again with the mount moved: the bridge from the base reaches it
    assert attachment(on.robot_path).all_attached


def test_a_wheel_hanging_higher_than_the_limit_is_left(tmp_path):
    g, _ = _raised_wheel(MAX_WHEEL_DROP + 0.5)
    on = _write(g, tmp_path / "on", stance=True)
    assert "ground_wheels" not in on.rules
    assert on.robot_path.read_bytes() == _write(g, tmp_path / "off", False).robot_path.read_bytes()


@pytest.mark.parametrize("seed,kind", [(0, "biped"), (2, "biped"), (3, "humanoid"),
                                       (3, "quadruped"), (4, "hexapod"),
                                       (0, "mobile_manipulator"), (5, "mobile_manipulator")])
def test_stance_leaves_robots_that_stand_alone(seed, kind, tmp_path):
    g = model_to_graph(procedural_spec(seed, kind).compile(), FS, name=kind)
    off = _write(g, tmp_path / "off", stance=False)
    on = _write(g, tmp_path / "on", stance=True)
    assert on.rules == off.rules
    assert on.robot_path.read_bytes() == off.robot_path.read_bytes()


def test_generate_reports_the_stance_rules_and_can_skip_them(trained, tmp_path):
    _, _, ckpt = trained
    kw = dict(seed=0, jobs=1, progress=False, quality=False, validate=False)
    generate(ckpt, 4, tmp_path / "on", **kw)
    generate(ckpt, 4, tmp_path / "off", stance=False, **kw)

    for name, stance in (("on", True), ("off", False)):
        assert json.loads((tmp_path / name / "run.json").read_text())["stance"] is stance
    rules = [r for line in (tmp_path / "off" / "manifest.jsonl").read_text().splitlines()
             for r in json.loads(line)["rules"]]
    assert "level_soles" not in rules and "balance_home" not in rules
