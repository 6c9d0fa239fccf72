"""Per-robot prior draws: the latent ``z_i`` and the node-latent noise of robot ``i`` of a
generation run, each from its own generator seeded by ``(seed, i)``, so a robot's draw does not
depend on the batch it is decoded in, the number of workers or the robots written before it.

A decoding that reaches the decoder's limits (``max_nodes`` nodes, or depth ``max_depth``) did
not finish its tree: it is a chain cut off by the limit, not a robot (in practice a runaway
chain past the deepest training robot). :func:`draw_robots` redraws such a robot's ``z`` from
its next stream, ``(seed, i, 2, k)`` for draw ``k = 1, 2, ...``, at most ``redraws`` times:
sampling from the prior conditioned on a finished tree, every redraw counted per robot.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np
import torch

from robovae.data.graph import RobotData
from robovae.errors import check_seed
from robovae.settings import check_settings, integer, number


class PriorModel(Protocol):
    """What :func:`draw_robots` needs of a model (:class:`~robovae.model.vae.RoboVAE`, which
    imports this module)."""

    hparams: Any

    def sample_prior(self, seed: int, indices: Sequence[int], temperature: float = 1.0,
                     node_temperature: float | None = None
                     ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(z, node_noise)`` of robots ``indices`` of a run with ``seed``."""

    def prior_latent(self, seed: int, index: int, temperature: float = 1.0,
                     draw: int = 0) -> torch.Tensor:
        """The latent of robot ``index`` (draw ``draw``) from the model's sampling prior."""

    def decode(self, z: torch.Tensor, *, node_noise: torch.Tensor | None = None
               ) -> list[RobotData]:
        """Robot graphs decoded from latents ``z`` (``node_noise`` given by keyword: a model's
        ``decode`` may take other arguments before it)."""


def latent_rng(seed: int, index: int, draw: int = 0) -> np.random.Generator:
    """The generator of robot ``index``'s latent in a run with ``seed``: NumPy PCG64 seeded by
    the pair ``(seed, index)``; redraw ``draw > 0`` by ``(seed, index, 2, draw)``."""
    key = [seed, index] if draw == 0 else [seed, index, 2, draw]
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(key)))


def _check_stream(name: str, seed: int, index: int, dim: int, temperature: float, draw: int,
                  **sizes: int) -> None:
    """Refuse a robot stream's arguments out of range (one line, :mod:`robovae.settings`)."""
    check_seed(seed, f"{name} seed")
    check_settings(name, index=(index, integer(0)), dim=(dim, integer(0)),
                   temperature=(temperature, number(0)), draw=(draw, integer(0)),
                   **{k: (v, integer(0)) for k, v in sizes.items()})


def latent(seed: int, index: int, dim: int, temperature: float = 1.0,
           draw: int = 0) -> torch.Tensor:
    """The latent of robot ``index`` of a run with ``seed`` under the standard normal prior:
    ``N(0, T² I)``, ``[dim]`` float32, from :func:`latent_rng`.

    Raises:
        SettingsError: ``seed`` outside ``[0, 2**31 - 1]``, ``index``, ``dim`` or ``draw``
            negative, ``temperature`` negative or not finite.
    """
    _check_stream("latent", seed, index, dim, temperature, draw)
    rng = latent_rng(seed, index, draw)
    return torch.from_numpy(rng.standard_normal(dim).astype(np.float32)) * temperature


def tree_depth(parent: torch.Tensor) -> int:
    """Depth of a pre-order tree given by its parent vector (root -1; a lone root: 0)."""
    depth = [0] * len(parent)
    for i, p in enumerate(parent.tolist()):
        depth[i] = 0 if p < 0 else depth[p] + 1
    return max(depth, default=0)


def unfinished(model: PriorModel, graph: RobotData) -> bool:
    """Whether ``graph``'s decoding reached the model's limits (``max_nodes`` or
    ``max_depth``): its tree was cut off, not finished."""
    hp = model.hparams
    return graph.num_nodes >= hp.max_nodes or tree_depth(graph.parent) >= hp.max_depth


