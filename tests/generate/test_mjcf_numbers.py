"""Numbers as MJCF writes them: the vectorised row rounding agrees with the scalar one and is
written back exactly."""

from __future__ import annotations

import mujoco
import numpy as np

from robovae.generate.mjcf_numbers import mjcf_round_rows, mjcf_round_vector


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
