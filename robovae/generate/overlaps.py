"""``clear_limbs``: limbs of the root that pass through each other at rest slide apart, each
along itself.

A decoded robot can hold two of its root's limbs through each other, or a limb through the
root's own geometry: a humanoid's hips decoded 6–14 cm above its root, inside the waist, where
the corpus has them below it (docs/generation.md, *Reconstructions overlap too*). The writer runs
this rule with the stance rules, on the compiled robot at ``qpos0``, before its floor placement.

With ``L`` the robot's extent (:func:`~robovae.evaluate.quality.stage.extent`), an *overlap* is
a pair of geoms of bodies that are neither the same body nor parent and child, one of them in
a limb (a child of the root with its subtree) and the other in another limb or in the root
body, deeper than :data:`TOLERANCE` ``· L`` and off joint
(:func:`~robovae.evaluate.quality.attachment.off_joint`: what the quality table counts as
bodies through each other). Overlaps inside one limb (a foot through its own shin) are left.

For the deepest overlap, each limb of the two (never the root body) is tried: slid as a whole
along its own direction ``u`` — from its mount (the root's child) to the mean of its geoms'
centres: a leg slides down, a spine up, an arm out — by ``t = k · STEP · L``, ``k = 1, 2, …``
up to :data:`MAX_SLIDE` ``· L``, the smallest ``t`` after which none of its geoms overlaps one
of another limb. A limb slides with its mirror image (the limb whose mount mirrors its mount
across the root's sagittal plane, ``y -> -y`` in the root's frame, with as many geoms), which
slides by the mirrored displacement; a limb on the plane slides in it. The limb that needs the
shorter slide moves; ties go to the first limb found. This
repeats, for at most :data:`MAX_ROUNDS` overlaps, until none is left (an overlap no slide
clears is passed over).

:func:`clear_limbs` returns the mounts' displacements in the root's frame; the writer builds the
robot again with them (its joining geometry follows the mounts) and keeps that robot only when
it has fewer overlaps between limbs than before (:func:`limb_overlaps`; a limb slid as a whole
changes none inside it) and every body is still attached.
"""

from __future__ import annotations

import mujoco
import numpy as np

from robovae.evaluate.quality.attachment import off_joint, robot_geoms
from robovae.evaluate.quality.stage import extent
from robovae.generate.stance import at_qpos0, root_limb

__all__ = ["MAX_ROUNDS", "MAX_SLIDE", "STEP", "TOLERANCE", "clear_limbs", "limb_overlaps"]

#: An overlap is deeper than this share of the robot's extent ``L`` (the quality table's 1 %).
TOLERANCE = 0.01
#: A slide is a multiple of this share of ``L``.
STEP = 0.01
#: Longest slide, as a share of ``L``.
MAX_SLIDE = 0.15
#: Overlaps cleared (or passed over) at most.
MAX_ROUNDS = 8


