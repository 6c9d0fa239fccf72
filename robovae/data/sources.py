"""Data sources, as the strings a config or the CLI gives (SPEC §5).

================================ ===========================================================
source                           robots
================================ ===========================================================
``zoo``                          locomotion models inside ``dm_control`` and ``gymnasium``
``menagerie:go2,unitree_a1``     Menagerie robots through the ``mujoco-menagerie`` package
                                 (``MENAGERIE_ROOT`` points it at an offline checkout)
``dir:PATH``                     every ``.xml``/``.urdf`` below ``PATH`` (recursive)
``file:PATH`` or ``PATH``        one file (a bare folder path acts as ``dir:``)
``synthetic:n=20,nodes=15,dim=5``  the paper's random trees (``seed=``, ``unseen=1`` adds one
                                 tree not isomorphic to the others, named ``random_unseen``)
``procedural:n=1000,seed=0``     procedural robots built in memory, in parallel, when the dataset
                                 is built (``classes=quadruped+humanoid``; see
                                 :mod:`robovae.data.procedural`)
================================ ===========================================================
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from robovae.data.procedural.batch import ProceduralSource, parse_procedural
from robovae.data.robot_file import SUFFIXES
from robovae.errors import MAX_SEED, RobovaeError
from robovae.options import option_int, source_options

if TYPE_CHECKING:
    from robovae.data.graph import RobotData


@dataclass
class Resolved:
    """What a list of sources expands to: files to load and graphs made in memory."""

    files: list[tuple[str | None, Path]] = field(default_factory=list)  # (name or None, path)
    graphs: list[RobotData] = field(default_factory=list)
    procedural: list[ProceduralSource] = field(default_factory=list)  # built by the dataset
    warnings: list[str] = field(default_factory=list)
    feature_set: str | None = None  # forced by synthetic sources (random<d>)


#: The options of ``synthetic:`` and their ranges (default, lowest, highest).
SYNTHETIC_OPTIONS = {"n": (20, 1, 1_000_000), "nodes": (15, 1, 10_000), "dim": (5, 1, 1_000),
                     "seed": (0, 0, 2**31 - 1), "unseen": (0, 0, 1)}


def parse_synthetic(arg: str) -> dict[str, int]:
    """The options of ``synthetic:n=20,nodes=15,dim=5,seed=0,unseen=0``, each an integer in
    its range (:data:`SYNTHETIC_OPTIONS`), defaults filled in.

    Raises:
        RobovaeError: one line naming the bad option (not ``key=value``, unknown, not an
            integer, out of range).
    """
    where = "synthetic source"
    given = source_options(where, arg, tuple(SYNTHETIC_OPTIONS))
    return {k: option_int(where, k, given[k], lo, hi) if k in given else default
            for k, (default, lo, hi) in SYNTHETIC_OPTIONS.items()}


def find_robot_files(folder: Path) -> list[Path]:
    """Robot files below ``folder``, sorted, skipping hidden folders."""
    out = []
    for dirpath, dirnames, filenames in os.walk(folder):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        out += [Path(dirpath) / f for f in sorted(filenames) if f.lower().endswith(SUFFIXES)]
    return out


def menagerie_file(name: str) -> Path:
    """The robot file of Menagerie robot ``name`` (``unitree_go2``; ``go2`` also accepted).

    Uses the ``mujoco-menagerie`` package, which downloads on first use or reads
    ``MENAGERIE_ROOT``. When the default entry point is absent from an offline checkout, the
    first robot entry point present is used.
    """
    try:
        import mujoco_menagerie
    except ImportError:
        raise RobovaeError("robovae: menagerie sources need the mujoco-menagerie package "
                           "(pip install 'robovae[menagerie]')") from None
    names = mujoco_menagerie.names()
    if name not in names:
        matches = [n for n in names if n.endswith("_" + name)]
        if len(matches) != 1:
            raise RobovaeError(f"robovae: unknown Menagerie robot '{name}'")
        name = matches[0]
    robot = mujoco_menagerie.get(name)
    try:
        folder = robot.path()
    except Exception as e:  # MenagerieError, DownloadError, network errors
        raise RobovaeError(f"robovae: menagerie:{name}: {' '.join(str(e).split())}") from None
    candidates = [robot.entry(robot.default_model).file]
    candidates += [e.file for e in robot.entry_points if e.kind == "robot"]
    for file in candidates:
        if (folder / file).is_file():
            return folder / file
    raise RobovaeError(f"robovae: menagerie:{name}: no robot file in {folder}")


#: The kinds a source string names before its colon (module table).
KINDS = ("zoo", "menagerie", "dir", "file", "synthetic", "procedural")


def _split(src: str) -> tuple[str, str]:
    """A source string's kind and argument: ``procedural:n=10`` → ``("procedural", "n=10")``,
    ``zoo`` → ``("zoo", "")``, a bare path → ``("", path)``; a path with a colon that names no
    kind (``runs:v2/robots``, ``C:\\robots``) is a bare path when it exists (else the kind
    before the colon is refused as unknown)."""
    if src == "zoo":
        return "zoo", ""
    kind, _, arg = src.partition(":") if ":" in src else ("", "", src)
    if kind not in KINDS and Path(src).expanduser().exists():
        return "", src
    return kind, arg


def source_list(sources: str | Sequence[str]) -> list[str]:
    """``sources`` as a list: one string is one source (not one per character)."""
    return [sources] if isinstance(sources, str) else list(sources)


def check_sources(sources: str | Sequence[str], feature_set: str | None = None) -> None:
    """Refuse a bad source string before anything is built, downloaded or imported (this
    module imports neither torch nor PyG: ``robovae data`` calls it before them): an unknown
    kind, a ``synthetic:`` or ``procedural:`` option that is not one, a ``dir:`` that is not a
    folder, a ``dir:``, ``file:`` or bare path that is empty (it would read the working
    folder), a ``menagerie:`` that names no robot; and ``synthetic:`` sources beside robot
    sources or of different ``dim`` (random trees carry ``random<dim>`` features: a robot's
    features, or another ``dim``'s, cannot share their dataset); with ``feature_set``, robot
    sources read with ``random<d>`` (no robot has those features). One string is one source.
    Files are checked when they are read.

    Raises:
        RobovaeError: one line naming the source.
    """
    dims: dict[int, str] = {}  # the dim of each synthetic source -> its first source
    robots = []  # the other sources
    for src in source_list(sources):
        kind, arg = _split(src)
        if kind == "synthetic":
            dims.setdefault(parse_synthetic(arg)["dim"], src)
            continue
        robots.append(src)
        if kind in ("dir", "file", "") and not arg.strip():  # not the working folder
            raise RobovaeError(f"robovae: source '{src}' names no "
                               f"{'folder' if kind == 'dir' else 'file or folder'}")
        if kind == "procedural":
            parse_procedural(arg)
        elif kind == "dir" and not Path(arg).expanduser().is_dir():
            raise RobovaeError(f"robovae: {Path(arg).expanduser()}: no such folder")
        elif kind == "menagerie" and not any(n.strip() for n in arg.split(",")):
            raise RobovaeError(f"robovae: source '{src}' names no robot (menagerie:go2,unitree_a1)")
        elif kind not in ("zoo", "menagerie", "dir", "file", ""):
            raise RobovaeError(f"robovae: unknown source '{src}' (zoo, menagerie:, dir:, file:, "
                               "synthetic:, procedural:)")
    first = list(dims.values())
    if first and robots:
        raise RobovaeError(f"robovae: source '{first[0]}' makes random trees with random<dim> "
                           f"features: it cannot share a dataset with robots ('{robots[0]}')")
    if len(first) > 1:
        raise RobovaeError(f"robovae: sources '{first[0]}' and '{first[1]}' make random trees "
                           "of different dim: they cannot share a dataset")
    if robots and feature_set is not None and feature_set.startswith("random"):
        raise RobovaeError(f"robovae: feature set '{feature_set}' holds random trees' features, "
                           f"which no robot has ('{robots[0]}'): read robots with paper34, "
                           "kinematic or full")


def resolve_sources(sources: str | Sequence[str], feature_set: str | None = None) -> Resolved:
    """Expand source strings into files, in-memory graphs and procedural batches (module table),
    after :func:`check_sources` (``feature_set``: the one asked for, checked against them).

    Raises:
        RobovaeError: a bad source (:func:`check_sources`) or one that cannot be read (a
            Menagerie robot not found, a synthetic set that cannot hold an unseen tree).
    """
    sources = source_list(sources)
    check_sources(sources, feature_set)
    out = Resolved()
    for src in sources:
        kind, arg = _split(src)
        if kind == "zoo":
            from robovae.data.zoo import zoo_files

            files, warns = zoo_files()
            out.files += [(n, p) for n, p in files]
            out.warnings += warns
        elif kind == "menagerie":
            for name in filter(None, (n.strip() for n in arg.split(","))):
                out.files.append((None, menagerie_file(name)))
        elif kind == "dir" or (kind == "" and Path(arg).is_dir()):
            out.files += [(None, p) for p in find_robot_files(Path(arg).expanduser())]
        elif kind in ("file", ""):
            out.files.append((None, Path(arg).expanduser()))
        elif kind == "synthetic":
            from robovae.data.synthetic import random_trees, unseen_random_tree

            o = parse_synthetic(arg)
            nodes, dim, seed = o["nodes"], o["dim"], o["seed"]
            trees = random_trees(o["n"], nodes, dim, seed=seed)
            if o["unseen"]:
                try:
                    extra = unseen_random_tree(trees, nodes, dim,
                                               seed=(seed + 1) % (MAX_SEED + 1))
                except RuntimeError as e:  # small trees: every shape is among the n
                    raise RobovaeError(f"robovae: {src}: {e}") from None
                extra.name = "random_unseen"
                trees.append(extra)
            out.graphs += trees
            out.feature_set = f"random{dim}"
        else:  # procedural (check_sources refused every other kind)
            out.procedural.append(parse_procedural(arg))
    return out
