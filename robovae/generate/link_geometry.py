"""Where the writer puts the geometry of a link without geom nodes, so that a robot is in one
piece: each link's geometry spans from its joint anchor towards its children's anchors.

All positions are in the link's body frame (m). A link's **anchor** ``a`` is the position of its
first joint (``joint.pos``), or its origin when it has no joint; a child link ``c`` is attached
at ``t_c = pos_c + R(quat_c) a_c`` (its anchor seen from the parent). The **thickness** ``r`` of
a link comes from ``link.size`` (``(r)`` sphere, ``(r, h)`` capsule: ``r``; ``(x, y, z)`` box:
the smallest half-size; no size: :data:`~robovae.generate.rules_geometry.DEFAULT_GEOM_RADIUS`).

1. The **primitive**: the link's first geom, written from ``link.size`` verbatim (so that the
   reader gives the same ``link.size`` back): sphere ``(r)``, capsule ``(r, h)``, box
   ``(x, y, z)``. In sets with a collision **box** (``link.box_pos``, ``link.box_quat``,
   ``link.box_half``: centre ``c``, orientation ``q`` and half-sizes ``a >= b >= e`` along the
   box's axes) the primitive fills that box instead, at ``c``: a capsule along the box's long
   axis (radius ``(b + e) / 2``) when ``a >= 1.5 b``, a sphere (radius the mean half-size) when
   ``a <= 1.2 e``, else the box itself, rotated by ``q``; its thickness is that radius, or
   ``e`` for a box. A capsule of a non-root link with a child link runs from the link's anchor
   to its first child's anchor instead (a limb segment joins its two joints whatever the
   decoded box's orientation says); a leaf link (no child link: a foot, a hand, a head) keeps
   its box, whatever its proportions. A foot keeps its sole and a head its volume, where
   ``link.size`` alone holds only the first geom. A leaf link *beside* its limb (its parent
   link carries the limb on through another child link that has children: a knee's spring
   rod) is no foot: it keeps the capsule, whose round ends do not reach past the rod into
   the limb as the box's corners do, unless the robot stands on it (the writer's stance rules
   give such a leaf, within ``SOLE_TOL · L`` of the robot's lowest point, its box back). A
   box that is round in its plane
   (``a <= 1.2 b``) and spun about its short axis by one of the link's hinges (the axis within
   15° of it, the box's centre within a quarter of ``(a + b) / 2`` of the axis line) is a
   **disc**: a wheel or a turntable, written as a cylinder of radius ``(a + b) / 2`` and
   half-height ``e`` about that axis (a square box there would roll on its corners).

   - root link (no link above it): at its origin, unrotated;
   - capsule / box: its axis (capsule axis, box z) points from ``a`` at the first child's
     anchor ``t`` (else at the centre of mass ``ipos``, else along +z) and it **starts at the
     anchor**: its end touches ``a``, centre ``a + (h + r) u`` (box: ``a + z u``);
   - sphere: at the anchor, or, for a leaf link (no child link), at its centre of mass.

2. **Bridges**, where the primitive does not reach a point it must reach (farther than
   :data:`COVER_TOL` ``· r`` from its surface): the link's anchor (for a non-root link) and the
   anchor of every child link. A bridge is a capsule from the point of the primitive's *core*
   nearest that point (a sphere's centre, a capsule's or cylinder's axis segment, a box's
   mid-surface: the box shrunk by its smallest half-size), or, to reach the link's own anchor,
   from the primitive's centre, to that point, of radius ``ρ = min(r, r_child)`` (``r`` for
   the own anchor), whose caps end at the two points (segment inset by ``ρ`` at both ends,
   so that it does not reach into the grandparent or grandchild); a bridge shorter than
   ``2ρ`` is a sphere touching both points (radius half the length, at least
   :data:`MIN_BRIDGE` ``· ρ``). Bridges are reported (``geom_bridge``) since a real robot's own
   geoms need none only when its features place them.

Every child's geometry then contains its anchor ``t_c`` (its primitive starts there, or a bridge
reaches it), and so does its parent's: the two touch at ``t_c``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from robovae.generate.graph_view import norm
from robovae.generate.rules_geometry import DEFAULT_GEOM_RADIUS

__all__ = ["COVER_TOL", "MIN_BRIDGE", "MIN_RADIUS", "GeomPlan", "LinkFrame", "box_fill",
           "link_geoms", "surface_gap", "thickness"]

#: A point farther than this times the thickness from the primitive's surface needs a bridge.
COVER_TOL = 0.25
#: A bridge shorter than this times its radius is a sphere.
MIN_BRIDGE = 0.05
#: Smallest radius of a capsule that fills a collision box (m): a flat box has no thickness.
MIN_RADIUS = 1e-3
#: A disc's hinge axis is within this angle's cosine (15°) of the box's short axis ...
DISC_COS = float(np.cos(np.radians(15.0)))
#: ... and the box's centre within this share of the disc's radius of the hinge's axis line.
DISC_OFFSET = 0.25
_AXES = np.eye(3)


@dataclass
class GeomPlan:
    """One geom in its body frame: MuJoCo type name, ``size`` (3), ``pos`` (3), ``quat`` (4),
    and whether it is a bridge."""

    type: str
    size: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    bridge: bool = False


@dataclass
class LinkFrame:
    """What the layout reads of one link (body frame, m).

    Attributes:
        size: ``link.size`` (zeros when absent), already repaired by the rules.
        anchor: its anchor ``a``.
        ipos: its centre of mass.
        children: ``[(t_c, r_c)]``: every child link's anchor and thickness.
        root: no link above it.
        box: ``(centre, quat, half-sizes)`` of its collision box, in sets that have one.
        hinges: ``[(position, axis)]`` of the hinge joints in its body.
        fill: :func:`box_fill` of ``box``, when the caller has it (else computed from ``box``).
        side: a leaf link beside its limb: its parent link carries the limb on through another
            child link that has children (a spring or a rod at a knee), so it is no foot.
    """

    size: np.ndarray
    anchor: np.ndarray
    ipos: np.ndarray
    children: list[tuple[np.ndarray, float]]
    root: bool
    box: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    hinges: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    fill: GeomPlan | None = None
    side: bool = False


def _n_size(size: np.ndarray) -> int:
    k = 0
    while k < 3 and size[k] > 0:
        k += 1
    return k


def box_fill(box: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> GeomPlan | None:
    """The primitive that fills a collision box ``(centre, quat, half-sizes)`` (module
    docstring), None without a box (or an empty one)."""
    return _box_primitive(*box) if box is not None and float(np.max(box[2])) > 0 else None


def thickness(size: np.ndarray,
              box: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
              fill: GeomPlan | None = None) -> float:
    """The radius a link's bridges take from its ``link.size``, or from its collision box when
    it has one (module docstring); ``fill``: the box's :func:`box_fill`, when the caller has
    it."""
    if fill is None:
        fill = box_fill(box)
    if fill is not None:
        return float(fill.size[0]) if fill.type != "box" else float(np.min(fill.size))
    k = _n_size(size)
    if k == 0:
        return DEFAULT_GEOM_RADIUS
    return float(size[0]) if k < 3 else float(np.min(size))


def _quat_z_to(u: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, np.asarray(u, dtype=float))
    return quat


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = norm(v)
    return v / n if n > 1e-9 else None


def _by_size(half: np.ndarray) -> tuple[list[int], float, float, float]:
    """A box's axes from its largest half-size to its smallest (stable: ties keep the axis
    order), and those half-sizes ``a >= b >= e``."""
    h = half.tolist()
    order = sorted(range(3), key=lambda k: -h[k])
    a, b, e = (h[k] for k in order)
    return order, a, b, e


def _box_primitive(center: np.ndarray, quat: np.ndarray, half: np.ndarray) -> GeomPlan:
    """The primitive that fills a collision box (module docstring)."""
    order, a, b, e = _by_size(half)
    q = quat / (norm(quat) or 1.0)
    if a >= 1.5 * b:
        r = max(0.5 * (b + e), MIN_RADIUS)
        axis = np.zeros(3)
        mujoco.mju_rotVecQuat(axis, _AXES[order[0]], q)
        return GeomPlan("capsule", np.array([r, max(a - r, 1e-4), 0.0]), center.copy(),
                        _quat_z_to(axis))
    if a <= 1.2 * e:
        return GeomPlan("sphere", np.array([(a + b + e) / 3.0, 0.0, 0.0]), center.copy(),
                        np.array([1.0, 0.0, 0.0, 0.0]))
    return GeomPlan("box", np.maximum(half, 1e-4), center.copy(), q)


def _disc(f: LinkFrame) -> GeomPlan | None:
    """The cylinder of a link whose collision box is a disc spun by one of its hinges (module
    docstring), else None."""
    assert f.box is not None  # called for a link whose box gave its fill
    center, quat, half = f.box
    order, a, b, e = _by_size(half)
    if a > 1.2 * b:
        return None
    n = np.zeros(3)
    mujoco.mju_rotVecQuat(n, _AXES[order[2]], quat / (norm(quat) or 1.0))
    r = 0.5 * (a + b)
    for pos, axis in f.hinges:
        u = _unit(np.asarray(axis, dtype=float))
        if u is None or abs(float(n @ u)) < DISC_COS:
            continue
        off = center - pos
        if norm(off - float(off @ u) * u) <= DISC_OFFSET * r:
            return GeomPlan("cylinder", np.array([max(r, 1e-4), max(e, 1e-4), 0.0]),
                            center.copy(), _quat_z_to(n))
    return None


def _box_geom(center: np.ndarray, quat: np.ndarray, half: np.ndarray) -> GeomPlan:
    """The collision box itself as a geom."""
    return GeomPlan("box", np.maximum(half, 1e-4), center.copy(), quat / (norm(quat) or 1.0))


def _primitive(f: LinkFrame, fill: GeomPlan | None) -> GeomPlan:
    """The link's first geom; ``fill``: :func:`box_fill` of its box."""
    if fill is not None:
        prim = fill
        if prim.type == "box" and f.hinges:
            return _disc(f) or prim
        if prim.type == "capsule" and not f.root and not f.children and not f.side:  # a sole
            assert f.box is not None  # the fill is that of the box
            return _box_geom(*f.box)
        if prim.type == "capsule" and not f.root and f.children:  # a limb segment: joined
            u = f.children[0][0] - f.anchor
            length = float(np.linalg.norm(u))
            if length > 2.0 * prim.size[0]:
                return GeomPlan("capsule", np.array([prim.size[0], 0.5 * length, 0.0]),
                                f.anchor + 0.5 * u, _quat_z_to(u / length))
        return prim
    k = _n_size(f.size)
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    if k == 0:
        size = np.array([DEFAULT_GEOM_RADIUS, 0.0, 0.0])
    else:
        size = np.where(np.arange(3) < k, f.size, 0.0)
    gtype = ("sphere", "sphere", "capsule", "box")[k]
    if f.root:
        return GeomPlan(gtype, size, np.zeros(3), ident)
    if gtype == "sphere":
        return GeomPlan(gtype, size, f.anchor if f.children else f.ipos.copy(), ident)
    u = None
    for t, _ in f.children:
        u = _unit(t - f.anchor)
        if u is not None:
            break
    if u is None:
        u = _unit(f.ipos - f.anchor)
    if u is None:
        u = np.array([0.0, 0.0, 1.0])
    reach = float(size[1] + size[0] if gtype == "capsule" else size[2])
    return GeomPlan(gtype, size, f.anchor + reach * u, _quat_z_to(u))


