"""Benchmark: generation throughput — decode, write MJCF, validate — against validating the same
files alone (issue 21: ``robovae generate --no-quality`` at >= 80 % of the MuJoCo-only
validation throughput, both on ``--jobs`` processes), and RAM.

Robots: with ``--ckpt``, N prior samples of a checkpoint decoded in float64 as ``robovae
generate`` decodes them (:func:`robovae.model.prior.draw_robots` with generate's 4 redraws,
:func:`robovae.generate.pipeline.prepare_records`: latents and node noise of seed 0, floating
base, mirrored limbs); without, the graphs of N procedural robots
(:func:`robovae.data.procedural.procedural_graphs`, ``paper34``) stand in for decoded ones (no
end-to-end row then). Rows (wall and CPU seconds; CPU of this process, or of the worker
processes once they have finished):

- ``decode`` (one torch thread, as ``generate`` decodes while its workers run) or
  ``procedural graphs``;
- ``writer``: rules + MjSpec + stance rules + files in this process, as a worker writes (no
  load check, no per-file fsync), one ``os.sync`` at the end;
- ``validate``: MuJoCo only, the written files, ``--jobs`` processes
  (:func:`robovae.generate.validate.validate_many`, ``--validation`` controls);
- ``write + validate`` in ``--jobs`` spawned worker processes
  (:func:`robovae.generate.build.build_robot` as generate's workers call it: scene, stance
  rules, no quality), less a separate run of the workers' start-up;
- with ``--ckpt``: ``generate()`` end to end (``quality=False``: decode in this process while
  the workers write and validate), then the same files validated alone.

Then, with ``--phases K`` (default 200; 0: none), the CPU per robot of each step of the writer
and of the validator, one process, on the first K robots: where a robot's milliseconds go
(each step timed on its own; steps that redo an earlier one, e.g. ``graph_to_spec``, which
applies the rules and builds the spec again, say so in their name).

Then the end-to-end throughput over the validation-only throughput of the same files (target
>= 80 %), with and without the fixed costs of each side (generate: model load, worker
start-up, summary, measured as a run of ``--jobs`` robots; validation: worker start-up, each
spawned worker importing the validator and this script, measured as a run of one chunk per
worker), and the peak RSS.

    PYTHONPATH=. python benchmarks/generate.py --ckpt runs/default/checkpoints/last.ckpt --n 2000
    PYTHONPATH=. python benchmarks/generate.py --n 1000    # procedural robots, no model
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

from robovae.data.tree_arrays import TreeArrays
from robovae.evaluate.tables import format_table
from robovae.generate.build import build_robot
from robovae.generate.validate import validate_many
from robovae.generate.writer import write_robot

_VALIDATE_CHUNK = 16  # validation work items per worker task: one each starts them all

# torch, PyG and the model stack are imported in main() and _graphs(): the spawned workers
# import this script again and, like robovae generate's, load only the writer, the validator
# and the measures (no torch).


def _cpu(children: bool = False) -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class _Clock:
    """Wall and CPU seconds of a block: this process's CPU, plus (``children``) that of the
    worker processes that finished inside it."""

    def __init__(self, children: bool = False) -> None:
        self.children = children

    def __enter__(self) -> _Clock:
        self.wall = time.perf_counter()
        self.cpu = _cpu() + (_cpu(True) if self.children else 0.0)
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall = time.perf_counter() - self.wall
        self.cpu = _cpu() + (_cpu(True) if self.children else 0.0) - self.cpu

    def minus(self, other: _Clock) -> _Clock:
        out = _Clock(self.children)
        out.wall, out.cpu = self.wall - other.wall, self.cpu - other.cpu
        return out


def _row(step: str, n: int, c: _Clock) -> dict:
    return {"step": step, "robots": n, "wall s": f"{c.wall:.2f}",
            "robots/s (wall)": f"{n / c.wall:.1f}", "CPU s": f"{c.cpu:.2f}",
            "CPU ms/robot": f"{1e3 * c.cpu / n:.2f}"}


def _phases(graphs: list, fs: str, root: Path) -> list[dict]:
    """CPU ms per robot of each writer and validator step, one process (module docstring)."""
    import mujoco

    from robovae.evaluate.quality.stage import stage_compiled
    from robovae.evaluate.quality.standing import HeldRun, first_steps
    from robovae.generate.graph_view import as_feature_set
    from robovae.generate.rules import apply_rules
    from robovae.generate.spec_builder import SpecBuilder
    from robovae.generate.validate import check_robot
    from robovae.generate.writer import graph_to_spec

    feature_set = as_feature_set(fs)
    cpu: dict[str, float] = {}

    def timed(step: str, fn, *a, **kw):
        t = time.process_time()
        out = fn(*a, **kw)
        cpu[step] = cpu.get(step, 0.0) + time.process_time() - t
        return out

    for i, g in enumerate(graphs):
        ruled, _ = timed("writer: rules (apply_rules)", apply_rules, g, feature_set)
        spec = timed("writer: MjSpec build (SpecBuilder)",
                     lambda r=ruled: SpecBuilder(r, feature_set, "robot", "auto", False).build())
        timed("writer: one compile", spec.compile)
        spec, _ = timed("writer: graph_to_spec (rules, build, compiles, stance, placement)",
                        graph_to_spec, g, feature_set, stance=True)
        timed("writer: to_xml", spec.to_xml)
        path = timed("writer: write_robot, all of it", write_robot, g, root / f"robot_{i:06d}",
                     feature_set, check=False, durable=False, stance=True).robot_path
        timed("validator: parse the file (MjSpec.from_file)", mujoco.MjSpec.from_file,
              str(path))
        checked = timed("validator: check_robot (held), all of it", check_robot, path)
        if checked.stage is None:
            continue
        # the staging and held simulation again, on the checked spec: their share of it
        st = timed("  of which: stage on the floor (stage_compiled, one compile)",
                   stage_compiled, checked.model, checked.spec, checked.floor)
        held = timed("  of which: held run set-up (HeldRun)", HeldRun, st)
        timed("  of which: 1 s held simulation (mujoco.rollout)", held.run,
              first_steps(held.model))
    return [{"step": k, "robots": len(graphs), "CPU ms/robot": f"{1e3 * v / len(graphs):.2f}"}
            for k, v in cpu.items()]


def _graphs(args: argparse.Namespace, model) -> list:
    """The graphs the workers get (:class:`TreeArrays`): decoded and prepared as generate()
    prepares them."""
    if model is None:
        from robovae.data.procedural import parse_procedural, procedural_graphs
        from robovae.generate.rules import floating_base
        from robovae.generate.symmetry import mirror_limbs

        fs = "paper34"
        graphs = procedural_graphs(parse_procedural(f"n={args.n}"), fs, jobs=1)
        return [TreeArrays.of(mirror_limbs(floating_base(g, fs)[0], fs)[0]) for g in graphs]
    from robovae.generate.pipeline import prepare_records
    from robovae.model.prior import draw_robots

    graphs = []
    for k in range(0, args.n, args.batch_size):
        chunk = list(range(k, min(args.n, k + args.batch_size)))
        # as generate() draws them: an unfinished decoding redraws its latent (default 4 times)
        z, decoded, draws = draw_robots(model, 0, chunk, 1.0, redraws=4)
        _, items = prepare_records(model, chunk, z, decoded, Path("unused"), draws=draws)
        graphs += [item[0] for item in items]
    return graphs


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--ckpt", help="checkpoint (default: procedural robots, no model)")
    p.add_argument("--n", type=int, default=1000)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--batch-size", type=int, default=1024)
    p.add_argument("--validation", choices=("held", "zero"), default="held")
    p.add_argument("--root", default=None, help="work folder (default: a temp folder)")
    p.add_argument("--phases", type=int, default=200,
                   help="robots timed step by step (writer and validator steps; 0: none)")
    args = p.parse_args()
    import torch

    from robovae.generate.pipeline import generate, worker_pool
    from robovae.model.checkpoint import load_model

    root = Path(args.root or tempfile.mkdtemp(prefix="robovae_genbench_"))
    rows = []
    model = load_model(args.ckpt).to(torch.float64) if args.ckpt else None
    fs = model.feature_set.name if model is not None else "paper34"
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    with _Clock() as c:
        graphs = _graphs(args, model)
    torch.set_num_threads(threads)
    rows.append(_row(f"decode (batch {args.batch_size}, 1 thread) + floating base, mirrored "
                     "limbs" if model is not None else "procedural graphs", args.n, c))

    with _Clock() as c:
        paths = [write_robot(g, root / "w" / f"robot_{i:06d}", fs, check=False,
                             durable=False, stance=True).robot_path
                 for i, g in enumerate(graphs)]
        os.sync()
    writer = c
    rows.append(_row("writer (rules + MjSpec + stance + files), 1 process", args.n, c))

    with _Clock(children=True) as c:
        checks = validate_many(paths, jobs=args.jobs, controls=args.validation)
    rows.append(_row(f"validate (MuJoCo only, {args.validation}), {args.jobs} processes",
                     args.n, c))

    # as generate's workers build them: scene, validation, no quality, the stance rules
    items = [(g, root / "b" / f"robot_{i:06d}", fs, f"robot_{i:06d}", True, True, False,
              args.validation, True) for i, g in enumerate(graphs)]
    with _Clock(children=True) as start, worker_pool(args.jobs) as pool:
        list(pool.map(build_robot, items[:args.jobs]))
    with _Clock(children=True) as c, worker_pool(args.jobs) as pool:
        list(pool.map(build_robot, items, chunksize=4))
    rows.append(_row(f"write + validate in {args.jobs} workers, less their start-up "
                     f"({start.wall:.1f} s)", args.n - args.jobs, c.minus(start)))

    phases = _phases(graphs[:args.phases], fs, root / "p") if args.phases > 0 else []

    ratio = None
    if model is not None:
        kw = {"jobs": args.jobs, "progress": False, "batch_size": args.batch_size,
              "quality": False, "controls": args.validation}
        with _Clock(children=True) as fixed:
            generate(model, args.jobs, root / "g0", **kw)
        with _Clock(children=True) as e2e:
            report = generate(model, args.n, root / "g", **kw)
        rows.append(_row(f"generate() end to end, --no-quality, {args.jobs} workers",
                         args.n, e2e))
        rows.append(_row(f"  the same less a run of {args.jobs} robots (model load, worker "
                         "start-up, summary)", args.n - args.jobs, e2e.minus(fixed)))
        files = [root / "g" / r / "robot.xml" for r in sorted(os.listdir(root / "g"))
                 if r.startswith("robot_")]
        # a run as short as validate_many makes with every worker started (one chunk each)
        few = _VALIDATE_CHUNK * args.jobs
        with _Clock(children=True) as vfixed:
            validate_many(files[:few], jobs=args.jobs, chunksize=_VALIDATE_CHUNK,
                          controls=args.validation)
        with _Clock(children=True) as val:
            validate_many(files, jobs=args.jobs, chunksize=_VALIDATE_CHUNK,
                          controls=args.validation)
        rows.append(_row(f"validate the same files alone, {args.jobs} processes", len(files),
                         val))
        rows.append(_row(f"  the same less a run of {few} robots (worker start-up)",
                         len(files) - few, val.minus(vfixed)))
        ratio = (val.wall / len(files)) / (e2e.wall / args.n)
        steady = ((val.minus(vfixed).wall / (len(files) - few))
                  / (e2e.minus(fixed).wall / (args.n - args.jobs)))
        by_cpu = ((val.minus(vfixed).cpu / (len(files) - few))
                  / (e2e.minus(fixed).cpu / (args.n - args.jobs)))

    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(format_table(rows, ["step", "robots", "wall s", "robots/s (wall)", "CPU s",
                              "CPU ms/robot"]))
    print(f"writer: {1e3 * writer.cpu / args.n:.2f} ms CPU per robot "
          f"({args.n / writer.cpu:.0f} robots per CPU-second)")
    if phases:
        print(format_table(phases, ["step", "robots", "CPU ms/robot"]))
    if ratio is not None:
        print(f"end to end / validation-only throughput (wall): {ratio:.0%} with each run's "
              f"fixed costs, {steady:.0%} without them (both sides); from the CPU per robot "
              f"without them (idle cores): {by_cpu:.0%}; target 80 %")
        print(report.format())
    valid = sum(cv.valid for cv in checks)
    mean_nodes = sum(g.num_nodes for g in graphs) / len(graphs)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"valid {valid}/{args.n} ({valid / args.n:.1%}), mean nodes {mean_nodes:.1f}, "
          f"peak RSS (main process) {peak:.0f} MiB")
    if args.root is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
