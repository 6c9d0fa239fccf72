"""Physical-constraint rules for decoded robot graphs (paper §6.1, SPEC §7).

A decoded graph carries continuous features that may be slightly (or wildly) outside what MuJoCo
accepts. Each rule below is a named function ``rule(data, feature_set) -> (repaired copy, fired)``
working on **physical** values (after :meth:`robovae.data.features.Normalizer.inverse`); it only
changes values that violate its constraint and says whether it changed anything ("fired").
:func:`apply_rules` runs them all, in the order of :data:`RULES`, and returns the repaired graph
and the names of the rules that fired.

Real robots that MuJoCo compiles pass every rule unchanged (tested on the zoo and the Menagerie
robots): thresholds sit below the smallest value found in that data, and "valid" means what MuJoCo
itself requires, not a stylistic preference.

Rules (in order):

``finite``
    NaN/±Inf in a node's own columns → a safe default: identity for quaternions, ``(0, 0, 1)`` for
    joint axes, 0 elsewhere (later rules then raise masses, sizes, ... to their minimum).
``one_hot`` (sets with categorical columns)
    one-hot columns (``joint.type``, ``geom.type``) → exact one-hot of their arg-max; flags
    (``joint.limited``, ``joint.actuated``, ``geom.collides``) → 0/1 at the 0.5 threshold.
``joint_type_valid`` (sets with ``joint.type``)
    MuJoCo allows a free joint only in a top-level body, alone in it: a free joint anywhere but
    the tree root (when it is the only joint of the bodies it leads to) becomes a hinge.
    MuJoCo also rejects a rotation (hinge or ball) after a ball joint in the same body: such a
    ball becomes a hinge.
``in_range``
    every non-categorical column is clipped to its registry range ``[low, high]`` (unit
    quaternions and axes are left to ``unit_quat``/``axis_unit``, which normalise instead, and
    the derived ``link.subtreemass`` to ``subtreemass_consistent``).
``unit_quat``
    ``link.quat``, ``link.iquat``, ``geom.quat``: norm off by more than :data:`UNIT_TOL` →
    normalised; (near) zero → identity.
``axis_unit``
    ``joint.axis`` likewise; (near) zero → ``(0, 0, 1)``.
``range_ordered``
    joint ranges: a range counts as "unlimited" when ``max(|lo|, |hi|)`` < :data:`RANGE_ZERO`
    (decoder noise around the ``(0, 0)`` the reader stores for unlimited joints) or, in sets
    with a ``limited`` flag (``full``), when the flag is 0; it is then set to exactly ``(0, 0)``
    (and the flag to 0). In ``paper34`` every other range is limited. Limited ranges are
    ordered (swapped when ``lo > hi``), clipped to ``[-2π, 2π]`` for hinges (MuJoCo accepts more,
    but a wider hinge range is meaningless; the widest in the data is 4.54 rad), ``[0, π]`` with
    ``lo = 0`` for ball joints (MuJoCo requires ``range[0] = 0``), the registry range for slides,
    and widened about their middle to at least :data:`MIN_RANGE_WIDTH` ``· max(1, |lo|, |hi|)``
    (MuJoCo needs ``lo < hi``, also after the 6 significant digits MJCF keeps). Free joints get
    no range. Actuator control ranges (``joint.ctrlrange``) follow the same zero/order/width rules
    (and are zero for joints whose ``actuated`` flag is 0).
``nonnegative_dynamics``
    ``joint.damping``, ``armature``, ``frictionloss``, ``stiffness`` and ``geom.friction`` ≥ 0.
``mass_positive``
    masses ≥ 0; a *moving* link (one with a joint between it and its parent link) must weigh at
    least :data:`MIN_MASS` (MuJoCo rejects moving bodies lighter than ``mjMINVAL``): lighter ones
    are raised to ``max(MIN_MASS, 1e-3 · median positive link mass)`` (:data:`DEFAULT_MASS` when
    no link has mass).
``inertia_positive``
    inertia components ≥ 0; for moving links each component ≥ ``max(MIN_INERTIA,
    INERTIA_RATIO · largest)`` (MuJoCo rejects moving bodies without inertia, and MJCF output
    rounds components 12 decades below the largest to 0): smaller ones are raised to that
    floor; a moving link with no inertia at all gets that of a solid sphere, ``0.4 · m · r²``
    with ``r`` its largest size (else :data:`DEFAULT_GEOM_RADIUS`).
``inertia_triangle``
    principal inertias satisfy ``a + b ≥ c`` for every permutation (MuJoCo checks this exactly):
    with ``a ≤ b ≤ c`` and ``a + b < c``, the two smaller components are raised — ``a`` first up
    to ``b``, then both equally — until ``a + b = c · (1 + 1e-4)`` (the margin survives float32
    and the XML's 6 significant digits). ``c`` is never lowered.
``size_positive``
    ``link.size``: negative → 0; a zero component means "absent"; trailing components (2nd or
    3rd) below :data:`SIZE_ZERO` m or below :data:`SIZE_ZERO_RATIO` times the largest are
    absent too (a decoder's "zero" is ``exp(log eps) ≈ 1e-4``, not 0: read literally it turns a
    capsule into a sub-millimetre plate); positive components below :data:`MIN_SIZE` are
    raised to it, and a zero before a positive component is raised too (the
    writer reads the size as sphere ``(r)``, capsule ``(r, h)`` or box ``(x, y, z)``).
    ``geom.size``: the components the primitive uses (sphere 1, capsule/cylinder 2,
    ellipsoid/box 3) ≥ :data:`MIN_SIZE`, the unused ones ≥ 0.
``limb_length``
    conservative degenerate-limb check: a *limb* is a subtree hanging off the trunk link (the
    root link, below any root joints) that holds at least one joint; it is degenerate when
    **every** link in it sits at its parent's origin with its centre of mass there too
    (``|pos|`` and ``|ipos| <`` :data:`MIN_LIMB_OFFSET`), i.e. the whole limb, bodies and
    masses, collapses into one point inside the trunk. Its links are then spread out:
    the first one radially in the trunk's x-y plane (limb ``k`` of ``K`` at angle ``2πk/K``, at
    the trunk's largest size or :data:`DEFAULT_LIMB_SEGMENT`), each further one straight down by
    twice its parent's largest size (or :data:`DEFAULT_LIMB_SEGMENT`). Real robots often have
    single links at their parent's origin (URDF dummy links); no real robot has a whole limb
    collapsed, so this never fires on them.
``subtreemass_consistent``
    ``link.subtreemass`` is derived: recomputed from the masses (link plus all descendant links)
    when it is off by more than a relative 1e-5.

:func:`joint_types` infers each joint node's MuJoCo type (``free``/``ball``/``slide``/``hinge``)
for the writer and the range rule: from the one-hot when the set has ``joint.type``; otherwise
(``paper34``) the tree's root joint is ``free`` when it is the only joint above the root link,
unlimited and its axis points along +z within 25° (MuJoCo compiles every free joint to axis
``(0, 0, 1)``, position 0 and no range, so a real free joint always looks like that, while e.g.
the dm_control jumping ball's root hinge turns about -z), and every other joint is a ``hinge``
(``paper34`` cannot tell slides or balls from hinges; their features are the same).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch

from robovae.data.features import (
    GEOM,
    GEOM_TYPES,
    JOINT,
    JOINT_TYPES,
    LINK,
    Feature,
    FeatureSet,
    get_feature_set,
)
from robovae.data.graph import RobotData, children

__all__ = [
    "DEFAULT_GEOM_RADIUS",
    "DEFAULT_LIMB_SEGMENT",
    "DEFAULT_MASS",
    "GEOM_SIZE_COMPONENTS",
    "HINGE_LIMIT",
    "INERTIA_RATIO",
    "MIN_INERTIA",
    "MIN_LIMB_OFFSET",
    "MIN_MASS",
    "MIN_RANGE_WIDTH",
    "MIN_SIZE",
    "RANGE_ZERO",
    "RULES",
    "UNIT_TOL",
    "apply_rules",
    "check_rules",
    "joint_types",
    "link_structure",
]

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
#: Smallest positive geom size component (m); the smallest real one is 1.7e-4 m.
MIN_SIZE = 1e-5
#: A trailing ``link.size`` component below this (m) is absent; real models use >= 1e-3.
SIZE_ZERO = 5e-4
#: ... or below this fraction of the largest component (real boxes: >= 0.05).
SIZE_ZERO_RATIO = 0.02
#: Radius of the sphere the writer gives a link without size (m); also the radius used to
#: derive a missing inertia.
DEFAULT_GEOM_RADIUS = 0.02
#: ``max(|lo|, |hi|)`` below this is an unlimited range (rad or m) where no ``limited`` flag
#: exists; every real limited joint or control range reaches at least 5e-3.
RANGE_ZERO = 1e-3
#: Narrowest limited range, relative to ``max(1, |lo|, |hi|)``.
MIN_RANGE_WIDTH = 1e-4
#: Widest hinge range end (rad).
HINGE_LIMIT = 2.0 * math.pi
#: Tolerance on the norm of unit quaternions and axes.
UNIT_TOL = 1e-4
#: A limb whose links all sit closer than this to their parent's origin is degenerate (m).
MIN_LIMB_OFFSET = 1e-4
#: Segment length used to spread a degenerate limb when no size says better (m).
DEFAULT_LIMB_SEGMENT = 0.1
#: Relative margin by which a repaired inertia exceeds the triangle inequality.
TRIANGLE_MARGIN = 1e-4
#: Cosine of the largest angle between a ``paper34`` root joint axis and +z for a free joint.
FREE_AXIS_COS = math.cos(math.radians(25.0))

_QUATS = ("link.quat", "link.iquat", "geom.quat")
_UNIT = (*_QUATS, "joint.axis")
_ONE_HOT = ("joint.type", "geom.type")
_FLAGS = ("joint.limited", "joint.actuated", "geom.collides")
_DYNAMICS = ("joint.damping", "joint.armature", "joint.frictionloss", "joint.stiffness",
             "geom.friction")
#: Size components each geom primitive uses (MuJoCo convention; MJCF output writes no others).
GEOM_SIZE_COMPONENTS = {"sphere": 1, "capsule": 2, "cylinder": 2, "ellipsoid": 3, "box": 3}

Rule = Callable[[RobotData, "str | FeatureSet"], tuple[RobotData, bool]]


# --- a mutable float64 view of a graph -------------------------------------------------------


class _View:
    """Float64 copy of ``x`` plus the tree, with feature accessors by registry key."""

    def __init__(self, data: RobotData, fs: FeatureSet) -> None:
        self.fs = fs
        self.x = data.x.detach().cpu().double().numpy().copy()
        self.types = data.node_type.tolist()
        self.parent = data.parent.tolist()
        self.kids = children(self.parent)
        self.mask = fs.mask(data.node_type).numpy()
        self.keys = {f.key for f in fs.features}

    def has(self, key: str) -> bool:
        return key in self.keys

    def nodes(self, node_type: int) -> list[int]:
        return [i for i, t in enumerate(self.types) if t == node_type]

    def get(self, i: int, key: str) -> np.ndarray:
        return self.x[i, self.fs.slice(key)]

    def set(self, i: int, key: str, value) -> None:
        self.x[i, self.fs.slice(key)] = value

    def to_data(self, data: RobotData) -> RobotData:
        out = data.clone()
        x = torch.from_numpy(self.x).to(torch.float32)
        out.x = torch.where(torch.from_numpy(self.mask), x, torch.zeros((), dtype=torch.float32))
        return out


def _registry(v: _View, key: str) -> Feature:
    return next(f for f in v.fs.features if f.key == key)


def _fs(feature_set: str | FeatureSet) -> FeatureSet:
    return get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set


# --- tree helpers shared with the writer ------------------------------------------------------


def link_structure(parent: list[int], types: list[int]) -> tuple[list[int], list[list[int]]]:
    """For every node, its nearest ancestor link (``-1`` if none) and, for links, the joint nodes
    on the path from that ancestor (top-down): the joints MuJoCo puts in the link's body.

    Geom nodes are transparent (a joint below a geom still belongs to the path).
    """
    n = len(parent)
    anc = [-1] * n
    chain: list[list[int]] = [[] for _ in range(n)]
    pending: list[list[int]] = [[] for _ in range(n)]  # joints above node i, since its anc link
    for i in range(n):  # pre-order: parents come first
        p = parent[i]
        if p >= 0:
            anc[i] = p if types[p] == LINK else anc[p]
            above = [] if types[p] == LINK else pending[p]
        else:
            above = []
        if types[i] == LINK:
            chain[i] = list(above)
        elif types[i] == JOINT:
            pending[i] = [*above, i]
        else:
            pending[i] = list(above)
    return anc, chain


def _moving_links(v: _View) -> list[int]:
    _, chain = link_structure(v.parent, v.types)
    return [i for i in v.nodes(LINK) if chain[i]]


def _free_root_allowed(parent: list[int], types: list[int]) -> bool:
    """Node 0 is a joint and the only joint of every link body it leads to."""
    if types[0] != JOINT:
        return False
    _, chain = link_structure(parent, types)
    return all(len(c) == 1 for c in chain if c and c[0] == 0)


def joint_types(data: RobotData, feature_set: str | FeatureSet) -> list[str]:
    """MuJoCo joint type name of every node (``""`` for non-joint nodes).

    From the ``joint.type`` one-hot when the set has it, else inferred (module docstring).
    """
    return _joint_types(_View(data, _fs(feature_set)))


def _joint_types(v: _View) -> list[str]:
    out = [""] * len(v.types)
    if v.has("joint.type"):
        for i in v.nodes(JOINT):
            onehot = np.nan_to_num(v.get(i, "joint.type"), nan=-np.inf)
            out[i] = JOINT_TYPES[int(np.argmax(onehot))]
        return out
    for i in v.nodes(JOINT):
        out[i] = "hinge"
    if _free_root_allowed(v.parent, v.types):
        rng = v.get(0, "joint.range")
        axis = v.get(0, "joint.axis")
        norm = float(np.linalg.norm(axis))
        unlimited = bool(np.all(np.abs(rng) < RANGE_ZERO))  # decoded zeros are not exact
        if unlimited and norm > 0 and axis[2] / norm >= FREE_AXIS_COS:
            out[0] = "free"
    return out


# --- rule implementations (mutate a _View) ----------------------------------------------------


def _finite(v: _View) -> None:
    bad = ~np.isfinite(v.x) & v.mask
    if not bad.any():
        return
    for key in _UNIT:
        if not v.has(key):
            continue
        sl = v.fs.slice(key)
        rows = np.nonzero(bad[:, sl].any(1))[0]
        default = [0.0, 0.0, 1.0] if key == "joint.axis" else [1.0, 0.0, 0.0, 0.0]
        for i in rows:
            v.x[i, sl] = default
            bad[i, sl] = False
    v.x[bad] = 0.0


def _one_hot(v: _View) -> None:
    for key in _ONE_HOT:
        if not v.has(key):
            continue
        owner = JOINT if key.startswith("joint.") else GEOM
        for i in v.nodes(owner):
            oh = v.get(i, key)
            snapped = np.zeros_like(oh)
            snapped[int(np.argmax(oh))] = 1.0
            v.set(i, key, snapped)
    for key in _FLAGS:
        if not v.has(key):
            continue
        owner = JOINT if key.startswith("joint.") else GEOM
        for i in v.nodes(owner):
            v.set(i, key, 1.0 if v.get(i, key)[0] >= 0.5 else 0.0)


def _joint_type_valid(v: _View) -> None:
    if not v.has("joint.type"):
        return
    types = _joint_types(v)
    free_ok = _free_root_allowed(v.parent, v.types)
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


def _in_range(v: _View) -> None:
    for f in v.fs.features:
        if f.transform == "categorical" or f.key in _UNIT or f.key == "link.subtreemass":
            continue
        sl = v.fs.slice(f.key)
        rows = v.mask[:, sl.start]
        v.x[rows, sl] = np.clip(v.x[rows, sl], f.low, f.high)


def _unit(vec: np.ndarray, default: list[float]) -> np.ndarray | None:
    """The repaired vector, or None when it is already unit within tolerance."""
    n = float(np.linalg.norm(vec))
    if n < 1e-9:
        return np.asarray(default, dtype=float)
    if abs(n - 1.0) > UNIT_TOL:
        return vec / n
    return None


def _unit_quat(v: _View) -> None:
    for key in _QUATS:
        if not v.has(key):
            continue
        owner = GEOM if key.startswith("geom.") else LINK
        for i in v.nodes(owner):
            q = _unit(v.get(i, key), [1.0, 0.0, 0.0, 0.0])
            if q is not None:
                v.set(i, key, q)


def _axis_unit(v: _View) -> None:
    for i in v.nodes(JOINT):
        a = _unit(v.get(i, "joint.axis"), [0.0, 0.0, 1.0])
        if a is not None:
            v.set(i, "joint.axis", a)


def _ceil32(v: float) -> float:
    """The smallest float32 value ≥ ``v`` (so a raised value still passes after storage)."""
    f = np.float32(v)
    return float(f if float(f) >= v else np.nextafter(f, np.float32(np.inf)))


def _floor32(v: float) -> float:
    """The largest float32 value ≤ ``v``."""
    f = np.float32(v)
    return float(f if float(f) <= v else np.nextafter(f, np.float32(-np.inf)))


def _fix_range(lo: float, hi: float, low: float, high: float) -> tuple[float, float]:
    """Order, clip to ``[low, high]`` and widen a limited range to the minimum width."""
    low, high = _ceil32(low), _floor32(high)
    if lo > hi:
        lo, hi = hi, lo
    lo, hi = min(max(lo, low), high), min(max(hi, low), high)
    width = MIN_RANGE_WIDTH * max(1.0, abs(lo), abs(hi))
    if hi - lo < (1.0 - 1e-3) * width:  # tolerance: float32 storage rounds the ends
        mid = min(max(0.5 * (lo + hi), low + 0.5 * width), high - 0.5 * width)
        lo, hi = mid - 0.5 * width, mid + 0.5 * width
    return lo, hi


def _range_ordered(v: _View) -> None:
    has_flag = v.has("joint.limited")
    reg = _registry(v, "joint.range")
    if not has_flag:  # paper34: near-zero ranges mean "unlimited"
        for i in v.nodes(JOINT):
            if np.abs(v.get(i, "joint.range")).max() < RANGE_ZERO:
                v.set(i, "joint.range", 0.0)
    types = _joint_types(v)
    for i in v.nodes(JOINT):
        lo, hi = (float(a) for a in v.get(i, "joint.range"))
        limited = (v.get(i, "joint.limited")[0] >= 0.5) if has_flag else (lo != 0 or hi != 0)
        if has_flag and limited and max(abs(lo), abs(hi)) < RANGE_ZERO:
            limited = False
        if types[i] == "free":
            limited = False
        if not limited:
            v.set(i, "joint.range", 0.0)
            if has_flag:
                v.set(i, "joint.limited", 0.0)
            continue
        if types[i] == "ball":
            lo, hi = 0.0, min(max(abs(lo), abs(hi)), _floor32(math.pi))
            hi = max(hi, _ceil32(MIN_RANGE_WIDTH))
        elif types[i] == "slide":
            lo, hi = _fix_range(lo, hi, reg.low, reg.high)
        else:
            lo, hi = _fix_range(lo, hi, -HINGE_LIMIT, HINGE_LIMIT)
        v.set(i, "joint.range", [lo, hi])
    if v.has("joint.ctrlrange"):
        creg = _registry(v, "joint.ctrlrange")
        actuated = v.has("joint.actuated")
        for i in v.nodes(JOINT):
            lo, hi = (float(a) for a in v.get(i, "joint.ctrlrange"))
            if (actuated and v.get(i, "joint.actuated")[0] < 0.5) or \
                    max(abs(lo), abs(hi)) < RANGE_ZERO:
                v.set(i, "joint.ctrlrange", 0.0)
            else:
                v.set(i, "joint.ctrlrange", _fix_range(lo, hi, creg.low, creg.high))


def _nonnegative_dynamics(v: _View) -> None:
    for key in _DYNAMICS:
        if not v.has(key):
            continue
        sl = v.fs.slice(key)
        rows = v.mask[:, sl.start]
        v.x[rows, sl] = np.maximum(v.x[rows, sl], 0.0)


def _mass_positive(v: _View) -> None:
    links = v.nodes(LINK)
    if not links:
        return
    sl = v.fs.slice("link.mass")
    v.x[links, sl] = np.maximum(v.x[links, sl], 0.0)
    masses = v.x[links, sl.start]
    positive = masses[masses > 0]
    floor = max(MIN_MASS, 1e-3 * float(np.median(positive))) if positive.size else DEFAULT_MASS
    floor = _ceil32(floor)
    for i in _moving_links(v):
        if v.x[i, sl.start] < MIN_MASS:
            v.x[i, sl.start] = floor


def _inertia_positive(v: _View) -> None:
    links = v.nodes(LINK)
    if not links:
        return
    sl = v.fs.slice("link.inertia")
    v.x[links, sl] = np.maximum(v.x[links, sl], 0.0)
    for i in _moving_links(v):
        inertia = v.get(i, "link.inertia")
        floor = _ceil32(max(MIN_INERTIA, INERTIA_RATIO * float(inertia.max())))
        if inertia.min() >= floor:
            continue
        if inertia.max() >= MIN_INERTIA:  # anisotropic: raise the small components
            v.set(i, "link.inertia", np.maximum(inertia, floor))
            continue
        size = float(v.get(i, "link.size").max()) if v.has("link.size") else 0.0
        r = size if size > 0 else DEFAULT_GEOM_RADIUS  # no inertia at all: a solid sphere
        sphere = 0.4 * float(v.get(i, "link.mass")[0]) * r * r
        sphere = min(sphere, _registry(v, "link.inertia").high)
        v.set(i, "link.inertia", _ceil32(max(MIN_INERTIA, sphere)))


def _triangle(inertia: np.ndarray) -> np.ndarray | None:
    """Repaired principal inertias, or None when ``a + b >= c`` holds for all permutations."""
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


def _inertia_triangle(v: _View) -> None:
    for i in v.nodes(LINK):
        fixed = _triangle(v.get(i, "link.inertia"))
        if fixed is not None:
            v.set(i, "link.inertia", fixed)


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
        s[: last + 1] = np.maximum(s[: last + 1], _ceil32(MIN_SIZE))
    return s


def _size_positive(v: _View) -> None:
    if v.has("link.size"):
        for i in v.nodes(LINK):
            v.set(i, "link.size", _size_prefix(v.get(i, "link.size")))
    if v.has("geom.size"):
        for i in v.nodes(GEOM):
            s = np.maximum(v.get(i, "geom.size"), 0.0)
            gtype = GEOM_TYPES[int(np.argmax(v.get(i, "geom.type")))] if v.has("geom.type") \
                else "box"
            n = GEOM_SIZE_COMPONENTS[gtype]
            s[:n] = np.maximum(s[:n], _ceil32(MIN_SIZE))
            v.set(i, "geom.size", s)


def _trunk(types: list[int], kids: list[list[int]]) -> int:
    """The first link reached from the root through joints (the trunk), or -1."""
    i = 0
    while types[i] != LINK:
        nxt = [c for c in kids[i] if types[c] != GEOM]
        if not nxt:
            return -1
        i = nxt[0]
    return i


def _subtree(kids: list[list[int]], i: int) -> list[int]:
    out, stack = [], [i]
    while stack:
        n = stack.pop()
        out.append(n)
        stack.extend(reversed(kids[n]))
    return out


def _largest_size(v: _View, i: int) -> float:
    return float(v.get(i, "link.size").max()) if v.has("link.size") else 0.0


def _limb_length(v: _View) -> None:
    if not v.nodes(LINK):
        return
    trunk = _trunk(v.types, v.kids)
    if trunk < 0:
        return
    limbs = []
    for c in v.kids[trunk]:
        nodes = _subtree(v.kids, c)
        links = [n for n in nodes if v.types[n] == LINK]
        if links and any(v.types[n] == JOINT for n in nodes):
            limbs.append(links)
    anc, _ = link_structure(v.parent, v.types)
    cap = _registry(v, "link.pos").high
    for k, links in enumerate(limbs):
        extent = max(max(float(np.linalg.norm(v.get(i, "link.pos"))),
                         float(np.linalg.norm(v.get(i, "link.ipos")))) for i in links)
        if extent >= MIN_LIMB_OFFSET:
            continue
        angle = 2.0 * math.pi * k / len(limbs)
        for i in links:
            if anc[i] == trunk:
                reach = min(_largest_size(v, trunk) or DEFAULT_LIMB_SEGMENT, cap)
                v.set(i, "link.pos", [reach * math.cos(angle), reach * math.sin(angle), 0.0])
            else:
                reach = min(2.0 * _largest_size(v, anc[i]) or DEFAULT_LIMB_SEGMENT, cap)
                v.set(i, "link.pos", [0.0, 0.0, -reach])


def _subtreemass_consistent(v: _View) -> None:
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


_IMPL: dict[str, Callable[[_View], None]] = {
    "finite": _finite,
    "one_hot": _one_hot,
    "joint_type_valid": _joint_type_valid,
    "in_range": _in_range,
    "unit_quat": _unit_quat,
    "axis_unit": _axis_unit,
    "range_ordered": _range_ordered,
    "nonnegative_dynamics": _nonnegative_dynamics,
    "mass_positive": _mass_positive,
    "inertia_positive": _inertia_positive,
    "inertia_triangle": _inertia_triangle,
    "size_positive": _size_positive,
    "limb_length": _limb_length,
    "subtreemass_consistent": _subtreemass_consistent,
}


def _check(data: RobotData, fs: FeatureSet) -> RobotData:
    if "link" not in fs.node_types or "joint" not in fs.node_types:
        raise ValueError(f"rules need a robot feature set (link and joint nodes), not {fs.name}")
    if data.x.shape[1] != fs.dim:
        raise ValueError(f"data has {data.x.shape[1]} columns, {fs.name} has {fs.dim}")
    return data


def _changed(before: np.ndarray, after: np.ndarray) -> bool:
    """True when float32 values differ (NaN compared equal to NaN)."""
    b, a = before.astype(np.float32), after.astype(np.float32)
    return bool(np.any((a != b) & ~(np.isnan(a) & np.isnan(b))))


def _make_rule(name: str) -> Rule:
    impl = _IMPL[name]

    def rule(data: RobotData, feature_set: str | FeatureSet = "paper34"
             ) -> tuple[RobotData, bool]:
        v = _View(_check(data, _fs(feature_set)), _fs(feature_set))
        before = v.x.copy()
        impl(v)
        return v.to_data(data), _changed(before, v.x)

    rule.__name__ = rule.__qualname__ = name
    rule.__doc__ = (f"Rule ``{name}`` (see :mod:`robovae.generate.rules`): returns the repaired "
                    f"copy of ``data`` and whether anything changed. Rules other than "
                    f"``finite`` expect finite values.")
    return rule


finite = _make_rule("finite")
one_hot = _make_rule("one_hot")
joint_type_valid = _make_rule("joint_type_valid")
in_range = _make_rule("in_range")
unit_quat = _make_rule("unit_quat")
axis_unit = _make_rule("axis_unit")
range_ordered = _make_rule("range_ordered")
nonnegative_dynamics = _make_rule("nonnegative_dynamics")
mass_positive = _make_rule("mass_positive")
inertia_positive = _make_rule("inertia_positive")
inertia_triangle = _make_rule("inertia_triangle")
size_positive = _make_rule("size_positive")
limb_length = _make_rule("limb_length")
subtreemass_consistent = _make_rule("subtreemass_consistent")

#: The rules, in the order :func:`apply_rules` runs them.
RULES: dict[str, Rule] = {
    "finite": finite,
    "one_hot": one_hot,
    "joint_type_valid": joint_type_valid,
    "in_range": in_range,
    "unit_quat": unit_quat,
    "axis_unit": axis_unit,
    "range_ordered": range_ordered,
    "nonnegative_dynamics": nonnegative_dynamics,
    "mass_positive": mass_positive,
    "inertia_positive": inertia_positive,
    "inertia_triangle": inertia_triangle,
    "size_positive": size_positive,
    "limb_length": limb_length,
    "subtreemass_consistent": subtreemass_consistent,
}


def apply_rules(data: RobotData, feature_set: str | FeatureSet = "paper34"
                ) -> tuple[RobotData, list[str]]:
    """Run every rule of :data:`RULES` in order on a graph in physical units.

    Args:
        data: a robot graph (``x`` in physical units, see :mod:`robovae.data.graph`).
        feature_set: the registry set ``data.x`` follows.

    Returns:
        A repaired copy (``data`` itself is not modified) and the names of the rules that
        changed something, in rule order.
    """
    fs = _fs(feature_set)
    v = _View(_check(data, fs), fs)
    fired = []
    for name, impl in _IMPL.items():
        before = v.x.copy()
        impl(v)
        if _changed(before, v.x):
            fired.append(name)
    return v.to_data(data), fired


def check_rules(data: RobotData, feature_set: str | FeatureSet = "paper34") -> list[str]:
    """Names of the rules that would change ``data`` (nothing is modified)."""
    return apply_rules(data, feature_set)[1]


def floating_base(data: RobotData, feature_set: str | FeatureSet = "paper34"
                  ) -> tuple[RobotData, bool]:
    """Give a generated robot a floating base: when the root node is a joint that is the only
    joint above the root link, set its features to those MuJoCo gives a free joint (range
    ``(0, 0)``, axis ``+z``, position 0, no damping/armature/friction/stiffness) — or, in sets
    with ``joint.type``, its type to ``free``.

    Not a physical rule (a hinge-anchored robot is a valid model): a generation choice.
    ``paper34`` has no joint type, so :func:`joint_types` calls a root joint free only when
    its features look exactly like a free joint's; a decoder's root features are rarely that
    exact, and without this every sampled robot would hang from a hinge in mid-air. Every
    training robot of the zoo whose root is a single joint is free-floating.

    Returns ``(data, changed)``.
    """
    fs = _fs(feature_set)
    v = _View(_check(data, fs), fs)
    if not _free_root_allowed(v.parent, v.types):
        return data, False
    before = v.x.copy()
    if v.has("joint.type"):
        v.set(0, "joint.type", np.eye(len(JOINT_TYPES))[JOINT_TYPES.index("free")])
    v.set(0, "joint.range", 0.0)
    v.set(0, "joint.axis", [0.0, 0.0, 1.0])
    for key in ("joint.pos", *_DYNAMICS, "joint.limited", "joint.actuated", "joint.gear",
                "joint.ctrlrange"):
        if key.startswith("joint.") and v.has(key):
            v.set(0, key, 0.0)
    return v.to_data(data), _changed(before, v.x)
