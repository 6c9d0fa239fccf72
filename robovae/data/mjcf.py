"""Compiled MuJoCo model → robot graph (SPEC §1); :func:`mjcf_to_graph` does file → graph.

Every feature is read from the compiled ``mujoco.MjModel`` (loaded by
:func:`~robovae.data.loading.load_robot`), so default classes, ``autolimits`` and
``inertiafromgeom`` are already resolved.

Graph rule: every body but the world is a *link*; every joint is a *joint* node between its
body and the body's parent (several joints chain ``parent — j1 — j2 — body``, in declaration
order); in the ``full`` feature set every primitive geom is a *geom* leaf under its body, before
the child bodies. The robot is the top-level body with the largest subtree (ties: the first
declared); other top-level bodies are dropped with a warning. Graph building is iterative (no
depth limit).

Bad input never gives a traceback: :func:`mjcf_to_graph` raises
:class:`~robovae.errors.RobotFileError`, one line ``robovae: <file>: <what> (<element/line>)``;
:func:`model_to_graph` raises :class:`FeatureValueError` for feature values that are NaN/±Inf or
beyond the float32 range.

Warnings (``data.warnings``, ``; ``-separated; the dataset report shows them) and the graph
still built: everything :func:`~robovae.data.loading.load_robot` had to change, other top-level
bodies (dropped), bodies without geoms (size features zero), and feature values outside the
registry range of their feature (:mod:`robovae.data.features`; e.g. a 100 m geom or a 1e6 kg
link: no real robot has them — check the units).
"""

from __future__ import annotations

import os

import mujoco
import numpy as np
import numpy.typing as npt
import torch

from robovae.data.actuators import joint_strength
from robovae.data.box_axes import quat_rotations, quat_to_axes
from robovae.data.features import (
    FEATURE_SETS,
    GEOM,
    GEOM_TYPE_IDS,
    JOINT,
    LINK,
    FeatureSet,
    get_feature_set,
)
from robovae.data.graph import RobotData, tree_data
from robovae.data.loading import element_name, load_robot, robot_name, robot_root
from robovae.errors import RobotFileError

_MESH = mujoco.mjtGeom.mjGEOM_MESH
_TRN_JOINT = mujoco.mjtTrn.mjTRN_JOINT
_PRIMITIVE = np.isin(np.arange(int(mujoco.mjtGeom.mjNGEOMTYPES)), GEOM_TYPE_IDS)  # by type id


def _first_geoms(model: mujoco.MjModel, bodies: np.ndarray) -> np.ndarray:
    """Each body's first collision geom, else its first geom, else -1 (geoms are stored body
    by body, in declaration order)."""
    first = np.where(model.body_geomnum > 0, model.body_geomadr, -1).astype(np.int64)
    colliding = np.flatnonzero((model.geom_contype != 0) | (model.geom_conaffinity != 0))
    owners, at = np.unique(model.geom_bodyid[colliding], return_index=True)
    first[owners] = colliding[at]
    return first[bodies]


def _geom_primitives(model: mujoco.MjModel, g: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                   np.ndarray, np.ndarray]:
    """(type ids, pos, quat, size) of geoms ``g``, meshes (and other non-primitives) replaced
    by the box of their bounding size, centred where it is."""
    gtype = model.geom_type[g].astype(np.int64)
    pos, quat, size = model.geom_pos[g].copy(), model.geom_quat[g].copy(), model.geom_size[g].copy()
    for k in np.flatnonzero(~_PRIMITIVE[gtype]).tolist():
        center, half = model.geom_aabb[g[k], :3], model.geom_aabb[g[k], 3:]
        offset = np.zeros(3)
        mujoco.mju_rotVecQuat(offset, center, quat[k])
        gtype[k], pos[k], size[k] = GEOM_TYPE_IDS[-1], pos[k] + offset, half
    return gtype, pos, quat, size


#: The 8 corners of a unit box, for :func:`_link_boxes`.
_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
#: An oriented box is kept only when it is this much smaller than the body-axis box.
_OBB_GAIN = 0.95


