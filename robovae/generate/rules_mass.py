"""Repair rules on mass and inertia: what MuJoCo requires of a moving body's inertial.

Each function repairs a :class:`~robovae.generate.graph_view.GraphView` in place (kg, kg·m²)
and only changes values that break its constraint; :mod:`robovae.generate.rules` runs it as the
rule of the same name. A *moving* link has at least one joint in its body
(:func:`~robovae.generate.bodies.moving_links`); MuJoCo rejects moving bodies whose mass or
principal inertias are below ``mjMINVAL`` (1e-15).

``mass_positive``
    ``link.mass ≥ 0``; a moving link lighter than :data:`MIN_MASS` is raised to
    ``max(MIN_MASS, 1e-3 · median positive link mass)`` (:data:`DEFAULT_MASS` when no link has
    a mass).
``inertia_positive``
    ``link.inertia ≥ 0``; for a moving link each component ``≥ max(MIN_INERTIA,``
    :data:`INERTIA_RATIO` ``· largest component)`` (MJCF output rounds components 12 decades
    below the largest to 0): smaller components are raised to that floor; a moving link with no
    inertia at all (every component below :data:`MIN_INERTIA`) gets that of a solid sphere,
    ``0.4 · m · r²`` with ``r`` its largest ``link.size`` (else
    :data:`~robovae.generate.rules_geometry.DEFAULT_GEOM_RADIUS`), capped at the registry's
    ``link.inertia`` maximum.
``inertia_triangle``
    principal inertias satisfy ``a + b ≥ c`` for every permutation (MuJoCo checks this exactly):
    with ``a ≤ b ≤ c`` and ``a + b < c``, the two smaller components are raised — ``a`` first
    up to ``b``, then both equally — until ``a + b = c · (1 +`` :data:`TRIANGLE_MARGIN` ``)``
    (the margin survives float32 and the XML's 6 significant digits). ``c`` is never lowered.
``subtreemass_consistent``
    ``link.subtreemass`` is derived: recomputed as the link's mass plus that of all descendant
    links when any link's stored value is off by more than a relative 1e-5.
"""

from __future__ import annotations

import numpy as np

from robovae.data.features import LINK
from robovae.generate.bodies import link_structure, moving_links
from robovae.generate.graph_view import GraphView, ceil32
from robovae.generate.rules_geometry import DEFAULT_GEOM_RADIUS

__all__ = ["DEFAULT_MASS", "INERTIA_RATIO", "MIN_INERTIA", "MIN_MASS", "TRIANGLE_MARGIN",
           "inertia_positive", "inertia_triangle", "mass_positive", "subtreemass_consistent"]

#: Lightest moving link accepted (kg). MuJoCo needs > 1e-15; the lightest real link (the
#: dm_control fruit fly) weighs 5.1e-8 kg.
MIN_MASS = 1e-9
#: Mass given to a moving link with none, when no link of the robot has a mass (kg).
DEFAULT_MASS = 1e-3
#: Smallest principal inertia of a moving link (kg·m²). MuJoCo needs > 1e-15; the smallest real
#: one (fruit fly) is 4.9e-14.
MIN_INERTIA = 1e-14
#: Smallest ratio between the principal inertias of a moving link: MJCF output drops vector
#: components 12 decades below the largest one, which would leave a moving body without inertia.
#: The most anisotropic real link (Cassie) has a ratio of 8e-4.
INERTIA_RATIO = 1e-9
#: Relative margin by which a repaired inertia exceeds the triangle inequality.
TRIANGLE_MARGIN = 1e-4


def mass_positive(v: GraphView) -> None:
    """Non-negative masses, moving links at least :data:`MIN_MASS` (module docstring)."""
    links = v.nodes(LINK)
    if not links:
        return
    sl = v.fs.slice("link.mass")
    v.x[links, sl] = np.maximum(v.x[links, sl], 0.0)
    masses = v.x[links, sl.start]
    positive = masses[masses > 0]
    floor = max(MIN_MASS, 1e-3 * float(np.median(positive))) if positive.size else DEFAULT_MASS
    floor = ceil32(floor)
    for i in moving_links(v.parent, v.types):
        if v.x[i, sl.start] < MIN_MASS:
            v.x[i, sl.start] = floor


def inertia_positive(v: GraphView) -> None:
    """Non-negative inertias, moving links with every component above the floor (module
    docstring)."""
    links = v.nodes(LINK)
    if not links:
        return
    sl = v.fs.slice("link.inertia")
    v.x[links, sl] = np.maximum(v.x[links, sl], 0.0)
    for i in moving_links(v.parent, v.types):
        inertia = v.get(i, "link.inertia")
        floor = ceil32(max(MIN_INERTIA, INERTIA_RATIO * float(inertia.max())))
        if inertia.min() >= floor:
            continue
        if inertia.max() >= MIN_INERTIA:  # anisotropic: raise the small components
            v.set(i, "link.inertia", np.maximum(inertia, floor))
            continue
        size = float(v.get(i, "link.size").max()) if v.has("link.size") else 0.0
        r = size if size > 0 else DEFAULT_GEOM_RADIUS  # no inertia at all: a solid sphere
        sphere = 0.4 * float(v.get(i, "link.mass")[0]) * r * r
        sphere = min(sphere, v.feature("link.inertia").high)
        v.set(i, "link.inertia", ceil32(max(MIN_INERTIA, sphere)))


def _triangle(inertia: np.ndarray) -> np.ndarray | None:
    """Principal inertias repaired for ``a + b ≥ c`` (module docstring), as float32 values that
    still satisfy it; None when it already holds for every permutation."""
    order = np.argsort(inertia, kind="stable")
    a, b, c = (float(inertia[k]) for k in order)
    if a + b >= c:
        return None
    need = c * (1.0 + TRIANGLE_MARGIN) - a - b
    step = min(need, b - a)
    a += step
    need -= step
    a += 0.5 * need
    b += 0.5 * need
    out = inertia.astype(float).copy()
    out[order[0]], out[order[1]] = a, b
    # make sure the float32 values still satisfy it
    f = out.astype(np.float32).astype(float)
    while f[order[0]] + f[order[1]] < f[order[2]]:
        f[order[0]] = float(np.nextafter(np.float32(f[order[0]]), np.float32(np.inf)))
        f[order[1]] = float(np.nextafter(np.float32(f[order[1]]), np.float32(np.inf)))
    return f


def inertia_triangle(v: GraphView) -> None:
    """Every link's principal inertias satisfy the triangle inequality (module docstring)."""
    for i in v.nodes(LINK):
        fixed = _triangle(v.get(i, "link.inertia"))
        if fixed is not None:
            v.set(i, "link.inertia", fixed)


def subtreemass_consistent(v: GraphView) -> None:
    """Recompute ``link.subtreemass`` from the masses when it disagrees (module docstring)."""
    links = v.nodes(LINK)
    if not links:
        return
    anc, _ = link_structure(v.parent, v.types)
    total = {i: float(v.get(i, "link.mass")[0]) for i in links}
    for i in reversed(links):  # children after parents in pre-order
        if anc[i] >= 0:
            total[anc[i]] += total[i]
    stored = np.array([v.get(i, "link.subtreemass")[0] for i in links])
    want = np.array([total[i] for i in links])
    if np.any(np.abs(stored - want) > 1e-5 * np.maximum(np.abs(want), 1e-12)):
        for i in links:
            v.set(i, "link.subtreemass", total[i])
