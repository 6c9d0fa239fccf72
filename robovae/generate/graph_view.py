"""A mutable float64 view of a robot graph's features, for the repair rules.

:class:`GraphView` copies ``data.x`` to a float64 NumPy array (physical units, the columns of a
:class:`~robovae.data.features.FeatureSet`) and gives access by registry key
(``view.get(i, "link.mass")``); :meth:`GraphView.to_data` turns it back into a graph of the
kind it came from (a PyG graph or :class:`~robovae.data.tree_arrays.TreeArrays`) whose columns a
node type does not own are exactly 0. Nothing here imports torch (worker processes that write
robots from ``TreeArrays`` never load it).

Graphs store float32. A value a rule raises to a floor or clips to a bound must still satisfy
the bound after that storage: :func:`ceil32` and :func:`floor32` give the nearest float32 on the
safe side.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, cast

import numpy as np
import numpy.typing as npt

from robovae.data.features import Feature, FeatureSet, get_feature_set
from robovae.data.tree_arrays import RobotTree, TreeArrays, children, feature_values

if TYPE_CHECKING:
    from robovae.data.graph import RobotData

__all__ = ["GraphView", "as_feature_set", "ceil32", "floor32", "node_mask", "norm"]


def as_feature_set(feature_set: str | FeatureSet) -> FeatureSet:
    """The registry set of that name, or ``feature_set`` itself.

    Raises:
        KeyError: unknown set name.
    """
    return get_feature_set(feature_set) if isinstance(feature_set, str) else feature_set


def node_mask(fs: FeatureSet, types: npt.ArrayLike) -> np.ndarray:
    """``fs.mask(types)`` as a NumPy ``[N, dim]`` bool array (:meth:`FeatureSet.mask_array`)."""
    return fs.mask_array(types)


class GraphView:
    """Float64 copy of ``data.x`` plus the tree, with feature accessors by registry key.

    Attributes:
        fs: the feature set of the columns.
        x: ``[N, fs.dim]`` float64 copy of ``data.x`` (NaN/Inf kept).
        types: node type per node (``LINK``, ``JOINT``, ``GEOM``).
        parent: parent index per node (``-1`` for the root), pre-order.
        kids: children of every node, in order.
        mask: ``[N, fs.dim]`` bool, the columns each node's type owns.
    """

    def __init__(self, data: RobotTree, fs: FeatureSet) -> None:
        self.fs = fs
        self.x = feature_values(data)
        self.types = data.node_type.tolist()
        self.parent = data.parent.tolist()
        self.kids = children(self.parent)
        self.mask = node_mask(fs, self.types)
        self.keys = {f.key for f in fs.features}

    def has(self, key: str) -> bool:
        """Whether the feature set has the feature ``key``."""
        return key in self.keys

    def nodes(self, node_type: int) -> list[int]:
        """Indices of the nodes of one type, in pre-order."""
        return [i for i, t in enumerate(self.types) if t == node_type]

    def get(self, i: int, key: str) -> np.ndarray:
        """The columns of feature ``key`` of node ``i`` (a view: writing to it changes ``x``)."""
        return self.x[i, self.fs.slice(key)]

    def set(self, i: int, key: str, value: npt.ArrayLike) -> None:
        """Set the columns of feature ``key`` of node ``i`` (a scalar fills them all)."""
        self.x[i, self.fs.slice(key)] = value

    def feature(self, key: str) -> Feature:
        """The registry entry of ``key`` (its range, transform, width)."""
        return next(f for f in self.fs.features if f.key == key)

    def to_data(self, data: RobotTree) -> RobotTree:
        """A copy of ``data`` (same kind) with ``x`` from the view as float32; columns a node
        type does not own are set to 0."""
        x = np.where(self.mask, self.x.astype(np.float32), np.float32(0))
        if isinstance(data, TreeArrays):
            return data.with_x(x)
        import torch  # a PyG graph: torch is loaded already

        out = cast("RobotData", data).clone()
        out.x = torch.from_numpy(x)
        return out


def norm(v: np.ndarray) -> float:
    """``float(np.linalg.norm(v))`` of a 1-D float64 vector, the same value (``np.linalg.norm``
    computes ``sqrt(v.dot(v))`` too) without its Python overhead."""
    return math.sqrt(float(v.dot(v)))


def ceil32(v: float) -> float:
    """The smallest float32 value ≥ ``v`` (so a raised value still passes after storage)."""
    f = np.float32(v)
    return float(f if float(f) >= v else np.nextafter(f, np.float32(np.inf)))


def floor32(v: float) -> float:
    """The largest float32 value ≤ ``v``."""
    f = np.float32(v)
    return float(f if float(f) <= v else np.nextafter(f, np.float32(-np.inf)))
