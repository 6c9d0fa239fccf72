"""Robot graph → MJCF writer (SPEC §7): round trips, scene, floor placement, atomic writes, and
garbage graphs that still compile.

Round-trip acceptance (MJCF → graph → ``write_robot`` → graph): the topology is exact and every
feature agrees within ``rtol = 1e-5`` (MJCF keeps 6 significant digits), with these documented
exceptions, by construction:

- ``paper34``: ``link.size`` of bodies that had no geom (size 0) comes back as the radius of the
  small sphere the writer gives them (``DEFAULT_GEOM_RADIUS, 0, 0``).
- ``full``: size components a primitive does not use (sphere: 2nd and 3rd, capsule/cylinder:
  3rd) come back as 0 — MJCF output writes only the used ones (``geom.size``, and ``link.size``
  when it is such a geom's size). Robots without any geom (Barkour, Z1 without their meshes)
  gain the writer's geoms, hence geom nodes, so they are skipped in ``full``.
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch

from robovae.data.actuators import NO_LOAD_SPEED
from robovae.data.features import GEOM, JOINT, LINK, get_feature_set
from robovae.data.graph import RobotData, tree_data
from robovae.data.mjcf import mjcf_to_graph, model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.locomotion import continuous_actuators
from robovae.generate import writer as writer_module
from robovae.generate.bodies import link_structure
from robovae.generate.rules import apply_rules
from robovae.generate.spec_builder import (
    DEFAULT_CTRLRANGE,
    DEFAULT_GEAR,
    WRITER_FIXES,
    is_link_primitive,
)
from robovae.generate.writer import WriteResult, graph_to_spec, scene_xml, write_robot
from tests.conftest import random_tree
from tests.reliability.strategies import assert_same_graph as assert_same
from tests.reliability.strategies import roundtrip_expected as expected

REPO = Path(__file__).resolve().parents[2]
MENAGERIE = Path(os.environ.get("ROBOVAE_SHARED_MENAGERIE", REPO.parent / "shared" / "menagerie"))
ZOO = dict(zoo_files()[0])
#: What the writer may report on a real robot: bridges where a link's primitive (from its size)
#: does not reach its anchor or a child's (the features do not place geoms).
LAYOUT = {"geom_bridge"}


@cache
def original(path: str, fs: str) -> RobotData:
    return mjcf_to_graph(path, fs)


@cache
def _quadruped(fs: str) -> RobotData:
    return model_to_graph(procedural_spec(3, "quadruped").compile(), fs, name="quadruped")


def quadruped(fs: str) -> RobotData:
    return _quadruped(fs).clone()


def roundtrip(path: str, fs: str, tmp: Path) -> tuple[RobotData, RobotData, WriteResult]:
    g = original(path, fs)
    result = write_robot(g, tmp, fs, name=Path(path).stem, clearance=None)
    return g, mjcf_to_graph(result.robot_path, fs), result


# --- round trips -----------------------------------------------------------------------------


@pytest.mark.parametrize("fs", ["paper34", "full"])
@pytest.mark.parametrize("name", sorted(ZOO))
def test_roundtrip_zoo(name, fs, tmp_path):
    g, back, result = roundtrip(str(ZOO[name]), fs, tmp_path)
    assert set(result.rules_fired) <= LAYOUT
    assert_same(g, back, expected(g, fs), fs, f"{name} ({fs})")


@pytest.mark.parametrize("fs", ["paper34", "full"])
def test_roundtrip_menagerie(fs, tmp_path):
    files = sorted(MENAGERIE.glob("*/*.xml"))
    if not files:
        pytest.skip(f"{MENAGERIE} not present")
    done = 0
    for path in files:
        g = original(str(path), fs)
        if fs == "full" and not (g.node_type == GEOM).any():
            continue  # no geom at all: the writer's geoms add nodes (module docstring)
        g, back, result = roundtrip(str(path), fs, tmp_path / path.parent.name)
        assert set(result.rules_fired) <= LAYOUT, path.parent.name
        assert_same(g, back, expected(g, fs), fs, f"{path.parent.name} ({fs})")
        done += 1
    assert done >= len(files) - 3


def test_roundtrip_in_memory_matches_file(tmp_path):
    """The spec holds the values the XML holds (numbers are rounded as MJCF writes them)."""
    g = quadruped("full")
    spec, fired = graph_to_spec(g, "full", clearance=None)
    assert fired == []
    mem = model_to_graph(spec.compile(), "full")
    path = tmp_path / "robot.xml"
    path.write_text(spec.to_xml())
    disk = mjcf_to_graph(path, "full")
    assert torch.equal(mem.x, disk.x)
    assert_same(g, mem, expected(g, "full"), "full", "quadruped")


# --- structure of the written robot ------------------------------------------------------------


def test_paper34_robot_structure(tmp_path):
    g = quadruped("paper34")
    result = write_robot(g, tmp_path, "paper34", name="quad")
    m = mujoco.MjModel.from_xml_path(str(result.robot_path))
    n_links = int((g.node_type == LINK).sum())
    n_joints = int((g.node_type == JOINT).sum())
    assert (result.n_bodies, result.n_joints) == (n_links, n_joints)
    assert result.n_geoms == m.ngeom >= n_links  # a primitive per link, plus bridges
    assert result.n_actuators == n_joints - 1  # one motor per non-free joint
    assert result.counts == {"bodies": n_links, "joints": n_joints, "geoms": m.ngeom,
                             "actuators": n_joints - 1}
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert set(m.jnt_type[1:].tolist()) == {mujoco.mjtJoint.mjJNT_HINGE}
    assert np.allclose(m.actuator_gear[:, 0], DEFAULT_GEAR)
    assert np.allclose(m.actuator_ctrlrange, DEFAULT_CTRLRANGE) and m.actuator_ctrllimited.all()
    # explicit inertials: the invented geoms do not change masses
    fs = get_feature_set("paper34")
    links = [i for i, t in enumerate(g.node_type.tolist()) if t == LINK]
    assert np.allclose(m.body_mass[1:], g.x[links, fs.slice("link.mass")].squeeze(1).numpy(),
                       rtol=1e-5)
    # the first geom of a body: size (r, h, 0) → capsule, (r, 0, 0) → sphere, (x, y, z) → box
    for b, i in enumerate(links, start=1):
        size = g.x[i, fs.slice("link.size")].numpy()
        want = {1: "sphere", 2: "capsule", 3: "box"}[int((size > 0).sum())]
        assert m.geom_type[m.body_geomadr[b]] == getattr(mujoco.mjtGeom, f"mjGEOM_{want.upper()}")
    # a segment's capsule starts at its joint (its end touches the anchor) and points at its
    # first child link
    anc, chain = link_structure(g.parent.tolist(), g.node_type.tolist())
    seg = next(i for i in links if anc[i] >= 0 and any(anc[c] == i for c in links))
    child = next(c for c in links if anc[c] == seg)
    b = links.index(seg) + 1
    geom = m.body_geomadr[b]
    assert m.geom_type[geom] == mujoco.mjtGeom.mjGEOM_CAPSULE
    anchor = g.x[chain[seg][0], fs.slice("joint.pos")].numpy()
    r, h = m.geom_size[geom, :2]
    axis = np.zeros(9)
    mujoco.mju_quat2Mat(axis, m.geom_quat[geom])
    u = axis.reshape(3, 3)[:, 2]
    assert np.allclose(m.geom_pos[geom], anchor + (h + r) * u, atol=1e-5)
    target = g.x[child, fs.slice("link.pos")].numpy() - anchor
    assert np.allclose(u, target / np.linalg.norm(target), atol=1e-5)
    assert '<mujoco model="quad">' in result.robot_path.read_text()


@pytest.mark.parametrize("kind,seed", [("humanoid", 1), ("mobile_manipulator", 3)])
def test_a_links_primitive_is_its_first_geom_by_name_and_its_bridges_follow(kind, seed):
    """``overlaps`` tells a link's primitive from its bridges by the names the writer gives."""
    fs = get_feature_set("kinematic")
    graph = model_to_graph(procedural_spec(seed, kind).compile(), fs)
    spec, rules = graph_to_spec(graph, fs)
    assert "geom_bridge" in rules
    m = spec.compile()
    bridged = 0
    for b in range(1, m.nbody):
        names = [m.geom(g).name for g in range(m.body_geomadr[b],
                                                m.body_geomadr[b] + m.body_geomnum[b])]
        assert [is_link_primitive(n) for n in names] == [True] + [False] * (len(names) - 1)
        bridged += len(names) > 1
    assert bridged > 0


