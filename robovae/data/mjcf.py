"""MJCF / URDF → robot graph (SPEC §1), parsed and compiled by MuJoCo itself.

The file is parsed into a ``mujoco.MjSpec`` (MuJoCo reads URDF too), assets whose files are
missing are dropped (:func:`drop_missing_assets`), the spec is compiled and every feature is
read from the compiled ``mujoco.MjModel``, so default classes, ``autolimits`` and
``inertiafromgeom`` are already resolved.

Graph rule: every body but the world is a *link*; every joint is a *joint* node between its
body and the body's parent (several joints chain ``parent — j1 — j2 — body``, in declaration
order); in the ``full`` feature set every primitive geom is a *geom* leaf under its body, before
the child bodies. The robot is the top-level body with the largest subtree (ties: the first
declared); other top-level bodies are dropped with a warning.
"""

from __future__ import annotations

import contextlib
import re
import warnings as pywarnings
from collections.abc import Iterator
from dataclasses import dataclass, field
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
from robovae.errors import RobotFileError

_MESH = mujoco.mjtGeom.mjGEOM_MESH
_TRN_JOINT = mujoco.mjtTrn.mjTRN_JOINT
_MAX_BYTES = 64 * 2**20


@dataclass
class LoadedRobot:
    """A compiled robot and what loading it had to change."""

    path: Path
    spec: mujoco.MjSpec
    model: mujoco.MjModel
    warnings: list[str] = field(default_factory=list)
    missing_meshes: list[str] = field(default_factory=list)


def _where(msg: str) -> tuple[str, str | None]:
    """Split a MuJoCo error message into (what, element/line)."""
    lines = [ln.strip() for ln in msg.strip().splitlines() if ln.strip()]
    what = lines[0] if lines else "unknown error"
    what = re.sub(r"^(XML Error: |Error: )+", "", what)
    where = None
    for ln in lines[1:]:
        m = re.match(r"Element (?:name )?'([^']*)'(?:, id (\d+))?, line (\d+)", ln)
        if m:
            elem = f"element '{m.group(1)}'" if m.group(1) else "unnamed element"
            where = f"{elem}, line {m.group(3)}" if m.group(3) != "0" else elem
        m = re.search(r"Line number=(\d+)", ln)
        if m:
            where = f"line {m.group(1)}"
    if what.startswith("XML parse error"):
        err = re.search(r"Error=(\w+)", msg)
        what = "malformed XML" + (f" ({err.group(1)})" if err else "")
    return what, where


SUFFIXES = (".xml", ".mjcf", ".urdf")


@contextlib.contextmanager
def capture_mujoco_warnings() -> Iterator[list[str]]:
    """Collect MuJoCo's warnings into a list instead of printing them and writing
    ``MUJOCO_LOG.TXT`` in the working directory."""
    got: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: got.append(" ".join(str(msg).split())))
    try:
        with pywarnings.catch_warnings(record=True) as caught:
            pywarnings.simplefilter("always")
            yield got
        got.extend(" ".join(str(w.message).split()) for w in caught)
    finally:
        mujoco.set_mju_user_warning(previous)


def _check_file(path: Path) -> None:
    if path.suffix.lower() not in SUFFIXES:
        raise RobotFileError(path, f"unsupported file type '{path.suffix}' (want .xml or .urdf)")
    if not path.is_file():
        raise RobotFileError(path, "no such file")
    size = path.stat().st_size
    if size == 0:
        raise RobotFileError(path, "empty file")
    if size > _MAX_BYTES:
        raise RobotFileError(path, f"file too large ({size / 2**20:.0f} MiB > 64 MiB)")
    head = path.read_bytes()[:4096]
    if b"<!ENTITY" in head or b"<!DOCTYPE" in head:
        raise RobotFileError(path, "DOCTYPE/ENTITY declarations are not allowed", "prolog")
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as e:
        if e.start < len(head) - 4:  # a cut multi-byte character at the end is fine
            raise RobotFileError(path, "not UTF-8 text", f"byte {e.start}") from None


def _asset_path(spec: mujoco.MjSpec, subdir: str, file: str) -> Path:
    base = Path(spec.modelfiledir or ".")
    p = Path(file)
    if spec.strippath:
        p = Path(p.name)
    return p if p.is_absolute() else base / (subdir or "") / p


