"""Many robots at once: one :class:`~robovae.envs.walk.WalkEnv` per robot in a Gymnasium vector
environment.

Different robots have observations and actions of different sizes, and a vector environment
needs one space for all. :func:`make_vector_env` pads every robot to the largest, **block by
block**, so that a column means the same thing for every robot:

- observation ``[root (10) | joint positions (Q) | joint velocities (V)]`` with ``Q`` / ``V``
  the largest joint-position / joint-velocity block over the robots; a robot's block is
  written at the block's start and the rest is 0;
- action ``[-1, 1]^A`` with ``A`` the largest actuator count; robot ``i`` uses the first
  ``nu_i`` entries and ignores the others.

The returned environment carries the masks (``True`` where a value is real) as attributes:
``obs_mask`` ``[n, 10 + Q + V]``, ``action_mask`` ``[n, A]`` (NumPy bool), and ``robots`` (the
robot files, in sub-environment order) and ``layouts``
(:class:`~robovae.envs.walk.Layout` per robot).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, SupportsFloat, cast

import gymnasium
import numpy as np
from gymnasium import spaces

from robovae.envs.walk import ROOT_DIM, Layout, WalkEnv
from robovae.errors import RobovaeError
from robovae.files import robot_files as files_in_folders

__all__ = ["PadObsAction", "action_mask", "make_vector_env", "obs_mask", "pad_obs",
           "padded_layout", "robot_files"]


def robot_files(source: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    """Robot files of a folder (:func:`robovae.files.robot_files`: a folder written by
    ``robovae generate`` gives its ``robot_*/robot.xml`` in order, a folder of ``*.xml`` files
    those), or a list of files as given.

    Raises:
        RobovaeError: the folder holds no robot file, or a listed file does not exist.
    """
    if isinstance(source, (str, os.PathLike)):
        folder = Path(source)
        if not folder.is_dir():
            raise RobovaeError(f"robovae: {folder}: not a folder of robots")
        files = files_in_folders([folder])
        if not files:
            raise RobovaeError(f"robovae: {folder}: no robot files (robot.xml, robot_*/robot.xml, "
                               "*/robot.xml or *.xml)")
        return files
    files = [Path(p) for p in source]
    missing = [str(p) for p in files if not p.is_file()]
    if missing:
        raise RobovaeError(f"robovae: {missing[0]}: no such robot file")
    if not files:
        raise RobovaeError("robovae: no robot files given")
    return files


def padded_layout(layouts: Sequence[Layout]) -> Layout:
    """The block-wise maximum of ``layouts``."""
    return Layout(max(x.qpos for x in layouts), max(x.qvel for x in layouts),
                  max(x.action for x in layouts))


def pad_obs(obs: np.ndarray, own: Layout, padded: Layout) -> np.ndarray:
    """``obs`` of a robot with layout ``own`` padded block by block to ``padded`` (zeros)."""
    out = np.zeros(padded.obs, dtype=np.float64)
    out[:ROOT_DIM + own.qpos] = obs[:ROOT_DIM + own.qpos]
    start = ROOT_DIM + padded.qpos
    out[start:start + own.qvel] = obs[ROOT_DIM + own.qpos:]
    return out


def obs_mask(own: Layout, padded: Layout) -> np.ndarray:
    """``True`` at the real entries of a padded observation."""
    return pad_obs(np.ones(own.obs), own, padded) > 0


def action_mask(own: Layout, padded: Layout) -> np.ndarray:
    """``True`` at the used entries of a padded action."""
    return np.arange(padded.action) < own.action


class PadObsAction(gymnasium.Wrapper):
    """Pad a :class:`~robovae.envs.walk.WalkEnv` to a common :class:`Layout` (module docstring).

    Raises:
        RobovaeError: the robot is larger than ``layout`` in some block.
    """

    def __init__(self, env: gymnasium.Env, layout: Layout) -> None:
        super().__init__(env)
        walk = cast(WalkEnv, env.unwrapped)  # Env.unwrapped is typed as a plain Env
        own: Layout = walk.layout
        if own.qpos > layout.qpos or own.qvel > layout.qvel or own.action > layout.action:
            raise RobovaeError(f"robovae: {walk.robot_path}: robot {own} does not fit "
                               f"the padded layout {layout}")
        self.own, self.padded = own, layout
        self.observation_space = spaces.Box(-np.inf, np.inf, (layout.obs,), np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (layout.action,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the robot's environment; the observation padded."""
        obs, info = self.env.reset(seed=seed, options=options)
        return pad_obs(obs, self.own, self.padded), info

    def step(self, action: np.ndarray
             ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step with the first ``nu`` entries of ``action``; the observation padded."""
        obs, reward, terminated, truncated, info = self.env.step(
            np.asarray(action)[:self.own.action])
        return pad_obs(obs, self.own, self.padded), reward, terminated, truncated, info


def _make(robot: str, layout: Layout, kwargs: dict) -> gymnasium.Env:
    """One padded sub-environment (top-level so that it pickles for worker processes)."""
    import robovae.envs  # noqa: F401  (registers robovae/Walk-v0 in the worker)

    return PadObsAction(gymnasium.make("robovae/Walk-v0", robot=robot, **kwargs), layout)


def make_vector_env(robots: str | os.PathLike | Sequence[str | os.PathLike],
                    asynchronous: bool = True, context: str | None = "spawn",
                    **env_kwargs: Any) -> gymnasium.vector.VectorEnv:
    """A vector environment with one ``robovae/Walk-v0`` per robot (module docstring).

    Args:
        robots: a folder or a list of robot files (:func:`robot_files`).
        asynchronous: ``AsyncVectorEnv`` (one worker process per robot) or ``SyncVectorEnv``.
        context: multiprocessing start method of the workers (``spawn``: safe when the parent
            process runs torch threads).
        **env_kwargs: passed to every :class:`~robovae.envs.walk.WalkEnv`.

    Returns:
        the vector environment, with ``robots``, ``layouts``, ``obs_mask`` and ``action_mask``.

    Raises:
        RobovaeError: as :func:`robot_files` and :class:`~robovae.envs.walk.WalkEnv` (a
            ``RobotFileError`` for a file that is not a robot), naming the first robot that
            cannot be an environment (checked here, before any worker starts).
    """
    files = robot_files(robots)
    layouts = []
    for f in files:
        env = WalkEnv(f, **env_kwargs)
        layouts.append(env.layout)
        env.close()
    layout = padded_layout(layouts)
    fns = [functools.partial(_make, str(f), layout, dict(env_kwargs)) for f in files]
    venv: gymnasium.vector.VectorEnv
    if asynchronous:
        venv = gymnasium.vector.AsyncVectorEnv(fns, context=context)
    else:
        venv = gymnasium.vector.SyncVectorEnv(fns)
    # extra attributes (module docstring), which VectorEnv does not declare
    extras = {"robots": files, "layouts": layouts,
              "obs_mask": np.stack([obs_mask(own, layout) for own in layouts]),
              "action_mask": np.stack([action_mask(own, layout) for own in layouts])}
    for name, value in extras.items():
        setattr(venv, name, value)
    return venv