def test_full_actuators_follow_the_flags(tmp_path):
    g = quadruped("full")
    fs = get_feature_set("full")
    joints = [i for i, t in enumerate(g.node_type.tolist()) if t == JOINT]
    g.x[joints[1], fs.slice("joint.actuated")] = 0.0  # one passive joint
    g.x[joints[1], fs.slice("joint.gear")] = 0.0
    g.x[joints[1], fs.slice("joint.ctrlrange")] = 0.0
    auto = write_robot(g, tmp_path / "auto", "full").n_actuators
    everything = write_robot(g, tmp_path / "all", "full", actuators="all").n_actuators
    none = write_robot(g, tmp_path / "none", "full", actuators="none").n_actuators
    assert (auto, everything, none) == (len(joints) - 2, len(joints) - 1, 0)
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "auto" / "robot.xml"))
    gear = g.x[joints[2], fs.slice("joint.gear")].item()
    assert m.actuator_gear[0, 0] == pytest.approx(gear, rel=1e-5)
    with pytest.raises(ValueError, match="actuators"):
        graph_to_spec(g, "full", actuators="some")


def test_fixed_base_is_welded(tmp_path):
    fs = get_feature_set("paper34")
    x = fs.empty(3)
    for i in (0, 2):
        x[i, fs.slice("link.mass")] = 1.0
        x[i, fs.slice("link.inertia")] = torch.tensor([0.1, 0.1, 0.1])
        x[i, fs.slice("link.quat")] = torch.tensor([1.0, 0, 0, 0])
        x[i, fs.slice("link.iquat")] = torch.tensor([1.0, 0, 0, 0])
        x[i, fs.slice("link.size")] = torch.tensor([0.05, 0.2, 0])
    x[0, fs.slice("link.pos")] = torch.tensor([0.0, 0.0, 0.5])
    x[2, fs.slice("link.pos")] = torch.tensor([0.0, 0.0, -0.4])
    x[2, fs.slice("link.subtreemass")] = 1.0
    x[0, fs.slice("link.subtreemass")] = 2.0
    x[1, fs.slice("joint.axis")] = torch.tensor([0.0, 1.0, 0.0])
    x[1, fs.slice("joint.range")] = torch.tensor([-1.0, 1.0])
    g = tree_data([-1, 0, 1], [LINK, JOINT, LINK], x, fs)
    result = write_robot(g, tmp_path, fs)
    assert result.rules_fired == ["geom_bridge"]  # the root capsule does not reach the hinge
    m = mujoco.MjModel.from_xml_path(str(result.robot_path))
    assert m.body_jntnum[1] == 0 and m.body_parentid[1] == 0  # welded to the world
    assert m.body_pos[1].tolist() == [0.0, 0.0, 0.5]  # no floor placement without free joint
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_HINGE and m.jnt_limited[0]
    assert m.jnt_range[0].tolist() == [-1.0, 1.0]
    # the root link's geom sits at its origin, unrotated
    assert m.geom_pos[0].tolist() == [0, 0, 0] and m.geom_quat[0].tolist() == [1, 0, 0, 0]