def drop_missing_assets(spec: mujoco.MjSpec) -> tuple[list[str], list[str]]:
    """Delete mesh geoms, meshes, textures and material links whose files are missing.

    Bodies keep their explicit ``<inertial>``. Returns ``(missing mesh names, warnings)``.
    Nothing is dropped when the files are present.
    """
    warnings: list[str] = []
    missing_mesh = {m.name for m in spec.meshes
                    if m.file and not _asset_path(spec, spec.meshdir, m.file).is_file()}
    if missing_mesh:
        for g in list(spec.geoms):
            if g.type == _MESH and g.meshname in missing_mesh:
                spec.delete(g)
        for m in list(spec.meshes):
            if m.name in missing_mesh:
                spec.delete(m)
        warnings.append(f"{len(missing_mesh)} mesh files missing: mesh geoms dropped")
    missing_tex = set()
    for t in list(spec.textures):
        files = [t.file, *list(t.cubefiles)] if hasattr(t, "cubefiles") else [t.file]
        if any(f and not _asset_path(spec, spec.texturedir, f).is_file() for f in files):
            missing_tex.add(t.name)
            spec.delete(t)
    if missing_tex:
        for mat in spec.materials:
            mat.textures = ["" if name in missing_tex else name for name in mat.textures]
        warnings.append(f"{len(missing_tex)} texture files missing: textures dropped")
    for h in list(spec.hfields):
        if h.file and not _asset_path(spec, spec.meshdir, h.file).is_file():
            for g in list(spec.geoms):
                if g.hfieldname == h.name:
                    spec.delete(g)
            spec.delete(h)
            warnings.append(f"height field '{h.name}' file missing: dropped")
    for s in list(spec.skins):
        if s.file and not _asset_path(spec, spec.meshdir, s.file).is_file():
            spec.delete(s)
            warnings.append(f"skin '{s.name}' file missing: dropped")
    return sorted(missing_mesh), warnings


def load_robot(path: str | Path) -> LoadedRobot:
    """Parse and compile an MJCF or URDF file, dropping assets whose files are missing.

    Raises:
        RobotFileError: one line naming the file, the problem and the element/line.
    """
    path = Path(path)
    _check_file(path)
    with capture_mujoco_warnings() as mj_warnings:
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except Exception as e:  # MuJoCo raises ValueError with its own message
            raise RobotFileError(path, *_where(str(e))) from None
        missing, warnings = drop_missing_assets(spec)
        try:
            model = spec.compile()
        except Exception as e:
            what, where = _where(str(e))
            if missing:
                what += f" (after dropping {len(missing)} mesh geoms whose files are missing)"
            raise RobotFileError(path, what, where) from None
    warnings += [f"MuJoCo: {w}" for w in mj_warnings]
    if model.nbody <= 1:
        raise RobotFileError(path, "no bodies in worldbody", "worldbody")
    bad = [n for n, a in (("body_mass", model.body_mass), ("body_pos", model.body_pos),
                          ("jnt_range", model.jnt_range), ("geom_size", model.geom_size))
           if a.size and not np.isfinite(a).all()]
    if bad:
        raise RobotFileError(path, f"non-finite values in {', '.join(bad)}")
    return LoadedRobot(path, spec, model, warnings, missing)


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
    for b in range(1, model.nbody):
        kids[model.body_parentid[b]].append(b)
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
    x = torch.from_numpy(np.stack(rows)).float()
    if not torch.isfinite(x).all():
        raise ValueError("non-finite feature values")
    return tree_data(parent, types, x, fs, name=name, source=source,
                     mj_id=torch.tensor(ids, dtype=torch.long), warnings="; ".join(warns))


def robot_name(path: Path, spec: mujoco.MjSpec | None = None) -> str:
    """The robot's name: ``<mujoco model="...">`` / ``<robot name>``, else the file stem."""
    name = (spec.modelname if spec is not None else "") or ""
    if not name or name in {"MuJoCo Model", "scene"}:
        name = path.stem
    return name


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
    except ValueError as e:
        raise RobotFileError(path, str(e)) from None


__all__ = ["LoadedRobot", "drop_missing_assets", "load_robot", "mjcf_to_graph",
           "model_to_graph", "robot_name", "robot_root"]
