"""Paired limbs: measure the mirror symmetry of a robot graph, and mirror a decoded side.

The **limbs** of a robot are the subtrees hanging off its trunk link
(:func:`~robovae.generate.bodies.trunk`) that hold at least one joint. A limb's *attachment*
``p`` is the ``link.pos`` of its first link (trunk frame, m); its *lengths* and *masses* are
``|link.pos|`` and ``link.mass`` of its links in pre-order.

**Mirrored pair** (:func:`mirrored_pairs`): two limbs of the same topology (node types and tree,
in order) whose lengths and masses agree within :data:`MIRROR_TOL` (10 %: ``|a - b| ≤
0.1 max(|a|, |b|)``, plus 1 mm / 1 g for values near zero). A robot is **symmetric**
(:func:`is_symmetric`) when its limbs form at least one mirrored pair and at most one limb
(a head, a tail, an abdomen carrying the legs) is left unpaired.

**Mirroring** (:func:`mirror_limbs`, a generation choice reported as ``mirror_limbs``): two
limbs of the trunk are a *near-mirror* pair when their link counts differ by at most
``max(1,`` :data:`LINK_COUNT_TOL` ``· the larger)``, their total lengths and total masses differ
by a factor whose product is at most :data:`SIZE_RATIO` ``²``, and at least one of them lies off
the trunk's sagittal plane (MuJoCo's convention: x forward, y left; the reflection is
``M = diag(1, -1, 1)``; a limb with ``|p_y| ≤`` :data:`ATTACH_TOL` ``· |p|`` lies on it: a
head, a tail, the front and back legs of a planar robot, which are never paired). Candidate
pairs are scored by ``|M p_A - p_B| / max(|p_A|, |p_B|) + |log(L_A / L_B)| + |log(m_A / m_B)|``
and taken greedily, best first; each pair's *source* (the first in pre-order, unless only the
second lies off the plane) is kept and the other limb is replaced, at its place among the
trunk's children, by the source's mirror image: topology, lengths, masses and every other
feature, attached at ``M p_A``. The mirror image of a subtree conjugates every local
frame by ``M``: positions ``p → M p`` (``link.pos``, ``link.ipos``, ``joint.pos``),
orientations ``(w, v) → (w, -M v)`` (``link.quat``, ``link.iquat``), hinge/slide axes
``a → -M a`` (so that a joint range keeps its sign), everything else (masses, inertias, sizes,
ranges, dynamics) unchanged. Subtree masses above the limb are then made consistent by the
writer's rule ``subtreemass_consistent``.

**Completing pairs** (:func:`complete_pairs`, reported as ``complete_pairs``): in a robot with
at least one near-mirror pair, a limb off the sagittal plane that is in no pair, has the
topology of a paired limb and lies as far off the plane as those pairs (``|p_y| ≥``
:data:`STRAY_TOL` ``· min |p_y|``; a third leg on one side) or off their ring (``|p|`` not
within :data:`RING_TOL` of a paired limb's: a mobile base's lone caster) with room for its
mirror image (``2 |p_y| ≥`` :data:`CLEAR_TOL` times its length) gets its mirror image as a
new limb, attached at ``M p`` right after it. The training robots pair their limbs
off the plane (0 of 1,000 procedural robots changed); no zoo or Menagerie robot is changed.

**Branches below the trunk** (:func:`mirror_branches`, reported as ``mirror_branches``): the
same mirroring for the children of a link below the trunk (a chest's arms, a mobile base's
column with two arms), across the trunk's sagittal plane as that link's frame sees it, for
pairs whose attachments lie on both sides of the plane (a hand's fingers never). A decoded
humanoid's arms hang off its chest, not off the trunk, and came out unequal: one leaning
clear of the hips, the other through them (docs/generation.md).

**Twins on the plane** (:func:`twin_limbs`, reported as ``twin_limbs``): two limbs that both lie
on the sagittal plane, of the same topology, not already a mirrored pair, whose total lengths
and masses differ by a factor whose product is at most :data:`SIZE_RATIO` ``²`` (a front and a
back caster, two legs of a planar walker) are made equal: the second in pre-order becomes a copy
of the first, every feature but its attachment (the first link's ``link.pos``), which stays its
own. Such limbs are equal in the training robots: 301 groups of 301 in 2,000 procedural robots
of the corpus (the casters of mobile manipulators, chiefly), 12 of 14 in the zoo and Menagerie
(dm_control's cheetah and Gymnasium's half-cheetah run on unequal legs); a decoded base whose
casters differ is a decoding error, not a design.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from robovae.data.box_axes import mirror_axes, quat_rotations
from robovae.data.features import JOINT, LINK, FeatureSet
from robovae.data.graph import tree_data
from robovae.data.tree_arrays import RobotTree, TreeArrays
from robovae.generate.bodies import subtree, trunk
from robovae.generate.graph_view import GraphView, as_feature_set, node_mask, norm

__all__ = ["ATTACH_TOL", "CLEAR_TOL", "MIRROR_TOL", "RING_TOL", "STRAY_TOL", "complete_pairs",
           "is_symmetric", "limbs", "mirror_branches", "mirror_limbs", "mirrored_pairs",
           "twin_limbs"]

#: Relative tolerance on lengths and masses of a mirrored pair.
MIRROR_TOL = 0.10
#: A limb whose attachment has ``|p_y| ≤ ATTACH_TOL |p|`` lies on the sagittal plane.
ATTACH_TOL = 0.25
#: A stray limb (:func:`complete_pairs`) lies as far off the sagittal plane as the pairs of its
#: topology: ``|p_y| ≥ STRAY_TOL · min |p_y|`` over them. Radial robots of the training corpus
#: with an odd leg count, rotated so that one leg sits 15–26° off the plane, keep their legs
#: (that leg is nearer the plane than the pairs'; by ``ATTACH_TOL`` alone 3 of 400 would have
#: been given a sixth or fourth leg).
STRAY_TOL = 0.9
#: ... or it is attached off their ring: ``| |p| - |p'| | > RING_TOL · max(|p|, |p'|)`` for
#: every paired limb ``p'`` of its topology. A radial robot's legs share one ring round the
#: trunk; a mobile base's lone caster sits nearer than its drive wheels' pair, or its caster
#: pairs', whichever the decoder gave it the topology of.
RING_TOL = 0.1
#: ... and, off the ring, its mirror image lies clear of it: ``2 |p_y| ≥ CLEAR_TOL · L``,
#: ``L`` the limb's length (the sum of its links' ``|link.pos|``). A tripod's odd leg near the
#: plane (decoded off its pair's ring) would get a twin beside it, the two legs through each
#: other. Of the strays off the ring in 10,000 samples, 35 of the 39 of robots whose limbs all
#: share one topology lie below 0.3, 6 of the other 177.
CLEAR_TOL = 0.3
#: Largest ratio of total lengths times total masses of a near-mirror pair.
SIZE_RATIO = 2.0
#: Largest difference in link count (fraction of the larger limb, at least 1) of a near-mirror
#: pair for :func:`mirror_limbs`.
LINK_COUNT_TOL = 0.5
_M = np.array([1.0, -1.0, 1.0])  # reflection across the trunk's xz (sagittal) plane
_FLOOR = {"len": 1e-3, "mass": 1e-3}



def limbs(v: GraphView) -> tuple[int, list[int]]:
    """The trunk link and the roots of its limbs (children of the trunk whose subtree holds a
    joint), in order; ``(-1, [])`` when there is no trunk."""
    t, nodes = _limbs(v)
    return t, list(nodes)


def _limbs(v: GraphView) -> tuple[int, dict[int, list[int]]]:
    """The trunk link and, per limb root in order (:func:`limbs`), the limb's nodes in
    pre-order."""
    t = trunk(v.types, v.kids) if v.nodes(LINK) else -1
    if t < 0:
        return -1, {}
    nodes = {c: subtree(v.kids, c) for c in v.kids[t]}
    return t, {c: sub for c, sub in nodes.items() if any(v.types[n] == JOINT for n in sub)}


def _shape(v: GraphView, i: int) -> tuple:
    return (v.types[i], tuple(_shape(v, c) for c in v.kids[i]))


def _profile(v: GraphView, nodes: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Lengths and masses of the links among a limb's ``nodes`` (module docstring)."""
    links = [n for n in nodes if v.types[n] == LINK]
    lengths = np.array([norm(v.get(n, "link.pos")) for n in links])
    masses = np.array([v.get(n, "link.mass")[0] for n in links])
    return lengths, masses


