"""Robot files of the reference populations the quality table compares samples with.

- :func:`real_robot_files`: the MJCF files of a Menagerie-like folder (``<robot>/<name>.xml``,
  ``scene*.xml`` left out); default folder ``$ROBOVAE_MENAGERIE``, else ``../shared/menagerie``
  from the working directory;
- :func:`procedural_files`: ``n`` robots of the procedural generator
  (:func:`robovae.data.procedural.write_procedural`, seeds ``seed … seed+n-1``, every kind in
  turn), written once into a cache folder and reused;
- :func:`written_files`: the graphs of procedural robots and of the zoo written the way
  ``robovae generate`` writes a decoded robot (floating base, mirrored limbs, the writer's
  rules and floor placement): what a model that reproduced its training robots would give.
"""

from __future__ import annotations

import os
from pathlib import Path

from robovae.data.procedural import parse_procedural, procedural_graphs, write_procedural

__all__ = ["procedural_files", "real_robot_files", "written_files"]


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


def written_files(n: int, root: str | os.PathLike = "data_cache", seed: int = 0,
                  zoo: bool = True) -> list[Path]:
    """``root/raw/quality_written_s<seed>/robot_<i>/robot.xml``: the ``paper34`` graphs of
    ``n`` procedural robots (seeds ``seed …``, :func:`~robovae.data.procedural.procedural_graphs`)
    and, with ``zoo``, of the installed zoo robots, each given a floating base
    (:func:`~robovae.generate.rules.floating_base`), its near-mirror limbs mirrored
    (:func:`~robovae.generate.symmetry.mirror_limbs`) and written by
    :func:`~robovae.generate.writer.write_robot`, as ``robovae generate`` does (written on first
    use, reused after)."""
    from robovae.data.loading import load_robot
    from robovae.data.mjcf import model_to_graph
    from robovae.data.zoo import zoo_files
    from robovae.generate.rules import floating_base
    from robovae.generate.symmetry import mirror_limbs
    from robovae.generate.writer import write_robot

    out = Path(root) / "raw" / f"quality_written_s{seed}"
    graphs = procedural_graphs(parse_procedural(f"n={n},seed={seed}"), jobs=1) if n > 0 else []
    if zoo:
        graphs += [model_to_graph(load_robot(f).model, "paper34") for _, f in zoo_files()[0]]
    paths = []
    for i, g in enumerate(graphs):
        folder = out / f"robot_{i:06d}"
        if not (folder / "robot.xml").is_file():
            g = mirror_limbs(floating_base(g, "paper34")[0], "paper34")[0]
            write_robot(g, folder, "paper34", name=f"written_{i:06d}", scene=False, check=False,
                        durable=False)
        paths.append(folder / "robot.xml")
    return paths
