"""The orientation of a link's collision box as a symmetric matrix (feature ``link.box_axes``).

A box is symmetric under half-turns about its axes and under sign flips of each axis, so a
quaternion of its orientation is not unique (8 rotations, and ``±q``, give the same box): a
network regressing it learns their average. The feature is instead

.. math::  A = u_1 u_1^\\top - u_3 u_3^\\top

with ``u1`` the box's longest axis and ``u3`` its shortest (body frame): every orientation of
the box gives one ``A``, every rotation giving the same box gives the same ``A``, and ``A``
is continuous in the rotation. Its eigenvalues are ``1, 0, -1`` (eigenvectors ``u1, u2, u3``),
so :func:`axes_to_quat` recovers the orientation from any symmetric matrix, including a
regressed one: the eigenvectors of its largest and smallest eigenvalues. Stored as the six
entries ``xx, yy, zz, xy, xz, yz``.
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["axes_to_quat", "axes_to_quats", "mirror_axes", "quat_rotations", "quat_to_axes"]

_I, _J = (0, 1, 2, 0, 0, 1), (0, 1, 2, 1, 2, 2)


def quat_rotations(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices ``[n, 3, 3]`` of unit quaternions ``[n, 4]`` (``w, x, y, z``)."""
    w, x, y, z = np.asarray(quat, float).T
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                     2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                     2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
                    -1).reshape(-1, 3, 3)


def quat_to_axes(quat: np.ndarray) -> np.ndarray:
    """``[n, 6]`` entries of ``A = u1 u1ᵀ - u3 u3ᵀ`` of boxes oriented by ``quat`` ``[n, 4]``
    (the box's axes, longest first, are the columns of the quaternion's rotation)."""
    r = quat_rotations(quat)
    u1, u3 = r[:, :, 0], r[:, :, 2]
    a = u1[:, :, None] * u1[:, None, :] - u3[:, :, None] * u3[:, None, :]
    return a[:, _I, _J]


def axes_to_quat(axes: np.ndarray) -> np.ndarray:
    """The orientation ``[4]`` (``w >= 0``) of a box from the six entries of its (possibly
    regressed) axis matrix: columns ``u1`` (largest eigenvalue), ``u2 = u3 × u1`` and ``u3``
    (smallest eigenvalue), a right-handed frame. One box of :func:`axes_to_quats`."""
    return axes_to_quats(np.asarray(axes, float)[None])[0]


def axes_to_quats(axes: np.ndarray) -> np.ndarray:
    """:func:`axes_to_quat` of ``[n, 6]`` axis matrices at once: ``[n, 4]`` (one batched
    eigendecomposition)."""
    axes = np.asarray(axes, float).reshape(-1, 6)
    a = np.zeros((len(axes), 3, 3))
    a[:, _I, _J] = axes
    a[:, _J, _I] = axes
    _, vecs = np.linalg.eigh(a)
    u1, u3 = vecs[:, :, 2], vecs[:, :, 0]
    rot = np.stack([u1, np.cross(u3, u1), u3], axis=2).reshape(-1, 9)
    quats = np.zeros((len(axes), 4))
    for k in range(len(axes)):
        mujoco.mju_mat2Quat(quats[k], rot[k])
    return np.where(quats[:, :1] >= 0, quats, -quats)


def mirror_axes(axes: np.ndarray, m: np.ndarray) -> np.ndarray:
    """The axis matrix of the mirror image of a box, ``M A M`` for the reflection ``M``:
    ``diag(m)`` when ``m`` is a vector of ±1, else the symmetric orthogonal ``3 × 3`` matrix
    ``m`` (a reflection across any plane through the origin, ``I - 2 n nᵀ``)."""
    m = np.asarray(m, float)
    if m.ndim == 1:
        return np.asarray(axes, float) * m[list(_I)] * m[list(_J)]
    a = np.zeros((3, 3))
    a[_I, _J] = axes
    a[_J, _I] = axes
    return (m @ a @ m)[_I, _J]
