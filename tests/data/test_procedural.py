"""Tests of the procedural legged-robot generator."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from robovae.data.procedural import (
    KINDS,
    ProceduralConfig,
    procedural_name,
    procedural_plan,
    procedural_spec,
    write_procedural,
)

HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
FREE = int(mujoco.mjtJoint.mjJNT_FREE)


def simulate_on_floor(path: Path, seconds: float = 1.0) -> mujoco.MjData:
    """Load a robot file, add a floor to a copy of its spec and simulate."""
    spec = mujoco.MjSpec.from_file(str(path))
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[:] = np.random.default_rng(0).uniform(-1, 1, model.nu)
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return data


def test_deterministic_per_seed() -> None:
    for kind in (*KINDS, None):
        assert procedural_spec(42, kind).to_xml() == procedural_spec(42, kind).to_xml()
    assert procedural_spec(1, "legged").to_xml() != procedural_spec(2, "legged").to_xml()
    assert procedural_plan(3) == procedural_plan(3)


def test_names() -> None:
    assert procedural_spec(42, "quadruped").modelname == "proc_quadruped_00042"
    assert procedural_name("hexapod", 7) == "proc_hexapod_00007"
    assert procedural_spec(5).modelname.startswith("proc_")


@pytest.mark.parametrize("kind", KINDS)
def test_counts_match_the_plan(kind: str) -> None:
    for seed in range(10):
        plan = procedural_plan(seed, kind)
        model = procedural_spec(seed, kind).compile()
        assert model.nbody == 2 + plan.num_segments  # world, torso, segments
        assert model.njnt == 1 + plan.num_hinges
        assert model.nu == plan.num_hinges
        assert model.jnt_type[0] == FREE and (model.jnt_type[1:] == HINGE).all()
        roles = plan.roles()
        if kind == "quadruped":
            assert roles == {"leg": 4}
        elif kind == "hexapod":
            assert roles == {"leg": 6}
        elif kind == "humanoid":
            assert roles == {"leg": 2, "arm": 2, "head": 1}
        else:
            assert set(roles) == {"leg"} and 2 <= roles["leg"] <= 8
        # every limb hangs off the torso; every segment body has 1-2 hinges
        assert int((model.body_parentid == 1).sum()) == plan.num_limbs
        per_body = np.bincount(model.jnt_bodyid[1:], minlength=model.nbody)[2:]
        assert ((per_body >= 1) & (per_body <= 2)).all()


def test_config_controls_the_limbs() -> None:
    cfg = ProceduralConfig(legged_legs=(5, 5), leg_segments=(3, 3), two_hinge_prob=0.0,
                           actuators=False)
    plan = procedural_plan(0, "legged", cfg)
    model = procedural_spec(0, "legged", cfg).compile()
    assert plan.roles() == {"leg": 5}
    assert model.nbody == 2 + 5 * 3 and model.njnt == 1 + 5 * 3 and model.nu == 0
    two = procedural_spec(0, "quadruped", ProceduralConfig(two_hinge_prob=1.0)).compile()
    assert np.bincount(two.jnt_bodyid[1:], minlength=two.nbody)[2:].tolist() == [2] * (
        two.nbody - 2)
    with pytest.raises(ValueError):
        ProceduralConfig(kinds=("snake",))
    with pytest.raises(ValueError):
        procedural_spec(0, "snake")


def test_joints_and_actuators_are_well_formed() -> None:
    for kind in KINDS:
        model = procedural_spec(11, kind).compile()
        hinges = np.arange(1, model.njnt)
        assert model.jnt_limited[hinges].all()
        lo, hi = model.jnt_range[hinges].T
        assert (lo < 0).all() and (hi > 0).all()
        axes = np.abs(model.jnt_axis[hinges])
        assert np.allclose(np.sort(axes, axis=1), [0, 0, 1])  # x, y or z
        dofs = model.jnt_dofadr[hinges]
        assert (model.dof_damping[dofs] > 0).all() and (model.dof_armature[dofs] > 0).all()
        # one motor per hinge, limited controls, positive gear
        assert sorted(model.actuator_trnid[:, 0].tolist()) == hinges.tolist()
        assert model.actuator_ctrllimited.all() and (model.actuator_gear[:, 0] > 0).all()
        assert (model.body_mass[1:] > 0).all()
        geom_types = set(model.geom_type.tolist())
        assert int(mujoco.mjtGeom.mjGEOM_SPHERE) in geom_types  # feet / head
        assert geom_types <= {int(mujoco.mjtGeom.mjGEOM_SPHERE),
                              int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_BOX)}


def test_files_compile_and_simulate(tmp_path: Path) -> None:
    paths = write_procedural(tmp_path, 32, seed=100, workers=1)  # 8 robots of each kind
    assert len(paths) == 32 and all(p.exists() for p in paths)
    assert {p.name.split("_")[1] for p in paths} == set(KINDS)
    for path in paths:
        model = mujoco.MjModel.from_xml_path(str(path))
        assert model.names.split(b"\0")[0].decode() == path.stem  # model name = file stem
        # only the robot: one top-level body, no floor / extra world geoms
        assert int((model.body_parentid[1:] == 0).sum()) == 1
        assert int((model.geom_bodyid == 0).sum()) == 0
        data = simulate_on_floor(path)
        assert np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all(), path.name
        assert not any(w.number for w in data.warning), path.name
        assert data.qpos[2] > 0.0, path.name  # did not fall through the floor


def test_write_skips_existing_files_and_is_atomic(tmp_path: Path) -> None:
    paths = write_procedural(tmp_path, 6, seed=3, kinds=["quadruped", "humanoid"], workers=1)
    assert [p.name for p in paths[:2]] == ["proc_quadruped_00003.xml", "proc_humanoid_00004.xml"]
    assert paths[0].read_text() == procedural_spec(3, "quadruped").to_xml()
    paths[0].write_text("keep me")
    again = write_procedural(tmp_path, 8, seed=3, kinds=["quadruped", "humanoid"], workers=1)
    assert again[:6] == paths and paths[0].read_text() == "keep me"
    assert sorted(tmp_path.iterdir()) == sorted(again)  # no temporary files left behind


def test_parallel_write_matches_serial(tmp_path: Path) -> None:
    serial = write_procedural(tmp_path / "a", 12, seed=9, workers=1)
    parallel = write_procedural(tmp_path / "b", 12, seed=9, workers=2)
    assert [p.name for p in serial] == [p.name for p in parallel]
    assert all(a.read_text() == b.read_text() for a, b in zip(serial, parallel))
