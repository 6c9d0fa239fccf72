"""The feature registry: the single source of truth for node features.

A :class:`FeatureSet` declares, for every column of the node feature matrix ``X`` (paper §4.1),
which node type owns it, its physical range, its unit and its transform. Everything else —
graph extraction, losses, metrics, the MJCF writer, normalisation — reads widths, masks and
ranges from here.

Normalisation (SPEC §2) maps a physical value ``v`` of column ``c`` to

.. math::  \\hat v = (T_c(v) - \\mu_c) / \\sigma_c, \\qquad
           T_c(v) = \\log(\\max(v, 0) + \\epsilon_c)
           \\text{ (heavy-tailed non-negative columns; else } T_c(v) = v),

with ``mu``/``sigma`` fitted on the training split over the nodes that own the column. One-hot
and flag columns are left as they are.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import cache
from typing import TYPE_CHECKING, Literal

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:  # torch is imported where a tensor is made: worker processes that only
    from torch import Tensor  # write and simulate robots never load it

Transform = Literal["none", "log", "categorical"]

#: Node type ids shared by every robot feature set. Synthetic sets use id 0 only.
LINK, JOINT, GEOM = 0, 1, 2

#: MuJoCo joint types in ``mjtJoint`` order (free=0, ball=1, slide=2, hinge=3).
JOINT_TYPES = ("free", "ball", "slide", "hinge")
#: Geom primitives a geom node may decode to, and their ``mjtGeom`` ids.
GEOM_TYPES = ("sphere", "capsule", "ellipsoid", "cylinder", "box")
GEOM_TYPE_IDS = (2, 3, 4, 5, 6)

_INF = math.inf


@dataclass(frozen=True)
class Feature:
    """One named feature of one node type.

    Attributes:
        name: short name, unique within its node type (``pos``, ``mass``, ...).
        node_type: the node type that owns the columns (``link``, ``joint``, ``geom``, ``node``).
        width: number of columns.
        low, high: physical range (used by validity rules and for clamping decoded values).
        transform: ``log`` for heavy-tailed non-negative values, ``categorical`` for one-hot and
            flags (not standardised), ``none`` otherwise.
        eps: offset of the log transform, in the feature's unit.
        min_std: smallest ``sigma_c`` of the normalisation, in transformed units: a column that
            barely varies in the training data (a quaternion that is the identity on most
            links) is not blown up to hundreds of standard deviations by its rare other values.
        unit: physical unit.
        source: where the value comes from in the compiled ``mujoco.MjModel``.
        doc: description (paper Table 1 wording where it applies).
    """

    name: str
    node_type: str
    width: int
    low: float = -_INF
    high: float = _INF
    transform: Transform = "none"
    eps: float = 0.0
    unit: str = ""
    source: str = ""
    doc: str = ""
    min_std: float = 0.0

    @property
    def key(self) -> str:
        """``<node_type>.<name>``, the feature's unique key in a set."""
        return f"{self.node_type}.{self.name}"


