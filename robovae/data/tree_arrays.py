"""A robot graph as NumPy arrays: what the writer's worker processes receive.

The MJCF writer, its repair rules and the validator read three fields of a robot graph
(:mod:`robovae.data.graph`): ``x`` ``[N, d]`` physical feature values, ``node_type`` ``[N]``
and ``parent`` ``[N]`` (pre-order, root ``-1``). :class:`TreeArrays` holds them as NumPy
arrays. A worker process given one unpickles it without importing torch and PyG, which a
PyG ``Data`` would need: a spawned worker of ``robovae generate`` starts on 0.6 s of CPU
instead of 3.9 s, the difference the work of about a hundred robots (docs/generation.md,
"Workers without torch").

Every function of :mod:`robovae.generate` that takes a robot graph takes either; it returns
the kind it was given (:meth:`TreeArrays.with_x`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias

import numpy as np

if TYPE_CHECKING:
    import torch

#: node indices or ids: a list, a NumPy array or a tensor (no torch import at run time)
_IntVector: TypeAlias = "Sequence[int] | np.ndarray | torch.Tensor"

__all__ = ["RobotTree", "TreeArrays", "children", "feature_values", "shared_nodes"]


@dataclass(frozen=True, eq=False)
class TreeArrays:
    """The fields of a robot graph the writer reads, as NumPy arrays.

    Attributes:
        x: ``[N, d]`` float32 physical feature values (the columns of a
            :class:`~robovae.data.features.FeatureSet`).
        node_type: ``[N]`` int64 node type ids.
        parent: ``[N]`` int64 parent index per node (``-1`` for the root), pre-order.
        name: robot name.
    """

    x: np.ndarray
    node_type: np.ndarray
    parent: np.ndarray
    name: str = ""

    @classmethod
    def of(cls, graph: Any) -> TreeArrays:
        """The arrays of a robot graph (a PyG ``Data`` or a :class:`TreeArrays`)."""
        if isinstance(graph, TreeArrays):
            return graph
        return cls(x=_numpy(graph.x).astype(np.float32, copy=True),
                   node_type=_numpy(graph.node_type).astype(np.int64, copy=True),
                   parent=_numpy(graph.parent).astype(np.int64, copy=True),
                   name=str(getattr(graph, "name", "") or ""))

    @property
    def num_nodes(self) -> int:
        """Number of nodes ``N``."""
        return int(self.x.shape[0])

    def with_x(self, x: np.ndarray) -> TreeArrays:
        """A copy with feature values ``x`` (stored as float32), the tree unchanged."""
        return replace(self, x=np.asarray(x, dtype=np.float32))


class RobotTree(Protocol):
    """A robot graph as the writer takes it: a PyG graph (:class:`~robovae.data.graph.
    RobotData`) or its :class:`TreeArrays`; ``x``, ``node_type`` and ``parent`` are tensors or
    NumPy arrays."""

    @property
    def x(self) -> Any: ...

    @property
    def node_type(self) -> Any: ...

    @property
    def parent(self) -> Any: ...


def _numpy(a: Any) -> np.ndarray:
    """A NumPy view of a NumPy array or a (CPU or device) torch tensor."""
    if isinstance(a, np.ndarray):
        return a
    return a.detach().cpu().numpy()


def feature_values(graph: RobotTree) -> np.ndarray:
    """A float64 copy of ``graph.x`` (NaN and Inf kept)."""
    return _numpy(graph.x).astype(np.float64)


def _as_list(a: Sequence[int] | Any) -> list[int]:
    """A list of a list, a NumPy array or a tensor."""
    return a.tolist() if hasattr(a, "tolist") else list(a)


def children(parent: Sequence[int] | Any) -> list[list[int]]:
    """Children lists in canonical order for a pre-order parent vector (a list, a NumPy array
    or a tensor)."""
    par = _as_list(parent)
    out: list[list[int]] = [[] for _ in par]
    for i, p in enumerate(par):
        if p >= 0:
            out[p].append(i)
    return out


def _paths(parent: Sequence[int]) -> list[tuple[int, ...]]:
    """Each node's place in its tree: the child ranks on its path from the root (``()`` for the
    root; rank 0 for the first child of its parent, in pre-order)."""
    out: list[tuple[int, ...]] = []
    ranks: dict[int, int] = {}
    for p in parent:
        if p < 0:
            out.append(())
        else:
            ranks[p] = ranks.get(p, -1) + 1
            out.append(out[p] + (ranks[p],))
    return out


def shared_nodes(source: tuple[_IntVector, _IntVector],
                 target: tuple[_IntVector, _IntVector]) -> np.ndarray:
    """For each node of the ``target`` tree, the node of the ``source`` tree it shares, or -1.

    Both trees are given as ``(parent, node_type)`` in pre-order (root ``-1``; lists, arrays
    or tensors). A target node shares the source node at the same place — reached from the
    root by the same child ranks — when the two have the same type: the matching of the
    reconstruction metrics (:mod:`robovae.evaluate.metrics`, its *correct* pairs). Equal trees
    share every node (``[0, 1, …]``); a limb added to the target shares nothing of its own, the
    nodes after it in pre-order still share theirs.
    """
    (sp, st), (tp, tt) = map(_as_list, source), map(_as_list, target)
    index = {path: i for i, path in enumerate(_paths(sp))}
    out = [index.get(path, -1) for path in _paths(tp)]
    return np.array([j if j >= 0 and st[j] == tt[i] else -1 for i, j in enumerate(out)],
                    dtype=np.int64)
