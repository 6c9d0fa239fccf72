"""Procedural legged robots, built as real MJCF with ``mujoco.MjSpec``.

A robot is generated in two steps, both deterministic for a seed:

1. :func:`procedural_plan` samples a :class:`RobotPlan` with ``numpy.random.default_rng(seed)``:
   a torso and a list of limbs, each limb a chain of segments, each segment one body with one
   or two hinge joints (axes among x/y/z, ranges ``lo < 0 < hi``, damping, armature) and a
   capsule/box (head: sphere) geom with an explicit mass or a density; legs end in a foot sphere
   and arms in a hand sphere.
2. :func:`procedural_spec` turns the plan into a ``mujoco.MjSpec``: ``worldbody`` holds exactly one
   body (the torso, with a free joint), every hinge gets one motor actuator (``ctrlrange``,
   ``gear``). No floor, light or camera is added: the file contains only the robot.

Kinds (:data:`KINDS`): ``quadruped`` (4 legs in side pairs), ``hexapod`` (6 legs in side
pairs), ``humanoid`` (upright torso, 2 legs, 2 arms and a head on a neck hinge) and ``legged``
(2–8 legs spread radially around the torso). :func:`write_procedural` writes many robots to
disk, in parallel for large batches.

Body / joint / actuator counts of a compiled model follow the plan::

    nbody = 2 + plan.num_segments          # world + torso + one body per segment
    njnt  = 1 + plan.num_hinges            # free joint + hinges
    nu    = plan.num_hinges if config.actuators else 0
"""

from __future__ import annotations

import math
import os
import tempfile
import warnings
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from multiprocessing import get_all_start_methods, get_context
from pathlib import Path

import mujoco
import numpy as np

__all__ = [
    "KINDS",
    "LimbPlan",
    "ProceduralConfig",
    "RobotPlan",
    "SegmentPlan",
    "build_spec",
    "procedural_name",
    "procedural_plan",
    "procedural_spec",
    "write_procedural",
]

#: Robot kinds the generator knows.
KINDS = ("quadruped", "hexapod", "humanoid", "legged")

Range = tuple[float, float]
IntRange = tuple[int, int]

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
_GEOM = {
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
}


