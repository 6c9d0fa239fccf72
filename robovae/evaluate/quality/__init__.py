"""Quality measures of robots: are they in one piece, paired, standing, moving, and how do they
compare with a training corpus and real robots (docs/generation.md, "Quality").

Every per-robot measure takes one robot (a file, a ``mujoco.MjSpec``, a ``mujoco.MjModel`` or
a :class:`~robovae.evaluate.quality.stage.Stage`; the physical ones need a model with a floor,
files and specs get one) and returns a small dataclass or a number; none changes the caller's
model. A :class:`~robovae.evaluate.quality.stage.Stage` is the robot compiled once for all of
them (``robovae generate`` stages the model its validator compiled:
:func:`~robovae.evaluate.quality.stage.stage_compiled`):

- :func:`~robovae.evaluate.quality.standing.standing` → ``StandResult`` (``.stands``);
- :func:`~robovae.evaluate.quality.locomotion.gait_speed` → float, extents/s
  (:func:`~robovae.evaluate.quality.locomotion.gait` → ``GaitResult``; the same gaits tuned
  to the body by CMA-ES: :func:`~robovae.evaluate.quality.gait_search.searched_gait`; either
  at a fixed budget of rollouts: :func:`~robovae.evaluate.quality.gait_search.budget_gait`);
- :func:`~robovae.evaluate.quality.attachment.attachment` → ``AttachResult``
  (``.all_attached``, ``.detached_share``, ``.penetration``);
- :func:`~robovae.evaluate.quality.symmetry.anatomy` → ``Anatomy`` (``.symmetric``,
  ``.one_limb``, counts);
- :func:`~robovae.evaluate.quality.measure.measure` → every measure as one dict.

Population measures: :mod:`~robovae.evaluate.quality.distribution` (1-D Wasserstein,
split-half reference, k-NN precision/recall) and :mod:`~robovae.evaluate.quality.report`.
"""

from robovae.evaluate.quality.attachment import AttachResult, attachment
from robovae.evaluate.quality.gait_search import GAIT_SEARCHES, budget_gait, searched_gait
from robovae.evaluate.quality.locomotion import GaitResult, actuated_base, gait, gait_speed
from robovae.evaluate.quality.stage import Stage, rest_pose, stage, stage_compiled
from robovae.evaluate.quality.standing import StandResult, standing
from robovae.evaluate.quality.symmetry import Anatomy, anatomy

__all__ = ["GAIT_SEARCHES", "Anatomy", "AttachResult", "GaitResult", "StandResult", "Stage",
           "actuated_base", "anatomy", "attachment", "budget_gait", "gait", "gait_speed",
           "rest_pose", "searched_gait", "stage", "stage_compiled", "standing"]
