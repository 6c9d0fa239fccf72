"""What a procedural robot is before it becomes an ``MjSpec``: a tree of parts.

A :class:`Part` is one body: its position in the parent body's frame (all frames stay aligned
with the world: x forward, y left, z up, no rotations), its joints, its geoms and its children.
A :class:`Geom` is a capsule or cylinder from one point to another, a sphere or an
axis-aligned box, with an explicit mass (MuJoCo computes the inertia from the shape). A
:class:`Joint` is a hinge, slide or ball joint with its limits, damping and armature, and the
gear of its motor (0: passive).

:class:`RobotPlan` is a whole robot: its root part, whether the root floats (free joint) or is
welded to the world, and the height of the root so that the lowest point sits ``clearance``
above ``z = 0`` (:func:`lowest_point`). :func:`reroot` hangs a tree from another of its parts
(a humanoid rooted at its torso, as dm_control's humanoid and Booster's T1 are, instead of its
pelvis).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

Vec = tuple[float, float, float]


@dataclass
class Joint:
    """A joint of a part: ``type`` is ``hinge``, ``slide`` or ``ball``; ``range`` is
    ``(lo, hi)`` with ``lo <= 0 <= hi`` (``None``: unlimited); ``gear`` 0 means no motor."""

    type: str
    axis: Vec
    range: tuple[float, float] | None
    damping: float
    armature: float
    stiffness: float = 0.0
    gear: float = 0.0


@dataclass
class Geom:
    """A primitive with an explicit mass (kg): ``capsule``/``cylinder`` use ``fromto`` and
    ``radius``; ``sphere`` uses ``pos`` and ``radius``; ``box`` uses ``pos`` and ``half``."""

    type: str
    mass: float
    radius: float = 0.0
    fromto: tuple[float, float, float, float, float, float] | None = None
    pos: Vec | None = None
    half: Vec | None = None


@dataclass(eq=False)
class Part:
    """One body: ``pos`` in the parent frame (m), joints in order, geoms, children. Parts
    compare by identity."""

    name: str
    pos: Vec
    joints: list[Joint] = field(default_factory=list)
    geoms: list[Geom] = field(default_factory=list)
    children: list[Part] = field(default_factory=list)

    def add(self, child: Part) -> Part:
        """Append ``child`` and return it."""
        self.children.append(child)
        return child

    def walk(self) -> Iterator[tuple[Part, Vec]]:
        """Every part of the subtree in pre-order, with its origin in this part's frame."""
        stack: list[tuple[Part, Vec]] = [(self, (0.0, 0.0, 0.0))]
        while stack:
            p, o = stack.pop()
            yield p, o
            for c in reversed(p.children):
                stack.append((c, (o[0] + c.pos[0], o[1] + c.pos[1], o[2] + c.pos[2])))

    def path_to(self, target: Part) -> list[Part] | None:
        """The parts from this one down to ``target`` (both included), ``None`` when
        ``target`` is not in the subtree."""
        if self is target:
            return [self]
        for c in self.children:
            tail = c.path_to(target)
            if tail is not None:
                return [self, *tail]
        return None

    def shift(self, d: Vec) -> None:
        """Move this part's origin by ``-d`` without moving anything in the world: its geoms and
        children are translated by ``d`` in its frame."""
        for g in self.geoms:
            if g.fromto is not None:
                g.fromto = (*_add(g.fromto[:3], d), *_add(g.fromto[3:], d))
            if g.pos is not None:
                g.pos = _add(g.pos, d)
        for c in self.children:
            c.pos = _add(c.pos, d)

    def mass(self) -> float:
        """Mass of the subtree (kg)."""
        return sum(g.mass for p, _ in self.walk() for g in p.geoms)


@dataclass
class RobotPlan:
    """A sampled robot: ``name`` (``proc_<kind>_<seed>``), ``kind``, ``seed``, the ``root``
    part, ``floating`` (free joint on the root, else welded to the world) and ``height`` (z of
    the root origin)."""

    name: str
    kind: str
    seed: int
    root: Part
    floating: bool
    height: float = 0.0
    actuators: bool = True
    self_collision: bool = False

    @property
    def num_segments(self) -> int:
        """Bodies below the root."""
        return sum(1 for _ in self.root.walk()) - 1

    @property
    def num_joints(self) -> int:
        """Joints besides the free joint."""
        return sum(len(p.joints) for p, _ in self.root.walk())

    @property
    def num_hinges(self) -> int:
        """Hinge joints."""
        return sum(j.type == "hinge" for p, _ in self.root.walk() for j in p.joints)

    @property
    def num_actuators(self) -> int:
        """Motors (joints with a gear) when ``actuators`` is on."""
        if not self.actuators:
            return 0
        return sum(j.gear > 0 for p, _ in self.root.walk() for j in p.joints)


def _add(a: tuple, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def reroot(root: Part, target: Part) -> Part:
    """Make ``target`` (a part below ``root``) the root of the same robot and return it.

    Every part on the path from ``root`` to ``target`` is hung under its former child, and
    each edge keeps its joints at the same place in the world: the joints of the edge
    ``a -> b`` (on ``b``) move to ``a``, whose origin moves to ``b``'s former origin (the
    joint anchor). Geometry, masses and the other children do not move; a flipped part is
    appended after the children its new parent already had. ``root`` must have no joints.

    Raises:
        ValueError: ``target`` is not in the tree, or ``root`` has joints.
    """
    path = root.path_to(target)
    if path is None or root.joints:
        raise ValueError(f"cannot reroot at '{target.name}'")
    origins: list[Vec] = [(0.0, 0.0, 0.0)]
    for p in path[1:]:
        origins.append(_add(origins[-1], p.pos))
    k = len(path) - 1
    joints = [path[i + 1].joints for i in range(k)]
    new_origin = origins[1:] + [origins[k]]  # part i moves to its former child's origin
    for i in range(k - 1, -1, -1):
        a, b = path[i], path[i + 1]
        a.children.remove(b)
        o = origins[i]
        a.shift((o[0] - new_origin[i][0], o[1] - new_origin[i][1], o[2] - new_origin[i][2]))
        a.joints = joints[i]
        b.children.append(a)
    for i in range(k):
        o, n = new_origin[i], new_origin[i + 1]
        path[i].pos = (o[0] - n[0], o[1] - n[1], o[2] - n[2])
    target.joints = []
    target.pos = (0.0, 0.0, 0.0)
    return target


def _low(g: Geom, o: Vec) -> float:
    if g.type in ("capsule", "cylinder"):
        assert g.fromto is not None  # capsules and cylinders have fromto (see Geom)
        a, b = g.fromto[:3], g.fromto[3:]
        if g.type == "capsule":
            return o[2] + min(a[2], b[2]) - g.radius
        d = [b[i] - a[i] for i in range(3)]
        n = math.sqrt(sum(x * x for x in d)) or 1.0
        rim = g.radius * math.sqrt(max(0.0, 1.0 - (d[2] / n) ** 2))
        return o[2] + min(a[2], b[2]) - rim
    assert g.pos is not None  # spheres and boxes have pos (see Geom)
    if g.type == "sphere":
        return o[2] + g.pos[2] - g.radius
    assert g.half is not None  # a box
    return o[2] + g.pos[2] - g.half[2]


def lowest_point(root: Part) -> float:
    """Lowest z of the robot in the root frame at ``qpos0`` (exact for these primitives)."""
    return min(_low(g, o) for p, o in root.walk() for g in p.geoms)
