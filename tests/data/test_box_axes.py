"""The box orientation feature ``link.box_axes``: one value per box, and back."""

from __future__ import annotations

import mujoco
import numpy as np

from robovae.data.box_axes import axes_to_quat, mirror_axes, quat_rotations, quat_to_axes


def _random_quats(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _same_box_axes(q1: np.ndarray, q2: np.ndarray) -> bool:
    """The two rotations give the same box: every axis equal up to sign."""
    r1, r2 = quat_rotations(q1[None])[0], quat_rotations(q2[None])[0]
    return bool(np.allclose(np.abs(np.sum(r1 * r2, axis=0)), 1.0, atol=1e-6))


def test_axes_round_trip_gives_the_same_box():
    for q in _random_quats(200):
        back = axes_to_quat(quat_to_axes(q[None])[0])
        assert back[0] >= 0 and abs(np.linalg.norm(back) - 1) < 1e-9
        assert _same_box_axes(q, back)


def test_rotations_that_keep_the_box_give_one_value():
    """A half-turn about any box axis (and -q) leaves the box and its feature unchanged,
    while the quaternions differ: the ambiguity the feature removes."""
    for q in _random_quats(50, seed=1):
        a = quat_to_axes(q[None])[0]
        np.testing.assert_allclose(quat_to_axes(-q[None])[0], a, atol=1e-12)
        for axis in np.eye(3):
            flip = np.zeros(4)
            mujoco.mju_axisAngle2Quat(flip, axis, np.pi)
            turned = np.zeros(4)
            mujoco.mju_mulQuat(turned, q, flip)
            assert not np.allclose(np.abs(turned), np.abs(q))
            np.testing.assert_allclose(quat_to_axes(turned[None])[0], a, atol=1e-12)


def test_a_noisy_matrix_decodes_to_the_nearest_box():
    rng = np.random.default_rng(2)
    for q in _random_quats(50, seed=3):
        a = quat_to_axes(q[None])[0] + rng.normal(scale=0.05, size=6)
        r1, r2 = quat_rotations(q[None])[0], quat_rotations(axes_to_quat(a)[None])[0]
        assert np.all(np.abs(np.sum(r1 * r2, axis=0)) > 0.97)  # every axis within ~14°


def test_mirror_axes_is_the_mirrored_box():
    m = np.array([1.0, -1.0, 1.0])
    for q in _random_quats(50, seed=4):
        r = quat_rotations(q[None])[0]
        u1, u3 = m * r[:, 0], m * r[:, 2]  # mirrored axes
        want = np.outer(u1, u1) - np.outer(u3, u3)
        got = mirror_axes(quat_to_axes(q[None])[0], m)
        np.testing.assert_allclose(got, want[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]],
                                   atol=1e-12)


def test_mirror_axes_across_any_plane():
    rng = np.random.default_rng(5)
    for q in _random_quats(20, seed=6):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        h = np.eye(3) - 2.0 * np.outer(n, n)
        r = quat_rotations(q[None])[0]
        u1, u3 = h @ r[:, 0], h @ r[:, 2]
        want = np.outer(u1, u1) - np.outer(u3, u3)
        got = mirror_axes(quat_to_axes(q[None])[0], h)
        np.testing.assert_allclose(got, want[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]],
                                   atol=1e-12)
    a = quat_to_axes(_random_quats(1, seed=7))[0]  # diag(m) and its matrix agree
    m = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(mirror_axes(a, np.diag(m)), mirror_axes(a, m), atol=1e-15)
