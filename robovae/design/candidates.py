"""One candidate robot of ``robovae optimize``, scored in a worker process without torch.

The optimiser's process prepares every candidate (:func:`robovae.design.optimize`): a latent
candidate's decoded graph gets ``robovae generate``'s fixes
(:func:`robovae.generate.fixes.decoded_fixes`) and travels as
:class:`~robovae.data.tree_arrays.TreeArrays`, a procedural baseline robot as its MJCF text.
A worker (:func:`evaluate`) writes the candidate into a scratch folder as ``robovae generate``
writes a robot (no scene, stance rules on), scores it (:func:`scored`) and deletes the folder.

This module and what it imports load neither torch nor PyG, so a spawned worker starts on the
writer, the validator and the simulation only (measured: 66-115 MB at peak instead of
466-525 MB, and about 5 s less CPU per worker; docs/design.md).
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from robovae.data.tree_arrays import TreeArrays
from robovae.design.score import score_robot

__all__ = ["Candidate", "evaluate", "failed", "scored"]

#: A worker's candidate: ``(robot, folder, feature_set, task, seeds, self_collision)``.
Candidate = tuple[TreeArrays | str, str, str, str, Sequence[int], bool]


def failed(error: Exception) -> dict:
    """The record of a candidate that could not be written: score 0 and the error on one line
    (``writer: <type>: <message>``)."""
    return {"score": 0.0, "error": " ".join(f"writer: {type(error).__name__}: {error}".split())}


def scored(path: Path, task: str, seeds: Sequence[int]) -> dict:
    """The score of a robot file under ``seeds``: seed ``seeds[0]``'s result (details, error),
    its score replaced, with more than one seed, by the median of the seeds' scores (all of them
    in ``scores``; a robot that fails under the first seed is not scored again)."""
    res = score_robot(path, task, seed=seeds[0])
    if len(seeds) > 1:
        scores = [res["score"]] + ([score_robot(path, task, seed=s)["score"] for s in seeds[1:]]
                                   if res.get("error") is None else [0.0] * (len(seeds) - 1))
        res.update(score=float(np.median(scores)), scores=scores)
    return res


def evaluate(item: Candidate) -> dict:
    """Write one candidate into a scratch folder, score it, delete the folder (worker).

    ``item`` is ``(robot, folder, feature_set, task, seeds, self_collision)``: ``robot`` the
    prepared graph (:class:`TreeArrays`, written by :func:`robovae.generate.writer.write_robot`,
    its bodies colliding with each other with ``self_collision``) or MJCF text (written as it
    is). Returns :func:`scored`'s record; a candidate that cannot be written scores 0
    (:func:`failed`)."""
    robot, folder_name, fs_name, task, seeds, self_collision = item
    from robovae.generate.writer import write_robot

    folder = Path(folder_name)
    try:
        if isinstance(robot, str):
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "robot.xml").write_text(robot)
        else:
            write_robot(robot, folder, fs_name, name=folder.name, scene=False, stance=True,
                        self_collision=self_collision)
        res = scored(folder / "robot.xml", task, seeds)
        if res.get("error"):  # the scratch file is gone: name the candidate, not the file
            res["error"] = res["error"].replace(f"{folder / 'robot.xml'}: ", "")
        return res
    except Exception as e:  # an unwritable candidate scores 0
        return failed(e)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
