"""Per-robot prior draws: the latent ``z_i`` and the node-latent noise of robot ``i`` of a
generation run, each from its own generator seeded by ``(seed, i)``, so a robot's draw does not
depend on the batch it is decoded in, the number of workers or the robots written before it."""

from __future__ import annotations

import numpy as np
import torch


def latent(seed: int, index: int, dim: int, temperature: float = 1.0) -> torch.Tensor:
    """The latent of robot ``index`` of a run with ``seed``: ``N(0, T² I)``, ``[dim]`` float32,
    from its own generator (NumPy PCG64 seeded by the pair ``(seed, index)``)."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, index])))
    return torch.from_numpy(rng.standard_normal(dim).astype(np.float32)) * temperature


def node_noise(seed: int, index: int, max_nodes: int, dim: int,
               temperature: float = 1.0) -> torch.Tensor:
    """The node-latent noise of robot ``index``: ``[max_nodes, dim]`` standard normals times
    ``T`` from the robot's second stream (``(seed, index, 1)``), so its node ``t`` draws
    ``w_t = mu^p + sigma^p eps_t`` whatever the batch."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, index, 1])))
    eps = rng.standard_normal((max_nodes, dim)).astype(np.float32)
    return torch.from_numpy(eps) * temperature
