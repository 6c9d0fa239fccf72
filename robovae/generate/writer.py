"""Robot graph → complete MJCF, built with ``mujoco.MjSpec`` (SPEC §7, paper §4.1/§6.1).

This is the inverse of :mod:`robovae.data.mjcf`: every feature the reader takes from the compiled
``MjModel`` is written back to the element it came from, so that MJCF → graph → MJCF → graph
reproduces the graph (tested on every zoo and Menagerie robot).

Mapping (nodes in pre-order; :func:`robovae.generate.rules.link_structure`):

- **link → body**, a child of its nearest ancestor link's body (the world body for the root
  link(s)): ``pos``, ``quat`` and an explicit ``<inertial>`` (``mass``, ``diaginertia``,
  ``ipos``, ``iquat``). ``compiler.inertiafromgeom = "false"``: geoms never change the inertials.
  A root link with no joint above it is welded to the world (fixed base).
- **joint → joint** of the body it leads to: all joints of a chain ``link — j1 — j2 — link``
  belong to the lower link's body, in order. Type from the ``joint.type`` one-hot (``full``) or
  inferred (``paper34``, see :func:`robovae.generate.rules.joint_types`: the root joint is
  ``free`` when it looks like one, every other joint a ``hinge``). Axis, pos, range (limited
  when the ``limited`` flag is set, or in ``paper34`` when the range is non-zero), damping,
  armature, frictionloss and stiffness.
- **geom → geom** of its link's body (``full``): type from the one-hot, pos, quat, size,
  friction; ``collides`` → ``contype = 1`` and ``conaffinity = 1`` with ``self_collision``,
  else ``conaffinity = 0`` (the robot collides with the floor, not with itself); non-colliding
  geoms get ``contype = conaffinity = 0``.
- **no geom nodes at all** (``paper34``, or a ``full`` graph without any): one primitive per
  body from ``link.size``, written verbatim so that it reads back as the same size: ``(r, 0, 0)``
  → sphere at the body origin, ``(r, h, 0)`` → capsule, ``(x, y, z)`` → box, the last two
  centred half-way to the body's first child link and pointing at it (else centred on the
  centre of mass and pointing at it from the origin, else along z); the root link's geom sits at
  its origin, unrotated. A body with zero size gets a sphere of radius
  :data:`~robovae.generate.rules.DEFAULT_GEOM_RADIUS` so the robot is visible and collides.
- **actuators**: one ``motor`` per non-free joint. ``actuators="auto"``: in sets with
  ``joint.actuated`` only the flagged joints, with their ``gear`` and ``ctrlrange``
  (``(0, 0)`` = unlimited); elsewhere every non-free joint with :data:`DEFAULT_GEAR` and
  :data:`DEFAULT_CTRLRANGE`. ``"all"``: every non-free joint (features when flagged, else the
  defaults). ``"none"``: no actuators.
- **floor placement**: when a top-level body has a free joint and ``clearance`` is not None,
  the model is compiled, ``mj_forward`` run at ``qpos0``, and the lowest point over the robot's
  geoms (corners of each geom's bounding box ``geom_aabb`` in the world frame) is lifted to
  ``z = clearance`` by shifting the free bodies' ``pos[2]``. This changes the root link's
  ``pos[2]`` (the only feature that changes); pass ``clearance=None`` to keep it.

Numbers are rounded to the 6 significant digits MJCF output keeps (and tiny vector components
dropped as ``MjSpec.to_xml`` drops them) before they enter the spec, so the spec and the written
file hold the same values; the few constraints that rounding could break (``a + b ≥ c`` of an
inertia sitting exactly on the boundary) are checked after rounding.

The writer also repairs structures no rule can (they change the topology, so they only happen
with malformed decoded graphs, never with real robots); their names join the fired list
(:data:`WRITER_FIXES`): ``empty_robot`` (no link node: one default body), ``dangling_joint``
(a joint with no link below it: dropped), ``joint_shared`` (a joint leading to several links:
each gets a copy), ``orphan_geom`` (a geom with no link above it: dropped),
``free_not_top_level`` (only with ``rules=False``: such a free joint is written as a hinge),
``dof_chain_split`` (joints of one body with more than 6 DoFs: MuJoCo's limit; the chain is
split with light intermediate bodies), ``inertia_rounding`` (see above).

What survives a round trip (MJCF → graph → :func:`write_robot` → graph), within the 6-digit
MJCF precision:

- ``full`` with geom nodes: the topology (``parent``, ``node_type``) and every feature, except
  the size components a primitive does not use (sphere: 2nd and 3rd, capsule/cylinder: 3rd),
  which MJCF output does not write, so they come back as 0 (``geom.size``, and ``link.size``
  when it copies such a geom's size; a few dm_control dog/rodent geoms carry them). A ``full``
  graph without any geom node (Barkour, Z1 without their meshes) gets the invented geoms
  described above, which come back as geom nodes.
- ``paper34``: the topology and every feature except ``link.size`` of bodies that had no geom
  (size zero: the writer gives them a small sphere, which then has a size). ``subtreemass`` is
  derived from the masses and recomputed by MuJoCo, so it survives too. Joint types are not
  features of ``paper34``: planar robots (slide root joints) come back with hinges, which have
  the same features.
"""

