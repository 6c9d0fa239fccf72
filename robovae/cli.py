"""The ``robovae`` command.

``robovae data``       build a dataset and print one row per robot;
``robovae generate``   sample robots from a checkpoint, write MJCF, validate, report;
``robovae interpolate`` robots on the latent line between two robots, with a contact sheet;
``robovae optimize``   CMA-ES over the latent space for walk / step / stand / reach, with baselines;
``robovae gait``       an open-loop gait tuned to each robot's body, for ``robovae/Walk-v0``;
``robovae render``     PNG contact sheets and original-vs-reconstruction pictures;
``robovae analyze``    statistics of the design space: descriptors, KL/MMD/coverage, latent
                       entropy, MuJoCo state entropy and standing test;
``robovae fit|validate|test|predict``  the Lightning CLI (model + data from a YAML config).
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from robovae.errors import RobovaeError
from robovae.evaluate.tables import format_table
from robovae.exits import (
    DISK_ERRORS,
    INTERRUPTED,
    interrupted,
    one_line_warnings,
    quiet_after_interrupt,
)

LIGHTNING_COMMANDS = ("fit", "validate", "test", "predict")
#: Robots ``robovae data`` lists (the build report holds them all).
MAX_TABLE_ROWS = 200


def cmd_data(args: argparse.Namespace) -> int:
    """Build the dataset of ``--source``s and print the per-robot table."""
    from robovae.data.features import get_feature_set  # NumPy only
    from robovae.data.sources import check_sources  # without torch: a typo refused at once

    get_feature_set(args.feature_set)
    check_sources(args.source, args.feature_set)
    from robovae.data.dataset import RobotDataset

    ds = RobotDataset(args.root, args.source, args.feature_set, jobs=args.jobs,
                      force_reload=args.rebuild)
    rows = []
    for r in ds.report["robots"]:
        w = r["warnings"]
        rows.append({**r, "warnings": (w[:70] + "…") if len(w) > 71 else w})
    cols = ["name", "links", "joints"] + (["geoms"] if ds.feature_set == "full" else []) + \
        ["depth", "limbs", "features", "warnings"]
    print(format_table(rows[:MAX_TABLE_ROWS], cols))
    if len(rows) > MAX_TABLE_ROWS:
        print(f"... {len(rows) - MAX_TABLE_ROWS} more robots: every row is in "
              f"{ds.processed_paths[1]}")
    rep = ds.report
    print(f"\n{len(rows)} robots, feature set {ds.feature_set}, {len(rep['skipped'])} skipped, "
          f"{len(rep['duplicates'])} duplicates; cache {ds.processed_paths[0]}")
    notes = rep["warnings"] + rep["duplicates"]
    for line in notes[:MAX_TABLE_ROWS]:
        print(f"note: {line}")
    for line in rep["skipped"]:
        print(line, file=sys.stderr)
    return 0


def cmd_generate(args: argparse.Namespace) -> int:
    """Sample robots from a checkpoint, write MJCF, validate, print the sample report."""
    from robovae.options import BATCH_SIZE, check_generate, check_like  # before the heavy imports

    if args.like:
        check_like(args.radius, args.n, args.redraws, args.seed, jobs=args.jobs)
        unused = [flag for flag, given in (
            ("--temperature", args.temperature != 1.0), ("--prior", args.prior is not None),
            ("--node-temperature", args.node_temperature is not None),
            ("--batch-size", args.batch_size != BATCH_SIZE)) if given]
        if unused:  # they were ignored silently until 2026-12-01
            raise RobovaeError(f"robovae: {', '.join(unused)}: not used with --like (variations "
                               "are drawn within --radius of the robot's own latent)")
        from robovae.design.variations import generate_like

        report = generate_like(args.ckpt, args.like, args.radius, args.n, args.out,
                               seed=args.seed, validate=args.validate, jobs=args.jobs,
                               scene=args.scene, overwrite=args.overwrite,
                               floating=args.floating_base, redraws=args.redraws,
                               mirror=args.mirror_limbs, stance=args.stance,
                               quality=args.quality, controls=args.validation,
                               self_collision=args.self_collision)
        print(report.format())
        print(f"manifest: {report.out / 'manifest.jsonl'}, summary: {report.out / 'summary.json'}")
        return 0
    check_generate(args.n, args.temperature, args.node_temperature, args.batch_size, args.jobs,
                   args.redraws, args.seed)
    from robovae.generate.pipeline import generate

    report = generate(args.ckpt, args.n, args.out, seed=args.seed,
                      temperature=args.temperature, validate=args.validate,
                      batch_size=args.batch_size, jobs=args.jobs, scene=args.scene,
                      overwrite=args.overwrite, floating=args.floating_base,
                      mirror=args.mirror_limbs, node_temperature=args.node_temperature,
                      quality=args.quality, controls=args.validation, redraws=args.redraws,
                      prior=args.prior, stance=args.stance,
                      self_collision=args.self_collision)
    print(report.format())
    print(f"manifest: {report.out / 'manifest.jsonl'}, summary: {report.out / 'summary.json'}")
    return 0


def cmd_interpolate(args: argparse.Namespace) -> int:
    """Decode the latent path between two robots, validate each step, draw a contact sheet."""
    from robovae.options import check_interpolate

    check_interpolate(args.steps)  # before the heavy imports (robovae.options)
    from robovae.design.variations import interpolate_files

    res = interpolate_files(args.ckpt, args.a, args.b, args.steps, args.out,
                            validate=args.validate, sheet=args.sheet,
                            self_collision=args.self_collision)
    rows = [{"step": k, "t": f"{s['t']:.3f}", "valid": s["valid"], "reason": s["reason"],
             "robot": s["path"]} for k, s in enumerate(res["steps"])]
    print(format_table(rows, ["step", "t", "valid", "reason", "robot"]))
    print(f"path: {Path(args.out) / 'path.json'}" + (f", sheet: {res['sheet']}"
                                                     if res["sheet"] else ""))
    return 0


def cmd_optimize(args: argparse.Namespace) -> int:
    """CMA-ES over the latent space for a task, with random-prior and procedural baselines."""
    from robovae.options import check_optimize

    check_optimize(args.task, args.budget, args.top, args.variance, args.population,  # before
                   args.score_sets, args.restart_after, args.local_step, args.distinct,  # torch
                   args.seed, args.jobs)
    from robovae.design.optimize import METHODS, optimize
    from robovae.design.score import GAIT_TASKS

    res = optimize(args.ckpt, args.task, args.budget, args.out, seed=args.seed, jobs=args.jobs,
                   top=args.top, variance=args.variance, population=args.population,
                   score_sets=args.score_sets, self_collision=args.self_collision,
                   **{k: v for k, v in (
                       ("restart_after", args.restart_after), ("local_step", args.local_step),
                       ("distinct", args.distinct)) if v is not None})
    held = "held-out median"  # the best robot re-scored with score seeds 1-8
    pick = "held-out best (rank)"  # the largest such median among the --top best robots
    rows = [{"method": m, "evaluations": res[m]["evaluations"], "best": f"{res[m]['best']:.4f}",
             "best index": res[m]["best_index"],
             held: "" if res[m]["heldout"] is None else f"{res[m]['heldout']:.4f}",
             pick: "" if res[m]["heldout_best"] is None else
             f"{res[m]['heldout_best']:.4f} ({res[m]['heldout_best_rank']})"}
            for m in METHODS]
    power = "best's W/kg"  # walk: mechanical power of the best robot's scoring gait per kg
    wheeled = "top wheeled"  # walk: top robots with a motor on an unlimited hinge (may roll)
    for m, row in zip(METHODS, rows):
        row[power] = "" if res[m].get("power_per_kg") is None else f"{res[m]['power_per_kg']:.0f}"
        row[wheeled] = "" if res[m].get("top_wheeled") is None else \
            f"{res[m]['top_wheeled']}/{res[m]['top_robots']}"
    columns = ["method", "evaluations", "best", "best index", held, pick]
    gaits = args.task in GAIT_TASKS
    print(format_table(rows, columns + ([power, wheeled] if gaits else [])))
    print(f"log: {res['log']}, convergence: {res['plot']}, best robots: {args.out}/best/")
    if gaits:  # robovae.design.results
        print(f"each best robot's gait: {args.out}/best/<method>/rank_<k>/gait.json "
              "(replay in robovae/Walk-v0: robovae.envs.gait); gaits tuned to the bodies: "
              f"robovae gait {args.out}/best/<method>")
    return 0


def cmd_gait(args: argparse.Namespace) -> int:
    """Tune each robot's open-loop gait (walk score's search + CMA-ES) and write it."""
    from robovae.design.gaits import tune_gaits
    from robovae.files import robot_files

    files = robot_files(args.paths)
    if not files:  # folders without robot files
        raise RobovaeError(f"robovae: {', '.join(args.paths)}: no robot files")
    res = tune_gaits(files, refine=args.refine, seed=args.seed, step=args.step, out=args.out,
                     jobs=args.jobs, starts=args.starts, hold=args.hold, noise=args.noise,
                     overwrite=args.overwrite)
    rows = [{"robot": str(f), "walk score": f"{g['walk_score']:.4f}",
             "tuned": f"{g['score']:.4f}", "m/s": f"{g['speed']:.3f}",
             "Hz": "" if g["frequency"] is None else f"{g['frequency']:.2f}",
             "wheeled": g["wheeled"], "gait": str(path)} for f, (path, g) in zip(files, res)]
    print(format_table(rows, ["robot", "walk score", "tuned", "m/s", "Hz", "wheeled", "gait"]))
    judged = "from the rest state" if args.starts == 1 else \
        f"the median from {args.starts} starts, {args.starts - 1} with noise {args.noise}"
    print("body lengths per second; walk score: the best of 8 random gaits; tuned: then "
          f"{args.refine // 16} CMA-ES generations of 16, each gait {judged}, each control held "
          f"{args.hold} physics step(s); replay a gait in robovae/Walk-v0 with robovae.envs.gait")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    """Contact sheet of robots, or a robot next to its reconstruction (``--ckpt``)."""
    from robovae.evaluate.figures import reconstruction_figure, sample_sheet

    if args.ckpt:
        for robot in args.paths:
            res = reconstruction_figure(args.ckpt, robot, args.out if len(args.paths) == 1
                                        else Path(args.out).with_name(f"{Path(robot).stem}.png"))
            print(f"{robot}: RA {res['ra']:.3f}, RA_true {res['ra_true']:.3f}, FRE "
                  f"{res['fre']:.2e} -> {res['image']}, {res['graphs']}")
    else:
        print(sample_sheet(args.paths, args.out, first=args.first, columns=args.columns))
    return 0


def cmd_analyze(args: argparse.Namespace) -> int:
    """Statistical view of a checkpoint's training robots and (optionally) its samples."""
    from robovae.files import writable_file
    from robovae.options import check_analyze

    check_analyze(behaviour=args.behaviour, jobs=args.jobs, permutations=args.permutations,
                  quality=args.quality, procedural=args.procedural, max_samples=args.max_samples,
                  entropy_seconds=args.entropy_seconds, gait_rollouts=args.gait_rollouts,
                  gait_search=args.gait_search, seed=args.seed,  # before the heavy imports
                  real=args.real)
    if args.json:  # and before minutes of analysis whose figures it would lose
        writable_file(args.json, "report")
    from robovae.evaluate.analyze import analyze, format_report, save_json

    result = analyze(args.ckpt, samples=args.samples, sources=args.source, root=args.root,
                     behaviour=args.behaviour, jobs=args.jobs, permutations=args.permutations,
                     seed=args.seed, max_samples=args.max_samples,
                     entropy_seconds=args.entropy_seconds, quality=args.quality,
                     procedural=args.procedural, real=args.real, locomotion=args.locomotion,
                     sheets=args.sheets, gait_search=args.gait_search,
                     gait_rollouts=args.gait_rollouts)
    print(format_report(result))
    if args.json:
        print(f"json: {save_json(result, args.json)}")
    return 0


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (:class:`RobovaeError`), not its usage
    text."""

    def error(self, message: str) -> NoReturn:
        raise RobovaeError(f"{self.prog}: {message} ({self.prog} --help lists the options)")


def build_parser() -> argparse.ArgumentParser:
    """The ``robovae`` argument parser: one sub-command per pipeline step."""
    from robovae.options import BATCH_SIZE  # no torch: the parser stays light

    p = _Parser(prog="robovae", description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser("data", help="build a robot dataset and print a table")
    d.add_argument("--source", action="append", default=None,
                   help="zoo | menagerie:NAME,... | dir:PATH | file:PATH | synthetic:... | "
                        "procedural:n=N (repeatable; default zoo)")
    d.add_argument("--feature-set", default="paper34",
                   help="paper34 | kinematic | full (synthetic sources: random<dim>)")
    d.add_argument("--root", default="data_cache", help="cache folder")
    d.add_argument("--jobs", type=int, default=0, help="worker processes (0: all cores)")
    d.add_argument("--rebuild", action="store_true", help="ignore the cache")
    d.set_defaults(func=cmd_data)
    g = sub.add_parser("generate", help="sample robots from a checkpoint and write MJCF")
    g.add_argument("--ckpt", required=True, help="Lightning checkpoint (e.g. last.ckpt)")
    g.add_argument("-n", type=int, default=100, help="number of robots")
    g.add_argument("--out", required=True, help="output folder (re-running resumes)")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--temperature", type=float, default=1.0, help="prior std multiplier")
    g.add_argument("--validate", action=argparse.BooleanOptionalAction, default=True,
                   help="simulate each robot 1 s in MuJoCo and classify it")
    g.add_argument("--validation", choices=("held", "zero"), default="held",
                   help="the validation's second: joints PD-held at rest (the first second of "
                   "the standing test; default) or zero controls")
    g.add_argument("--scene", action=argparse.BooleanOptionalAction, default=True,
                   help="also write scene.xml (floor + light + robot)")
    g.add_argument("--batch-size", type=int, default=BATCH_SIZE, help="latents decoded at once")
    g.add_argument("--jobs", type=int, default=0, help="validation processes (0: all cores)")
    g.add_argument("--floating-base", action=argparse.BooleanOptionalAction, default=True,
                   help="a robot whose root is a single joint gets a free joint (paper34 has "
                   "no joint types: otherwise its root would be a hinge to the world)")
    g.add_argument("--overwrite", action="store_true",
                   help="--out holds robots of another checkpoint/seed: delete them first")
    g.add_argument("--mirror-limbs", action=argparse.BooleanOptionalAction, default=True,
                   help="near-mirror limb pairs on the trunk become exact mirror images, a "
                        "stray limb beside them gets its mirror image, near-equal limbs on "
                        "the sagittal plane become equal, and near-mirror branches below the "
                        "trunk (a chest's arms) mirror images")
    g.add_argument("--stance", action=argparse.BooleanOptionalAction, default=True,
                   help="a free-floating robot's hanging wheels are lowered onto the floor, its "
                   "soles laid flat, and a robot on two feet gets its stilts stood on their "
                   "ends, ankle motors strong enough for its soles and a home keyframe with its "
                   "centre of mass over them (ground_wheels, level_soles, level_stilts, "
                   "strong_ankles, balance_home)")
    g.add_argument("--self-collision", action="store_true",
                   help="the robot's bodies collide with each other (legs with the trunk and "
                   "each other), but for the pairs in contact at rest (self_collision_excludes)")
    g.add_argument("--quality", action=argparse.BooleanOptionalAction, default=True,
                   help="measure every valid robot: attached, symmetric, standing (the "
                   "standing test continues the validation's held second)")
    g.add_argument("--redraws", type=int, default=4,
                   help="a sample whose decoding reached the decoder's node or depth limit (an "
                   "unfinished tree) redraws its latent up to this many times (rule "
                   "redraw_unfinished)")
    g.add_argument("--prior", choices=["mixture", "standard"], default=None,
                   help="sampling prior: the latent mixture fitted to the training robots "
                   "(default when the checkpoint has one) or the standard normal N(0, I)")
    g.add_argument("--node-temperature", type=float, default=None,
                   help="std multiplier of the node latents' noise (default: the checkpoint's "
                   "node_temperature, else --temperature); 0: every node's detail at its "
                   "prior mean, more robots stand, fewer training robots are covered "
                   "(docs/generation.md)")
    g.add_argument("--like", help="a robot file: sample variations of it (around its encoded "
                   "latent, within --radius) instead of prior samples")
    g.add_argument("--radius", type=float, default=1.0,
                   help="with --like: radius of the variations in the prior's standard "
                        "deviations, in its principal subspace (0: reconstructions; the "
                        "prior's own draws lie about 3 from its mean)")
    g.set_defaults(func=cmd_generate)
    i = sub.add_parser("interpolate", help="robots on the latent line between two robots, "
                       "validated, with a contact sheet")
    i.add_argument("a", help="first robot file (t = 0)")
    i.add_argument("b", help="second robot file (t = 1)")
    i.add_argument("--ckpt", required=True, help="Lightning checkpoint (e.g. last.ckpt)")
    i.add_argument("--steps", type=int, default=8, help="robots on the path, ends included")
    i.add_argument("--out", required=True, help="output folder (must not exist or be empty)")
    i.add_argument("--validate", action=argparse.BooleanOptionalAction, default=True,
                   help="simulate each step 1 s in MuJoCo and classify it")
    i.add_argument("--sheet", action=argparse.BooleanOptionalAction, default=True,
                   help="render the contact sheet sheet.png (MUJOCO_GL=egl off-screen)")
    i.add_argument("--self-collision", action="store_true",
                   help="the steps' bodies collide with each other, but for the pairs in "
                   "contact at rest (self_collision_excludes)")
    i.set_defaults(func=cmd_interpolate)
    o = sub.add_parser("optimize", help="CMA-ES over the latent space for a task (walk, step, "
                       "stand, reach), against random prior samples and procedural robots")
    o.add_argument("--ckpt", required=True, help="Lightning checkpoint (e.g. last.ckpt)")
    o.add_argument("--task", required=True,
                   help="walk | step (walk, wheeled robots score 0) | stand | reach")
    o.add_argument("--budget", type=int, required=True,
                   help="robot evaluations per method (CMA-ES, prior, procedural)")
    o.add_argument("--out", required=True, help="output folder (re-running continues its log)")
    o.add_argument("--seed", type=int, default=0)
    o.add_argument("--top", type=int, default=10,
                   help="best robots written and re-scored with held-out seeds, per method")
    o.add_argument("--variance", type=float, default=0.9,
                   help="CMA-ES searches the sampling prior's leading directions that hold this "
                        "share of its variance (1: the whole latent space; docs/design.md)")
    o.add_argument("--population", type=int, default=None,
                   help="CMA-ES candidates per generation (default: 4 + floor(3 ln k) for k "
                        "searched directions)")
    o.add_argument("--score-sets", type=int, default=1,
                   help="score each robot with this many score seeds and take the median (for "
                        "walk: sets of 8 gaits; each evaluation costs that many scorings)")
    o.add_argument("--restart-after", type=int, default=None,
                   help="CMA-ES generations without a better robot before it restarts, in "
                        "turn locally (around the best so far) and globally (IPOP); default 10")
    o.add_argument("--local-step", type=float, default=None,
                   help="step size of a local restart, in the whitened prior's units; "
                        "default 0.15")
    o.add_argument("--distinct", type=float, default=None,
                   help="least distance between two latent designs among the --top best robots, "
                        "in the whitened prior's units (0: near copies allowed); default 1")
    o.add_argument("--self-collision", action="store_true",
                   help="every robot's bodies collide with each other, but for the pairs in "
                   "contact at rest (legs cannot pass through the trunk or each other)")
    o.add_argument("--jobs", type=int, default=0, help="scoring processes (0: all cores)")
    o.set_defaults(func=cmd_optimize)
    t = sub.add_parser("gait", help="tune an open-loop gait to each robot's body (the walk "
                       "score's 8 random gaits, then CMA-ES) and write it for robovae/Walk-v0")
    t.add_argument("paths", nargs="+", help="robot files or folders (robot_*/robot.xml)")
    t.add_argument("--refine", type=int, default=496,
                   help="CMA-ES gaits after the 8 random gaits, in generations of 16")
    t.add_argument("--starts", type=int, default=4,
                   help="judge each gait by its median speed from this many starts: the rest "
                        "state and the others with robovae/Walk-v0's reset noise (1: the rest "
                        "state only)")
    t.add_argument("--hold", type=int, default=5,
                   help="physics steps each control is held, as robovae/Walk-v0's frame_skip "
                        "(1: a control at every step)")
    t.add_argument("--noise", type=float, default=0.05,
                   help="scale of the starts' noise (robovae/Walk-v0's reset_noise_scale)")
    t.add_argument("--seed", type=int, default=0, help="the walk score's seed")
    t.add_argument("--step", action="store_true",
                   help="refuse wheeled robots (a motor on a hinge without limits), as task "
                        "step does")
    t.add_argument("--out", help="folder for the gait files (default: gait_tuned.json beside "
                   "each robot)")
    t.add_argument("--overwrite", action="store_true",
                   help="replace gait files of other robots at the destinations (e.g. an earlier "
                        "run's into the same --out)")
    t.add_argument("--jobs", type=int, default=0, help="processes (0: all cores)")
    t.set_defaults(func=cmd_gait)
    r = sub.add_parser("render", help="PNG contact sheet of robots, or original vs "
                       "reconstruction with --ckpt (MUJOCO_GL=egl renders off-screen)")
    r.add_argument("paths", nargs="+", help="robot files or folders (robot_*/robot.xml)")
    r.add_argument("--out", required=True, help="output PNG")
    r.add_argument("--ckpt", help="reconstruct each robot with this model (side by side)")
    r.add_argument("--first", type=int, default=20, help="robots on the contact sheet")
    r.add_argument("--columns", type=int, default=5)
    r.set_defaults(func=cmd_render)
    a = sub.add_parser("analyze", help="descriptor statistics, KL/MMD/coverage against the "
                       "training robots, latent entropy, MuJoCo state entropy and standing test")
    a.add_argument("--ckpt", required=True, help="Lightning checkpoint (e.g. last.ckpt)")
    a.add_argument("--samples", help="folder written by robovae generate (valid robots used)")
    a.add_argument("--source", action="append", default=None,
                   help="data source of the training robots (repeatable; default: the "
                        "checkpoint's)")
    a.add_argument("--root", default="data_cache", help="dataset cache folder")
    a.add_argument("--json", help="write the full result (per-robot rows too) to this file")
    a.add_argument("--behaviour", type=int, default=100,
                   help="MuJoCo measures on at most this many robots per population (0: none)")
    a.add_argument("--entropy-seconds", type=float, default=3.0,
                   help="length of each random-actuation episode")
    a.add_argument("--max-samples", type=int, default=None, help="use the first N samples")
    a.add_argument("--permutations", type=int, default=200, help="MMD permutation test size")
    a.add_argument("--seed", type=int, default=0)
    a.add_argument("--jobs", type=int, default=0, help="MuJoCo worker processes (0: all cores)")
    a.add_argument("--quality", type=int, default=200, help="quality measures on at most N "
                   "robots per population: samples, corpus, procedural, real (0: none)")
    a.add_argument("--procedural", type=int, default=200, help="procedural robots compared")
    a.add_argument("--real", help="folder of real robots (default ../shared/menagerie)")
    a.add_argument("--locomotion", action="store_true",
                   help="also measure gait speed (--gait-rollouts of 4 s per robot: slow)")
    a.add_argument("--gait-search", default="random",
                   help="gait speed: 'random' open-loop gaits, or 'cma': the best of a quarter "
                   "of the budget tuned by CMA-ES")
    a.add_argument("--gait-rollouts", type=int, default=64,
                   help="gait speed: rollouts per robot (default 64)")
    a.add_argument("--sheets", help="write quality contact sheets (PNG) into this folder")
    a.set_defaults(func=cmd_analyze)
    for name in LIGHTNING_COMMANDS:
        sub.add_parser(name, help=f"Lightning CLI: {name} (see robovae {name} --help)",
                       add_help=False)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``robovae`` console script. Ctrl-C ends a run with one line and exit
    status :data:`INTERRUPTED` (every file is written whole or not at all: ``generate``,
    ``generate --like``, ``optimize`` and ``fit --ckpt_path last`` go on from there when run
    again), not with Python's traceback of wherever the run was."""
    explicit = argv is not None
    argv = list(sys.argv[1:] if argv is None else argv)
    with one_line_warnings():
        try:
            return _main(argv, explicit)
        except BaseException as e:
            if not interrupted(e):
                raise
            threading.excepthook = quiet_after_interrupt
            print("\nrobovae: interrupted; the files written are whole (generate and optimize "
                  "go on from them when run again)", file=sys.stderr)
            return INTERRUPTED


def _main(argv: list[str], explicit: bool) -> int:
    args = None
    try:
        if argv and argv[0] in LIGHTNING_COMMANDS:
            from robovae.model.cli import run_lightning_cli

            run_lightning_cli(argv if explicit else None)
            return 0
        args = build_parser().parse_args(argv)
        if getattr(args, "jobs", 0) < 0:
            raise RobovaeError(f"robovae: --jobs must be 0 (all cores) or more, not {args.jobs}")
        if args.command == "data" and not args.source:
            args.source = ["zoo"]
        return args.func(args)
    except (RobovaeError, KeyError) as e:
        msg = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
        print(msg if str(msg).startswith("robovae") else f"robovae: {msg}", file=sys.stderr)
        return 2
    except OSError as e:  # the disk filled up (or became read-only) while the run wrote
        if e.errno not in DISK_ERRORS:
            raise
        where = e.filename or getattr(args, "out", None) or "the output"
        print(f"robovae: {where}: cannot write there ({e.strerror}); what was written whole "
              "is kept", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
