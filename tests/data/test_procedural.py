"""Tests of the procedural robot generator (robovae.data.procedural)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch

from robovae.cli import main
from robovae.data.dataset import RobotDataset
from robovae.data.features import get_feature_set
from robovae.data.graph import limbs
from robovae.data.mjcf import mjcf_to_graph, model_to_graph
from robovae.data.procedural import (
    CLASSES,
    ProceduralConfig,
    default_mix,
    parse_procedural,
    procedural_graphs,
    procedural_name,
    procedural_plan,
    procedural_spec,
    write_procedural,
)
from robovae.data.procedural.batch import generator_digest
from robovae.data.procedural.blueprint import Part, RobotPlan, reroot
from robovae.data.procedural.coverage import (
    MENAGERIE_CLASSES,
    links_and_joints,
    ordered_tree,
    plan_tree,
    shape_stats,
    tree_shape,
)
from robovae.data.procedural.robots import draw_class
from robovae.errors import RobovaeError
from robovae.evaluate.behaviour import standing_test
from robovae.evaluate.quality.attachment import attachment

HINGE, SLIDE = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
FREE = int(mujoco.mjtJoint.mjJNT_FREE)
FLOATING = [c for c in CLASSES if c != "arm"]


def on_floor(spec: mujoco.MjSpec) -> mujoco.MjModel:
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    return spec.compile()


def detached(model: mujoco.MjModel) -> list[str]:
    """Bodies none of whose geoms comes within 5 % of the robot's extent of a parent geom."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    tol = 0.05 * model.stat.extent
    out = []
    for b in range(2, model.nbody):
        p = model.body_parentid[b]
        mine = range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b])
        theirs = range(model.body_geomadr[p], model.body_geomadr[p] + model.body_geomnum[p])
        if not any(mujoco.mj_geomDistance(model, data, g, h, 1.0, None) <= tol
                   for g in mine for h in theirs):
            out.append(model.body(b).name)
    return out


@pytest.mark.parametrize("kind", CLASSES)
def test_every_class_compiles_and_simulates_one_second(kind: str) -> None:
    for seed in range(3):
        model = on_floor(procedural_spec(seed, kind))
        data = mujoco.MjData(model)
        data.ctrl[:] = np.random.default_rng(seed).uniform(-1, 1, model.nu)
        for _ in range(round(1.0 / model.opt.timestep)):
            mujoco.mj_step(model, data)
        assert np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all(), (kind, seed)
        assert not any(w.number for w in data.warning), (kind, seed)
        if kind != "arm":
            assert data.qpos[2] > 0.0, (kind, seed)  # did not fall through the floor


@pytest.mark.parametrize("kind", FLOATING)
def test_floating_robots_stand_when_held(kind: str) -> None:
    for seed in range(2):
        r = standing_test(procedural_spec(seed, kind), seconds=1.0)
        assert r["floating"] and r["stands"] and not r["unstable"], (kind, seed, r)


@pytest.mark.parametrize("kind", CLASSES)
def test_bodies_are_joined_and_only_the_robot_is_there(kind: str) -> None:
    for seed in range(3):
        plan = procedural_plan(seed, kind)
        model = procedural_spec(seed, kind).compile()
        assert detached(model) == [], (kind, seed)
        assert int((model.body_parentid[1:] == 0).sum()) == 1  # one robot, no floor
        assert int((model.geom_bodyid == 0).sum()) == 0
        assert model.nbody == 2 + plan.num_segments
        assert model.njnt == plan.num_joints + plan.floating
        assert model.nu == plan.num_actuators > 0
        assert (model.jnt_type[0] == FREE) == plan.floating
        lo, hi = model.jnt_range[model.jnt_limited.astype(bool)].T
        assert (lo <= 0).all() and (hi >= 0).all()  # qpos0 inside every limit
        assert (model.actuator_gear[:, 0] > 0).all() and model.actuator_ctrllimited.all()
        assert (model.body_mass[1:] > 0).all()
        if plan.floating:  # lowest point `clearance` above z = 0
            spec = procedural_spec(seed, kind)
            data = mujoco.MjData(model)
            mujoco.mj_forward(model, data)
            assert spec.bodies[1].pos[2] == pytest.approx(plan.height)


