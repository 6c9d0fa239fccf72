"""Does the generator cover a real robot's tree? Shape statistics of real and generated robots.

For a robot graph (``full`` feature set): nodes of the link/joint tree, links, joints,
degrees of freedom (free 6, ball 3, hinge/slide 1), limbs (:func:`robovae.data.graph.limbs`)
and the tree shape: an AHU canonical string of the rooted link/joint tree with node types,
equal for two graphs exactly when their trees are isomorphic with matching types (children
unordered). :func:`ordered_tree` is the tree with its children in file order, the way
reconstruction accuracy matches a decoded tree to the truth (k-th child to k-th child);
:func:`plan_tree` gives the same string from a procedural plan without building it.

:func:`coverage_rows` samples ``n`` robots of each class and reports, for each real robot, the
ranges of its class and whether each statistic lies in them, and whether some sampled robot has
exactly its tree, unordered and ordered.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import torch

from robovae.data.features import get_feature_set
from robovae.data.graph import RobotData, children, limbs
from robovae.data.mjcf import mjcf_to_graph
from robovae.data.procedural.batch import ProceduralSource, procedural_graphs
from robovae.data.procedural.blueprint import Part, RobotPlan

#: Class of each Menagerie robot of ``../shared/menagerie`` (the unseen test set).
MENAGERIE_CLASSES = {
    "unitree_go1": "quadruped", "unitree_go2": "quadruped", "unitree_a1": "quadruped",
    "boston_dynamics_spot": "quadruped", "google_barkour_v0": "quadruped",
    "google_barkour_vb": "quadruped", "berkeley_humanoid": "humanoid",
    "booster_t1": "humanoid", "fourier_n1": "humanoid", "pal_talos": "humanoid",
    "unitree_g1": "humanoid", "unitree_h1": "humanoid", "agility_cassie": "biped",
    "unitree_z1": "arm", "agilex_piper": "arm", "pal_tiago": "mobile_manipulator",
    "pal_tiago_dual": "mobile_manipulator",
}
_DOF = {0: 6, 1: 3, 2: 1, 3: 1}  # joint.type one-hot column -> degrees of freedom


def tree_shape(data: RobotData) -> str:
    """AHU canonical string of the rooted tree labelled with node types."""
    kids = children(data.parent)
    types = data.node_type.tolist()
    code = [""] * len(types)
    for i in range(len(types) - 1, -1, -1):  # pre-order: children come after their parent
        code[i] = f"{types[i]}(" + "".join(sorted(code[c] for c in kids[i])) + ")"
    return code[0]


def ordered_tree(data: RobotData) -> str:
    """The tree with children in file order: ``L`` link, ``J`` joint, ``G`` geom, each
    followed by its children in brackets, e.g. ``J(L(J(L)J(L)))``."""
    kids = children(data.parent)
    letters = ["LJG"[t] for t in data.node_type.tolist()]
    code = [""] * len(letters)
    for i in range(len(letters) - 1, -1, -1):
        code[i] = letters[i] + (f"({''.join(code[c] for c in kids[i])})" if kids[i] else "")
    return code[0]


def plan_tree(plan: RobotPlan) -> str:
    """:func:`ordered_tree` of the ``paper34`` graph of a procedural ``plan`` (the free joint
    on top when the plan floats), computed from the plan alone."""

    def edge(part: Part) -> str:
        code = "L" + (f"({''.join(edge(c) for c in part.children)})" if part.children else "")
        for _ in part.joints:
            code = f"J({code})"
        return code

    code = edge(plan.root)
    return f"J({code})" if plan.floating else code


def shape_stats(data: RobotData) -> dict:
    """Nodes and links without geoms, joints, DoF (free 6, ball 3, hinge and slide 1) and
    limbs of a graph of the ``full`` feature set.

    Raises:
        ValueError: another feature set (joint types are read from ``joint.type``).
    """
    fs = get_feature_set("full")
    if data.x.shape[1] != fs.dim:
        raise ValueError("shape statistics need a graph of the 'full' feature set")
    joints = data.node_type == 1
    kinds = data.x[joints][:, fs.slice("joint.type")].argmax(1).tolist()
    links = int((data.node_type == 0).sum())
    return {"nodes": links + len(kinds), "links": links, "joints": len(kinds),
            "dof": sum(_DOF[k] for k in kinds), "limbs": limbs(data)}


def coverage_rows(robots: Mapping[str, tuple[str, Path]], n: int = 2000, seed: int = 0,
                  jobs: int = 0) -> list[dict]:
    """One row per real robot ``{name: (class, file)}``: its statistics, the range
    ``min-max`` of its class over ``n`` sampled robots, ``in range`` (every statistic inside),
    ``same tree`` (some sampled robot has exactly its tree shape, children unordered) and
    ``same ordered tree`` (some sampled robot has its tree with children in the same order)."""
    stats: dict[str, dict] = {}
    for kind in sorted({k for k, _ in robots.values()}):
        graphs = procedural_graphs(ProceduralSource(n, seed, {kind: 1.0}), "full", jobs)
        rows = [shape_stats(g) for g in graphs]
        trees = [links_and_joints(g) for g in graphs]
        stats[kind] = {"ranges": {k: (min(r[k] for r in rows), max(r[k] for r in rows))
                                  for k in rows[0]},
                       "shapes": {tree_shape(t) for t in trees},
                       "ordered": {ordered_tree(t) for t in trees}}
    out = []
    for name, (kind, path) in robots.items():
        g = mjcf_to_graph(path, "full")
        s = shape_stats(g)
        ranges = stats[kind]["ranges"]
        row: dict = {"robot": name, "class": kind}
        for k, v in s.items():
            lo, hi = ranges[k]
            row[k] = f"{v} ({lo}-{hi})"
        row["in range"] = "yes" if all(ranges[k][0] <= v <= ranges[k][1]
                                       for k, v in s.items()) else "no"
        tree = links_and_joints(g)
        row["same tree"] = "yes" if tree_shape(tree) in stats[kind]["shapes"] else "no"
        row["same ordered tree"] = "yes" if ordered_tree(tree) in stats[kind]["ordered"] \
            else "no"
        out.append(row)
    return out


def links_and_joints(data: RobotData) -> RobotData:
    """The ``paper34``-style tree (geom leaves dropped) of a ``full`` graph: geoms are leaves
    listed under their link, so dropping them keeps a pre-order tree."""
    keep = (data.node_type != 2).nonzero().view(-1)
    index = {int(old): new for new, old in enumerate(keep.tolist())}
    parent = [index[int(data.parent[i])] if int(data.parent[i]) >= 0 else -1
              for i in keep.tolist()]
    return RobotData(parent=torch.tensor(parent), node_type=data.node_type[keep],
                     num_nodes=len(parent))