from __future__ import annotations

import math
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np

from robovae.data.features import (
    GEOM,
    GEOM_TYPE_IDS,
    GEOM_TYPES,
    JOINT,
    LINK,
    FeatureSet,
    get_feature_set,
)
from robovae.data.graph import RobotData
from robovae.data.mjcf import capture_mujoco_warnings
from robovae.generate.rules import (
    DEFAULT_GEOM_RADIUS,
    GEOM_SIZE_COMPONENTS,
    MIN_INERTIA,
    MIN_MASS,
    apply_rules,
    joint_types,
    link_structure,
)

__all__ = [
    "DEFAULT_CLEARANCE",
    "DEFAULT_CTRLRANGE",
    "DEFAULT_GEAR",
    "WRITER_FIXES",
    "WriteResult",
    "graph_to_spec",
    "scene_xml",
    "write_robot",
]

#: Gap between the lowest geom point and the floor for free-floating robots (m).
DEFAULT_CLEARANCE = 0.01
#: Motor gear when the feature set has none for the joint.
DEFAULT_GEAR = 1.0
#: Motor control range when the feature set has none for the joint.
DEFAULT_CTRLRANGE = (-1.0, 1.0)
#: Names the writer adds to the fired list when it repairs the tree structure.
WRITER_FIXES = ("empty_robot", "dangling_joint", "joint_shared", "orphan_geom",
                "free_not_top_level", "dof_chain_split", "inertia_rounding")

ActuatorMode = Literal["auto", "all", "none"]

_JNT = {"free": mujoco.mjtJoint.mjJNT_FREE, "ball": mujoco.mjtJoint.mjJNT_BALL,
        "slide": mujoco.mjtJoint.mjJNT_SLIDE, "hinge": mujoco.mjtJoint.mjJNT_HINGE}
_DOFS = {"free": 6, "ball": 3, "slide": 1, "hinge": 1}
_TRUE, _FALSE = mujoco.mjtLimited.mjLIMITED_TRUE, mujoco.mjtLimited.mjLIMITED_FALSE
_SPHERE, _CAPSULE, _BOX = (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE,
                           mujoco.mjtGeom.mjGEOM_BOX)
_GEOM_SIZES = tuple(GEOM_SIZE_COMPONENTS[t] for t in GEOM_TYPES)
_LINK_RGBA = [0.55, 0.6, 0.7, 1.0]
_GEOM_RGBA = [0.8, 0.55, 0.35, 1.0]


@dataclass
class WriteResult:
    """What :func:`write_robot` wrote.

    Attributes:
        robot_path: ``robot.xml``.
        scene_path: ``scene.xml`` (floor, light, ``<include file="robot.xml"/>``) or None.
        rules_fired: names of the rules (and writer fixes) that changed something.
        n_bodies, n_joints, n_geoms, n_actuators: counts of the compiled robot (world excluded).
    """

    robot_path: Path
    scene_path: Path | None
    rules_fired: list[str] = field(default_factory=list)
    n_bodies: int = 0
    n_joints: int = 0
    n_geoms: int = 0
    n_actuators: int = 0

    @property
    def rules(self) -> list[str]:
        """Alias of :attr:`rules_fired`."""
        return self.rules_fired

    @property
    def counts(self) -> dict[str, int]:
        """``{"bodies": ..., "joints": ..., "geoms": ..., "actuators": ...}``."""
        return {"bodies": self.n_bodies, "joints": self.n_joints, "geoms": self.n_geoms,
                "actuators": self.n_actuators}


# --- number rounding as MJCF output does it ---------------------------------------------------