def _frame(g: GeomPlan) -> np.ndarray:
    """``R(g.quat)ᵀ``: world-to-geom rotation of ``g`` (for :func:`surface_gap`)."""
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, g.quat)
    return mat.reshape(3, 3).T


def surface_gap(g: GeomPlan, p: np.ndarray, rot_t: np.ndarray | None = None) -> float:
    """Distance (m) from point ``p`` to the surface of ``g`` (≤ 0 inside); ``rot_t``:
    :func:`_frame` of ``g`` when already computed."""
    local = (_frame(g) if rot_t is None else rot_t) @ (p - g.pos)
    if g.type == "sphere":
        return norm(local) - float(g.size[0])
    if g.type == "capsule":
        h = float(g.size[1])
        local[2] -= min(max(float(local[2]), -h), h)
        return norm(local) - float(g.size[0])
    if g.type == "cylinder":  # a box in (radial, axial) distance
        out = np.array([math.hypot(local[0], local[1]) - float(g.size[0]),
                        abs(float(local[2])) - float(g.size[1])])
        return norm(np.maximum(out, 0.0)) + min(float(out.max()), 0.0)
    out = np.abs(local) - g.size
    return norm(np.maximum(out, 0.0)) + min(float(out.max()), 0.0)


def _bridge(a: np.ndarray, b: np.ndarray, radius: float) -> GeomPlan:
    d = b - a
    length = norm(d)
    if length <= 2.0 * radius:  # a sphere touching both ends
        r = max(0.5 * length, MIN_BRIDGE * radius)
        return GeomPlan("sphere", np.array([r, 0.0, 0.0]), 0.5 * (a + b),
                        np.array([1.0, 0, 0, 0]), True)
    return GeomPlan("capsule", np.array([radius, 0.5 * length - radius, 0.0]), 0.5 * (a + b),
                    _quat_z_to(d / length), True)