class _Limbs:
    """The robot's geoms at ``qpos0``, their limbs, and the overlap pairs a slide can change."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, root: int) -> None:
        self.model, self.data, self.root = model, data, root
        self.size = extent(model, data, root)
        self.geoms = np.array([g for gs in robot_geoms(model, root).values() for g in gs],
                              dtype=int)
        body = model.geom_bodyid[self.geoms]
        self.limb = np.array([root_limb(model, int(b), root) for b in body], dtype=int)
        parent = model.body_parentid[body]
        pos, rb = data.geom_xpos[self.geoms], model.geom_rbound[self.geoms]
        gap = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - (rb[:, None] + rb[None])
        cand = np.triu((self.limb[:, None] != self.limb[None]) & (body[:, None] != body[None])
                       & (parent[:, None] != body[None]) & (body[:, None] != parent[None]), 1)
        self.touching = [(int(i), int(j)) for i, j in zip(*np.nonzero(cand & (gap < 0)))]
        self.pairs = [(int(i), int(j)) for i, j in zip(*np.nonzero(
            cand & (gap < MAX_SLIDE * self.size)))]  # what a slide can make meet
        self._off: dict[tuple[int, int], bool] = {}
        rot = data.xmat[root].reshape(3, 3)
        self.to_root = rot.T
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

    def move(self, group: list[tuple[int, np.ndarray]], t: float) -> None:
        """Translate each limb of ``group`` by ``t`` times its direction (world) in ``data``."""
        for limb, u in group:
            self.data.geom_xpos[self.geoms[self.limb == limb]] += t * u

    def _mount(self, limb: int) -> np.ndarray:
        return self.to_root @ (self.data.xpos[limb] - self.data.xpos[self.root])

    def partner(self, limb: int) -> int:
        """The limb whose mount mirrors ``limb``'s across the sagittal plane (``limb`` itself
        when it sits on the plane), within :data:`STEP` ``· L`` and with as many geoms; else
        -1."""
        p = self._mount(limb) * [1.0, -1.0, 1.0]
        n = int((self.limb == limb).sum())
        best, near = -1, STEP * self.size
        for other in dict.fromkeys(self.limb.tolist()):
            if other != self.root and int((self.limb == other).sum()) == n:
                d = float(np.linalg.norm(self._mount(other) - p))
                if d <= near:
                    best, near = other, d
        return best

    def group(self, limb: int, offset: np.ndarray) -> list[tuple[int, np.ndarray]] | None:
        """``limb`` and its mirror image, each with its direction of slide: from the mount
        (moved by ``offset``) to the mean of the limb's geoms' centres, the partner's its mirror
        image, a limb on the plane's kept in the plane; None when it has no length."""
        d = self.data.geom_xpos[self.geoms[self.limb == limb]].mean(0) \
            - (self.data.xpos[limb] + offset)
        other = self.partner(limb)
        if other == limb:
            d = 0.5 * (d + self.reflect @ d)
        n = float(np.linalg.norm(d))
        if n <= 1e-6 * self.size:
            return None
        u = d / n
        return [(limb, u)] + ([(other, self.reflect @ u)] if other not in (limb, -1) else [])

    def slide(self, group: list[tuple[int, np.ndarray]], threshold: float) -> float | None:
        """Smallest slide ``t`` (m) of ``group`` after which none of its geoms overlaps one of
        another limb deeper than ``threshold``; None beyond :data:`MAX_SLIDE` ``· L``."""
        mine = np.isin(self.limb, [limb for limb, _ in group])
        pairs = [(i, j) for i, j in self.pairs if mine[i] or mine[j]]
        step = STEP * self.size
        moved, found = 0.0, None
        for k in range(1, int(round(MAX_SLIDE / STEP)) + 1):
            self.move(group, step)
            moved = k * step
            if not self.overlaps(pairs, threshold):
                found = moved
                break
        self.move(group, -moved)
        return found


def limb_overlaps(model: mujoco.MjModel, root: int, data: mujoco.MjData | None = None,
                  tolerance: float = TOLERANCE) -> int:
    """How many geom pairs of different limbs of the root (or a limb and the root body)
    overlap off joint deeper than ``tolerance · L`` at ``qpos0`` (module docstring)."""
    data = at_qpos0(model, data)
    limbs = _Limbs(model, data, root)
    return len(limbs.overlaps(limbs.touching, tolerance * limbs.size))


def clear_limbs(model: mujoco.MjModel, root: int, data: mujoco.MjData | None = None,
                tolerance: float = TOLERANCE) -> dict[str, np.ndarray]:
    """Slides that clear overlaps between the root's limbs (module docstring): per mount
    body's name, its displacement in the root's frame (empty when nothing overlaps or no slide
    clears it). ``model``: the robot compiled; ``root``: its root body; ``data``: its
    kinematics at ``qpos0`` (left as given), made here when not given."""
    data = at_qpos0(model, data)
    if model.body_geomnum[root:].sum() < 2:
        return {}
    limbs = _Limbs(model, data, root)
    threshold = tolerance * limbs.size
    if not limbs.overlaps(limbs.touching, threshold):
        return {}  # most robots: nothing to clear
    saved = data.geom_xpos.copy()
    shifts: dict[int, np.ndarray] = {}
    passed: set[tuple[int, int]] = set()
    try:
        for _ in range(MAX_ROUNDS):
            over = limbs.overlaps([ij for ij in limbs.pairs if ij not in passed], threshold)
            if not over:
                break
            _, i, j = max(over)
            best: tuple[float, list[tuple[int, np.ndarray]]] | None = None
            for limb in dict.fromkeys((int(limbs.limb[i]), int(limbs.limb[j]))):
                group = None if limb == root else \
                    limbs.group(limb, shifts.get(limb, np.zeros(3)))
                t = None if group is None else limbs.slide(group, threshold)
                if t is not None and group is not None and (best is None or t < best[0]):
                    best = (t, group)
            if best is None:
                passed.add((i, j))
                continue
            t, group = best
            limbs.move(group, t)
            for limb, u in group:
                shifts[limb] = shifts.get(limb, np.zeros(3)) + t * u
    finally:
        data.geom_xpos[:] = saved
    return {model.body(b).name: limbs.to_root @ s for b, s in shifts.items()}