def _oriented_boxes(pts: np.ndarray, starts: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(centre, quat, half-sizes)`` of one box per group of points (``pts [n, 3]``, group
    ``k`` the rows ``starts[k]:starts[k+1]``): along the group's principal axes (longest
    extent first, right-handed, ``w >= 0``), or along the frame's own axes (identity) when that
    box is not :data:`_OBB_GAIN` smaller in volume. Every group is handled at once (segment
    reductions and a batched ``eigh``)."""
    counts = np.diff(np.append(starts, len(pts)))
    owner = np.repeat(np.arange(len(starts)), counts)
    mean = np.add.reduceat(pts, starts, axis=0) / counts[:, None]
    d = pts - mean[owner]
    cov = np.add.reduceat(d[:, :, None] * d[:, None, :], starts, axis=0)
    cov = cov / np.maximum(counts - 1, 1)[:, None, None] + 1e-12 * np.eye(3)
    cand = np.linalg.eigh(cov)[1][:, :, ::-1]
    local = np.einsum("pi,pij->pj", pts, cand[owner])
    lo, hi = np.minimum.reduceat(pts, starts, axis=0), np.maximum.reduceat(pts, starts, axis=0)
    c_lo = np.minimum.reduceat(local, starts, axis=0)
    c_hi = np.maximum.reduceat(local, starts, axis=0)
    use = np.prod(c_hi - c_lo, 1) < _OBB_GAIN * np.prod(hi - lo, 1)
    rot = np.where(use[:, None, None], cand, np.eye(3))
    lo, hi = np.where(use[:, None], c_lo, lo), np.where(use[:, None], c_hi, hi)
    order = np.argsort(-(hi - lo), axis=1, kind="stable")
    rot = np.take_along_axis(rot, order[:, None, :], axis=2)
    lo, hi = np.take_along_axis(lo, order, 1), np.take_along_axis(hi, order, 1)
    flip = np.linalg.det(rot) < 0
    rot[flip, :, 2] *= -1.0
    lo[flip, 2], hi[flip, 2] = -hi[flip, 2], -lo[flip, 2]
    quat = np.zeros((len(starts), 4))
    for k in range(len(starts)):
        mujoco.mju_mat2Quat(quat[k], rot[k].flatten())
    quat *= np.where(quat[:, :1] >= 0, 1.0, -1.0)
    return np.einsum("kij,kj->ki", rot, 0.5 * (lo + hi)), quat, 0.5 * (hi - lo)


def _link_boxes(model: mujoco.MjModel, bodies: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(centre, quat, half-sizes)`` (``[len(bodies), 3 | 4 | 3]``) of the oriented box that
    bounds each body's collision geoms (all its geoms when none collides; zeros, identity
    without geoms), body frame (:func:`_oriented_boxes` of the corners of every geom's own
    bounding box, ``geom_aabb``)."""
    m = model
    n = len(bodies)
    center, half, quat = np.zeros((n, 3)), np.zeros((n, 3)), np.tile([1.0, 0, 0, 0], (n, 1))
    colliding = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
    owner = m.geom_bodyid.astype(np.int64)
    has_colliding = np.bincount(owner[colliding], minlength=m.nbody) > 0
    g = np.flatnonzero(colliding | ~has_colliding[owner])
    g = g[np.argsort(owner[g], kind="stable")]
    if g.size == 0:
        return center, quat, half
    local = m.geom_aabb[g, None, :3] + _CORNERS[None] * m.geom_aabb[g, None, 3:]
    pts = np.einsum("gij,gcj->gci", quat_rotations(m.geom_quat[g]), local) + m.geom_pos[g, None]
    groups, first = np.unique(owner[g], return_index=True)
    c, q, h = _oriented_boxes(pts.reshape(-1, 3), 8 * first)
    row = np.full(m.nbody, -1)
    row[groups] = np.arange(len(groups))
    have = row[bodies] >= 0
    center[have], quat[have], half[have] = c[row[bodies][have]], q[row[bodies][have]], \
        h[row[bodies][have]]
    return center, quat, half


def _first_actuators(model: mujoco.MjModel, joints: np.ndarray) -> np.ndarray:
    """The first actuator driving each joint through a joint transmission, else -1."""
    first = np.full(model.njnt, -1, dtype=np.int64)
    acts = np.flatnonzero(model.actuator_trntype == _TRN_JOINT)
    targets, at = np.unique(model.actuator_trnid[acts, 0], return_index=True)
    first[targets] = acts[at]
    return first[joints]


#: Features copied as they are from a compiled array (rows: the node's body / joint or dof).
_LINK_ARRAYS = {"link.pos": "body_pos", "link.mass": "body_mass", "link.inertia": "body_inertia",
                "link.quat": "body_quat", "link.subtreemass": "body_subtreemass",
                "link.ipos": "body_ipos", "link.iquat": "body_iquat"}
_JOINT_ARRAYS = {"joint.stiffness": "jnt_stiffness", "joint.axis": "jnt_axis",
                 "joint.pos": "jnt_pos", "joint.armature": "dof_armature",
                 "joint.damping": "dof_damping", "joint.frictionloss": "dof_frictionloss"}


