"""Fixed-base arms (z1 / piper / franka / ur5e-like): a welded base, 4-7 hinges, a gripper.

Hinge patterns (base yaw first): 4 ``z y y y``; 5 ``z y y y x``; 6 ``z y y y z x`` or
``z y y x y x``; 7 ``z y z y z y z``. The shoulder rises from the base, the upper arm leans
``a`` above horizontal, the forearm reaches out, short wrist links follow. With probability
``flange`` 1-2 welded end-effector bodies end the chain (franka's link8 and hand, n1's
end-effector link);
with probability ``gripper`` a gripper follows (:func:`~.parts.sample_gripper`: two parallel
jaws on slides or hinges, one moving jaw, or two linkage jaws).
:func:`sample_arm` draws an arm once and :func:`build_arm` builds it, so that mobile
manipulators mirror their two arms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from robovae.data.procedural.blueprint import Geom, Part, Vec
from robovae.data.procedural.parts import (
    AUTO,
    Hand,
    Link,
    build_hand,
    chain,
    cross,
    flange,
    sample_gripper,
)
from robovae.data.procedural.sampler import Sampler

_UP = 0.5 * math.pi  # elevation of the shoulder link, straight up
_PATTERNS = {4: ["zyyy"], 5: ["zyyyx"], 6: ["zyyyzx", "zyyxyx"], 7: ["zyzyzyz"]}


@dataclass
class ArmPlan:
    """An arm drawn once: hinge axes (``x`` along the heading, ``y`` across, ``z`` up), the
    link vectors as ``(elevation, length)``, radius, link masses, the lengths of the welded
    flange bodies (none: no flange) and the hand (``None``: bare)."""

    pattern: str
    links: list[tuple[float, float]]
    radius: float
    masses: list[float]
    flange: list[float]
    hand: Hand | None


def sample_arm(s: Sampler, scale: float = 1.0, mass: float | None = None,
               hinges: int | None = None) -> ArmPlan:
    """Draw an arm from the ``arm`` ranges through ``s``; lengths times ``scale``; ``hinges``
    overrides ``hinges`` of the ranges."""
    n = hinges or int(s.pick("hinges"))
    options = _PATTERNS[n]
    pattern = options[s.rng.randrange(len(options))]
    lean, reach = s.u((0.3, 1.4)), s.u((-0.6, 0.4))
    upper, fore = s.u("upper_arm", scale), s.u("forearm", scale)
    links = [(_UP, s.u("shoulder", scale)), (lean, upper), (reach, fore)]
    if n == 7:  # redundant arm: upper arm and forearm split over two joints each
        links = [links[0], (lean, 0.5 * upper), (lean, 0.5 * upper), (reach, 0.5 * fore),
                 (reach, 0.5 * fore)]
    while len(links) < n:
        links.append((reach, s.u("wrist", scale)))
    total = mass if mass is not None else s.u("mass")
    radius = s.u("radius", scale)
    weights = [1.0 / (1.0 + 0.6 * k) for k in range(n)]
    masses = [total * w / sum(weights) for w in weights]
    bodies = int(s.pick("flange_bodies")) if s.p("flange") else 0
    lengths = [s.u("flange_length", scale) / bodies for _ in range(bodies)]
    hand = sample_gripper(s, scale) if s.p("gripper") else None
    return ArmPlan(pattern, links, radius, masses, lengths, hand)


def build_arm(s: Sampler, plan: ArmPlan, parent: Part, prefix: str, anchor: Vec,
              heading: Vec) -> None:
    """Build ``plan`` on ``parent`` at ``anchor``, reaching along the horizontal unit vector
    ``heading``."""
    side = cross((0.0, 0.0, 1.0), heading)
    frame = {"x": heading, "y": side, "z": (0.0, 0.0, 1.0)}
    n = len(plan.pattern)
    links: list[Link] = []
    vec: Vec = (0.0, 0.0, 0.0)
    for k, (ax, (angle, length)) in enumerate(zip(plan.pattern, plan.links)):
        c = 0.0 if angle == _UP else math.cos(angle) * length
        vec = (heading[0] * c, heading[1] * c, math.sin(angle) * length)
        links.append(([s.hinge(frame[ax], "limit", gear=AUTO)], vec,
                      plan.radius * (1.0 - 0.5 * k / n), plan.masses[k]))
    last, tip = chain(parent, prefix, anchor, links)
    n_d = math.sqrt(sum(c * c for c in vec)) or 1.0
    d = (vec[0] / n_d, vec[1] / n_d, vec[2] / n_d)
    for k, length in enumerate(plan.flange):
        last, tip = flange(last, f"{prefix}flange{k}", tip, d, length, 0.5 * plan.radius,
                           0.5 * plan.masses[-1] / len(plan.flange))
    if plan.hand is not None:
        build_hand(s, last, prefix, tip, d, plan.hand)


def add_arm(s: Sampler, parent: Part, prefix: str, anchor: Vec, heading: Vec,
            scale: float = 1.0, mass: float | None = None) -> None:
    """Draw and build one arm (:func:`sample_arm`, :func:`build_arm`)."""
    build_arm(s, sample_arm(s, scale, mass), parent, prefix, anchor, heading)


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a fixed-base arm (the welded base) and ``floating=False``."""
    r, h = s.u("base_radius"), s.u("base_height")
    base = Part("base", (0.0, 0.0, 0.0))
    base.geoms.append(Geom("cylinder", s.u((0.3, 2.0)), r, fromto=(0.0, 0.0, 0.0, 0.0, 0.0, h)))
    add_arm(s, base, "link", (0.0, 0.0, h), (1.0, 0.0, 0.0))
    return base, False
