"""Numbers as MJCF writes them: the vectorised row and group roundings agree with the scalar one
and are written back exactly."""

from __future__ import annotations

import mujoco
import numpy as np

from robovae.generate.mjcf_numbers import (
    mjcf_round,
    mjcf_round_groups,
    mjcf_round_rows,
    mjcf_round_vector,
    mjcf_round_vectors,
)


def test_rows_round_like_vectors_and_survive_mjcf_output():
    rng = np.random.default_rng(0)
    a = rng.choice([-1, 1], (400, 3)) * 10.0 ** rng.uniform(-15, 8, (400, 3))
    a[::7, 1] = 10.0 ** rng.integers(-8, 5, len(a[::7]))  # exact powers of ten
    a[::11, 2] = 1e-14 * a[::11, 0]  # negligible next to the row's largest: written as 0
    a[5, 0], a[6, 1] = np.nan, np.inf
    rows = mjcf_round_rows(a)
    for r, row in zip(rows, a):
        want = mjcf_round_vector(row)
        assert np.array_equal(r, want, equal_nan=True)
    # a body position of rounded values is written and read back bit for bit
    spec = mujoco.MjSpec()
    finite = rows[np.isfinite(rows).all(axis=1)][:50]
    for k, p in enumerate(finite):
        body = spec.worldbody.add_body(name=f"b{k}", pos=p.tolist())
        body.add_geom(size=[0.1, 0, 0])
    spec.compile()
    model = mujoco.MjModel.from_xml_string(spec.to_xml())
    assert np.array_equal(model.body_pos[1:], finite)


def test_groups_round_like_rows_group_by_group():
    """The feature matrix rounded in one pass: each group of columns as its own rows."""
    rng = np.random.default_rng(1)
    a = rng.choice([-1, 1], (300, 9)) * 10.0 ** rng.uniform(-15, 8, (300, 9))
    a[::5, 4] = 1e-14 * a[::5, 3]  # negligible within its group (3:6), not within the row
    a[3, 2], a[4, 7], a[8, 0] = np.nan, -np.inf, 0.0
    starts = np.array([0, 1, 3, 6])
    got = mjcf_round_groups(a, starts)
    for lo, hi in zip(starts, [*starts[1:], a.shape[1]]):
        assert np.array_equal(got[:, lo:hi], mjcf_round_rows(a[:, lo:hi]), equal_nan=True)
    assert mjcf_round_groups(np.zeros((0, 9)), starts).shape == (0, 9)


def test_vectors_round_exactly_like_one_vector_at_a_time():
    """Rows of concatenated vectors in one pass: the very numbers of mjcf_round_vector (no tie
    may round the other way), also beside a non-finite row."""
    rng = np.random.default_rng(3)
    a = rng.choice([-1, 1], (400, 10)) * 10.0 ** rng.uniform(-15, 8, (400, 10))
    a[::7, 5] = 1e-13 * a[::7, 4]  # negligible within its vector (3:6), not within the row
    a[1::9] = np.round(a[1::9], 7) + 5e-7  # decimal ties at the 6th digit
    starts = np.array([0, 3, 6])
    want = [sum((mjcf_round_vector(v) for v in np.split(row, starts[1:])), []) for row in a]
    assert mjcf_round_vectors(a, starts) == want
    a[2, 7] = np.nan
    assert np.array_equal(mjcf_round_vectors(a[:3], starts)[2],
                          sum((mjcf_round_vector(v) for v in np.split(a[2], starts[1:])), []),
                          equal_nan=True)


def test_vector_rounding_of_lists_and_arrays_with_non_finite_values():
    """The fast path (every component finite) and the general one agree with mjcf_round."""
    rng = np.random.default_rng(2)
    for _ in range(2000):
        v = rng.standard_normal(4) * 10.0 ** rng.integers(-20, 20, 4)
        if rng.random() < 0.3:
            v[rng.integers(4)] = rng.choice([np.nan, np.inf, -np.inf, -0.0, 1e308])
        finite = v[np.isfinite(v)]
        big = np.abs(finite).max(initial=0.0)
        want = [0.0 if np.isfinite(x) and abs(x) <= 1e-12 * big else mjcf_round(x) for x in v]
        for got in (mjcf_round_vector(v), mjcf_round_vector(v.tolist())):
            assert np.array_equal(got, want, equal_nan=True)
            assert all(np.signbit(g) == np.signbit(w) for g, w in zip(got, want) if g == g)
