"""Benchmark: ``robovae/Walk-v0`` over generated robots.

1. ``gymnasium.utils.env_checker.check_env`` on the first ``--check`` generated robots that
   have actuators (robots without any are refused with the one-line error and counted apart);
2. a vector environment (``AsyncVectorEnv``, one worker process per robot) over ``--vector``
   of them, taking ``--steps`` vector steps with random actions (episodes reset
   automatically).

Prints one table: robots, passes / failures / refusals, seconds and (vector) steps per second,
counting one step per sub-environment.

Robots come from ``--samples`` (a ``robovae generate`` folder), or are generated here from
``--ckpt`` into a temporary folder (``--n`` robots, seed 0)::

    PYTHONPATH=. python benchmarks/envs.py --ckpt runs/tiny/checkpoints/last.ckpt --n 400
    PYTHONPATH=. python benchmarks/envs.py --samples runs/tiny/samples
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import gymnasium
import numpy as np
from gymnasium.utils.env_checker import check_env

import robovae.envs  # noqa: F401
from robovae.envs.vector import make_vector_env, robot_files
from robovae.errors import RobovaeError
from robovae.evaluate.tables import format_table


def checked(files: list[Path], want: int, render: bool) -> tuple[list[Path], dict]:
    """check_env on robots until ``want`` robots with actuators were checked."""
    counts = {"passed": 0, "failed": 0, "refused": 0}
    ok, failures = [], []
    for f in files:
        if counts["passed"] + counts["failed"] >= want:
            break
        try:
            env = gymnasium.make("robovae/Walk-v0", robot=str(f),
                                 render_mode="rgb_array" if render else None)
        except RobovaeError:
            counts["refused"] += 1
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                check_env(env.unwrapped, skip_render_check=not render)
            counts["passed"] += 1
            ok.append(f)
        except Exception as e:  # a failure is what we measure: record it, go on
            counts["failed"] += 1
            failures.append(f"{f}: {type(e).__name__}: {' '.join(str(e).split())[:200]}")
        finally:
            env.close()
    for line in failures:
        print("FAILED", line)
    return ok, counts


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--samples", help="folder written by robovae generate")
    p.add_argument("--ckpt", help="checkpoint to generate robots from (when no --samples)")
    p.add_argument("--n", type=int, default=400, help="robots to generate from --ckpt")
    p.add_argument("--check", type=int, default=100, help="robots given to check_env")
    p.add_argument("--render", action="store_true", help="include check_env's render checks")
    p.add_argument("--vector", type=int, default=16, help="robots in the vector env")
    p.add_argument("--steps", type=int, default=10_000, help="vector env steps")
    args = p.parse_args()
    if not args.samples:
        if not args.ckpt:
            p.error("give --samples or --ckpt")
        from robovae.generate.pipeline import generate

        args.samples = tempfile.mkdtemp(prefix="robovae_envs_")
        generate(args.ckpt, args.n, args.samples, seed=0, validate=False, progress=False)
    files = robot_files(args.samples)
    rows = []
    t = time.perf_counter()
    ok, counts = checked(files, args.check, args.render)
    dt = time.perf_counter() - t
    rows.append({"test": "check_env" + (" (+render)" if args.render else ""),
                 "robots": counts["passed"] + counts["failed"], **counts,
                 "seconds": f"{dt:.1f}", "steps/s": ""})
    robots = ok[:args.vector]
    venv = make_vector_env(robots)
    venv.reset(seed=0)
    venv.action_space.seed(0)
    episodes, errors = 0, 0
    t = time.perf_counter()
    for _ in range(args.steps):
        _, reward, terminated, truncated, _ = venv.step(venv.action_space.sample())
        episodes += int(np.sum(terminated | truncated))
        errors += int(not np.isfinite(reward).all())
    dt = time.perf_counter() - t
    venv.close()
    rows.append({"test": f"AsyncVectorEnv x{len(robots)}, {args.steps} steps",
                 "robots": len(robots), "passed": len(robots) if not errors else 0,
                 "failed": errors, "refused": "", "seconds": f"{dt:.1f}",
                 "steps/s": f"{args.steps * len(robots) / dt:.0f} "
                            f"({args.steps / dt:.0f} vector)"})
    print(format_table(rows, ["test", "robots", "passed", "failed", "refused", "seconds",
                              "steps/s"]))
    print(f"robots from {args.samples}; vector env: {episodes} episodes ended "
          f"(terminated or truncated), non-finite rewards in {errors} steps")


if __name__ == "__main__":
    main()