def hinges_per_limb(model: mujoco.MjModel) -> list[int]:
    """Hinges in each subtree hanging off the root body, in order."""
    top = [b for b in range(model.nbody) if model.body_parentid[b] == 1 and b > 1]
    out = []
    for t in top:
        bodies = [b for b in range(model.nbody) if b >= t and _under(model, b, t)]
        out.append(int(sum((model.jnt_type[model.jnt_bodyid == b] == HINGE).sum()
                           for b in bodies)))
    return out


def _under(model: mujoco.MjModel, b: int, t: int) -> bool:
    while b > t:
        b = model.body_parentid[b]
    return b == t


def hinges_below(model: mujoco.MjModel, name: str) -> int:
    """Hinges of the subtree of body ``name``."""
    t = model.body(name).id
    return int(sum((model.jnt_type[model.jnt_bodyid == b] == HINGE).sum()
                   for b in range(t, model.nbody) if _under(model, b, t)))


def world_geoms(part: Part, origin=(0.0, 0.0, 0.0)) -> dict:
    """``{(part name, k): world points of geom k}`` of a plan's subtree."""
    out = {}
    for p, o in part.walk():
        o = (o[0] + origin[0], o[1] + origin[1], o[2] + origin[2])
        for k, g in enumerate(p.geoms):
            pts = [g.fromto[:3], g.fromto[3:]] if g.fromto is not None else [g.pos]
            out[p.name, k] = [tuple(a + b for a, b in zip(o, q)) for q in pts]
    return out


def joint_anchors(part: Part) -> dict:
    """``{sorted names of the two parts a joint's edge joins: (world anchor, joint types)}``:
    the edge, not which side is the parent."""
    out = {}
    origin = {p.name: o for p, o in part.walk()}
    for p in (q for q, _ in part.walk()):
        for c in p.children:
            if c.joints:
                out[tuple(sorted((p.name, c.name)))] = (origin[c.name],
                                                        [j.type for j in c.joints])
    return out


def test_real_joint_patterns() -> None:
    for seed in range(8):
        quad = procedural_spec(seed, "quadruped").compile()
        # go1/go2/a1/spot tree, sometimes with 1-2 welded sensor bodies (barkour_vb)
        assert model_to_graph(quad).num_nodes in (26, 27, 28)
        assert [h for h in hinges_per_limb(quad) if h] == [3, 3, 3, 3]
        axes = np.abs(quad.jnt_axis[1:4]).argmax(1).tolist()
        assert axes == [0, 1, 1]  # abduction x, flexion y, knee y
        assert hinges_per_limb(procedural_spec(seed, "hexapod").compile()) == [3] * 6
        assert sum(model_to_graph(procedural_spec(s, "quadruped").compile()).num_nodes == 26
                   for s in range(40)) >= 24  # mostly the plain 26-node tree
        human = procedural_spec(seed, "humanoid").compile()
        legs = [hinges_below(human, f"{side}_leg0") for side in ("left", "right")]
        assert legs[0] == legs[1] and 5 <= legs[0] <= 8  # 5-7 + a toe hinge
        arm = procedural_spec(seed, "arm").compile()
        chain_hinges = [b for b in range(arm.nbody) if re.fullmatch(r"link\d", arm.body(b).name)]
        assert 4 <= len(chain_hinges) <= 7 and arm.jnt_type[0] != FREE
        assert int((arm.jnt_type == SLIDE).sum()) in (0, 2)
        mobile = procedural_spec(seed, "mobile_manipulator").compile()
        wheels = [n for n in (mobile.body(b).name for b in range(mobile.nbody)) if "wheel" in n]
        assert len(wheels) >= 2
        biped = procedural_plan(seed, "biped")
        assert biped.root.children[0].joints[0].type == "hinge"
        assert limbs(model_to_graph(procedural_spec(seed, "biped").compile())) == 2


def subtree(part: Part) -> str:
    """The ordered tree below ``part`` (its joints on top)."""
    return plan_tree(RobotPlan("x", "x", 0, part, False))


def find(part: Part, name: str) -> Part | None:
    return next((p for p, _ in part.walk() if p.name == name), None)