# --- floor placement and scene ---------------------------------------------------------------


def _lowest(model: mujoco.MjModel) -> float:
    return writer_module._lowest_point(model)


@pytest.mark.parametrize("fs", ["paper34", "full"])
def test_free_robot_is_placed_above_the_floor(fs, tmp_path):
    g = quadruped(fs)
    result = write_robot(g, tmp_path, fs, clearance=0.02)
    m = mujoco.MjModel.from_xml_path(str(result.robot_path))
    assert _lowest(m) == pytest.approx(0.02, abs=1e-4)
    # only the root link's z changed
    back = mjcf_to_graph(result.robot_path, fs)
    want = expected(g, fs)
    z = get_feature_set(fs).slice("link.pos").start + 2
    want[1, z] = back.x[1, z]
    assert_same(g, back, want, fs, "placed quadruped")
    assert back.x[1, z] != pytest.approx(g.x[1, z].item())
    for bad in (float("nan"), -1.0):  # wrote a robot, as if placed, until 2026-11-29
        with pytest.raises(ValueError, match="write_robot.clearance must be a number >= 0"):
            write_robot(g, tmp_path / "bad", fs, clearance=bad)
    assert not (tmp_path / "bad").exists()


def test_scene_loads_and_simulates(tmp_path):
    g = quadruped("full")
    result = write_robot(g, tmp_path, "full", name="quad")
    assert result.scene_path == tmp_path / "scene.xml"
    text = result.scene_path.read_text()
    assert '<include file="robot.xml"' in text
    m = mujoco.MjModel.from_xml_path(str(result.scene_path))
    robot = mujoco.MjModel.from_xml_path(str(result.robot_path))
    assert m.nbody == robot.nbody and m.ngeom == robot.ngeom + 1 and m.nlight == 1
    assert m.geom(0).name == "floor" and m.geom_type[0] == mujoco.mjtGeom.mjGEOM_PLANE
    d = mujoco.MjData(m)
    for _ in range(250):
        mujoco.mj_step(m, d)
    assert np.isfinite(d.qpos).all() and d.ncon > 0  # it fell onto the floor
    assert scene_xml("other.xml").count("<include") == 1


