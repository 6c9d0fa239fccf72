"""Generators for the reliability property tests (``test_fuzz.py``).

- :func:`robot_descs` (hypothesis): random *valid* robots — random nesting, hinge/slide/ball
  joints (0-2 per body, a free joint only at the root), sphere/capsule/box geoms with random
  sizes and masses, explicit inertials, motors — as plain data, built into a ``mujoco.MjSpec``
  by :func:`build_spec`. "Valid" means what MuJoCo and the writer's rules accept, so a round
  trip must not need any repair (values stay well inside the thresholds of
  :mod:`robovae.generate.rules`).
- :func:`roundtrip_expected` / :func:`assert_same_graph`: the round-trip comparison of
  ``tests/generate/test_writer.py`` (same documented exceptions).
- :func:`mutate`: seeded byte / attribute / element mutations of a robot file.
- :func:`run_cases`: loads files with :func:`robovae.data.mjcf.mjcf_to_graph` in spawned worker
  processes with a per-case timeout, so crashes (including segfaults) and hangs are counted
  rather than taking the test run down.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing as mp
import os
import random
import re
import time
import traceback
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from multiprocessing.connection import wait
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

# --- random valid robots (hypothesis) ---------------------------------------------------------


@dataclass
class JointDesc:
    type: str  # free, hinge, slide, ball
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    range: tuple[float, float] | None = None  # None: unlimited
    damping: float = 0.0
    armature: float = 0.0
    frictionloss: float = 0.0
    stiffness: float = 0.0
    motor: tuple[float, tuple[float, float] | None] | None = None  # (gear, ctrlrange)


@dataclass
class GeomDesc:
    type: str  # sphere, capsule, box
    size: tuple[float, float, float]
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    friction: tuple[float, float, float]
    collides: bool
    mass: float | None  # None: density 1000


@dataclass
class BodyDesc:
    parent: int  # -1: the world
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    joints: list[JointDesc] = field(default_factory=list)
    geoms: list[GeomDesc] = field(default_factory=list)
    # (mass, diaginertia, ipos, iquat) or None: from the geoms
    inertial: tuple[float, tuple, tuple, tuple] | None = None


def _f(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def _signed(lo: float, hi: float) -> st.SearchStrategy[float]:
    """|x| in [lo, hi], either sign."""
    return st.tuples(_f(lo, hi), st.booleans()).map(lambda t: -t[0] if t[1] else t[0])


@st.composite
def _unit(draw, n: int) -> tuple[float, ...]:
    v = draw(st.tuples(*[_f(-1.0, 1.0)] * n).filter(lambda v: math.hypot(*v) > 0.2))
    norm = math.hypot(*v)
    return tuple(a / norm for a in v)


@st.composite
def _position(draw, lo: float = 0.05, hi: float = 0.5) -> tuple[float, float, float]:
    """A position at least ``lo`` from the origin (whole limbs collapsed onto their parent's
    origin are what the ``limb_length`` rule repairs)."""
    x, y = draw(_f(-hi, hi)), draw(_f(-hi, hi))
    return x, y, draw(_signed(lo, hi))


@st.composite
def _joint(draw, jtype: str) -> JointDesc:
    rng = None
    if draw(st.booleans()):
        if jtype == "ball":
            rng = (0.0, draw(_f(0.1, 3.0)))
        elif jtype == "slide":
            rng = (draw(_f(-0.5, -0.01)), draw(_f(0.01, 0.5)))
        else:
            rng = (draw(_f(-3.0, -0.05)), draw(_f(0.05, 3.0)))
    small = st.one_of(st.just(0.0), _f(1e-3, 5.0))
    motor = None
    if draw(st.booleans()):
        ctrl = (draw(_f(-2.0, -0.1)), draw(_f(0.1, 2.0))) if draw(st.booleans()) else None
        motor = (draw(_f(1.0, 100.0)), ctrl)
    return JointDesc(jtype, draw(_unit(3)), draw(st.tuples(*[_f(-0.1, 0.1)] * 3)), rng,
                     draw(small), draw(small), draw(small), draw(small), motor)


@st.composite
def _geom(draw) -> GeomDesc:
    gtype = draw(st.sampled_from(["sphere", "capsule", "box"]))
    if gtype == "sphere":
        size = (draw(_f(0.02, 0.3)), 0.0, 0.0)
    elif gtype == "capsule":
        size = (draw(_f(0.02, 0.1)), draw(_f(0.02, 0.3)), 0.0)
    else:  # not flatter than 1:5 (a + b >= c keeps a margin through the XML's 6 digits)
        a = draw(_f(0.04, 0.2))
        size = (a, a * draw(_f(0.2, 1.0)), a * draw(_f(0.2, 1.0)))
    friction = (draw(_f(0.1, 2.0)), draw(_f(1e-3, 0.1)), draw(_f(1e-5, 1e-3)))
    mass = draw(st.one_of(st.none(), _f(0.01, 10.0)))
    return GeomDesc(gtype, size, draw(st.tuples(*[_f(-0.2, 0.2)] * 3)), draw(_unit(4)),
                    friction, draw(st.booleans()), mass)


@st.composite
def robot_descs(draw, max_bodies: int = 8) -> list[BodyDesc]:
    """A random valid robot: one top-level body (free, welded or 1 limited joint) and a random
    tree below it (each body 0-2 joints; a ball joint last among them)."""
    n = draw(st.integers(1, max_bodies))
    bodies = []
    for i in range(n):
        parent = -1 if i == 0 else draw(st.integers(0, i - 1))
        if i == 0:
            root = draw(st.sampled_from(["free", "welded", "hinge", "slide"]))
            joints = [JointDesc("free")] if root == "free" else [] if root == "welded" else \
                [draw(_joint(root).filter(lambda j: j.range is not None))]  # limited: not free
        else:
            kinds = draw(st.lists(st.sampled_from(["hinge", "slide", "ball"]), max_size=2))
            kinds.sort(key=lambda k: k == "ball")  # nothing rotates after a ball joint
            kinds = kinds[: kinds.index("ball") + 1] if "ball" in kinds else kinds
            joints = [draw(_joint(k)) for k in kinds]
        geoms = draw(st.lists(_geom(), min_size=1 if i == 0 else 0, max_size=3))
        inertial = None
        if not geoms or draw(st.booleans()):
            inertia = tuple(draw(_f(0.051, 0.1)) for _ in range(3))  # a + b > c always
            inertial = (draw(_f(0.05, 5.0)), inertia, draw(st.tuples(*[_f(-0.1, 0.1)] * 3)),
                        draw(_unit(4)))
        bodies.append(BodyDesc(parent, draw(_position()), draw(_unit(4)), joints, geoms,
                               inertial))
    return bodies


_JOINT_TYPE = {"free": "mjJNT_FREE", "hinge": "mjJNT_HINGE", "slide": "mjJNT_SLIDE",
               "ball": "mjJNT_BALL"}
_GEOM_TYPE = {"sphere": "mjGEOM_SPHERE", "capsule": "mjGEOM_CAPSULE", "box": "mjGEOM_BOX"}


def build_spec(bodies: list[BodyDesc], name: str = "random"):
    """The ``mujoco.MjSpec`` of a :func:`robot_descs` robot (angles in radians)."""
    import mujoco

    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.compiler.degree = False
    true, false = mujoco.mjtLimited.mjLIMITED_TRUE, mujoco.mjtLimited.mjLIMITED_FALSE
    made = []
    for i, b in enumerate(bodies):
        parent = spec.worldbody if b.parent < 0 else made[b.parent]
        body = parent.add_body(name=f"b{i}", pos=list(b.pos), quat=list(b.quat))
        made.append(body)
        if b.inertial is not None:
            mass, inertia, ipos, iquat = b.inertial
            body.mass, body.inertia, body.ipos, body.iquat = mass, list(inertia), list(ipos), \
                list(iquat)
            body.explicitinertial = True
        for k, j in enumerate(b.joints):
            jt = getattr(mujoco.mjtJoint, _JOINT_TYPE[j.type])
            joint = body.add_joint(name=f"b{i}_j{k}", type=jt)
            if j.type == "free":
                continue
            joint.axis, joint.pos = list(j.axis), list(j.pos)
            joint.limited = true if j.range else false
            if j.range:
                joint.range = list(j.range)
            joint.damping[0], joint.armature = j.damping, j.armature
            joint.frictionloss, joint.stiffness[0] = j.frictionloss, j.stiffness
            if j.motor:
                gear, ctrl = j.motor
                act = spec.add_actuator(name=f"b{i}_j{k}_motor", target=f"b{i}_j{k}",
                                        trntype=mujoco.mjtTrn.mjTRN_JOINT)
                act.set_to_motor()
                act.gear = [gear, 0, 0, 0, 0, 0]
                act.ctrllimited = true if ctrl else false
                if ctrl:
                    act.ctrlrange = list(ctrl)
        for k, g in enumerate(b.geoms):
            geom = body.add_geom(name=f"b{i}_g{k}", type=getattr(mujoco.mjtGeom,
                                                                 _GEOM_TYPE[g.type]),
                                 size=list(g.size), pos=list(g.pos), quat=list(g.quat),
                                 friction=list(g.friction))
            geom.contype = geom.conaffinity = int(g.collides)
            if g.mass is not None:
                geom.mass = g.mass
    return spec


# --- round-trip comparison (as in tests/generate/test_writer.py) ------------------------------

RTOL, ATOL = 1e-5, 1e-9


def roundtrip_expected(g, fs_name: str) -> np.ndarray:
    """The features a round trip must give back: ``g.x`` except ``paper34`` links without a
    geom (the writer's sphere) and, in ``full``, size components a primitive does not use."""
    from robovae.data.features import GEOM, GEOM_TYPES, LINK, get_feature_set
    from robovae.generate.rules_geometry import DEFAULT_GEOM_RADIUS, GEOM_SIZE_COMPONENTS

    fs = get_feature_set(fs_name)
    x = g.x.double().numpy().copy()
    types = g.node_type.tolist()
    size = fs.slice("link.size")
    if fs_name == "paper34":
        for i in (i for i, t in enumerate(types) if t == LINK):
            if not x[i, size].any():
                x[i, size] = [DEFAULT_GEOM_RADIUS, 0.0, 0.0]
        return x
    gsize, gtype, coll = fs.slice("geom.size"), fs.slice("geom.type"), fs.slice("geom.collides")
    used = {}
    for i in (i for i, t in enumerate(types) if t == GEOM):
        used[i] = GEOM_SIZE_COMPONENTS[GEOM_TYPES[int(np.argmax(x[i, gtype]))]]
        x[i, gsize.start + used[i]:gsize.stop] = 0.0
    parent = g.parent.tolist()
    for i in (i for i, t in enumerate(types) if t == LINK):
        geoms = [c for c in range(len(types)) if parent[c] == i and types[c] == GEOM]
        first = next((c for c in geoms if x[c, coll.start] > 0.5), geoms[0] if geoms else -1)
        if first >= 0:
            x[i, size.start + used[first]:size.stop] = 0.0
    return x


def assert_same_graph(g, back, want: np.ndarray, fs_name: str, what: str) -> None:
    """Topology exact, features within ``RTOL``/``ATOL`` of ``want``."""
    from robovae.data.features import get_feature_set

    assert g.parent.tolist() == back.parent.tolist(), f"{what}: parents differ"
    assert g.node_type.tolist() == back.node_type.tolist(), f"{what}: node types differ"
    got = back.x.double().numpy()
    bad = ~np.isclose(got, want, rtol=RTOL, atol=ATOL)
    if bad.any():
        cols = get_feature_set(fs_name).columns
        r, c = np.argwhere(bad)[0]
        raise AssertionError(f"{what}: {int(bad.sum())} values differ, first: node {r} "
                             f"{cols[c]} {want[r, c]!r} -> {got[r, c]!r}")


# --- mutations --------------------------------------------------------------------------------

#: Replacement attribute values: non-numbers, non-finite, huge, tiny, negative, wrong arity.
NASTY_VALUES = ["nan", "inf", "-inf", "NaN nan nan", "-1", "0", "0 0 0", "-0", "1e308", "-1e308",
                "3.5e38", "1e39", "1e-320", "1e400", "", " ", "abc", "1 2", "1 2 3 4 5 6 7 8 9",
                "0x10", "1,2,3", "true", "99999999999999999999", "-99999999999", "1e6 1e6 1e6",
                "100000", "\u00e9\u00e9", "&amp;", "free", "ball", "mesh", "hfield", "plane",
                "none", "../../../etc/passwd", "/dev/zero"]
#: Byte strings inserted at random places.
NASTY_BYTES = [b"<", b">", b'"', b"'", b"&", b"&amp;", b"&#0;", b"&#xD800;", b"&lol;", b"<!--",
               b"-->", b"<![CDATA[", b"]]>", b"<!DOCTYPE x>", b"\x00", b"\xff\xfe", b"\xc3",
               b"\xe9", b"<body>", b"</body>", b"<body/>", b"<joint/>", b"<geom/>", b"</mujoco>",
               b"<mujoco>", b'<include file="x.xml"/>', b"<?xml version='1.0'?>", b"\r\n",
               b"\t" * 50, b" nan ", b"1e999"]
#: Elements inserted into random places.
NEW_ELEMENTS = [
    '<body name="x"><geom size="0.1"/></body>', "<body/>", '<joint type="free"/>', "<freejoint/>",
    '<joint type="ball"/>', '<joint type="slide" range="1 -1"/>', '<geom type="mesh" mesh="m"/>',
    '<geom type="plane" size="0 0 1"/>', '<geom type="hfield"/>', '<geom size="-1"/>',
    '<inertial mass="-1" pos="0 0 0" diaginertia="1 1 1"/>', '<inertial mass="0" pos="0 0 0"/>',
    '<site name="s"/>', "<camera/>", '<light directional="true"/>', "<frame><body/></frame>",
    '<replicate count="3" offset="0 0 1"><body><geom size="0.1"/></body></replicate>',
    '<replicate count="100000"><body/></replicate>', '<include file="missing.xml"/>',
    '<flexcomp type="grid" count="2000 2000 1" spacing="1 1 1" dim="2"/>',
    '<attach model="nope" body="b" prefix="p"/>', '<default class="c"><geom size="1"/></default>',
    '<motor joint="nope"/>', '<position joint="nope" kp="1e400"/>', "<wing/>", "<mujoco/>",
    '<hfield name="h" nrow="100000" ncol="100000" size="1 1 1 1"/>',
    '<texture name="t" type="2d" builtin="checker" width="100000" height="100000"/>',
    '<mesh name="m" vertex="0 0 0 1 0 0 0 1 0"/>', '<mesh name="m2" file="/dev/zero"/>',
]
_MJCF_TAGS = ["body", "geom", "joint", "site", "inertial", "worldbody", "mujoco", "default",
              "include", "replicate", "frame", "freejoint", "asset", "mesh", "actuator", "motor",
              "link", "robot", "visual", "collision", "origin", "axis", "limit", "unknown"]
_ATTR = re.compile(rb"""([A-Za-z_:][-\w:.]*)\s*=\s*("[^"]*"|'[^']*')""")


def _mutate_tree(text: bytes, rng: random.Random, ops: list[str]) -> bytes:
    """One or two element mutations (delete, duplicate, move, rename, nest, insert)."""
    try:
        return _mutate_tree_once(text, rng, ops)
    except RecursionError:  # ElementTree serialises recursively: nests of nests are too deep
        ops.append("element mutation skipped (too deep to serialise)")
        return text


def _mutate_tree_once(text: bytes, rng: random.Random, ops: list[str]) -> bytes:
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return text
    for _ in range(1 if rng.random() < 0.7 else 2):
        elems = list(root.iter())
        parents = {c: p for p in elems for c in p}
        e = rng.choice(elems)
        op = rng.choice(["delete", "delete", "duplicate", "duplicate", "move", "move", "rename",
                         "nest", "insert"])
        ops.append(f"element {op} <{e.tag}>")
        if op in ("delete", "duplicate", "move", "nest") and e not in parents:
            continue
        if op == "delete":
            parents[e].remove(e)
        elif op == "duplicate":
            p = parents[e]
            p.insert(list(p).index(e), ET.fromstring(ET.tostring(e)))
        elif op == "move":
            target = rng.choice(elems)
            if any(x is target for x in e.iter()):  # not into itself or its own subtree
                continue
            parents[e].remove(e)
            target.append(e)
        elif op == "rename":
            e.tag = rng.choice(_MJCF_TAGS)
        elif op == "nest":  # wrap in a chain of bodies (sometimes beyond the parser's depth)
            p, k = parents[e], list(parents[e]).index(e)
            p.remove(e)
            depth = rng.choice([1, 1, 5, 50, 600])
            outer = inner = ET.Element("body")
            for _ in range(depth - 1):
                inner = ET.SubElement(inner, "body")
            inner.append(e)
            p.insert(k, outer)
        else:
            e.append(ET.fromstring(rng.choice(NEW_ELEMENTS)))
    return ET.tostring(root)


def _numbers(value: bytes, fn) -> bytes:
    """``value`` with every number ``v`` replaced by ``fn(v)`` (other tokens kept)."""
    out = []
    for tok in value.split():
        try:
            out.append(repr(fn(float(tok))).encode())
        except (ValueError, OverflowError):
            out.append(tok)
    return b" ".join(out)


def _mutate_attrs(text: bytes, rng: random.Random, ops: list[str]) -> bytes:
    """One or two attribute mutations (perturbed numbers, nasty value, scaled numbers, delete,
    duplicate, rename, swap)."""
    for _ in range(1 if rng.random() < 0.6 else 2):
        matches = list(_ATTR.finditer(text))
        if not matches:
            return text
        m = rng.choice(matches)
        name, value = m.group(1), m.group(2)[1:-1]
        op = rng.choice(["perturb", "perturb", "perturb", "value", "value", "scale", "delete",
                         "duplicate", "rename", "swap"])
        ops.append(f"attribute {op} {name.decode(errors='replace')}")
        if op == "perturb":
            new = name + b'="' + _numbers(value, lambda v: v * rng.uniform(0.5, 2.0)
                                          + rng.choice([0.0, 0.0, 1e-3, -0.1])) + b'"'
        elif op == "value":
            new = name + b'="' + rng.choice(NASTY_VALUES).encode() + b'"'
        elif op == "scale":
            factor = rng.choice([-1.0, 0.0, 1e-9, 1e6, 1e30, 1e300])
            new = name + b'="' + _numbers(value, lambda v, f=factor: v * f) + b'"'
        elif op == "delete":
            new = b""
        elif op == "duplicate":
            new = m.group(0) + b" " + m.group(0)
        elif op == "rename":
            new = rng.choice([b"size", b"pos", b"type", b"mass", b"name", b"class", b"file",
                              b"childclass", b"bogus"]) + b"=" + m.group(2)
        else:
            other = rng.choice(matches)
            new = name + b"=" + other.group(2)
        text = text[:m.start()] + new + text[m.end():]
    return text


def _mutate_bytes(text: bytes, rng: random.Random, ops: list[str]) -> bytes:
    """One to three byte mutations (flip, delete span, duplicate span, truncate, insert)."""
    data = bytearray(text)
    for _ in range(rng.randint(1, 3)):
        if not data:
            data = bytearray(b"<")
        op = rng.choice(["flip", "delete", "duplicate", "truncate", "insert", "insert"])
        ops.append(f"bytes {op}")
        i = rng.randrange(len(data))
        if op == "flip":
            for _ in range(rng.randint(1, 8)):
                data[rng.randrange(len(data))] = rng.randrange(256)
        elif op == "delete":
            del data[i:i + rng.randint(1, 200)]
        elif op == "duplicate":
            chunk = data[i:i + rng.randint(1, 500)]
            j = rng.randrange(len(data))
            data[j:j] = chunk
        elif op == "truncate":
            del data[i:]
        else:
            data[i:i] = rng.choice(NASTY_BYTES)
    return bytes(data)


def mutate(text: bytes, rng: random.Random) -> tuple[bytes, list[str]]:
    """A mutated copy of a robot file and the mutations applied: element (35 %), attribute
    (40 %) or byte (25 %) mutations, and in one case out of ten a second kind on top."""
    ops: list[str] = []
    kinds = [rng.choices(["tree", "attrs", "bytes"], [0.35, 0.4, 0.25])[0]]
    if rng.random() < 0.1:
        kinds.append(rng.choice(["tree", "attrs", "bytes"]))
    for kind in kinds:
        fn = {"tree": _mutate_tree, "attrs": _mutate_attrs, "bytes": _mutate_bytes}[kind]
        text = fn(text, rng, ops)
    return text, ops


_INCLUDE = re.compile(rb"""<include\s[^>]*file\s*=\s*["']([^"']+)["']""")


def included_files(path: Path) -> dict[str, bytes]:
    """The files ``path`` includes (recursively, relative paths), to copy beside its mutants."""
    out: dict[str, bytes] = {}
    todo = [path.read_bytes()]
    while todo:
        for m in _INCLUDE.finditer(todo.pop()):
            rel = m.group(1).decode()
            target = path.parent / rel
            if rel not in out and not Path(rel).is_absolute() and target.is_file():
                out[rel] = target.read_bytes()
                todo.append(out[rel])
    return out


# --- running cases in worker processes -------------------------------------------------------


@dataclass
class Outcome:
    """What loading one file gave: ``graph``, ``error`` (one line), ``multiline`` (an error
    whose message is not one ``robovae: <file>: ...`` line), ``crash`` (any other exception,
    or the worker died) or ``hang`` (over the per-case timeout)."""

    kind: str
    detail: str = ""
    seconds: float = 0.0


def harness_check_loader(path: str, fs: str):
    """A stand-in for ``mjcf_to_graph`` that misbehaves on purpose (file name ``hang``,
    ``abort``, ``boom``, ``multi``), to check that :func:`run_cases` counts every outcome;
    other files give a one-node graph (``good*``) or a one-line error. Imports nothing heavy,
    so its workers start in a moment."""
    from types import SimpleNamespace

    from robovae.errors import RobotFileError, RobovaeError

    stem = Path(path).stem
    if stem == "hang":
        time.sleep(3600)
    if stem == "abort":
        os.abort()  # dies like a segfault would
    if stem == "boom":
        raise KeyError("boom")
    if stem == "multi":
        raise RobovaeError(f"robovae: {path}: two\nlines")
    if stem.startswith("good"):
        return SimpleNamespace(x=np.zeros((1, 3)), num_nodes=1, parent=[-1], warnings="")
    raise RobotFileError(path, "bad file", "line 1")


def _worker(conn, cwd: str, loader: str) -> None:
    """Worker process: receive ``(path, feature set)``, send back ``(kind, detail)``."""
    import importlib
    import sys

    os.chdir(cwd)
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ["OMP_NUM_THREADS"] = "1"
    from robovae.errors import RobovaeError

    module, _, func = loader.partition(":")
    load = getattr(importlib.import_module(module), func)  # imported before any clock starts
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)

    conn.send(("ready", ""))
    while True:
        item = conn.recv()
        if item is None:
            return
        path, fs = item
        try:
            g = load(path, fs)
            problems = []
            if not bool(np.isfinite(np.asarray(g.x)).all()):
                problems.append("non-finite features")
            if g.num_nodes < 1 or int(g.parent[0]) != -1:
                problems.append("bad tree")
            if "\n" in getattr(g, "warnings", ""):
                problems.append("multi-line warnings")
            result = ("crash", "graph: " + ", ".join(problems)) if problems else ("graph", "")
        except RobovaeError as e:
            msg = str(e)
            ok = "\n" not in msg and msg.startswith(f"robovae: {path}: ")
            result = ("error" if ok else "multiline", msg)
        except BaseException as e:  # noqa: BLE001 - counting exactly these is the point
            result = ("crash", f"{type(e).__name__}: {e}\n{traceback.format_exc()}")
        conn.send(result)


