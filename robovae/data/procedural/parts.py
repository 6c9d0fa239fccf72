"""Parts every procedural class shares: joined limb chains, grippers, hands, welded bodies,
wheels, motors.

An end effector is drawn once per robot as a :class:`Hand` (:func:`sample_gripper`,
:func:`sample_fingers`) and built on each arm by :func:`build_hand`, so that a robot's two
hands are the same, as on real robots.

Geometry is *joined*: a body's capsule runs from its own origin (its joint anchor) to the origin
of its child (:func:`chain`), so every body touches its parent and child. Motor gears are sized
after the tree is built (:func:`size_motors`): a joint created with ``gear=AUTO`` gets the
torque (N·m, or N for slides) that holds its subtree out against gravity,
``M_sub · g · R_sub`` (``R_sub``: farthest geom point of the subtree from the joint; a slide
gets the force ``2 M_sub · g``), and every
gear is then multiplied by the robot's strength (``common.strength`` in ``ranges.yaml``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from robovae.data.procedural.blueprint import Geom, Joint, Part, Vec
from robovae.data.procedural.sampler import G, Sampler

#: ``gear`` of a joint whose motor is sized from its subtree by :func:`size_motors`.
AUTO = -1.0

Link = tuple[list[Joint], Vec, float, float]  # joints, vector to the next anchor, radius, mass


def add(a: Vec, b: Vec, k: float = 1.0) -> Vec:
    """``a + k b``."""
    return (a[0] + k * b[0], a[1] + k * b[1], a[2] + k * b[2])


def norm(v: Vec) -> float:
    """Euclidean length of ``v``."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def unit(v: Vec) -> Vec:
    """``v / |v|`` (``v`` itself when it is zero)."""
    n = norm(v) or 1.0
    return (v[0] / n, v[1] / n, v[2] / n)


