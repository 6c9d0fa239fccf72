"""How strong each joint's actuators are, whatever convention the file uses.

MJCF files express the same motor in several ways: ``gear="300" ctrlrange="-1 1"``,
``gear="1" ctrlrange="-300 300"``, or a position servo ``kp="500"`` whose force is limited by
``forcerange`` or not at all. The **strength** of a joint is the largest force (N·m for a hinge
or ball, N for a slide) its actuators (joint transmission) can apply, summed over them:

- motor-like (fixed gain, no bias): ``|gear · gain| · max|ctrlrange|`` when the control is
  limited (``actrange`` for an integrator);
- servo (fixed gain, affine bias): ``|gear| · kp · h`` with ``h`` the half-width of its control
  range, else of the joint's range (the force it applies a range away from its target);
- either is capped by ``|gear| · max|forcerange|`` when force-limited; an actuator bounded by
  nothing counts 0 (unknown).

``kinematic`` graphs carry it as ``joint.torque``, and the writer gives each actuated joint a
motor of that gear with control range ``(-1, 1)``. The standing test's hold may not exceed
what the actuators can give (:func:`torque_limits`): the same bounds, but a servo counts only
its ``forcerange`` and an unbounded actuator makes its joint's limit ``inf``.

**Continuous joints** (hinges without limits: wheels, rotors) get a DC motor's torque–speed
line (:func:`speed_limited`): ``τ = g (u − q̇ / ω₀)``, the control ``u ∈ [-1, 1]``, stall torque
``g`` (the gear), no-load speed ``ω₀`` = :data:`NO_LOAD_SPEED`; the force is also capped at the
stall torque (``forcerange [-1, 1]``), so its strength above stays ``g``. MuJoCo's plain motor
gives its torque at any speed, and a joint without range then spins up until only its damping
holds it (generated paddles reached 300 rad/s, 1.2 kW per kg of robot). Joints with a range
keep plain motors: the range bounds their travel.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

__all__ = ["NO_LOAD_SPEED", "actuator_force", "joint_strength", "speed_limited", "torque_limits"]

#: No-load speed (rad/s) of the motor of a continuous joint: generous beside real wheels
#: (TIAGo's and Husky's turn at 6–10 rad/s at top speed).
NO_LOAD_SPEED = 20.0

_TRN_JOINT = int(mujoco.mjtTrn.mjTRN_JOINT)
_GAIN_FIXED = int(mujoco.mjtGain.mjGAIN_FIXED)
_BIAS_NONE = int(mujoco.mjtBias.mjBIAS_NONE)
_BIAS_AFFINE = int(mujoco.mjtBias.mjBIAS_AFFINE)
_DYN_INTEGRATOR = int(mujoco.mjtDyn.mjDYN_INTEGRATOR)


def _half(lo_hi: np.ndarray) -> float:
    return 0.5 * float(abs(lo_hi[1] - lo_hi[0]))


def actuator_force(model: mujoco.MjModel, a: int, servos: bool = True) -> float:
    """The largest force actuator ``a``, of joint transmission, can put on its joint (module
    docstring), ``inf`` when nothing bounds it: a servo counts ``|gear| · kp · h`` when
    ``servos``, else (and when it has no span ``h``) only its ``forcerange``; an actuator of
    another kind only its ``forcerange``."""
    gear = abs(float(model.actuator_gear[a, 0]))
    gain = abs(float(model.actuator_gainprm[a, 0]))
    force = math.inf
    if model.actuator_gaintype[a] == _GAIN_FIXED and model.actuator_biastype[a] == _BIAS_NONE:
        if model.actuator_dyntype[a] == _DYN_INTEGRATOR:
            if model.actuator_actlimited[a]:
                force = gear * gain * float(np.abs(model.actuator_actrange[a]).max())
        elif model.actuator_ctrllimited[a]:
            force = gear * gain * float(np.abs(model.actuator_ctrlrange[a]).max())
    elif (servos and model.actuator_gaintype[a] == _GAIN_FIXED
          and model.actuator_biastype[a] == _BIAS_AFFINE):
        j = int(model.actuator_trnid[a, 0])
        span = _half(model.actuator_ctrlrange[a]) if model.actuator_ctrllimited[a] \
            else _half(model.jnt_range[j]) if model.jnt_limited[j] else 0.0
        force = gear * gain * span if span > 0 else math.inf
    if model.actuator_forcelimited[a]:  # forcerange clamps the force before the gear
        force = min(force, gear * float(np.abs(model.actuator_forcerange[a]).max()))
    return force


def _joint_actuators(model: mujoco.MjModel) -> list[tuple[int, int]]:
    """``(actuator, joint)`` of every actuator with a joint transmission."""
    return [(a, int(model.actuator_trnid[a, 0])) for a in range(model.nu)
            if model.actuator_trntype[a] == _TRN_JOINT]


def joint_strength(model: mujoco.MjModel) -> np.ndarray:
    """Strength of every joint ``[njnt]``: the sum of its actuators'
    :func:`actuator_force`, an unbounded one counting 0 (unknown); 0 without an actuator."""
    out = np.zeros(model.njnt)
    for a, j in _joint_actuators(model):
        force = actuator_force(model, a)
        out[j] += force if math.isfinite(force) else 0.0
    return out


def torque_limits(model: mujoco.MjModel) -> dict[int, float]:
    """The largest force the robot's own actuators can put on each joint they drive through a
    joint transmission, for a hold that must not exceed it: the sum of their
    :func:`actuator_force` without servo spans (a servo's force is bounded by its
    ``forcerange`` only), ``inf`` when any of them is unbounded."""
    out: dict[int, float] = {}
    for a, j in _joint_actuators(model):
        out[j] = out.get(j, 0.0) + actuator_force(model, a, servos=False)
    return out


def speed_limited(actuator: mujoco.MjsActuator, gear: float,
                  no_load_speed: float = NO_LOAD_SPEED) -> None:
    """Make a joint motor of gear ``gear`` (control range ``(-1, 1)``) a DC motor (module
    docstring): force ``u − v / (g ω₀)`` on the actuator velocity ``v = g q̇`` (MuJoCo's affine
    bias, ``biasprm[2]``), capped at ``±1`` (torque ``±g``)."""
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.biasprm = [0.0, 0.0, -1.0 / (abs(gear) * no_load_speed)] + [0.0] * 7
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = [-1.0, 1.0]
