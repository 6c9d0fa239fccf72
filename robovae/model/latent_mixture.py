"""``LatentMixture``: a Gaussian mixture fitted to the training robots' latents, to sample from.

A VAE is trained so that the *aggregate posterior* ``q(z) = E_G q(z | G)`` is close to
``N(0, I)``, but at a KL of a few tens of nats per robot it is not: robot classes form
clusters in the few latent directions that carry the robot (the tree latent), and the standard
normal puts much of its mass between them, where the decoder makes hybrids (a two-legged
trunk with a quadruped's hips). Ex-post density estimation (Ghosh et al. 2020, *From
variational to deterministic autoencoders*) fits a density to the posterior means
``mu(G)`` of the training robots after training and samples from it instead:

.. math::  p(z) = \\sum_k \\pi_k \\, \\mathcal N(z; m_k, \\operatorname{diag} s_k^2)

fitted by expectation-maximisation on ``mu(G)`` (:meth:`LatentMixture.fit`), each variance at
least ``min_std²``. Sampling at temperature ``T`` draws a component, then
``z = m_k + T s_k ε``. The parameters are buffers: they travel in the model's checkpoint.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import Tensor, nn
from torch_geometric.data import Batch

from robovae.settings import check_settings, integer, number

__all__ = ["LatentMixture", "fit_to_robots", "principal_basis"]


class LatentMixture(nn.Module):
    """A diagonal Gaussian mixture over latents ``[latent_dim]`` with ``components`` parts.

    Args:
        latent_dim: width of the latents.
        components: number of mixture components ``K``.
    """

    weights: Tensor
    means: Tensor
    stds: Tensor
    fitted: Tensor

    def __init__(self, latent_dim: int, components: int) -> None:
        super().__init__()
        check_settings("LatentMixture", latent_dim=(latent_dim, integer(1)),
                       components=(components, integer(1)))
        self.register_buffer("weights", torch.full((components,), 1.0 / components))
        self.register_buffer("means", torch.zeros(components, latent_dim))
        self.register_buffer("stds", torch.ones(components, latent_dim))
        self.register_buffer("fitted", torch.zeros((), dtype=torch.bool))

    @torch.no_grad()
    def log_prob(self, z: Tensor) -> Tensor:
        """``log p(z)`` of latents ``[N, D]`` under the mixture, ``[N]``."""
        return torch.logsumexp(self._joint(z.to(self.means), self.weights.log(), self.means,
                                           self.stds.square()), dim=1)

    @staticmethod
    def _joint(z: Tensor, logw: Tensor, means: Tensor, var: Tensor) -> Tensor:
        """``log pi_k + log N(z_n; m_k, diag var_k)``, ``[N, K]``, without an ``[N, K, D]``
        temporary."""
        inv = 1.0 / var
        quad = (z.square() @ inv.T - 2.0 * z @ (means * inv).T
                + (means.square() * inv).sum(1)[None])
        norm = var.log().sum(1) + z.shape[1] * math.log(2 * math.pi)
        return logw[None] - 0.5 * (quad + norm[None])

    @torch.no_grad()
    def fit(self, mu: Tensor, iters: int = 200, min_std: float = 0.05, seed: int = 0,
            tol: float = 1e-6) -> LatentMixture:
        """Fit by EM to the rows of ``mu`` ``[N, D]`` (``N >= K``): means initialised at ``K``
        distinct rows drawn with ``seed``, stopped after ``iters`` steps or when the mean
        log-likelihood gains less than ``tol``. Float64 inside; returns ``self``.

        Raises:
            ValueError: ``mu`` not ``[N, latent_dim]``, fewer rows than components, or rows
                that are not finite (a diverged model's latents: the mixture is left as it was).
        """
        x = mu.detach().double().cpu()
        n, k = x.shape[0], self.means.shape[0]
        if x.ndim != 2 or x.shape[1] != self.means.shape[1]:
            raise ValueError(f"robovae: a latent mixture of dimension {self.means.shape[1]} is "
                             f"fitted to latents [N, {self.means.shape[1]}], got "
                             f"{list(x.shape)}")
        bad = int((~torch.isfinite(x).all(1)).sum())
        if bad:
            raise ValueError(f"robovae: {bad} of {n} latents to fit the mixture to are not "
                             "finite (NaN or inf: did training diverge?)")
        if n < k:
            raise ValueError(f"robovae: fitting {k} mixture components needs at least {k} "
                             f"latents, got {n}")
        g = torch.Generator().manual_seed(seed)
        means = x[torch.randperm(n, generator=g)[:k]].clone()
        var = x.var(0, unbiased=False).clamp_min(min_std ** 2).expand(k, -1).clone()
        logw = torch.full((k,), -math.log(k), dtype=torch.float64)
        last = -math.inf
        for _ in range(iters):
            joint = self._joint(x, logw, means, var)
            ll = torch.logsumexp(joint, dim=1, keepdim=True)
            resp = (joint - ll).exp()
            nk = resp.sum(0).clamp_min(1e-10)
            means = (resp.T @ x) / nk[:, None]
            var = ((resp.T @ x.square()) / nk[:, None] - means.square()).clamp_min(min_std ** 2)
            logw = (nk / n).log()
            mean_ll = float(ll.mean())
            if mean_ll - last < tol:
                break
            last = mean_ll
        self.weights.copy_(logw.exp() / logw.exp().sum())
        self.means.copy_(means)
        self.stds.copy_(var.sqrt())
        self.fitted.fill_(True)
        return self

    def draw(self, rng: np.random.Generator, temperature: float = 1.0) -> Tensor:
        """One latent ``[D]`` float32 from ``rng``: a component ``k ~ pi``, then
        ``m_k + T s_k ε``."""
        w = self.weights.double().cpu().numpy()
        k = int(rng.choice(len(w), p=w / w.sum()))
        eps = torch.from_numpy(rng.standard_normal(self.means.shape[1]).astype(np.float32))
        return self.means[k].float().cpu() + temperature * self.stds[k].float().cpu() * eps

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean ``[D]`` and covariance ``[D, D]`` (float64) of the mixture:

        .. math::  m = \\sum_k \\pi_k m_k, \\qquad
                   C = \\sum_k \\pi_k (\\mathrm{diag}(s_k^2) + m_k m_k^\\top) - m m^\\top
        """
        w = self.weights.double().cpu().numpy()
        w = w / w.sum()
        means = self.means.double().cpu().numpy()
        var = self.stds.double().cpu().numpy() ** 2
        m = w @ means
        cov = np.diag(w @ var) + (means * w[:, None]).T @ means - np.outer(m, m)
        return m, 0.5 * (cov + cov.T)


def principal_basis(cov: np.ndarray, variance: float) -> np.ndarray:
    """``B = U_k diag(lambda_k)^{1/2}`` ``[d, k]``: the fewest leading eigenvectors of ``cov``
    (``cov = U diag(lambda) U^T``, ``lambda`` descending), scaled by their standard deviations,
    that hold the share ``variance`` of its trace (``sum_{i<=k} lambda_i >= variance ·
    tr cov``). ``z = m + B y`` maps the whitened coordinates ``y`` of the principal subspace
    to latents: ``y ~ N(0, I_k)`` has the covariance of ``cov`` in that subspace.

    Raises:
        SettingsError: ``variance`` not a number in ``(0, 1]`` (0 kept one direction, 2 or NaN
            all of them).
    """
    check_settings("principal_basis", variance=(variance, number(0, 1, low_open=True)))
    lam, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    lam, vecs = np.clip(lam[::-1], 0.0, None), vecs[:, ::-1]
    share = np.cumsum(lam) / lam.sum()
    k = min(int(np.searchsorted(share, variance - 1e-9)) + 1, len(lam))
    return vecs[:, :k] * np.sqrt(lam[:k])


@torch.no_grad()
def fit_to_robots(mixture: LatentMixture, encode: Callable[[Batch], tuple[Tensor, Tensor]],
                  robots: Sequence, max_robots: int = 20_000, batch_size: int = 256,
                  seed: int = 0) -> LatentMixture:
    """Fit ``mixture`` to the posterior means ``encode(batch)[0]`` of ``robots`` (a sequence of
    graphs, e.g. a training split): all of them, or ``max_robots`` drawn with ``seed`` (the
    same ones in every process of a data-parallel run). At least as many robots as
    components; with fewer, the mixture is left unfitted."""
    n = len(robots)
    if n < mixture.means.shape[0]:
        return mixture
    pick = torch.arange(n) if n <= max_robots else \
        torch.randperm(n, generator=torch.Generator().manual_seed(seed))[:max_robots].sort()[0]
    mus = []
    for k in range(0, len(pick), batch_size):
        batch = Batch.from_data_list([robots[int(i)] for i in pick[k:k + batch_size]])
        mus.append(encode(batch)[0].detach().cpu())
    return mixture.fit(torch.cat(mus), seed=seed)
