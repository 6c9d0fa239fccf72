"""Motors of continuous joints: a DC motor's torque-speed line (robovae.data.actuators)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from robovae.data.actuators import NO_LOAD_SPEED, joint_strength, speed_limited, torque_limits
from robovae.data.procedural import procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.locomotion import continuous_actuators


def wheel(gear: float, dc: bool) -> mujoco.MjModel:
    """A 0.1 m disc on a hinge without limits (fixed base, no damping), one motor."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="wheel")
    body.add_joint(name="spin", axis=[0, 0, 1])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.1, 0.02, 0], mass=0.5)
    act = spec.add_actuator(target="spin", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.gear[0] = gear
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.ctrlrange = [-1.0, 1.0]
    if dc:
        speed_limited(act, gear)
    return spec.compile()


def top_speed(model: mujoco.MjModel, u: float, seconds: float = 2.0) -> float:
    data = mujoco.MjData(model)
    data.ctrl[:] = u
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return float(data.qvel[0])


def test_a_dc_motor_stops_at_its_no_load_speed_with_the_same_strength() -> None:
    dc, plain = wheel(5.0, True), wheel(5.0, False)
    assert top_speed(dc, 1.0) == pytest.approx(NO_LOAD_SPEED, rel=0.02)
    assert top_speed(dc, -0.5) == pytest.approx(-0.5 * NO_LOAD_SPEED, rel=0.02)
    assert top_speed(plain, 1.0) > 10 * NO_LOAD_SPEED  # a plain motor spins on and on
    # the same strength as the plain motor: stall torque = gear, in both strength measures
    assert joint_strength(dc)[0] == joint_strength(plain)[0] == 5.0
    assert torque_limits(dc)[0] == torque_limits(plain)[0] == 5.0
    data = mujoco.MjData(dc)
    data.ctrl[:] = 1.0
    mujoco.mj_forward(dc, data)
    assert data.qfrc_actuator[0] == pytest.approx(5.0)  # full torque at standstill


def test_wheels_get_dc_motors_and_joints_with_a_range_plain_ones() -> None:
    model = procedural_spec(0, kind="mobile_manipulator").compile()
    wheels = continuous_actuators(model)
    assert wheels.any() and not wheels.all()
    affine = model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
    assert np.array_equal(affine, wheels)
    gear = model.actuator_gear[wheels, 0]
    assert model.actuator_biasprm[wheels, 2] == pytest.approx(-1.0 / (gear * NO_LOAD_SPEED))


def test_torque_limits_and_strength_by_hand() -> None:
    """Joint torque an actuator can give: gear · gain · ctrl for a motor, gear · forcerange;
    a position servo is not limited by its control range (``torque_limits``) but its strength
    is kp times half its control range (``joint_strength``), both capped by forcerange."""
    xml = """<mujoco><worldbody><body>
      <joint name="j0" type="hinge"/><joint name="j1" type="hinge" axis="1 0 0"/>
      <joint name="j2" type="hinge" axis="0 1 0"/><joint name="j3" type="slide"/>
      <joint name="j4" type="slide" axis="1 0 0"/>
      <geom size="0.1"/></body></worldbody>
    <actuator>
      <motor joint="j0" gear="2" ctrlrange="-3 3"/>
      <general joint="j1" gainprm="5" gear="2" ctrlrange="-1 3"/>
      <position joint="j2" kp="100" ctrlrange="-1 1"/>
      <position joint="j3" kp="100" gear="3" forcerange="-2 2"/>
      <motor joint="j4" gear="10" ctrlrange="-1 1" forcerange="-4 4"/>
    </actuator></mujoco>"""
    lim = torque_limits(mujoco.MjModel.from_xml_string(xml))
    assert lim[0] == pytest.approx(6.0)
    assert lim[1] == pytest.approx(30.0)
    assert lim[2] == math.inf
    assert lim[3] == pytest.approx(6.0)
    assert lim[4] == pytest.approx(min(10.0, 40.0))
    strength = joint_strength(mujoco.MjModel.from_xml_string(xml))
    assert strength == pytest.approx([6.0, 30.0, 100.0, 6.0, 10.0])
    # the gymnasium humanoid's motors (gain 1): gear (25 ... 300) · ctrlrange ±0.4
    model = mujoco.MjModel.from_xml_path(str(dict(zoo_files()[0])["gym_humanoid"]))
    assert torque_limits(model) == pytest.approx(
        {int(model.actuator_trnid[a, 0]): 0.4 * model.actuator_gear[a, 0]
         for a in range(model.nu)})
    assert torque_limits(model)[1] == pytest.approx(40.0)  # abdomen_y: gear 100