def _close(a: np.ndarray, b: np.ndarray, floor: float) -> bool:
    return bool(np.all(np.abs(a - b) <= MIRROR_TOL * np.maximum(np.abs(a), np.abs(b)) + floor))


def _is_pair(v: GraphView, limb: dict[int, list[int]], a: int, b: int) -> bool:
    if _shape(v, a) != _shape(v, b):
        return False
    (la, ma), (lb, mb) = _profile(v, limb[a]), _profile(v, limb[b])
    return _close(la, lb, _FLOOR["len"]) and _close(ma, mb, _FLOOR["mass"])


def mirrored_pairs(data: RobotTree, feature_set: str | FeatureSet = "paper34"
                   ) -> tuple[int, int]:
    """``(pairs, limbs)``: how many disjoint mirrored pairs the trunk's limbs form (greedy, in
    order) and how many limbs it has (module docstring)."""
    v = GraphView(data, as_feature_set(feature_set))
    _, limb = _limbs(v)
    free = list(limb)
    pairs = 0
    while free:
        a = free.pop(0)
        b = next((b for b in free if _is_pair(v, limb, a, b)), None)
        if b is not None:
            free.remove(b)
            pairs += 1
    return pairs, len(limb)


def is_symmetric(data: RobotTree, feature_set: str | FeatureSet = "paper34") -> bool:
    """At least one mirrored pair and at most one unpaired limb (module docstring)."""
    pairs, n = mirrored_pairs(data, feature_set)
    return pairs >= 1 and n - 2 * pairs <= 1


