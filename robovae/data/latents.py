"""The prediction dataset of generation: robot indices whose latents the model draws.

Robot ``i`` of a run with seed ``s`` has latent ``z_i ~ N(0, T² I)`` drawn from a generator
seeded by ``(s, i)`` (:func:`robovae.generate.pipeline.latent`), so items carry only the index,
the seed and the temperature; the model, which knows its latent size, draws ``z_i``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from torch.utils.data import Dataset


class LatentIndices(Dataset):
    """Robot indices to generate, each item ``{"index", "seed", "temperature", "redraws"}``
    (``redraws``: how often an unfinished decoding may redraw its latent,
    :func:`robovae.model.prior.draw_robots`)."""

    def __init__(self, n: int, seed: int = 0, temperature: float = 1.0,
                 skip: Sequence[int] = (), redraws: int = 0) -> None:
        skipped = set(skip)
        self.indices = [i for i in range(n) if i not in skipped]
        self.seed, self.temperature, self.redraws = seed, temperature, redraws

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, k: int) -> dict[str, Any]:
        return {"index": self.indices[k], "seed": self.seed, "temperature": self.temperature,
                "redraws": self.redraws}
