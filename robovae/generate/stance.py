"""Stance: a free-floating robot written with its wheels on the floor, its soles flat on it
and, when it stands on two feet, its stilts upright (its ankles and balance:
:mod:`robovae.generate.bipeds`).

Three named rules that the writer runs on the compiled robot at ``qpos0``, before its floor
placement (:func:`robovae.generate.writer.graph_to_spec` with ``stance=True``; ``robovae
generate`` asks for them, ``--no-stance`` does not). Each is reported per robot when it changes
something. All three look at the robot's geometry at rest only, never at a simulation.

**Support.** Each geom of the robot has candidate lowest points at rest: a box's corners, the
bottoms of a capsule's end spheres, a sphere's bottom, else the corners of the geom's bounding
box. The robot's size ``L`` is the diagonal of the box around all of them; its *support
points* are those within :data:`SUPPORT_TOL` ``· L`` of the lowest: where the robot meets the
floor once it has settled a little.

``ground_wheels``
    A decoded wheeled base often hangs some of its wheels above the floor (their mounts'
    heights are decoded one by one): the base then rocks on one axle and tips. A *wheel* is a
    body on a hinge without limits whose axis lies within 45° of horizontal at rest, with a
    cylinder or sphere geom, mounted on the root body directly or through one body (a caster's
    swivel) that carries nothing else: that child of the root is its *mount*. A wheel of
    radius ``r`` whose lowest point lies at most :data:`MAX_WHEEL_DROP` ``· r`` above the
    robot's lowest point, and whose mount's lowest point (the wheel's, or a swivel's below it)
    lies more than :data:`WHEEL_TOL` ``· r`` above it, is lowered by moving its mount straight
    down (its position in the root's frame) until the mount's lowest point is on that level;
    the robot is then built again, so the geometry that joins the mount to the root reaches
    it where it now is. Wheels hanging higher are left: they are not meant to roll on the
    floor.

``level_soles``
    A decoded collision box is a few degrees off, and a foot that meets the floor on an edge
    or a corner gives no support: a biped on two edges tips over at once. A *sole* is a box
    geom of a leaf link (a body without child bodies) whose lowest corner lies within
    :data:`SOLE_TOL` ``· L`` of the robot's lowest point and whose axis nearest to vertical is
    not its longest (a foot lying on the floor, not a shin standing on its end). A sole tilted
    by ``0 < α ≤`` :data:`MAX_SOLE_TILT` from lying on one of its faces is turned about its
    centre by the smallest rotation that makes that face horizontal (``R' = R_α R``, ``R_α``
    the rotation taking the box axis nearest to vertical onto ``+z``); its size and centre are
    kept.

``level_stilts``
    A biped whose legs end in boxes standing on their end (a *stilt*: a box of a leaf link
    whose lowest corner lies within :data:`SOLE_TOL` ``· L`` of the robot's lowest point and
    whose axis nearest to vertical is its longest) meets the floor on two edges and tips over
    however its centre of mass lies. When the robot is a biped — its candidate lowest points
    within :data:`BIPED_TOL` ``· L`` of the lowest belong to exactly two limbs of the root body
    (two legs, and no third limb or the body itself near the floor) — each such stilt tilted by
    ``0 < α ≤`` :data:`MAX_SOLE_TILT` from vertical is turned about its centre as
    ``level_soles`` turns a sole, so that it stands on its end face. Only then: a robot on
    more legs stands on their edges, and its shins keep their slant (the procedural
    quadrupeds' and hexapods' do, and so do decoded ones with two of four feet on the floor).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from robovae.generate.mjcf_numbers import mjcf_round_vector

__all__ = ["BIPED_TOL", "MAX_SOLE_TILT", "MAX_WHEEL_DROP", "SOLE_TOL", "SUPPORT_TOL",
           "WHEEL_TOL", "Points", "at_qpos0", "biped", "candidate_points", "ground_wheels",
           "level_soles", "level_stilts", "root_limb", "support_points"]

#: A sole's lowest corner lies within this share of the robot's size L of its lowest point.
SOLE_TOL = 0.02
#: Largest tilt (degrees) of a sole that ``level_soles`` lays flat.
MAX_SOLE_TILT = 30.0
#: Support points lie within this share of the robot's size L of its lowest point.
SUPPORT_TOL = 0.03
#: ``level_stilts``: a biped's points within this share of L of its lowest lie on two limbs.
BIPED_TOL = 0.10
_BOX = int(mujoco.mjtGeom.mjGEOM_BOX)
_CAPSULE = int(mujoco.mjtGeom.mjGEOM_CAPSULE)
_SPHERE = int(mujoco.mjtGeom.mjGEOM_SPHERE)
_CYLINDER = int(mujoco.mjtGeom.mjGEOM_CYLINDER)
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
#: A wheel hangs when its mount's lowest point is more than this share of its radius above the
#: robot's lowest point.
WHEEL_TOL = 0.05
#: ``ground_wheels`` lowers wheels hanging at most this many radii above the lowest point.
MAX_WHEEL_DROP = 4.0
#: A wheel's hinge axis is within 45° of horizontal.
_WHEEL_AXIS_SIN = math.sin(math.radians(45.0))
_SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)

#: :func:`candidate_points`' result: the points ``[P, 3]`` and the geom of each ``[P]``.
Points = tuple[np.ndarray, np.ndarray]


def candidate_points(model: mujoco.MjModel, data: mujoco.MjData) -> Points:
    """Every robot geom's candidate lowest points (world frame, module docstring) at ``data``'s
    pose (kinematics done) and their geoms, geom by geom in id order (one vectorised pass per
    geom type). The stance rules take them as ``points`` so that one pose's points are computed
    once for all of them."""
    robot = np.flatnonzero(model.geom_bodyid != 0)
    if not len(robot):
        return np.zeros((0, 3)), np.zeros(0, dtype=int)
    kind = model.geom_type[robot]
    rot = data.geom_xmat[robot].reshape(-1, 3, 3)
    pos, size = data.geom_xpos[robot], model.geom_size[robot]
    count = np.where(kind == _CAPSULE, 2, np.where(kind == _SPHERE, 1, 8))
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    pts = np.empty((int(count.sum()), 3))
    for sel, local in ((kind == _BOX, lambda i: _SIGNS[None] * size[i][:, None]),
                       (~np.isin(kind, (_BOX, _CAPSULE, _SPHERE)),
                        lambda i: (model.geom_aabb[robot[i]][:, None, :3]
                                   + _SIGNS[None] * model.geom_aabb[robot[i]][:, None, 3:]))):
        i = np.flatnonzero(sel)
        if len(i):
            corners = pos[i][:, None] + np.matmul(local(i), rot[i].transpose(0, 2, 1))
            pts[(start[i][:, None] + np.arange(8)).ravel()] = corners.reshape(-1, 3)
    i = np.flatnonzero(kind == _CAPSULE)
    if len(i):
        axis = rot[i][:, :, 2]
        half = size[i][:, 1:2]
        ends = np.stack([pos[i] + (-half) * axis, pos[i] + half * axis], axis=1)
        ends[:, :, 2] -= size[i][:, None, 0]
        pts[(start[i][:, None] + np.arange(2)).ravel()] = ends.reshape(-1, 3)
    i = np.flatnonzero(kind == _SPHERE)
    if len(i):
        bottom = pos[i].copy()
        bottom[:, 2] -= size[i][:, 0]
        pts[start[i]] = bottom
    return pts, np.repeat(robot, count)


def _extent(points: np.ndarray) -> float:
    return max(float(np.linalg.norm(points.max(0) - points.min(0))), 1e-9) if len(points) else 0.0


def support_points(model: mujoco.MjModel, data: mujoco.MjData, tol: float = SUPPORT_TOL,
                   points: Points | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The support points at ``data``'s pose (kinematics done), their geoms and the robot's
    size ``L`` (module docstring); ``tol``: share of ``L`` above the lowest point; ``points``:
    every geom's candidate lowest points and their geoms at that pose, when the caller has
    them."""
    pts, owner = candidate_points(model, data) if points is None else points
    if not len(pts):
        return pts, owner, 0.0
    ext = _extent(pts)
    low = pts[:, 2] <= pts[:, 2].min() + tol * ext
    return pts[low], owner[low], ext


