"""Open-loop gaits tuned to the body with CMA-ES: how fast can this robot go?

:func:`~robovae.evaluate.quality.locomotion.gait` draws random sinusoidal gaits; a robot's best
of a few random gaits is a lower bound on its speed that the luck of the draw dominates (a
robot several gaits of the draw happen to suit beats a better body). :func:`searched_gait`
starts with the same random gaits (the same ``seed`` and ``rollouts`` give the same first
rollouts, so its speed is never below :func:`gait`'s) and goes on with CMA-ES (the ``cmaes``
package) over the gait's parameters, from the best random gait:

    x = [A_1 … A_nu,  phi_1 / 2π … phi_nu / 2π,  (f - f_lo) / (f_hi - f_lo),  B_c …]

amplitudes in [0, 1], phases in turns (periodic; bounded at ±10 turns only because the
package wants bounds), the frequency scaled into [0, 1], offsets in [-1, 1] for the actuators
of unlimited hinges only (:func:`~robovae.evaluate.quality.locomotion.continuous_actuators`):
``2 nu + 1 + n_c`` numbers, step size ``step`` (0.3) and a population of ``population`` (16),
one ``mujoco.rollout`` call per generation, for ``refine // population`` generations. The
objective is the same speed, fall, flight and divergence rules as :func:`gait` (the same
:class:`~robovae.evaluate.quality.locomotion.GaitTrials`); the result is the best gait of all
rollouts, ``GaitResult.rollouts`` counting all of them. Deterministic for a robot and
``seed``.

:func:`budget_gait` is the locomotion measure's search (``robovae analyze --locomotion
--gait-search random|cma --gait-rollouts N``) at a fixed budget of ``N`` rollouts: ``random``
is :func:`gait`; ``cma`` spends a quarter of the budget on random gaits and the rest on CMA-ES
generations of 16 (``N = 64``: 16 random gaits, then 3 generations), never more rollouts
than ``N``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from robovae.errors import check_seed
from robovae.evaluate.quality.locomotion import GaitResult, GaitTrials, gait, random_gaits
from robovae.evaluate.quality.stage import Robot
from robovae.settings import check_settings, choice, integer, number, span

__all__ = ["GAIT_SEARCHES", "budget_gait", "searched_gait", "trials_search"]

#: Bound of the phases, in turns: the search needs bounds, a phase is periodic.
_PHASE_TURNS = 10.0
#: The searches :func:`budget_gait` knows.
GAIT_SEARCHES = ("random", "cma")
#: :func:`budget_gait`'s CMA-ES population.
_BUDGET_POPULATION = 16


def searched_gait(robot: Robot, rollouts: int = 16, refine: int = 496, seconds: float = 4.0,
                  seed: int = 0, frequency: tuple[float, float] = (0.5, 3.0),
                  settle: float = 0.25, max_steps: int = 2_000,
                  max_tilt: float | None = None, population: int = 16,
                  step: float = 0.3) -> GaitResult:
    """``rollouts`` random gaits (:func:`~robovae.evaluate.quality.locomotion.gait`, the same
    arguments), then ``refine // population`` CMA-ES generations of ``population`` gaits from
    the best of them (module docstring). ``step``: CMA-ES's initial step size in the
    parameters' units (amplitude, turns of phase, share of the frequency range, offset).

    Raises:
        SettingsError: (a ``ValueError``) ``rollouts`` below 1, ``refine`` below 0,
            ``population`` below 2, ``step`` not > 0, a ``seed`` out of ``[0, 2**31 - 1]``, a
            ``frequency`` range that is not ``0 < low < high`` (finite), or a setting of
            :class:`~robovae.evaluate.quality.locomotion.GaitTrials` out of range.
        RobovaeError: a model without a floor; RobotFileError: a file that does not load.
    """
    _check(rollouts, refine, population, step, seed, frequency)
    return trials_search(GaitTrials(robot, seconds, settle, max_steps, max_tilt), rollouts,
                         refine, seed, frequency, population, step)


def _check(rollouts: int, refine: int, population: int, step: float, seed: int,
           frequency: tuple[float, float]) -> None:
    check_settings("searched_gait", rollouts=(rollouts, integer(1)), refine=(refine, integer(0)),
                   population=(population, integer(2)), step=(step, number(0, low_open=True)),
                   frequency=(frequency, span(strict=True)))  # CMA-ES searches a share of it
    check_seed(seed, "gait seed")


def trials_search(trials: GaitTrials, rollouts: int = 16, refine: int = 496, seed: int = 0,
                  frequency: tuple[float, float] = (0.5, 3.0), population: int = 16,
                  step: float = 0.3) -> GaitResult:
    """:func:`searched_gait` on a robot's trials already set up (a ``hold``, starts from
    :meth:`~robovae.evaluate.quality.locomotion.GaitTrials.perturb`): every gait, random or of
    CMA-ES, is judged by :meth:`~robovae.evaluate.quality.locomotion.GaitTrials.run`.

    Raises:
        ValueError: as :func:`searched_gait`.
    """
    _check(rollouts, refine, population, step, seed, frequency)
    nu = trials.model.nu
    generations = refine // population
    if nu == 0 or trials.actuated_base:
        return trials.nothing(rollouts + generations * population)
    amp, phase, freq, offset = random_gaits(np.random.default_rng(seed), rollouts, nu,
                                            frequency, trials.continuous)
    speeds, unstable, best_run = trials.run(amp, phase, freq, offset)
    k = int(np.argmax(speeds))
    best = (float(speeds[k]), float(freq[k]), amp[k], phase[k], offset[k], best_run)
    cont = np.flatnonzero(trials.continuous)
    f_lo, f_span = frequency[0], frequency[1] - frequency[0]
    mean = np.concatenate([amp[k], phase[k] / (2 * np.pi), [(freq[k] - f_lo) / f_span],
                           offset[k, cont]])
    bounds = np.concatenate([np.tile([0.0, 1.0], (nu, 1)),
                             np.tile([-_PHASE_TURNS, _PHASE_TURNS], (nu, 1)), [[0.0, 1.0]],
                             np.tile([-1.0, 1.0], (len(cont), 1))])
    # imported here: cmaes imports SciPy's stats, a second of every worker's start
    from cmaes import CMA

    optimizer = CMA(mean=mean, sigma=step, bounds=bounds, population_size=population,
                    seed=seed)
    for _ in range(generations):
        xs = np.array([optimizer.ask() for _ in range(population)])
        g_amp, g_phase = xs[:, :nu], xs[:, nu:2 * nu] * (2 * np.pi)
        g_freq = f_lo + f_span * xs[:, 2 * nu]
        g_offset = np.zeros((population, nu))
        g_offset[:, cont] = xs[:, 2 * nu + 1:]
        speeds, bad, run = trials.run(g_amp, g_phase, g_freq, g_offset)
        unstable += bad
        k = int(np.argmax(speeds))
        if speeds[k] > best[0]:
            best = (float(speeds[k]), float(g_freq[k]), g_amp[k], np.mod(g_phase[k], 2 * np.pi),
                    g_offset[k], run)
        optimizer.tell(list(zip(xs, -speeds)))
    speed, freq_best, amp_best, phase_best, offset_best, run = best
    power = trials.power(run) if speed > 0 else 0.0
    return trials.result(speed, freq_best, amp_best, phase_best, offset_best, unstable,
                         rollouts + generations * population, power)


def budget_gait(robot: Robot, search: str = "random", rollouts: int = 64,
                **kw: Any) -> GaitResult:
    """The best gait of at most ``rollouts`` rollouts found by ``search`` (module docstring):
    ``"random"``, :func:`~robovae.evaluate.quality.locomotion.gait`; ``"cma"``,
    :func:`searched_gait` with ``max(1, rollouts // 4)`` random gaits and the rest in CMA-ES
    generations of 16 (a remainder below 16 unspent). ``kw``: the other arguments of either
    (``seconds``, ``seed``, ``frequency``, ``settle``, ``max_steps``, ``max_tilt``).

    Raises:
        SettingsError: an unknown ``search`` or ``rollouts`` below 1 (and the settings of
            the search called).
    """
    check_settings("budget_gait", search=(search, choice(GAIT_SEARCHES)),
                   rollouts=(rollouts, integer(1)))
    if search == "random":
        return gait(robot, rollouts=rollouts, **kw)
    first = max(1, rollouts // 4)
    return searched_gait(robot, rollouts=first, refine=rollouts - first,
                         population=_BUDGET_POPULATION, **kw)
