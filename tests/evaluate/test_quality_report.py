"""Quality records of many robots and the side-by-side table (robovae.evaluate.quality)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from robovae.data.procedural import parse_procedural, procedural_spec
from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.measure import QUALITY_KEYS, measure, measure_many, robot_quality
from robovae.evaluate.quality.populations import procedural_files, real_robot_files, written_files
from robovae.evaluate.quality.report import (
    contact_sheets,
    format_quality,
    quality_table,
    summarize,
)

ZOO = dict(zoo_files()[0])


def test_measure_records_every_measure_and_errors_in_one_line(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    rows = measure_many([ZOO["gym_ant"], bad, procedural_spec(0, "hexapod")], jobs=1,
                        progress=False, names=["ant", "bad", "hexapod"],
                        gait_kw={"rollouts": 2, "seconds": 0.5}, locomotion=True)
    ant, broken, hexapod = rows
    assert [r["name"] for r in rows] == ["ant", "bad", "hexapod"]
    assert "error" in broken and "\n" not in broken["error"]
    assert ant["all_attached"] and ant["symmetric"] and ant["stands"]
    assert (ant["limbs"], ant["bodies"], ant["dof"]) == (4, 13, 14)
    assert ant["d_limbs"] == 4 and ant["gait_speed"] > 0
    assert hexapod["limbs"] == 6 and hexapod["pairs"] == 3
    # rolling told from stepping: a motor on a hinge without limits makes a robot wheeled
    assert ant["wheeled"] is False and hexapod["wheeled"] is False
    assert measure(procedural_spec(0, "mobile_manipulator"), describe=False)["wheeled"] is True
    assert all(ant[f"t_{k}"] >= 0 for k in ("load", "anatomy", "attachment", "standing"))
    compact = robot_quality(procedural_spec(0, "hexapod"))
    assert set(compact) == set(QUALITY_KEYS)
    assert measure(ZOO["gym_half_cheetah"], describe=False)["stands"] is None  # not floating


def test_a_spec_named_robot_keeps_its_name(tmp_path) -> None:
    """The writer names its specs "robot" by default: only a file ``robot_<i>/robot.xml`` is
    named after its folder; a spec keeps its model name."""
    from robovae.data.procedural import procedural_graphs
    from robovae.generate.writer import graph_to_spec, write_robot

    graph = procedural_graphs(parse_procedural("n=1"), jobs=1)[0]
    spec, _ = graph_to_spec(graph)
    assert spec.modelname == "robot"
    rec = measure(spec, describe=False)
    assert "error" not in rec and rec["name"] == "robot" and rec["path"] is None
    path = write_robot(graph, tmp_path / "robot_000007", scene=False).robot_path
    assert measure(path, describe=False)["name"] == "robot_000007"


def test_summary_shares_leave_errors_out() -> None:
    rows = [{"all_attached": True, "symmetric": True, "one_limb": False, "floating": True,
             "stands": True, "detached_share": 0.0, "self_penetrating": False, "limbs": 4},
            {"all_attached": False, "symmetric": False, "one_limb": True, "floating": False,
             "stands": None, "detached_share": 0.5, "self_penetrating": True, "limbs": 1},
            {"error": "RobotFileError: x"}]
    s = summarize(rows)
    assert s["robots"] == 3 and s["errors"] == 1
    assert s["all_attached"] == 0.5 and s["symmetric"] == 0.5 and s["one_limb"] == 0.5
    assert s["detached_share"] == 0.25 and s["self_penetrating"] == 0.5
    assert s["floating"] == 1 and s["standing"] == 1.0 and s["mean_limbs"] == 2.5
    assert math.isnan(s["gait_speed"]) and math.isnan(summarize([])["standing"])
    assert math.isnan(s["wheeled"])  # not measured
    speeds = summarize([{"wheeled": w, "gait_speed": v}
                        for w, v in ((False, 0.4), (True, 0.1), (False, 0.6), (True, 0.2))])
    assert speeds["wheeled"] == 0.5 and speeds["gait_speed"] == pytest.approx(0.3)
    assert speeds["gait_speed_legged"] == pytest.approx(0.5)


def test_populations_measured_in_one_pool_as_in_this_process(tmp_path) -> None:
    """``robovae analyze`` measures its populations in one pool of workers (each worker's imports
    cost seconds): the rows are those measured in this process, and the pool outlives each
    call."""
    from robovae.data.workers import process_pool

    pops = [[ZOO["gym_ant"], ZOO["gym_hopper"], ZOO["gym_walker2d"]],
            procedural_files(3, tmp_path, seed=3)]

    def untimed(rows):  # as JSON text: NaN (a ratio of nothing) equals itself
        return json.dumps([{k: v for k, v in r.items() if not k.startswith("t_")}
                           for r in rows], sort_keys=True)

    here = [untimed(measure_many(p, jobs=1, progress=False)) for p in pops]
    with process_pool(2) as pool:
        shared = [untimed(measure_many(p, jobs=2, progress=False, pool=pool)) for p in pops]
        assert pool.submit(int, "7").result() == 7  # still running
    assert shared == here and json.loads(here[0])[0]["stands"] and len(json.loads(here[1])) == 3


def test_quality_table_compares_with_the_corpus_and_real_robots(tmp_path, menagerie_dir
                                                                ) -> None:
    kw = {"jobs": 1, "progress": False}
    corpus = measure_many([ZOO[n] for n in ("gym_ant", "dmc_quadruped", "gym_walker2d",
                                             "gym_humanoid")], **kw)
    proc = measure_many(procedural_files(4, tmp_path, seed=3), **kw)
    real = measure_many(real_robot_files(menagerie_dir)[:3], **kw)
    pops = {"samples": corpus[:2], "training corpus": corpus, "procedural": proc,
            "real robots": real}
    rows, cols, numbers = quality_table(pops)
    assert cols == ["measure", "samples", "training corpus", "procedural", "real robots"]
    assert numbers["training corpus"]["precision_corpus"] != numbers["training corpus"][
        "precision_corpus"]  # NaN: no precision of the corpus against itself
    # samples drawn from the corpus lie on its manifold
    assert numbers["samples"]["precision_corpus"] == 1.0
    assert numbers["samples"]["w1_limbs"] == pytest.approx(0.75)  # {4, 4} vs {4, 4, 2, 3}
    assert numbers["training corpus"]["w1_limbs"] > 0  # split-half reference
    assert numbers["procedural"]["all_attached"] == 1.0
    assert len(real_robot_files(menagerie_dir)) == 17
    text = format_quality(pops)
    assert "symmetric (mirrored limb pairs)" in text and "recall vs real robots" in text
    assert real_robot_files(tmp_path / "absent") == []


def test_contact_sheets_one_png_per_population(tmp_path) -> None:
    from PIL import Image

    rows = measure_many([ZOO["gym_ant"], ZOO["gym_hopper"]], jobs=1, progress=False,
                        describe=False, names=["ant", "hopper"])
    paths = contact_sheets({"training corpus": rows, "empty": []}, tmp_path, columns=2)
    assert paths == [tmp_path / "quality_training_corpus.png"]
    assert Image.open(paths[0]).size == (2 * 240, 180)


def test_written_files_are_robots_as_generate_writes_them(tmp_path) -> None:
    files = written_files(3, tmp_path, zoo=False)
    assert [f.parent.name for f in files] == ["robot_000000", "robot_000001", "robot_000002"]
    assert {f.parent.parent.name for f in files} == {"procedural"}
    again = written_files(3, tmp_path, zoo=False)  # reused, not written again
    assert again == files and all(f.stat().st_mtime_ns == g.stat().st_mtime_ns
                                  for f, g in zip(files, again))
    rows = [robot_quality(f) for f in files]
    assert all("error" not in r and r["floating"] for r in rows)


def test_written_files_are_the_same_robots_whatever_n_asked_and_the_writer_is_part_of_the_cache(
        tmp_path, monkeypatch) -> None:
    """A file of the cache is one robot: procedural robot i whether 2 or 3 were asked (robot 2
    was once the first zoo robot, written when 2 procedural robots came first), and a cache of
    another writer is not reused."""
    import robovae.generate.writer as writer

    with_zoo = written_files(2, tmp_path)
    assert [f.parent.parent.name for f in with_zoo] == ["procedural"] * 2 + ["zoo"] * (
        len(with_zoo) - 2) and len(with_zoo) > 2
    three = written_files(3, tmp_path, zoo=False)
    assert three[:2] == with_zoo[:2] and three[2] not in with_zoo
    fresh = written_files(3, tmp_path / "fresh", zoo=False)
    assert three[2].read_text() == fresh[2].read_text()
    monkeypatch.setattr(writer, "WRITER", writer.WRITER + ", something else")
    other = written_files(3, tmp_path, zoo=False)
    assert other[0].parents[2] != three[0].parents[2] and other[0].is_file()


def test_corpus_files_rebuild_procedural_training_robots(tmp_path):
    """Procedural training robots have no file: the corpus column writes them from their seed
    (the same robot as the generator's), spread over the corpus; file robots are their file."""
    from robovae.data.procedural.robots import procedural_spec
    from robovae.evaluate.quality.populations import corpus_files

    sources = [f"procedural:quadruped:{s}" for s in range(6)] + [None, "/some/robot.xml"]
    names = [f"r{i}" for i in range(8)]
    files, picked = corpus_files(sources, names, 3, tmp_path)
    assert picked == ["r0", "r2", "r4"]  # every 7 // 3 = 2nd of the 7 with a source
    assert files[1].endswith("proc_quadruped_000002.xml")
    assert Path(files[1]).read_text() == procedural_spec(2, "quadruped").to_xml()
    assert corpus_files(sources, names, 10, tmp_path)[0][-1] == "/some/robot.xml"
    assert corpus_files([None], ["x"], 3, tmp_path) == ([], [])


def test_measure_refuses_bad_settings_instead_of_an_error_per_robot() -> None:
    from robovae.errors import SettingsError

    with pytest.raises(SettingsError, match="standing.seconds"):
        measure(ZOO["gym_ant"], describe=False, stand_kw={"seconds": -1.0})
    with pytest.raises(SettingsError, match="budget_gait.search"):
        measure(ZOO["gym_ant"], describe=False, locomotion=True, gait_search="grid")
    with pytest.raises(SettingsError, match="measure_many.jobs"):
        measure_many([ZOO["gym_ant"]], jobs=-1, progress=False)
