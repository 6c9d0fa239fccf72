"""Robots whose bodies collide with each other: the pairs in contact at rest are excluded.

A robot written with self-collision (the writer's and the procedural generator's
``self_collision``) gives every geom ``contype = conaffinity = 1``, so that a leg cannot pass
through the trunk or the other legs. MuJoCo already leaves out the contacts of a body with its
parent, but geometry that joins meets other bodies where limbs start: a thigh overlaps the trunk
across the small bodies of a hip whose joints sit at one point, the legs of a spider start at
one point of its body. Such a pair is in contact at rest and pushes itself apart from the first
step (written with self-collision, 122 of 200 decoded samples of the default model and 65 of
100 procedural robots failed the validation's ``self_penetration`` check). As robot models do
(MuJoCo Menagerie's ``<exclude>``), :func:`exclude_resting_contacts` excludes every pair of
bodies with a contact in a rest pose — ``qpos0`` and every keyframe, each as it is and with its
hinge and slide positions clipped into their ranges (the rest pose the validator and the
standing test start from is one of these) —: those pairs never collide, every other pair does.
"""

from __future__ import annotations

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings

__all__ = ["exclude_resting_contacts", "rest_poses", "resting_pairs"]

_MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def rest_poses(model: mujoco.MjModel) -> list[np.ndarray]:
    """``qpos0`` and every keyframe's ``qpos``, each also with its limited hinge and slide
    positions clipped into their ranges (module docstring)."""
    j = np.flatnonzero(np.isin(model.jnt_type, _MOVING) & (model.jnt_limited != 0))
    a = model.jnt_qposadr[j]
    poses = []
    for q in (model.qpos0, *model.key_qpos):
        clipped = q.copy()
        clipped[a] = np.clip(q[a], model.jnt_range[j, 0], model.jnt_range[j, 1])
        poses += [q, clipped]
    return poses


def resting_pairs(model: mujoco.MjModel) -> list[tuple[int, int]]:
    """Body pairs ``(b1, b2)``, ``b1 < b2``, of the robot (world excluded) with a contact in one
    of its :func:`rest_poses`, sorted."""
    data = mujoco.MjData(model)
    pairs: set[tuple[int, int]] = set()
    for qpos in rest_poses(model):
        data.qpos[:] = qpos
        mujoco.mj_fwdPosition(model, data)  # kinematics and collision: the contacts at qpos
        if not data.ncon:
            continue
        bodies = model.geom_bodyid[data.contact.geom[:data.ncon]]
        bodies = bodies[(bodies != 0).all(axis=1)]
        pairs.update(map(tuple, np.sort(bodies, axis=1).tolist()))
    return sorted(pairs)


def exclude_resting_contacts(spec: mujoco.MjSpec) -> int:
    """Add an ``<exclude>`` to ``spec`` for every body pair of :func:`resting_pairs` of its
    compiled model; the number of pairs excluded. The spec is compiled once (it must compile)."""
    with capture_mujoco_warnings():
        model = spec.compile()
    pairs = resting_pairs(model)
    for b1, b2 in pairs:
        spec.add_exclude(bodyname1=model.body(b1).name, bodyname2=model.body(b2).name)
    return len(pairs)
