"""Repair rules on single values: finite numbers, exact categories, registry ranges, unit
vectors.

Each function repairs a :class:`~robovae.generate.graph_view.GraphView` in place (physical
units) and only changes values that break its constraint; :mod:`robovae.generate.rules` runs it
as the rule of the same name.

``finite``
    NaN/±Inf in a node's own columns → a safe default: identity ``(1, 0, 0, 0)`` for the
    quaternions, ``(0, 0, 1)`` for joint axes, 0 elsewhere (later rules then raise masses,
    sizes, ... to their minimum).
``one_hot`` (sets with categorical columns)
    one-hot columns (``joint.type``, ``geom.type``) → exact one-hot of their arg-max; flags
    (``joint.limited``, ``joint.actuated``, ``geom.collides``) → 0/1 at the 0.5 threshold.
``in_range``
    every non-categorical column is clipped to its registry range ``[low, high]``, except the
    unit quaternions and axes (left to ``unit_quat``/``axis_unit``, which normalise instead)
    and the derived ``link.subtreemass`` (left to ``subtreemass_consistent``).
``unit_quat``
    ``link.quat``, ``link.iquat``, ``geom.quat``: ``| |q| - 1 | >``
    :data:`UNIT_TOL` →
    ``q / |q|``; ``|q| < 1e-9`` → identity.
``axis_unit``
    ``joint.axis`` likewise; ``|a| < 1e-9`` → ``(0, 0, 1)``.

Rules other than ``finite`` expect finite values.
"""

from __future__ import annotations

import numpy as np

from robovae.data.features import GEOM, JOINT, LINK
from robovae.generate.graph_view import GraphView, norm

__all__ = ["QUATERNIONS", "UNIT_TOL", "UNIT_VECTORS", "axis_unit", "finite", "in_range",
           "one_hot", "unit_quat"]

#: Tolerance on the norm of unit quaternions and axes.
UNIT_TOL = 1e-4
#: Quaternion features (unit norm, identity ``(1, 0, 0, 0)`` by default).
QUATERNIONS = ("link.quat", "link.iquat", "geom.quat")
#: Every unit-vector feature: the quaternions and ``joint.axis``.
UNIT_VECTORS = (*QUATERNIONS, "joint.axis")
_ONE_HOT = ("joint.type", "geom.type")
_FLAGS = ("joint.limited", "joint.actuated", "geom.collides")


def _owner(key: str) -> int:
    return JOINT if key.startswith("joint.") else GEOM if key.startswith("geom.") else LINK


def finite(v: GraphView) -> None:
    """Replace NaN/±Inf in the nodes' own columns (module docstring)."""
    bad = ~np.isfinite(v.x) & v.mask
    if not bad.any():
        return
    for key in UNIT_VECTORS:
        if not v.has(key):
            continue
        sl = v.fs.slice(key)
        rows = np.nonzero(bad[:, sl].any(1))[0]
        default = [0.0, 0.0, 1.0] if key == "joint.axis" else [1.0, 0.0, 0.0, 0.0]
        for i in rows:
            v.x[i, sl] = default
            bad[i, sl] = False
    v.x[bad] = 0.0


def one_hot(v: GraphView) -> None:
    """Snap one-hot columns to their arg-max and flags to 0/1 (module docstring)."""
    for key in _ONE_HOT:
        if not v.has(key):
            continue
        for i in v.nodes(_owner(key)):
            oh = v.get(i, key)
            snapped = np.zeros_like(oh)
            snapped[int(np.argmax(oh))] = 1.0
            v.set(i, key, snapped)
    for key in _FLAGS:
        if not v.has(key):
            continue
        for i in v.nodes(_owner(key)):
            v.set(i, key, 1.0 if v.get(i, key)[0] >= 0.5 else 0.0)


def in_range(v: GraphView) -> None:
    """Clip every non-categorical column to its registry range (module docstring)."""
    for f in v.fs.features:
        if f.transform == "categorical" or f.key in UNIT_VECTORS or f.key == "link.subtreemass":
            continue
        sl = v.fs.slice(f.key)
        rows = v.mask[:, sl.start]
        v.x[rows, sl] = np.clip(v.x[rows, sl], f.low, f.high)


def _unit(vec: np.ndarray, default: list[float]) -> np.ndarray | None:
    """The repaired vector, or None when it is already unit within tolerance."""
    n = norm(vec)
    if n < 1e-9:
        return np.asarray(default, dtype=float)
    if abs(n - 1.0) > UNIT_TOL:
        return vec / n
    return None


def unit_quat(v: GraphView) -> None:
    """Normalise the quaternions (module docstring)."""
    for key in QUATERNIONS:
        if not v.has(key):
            continue
        for i in v.nodes(_owner(key)):
            q = _unit(v.get(i, key), [1.0, 0.0, 0.0, 0.0])
            if q is not None:
                v.set(i, key, q)


def axis_unit(v: GraphView) -> None:
    """Normalise the joint axes (module docstring)."""
    for i in v.nodes(JOINT):
        a = _unit(v.get(i, "joint.axis"), [0.0, 0.0, 1.0])
        if a is not None:
            v.set(i, "joint.axis", a)