def _fill(model: mujoco.MjModel, fs: FeatureSet, x: np.ndarray, types: np.ndarray,
          ids: np.ndarray) -> int:
    """Write every feature of every node into ``x`` (rows in node order) straight from the
    compiled arrays; returns the number of links without geoms."""
    keys = {f.key for f in fs.features}
    m = model

    def put(rows: np.ndarray, key: str, values: npt.ArrayLike) -> None:
        if key in keys and rows.size:
            x[rows, fs.slice(key)] = np.asarray(values, dtype=np.float64).reshape(len(rows), -1)

    rows = np.flatnonzero(types == LINK)
    b = ids[rows]
    for key, attr in _LINK_ARRAYS.items():
        put(rows, key, getattr(m, attr)[b])
    first = _first_geoms(m, b)
    has = first >= 0
    put(rows[has], "link.size", _geom_primitives(m, first[has])[3])
    if "link.box_half" in keys:
        center, quat, half = _link_boxes(m, b)
        put(rows, "link.box_pos", center)
        put(rows, "link.box_axes", quat_to_axes(quat))
        put(rows, "link.box_half", half)

    rows = np.flatnonzero(types == JOINT)
    j = ids[rows]
    dof = m.jnt_dofadr[j]
    limited = m.jnt_limited[j].astype(bool)
    put(rows, "joint.type", np.eye(4)[m.jnt_type[j]])
    put(rows, "joint.limited", limited.astype(np.float64))
    put(rows, "joint.range", np.where(limited[:, None], m.jnt_range[j], 0.0))
    for key, attr in _JOINT_ARRAYS.items():
        put(rows, key, getattr(m, attr)[dof if attr.startswith("dof_") else j])
    act = _first_actuators(m, j)
    on = act >= 0
    a = act[on]
    put(rows[on], "joint.actuated", np.ones(len(a)))
    if "joint.torque" in keys:
        put(rows, "joint.torque", joint_strength(m)[j])
    put(rows[on], "joint.gear", m.actuator_gear[a, 0])
    put(rows[on], "joint.ctrlrange", np.where(m.actuator_ctrllimited[a, None] != 0,
                                              m.actuator_ctrlrange[a], 0.0))

    rows = np.flatnonzero(types == GEOM)
    g = ids[rows]
    gtype, pos, quat, size = _geom_primitives(m, g)
    onehot = np.eye(len(GEOM_TYPE_IDS))[np.searchsorted(GEOM_TYPE_IDS, gtype)]
    put(rows, "geom.type", onehot)
    put(rows, "geom.pos", pos)
    put(rows, "geom.quat", quat)
    put(rows, "geom.size", size)
    put(rows, "geom.friction", m.geom_friction[g])
    put(rows, "geom.collides", ((m.geom_contype[g] != 0) | (m.geom_conaffinity[g] != 0))
        .astype(np.float64))
    return int((~has).sum())


class FeatureValueError(ValueError):
    """A feature value the graph cannot hold (NaN/Inf, beyond float32), with the element."""

    def __init__(self, what: str, where: str | None = None) -> None:
        self.what, self.where = what, where
        super().__init__(f"{what} ({where})" if where else what)


_NODE_KIND = {LINK: "body", JOINT: "joint", GEOM: "geom"}
_F32_MAX = float(np.finfo(np.float32).max)


_BOUNDS: dict[int, tuple[FeatureSet, np.ndarray, np.ndarray, np.ndarray]] = {}


def _outside(fs: FeatureSet, x: np.ndarray, t: np.ndarray) -> bool:
    """Whether any non-categorical value lies outside its registry range (1e-6 relative
    tolerance): the quick test before :func:`_check_values` names the features."""
    if id(fs) not in _BOUNDS:
        col_types, lows, highs = [], [], []
        for f in fs.features:
            ti = fs.node_types.index(f.node_type) if f.transform != "categorical" else -1
            col_types += [ti] * f.width
            lows += [f.low - 1e-6 * max(1.0, abs(f.low))] * f.width
            highs += [f.high + 1e-6 * max(1.0, abs(f.high))] * f.width
        _BOUNDS[id(fs)] = (fs, np.array(col_types), np.array(lows), np.array(highs))
    _, col_type, low, high = _BOUNDS[id(fs)]
    for ti in np.unique(t).tolist():
        cols = col_type == ti
        sub = x[t == ti][:, cols]
        if (sub.min(0) < low[cols]).any() or (sub.max(0) > high[cols]).any():
            return True
    return False


