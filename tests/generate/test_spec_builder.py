"""``SpecBuilder.move_built``: links moved in the spec already built give the spec a build of
the moved values gives, to the byte of its MJCF, and the undo gives back the spec as it was."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robovae.data.features import LINK, get_feature_set
from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.generate.mjcf_numbers import mjcf_round_vector
from robovae.generate.rules import apply_rules
from robovae.generate.spec_builder import SpecBuilder


def _builder(kind: str, seed: int, fs_name: str) -> SpecBuilder:
    fs = get_feature_set(fs_name)
    data, _ = apply_rules(model_to_graph(procedural_spec(seed, kind).compile(), fs), fs)
    return SpecBuilder(data, fs, "robot", "auto", False)


def _xml(spec: mujoco.MjSpec) -> tuple[str, int]:
    model = spec.compile()
    return spec.to_xml(), model.ngeom


def _rebuilt(kind: str, seed: int, fs_name: str, shifts: dict[str, np.ndarray]
             ) -> tuple[str, int, list[str]]:
    """The reference: a new builder whose values are moved before it builds."""
    made = _builder(kind, seed, fs_name)
    pos = made.fs.slice("link.pos")
    for name, shift in shifts.items():
        i = int(name.removeprefix("link"))
        made.x[i, pos] = mjcf_round_vector(made.x[i, pos] + shift)
    return *_xml(made.build()), list(made.fixes)


@pytest.mark.parametrize(("kind", "seed", "fs_name"), [
    ("humanoid", 900003, "kinematic"), ("hexapod", 4, "paper34"), ("arm", 1, "kinematic"),
    ("quadruped", 7, "full")])
def test_links_moved_in_place_are_the_robot_built_again(kind, seed, fs_name):
    builder = _builder(kind, seed, fs_name)
    spec = builder.build()
    kept = built = (*_xml(spec), list(builder.fixes))
    base = builder.x.copy()
    links = [i for i, t in enumerate(builder.types) if t == LINK and builder.anc[i] >= 0]
    rng = np.random.default_rng(seed)
    counts = set()
    total: dict[str, np.ndarray] = {}
    for n in range(8):  # passes: each adds its moves to those kept, as the writer's slides do
        trial = dict(total)
        for i in rng.choice(links, size=min(3, len(links)), replace=False).tolist():
            trial[f"link{i}"] = trial.get(f"link{i}", np.zeros(3)) + rng.normal(0, 0.06, 3)
        undo = builder.move_built(trial, base)
        moved = (*_xml(spec), list(builder.fixes))
        assert moved == _rebuilt(kind, seed, fs_name, trial)
        counts.add(int(np.sign(moved[1] - kept[1])))
        if n % 2 == 0:  # a pass not kept: the spec as it was before it
            undo()
            assert (*_xml(spec), list(builder.fixes)) == kept
        else:
            total, kept = trial, moved
    # moved back: the bridges the moves gained are deleted, the spec is the one built
    builder.move_built({name: np.zeros(3) for name in total}, base)
    back = (*_xml(spec), list(builder.fixes))
    assert back == built
    if fs_name != "full":  # the writer's joining geometry gained bridges, then lost them
        assert 1 in counts and back[1] < kept[1]


def test_moving_a_node_that_is_no_link_body_is_refused():
    builder = _builder("hexapod", 4, "kinematic")
    builder.build()
    joint = next(i for i, t in enumerate(builder.types) if t != LINK)
    with pytest.raises(ValueError, match="not a link body"):
        builder.move_built({f"link{joint}": np.zeros(3)}, builder.x.copy())
