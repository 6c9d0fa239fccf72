"""robovae generate: folders + manifest + summary, resume, determinism, the predict path."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import lightning as L
import mujoco
import pytest
import torch

from robovae.cli import main
from robovae.data.datamodule import RobotDataModule
from robovae.errors import RobovaeError
from robovae.generate.pipeline import (
    MANIFEST,
    RUN,
    SUMMARY,
    generate,
    latent,
    node_noise,
    read_manifest,
)
from robovae.generate.predict import RobotWriter
from robovae.generate.validate import REASONS
from robovae.generate.writer import WRITER
from robovae.model.vae import RoboVAE


def _files(out: Path) -> dict[str, bytes]:
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.glob("robot_*/*.xml"))}


def test_generate_writes_loadable_robots_and_a_report(trained, tmp_path):
    model, _, ckpt = trained
    out = tmp_path / "gen"
    report = generate(ckpt, 12, out, seed=3, jobs=1, progress=False, batch_size=5)
    assert report.total == report.new == 12
    recs = read_manifest(out)
    assert sorted(recs) == list(range(12))
    for i, rec in recs.items():
        folder = out / f"robot_{i:06d}"
        mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
        assert rec["reason"] in REASONS
        assert len(rec["latent"]) == 8 and rec["seed"] == 3
        assert rec["counts"]["bodies"] >= 1
    summary = json.loads((out / SUMMARY).read_text())
    assert summary["total"] == 12 and 0 <= summary["metrics"]["validity"] <= 1
    assert "validity" in report.format()
    # valid robots carry their quality record; the summary counts them
    valid = [r for r in recs.values() if r["valid"]]
    assert all({"all_attached", "symmetric", "stands"} <= set(r["quality"]) for r in valid)
    q = summary["metrics"]["quality"]
    assert q["robots"] == len(valid)
    if valid:
        assert q["all_attached"] == sum(r["quality"]["all_attached"] for r in valid) / len(valid)
        assert "all bodies attached" in report.format()


def test_no_quality_skips_the_measures_and_keeps_the_robots(trained, tmp_path):
    _, _, ckpt = trained
    with_q = generate(ckpt, 4, tmp_path / "q", seed=3, jobs=1, progress=False)
    without = generate(ckpt, 4, tmp_path / "no_q", seed=3, jobs=1, progress=False,
                       quality=False)
    recs, bare = read_manifest(tmp_path / "q"), read_manifest(tmp_path / "no_q")
    assert any("quality" in r for r in recs.values())
    assert not any("quality" in r for r in bare.values())
    assert [r["valid"] for r in recs.values()] == [r["valid"] for r in bare.values()]
    assert "attached" in with_q.format() and "attached" not in without.format()


@pytest.mark.parametrize("fixture", ["trained", "trained_nodes"])
def test_same_seed_gives_byte_identical_files(fixture, request, tmp_path):
    """A robot depends on (checkpoint, seed, index) only, not on the batch it was decoded in
    (with node latents too: their noise comes from the robot's own stream)."""
    _, _, ckpt = request.getfixturevalue(fixture)
    generate(ckpt, 6, tmp_path / "a", seed=1, validate=False, progress=False, batch_size=6)
    generate(ckpt, 6, tmp_path / "b", seed=1, validate=False, progress=False, batch_size=2)
    generate(ckpt, 6, tmp_path / "c", seed=2, validate=False, progress=False)
    a, b, c = (_files(tmp_path / k) for k in "abc")
    assert a == b and len(a) == 12
    assert a != c


def test_resume_skips_done_robots_and_survives_a_torn_line(trained, tmp_path):
    _, _, ckpt = trained
    out = tmp_path / "gen"
    generate(ckpt, 4, out, validate=False, progress=False)
    # a crash in the middle of writing the 5th line
    with (out / MANIFEST).open("a") as f:
        f.write('{"index": 4, "na')
    report = generate(ckpt, 7, out, validate=False, progress=False)
    assert report.new == 3 and report.total == 7
    assert sorted(read_manifest(out)) == list(range(7))
    lines = (out / MANIFEST).read_text().splitlines()
    assert sum(1 for ln in lines if ln.startswith('{"index": 4, "na')) == 1  # left, ignored
    ref = tmp_path / "ref"
    generate(ckpt, 7, ref, validate=False, progress=False)
    assert _files(out) == _files(ref)


def test_node_noise_depends_on_seed_and_index_only(trained_nodes):
    model = trained_nodes[0]
    z, noise = model.sample_prior(4, [2, 7, 9], temperature=0.5)
    z1, noise1 = model.sample_prior(4, [7])
    assert torch.equal(z[1], 0.5 * z1[0]) and torch.equal(noise[1], 0.5 * noise1[0])
    assert noise.shape == (3, model.hparams.max_nodes, 6)
    assert torch.equal(noise1[0], node_noise(4, 7, model.hparams.max_nodes, 6))
    assert not torch.equal(noise1[0], node_noise(4, 8, model.hparams.max_nodes, 6))


def test_node_noise_at_temperature_zero_decodes_as_the_drawn_noise_scaled_by_zero(trained_nodes):
    model = copy.deepcopy(trained_nodes[0]).to(torch.float64)
    hp = model.hparams
    z, noise = model.sample_prior(3, list(range(12)), node_temperature=0.0)
    assert torch.equal(noise, torch.zeros_like(noise)) and not torch.signbit(noise).any()
    # what the draw gave before: standard normals times 0, half of them -0.0
    drawn = torch.stack([node_noise(3, i, hp.max_nodes, hp.node_latent_dim) for i in range(12)])
    scaled = (drawn * 0.0).to(torch.float64)
    assert torch.signbit(scaled).any()
    for a, b in zip(model.decode(z, node_noise=noise), model.decode(z, node_noise=scaled)):
        assert torch.equal(a.parent, b.parent) and torch.equal(a.node_type, b.node_type)
        assert torch.equal(a.x, b.x) and torch.equal(torch.signbit(a.x), torch.signbit(b.x))


def test_node_temperature_sets_the_node_noise_only(trained_nodes, tmp_path):
    _, _, ckpt = trained_nodes
    kw = dict(seed=2, validate=False, progress=False, jobs=1)
    generate(ckpt, 4, tmp_path / "a", **kw)
    generate(ckpt, 4, tmp_path / "b", node_temperature=1.0, **kw)
    generate(ckpt, 4, tmp_path / "c", node_temperature=0.0, **kw)
    a, b, c = (_files(tmp_path / k) for k in "abc")
    assert a == b and a != c  # default: the node noise follows --temperature
    za, zc = read_manifest(tmp_path / "a"), read_manifest(tmp_path / "c")
    assert all(za[i]["latent"] == zc[i]["latent"] for i in range(4))  # z is the same


def test_the_checkpoints_node_temperature_is_the_default(trained_nodes, tmp_path):
    model = trained_nodes[0]
    cold = copy.deepcopy(model)
    cold.hparams.node_temperature = 0.0  # as configs/default.yaml trains it
    kw = dict(seed=2, validate=False, progress=False, jobs=1)
    generate(model, 4, tmp_path / "zero", node_temperature=0.0, **kw)
    generate(cold, 4, tmp_path / "model", **kw)
    generate(cold, 4, tmp_path / "one", node_temperature=1.0, **kw)
    generate(model, 4, tmp_path / "plain", **kw)
    zero, cold_files, one, plain = (_files(tmp_path / k) for k in ("zero", "model", "one",
                                                                  "plain"))
    assert zero == cold_files and one == plain and cold_files != plain
    run = json.loads((tmp_path / "model" / RUN).read_text())
    assert run["node_temperature"] == 0.0  # the setting used, recorded
    assert json.loads((tmp_path / "plain" / RUN).read_text())["node_temperature"] is None
    graphs = cold.sample(2, generator=torch.Generator().manual_seed(0))
    again = model.sample(2, generator=torch.Generator().manual_seed(0), node_temperature=0.0)
    assert all(torch.equal(a.x, b.x) for a, b in zip(graphs, again))


@pytest.mark.parametrize("arg", [dict(node_temperature=-0.5), dict(temperature=-1.0),
                                 dict(temperature=float("nan"))])
def test_a_negative_temperature_is_refused_before_writing(trained, tmp_path, arg):
    with pytest.raises(RobovaeError, match="temperature must be a finite number >= 0"):
        generate(trained[2], 2, tmp_path / "gen", progress=False, **arg)
    assert not (tmp_path / "gen").exists()


def test_latent_depends_on_seed_and_index_only():
    assert (latent(0, 5, 8) == latent(0, 5, 8)).all()
    assert not (latent(0, 5, 8) == latent(0, 6, 8)).all()
    assert not (latent(1, 5, 8) == latent(0, 5, 8)).all()
    assert (latent(0, 5, 8, temperature=0.5) == 0.5 * latent(0, 5, 8)).all()


def test_predict_writer_matches_generate(trained, tmp_path):
    _, _, ckpt = trained
    # precision 64-true turns the module into float64 in place: not the session's shared model
    model = copy.deepcopy(trained[0])
    dm = RobotDataModule(["zoo"], root=str(tmp_path / "cache"), predict_samples=5,
                         predict_seed=4, batch_size=2)
    writer = RobotWriter(str(tmp_path / "pred"), validate=False)
    trainer = L.Trainer(accelerator="cpu", devices=1, logger=False, callbacks=[writer],
                        precision="64-true",
                        enable_progress_bar=False, enable_model_summary=False)
    trainer.predict(model, dm, return_predictions=False)
    assert sorted(read_manifest(tmp_path / "pred")) == list(range(5))
    generate(ckpt, 5, tmp_path / "gen", seed=4, validate=False, progress=False)
    assert _files(tmp_path / "pred") == _files(tmp_path / "gen")
    # resume: nothing left to do
    trainer.predict(model, dm, return_predictions=False)
    assert len(dm.predict_set) == 0 and writer.report.total == 5


def test_predict_writer_self_collision_matches_generate(trained, tmp_path):
    """RobotWriter(self_collision=True) writes generate --self-collision's files and run, so
    either command resumes the other's folder."""
    _, _, ckpt = trained
    model = copy.deepcopy(trained[0])
    dm = RobotDataModule(["zoo"], root=str(tmp_path / "cache"), predict_samples=3,
                         predict_seed=2, batch_size=4)
    writer = RobotWriter(str(tmp_path / "pred"), validate=False, jobs=1, self_collision=True)
    trainer = L.Trainer(accelerator="cpu", devices=1, logger=False, callbacks=[writer],
                        precision="64-true",
                        enable_progress_bar=False, enable_model_summary=False)
    trainer.predict(model, dm, return_predictions=False)
    generate(ckpt, 3, tmp_path / "gen", seed=2, validate=False, progress=False, jobs=1,
             self_collision=True)
    assert _files(tmp_path / "pred") == _files(tmp_path / "gen")
    assert json.loads((tmp_path / "pred" / RUN).read_text())["self_collision"] is True
    with pytest.raises(RobovaeError, match="self_collision differ"):
        generate(ckpt, 3, tmp_path / "pred", seed=2, validate=False, progress=False, jobs=1)


def test_predict_resumes_a_validated_generation(trained, tmp_path):
    """A validated folder of ``robovae generate`` records its validation (held controls);
    RobotWriter, which validates the same way, left it out of its ``run.json`` and so refused
    generate's folder ("validation differ") while a ``--no-validate`` generate resumed its
    own (until 2026-12-02). Both now build the record in one place: each resumes the other's
    validated folder, and an unvalidated run is refused."""
    _, _, ckpt = trained
    out = tmp_path / "gen"
    generate(ckpt, 2, out, seed=2, progress=False, jobs=1)
    dm = RobotDataModule(["zoo"], root=str(tmp_path / "cache"), predict_samples=3,
                         predict_seed=2, batch_size=4)
    writer = RobotWriter(str(out), jobs=1)
    trainer = L.Trainer(accelerator="cpu", devices=1, logger=False, callbacks=[writer],
                        precision="64-true", enable_progress_bar=False,
                        enable_model_summary=False)
    trainer.predict(copy.deepcopy(trained[0]), dm, return_predictions=False)
    assert (writer.report.total, writer.report.new) == (3, 1)
    assert json.loads((out / RUN).read_text())["validation"] == "held"
    assert all("valid" in r for r in read_manifest(out).values())
    assert generate(ckpt, 3, out, seed=2, progress=False, jobs=1).new == 0  # and back
    with pytest.raises(RobovaeError, match="validation differ"):
        generate(ckpt, 4, out, seed=2, validate=False, progress=False, jobs=1)


def test_predict_refuses_an_untrained_model(tmp_path):
    """``robovae predict`` without ``--ckpt_path`` sampled a model of random weights and no
    fitted normaliser: 3 "robots", all degenerate, exit 0 (until 2026-11-29). Refused, and no
    output folder is left."""
    dm = RobotDataModule(["zoo"], root=str(tmp_path / "cache"), predict_samples=3)
    writer = RobotWriter(str(tmp_path / "pred"), validate=False)
    trainer = L.Trainer(accelerator="cpu", devices=1, logger=False, callbacks=[writer],
                        enable_progress_bar=False, enable_model_summary=False)
    with pytest.raises(RobovaeError, match="the model to sample from is untrained"):
        trainer.predict(RoboVAE(hidden_dim=16, latent_dim=8), dm, return_predictions=False)
    assert not (tmp_path / "pred").exists()


def test_cli_generate(trained, tmp_path, capsys):
    _, _, ckpt = trained
    assert main(["generate", "--ckpt", str(ckpt), "-n", "3", "--out", str(tmp_path / "g"),
                 "--jobs", "1"]) == 0
    out = capsys.readouterr().out
    assert "3 robots" in out and "validity" in out


def test_a_second_run_into_a_folder_being_written_is_refused(trained, tmp_path, capsys):
    """Two ``robovae generate`` runs given one ``--out`` both made every robot and appended
    every record twice (measured: 60 robots, 120 manifest lines, until 2026-11-29); the second
    is now refused in one line while the first holds the folder, and writes nothing."""
    from robovae.files import LOCK, FolderLock

    _, _, ckpt = trained
    out = tmp_path / "g"
    with FolderLock(out, "robots"):  # the first run, still writing
        assert main(["generate", "--ckpt", str(ckpt), "-n", "2", "--out", str(out),
                     "--jobs", "1"]) == 2
        err = capsys.readouterr().err
        assert "another run is writing there" in err and err.count("\n") == 1
        assert sorted(p.name for p in out.iterdir()) == [LOCK]
    generate(ckpt, 2, out, validate=False, progress=False, jobs=1)  # once it has ended
    assert not (out / LOCK).exists() and sorted(read_manifest(out)) == [0, 1]


def test_cli_generate_bad_checkpoint_is_one_line(tmp_path, capsys):
    bad = tmp_path / "x.ckpt"
    bad.write_bytes(b"not a checkpoint")
    assert main(["generate", "--ckpt", str(bad), "-n", "1", "--out", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"robovae: {bad}") and "\n" not in err


@pytest.mark.parametrize("n", ["-5", "0"])
def test_cli_generate_n_must_be_a_positive_integer(trained, n, tmp_path, capsys):
    _, _, ckpt = trained
    code = main(["generate", "--ckpt", str(ckpt), "-n", n, "--out", str(tmp_path / "g")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "-n" in err and "\n" not in err
    assert not (tmp_path / "g").exists()  # nothing written


def test_cli_generate_n_not_an_integer_is_a_one_line_usage_error(trained, tmp_path, capsys):
    _, _, ckpt = trained
    code = main(["generate", "--ckpt", str(ckpt), "-n", "2.5", "--out", str(tmp_path / "g")])
    assert code == 2 and not (tmp_path / "g").exists()
    assert capsys.readouterr().err == ("robovae generate: argument -n: invalid int value: '2.5' "
                                       "(robovae generate --help lists the options)\n")


def test_generate_batch_size_and_jobs_are_checked(trained, tmp_path):
    _, _, ckpt = trained
    for kw in ({"batch_size": 0}, {"batch_size": 2.0}, {"jobs": -1}):
        with pytest.raises(RobovaeError, match="must be an integer of at least"):
            generate(ckpt, 3, tmp_path / "g", progress=False, **kw)
    assert not (tmp_path / "g").exists()


def test_generate_n_must_be_a_positive_integer(trained, tmp_path):
    _, _, ckpt = trained
    for n in (-5, 0, 1.0, True):
        with pytest.raises(RobovaeError, match="-n must be an integer of at least 1"):
            generate(ckpt, n, tmp_path / "g", progress=False)
    with pytest.raises(RobovaeError, match="--seed must be an integer in"):
        generate(ckpt, 3, tmp_path / "g", progress=False, seed=-1)
    for r in (-1, 1.5):
        with pytest.raises(RobovaeError, match="redraws"):
            generate(ckpt, 3, tmp_path / "g", progress=False, redraws=r)
    assert not (tmp_path / "g").exists()


def test_unfinished_trees_are_redrawn_and_reported(trained, tmp_path):
    """The small model runs away to its node limit from most latents: with redraws those
    robots draw new latents (rule redraw_unfinished, the draw in the record)."""
    _, _, ckpt = trained
    kw = dict(jobs=1, progress=False, validate=False, quality=False, scene=False)
    generate(ckpt, 10, tmp_path / "none", redraws=0, **kw)
    generate(ckpt, 10, tmp_path / "some", redraws=3, **kw)
    none, some = read_manifest(tmp_path / "none"), read_manifest(tmp_path / "some")
    assert all(r["draw"] == 0 and "redraw_unfinished" not in r["rules"] for r in none.values())
    moved = [i for i, r in some.items() if r["draw"] > 0]
    assert moved and all("redraw_unfinished" in some[i]["rules"] for i in moved)
    assert all(some[i]["latent"] != none[i]["latent"] for i in moved)
    kept = [i for i in some if i not in moved]
    assert all(some[i]["latent"] == none[i]["latent"] for i in kept)
    assert json.loads((tmp_path / "some" / RUN).read_text())["redraws"] == 3


def test_cli_generate_self_collision(trained, tmp_path, capsys):
    """--self-collision: every robot geom collides with the others, the run says so, and a
    folder of robots that do not collide with themselves is not continued with it."""
    import mujoco

    _, _, ckpt = trained
    out, plain = tmp_path / "sc", tmp_path / "plain"

    def args(folder):
        return ["generate", "--ckpt", str(ckpt), "-n", "3", "--out", str(folder), "--jobs", "1",
                "--no-quality"]

    assert main([*args(out), "--self-collision"]) == 0
    assert json.loads((out / RUN).read_text())["self_collision"] is True
    records = read_manifest(out).values()
    assert any(r["valid"] for r in records)  # the tiny model also decodes rigid bodies
    for rec in records:
        assert rec["reason"] != "self_penetration", rec
        model = mujoco.MjModel.from_xml_path(str(out / rec["path"]))
        assert (model.geom_conaffinity[model.geom_bodyid != 0] == 1).all()
    assert main(args(plain)) == 0
    assert "self_collision" not in json.loads((plain / RUN).read_text())
    capsys.readouterr()
    assert main([*args(plain), "--self-collision"]) == 2
    assert "self_collision differ" in capsys.readouterr().err


def test_cli_generate_unwritable_out_is_one_line(trained, tmp_path, capsys):
    """An --out below a file cannot be created (chmod does not stop root: a file as parent)."""
    _, _, ckpt = trained
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    for out in (blocker / "g", blocker):
        assert main(["generate", "--ckpt", str(ckpt), "-n", "2", "--out", str(out),
                     "--jobs", "1"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"robovae: {out}: cannot write") and "\n" not in err
    assert blocker.read_text() == "not a folder"


def test_a_folder_of_another_run_is_refused_unless_overwrite(trained, tmp_path):
    _, _, ckpt = trained
    out = tmp_path / "gen"
    generate(ckpt, 3, out, seed=0, validate=False, progress=False)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(RobovaeError, match="seed differ"):
        generate(ckpt, 3, out, seed=1, validate=False, progress=False)
    assert sorted(read_manifest(out)) == [0, 1, 2]  # nothing lost
    report = generate(ckpt, 2, out, seed=1, validate=False, progress=False, overwrite=True)
    assert report.new == 2 and sorted(p.name for p in out.glob("robot_*")) == [
        "robot_000000", "robot_000001"]
    assert (out / "notes.txt").read_text() == "mine"
    assert json.loads((out / RUN).read_text())["seed"] == 1


def test_a_damaged_run_record_or_manifest_line_is_no_traceback(trained, tmp_path):
    """A ``run.json`` cut short is refused in one line (a JSONDecodeError until 2026-11-29)
    and replaced with ``overwrite``; a manifest line that is JSON but no record (a
    TypeError) is skipped like a torn line: its robot is made again, the same."""
    _, _, ckpt = trained
    out = tmp_path / "gen"
    generate(ckpt, 3, out, seed=0, validate=False, progress=False)
    whole = (out / RUN).read_text()
    (out / RUN).write_text(whole[:30])
    with pytest.raises(RobovaeError, match="run.json: not a generation run's record") as e:
        generate(ckpt, 3, out, seed=0, validate=False, progress=False)
    assert "\n" not in str(e.value) and (out / RUN).read_text() == whole[:30]
    generate(ckpt, 3, out, seed=0, validate=False, progress=False, overwrite=True)
    assert (out / RUN).read_text() == whole
    files = _files(out)
    lines = (out / MANIFEST).read_text().splitlines()
    (out / MANIFEST).write_text("\n".join(["[1]", '{"index": "x"}', *lines[1:]]) + "\n")
    assert sorted(read_manifest(out)) == [1, 2]
    report = generate(ckpt, 3, out, seed=0, validate=False, progress=False)
    assert report.new == 1 and _files(out) == files


def test_a_folder_written_by_another_writer_is_refused_unless_overwrite(trained, tmp_path):
    """Robots written before a writer change are not resumed as if they were this writer's
    (training is deterministic: the README main job re-run after an upgrade meets the same
    checkpoint in the same folder)."""
    _, _, ckpt = trained
    out = tmp_path / "gen"
    generate(ckpt, 3, out, seed=0, validate=False, progress=False)
    run = json.loads((out / RUN).read_text())
    assert run["writer"] == WRITER
    del run["writer"]  # as a robovae of before this field wrote it
    (out / RUN).write_text(json.dumps(run))
    with pytest.raises(RobovaeError, match="writer differ"):
        generate(ckpt, 3, out, seed=0, validate=False, progress=False)
    assert sorted(read_manifest(out)) == [0, 1, 2]  # nothing lost
    report = generate(ckpt, 3, out, seed=0, validate=False, progress=False, overwrite=True)
    assert report.new == 3
    assert json.loads((out / RUN).read_text())["writer"] == WRITER


def test_the_validation_is_part_of_the_run(trained, tmp_path):
    """Held validation (the default) is recorded in run.json: a folder validated one way is not
    resumed the other way; zero controls remain available."""
    _, _, ckpt = trained
    held = generate(ckpt, 3, tmp_path / "held", jobs=1, progress=False, quality=False)
    assert json.loads((tmp_path / "held" / RUN).read_text())["validation"] == "held"
    with pytest.raises(RobovaeError, match="validation differ"):
        generate(ckpt, 3, tmp_path / "held", jobs=1, progress=False, controls="zero")
    zero = generate(ckpt, 3, tmp_path / "zero", jobs=1, progress=False, quality=False,
                    controls="zero")
    assert "validation" not in json.loads((tmp_path / "zero" / RUN).read_text())
    assert _files(tmp_path / "held") == _files(tmp_path / "zero")  # the same robots
    assert set(held.reasons) | set(zero.reasons) <= set(REASONS)


@pytest.mark.timeout(180)
def test_worker_processes_give_the_same_robots(trained, tmp_path):
    """Writing and validating in spawned workers (a forked worker can deadlock in torch)."""
    _, _, ckpt = trained
    threads = torch.get_num_threads()
    one = generate(ckpt, 6, tmp_path / "one", jobs=1, progress=False)
    # two batches: the second is decoded while the workers build the first
    two = generate(ckpt, 6, tmp_path / "two", jobs=2, progress=False, batch_size=4)
    assert torch.get_num_threads() == threads  # decoding used one thread, then restored
    assert _files(tmp_path / "one") == _files(tmp_path / "two")
    assert one.reasons == two.reasons
    strip = lambda r: {k: v for k, v in r.items() if k != "detail"}  # noqa: E731
    assert [strip(r) for r in read_manifest(tmp_path / "one").values()] == \
        [strip(r) for _, r in sorted(read_manifest(tmp_path / "two").items())]


def test_warm_workers_start_at_once_and_drop_queued_robots_on_an_error():
    """generate()'s worker pool starts its workers before the model loads, and an error (a
    refused folder, Ctrl-C) cancels the robots still queued instead of waiting for them."""
    import time

    from robovae.generate import pipeline

    with pytest.raises(KeyboardInterrupt), pipeline.worker_pool(2, warm=True) as pool:
        assert len(pool._processes) == pool.workers  # started warm, before any work item
        workers = list(pool._processes.values())
        manager = pool._executor_manager_thread
        queued = [pool.submit(time.sleep, 0.2) for _ in range(30)]
        raise KeyboardInterrupt
    deadline = time.monotonic() + 10  # the pool's manager thread cancels them
    while not all(f.done() for f in queued) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert sum(f.cancelled() for f in queued) >= 20
    # The workers are ended (WorkerPool.terminate). The manager thread reaps them:
    # joining them here as well would race it for waitpid and misread them as alive.
    manager.join(timeout=60)
    assert not manager.is_alive()
    assert not any(w.is_alive() for w in workers)


def test_predict_writer_ends_its_workers_on_an_exception(tmp_path):
    """``robovae predict`` interrupted: the writer's validation workers stop at once."""
    import time
    from concurrent.futures.process import BrokenProcessPool

    from robovae.generate import pipeline

    writer = RobotWriter(str(tmp_path / "pred"), validate=True)
    pool = writer._pool = pipeline.worker_pool(1, warm=True)
    busy = pool.submit(time.sleep, 120)
    while not busy.running():  # sent to the worker (else it is only cancelled)
        time.sleep(0.01)
    writer.on_exception(None, None, KeyboardInterrupt())
    assert writer._pool is None
    with pytest.raises(BrokenProcessPool):
        busy.result(timeout=20)


def test_no_worker_starts_for_a_refused_or_finished_run(trained, tmp_path):
    """Workers start only once the run is accepted and has robots to make: a refused
    checkpoint or folder, or a finished folder, returns without processes left importing."""
    import multiprocessing

    _, _, ckpt = trained
    before = set(multiprocessing.active_children())  # another test's pool may still be ending
    bad = tmp_path / "x.ckpt"
    bad.write_bytes(b"not a checkpoint")
    out = tmp_path / "gen"
    with pytest.raises(RobovaeError):
        generate(bad, 2, out, jobs=2, progress=False)
    generate(ckpt, 2, out, seed=0, jobs=2, validate=False, progress=False)
    with pytest.raises(RobovaeError, match="seed differ"):
        generate(ckpt, 2, out, seed=1, jobs=2, validate=False, progress=False)
    assert generate(ckpt, 2, out, seed=0, jobs=2, validate=False, progress=False).new == 0
    assert set(multiprocessing.active_children()) - before == set()
