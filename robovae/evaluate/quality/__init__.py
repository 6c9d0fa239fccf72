"""Quality measures of robots: are they in one piece, paired, standing, moving, and how do they
compare with a training corpus and real robots (docs/generation.md, "Quality").

Every measure takes one robot (a file, a ``mujoco.MjSpec`` or a ``mujoco.MjModel`` with a
floor) and returns a small dataclass or a number:

- :func:`~robovae.evaluate.quality.standing.standing` → ``StandResult``;
- :func:`~robovae.evaluate.quality.locomotion.gait_speed` → float (and ``gait`` →
  ``GaitResult``).
"""

from robovae.evaluate.quality.locomotion import GaitResult, gait, gait_speed
from robovae.evaluate.quality.stage import Stage, stage
from robovae.evaluate.quality.standing import StandResult, standing

__all__ = ["GaitResult", "StandResult", "Stage", "gait", "gait_speed", "stage", "standing"]