def test_write_without_scene(tmp_path):
    result = write_robot(quadruped("paper34"), tmp_path, "paper34", scene=False)
    assert result.scene_path is None and result.rules == result.rules_fired
    assert set(result.rules) <= LAYOUT
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.xml"]


# --- atomic writes ---------------------------------------------------------------------------


def test_atomic_write_leaves_no_temp_files(tmp_path):
    out = tmp_path / "robot_0"
    write_robot(quadruped("paper34"), out, "paper34")
    assert sorted(p.name for p in out.iterdir()) == ["robot.xml", "scene.xml"]
    # rewriting replaces both files in place
    first = (out / "robot.xml").read_text()
    write_robot(quadruped("full"), out, "full")
    assert sorted(p.name for p in out.iterdir()) == ["robot.xml", "scene.xml"]
    assert (out / "robot.xml").read_text() != first


def test_failed_write_leaves_nothing_behind(tmp_path, monkeypatch):
    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(writer_module.os, "replace", broken_replace)
    out = tmp_path / "robot_1"
    with pytest.raises(OSError, match="disk full"):
        write_robot(quadruped("paper34"), out, "paper34")
    assert list(out.iterdir()) == []  # neither a half-written robot.xml nor a temp file


def test_a_stale_temporary_file_is_left_alone(tmp_path):
    """A temporary file of the same name (a crashed writer with this pid) does not stop the
    write: another name is used, and the stale file is not touched."""
    out = tmp_path / "robot_2"
    out.mkdir()
    stale = out / f".robot.xml.{os.getpid()}.tmp"
    stale.write_text("stale")
    write_robot(quadruped("paper34"), out, "paper34")
    write_robot(quadruped("paper34"), tmp_path / "fresh", "paper34")
    assert (out / "robot.xml").read_bytes() == (tmp_path / "fresh" / "robot.xml").read_bytes()
    assert stale.read_text() == "stale"
    assert sorted(p.name for p in out.iterdir()) == sorted([stale.name, "robot.xml", "scene.xml"])


