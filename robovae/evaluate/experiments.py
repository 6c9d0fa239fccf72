"""The paper's experiments (§5, SPEC §6), one command each, and the tables of ``docs/results.md``.

Every experiment is a Lightning CLI config under ``configs/`` (``robovae fit --config ...`` runs it
alone); this module runs them for several seeds, scores the greedy reconstructions of the test
robots (RA, RA_true, exact, FRE; :mod:`robovae.evaluate.metrics`), stores one ``result.json`` per
run, and renders the result tables and loss curves (runner:
:mod:`robovae.evaluate.experiment_runner`, tables: :mod:`robovae.evaluate.experiment_tables`)::

    python -m robovae.evaluate.experiments run menagerie4 --seeds 0,1,2
    python -m robovae.evaluate.experiments loo --seeds 0,1,2      # leave-one-out over the 17
    python -m robovae.evaluate.experiments ablation --seeds 0,1,2 --loo   # + LOO per variant
    python -m robovae.evaluate.experiments report                 # docs/results.md + docs/img
    python -m robovae.evaluate.experiments all                    # everything (``--all`` too)

Runs live in ``runs/experiments/<experiment>/<variant>/seed<k>/`` (``metrics.csv`` of the CSV
logger, ``result.json``, ``checkpoints/last.ckpt``). ``report`` only reads those folders: every
number in the tables comes from a run that was done, with its seed, epochs, wall time and the
machine load measured around it.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from robovae.errors import RobovaeError
from robovae.evaluate.experiment_runner import (  # noqa: F401  (the runner's public names)
    ABLATIONS,
    DOCS,
    EXPERIMENTS,
    MENAGERIE17,
    REPO,
    RUNS,
    Experiment,
    FitTimer,
    RunSpec,
    experiment_specs,
    loo_specs,
    run_all,
    run_one,
)
from robovae.evaluate.experiment_tables import (  # noqa: F401  (the tables' public names)
    experiments_table,
    load_results,
    loo_table,
    loss_curve_png,
    per_robot_table,
    report,
)
from robovae.evaluate.pretrained import finetune_specs, zeroshot


def _seeds(s: str) -> list[int]:
    return [int(x) for x in s.split(",") if x.strip()]


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m robovae.evaluate.experiments {run,loo,zeroshot,finetune,ablation,report,all}``:
    exit code; a bad checkpoint, robot or variant is one line on stderr and exit code 2."""
    try:
        return _main(argv)
    except RobovaeError as e:
        print(e if str(e).startswith("robovae") else f"robovae: {e}", file=sys.stderr)
        return 2


