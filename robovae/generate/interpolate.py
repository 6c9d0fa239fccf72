"""Latent interpolation between two robots, written and validated as MuJoCo models.

For robots ``a`` and ``b`` with encoded means ``mu_a``, ``mu_b`` (the encoder's ``q(z | G)``
means), step ``k`` of ``n`` decodes ``z_k = (1 - t_k) mu_a + t_k mu_b`` with ``t_k = k / (n - 1)``
greedily: its tree from ``z_k``, then each node's latent carried from the nodes it shares with
the two robots (:mod:`robovae.model.node_transfer`), weighted ``1 - t_k`` and ``t_k``: a node
both trees have blends ``(1 - t_k) w^a + t_k w^b``, a node of one robot's tree keeps that
robot's latent, a node of neither takes its conditional prior mean. So the two ends are the
robots' reconstructions (exactly where a robot's reconstructed tree is its own). Every step
then gets the decoded fixes of ``robovae generate``
(:func:`~robovae.generate.fixes.decoded_fixes`: rails with ends, a floating base; limbs are not
mirrored, so that the ends stay the reconstructions) and the writer's stance rules
(:mod:`robovae.generate.stance`), writes ``step_<k>/robot.xml`` (with ``self_collision`` its
bodies collide with each other but for the pairs in contact at rest,
:mod:`robovae.data.self_collision`) and validates it in MuJoCo
(:func:`~robovae.generate.validate.validate_robot`): the paper's §6.2 question of whether the
space between two designs holds usable robots.
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
from robovae.model.node_transfer import EncodedRobot, decode_near
from robovae.model.vae import RoboVAE
from robovae.options import check_interpolate


@dataclass
class Step:
    """One point of an interpolation path."""

    t: float
    graph: RobotData
    path: Path | None = None
    validation: Validation | None = None


@torch.no_grad()
def latent_path(model: RoboVAE, a: RobotData, b: RobotData, steps: int = 11
                ) -> tuple[np.ndarray, torch.Tensor, tuple[EncodedRobot, EncodedRobot]]:
    """``(t, z, ends)``: ``steps`` evenly spaced ``t`` in [0, 1], ``z_t = (1 - t) mu_a + t
    mu_b`` ``[steps, latent_dim]`` and the two robots encoded (module docstring).

    Raises:
        SettingsError: (a ``ValueError``) ``steps`` not an integer in ``[2, MAX_STEPS]``
            (:func:`robovae.options.check_interpolate`).
    """
    check_interpolate(steps)
    mu, (wa, wb) = model.encode_nodes(Batch.from_data_list([a, b]))
    t = np.linspace(0.0, 1.0, steps)
    tt = torch.as_tensor(t, dtype=mu.dtype, device=mu.device)[:, None]
    z = (1 - tt) * mu[0] + tt * mu[1]
    return t, z, (EncodedRobot(mu[0], wa, (a.parent, a.node_type)),
                  EncodedRobot(mu[1], wb, (b.parent, b.node_type)))


#: Steps decoded at once (the decoder's memory grows with the batch).
DECODE_BATCH = 256


def step_name(k: int, steps: int) -> str:
    """``step_<k>``, ``k`` zero-padded to the width of the last step's index (at least 2)."""
    return f"step_{k:0{max(2, len(str(steps - 1)))}d}"


def interpolate(model: RoboVAE, a: RobotData, b: RobotData, steps: int = 11,
                out: str | Path | None = None, validate: bool = True,
                self_collision: bool = False) -> list[Step]:
    """Decode the latent path from ``a`` to ``b`` (:data:`DECODE_BATCH` steps at a time);
    with ``out``, write each step's MJCF under ``out/step_<k>/`` (:func:`step_name`) and
    (``validate``) simulate it (see the module docstring)."""
    t, z, ends = latent_path(model, a, b, steps)
    tt = torch.as_tensor(t, dtype=z.dtype)[:, None]
    weights = torch.cat([1 - tt, tt], 1)
    graphs = [g for i in range(0, steps, DECODE_BATCH) for g in decode_near(
        model, z[i:i + DECODE_BATCH], ends, weights[i:i + DECODE_BATCH])]
    result = []
    for k, (tk, g) in enumerate(zip(t.tolist(), graphs)):
        g, _ = decoded_fixes(g, model.feature_set, mirror=False)
        step = Step(tk, g)
        if out is not None:
            name = step_name(k, steps)
            written = write_robot(g, Path(out) / name, model.feature_set, name=name,
                                  stance=True, self_collision=self_collision)
            step.path = Path(written.robot_path)
            if validate:
                step.validation = validate_robot(step.path)
        result.append(step)
    return result
