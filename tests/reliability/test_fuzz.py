"""Property tests and a fuzz test of the MJCF reader and writer.

(a) Random valid robots built with ``mujoco.MjSpec`` (:func:`strategies.robot_descs`: random
    nesting, hinge/slide/ball joints, a free joint only at the root, sphere/capsule/box geoms
    with random sizes and masses, explicit inertials, motors) survive MJCF → graph →
    :func:`~robovae.generate.writer.write_robot` → graph: topology exact, features within
    ``rtol = 1e-5`` (the exceptions of ``tests/generate/test_writer.py``), no rule fires.
(b) Random feature vectors (``tests.conftest.random_tree``: randn·10 with NaN/Inf, plus NaN,
    ±Inf, ±3e38, ±1e30, denormals and zeros dropped into random owned cells) through
    :func:`~robovae.generate.rules.apply_rules` + :func:`~robovae.generate.writer.graph_to_spec`
    always give a model MuJoCo compiles, whose written XML reads back into a graph; the rules
    leave finite values, and a second pass changes nothing.
(c) Fuzz: :data:`N_FUZZ` mutated robot files (the corpus' good files and every zoo file, with
    byte, attribute and element mutations from a seeded RNG) through
    :func:`~robovae.data.mjcf.mjcf_to_graph` in two spawned workers with a per-case timeout.
    The only allowed outcomes are a graph or a one-line ``robovae: <file>: ...`` error:
    crashes (any other exception, or a dead worker), hangs and multi-line messages must all
    be 0.

Hypothesis runs derandomized with ``deadline=None`` and no example database, so CI is
reproducible; the fuzz RNG has a fixed seed.
"""

from __future__ import annotations

import random
import resource
import shutil
import tempfile
import time
from collections import Counter
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robovae.data.features import GEOM, JOINT, LINK, get_feature_set
from robovae.data.mjcf import mjcf_to_graph
from robovae.data.zoo import zoo_files
from robovae.generate.rules import apply_rules
from robovae.generate.writer import graph_to_spec, write_robot
from tests.conftest import CORPUS, random_tree
from tests.reliability.strategies import (
    assert_same_graph,
    build_spec,
    included_files,
    mutate,
    robot_descs,
    roundtrip_expected,
    run_cases,
)

pytestmark = pytest.mark.timeout(300, method="thread")

FEATURE_SETS = ["paper34", "full"]
N_FUZZ = 1000
FUZZ_SEED = 20240611
CASE_TIMEOUT = 30.0  # s; the slowest unmutated seed loads in ~1.5 s (on a busy machine 5 s)

_SETTINGS = dict(deadline=None, derandomize=True, database=None, print_blob=True,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# --- (a) random valid robots round-trip exactly ------------------------------------------------


@pytest.mark.parametrize("fs", FEATURE_SETS)
@settings(max_examples=40, **_SETTINGS)
@given(bodies=robot_descs())
def test_random_valid_robot_roundtrip(fs, bodies):
    spec = build_spec(bodies)
    spec.compile()  # to_xml needs a compiled spec
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "random.xml"
        src.write_text(spec.to_xml())
        g = mjcf_to_graph(src, fs)
        counts = torch.bincount(g.node_type, minlength=3).tolist()
        assert counts[LINK] == len(bodies)
        assert counts[JOINT] == sum(len(b.joints) for b in bodies)
        if fs == "full":
            assert counts[GEOM] == sum(len(b.geoms) for b in bodies)
        assert "registry range" not in g.warnings
        result = write_robot(g, Path(tmp) / "out", fs, name="random", scene=False,
                             clearance=None)
        # a valid robot needs no repair; bridges join links whose size does not reach a joint
        assert set(result.rules_fired) <= {"geom_bridge"}
        back = mjcf_to_graph(result.robot_path, fs)
    assert_same_graph(g, back, roundtrip_expected(g, fs), fs, f"random robot ({fs})")


# --- (b) garbage features always give a compilable model -------------------------------------

SPECIAL = [float("nan"), float("inf"), -float("inf"), 3e38, -3e38, 1e30, -1e30, 1e-30, 1e-45,
           0.0, -0.0, 1.0, -1.0]


@pytest.mark.parametrize("fs", [*FEATURE_SETS, "kinematic"])
@settings(max_examples=50, **_SETTINGS)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 40),
       specials=st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 10**6),
                                   st.sampled_from(SPECIAL)), max_size=30),
       clearance=st.sampled_from([None, 0.01]))