def _check_values(model: mujoco.MjModel, fs: FeatureSet, x: np.ndarray, types: list[int],
                  ids: list[int], warns: list[str]) -> None:
    """Raise on values float32 cannot hold; warn about values outside the registry ranges."""
    bad = ~np.isfinite(x) | (np.abs(x) > _F32_MAX)
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        what = "non-finite" if not np.isfinite(x[r, c]) else "beyond the float32 range"
        raise FeatureValueError(f"feature value {what}: {fs.columns[c]} = {x[r, c]:.3g}",
                                element_name(model, _NODE_KIND[types[r]], ids[r]))
    t = np.asarray(types)
    if not _outside(fs, x, t):
        return
    out = []
    for f in fs.features:
        if f.transform == "categorical":
            continue
        sl = fs.slice(f.key)
        vals = x[t == fs.node_types.index(f.node_type), sl]
        if not vals.size:
            continue
        lo, hi = float(vals.min()), float(vals.max())
        tol = 1e-6
        if lo < f.low - tol * max(1.0, abs(f.low)) or hi > f.high + tol * max(1.0, abs(f.high)):
            out.append(f"{f.key} [{lo:.3g}, {hi:.3g}] outside [{f.low:g}, {f.high:g}]")
    if out:
        warns.append(f"feature values outside their registry range (check the units): "
                     f"{', '.join(out)}")


def model_to_graph(
    model: mujoco.MjModel,
    feature_set: str | FeatureSet = "paper34",
    name: str = "",
    source: str = "",
    warnings: list[str] | None = None,
) -> RobotData:
    """Robot graph of a compiled model (SPEC §1), features read from ``model``.

    Besides the :mod:`robovae.data.graph` fields, the result holds ``mj_id`` (the MuJoCo id of
    each node's body, joint or geom) and ``warnings`` (one string, ``; ``-separated).

    Raises:
        KeyError: an unknown feature set, or ``random<d>``: the synthetic trees' features,
            which no robot has.
    """
    fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
    if "link" not in fs.node_types:
        raise KeyError(f"feature set {fs.name!r} holds random trees' features, which no robot "
                       f"has: read robots with one of {', '.join(FEATURE_SETS)}")
    with_geoms = "geom" in fs.node_types
    root, warns = robot_root(model)
    warns = list(warnings or []) + warns
    kids: list[list[int]] = [[] for _ in range(model.nbody)]
    for b, p in enumerate(model.body_parentid.tolist()[1:], start=1):
        kids[p].append(b)
    jntadr, jntnum = model.body_jntadr.tolist(), model.body_jntnum.tolist()
    geomadr, geomnum = model.body_geomadr.tolist(), model.body_geomnum.tolist()
    graph_geoms = _PRIMITIVE[model.geom_type] | (model.geom_type == _MESH)
    parent: list[int] = []
    types: list[int] = []
    ids: list[int] = []
    stack: list[tuple[int, int]] = [(root, -1)]  # (body, parent node), depth-first pre-order
    while stack:
        b, p = stack.pop()
        for j in range(jntadr[b], jntadr[b] + jntnum[b]):
            parent.append(p)
            types.append(JOINT)
            ids.append(j)
            p = len(parent) - 1
        parent.append(p)
        types.append(LINK)
        ids.append(b)
        p = len(parent) - 1
        if with_geoms:
            for g in range(geomadr[b], geomadr[b] + geomnum[b]):
                if graph_geoms[g]:
                    parent.append(p)
                    types.append(GEOM)
                    ids.append(g)
        stack.extend((c, p) for c in reversed(kids[b]))
    x64 = np.zeros((len(parent), fs.dim))
    no_geom = _fill(model, fs, x64, np.asarray(types), np.asarray(ids, dtype=np.int64))
    if no_geom:
        warns.append(f"{no_geom} bodies without geoms: size features zero")
    _check_values(model, fs, x64, types, ids, warns)
    x = torch.from_numpy(x64).float()
    return tree_data(parent, types, x, fs, name=name, source=source,
                     mj_id=torch.tensor(ids, dtype=torch.long), warnings="; ".join(warns))


def mjcf_to_graph(path: str | os.PathLike, feature_set: str | FeatureSet = "paper34",
                  name: str | None = None) -> RobotData:
    """Load an MJCF/URDF file and return its robot graph (see :func:`model_to_graph`).

    Raises:
        RobotFileError: for any problem with the file (one line, never a traceback).
    """
    loaded = load_robot(path)
    try:
        return model_to_graph(loaded.model, feature_set, name or robot_name(loaded.path,
                              loaded.spec), str(loaded.path), loaded.warnings)
    except FeatureValueError as e:
        raise RobotFileError(path, e.what, e.where) from None
    except UnicodeDecodeError:
        raise RobotFileError(path, "not UTF-8 text (in a name or file name)") from None
    except ValueError as e:
        raise RobotFileError(path, str(e)) from None



__all__ = ["FeatureValueError", "mjcf_to_graph", "model_to_graph", "robot_root"]
