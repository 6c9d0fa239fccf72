"""One-line errors for bad input.

Every problem with an input file is reported as a single line::

    robovae: <file>: <what> (<element/line>)

and never as a traceback. Library code raises :class:`RobotFileError`; the CLI and the
dataset builder print ``str(err)`` and go on with the other files.
"""

from __future__ import annotations

import math
import numbers
import os
from typing import TypeGuard


class RobovaeError(Exception):
    """Base class of every error robovae raises on purpose."""


class SettingsError(RobovaeError, ValueError):
    """A setting out of its range (:func:`robovae.settings.check_settings`): a one-line
    :class:`RobovaeError`, and the ``ValueError`` Python raises for a bad argument."""


def is_integer(value: object) -> TypeGuard[numbers.Integral]:
    """An integer, not a bool (NumPy's integers count): the one test of every integer setting
    (:func:`check_count`, :func:`check_seed`, :func:`robovae.settings.integer`)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_finite(value: object) -> TypeGuard[numbers.Real]:
    """A finite real number, not a bool (NumPy's count): the one test of every number
    setting (:func:`robovae.settings.number`)."""
    return (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(value))


#: The largest seed a command takes (a robot's or a run's streams derive from it).
MAX_SEED = 2**31 - 1


def check_seed(seed: object, option: str = "--seed") -> None:
    """Refuse ``seed`` unless it is an integer in ``[0, MAX_SEED]``: one line ``robovae:
    <option> must be an integer in [0, 2147483647], not <value>`` (NumPy's integers count)."""
    if not is_integer(seed) or not 0 <= int(seed) <= MAX_SEED:
        raise SettingsError(f"robovae: {option} must be an integer in [0, {MAX_SEED}], "
                            f"not {seed!r}")


def check_count(option: str, value: object, least: int) -> None:
    """Refuse ``value`` unless it is an integer (not a bool; NumPy's integers count) of at
    least ``least``: one line ``robovae: <option> must be an integer of at least <least>, not
    <value>``."""
    if not is_integer(value) or int(value) < least:
        raise SettingsError(f"robovae: {option} must be an integer of at least {least}, "
                            f"not {value!r}")


class RobotFileError(RobovaeError):
    """A robot file that cannot become a robot graph.

    Args:
        path: the offending file.
        what: what is wrong, in a few words.
        where: the element and/or line, when known.
    """

    def __init__(self, path: str | os.PathLike[str], what: str, where: str | None = None) -> None:
        self.path = os.fspath(path)
        self.what = " ".join(str(what).split())  # always one line
        self.where = " ".join(where.split()) if where else None
        super().__init__(self.line())

    def line(self) -> str:
        """The one-line message ``robovae: <file>: <what> (<where>)``."""
        tail = f" ({self.where})" if self.where else ""
        return f"robovae: {self.path}: {self.what}{tail}"

    def __str__(self) -> str:
        return self.line()
