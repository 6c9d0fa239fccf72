"""Ancestral sampling from a trained :class:`~robovae.model.vae.RoboVAE`: the prior draws of a
generation run (:mod:`robovae.model.prior`) in the model's units and sampling settings.

A sample is ``z`` from the sampling prior (``prior``: the latent mixture fitted to the training
robots, or ``N(0, I)``) at temperature ``T`` (its spread times ``T``), then node by node
``w_t = mu^p_t + sigma^p_t * T_w * eps_t`` from the node latents' conditional prior with
``eps_t ~ N(0, I)``. The node temperature ``T_w`` is the caller's when given, else the model's
``node_temperature`` setting, else ``T``; ``T_w = 0`` puts every node's detail at its prior
mean (decoding from ``z`` alone).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch import Tensor

from robovae.data.graph import RobotData
from robovae.errors import SettingsError, check_seed
from robovae.model.latent_mixture import LatentMixture, principal_basis
from robovae.model.prior import latent, latent_rng, node_noise
from robovae.settings import check_settings, integer, number

__all__ = ["PriorSampling"]


class PriorSampling:
    """Sampling methods of :class:`~robovae.model.vae.RoboVAE` (a mixin: it reads the model's
    ``hparams``, ``latent_mixture``, ``dtype`` and :meth:`decode`)."""

    hparams: Any
    latent_mixture: LatentMixture | None
    dtype: torch.dtype

    def node_temperature_for(self, temperature: float = 1.0,
                             node_temperature: float | None = None) -> float:
        """The node latents' temperature ``T_w`` of a draw at ``temperature``: the given
        ``node_temperature``, else the model's ``node_temperature`` setting, else
        ``temperature`` (module docstring)."""
        if node_temperature is None:
            node_temperature = self.hparams.get("node_temperature")
        return float(temperature if node_temperature is None else node_temperature)

    def sample_prior(self, seed: int, indices: Sequence[int], temperature: float = 1.0,
                     node_temperature: float | None = None) -> tuple[Tensor, Tensor]:
        """``(z, node_noise)`` of robots ``indices`` of a generation run with ``seed``: the
        arguments of :meth:`decode` for ancestral sampling. ``z`` is ``[B, latent_dim]``
        (:meth:`prior_latent` at ``temperature``), ``node_noise`` ``[B, max_nodes,
        node_latent_dim]`` (:func:`~robovae.model.prior.node_noise` at
        :meth:`node_temperature_for`), both in the model's dtype; robot ``i`` draws the same
        values in any batch.

        Raises:
            SettingsError: ``seed`` out of ``[0, 2**31 - 1]``, a negative index, a temperature
                that is not a finite number ``>= 0``.
        """
        check_seed(seed, "sample_prior seed")
        check_settings("sample_prior", temperature=(temperature, number(0)),
                       node_temperature=(node_temperature, number(0).or_none()))
        index = integer(0)
        bad = [i for i in indices if not index.test(i)][:1]
        if bad or not len(indices):
            raise SettingsError(f"robovae: sample_prior.indices must be a non-empty sequence of "
                                f"integers >= 0, got {'no index' if not bad else bad[0]!r}")
        hp = self.hparams
        t_w = self.node_temperature_for(temperature, node_temperature)
        z = torch.stack([self.prior_latent(seed, int(i), temperature) for i in indices])
        noise = torch.stack([node_noise(seed, int(i), hp.max_nodes, hp.node_latent_dim, t_w)
                             for i in indices])
        return z.to(self.dtype), noise.to(self.dtype)

    def sampling_mixture(self) -> LatentMixture | None:
        """The sampling mixture when the model samples from one (``prior``) and has it."""
        mix = self.latent_mixture
        use = self.hparams.get("prior", "standard") == "mixture"
        return mix if use and mix is not None and bool(mix.fitted) else None

    def prior_moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean ``m`` ``[latent_dim]`` and covariance ``C`` ``[latent_dim, latent_dim]``
        (float64) of the sampling prior: the fitted mixture's
        (:meth:`~robovae.model.latent_mixture.LatentMixture.moments`), else ``0`` and ``I``."""
        mix = self.sampling_mixture()
        if mix is None:
            d = int(self.hparams.latent_dim)
            return np.zeros(d), np.eye(d)
        return mix.moments()

    def prior_directions(self, variance: float) -> tuple[np.ndarray, np.ndarray]:
        """``(m, B)``: the sampling prior's mean and the basis ``B = U_k diag(lambda_k)^{1/2}``
        of its principal subspace holding the share ``variance`` of its variance
        (:func:`~robovae.model.latent_mixture.principal_basis`), so that ``z = m + B y`` with
        ``y ~ N(0, I_k)`` is spread like the prior there. ``robovae optimize`` searches ``y``
        (``variance`` 0.9); ``robovae generate --like`` draws its variations in ``y``'s units
        (0.95)."""
        mean, cov = self.prior_moments()
        return mean, principal_basis(cov, variance)

    def prior_latent(self, seed: int, index: int, temperature: float = 1.0,
                     draw: int = 0) -> Tensor:
        """Robot ``index``'s latent ``[latent_dim]`` (float32) of a run with ``seed``, draw
        ``draw``, from the sampling prior (``prior``): the fitted mixture, else ``N(0, T² I)``
        (:func:`~robovae.model.prior.latent`); each from the robot's own generator
        (:func:`~robovae.model.prior.latent_rng`)."""
        mix = self.sampling_mixture()
        if mix is None:
            return latent(seed, index, self.hparams.latent_dim, temperature, draw)
        return mix.draw(latent_rng(seed, index, draw), temperature)

    @torch.no_grad()
    def sample(self, n: int, temperature: float = 1.0,
               generator: torch.Generator | None = None,
               node_temperature: float | None = None) -> list[RobotData]:
        """Decode ``n`` robots of the sampling prior at ``temperature`` (node latents at
        :meth:`node_temperature_for`): those of a generation run (:meth:`sample_prior`) whose
        seed is drawn from ``generator``.

        Raises:
            SettingsError: ``n`` not an integer ``>= 0`` (0: no robot), a temperature as
                :meth:`sample_prior` refuses.
        """
        check_settings("sample", n=(n, integer(0)))
        seed = int(torch.randint(0, 2**31 - 1, (1,), generator=generator))
        if n == 0:
            return []
        z, noise = self.sample_prior(seed, range(n), temperature, node_temperature)
        return self.decode(z, node_noise=noise)  # type: ignore[attr-defined]