@dataclass(frozen=True)
class FeatureSet:
    """An ordered list of features with the derived column layout.

    Attributes:
        name: registry name (``paper34``, ``full``, ``random5``, ...).
        node_types: node type names, index = node type id.
        features: features in column order.
    """

    name: str
    node_types: tuple[str, ...]
    features: tuple[Feature, ...]
    _slices: dict[str, slice] = field(init=False, repr=False, compare=False)
    _type_mask: np.ndarray = field(init=False, repr=False, compare=False)
    _torch_mask: Tensor | None = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        slices, start = {}, 0
        for f in self.features:
            if f.node_type not in self.node_types:
                raise ValueError(f"feature {f.key} has unknown node type {f.node_type!r}")
            if f.key in slices:
                raise ValueError(f"feature {f.key} declared twice in {self.name}")
            slices[f.key] = slice(start, start + f.width)
            start += f.width
        object.__setattr__(self, "_slices", slices)
        mask = np.zeros((len(self.node_types), start), dtype=bool)
        for f in self.features:
            mask[self.node_types.index(f.node_type), slices[f.key]] = True
        object.__setattr__(self, "_type_mask", mask)

    def __getstate__(self) -> dict:
        """Pickled without the cached torch mask: a worker process unpickling a set need not
        import torch."""
        return {k: v for k, v in self.__dict__.items() if k != "_torch_mask"}

    @property
    def dim(self) -> int:
        """Total number of columns ``d``."""
        return sum(f.width for f in self.features)

    @property
    def num_node_types(self) -> int:
        return len(self.node_types)

    @property
    def columns(self) -> list[str]:
        """Column names, e.g. ``joint.range[0]``, ``link.mass``."""
        out = []
        for f in self.features:
            out += [f.key] if f.width == 1 else [f"{f.key}[{i}]" for i in range(f.width)]
        return out

    def slice(self, key: str) -> slice:
        """Columns of feature ``key`` (``<node_type>.<name>``)."""
        return self._slices[key]

    def features_of(self, node_type: str) -> list[Feature]:
        """The features of node type ``node_type`` (``link``/``joint``/...), in column order."""
        return [f for f in self.features if f.node_type == node_type]

    def type_mask(self) -> Tensor:
        """Boolean ``[num_node_types, dim]``: which columns belong to which node type (a
        fresh copy)."""
        import torch

        return torch.from_numpy(self._type_mask.copy())

    def mask_array(self, node_type: npt.ArrayLike) -> np.ndarray:
        """:meth:`mask` as a NumPy array, for node type ids in any sequence (no torch needed)."""
        return self._type_mask[np.asarray(node_type, dtype=np.int64)]

    def mask(self, node_type: Tensor) -> Tensor:
        """Per-node column mask ``[N, dim]`` for a vector of node type ids."""
        mask = self._torch_mask
        if mask is None:
            mask = self.type_mask()
            object.__setattr__(self, "_torch_mask", mask)
        return mask[node_type]

    def column_attr(self, attr: str) -> Tensor:
        """A per-column tensor of a :class:`Feature` attribute (``low``, ``high``, ``eps``)."""
        vals = []
        for f in self.features:
            vals += [float(getattr(f, attr))] * f.width
        import torch

        return torch.tensor(vals, dtype=torch.float64)

    def column_transform(self, transform: Transform) -> Tensor:
        """Boolean ``[dim]``: columns whose transform is ``transform``."""
        out = []
        for f in self.features:
            out += [f.transform == transform] * f.width
        import torch

        return torch.tensor(out, dtype=torch.bool)

    def empty(self, n: int) -> Tensor:
        """A zero feature matrix for ``n`` nodes."""
        import torch

        return torch.zeros(n, self.dim, dtype=torch.float32)


# --- the declarations ------------------------------------------------------------------------

_R = math.pi * 2  # hinge ranges beyond +-2pi are unusual but legal


def _joint_paper() -> list[Feature]:
    """Appendix E, joint rows (12 columns)."""
    return [
        Feature("range", "joint", 2, -1e3, 1e3, unit="rad|m", source="jnt_range",
                doc="Allowed motion limits [min, max] (zero when unlimited)"),
        Feature("stiffness", "joint", 1, 0.0, 1e6, "log", 1e-3, "N·m/rad", "jnt_stiffness",
                "Joint stiffness (spring constant)"),
        Feature("axis", "joint", 3, -1.0, 1.0, min_std=0.1, unit="", source="jnt_axis",
                doc="Axis of rotation / translation, unit vector (local frame)"),
        Feature("pos", "joint", 3, -10.0, 10.0, min_std=0.005, unit="m", source="jnt_pos",
                doc="Anchor position of the joint in its body frame"),
        Feature("armature", "joint", 1, 0.0, 1e3, "log", 1e-5, "kg·m²", "dof_armature",
                "Added rotational inertia for the joint's first DoF"),
        Feature("damping", "joint", 1, 0.0, 1e4, "log", 1e-3, "N·m·s/rad", "dof_damping",
                "Viscous damping coefficient"),
        Feature("frictionloss", "joint", 1, 0.0, 1e4, "log", 1e-3, "N·m", "dof_frictionloss",
                "Static friction before motion occurs"),
    ]