def _core(g: GeomPlan, p: np.ndarray, rot_t: np.ndarray) -> np.ndarray:
    """The point of ``g``'s core nearest ``p``: a sphere's centre, a capsule's or a
    cylinder's axis segment, a box's mid-surface (the box shrunk by its smallest half-size)."""
    if g.type == "sphere":
        return g.pos.copy()
    local = rot_t @ (p - g.pos)
    if g.type in ("capsule", "cylinder"):
        h = float(g.size[1])
        local = np.array([0.0, 0.0, min(max(float(local[2]), -h), h)])
    else:
        inner = g.size - float(np.min(g.size))
        local = np.clip(local, -inner, inner)
    return g.pos + rot_t.T @ local


def link_geoms(f: LinkFrame) -> list[GeomPlan]:
    """The primitive of a link, then its bridges (module docstring)."""
    fill = f.fill if f.fill is not None else box_fill(f.box)
    prim = _primitive(f, fill)
    r = thickness(f.size, fill=fill)
    out = [prim]
    rot_t = _frame(prim)
    if not f.root and surface_gap(prim, f.anchor, rot_t) > COVER_TOL * r:
        out.append(_bridge(prim.pos, f.anchor, r))
    for t, r_child in f.children:
        if surface_gap(prim, t, rot_t) > COVER_TOL * r:
            out.append(_bridge(_core(prim, t, rot_t), t, min(r, r_child)))
    return out
