"""Robot files of the reference populations the quality table compares samples with.

- :func:`real_robot_files`: the MJCF files of a Menagerie-like folder (``<robot>/<name>.xml``,
  ``scene*.xml`` left out); default folder ``$ROBOVAE_MENAGERIE``, else ``../shared/menagerie``
  from the working directory;
- :func:`procedural_files`: ``n`` robots of the procedural generator
  (:func:`robovae.data.procedural.write_procedural`, seeds ``seed … seed+n-1``, every kind in
  turn), written once into a cache folder and reused; the quality table draws them from
  :data:`HOLDOUT_SEED` on, seeds no config trains on (``default``: 0–9,999, ``large``:
  0–99,999), so that the column is the generator, not the training set;
- :func:`corpus_files`: files of ``n`` training robots spread over the corpus (every
  ``len/n``-th); a procedural training robot (source ``procedural:<class>:<seed>``) is written
  from its seed, a file robot is its own file;
- :func:`written_files`: the graphs of procedural robots and of the zoo written the way
  ``robovae generate`` writes a decoded robot (floating base, mirrored limbs, the writer's
  rules and floor placement): what a model that reproduced its training robots would give.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path

from robovae.data.procedural import parse_procedural, procedural_graphs, write_procedural
from robovae.files import atomic_write

__all__ = ["HOLDOUT_SEED", "corpus_files", "procedural_files", "real_robot_files", "source_file",
           "written_files"]

#: First procedural seed of the quality table's generator column (beyond every config's
#: training robots).
HOLDOUT_SEED = 1_000_000


def real_robot_files(folder: str | os.PathLike | None = None) -> list[Path]:
    """Robot files of a Menagerie-like folder, sorted; ``[]`` when the folder is absent."""
    folder = Path(folder or os.environ.get("ROBOVAE_MENAGERIE", "../shared/menagerie"))
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.glob("*/*.xml") if not p.name.startswith("scene"))


def procedural_files(n: int, root: str | os.PathLike = "data_cache", seed: int = 0
                     ) -> list[Path]:
    """``n`` procedural robot files in ``root/raw/quality_procedural_s<seed>`` (written on
    first use, reused after)."""
    if n <= 0:
        return []
    return write_procedural(Path(root) / "raw" / f"quality_procedural_s{seed}", n, seed=seed)


def source_file(source: str, root: str | os.PathLike = "data_cache") -> str:
    """The robot file of a training graph's ``source``: a file path as it is, and for
    ``procedural:<class>:<seed>`` the robot written once into ``root/raw/quality_corpus``
    from its seed (reused after)."""
    from robovae.data.procedural.robots import procedural_spec

    if not source.startswith("procedural:"):
        return source
    _, kind, seed = source.split(":")
    path = Path(root) / "raw" / "quality_corpus" / f"proc_{kind}_{int(seed):06d}.xml"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, procedural_spec(int(seed), kind).to_xml())  # reused after: whole
    return str(path)


def corpus_files(sources: Sequence[str | None], names: Sequence[str], n: int,
                 root: str | os.PathLike = "data_cache") -> tuple[list[str], list[str]]:
    """Files and names of ``n`` training robots, every ``len/n``-th of ``sources`` (the graphs'
    ``source``: a file path or ``procedural:<class>:<seed>``, :func:`source_file`; robots
    without one are skipped)."""
    known = [(s, m) for s, m in zip(sources, names) if s]
    if n <= 0 or not known:
        return [], []
    step = max(1, len(known) // n)
    picked = known[::step][:n]
    return [source_file(src, root) for src, _ in picked], [m for _, m in picked]


def written_files(n: int, root: str | os.PathLike = "data_cache", seed: int = 0,
                  zoo: bool = True) -> list[Path]:
    """The ``paper34`` graphs of ``n`` procedural robots (seeds ``seed …``,
    :func:`~robovae.data.procedural.procedural_graphs`) and, with ``zoo``, of the installed zoo
    robots, each given ``robovae generate``'s fixes of a decoded graph
    (:func:`~robovae.generate.fixes.decoded_fixes`: a floating base, near-mirror limbs
    mirrored, near-equal limbs on the plane made equal, slides limited) and written by
    :func:`~robovae.generate.writer.write_robot`, as ``robovae generate`` does: procedural robot
    ``i`` in ``procedural/robot_<i>/robot.xml``, a zoo robot in ``zoo/<name>/robot.xml``, both
    under ``root/raw/quality_written_<writer>_s<seed>`` (``<writer>``: a digest of
    :data:`~robovae.generate.writer.WRITER`). Written on first use and reused after: a file is
    the same robot whatever ``n`` asked for it, and files of another writer are not reused."""
    from robovae.data.loading import load_robot
    from robovae.data.mjcf import model_to_graph
    from robovae.data.zoo import zoo_files
    from robovae.generate.fixes import decoded_fixes
    from robovae.generate.writer import WRITER, write_robot

    writer = hashlib.sha256(WRITER.encode()).hexdigest()[:12]
    out = Path(root) / "raw" / f"quality_written_{writer}_s{seed}"
    robots = [(out / "procedural" / f"robot_{i:06d}", g) for i, g in
              enumerate(procedural_graphs(parse_procedural(f"n={n},seed={seed}"), jobs=1)
                        if n > 0 else [])]
    if zoo:
        robots += [(out / "zoo" / name, model_to_graph(load_robot(f).model, "paper34"))
                   for name, f in zoo_files()[0]]
    for folder, g in robots:
        if not (folder / "robot.xml").is_file():
            tree, _ = decoded_fixes(g, "paper34")
            write_robot(tree, folder, "paper34", name=f"written_{folder.name}", scene=False,
                        check=False, durable=False)
    return [folder / "robot.xml" for folder, _ in robots]