@dataclass(frozen=True)
class ProceduralConfig:
    """Sampling ranges of the procedural generator (lengths in m, angles in rad, SI units).

    Every ``(lo, hi)`` pair is sampled uniformly (integers inclusive).

    Attributes:
        kinds: kinds drawn from when :func:`procedural_spec` gets ``kind=None``.
        legged_legs: number of legs of the generic ``legged`` kind.
        leg_segments, arm_segments: bodies per leg / arm.
        symmetric_prob: probability that all legs (and both arms) of a robot share one sampled
            template; otherwise every limb is sampled on its own.
        two_hinge_prob: probability that a segment carries two hinges (distinct axes) not one.
        torso_length, torso_width, torso_height: torso half-sizes (x, y, z).
        torso_geoms: torso primitives of non-humanoids (humanoids use capsule or box).
        torso_mass: explicit torso mass, used with probability ``explicit_mass_prob``.
        segment_length, segment_radius: segment length and capsule radius / box half-width.
        segment_geoms: segment primitives.
        segment_mass: explicit segment mass, used with probability ``explicit_mass_prob``.
        density: geom density when no explicit mass is used (kg/m³).
        explicit_mass_prob: probability that a geom gets ``mass`` rather than ``density``.
        foot_radius, hand_radius, head_radius: end-effector sphere radii.
        hip_tilt: first leg segment's angle below horizontal.
        knee_tilt: later leg segments' angle below horizontal.
        joint_lower, joint_upper: hinge range ends (``lower < 0 < upper`` always).
        damping, armature: hinge damping and armature.
        actuators: add one motor per hinge.
        gear: motor gear; ``ctrlrange`` is ``[-ctrl_limit, ctrl_limit]``.
        self_collision: when False, robot geoms get ``conaffinity=0`` (they still collide with
            a default floor but not with each other).
        clearance: gap between the robot's lowest point and ``z = 0`` at ``qpos0``.
    """

    kinds: tuple[str, ...] = KINDS
    legged_legs: IntRange = (2, 8)
    leg_segments: IntRange = (2, 3)
    arm_segments: IntRange = (2, 3)
    symmetric_prob: float = 0.7
    two_hinge_prob: float = 0.3
    torso_length: Range = (0.12, 0.35)
    torso_width: Range = (0.07, 0.16)
    torso_height: Range = (0.04, 0.10)
    torso_geoms: tuple[str, ...] = ("box", "capsule", "sphere")
    torso_mass: Range = (1.0, 8.0)
    segment_length: Range = (0.08, 0.28)
    segment_radius: Range = (0.015, 0.045)
    segment_geoms: tuple[str, ...] = ("capsule", "capsule", "box")
    segment_mass: Range = (0.05, 1.0)
    density: Range = (300.0, 1500.0)
    explicit_mass_prob: float = 0.5
    foot_radius: Range = (0.02, 0.05)
    hand_radius: Range = (0.02, 0.045)
    head_radius: Range = (0.06, 0.11)
    hip_tilt: Range = (0.0, 0.6)
    knee_tilt: Range = (0.9, 1.5)
    joint_lower: Range = (-1.5, -0.2)
    joint_upper: Range = (0.2, 1.5)
    damping: Range = (0.05, 2.0)
    armature: Range = (0.002, 0.05)
    actuators: bool = True
    gear: Range = (10.0, 120.0)
    ctrl_limit: float = 1.0
    self_collision: bool = False
    clearance: float = 0.02

    def __post_init__(self) -> None:
        for k in self.kinds:
            if k not in KINDS:
                raise ValueError(f"unknown procedural kind {k!r} (known: {', '.join(KINDS)})")
        for g in (*self.torso_geoms, *self.segment_geoms):
            if g not in _GEOM:
                raise ValueError(f"unknown geom type {g!r} (known: {', '.join(_GEOM)})")
        if self.joint_lower[1] >= 0 or self.joint_upper[0] <= 0:
            raise ValueError("joint ranges must satisfy lower < 0 < upper")
        if min(self.legged_legs[0], self.leg_segments[0], self.arm_segments[0]) < 1:
            raise ValueError("limb and segment counts must be >= 1")


@dataclass(frozen=True)
class SegmentPlan:
    """One limb segment: a body whose origin is its hinge(s), and its geom.

    The geom runs from the body origin along ``direction`` for ``length`` (sphere segments
    are a sphere of diameter ``length`` centred half-way).
    """

    length: float
    radius: float
    geom: str
    direction: tuple[float, float, float]
    axes: tuple[str, ...]
    ranges: tuple[Range, ...]
    damping: tuple[float, ...]
    armature: tuple[float, ...]
    gear: tuple[float, ...]
    mass: float | None
    density: float | None

    @property
    def tip(self) -> np.ndarray:
        """End of the segment in its body frame (the next segment's origin)."""
        return np.asarray(self.direction) * self.length


@dataclass(frozen=True)
class LimbPlan:
    """A chain of segments attached to the torso at ``anchor`` (torso frame)."""

    role: str  # "leg", "arm" or "head"
    anchor: tuple[float, float, float]
    segments: tuple[SegmentPlan, ...]
    end_radius: float  # foot / hand sphere radius, 0 for none
    end_mass: float | None
    end_density: float | None