def _first_link(v: GraphView, nodes: list[int]) -> int:
    """The first link among a limb's ``nodes``, else -1."""
    return next((n for n in nodes if v.types[n] == LINK), -1)


@dataclass(frozen=True)
class _Plane:
    """The robot's sagittal plane seen from a link's frame: ``x -> h x + offset`` reflects a
    point of that frame across it (``h`` a ``3 × 3`` reflection; the trunk's: ``diag(1, -1,
    1)``, no offset)."""

    h: np.ndarray
    offset: np.ndarray

    def mirror(self, p: np.ndarray) -> np.ndarray:
        return self.h @ p + self.offset

    def off(self, p: np.ndarray) -> bool:
        """``p`` lies off the plane: its distance to it above ``ATTACH_TOL |p|``."""
        return bool(0.5 * norm(p - self.mirror(p)) > ATTACH_TOL * max(norm(p), 1e-9))


_TRUNK = _Plane(np.diag(_M), np.zeros(3))


def _planned_pairs(v: GraphView, limb: dict[int, list[int]], plane: _Plane = _TRUNK
                   ) -> list[tuple[int, int]]:
    """Near-mirror pairs ``(source, replaced)`` of the limbs ``limb`` (root: nodes) of a link
    whose frame sees the sagittal plane as ``plane``, best first (module docstring)."""
    roots = list(limb)
    info = {}
    for r in roots:
        f = _first_link(v, limb[r])
        if f >= 0:
            p = np.asarray(v.get(f, "link.pos"), dtype=float)
            lengths, masses = _profile(v, limb[r])
            off = plane.off(p)
            info[r] = (p, len(lengths), float(lengths.sum()) + 1e-9,
                       float(masses.sum()) + 1e-9, off)
    cands = []
    for ia, a in enumerate(roots):
        for b in roots[ia + 1:]:
            if a not in info or b not in info:
                continue
            (pa, na, la, ma, off_a), (pb, nb, lb, mb, off_b) = info[a], info[b]
            if not (off_a or off_b) or abs(na - nb) > max(1, LINK_COUNT_TOL * max(na, nb)):
                continue  # both on the plane, or not meant as a pair
            size_gap = abs(np.log(la / lb)) + abs(np.log(ma / mb))
            if size_gap > 2.0 * np.log(SIZE_RATIO):
                continue
            scale = max(norm(pa), norm(pb), 1e-9)
            score = norm(plane.mirror(pa) - pb) / scale + size_gap
            cands.append((score, a, b) if off_a else (score, b, a))
    used: set[int] = set()
    pairs = []
    for _, a, b in sorted(cands):
        if a not in used and b not in used:
            used |= {a, b}
            pairs.append((a, b))
    return pairs


