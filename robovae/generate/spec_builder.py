"""Robot graph → ``mujoco.MjSpec``: which element every node and feature becomes (SPEC §7,
paper §4.1/§6.1).

The inverse of :mod:`robovae.data.mjcf`: every feature the reader takes from the compiled
``MjModel`` is written back to the element it came from. Nodes are in pre-order; bodies and
their joints follow :func:`robovae.generate.bodies.link_structure`. Numbers enter the spec
rounded as MJCF output writes them (:mod:`robovae.generate.mjcf_numbers`).

- **link → body**, a child of its nearest ancestor link's body (the world body for the root
  link(s)): ``pos``, ``quat`` and an explicit ``<inertial>`` (``mass``, ``diaginertia``,
  ``ipos``, ``iquat``). ``compiler.inertiafromgeom = "false"``: geoms never change the inertials.
  A root link with no joint above it is welded to the world (fixed base).
- **joint → joint** of the body it leads to: all joints of a chain ``link — j1 — j2 — link``
  belong to the lower link's body, in order. Type from
  :func:`~robovae.generate.bodies.joint_types`. Axis, pos, range (limited when the ``limited``
  flag is set, or in ``paper34`` when the range is non-zero), damping, armature, frictionloss
  and stiffness.
- **geom → geom** of its link's body (``full``): type from the one-hot, pos, quat, size (the
  components the primitive uses), friction; ``collides`` → ``contype = 1`` and
  ``conaffinity = 1`` with ``self_collision``, else ``conaffinity = 0`` (the robot collides with
  the floor, not with itself); non-colliding geoms get ``contype = conaffinity = 0``.
- **no geom nodes at all** (``paper34``, or a ``full`` graph without any): geometry that
  joins, :mod:`robovae.generate.link_geometry`: first a primitive from ``link.size``, written
  verbatim so that it reads back as the same size (``(r, 0, 0)`` sphere, ``(r, h, 0)`` capsule,
  ``(x, y, z)`` box, no size: a sphere of radius
  :data:`~robovae.generate.rules_geometry.DEFAULT_GEOM_RADIUS`), starting at the link's joint
  anchor and pointing at its first child's anchor; then capsule *bridges* of the link's
  thickness to its anchor and its children's anchors where the primitive does not reach them
  (``geom_bridge``). The root link's primitive sits at its origin, unrotated.
- **actuators**: one ``motor`` per non-free joint (on a hinge without limits, when its control
  range is ``(-1, 1)``, a DC motor with a no-load speed:
  :func:`robovae.data.actuators.speed_limited`). ``actuators="auto"``: in sets with
  ``joint.actuated`` only the flagged joints, with their ``gear`` and ``ctrlrange``
  (``(0, 0)`` = unlimited), or, with ``joint.torque`` (``kinematic``), a gear of the joint's
  strength and the control range ``(-1, 1)``; elsewhere every non-free joint with
  :data:`DEFAULT_GEAR` and :data:`DEFAULT_CTRLRANGE`. ``"all"``: every non-free joint
  (features when flagged, else the defaults). ``"none"``: no actuators.

Structures no rule can repair (they change the topology; malformed decoded graphs only) are
repaired here, and their names recorded (:data:`WRITER_FIXES`): ``empty_robot`` (no link node:
one default body), ``dangling_joint`` (a joint with no link below it: dropped),
``joint_shared`` (a joint leading to several links: the first of them in pre-order gets it,
the others are attached through their own joints only, so a written robot has at most as many
joints as the graph; a free joint is copied to each top-level link), ``orphan_geom`` (a geom
with no link above it: dropped), ``free_not_top_level`` (a free joint below the top level or
not alone in its body, possible only without the rules: written as a hinge),
``dof_chain_split`` (joints of one body with more than 6 DoFs, MuJoCo's limit: the chain is
split with intermediate bodies of mass ``max(MIN_MASS, 1e-3 m)`` and inertia
``max(MIN_INERTIA, 1e-3 · mean inertia)``),
``inertia_rounding`` (the rounded inertia had to be raised for ``a + b ≥ c``,
:func:`~robovae.generate.mjcf_numbers.rounded_inertia`). ``geom_bridge`` is not a repair of the
tree but is reported alike: some link's primitive (from its size) did not reach a joint anchor.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import mujoco
import numpy as np
import numpy.typing as npt

from robovae.data.actuators import speed_limited
from robovae.data.box_axes import axes_to_quats
from robovae.data.features import GEOM, GEOM_TYPE_IDS, GEOM_TYPES, JOINT, LINK, FeatureSet
from robovae.data.tree_arrays import RobotTree, feature_values
from robovae.generate.bodies import joint_types, link_structure
from robovae.generate.link_geometry import GeomPlan, LinkFrame, box_fill, link_geoms, thickness
from robovae.generate.mjcf_numbers import (
    mjcf_round,
    mjcf_round_groups,
    mjcf_round_vector,
    mjcf_round_vectors,
    rounded_inertia,
)
from robovae.generate.rules_geometry import DEFAULT_GEOM_RADIUS, GEOM_SIZE_COMPONENTS
from robovae.generate.rules_mass import MIN_INERTIA, MIN_MASS

__all__ = ["DEFAULT_CTRLRANGE", "DEFAULT_GEAR", "PRIMITIVES", "WRITER_FIXES", "ActuatorMode",
           "SpecBuilder", "is_link_primitive", "link_geom_name"]

#: Motor gear when the feature set has none for the joint.
DEFAULT_GEAR = 1.0
#: Motor control range when the feature set has none for the joint.
DEFAULT_CTRLRANGE = (-1.0, 1.0)
#: Names the writer adds to the fired list when it repairs the tree structure.
WRITER_FIXES = ("empty_robot", "dangling_joint", "joint_shared", "orphan_geom",
                "free_not_top_level", "dof_chain_split", "inertia_rounding", "geom_bridge")

ActuatorMode = Literal["auto", "all", "none"]


def link_geom_name(link: int, k: int) -> str:
    """Name of the ``k``-th geom the writer makes for link ``link``: ``link<i>_geom`` for its
    primitive (``k = 0``), ``link<i>_geom<k>`` for the bridges after it
    (:func:`~robovae.generate.link_geometry.link_geoms`)."""
    return f"link{link}_geom" if k == 0 else f"link{link}_geom{k}"


def is_link_primitive(name: str) -> bool:
    """Whether a geom named ``name`` is a link's primitive as :func:`link_geom_name` names it
    (not one of its bridges)."""
    return name.startswith("link") and name.endswith("_geom") and name[4:-5].isdigit()


_JNT = {"free": mujoco.mjtJoint.mjJNT_FREE, "ball": mujoco.mjtJoint.mjJNT_BALL,
        "slide": mujoco.mjtJoint.mjJNT_SLIDE, "hinge": mujoco.mjtJoint.mjJNT_HINGE}
_DOFS = {"free": 6, "ball": 3, "slide": 1, "hinge": 1}
_TRUE, _FALSE = mujoco.mjtLimited.mjLIMITED_TRUE, mujoco.mjtLimited.mjLIMITED_FALSE
_SPHERE = mujoco.mjtGeom.mjGEOM_SPHERE
#: The MuJoCo geom type of each kind of :class:`~robovae.generate.link_geometry.GeomPlan`.
PRIMITIVES = {"sphere": _SPHERE, "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
              "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "box": mujoco.mjtGeom.mjGEOM_BOX}
_GEOM_SIZES = tuple(GEOM_SIZE_COMPONENTS[t] for t in GEOM_TYPES)
_GEOM_GROUPS = np.array([0, 3, 6])  # size, pos, quat of a geom plan
_LINK_RGBA = [0.55, 0.6, 0.7, 1.0]
_GEOM_RGBA = [0.8, 0.55, 0.35, 1.0]


def _geom_numbers(plans: list[GeomPlan]) -> list[list[float]]:
    """Each plan's size, pos and quat as MJCF writes them (each a vector), in one pass."""
    if not plans:
        return []
    return mjcf_round_vectors(np.array([np.concatenate([p.size, p.pos, p.quat])
                                        for p in plans]), _GEOM_GROUPS)