@dataclass(frozen=True)
class RobotPlan:
    """Everything :func:`procedural_spec` needs to build one robot."""

    name: str
    kind: str
    seed: int
    torso_geom: str
    torso_size: tuple[float, float, float]  # half-sizes along x, y, z
    torso_upright: bool  # humanoid: capsule axis along z instead of x
    torso_mass: float | None
    torso_density: float | None
    limbs: tuple[LimbPlan, ...]
    height: float = 0.0  # torso z at qpos0, so the lowest point sits ``clearance`` above z=0
    actuators: bool = True
    ctrl_limit: float = 1.0
    self_collision: bool = False

    @property
    def num_limbs(self) -> int:
        return len(self.limbs)

    @property
    def num_segments(self) -> int:
        """Bodies below the torso."""
        return sum(len(limb.segments) for limb in self.limbs)

    @property
    def num_hinges(self) -> int:
        return sum(len(s.axes) for limb in self.limbs for s in limb.segments)

    def roles(self) -> dict[str, int]:
        """Number of limbs per role, e.g. ``{"leg": 2, "arm": 2, "head": 1}``."""
        out: dict[str, int] = {}
        for limb in self.limbs:
            out[limb.role] = out.get(limb.role, 0) + 1
        return out


# --- sampling ----------------------------------------------------------------------------------


def procedural_name(kind: str, seed: int) -> str:
    """Model (and file stem) name of a robot, e.g. ``proc_quadruped_00042``."""
    return f"proc_{kind}_{seed:05d}"


def _u(rng: np.random.Generator, r: Range) -> float:
    """Uniform in ``[r[0], r[1])`` (``rng.random()`` is several times faster than ``uniform``)."""
    return r[0] + (r[1] - r[0]) * rng.random()


def _direction(outward: np.ndarray, tilt: float) -> tuple[float, float, float]:
    """Unit vector ``tilt`` rad below the horizontal unit vector ``outward``."""
    c = math.cos(tilt)
    return (c * float(outward[0]), c * float(outward[1]), -math.sin(tilt))


@dataclass
class _Template:
    """Direction-free part of a limb, shared by symmetric limbs."""

    lengths: list[float]
    radii: list[float]
    geoms: list[str]
    tilts: list[float]
    axes: list[tuple[str, ...]]
    ranges: list[tuple[Range, ...]]
    damping: list[tuple[float, ...]]
    armature: list[tuple[float, ...]]
    gear: list[tuple[float, ...]]
    masses: list[float | None]
    densities: list[float | None]
    end_radius: float
    end_mass: float | None
    end_density: float | None


def _mass_or_density(rng: np.random.Generator, cfg: ProceduralConfig, mass: Range
                     ) -> tuple[float | None, float | None]:
    if rng.random() < cfg.explicit_mass_prob:
        return _u(rng, mass), None
    return None, _u(rng, cfg.density)


def _template(rng: np.random.Generator, cfg: ProceduralConfig, role: str, n_seg: int
              ) -> _Template:
    lengths, radii, geoms, tilts = [], [], [], []
    axes, ranges, damping, armature, gear, masses, densities = [], [], [], [], [], [], []
    for k in range(n_seg):
        lengths.append(_u(rng, cfg.segment_length))
        radii.append(_u(rng, cfg.segment_radius))
        geoms.append(str(cfg.segment_geoms[rng.integers(len(cfg.segment_geoms))]))
        if role == "leg":
            tilts.append(_u(rng, cfg.hip_tilt) if k == 0 and n_seg > 1 else _u(rng, cfg.knee_tilt))
        else:  # arms hang down and out
            tilts.append(_u(rng, (0.9, 1.45)))
        n_hinge = 2 if rng.random() < cfg.two_hinge_prob else 1
        ax = tuple("xyz"[int(i)] for i in rng.permutation(3)[:n_hinge])  # distinct axes
        axes.append(ax)
        ranges.append(tuple((_u(rng, cfg.joint_lower), _u(rng, cfg.joint_upper))
                            for _ in ax))
        damping.append(tuple(_u(rng, cfg.damping) for _ in ax))
        armature.append(tuple(_u(rng, cfg.armature) for _ in ax))
        gear.append(tuple(_u(rng, cfg.gear) for _ in ax))
        m, d = _mass_or_density(rng, cfg, cfg.segment_mass)
        masses.append(m)
        densities.append(d)
    end_r = _u(rng, cfg.foot_radius if role == "leg" else cfg.hand_radius)
    end_m, end_d = _mass_or_density(rng, cfg, (0.01, 0.2))
    return _Template(lengths, radii, geoms, tilts, axes, ranges, damping, armature, gear,
                     masses, densities, end_r, end_m, end_d)


