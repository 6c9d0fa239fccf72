"""Attachment, symmetry and distribution measures (robovae.evaluate.quality) on real MuJoCo
models and known arrays."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from robovae.data.procedural import procedural_spec
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.quality.distribution import precision_recall, split_half, wasserstein_1d
from robovae.evaluate.quality.symmetry import anatomy

CAPSULE = mujoco.mjtGeom.mjGEOM_CAPSULE


def legged(lengths: list[float], masses: list[float] | None = None, gap: float = 0.0
           ) -> mujoco.MjSpec:
    """A 0.2 m box trunk with one leg per length (hip hinge + knee hinge), spread around the
    trunk; the first leg's thigh starts ``gap`` m away from the trunk."""
    spec = mujoco.MjSpec()
    trunk = spec.worldbody.add_body(name="trunk", pos=[0, 0, 1])
    trunk.add_freejoint()
    trunk.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.05], mass=2.0)
    masses = masses or [0.5] * len(lengths)
    for k, (length, mass) in enumerate(zip(lengths, masses)):
        a = 2 * math.pi * k / len(lengths)
        d = np.array([math.cos(a), math.sin(a), 0.0])
        thigh = trunk.add_body(name=f"thigh{k}", pos=(0.1 + (gap if k == 0 else 0.0)) * d)
        thigh.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=[-d[1], d[0], 0])
        thigh.add_geom(type=CAPSULE, size=[0.02, 0, 0], fromto=[0, 0, 0, *(length / 2 * d)],
                       mass=mass / 2)
        shin = thigh.add_body(name=f"shin{k}", pos=length / 2 * d)
        shin.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=[-d[1], d[0], 0])
        shin.add_geom(type=CAPSULE, size=[0.02, 0, 0], fromto=[0, 0, 0, 0, 0, -length / 2],
                      mass=mass / 2)
    return spec


def test_a_detached_body_is_detected() -> None:
    whole = attachment(legged([0.4] * 4))
    assert whole.bodies == 8 and whole.detached == 0 and whole.all_attached
    apart = attachment(legged([0.4] * 4, gap=0.5))  # extent ~1.4 m: 0.5 m > 5 %
    assert apart.detached == 1 and apart.detached_bodies == ["thigh0"]
    assert apart.detached_share == pytest.approx(1 / 8) and not apart.all_attached
    near = attachment(legged([0.4] * 4, gap=0.02))  # within 5 % of the extent
    assert near.detached == 0


def test_self_penetration_between_non_adjacent_bodies() -> None:
    spec = legged([0.4] * 2)
    # the two shins turned towards each other meet under the trunk
    assert attachment(spec).penetration == 0.0
    spec.body("shin1").geoms[0].fromto = [0, 0, 0, 0.4, 0, 0]  # towards leg 0's shin
    spec.body("shin0").geoms[0].fromto = [0, 0, 0, -0.4, 0, 0]
    r = attachment(spec)
    assert r.penetration > 0.02 and r.penetrating_pairs >= 1
    assert r.off_joint_pairs == r.penetrating_pairs  # no joint where the shins meet
    assert attachment(spec, tolerance=1.0).penetrating_pairs == 0


def test_an_overlap_around_a_joint_is_not_off_joint() -> None:
    spec = legged([0.4] * 2)
    # a hip of two hinges at one point: leg 0's shin hangs from the hip itself, thick, so its
    # top reaches into the trunk (its grandparent) around the hip's joints
    shin = spec.body("shin0")
    shin.pos = [0, 0, 0]
    shin.geoms[0].size = [0.06, 0, 0]
    r = attachment(spec)
    assert r.penetration > 0.04 and r.penetrating_pairs == 1 and r.off_joint_pairs == 0
    # the same shin hung 0.3 m out from the hip on a long thigh, then turned back under the
    # trunk: the overlap holds neither the hip's nor the knee's joint
    spec = legged([0.6] * 2)
    spec.body("shin0").geoms[0].fromto = [0, 0, 0, -0.3, 0, -0.02]
    spec.body("shin0").geoms[0].size = [0.06, 0, 0]
    r = attachment(spec)
    assert r.penetrating_pairs >= 1 and r.off_joint_pairs >= 1


def test_a_mirrored_robot_is_symmetric_and_an_asymmetric_one_is_not() -> None:
    four = anatomy(legged([0.4] * 4))
    assert four.limbs == 4 and four.pairs == 2 and four.symmetric and not four.one_limb
    assert four.bodies == 9 and four.dof == 6 + 8
    assert four.mass == pytest.approx(2.0 + 4 * 0.5)
    longer = anatomy(legged([0.4, 0.6]))  # 50 % longer
    assert longer.pairs == 0 and not longer.symmetric
    heavier = anatomy(legged([0.4, 0.4], masses=[0.5, 0.6]))  # 20 % heavier
    assert not heavier.symmetric
    close = anatomy(legged([0.4, 0.42], masses=[0.5, 0.52]))  # within 10 %
    assert close.symmetric and close.pairs == 1
    three = anatomy(legged([0.4] * 3))  # one odd limb out is allowed
    assert three.pairs == 1 and three.unpaired == 1 and three.symmetric
    one = anatomy(legged([0.4]))
    assert one.one_limb and not one.symmetric
    assert anatomy(procedural_spec(3, "hexapod")).pairs == 3


def test_wasserstein_on_known_arrays() -> None:
    assert wasserstein_1d([0, 1, 2], [0, 1, 2]) == 0.0
    assert wasserstein_1d([0.0], [3.0]) == pytest.approx(3.0)
    assert wasserstein_1d([0, 1, 2], [1, 2, 3]) == pytest.approx(1.0)  # a shift by 1
    assert wasserstein_1d([0, 1], [0]) == pytest.approx(0.5)
    assert wasserstein_1d([0, 2], [1, 1, 1]) == pytest.approx(1.0)
    assert wasserstein_1d([0, np.nan, 4], [4, 0]) == 0.0
    rng = np.random.default_rng(0)
    x = rng.normal(size=400)
    # the W1 of two equal-size samples is the mean gap of their sorted values
    y = rng.normal(1.0, 1.0, 400)
    assert wasserstein_1d(x, y) == pytest.approx(np.mean(np.abs(np.sort(x) - np.sort(y))))
    with pytest.raises(ValueError):
        wasserstein_1d([], [1.0])


def test_split_half_reference_shrinks_with_corpus_size() -> None:
    rng = np.random.default_rng(1)
    small, large = split_half(rng.normal(size=20)), split_half(rng.normal(size=2000))
    assert 0 < large < small < 1
    assert split_half([5.0] * 10) == 0.0 and math.isnan(split_half([1.0]))


def test_precision_and_recall_on_known_sets() -> None:
    grid = np.array([[i, j] for i in range(5) for j in range(5)], dtype=float)
    assert precision_recall(grid, grid) == (1.0, 1.0)
    far = grid + 100.0
    assert precision_recall(grid, far) == (0.0, 0.0)
    # samples only in the left column: all look real, but they cover a fraction of the grid
    left = grid[grid[:, 0] == 0]
    p, r = precision_recall(grid, left, k=1)
    assert p == 1.0 and 0.2 <= r < 0.5
    # half the samples far away: precision 0.5
    p, _ = precision_recall(grid, np.concatenate([grid, far]))
    assert p == 0.5
    with pytest.raises(ValueError):
        precision_recall(grid, np.zeros((3, 3)))
