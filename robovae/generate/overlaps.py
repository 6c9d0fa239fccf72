"""``clear_limbs``: branches of a robot that pass through each other at rest slide apart.

A decoded robot can hold two of its root's limbs through each other, a limb through the root's
own geometry, or one part of a limb through another: a humanoid's hips decoded 6–14 cm above
its root, inside the waist, where the corpus has them below it; its arms, hung from the chest,
beside the waist through it (docs/generation.md, *Reconstructions overlap too*). The writer runs
this rule with the stance rules, on the compiled robot at ``qpos0``, before its floor placement;
on a fixed-base robot too (an arm's fingers written through each other), which gets no other
stance rule.

With ``L`` the robot's extent (:func:`~robovae.evaluate.quality.stage.extent`), an *overlap* is
a pair of geoms of bodies that are neither the same body nor parent and child, deeper than
:data:`TOLERANCE` ``· L`` and off joint (:func:`~robovae.evaluate.quality.attachment.off_joint`):
what the quality table counts as bodies through each other.

A **branch** is a body of a link below the root with its subtree. For an overlap of bodies
``a`` and ``b`` with nearest common ancestor ``c``, the branches that can part them are those of
the bodies on the tree path from ``c`` down to ``a`` and down to ``b`` (``c`` excluded), taken
level by level: first the two bodies just below ``c`` (for two legs crossing, the two hips;
for an arm through the waist it hangs beside, the chest), then the two below those, and so on.
Each branch of a level is tried along two directions: its own ``u`` — from its mount (the
branch's top body) to the mean of its geoms' centres: a leg slides down, a spine up, an arm
out — and straight out of the overlap (from the point of its geom deepest in the other to the
other's point deepest in it, ``mj_geomDistance``), by ``t = k · STEP · L``, ``k = 1, 2, …`` up
to :data:`MAX_SLIDE` ``· L``: the smallest ``t`` after which none of its geoms overlaps one
outside it. The geometry the writer joins a mount with follows the slide: the parent's
bridges that end at the branch's anchor, and a non-root parent's limb segment that ends there,
stretch to it; a bridge whose end comes inside the parent's first geom is no longer there (the
writer makes none; :func:`~robovae.generate.link_geometry.link_geoms`). A branch slides with
its mirror image (the branch whose mount mirrors its mount across the root's sagittal plane,
``y -> -y`` in the root's frame, with as many geoms, neither above nor below it), which slides
by the mirrored displacement; a branch on the plane slides in it. The first level with a slide
that clears gives the shortest of its slides (ties: its first branch and its own direction), so
that a limb moves before its foot. This repeats, for at most :data:`MAX_ROUNDS` overlaps, until
none is left (an overlap no slide clears is passed over).

:func:`clear_limbs` returns the mounts' displacements in their parents' frames; the writer
builds the robot again with them (the geometry joining a mount to its parent follows it; the
spec is moved in place, :meth:`~robovae.generate.spec_builder.SpecBuilder.move_built`) and
keeps that robot only when fewer of its geoms overlap off joint and every body is still
attached (:func:`~robovae.evaluate.quality.attachment.attachment`). The robot built again is
not quite the one the rule tested (a bridge the writer adds, a segment that turns), so while
overlaps are left the writer runs the rule again on it, up to :data:`PASSES` times, adding the
slides.
"""

from __future__ import annotations

import mujoco
import numpy as np

from robovae.evaluate.quality.attachment import near_pairs, off_joint, robot_geoms
from robovae.evaluate.quality.stage import extent
from robovae.generate.link_geometry import COVER_TOL, GeomPlan, surface_gap
from robovae.generate.spec_builder import PRIMITIVES, is_link_primitive
from robovae.generate.stance import at_qpos0

__all__ = ["MAX_ROUNDS", "MAX_SLIDE", "PASSES", "STEP", "TOLERANCE", "clear_limbs"]

