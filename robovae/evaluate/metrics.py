"""Reconstruction metrics (SPEC §4): RA, RA_true, exact match, FRE and per-feature error.

**Matching.** The decoded tree is matched to the true tree from the roots down: the two roots
form a pair, and the ``k``-th child (in canonical pre-order) of a matched pair's true node is
matched to the ``k``-th child of its decoded node. Children without a partner (extra children in
the output, missing children in the output) are unmatched, and so are their whole subtrees.
Matching is purely **structural**: a matched pair whose node types disagree still has its
children matched, but the pair itself is not *correct*.

**Correct nodes.** A matched pair ``(i, j)`` is correct when ``type_true[i] == type_pred[j]``.
With ``C`` the number of correct pairs, ``N_true``/``N_pred`` the node counts:

.. math::

    \\mathrm{RA} = C / N_{pred}, \\qquad \\mathrm{RA_{true}} = C / N_{true}, \\qquad
    \\mathrm{exact} = [C = N_{true} = N_{pred}]

RA is the paper's metric (extra output nodes are penalised); RA_true penalises missing subtrees.

**FRE** is the mean squared error in normalised model units over every (node, own column)
entry of the correct nodes:

.. math::

    \\mathrm{FRE} = \\frac{\\sum_{(i,j) \\in \\mathcal C} \\sum_{c \\in M(t_i)}
        (\\hat x^{pred}_{jc} - \\hat x^{true}_{ic})^2}{\\sum_{(i,j) \\in \\mathcal C} |M(t_i)|}

where ``M(t)`` is the set of columns owned by node type ``t`` and ``\\hat x = `` the
normaliser's output (raw values when no normaliser is given). Nodes outside ``\\mathcal C``
(unmatched or wrong type) have no ground truth to compare with and are excluded, as in the
paper. FRE is ``nan`` when there is no scored entry.

**Per-feature error** (physical units): for every feature key ``k`` of the feature set (e.g.
``link.mass``), the mean absolute error over all columns of ``k`` and all correct nodes whose
type owns ``k``; ``nan`` when no correct node owns it. Quaternions are compared component-wise
(no sign canonicalisation).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch
from torch import Tensor
from torch_geometric.data import Data

from robovae.data.features import FeatureSet, get_feature_set
from robovae.data.normalizer import Normalizer

__all__ = ["Reconstruction", "match_trees", "reconstruction_metrics", "summarize"]


@dataclass
class Reconstruction:
    """Reconstruction result for one robot.

    Attributes:
        name: robot name (from the true graph).
        ra: correct nodes / nodes in the output tree.
        ra_true: correct nodes / nodes in the true tree.
        exact: the trees are identical in structure and node types.
        fre: feature MSE over correct nodes and their own columns, normalised units (nan when
            there is no correct node).
        n_true, n_pred, n_correct: node counts.
        feature_mae: mean absolute error per feature key, physical units (nan when no correct
            node owns the feature).
    """

    name: str
    ra: float
    ra_true: float
    exact: bool
    fre: float
    n_true: int
    n_pred: int
    n_correct: int
    feature_mae: dict[str, float] = field(default_factory=dict)


def _as_list(v: Tensor | Sequence[int]) -> list[int]:
    return v.view(-1).tolist() if isinstance(v, Tensor) else [int(a) for a in v]


def _children(parent: list[int]) -> tuple[int, list[list[int]]]:
    """Root index and children lists (in index order, i.e. canonical order for pre-order)."""
    kids: list[list[int]] = [[] for _ in parent]
    root = -1
    for i, p in enumerate(parent):
        if p < 0:
            if root < 0:
                root = i
        else:
            kids[p].append(i)
    return root, kids


def match_trees(
    true_parent: Tensor | Sequence[int],
    true_type: Tensor | Sequence[int],
    pred_parent: Tensor | Sequence[int],
    pred_type: Tensor | Sequence[int],
) -> list[tuple[int, int]]:
    """Structurally match two rooted ordered trees from the roots down.

    The roots are matched; for every matched pair ``(i, j)`` and every ``k < min(#children)``,
    the ``k``-th child of ``i`` in the true tree is matched to the ``k``-th child of ``j`` in the
    predicted tree. Matching ignores node types (a wrong-type pair still has its children
    matched); use the types to decide which pairs are *correct*. Iterative, so trees of any
    depth are fine.

    Args:
        true_parent: parent vector of the true tree (root = -1), children in canonical order.
        pred_parent: parent vector of the decoded tree, same convention.
        true_type: node type per node of the true tree (only checked for length).
        pred_type: node type per node of the decoded tree (only checked for length).

    Returns:
        Matched ``(true_idx, pred_idx)`` pairs in depth-first pre-order of the matched subtree,
        root pair first. Empty when either tree is empty.
    """
    tp, pp = _as_list(true_parent), _as_list(pred_parent)
    if len(_as_list(true_type)) != len(tp) or len(_as_list(pred_type)) != len(pp):
        raise ValueError("parent and type vectors differ in length")
    t_root, t_kids = _children(tp)
    p_root, p_kids = _children(pp)
    if t_root < 0 or p_root < 0:
        return []
    pairs: list[tuple[int, int]] = []
    stack = [(t_root, p_root)]
    while stack:
        i, j = stack.pop()
        pairs.append((i, j))
        stack.extend(reversed(list(zip(t_kids[i], p_kids[j]))))
    return pairs


def _resolve_feature_set(
    feature_set: str | FeatureSet | None, normalizer: Normalizer | None
) -> FeatureSet | None:
    if isinstance(feature_set, str):
        return get_feature_set(feature_set)
    if feature_set is not None:
        return feature_set
    if normalizer is not None:
        return normalizer.feature_set
    return None


def reconstruction_metrics(
    true: Data,
    pred: Data,
    normalizer: Normalizer | None = None,
    feature_set: str | FeatureSet | None = None,
) -> Reconstruction:
    """RA, RA_true, exact, FRE and per-feature MAE of a decoded robot against the truth.

    ``RA = C / N_pred``, ``RA_true = C / N_true``, ``exact = (C == N_true == N_pred)`` with ``C``
    the number of matched pairs (see :func:`match_trees`) whose node types agree.
    ``FRE = sum_{correct (i,j)} sum_{c in own cols(t_i)} (n(x_pred)_jc - n(x_true)_ic)^2 /
    sum_{correct} |own cols(t_i)|`` with ``n`` the normaliser (identity when ``None``).
    ``feature_mae[k] = mean |x_pred - x_true|`` over the columns of feature ``k`` and the
    correct nodes owning it, physical units.

    Args:
        true: the true robot graph (``parent``, ``node_type``, physical ``x``).
        pred: the decoded robot graph, same attributes.
        normalizer: maps physical ``x`` to model units for FRE; ``None`` scores raw values.
        feature_set: the column layout; defaults to the normaliser's. Without either, the
            own-column mask is taken from ``true.x_mask`` and ``feature_mae`` is empty.

    Returns:
        A :class:`Reconstruction`.
    """
    t_type = _as_list(true.node_type)
    p_type = _as_list(pred.node_type)
    n_true, n_pred = len(t_type), len(p_type)
    pairs = match_trees(true.parent, t_type, pred.parent, p_type)
    correct = [(i, j) for i, j in pairs if t_type[i] == p_type[j]]
    n_correct = len(correct)
    ra = n_correct / n_pred if n_pred else 0.0
    ra_true = n_correct / n_true if n_true else 0.0
    exact = n_correct == n_true == n_pred

    fs = _resolve_feature_set(feature_set, normalizer)
    fre = math.nan
    feature_mae: dict[str, float] = {}
    if fs is not None:
        feature_mae = {f.key: math.nan for f in fs.features}
    if n_correct:
        ti = torch.tensor([i for i, _ in correct], dtype=torch.long)
        pj = torch.tensor([j for _, j in correct], dtype=torch.long)
        types = torch.as_tensor(t_type, dtype=torch.long)[ti]
        xt = true.x[ti].detach().float().cpu()
        xp = pred.x[pj].detach().float().cpu()
        if fs is not None:
            mask = fs.mask(types)
        elif getattr(true, "x_mask", None) is not None:
            mask = true.x_mask[ti].bool().cpu()
        else:
            mask = torch.ones_like(xt, dtype=torch.bool)

        if normalizer is not None:
            dev = normalizer.mean.device
            with torch.no_grad():
                nt = normalizer(xt.to(dev), types.to(dev)).cpu()
                np_ = normalizer(xp.to(dev), types.to(dev)).cpu()
        else:
            nt, np_ = xt, xp
        sq = (np_.double() - nt.double()) ** 2
        count = int(mask.sum())
        if count:
            fre = float(sq[mask].sum() / count)

        if fs is not None:
            abs_err = (xp.double() - xt.double()).abs()
            for f in fs.features:
                owners = types == fs.node_types.index(f.node_type)
                if bool(owners.any()):
                    feature_mae[f.key] = float(abs_err[owners][:, fs.slice(f.key)].mean())

    return Reconstruction(
        name=str(getattr(true, "name", "") or ""), ra=ra, ra_true=ra_true, exact=exact,
        fre=fre, n_true=n_true, n_pred=n_pred, n_correct=n_correct, feature_mae=feature_mae,
    )


def _nanmean(values: list[float]) -> float:
    vals = [v for v in values if not math.isnan(v)]
    return sum(vals) / len(vals) if vals else math.nan


def summarize(results: list[Reconstruction]) -> dict[str, float]:
    """Aggregate per-robot results (each robot weighs the same).

    Returns:
        ``ra`` = mean RA, ``ra_true`` = mean RA_true, ``exact`` = share of exact matches,
        ``fre`` = mean of the per-robot FRE ignoring nan, ``count`` = number of robots, and
        ``mae/<feature key>`` = mean of the per-robot feature MAE ignoring nan. Means of an
        empty list are nan.
    """
    n = len(results)
    out: dict[str, float] = {
        "ra": sum(r.ra for r in results) / n if n else math.nan,
        "ra_true": sum(r.ra_true for r in results) / n if n else math.nan,
        "exact": sum(float(r.exact) for r in results) / n if n else math.nan,
        "fre": _nanmean([r.fre for r in results]),
        "count": float(n),
    }
    keys: dict[str, None] = {}
    for r in results:
        keys.update(dict.fromkeys(r.feature_mae))
    for k in keys:
        out[f"mae/{k}"] = _nanmean([r.feature_mae.get(k, math.nan) for r in results])
    return out
