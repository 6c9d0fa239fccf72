"""Physical-constraint rules for decoded robot graphs (paper §6.1, SPEC §7): the registry.

A decoded graph carries continuous features that may be slightly (or wildly) outside what MuJoCo
accepts. A *rule* is a named function ``rule(data, feature_set) -> (repaired copy, fired)``
working on **physical** values (after :meth:`robovae.data.normalizer.Normalizer.inverse`); it
only changes values that violate its constraint and says whether any float32 value changed
("fired"). ``data`` itself is never modified. :func:`apply_rules` runs every rule in the order
of :data:`RULES` and returns the repaired graph and the names of the rules that fired.

"Valid" means what MuJoCo itself requires: real robots that MuJoCo compiles (the zoo and the
Menagerie robots) pass every rule unchanged.

Order and kinds (each rule's exact contract is in its module):

1. ``finite``, ``one_hot`` — :mod:`robovae.generate.rules_values`;
2. ``joint_type_valid`` — :mod:`robovae.generate.rules_joints`;
3. ``in_range``, ``unit_quat``, ``axis_unit`` — :mod:`robovae.generate.rules_values`;
4. ``range_ordered``, ``nonnegative_dynamics`` — :mod:`robovae.generate.rules_joints`;
5. ``mass_positive``, ``inertia_positive``, ``inertia_triangle`` —
   :mod:`robovae.generate.rules_mass`;
6. ``size_positive``, ``limb_length`` — :mod:`robovae.generate.rules_geometry`;
7. ``subtreemass_consistent`` (after every mass change) — :mod:`robovae.generate.rules_mass`.

:func:`floating_base` is not a rule (a robot anchored by a hinge is a valid model) but the
generation choice of giving a robot whose root is a single joint a free joint; nor is
:func:`slide_limited` (a slide without limits is valid), the fix that gives a decoded rail its
ends.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robovae.data.features import JOINT_TYPES, FeatureSet
from robovae.data.tree_arrays import RobotTree
from robovae.generate import rules_geometry, rules_joints, rules_mass, rules_values
from robovae.generate.bodies import free_root_allowed
from robovae.generate.graph_view import GraphView, as_feature_set

__all__ = ["RULES", "Rule", "apply_rules", "check_rules", "floating_base", "slide_limited"]

Rule = Callable[[RobotTree, "str | FeatureSet"], tuple[RobotTree, bool]]

_IMPL: dict[str, Callable[[GraphView], None]] = {
    "finite": rules_values.finite,
    "one_hot": rules_values.one_hot,
    "joint_type_valid": rules_joints.joint_type_valid,
    "in_range": rules_values.in_range,
    "unit_quat": rules_values.unit_quat,
    "axis_unit": rules_values.axis_unit,
    "range_ordered": rules_joints.range_ordered,
    "nonnegative_dynamics": rules_joints.nonnegative_dynamics,
    "mass_positive": rules_mass.mass_positive,
    "inertia_positive": rules_mass.inertia_positive,
    "inertia_triangle": rules_mass.inertia_triangle,
    "size_positive": rules_geometry.size_positive,
    "limb_length": rules_geometry.limb_length,
    "subtreemass_consistent": rules_mass.subtreemass_consistent,
}


def _view(data: RobotTree, fs: FeatureSet) -> GraphView:
    if "link" not in fs.node_types or "joint" not in fs.node_types:
        raise ValueError(f"rules need a robot feature set (link and joint nodes), not {fs.name}")
    if data.x.shape[1] != fs.dim:
        raise ValueError(f"data has {data.x.shape[1]} columns, {fs.name} has {fs.dim}")
    return GraphView(data, fs)


def _changed(before: np.ndarray, after: np.ndarray) -> bool:
    """True when float32 values differ (NaN compared equal to NaN)."""
    b, a = before.astype(np.float32), after.astype(np.float32)
    return bool(np.any((a != b) & ~(np.isnan(a) & np.isnan(b))))


def _make_rule(name: str, impl: Callable[[GraphView], None]) -> Rule:
    def rule(data: RobotTree, feature_set: str | FeatureSet = "paper34"
             ) -> tuple[RobotTree, bool]:
        v = _view(data, as_feature_set(feature_set))
        before = v.x.copy()
        impl(v)
        return v.to_data(data), _changed(before, v.x)

    rule.__name__ = rule.__qualname__ = name
    rule.__doc__ = (f"Rule ``{name}`` (see :mod:`{impl.__module__}`): returns the repaired "
                    f"copy of ``data`` and whether anything changed. Rules other than "
                    f"``finite`` expect finite values.")
    return rule


#: The rules, in the order :func:`apply_rules` runs them.
RULES: dict[str, Rule] = {name: _make_rule(name, impl) for name, impl in _IMPL.items()}

#: Not a rule (a slide without limits is valid) but a fix of decoded graphs
#: (:mod:`robovae.generate.fixes`): every unlimited slide joint off the trunk gets the range
#: ``±SLIDE_STROKE`` (:func:`robovae.generate.rules_joints.slide_limited`; sets without
#: ``joint.type`` have no slides). ``(data, feature_set) -> (repaired copy, changed)``;
#: raises ``ValueError`` as :func:`apply_rules`.
slide_limited: Rule = _make_rule("slide_limited", rules_joints.slide_limited)
slide_limited.__doc__ = ("Fix ``slide_limited`` (see :mod:`robovae.generate.rules_joints`; not "
                         "one of :data:`RULES`): returns the repaired copy of ``data`` and "
                         "whether anything changed.")


def apply_rules(data: RobotTree, feature_set: str | FeatureSet = "paper34"
                ) -> tuple[RobotTree, list[str]]:
    """Run every rule of :data:`RULES` in order on a graph in physical units.

    Args:
        data: a robot graph (``x`` in physical units, see :mod:`robovae.data.graph`).
        feature_set: the registry set ``data.x`` follows.

    Returns:
        A repaired copy (``data`` itself is not modified) and the names of the rules that
        changed something, in rule order.

    Raises:
        ValueError: the feature set has no link or joint nodes, or ``data.x`` has another width.
    """
    v = _view(data, as_feature_set(feature_set))
    fired = []
    for name, impl in _IMPL.items():
        before = v.x.copy()
        impl(v)
        if _changed(before, v.x):
            fired.append(name)
    return v.to_data(data), fired


def check_rules(data: RobotTree, feature_set: str | FeatureSet = "paper34") -> list[str]:
    """Names of the rules that would change ``data`` (nothing is modified)."""
    return apply_rules(data, feature_set)[1]


def floating_base(data: RobotTree, feature_set: str | FeatureSet = "paper34"
                  ) -> tuple[RobotTree, bool]:
    """Give a robot a floating base: when the root node is a joint that is the only joint above
    the root link (:func:`~robovae.generate.bodies.free_root_allowed`), set its features to
    those MuJoCo gives a free joint — range ``(0, 0)``, axis ``+z``, position 0, no damping,
    armature, friction, stiffness, limit flag, actuation, gear or control range — and, in sets
    with ``joint.type``, its type to ``free``. Otherwise ``data`` is returned unchanged.

    ``paper34`` has no joint type: :func:`~robovae.generate.bodies.joint_types` calls a root
    joint free only when its features look like a free joint's, which this ensures.

    Returns:
        ``(data, changed)``: a repaired copy (or ``data`` itself) and whether a value changed.

    Raises:
        ValueError: as :func:`apply_rules`.
    """
    v = _view(data, as_feature_set(feature_set))
    if not free_root_allowed(v.parent, v.types):
        return data, False
    before = v.x.copy()
    if v.has("joint.type"):
        v.set(0, "joint.type", np.eye(len(JOINT_TYPES))[JOINT_TYPES.index("free")])
    v.set(0, "joint.range", 0.0)
    v.set(0, "joint.axis", [0.0, 0.0, 1.0])
    for key in ("joint.pos", *rules_joints.DYNAMICS, "joint.limited", "joint.actuated",
                "joint.gear", "joint.ctrlrange"):
        if key.startswith("joint.") and v.has(key):
            v.set(0, key, 0.0)
    return v.to_data(data), _changed(before, v.x)