def _leaves(model: mujoco.MjModel) -> set[int]:
    parents = set(model.body_parentid[1:].tolist())
    return {b for b in range(1, model.nbody) if b not in parents}


def at_qpos0(model: mujoco.MjModel, data: mujoco.MjData | None = None) -> mujoco.MjData:
    """``data`` (the caller's, kinematics done at ``qpos0``), else a new ``MjData`` with its
    kinematics at ``qpos0`` (about 0.35 ms to make: callers that have one pass it on)."""
    if data is None:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
    return data


def _mount(model: mujoco.MjModel, body: int, root: int) -> int | None:
    """The child of ``root`` that carries ``body`` directly or through one body, else None."""
    parent = int(model.body_parentid[body])
    if parent == root:
        return body
    return parent if int(model.body_parentid[parent]) == root else None


def _subtree(model: mujoco.MjModel, body: int) -> list[int]:
    """``body`` and every body below it."""
    out = [body]
    for b in range(body + 1, model.nbody):  # MuJoCo numbers a child after its parent
        if model.body_parentid[b] in out:
            out.append(b)
    return out


def ground_wheels(model: mujoco.MjModel, root: int, data: mujoco.MjData | None = None,
                  points: Points | None = None) -> dict[str, np.ndarray]:
    """Where hanging wheels' mounts go (``ground_wheels``, module docstring): per mount body's
    name, its displacement in the root's frame (empty when no wheel hangs). ``model``: the
    robot compiled, ``root``: its free-floating root body; ``data``: its kinematics at
    ``qpos0``, made here when not given; ``points``: :func:`candidate_points` at that pose,
    when the caller has them. The writer builds the robot again with the mounts moved, so that
    the geometry joining them to the root follows them."""
    data = at_qpos0(model, data)
    pts, owner = candidate_points(model, data) if points is None else points
    if not len(pts):
        return {}
    low = float(pts[:, 2].min())
    body_of = model.geom_bodyid[owner]
    drop: dict[int, float] = {}  # mount -> how far it goes down
    for j in np.flatnonzero((model.jnt_type == _HINGE) & (model.jnt_limited == 0)).tolist():
        body = int(model.jnt_bodyid[j])
        mount = _mount(model, body, root)
        if mount is None or not model.body(mount).name \
                or abs(float(data.xaxis[j, 2])) > _WHEEL_AXIS_SIN \
                or set(_subtree(model, mount)) != {mount, body}:
            continue
        geoms = [g for g in range(model.body_geomadr[body],
                                  model.body_geomadr[body] + model.body_geomnum[body])
                 if model.geom_type[g] in (_CYLINDER, _SPHERE)]
        if not geoms:
            continue
        radius = max(float(model.geom_size[g, 0]) for g in geoms)
        gap = float(pts[np.isin(owner, geoms), 2].min()) - low
        # the mount goes down until its lowest part (the wheel, or a swivel below it) is there
        fall = float(pts[np.isin(body_of, (mount, body)), 2].min()) - low
        if WHEEL_TOL * radius < fall and gap <= MAX_WHEEL_DROP * radius:
            drop[mount] = fall
    to_root = data.xmat[root].reshape(3, 3).T  # world to the root's frame
    return {model.body(m).name: to_root @ np.array([0.0, 0.0, -d]) for m, d in drop.items()}