def _plan(data: RobotTree, feature_set: str | FeatureSet
          ) -> tuple[GraphView, dict[int, list[int]], list[tuple[int, int]]]:
    """The graph's view, its trunk's limbs (root: nodes) and their near-mirror pairs."""
    v = GraphView(data, as_feature_set(feature_set))
    _, limb = _limbs(v)
    return v, limb, _planned_pairs(v, limb)


def _mirror_row(v: GraphView, row: np.ndarray, node_type: int, m: np.ndarray) -> np.ndarray:
    """A node's features mirrored by the reflection ``m`` of its frame (module docstring)."""
    out = row.copy()

    def put(key: str, fn: Callable[[np.ndarray], np.ndarray]) -> None:
        if v.has(key):
            sl = v.fs.slice(key)
            out[sl] = fn(row[sl])

    if node_type == LINK:
        for key in ("link.pos", "link.ipos", "link.box_pos"):
            put(key, lambda p: m @ p)
        for key in ("link.quat", "link.iquat"):
            put(key, lambda q: np.concatenate([q[:1], -(m @ q[1:])]))
        put("link.box_axes", lambda a: mirror_axes(a, m))
    elif node_type == JOINT:
        put("joint.pos", lambda p: m @ p)
        put("joint.axis", lambda a: -(m @ a))
    return out


def mirror_limbs(data: RobotTree, feature_set: str | FeatureSet = "paper34"
                 ) -> tuple[RobotTree, bool]:
    """Replace the second limb of every near-mirror pair by the mirror image of the first
    (module docstring).

    Returns:
        ``(data, changed)``: the new graph, of ``data``'s kind (PyG or
        :class:`~robovae.data.tree_arrays.TreeArrays`; ``data`` itself when no pair was found),
        and whether a feature or the tree changed.
    """
    v, _, plan = _plan(data, feature_set)
    if not plan:
        return data, False
    return _rebuild(data, v, {b: (a, _TRUNK) for a, b in plan}, set())


def complete_pairs(data: RobotTree, feature_set: str | FeatureSet = "paper34"
                   ) -> tuple[RobotTree, bool]:
    """Give every stray limb its mirror image (module docstring): in a robot whose trunk has
    at least one near-mirror pair, a limb off the sagittal plane, in no pair, with the
    topology of a paired limb and as far off the plane as those pairs (or off their ring, with
    room for its mirror image) gets its mirror image as a new limb, attached at ``M p`` right
    after it (a generation choice reported as ``complete_pairs``; run after
    :func:`mirror_limbs`). The training robots pair their limbs off the plane; a decoded
    robot with a pair and a third leg on one side is a decoding error, and mirroring the
    stray limb is the repair that keeps what was decoded (removing it instead: the same
    symmetry, 2 points less standing, docs/generation.md).

    Returns:
        ``(data, changed)``: the new graph (``data`` itself when nothing was added) and whether
        a limb was added.
    """
    v, limb, plan = _plan(data, feature_set)
    if not plan:
        return data, False

    def side(r: int) -> float:  # |p_y| of the limb's attachment
        return abs(float(v.get(_first_link(v, limb[r]), "link.pos")[1]))

    def radius(r: int) -> float:  # |p| of the limb's attachment
        return norm(v.get(_first_link(v, limb[r]), "link.pos"))

    reach: dict[tuple, float] = {}  # per paired topology, the smallest |p_y| of its pairs
    rings: dict[tuple, list[float]] = {}  # ... and the |p| of each of its paired limbs
    for r in (r for pair in plan for r in pair):
        reach[_shape(v, r)] = min(reach.get(_shape(v, r), np.inf), side(r))
        rings.setdefault(_shape(v, r), []).append(radius(r))
    paired = {r for pair in plan for r in pair}
    stray = set()
    for r in limb:
        f = _first_link(v, limb[r])
        if r in paired or f < 0 or _shape(v, r) not in reach:
            continue
        p = np.asarray(v.get(f, "link.pos"), dtype=float)
        shape, n = _shape(v, r), norm(p)
        ring = any(abs(n - q) <= RING_TOL * max(n, q) for q in rings[shape])
        clear = 2.0 * abs(p[1]) >= CLEAR_TOL * float(_profile(v, limb[r])[0].sum())
        if _TRUNK.off(p) and (abs(p[1]) >= STRAY_TOL * reach[shape] or not ring and clear):
            stray.add(r)
    if not stray:
        return data, False
    return _rebuild(data, v, {}, stray)


