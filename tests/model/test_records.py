"""Training-robot records stored column by column in checkpoints."""

from __future__ import annotations

import io

import pytest
import torch

from robovae.model.checkpoint import load_model
from robovae.model.records import FORMAT, from_columns, to_columns


def _round_trip(obj):
    """Through ``torch.save`` and a weights-only ``torch.load``, as a checkpoint goes."""
    buf = io.BytesIO()
    torch.save(obj, buf)
    buf.seek(0)
    return torch.load(buf, weights_only=True)


def test_records_come_back_equal_with_their_types():
    records = [{"name": "ant", "key": "ab12", "nodes": 9, "mass": 0.1 + 0.2, "limbs": 4,
                "odd": None, "flag": True, "mixed": 1, "text": "two\nlines"},
               {"name": "", "key": "cd34", "nodes": 2 ** 40, "mass": 1e-300, "limbs": 0,
                "odd": "x", "flag": False, "mixed": 2.5, "text": ""}]
    stored = _round_trip(to_columns(records))
    cols = stored["columns"]
    assert stored["format"] == FORMAT and stored["n"] == 2
    assert cols["nodes"].dtype == torch.int64 and cols["mass"].dtype == torch.float64
    assert cols["name"] == "ant\n" and cols["key"] == "ab12\ncd34"
    assert isinstance(cols["odd"], list) and isinstance(cols["flag"], list)  # not int columns
    assert isinstance(cols["mixed"], list) and isinstance(cols["text"], list)
    back = from_columns(stored)
    assert back == records
    assert [[type(v) for v in r.values()] for r in back] == \
        [[type(v) for v in r.values()] for r in records]


def test_empty_single_and_uneven_record_lists():
    assert from_columns(_round_trip(to_columns([]))) == []
    assert from_columns(_round_trip(to_columns([{"name": ""}]))) == [{"name": ""}]
    assert from_columns(to_columns([{}, {}])) == [{}, {}]
    uneven = [{"name": "a", "nodes": 3}, {"nodes": 4, "name": "b"}, {"name": "go2"}]
    assert to_columns(uneven) == uneven  # kept as the plain list
    assert from_columns(uneven) == uneven  # and so are older checkpoints' lists
    assert from_columns(None) == []


def test_unknown_or_broken_formats_are_refused():
    with pytest.raises(ValueError, match="unknown record format 'rows/9'"):
        from_columns({"format": "rows/9"})
    stored = to_columns([{"name": "a", "nodes": 1}, {"name": "b", "nodes": 2}])
    stored["columns"]["nodes"] = torch.tensor([1])
    with pytest.raises(ValueError, match="unequal length"):
        from_columns(stored)


def test_a_checkpoint_stores_columns_and_loads_the_same_records(trained):
    model, _, ckpt = trained
    stored = torch.load(ckpt, weights_only=True)["robovae_training_robots"]
    assert stored["format"] == FORMAT and stored["n"] == len(model.training_robots) > 0
    assert load_model(ckpt).training_robots == model.training_robots