def draw_robots(model: PriorModel, seed: int, indices: Sequence[int], temperature: float = 1.0,
                node_temperature: float | None = None, redraws: int = 0, noise: bool = True,
                ) -> tuple[torch.Tensor, list[RobotData], list[int]]:
    """Decode robots ``indices`` of a run with ``seed`` from the prior (module docstring).

    ``temperature`` scales ``z``, ``node_temperature`` (default: the model's setting, else
    ``temperature``; :mod:`robovae.model.sampling`) the node latents' noise; ``noise=False``
    decodes every node latent at its conditional prior mean instead (decoding from ``z`` alone,
    as :mod:`robovae.design.optimize` does). Returns ``(z, graphs, draws)``: the latents
    decoded ``[B, latent_dim]``, the graphs, and per robot the draw that was kept (0: the
    first; ``k``: after ``k`` redraws of an unfinished tree, at most ``redraws``; the last draw
    is kept even if unfinished).
    """
    z, drawn = model.sample_prior(seed, indices, temperature, node_temperature)
    eps = drawn if noise else None

    def redraw(rows: list[int], k: int) -> tuple[torch.Tensor, list[RobotData]]:
        zk = torch.stack([model.prior_latent(seed, int(indices[b]), temperature, draw=k)
                          for b in rows]).to(z)
        return zk, model.decode(zk, node_noise=None if eps is None else eps[rows])

    return redraw_unfinished(model, z, model.decode(z, node_noise=eps), redraw, redraws)


def redraw_unfinished(model: PriorModel, z: torch.Tensor, graphs: list,
                      redraw: Callable[[list[int], int], tuple[torch.Tensor, list]],
                      redraws: int) -> tuple[torch.Tensor, list, list[int]]:
    """Replace the unfinished decodings (:func:`unfinished`) among ``graphs``, decoded from the
    rows of ``z``: ``redraw(rows, k)`` gives draw ``k`` (1, 2, …, at most ``redraws``) of those
    rows, ``(z_k, graphs_k)``, until every tree is finished. ``z`` and ``graphs`` are updated in
    place; returns ``(z, graphs, draws)``, ``draws`` the draw kept per row (the last is kept even
    if unfinished). The one redraw rule of prior samples (:func:`draw_robots`) and of a robot's
    variations (:func:`robovae.design.variations.draw_variations`)."""
    draws = [0] * len(graphs)
    todo = [b for b, g in enumerate(graphs) if unfinished(model, g)]
    for k in range(1, redraws + 1):
        if not todo:
            break
        zk, again = redraw(todo, k)
        for b, zb, g in zip(todo, zk, again):
            z[b], graphs[b], draws[b] = zb, g, k
        todo = [b for b in todo if unfinished(model, graphs[b])]
    return z, graphs, draws


def node_noise(seed: int, index: int, max_nodes: int, dim: int,
               temperature: float = 1.0) -> torch.Tensor:
    """The node-latent noise of robot ``index``: ``[max_nodes, dim]`` standard normals times
    ``T`` from the robot's second stream (``(seed, index, 1)``), so its node ``t`` draws
    ``w_t = mu^p + sigma^p eps_t`` whatever the batch. At ``T = 0`` (every node at its prior
    mean) the noise is zeros without a draw (0.27 ms a robot saved; the decoded robots are the
    same to the bit, the sign of zero included).

    Raises:
        SettingsError: as :func:`latent` (``max_nodes`` and ``dim`` negative).
    """
    _check_stream("node_noise", seed, index, dim, temperature, 0, max_nodes=max_nodes)
    if temperature == 0:
        return torch.zeros(max_nodes, dim)
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, index, 1])))
    eps = rng.standard_normal((max_nodes, dim)).astype(np.float32)
    return torch.from_numpy(eps) * temperature