def _link_paper() -> list[Feature]:
    """Appendix E, body rows (22 columns)."""
    return [
        Feature("pos", "link", 3, -10.0, 10.0, min_std=0.005, unit="m", source="body_pos",
                doc="Body position in its parent frame"),
        Feature("mass", "link", 1, 0.0, 1e4, "log", 1e-4, "kg", "body_mass", "Mass of the body"),
        Feature("inertia", "link", 3, 0.0, 1e4, "log", 1e-7, "kg·m²", "body_inertia",
                "Diagonal inertia in the inertial frame"),
        Feature("quat", "link", 4, -1.0, 1.0, min_std=0.1, source="body_quat",
                doc="Orientation in the parent frame, unit quaternion (w, x, y, z)"),
        Feature("subtreemass", "link", 1, 0.0, 1e5, "log", 1e-4, "kg", "body_subtreemass",
                "Mass of the body and its descendants"),
        Feature("ipos", "link", 3, -10.0, 10.0, min_std=0.005, unit="m", source="body_ipos",
                doc="Centre of mass in the body frame"),
        Feature("iquat", "link", 4, -1.0, 1.0, min_std=0.1, source="body_iquat",
                doc="Orientation of the inertial frame in the body frame"),
        Feature("size", "link", 3, 0.0, 10.0, "log", 1e-4, "m", "geom_size",
                "Size of the body's first collision geom (else first geom; zero if none)"),
    ]


def _joint_full() -> list[Feature]:
    return [
        Feature("type", "joint", len(JOINT_TYPES), 0.0, 1.0, "categorical", source="jnt_type",
                doc="Joint type one-hot: " + ", ".join(JOINT_TYPES)),
        Feature("limited", "joint", 1, 0.0, 1.0, "categorical", source="jnt_limited",
                doc="1 when the joint range is enforced"),
        *_joint_paper(),
        Feature("actuated", "joint", 1, 0.0, 1.0, "categorical", source="actuator_trnid",
                doc="1 when an actuator drives this joint"),
        Feature("gear", "joint", 1, -1e4, 1e4, unit="", source="actuator_gear[0]",
                doc="Gear of the first actuator on this joint (0 when none)"),
        Feature("ctrlrange", "joint", 2, -1e4, 1e4, unit="", source="actuator_ctrlrange",
                doc="Control range of that actuator (0, 0 when unlimited/none)"),
    ]


def _joint_kinematic() -> list[Feature]:
    """``full``'s joint columns with the actuator as one convention-free strength."""
    return [
        *_joint_full()[:-2],
        Feature("torque", "joint", 1, 0.0, 1e5, "log", 1e-2, "N·m|N", "actuator_gear",
                "Strength of the joint's actuators: the largest force they can apply "
                "(robovae.data.actuators; 0 when none or unbounded)"),
    ]


def _link_box() -> list[Feature]:
    """The link's collision shape as one box (``kinematic``: a tree without geom nodes that still
    tells the writer where a foot or a head is)."""
    return [
        Feature("box_pos", "link", 3, -10.0, 10.0, min_std=0.005, unit="m", source="geom_aabb",
                doc="Centre of the oriented box bounding the body's collision geoms (else all "
                    "its geoms), body frame (zero if none)"),
        Feature("box_axes", "link", 6, -1.0, 1.0, min_std=0.1, source="geom_aabb",
                doc="Orientation of that box in the body frame as the matrix u1 u1ᵀ - u3 u3ᵀ "
                    "of its longest and shortest axes (entries xx, yy, zz, xy, xz, yz; one "
                    "value per box orientation, robovae.data.box_axes). The axes: the "
                    "principal axes of the geoms' corners; the body axes when those bound "
                    "them as tightly"),
        Feature("box_half", "link", 3, 0.0, 10.0, "log", 1e-4, "m", "geom_aabb",
                "Half-sizes of that box along its own axes, longest first (zero if none)"),
    ]


