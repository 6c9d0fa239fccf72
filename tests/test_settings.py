"""Settings rules (robovae.settings) and the constructors that state them."""

from __future__ import annotations

import math

import pytest

from robovae.data.datamodule import RobotDataModule
from robovae.errors import RobovaeError
from robovae.model.vae import RoboVAE
from robovae.settings import FEATURE_SET, check_settings, choice, integer, number


def test_integer_takes_integers_only():
    rule = integer(1)
    assert rule.test(1) and rule.test(10**9)
    assert not any(rule.test(v) for v in (0, -3, True, 1.0, "2", None))
    assert rule.or_none().test(None) and not rule.or_none().test(0)


def test_number_is_finite_and_keeps_its_ends():
    assert number(0).test(0) and number(0).test(2.5) and number(0).test(3)
    assert not any(number(0).test(v) for v in (-1e-9, math.nan, math.inf, True, "1", None))
    share = number(0, 1, high_open=True)
    assert share.test(0.0) and share.test(0.99) and not share.test(1.0)
    assert not number(0, low_open=True).test(0.0)
    assert share.want == "a number in [0, 1)" and number(0, low_open=True).want == "a number > 0"


def test_choice_and_feature_set():
    assert choice(("a", "b")).test("b") and not choice(("a", "b")).test("c")
    assert FEATURE_SET.test("paper34") and FEATURE_SET.test("random7")
    assert not any(FEATURE_SET.test(v) for v in ("random0", "nope", 3, None))


def test_check_settings_names_every_bad_setting_in_one_line():
    check_settings("model", a=(1, integer(1)), b=(None, number(0).or_none()))
    with pytest.raises(ValueError) as e:
        check_settings("model", a=(0, integer(1)), b=(0.5, number(0)), c=(-2.0, number(0)))
    msg = str(e.value)
    assert msg == ("robovae: model.a must be an integer >= 1, got 0; "
                   "model.c must be a number >= 0, got -2.0")


def test_the_model_refuses_settings_out_of_range():
    """Accepted before 2026-11-29 (negative beta and learning rate trained without a word)."""
    with pytest.raises(ValueError, match=r"^robovae: model\.beta must be a number >= 0, got -1; "
                                         r"model\.lr must be a number > 0, got 0$"):
        RoboVAE(beta=-1, lr=0)
    with pytest.raises(ValueError, match="model.max_nodes must be an integer >= 1, got 0"):
        RoboVAE(max_nodes=0)
    RoboVAE(support_margin=None, beta_nodes=None, node_temperature=0.0)  # the nulls are allowed


def test_the_data_module_refuses_settings_out_of_range():
    with pytest.raises(ValueError, match=r"data\.predict_temperature must be a number >= 0, "
                                         r"got -0\.5"):
        RobotDataModule(predict_temperature=-0.5)
    with pytest.raises(ValueError, match="must be below 1 .no robot left to train on., got 1"):
        RobotDataModule(val_fraction=0.5, test_fraction=0.5)
    RobotDataModule(val_fraction=0.0, test_fraction=0.0)


def test_the_data_module_refuses_bad_sources_when_built(tmp_path):
    """A bad source is refused when the module is built (the settings' moment), before any
    data; before 2026-11-29 random trees beside robots failed when the dataset was built."""
    with pytest.raises(RobovaeError, match="cannot share a dataset with robots .'zoo'."):
        RobotDataModule(root=tmp_path / "cache", sources=["zoo", "synthetic:n=2"])
    with pytest.raises(RobovaeError, match="procedural source: n=0 is outside"):
        RobotDataModule(root=tmp_path / "cache", sources=["procedural:n=0"])
    assert not (tmp_path / "cache").exists()


def test_counts_and_seeds_take_numpy_integers_only_as_integers():
    import numpy as np

    from robovae.errors import MAX_SEED, SettingsError, check_count, check_seed

    check_count("-n", np.int64(3), 1)
    check_seed(np.uint32(7))
    check_seed(MAX_SEED)
    for bad in (True, 2.0, -1, MAX_SEED + 1, np.int64(-2)):
        with pytest.raises(SettingsError, match=r"--seed must be an integer in \[0, 2147483647\]"):
            check_seed(bad)
    for bad in (True, 3.0, np.float64(3), 0):
        with pytest.raises(SettingsError, match="-n must be an integer of at least 1"):
            check_count("-n", bad, 1)