def _limb(t: _Template, role: str, anchor: Sequence[float], outward: np.ndarray) -> LimbPlan:
    segs = tuple(
        SegmentPlan(length=t.lengths[k], radius=t.radii[k], geom=t.geoms[k],
                    direction=_direction(outward, t.tilts[k]), axes=t.axes[k],
                    ranges=t.ranges[k], damping=t.damping[k], armature=t.armature[k],
                    gear=t.gear[k], mass=t.masses[k], density=t.densities[k])
        for k in range(len(t.lengths))
    )
    return LimbPlan(role, tuple(float(a) for a in anchor), segs, t.end_radius, t.end_mass,
                    t.end_density)


def _limbs_of(rng: np.random.Generator, cfg: ProceduralConfig, role: str, n_seg: IntRange,
              places: list[tuple[np.ndarray, np.ndarray]]) -> list[LimbPlan]:
    """One limb per (anchor, outward) place, from one shared or per-limb templates."""
    symmetric = rng.random() < cfg.symmetric_prob
    shared = _template(rng, cfg, role, int(rng.integers(n_seg[0], n_seg[1] + 1)))
    out = []
    for anchor, outward in places:
        t = shared if symmetric else _template(rng, cfg, role,
                                               int(rng.integers(n_seg[0], n_seg[1] + 1)))
        out.append(_limb(t, role, anchor, outward))
    return out


def _side_places(n_legs: int, size: tuple[float, float, float]) -> list[tuple[np.ndarray,
                                                                              np.ndarray]]:
    """Legs in left/right pairs along the torso's x axis (an odd leg goes to the rear)."""
    length, width, _ = size
    pairs = n_legs // 2
    xs = np.linspace(0.8 * length, -0.8 * length, pairs) if pairs > 1 else np.zeros(pairs)
    places = []
    for x in xs:
        for side in (1.0, -1.0):
            out = np.array([0.4 * x / max(length, 1e-9), side, 0.0])
            places.append((np.array([x, side * width, 0.0]), out / np.linalg.norm(out)))
    if n_legs % 2:
        places.append((np.array([-length, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])))
    return places


