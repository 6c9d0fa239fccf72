"""A :class:`~robovae.data.procedural.blueprint.RobotPlan` → ``mujoco.MjSpec`` (no XML).

``worldbody`` holds exactly the robot: the root body at ``(0, 0, plan.height)`` with a free
joint named ``root`` when the plan floats (else welded to the world), and below it one body per
part (frames aligned with the world), its joints (limited when the part gives a range, damping,
armature, stiffness) and geoms (explicit masses). Every joint with a gear gets a motor
(``ctrlrange [-1, 1]``, ``gear``: the torque limit, N·m or N) when ``plan.actuators``; a
hinge without range (a wheel) a DC motor with a no-load speed
(:func:`robovae.data.actuators.speed_limited`). Geoms
collide with a floor but not with each other unless ``plan.self_collision``; then the body pairs
in contact at rest are excluded from colliding (:mod:`robovae.data.self_collision`). No floor,
light or camera is added.
"""

from __future__ import annotations

import mujoco

from robovae.data.actuators import speed_limited
from robovae.data.procedural.blueprint import Part, RobotPlan
from robovae.data.self_collision import exclude_resting_contacts

_GEOM = {"capsule": mujoco.mjtGeom.mjGEOM_CAPSULE, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
         "sphere": mujoco.mjtGeom.mjGEOM_SPHERE, "box": mujoco.mjtGeom.mjGEOM_BOX}
_JOINT = {"hinge": mujoco.mjtJoint.mjJNT_HINGE, "slide": mujoco.mjtJoint.mjJNT_SLIDE,
          "ball": mujoco.mjtJoint.mjJNT_BALL}
_TRUE, _FALSE = mujoco.mjtLimited.mjLIMITED_TRUE, mujoco.mjtLimited.mjLIMITED_FALSE
_TRN_JOINT = mujoco.mjtTrn.mjTRN_JOINT


def _fill(spec: mujoco.MjSpec, body: mujoco.MjsBody, part: Part, conaff: int,
          actuators: bool) -> None:
    for k, j in enumerate(part.joints):
        name = f"{part.name}_j{k}"
        extra = {} if j.type == "ball" else {"axis": list(j.axis)}
        if j.range is not None:
            extra.update(limited=_TRUE, range=list(j.range))
        body.add_joint(name=name, type=_JOINT[j.type], damping=j.damping, armature=j.armature,
                       stiffness=j.stiffness, limited=extra.pop("limited", _FALSE), **extra)
        if actuators and j.gear > 0:
            act = spec.add_actuator(name=f"{name}_motor", target=name, trntype=_TRN_JOINT,
                                    ctrllimited=_TRUE, ctrlrange=[-1.0, 1.0],
                                    gear=[j.gear, 0.0, 0.0, 0.0, 0.0, 0.0])
            if j.type == "hinge" and j.range is None:  # a wheel: a DC motor
                speed_limited(act, j.gear)
    for g in part.geoms:
        if g.fromto is not None:
            body.add_geom(type=_GEOM[g.type], fromto=list(g.fromto), size=[g.radius, 0.0, 0.0],
                          mass=g.mass, conaffinity=conaff)
        elif g.type == "sphere":
            assert g.pos is not None  # a sphere has pos (see Geom)
            body.add_geom(type=_GEOM["sphere"], pos=list(g.pos), size=[g.radius, 0.0, 0.0],
                          mass=g.mass, conaffinity=conaff)
        else:
            assert g.pos is not None and g.half is not None  # a box has both (see Geom)
            body.add_geom(type=_GEOM["box"], pos=list(g.pos), size=list(g.half), mass=g.mass,
                          conaffinity=conaff)


def build_spec(plan: RobotPlan) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` of ``plan`` (see the module docstring)."""
    spec = mujoco.MjSpec()
    spec.modelname = plan.name
    spec.compiler.degree = False  # ranges are in radians
    conaff = 1 if plan.self_collision else 0
    root = spec.worldbody.add_body(name=plan.root.name, pos=[0.0, 0.0, plan.height])
    if plan.floating:
        root.add_freejoint(name="root")
    _fill(spec, root, plan.root, conaff, plan.actuators)
    stack = [(root, c) for c in reversed(plan.root.children)]
    while stack:
        parent, part = stack.pop()
        body = parent.add_body(name=part.name, pos=list(part.pos))
        _fill(spec, body, part, conaff, plan.actuators)
        stack.extend((body, c) for c in reversed(part.children))
    if plan.self_collision:
        exclude_resting_contacts(spec)
    return spec