def test_humanoid_layouts_follow_real_files() -> None:
    """Pelvis root with the legs first (unitree) or last (talos); torso root with the waist
    chain ending in the pelvis and legs (t1, dm_control); the head before the arms mostly."""
    layouts, head_first = set(), []
    for seed in range(60):
        plan = procedural_plan(seed, "humanoid")
        names = [c.name for c in plan.root.children]
        if "left_arm0" not in [p.name for p, _ in plan.root.walk()]:
            continue
        if plan.root.name == "pelvis":
            legs = names.index("left_leg0")
            assert names[legs + 1] == "right_leg0"
            others = [n for n in names if "_leg" not in n and "sensor" not in n]
            first = names.index(others[0])
            layouts.add("legs_first" if legs < first else "upper_first")
        else:
            assert plan.root.name == "torso"
            pelvis = find(plan.root, "pelvis")
            assert pelvis is not find(plan.root, "torso") and pelvis.children
            assert [c.name for c in pelvis.children if "_leg" in c.name] == ["left_leg0",
                                                                                "right_leg0"]
            lower = next(k for k, c in enumerate(plan.root.children) if find(c, "pelvis"))
            arms = names.index("left_arm0")
            layouts.add("torso_root" if lower > arms else "torso_root_mid")
        holder = next(p for p, _ in plan.root.walk() if "left_arm0" in
                      [c.name for c in p.children])
        kids = [c.name for c in holder.children]
        if "neck0" in kids:
            head_first.append(kids.index("neck0") < kids.index("left_arm0"))
    assert layouts == {"legs_first", "upper_first", "torso_root", "torso_root_mid"}
    assert sum(head_first) > len(head_first) / 2 > 0


def test_reroot_keeps_the_robot_in_place() -> None:
    """Hanging a humanoid from its torso moves no geom and no joint anchor, and each joint
    stays on the edge between the same two bodies."""
    seed = next(s for s in range(100) if procedural_plan(s, "humanoid").root.name == "pelvis"
                and find(procedural_plan(s, "humanoid").root, "waist1"))
    plan = procedural_plan(seed, "humanoid")
    torso = next(p for p, _ in plan.root.walk() if find(p, "left_arm0") in p.children)
    at = {p.name: o for p, o in plan.root.walk()}[torso.name]
    geoms, anchors = world_geoms(plan.root, tuple(-x for x in at)), joint_anchors(plan.root)
    mass, n = plan.root.mass(), plan.num_joints
    root = reroot(plan.root, torso)
    assert root is torso and not root.joints and root.pos == (0.0, 0.0, 0.0)
    after = world_geoms(root)
    assert after.keys() == geoms.keys()
    for k, pts in geoms.items():
        assert np.allclose(after[k], pts, atol=1e-12), k
    moved = joint_anchors(root)
    assert moved.keys() == anchors.keys()
    for k, (pos, types) in anchors.items():
        assert np.allclose(moved[k][0], np.subtract(pos, at), atol=1e-12) and moved[k][1] == types
    assert root.mass() == pytest.approx(mass)
    assert sum(len(p.joints) for p, _ in root.walk()) == n
    with pytest.raises(ValueError):
        reroot(root, Part("elsewhere", (0.0, 0.0, 0.0)))


def test_hands_and_arms_are_mirrored() -> None:
    """Both hands of a humanoid and both arms of a mobile manipulator follow one plan; only
    arms with a wrist (5+ hinges) carry a hand."""
    kinds = set()
    for seed in range(80):
        root = procedural_plan(seed, "humanoid").root
        left, right = find(root, "left_arm0"), find(root, "right_arm0")
        if left is None:
            continue
        assert subtree(left) == subtree(right)
        chain = [p for p, _ in left.walk() if re.fullmatch(r"left_arm\d", p.name)]
        end = chain[-1]
        if end.children and end.children[0].name == "left_end_effector":
            end = end.children[0]
        if len(chain) < 5:
            assert not end.children
        elif end.children:
            kinds.add("fingers" if end.children[0].name.startswith("left_f") else "gripper")
        mobile = procedural_plan(seed, "mobile_manipulator").root
        if find(mobile, "arm_left_0"):
            assert subtree(find(mobile, "arm_left_0")) == subtree(find(mobile, "arm_right_0"))
    assert kinds == {"fingers", "gripper"}


def test_side_branches_and_sensor_bodies_come_first_or_last() -> None:
    """Cassie lists each rod before the chain's next body (``rods_first``); barkour_vb lists
    its welded sensor bodies before the legs (``sensor_slot``); both orders occur."""
    rods, slots = set(), set()
    for seed in range(40):
        pitch = procedural_plan(seed, "biped").root.children[0].children[0].children[0]
        names = [c.name for c in pitch.children]
        if "left_achilles" in names:
            rods.add(names.index("left_achilles") < names.index("left_knee"))
        names = [c.name for c in procedural_plan(seed, "quadruped").root.children]
        if "sensor0" in names:
            slots.add(names.index("sensor0") < names.index("FL_hip"))
    assert rods == {True, False} and slots == {True, False}


