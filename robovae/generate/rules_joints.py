"""Repair rules on joints: types MuJoCo accepts where they sit, valid ranges, non-negative
dynamics.

Each function repairs a :class:`~robovae.generate.graph_view.GraphView` in place (physical
units: rad for hinge and ball ranges, m for slides) and only changes values that break its
constraint; :mod:`robovae.generate.rules` runs it as the rule of the same name. Joint types are
those of :func:`~robovae.generate.bodies.joint_types`.

``joint_type_valid`` (sets with ``joint.type``)
    MuJoCo allows a free joint only in a top-level body, alone in it: a free joint anywhere but
    the tree root (when it is the only joint of the bodies it leads to) becomes a hinge.
    MuJoCo also rejects a rotation (hinge or ball) after a ball joint in the same body: such a
    ball becomes a hinge.
``range_ordered``
    a joint range is *unlimited* when ``max(|lo|, |hi|) <``
    :data:`~robovae.generate.bodies.RANGE_ZERO` or, in sets with a ``joint.limited`` flag,
    when the flag is 0; it is then set to exactly ``(0, 0)`` (and the flag to 0). In
    ``paper34`` every other range is limited. Free joints get no range. Limited ranges are
    ordered (swapped when ``lo > hi``) and clipped: hinges to ``[-2π, 2π]``
    (:data:`HINGE_LIMIT`), ball joints to ``[0, π]`` with ``lo = 0`` (MuJoCo requires
    ``range[0] = 0``), slides to the registry range of ``joint.range``; then widened about their
    middle to at least :data:`MIN_RANGE_WIDTH` ``· max(1, |lo|, |hi|)`` (MuJoCo needs
    ``lo < hi``, also after the 6 significant digits MJCF keeps). Actuator control ranges
    (``joint.ctrlrange``) follow the same zero/order/width rules within their registry range,
    and are ``(0, 0)`` for joints whose ``joint.actuated`` flag is 0.
``nonnegative_dynamics``
    ``joint.damping``, ``armature``, ``frictionloss``, ``stiffness`` and ``geom.friction``
    ``≥ 0``.

Not a rule (MuJoCo accepts it, and a real robot written by the writer keeps it) but a fix of
decoded graphs (:mod:`robovae.generate.fixes`):

``slide_limited`` (sets with ``joint.type``)
    A slide joint is a rail of finite length: one without limits lets its body run off any
    distance (a decoded robot that the walk optimiser shook shed eleven bodies along such
    rails, metres from its trunk, all of them "attached" at rest). A slide that is unlimited
    (as ``range_ordered`` decides it: the ``joint.limited`` flag below 0.5 or both range ends
    within :data:`~robovae.generate.bodies.RANGE_ZERO` of 0) and that is not a joint of the
    trunk (those connect the robot to the world, as dm_control's planar ``rootx``/``rootz``
    do) gets the range ``[-SLIDE_STROKE, SLIDE_STROKE]`` (:data:`SLIDE_STROKE`, 5 cm: the
    order of the real robots' grippers and suspensions, whose non-root slides are all
    limited) and its flag set.
"""

from __future__ import annotations

import math

import numpy as np

from robovae.data.features import JOINT, JOINT_TYPES, LINK
from robovae.generate.bodies import (
    RANGE_ZERO,
    free_root_allowed,
    link_structure,
    trunk,
    view_joint_types,
)
from robovae.generate.graph_view import GraphView, ceil32, floor32

__all__ = ["DYNAMICS", "HINGE_LIMIT", "MIN_RANGE_WIDTH", "SLIDE_STROKE", "joint_type_valid",
           "nonnegative_dynamics", "range_ordered", "slide_limited"]

#: Narrowest limited range, relative to ``max(1, |lo|, |hi|)``.
MIN_RANGE_WIDTH = 1e-4
#: Widest hinge range end (rad).
HINGE_LIMIT = 2.0 * math.pi
#: Half-stroke (m) of a slide joint off the trunk that the decoding leaves unlimited.
SLIDE_STROKE = 0.05
#: Dynamics features that must be non-negative.
DYNAMICS = ("joint.damping", "joint.armature", "joint.frictionloss", "joint.stiffness",
            "geom.friction")


def joint_type_valid(v: GraphView) -> None:
    """Turn free joints off the root and balls followed by rotations into hinges (module
    docstring)."""
    if not v.has("joint.type"):
        return
    types = view_joint_types(v)
    free_ok = free_root_allowed(v.parent, v.types)
    hinge = np.eye(len(JOINT_TYPES))[JOINT_TYPES.index("hinge")]
    for i in v.nodes(JOINT):
        if types[i] == "free" and not (i == 0 and free_ok):
            v.set(i, "joint.type", hinge)
            types[i] = "hinge"
    _, chain = link_structure(v.parent, v.types)
    for i in v.nodes(LINK):
        for k, j in enumerate(chain[i]):
            if types[j] == "ball" and any(types[c] in ("ball", "hinge") for c in chain[i][k + 1:]):
                v.set(j, "joint.type", hinge)
                types[j] = "hinge"


