"""Motors of continuous joints: a DC motor's torque-speed line (robovae.data.actuators)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robovae.data.actuators import NO_LOAD_SPEED, joint_strength, speed_limited
from robovae.data.procedural import procedural_spec
from robovae.evaluate.quality.locomotion import continuous_actuators
from robovae.evaluate.quality.standing import torque_limits


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