#: An overlap is deeper than this share of the robot's extent ``L`` (the quality table's 1 %).
TOLERANCE = 0.01
#: A slide is a multiple of this share of ``L``.
STEP = 0.01
#: Longest slide, as a share of ``L``.
MAX_SLIDE = 0.15
#: Overlaps cleared (or passed over) at most.
MAX_ROUNDS = 8
#: The writer runs the rule at most this many times, each on the robot it built again.
PASSES = 3

_CAPSULE = int(mujoco.mjtGeom.mjGEOM_CAPSULE)
_KINDS = {int(t): kind for kind, t in PRIMITIVES.items()}  # geom type -> GeomPlan kind
_FAR = np.array([1e6, 1e6, 1e6])  # where a bridge the writer would not make is put
_Group = list[tuple[int, np.ndarray]]  # (branch's top body, direction of slide, world)


class _Branches:
    """The robot's geoms at ``qpos0``, the bodies above each, and the pairs a slide can
    change."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, root: int) -> None:
        self.model, self.data, self.root = model, data, root
        self.size = extent(model, data, root)
        self.geoms = np.array([g for gs in robot_geoms(model, root).values() for g in gs],
                              dtype=int)
        self.body = model.geom_bodyid[self.geoms]
        self.up: dict[int, list[int]] = {}  # body -> itself and its ancestors up to the root
        for b in dict.fromkeys(self.body.tolist()):
            chain = [int(b)]
            while chain[-1] != root and chain[-1] > 0:
                chain.append(int(model.body_parentid[chain[-1]]))
            self.up[int(b)] = chain
        # the pairs that overlap, and those a slide can make meet
        self.touching, self.pairs = near_pairs(model, data, self.geoms,
                                               (0.0, MAX_SLIDE * self.size))
        self._off: dict[tuple[int, int], bool] = {}
        self._inside: dict[int, np.ndarray] = {}
        self._partner: dict[int, int] = {}
        self._followers: dict[int, list[tuple[int, int, int | None, np.ndarray]]] = {}
        self._ends: dict[int, np.ndarray] = {}  # capsule -> its segment's ends, as moved
        rot = data.xmat[root].reshape(3, 3)
        self.reflect = rot @ np.diag([1.0, -1.0, 1.0]) @ rot.T  # the sagittal plane, world

    def off(self, i: int, j: int) -> bool:
        """Whether geoms ``i`` and ``j`` meet off joint (at rest: a slide barely changes it)."""
        if (i, j) not in self._off:
            self._off[i, j] = off_joint(self.model, self.data, int(self.geoms[i]),
                                        int(self.geoms[j]))
        return self._off[i, j]

    def depth(self, i: int, j: int) -> float:
        """Overlap (m, ``0`` when apart) of geoms ``i`` and ``j`` (indices into ``geoms``)."""
        return -float(mujoco.mj_geomDistance(self.model, self.data, int(self.geoms[i]),
                                             int(self.geoms[j]), 0.0, None))

    def overlaps(self, pairs: list[tuple[int, int]], threshold: float
                 ) -> list[tuple[float, int, int]]:
        """The ``(depth, i, j)`` of ``pairs`` that overlap off joint deeper than
        ``threshold``."""
        out = []
        for i, j in pairs:
            d = self.depth(i, j)
            if d > threshold and self.off(i, j):
                out.append((d, i, j))
        return out

    def any_overlap(self, pairs: list[tuple[int, int]], threshold: float) -> bool:
        """Whether one of ``pairs`` overlaps off joint deeper than ``threshold``."""
        return any(self.depth(i, j) > threshold and self.off(i, j) for i, j in pairs)

    def inside(self, top: int) -> np.ndarray:
        """Mask of the geoms in the branch of body ``top``."""
        if top not in self._inside:
            self._inside[top] = np.array([top in self.up[int(b)] for b in self.body])
        return self._inside[top]

    def levels(self, i: int, j: int) -> list[list[int]]:
        """The top bodies of the branches that part geoms ``i`` and ``j``, level by level:
        the bodies on the paths from their bodies' nearest common ancestor down to each, the
        ``k``-th below it on both paths in level ``k`` (``i``'s first), those that
        :func:`_link_top` can move."""
        a, b = self.up[int(self.body[i])], self.up[int(self.body[j])]
        common = next(x for x in a if x in b)
        down_a, down_b = a[:a.index(common)][::-1], b[:b.index(common)][::-1]
        out = []
        for k in range(max(len(down_a), len(down_b))):
            level = [p[k] for p in (down_a, down_b) if k < len(p)
                     and _link_top(self.model, p[k]) is not None]
            if level:
                out.append(level)
        return out

    def move(self, group: _Group, t: float) -> None:
        """Translate each branch of ``group`` by ``t`` times its direction (world) in
        ``data``; the capsules of its parent that end at its anchor follow it (:meth:`_follow`).
        """
        for top, u in group:
            mine = self.inside(top)
            self.data.geom_xpos[self.geoms[mine]] += t * u
            for n in np.flatnonzero(mine).tolist():
                if n in self._ends:
                    self._ends[n] += t * u
            for i, k, prim, offset in self._follow(top):
                self._ends[i][k] += t * u
                self._reshape(i, None if prim is None else (prim, self._ends[i][k] + offset))

    def _follow(self, top: int) -> list[tuple[int, int, int | None, np.ndarray]]:
        """The capsules of ``top``'s parent body that the writer makes end at ``top``'s
        anchor (its first joint, else its origin), which follow it: a non-root link's limb
        segment (its primitive, named as
        :func:`~robovae.generate.spec_builder.is_link_primitive` says) whose segment ends
        there, and the bridges (its other geoms) whose caps end there. Each as ``(index into
        geoms, end, the parent's first geom for a bridge, the anchor from that end)``: a
        bridge is left out where its parent's first geom covers the anchor (the writer makes
        none there)."""
        if top not in self._followers:
            m, d = self.model, self.data
            anchor = d.xanchor[m.body_jntadr[top]] if m.body_jntnum[top] else d.xpos[top]
            parent = int(m.body_parentid[top])
            mine = np.flatnonzero(self.body == parent)
            first = next((int(i) for i in mine
                          if is_link_primitive(m.geom(int(self.geoms[i])).name)), None)
            found: list[tuple[int, int, int | None, np.ndarray]] = []
            for i in mine:
                g = int(self.geoms[i])
                bridge = int(i) != first
                if m.geom_type[g] != _CAPSULE or (parent == self.root and not bridge):
                    continue
                ends = self._ends.setdefault(int(i), self._segment(g))
                reach = 1.01 * m.geom_size[g, 0] if bridge else 1e-3 * self.size
                for k in (0, 1):
                    if np.linalg.norm(ends[k] - anchor) <= reach + 1e-6:
                        found.append((int(i), k, first if bridge else None, anchor - ends[k]))
            self._followers[top] = found
        return self._followers[top]

    def _covers(self, i: int, p: np.ndarray) -> bool:
        """Whether geom ``geoms[i]`` (as posed now) covers point ``p`` as the writer's
        bridges ask (:data:`~robovae.generate.link_geometry.COVER_TOL`)."""
        m, g = self.model, int(self.geoms[i])
        kind = _KINDS.get(int(m.geom_type[g]))
        if kind is None:
            return False
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, self.data.geom_xmat[g])
        plan = GeomPlan(kind, m.geom_size[g].copy(), self.data.geom_xpos[g].copy(), quat)
        r = float(m.geom_size[g, 0]) if kind != "box" else float(np.min(m.geom_size[g]))
        return surface_gap(plan, p) <= COVER_TOL * r

    def _segment(self, g: int) -> np.ndarray:
        """The two ends of capsule ``g``'s segment (world)."""
        axis = self.data.geom_xmat[g].reshape(3, 3)[:, 2] * self.model.geom_size[g, 1]
        return np.stack([self.data.geom_xpos[g] - axis, self.data.geom_xpos[g] + axis])

    def _reshape(self, i: int, cover: tuple[int, np.ndarray] | None = None) -> None:
        """Capsule ``geoms[i]`` made again from its segment's ends (``data``'s pose, the
        model's half-length and bounding radius: restored by :func:`clear_limbs`); put far
        away where ``cover`` ``(geom, point)`` says that geom covers the point its bridge
        reaches."""
        g, (a, b) = int(self.geoms[i]), self._ends[i]
        if cover is not None and self._covers(*cover):
            self.data.geom_xpos[g] = _FAR
            return
        d = b - a
        half = 0.5 * float(np.linalg.norm(d))
        if half <= 1e-9:
            return
        quat, mat = np.zeros(4), np.zeros(9)
        mujoco.mju_quatZ2Vec(quat, d)
        mujoco.mju_quat2Mat(mat, quat)
        self.data.geom_xpos[g] = 0.5 * (a + b)
        self.data.geom_xmat[g] = mat
        self.model.geom_size[g, 1] = half
        self.model.geom_rbound[g] = half + self.model.geom_size[g, 0]

    def _mirror(self, p: np.ndarray) -> np.ndarray:
        r = self.data.xpos[self.root]
        return r + self.reflect @ (p - r)

    def partner(self, top: int) -> int:
        """The branch whose mount mirrors ``top``'s across the sagittal plane (``top`` itself
        when it sits on the plane), within :data:`STEP` ``· L``, with as many geoms and
        neither above nor below it; else -1."""
        if top in self._partner:
            return self._partner[top]
        p = self._mirror(self.data.xpos[top])
        n = int(self.inside(top).sum())
        best, near = -1, STEP * self.size
        for other in range(1, self.model.nbody):
            if other != top and (self.model.body_rootid[other] != self.root
                                 or other == self.root or _link_top(self.model, other) is None
                                 or _related(self.model, top, other)):
                continue
            d = float(np.linalg.norm(self.data.xpos[other] - p))
            if d <= near and int(self.inside(other).sum()) == n:
                best, near = other, d
        self._partner[top] = best
        return best

    def away(self, i: int, j: int) -> np.ndarray:
        """The direction (world) in which geom ``i`` leaves geom ``j`` fastest: from the point
        of ``i`` deepest in ``j`` to the point of ``j`` deepest in ``i``."""
        fromto = np.zeros(6)
        mujoco.mj_geomDistance(self.model, self.data, int(self.geoms[i]), int(self.geoms[j]),
                               0.0, fromto)
        return fromto[3:] - fromto[:3]

    def groups(self, top: int, offset: np.ndarray, i: int, j: int) -> list[_Group]:
        """Branch ``top`` with its mirror image, slid along itself (:meth:`group`: from the
        mount, moved by ``offset``, to the mean of its geoms' centres) and out of the overlap
        of geoms ``i`` and ``j`` (:meth:`away`, for the one of them in the branch)."""
        mine = self.inside(top)
        if not mine.any():
            return []
        along = self.data.geom_xpos[self.geoms[mine]].mean(0) - (self.data.xpos[top] + offset)
        out = self.away(i, j) if mine[i] else self.away(j, i)
        return [g for d in (along, out) if (g := self.group(top, d)) is not None]

    def group(self, top: int, d: np.ndarray) -> _Group | None:
        """Branch ``top`` sliding along ``d`` (world) with its mirror image, which slides
        along the mirror image of ``d``; a branch on the plane slides in it; None when ``d``
        (in the plane, for a branch on it) has no length."""
        other = self.partner(top)
        if other == top:
            d = 0.5 * (d + self.reflect @ d)
        n = float(np.linalg.norm(d))
        if n <= 1e-6 * self.size:
            return None
        u = d / n
        return [(top, u)] + ([(other, self.reflect @ u)] if other not in (top, -1) else [])

    def shortest(self, groups: list[_Group], first: tuple[int, int], threshold: float
                 ) -> tuple[float, _Group] | None:
        """The smallest slide ``t`` (m) of one of ``groups`` after which none of its geoms
        overlaps one outside it deeper than ``threshold`` (the pair ``first`` tried first),
        with that group; the first group on ties; None beyond :data:`MAX_SLIDE` ``· L``."""
        tests = []
        for group in groups:
            label = np.full(len(self.geoms), -1)  # which branch of the group holds a geom
            for k, (top, _) in enumerate(group):
                label[self.inside(top)] = k
            pairs = [(i, j) for i, j in self.pairs if label[i] != label[j]]
            pairs.sort(key=lambda ij: ij != first)
            tests.append(pairs)
        step = STEP * self.size
        for k in range(1, int(round(MAX_SLIDE / STEP)) + 1):
            for group, pairs in zip(groups, tests):
                self.move(group, k * step)
                clear = not self.any_overlap(pairs, threshold)
                self.move(group, -k * step)
                if clear:
                    return k * step, group
        return None


def _link_top(model: mujoco.MjModel, body: int) -> str | None:
    """The writer's link name (``link<i>``) whose ``link.pos`` places ``body``: the body of
    link ``i`` or its first intermediate body (``link<i>_split0``); None for any other body
    (a later intermediate body, a link below its own intermediate bodies, a foreign name)."""
    name = model.body(body).name
    if name.endswith("_split0"):
        name = name.removesuffix("_split0")
    elif model.body(int(model.body_parentid[body])).name.startswith(f"{name}_split"):
        return None
    return name if name.startswith("link") and name[4:].isdigit() else None


def _related(model: mujoco.MjModel, a: int, b: int) -> bool:
    """Whether body ``a`` is above or below body ``b`` (or is it)."""
    def above(x: int, y: int) -> bool:  # x on y's path to the world
        while y > x:
            y = int(model.body_parentid[y])
        return y == x
    return above(a, b) or above(b, a)


def clear_limbs(model: mujoco.MjModel, root: int, data: mujoco.MjData | None = None,
                tolerance: float = TOLERANCE) -> dict[str, np.ndarray]:
    """Slides that clear overlaps between the robot's branches (module docstring): per link
    name (``link<i>``), the displacement of its mount in its parent's frame (empty when
    nothing overlaps or no slide clears it). ``model``: the robot compiled; ``root``: its root
    body; ``data``: its kinematics at ``qpos0`` (left as given), made here when not given."""
    data = at_qpos0(model, data)
    if model.body_geomnum[root:].sum() < 2:
        return {}
    branches = _Branches(model, data, root)
    threshold = tolerance * branches.size
    if not branches.overlaps(branches.touching, threshold):
        return {}  # most robots: nothing to clear
    saved = (data.geom_xpos.copy(), data.geom_xmat.copy(), model.geom_size.copy(),
             model.geom_rbound.copy())
    shifts: dict[int, np.ndarray] = {}
    passed: set[tuple[int, int]] = set()
    try:
        for _ in range(MAX_ROUNDS):
            over = branches.overlaps([ij for ij in branches.pairs if ij not in passed],
                                     threshold)
            if not over:
                break
            _, i, j = max(over)
            best = None
            for level in branches.levels(i, j):  # the branches nearest the common ancestor
                groups = [g for top in level
                          for g in branches.groups(top, shifts.get(top, np.zeros(3)), i, j)]
                if groups and (best := branches.shortest(groups, (i, j), threshold)):
                    break
            if best is None:
                passed.add((i, j))
                continue
            t, group = best
            branches.move(group, t)
            for top, u in group:
                shifts[top] = shifts.get(top, np.zeros(3)) + t * u
    finally:
        for now, then in zip((data.geom_xpos, data.geom_xmat, model.geom_size,
                              model.geom_rbound), saved):
            now[:] = then
    out = {}
    for top, s in shifts.items():
        name = _link_top(model, top)
        assert name is not None  # levels() offers only such bodies
        out[name] = data.xmat[int(model.body_parentid[top])].reshape(3, 3).T @ s
    return out