@pytest.mark.parametrize("kind", CLASSES)
def test_plan_tree_is_the_ordered_tree_of_the_graph(kind: str) -> None:
    for seed in range(6):
        graph = model_to_graph(procedural_spec(seed, kind).compile(), "full")
        assert plan_tree(procedural_plan(seed, kind)) == ordered_tree(links_and_joints(graph))


def test_deterministic_per_seed_and_names() -> None:
    for kind in (*CLASSES, None):
        assert procedural_spec(42, kind).to_xml() == procedural_spec(42, kind).to_xml()
    assert procedural_spec(1, "humanoid").to_xml() != procedural_spec(2, "humanoid").to_xml()
    assert procedural_spec(42, "quadruped").modelname == procedural_name("quadruped", 42) \
        == "proc_quadruped_00042"
    assert procedural_spec(5).modelname == procedural_name(draw_class(5, default_mix()), 5)


def test_batches_are_seeded_and_independent_of_workers() -> None:
    src = parse_procedural("n=70,seed=3")
    threads = torch.get_num_threads()
    serial = procedural_graphs(src, jobs=1)
    assert torch.get_num_threads() == threads  # built single-threaded, then restored
    parallel = procedural_graphs(src, jobs=2)
    other = procedural_graphs(parse_procedural("n=70,seed=4"), jobs=1)
    assert [g.name for g in serial] == [g.name for g in parallel]
    assert all(torch.equal(a.x, b.x) and torch.equal(a.parent, b.parent)
               for a, b in zip(serial, parallel))
    assert [g.name for g in serial] != [g.name for g in other]


def test_class_mix() -> None:
    mix = default_mix()
    assert set(mix) == set(CLASSES) and sum(mix.values()) == pytest.approx(1.0)
    drawn = [draw_class(s, mix) for s in range(4000)]
    for c, w in mix.items():
        assert drawn.count(c) / len(drawn) == pytest.approx(w, abs=0.03)
    src = parse_procedural("n=40,classes=quadruped+humanoid*3")
    assert src.mix == {"quadruped": 0.25, "humanoid": 0.75}
    kinds = {g.name.split("_")[1] for g in procedural_graphs(src, jobs=1)}
    assert kinds == {"quadruped", "humanoid"}
    # weights whose sum overflows a float are still a mix
    assert parse_procedural("classes=arm*1e308+humanoid*1e308").mix == {"arm": 0.5,
                                                                        "humanoid": 0.5}


