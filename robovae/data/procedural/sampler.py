"""Random draws of the procedural generator, read from ``ranges.yaml`` by name.

:class:`Sampler` wraps ``random.Random(seed)`` (fast scalar draws, the same sequence on every
platform) and one class section of ``ranges.yaml`` (:func:`load_ranges`): ``u("thigh")`` is
uniform in the ``[lo, hi]`` of ``thigh``, ``i`` an integer in it (inclusive), ``p`` a coin with
the given probability, ``pick`` a weighted choice of a mapping's keys. It also makes the joints
every class uses (:meth:`Sampler.hinge`), with damping and armature from ``common``.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import yaml

from robovae.data.procedural.blueprint import Joint, Vec

RANGES_FILE = Path(__file__).with_name("ranges.yaml")
AXES: dict[str, Vec] = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
G = 9.81


@cache
def load_ranges() -> dict:
    """The parsed ``ranges.yaml`` (cached)."""
    return yaml.safe_load(RANGES_FILE.read_text())


class Sampler:
    """Draws for one robot of class ``kind`` (see the module docstring)."""

    def __init__(self, seed: int, kind: str, strength: tuple[float, float] | None = None) -> None:
        ranges = load_ranges()
        self.rng = random.Random(seed)
        self.r = ranges[kind]
        self.common = ranges["common"]
        self.strength = self.u(tuple(strength) if strength else self.common["strength"])

    def section(self, kind: str) -> Sampler:
        """A sampler reading the ranges of class ``kind`` from the same random stream."""
        other = object.__new__(Sampler)
        other.__dict__.update(self.__dict__)
        other.r = load_ranges()[kind]
        return other

    def u(self, key: str | Sequence[float], scale: float = 1.0) -> float:
        """Uniform in the range ``key`` (a name or a pair), times ``scale``."""
        lo, hi = self.r[key] if isinstance(key, str) else key
        return (lo + (hi - lo) * self.rng.random()) * scale

    def i(self, key: str) -> int:
        """Integer in the range ``key``, both ends included."""
        lo, hi = self.r[key]
        return self.rng.randint(int(lo), int(hi))

    def p(self, key: str) -> bool:
        """True with the probability ``key``."""
        return self.rng.random() < self.r[key]

    def pick(self, key: str) -> str:
        """A key of the mapping ``key``, drawn by weight (keys returned as strings)."""
        options = self.r[key]
        total = sum(options.values())
        x = self.rng.random() * total
        for k, w in options.items():
            x -= w
            if x < 0:
                return str(k)
        return str(k)

    def sign(self) -> float:
        """+1 or -1 with equal probability."""
        return 1.0 if self.rng.random() < 0.5 else -1.0

    def hinge(self, axis: str | Vec, limit: str | tuple | None = "limit",
              gear: float = 0.0, stiffness: float = 0.0) -> Joint:
        """A hinge about ``axis`` with limits: ``(-a, b)`` with ``a``, ``b`` drawn from the range
        named ``limit``; drawn from the two ranges of a pair of pairs; a pair of numbers as
        given; ``None`` unlimited. Damping and armature from ``common``,
        and motor gear ``gear`` (0: passive; scaled later by
        :func:`~robovae.data.procedural.parts.size_motors`)."""
        ax = AXES[axis] if isinstance(axis, str) else axis
        rng = None
        if limit is not None:
            if isinstance(limit, str):
                rng = (-self.u(limit), self.u(limit))
            elif isinstance(limit[0], tuple):
                rng = (self.u(limit[0]), self.u(limit[1]))
            else:
                rng = (float(limit[0]), float(limit[1]))
        return Joint("hinge", ax, rng, self.u(self.common["damping"]),
                     self.u(self.common["armature"]), stiffness, gear)

    def slide(self, axis: Vec, travel: tuple[float, float], gear: float) -> Joint:
        """A limited slide joint with range ``travel`` (m) and a motor of gear ``gear`` N."""
        return Joint("slide", axis, travel, self.u(self.common["damping"]) * 10.0,
                     self.u(self.common["armature"]), 0.0, gear)
