"""Gymnasium environments for any robot file; importing this package registers them.

``robovae/Walk-v0`` (:class:`robovae.envs.walk.WalkEnv`, 1000 steps per episode)::

    import gymnasium
    import robovae.envs  # noqa: F401  (registers robovae/Walk-v0)

    env = gymnasium.make("robovae/Walk-v0", robot="runs/samples/robot_000000/robot.xml")

:func:`robovae.envs.vector.make_vector_env` runs one environment per robot of a folder in a
``gymnasium.vector.AsyncVectorEnv``, observations and actions padded to the largest robot.
"""

from __future__ import annotations

import gymnasium

WALK_ID = "robovae/Walk-v0"

if WALK_ID not in gymnasium.registry:
    gymnasium.register(id=WALK_ID, entry_point="robovae.envs.walk:WalkEnv",
                       max_episode_steps=1000)

__all__ = ["WALK_ID"]
