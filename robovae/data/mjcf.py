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

Bad input (SPEC §1; ``tests/data/corpus``) never gives a traceback: :func:`load_robot` and
:func:`mjcf_to_graph` raise :class:`~robovae.errors.RobotFileError`, one line
``robovae: <file>: <what> (<element/line>)``. Before MuJoCo sees a file, it and the files it
includes are scanned (:func:`scan_robot_file`): they must be regular UTF-8 files of at most
64 MiB in all, without ``<!DOCTYPE``/``<!ENTITY`` declarations (no entity-expansion bombs) or
character references to characters XML forbids (``&#xD800;``, which MuJoCo would decode into
invalid UTF-8), and declare at most :data:`MAX_BODIES` bodies (``<replicate>`` counts
multiplied in), :data:`MAX_FLEX_POINTS` ``<flexcomp>`` points, no height field larger than
:data:`MAX_HFIELD_CELLS` cells and no builtin texture larger than :data:`MAX_TEXTURE_PIXELS`
pixels (the parsed spec is checked again). Beyond these limits MuJoCo's parser and compiler,
super-linear in the model size or allocating such arrays in full, would hang the build or
exhaust memory. Bodies nest at most about 496 deep in MJCF (MuJoCo's XML parser stops at 500
element levels; URDF chains, whose links are not nested, and in-memory specs have no such
limit; graph building is iterative). NaN or ±Inf in any compiled array a feature is read from
is an error naming the array and element.

Warnings (``data.warnings``, ``; ``-separated; the dataset report shows them) and the graph
still built: mesh, texture, height-field and skin files that are missing (their geoms are
dropped; bodies keep their explicit ``<inertial>``), other top-level bodies (dropped), bodies
without geoms (size features zero), MuJoCo's own warnings (e.g. ``XML contains a 'NaN'`` for
an attribute no feature reads), and feature values outside the registry range of their
feature (:mod:`robovae.data.features`; e.g. a 100 m geom or a 1e6 kg link: no real robot has
them — check the units). Values beyond the float32 range are an error.
"""

from __future__ import annotations

import contextlib
import math
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
#: Most bodies (MJCF ``<body>``, URDF ``<link>``) a robot file and its includes may declare.
#: MuJoCo's parser and compiler are super-linear: 5,000 bodies load in ~5 s, 20,000 in ~2 min.
MAX_BODIES = 10_000
#: Most points the ``<flexcomp>`` elements of a file may generate.
MAX_FLEX_POINTS = 100_000
#: Largest height field (rows × columns) MuJoCo is asked to allocate.
MAX_HFIELD_CELLS = 2**24
#: Largest builtin texture (pixels, all cube faces) MuJoCo is asked to generate.
MAX_TEXTURE_PIXELS = 2**24
#: Element nesting MuJoCo's XML parser (tinyxml2) accepts.
XML_MAX_DEPTH = 500


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


_COMMENT = re.compile(rb"<!--.*?(?:-->|\Z)", re.S)
_CHAR_REF = re.compile(rb"&#(x[0-9a-fA-F]+|[0-9]+);")
_TAG = re.compile(rb"<(/?)(body|link|replicate|flexcomp|include|hfield|texture)\b([^>]*)>")
_ATTR = re.compile(rb"""\b(count|file|nrow|ncol|width|height|builtin|type)\s*=\s*"""
                   rb"""(?:"([^"]*)"|'([^']*)')""")


def _ints(text: bytes) -> list[int]:
    """The numbers of a ``count`` attribute (unparsable ones are left to MuJoCo)."""
    out = []
    for tok in text.split():
        try:
            out.append(max(0, int(float(tok))))
        except (ValueError, OverflowError):
            out.append(0)
    return out


def _line(data: bytes, offset: int) -> int:
    return data.count(b"\n", 0, offset) + 1


def _xml_char(code: int) -> bool:
    """Whether ``code`` is a character XML 1.0 allows (no NUL, controls or surrogates)."""
    return code in (0x9, 0xA, 0xD) or 0x20 <= code <= 0xD7FF or 0xE000 <= code <= 0xFFFD \
        or 0x10000 <= code <= 0x10FFFF


