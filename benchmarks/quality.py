"""Benchmark: CPU time of validation and of each quality measure per robot, and of all of them
for many robots on ``--jobs`` cores (issue 21: 10,000 validated robots with every measure but
locomotion in <= 120 s on 2 cores, i.e. about 24 ms of CPU per robot).

Robots (``--robots``): ``written`` (default; the graphs of ``--n`` procedural robots and of the
zoo written the way ``robovae generate`` writes a decoded robot,
:func:`robovae.evaluate.quality.populations.written_files`), ``procedural`` (the procedural
generator's own MJCF files) or a ``robovae generate`` folder (``--samples DIR``).

1. Per robot, in this process, after ``--warmup`` robots, the CPU time (``time.process_time``)
   of each stage as ``robovae generate`` runs it. With ``--controls held`` (default):
   ``validate`` (parse, compile with a floor, checks at rest, the floor moved to the robot's
   lowest point and the spec compiled again, the hold, 1 s of held simulation:
   :func:`~robovae.generate.validate.check_robot`), ``anatomy`` (counts, limbs, symmetry),
   ``attachment`` (detached bodies, self-penetration), ``standing`` (the held simulation
   continued to at most 3 s), ``descriptors`` (graph descriptors). With ``--controls zero``
   (the validation before 2026-11-25): ``validate`` (1 s with zero controls), ``load``
   (:func:`~robovae.evaluate.quality.stage.stage_compiled`), then the same measures, the
   standing test simulating from the start.
2. Validation and every measure but locomotion (``measure(describe=True)``) of every robot in
   ``--jobs`` worker processes (``spawn``): the workers' CPU time and the wall clock, less
   those of a separate run of the workers' start-up (imports and one robot each).
3. Locomotion (64 rollouts of 4 s) on ``--gait`` robots, in this process.

Prints one table, the load average, and the time of 10,000 robots: the CPU per robot over
``--jobs`` (an otherwise idle machine with that many cores) and at the measured wall rate (this
machine as loaded as it was).

    PYTHONPATH=. python benchmarks/quality.py --n 200 --jobs 2 --gait 4
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from robovae.data.mjcf import model_to_graph
from robovae.evaluate.descriptors import descriptors
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.quality.measure import measure
from robovae.evaluate.quality.populations import procedural_files, written_files
from robovae.evaluate.quality.stage import stage_compiled
from robovae.evaluate.quality.standing import standing
from robovae.evaluate.quality.symmetry import anatomy
from robovae.evaluate.tables import format_table
from robovae.generate.validate import check_robot

STAGES = ("validate", "load", "anatomy", "attachment", "standing", "descriptors")


def _staged(checked):
    """The stage the measures run on, and the held run the standing test continues."""
    if checked.stage is not None:
        return checked.stage, checked.held
    c = checked
    return stage_compiled(c.model, c.spec, c.floor, c.data), None


def stage_times(path: str, controls: str = "held") -> dict[str, float]:
    """CPU seconds of each stage of one robot (module docstring, 1.); the measures only for a
    valid robot."""
    out = {}
    t = time.process_time()
    checked = check_robot(path, controls=controls)
    out["validate"] = time.process_time() - t
    if not checked.validation.valid:
        return out
    t = time.process_time()
    st, held = _staged(checked)
    if held is None:
        out["load"] = time.process_time() - t
    for name, fn in (("anatomy", anatomy), ("attachment", attachment),
                     ("standing", lambda s: standing(s, held=held)),
                     ("descriptors", lambda s: descriptors(model_to_graph(s.model)))):
        t = time.process_time()
        fn(st)
        out[name] = time.process_time() - t
    return out


def validate_and_measure(item: tuple[str, str]) -> bool:
    """What a generation worker does for one robot file: validate it and, when valid, measure
    it on the validator's model (every measure but locomotion). Returns validity."""
    path, controls = item
    checked = check_robot(path, controls=controls)
    if checked.validation.valid:
        st, held = _staged(checked)
        measure(st, describe=True, held=held)
    return checked.validation.valid


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _files(args: argparse.Namespace, tmp: str) -> list[str]:
    if args.samples:
        from robovae.evaluate.analyze import sample_files

        return [str(f) for _, f in sample_files(args.samples)][:args.n]
    if args.robots == "procedural":
        return [str(f) for f in procedural_files(args.n, tmp)]
    return [str(f) for f in written_files(args.n, tmp)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--robots", choices=("written", "procedural"), default="written")
    p.add_argument("--samples", help="robovae generate folder (instead of --robots)")
    p.add_argument("--n", type=int, default=200, help="robots (written: plus the zoo's)")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--warmup", type=int, default=5, help="robots run before timing")
    p.add_argument("--gait", type=int, default=4, help="robots for the locomotion measure")
    p.add_argument("--controls", choices=("held", "zero"), default="held",
                   help="the validation's simulation (robovae.generate.validate)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        files = _files(args, tmp)
        for f in files[:args.warmup]:
            stage_times(f, args.controls)
        per = [stage_times(f, args.controls) for f in files]
        valid = [r for r in per if "anatomy" in r]
        table = []
        for k in STAGES:
            if k == "load" and args.controls == "held":
                continue
            t = np.array([r[k] for r in (per if k == "validate" else valid)])
            table.append({"stage": k, "robots": len(t),
                          "CPU ms/robot": f"{1e3 * t.mean():.2f} ± {1e3 * t.std():.2f}"})
        cpu = float(np.mean([sum(r.values()) for r in per]))
        table.append({"stage": "total (validation + every measure but locomotion)",
                      "robots": len(per), "CPU ms/robot": f"{1e3 * cpu:.2f}"})

        ctx = multiprocessing.get_context("spawn")
        c0, w0 = _children_cpu(), time.perf_counter()
        with ProcessPoolExecutor(args.jobs, mp_context=ctx) as pool:
            list(pool.map(validate_and_measure, [(f, args.controls) for f in files[:args.jobs]]))
        startup, startup_cpu = time.perf_counter() - w0, _children_cpu() - c0
        c0, w0 = _children_cpu(), time.perf_counter()
        with ProcessPoolExecutor(args.jobs, mp_context=ctx) as pool:
            chunk = max(1, min(16, len(files) // (4 * args.jobs)))
            list(pool.map(validate_and_measure, [(f, args.controls) for f in files],
                          chunksize=chunk))
        wall = time.perf_counter() - w0 - startup
        workers_cpu = _children_cpu() - c0 - startup_cpu
        table.append({"stage": f"the same in {args.jobs} processes (less a separate run of the "
                               f"workers' start-up: {startup:.1f} s, {startup_cpu:.1f} s CPU)",
                      "robots": len(files),
                      "CPU ms/robot": f"{1e3 * workers_cpu / len(files):.2f} "
                                      f"({1e3 * wall / len(files):.2f} wall)"})
        if args.gait:
            t = time.process_time()
            for f in files[:args.gait]:
                measure(f, locomotion=True, describe=False)
            gait = (time.process_time() - t) / args.gait
            table.append({"stage": "locomotion (64 x 4 s) with every other measure",
                          "robots": args.gait, "CPU ms/robot": f"{1e3 * gait:.0f}"})
    what = args.samples or args.robots
    print(f"robots: {len(files)} ({what}), {len(valid)} valid, validation {args.controls}; "
          f"load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(format_table(table, ["stage", "robots", "CPU ms/robot"]))
    print(f"10,000 robots, validation + every measure but locomotion, {args.jobs} cores: "
          f"{10_000 * cpu / args.jobs:.0f} s from the CPU per robot (idle cores), "
          f"{10_000 * workers_cpu / len(files) / args.jobs:.0f} s from the workers' CPU, "
          f"{startup + 10_000 * wall / len(files):.0f} s at the measured wall rate of this "
          f"machine (as loaded as it was), worker start-up once (target 120 s)")


if __name__ == "__main__":
    main()