@pytest.mark.parametrize("arg, message", [
    ("n=-1", "n=-1 is outside"),
    ("n=abc", "n='abc' is not an integer"),
    ("classes=dragon", "unknown procedural class 'dragon'"),
    ("n=5,size=3", "unknown option 'size'"),
    ("n=5,classes=arm*x", "weight 'x' of class 'arm'"),
    ("n=5,classes=arm*0", "needs a positive weight"),
    # accepted before 2026-11-29 (drawn as if the weight were ignored or the only one)
    ("n=5,classes=arm*nan+humanoid", "weight of procedural class 'arm' must be a finite "
                                     "number >= 0, got nan"),
    ("n=5,classes=arm*inf", "weight of procedural class 'arm' must be a finite"),
    ("n=5,classes=arm*-1+humanoid", "weight of procedural class 'arm' must be a finite"),
    ("n", "'n' is not key=value"),
])
def test_bad_specs_give_one_line_errors(arg: str, message: str, tmp_path: Path,
                                        capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(RobovaeError, match=message):
        parse_procedural(arg)
    with pytest.raises(RobovaeError, match=message):
        RobotDataset(tmp_path, [f"procedural:{arg}"], progress=False)
    assert main(["data", "--source", f"procedural:{arg}", "--root", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    with pytest.raises(ValueError):
        procedural_spec(0, "dragon")


def test_generator_settings_are_refused_in_one_line(tmp_path: Path) -> None:
    """Accepted until 2026-11-29: NaN, negative or reversed strength ranges compiled robots
    with such gears, a negative clearance sank them into the floor, a negative seed named a
    file ``proc_quadruped_-0001.xml``."""
    for bad, message in (({"gear": (math.nan, 2.0)}, "ProceduralConfig.gear must be a range"),
                         ({"gear": (3.0, 1.0)}, "ProceduralConfig.gear must be a range"),
                         ({"gear": (-2.0, -1.0)}, "ProceduralConfig.gear must be a range"),
                         ({"clearance": -1.0}, "ProceduralConfig.clearance must be a number")):
        with pytest.raises(ValueError, match=message):
            ProceduralConfig(**bad)
    with pytest.raises(ValueError, match="procedural robot.seed must be an integer >= 0"):
        procedural_spec(-1, "quadruped")
    with pytest.raises(ValueError, match="write_procedural.seed must be an integer >= 0"):
        write_procedural(tmp_path / "w", 2, seed=-1)
    assert not (tmp_path / "w").exists()
    # workers -5 and 2.5 ran in one process, jobs -1 too, until 2026-11-29
    for workers in (-5, 0, 2.5):
        with pytest.raises(ValueError, match="write_procedural.workers must be an integer >= 1"):
            write_procedural(tmp_path / "w", 2, workers=workers)
    assert not (tmp_path / "w").exists()
    with pytest.raises(ValueError, match="procedural_graphs.jobs must be an integer >= 0"):
        procedural_graphs(parse_procedural("n=2"), jobs=-1)


def inertia_tensors(g, fs: str) -> torch.Tensor:
    """``R diag(I) R^T`` of every node from ``link.iquat`` and ``link.inertia`` (float64)."""
    f = get_feature_set(fs)
    q = g.x[:, f.slice("link.iquat")].double().numpy()
    inertia = g.x[:, f.slice("link.inertia")].double().numpy()
    out = np.zeros((len(q), 3, 3))
    for i in range(len(q)):
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, q[i] / (np.linalg.norm(q[i]) or 1.0))
        r = rot.reshape(3, 3)
        out[i] = r @ np.diag(inertia[i]) @ r.T
    return torch.from_numpy(out)


def test_in_memory_graphs_equal_the_mjcf_files(tmp_path: Path) -> None:
    src = parse_procedural("n=14,seed=11")
    paths = write_procedural(tmp_path, 14, seed=11, workers=1)
    for fs in ("paper34", "full"):
        for g, path in zip(procedural_graphs(src, fs, jobs=1), paths):
            f = mjcf_to_graph(path, fs)
            assert g.name == f.name == path.stem
            for key in ("parent", "node_type", "x_mask", "depth"):
                assert torch.equal(g[key], f[key]), (path.name, key)
            # the file holds MuJoCo's 6 significant digits, the in-memory graph full values;
            # principal inertia axes are not unique when two moments (nearly) agree, so links
            # compare their inertia tensors, not ``link.iquat``
            sl = get_feature_set(fs).slice("link.iquat")
            keep = torch.ones(g.x.shape[1], dtype=torch.bool)
            keep[sl] = False
            assert torch.allclose(g.x[:, keep], f.x[:, keep], rtol=2e-4, atol=1e-6), path.name
            links = g.node_type == 0
            a, b = inertia_tensors(g, fs)[links], inertia_tensors(f, fs)[links]
            scale = a.abs().amax(dim=(1, 2), keepdim=True)
            assert torch.allclose(a / scale, b / scale, atol=1e-3), path.name


def test_dataset_caches_procedural_sources(tmp_path: Path) -> None:
    ds = RobotDataset(tmp_path, ["procedural:n=12,seed=2"], progress=False)
    assert len(ds) == 12 and ds.names[0] == procedural_name(draw_class(2, default_mix()), 2)
    again = RobotDataset(tmp_path, ["procedural:n=12,seed=2"], progress=False)
    assert again.processed_paths == ds.processed_paths
    assert torch.equal(again[5].x, ds[5].x)
    other = RobotDataset(tmp_path, ["procedural:n=12,seed=3"], progress=False)
    assert other.processed_paths != ds.processed_paths
    # the key holds a digest of the generator's code and ranges: a cache built by another
    # version of the generator is not reused
    assert parse_procedural("n=12,seed=2").key().endswith(f"_g{generator_digest()}")
    assert len(generator_digest()) == 12


def test_config_strength_and_actuators() -> None:
    strong = procedural_spec(0, "quadruped").compile()
    weak = procedural_spec(0, "quadruped", ProceduralConfig(gear=(0.001, 0.002))).compile()
    assert (weak.actuator_gear[:, 0] < 0.01 * strong.actuator_gear[:, 0]).all()
    assert procedural_spec(0, "quadruped", ProceduralConfig(actuators=False)).compile().nu == 0
    with pytest.raises(ValueError):
        ProceduralConfig(mix={"dragon": 1.0})


def test_write_skips_existing_files_and_is_atomic(tmp_path: Path) -> None:
    paths = write_procedural(tmp_path, 6, seed=3, classes=["quadruped", "humanoid"], workers=1)
    assert paths[0].read_text() == procedural_spec(3, paths[0].stem.split("_")[1]).to_xml()
    paths[0].write_text("keep me")
    again = write_procedural(tmp_path, 8, seed=3, classes=["quadruped", "humanoid"], workers=1)
    assert again[:6] == paths and paths[0].read_text() == "keep me"
    assert sorted(tmp_path.iterdir()) == sorted(again)  # no temporary files left behind


MENAGERIE = Path(__file__).resolve().parents[2].parent / "shared" / "menagerie"


@pytest.mark.skipif(not (MENAGERIE / "unitree_go2" / "go2.xml").is_file(),
                    reason="../shared/menagerie not present")
def test_quadrupeds_have_the_real_quadruped_tree() -> None:
    go2 = mjcf_to_graph(MENAGERIE / "unitree_go2" / "go2.xml", "full")
    quad = model_to_graph(procedural_spec(0, "quadruped").compile(), "full")
    assert shape_stats(quad) == shape_stats(go2) == {"nodes": 26, "links": 13, "joints": 13,
                                                      "dof": 18, "limbs": 4}
    assert tree_shape(links_and_joints(quad)) == tree_shape(links_and_joints(go2))
    assert tree_shape(links_and_joints(quad)) != tree_shape(
        links_and_joints(model_to_graph(procedural_spec(0, "hexapod").compile(), "full")))
    with pytest.raises(ValueError):
        shape_stats(model_to_graph(procedural_spec(0, "quadruped").compile(), "paper34"))


@pytest.mark.skipif(not (MENAGERIE / "unitree_go2" / "go2.xml").is_file(),
                    reason="../shared/menagerie not present")
def test_real_ordered_trees_are_drawn() -> None:
    """The generator draws the exact ordered trees of 14 of the 17 unseen robots among its
    first robots of each class (g1, n1 and talos are possible but rarer: docs/data.md)."""
    first = {"quadruped": 20, "humanoid": 1000, "biped": 200, "arm": 20,
             "mobile_manipulator": 1000}
    drawn = {kind: {plan_tree(procedural_plan(s, kind)) for s in range(n)}
             for kind, n in first.items()}
    missing = []
    for name, kind in MENAGERIE_CLASSES.items():
        path = next(p for p in (MENAGERIE / name).glob("*.xml") if "scene" not in p.name)
        if ordered_tree(mjcf_to_graph(path, "paper34")) not in drawn[kind]:
            missing.append(name)
    assert missing == ["fourier_n1", "pal_talos", "unitree_g1"]


def test_arm_end_effectors() -> None:
    """Arms end bare or in a gripper of each kind, after 0-2 welded flange bodies."""
    kinds, flanges = set(), set()
    for seed in range(60):
        root = procedural_plan(seed, "arm").root
        chain = [p for p, _ in root.walk() if re.fullmatch(r"link\d", p.name)]
        end, n = chain[-1], 0
        while any(c.name == f"linkflange{n}" for c in end.children):
            end = next(c for c in end.children if c.name == f"linkflange{n}")
            assert not end.joints
            n += 1
        flanges.add(n)
        names = [c.name for c in end.children]
        joints = [j.type for c in end.children for j in c.joints]
        if not names:
            kinds.add("bare")
        elif names == ["linkjaw"]:
            kinds.add("jaw")
        elif names == ["linkfinger0", "linkfinger1"]:
            kinds.add("slides" if joints == ["slide", "slide"] else "hinges")
        else:
            assert names[0] == "linkjaw0_outer0" and all(j == "hinge" for j in joints)
            kinds.add("linkage")
    assert kinds == {"bare", "slides", "hinges", "jaw", "linkage"} and flanges == {0, 1, 2}


def test_procedural_bodies_do_not_pass_through_each_other() -> None:
    # legs crossing under a quadruped (inward knees), arms hanging through a humanoid's hips,
    # a mobile manipulator's arm through its column or head: overlaps away from joints
    off = {s: attachment(procedural_spec(s)).off_joint_pairs for s in range(100)}
    assert sum(v > 0 for v in off.values()) <= 1, {s: v for s, v in off.items() if v}
