"""What ``robovae generate`` does to a decoded graph before the writer: the generation choices
that are not validity rules, each reported by name when it changes the graph.

1. ``floating_base`` (``floating``): a root that is a single joint becomes a free joint
   (:func:`robovae.generate.rules.floating_base`);
2. ``mirror_limbs``, ``complete_pairs``, ``twin_limbs`` and ``mirror_branches``
   (``mirror``): near-mirror limb pairs become exact mirror images, a stray limb beside them
   gets its mirror image, near-equal limbs on the sagittal plane become equal, near-mirror
   branches of a link below the trunk on both sides of the plane (a chest's arms) become exact
   mirror images
   (:mod:`robovae.generate.symmetry`);
3. ``slide_limited`` (always, last: a mirrored limb carries its partner's joints): a slide
   joint off the trunk without limits gets a 5 cm stroke either way
   (:func:`robovae.generate.rules.slide_limited`).

The writer's stance rules (:mod:`robovae.generate.stance`) come after, on the compiled robot.

The fixes run on the graph's NumPy arrays (:class:`~robovae.data.tree_arrays.TreeArrays`); a
PyG graph is made again once, at the end, when one of them changed it.
"""

from __future__ import annotations

from typing import overload

import numpy as np
import torch

from robovae.data.features import FeatureSet
from robovae.data.graph import RobotData, tree_data
from robovae.data.tree_arrays import TreeArrays
from robovae.generate.rules import floating_base, slide_limited
from robovae.generate.symmetry import complete_pairs, mirror_branches, mirror_limbs, twin_limbs

__all__ = ["decoded_fixes"]


# RobotData first: a class of untyped PyG, mypy would match it to any overload
@overload
def decoded_fixes(graph: RobotData, feature_set: str | FeatureSet, floating: bool = True,
                  mirror: bool = True) -> tuple[RobotData, list[str]]: ...


@overload
def decoded_fixes(graph: TreeArrays, feature_set: str | FeatureSet, floating: bool = True,
                  mirror: bool = True) -> tuple[TreeArrays, list[str]]: ...


def decoded_fixes(graph: TreeArrays | RobotData, feature_set: str | FeatureSet,
                  floating: bool = True, mirror: bool = True
                  ) -> tuple[TreeArrays | RobotData, list[str]]:
    """The graph as ``robovae generate`` writes it (module docstring), of ``graph``'s kind (a
    PyG graph or :class:`~robovae.data.tree_arrays.TreeArrays`), and the names of the fixes
    that changed it, in order; ``graph`` itself is not modified (it is returned when no fix
    changed it)."""
    fixes: list[str] = []
    steps = ([("floating_base", floating_base)] if floating else []) + \
        ([("mirror_limbs", mirror_limbs), ("complete_pairs", complete_pairs),
          ("twin_limbs", twin_limbs), ("mirror_branches", mirror_branches)] if mirror else []) \
        + [("slide_limited", slide_limited)]
    start = arrays = TreeArrays.of(graph)
    for name, fix in steps:
        fixed, changed = fix(arrays, feature_set)
        arrays = TreeArrays.of(fixed)  # the same object: the fixes keep their input's kind
        fixes += [name] if changed else []
    if not fixes:
        return graph, fixes
    if isinstance(graph, TreeArrays):
        return arrays, fixes
    return _as_graph(graph, start, arrays, feature_set), fixes


def _as_graph(graph: RobotData, start: TreeArrays, arrays: TreeArrays,
              feature_set: str | FeatureSet) -> RobotData:
    """The PyG graph of ``arrays``, the fixed ``start`` (the arrays of ``graph``): a copy of
    ``graph`` with the new features when the tree is the same, else a graph built for the new
    tree."""
    x = torch.from_numpy(arrays.x)
    if (np.array_equal(arrays.parent, start.parent)
            and np.array_equal(arrays.node_type, start.node_type)):
        out = graph.clone()
        out.x = x
        return out
    return tree_data(arrays.parent.tolist(), arrays.node_type.tolist(), x, feature_set,
                     name=getattr(graph, "name", ""), source=getattr(graph, "source", ""))
