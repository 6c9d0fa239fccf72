"""Drawings of robot trees: a tidy top-down layout and a networkx plot coloured by node type.

:func:`tree_layout` places a pre-order tree with its leaves on consecutive integers ``x`` (in
pre-order), every parent centred over its first and last child, and ``y = -depth``.
:func:`draw_graph` draws the tree in that layout, root at the top, nodes coloured and shaped by
type (:data:`NODE_TYPE_NAMES`, :data:`NODE_TYPE_COLORS`, :data:`NODE_TYPE_MARKERS`), with a
legend of the node counts per type.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from robovae.data.graph import children

__all__ = ["NODE_TYPE_COLORS", "NODE_TYPE_MARKERS", "NODE_TYPE_NAMES", "draw_graph",
           "tree_layout"]

#: Legend names of node types 0, 1, 2.
NODE_TYPE_NAMES = ("link", "joint", "geom")
#: Colours of node types 0, 1, 2.
NODE_TYPE_COLORS = ("#4C72B0", "#DD8452", "#55A868")
#: Matplotlib markers of node types 0, 1, 2.
NODE_TYPE_MARKERS = ("o", "s", "^")


def tree_layout(parent: Sequence[int] | Any) -> dict[int, tuple[float, float]]:
    """A tidy top-down layout of a pre-order tree: leaves on consecutive x in pre-order, each
    parent centred over its first and last child, ``y = -depth``. Returns ``{node: (x, y)}``."""
    par = parent.tolist() if hasattr(parent, "tolist") else list(parent)
    n = len(par)
    kids = children(par)
    depth = [0] * n
    for i in range(1, n):
        depth[i] = depth[par[i]] + 1
    x = [0.0] * n
    leaf = 0
    for i in range(n):  # pre-order: leaves left to right
        if not kids[i]:
            x[i] = float(leaf)
            leaf += 1
    for i in reversed(range(n)):  # children have larger indices than their parent
        if kids[i]:
            x[i] = 0.5 * (x[kids[i][0]] + x[kids[i][-1]])
    return {i: (x[i], -float(depth[i])) for i in range(n)}


def draw_graph(data: Any, path: str | os.PathLike | None = None, ax: Any = None,
               title: str | None = None,
               type_names: Sequence[str] = NODE_TYPE_NAMES) -> Figure | Path:
    """Draw a robot tree (root at the top), nodes coloured and shaped by type, with a legend.

    Args:
        data: a :class:`~robovae.data.graph.RobotData` (or anything with ``parent`` and
            optionally ``node_type``).
        path: write a PNG there and return the path; otherwise return the figure.
        ax: draw into this matplotlib axes instead of a new figure.
        title: axes title; default: ``data.name``.
        type_names: legend names of node types 0, 1, 2.
    """
    import networkx as nx

    parent = data.parent.tolist() if hasattr(data.parent, "tolist") else list(data.parent)
    n = len(parent)
    types_attr = getattr(data, "node_type", None)
    types = ([int(t) for t in types_attr.tolist()] if types_attr is not None else [0] * n)
    pos = tree_layout(parent)
    g = nx.DiGraph()
    g.add_nodes_from(range(n))
    g.add_edges_from((p, i) for i, p in enumerate(parent) if p >= 0)
    leaves = max(1, sum(1 for k in children(parent) if not k))
    depth = int(-min(y for _, y in pos.values())) if n else 0
    if ax is None:
        fig = Figure(figsize=(min(max(4.0, 0.42 * leaves + 1.5), 40.0),
                              min(max(3.0, 0.75 * (depth + 1) + 1.0), 30.0)), dpi=100)
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    node_size = 260 if n <= 40 else 120 if n <= 150 else 40
    nx.draw_networkx_edges(g, pos, ax=ax, arrows=False, edge_color="#888888", width=1.2)
    handles = []
    for t in sorted(set(types)):
        nodes = [i for i in range(n) if types[i] == t]
        name = type_names[t] if t < len(type_names) else f"type {t}"
        color = NODE_TYPE_COLORS[t % len(NODE_TYPE_COLORS)]
        marker = NODE_TYPE_MARKERS[t % len(NODE_TYPE_MARKERS)]
        nx.draw_networkx_nodes(g, pos, nodelist=nodes, ax=ax, node_color=color,
                               node_shape=marker, node_size=node_size, edgecolors="black",
                               linewidths=0.6)
        handles.append(Line2D([], [], linestyle="", marker=marker, markerfacecolor=color,
                              markeredgecolor="black", markersize=9,
                              label=f"{name} ({len(nodes)})"))
    if n <= 60:
        nx.draw_networkx_labels(g, pos, ax=ax, font_size=7, font_color="white")
    ax.legend(handles=handles, loc="upper right", fontsize=8, frameon=True)
    ax.set_title(title if title is not None else (getattr(data, "name", "") or "robot graph"))
    ax.set_axis_off()
    ax.margins(0.08)
    if path is None:
        return fig
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight", format="png")
    return path
