"""One generated robot's folder: write it, validate it, measure its quality — what a worker
process of :mod:`robovae.generate.pipeline` does for each robot.

Kept apart from the pipeline so that the worker processes import only the writer, the
validator and the quality measures, none of which imports torch: the pipeline sends each graph
as :class:`~robovae.data.tree_arrays.TreeArrays`, and a worker starts on 0.6 s of CPU (3.9 s
with torch and PyG).
"""

from __future__ import annotations

from typing import Any

from robovae.evaluate.quality.measure import robot_quality
from robovae.evaluate.quality.stage import stage_compiled
from robovae.generate.validate import check_robot
from robovae.generate.writer import write_robot

__all__ = ["build_robot", "warm_up"]


def warm_up() -> None:
    """Nothing: a new worker process given it imports this module (the writer, the validator,
    the quality measures) before its first robot."""


def build_robot(item: tuple) -> dict:
    """Write one robot folder, validate it and measure its quality: ``item`` is ``(graph,
    folder, feature_set, name, scene, validate, quality[, controls[, stance[,
    self_collision]]])`` (``controls``: the validation's simulation, ``"held"`` by default, see
    :mod:`robovae.generate.validate`; ``stance``: the writer's stance rules,
    :mod:`robovae.generate.stance`, off by default; ``self_collision``: the robot's bodies
    collide with each other, :mod:`robovae.data.self_collision`, off by default).
    Returns the robot's part of its manifest record (``rules``, ``counts``, ``valid``,
    ``reason``, ``detail``, ``quality``); a graph the writer cannot write is a ``compile``
    failure, never an exception.

    The quality measures run on the model the validator compiled
    (:func:`~robovae.evaluate.quality.stage.stage_compiled`): the file is parsed once; with
    held validation the standing test continues the validation's simulation.
    """
    graph, folder, feature_set, name, scene, validate, quality = item[:7]
    controls = item[7] if len(item) > 7 else "held"
    stance = bool(item[8]) if len(item) > 8 else False
    self_collision = bool(item[9]) if len(item) > 9 else False
    try:
        # the validator loads the file anyway; the caller syncs a batch's files at once
        res = write_robot(graph, folder, feature_set, name=name, scene=scene,
                          check=not validate, durable=False, stance=stance,
                          self_collision=self_collision)
    except Exception as e:  # the rules make every graph writable; never lose a whole batch
        return {"rules": [], "counts": {}, "valid": False, "reason": "compile",
                "detail": f"writer error: {' '.join(str(e).split())}"}
    rec: dict[str, Any] = {"rules": res.rules, "counts": res.counts}
    if validate:
        checked = check_robot(res.robot_path, controls=controls)
        v = checked.validation
        rec.update(valid=v.valid, reason=v.reason, detail=v.detail)
        if v.valid and quality:  # attached, symmetric, standing ... (robovae.evaluate.quality)
            if checked.stage is not None:
                rec["quality"] = robot_quality(checked.stage, checked.held)
            else:
                rec["quality"] = robot_quality(stage_compiled(
                    checked.model, checked.spec, checked.floor, checked.data))
    return rec