def _q(v: float) -> float:
    """``v`` at the 6 significant digits ``MjSpec.to_xml`` writes."""
    v = float(v)
    if not math.isfinite(v) or abs(v) < 1e-16:
        return v if not math.isfinite(v) else 0.0
    return float(f"{v:.6g}")


def _qv(vec) -> list[float]:
    """A vector as written: rounded, components 12 decades below the largest dropped."""
    arr = [float(a) for a in np.asarray(vec, dtype=float).ravel()]
    big = max((abs(a) for a in arr if math.isfinite(a)), default=0.0)
    return [0.0 if math.isfinite(a) and abs(a) <= 1e-12 * big else _q(a) for a in arr]


def _q_up(v: float) -> float:
    """The smallest 6-significant-digit number ≥ ``v``."""
    q = _q(v)
    step = 1e-6
    while q < v:
        q = _q(v * (1.0 + step) if v > 0 else v * (1.0 - step))
        step *= 2.0
    return q


def _rounded_inertia(inertia) -> tuple[list[float], bool]:
    """Rounded diagonal inertia still satisfying ``a + b >= c`` (and whether it had to move)."""
    out = _qv(inertia)
    moved = False
    for _ in range(20):
        a, b, c = sorted(out)
        if a + b >= c:
            break
        order = np.argsort(out, kind="stable")
        deficit = c - a - b
        for k in order[:2]:
            out[k] = _q_up(out[k] + 0.5 * deficit + 1e-6 * c)
        moved = True
    return out, moved


# --- building the spec -----------------------------------------------------------------------


def _quat_z_to(u: np.ndarray) -> list[float]:
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, np.asarray(u, dtype=float))
    return quat.tolist()


