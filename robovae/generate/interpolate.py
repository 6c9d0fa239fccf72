"""Latent interpolation between two robots, written and validated as MuJoCo models.

For robots ``a`` and ``b`` with encoded means ``mu_a``, ``mu_b`` (the encoder's ``q(z | G)``
means), step ``k`` of ``n`` decodes ``z_k = (1 - t_k) mu_a + t_k mu_b`` with ``t_k = k / (n - 1)``
greedily. With node latents, the nodes' latent means are interpolated the same way, node by
node in pre-order, the shorter robot's list padded with the other's tail:
``w_k[i] = (1 - t_k) w_a[i] + t_k w_b[i]``; so the two ends are exactly the robots'
reconstructions. Every step then gets the decoded fixes of ``robovae generate``
(:func:`~robovae.generate.fixes.decoded_fixes`: rails with ends, a floating base; limbs are not
mirrored, so that the ends stay the reconstructions) and
the writer's stance rules (:mod:`robovae.generate.stance`), writes ``step_<k>/robot.xml`` and
validates it in MuJoCo (:func:`~robovae.generate.validate.validate_robot`): the paper's §6.2
question of whether the space between two designs holds usable robots.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch_geometric.data import Batch

from robovae.data.graph import RobotData
from robovae.generate.fixes import decoded_fixes
from robovae.generate.validate import Validation, validate_robot
from robovae.generate.writer import write_robot
from robovae.model.vae import RoboVAE


@dataclass
class Step:
    """One point of an interpolation path."""

    t: float
    graph: RobotData
    path: Path | None = None
    validation: Validation | None = None


@torch.no_grad()
def latent_path(model: RoboVAE, a: RobotData, b: RobotData, steps: int = 11
                ) -> tuple[np.ndarray, torch.Tensor, list[torch.Tensor]]:
    """``(t, z, w)``: ``steps`` evenly spaced ``t`` in [0, 1], ``z_t = (1 - t) mu_a + t mu_b``
    and each step's node latents (module docstring).

    Raises:
        ValueError: ``steps < 2``.
    """
    if steps < 2:
        raise ValueError(f"an interpolation needs at least 2 steps, got {steps}")
    mu, (wa, wb) = model.encode_nodes(Batch.from_data_list([a, b]))
    t = np.linspace(0.0, 1.0, steps)
    tt = torch.as_tensor(t, dtype=mu.dtype, device=mu.device)[:, None]
    z = (1 - tt) * mu[0] + tt * mu[1]
    na, nb = wa.shape[0], wb.shape[0]
    wa, wb = torch.cat([wa, wb[na:]]), torch.cat([wb, wa[nb:]])  # both max(na, nb) long
    return t, z, [(1 - tk) * wa + tk * wb for tk in tt[:, :, None]]


#: Steps decoded at once (the decoder's memory grows with the batch).
DECODE_BATCH = 256


def step_name(k: int, steps: int) -> str:
    """``step_<k>``, ``k`` zero-padded to the width of the last step's index (at least 2)."""
    return f"step_{k:0{max(2, len(str(steps - 1)))}d}"


def interpolate(model: RoboVAE, a: RobotData, b: RobotData, steps: int = 11,
                out: str | Path | None = None, validate: bool = True) -> list[Step]:
    """Decode the latent path from ``a`` to ``b`` (:data:`DECODE_BATCH` steps at a time);
    with ``out``, write each step's MJCF under ``out/step_<k>/`` (:func:`step_name`) and
    (``validate``) simulate it (see the module docstring)."""
    t, z, w = latent_path(model, a, b, steps)
    graphs = [g for i in range(0, steps, DECODE_BATCH) for g in model.decode(
        z[i:i + DECODE_BATCH], node_latents=w[i:i + DECODE_BATCH], clamp=False)]
    result = []
    for k, (tk, g) in enumerate(zip(t.tolist(), graphs)):
        g, _ = decoded_fixes(g, model.feature_set, mirror=False)
        step = Step(tk, g)
        if out is not None:
            name = step_name(k, steps)
            written = write_robot(g, Path(out) / name, model.feature_set, name=name,
                                  stance=True)
            step.path = Path(written.robot_path)
            if validate:
                step.validation = validate_robot(step.path)
        result.append(step)
    return result