def _radial_places(rng: np.random.Generator, n_legs: int, size: tuple[float, float, float]
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Legs spread evenly around the torso outline (an ellipse of its x/y half-sizes)."""
    phase = float(rng.uniform(0.0, 2.0 * math.pi / n_legs))
    places = []
    for k in range(n_legs):
        a = phase + 2.0 * math.pi * k / n_legs
        c, s = math.cos(a), math.sin(a)
        places.append((np.array([size[0] * c, size[1] * s, 0.0]), np.array([c, s, 0.0])))
    return places


def _lowest_point(plan: RobotPlan) -> float:
    """Lowest z of the robot in the torso frame at ``qpos0`` (conservative for boxes)."""
    lx, ly, lz = plan.torso_size
    if plan.torso_geom == "sphere":
        low = -lx
    elif plan.torso_geom == "capsule" and plan.torso_upright:
        low = -(lz + lx)
    elif plan.torso_geom == "capsule":
        low = -ly
    else:
        low = -lz
    for limb in plan.limbs:
        p = np.asarray(limb.anchor, dtype=float)
        for seg in limb.segments:
            reach = seg.radius * (math.sqrt(2.0) if seg.geom == "box" else 1.0)
            end = p + seg.tip
            low = min(low, p[2] - reach, end[2] - reach)
            p = end
        low = min(low, p[2] - limb.end_radius)
    return float(low)


def procedural_plan(seed: int, kind: str | None = None,
                    config: ProceduralConfig | None = None) -> RobotPlan:
    """Sample the plan of one robot (deterministic for ``seed``, ``kind`` and ``config``).

    Args:
        seed: seed of ``numpy.random.default_rng``.
        kind: one of :data:`KINDS`; ``None`` draws one from ``config.kinds``.
        config: sampling ranges (defaults to :class:`ProceduralConfig()`).
    """
    cfg = config or ProceduralConfig()
    rng = np.random.default_rng(seed)
    if kind is None:
        kind = str(cfg.kinds[rng.integers(len(cfg.kinds))])
    if kind not in KINDS:
        raise ValueError(f"unknown procedural kind {kind!r} (known: {', '.join(KINDS)})")

    upright = kind == "humanoid"
    if upright:
        geom = "capsule" if rng.random() < 0.5 else "box"
        w = _u(rng, cfg.torso_width)
        size = (0.7 * w, w, _u(rng, (1.2, 2.2)) * w)  # tall and flat
    else:
        geom = str(cfg.torso_geoms[rng.integers(len(cfg.torso_geoms))])
        length, w = _u(rng, cfg.torso_length), _u(rng, cfg.torso_width)
        h = min(_u(rng, cfg.torso_height), w)
        if geom == "sphere":
            size = (w, w, w)
        elif geom == "capsule":  # capsule along x: radius w, half-length `length`
            size = (length, w, w)
        else:
            size = (length, w, h)
    t_mass, t_density = _mass_or_density(rng, cfg, cfg.torso_mass)

    limbs: list[LimbPlan] = []
    if kind in ("quadruped", "hexapod"):
        limbs += _limbs_of(rng, cfg, "leg", cfg.leg_segments,
                           _side_places(4 if kind == "quadruped" else 6, size))
    elif kind == "legged":
        n_legs = int(rng.integers(cfg.legged_legs[0], cfg.legged_legs[1] + 1))
        places = (_side_places(n_legs, size) if geom != "sphere" and rng.random() < 0.5
                  else _radial_places(rng, n_legs, size))
        limbs += _limbs_of(rng, cfg, "leg", cfg.leg_segments, places)
    else:  # humanoid: legs straight down from the hips, arms from the shoulders, a head
        wx, wy, hz = size
        bottom = -(hz + wx) if geom == "capsule" else -hz
        top = hz
        hip = 0.5 * wy
        legs = [(np.array([0.0, s * hip, bottom]), np.array([0.0, s, 0.0])) for s in (1.0, -1.0)]
        hcfg = _replace_tilts(cfg)
        limbs += _limbs_of(rng, hcfg, "leg", cfg.leg_segments, legs)
        arms = [(np.array([0.0, s * wy, 0.8 * top]), np.array([0.0, s, 0.0]))
                for s in (1.0, -1.0)]
        limbs += _limbs_of(rng, cfg, "arm", cfg.arm_segments, arms)
        limbs.append(_head(rng, cfg, top + (wx if geom == "capsule" else 0.0)))

    plan = RobotPlan(name=procedural_name(kind, seed), kind=kind, seed=seed, torso_geom=geom,
                     torso_size=tuple(float(s) for s in size), torso_upright=upright,
                     torso_mass=t_mass, torso_density=t_density, limbs=tuple(limbs),
                     actuators=cfg.actuators, ctrl_limit=cfg.ctrl_limit,
                     self_collision=cfg.self_collision)
    height = -_lowest_point(plan) + cfg.clearance
    return replace(plan, height=height)


def _replace_tilts(cfg: ProceduralConfig) -> ProceduralConfig:
    """Humanoid legs: every segment nearly vertical."""
    return replace(cfg, hip_tilt=(1.35, 0.5 * math.pi), knee_tilt=(1.35, 0.5 * math.pi))


def _head(rng: np.random.Generator, cfg: ProceduralConfig, top: float) -> LimbPlan:
    """A head: one sphere segment on a neck hinge on top of the torso."""
    r = _u(rng, cfg.head_radius)
    axis = "xyz"[int(rng.integers(3))]
    m, d = _mass_or_density(rng, cfg, (0.3, 2.0))
    seg = SegmentPlan(length=2.0 * r, radius=r, geom="sphere", direction=(0.0, 0.0, 1.0),
                      axes=(axis,), ranges=((_u(rng, cfg.joint_lower), _u(rng, cfg.joint_upper)),),
                      damping=(_u(rng, cfg.damping),), armature=(_u(rng, cfg.armature),),
                      gear=(_u(rng, cfg.gear),), mass=m, density=d)
    return LimbPlan("head", (0.0, 0.0, top), (seg,), 0.0, None, None)


# --- building ----------------------------------------------------------------------------------


def _set_inertia(geom, mass: float | None, density: float | None) -> None:
    if mass is not None:
        geom.mass = mass
    elif density is not None:
        geom.density = density


def build_spec(plan: RobotPlan) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` of a sampled plan (see :func:`procedural_spec`)."""
    spec = mujoco.MjSpec()
    spec.modelname = plan.name
    spec.compiler.degree = False  # ranges are in radians
    conaff = 1 if plan.self_collision else 0

    torso = spec.worldbody.add_body(name="torso", pos=[0.0, 0.0, plan.height])
    torso.add_freejoint(name="root")
    lx, ly, lz = plan.torso_size
    if plan.torso_geom == "box":
        g = torso.add_geom(name="torso_geom", type=_GEOM["box"], size=[lx, ly, lz])
    elif plan.torso_geom == "sphere":
        g = torso.add_geom(name="torso_geom", type=_GEOM["sphere"], size=[lx, 0.0, 0.0])
    elif plan.torso_upright:
        g = torso.add_geom(name="torso_geom", type=_GEOM["capsule"], size=[lx, lz, 0.0])
    else:
        g = torso.add_geom(name="torso_geom", type=_GEOM["capsule"],
                           fromto=[-lx, 0.0, 0.0, lx, 0.0, 0.0], size=[ly, 0.0, 0.0])
    g.conaffinity = conaff
    _set_inertia(g, plan.torso_mass, plan.torso_density)

    counters: dict[str, int] = {}
    for limb in plan.limbs:
        idx = counters.get(limb.role, 0)
        counters[limb.role] = idx + 1
        prefix = limb.role if limb.role == "head" else f"{limb.role}{idx}"
        parent, pos = torso, list(limb.anchor)
        for k, seg in enumerate(limb.segments):
            name = f"{prefix}_{k}"
            body = parent.add_body(name=name, pos=pos)
            for a, axis in enumerate(seg.axes):
                jname = f"{name}_{axis}"
                body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_HINGE, axis=_AXES[axis],
                               range=list(seg.ranges[a]), limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                               damping=seg.damping[a], armature=seg.armature[a])
                if plan.actuators:
                    act = spec.add_actuator(name=f"{jname}_motor", target=jname,
                                            trntype=mujoco.mjtTrn.mjTRN_JOINT)
                    act.set_to_motor()
                    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
                    act.ctrlrange = [-plan.ctrl_limit, plan.ctrl_limit]
                    act.gear[0] = seg.gear[a]
            tip = seg.tip.tolist()
            if seg.geom == "sphere":
                g = body.add_geom(name=f"{name}_geom", type=_GEOM["sphere"],
                                  pos=[0.5 * c for c in tip], size=[seg.radius, 0.0, 0.0])
            else:
                g = body.add_geom(name=f"{name}_geom", type=_GEOM[seg.geom],
                                  fromto=[0.0, 0.0, 0.0, *tip], size=[seg.radius, seg.radius, 0])
            g.conaffinity = conaff
            _set_inertia(g, seg.mass, seg.density)
            parent, pos = body, tip
        if limb.end_radius > 0:
            end = "foot" if limb.role == "leg" else "hand"
            g = parent.add_geom(name=f"{prefix}_{end}", type=_GEOM["sphere"], pos=pos,
                                size=[limb.end_radius, 0.0, 0.0])
            g.conaffinity = conaff
            _set_inertia(g, limb.end_mass, limb.end_density)
    return spec


