"""Lists of flat records stored column by column in a checkpoint.

A model keeps one record per training robot (:func:`robovae.evaluate.samples.robot_record`:
name, duplicate key, topology, counts, mass) so that generation can measure novelty from the
checkpoint alone. Tens of thousands of small dicts are slow for ``torch.load(weights_only=True)``
to rebuild (docs/generation.md), so :func:`to_columns` stores them as one column per key:

- a key whose every value is an ``int`` (not a ``bool``): an ``int64`` tensor;
- every value a ``float``: a ``float64`` tensor (Python floats round-trip exactly);
- every value a ``str`` without a line break: one string, the values joined by ``"\\n"``;
- anything else (``None``, booleans, mixed types): the plain list of values.

Records without the same keys in the same order are stored as the plain list they are.
:func:`from_columns` gives back equal records, and takes the plain list of older checkpoints
as it is.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

__all__ = ["from_columns", "to_columns"]

#: The format tag of a columnar record list.
FORMAT = "columns/1"


def _column(values: list) -> torch.Tensor | str | list:
    kinds = {type(v) for v in values}
    if kinds == {int}:
        return torch.tensor(values, dtype=torch.int64)
    if kinds == {float}:
        return torch.tensor(values, dtype=torch.float64)
    if kinds == {str} and not any("\n" in v for v in values):
        return "\n".join(values)
    return list(values)


def _values(column: torch.Tensor | str | list, n: int) -> list:
    if isinstance(column, torch.Tensor):
        return column.tolist()
    if isinstance(column, str):
        return column.split("\n") if n else []
    return list(column)


def to_columns(records: Sequence[dict]) -> dict | list[dict]:
    """``records`` as ``{"format": FORMAT, "n": N, "keys": [...], "columns": {key: column}}``
    (module docstring), or as the plain list when their keys differ."""
    records = list(records)
    keys = list(records[0]) if records else []
    if any(list(r) != keys for r in records):
        return records
    return {"format": FORMAT, "n": len(records), "keys": keys,
            "columns": {k: _column([r[k] for r in records]) for k in keys}}


def from_columns(stored: dict | Sequence[dict] | None) -> list[dict]:
    """The records :func:`to_columns` stored (a plain list, or ``None``: as they are).

    Raises:
        ValueError: a dict that is not a record list of a known format.
    """
    if stored is None:
        return []
    if not isinstance(stored, dict):
        return list(stored)
    if stored.get("format") != FORMAT:
        raise ValueError(f"unknown record format {stored.get('format')!r} (want {FORMAT!r})")
    n, keys = int(stored["n"]), list(stored["keys"])
    columns = [_values(stored["columns"][k], n) for k in keys]
    if any(len(c) != n for c in columns):
        raise ValueError(f"record columns of unequal length (want {n})")
    return [dict(zip(keys, row)) for row in zip(*columns)] if keys else [{} for _ in range(n)]
