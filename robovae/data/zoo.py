"""The zoo: locomotion models shipped inside the ``dm_control`` and ``gymnasium`` packages.

They install from PyPI and need no network, which makes them the embedded default dataset.
Each entry is ``(name, package, path inside the package, category)``; entries whose package
is not installed are skipped with a warning. The list is documented in ``docs/data.md``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import NamedTuple


class ZooEntry(NamedTuple):
    name: str
    package: str
    path: str
    category: str


ZOO: tuple[ZooEntry, ...] = (
    ZooEntry("dmc_cheetah", "dm_control", "suite/cheetah.xml", "planar"),
    ZooEntry("dmc_dog", "dm_control", "suite/dog.xml", "quadruped"),
    ZooEntry("dmc_fish", "dm_control", "suite/fish.xml", "swimmer"),
    ZooEntry("dmc_hopper", "dm_control", "suite/hopper.xml", "planar"),
    ZooEntry("dmc_humanoid", "dm_control", "suite/humanoid.xml", "humanoid"),
    ZooEntry("dmc_humanoid_CMU", "dm_control", "suite/humanoid_CMU.xml", "humanoid"),
    ZooEntry("dmc_quadruped", "dm_control", "suite/quadruped.xml", "quadruped"),
    ZooEntry("dmc_swimmer", "dm_control", "suite/swimmer.xml", "swimmer"),
    ZooEntry("dmc_walker", "dm_control", "suite/walker.xml", "planar"),
    ZooEntry("dmc_humanoid_CMU_V2019", "dm_control",
             "locomotion/walkers/assets/humanoid_CMU_V2019.xml", "humanoid"),
    ZooEntry("dmc_humanoid_CMU_V2020", "dm_control",
             "locomotion/walkers/assets/humanoid_CMU_V2020.xml", "humanoid"),
    ZooEntry("dmc_rodent", "dm_control", "locomotion/walkers/assets/rodent.xml", "quadruped"),
    ZooEntry("dmc_dog_v2", "dm_control", "locomotion/walkers/assets/dog_v2/dog.xml",
             "quadruped"),
    ZooEntry("dmc_fruitfly", "dm_control",
             "locomotion/walkers/assets/fruitfly_v2/fruitfly.xml", "hexapod"),
    ZooEntry("dmc_jumping_ball", "dm_control",
             "locomotion/walkers/assets/jumping_ball/jumping_ball_with_head.xml", "other"),
    ZooEntry("dmc_boxhead", "dm_control", "locomotion/soccer/assets/boxhead/boxhead.xml",
             "other"),
    ZooEntry("gym_ant", "gymnasium", "envs/mujoco/assets/ant.xml", "quadruped"),
    ZooEntry("gym_half_cheetah", "gymnasium", "envs/mujoco/assets/half_cheetah.xml", "planar"),
    ZooEntry("gym_hopper", "gymnasium", "envs/mujoco/assets/hopper.xml", "planar"),
    ZooEntry("gym_humanoid", "gymnasium", "envs/mujoco/assets/humanoid.xml", "humanoid"),
    ZooEntry("gym_humanoidstandup", "gymnasium", "envs/mujoco/assets/humanoidstandup.xml",
             "humanoid"),
    ZooEntry("gym_swimmer", "gymnasium", "envs/mujoco/assets/swimmer.xml", "swimmer"),
    ZooEntry("gym_walker2d", "gymnasium", "envs/mujoco/assets/walker2d.xml", "planar"),
    ZooEntry("gym_walker2d_v5", "gymnasium", "envs/mujoco/assets/walker2d_v5.xml", "planar"),
)


def zoo_files() -> tuple[list[tuple[str, Path]], list[str]]:
    """``[(name, file)]`` of the installed zoo models, and warnings for missing packages."""
    found, warnings = [], []
    roots: dict[str, Path | None] = {}
    for entry in ZOO:
        if entry.package not in roots:
            spec = importlib.util.find_spec(entry.package)
            roots[entry.package] = (Path(next(iter(spec.submodule_search_locations)))
                                    if spec and spec.submodule_search_locations else None)
            if roots[entry.package] is None:
                warnings.append(f"package {entry.package} not installed: its zoo models skipped "
                                f"(pip install 'robovae[zoo]')")
        root = roots[entry.package]
        if root is not None:
            found.append((entry.name, root / entry.path))
    return found, warnings


def zoo_category(name: str) -> str:
    """Category of a zoo robot (``quadruped``, ``humanoid``, ...), ``unknown`` otherwise."""
    return next((e.category for e in ZOO if e.name == name), "unknown")
