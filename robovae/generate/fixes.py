"""What ``robovae generate`` does to a decoded graph before the writer: the generation choices
that are not validity rules, each reported by name when it changes the graph.

1. ``floating_base`` (``floating``): a root that is a single joint becomes a free joint
   (:func:`robovae.generate.rules.floating_base`);
2. ``mirror_limbs`` and ``complete_pairs`` (``mirror``): near-mirror limb pairs become exact
   mirror images, a stray limb beside them gets its mirror image
   (:mod:`robovae.generate.symmetry`);
3. ``slide_limited`` (always, last: a mirrored limb carries its partner's joints): a slide
   joint off the trunk without limits gets a 5 cm stroke either way
   (:func:`robovae.generate.rules.slide_limited`).

The writer's stance rules (:mod:`robovae.generate.stance`) come after, on the compiled robot.
"""

from __future__ import annotations

from robovae.data.features import FeatureSet
from robovae.data.graph import RobotData
from robovae.generate.rules import floating_base, slide_limited
from robovae.generate.symmetry import complete_pairs, mirror_limbs

__all__ = ["decoded_fixes"]


def decoded_fixes(graph: RobotData, feature_set: str | FeatureSet, floating: bool = True,
                  mirror: bool = True) -> tuple[RobotData, list[str]]:
    """The graph as ``robovae generate`` writes it (module docstring) and the names of the
    fixes that changed it, in order; ``graph`` itself is not modified."""
    fixes: list[str] = []
    steps = ([("floating_base", floating_base)] if floating else []) + \
        ([("mirror_limbs", mirror_limbs), ("complete_pairs", complete_pairs)] if mirror else []) \
        + [("slide_limited", slide_limited)]
    for name, fix in steps:
        graph, changed = fix(graph, feature_set)
        fixes += [name] if changed else []
    return graph, fixes