def _floor_boxes(model: mujoco.MjModel, data: mujoco.MjData, on_end: bool,
                 points: Points | None = None) -> list[tuple[int, np.ndarray, float]]:
    """The named box geoms of leaf links whose lowest corner lies within :data:`SOLE_TOL`
    ``· L`` of the robot's lowest point, lying (``on_end=False``: the axis nearest to vertical is
    not the longest) or standing on their end (``on_end=True``), tilted by ``0 < tilt <=``
    :data:`MAX_SOLE_TILT` degrees: ``(geom, up, tilt)``, ``up`` the box axis nearest to
    vertical, pointing up (world frame). ``points``: :func:`candidate_points` at ``data``'s
    pose, when the caller has them."""
    pts, owner = candidate_points(model, data) if points is None else points
    if not len(pts):
        return []
    low, ext = float(pts[:, 2].min()), _extent(pts)
    leaves = _leaves(model)
    out = []
    for g in np.unique(owner[pts[:, 2] <= low + SOLE_TOL * ext]).tolist():
        if model.geom_type[g] != _BOX or int(model.geom_bodyid[g]) not in leaves \
                or not model.geom(g).name:
            continue
        rot = data.geom_xmat[g].reshape(3, 3)
        k = int(np.argmax(np.abs(rot[2])))
        if (model.geom_size[g, k] >= model.geom_size[g].max()) != on_end:
            continue
        up = rot[:, k] * np.sign(rot[2, k])
        tilt = math.degrees(math.acos(min(1.0, float(up[2]))))
        if 1e-3 < tilt <= MAX_SOLE_TILT:
            out.append((g, up, tilt))
    return out