def _main(argv: Sequence[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--all":
        argv[0] = "all"
    # Lightning CLI overrides after ``--`` (``run menagerie2 -- --model.latent_dim=64``)
    passthrough = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    p = argparse.ArgumentParser(prog="python -m robovae.evaluate.experiments",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--seeds", type=_seeds, default=[0, 1, 2])
    common.add_argument("--epochs", type=int, default=None, help="override max_epochs")
    common.add_argument("--threads", type=int, default=0, help="torch threads (0: default)")
    common.add_argument("--jobs", type=int, default=1, help="runs in parallel (processes)")
    common.add_argument("--redo", action="store_true", help="re-run runs that have a result")
    common.add_argument("--variant", default="default", help="ablation variant name")
    common.add_argument("--root", default=str(RUNS), help="where runs are stored")
    r = sub.add_parser("run", parents=[common], help="one experiment of SPEC §6")
    r.add_argument("experiment", choices=list(EXPERIMENTS))
    r.add_argument("overrides", nargs="*", help="extra Lightning CLI arguments (after --)")
    lo = sub.add_parser("loo", parents=[common], help="leave-one-out over the 17 robots")
    lo.add_argument("--robots", default=",".join(MENAGERIE17))
    lo.add_argument("overrides", nargs="*", help="extra Lightning CLI arguments (after --)")
    ab = sub.add_parser("ablation", parents=[common], help="the ablation variants")
    ab.add_argument("--only", default="", help="comma-separated variants")
    ab.add_argument("--loo", action="store_true", help="also the leave-one-out per variant")
    zs = sub.add_parser("zeroshot", help="a pretrained checkpoint on the 17 unseen robots")
    zs.add_argument("--ckpt", required=True)
    zs.add_argument("--name", required=True, help="label of the model (default, large, ...)")
    zs.add_argument("--menagerie", default=str(REPO.parent / "shared" / "menagerie"))
    zs.add_argument("--root", default=str(RUNS), help="where runs are stored")
    ft = sub.add_parser("finetune", parents=[common],
                        help="fine-tune a pretrained checkpoint on 16 robots, test the 17th")
    ft.add_argument("--ckpt", required=True)
    ft.add_argument("--name", required=True, help="label of the model (default, large, ...)")
    ft.add_argument("--robots", default=",".join(MENAGERIE17))
    ft.add_argument("overrides", nargs="*", help="extra Lightning CLI arguments (after --)")
    rp = sub.add_parser("report", help="write docs/results.md tables and docs/img loss curves")
    rp.add_argument("--root", default=str(RUNS), help="where runs are stored")
    al = sub.add_parser("all", parents=[common], help="every experiment, LOO, ablation, report")
    al.add_argument("--skip-ablation", action="store_true")
    args = p.parse_args(argv)
    variants = [args.variant] if hasattr(args, "variant") else []
    variants += [v for v in getattr(args, "only", "").split(",") if v]
    unknown = [v for v in variants if v not in ABLATIONS]
    if unknown:  # run as the default configs under another name, until 2026-11-29
        raise RobovaeError(f"robovae: unknown ablation variant {', '.join(unknown)} (known: "
                           f"{', '.join(ABLATIONS)})")
    robots = args.robots.split(",") if hasattr(args, "robots") else []
    strangers = [r for r in robots if r not in MENAGERIE17]
    if strangers:  # trained on all 17 and tested on none
        raise RobovaeError(f"robovae: --robots names {', '.join(repr(r) for r in strangers)}, "
                           f"not one of the 17 ({', '.join(MENAGERIE17)})")
    if passthrough:
        if not hasattr(args, "overrides"):
            p.error(f"{args.cmd} takes no Lightning CLI overrides")
        args.overrides = [*args.overrides, *passthrough]
    root = Path(args.root)
    if args.cmd == "report":
        report(root=root)
        return 0
    if args.cmd == "zeroshot":
        res = zeroshot(args.ckpt, args.name, args.menagerie, root)
        s = res["summary_z"]
        print(f"[zeroshot/{args.name}] from z: RA {s['ra']:.4f} RA_true {s['ra_true']:.4f} "
              f"exact {s['exact']:.3f} FRE {s['fre']:.3g}")
        return 0
    redo = not args.redo
    ex = {"epochs": args.epochs, "threads": args.threads, "root": root}
    if args.cmd == "run":
        extra = [*ABLATIONS.get(args.variant, ("", ()))[1], *args.overrides]
        run_all(experiment_specs(args.experiment, args.seeds, args.variant, extra, **ex),
                 args.jobs, redo)
    elif args.cmd == "loo":
        extra = [*ABLATIONS.get(args.variant, ("", ()))[1], *args.overrides]
        run_all(loo_specs(args.seeds, args.robots.split(","), args.variant, extra, **ex),
                 args.jobs, redo)
    elif args.cmd == "finetune":
        run_all(finetune_specs(args.ckpt, args.name, args.seeds, args.robots.split(","),
                               args.overrides, **ex), args.jobs, redo)
    elif args.cmd == "ablation":
        names = args.only.split(",") if args.only else list(ABLATIONS)
        specs = []
        for v in names:
            ov = list(ABLATIONS[v][1])
            for exp in ("menagerie2", "menagerie4"):
                specs += experiment_specs(exp, args.seeds, v, ov, **ex)
            if args.loo:
                specs += loo_specs(args.seeds, variant=v, extra=ov, **ex)
        run_all(specs, args.jobs, redo)
    elif args.cmd == "all":
        specs = []
        for name in EXPERIMENTS:
            specs += experiment_specs(name, args.seeds, **ex)
        specs += loo_specs(args.seeds, **ex)
        if not args.skip_ablation:  # every seed at 2 and 4 robots, the first for the LOO
            for v, (_, flags) in ABLATIONS.items():
                if v == "default":
                    continue
                for exp in ("menagerie2", "menagerie4"):
                    specs += experiment_specs(exp, args.seeds, v, list(flags), **ex)
                specs += loo_specs(args.seeds[:1], variant=v, extra=list(flags), **ex)
        run_all(specs, args.jobs, redo)
        report(root=root)
    return 0


if __name__ == "__main__":
    sys.exit(main())
