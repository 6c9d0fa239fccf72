"""Fixed-base arms (z1 / piper / franka-like): a welded base, 4-7 hinges, a gripper.

Hinge patterns (base yaw first): 4 ``z y y y``; 5 ``z y y y x``; 6 ``z y y y z x`` or
``z y y x y x``; 7 ``z y z y z y z``. The shoulder rises from the base, the upper arm leans
``a`` above horizontal, the forearm reaches out, short wrist links follow; a parallel-jaw
gripper (two fingers on slides, or on hinges) ends the chain with probability ``gripper``.
:func:`add_arm` is shared with mobile manipulators.
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Geom, Part, Vec
from robovae.data.procedural.parts import AUTO, Link, chain, cross, gripper
from robovae.data.procedural.sampler import Sampler

_PATTERNS = {4: ["zyyy"], 5: ["zyyyx"], 6: ["zyyyzx", "zyyxyx"], 7: ["zyzyzyz"]}


def add_arm(s: Sampler, parent: Part, prefix: str, anchor: Vec, heading: Vec,
            scale: float = 1.0, mass: float | None = None) -> None:
    """An arm (ranges of the ``arm`` section through ``s``) on ``parent`` at ``anchor``,
    reaching along the horizontal unit vector ``heading``; lengths times ``scale``."""
    n = int(s.pick("hinges"))
    options = _PATTERNS[n]
    pattern = options[s.rng.randrange(len(options))]
    side = cross((0.0, 0.0, 1.0), heading)
    frame = {"x": heading, "y": side, "z": (0.0, 0.0, 1.0)}

    def along(angle: float, length: float) -> Vec:
        c, z = math.cos(angle) * length, math.sin(angle) * length
        return (heading[0] * c, heading[1] * c, z)

    lean, reach = s.u((0.3, 1.4)), s.u((-0.6, 0.4))
    upper, fore = s.u("upper_arm", scale), s.u("forearm", scale)
    vectors = [(0.0, 0.0, s.u("shoulder", scale)), along(lean, upper), along(reach, fore)]
    if n == 7:  # redundant arm: upper arm and forearm split over two joints each
        vectors = [vectors[0], along(lean, 0.5 * upper), along(lean, 0.5 * upper),
                   along(reach, 0.5 * fore), along(reach, 0.5 * fore)]
    while len(vectors) < n:
        vectors.append(along(reach, s.u("wrist", scale)))
    total = mass if mass is not None else s.u("mass")
    radius = s.u("radius", scale)
    weights = [1.0 / (1.0 + 0.6 * k) for k in range(n)]
    links: list[Link] = []
    for k, (ax, vec) in enumerate(zip(pattern, vectors)):
        links.append(([s.hinge(frame[ax], "limit", gear=AUTO)], vec,
                      radius * (1.0 - 0.5 * k / n), total * weights[k] / sum(weights)))
    last, tip = chain(parent, prefix, anchor, links)
    if s.p("gripper"):
        d = vectors[-1]
        n_d = math.sqrt(sum(c * c for c in d)) or 1.0
        gripper(s, last, prefix, tip, (d[0] / n_d, d[1] / n_d, d[2] / n_d), scale,
                s.p("hinge_fingers"))


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a fixed-base arm (the welded base) and ``floating=False``."""
    r, h = s.u("base_radius"), s.u("base_height")
    base = Part("base", (0.0, 0.0, 0.0))
    base.geoms.append(Geom("cylinder", s.u((0.3, 2.0)), r, fromto=(0.0, 0.0, 0.0, 0.0, 0.0, h)))
    add_arm(s, base, "link", (0.0, 0.0, h), (1.0, 0.0, 0.0))
    return base, False