class _Builder:
    def __init__(self, data: RobotData, fs: FeatureSet, name: str, actuators: ActuatorMode,
                 self_collision: bool) -> None:
        self.fs, self.name = fs, name
        self.x = data.x.detach().cpu().double().numpy()
        self.types = data.node_type.tolist()
        self.parent = data.parent.tolist()
        self.keys = {f.key for f in fs.features}
        self.jtypes = joint_types(data, fs)
        self.anc, self.chain = link_structure(self.parent, self.types)
        self.actuators = actuators
        self.self_collision = self_collision
        self.fixes: list[str] = []
        self.free_bodies: list[mujoco.MjsBody] = []

    def get(self, i: int, key: str) -> np.ndarray:
        return self.x[i, self.fs.slice(key)]

    def has(self, key: str) -> bool:
        return key in self.keys

    def fix(self, name: str) -> None:
        if name not in self.fixes:
            self.fixes.append(name)

    # -- elements ------------------------------------------------------------------------------

    def _inertial(self, body: mujoco.MjsBody, mass: float, inertia, ipos, iquat) -> None:
        body.mass = _q(mass)
        body.inertia, moved = _rounded_inertia(inertia)
        if moved:
            self.fix("inertia_rounding")
        body.ipos = _qv(ipos)
        body.iquat = _qv(iquat)
        body.explicitinertial = True

    def _joint(self, body: mujoco.MjsBody, j: int, jtype: str, name: str) -> mujoco.MjsJoint:
        joint = body.add_joint(name=name, type=_JNT[jtype])
        if jtype != "free":
            joint.axis = _qv(self.get(j, "joint.axis"))
            joint.pos = _qv(self.get(j, "joint.pos"))
        lo, hi = (float(a) for a in self.get(j, "joint.range"))
        limited = lo != 0.0 or hi != 0.0
        if self.has("joint.limited"):
            limited = limited and self.get(j, "joint.limited")[0] >= 0.5
        if limited and jtype != "free":
            joint.limited = _TRUE
            joint.range = _qv([lo, hi])
        else:
            joint.limited = _FALSE
        joint.damping[0] = _q(self.get(j, "joint.damping")[0])
        joint.armature = _q(self.get(j, "joint.armature")[0])
        joint.frictionloss = _q(self.get(j, "joint.frictionloss")[0])
        joint.stiffness[0] = _q(self.get(j, "joint.stiffness")[0])
        return joint

    def _actuate(self, spec: mujoco.MjSpec, j: int, jtype: str, jname: str) -> None:
        if self.actuators == "none" or jtype == "free":
            return
        flagged = self.has("joint.actuated") and self.get(j, "joint.actuated")[0] >= 0.5
        if self.actuators == "auto" and self.has("joint.actuated") and not flagged:
            return
        gear = _q(self.get(j, "joint.gear")[0]) if flagged and self.has("joint.gear") \
            else DEFAULT_GEAR
        if flagged and self.has("joint.ctrlrange"):
            ctrl = _qv(self.get(j, "joint.ctrlrange"))
        else:
            ctrl = list(DEFAULT_CTRLRANGE)
        act = spec.add_actuator(name=f"{jname}_motor", target=jname,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        act.gear = [gear] * (3 if jtype == "ball" else 1) + [0.0] * (3 if jtype == "ball" else 5)
        if ctrl[0] != 0.0 or ctrl[1] != 0.0:
            act.ctrllimited = _TRUE
            act.ctrlrange = ctrl
        else:
            act.ctrllimited = _FALSE

    def _groups(self, joints: list[int], top_level: bool) -> list[list[tuple[int, str]]]:
        """Joints of one link split into bodies of at most 6 DoFs (free only alone, on top)."""
        typed = []
        for j in joints:
            t = self.jtypes[j]
            if t == "free" and not (top_level and len(joints) == 1):
                self.fix("free_not_top_level")
                t = "hinge"
            typed.append((j, t))
        groups: list[list[tuple[int, str]]] = [[]]
        dofs = 0
        for j, t in typed:
            if dofs + _DOFS[t] > 6:
                groups.append([])
                dofs = 0
            groups[-1].append((j, t))
            dofs += _DOFS[t]
        if len(groups) > 1:
            self.fix("dof_chain_split")
        return groups

    def _invented_geom(self, body: mujoco.MjsBody, i: int, first_child: int, root: bool) -> None:
        size = np.maximum(self.get(i, "link.size"), 0.0) if self.has("link.size") \
            else np.zeros(3)
        k = 0
        while k < 3 and size[k] > 0:
            k += 1
        pos, quat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
        if k >= 2 and not root:
            target = self.get(first_child, "link.pos") if first_child >= 0 else np.zeros(3)
            ipos = self.get(i, "link.ipos")
            if np.linalg.norm(target) > 1e-9:
                u, c = target / np.linalg.norm(target), 0.5 * target
            elif np.linalg.norm(ipos) > 1e-9:
                u, c = ipos / np.linalg.norm(ipos), ipos
            else:
                u, c = np.array([0.0, 0.0, 1.0]), np.zeros(3)
            pos, quat = _qv(c), _qv(_quat_z_to(u))
        if k == 0:
            gtype, gsize = _SPHERE, [DEFAULT_GEOM_RADIUS, 0.0, 0.0]
        else:
            gtype = (_SPHERE, _CAPSULE, _BOX)[k - 1]
            gsize = _qv(size)
        g = body.add_geom(name=f"link{i}_geom", type=gtype, size=gsize, pos=pos, quat=quat,
                          rgba=_LINK_RGBA)
        g.contype, g.conaffinity = 1, int(self.self_collision)

    def _graph_geom(self, body: mujoco.MjsBody, g: int) -> None:
        k = int(np.argmax(self.get(g, "geom.type")))
        size = _qv(self.get(g, "geom.size"))
        size[_GEOM_SIZES[k]:] = [0.0] * (3 - _GEOM_SIZES[k])  # MJCF keeps the used ones only
        geom = body.add_geom(name=f"geom{g}", type=mujoco.mjtGeom(GEOM_TYPE_IDS[k]),
                             pos=_qv(self.get(g, "geom.pos")), quat=_qv(self.get(g, "geom.quat")),
                             size=size,
                             friction=_qv(self.get(g, "geom.friction")), rgba=_GEOM_RGBA)
        collides = self.get(g, "geom.collides")[0] >= 0.5 if self.has("geom.collides") else True
        geom.contype = int(collides)
        geom.conaffinity = int(collides and self.self_collision)

    # -- the tree --------------------------------------------------------------------------------

    def build(self) -> mujoco.MjSpec:
        spec = mujoco.MjSpec()
        spec.modelname = self.name
        spec.compiler.degree = False
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        links = [i for i, t in enumerate(self.types) if t == LINK]
        if not links:
            self.fix("empty_robot")
            body = spec.worldbody.add_body(name="link0")
            r = DEFAULT_GEOM_RADIUS
            self._inertial(body, 1e-3, [0.4e-3 * r * r] * 3, [0, 0, 0], [1, 0, 0, 0])
            g = body.add_geom(name="link0_geom", type=_SPHERE, size=[r, 0, 0], rgba=_LINK_RGBA)
            g.contype, g.conaffinity = 1, int(self.self_collision)
            return spec

        used: dict[int, int] = {}
        bodies: dict[int, mujoco.MjsBody] = {}
        acts: list[tuple[int, str, str]] = []
        for i in links:
            parent_body = bodies[self.anc[i]] if self.anc[i] >= 0 else spec.worldbody
            top_level = self.anc[i] < 0
            groups = self._groups(self.chain[i], top_level)
            pos, quat = _qv(self.get(i, "link.pos")), _qv(self.get(i, "link.quat"))
            for k, group in enumerate(groups[:-1]):  # > 6 DoFs: light intermediate bodies
                mid = parent_body.add_body(name=f"link{i}_split{k}", pos=pos, quat=quat)
                pos, quat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
                m = max(MIN_MASS, 1e-3 * float(self.get(i, "link.mass")[0]))
                inertia = max(MIN_INERTIA, 1e-3 * float(np.mean(self.get(i, "link.inertia"))))
                self._inertial(mid, m, [inertia] * 3, [0, 0, 0], [1, 0, 0, 0])
                for j, t in group:
                    acts.append(self._add_joint(mid, j, t, used, top_level and k == 0))
                parent_body = mid
                top_level = False
            body = parent_body.add_body(name=f"link{i}", pos=pos, quat=quat)
            bodies[i] = body
            self._inertial(body, float(self.get(i, "link.mass")[0]), self.get(i, "link.inertia"),
                           self.get(i, "link.ipos"), self.get(i, "link.iquat"))
            for j, t in groups[-1]:
                acts.append(self._add_joint(body, j, t, used, top_level))
        if any(t == JOINT and j not in used for j, t in enumerate(self.types)):
            self.fix("dangling_joint")

        geoms = [g for g, t in enumerate(self.types) if t == GEOM]
        if geoms and self.has("geom.type"):
            for g in geoms:
                if self.anc[g] < 0:
                    self.fix("orphan_geom")
                    continue
                self._graph_geom(bodies[self.anc[g]], g)
        else:
            first_child: dict[int, int] = {}
            for i in links:
                if self.anc[i] >= 0:
                    first_child.setdefault(self.anc[i], i)
            for i in links:
                self._invented_geom(bodies[i], i, first_child.get(i, -1), self.anc[i] < 0)

        for j, t, jname in acts:
            self._actuate(spec, j, t, jname)
        return spec

    def _add_joint(self, body: mujoco.MjsBody, j: int, jtype: str, used: dict[int, int],
                   top_level: bool) -> tuple[int, str, str]:
        n = used.get(j, 0)
        used[j] = n + 1
        if n:
            self.fix("joint_shared")
        jname = f"joint{j}" if n == 0 else f"joint{j}_{n}"
        self._joint(body, j, jtype, jname)
        if jtype == "free" and top_level:
            self.free_bodies.append(body)
        return j, jtype, jname


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    with capture_mujoco_warnings():
        try:
            return spec.compile()
        except Exception as e:  # MuJoCo raises ValueError with its own message
            msg = " ".join(str(e).split())
            raise ValueError(f"MuJoCo rejected the generated robot: {msg}") from None


def _lowest_point(model: mujoco.MjModel) -> float:
    """Lowest world z over all geoms' bounding boxes at ``qpos0``."""
    data = mujoco.MjData(model)
    with capture_mujoco_warnings():
        mujoco.mj_forward(model, data)
    low = math.inf
    for g in range(model.ngeom):
        center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        row = data.geom_xmat[g].reshape(3, 3)[2]
        z = data.geom_xpos[g, 2] + row @ center - np.abs(row) @ half
        low = min(low, float(z))
    return low


def _build(data: RobotData, fs: FeatureSet, name: str, rules: bool, actuators: ActuatorMode,
           clearance: float | None, self_collision: bool
           ) -> tuple[mujoco.MjSpec, mujoco.MjModel, list[str]]:
    if actuators not in ("auto", "all", "none"):
        raise ValueError(f"actuators must be 'auto', 'all' or 'none', not {actuators!r}")
    fired: list[str] = []
    if rules:
        data, fired = apply_rules(data, fs)
    builder = _Builder(data, fs, name, actuators, self_collision)
    spec = builder.build()
    fired += builder.fixes
    model = _compile(spec)
    if clearance is not None and builder.free_bodies and model.ngeom:
        dz = clearance - _lowest_point(model)
        for body in builder.free_bodies:
            body.pos = [body.pos[0], body.pos[1], _q(body.pos[2] + dz)]
        model = _compile(spec)
    return spec, model, fired


def graph_to_spec(
    data: RobotData,
    feature_set: str | FeatureSet = "paper34",
    name: str = "robot",
    rules: bool = True,
    *,
    actuators: ActuatorMode = "auto",
    clearance: float | None = DEFAULT_CLEARANCE,
    self_collision: bool = False,
) -> tuple[mujoco.MjSpec, list[str]]:
    """Build the ``mujoco.MjSpec`` of a robot graph (module docstring for the mapping).

    Args:
        data: robot graph in physical units (e.g. decoded and de-normalised).
        feature_set: the registry set ``data.x`` follows (``paper34`` or ``full``).
        name: model name (``spec.modelname``).
        rules: apply :func:`robovae.generate.rules.apply_rules` first (recommended: without
            them a malformed graph may not compile).
        actuators: ``auto``, ``all`` or ``none`` (module docstring).
        clearance: lift free-floating robots so their lowest point is this high above
            ``z = 0``; ``None`` keeps the root link's position.
        self_collision: let the robot's geoms collide with each other (``conaffinity = 1``).

    Returns:
        The spec (already compiled once, so ``spec.to_xml()`` works) and the names of the rules
        and writer fixes that changed something.

    Raises:
        ValueError: when MuJoCo rejects the model (only possible with ``rules=False``).
    """
    fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
    spec, _, fired = _build(data, fs, name, rules, actuators, clearance, self_collision)
    return spec, fired


def scene_xml(robot_file: str = "robot.xml", name: str = "scene") -> str:
    """MJCF of a scene: ``<include file=robot_file/>``, a floor plane and a light.

    The floor and light are built with ``MjSpec``; the ``<include>`` element (which ``MjSpec``
    cannot express) is added to its XML tree.
    """
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                            rgba=[0.82, 0.84, 0.86, 1.0])
    spec.worldbody.add_light(name="sun", pos=[0, 0, 4], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    spec.compile()
    root = ET.fromstring(spec.to_xml())
    for compiler in root.findall("compiler"):  # the robot file's compiler settings apply
        root.remove(compiler)
    root.insert(0, ET.Element("include", file=robot_file))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def _atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then ``os.replace`` it into place."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_robot(
    data: RobotData,
    out_dir: str | os.PathLike,
    feature_set: str | FeatureSet = "paper34",
    name: str = "robot",
    scene: bool = True,
    *,
    rules: bool = True,
    actuators: ActuatorMode = "auto",
    clearance: float | None = DEFAULT_CLEARANCE,
    self_collision: bool = False,
) -> WriteResult:
    """Write a robot graph as ``out_dir/robot.xml`` (and ``out_dir/scene.xml``).

    Both files are written atomically (temporary file in ``out_dir``, then ``os.replace``),
    ``robot.xml`` first: when ``scene.xml`` exists, the folder is complete. The robot XML is
    checked to load with MuJoCo before anything is written.

    Args:
        data: the robot graph (as in :func:`graph_to_spec`).
        feature_set: as in :func:`graph_to_spec`.
        name: as in :func:`graph_to_spec`.
        rules: as in :func:`graph_to_spec`.
        actuators: as in :func:`graph_to_spec`.
        clearance: as in :func:`graph_to_spec`.
        self_collision: as in :func:`graph_to_spec`.
        out_dir: folder to write into (created if missing).
        scene: also write ``scene.xml`` (floor, light, ``<include file="robot.xml"/>``).

    Raises:
        ValueError: when MuJoCo rejects the model (only possible with ``rules=False``).
    """
    fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
    spec, model, fired = _build(data, fs, name, rules, actuators, clearance, self_collision)
    xml = spec.to_xml()
    with capture_mujoco_warnings():
        try:
            mujoco.MjModel.from_xml_string(xml)
        except Exception as e:
            msg = " ".join(str(e).split())
            raise ValueError(f"the written robot XML does not load: {msg}") from None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    robot_path = out / "robot.xml"
    _atomic_write(robot_path, xml)
    scene_path = None
    if scene:
        scene_path = out / "scene.xml"
        _atomic_write(scene_path, scene_xml(robot_path.name, f"{name}_scene"))
    return WriteResult(robot_path, scene_path, fired, n_bodies=model.nbody - 1,
                       n_joints=model.njnt, n_geoms=model.ngeom, n_actuators=model.nu)
