"""``Normalizer``: the per-column transform and standardisation of node features.

Fitted on a training split, its statistics are buffers that travel in every checkpoint. The
transform of each column (``log`` for heavy tails, ``categorical`` left alone, ``eps`` and
``min_std``) comes from the feature registry (:mod:`robovae.data.features`).
"""

from __future__ import annotations

from collections.abc import Iterator

import torch
from torch import Tensor, nn

from robovae.data.features import FeatureSet, get_feature_set


class Normalizer(nn.Module):
    """Per-column transform + standardisation, fitted on a training split.

    The statistics are buffers, so they travel inside every checkpoint of a module that owns
    the normaliser: ``forward`` maps physical values to model units, :meth:`inverse` back.

    .. math::  \\hat x_{ic} = m_{ic} (T_c(x_{ic}) - \\mu_c) / \\sigma_c

    where ``m`` is the node's column mask (paper §4.1: rows carry zeros in the other types'
    columns). ``low``/``high`` hold each column's training range in model units, so decoded
    samples can be kept on the support of the data (:meth:`inverse` with ``clamp``).
    """

    mean: Tensor
    std: Tensor
    low: Tensor
    high: Tensor
    fitted: Tensor
    # non-persistent buffers, rebuilt from the feature set
    type_mask: Tensor
    is_log: Tensor
    is_cat: Tensor
    eps: Tensor
    min_std: Tensor

    def __init__(self, feature_set: str | FeatureSet) -> None:
        super().__init__()
        fs = get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set
        self.feature_set = fs
        d = fs.dim
        self.register_buffer("mean", torch.zeros(d))
        self.register_buffer("std", torch.ones(d))
        self.register_buffer("low", torch.full((d,), -torch.inf))
        self.register_buffer("high", torch.full((d,), torch.inf))
        self.register_buffer("fitted", torch.zeros((), dtype=torch.bool))
        self.register_buffer("type_mask", fs.type_mask(), persistent=False)
        self.register_buffer("is_log", fs.column_transform("log"), persistent=False)
        self.register_buffer("is_cat", fs.column_transform("categorical"), persistent=False)
        self.register_buffer("eps", fs.column_attr("eps").float(), persistent=False)
        self.register_buffer("min_std", fs.column_attr("min_std").float(), persistent=False)

    def _t(self, x: Tensor) -> Tensor:
        return torch.where(self.is_log, torch.log(x.clamp_min(0.0) + self.eps.clamp_min(1e-12)), x)

    def _t_inv(self, y: Tensor) -> Tensor:
        back = (torch.exp(y.clamp(max=30.0)) - self.eps).clamp_min(0.0)
        return torch.where(self.is_log, back, y)

    @torch.no_grad()
    def fit(self, x: Tensor, node_type: Tensor, rows: Tensor | None = None,
            chunk: int = 1 << 17) -> Normalizer:
        """Fit ``mu``/``sigma`` per column over the nodes that own it (training split only);
        ``sigma_c`` is at least the feature's ``min_std`` (1 for a constant column).

        Two streaming passes over ``chunk`` rows at a time (sums and the range of the
        transformed values, then squared deviations), so fitting on millions of nodes holds a
        few chunk-sized temporaries, never copies of ``x``. ``rows`` (bool, one per row of
        ``x``) selects the nodes to fit on. The range in model units is that of the
        transformed values mapped by ``(t - mu) / sigma``, which keeps their order.
        """
        d, n = x.shape[1], x.shape[0]

        def chunks() -> Iterator[tuple[Tensor, Tensor]]:
            for a in range(0, n, chunk):
                xs, ts = x[a:a + chunk], node_type[a:a + chunk]
                if rows is not None:
                    keep = rows[a:a + chunk]
                    xs, ts = xs[keep], ts[keep]
                if not len(ts):
                    continue
                own = self.type_mask[ts]
                yield torch.where(own, self._t(xs.float()), torch.zeros(())), own

        count, total = torch.zeros(d, dtype=torch.float64), torch.zeros(d, dtype=torch.float64)
        t_low, t_high = torch.full((d,), torch.inf), torch.full((d,), -torch.inf)
        for t, own in chunks():
            count += own.sum(0)
            total += t.double().sum(0)
            t_low = torch.minimum(t_low, torch.where(own, t, torch.inf).amin(0))
            t_high = torch.maximum(t_high, torch.where(own, t, -torch.inf).amax(0))
        mean = (total / count.clamp_min(1.0)).float()
        sq = torch.zeros(d, dtype=torch.float64)
        for t, own in chunks():
            sq += torch.where(own, t - mean, torch.zeros(())).double().square().sum(0)
        std = (sq / count.clamp_min(1.0)).sqrt().float()
        std = torch.where(std < 1e-6, torch.ones_like(std), std)
        std = torch.maximum(std, self.min_std)
        self.mean.copy_(torch.where(self.is_cat, torch.zeros_like(mean), mean))
        self.std.copy_(torch.where(self.is_cat, torch.ones_like(std), std))
        unseen = count == 0
        self.low.copy_(torch.where(unseen, -torch.inf, (t_low - self.mean) / self.std))
        self.high.copy_(torch.where(unseen, torch.inf, (t_high - self.mean) / self.std))
        self.fitted.fill_(True)
        return self

    def forward(self, x: Tensor, node_type: Tensor) -> Tensor:
        """Physical values → normalised model units (zero outside the node's own columns)."""
        mask = self.type_mask[node_type]
        return torch.where(mask, (self._t(x) - self.mean) / self.std, torch.zeros_like(x))

    def inverse(self, y: Tensor, node_type: Tensor, clamp: float | None = None) -> Tensor:
        """Normalised model units → physical values (zero outside the node's own columns).

        With ``clamp = c``, each column is first clipped to its training range widened by
        ``c`` times its width on both sides: ``[lo - c (hi - lo), hi + c (hi - lo)]``.
        """
        mask = self.type_mask[node_type]
        if clamp is not None:
            width = (self.high - self.low).nan_to_num(nan=0.0, posinf=0.0)
            lo = (self.low - clamp * width).nan_to_num(neginf=-1e6)
            hi = (self.high + clamp * width).nan_to_num(posinf=1e6)
            y = torch.maximum(torch.minimum(y, hi), lo)
        return torch.where(mask, self._t_inv(y * self.std + self.mean), torch.zeros_like(y))

    def extra_repr(self) -> str:
        """Feature set name and whether the statistics were fitted."""
        return f"feature_set={self.feature_set.name}, fitted={bool(self.fitted)}"