def procedural_spec(seed: int, kind: str | None = None,
                    config: ProceduralConfig | None = None) -> mujoco.MjSpec:
    """A procedural legged robot as a ``mujoco.MjSpec`` (deterministic per seed).

    The model is named ``proc_<kind>_<seed:05d>``; ``worldbody`` holds only the ``torso`` body
    (free joint), whose limbs are chains of bodies with 1–2 limited, damped hinges each, and one
    motor per hinge. No floor is included.

    Args:
        seed: seed of ``numpy.random.default_rng``.
        kind: one of :data:`KINDS`, or ``None`` to draw one from ``config.kinds``.
        config: sampling ranges (defaults to :class:`ProceduralConfig()`).
    """
    return build_spec(procedural_plan(seed, kind, config))


# --- writing -----------------------------------------------------------------------------------


def _atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _write_batch(out_dir: str, jobs: list[tuple[int, str]], config: ProceduralConfig) -> None:
    for seed, kind in jobs:
        spec = procedural_spec(seed, kind, config)
        _atomic_write(Path(out_dir) / f"{spec.modelname}.xml", spec.to_xml())


def write_procedural(
    out_dir: str | os.PathLike,
    n: int,
    seed: int = 0,
    kinds: Sequence[str] | None = None,
    config: ProceduralConfig | None = None,
    workers: int | None = None,
) -> list[Path]:
    """Write ``n`` procedural robots as MJCF files ``<out_dir>/proc_<kind>_<seed>.xml``.

    Robot ``i`` has seed ``seed + i`` and kind ``kinds[i % len(kinds)]`` (``kinds`` defaults to
    ``config.kinds``). Files that already exist are left untouched (so an interrupted run can be
    resumed); new files are written to a temporary file and moved into place with ``os.replace``.

    Args:
        out_dir: output directory (created if missing).
        n: number of robots.
        seed: seed of the first robot.
        kinds: kinds to cycle through.
        config: sampling ranges.
        workers: processes to use; ``None`` uses every CPU for large batches (>= 500 robots to
            write) and stays in-process otherwise; ``1`` never starts processes.

    Returns:
        the ``n`` paths, in robot order (including the ones that already existed).
    """
    cfg = config or ProceduralConfig()
    kinds = tuple(kinds) if kinds is not None else cfg.kinds
    if not kinds:
        raise ValueError("kinds must not be empty")
    for k in kinds:
        if k not in KINDS:
            raise ValueError(f"unknown procedural kind {k!r} (known: {', '.join(KINDS)})")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    todo: list[tuple[int, str]] = []
    for i in range(n):
        s, k = seed + i, kinds[i % len(kinds)]
        path = out / f"{procedural_name(k, s)}.xml"
        paths.append(path)
        if not path.exists():
            todo.append((s, k))
    if workers is None:
        workers = (os.cpu_count() or 1) if len(todo) >= 500 else 1
    workers = max(1, min(workers, len(todo)))
    if workers == 1:
        _write_batch(str(out), todo, cfg)
        return paths
    chunk = max(1, min(250, math.ceil(len(todo) / (4 * workers))))
    batches = [todo[i:i + chunk] for i in range(0, len(todo), chunk)]
    # fork where available: workers only use numpy and mujoco (never torch), and unlike spawn it
    # works from unguarded scripts, notebooks and `python -` (no re-import of __main__)
    method = "fork" if "fork" in get_all_start_methods() else "spawn"
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*fork.*", category=DeprecationWarning)
        with ProcessPoolExecutor(workers, mp_context=get_context(method)) as pool:
            for f in [pool.submit(_write_batch, str(out), b, cfg) for b in batches]:
                f.result()
    return paths