def twin_limbs(data: RobotTree, feature_set: str | FeatureSet = "paper34"
               ) -> tuple[RobotTree, bool]:
    """Make the near-equal limbs on the sagittal plane equal (module docstring): of every such
    pair (greedy, most alike first), the second in pre-order becomes a copy of the first,
    attached where it was (a generation choice reported as ``twin_limbs``; run after
    :func:`mirror_limbs`).

    Returns:
        ``(data, changed)``: the new graph (``data`` itself when no pair was found) and whether
        a feature changed.
    """
    v = GraphView(data, as_feature_set(feature_set))
    _, limb = _limbs(v)
    info = {}
    for r, nodes in limb.items():
        f = _first_link(v, nodes)
        if f >= 0 and not _TRUNK.off(np.asarray(v.get(f, "link.pos"), dtype=float)):
            lengths, masses = _profile(v, nodes)
            info[r] = (float(lengths.sum()) + 1e-9, float(masses.sum()) + 1e-9)
    roots = list(info)
    cands = []
    for ia, a in enumerate(roots):
        for b in roots[ia + 1:]:
            if _shape(v, a) != _shape(v, b) or _is_pair(v, limb, a, b):
                continue
            gap = abs(np.log(info[a][0] / info[b][0])) + abs(np.log(info[a][1] / info[b][1]))
            if gap <= 2.0 * np.log(SIZE_RATIO):
                cands.append((gap, a, b))
    used: set[int] = set()
    copy: dict[int, int] = {}
    for _, a, b in sorted(cands):
        if a not in used and b not in used:
            used |= {a, b}
            copy[b] = a
    if not copy:
        return data, False
    return _rebuild(data, v, {}, set(), copy, limb)


