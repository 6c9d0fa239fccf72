"""The option checks of robovae's commands, importable without torch.

Each library entry point calls its check before any work: :func:`robovae.generate.pipeline.
generate` calls :func:`check_generate`, :func:`robovae.design.variations.generate_like`
:func:`check_like`, :func:`robovae.design.variations.interpolate_files`
:func:`check_interpolate`, :func:`robovae.design.optimize.optimize` :func:`check_optimize`,
:func:`robovae.evaluate.analyze.analyze` :func:`check_analyze`.
The ``robovae`` command calls the same check before it imports the entry point's module (with it
torch, PyG and Lightning: 5–9 s), so that a mistyped option is refused, in one line, in under a
second. Every check raises :class:`~robovae.errors.RobovaeError` naming the option.

The data sources' options (``synthetic:n=20,…``, ``procedural:n=1000,…``) are parsed by
:func:`source_options` and :func:`option_int`, the same way for every source.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from robovae.errors import RobovaeError, check_count

__all__ = ["check_analyze", "check_generate", "check_interpolate", "check_like", "check_optimize",
           "option_int", "source_options"]


def source_options(where: str, arg: str, keys: Sequence[str]) -> dict[str, str]:
    """The ``key=value`` options of a source string's argument (``n=20,seed=0``), every key one
    of ``keys``; ``where`` names the source in errors (``synthetic source``).

    Raises:
        RobovaeError: one line naming the option that is not ``key=value`` or not known.
    """
    out: dict[str, str] = {}
    for part in filter(None, (p.strip() for p in arg.split(","))):
        if "=" not in part:
            raise RobovaeError(f"robovae: {where}: option '{part}' is not key=value")
        k, v = (t.strip() for t in part.split("=", 1))
        if k not in keys:
            raise RobovaeError(f"robovae: {where}: unknown option '{k}' ({', '.join(keys)})")
        out[k] = v
    return out


def option_int(where: str, name: str, text: str, lo: int, hi: int) -> int:
    """The integer option ``name=text`` of ``where`` (e.g. a source string), in ``[lo, hi]``.

    Raises:
        RobovaeError: one line, ``robovae: <where>: <name>='x' is not an integer`` or ``…
            is outside [lo, hi]``.
    """
    try:
        v = int(text)
    except ValueError:
        raise RobovaeError(f"robovae: {where}: {name}={text!r} is not an integer") from None
    if not lo <= v <= hi:
        raise RobovaeError(f"robovae: {where}: {name}={v} is outside [{lo}, {hi}]")
    return v


def _check_redraws(redraws: object) -> None:
    if isinstance(redraws, bool) or not isinstance(redraws, int) or redraws < 0:
        raise RobovaeError(f"robovae: --redraws must be a non-negative integer, got {redraws!r}")


def check_generate(n: object, temperature: object = 1.0, node_temperature: object = None,
                   batch_size: object = 256, jobs: object = 0, redraws: object = 4) -> None:
    """``robovae generate``: ``n`` and ``batch_size`` positive integers, ``jobs`` and
    ``redraws`` integers ``>= 0``, the temperatures finite and ``>= 0`` (``node_temperature``
    may be None: the checkpoint's)."""
    _check_redraws(redraws)
    for name, t in (("--temperature", temperature), ("--node-temperature", node_temperature)):
        if t is not None and (isinstance(t, bool) or not isinstance(t, (int, float))
                              or not 0 <= t < math.inf):
            raise RobovaeError(f"robovae: {name} must be a non-negative number, got {t!r}")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise RobovaeError(f"robovae: the number of robots (-n) must be a positive integer, "
                           f"not {n!r}")
    check_count("--batch-size", batch_size, 1)
    check_count("--jobs", jobs, 0)


def check_like(radius: float, n: int, redraws: object = 4) -> None:
    """``robovae generate --like``: ``radius`` finite and ``>= 0``, ``n >= 1``, ``redraws``
    an integer ``>= 0``."""
    if not (math.isfinite(radius) and radius >= 0):
        raise RobovaeError(f"robovae: --radius must be a finite number >= 0, got {radius}")
    if n < 1:
        raise RobovaeError(f"robovae: -n must be >= 1, got {n}")
    _check_redraws(redraws)


def check_interpolate(steps: int) -> None:
    """``robovae interpolate``: at least the two ends."""
    if steps < 2:
        raise RobovaeError(f"robovae: --steps must be >= 2 (the two ends), got {steps}")


def check_optimize(task: str, budget: int, top: int = 10, variance: float = 0.9,
                   population: int | None = None, score_sets: int = 1,
                   restart_after: int | None = None, local_step: float | None = None,
                   distinct: float | None = None) -> None:
    """``robovae optimize``: a known task (:data:`robovae.design.score.TASKS`), ``budget`` and
    ``top`` positive, ``variance`` in ``(0, 1]``, ``population`` (None: the ``cmaes``
    default) at least 2, ``score_sets`` and ``restart_after`` at least 1, ``local_step`` finite
    and ``> 0``, ``distinct`` finite and ``>= 0`` (None: not given, the entry point's default)."""
    from robovae.design.score import TASKS  # MuJoCo only

    if task not in TASKS:
        raise RobovaeError(f"robovae: unknown task {task!r} (choose from {', '.join(TASKS)})")
    if budget <= 0:
        raise RobovaeError(f"robovae: --budget must be > 0, got {budget}")
    if top < 1:
        raise RobovaeError(f"robovae: --top must be >= 1, got {top}")
    if not 0.0 < variance <= 1.0:
        raise RobovaeError(f"robovae: --variance must be in (0, 1], got {variance}")
    if population is not None and population < 2:
        raise RobovaeError(f"robovae: --population must be >= 2, got {population}")
    if score_sets < 1:
        raise RobovaeError(f"robovae: --score-sets must be >= 1, got {score_sets}")
    if restart_after is not None and restart_after < 1:
        raise RobovaeError(f"robovae: --restart-after must be >= 1, got {restart_after}")
    if local_step is not None and not (local_step > 0 and math.isfinite(local_step)):
        raise RobovaeError(f"robovae: --local-step must be > 0, got {local_step}")
    if distinct is not None and not (distinct >= 0 and math.isfinite(distinct)):
        raise RobovaeError(f"robovae: --distinct must be >= 0, got {distinct}")


def check_analyze(max_samples: int | None = None, entropy_seconds: float = 3.0,
                  gait_rollouts: int = 64, gait_search: str = "random", **counts: int) -> None:
    """``robovae analyze``: every count of ``counts`` (``behaviour``, ``jobs``, …) an integer
    ``>= 0``, ``max_samples`` (None: all) and ``gait_rollouts`` at least 1, ``entropy_seconds``
    positive and finite, ``gait_search`` one of
    :data:`robovae.evaluate.quality.gait_search.GAIT_SEARCHES`."""
    from robovae.evaluate.quality.gait_search import GAIT_SEARCHES  # MuJoCo only

    for name, k in counts.items():
        check_count(f"--{name}", k, 0)
    if max_samples is not None:
        check_count("--max-samples", max_samples, 1)
    if not 0 < entropy_seconds < math.inf:
        raise RobovaeError(f"robovae: --entropy-seconds must be a positive number, not "
                           f"{entropy_seconds!r}")
    check_count("--gait-rollouts", gait_rollouts, 1)
    if gait_search not in GAIT_SEARCHES:
        raise RobovaeError(f"robovae: --gait-search must be one of {', '.join(GAIT_SEARCHES)}, "
                           f"not {gait_search!r}")