def _geom_full() -> list[Feature]:
    return [
        Feature("type", "geom", len(GEOM_TYPES), 0.0, 1.0, "categorical", source="geom_type",
                doc="Geom primitive one-hot: " + ", ".join(GEOM_TYPES)
                + " (a mesh becomes a box of its bounding size)"),
        Feature("pos", "geom", 3, -10.0, 10.0, min_std=0.005, unit="m", source="geom_pos",
                doc="Geom position in its body frame"),
        Feature("quat", "geom", 4, -1.0, 1.0, min_std=0.1, source="geom_quat",
                doc="Geom orientation in its body frame"),
        Feature("size", "geom", 3, 0.0, 10.0, "log", 1e-4, "m", "geom_size",
                doc="Primitive size parameters (MuJoCo convention)"),
        Feature("friction", "geom", 3, 0.0, 10.0, "log", 1e-5, "", "geom_friction",
                doc="Sliding, torsional, rolling friction"),
        Feature("collides", "geom", 1, 0.0, 1.0, "categorical", source="geom_contype",
                doc="1 when contype or conaffinity is non-zero"),
    ]


@cache
def get_feature_set(name: str) -> FeatureSet:
    """The registered feature set called ``name``.

    ``paper34`` (appendix E, link + joint), ``kinematic`` (the same link/joint tree, plus the
    joint's type, limit flag and actuator strength and the link's collision box), ``full``
    (adds joint type, actuator and geom nodes) or ``random<d>`` (the paper's synthetic trees:
    ``d`` features in [0, 1] on one node type).
    """
    if name == "paper34":
        return FeatureSet("paper34", ("link", "joint"), tuple(_joint_paper() + _link_paper()))
    if name == "kinematic":
        return FeatureSet("kinematic", ("link", "joint"),
                          tuple(_joint_kinematic() + _link_paper() + _link_box()))
    if name == "full":
        return FeatureSet(
            "full", ("link", "joint", "geom"),
            tuple(_joint_full() + _link_paper() + _geom_full()),
        )
    m = re.fullmatch(r"random(\d+)", name)
    if m and int(m.group(1)) > 0:
        feats = tuple(Feature(f"f{i}", "node", 1, 0.0, 1.0) for i in range(int(m.group(1))))
        return FeatureSet(name, ("node",), feats)
    raise KeyError(f"unknown feature set {name!r} (known: paper34, kinematic, full, random<d>)")


FEATURE_SETS = ("paper34", "kinematic", "full")


def feature_table(name: str) -> str:
    """Markdown reference of a feature set: a heading and one row per feature (key, width,
    range, transform, unit, MuJoCo source, description). ``docs/data.md`` holds the tables of
    :data:`FEATURE_SETS` as printed by ``python -m robovae.data.features``; a test keeps them
    equal to the registry."""
    fs = get_feature_set(name)
    lines = [f"### `{fs.name}` ({fs.dim} columns; node types: {', '.join(fs.node_types)})", "",
             "| key | width | range | transform | unit | MuJoCo source | description |",
             "|---|---|---|---|---|---|---|"]
    for f in fs.features:
        cells = [f"`{f.key}`", str(f.width), f"[{f.low:g}, {f.high:g}]", f.transform, f.unit,
                 f"`{f.source}`" if f.source else "", f.doc]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    print("\n\n".join(feature_table(n) for n in FEATURE_SETS))