def cross(a: Vec, b: Vec) -> Vec:
    """Cross product ``a × b``."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def capsule(a: Vec, b: Vec, radius: float, mass: float) -> Geom:
    """A capsule from ``a`` to ``b`` (a sphere when they coincide)."""
    if norm((b[0] - a[0], b[1] - a[1], b[2] - a[2])) < 1e-6:
        return Geom("sphere", mass, radius, pos=a)
    return Geom("capsule", mass, radius, fromto=(*a, *b))


def chain(parent: Part, prefix: str, anchor: Vec, links: list[Link]) -> tuple[Part, Vec]:
    """Append a joined chain of bodies ``<prefix>0, <prefix>1, ...`` to ``parent``.

    Body 0 sits at ``anchor`` (parent frame); body ``k+1`` at the end of body ``k``'s vector,
    and body ``k``'s capsule spans that vector. Returns the last body and its tip (its frame).
    """
    body, pos = parent, anchor
    for k, (joints, vec, radius, mass) in enumerate(links):
        body = body.add(Part(f"{prefix}{k}", pos, list(joints)))
        body.geoms.append(capsule((0.0, 0.0, 0.0), vec, radius, mass))
        pos = vec
    return body, pos


def perpendicular(d: Vec) -> Vec:
    """A unit vector perpendicular to ``d`` (horizontal when ``d`` is not vertical)."""
    side = cross((0.0, 0.0, 1.0), d)
    return unit(side) if norm(side) > 1e-6 else (0.0, 1.0, 0.0)


@dataclass
class Hand:
    """An end effector drawn once and built on every arm of a robot (real robots mirror their
    hands): ``kind`` is ``slides`` or ``hinges`` (two parallel jaws), ``jaw`` (one moving jaw
    against a fixed one), ``linkage`` (two jaws of linkage bars) or ``fingers``; ``length``
    and ``travel`` size the jaws; ``fingers`` holds the phalanx lengths of each finger, the
    thumb first; ``thumb_last`` lists it last instead; ``jaws`` holds ``(outer, inner, tips)``
    of each linkage jaw."""

    kind: str
    length: float = 0.0
    travel: float = 0.0
    fingers: list[list[float]] = field(default_factory=list)
    thumb_last: bool = False
    jaws: list[tuple[int, int, int]] = field(default_factory=list)


def sample_gripper(s: Sampler, scale: float) -> Hand:
    """A gripper from the ``arm`` section (``gripper_kind``, ``finger``, ``finger_travel``,
    ``linkage_outer``/``inner``/``tips``) through ``s``."""
    kind = s.pick("gripper_kind")
    hand = Hand(kind, s.u("finger", scale), s.u("finger_travel", scale))
    if kind == "linkage":
        hand.jaws = [(int(s.pick("linkage_outer")), int(s.pick("linkage_inner")),
                      int(s.pick("linkage_tips"))) for _ in range(2)]
    return hand


def sample_fingers(s: Sampler, scale: float) -> Hand:
    """A fingered hand from the ``humanoid`` section: ``fingers`` fingers of ``phalanges``
    hinges each, the thumb ``thumb_extra`` more, listed ``thumb`` first or last."""
    n, k = int(s.pick("fingers")), int(s.pick("phalanges"))
    thumb = k + int(s.pick("thumb_extra"))
    lengths = [[s.u("phalanx", scale) for _ in range(thumb if f == 0 else k)] for f in range(n)]
    return Hand("fingers", fingers=lengths, thumb_last=s.pick("thumb") == "last")


def _finger_link(s: Sampler, axis: Vec, d: Vec, ln: float, lim: tuple) -> Link:
    return ([s.hinge(axis, lim, gear=AUTO)], (d[0] * ln, d[1] * ln, d[2] * ln),
            max(0.004, 0.15 * ln), max(0.005, 15.0 * ln ** 2))


def build_hand(s: Sampler, body: Part, prefix: str, tip: Vec, direction: Vec, hand: Hand
               ) -> None:
    """Build ``hand`` at ``tip`` of ``body``, pointing along the unit vector ``direction``."""
    side = perpendicular(direction)
    axis = cross(direction, side)
    length, travel = hand.length, hand.travel
    if hand.kind in ("slides", "hinges"):
        for k, sgn in enumerate((1.0, -1.0)):
            base = add(tip, side, sgn * 0.5 * travel)
            if hand.kind == "hinges":
                j = s.hinge(axis, ((-0.1, -0.05), (0.6, 1.0)), gear=AUTO)
            else:
                j = s.slide((sgn * side[0], sgn * side[1], sgn * side[2]), (0.0, travel),
                            gear=AUTO)
            f = body.add(Part(f"{prefix}finger{k}", base, [j]))
            f.geoms.append(capsule((0.0, 0.0, 0.0), add((0.0, 0.0, 0.0), direction, length),
                                   max(0.004, 0.15 * length), max(0.01, 20.0 * length ** 2)))
    elif hand.kind == "jaw":  # a fixed jaw on the body, one jaw on a hinge
        r = max(0.004, 0.15 * length)
        fixed = add(tip, side, -0.5 * travel)
        body.geoms.append(capsule(fixed, add(fixed, direction, length), r,
                                  max(0.01, 20.0 * length ** 2)))
        f = body.add(Part(f"{prefix}jaw", add(tip, side, 0.5 * travel),
                          [s.hinge(axis, ((-0.1, -0.05), (0.6, 1.0)), gear=AUTO)]))
        f.geoms.append(capsule((0.0, 0.0, 0.0), add((0.0, 0.0, 0.0), direction, length), r,
                               max(0.01, 20.0 * length ** 2)))
    elif hand.kind == "linkage":  # per jaw: an outer bar chain, an inner bar chain + tips
        for k, (outer, inner, tips) in enumerate(hand.jaws):
            sgn = 1.0 if k == 0 else -1.0
            d = unit(add(direction, side, sgn * 0.3))
            lim = ((-0.1, -0.05), (0.5, 0.9))
            chain(body, f"{prefix}jaw{k}_outer", add(tip, side, sgn * 0.3 * travel),
                  [_finger_link(s, axis, d, length / outer, lim) for _ in range(outer)])
            last, end = chain(body, f"{prefix}jaw{k}_inner", add(tip, side, sgn * 0.1 * travel),
                              [_finger_link(s, axis, d, 0.8 * length / inner, lim)
                               for _ in range(inner)])
            for t in range(tips):
                spread = add(end, axis, (t - 0.5 * (tips - 1)) * 0.3 * travel)
                chain(last, f"{prefix}jaw{k}_tip{t}_",
                      spread, [_finger_link(s, axis, direction, 0.4 * length, lim)])
    elif hand.kind == "fingers":
        n = len(hand.fingers)
        gap = 0.6 * sum(f[0] for f in hand.fingers) / n
        order = list(range(1, n)) + [0] if hand.thumb_last else list(range(n))
        for k in order:  # k = 0 is the thumb, turned to the side
            offset = (k - 0.5 * (n - 1)) * gap
            d = direction if k else unit(add(direction, axis, 0.8))
            chain(body, f"{prefix}f{k}_", add(tip, side, offset),
                  [_finger_link(s, axis, d, ln, ((-0.2, -0.05), (0.8, 1.6)))
                   for ln in hand.fingers[k]])


def flange(body: Part, name: str, tip: Vec, direction: Vec, length: float, radius: float,
           mass: float) -> tuple[Part, Vec]:
    """A welded end-effector body at ``tip`` of ``body`` (franka's hand, n1's end-effector
    link): a short capsule along ``direction``. Returns it and its end (its frame)."""
    end = (direction[0] * length, direction[1] * length, direction[2] * length)
    part = body.add(Part(name, tip))
    part.geoms.append(capsule((0.0, 0.0, 0.0), end, radius, mass))
    return part, end


def welded_boxes(s: Sampler, n: int, prefix: str, places: list[Vec]) -> list[Part]:
    """``n`` welded sensor bodies (IMU, camera: no joint, a small box) at ``places``, not yet
    attached to a parent."""
    out = []
    for k in range(n):
        box = s.u((0.01, 0.03))
        part = Part(f"{prefix}sensor{k}", places[k % len(places)])
        part.geoms.append(Geom("box", s.u((0.01, 0.1)), pos=(0.0, 0.0, 0.0), half=(box,) * 3))
        out.append(part)
    return out


def sensors(s: Sampler, body: Part, prefix: str, half: Vec) -> None:
    """0-2 welded sensor bodies on the top and front of ``body``, whose geometry spans ``half``
    (half-sizes): ``sensors`` of the class sets the count, ``sensor_slot`` whether they come
    before the other children of ``body`` (barkour_vb, the head bodies of Unitree's go2
    URDF) or after them."""
    n = int(s.pick("sensors"))
    parts = welded_boxes(s, n, prefix, [(0.0, 0.0, half[2]), (half[0], 0.0, 0.3 * half[2])])
    if n and s.pick("sensor_slot") == "first":
        body.children[:0] = parts
    else:
        body.children += parts


def wheel(body: Part, name: str, pos: Vec, radius: float, width: float, mass: float,
          joint: Joint) -> Part:
    """A wheel body at ``pos`` spinning about y: a cylinder across y."""
    w = body.add(Part(name, pos, [joint]))
    w.geoms.append(Geom("cylinder", mass, radius, fromto=(0.0, -0.5 * width, 0.0,
                                                          0.0, 0.5 * width, 0.0)))
    return w


def _reach(part: Part) -> float:
    """Farthest geom point of ``part``'s subtree from its origin (m)."""
    far = 0.0
    for p, o in part.walk():
        for g in p.geoms:
            if g.fromto is not None:
                pts = [g.fromto[:3], g.fromto[3:]]
            else:
                assert g.pos is not None  # a sphere or a box (see Geom)
                pts = [g.pos]
            for q in pts:
                far = max(far, norm(add(o, q)) + g.radius)
    return far


def size_motors(root: Part, strength: float) -> None:
    """Resolve ``AUTO`` gears to ``M_sub · g · R_sub`` and scale every gear by ``strength``."""
    for p, _ in root.walk():
        for j in p.joints:
            if j.gear == AUTO and j.type == "slide":
                j.gear = max(1.0, 2.0 * p.mass() * G)
            elif j.gear == AUTO:
                j.gear = max(0.05, p.mass() * G * _reach(p))
            j.gear *= strength
