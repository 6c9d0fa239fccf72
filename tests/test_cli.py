"""The robovae command's conventions: bad input is one line on stderr, exit status 2."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from robovae.cli import main
from robovae.data.zoo import zoo_files
from tests.conftest import in_fresh_python

BAD_XML = "<mujoco><worldbody><body></mujoco>"


@pytest.mark.parametrize("argv", [
    ["data", "--root", "{tmp}/cache"],
    ["generate", "--ckpt", "{tmp}/none.ckpt", "--out", "{tmp}/out"],
    ["optimize", "--ckpt", "{tmp}/none.ckpt", "--task", "walk", "--budget", "2",
     "--out", "{tmp}/out"],
    ["analyze", "--ckpt", "{tmp}/none.ckpt", "--root", "{tmp}/cache"],
])
def test_negative_jobs_is_a_one_line_error(argv, tmp_path, capsys) -> None:
    args = [a.format(tmp=tmp_path) for a in argv] + ["--jobs", "-3"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err == "robovae: --jobs must be 0 (all cores) or more, not -3\n"
    assert list(tmp_path.iterdir()) == []  # nothing written


def _render(tmp_path: Path, *robots: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run([sys.executable, "-m", "robovae.cli", "render", *map(str, robots),
                           "--out", str(tmp_path / "sheet.png")], env=env,
                          capture_output=True, text=True, timeout=300)


def test_render_names_a_bad_file_in_one_line(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text(BAD_XML)
    hopper = dict(zoo_files()[0])["gym_hopper"]
    got = _render(tmp_path, hopper, bad)
    assert got.returncode == 0, got.stderr[-2000:]
    lines = got.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"robovae: contact sheet tile 1 (bad) left grey: {bad}: "
                               "malformed XML (")
    assert (tmp_path / "sheet.png").is_file()
    (tmp_path / "sheet.png").unlink()
    got = _render(tmp_path, bad)  # no robot to draw: an error, no sheet
    assert got.returncode == 2
    lines = got.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"robovae: no robot drawn, nothing written to "
                               f"{tmp_path / 'sheet.png'} (tile 0 (bad) left grey: {bad}: "
                               "malformed XML (")
    assert not (tmp_path / "sheet.png").exists()


@pytest.mark.parametrize("argv, expect", [
    (["fitt"], "robovae: argument command: invalid choice: 'fitt'"),
    (["generate", "--ckpt", "x"], "robovae generate: the following arguments are required: --out"),
    (["fit", "--config", "{tmp}/none.yaml"],
     "robovae fit ({tmp}/none.yaml): Parser key \"config\": File does not exist"),
    (["fit", "--config", "{tmp}/bad.yaml"],
     "robovae fit ({tmp}/bad.yaml): Subcommand 'fit' does not accept option 'model.bogus'"),
    (["test", "--nosuchflag", "3"], "robovae test: unrecognized arguments: --nosuchflag 3"),
])
def test_usage_errors_are_one_line(argv, expect, tmp_path, capsys) -> None:
    (tmp_path / "bad.yaml").write_text("model: {bogus: 1}\n")
    assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(expect.format(tmp=tmp_path)) and err.count("\n") == 1
    assert err.rstrip().endswith("--help lists the options)")


@pytest.mark.parametrize("flag", ["--config", "-c", "--config="])
def test_a_config_that_is_not_text_is_one_line(flag, tmp_path, capsys) -> None:
    """A binary file given as a config was a UnicodeDecodeError traceback (exit 1)."""
    config = tmp_path / "bin.yaml"
    config.write_bytes(b"model:\xc6\x00\xff")
    argv = ["fit", f"--config={config}"] if flag.endswith("=") else ["fit", flag, str(config)]
    assert main(argv) == 2
    assert capsys.readouterr().err == (f"robovae fit ({config}): not a YAML config (not UTF-8 "
                                       "text, byte 6)\n")


@pytest.mark.parametrize("option", [["--first", "0"], ["--columns", "0"], ["--columns", "-1"]])
def test_render_counts_must_be_positive(option, tmp_path, capsys) -> None:
    hopper = dict(zoo_files()[0])["gym_hopper"]
    assert main(["render", str(hopper), "--out", str(tmp_path / "s.png"), *option]) == 2
    assert capsys.readouterr().err == (f"robovae: {option[0]} must be an integer of at least 1, "
                                       f"not {int(option[1])}\n")
    assert not (tmp_path / "s.png").exists()


def test_analyze_gait_search_is_checked_first(tmp_path, capsys) -> None:
    argv = ["analyze", "--ckpt", str(tmp_path / "none.ckpt"), "--samples", str(tmp_path),
            "--root", str(tmp_path / "cache"), "--gait-search", "grid"]
    assert main(argv) == 2
    assert capsys.readouterr().err == ("robovae: --gait-search must be one of random, cma, not "
                                       "'grid'\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option, value, least", [
    ("--max-samples", "0", 1), ("--max-samples", "-2", 1), ("--quality", "-1", 0),
    ("--behaviour", "-1", 0), ("--permutations", "-5", 0), ("--procedural", "-1", 0),
    ("--gait-rollouts", "0", 1),
])
def test_analyze_counts_are_checked_first(option, value, least, tmp_path, capsys) -> None:
    argv = ["analyze", "--ckpt", str(tmp_path / "none.ckpt"), "--samples", str(tmp_path),
            "--root", str(tmp_path / "cache"), option, value]
    assert main(argv) == 2
    assert capsys.readouterr().err == (f"robovae: {option} must be an integer of at least "
                                       f"{least}, not {value}\n")
    assert list(tmp_path.iterdir()) == []


def test_option_mistakes_are_refused_before_torch_is_imported(tmp_path) -> None:
    """A mistyped option of generate, generate --like, interpolate, optimize, analyze or gait
    is refused by robovae.options before the command imports torch, PyG and Lightning (5-9 s),
    and before anything is written."""
    robot = str(dict(zoo_files()[0])["gym_hopper"])
    ck, out = str(tmp_path / "none.ckpt"), str(tmp_path / "out")
    cases = [["generate", "--ckpt", ck, "-n", "-5", "--out", out],
             ["generate", "--ckpt", ck, "--like", robot, "--radius", "-1", "--out", out],
             ["interpolate", robot, robot, "--ckpt", ck, "--steps", "1", "--out", out],
             ["optimize", "--ckpt", ck, "--task", "fly", "--budget", "2", "--out", out],
             ["optimize", "--ckpt", ck, "--task", "walk", "--budget", "2", "--distinct", "-1",
              "--out", out],
             ["analyze", "--ckpt", ck, "--entropy-seconds", "0"],
             # a negative seed: tracebacks after a half-made folder before 2026-11-29
             ["generate", "--ckpt", ck, "-n", "2", "--seed", "-1", "--out", out],
             ["generate", "--ckpt", ck, "--like", robot, "--seed", "-1", "--out", out],
             ["optimize", "--ckpt", ck, "--task", "walk", "--budget", "2", "--seed", "-1",
              "--out", out],
             ["analyze", "--ckpt", ck, "--seed", "2147483648"],
             ["gait", robot, "--seed", "-1", "--out", out],
             # an allocation of 26 GB and a traceback before 2026-11-29
             ["interpolate", robot, robot, "--ckpt", ck, "--steps", "100000000", "--out", out],
             # minutes of analysis without the real robots asked for, before 2026-11-29
             ["analyze", "--ckpt", ck, "--real", str(tmp_path / "no_such_folder")]]
    codes, loaded, err = in_fresh_python("from robovae.cli import main\n"
                                         f"result = [main(argv) for argv in {cases!r}]")
    assert codes == [2] * len(cases) and loaded == []
    lines = err.strip().splitlines()
    assert len(lines) == len(cases) and all(line.startswith("robovae: ") for line in lines)
    assert "-n must be an integer of at least 1, not -5" in lines[0] and "--distinct" in lines[4]
    assert all("--seed must be an integer in [0, 2147483647]" in line for line in lines[6:11])
    assert "--steps must be an integer in [2, 10000]" in lines[11]
    assert "no_such_folder: no such folder of real robots (--real)" in lines[12]
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_ends_a_run_in_one_line(trained, tmp_path) -> None:
    """Ctrl-C (SIGINT to the command's process group, as a terminal sends it) in ``robovae
    generate`` with two workers: the run ends at once with exit status 130 and one line, the
    manifest holds whole records and the folder is free for the same command to go on. Until
    2026-11-29 Python's ``KeyboardInterrupt`` traceback of wherever the run was, the workers'
    tracebacks too, and in 2 runs of 20 a process that never ended (its worker queue's feeder
    thread, blocked on a pipe no worker read any more, joined at exit).

    Batches of 64 latents: the manifest is flushed a batch at a time, once the next batch is
    queued, so the first line waits for two batches decoded and one built (generate's 1,024
    make that a minute or more); at the interrupt the workers still have a batch's chunks
    queued, as in a run of 1,024."""
    import json
    import signal
    import time

    out = tmp_path / "gen"
    proc = subprocess.Popen(
        [sys.executable, "-m", "robovae.cli", "generate", "--ckpt", str(trained[2]), "-n",
         "100000", "--out", str(out), "--jobs", "2", "--no-quality", "--batch-size", "64"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: (signal.signal(signal.SIGINT, signal.SIG_DFL), os.setpgrp()))
    try:
        deadline = time.monotonic() + 120
        manifest = out / "manifest.jsonl"
        while not (manifest.is_file() and manifest.stat().st_size) and proc.poll() is None:
            assert time.monotonic() < deadline, "no robot written in 120 s"
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130, err[-2000:]
    assert "robovae: interrupted; the files written are whole" in err
    assert "KeyboardInterrupt" not in err
    records = [json.loads(line) for line in manifest.read_text().splitlines()]
    assert records and all((out / r["path"]).is_file() for r in records)
    assert not (out / ".robovae.lock").exists()


def test_an_interrupted_import_is_an_interrupt() -> None:
    """Ctrl-C inside an extension module's import surfaces as ``ImportError: initialization
    failed`` raised from it (MuJoCo's, seen): the CLI still reads it as Ctrl-C."""
    from robovae.exits import interrupted as _interrupted

    try:
        try:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as k:
                raise ImportError("initialization failed") from k
        except ImportError as i:
            raise ImportError("initialization failed") from i
    except ImportError as e:
        assert _interrupted(e)
    assert not _interrupted(ValueError("x")) and not _interrupted(None)