def _link_frames(v: GraphView, t: int) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Position and rotation, in the frame of the trunk link ``t``, of every link below it at
    rest (joints at zero): ``link.pos`` and ``link.quat`` composed down the tree."""
    frames = {t: (np.zeros(3), np.eye(3))}
    for n in subtree(v.kids, t)[1:]:
        if v.types[n] != LINK:
            continue
        up = v.parent[n]
        while v.types[up] != LINK:
            up = v.parent[up]
        p0, r0 = frames[up]
        q = np.asarray(v.get(n, "link.quat"), float) if v.has("link.quat") else np.zeros(4)
        r = quat_rotations(q / norm(q))[0] if norm(q) > 1e-9 else np.eye(3)
        frames[n] = (p0 + r0 @ np.asarray(v.get(n, "link.pos"), float), r0 @ r)
    return frames


def _is_mirror(v: GraphView, a: list[int], b: list[int], plane: _Plane) -> bool:
    """The branch of nodes ``b`` is already the mirror image of ``a`` (to float32 rounding)."""
    if _shape(v, a[0]) != _shape(v, b[0]):
        return False
    want = np.stack([_mirror_row(v, v.x[n], v.types[n], plane.h) for n in a])
    want[a.index(_first_link(v, a)), v.fs.slice("link.pos")] += plane.offset
    return bool(np.allclose(want, v.x[b], rtol=1e-5, atol=1e-6))


def mirror_branches(data: RobotTree, feature_set: str | FeatureSet = "paper34"
                    ) -> tuple[RobotTree, bool]:
    """:func:`mirror_limbs` for the branches of the links below the trunk that straddle the
    sagittal plane: a chest's arms, a mobile base's column with two arms, a head's ears.

    A link ``h`` below the trunk at ``p_h`` with rotation ``R_h`` (trunk frame, at rest) sees
    the trunk's sagittal plane as the reflection ``x -> H x + c`` of its own frame,
    ``H = R_hᵀ M R_h`` and ``c = R_hᵀ (M - I) p_h``. Its children holding a joint are its
    *branches*; their near-mirror pairs (the rule of :func:`mirror_limbs`, with that
    reflection) whose attachments lie on both sides of the plane (a hand's two fingers do
    not) are made exact mirror images: the second is replaced by the first reflected by ``H``,
    attached at ``H p_A + c``, so that the pair is symmetric about the robot's plane even when
    the decoded chest sits beside it. Pairs that already are, to float32 rounding, and branches
    inside a pair of another link are left as they are (a generation choice reported as
    ``mirror_branches``; run after :func:`mirror_limbs`).

    Returns:
        ``(data, changed)``: the new graph (``data`` itself when no pair was found) and whether
        a feature or the tree changed.
    """
    v = GraphView(data, as_feature_set(feature_set))
    t = trunk(v.types, v.kids) if v.nodes(LINK) else -1
    if t < 0:
        return data, False
    frames = _link_frames(v, t)
    replace: dict[int, tuple[int, _Plane]] = {}
    claimed: set[int] = set()  # the nodes of branches already paired
    for h, (p_h, r_h) in frames.items():
        if h == t or h in claimed:
            continue
        branch = {c: subtree(v.kids, c) for c in v.kids[h]}
        branch = {c: sub for c, sub in branch.items() if any(v.types[n] == JOINT for n in sub)}
        if len(branch) < 2:
            continue
        plane = _Plane(r_h.T @ np.diag(_M) @ r_h, r_h.T @ ((_M - 1.0) * p_h))
        # each branch's attachment's y in the trunk frame
        side = {c: float((p_h + r_h @ v.get(_first_link(v, sub), "link.pos"))[1])
                for c, sub in branch.items()}
        for a, b in _planned_pairs(v, branch, plane):
            if side[a] * side[b] >= 0.0:
                continue  # not on both sides of the plane: a hand's fingers, a foot's toes
            claimed |= set(branch[a]) | set(branch[b])
            if not _is_mirror(v, branch[a], branch[b], plane):
                replace[b] = (a, plane)
    if not replace:
        return data, False
    return _rebuild(data, v, replace, set())


def _rebuild(data: RobotTree, v: GraphView, replace: dict[int, tuple[int, _Plane]],
             twin: set[int], copy: dict[int, int] | None = None,
             limb: dict[int, list[int]] | None = None) -> tuple[RobotTree, bool]:
    """The graph with the child ``b`` of a link replaced by the mirror image of ``a`` across
    ``plane`` (``replace[b] = (a, plane)``, the plane as the link's frame sees it), each child
    of the trunk in ``twin`` followed by its own mirror image, and the child ``b`` replaced by
    a copy of ``copy[b]`` attached where ``b`` was (its first link's ``link.pos``; ``limb``:
    the limbs' nodes); ``(graph, changed)``, the graph of ``data``'s kind
    (:class:`~robovae.data.tree_arrays.TreeArrays` or PyG)."""
    parent: list[int] = []
    types: list[int] = []
    rows: list[np.ndarray] = []
    copy = copy or {}
    attach = v.fs.slice("link.pos")

    def emit(i: int, new_parent: int, h: np.ndarray | None) -> None:
        me = len(types)
        parent.append(new_parent)
        types.append(v.types[i])
        rows.append(_mirror_row(v, v.x[i], v.types[i], h) if h is not None else v.x[i])
        for c in v.kids[i]:
            if h is None and c in replace:
                a, plane = replace[c]
                start = len(types)
                emit(a, me, plane.h)
                if np.any(plane.offset):  # the attachment, in the frame of the link it hangs on
                    nodes = subtree(v.kids, a)
                    first = start + nodes.index(_first_link(v, nodes))
                    rows[first] = rows[first].copy()
                    rows[first][attach] += plane.offset
            elif h is None and c in copy:
                start = len(types)
                emit(copy[c], me, None)
                assert limb is not None  # given with copy
                first = start + limb[copy[c]].index(_first_link(v, limb[copy[c]]))
                rows[first] = rows[first].copy()
                rows[first][attach] = v.x[_first_link(v, limb[c])][attach]
            else:
                emit(c, me, h)
            if h is None and c in twin:
                emit(c, me, _TRUNK.h)

    emit(0, -1, None)
    x = np.where(node_mask(v.fs, types), np.stack(rows).astype(np.float32), np.float32(0))
    changed = (parent != v.parent or types != v.types
               or not np.array_equal(x, TreeArrays.of(data).x))
    if not changed:
        return data, False
    name = getattr(data, "name", "")
    if isinstance(data, TreeArrays):
        return TreeArrays(x, np.array(types, dtype=np.int64), np.array(parent, dtype=np.int64),
                          name), True
    return tree_data(parent, types, torch.from_numpy(x), v.fs, name=name,
                     source=getattr(data, "source", "")), True
