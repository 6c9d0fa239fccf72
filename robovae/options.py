"""The option checks of robovae's commands, importable without torch.

Each library entry point calls its check before any work: :func:`robovae.generate.pipeline.
generate` calls :func:`check_generate`, :func:`robovae.design.variations.generate_like`
:func:`check_like`, :func:`robovae.design.variations.interpolate_files`
:func:`check_interpolate`, :func:`robovae.design.optimize.optimize` :func:`check_optimize`,
:func:`robovae.evaluate.analyze.analyze` :func:`check_analyze`.
The ``robovae`` command calls the same check before it imports the entry point's module (with it
torch, PyG and Lightning: 5–9 s), so that a mistyped option is refused, in one line, in under a
second. Every check raises :class:`~robovae.errors.SettingsError` (a ``RobovaeError`` and a
``ValueError``) naming the option.

The data sources' options (``synthetic:n=20,…``, ``procedural:n=1000,…``) are parsed by
:func:`source_options` and :func:`option_int`, the same way for every source.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from robovae.errors import SettingsError, check_count, check_seed, is_integer
from robovae.settings import number

__all__ = ["check_analyze", "check_generate", "check_interpolate", "check_like", "check_optimize",
           "check_variance", "option_int", "source_options"]


def source_options(where: str, arg: str, keys: Sequence[str]) -> dict[str, str]:
    """The ``key=value`` options of a source string's argument (``n=20,seed=0``), every key one
    of ``keys``; ``where`` names the source in errors (``synthetic source``).

    Raises:
        SettingsError: one line naming the option that is not ``key=value`` or not known.
    """
    out: dict[str, str] = {}
    for part in filter(None, (p.strip() for p in arg.split(","))):
        if "=" not in part:
            raise SettingsError(f"robovae: {where}: option '{part}' is not key=value")
        k, v = (t.strip() for t in part.split("=", 1))
        if k not in keys:
            raise SettingsError(f"robovae: {where}: unknown option '{k}' ({', '.join(keys)})")
        out[k] = v
    return out


def option_int(where: str, name: str, text: str, lo: int, hi: int) -> int:
    """The integer option ``name=text`` of ``where`` (e.g. a source string), in ``[lo, hi]``.

    Raises:
        SettingsError: one line, ``robovae: <where>: <name>='x' is not an integer`` or ``…
            is outside [lo, hi]``.
    """
    try:
        v = int(text)
    except ValueError:
        raise SettingsError(f"robovae: {where}: {name}={text!r} is not an integer") from None
    if not lo <= v <= hi:
        raise SettingsError(f"robovae: {where}: {name}={v} is outside [{lo}, {hi}]")
    return v


#: Most robots on one latent path (``robovae interpolate --steps``): each is written,
#: validated and drawn in one batch.
MAX_STEPS = 10_000


#: Largest CMA-ES population ``robovae optimize`` takes (its arrays grow with it; 10**8 ran over
#: a minute without scoring a robot).
MAX_POPULATION = 10_000


def _finite(name: str, value: object, least: float = 0.0) -> None:
    """Refuse ``value`` unless it is a finite number (not a bool) ``>= least``."""
    if not number(least).test(value):
        raise SettingsError(f"robovae: {name} must be a finite number >= {least:g}, "
                            f"got {value!r}")


#: Latents ``robovae generate`` decodes at once by default (the decoder's steps are shared by
#: the batch: 2.5 against 4.4 ms of CPU a robot at 256, no faster beyond; docs/generation.md).
BATCH_SIZE = 1024


def check_generate(n: object, temperature: object = 1.0, node_temperature: object = None,
                   batch_size: object = BATCH_SIZE, jobs: object = 0, redraws: object = 4,
                   seed: object = 0) -> None:
    """``robovae generate``: ``n`` and ``batch_size`` positive integers, ``jobs`` and
    ``redraws`` integers ``>= 0``, the temperatures finite and ``>= 0`` (``node_temperature``
    may be None: the checkpoint's), ``seed`` in ``[0, MAX_SEED]``."""
    check_count("-n", n, 1)
    check_count("--redraws", redraws, 0)
    _finite("--temperature", temperature)
    if node_temperature is not None:
        _finite("--node-temperature", node_temperature)
    check_count("--batch-size", batch_size, 1)
    check_count("--jobs", jobs, 0)
    check_seed(seed)


def check_like(radius: object, n: object, redraws: object = 4, seed: object = 0,
               variance: object = 0.95, jobs: object = 0) -> None:
    """``robovae generate --like``: ``radius`` finite and ``>= 0``, ``n >= 1``, ``redraws``
    and ``jobs`` integers ``>= 0``, ``seed`` in ``[0, MAX_SEED]``, ``variance`` in ``(0, 1]``
    (:func:`check_variance`)."""
    _finite("--radius", radius)
    check_count("-n", n, 1)
    check_count("--redraws", redraws, 0)
    check_seed(seed)
    check_variance(variance)
    check_count("--jobs", jobs, 0)


def check_interpolate(steps: object) -> None:
    """``robovae interpolate``: at least the two ends, at most :data:`MAX_STEPS`."""
    if not is_integer(steps) or not 2 <= int(steps) <= MAX_STEPS:
        raise SettingsError(f"robovae: --steps must be an integer in [2, {MAX_STEPS}] (the two "
                            f"ends and the robots between), got {steps!r}")


def check_optimize(task: str, budget: object, top: object = 10, variance: object = 0.9,
                   population: object = None, score_sets: object = 1,
                   restart_after: object = None, local_step: object = None,
                   distinct: object = None, seed: object = 0, jobs: object = 0) -> None:
    """``robovae optimize``: a known task (:data:`robovae.design.score.TASKS`), ``budget`` and
    ``top`` positive integers, ``variance`` in ``(0, 1]``, ``population`` (None: the ``cmaes``
    default) an integer from 2 to :data:`MAX_POPULATION`, ``score_sets`` and
    ``restart_after`` integers of at least 1, ``local_step`` finite and ``> 0``, ``distinct``
    finite and ``>= 0`` (None: not given, the entry point's default), ``seed`` in
    ``[0, MAX_SEED]``, ``jobs`` an integer ``>= 0``."""
    from robovae.design.score import TASKS  # MuJoCo only

    if task not in TASKS:
        raise SettingsError(f"robovae: unknown task {task!r} (choose from {', '.join(TASKS)})")
    check_count("--budget", budget, 1)
    check_count("--top", top, 1)
    check_variance(variance)
    if population is not None:
        check_count("--population", population, 2)
        if is_integer(population) and int(population) > MAX_POPULATION:  # 10**8: a minute
            raise SettingsError(f"robovae: --population must be at most {MAX_POPULATION:,} "
                                f"(CMA-ES's own default is 4 + 3 ln k, 10 to 16 here), got "
                                f"{population}")
    check_count("--score-sets", score_sets, 1)
    if restart_after is not None:
        check_count("--restart-after", restart_after, 1)
    if local_step is not None and not number(0, low_open=True).test(local_step):
        raise SettingsError(f"robovae: --local-step must be a finite number > 0, got "
                            f"{local_step!r}")
    if distinct is not None:
        _finite("--distinct", distinct)
    check_seed(seed)
    check_count("--jobs", jobs, 0)


def check_variance(variance: object) -> None:
    """The share of the prior's variance whose principal subspace is searched or varied in
    (``--variance``): a number in ``(0, 1]``."""
    if not number(0, 1, low_open=True).test(variance):
        raise SettingsError(f"robovae: --variance must be a number in (0, 1], got {variance!r}")


def check_analyze(max_samples: int | None = None, entropy_seconds: float = 3.0,
                  gait_rollouts: int = 64, gait_search: str = "random", seed: object = 0,
                  real: str | os.PathLike | None = None, **counts: int) -> None:
    """``robovae analyze``: every count of ``counts`` (``behaviour``, ``jobs``, …) an integer
    ``>= 0``, ``max_samples`` (None: all) and ``gait_rollouts`` at least 1, ``entropy_seconds``
    positive and finite, ``gait_search`` one of
    :data:`robovae.evaluate.quality.gait_search.GAIT_SEARCHES`, ``seed`` in ``[0, MAX_SEED]``,
    ``real`` (the command's ``--real``; None: not given) a folder that exists (the library's
    :func:`~robovae.evaluate.analyze.analyze` takes a missing folder for no real robots)."""
    from robovae.evaluate.quality.gait_search import GAIT_SEARCHES  # MuJoCo only

    for name, k in counts.items():
        check_count(f"--{name}", k, 0)
    if max_samples is not None:
        check_count("--max-samples", max_samples, 1)
    if not number(0, low_open=True).test(entropy_seconds):
        raise SettingsError(f"robovae: --entropy-seconds must be a positive number, not "
                            f"{entropy_seconds!r}")
    check_count("--gait-rollouts", gait_rollouts, 1)
    if gait_search not in GAIT_SEARCHES:
        raise SettingsError(f"robovae: --gait-search must be one of {', '.join(GAIT_SEARCHES)}, "
                            f"not {gait_search!r}")
    check_seed(seed)
    if real is not None and not Path(real).is_dir():  # given, not found: not silently none
        raise SettingsError(f"robovae: {real}: no such folder of real robots (--real)")
