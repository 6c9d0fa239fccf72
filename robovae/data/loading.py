"""Reading a robot file (MJCF or URDF) into a compiled MuJoCo model, missing assets dropped.

:func:`load_robot` checks the file (:func:`~robovae.data.robot_file.scan_robot_file`), parses it
into a ``mujoco.MjSpec`` (MuJoCo reads URDF too), checks the parsed spec again (body count,
height-field and texture sizes), drops mesh, texture, height-field and skin assets whose files
are missing (:func:`drop_missing_assets`: their geoms go, bodies keep their explicit
``<inertial>``), compiles the spec and refuses NaN or ±Inf in any compiled array a feature is
read from (naming the array and element).

Every problem is a one-line :class:`~robovae.errors.RobotFileError`,
``robovae: <file>: <what> (<element/line>)``, never a traceback. What loading had to change,
and MuJoCo's own warnings (captured with :func:`capture_mujoco_warnings`, never printed or
written to ``MUJOCO_LOG.TXT``), are returned as warnings.
"""

from __future__ import annotations

import contextlib
import os
import re
import warnings as pywarnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robovae.data.robot_file import (
    MAX_BODIES,
    MAX_HFIELD_CELLS,
    MAX_TEXTURE_PIXELS,
    XML_MAX_DEPTH,
    scan_robot_file,
)
from robovae.errors import RobotFileError

_MESH = mujoco.mjtGeom.mjGEOM_MESH


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
        if err and err.group(1) == "XML_ELEMENT_DEPTH_EXCEEDED":
            what = (f"XML nested too deep (MuJoCo's XML parser stops at {XML_MAX_DEPTH} element "
                    f"levels, about {XML_MAX_DEPTH - 4} nested bodies)")
        else:
            what = "malformed XML" + (f" ({err.group(1)})" if err else "")
    return what, where


def mujoco_error_line(msg: str) -> str:
    """A MuJoCo load or compile error as one line, ``what (element/line)``: its XML parse
    errors named (``malformed XML (XML_ERROR_...) (line N)``)."""
    what, where = _where(msg)
    return f"{what} ({where})" if where else what


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


def quiet_forward(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """``mujoco.mj_forward`` with MuJoCo's warnings collected (:func:`capture_mujoco_warnings`)
    instead of printed: a near-singular robot warns at rest, the measures judge it themselves
    (``data.warning`` still counts the warnings)."""
    with capture_mujoco_warnings():
        mujoco.mj_forward(model, data)


def _check_spec(path: Path, spec: mujoco.MjSpec) -> None:
    """Refuse specs whose compilation would allocate absurd amounts of memory."""
    if len(spec.bodies) > MAX_BODIES + 1:
        raise RobotFileError(path, f"more than {MAX_BODIES} bodies: MuJoCo would take "
                             "minutes to load them")
    for h in spec.hfields:
        if h.nrow * h.ncol > MAX_HFIELD_CELLS:
            raise RobotFileError(path, f"height field too large ({h.nrow} x {h.ncol} > "
                                 f"{MAX_HFIELD_CELLS} cells)", f"hfield '{h.name}'")
    cube = {mujoco.mjtTexture.mjTEXTURE_CUBE, mujoco.mjtTexture.mjTEXTURE_SKYBOX}
    for t in spec.textures:
        if t.builtin != mujoco.mjtBuiltin.mjBUILTIN_NONE:
            pixels = t.width * t.height * (6 if t.type in cube else 1)
            if pixels > MAX_TEXTURE_PIXELS:
                raise RobotFileError(path, f"builtin texture too large ({t.width} x {t.height} "
                                     f"> {MAX_TEXTURE_PIXELS} pixels)", f"texture '{t.name}'")


#: Compiled arrays the features are read from, checked for NaN/Inf, with the object their rows
#: belong to (``dof`` rows are named by their joint).
_FINITE = {
    "body": ("body_pos", "body_quat", "body_mass", "body_inertia", "body_ipos", "body_iquat"),
    "joint": ("jnt_pos", "jnt_axis", "jnt_range", "jnt_stiffness"),
    "dof": ("dof_armature", "dof_damping", "dof_frictionloss"),
    "geom": ("geom_pos", "geom_quat", "geom_size", "geom_friction", "geom_aabb"),
    "actuator": ("actuator_gear", "actuator_ctrlrange"),
}
_OBJ = {"body": mujoco.mjtObj.mjOBJ_BODY, "joint": mujoco.mjtObj.mjOBJ_JOINT,
        "geom": mujoco.mjtObj.mjOBJ_GEOM, "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR}


def element_name(model: mujoco.MjModel, kind: str, i: int) -> str:
    """``body 'torso'`` / ``joint 3``: element ``i`` of ``kind`` (``body``, ``joint``, ``dof``,
    ``geom``, ``actuator``; a ``dof`` is named by its joint) for error messages."""
    if kind == "dof":
        kind, i = "joint", int(model.dof_jntid[i])
    name = mujoco.mj_id2name(model, _OBJ[kind], i)
    return f"{kind} '{name}'" if name else f"{kind} {i}"


def _check_finite(path: Path, model: mujoco.MjModel) -> None:
    for kind, arrays in _FINITE.items():
        for attr in arrays:
            a = getattr(model, attr)
            if a.size and not np.isfinite(a).all():
                row = int(np.argwhere(~np.isfinite(a.reshape(len(a), -1)))[0, 0])
                raise RobotFileError(path, f"non-finite values in {attr}",
                                     element_name(model, kind, row))


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


def _load(path: Path) -> tuple[mujoco.MjSpec, mujoco.MjModel, list[str], list[str],
                              list[str]]:
    with capture_mujoco_warnings() as mj_warnings:
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except Exception as e:  # MuJoCo raises ValueError with its own message
            raise RobotFileError(path, *_where(str(e))) from None
        _check_spec(path, spec)
        missing, warnings = drop_missing_assets(spec)
        try:
            model = spec.compile()
        except Exception as e:
            what, where = _where(str(e))
            if missing:
                what += f" (after dropping {len(missing)} mesh geoms whose files are missing)"
            raise RobotFileError(path, what, where) from None
    return spec, model, missing, warnings, mj_warnings


def load_robot(path: str | os.PathLike) -> LoadedRobot:
    """Parse and compile an MJCF or URDF file, dropping assets whose files are missing.

    Raises:
        RobotFileError: one line naming the file, the problem and the element/line.
    """
    path = Path(path)
    scan_robot_file(path)
    try:
        spec, model, missing, warnings, mj_warnings = _load(path)
    except UnicodeDecodeError:  # names or file names that are not UTF-8 after XML decoding
        raise RobotFileError(path, "not UTF-8 text (in a name or file name)") from None
    warnings += [f"MuJoCo: {w}" for w in mj_warnings]
    if model.nbody <= 1:
        raise RobotFileError(path, "no bodies in worldbody", "worldbody")
    _check_finite(path, model)
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


def robot_name(path: Path, spec: mujoco.MjSpec | None = None) -> str:
    """The robot's name: ``<mujoco model="...">`` / ``<robot name>``, else the file stem."""
    name = (spec.modelname if spec is not None else "") or ""
    if not name or name in {"MuJoCo Model", "scene"}:
        name = path.stem
    return name



__all__ = ["LoadedRobot", "capture_mujoco_warnings", "drop_missing_assets", "element_name",
           "load_robot", "quiet_forward", "robot_name", "robot_root"]
