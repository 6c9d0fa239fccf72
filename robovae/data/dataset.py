"""``RobotDataset``: robot graphs from any mix of sources, cached on disk (PyG ``InMemoryDataset``).

The processed cache lives in ``<root>/processed/robots_<key>.pt`` where ``key`` hashes the
source strings, the feature set, the package version and the size/mtime of every source
file, so the cache is rebuilt whenever any of them changes. A build report (one row per robot,
plus skipped files and duplicates) is saved beside it as JSON.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import os
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path
from typing import IO, cast

import torch
from torch_geometric.data import Data, InMemoryDataset
from torch_geometric.data.dataset import files_exist

import robovae
from robovae.data.features import GEOM, JOINT, LINK, get_feature_set
from robovae.data.graph import RobotData, limbs
from robovae.data.mjcf import mjcf_to_graph
from robovae.data.procedural.batch import procedural_graphs
from robovae.data.sources import resolve_sources, source_list
from robovae.data.workers import process_pool
from robovae.errors import RobotFileError, RobovaeError
from robovae.files import FolderLock, atomic_json, writable
from robovae.settings import check_settings, integer

log = logging.getLogger("robovae")

#: Below this many files, loading runs in-process (worker start-up costs more than it saves).
PARALLEL_MIN_FILES = 64


def _load_one(item: tuple[str | None, str, str]) -> tuple[dict | None, str | None]:
    """Worker: one file → the graph's fields as numpy arrays (tensors would travel between
    processes as shared-memory file descriptors, which run out on large builds)."""
    name, path, feature_set = item
    try:
        data = mjcf_to_graph(path, feature_set, name=name)
        return {k: v.numpy() if isinstance(v, torch.Tensor) else v
                for k, v in data.to_dict().items()}, None
    except RobotFileError as e:
        return None, e.line()
    except Exception as e:  # never a traceback for bad input: report and go on
        return None, RobotFileError(path, f"cannot load: {type(e).__name__}: {e}").line()


def _from_fields(fields: dict) -> RobotData:
    return RobotData(**{k: torch.from_numpy(v) if hasattr(v, "dtype") else v
                        for k, v in fields.items()})


def graph_key(data: RobotData, decimals: int = 6) -> str:
    """Hash of topology, node types and rounded features: equal keys = duplicate robots."""
    h = hashlib.sha1()
    h.update(data.parent.numpy().tobytes())
    h.update(data.node_type.numpy().tobytes())
    h.update(torch.round(data.x.double(), decimals=decimals).numpy().tobytes())
    return h.hexdigest()


def summary_row(data: RobotData) -> dict:
    """One report row: name, node counts per type, depth, limbs, features, warnings."""
    counts = torch.bincount(data.node_type, minlength=3).tolist()
    return {"name": data.name, "source": data.source, "nodes": int(data.num_nodes),
            "links": counts[LINK], "joints": counts[JOINT], "geoms": counts[GEOM],
            "depth": int(data.depth.max()), "limbs": limbs(data),
            "features": int(data.x.shape[1]), "warnings": getattr(data, "warnings", "")}


#: The modules that turn a robot file into a graph: their code is part of every cache key.
_READER_MODULES = ("actuators.py", "box_axes.py", "features.py", "graph.py", "loading.py",
                   "mjcf.py", "robot_file.py")


@cache
def reader_digest() -> str:
    """A digest of the code that reads robot files into graphs (:data:`_READER_MODULES`): a
    cached dataset is a function of its sources *and* of how features are read (a changed or
    added feature column must not reuse a cache built before it)."""
    h = hashlib.sha1()
    for name in _READER_MODULES:
        h.update(name.encode() + b"\0" + (Path(__file__).parent / name).read_bytes())
    return h.hexdigest()[:12]


class _Sink:
    """A binary file for ``torch.save`` that keeps the ``OSError`` of its last failed write:
    ``torch.save`` replaces it with a ``RuntimeError`` that does not say the disk is full."""

    def __init__(self, f: io.BufferedWriter) -> None:
        self.f = f
        self.error: OSError | None = None

    def write(self, data: bytes) -> int:
        try:
            return self.f.write(data)
        except OSError as e:
            self.error = e
            raise

    def flush(self) -> None:
        self.f.flush()


class RobotDataset(InMemoryDataset):
    """Robot graphs from MJCF/URDF files, Menagerie, the zoo or synthetic generators.

    Args:
        root: cache folder (processed graphs and their build report).
        sources: source strings (see :mod:`robovae.data.sources`), default ``["zoo"]``; one
            string is one source.
        feature_set: registry name (``paper34``, ``full``); synthetic sources force
            ``random<d>``.
        jobs: worker processes for loading many files (``0``: all cores; an integer >= 0).
        progress: show a progress bar while building.
        force_reload: rebuild even when a matching cache exists.
        transform: PyG transform applied on access.

    Attributes:
        report: ``{"robots": [...rows], "skipped": [one-line errors], "duplicates": [...],
        "warnings": [...]}`` of the build that made the cache.
    """

    def __init__(
        self,
        root: str | Path = "data_cache",
        sources: Sequence[str] = ("zoo",),
        feature_set: str = "paper34",
        jobs: int = 0,
        progress: bool = True,
        force_reload: bool = False,
        transform: Callable | None = None,
    ) -> None:
        check_settings("RobotDataset", jobs=(jobs, integer(0)))
        self.sources = source_list(sources)
        self.jobs = jobs or (os.cpu_count() or 1)
        self.progress = progress
        root = Path(root)
        self._resolved = resolve_sources(self.sources, feature_set)
        self.feature_set = self._resolved.feature_set or feature_set
        get_feature_set(self.feature_set)  # fail early on unknown names
        self._key = self._fingerprint()
        made = [d for d in (root / "processed", root / "raw", root) if not d.exists()]
        try:
            if not root.is_dir():  # to be made: one line if it cannot (an existing cache may
                writable(root, "the dataset cache")  # be read-only: not tried)
            super().__init__(str(root), transform=transform, force_reload=force_reload,
                             log=False)
        except BaseException:  # a failed build leaves no empty cache folders behind
            for d in made:
                with contextlib.suppress(OSError):  # not empty (another build's): kept
                    d.rmdir()
            raise
        self.load(self.processed_paths[0], data_cls=RobotData)
        self.report = json.loads(Path(self.processed_paths[1]).read_text())

    # --- cache identity ------------------------------------------------------------------

    def _fingerprint(self) -> str:
        h = hashlib.sha1()
        h.update(json.dumps([self.sources, self.feature_set, robovae.__version__,
                             reader_digest()]).encode())
        for name, path in self._resolved.files:
            try:
                st = path.stat()
                h.update(f"{name}|{path}|{st.st_size}|{st.st_mtime_ns}".encode())
            except OSError:
                h.update(f"{name}|{path}|missing".encode())
        for g in self._resolved.graphs:
            h.update(graph_key(g).encode())
        for src in self._resolved.procedural:  # generated from the key alone: deterministic
            h.update(src.key().encode())
        return h.hexdigest()[:16]

    @property
    def raw_file_names(self) -> list[str]:
        return []

    @property
    def processed_file_names(self) -> list[str]:
        return [f"robots_{self._key}.pt", f"robots_{self._key}.json"]

    def _process(self) -> None:
        """PyG's build step, once across processes: a process that finds another building a
        cache in this root waits for it (:class:`~robovae.files.FolderLock` with ``wait``),
        then reads the cache that one made (PyG looks again) instead of building it a second
        time beside it (parallel training runs given one ``root``). A cache that exists is read
        without the lock (it may be read-only)."""
        if not self.force_reload and files_exist(self.processed_paths):
            return super()._process()
        with FolderLock(self.processed_dir, "the dataset cache", wait=True):
            return super()._process()

    def download(self) -> None:  # sources are resolved in __init__
        """Nothing to download: sources are local files, packages or generators."""
        pass

    @classmethod
    def save(cls, data_list: Sequence[RobotData], path: str) -> None:
        """Collate ``data_list`` and write the cache atomically: to a temporary file beside
        ``path``, then ``os.replace``. A process that has the old file memory-mapped
        (:meth:`load`) keeps reading the old file's pages, never a half-written one (rewriting
        it in place, as ``force_reload`` would, could end such a process with SIGBUS).

        Raises:
            OSError: naming ``path``, when the file cannot be written (a full disk: ``torch.save``
                itself reports that as a ``RuntimeError`` of its zip writer).
        """
        data, slices = cls.collate(data_list)
        tmp = f"{path}.{os.getpid()}.tmp"
        try:
            with open(tmp, "wb") as f:
                sink = _Sink(f)
                try:
                    torch.save((data.to_dict(), slices, data.__class__), cast(IO[bytes], sink))
                except RuntimeError:
                    if sink.error is None:
                        raise
                    raise sink.error from None
            os.replace(tmp, path)
        except OSError as e:
            raise OSError(e.errno, e.strerror, path) from None
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)

    def load(self, path: str, data_cls: type[Data] = RobotData) -> None:
        """Load the processed cache memory-mapped (``torch.load(mmap=True)``): the collated
        tensors stay in the page cache, read on demand and shared by every process that maps
        the file (the DDP training processes hold one copy of the dataset between them)."""
        data, self.slices, data_cls = torch.load(path, mmap=True, weights_only=False)
        self.data = data_cls.from_dict(data) if isinstance(data, dict) else data

    # --- build -----------------------------------------------------------------------------

    def _load_files(self) -> tuple[list[RobotData], list[str]]:
        items = [(n, str(p), self.feature_set) for n, p in self._resolved.files]
        if not items:
            return [], []
        from tqdm.auto import tqdm

        bar = tqdm(total=len(items), desc="robots", unit="file", disable=not self.progress)
        results: list[tuple[dict | None, str | None]] = []
        if self.jobs > 1 and len(items) >= PARALLEL_MIN_FILES:
            chunk = max(1, min(64, len(items) // (self.jobs * 8)))
            with process_pool(self.jobs) as pool:
                for r in pool.map(_load_one, items, chunksize=chunk):
                    results.append(r)
                    bar.update()
        else:
            for item in items:
                results.append(_load_one(item))
                bar.update()
        bar.close()
        return [_from_fields(d) for d, _ in results if d is not None], [e for _, e in results if e]

    def process(self) -> None:
        """Parse every source into robot graphs; a bad file gives a one-line error and is
        skipped."""
        graphs, skipped = self._load_files()
        graphs += self._resolved.graphs
        for src in self._resolved.procedural:
            graphs += procedural_graphs(src, self.feature_set, self.jobs, self.progress)
        kept, duplicates, names = [], [], set()
        seen: dict[str, str] = {}  # graph_key -> name of the robot kept
        for g in graphs:
            key = graph_key(g)
            if key in seen:
                duplicates.append(f"{g.name} ({g.source}) duplicates {seen[key]}: skipped")
                continue
            base, k = g.name or Path(g.source).stem, 2
            g.name = base
            while g.name in names:
                g.name, k = f"{base}_{k}", k + 1
            names.add(g.name)
            seen[key] = g.name
            kept.append(g)
        if not kept:  # one line: the first failed file's error (each file's is in skipped)
            more = f" ({len(skipped)} files failed, the first shown)" if len(skipped) > 1 else ""
            raise RobovaeError((f"{skipped[0]}; " if skipped else "robovae: ")
                               + f"no robot loaded from sources {self.sources}{more}")
        report = {"robots": [summary_row(g) for g in kept], "skipped": skipped,
                  "duplicates": duplicates, "warnings": self._resolved.warnings,
                  "sources": self.sources, "feature_set": self.feature_set}
        self.save(kept, self.processed_paths[0])
        atomic_json(self.processed_paths[1], report)

    # --- access ----------------------------------------------------------------------------

    @property
    def names(self) -> list[str]:
        """Robot names in dataset order."""
        return [r["name"] for r in self.report["robots"]]

    def node_rows(self, indices: Sequence[int]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The collated node features ``x`` and ``node_type`` of the whole dataset, and a bool
        mask of the rows that belong to the robots ``indices`` (positions in this dataset).

        Statistics over many robots (the normaliser of a training split) read the collated
        storage through this mask instead of separating one ``Data`` object per robot.
        """
        store, ptr = self._data, self.slices["x"]
        graph_ids = torch.arange(len(ptr) - 1)
        if self._indices is not None:  # a subset view: positions → stored graphs
            graph_ids = torch.as_tensor(self.indices())
        keep = torch.zeros(len(ptr) - 1, dtype=torch.bool)
        keep[graph_ids[torch.as_tensor(list(indices), dtype=torch.long)]] = True
        rows = torch.repeat_interleave(keep, ptr.diff())
        return store.x, store.node_type, rows

    def by_name(self, name: str) -> RobotData:
        """The robot called ``name``."""
        try:
            return self[self.names.index(name)]
        except ValueError:
            raise KeyError(f"no robot named {name!r} (have: {', '.join(self.names)})") from None