def test_garbage_features_always_compile(fs, seed, n, specials, clearance):
    g = random_tree(np.random.default_rng(seed), fs, n)
    owned = torch.nonzero(g.x_mask).tolist()
    x = g.x.clone()
    for r, c, value in specials:
        i, j = owned[(r * 7919 + c) % len(owned)]
        x[i, j] = value
    g.x = x
    repaired, fired = apply_rules(g, fs)
    assert torch.isfinite(repaired.x).all()
    assert apply_rules(repaired, fs)[1] == []  # the repair is complete: a second pass is a no-op
    spec, fired = graph_to_spec(g, fs, clearance=clearance)
    xml = spec.to_xml()
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.nbody >= 2
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "robot.xml"
        path.write_text(xml)
        back = mjcf_to_graph(path, fs)
    assert torch.isfinite(back.x).all() and back.x.shape[1] == get_feature_set(fs).dim


# --- (c) fuzzing the reader --------------------------------------------------------------------


def _seeds() -> list[tuple[str, Path]]:
    good = [(p.stem, p) for p in sorted(CORPUS.glob("good_*"))]
    return good + [(name, path) for name, path in zoo_files()[0]]


def test_fuzz_mjcf_to_graph(tmp_path):
    seeds = _seeds()
    assert len(seeds) >= 20
    rng = random.Random(FUZZ_SEED)
    folders, cases, ops = {}, [], []
    for name, path in seeds:  # one folder per seed, with the files it includes
        folders[name] = tmp_path / name
        folders[name].mkdir()
        for rel, data in included_files(path).items():
            (folders[name] / rel).parent.mkdir(parents=True, exist_ok=True)
            (folders[name] / rel).write_bytes(data)
    texts = {name: path.read_bytes() for name, path in seeds}
    # round robin over the seeds; the four big ones (> 60 KiB: dm_control dog, dog_v2, rodent,
    # fruit fly, 0.1-1 s a load) in one round out of three
    schedule = [(r, name, path) for r in range(N_FUZZ) for name, path in seeds
                if len(texts[name]) < 60 * 2**10 or r % 3 == 0][:N_FUZZ]
    for k, (r, name, path) in enumerate(schedule):
        text, applied = mutate(texts[name], rng)
        case = folders[name] / f"case{k:04d}{path.suffix}"
        case.write_bytes(text)
        cases.append((str(case), FEATURE_SETS[r % 2]))
        ops.append(applied)

    start, cpu = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    outcomes = run_cases(cases, workers=2, timeout=CASE_TIMEOUT, cwd=str(tmp_path))
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = after.ru_utime + after.ru_stime - cpu.ru_utime - cpu.ru_stime
    counts = Counter(o.kind for o in outcomes)
    slowest = max(outcomes, key=lambda o: o.seconds)
    print(f"\nfuzz: {N_FUZZ} mutated inputs from {len(seeds)} seeds in {elapsed:.1f} s "
          f"({cpu_s:.0f} s worker CPU): "
          f"{counts['graph']} graphs, {counts['error']} one-line errors, {counts['crash']} "
          f"crashes, {counts['hang']} hangs, {counts['multiline']} multi-line messages; "
          f"slowest case {slowest.seconds:.2f} s")
    failures = [(cases[i][0], cases[i][1], ops[i], o) for i, o in enumerate(outcomes)
                if o.kind not in ("graph", "error")]
    if failures:
        keep = tmp_path.parent / "fuzz_failures"
        keep.mkdir(exist_ok=True)
        for case, *_ in failures:
            shutil.copy(case, keep / Path(case).name)
        lines = [f"{o.kind}: {Path(c).parent.name}/{Path(c).name} ({fs}; {', '.join(a)}): "
                 f"{o.detail.splitlines()[0] if o.detail else ''}" for c, fs, a, o in failures]
        pytest.fail(f"{len(failures)} fuzz failures (inputs kept in {keep}):\n"
                    + "\n".join(lines[:20]))
    assert counts["graph"] >= N_FUZZ // 10 and counts["error"] >= N_FUZZ // 10


def test_fuzz_harness_counts_every_outcome(tmp_path):
    """The harness itself, with a stand-in loader: a hang, a dying worker, an unexpected
    exception and a multi-line message are each counted (and the worker replaced); the cases
    around them still give their graph or one-line error."""
    names = ["good0", "hang", "abort", "boom", "multi", "bad", "good1"]
    for name in names:
        (tmp_path / f"{name}.xml").write_text("<mujoco/>")
    cases = [(str(tmp_path / f"{n}.xml"), "paper34") for n in names]
    outcomes = run_cases(cases, workers=1, timeout=3.0, cwd=str(tmp_path),
                         loader="tests.reliability.strategies:harness_check_loader")
    assert [o.kind for o in outcomes] == ["graph", "hang", "crash", "crash", "multiline",
                                          "error", "graph"]
    assert "worker died" in outcomes[2].detail and "KeyError" in outcomes[3].detail