def test_fast_write_gives_the_same_files(tmp_path):
    """Without the load check and the per-file fsync the files are the same; the scene (built
    once per process) names the robot's scene."""
    g = quadruped("paper34")
    a = write_robot(g, tmp_path / "a", "paper34", name="q")
    b = write_robot(g, tmp_path / "b", "paper34", name="q", check=False, durable=False)
    for f in ("robot.xml", "scene.xml"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()
    assert a.counts == b.counts
    assert scene_xml("r.xml", "other").count('model="other"') == 1
    assert 'model="q_scene"' in (tmp_path / "a" / "scene.xml").read_text()


def test_scene_is_written_after_the_robot(tmp_path, monkeypatch):
    calls = []
    real = writer_module.atomic_write

    def spy(path, text, durable=True):
        calls.append(path.name)
        return real(path, text, durable)

    monkeypatch.setattr(writer_module, "atomic_write", spy)
    write_robot(quadruped("paper34"), tmp_path, "paper34")
    assert calls == ["robot.xml", "scene.xml"]


# --- garbage in, compilable robot out --------------------------------------------------------


@pytest.mark.parametrize("fs", ["paper34", "full"])
def test_random_garbage_always_compiles(fs):
    """100 random trees per set (200 in all): the written XML always loads in MuJoCo."""
    rng = np.random.default_rng(0 if fs == "paper34" else 1)
    for k in range(100):
        g = random_tree(rng, fs, int(rng.integers(1, 40)))
        spec, fired = graph_to_spec(g, fs, clearance=0.01 if k % 2 else None)
        assert fired  # garbage always needs repairs
        model = mujoco.MjModel.from_xml_string(spec.to_xml())
        assert model.nbody >= 2


def test_noisy_real_robot_compiles_and_keeps_its_topology():
    """Decoder-like output: a real robot with noisy features keeps its tree."""
    g = quadruped("full")
    gen = torch.Generator().manual_seed(0)
    g.x = torch.where(g.x_mask, g.x + 0.3 * torch.randn(g.x.shape, generator=gen), g.x)
    spec, fired = graph_to_spec(g, "full")
    assert fired and not set(fired) & set(WRITER_FIXES)
    back = model_to_graph(spec.compile(), "full")
    assert torch.equal(back.parent, g.parent) and torch.equal(back.node_type, g.node_type)
    repaired, _ = apply_rules(g, "full")
    mass = get_feature_set("full").slice("link.mass")
    assert torch.allclose(back.x[:, mass], repaired.x[:, mass], rtol=1e-5)


def test_writer_fixes_malformed_trees():
    fs = get_feature_set("paper34")
    # a joint leading to two links, a dangling joint, and 8 hinges in one chain
    parent = [-1, 0, 1, 1, 0, 0, 5, 6, 7, 8, 9, 10, 11, 12]
    types = [LINK, JOINT, LINK, LINK, JOINT, JOINT, JOINT, JOINT, JOINT, JOINT, JOINT, JOINT,
             JOINT, LINK]
    g = tree_data(parent, types, torch.rand(len(parent), fs.dim), fs)
    spec, fired = graph_to_spec(g, fs)
    assert {"joint_shared", "dangling_joint", "dof_chain_split"} <= set(fired)
    m = mujoco.MjModel.from_xml_string(spec.to_xml())
    assert m.nbody - 1 == 4 + 1  # 4 links + 1 intermediate body for the 8-hinge chain
    # no link at all: one default body
    g = tree_data([-1, 0], [JOINT, JOINT], torch.rand(2, fs.dim), fs)
    spec, fired = graph_to_spec(g, fs)
    assert "empty_robot" in fired and spec.compile().nbody == 2


def test_shared_joints_are_not_copied_down_a_chain():
    """A decoding cut off by the node limit can be a chain of joints with a link hanging from
    each (J1 -> J2 -> ... -> Jk, Ji -> Li): every joint is written once, to the first link
    below it, not copied to every link further down (k (k + 1) / 2 joints, 6,720 for one
    256-node decoding)."""
    fs = get_feature_set("paper34")
    k = 12
    parent, types = [-1], [LINK]
    for i in range(k):
        j = len(parent)
        parent += [0 if i == 0 else j - 2, j]
        types += [JOINT, LINK]
    g = tree_data(parent, types, torch.rand(len(parent), fs.dim), fs)
    spec, fired = graph_to_spec(g, fs)
    assert "joint_shared" in fired
    m = mujoco.MjModel.from_xml_string(spec.to_xml())
    assert m.njnt == k and m.nbody - 1 == k + 1


def test_rules_false_may_fail():
    g = quadruped("paper34")
    fs = get_feature_set("paper34")
    moving = [i for i, c in enumerate(link_structure(g.parent.tolist(),
                                                     g.node_type.tolist())[1]) if c]
    g.x[moving[0], fs.slice("link.mass")] = 0.0
    g.x[moving[0], fs.slice("link.inertia")] = 0.0
    with pytest.raises(ValueError, match="MuJoCo rejected"):
        graph_to_spec(g, fs, rules=False)
    spec, fired = graph_to_spec(g, fs)
    assert {"mass_positive", "inertia_positive"} <= set(fired)


@pytest.mark.parametrize("seed", [0, 8, 5])  # quadruped, humanoid, hexapod
def test_kinematic_round_trip_keeps_feet_and_motors(seed):
    """The ``kinematic`` set rebuilds a procedural robot that still stands: every body attached,
    each link's primitive fills its collision box (a humanoid's foot is a box, not the ankle
    sphere its first geom is), and the motors keep their gears."""
    from robovae.evaluate.quality.attachment import attachment
    from robovae.evaluate.quality.measure import measure

    model = procedural_spec(seed).compile()
    g = model_to_graph(model, "kinematic")
    out, fired = graph_to_spec(g, "kinematic")
    back = out.compile()
    assert set(fired) <= {"geom_bridge"}
    assert attachment(back).all_attached
    np.testing.assert_allclose(np.sort(back.actuator_gear[:, 0]),
                               np.sort(model.actuator_gear[:, 0]), rtol=1e-4)
    assert measure(out, describe=False, name=f"rt{seed}")["stands"]
    if seed == 8:  # the humanoid: its foot's primitive spans the sole, not the ankle sphere
        foot = model.body("left_leg5").id
        sole = [k for k in range(model.ngeom) if model.geom_bodyid[k] == foot
                and model.geom_type[k] == mujoco.mjtGeom.mjGEOM_BOX][0]
        node = int(((g.node_type == LINK) & (g.mj_id == foot)).nonzero()[0, 0])
        body = back.body(f"link{node}").id
        first = next(k for k in range(back.ngeom) if back.geom_bodyid[k] == body)
        assert back.geom_type[first] != mujoco.mjtGeom.mjGEOM_SPHERE
        np.testing.assert_allclose(np.sort(back.geom_aabb[first, 3:])[-1],
                                   model.geom_size[sole].max(), atol=0.005)


# --- the writer's worker processes: graphs as NumPy arrays, no torch -------------------------


@pytest.mark.parametrize("fs", ["paper34", "full"])
def test_tree_arrays_write_the_same_robot(fs, tmp_path):
    """A graph given as :class:`TreeArrays` is written byte for byte as the PyG graph is (a real
    robot and random trees, which most rules repair); the rules return the kind they got."""
    from robovae.data.tree_arrays import TreeArrays

    rng = np.random.default_rng(3)
    graphs = [quadruped(fs)] + [random_tree(rng, fs, int(rng.integers(2, 30))) for _ in range(8)]
    for k, g in enumerate(graphs):
        arrays = TreeArrays.of(g)
        assert arrays.num_nodes == g.num_nodes and arrays.x.dtype == np.float32
        a = write_robot(g, tmp_path / f"g{k}", fs, name="r", stance=True)
        b = write_robot(arrays, tmp_path / f"a{k}", fs, name="r", stance=True)
        for f in ("robot.xml", "scene.xml"):
            assert (tmp_path / f"g{k}" / f).read_bytes() == (tmp_path / f"a{k}" / f).read_bytes()
        assert a.rules == b.rules and a.counts == b.counts
        repaired, fired = apply_rules(arrays, fs)
        assert isinstance(repaired, TreeArrays) and fired == apply_rules(g, fs)[1]
        np.testing.assert_array_equal(repaired.x, apply_rules(g, fs)[0].x.numpy())


def test_a_worker_writes_validates_and_measures_without_torch(tmp_path):
    """What a worker process of ``robovae generate`` does with one robot (write, validate,
    measure: :func:`~robovae.generate.build.build_robot`), in a fresh interpreter given the
    graph as pickled :class:`TreeArrays`: the robot is valid and measured, and neither torch,
    PyG nor ``cmaes`` (with SciPy's stats, 0.7 s to import) is ever imported."""
    import pickle
    import subprocess
    import sys

    from robovae.data.tree_arrays import TreeArrays

    item = (TreeArrays.of(quadruped("paper34")), tmp_path / "robot_0", "paper34", "q", True,
            True, True, "held", True)
    (tmp_path / "item.pkl").write_bytes(pickle.dumps(item))
    script = (
        "import pickle, sys, json\n"
        "from robovae.generate.build import build_robot\n"
        f"rec = build_robot(pickle.loads(open({str(tmp_path / 'item.pkl')!r}, 'rb').read()))\n"
        "print(json.dumps({'valid': rec['valid'], 'quality': 'quality' in rec,\n"
        "  'error': rec.get('quality', {}).get('error'),\n"
        "  'loaded': [m for m in ('torch', 'torch_geometric', 'cmaes', 'scipy.stats')\n"
        "             if m in sys.modules]}))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True, cwd=REPO)
    rec = __import__("json").loads(out.stdout.strip().splitlines()[-1])
    assert rec == {"valid": True, "quality": True, "error": None, "loaded": []}
    assert mujoco.MjModel.from_xml_path(str(tmp_path / "robot_0" / "robot.xml")).nbody > 2


@pytest.mark.parametrize("fs", ["kinematic", "full"])
def test_the_writer_gives_continuous_joints_dc_motors(fs):
    """A mobile manipulator through its graph and the writer: its wheels (hinges without
    limits) get DC motors as the procedural generator's do, its limited joints plain motors."""
    original = procedural_spec(1, kind="mobile_manipulator").compile()
    model = graph_to_spec(model_to_graph(original, fs), fs)[0].compile()
    affine = int(mujoco.mjtBias.mjBIAS_AFFINE)
    for m in (original, model):
        free = continuous_actuators(m)
        assert free.sum() >= 2
        assert np.array_equal(m.actuator_biastype == affine, free)
        gear = m.actuator_gear[free, 0]
        assert m.actuator_biasprm[free, 2] == pytest.approx(-1.0 / (gear * NO_LOAD_SPEED))
        assert (m.actuator_forcerange[free] == [-1.0, 1.0]).all()
