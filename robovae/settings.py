"""The allowed values of a class's settings (a config's ``model:`` and ``data:`` sections).

A constructor states each setting's rule and calls :func:`check_settings` first, so that a value
out of range is refused when the class is built — by ``robovae fit`` before the dataset is
built and before any training, in one line naming every bad setting
(:meth:`robovae.model.cli.RoboVAECLI.instantiate_classes`) — not minutes later, or never (a
negative ``beta`` or ``lr`` trains without complaint). Importable without torch.

    check_settings("model", beta=(beta, number(0)), hidden_dim=(hidden_dim, integer(1)))
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from robovae.errors import SettingsError, is_finite, is_integer

__all__ = ["FEATURE_SET", "FINITE", "Rule", "check_settings", "choice", "integer", "number",
           "span"]


@dataclass(frozen=True)
class Rule:
    """The values a setting may take: ``test(value)`` says whether ``value`` is one, ``want``
    says which they are (``an integer >= 1``)."""

    test: Callable[[object], bool]
    want: str

    def or_none(self) -> Rule:
        """The same values, or None (``null`` in a config)."""
        return Rule(lambda v: v is None or self.test(v), f"{self.want}, or null")


#: Any finite number (a reward weight may be negative).
FINITE = Rule(is_finite, "a finite number")


def integer(least: int) -> Rule:
    """An integer (not a bool; NumPy's integers count) ``>= least``."""
    return Rule(lambda v: is_integer(v) and int(v) >= least, f"an integer >= {least}")


def number(low: float, high: float = math.inf, *, low_open: bool = False,
           high_open: bool = False) -> Rule:
    """A finite number in ``[low, high]`` (``low_open``/``high_open``: that end excluded)."""
    def test(v: object) -> bool:
        if not is_finite(v):
            return False
        x = float(v)
        return (x > low if low_open else x >= low) and (x < high if high_open else x <= high)

    if high == math.inf:
        want = f"a number {'>' if low_open else '>='} {low:g}"
    else:
        want = (f"a number in {'(' if low_open else '['}{low:g}, {high:g}"
                f"{')' if high_open else ']'}")
    return Rule(test, want)


def span(strict: bool = False) -> Rule:
    """A range ``(low, high)`` of finite numbers with ``0 < low <= high`` (``strict``:
    ``low < high``): a strength range, a gait's frequency range."""
    def test(v: object) -> bool:
        return (isinstance(v, (tuple, list)) and len(v) == 2 and all(is_finite(x) for x in v)
                and float(v[0]) > 0 and (float(v[0]) < float(v[1]) if strict
                                         else float(v[0]) <= float(v[1])))

    return Rule(test, f"a range (low, high) with 0 < low {'<' if strict else '<='} high")


def choice(values: Sequence[str]) -> Rule:
    """One of ``values``."""
    return Rule(lambda v: v in values, f"one of {', '.join(values)}")


def _is_feature_set(v: object) -> bool:
    from robovae.data.features import get_feature_set  # NumPy only

    if not isinstance(v, str):
        return False
    try:
        get_feature_set(v)
    except KeyError:
        return False
    return True


#: A feature set of the registry (:func:`robovae.data.features.get_feature_set`).
FEATURE_SET = Rule(_is_feature_set, "a feature set: paper34, kinematic, full or random<d>")


def check_settings(section: str, **settings: tuple[object, Rule]) -> None:
    """Refuse every setting whose value breaks its rule, ``name=(value, rule)``.

    Raises:
        SettingsError: (a ``ValueError``) one line, ``robovae: <section>.<name> must be
            <want>, got <value>`` for each bad setting, joined by ``;``.
    """
    bad = [f"{section}.{name} must be {rule.want}, got {value!r}"
           for name, (value, rule) in settings.items() if not rule.test(value)]
    if bad:
        raise SettingsError("robovae: " + "; ".join(bad))
