"""Repair rules on geometry: geom sizes MuJoCo accepts, and no limb collapsed into one point.

Each function repairs a :class:`~robovae.generate.graph_view.GraphView` in place (m) and only
changes values that break its constraint; :mod:`robovae.generate.rules` runs it as the rule of
the same name.

``size_positive``
    ``link.size`` (read by the writer as sphere ``(r)``, capsule ``(r, h)`` or box
    ``(x, y, z)``): negative → 0; a zero component means "absent"; trailing components (2nd or
    3rd) below :data:`SIZE_ZERO` or below :data:`SIZE_ZERO_RATIO` times the largest are set to 0
    (a decoder's "zero" is ``exp(log eps) ≈ 1e-4``, not 0); every component up to the last
    positive one is raised to at least :data:`MIN_SIZE`. ``geom.size``: the components the
    primitive uses (:data:`GEOM_SIZE_COMPONENTS`: sphere 1, capsule/cylinder 2, ellipsoid/box
    3) ``≥ MIN_SIZE``, the unused ones ``≥ 0``.
``limb_length``
    a *limb* is a subtree hanging off the trunk link (:func:`~robovae.generate.bodies.trunk`)
    that holds at least one joint; it is degenerate when **every** link in it has
    ``|link.pos|`` and ``|link.ipos| <`` :data:`MIN_LIMB_OFFSET`, i.e. the whole limb, bodies
    and masses, sits in one point inside the trunk. Its links are then spread out: a link
    directly below the trunk to ``r (cos 2πk/K, sin 2πk/K, 0)`` for limb ``k`` of ``K``, with
    ``r`` the trunk's largest ``link.size`` (else :data:`DEFAULT_LIMB_SEGMENT`); every further
    link to ``(0, 0, -d)`` with ``d`` twice its parent link's largest size (else
    ``DEFAULT_LIMB_SEGMENT``); ``r`` and ``d`` capped at the registry's ``link.pos`` maximum.
    Single links at their parent's origin (URDF dummy links) are left alone.
"""

from __future__ import annotations

import math

import numpy as np

from robovae.data.features import GEOM, GEOM_TYPES, JOINT, LINK
from robovae.generate.bodies import link_structure, subtree, trunk
from robovae.generate.graph_view import GraphView, ceil32, norm

__all__ = ["DEFAULT_GEOM_RADIUS", "DEFAULT_LIMB_SEGMENT", "GEOM_SIZE_COMPONENTS",
           "MIN_LIMB_OFFSET", "MIN_SIZE", "SIZE_ZERO", "SIZE_ZERO_RATIO", "limb_length",
           "size_positive"]

#: Smallest positive geom size component (m); the smallest real one is 1.7e-4 m.
MIN_SIZE = 1e-5
#: A trailing ``link.size`` component below this (m) is absent; real models use >= 1e-3.
SIZE_ZERO = 5e-4
#: ... or below this fraction of the largest component (real boxes: >= 0.05).
SIZE_ZERO_RATIO = 0.02
#: Radius of the sphere the writer gives a link without size (m); also the radius used to
#: derive a missing inertia.
DEFAULT_GEOM_RADIUS = 0.02
#: A limb whose links all sit closer than this to their parent's origin is degenerate (m).
MIN_LIMB_OFFSET = 1e-4
#: Segment length used to spread a degenerate limb when no size says better (m).
DEFAULT_LIMB_SEGMENT = 0.1
#: Size components each geom primitive uses (MuJoCo convention; MJCF output writes no others).
GEOM_SIZE_COMPONENTS = {"sphere": 1, "capsule": 2, "cylinder": 2, "ellipsoid": 3, "box": 3}


def _size_prefix(size: np.ndarray) -> np.ndarray:
    s = np.maximum(size, 0.0)
    tiny = max(SIZE_ZERO, SIZE_ZERO_RATIO * float(s.max(initial=0.0)))
    for k in range(len(s) - 1, 0, -1):  # trailing components only; the first one stays
        if s[k] >= tiny:
            break
        s[k] = 0.0
    pos = np.nonzero(s > 0)[0]
    if pos.size:
        last = int(pos[-1])
        s[: last + 1] = np.maximum(s[: last + 1], ceil32(MIN_SIZE))
    return s


def size_positive(v: GraphView) -> None:
    """Link and geom sizes MuJoCo accepts (module docstring)."""
    if v.has("link.size"):
        for i in v.nodes(LINK):
            v.set(i, "link.size", _size_prefix(v.get(i, "link.size")))
    if v.has("geom.size"):
        for i in v.nodes(GEOM):
            s = np.maximum(v.get(i, "geom.size"), 0.0)
            gtype = GEOM_TYPES[int(np.argmax(v.get(i, "geom.type")))] if v.has("geom.type") \
                else "box"
            n = GEOM_SIZE_COMPONENTS[gtype]
            s[:n] = np.maximum(s[:n], ceil32(MIN_SIZE))
            v.set(i, "geom.size", s)



def _largest_size(v: GraphView, i: int) -> float:
    return float(v.get(i, "link.size").max()) if v.has("link.size") else 0.0


def limb_length(v: GraphView) -> None:
    """Spread out limbs collapsed into one point (module docstring)."""
    if not v.nodes(LINK):
        return
    root_link = trunk(v.types, v.kids)
    if root_link < 0:
        return
    limbs = []
    for c in v.kids[root_link]:
        nodes = subtree(v.kids, c)
        links = [n for n in nodes if v.types[n] == LINK]
        if links and any(v.types[n] == JOINT for n in nodes):
            limbs.append(links)
    anc, _ = link_structure(v.parent, v.types)
    cap = v.feature("link.pos").high
    for k, links in enumerate(limbs):
        extent = max(max(norm(v.get(i, "link.pos")), norm(v.get(i, "link.ipos")))
                     for i in links)
        if extent >= MIN_LIMB_OFFSET:
            continue
        angle = 2.0 * math.pi * k / len(limbs)
        for i in links:
            if anc[i] == root_link:
                reach = min(_largest_size(v, root_link) or DEFAULT_LIMB_SEGMENT, cap)
                v.set(i, "link.pos", [reach * math.cos(angle), reach * math.sin(angle), 0.0])
            else:
                reach = min(2.0 * _largest_size(v, anc[i]) or DEFAULT_LIMB_SEGMENT, cap)
                v.set(i, "link.pos", [0.0, 0.0, -reach])