def _fix_range(lo: float, hi: float, low: float, high: float) -> tuple[float, float]:
    """Order, clip to ``[low, high]`` (float32-safe) and widen a limited range to at least
    :data:`MIN_RANGE_WIDTH` ``· max(1, |lo|, |hi|)`` about its middle, staying inside."""
    low, high = ceil32(low), floor32(high)
    if lo > hi:
        lo, hi = hi, lo
    lo, hi = min(max(lo, low), high), min(max(hi, low), high)
    width = MIN_RANGE_WIDTH * max(1.0, abs(lo), abs(hi))
    if hi - lo < (1.0 - 1e-3) * width:  # tolerance: float32 storage rounds the ends
        mid = min(max(0.5 * (lo + hi), low + 0.5 * width), high - 0.5 * width)
        lo, hi = mid - 0.5 * width, mid + 0.5 * width
    return lo, hi


def _decoded_limited(v: GraphView, i: int, has_flag: bool) -> bool:
    """Whether joint ``i`` is limited as ``range_ordered`` reads it: its ``joint.limited`` flag
    (where the set has one) at least 0.5 and a range end at least ``RANGE_ZERO`` from 0."""
    flagged = not has_flag or v.get(i, "joint.limited")[0] >= 0.5
    return bool(flagged and np.abs(v.get(i, "joint.range")).max() >= RANGE_ZERO)


def range_ordered(v: GraphView) -> None:
    """Make every joint and control range unlimited or a valid limited range (module
    docstring)."""
    has_flag = v.has("joint.limited")
    reg = v.feature("joint.range")
    if not has_flag:  # paper34: near-zero ranges mean "unlimited"
        for i in v.nodes(JOINT):
            if np.abs(v.get(i, "joint.range")).max() < RANGE_ZERO:
                v.set(i, "joint.range", 0.0)
    types = view_joint_types(v)
    for i in v.nodes(JOINT):
        lo, hi = (float(a) for a in v.get(i, "joint.range"))
        limited = _decoded_limited(v, i, has_flag)
        if types[i] == "free":
            limited = False
        if not limited:
            v.set(i, "joint.range", 0.0)
            if has_flag:
                v.set(i, "joint.limited", 0.0)
            continue
        if types[i] == "ball":
            lo, hi = 0.0, min(max(abs(lo), abs(hi)), floor32(math.pi))
            hi = max(hi, ceil32(MIN_RANGE_WIDTH))
        elif types[i] == "slide":
            lo, hi = _fix_range(lo, hi, reg.low, reg.high)
        else:
            lo, hi = _fix_range(lo, hi, -HINGE_LIMIT, HINGE_LIMIT)
        v.set(i, "joint.range", [lo, hi])
    if v.has("joint.ctrlrange"):
        creg = v.feature("joint.ctrlrange")
        actuated = v.has("joint.actuated")
        for i in v.nodes(JOINT):
            lo, hi = (float(a) for a in v.get(i, "joint.ctrlrange"))
            if (actuated and v.get(i, "joint.actuated")[0] < 0.5) or \
                    max(abs(lo), abs(hi)) < RANGE_ZERO:
                v.set(i, "joint.ctrlrange", 0.0)
            else:
                v.set(i, "joint.ctrlrange", _fix_range(lo, hi, creg.low, creg.high))


def slide_limited(v: GraphView) -> None:
    """Limit the unlimited slide joints off the trunk to ``±SLIDE_STROKE`` (module docstring:
    a fix of decoded graphs, not one of the rules)."""
    if not v.has("joint.type"):
        return
    types = view_joint_types(v)
    slides = [i for i in v.nodes(JOINT) if types[i] == "slide"]
    if not slides:
        return
    top = trunk(v.types, v.kids)
    root_joints = set(link_structure(v.parent, v.types)[1][top]) if top >= 0 else set()
    has_flag = v.has("joint.limited")
    for i in slides:
        if i in root_joints or _decoded_limited(v, i, has_flag):
            continue
        v.set(i, "joint.range", [-SLIDE_STROKE, SLIDE_STROKE])
        if has_flag:
            v.set(i, "joint.limited", 1.0)


def nonnegative_dynamics(v: GraphView) -> None:
    """Clip the dynamics features of :data:`DYNAMICS` at 0."""
    for key in DYNAMICS:
        if not v.has(key):
            continue
        sl = v.fs.slice(key)
        rows = v.mask[:, sl.start]
        v.x[rows, sl] = np.maximum(v.x[rows, sl], 0.0)
