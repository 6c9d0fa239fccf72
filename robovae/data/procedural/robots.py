"""One procedural robot from a seed: its class, its plan, its ``MjSpec``.

:func:`procedural_plan` draws the class (when not given) from the class mix with
``random.Random("mix<seed>")``, samples the class's part tree with a
:class:`~robovae.data.procedural.sampler.Sampler` seeded with ``seed`` (ranges from
``ranges.yaml``), sizes the motors and lifts the root so that the lowest point sits
``clearance`` above ``z = 0`` (floating robots; welded arms stand on ``z = 0``).
:func:`procedural_spec` builds the ``MjSpec``. Same seed, class and config: the same robot.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import mujoco

from robovae.data.procedural import arm, biped, hexapod, humanoid, mobile, quadruped, radial
from robovae.data.procedural.blueprint import Part, RobotPlan, lowest_point
from robovae.data.procedural.parts import size_motors
from robovae.data.procedural.sampler import Sampler, load_ranges
from robovae.data.procedural.spec import build_spec
from robovae.settings import check_settings, integer, number, span

#: Robot classes and the function that samples each one's root part.
CLASSES: dict[str, Callable[[Sampler], tuple[Part, bool]]] = {
    "quadruped": quadruped.sample,
    "hexapod": hexapod.sample,
    "radial": radial.sample,
    "humanoid": humanoid.sample,
    "biped": biped.sample,
    "arm": arm.sample,
    "mobile_manipulator": mobile.sample,
}


def default_mix() -> dict[str, float]:
    """The default class mix (``mix`` of ``ranges.yaml``), weights summing to 1."""
    mix = load_ranges()["mix"]
    total = sum(mix.values())
    return {k: v / total for k, v in mix.items()}


def check_classes(classes: Mapping[str, float] | Sequence[str]) -> dict[str, float]:
    """A class mix as ``{class: weight}`` (a list gets equal weights).

    The weights are normalised to sum to 1 (divided by the largest first when their sum
    overflows, so that any finite weights can be given).

    Raises:
        ValueError: an unknown class, a weight that is not a finite number ``>= 0``, or no
            positive weight.
    """
    mix = dict(classes) if isinstance(classes, Mapping) else {c: 1.0 for c in classes}
    for c, w in mix.items():
        if c not in CLASSES:
            raise ValueError(f"unknown procedural class '{c}' (known: {', '.join(CLASSES)})")
        if not number(0).test(w):
            raise ValueError(f"the weight of procedural class '{c}' must be a finite number "
                             f">= 0, got {w!r}")
    if not mix or max(mix.values()) <= 0:
        raise ValueError("the procedural class mix needs a positive weight")
    if not math.isfinite(sum(mix.values())):  # huge weights: the sum overflows
        top = max(mix.values())
        mix = {c: w / top for c, w in mix.items()}
    total = sum(mix.values())
    return {c: w / total for c, w in mix.items()}


@dataclass(frozen=True)
class ProceduralConfig:
    """Options of the generator besides the ranges of ``ranges.yaml``.

    Attributes:
        mix: class weights (default: ``mix`` of ``ranges.yaml``).
        gear: robot strength range: every motor's gear is the torque that holds its load
            times a strength drawn from this range (default ``common.strength``; tiny values
            make motors too weak to stand).
        actuators: add the motors.
        self_collision: let robot geoms collide with each other (not only with a floor).
        clearance: gap between a floating robot's lowest point and ``z = 0`` at ``qpos0`` (m).

    Raises:
        ValueError: a bad ``mix`` (:func:`check_classes`), a ``gear`` range that is not
            ``0 < low <= high`` (finite), a ``clearance`` that is not a finite number ``>= 0``.
    """

    mix: Mapping[str, float] = field(default_factory=default_mix)
    gear: tuple[float, float] | None = None
    actuators: bool = True
    self_collision: bool = False
    clearance: float = 0.02

    def __post_init__(self) -> None:
        object.__setattr__(self, "mix", check_classes(self.mix))
        check_settings("ProceduralConfig", gear=(self.gear, span().or_none()),
                       clearance=(self.clearance, number(0)))


def procedural_name(kind: str, seed: int) -> str:
    """Model name of a robot, e.g. ``proc_quadruped_00042``."""
    return f"proc_{kind}_{seed:05d}"


def draw_class(seed: int, mix: Mapping[str, float]) -> str:
    """The class of robot ``seed`` under ``mix`` (normalised weights)."""
    x = random.Random(f"mix{seed}").random()
    for c, w in mix.items():
        x -= w
        if x < 0:
            return c
    return c


def procedural_plan(seed: int, kind: str | None = None,
                    config: ProceduralConfig | None = None) -> RobotPlan:
    """The plan of robot ``seed`` of class ``kind`` (``None``: drawn from ``config.mix``).

    Raises:
        ValueError: an unknown class, a ``seed`` that is not an integer ``>= 0``.
    """
    check_settings("procedural robot", seed=(seed, integer(0)))
    cfg = config or ProceduralConfig()
    if kind is None:
        kind = draw_class(seed, cfg.mix)
    if kind not in CLASSES:
        raise ValueError(f"unknown procedural class '{kind}' (known: {', '.join(CLASSES)})")
    s = Sampler(seed, kind, cfg.gear)
    root, floating = CLASSES[kind](s)
    size_motors(root, s.strength)
    low = lowest_point(root)
    height = -low + (cfg.clearance if floating else 0.0)
    return RobotPlan(procedural_name(kind, seed), kind, seed, root, floating, height,
                     cfg.actuators, cfg.self_collision)


def procedural_spec(seed: int, kind: str | None = None,
                    config: ProceduralConfig | None = None) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` of robot ``seed`` (see :func:`procedural_plan`)."""
    return build_spec(procedural_plan(seed, kind, config))
