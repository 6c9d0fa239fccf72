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

from pathlib import Path

import mujoco
import numpy as np
import torch

from robovae.data.features import (
    GEOM,
    GEOM_TYPE_IDS,
    JOINT,
    LINK,
    FeatureSet,
    get_feature_set,
)
from robovae.data.graph import RobotData, tree_data
from robovae.data.loading import element_name, load_robot, robot_name
from robovae.errors import RobotFileError

_MESH = mujoco.mjtGeom.mjGEOM_MESH
_TRN_JOINT = mujoco.mjtTrn.mjTRN_JOINT


def robot_root(model: mujoco.MjModel) -> tuple[int, list[str]]:
    """The top-level body whose subtree is largest (first declared on ties), and warnings."""
    top = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    size = np.bincount(model.body_rootid, minlength=model.nbody)
    root = max(top, key=lambda b: (size[b], -b))
    warnings = []
    dropped = [b for b in top if b != root]
    if dropped:
        names = ", ".join(repr(model.body(b).name or f"body{b}") for b in dropped[:5])
        more = f" and {len(dropped) - 5} more" if len(dropped) > 5 else ""
        warnings.append(f"dropped {len(dropped)} other top-level bodies: {names}{more}")
    return int(root), warnings


def _first_geom(model: mujoco.MjModel, body: int) -> int:
    """The body's first collision geom, else its first geom, else -1."""
    start, n = model.body_geomadr[body], model.body_geomnum[body]
    if n <= 0:
        return -1
    ids = range(start, start + n)
    for g in ids:
        if model.geom_contype[g] or model.geom_conaffinity[g]:
            return g
    return start


def _geom_primitive(model: mujoco.MjModel, g: int) -> tuple[int, np.ndarray, np.ndarray,
                                                            np.ndarray]:
    """(geom type id, pos, quat, size) with meshes replaced by their bounding box."""
    gtype = int(model.geom_type[g])
    pos, quat, size = model.geom_pos[g].copy(), model.geom_quat[g].copy(), model.geom_size[g]
    if gtype in GEOM_TYPE_IDS:
        return gtype, pos, quat, size.copy()
    center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    offset = np.zeros(3)
    mujoco.mju_rotVecQuat(offset, center, quat)
    return GEOM_TYPE_IDS[-1], pos + offset, quat, half.copy()


class _Writer:
    """Fills feature rows of one robot from the compiled model (reads the registry slices)."""

    def __init__(self, model: mujoco.MjModel, fs: FeatureSet) -> None:
        self.m, self.fs = model, fs
        self.keys = {f.key for f in fs.features}
        self.act_of_joint: dict[int, int] = {}
        for a in range(model.nu):
            if model.actuator_trntype[a] == _TRN_JOINT:
                self.act_of_joint.setdefault(int(model.actuator_trnid[a, 0]), a)

    def put(self, row: np.ndarray, key: str, value) -> None:
        if key in self.keys:
            row[self.fs.slice(key)] = value

    def link(self, row: np.ndarray, b: int) -> bool:
        m, put = self.m, self.put
        put(row, "link.pos", m.body_pos[b])
        put(row, "link.mass", m.body_mass[b])
        put(row, "link.inertia", m.body_inertia[b])
        put(row, "link.quat", m.body_quat[b])
        put(row, "link.subtreemass", m.body_subtreemass[b])
        put(row, "link.ipos", m.body_ipos[b])
        put(row, "link.iquat", m.body_iquat[b])
        g = _first_geom(m, b)
        if g >= 0:
            put(row, "link.size", _geom_primitive(m, g)[3])
        return g >= 0

    def joint(self, row: np.ndarray, j: int) -> None:
        m, put = self.m, self.put
        dof = m.jnt_dofadr[j]
        limited = bool(m.jnt_limited[j])
        put(row, "joint.type", np.eye(4)[m.jnt_type[j]])
        put(row, "joint.limited", float(limited))
        put(row, "joint.range", m.jnt_range[j] if limited else 0.0)
        put(row, "joint.stiffness", m.jnt_stiffness[j])
        put(row, "joint.axis", m.jnt_axis[j])
        put(row, "joint.pos", m.jnt_pos[j])
        put(row, "joint.armature", m.dof_armature[dof])
        put(row, "joint.damping", m.dof_damping[dof])
        put(row, "joint.frictionloss", m.dof_frictionloss[dof])
        a = self.act_of_joint.get(j)
        if a is not None:
            put(row, "joint.actuated", 1.0)
            put(row, "joint.gear", m.actuator_gear[a, 0])
            put(row, "joint.ctrlrange", m.actuator_ctrlrange[a] if m.actuator_ctrllimited[a]
                else 0.0)

    def geom(self, row: np.ndarray, g: int) -> None:
        m, put = self.m, self.put
        gtype, pos, quat, size = _geom_primitive(m, g)
        put(row, "geom.type", np.eye(len(GEOM_TYPE_IDS))[GEOM_TYPE_IDS.index(gtype)])
        put(row, "geom.pos", pos)
        put(row, "geom.quat", quat)
        put(row, "geom.size", size)
        put(row, "geom.friction", m.geom_friction[g])
        put(row, "geom.collides", float(bool(m.geom_contype[g] or m.geom_conaffinity[g])))


class FeatureValueError(ValueError):
    """A feature value the graph cannot hold (NaN/Inf, beyond float32), with the element."""

    def __init__(self, what: str, where: str | None = None) -> None:
        self.what, self.where = what, where
        super().__init__(f"{what} ({where})" if where else what)


_NODE_KIND = {LINK: "body", JOINT: "joint", GEOM: "geom"}
_F32_MAX = float(np.finfo(np.float32).max)


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
    """
    fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
    with_geoms = "geom" in fs.node_types
    root, warns = robot_root(model)
    warns = list(warnings or []) + warns
    writer = _Writer(model, fs)
    kids: list[list[int]] = [[] for _ in range(model.nbody)]
    for b, p in enumerate(model.body_parentid.tolist()[1:], start=1):
        kids[p].append(b)
    parent: list[int] = []
    types: list[int] = []
    ids: list[int] = []
    rows: list[np.ndarray] = []
    no_geom = 0

    def add(p: int, t: int, mj_id: int) -> tuple[int, np.ndarray]:
        parent.append(p)
        types.append(t)
        ids.append(mj_id)
        rows.append(np.zeros(fs.dim))
        return len(parent) - 1, rows[-1]

    stack: list[tuple[int, int]] = [(root, -1)]  # (body, parent node)
    while stack:
        b, p = stack.pop()
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            p, row = add(p, JOINT, j)
            writer.joint(row, j)
        p, row = add(p, LINK, b)
        no_geom += not writer.link(row, b)
        if with_geoms:
            for g in range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b]):
                if model.geom_type[g] in GEOM_TYPE_IDS or model.geom_type[g] == _MESH:
                    writer.geom(add(p, GEOM, g)[1], g)
        stack.extend((c, p) for c in reversed(kids[b]))
    if no_geom:
        warns.append(f"{no_geom} bodies without geoms: size features zero")
    x64 = np.stack(rows)
    _check_values(model, fs, x64, types, ids, warns)
    x = torch.from_numpy(x64).float()
    return tree_data(parent, types, x, fs, name=name, source=source,
                     mj_id=torch.tensor(ids, dtype=torch.long), warnings="; ".join(warns))


def mjcf_to_graph(path: str | Path, feature_set: str | FeatureSet = "paper34",
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