def _lay_flat(spec: mujoco.MjSpec, model: mujoco.MjModel, data: mujoco.MjData, g: int,
              up: np.ndarray) -> None:
    """Turn box geom ``g`` of ``spec`` about its centre by the smallest rotation that takes its
    axis ``up`` onto ``+z`` (``R' = R_α R``): the face across that axis becomes horizontal."""
    q_turn, q_world, q_body, q_local = (np.zeros(4) for _ in range(4))
    mujoco.mju_quatZ2Vec(q_turn, up)  # the rotation taking +z onto `up`; its inverse levels
    mujoco.mju_negQuat(q_turn, q_turn)
    mujoco.mju_mat2Quat(q_world, data.geom_xmat[g].reshape(9))
    mujoco.mju_mulQuat(q_world, q_turn, q_world)
    mujoco.mju_negQuat(q_body, data.xquat[int(model.geom_bodyid[g])])
    mujoco.mju_mulQuat(q_local, q_body, q_world)
    spec.geom(model.geom(g).name).quat = mjcf_round_vector(q_local)


def level_soles(spec: mujoco.MjSpec, model: mujoco.MjModel,
                data: mujoco.MjData | None = None, points: Points | None = None) -> bool:
    """Lay the robot's soles flat (``level_soles``, module docstring): changes the quaternions
    of the sole geoms of ``spec`` (``model``: ``spec`` compiled; ``data``: its kinematics at
    ``qpos0``, made here when not given; ``points``: :func:`candidate_points` at that pose).
    Returns whether a sole was turned (``spec`` then needs compiling again; ``model`` and
    ``data`` are left alone)."""
    data = at_qpos0(model, data)
    soles = _floor_boxes(model, data, on_end=False, points=points)
    for g, up, _ in soles:
        _lay_flat(spec, model, data, g, up)
    return bool(soles)


def level_stilts(spec: mujoco.MjSpec, model: mujoco.MjModel, root: int,
                 data: mujoco.MjData | None = None, points: Points | None = None) -> bool:
    """Stand a biped's stilts straight (``level_stilts``, module docstring): changes the
    quaternions of the stilt geoms of ``spec`` when the robot is a biped, its points within
    :data:`BIPED_TOL` ``· L`` of its lowest point on exactly two limbs of ``root`` (``model``:
    ``spec`` compiled; ``data``: its kinematics at ``qpos0``, made here when not given;
    ``points``: :func:`candidate_points` at that pose). Returns whether a stilt was turned."""
    data = at_qpos0(model, data)
    points = candidate_points(model, data) if points is None else points
    if not biped(model, data, root, points):
        return False
    stilts = _floor_boxes(model, data, on_end=True, points=points)
    for g, up, _ in stilts:
        _lay_flat(spec, model, data, g, up)
    return bool(stilts)


def biped(model: mujoco.MjModel, data: mujoco.MjData, root: int, points: Points,
          tol: float = BIPED_TOL) -> bool:
    """Whether the robot is a biped: its candidate lowest points (``points``, at ``data``'s
    pose) within ``tol · L`` of the lowest lie on exactly two limbs of ``root`` (two legs,
    and no third limb or the root body itself near the floor)."""
    near = support_points(model, data, tol=tol, points=points)[1]
    legs = {root_limb(model, int(model.geom_bodyid[g]), root) for g in near}
    return len(legs) == 2 and root not in legs


def root_limb(model: mujoco.MjModel, body: int, root: int) -> int:
    """The child of ``root`` whose subtree holds ``body`` (``root`` for the root itself)."""
    while body != root and model.body_parentid[body] != root and body != 0:
        body = int(model.body_parentid[body])
    return body
