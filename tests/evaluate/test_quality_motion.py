"""Standing and locomotion measures (robovae.evaluate.quality) on real MuJoCo robots."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from mujoco import rollout

from robovae.data.procedural import ProceduralConfig, procedural_spec
from robovae.errors import RobovaeError
from robovae.evaluate.quality import anatomy, attachment, gait, gait_speed, stage, standing
from robovae.evaluate.quality.locomotion import (
    actuated_base,
    continuous_actuators,
    sinusoid_controls,
)
from robovae.evaluate.quality.measure import measure
from robovae.evaluate.quality.stage import prepare, rest_pose, robot_points, stage_compiled
from robovae.evaluate.quality.standing import HeldRun, first_steps
from robovae.generate.validate import check_robot

FAST = {"rollouts": 8, "seconds": 2.0}


def stick(lean: float = 0.03, actuated: bool = False) -> mujoco.MjSpec:
    """A 1 m stick on a round foot with a 5 kg ball on top, leaning ``lean`` m sideways."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="stick", pos=[0, 0, 0.05])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.05, 0, 0],
                  fromto=[0, 0, 0, lean, 0, 1.0], mass=0.5)
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0], pos=[lean, 0, 1.0],
                  mass=5.0)
    if actuated:
        arm = body.add_body(name="arm", pos=[lean, 0, 1.0])
        arm.add_joint(name="swing", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
        arm.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.03, 0, 0],
                     fromto=[0, 0, 0, 0.3, 0, 0], mass=0.2)
        spec.add_actuator(target="swing", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    return spec


def test_a_quadruped_stands_and_a_top_heavy_stick_falls() -> None:
    quad = standing(procedural_spec(2, "quadruped"))
    assert quad.floating and quad.stands and quad.up and quad.upright and not quad.unstable
    assert quad.fell_at is None and quad.settled  # at rest after 1 s: stopped early
    assert quad.seconds == pytest.approx(1.0, abs=0.01)
    assert quad.min_height_ratio >= 0.5 and quad.max_tilt <= 45
    fell = standing(stick())
    assert fell.floating and fell.stands is False and fell.upright is False
    assert 0 < fell.fell_at < 3.0 and fell.max_tilt > 45


def test_stopping_early_does_not_change_the_verdict() -> None:
    """At rest or fallen, the rest of the 3 s cannot change the outcome."""
    for robot in [procedural_spec(s, k) for s in range(3) for k in ("quadruped", "humanoid")]:
        early, full = standing(robot), standing(robot, rest=0.0, chunk_seconds=3.0)
        assert full.seconds == pytest.approx(3.0, abs=0.01) and not full.settled
        assert early.stands == full.stands and early.fell_at == full.fell_at
        if early.stands:
            assert early.height_ratio == pytest.approx(full.height_ratio, abs=0.01)


def test_a_robot_at_rest_sleeps_and_each_sleeping_segment_starts_awake() -> None:
    """After the first second MuJoCo's sleeping freezes a held robot at rest (velocities exactly
    zero); a new segment from a pose in the air falls, whatever the last segment left."""
    held = HeldRun(stage(procedural_spec(2, "quadruped")))
    nq, nv = held.model.nq, held.model.nv
    held.run(first_steps(held.model))
    states, _ = held.run(250, sleep=1e-3)
    assert held.stage.data.ntree_awake == 0 and not states[-1, 1 + nq:1 + nq + nv].any()
    lifted = held.start.copy()
    lifted[1 + 2] += 0.1  # the free joint's z, zero velocity: a tree that may sleep at once
    held.state = lifted
    z = held.run(50, sleep=1e-3)[0][:, 1 + 2]
    assert z[-1] < z[0] - 0.01  # fell: not left asleep by the segment before
    assert standing(stick()).fell_at == standing(stick(), rest=0.0).fell_at  # falling: awake


def test_standing_accepts_a_model_with_a_floor_and_leaves_it_unchanged() -> None:
    spec, _ = prepare(procedural_spec(2, "quadruped"))
    model = spec.compile()
    stiffness = model.jnt_stiffness.copy()
    assert standing(model).stands
    assert (model.jnt_stiffness == stiffness).all() and model.nu == 12
    with pytest.raises(RobovaeError, match="no floor"):
        standing(procedural_spec(2, "quadruped").compile())


@pytest.mark.parametrize("bad, message", [
    # a verdict on nothing, a NaN verdict or a traceback until 2026-11-29
    ({"seconds": -1.0}, "standing.seconds must be a number > 0, got -1.0"),
    ({"seconds": math.nan}, "standing.seconds must be a number > 0, got nan"),
    ({"stiffness": -1.0}, "standing.stiffness must be a number >= 0"),
    ({"max_tilt": -5.0}, r"standing.max_tilt must be a number in \[0, 180\]"),
    ({"max_steps": 0}, "standing.max_steps must be an integer >= 1, got 0"),
])
def test_standing_refuses_settings_out_of_range(bad: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message) as e:
        standing(procedural_spec(1, "quadruped"), **bad)
    assert "\n" not in str(e.value)


def test_attachment_and_anatomy_refuse_settings_out_of_range() -> None:
    """A negative or NaN gap judged every body attached until 2026-11-29."""
    quad = procedural_spec(1, "quadruped")
    for bad in ({"gap": -1.0}, {"gap": math.nan}, {"tolerance": -0.1}):
        with pytest.raises(ValueError, match=f"attachment.{next(iter(bad))} must be a number"):
            attachment(quad, **bad)
    with pytest.raises(ValueError, match="anatomy.tolerance must be a number >= 0, got nan"):
        anatomy(quad, tolerance=math.nan)


def test_standing_skips_a_robot_without_a_free_root() -> None:
    spec = stick()
    spec.delete(spec.joints[0])
    r = standing(spec)
    assert r.floating is False and r.stands is None


def test_gait_speed_is_seeded_and_a_weak_robot_moves_less() -> None:
    strong = gait(procedural_spec(2, "quadruped"), **FAST)
    again = gait(procedural_spec(2, "quadruped"), **FAST)
    other = gait(procedural_spec(2, "quadruped"), seed=1, **FAST)
    weak = gait(procedural_spec(2, "quadruped", ProceduralConfig(gear=(0.001, 0.002))), **FAST)
    assert strong.speed == again.speed and strong.speed != other.speed
    assert strong.rollouts == 8 and strong.unstable == 0 and strong.seconds == pytest.approx(2)
    assert strong.speed == pytest.approx(strong.speed_m_s / strong.extent)
    assert strong.amplitude.shape == (12,) and 0.5 <= strong.frequency <= 3.0
    assert weak.speed < 0.25 * strong.speed
    # what the best gait spends: mechanical power (W) while its distance counts
    assert strong.power > 0 and strong.mass == pytest.approx(
        procedural_spec(2, "quadruped").compile().body_subtreemass[1])
    assert weak.power < 0.01 * strong.power
    assert gait_speed(procedural_spec(2, "quadruped"), **FAST) == strong.speed


def test_a_gait_that_falls_stops_counting() -> None:
    quad = procedural_spec(2, "quadruped")
    free = gait(quad, **FAST)
    assert gait(quad, max_tilt=180.0, **FAST).speed == free.speed  # never falls
    # the root tilts a little from the first sample on: with a 0° bound it has always fallen
    assert gait(quad, max_tilt=0.0, **FAST).speed == 0.0
    assert 0.0 <= gait(quad, max_tilt=20.0, **FAST).speed <= free.speed


def gantry() -> mujoco.MjSpec:
    """A 0.2 m box on x and z slides to the world, each with a motor: its root is moved by its
    own motors."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="cart", pos=[0, 0, 0.1])
    for name in ("x", "z"):
        body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE,
                       axis=[1, 0, 0] if name == "x" else [0, 0, 1])
        spec.add_actuator(target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT).gear[0] = 20.0
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1], mass=1.0)
    return spec


def cart(lift_gear: float) -> mujoco.MjSpec:
    """A box on passive x and z slides to the world, rolled by a motorised wheel (damped, so
    that a constant torque turns it at a bounded speed); a piston on a vertical slide with a
    motor of gear ``lift_gear`` (control range ``[0.9, 1]``) pushes on the floor whatever the
    gait and, when strong, lifts the cart off it (standing in for numerical energy)."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="cart", pos=[0, 0, 0.15])
    for name, axis in (("x", [1, 0, 0]), ("z", [0, 0, 1])):
        body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.05], mass=1.0)
    wheel = body.add_body(name="wheel", pos=[0, 0, -0.05])
    wheel.add_joint(name="roll", axis=[0, 1, 0]).damping[0] = 0.5
    wheel.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.1, 0, 0],
                   fromto=[0, 0.11, 0, 0, 0.16, 0], mass=0.3)
    piston = body.add_body(name="piston", pos=[0.15, 0, -0.05])
    piston.add_joint(name="push", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, -1])
    piston.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.02, 0.02], mass=0.1)
    spec.add_actuator(target="roll", trntype=mujoco.mjtTrn.mjTRN_JOINT).gear[0] = 5.0
    act = spec.add_actuator(target="push", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.gear[0] = lift_gear
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.ctrlrange = [0.9, 1.0]
    return spec


def test_a_rollout_that_flies_does_not_count() -> None:
    """The centre of mass may not rise more than half the extent: lifted gaits score 0 and
    count as unstable, the same cart held down moves."""
    grounded, flying = gait(cart(0.0), **FAST), gait(cart(200.0), **FAST)
    assert grounded.speed > 0 and grounded.unstable == 0
    assert flying.speed == 0.0 and flying.unstable == FAST["rollouts"]


def _rolled(model: mujoco.MjModel, r, offset) -> float:
    """Horizontal distance (m) the cart's root covers under gait ``r`` with ``offset``."""
    steps = round(r.seconds / model.opt.timestep)
    ctrl = sinusoid_controls(model, r.amplitude[None], r.phase[None],
                             np.array([r.frequency]), steps, offset[None])
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    states, _ = rollout.rollout(model, data, state[None], ctrl, nstep=steps)
    return abs(float(states[0, -1, 1] - states[0, 0, 1]))  # qpos[0]: the x slide


def test_a_wheel_is_turned_not_only_rocked() -> None:
    """The motor of an unlimited hinge gets a constant offset in each gait, so the cart rolls
    on; a sinusoid alone rocks its wheel about its rest angle. Other actuators get none."""
    model = cart(0.0).compile()
    assert continuous_actuators(model).tolist() == [True, False]
    assert not continuous_actuators(procedural_spec(2, "quadruped").compile()).any()
    assert not continuous_actuators(gantry().compile()).any()  # slides
    thruster = mujoco.MjSpec()  # a site transmission on a model without joints
    body = thruster.worldbody.add_body(name="b")
    body.add_geom(size=[0.1, 0, 0])
    body.add_site(name="s")
    thruster.add_actuator(target="s", trntype=mujoco.mjtTrn.mjTRN_SITE).gear[2] = 1.0
    assert continuous_actuators(thruster.compile()).tolist() == [False]
    r = gait(cart(0.0), **FAST)
    assert r.offset[0] != 0.0 and r.offset[1] == 0.0
    assert _rolled(model, r, r.offset) > 3 * _rolled(model, r, np.zeros(2))
    quad = gait(procedural_spec(2, "quadruped"), **FAST)
    assert not quad.offset.any()
    # controls stay in the actuators' ranges; a zero offset leaves the sinusoids untouched
    amp, phase = np.ones((4, 2)), np.zeros((4, 2))
    freq, off = np.ones(4), np.array([[1.0, 0.0]] * 4)
    ctrl = sinusoid_controls(model, amp, phase, freq, 600, off)
    assert ctrl[..., 0].max() == 1.0 and ctrl[..., 0].min() == pytest.approx(0.0, abs=1e-3)
    assert ctrl[..., 1].min() >= 0.9 and ctrl[..., 1].max() <= 1.0
    assert np.array_equal(sinusoid_controls(model, amp, phase, freq, 600, 0 * off),
                          sinusoid_controls(model, amp, phase, freq, 600))


def test_a_robot_moved_by_a_motor_on_its_root_does_not_walk() -> None:
    """Motors on the joints between the root and the world make a gantry: speed 0; the same
    slides unactuated (a planar robot) are walked by the robot's other motors."""
    model = gantry().compile()
    assert actuated_base(model, 1) and not actuated_base(cart(0.0).compile(), 1)
    r = gait(gantry(), **FAST)
    assert r.actuated_base and r.speed == 0.0 and r.unstable == 0


def test_a_robot_without_actuators_does_not_move() -> None:
    r = gait(stick(), **FAST)
    assert r.speed == 0.0 and math.isnan(r.frequency) and r.power == 0.0
    assert gait(stick(actuated=True), **FAST).frequency > 0


def test_stage_measures_the_robot_not_the_floor() -> None:
    st = stage(stick(lean=0.0))
    # box around the stick: 0.2 m wide (ball), from z = 0 (foot) to 1.15 m (ball top)
    assert st.extent == pytest.approx(math.sqrt(0.2 ** 2 + 0.2 ** 2 + 1.15 ** 2), rel=1e-6)
    assert st.free and st.floor_z == pytest.approx(0.0, abs=1e-9)


def test_rest_pose_is_the_home_keyframe_within_joint_ranges(menagerie_dir) -> None:
    go2 = menagerie_dir / "unitree_go2" / "go2.xml"
    model = stage(go2).model
    home = model.key_qpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")]
    assert (rest_pose(model) == home).all()
    # Go2's qpos0 bends its knees outside their range: held at qpos0 it would fold over
    assert model.qpos0[9] > model.jnt_range[3, 1]
    assert standing(go2).stands
    spec = stick(actuated=True)
    spec.joints[1].range = [0.5, 1.0]
    spec.joints[1].limited = mujoco.mjtLimited.mjLIMITED_TRUE
    m = spec.compile()
    assert m.qpos0[7] == 0 and rest_pose(m)[7] == m.jnt_range[1, 0] > 0  # clipped into range


def test_the_floor_goes_under_the_clipped_rest_pose(tmp_path) -> None:
    """A joint whose range excludes its qpos0 starts clipped into its range (rest_pose): the
    floor goes under that pose, where the standing test starts, not under qpos0."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    body = spec.worldbody.add_body(name="trunk", pos=[0, 0, 1.0])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0])
    leg = body.add_body(name="leg")
    leg.add_joint(name="hip", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0], range=[1.0, 1.5],
                  limited=mujoco.mjtLimited.mjLIMITED_TRUE)
    leg.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.02, 0, 0],
                 fromto=[0, 0, 0, 0, 0, -0.5])
    path = tmp_path / "leg.xml"
    path.write_text(spec.to_xml())
    st = stage(path)
    lowest = {}
    for name, q in (("qpos0", st.model.qpos0), ("rest", rest_pose(st.model))):
        data = mujoco.MjData(st.model)
        data.qpos[:] = q
        mujoco.mj_kinematics(st.model, data)
        lowest[name] = float(robot_points(st.model, data, st.root)[:, 2].min())
    assert lowest["rest"] > lowest["qpos0"] + 0.1  # the leg swung up by 1 rad
    assert st.floor_z == pytest.approx(lowest["rest"], abs=1e-9)
    checked = check_robot(path)  # the validator's model, staged without loading again
    assert stage_compiled(checked.model, checked.spec, checked.floor, checked.data).floor_z \
        == pytest.approx(lowest["rest"], abs=1e-9)


def test_the_validators_model_gives_the_same_measures(tmp_path) -> None:
    """robovae generate measures the model the validator compiled (floor at z = 0, moved to
    the robot's lowest point): the same records as measuring the file from scratch."""
    for k, spec in enumerate([procedural_spec(2, "quadruped"), procedural_spec(1, "humanoid")]):
        spec.body(spec.bodies[1].name).pos[2] += 0.3  # floating above z = 0
        path = tmp_path / f"robot{k}.xml"
        path.write_text(spec.to_xml())
        checked = check_robot(path)
        assert checked.validation.valid and checked.floor is not None
        st = stage_compiled(checked.model, checked.spec, checked.floor, checked.data)
        assert st.floor_z == stage(path).floor_z > 0.2
        fresh, reused = measure(path), measure(st)
        same = [k for k in fresh if not k.startswith("t_") and k not in ("name", "path")]
        assert "stands" in same and "error" not in same
        assert {k: fresh[k] for k in same} == {k: reused[k] for k in same}
        # the standing test simulated on the stage's data and left it at rest
        assert st.data.time == 0 and (st.data.qpos == st.model.qpos0).all()


def test_a_near_singular_robot_is_measured_without_printing_mujoco_warnings(
        tmp_path, monkeypatch, capfd) -> None:
    """Two hinges with one axis in one body make the inertia matrix singular: MuJoCo warns at
    every ``mj_forward``. The measures and scores judge such a robot; MuJoCo's message must
    not reach the terminal or a ``MUJOCO_LOG.TXT`` in the working directory."""
    from robovae.design.score import score_robot
    from robovae.evaluate.quality.attachment import attachment

    spec = stick(actuated=True)
    spec.body("arm").add_joint(name="twin", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    spec.add_actuator(target="twin", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    spec.compile()
    path = tmp_path / "robot.xml"
    path.write_text(spec.to_xml())
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    monkeypatch.chdir(tmp_path)
    mujoco.set_mju_user_warning(lambda msg: None)  # this check's own forward stays quiet
    try:
        mujoco.mj_forward(model, data)
    finally:
        mujoco.set_mju_user_warning(None)
    assert data.warning[mujoco.mjtWarning.mjWARN_INERTIA].number  # the robot does warn
    capfd.readouterr()
    gait(path, rollouts=2, seconds=0.2)
    standing(path)
    attachment(path)
    check_robot(path)
    for task in ("walk", "stand", "reach"):
        score_robot(path, task)
    out, err = capfd.readouterr()
    assert "WARNING" not in out + err
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