class SpecBuilder:
    """Builds the ``MjSpec`` of one robot graph (module docstring for the mapping).

    Args:
        data: robot graph in physical units (normally repaired by the rules).
        fs: the feature set of ``data.x``.
        name: model name.
        actuators: ``auto``, ``all`` or ``none``.
        self_collision: robot geoms collide with each other.

    Attributes:
        fixes: names of the structural repairs made (:data:`WRITER_FIXES`), after :meth:`build`.
        free_bodies: top-level bodies holding a free joint, after :meth:`build`.
    """

    def __init__(self, data: RobotTree, fs: FeatureSet, name: str, actuators: ActuatorMode,
                 self_collision: bool) -> None:
        self.fs, self.name = fs, name
        # every value as MJCF output writes it, feature by feature, in one pass
        starts = np.array([fs.slice(f.key).start for f in fs.features])
        self.x = mjcf_round_groups(feature_values(data), starts)
        self.types = data.node_type.tolist()
        self.parent = data.parent.tolist()
        self.keys = {f.key for f in fs.features}
        self.jtypes = joint_types(data, fs)
        self.anc, self.chain = link_structure(self.parent, self.types)
        self.actuators = actuators
        self.self_collision = self_collision
        self.fixes: list[str] = []
        self.free_bodies: list[mujoco.MjsBody] = []
        self._shapes: dict[int, tuple] | None = None  # link -> (size, box, fill, thickness)
        self._continuous: set[str] = set()  # names of the hinges without limits
        #: leaf links beside their limb written as rods (:class:`LinkFrame` ``side``) ...
        self.side_leaves: list[int] = []
        #: ... except these, which the robot stands on (the writer's ``feet``)
        self.feet: set[int] = set()
        # what build() made, for move_built(): the spec, the body each link.pos places and
        # each link's body, children, invented geoms and their plans (None: the graph's geoms)
        self._spec: mujoco.MjSpec | None = None
        self._placed: dict[int, mujoco.MjsBody] = {}
        self._bodies: dict[int, mujoco.MjsBody] = {}
        self._kids: dict[int, list[int]] | None = None
        self._geoms: dict[int, list[mujoco.MjsGeom]] = {}
        self._plans: dict[int, list[GeomPlan]] = {}

    def move_built(self, shifts: dict[str, np.ndarray], base: np.ndarray) -> Callable[[], None]:
        """Move the links of the spec :meth:`build` made, in place, to where :meth:`build`
        would put them for a builder whose values are ``base`` (this one's before any move)
        with each ``link<i>`` named in ``shifts`` moved by ``shifts[name]`` in its parent's
        frame (its ``link.pos``, rounded as MJCF writes it): the values and the bodies their
        ``link.pos`` places, the geometry joining each moved link's parent to its children
        made again (:func:`~robovae.generate.link_geometry.link_geoms`: geom ``k`` from plan
        ``k``, a bridge gained added, one lost deleted) and ``geom_bridge`` in :attr:`fixes`
        as that build would record it — the same spec, to the byte of its MJCF, without
        building it (a compile is still due). Returns the undo: the spec as it was."""
        pos = self.fs.slice("link.pos")
        target = base[:, pos].copy()
        for name, shift in shifts.items():
            i = name.removeprefix("link")
            if not i.isdigit() or int(i) not in self._placed:
                raise ValueError(f"move_built: {name!r} is not a link body of this robot")
            target[int(i)] = mjcf_round_vector(base[int(i), pos] + shift)
        moved = [i for i in self._placed if (target[i] != self.x[i, pos]).any()]
        rows = {i: self.x[i, pos].copy() for i in moved}
        parents = sorted({self.anc[i] for i in moved if self.anc[i] >= 0}) \
            if self._kids is not None else []
        plans = {k: self._plans[k] for k in parents}
        fixes = list(self.fixes)

        def put(values: dict[int, np.ndarray]) -> None:
            for i, row in values.items():
                self.x[i, pos] = row
                self._placed[i].pos = self.vec(i, "link.pos")

        def undo() -> None:
            put(rows)
            for k, made in plans.items():
                self._set_link_geoms(k, made)
            self.fixes[:] = fixes

        put({i: target[i] for i in moved})
        for k in parents:
            self._set_link_geoms(k, link_geoms(self._link_frame(k, self._kids or {})))
        bridged = any(plan.bridge for made in self._plans.values() for plan in made)
        if bridged != ("geom_bridge" in self.fixes):  # always the last fix build records
            self.fixes[:] = [f for f in self.fixes if f != "geom_bridge"] \
                + (["geom_bridge"] if bridged else [])
        return undo

    def _set_link_geoms(self, i: int, plans: list[GeomPlan]) -> None:
        """Link ``i``'s geoms remade in place from ``plans`` (its body's geoms are its
        plans' alone: build adds no other there)."""
        geoms, spec = self._geoms[i], self._spec
        assert spec is not None  # build made the geoms
        for g in geoms[len(plans):]:
            spec.delete(g)
        del geoms[len(plans):]
        for k in range(len(geoms), len(plans)):
            geoms.append(self._link_geom(self._bodies[i], i, k))
        for g, plan, v in zip(geoms, plans, _geom_numbers(plans)):
            g.type, g.size, g.pos, g.quat = PRIMITIVES[plan.type], v[:3], v[3:6], v[6:]
        self._plans[i] = plans

    def _link_geom(self, body: mujoco.MjsBody, i: int, k: int, **values: object
                   ) -> mujoco.MjsGeom:
        g = body.add_geom(name=link_geom_name(i, k), rgba=_LINK_RGBA, **values)
        g.contype, g.conaffinity = 1, int(self.self_collision)
        return g

    def get(self, i: int, key: str) -> np.ndarray:
        """The columns of feature ``key`` of node ``i`` (rounded as MJCF writes them)."""
        return self.x[i, self.fs.slice(key)]

    def vec(self, i: int, key: str) -> list[float]:
        """:meth:`get` as a list (for the spec's setters)."""
        return self.x[i, self.fs.slice(key)].tolist()

    def has(self, key: str) -> bool:
        """Whether the feature set has ``key``."""
        return key in self.keys

    def fix(self, name: str) -> None:
        """Record the structural repair ``name`` (once)."""
        if name not in self.fixes:
            self.fixes.append(name)

    # -- elements ------------------------------------------------------------------------------

    def _inertial(self, body: mujoco.MjsBody, mass: float, inertia: npt.ArrayLike,
                  ipos: npt.ArrayLike, iquat: npt.ArrayLike) -> None:
        body.mass = mjcf_round(mass)
        body.inertia, moved = rounded_inertia(inertia)
        if moved:
            self.fix("inertia_rounding")
        body.ipos = mjcf_round_vector(ipos)
        body.iquat = mjcf_round_vector(iquat)
        body.explicitinertial = True

    def _joint(self, body: mujoco.MjsBody, j: int, jtype: str, name: str) -> mujoco.MjsJoint:
        joint = body.add_joint(name=name, type=_JNT[jtype])
        if jtype != "free":
            joint.axis = self.vec(j, "joint.axis")
            joint.pos = self.vec(j, "joint.pos")
        lo, hi = (float(a) for a in self.get(j, "joint.range"))
        limited = lo != 0.0 or hi != 0.0
        if self.has("joint.limited"):
            limited = limited and self.get(j, "joint.limited")[0] >= 0.5
        if limited and jtype != "free":
            joint.limited = _TRUE
            joint.range = [lo, hi]
        else:
            if jtype == "hinge":
                self._continuous.add(name)
            joint.limited = _FALSE
        joint.damping[0] = float(self.get(j, "joint.damping")[0])
        joint.armature = float(self.get(j, "joint.armature")[0])
        joint.frictionloss = float(self.get(j, "joint.frictionloss")[0])
        joint.stiffness[0] = float(self.get(j, "joint.stiffness")[0])
        return joint

    def _actuate(self, spec: mujoco.MjSpec, j: int, jtype: str, jname: str) -> None:
        if self.actuators == "none" or jtype == "free":
            return
        flagged = self.has("joint.actuated") and self.get(j, "joint.actuated")[0] >= 0.5
        if self.actuators == "auto" and self.has("joint.actuated") and not flagged:
            return
        gear = float(self.get(j, "joint.gear")[0]) if flagged and self.has("joint.gear") \
            else DEFAULT_GEAR
        if flagged and self.has("joint.torque") and self.get(j, "joint.torque")[0] > 0:
            gear = float(self.get(j, "joint.torque")[0])  # a motor of that strength
        if flagged and self.has("joint.ctrlrange"):
            ctrl = self.vec(j, "joint.ctrlrange")
        else:
            ctrl = list(DEFAULT_CTRLRANGE)
        act = spec.add_actuator(name=f"{jname}_motor", target=jname,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        act.gear = [gear] * (3 if jtype == "ball" else 1) + [0.0] * (3 if jtype == "ball" else 5)
        if jname in self._continuous and gear != 0.0 and tuple(ctrl) == DEFAULT_CTRLRANGE:
            speed_limited(act, gear)  # a wheel: a DC motor
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

    def _anchor(self, i: int) -> np.ndarray:
        """Link ``i``'s anchor in its body frame: its first joint's position, else 0."""
        chain = self.chain[i]
        return np.array(self.vec(chain[0], "joint.pos")) if chain \
            and self.jtypes[chain[0]] != "free" else np.zeros(3)

    def _link_shape(self, i: int) -> tuple[
            np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray] | None, GeomPlan | None,
            float]:
        """Link ``i``'s ``link.size`` (zeros when absent), its collision box ``(centre, quat,
        half-sizes)`` if the set has one, the primitive that fills it
        (:func:`~robovae.generate.link_geometry.box_fill`) and its thickness; every link's
        computed at the first call (the box orientations in one batch)."""
        if self._shapes is None:
            links = [k for k, t in enumerate(self.types) if t == LINK]
            quats = axes_to_quats(self.x[links, self.fs.slice("link.box_axes")]) \
                if self.has("link.box_half") and links else None
            self._shapes = {}
            for n, k in enumerate(links):
                size = np.maximum(self.get(k, "link.size"), 0.0) if self.has("link.size") \
                    else np.zeros(3)
                box = None
                if quats is not None:
                    box = (np.array(self.vec(k, "link.box_pos")), quats[n],
                           np.maximum(self.get(k, "link.box_half"), 0.0))
                fill = box_fill(box)
                self._shapes[k] = (size, box, fill, thickness(size, fill=fill))
        return self._shapes[i]

    def _link_frame(self, i: int, kids: dict[int, list[int]]) -> LinkFrame:
        children = []
        for c in kids[i]:
            t = np.zeros(3)
            mujoco.mju_rotVecQuat(t, self._anchor(c),
                                  np.array(self.vec(c, "link.quat")))
            t += np.array(self.vec(c, "link.pos"))
            children.append((t, self._link_shape(c)[3]))
        size, box, fill, _ = self._link_shape(i)
        hinges = [(np.array(self.vec(j, "joint.pos")), np.array(self.vec(j, "joint.axis")))
                  for j in self.chain[i] if self.jtypes[j] == "hinge"] if box is not None else []
        p = self.anc[i]
        side = not kids[i] and p >= 0 and any(kids[c] for c in kids[p] if c != i) \
            and i not in self.feet
        if side:
            self.side_leaves.append(i)
        return LinkFrame(size, self._anchor(i), np.array(self.get(i, "link.ipos")), children,
                         p < 0, box, hinges, fill, side)

    def _invented_geoms(self, bodies: dict[int, mujoco.MjsBody], kids: dict[int, list[int]]
                        ) -> None:
        """Every link's geoms (:func:`~robovae.generate.link_geometry.link_geoms`), their
        numbers rounded in one pass (size, pos and quat each a vector)."""
        plans = [(i, k, plan) for i in kids
                 for k, plan in enumerate(link_geoms(self._link_frame(i, kids)))]
        if not plans:
            return
        if any(plan.bridge for _, _, plan in plans):
            self.fix("geom_bridge")
        self._kids, self._bodies = kids, bodies
        self._geoms = {i: [] for i in kids}
        self._plans = {i: [] for i in kids}
        for (i, k, plan), v in zip(plans, _geom_numbers([plan for _, _, plan in plans])):
            self._geoms[i].append(self._link_geom(bodies[i], i, k, type=PRIMITIVES[plan.type],
                                                  size=v[:3], pos=v[3:6], quat=v[6:]))
            self._plans[i].append(plan)

    def _graph_geom(self, body: mujoco.MjsBody, g: int) -> None:
        k = int(np.argmax(self.get(g, "geom.type")))
        size = self.vec(g, "geom.size")
        size[_GEOM_SIZES[k]:] = [0.0] * (3 - _GEOM_SIZES[k])  # MJCF keeps the used ones only
        geom = body.add_geom(name=f"geom{g}", type=mujoco.mjtGeom(GEOM_TYPE_IDS[k]),
                             pos=self.vec(g, "geom.pos"),
                             quat=self.vec(g, "geom.quat"), size=size,
                             friction=self.vec(g, "geom.friction"),
                             rgba=_GEOM_RGBA)
        collides = self.get(g, "geom.collides")[0] >= 0.5 if self.has("geom.collides") else True
        geom.contype = int(collides)
        geom.conaffinity = int(collides and self.self_collision)

    # -- the tree --------------------------------------------------------------------------------

    def build(self) -> mujoco.MjSpec:
        """The spec of the robot (not compiled)."""
        spec = self._spec = mujoco.MjSpec()
        self._placed = {}
        spec.modelname = self.name
        spec.compiler.degree = False
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        links = [i for i, t in enumerate(self.types) if t == LINK]
        if not links:
            self.fix("empty_robot")
            body = spec.worldbody.add_body(name="link0")
            r = DEFAULT_GEOM_RADIUS
            self._inertial(body, 1e-3, [0.4e-3 * r * r] * 3, [0, 0, 0], [1, 0, 0, 0])
            g = body.add_geom(name=link_geom_name(0, 0), type=_SPHERE, size=[r, 0, 0],
                              rgba=_LINK_RGBA)
            g.contype, g.conaffinity = 1, int(self.self_collision)
            return spec

        used: dict[int, int] = {}
        bodies: dict[int, mujoco.MjsBody] = {}
        acts: list[tuple[int, str, str]] = []
        for i in links:
            parent_body = bodies[self.anc[i]] if self.anc[i] >= 0 else spec.worldbody
            top_level = self.anc[i] < 0
            chain = [j for j in self.chain[i]
                     if j not in used or (top_level and self.jtypes[j] == "free")]
            if len(chain) < len(self.chain[i]):
                self.fix("joint_shared")  # the joint moves the first link below it only
            groups = self._groups(chain, top_level)
            pos = self.vec(i, "link.pos")
            quat = self.vec(i, "link.quat")
            for k, group in enumerate(groups[:-1]):  # > 6 DoFs: light intermediate bodies
                mid = parent_body.add_body(name=f"link{i}_split{k}", pos=pos, quat=quat)
                self._placed.setdefault(i, mid)
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
            self._placed.setdefault(i, body)
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
            kids: dict[int, list[int]] = {i: [] for i in links}
            for i in links:
                if self.anc[i] >= 0:
                    kids[self.anc[i]].append(i)
            self._invented_geoms(bodies, kids)

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