class _Slot:
    def __init__(self, ctx, cwd: str, loader: str) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, cwd, loader), daemon=True)
        self.proc.start()
        child.close()
        self.case: int | None = None
        self.started = 0.0
        self.ready = False

    def stop(self, kill: bool = False) -> None:
        if kill:
            self.proc.kill()
        else:
            with contextlib.suppress(OSError):
                self.conn.send(None)
        self.proc.join(10)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


def run_cases(cases: list[tuple[str, str]], workers: int = 2, timeout: float = 20.0,
              cwd: str | None = None, loader: str = "robovae.data.mjcf:mjcf_to_graph"
              ) -> list[Outcome]:
    """Load every ``(path, feature set)`` with ``loader`` (``module:function``) in ``workers``
    spawned processes; a case running longer than ``timeout`` seconds is a ``hang`` (its worker
    is killed and replaced), a worker that dies is a ``crash``."""
    ctx = mp.get_context("spawn")
    cwd = cwd or os.getcwd()
    slots = [_Slot(ctx, cwd, loader) for _ in range(max(1, workers))]
    out: list[Outcome | None] = [None] * len(cases)
    todo = list(range(len(cases)))[::-1]
    try:
        while todo or any(s.case is not None for s in slots):
            for s in slots:
                if s.ready and s.case is None and todo:
                    s.case, s.started = todo.pop(), time.monotonic()
                    s.conn.send(cases[s.case])
            ready = wait([s.conn for s in slots], timeout=0.5)
            for k, s in enumerate(slots):
                if s.conn in ready:
                    try:
                        kind, detail = s.conn.recv()
                    except (EOFError, OSError):
                        s.proc.join(5)
                        if not s.ready:
                            raise RuntimeError(f"fuzz worker failed to start (exit code "
                                               f"{s.proc.exitcode})") from None
                        kind, detail = "crash", f"worker died (exit code {s.proc.exitcode})"
                    if kind == "ready":
                        s.ready = True
                        continue
                    if s.case is not None:
                        out[s.case] = Outcome(kind, detail, time.monotonic() - s.started)
                        s.case = None
                    if kind == "crash" and detail.startswith("worker died"):
                        s.stop(kill=True)
                        slots[k] = _Slot(ctx, cwd, loader)
                elif s.case is not None and time.monotonic() - s.started > timeout:
                    out[s.case] = Outcome("hang", f"over {timeout:.0f} s", timeout)
                    s.case = None
                    s.stop(kill=True)
                    slots[k] = _Slot(ctx, cwd, loader)
    finally:
        for s in slots:
            s.stop(kill=s.case is not None)
    return [o if o is not None else Outcome("crash", "no result") for o in out]
