"""Robot files of the reference populations the quality table compares samples with.

- :func:`real_robot_files`: the MJCF files of a Menagerie-like folder (``<robot>/<name>.xml``,
  ``scene*.xml`` left out); default folder ``$ROBOVAE_MENAGERIE``, else ``../shared/menagerie``
  from the working directory;
- :func:`procedural_files`: ``n`` robots of the procedural generator
  (:func:`robovae.data.procedural.write_procedural`, seeds ``seed … seed+n-1``, every kind in
  turn), written once into a cache folder and reused.
"""

from __future__ import annotations

import os
from pathlib import Path

from robovae.data.procedural import write_procedural

__all__ = ["procedural_files", "real_robot_files"]


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