def scan_robot_file(path: str | Path) -> None:
    """Check a robot file and the files it includes before MuJoCo parses them.

    Raises:
        RobotFileError: unsupported suffix, missing or unreadable file, empty, too large, not
            UTF-8, DOCTYPE/ENTITY declarations, character references to forbidden
            characters, more than :data:`MAX_BODIES` bodies or :data:`MAX_FLEX_POINTS` flex
            points, height fields or builtin textures over :data:`MAX_HFIELD_CELLS` /
            :data:`MAX_TEXTURE_PIXELS`, an include that is not a regular file.
    """
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise RobotFileError(path, f"unsupported file type '{path.suffix}' (want .xml or .urdf)")
    if not path.exists():
        raise RobotFileError(path, "no such file")
    if not path.is_file():
        raise RobotFileError(path, "not a regular file")
    base = path.parent
    seen: set[Path] = set()
    total = {"bytes": 0, "bodies": 0, "flex": 0}

    def scan(file: Path, factor: int, where: str) -> None:
        inc = f"included file '{file.name}', " if where else ""
        try:
            size = file.stat().st_size
            if total["bytes"] + size > _MAX_BYTES:
                raise RobotFileError(path, f"file too large ({(total['bytes'] + size) / 2**20:.0f}"
                                     f" MiB > {_MAX_BYTES // 2**20} MiB)", where or None)
            data = file.read_bytes()
        except OSError as e:
            raise RobotFileError(path, f"cannot read: {e.strerror or e}", where or None) from None
        total["bytes"] += len(data)
        if not data.strip():
            raise RobotFileError(path, "empty file", where or None)
        if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
            raise RobotFileError(path, "not UTF-8 text (UTF-16 byte-order mark)",
                                 f"{inc}line 1")
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as e:
            raise RobotFileError(path, "not UTF-8 text",
                                 f"{inc}line {_line(data, e.start)}, byte {e.start}") from None
        for token in (b"<!DOCTYPE", b"<!ENTITY"):
            at = data.find(token)
            if at >= 0:
                raise RobotFileError(path, "DOCTYPE/ENTITY declarations are not allowed",
                                     f"{inc}line {_line(data, at)}")
        for m in _CHAR_REF.finditer(data):  # MuJoCo would turn these into invalid UTF-8
            ref = m.group(1)
            code = int(ref[1:], 16) if ref[:1] == b"x" else int(ref)
            if not _xml_char(code):
                raise RobotFileError(path, f"invalid character reference "
                                     f"'{m.group(0).decode()}'", f"{inc}line "
                                     f"{_line(data, m.start())}")
        stack = [factor]  # copies of the current element (product of enclosing replicates)
        for m in _TAG.finditer(_COMMENT.sub(b"", data)):
            closing, tag, attrs = m.group(1), m.group(2), m.group(3)
            self_closing = attrs.rstrip().endswith(b"/")
            values = {a.group(1): a.group(2) if a.group(2) is not None else a.group(3)
                      for a in _ATTR.finditer(attrs)}
            if tag == b"replicate":
                if closing:
                    if len(stack) > 1:
                        stack.pop()
                elif not self_closing:
                    n = _ints(values.get(b"count", b"1"))
                    stack.append(stack[-1] * (n[0] if n else 1))
            elif closing:
                continue
            elif tag in (b"body", b"link"):
                total["bodies"] += stack[-1]
                if total["bodies"] > MAX_BODIES:
                    raise RobotFileError(path, f"more than {MAX_BODIES} bodies: MuJoCo "
                                         "would take minutes to load them", where or None)
            elif tag == b"flexcomp":
                points = stack[-1] * math.prod(_ints(values.get(b"count", b"1")) or [1])
                total["flex"] += points
                if total["flex"] > MAX_FLEX_POINTS:
                    raise RobotFileError(path, f"flexcomp count too large (more than "
                                         f"{MAX_FLEX_POINTS} points)", where or None)
            elif tag == b"hfield":
                cells = math.prod(_ints(values.get(b"nrow", b"0") + b" "
                                        + values.get(b"ncol", b"0")))
                if cells > MAX_HFIELD_CELLS:
                    raise RobotFileError(path, f"height field too large (more than "
                                         f"{MAX_HFIELD_CELLS} cells)", f"{inc}line "
                                         f"{_line(data, m.start())}")
            elif tag == b"texture" and values.get(b"builtin", b"none").strip() != b"none":
                cube = values.get(b"type", b"").strip() in (b"cube", b"skybox")
                pixels = math.prod(_ints(values.get(b"width", b"0") + b" "
                                         + values.get(b"height", b"0"))) * (6 if cube else 1)
                if pixels > MAX_TEXTURE_PIXELS:
                    raise RobotFileError(path, f"builtin texture too large (more than "
                                         f"{MAX_TEXTURE_PIXELS} pixels)", f"{inc}line "
                                         f"{_line(data, m.start())}")
            elif tag == b"include" and b"file" in values:
                name = values[b"file"].decode("utf-8", "replace")
                target = Path(name) if Path(name).is_absolute() else base / name
                try:
                    key = target.resolve()
                except (OSError, RuntimeError):
                    continue  # MuJoCo reports it
                if key in seen or not target.exists():
                    continue  # loops and missing files: MuJoCo reports them
                if not target.is_file():
                    raise RobotFileError(path, "included file is not a regular file",
                                         f"include '{name}'")
                seen.add(key)
                scan(target, stack[-1], f"include '{name}'")

    seen.add(path.resolve())
    scan(path, 1, "")


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


def _element(model: mujoco.MjModel, kind: str, i: int) -> str:
    """``body 'torso'`` / ``joint 3``: a model element for error messages."""
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
                                     _element(model, kind, row))


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


def load_robot(path: str | Path) -> LoadedRobot:
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
                                _element(model, _NODE_KIND[types[r]], ids[r]))
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
    except FeatureValueError as e:
        raise RobotFileError(path, e.what, e.where) from None
    except UnicodeDecodeError:
        raise RobotFileError(path, "not UTF-8 text (in a name or file name)") from None
    except ValueError as e:
        raise RobotFileError(path, str(e)) from None


__all__ = ["MAX_BODIES", "MAX_FLEX_POINTS", "MAX_HFIELD_CELLS", "MAX_TEXTURE_PIXELS",
           "FeatureValueError", "LoadedRobot", "drop_missing_assets", "load_robot",
           "mjcf_to_graph", "model_to_graph", "robot_name", "robot_root", "scan_robot_file"]
