"""Many procedural robots at once: graphs for datasets (in parallel), or MJCF files.

Robot ``i`` of a batch ``(n, seed, mix)`` has seed ``seed + i`` and its class drawn from the
mix (:func:`~robovae.data.procedural.robots.draw_class`), so a batch is the same for the same
``n``, ``seed`` and mix, whatever the number of workers.

:func:`procedural_graphs` takes the fast path: each worker samples a plan, builds its
``MjSpec``, compiles it and reads the graph from the compiled ``MjModel``
(:func:`~robovae.data.mjcf.model_to_graph`), never writing or parsing XML. The graph equals
the one of the MJCF file :func:`write_procedural` writes up to the 6 significant digits MuJoCo
writes numbers with (``tests/data/test_procedural.py`` checks it).

Importing this module does not import torch (nor does :mod:`robovae.data.procedural`): a
batch's parsing, its files and its cache key need MuJoCo only, and the graphs' modules are
imported where graphs are made.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import as_completed
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from robovae.data.procedural.robots import (
    CLASSES,
    ProceduralConfig,
    check_classes,
    default_mix,
    draw_class,
    procedural_spec,
)
from robovae.data.workers import process_pool
from robovae.errors import RobovaeError
from robovae.files import atomic_write
from robovae.options import option_int, source_options
from robovae.settings import FEATURE_SET, check_settings, integer

if TYPE_CHECKING:
    from robovae.data.graph import RobotData

#: Most robots one ``procedural:`` source may ask for.
MAX_ROBOTS = 10_000_000


@cache
def generator_digest() -> str:
    """A digest of the generator's code and ranges (the ``.py`` files and ``ranges.yaml`` of
    this package): a batch is a function of its ``n``, ``seed`` and mix *and* of them."""
    h = hashlib.sha1()
    folder = Path(__file__).parent
    for path in sorted([*folder.glob("*.py"), folder / "ranges.yaml"]):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:12]


@dataclass(frozen=True)
class ProceduralSource:
    """A parsed ``procedural:`` source: ``n`` robots from ``seed`` with class ``mix``."""

    n: int
    seed: int
    mix: dict[str, float]

    def key(self) -> str:
        """A string naming the batch for cache keys, with the :func:`generator_digest`, so a
        dataset cache built by another version of the generator is not reused."""
        mix = "+".join(f"{c}{w:.4g}" for c, w in sorted(self.mix.items()))
        return f"procedural_n{self.n}_s{self.seed}_{mix}_g{generator_digest()}"


def _int(name: str, text: str, lo: int, hi: int) -> int:
    return option_int("procedural source", name, text, lo, hi)


def parse_procedural(arg: str) -> ProceduralSource:
    """Parse the options of ``procedural:n=1000,seed=0,classes=quadruped+humanoid``.

    ``classes`` lists classes with equal weights, or ``class*weight`` terms
    (``quadruped*3+arm``); the default is :func:`~robovae.data.procedural.default_mix`.

    Raises:
        RobovaeError: one line naming the bad option (not ``key=value``, unknown key, ``n``
            or ``seed`` not an integer or negative, an unknown class, a bad weight).
    """
    opts = source_options("procedural source", arg, ("n", "seed", "classes"))
    n = _int("n", opts.get("n", "100"), 1, MAX_ROBOTS)
    seed = _int("seed", opts.get("seed", "0"), 0, 2**31 - 1)
    mix: dict[str, float] = default_mix()
    if "classes" in opts:
        mix = {}
        for term in filter(None, opts["classes"].split("+")):
            name, _, w = term.partition("*")
            try:
                weight = float(w) if w else 1.0
            except ValueError:
                raise RobovaeError(f"robovae: procedural source: weight '{w}' of class "
                                   f"'{name}' is not a number") from None
            mix[name.strip()] = mix.get(name.strip(), 0.0) + weight
        try:
            mix = check_classes(mix)
        except ValueError as e:
            raise RobovaeError(f"robovae: procedural source: {e}") from None
    return ProceduralSource(n, seed, mix)


def _jobs(source: ProceduralSource) -> list[tuple[int, str]]:
    return [(source.seed + i, draw_class(source.seed + i, source.mix)) for i in range(source.n)]


def _graph_batch(jobs: list[tuple[int, str]], feature_set: str) -> list[dict]:
    """Worker: robots → graph fields as numpy arrays (tensors would travel as shared-memory
    file descriptors, which run out on large builds). Torch runs single-threaded meanwhile
    (the thread count is restored after): on graphs of about 100 nodes and more its intra-op
    thread pool wakes for each tiny tensor operation, which costs milliseconds per graph when
    the cores are busy, as they are with one worker per core."""
    import torch

    from robovae.data.mjcf import model_to_graph

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        out = []
        for seed, kind in jobs:
            spec = procedural_spec(seed, kind)
            data = model_to_graph(spec.compile(), feature_set, spec.modelname,
                                  f"procedural:{kind}:{seed}")
            out.append({k: v.numpy() if isinstance(v, torch.Tensor) else v
                        for k, v in data.to_dict().items()})
        return out
    finally:
        torch.set_num_threads(threads)


def _run(fn: Callable[..., list], jobs: list, args: tuple, workers: int, progress: bool,
         desc: str) -> list:
    """``fn(chunk, *args)`` over chunks of ``jobs`` in ``workers`` processes, results in order."""
    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs), desc=desc, unit="robot", disable=not progress)
    if workers <= 1 or len(jobs) < 64:
        out = []
        for i in range(0, len(jobs), 256):
            out += fn(jobs[i:i + 256], *args)
            bar.update(len(jobs[i:i + 256]))
        bar.close()
        return out
    chunk = max(16, min(500, math.ceil(len(jobs) / (8 * workers))))
    chunks = [jobs[i:i + chunk] for i in range(0, len(jobs), chunk)]
    results: list = [None] * len(chunks)
    with process_pool(workers) as pool:
        futures = {pool.submit(fn, c, *args): k for k, c in enumerate(chunks)}
        for f in as_completed(futures):
            results[futures[f]] = f.result()
            bar.update(len(chunks[futures[f]]))
    bar.close()
    return [r for part in results for r in part]


def procedural_graphs(source: ProceduralSource, feature_set: str = "paper34", jobs: int = 0,
                      progress: bool = False) -> list[RobotData]:
    """The graphs of a procedural batch, built in ``jobs`` processes (0: all cores).

    Raises:
        SettingsError: ``jobs`` negative, an unknown ``feature_set``.
    """
    check_settings("procedural_graphs", jobs=(jobs, integer(0)),
                   feature_set=(feature_set, FEATURE_SET))
    import torch

    from robovae.data.graph import RobotData

    workers = jobs or (os.cpu_count() or 1)
    fields = _run(_graph_batch, _jobs(source), (feature_set,), workers, progress, "robots")
    return [RobotData(**{k: torch.from_numpy(v) if hasattr(v, "dtype") else v
                         for k, v in f.items()}) for f in fields]


def _write_batch(jobs: list[tuple[int, str, str]], config: ProceduralConfig) -> list[None]:
    for seed, kind, path in jobs:
        atomic_write(path, procedural_spec(seed, kind, config).to_xml(), durable=False)
    return [None] * len(jobs)


def write_procedural(out_dir: str | os.PathLike, n: int, seed: int = 0,
                     classes: Sequence[str] | Mapping[str, float] | None = None,
                     config: ProceduralConfig | None = None, workers: int | None = None
                     ) -> list[Path]:
    """Write ``n`` robots as MJCF files ``<out_dir>/proc_<class>_<seed>.xml``, in robot order.

    Robot ``i`` is robot ``seed + i`` of the batch (module docstring); ``classes`` (a list or
    ``{class: weight}``) defaults to ``config.mix``. Existing files are left untouched (an
    interrupted run resumes); new ones are written to a temporary file and moved into place.
    ``workers``: processes (``None``: every CPU from 500 files to write, else in-process).

    Raises:
        ValueError: an unknown class, ``n`` or ``seed`` not an integer ``>= 0``, ``workers``
            (when given) not an integer ``>= 1``.
    """
    cfg = config or ProceduralConfig()
    check_settings("write_procedural", n=(n, integer(0)), seed=(seed, integer(0)),
                   workers=(workers, integer(1).or_none()))
    mix = check_classes(classes) if classes is not None else dict(cfg.mix)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths, todo = [], []
    for s in range(seed, seed + n):
        kind = draw_class(s, mix)
        path = out / f"proc_{kind}_{s:05d}.xml"
        paths.append(path)
        if not path.exists():
            todo.append((s, kind, str(path)))
    if workers is None:
        workers = (os.cpu_count() or 1) if len(todo) >= 500 else 1
    _run(_write_batch, todo, (cfg,), workers, False, "files")
    return paths


__all__ = ["CLASSES", "MAX_ROBOTS", "ProceduralSource", "parse_procedural", "procedural_graphs",
           "write_procedural"]
