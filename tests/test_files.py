"""Atomic writes (robovae.files): the old file or the new one, never half of one."""

from __future__ import annotations

import os

import pytest

from robovae import files
from robovae.errors import RobovaeError
from robovae.files import atomic_write, robot_files


@pytest.mark.parametrize("durable", [True, False])
def test_atomic_write_replaces_the_file_and_leaves_no_temporary(tmp_path, durable):
    path = tmp_path / "log.json"
    assert atomic_write(path, "first", durable) == path
    atomic_write(str(path), "second é", durable)
    assert path.read_text(encoding="utf-8") == "second é"
    assert [p.name for p in tmp_path.iterdir()] == ["log.json"]


def test_a_failed_write_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "summary.json"
    atomic_write(path, "old")

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(files.os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        atomic_write(path, "new")
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_a_stale_temporary_of_this_pid_is_not_touched(tmp_path):
    stale = tmp_path / f".robot.xml.{os.getpid()}.tmp"
    stale.write_text("stale")
    atomic_write(tmp_path / "robot.xml", "<mujoco/>")
    assert stale.read_text() == "stale"
    assert (tmp_path / "robot.xml").read_text() == "<mujoco/>"


def test_files_get_the_mode_of_an_ordinary_open(tmp_path):
    """Robot files and reports are for others to read too: ``0o666`` less the umask, as
    ``open`` gives, not a temporary file's private 0600."""
    atomic_write(tmp_path / "robot.xml", "<mujoco/>")
    (tmp_path / "plain.xml").write_text("<mujoco/>")
    mode = lambda name: (tmp_path / name).stat().st_mode & 0o777  # noqa: E731
    assert mode("robot.xml") == mode("plain.xml")


def test_atomic_json_writes_the_document(tmp_path):
    from robovae.files import atomic_json

    path = atomic_json(tmp_path / "summary.json", {"valid": 1.0, "reasons": ["valid"]}, False)
    assert path.read_text() == '{\n "valid": 1.0,\n "reasons": [\n  "valid"\n ]\n}'


def test_robot_files_from_files_and_folders(tmp_path):
    """A robot's folder gives its robot.xml (not its scene.xml), a generate folder its
    robot_*/robot.xml, an optimize run's best/<method> its rank_*/robot.xml, any other folder
    its *.xml; a missing path is one line."""
    for folder in ("gen/robot_000001", "gen/robot_000000", "best/cma/rank_0", "best/cma/rank_1"):
        (tmp_path / folder).mkdir(parents=True)
        for name in ("robot.xml", "scene.xml"):
            (tmp_path / folder / name).write_text("<mujoco/>")
    (tmp_path / "loose").mkdir()
    for name in ("b.xml", "a.xml"):
        (tmp_path / "loose" / name).write_text("<mujoco/>")
    found = robot_files([tmp_path / "gen/robot_000001", tmp_path / "gen", tmp_path / "best/cma",
                         tmp_path / "loose", tmp_path / "loose/b.xml"])
    assert [str(p.relative_to(tmp_path)) for p in found] == [
        "gen/robot_000001/robot.xml", "gen/robot_000000/robot.xml", "gen/robot_000001/robot.xml",
        "best/cma/rank_0/robot.xml", "best/cma/rank_1/robot.xml", "loose/a.xml", "loose/b.xml",
        "loose/b.xml"]
    with pytest.raises(RobovaeError, match=r"nope: no such file or folder$"):
        robot_files([tmp_path / "nope"])


def test_a_folder_lock_refuses_a_second_holder_and_is_gone_after(tmp_path):
    """Two locks on one folder (two runs given one ``--out``): the second is refused in one line
    naming the folder and the first's process; released, the lock file is removed and the
    folder can be locked again."""
    out = tmp_path / "runs" / "out"
    with files.FolderLock(out, "robots") as lock:
        assert out.is_dir() and lock.path.read_text().strip() == str(os.getpid())
        with pytest.raises(RobovaeError) as e:
            files.FolderLock(out).acquire()
        message = str(e.value)
        assert "\n" not in message and str(out) in message
        assert f"another run is writing there (process {os.getpid()}" in message
    assert not (out / files.LOCK).exists()
    files.FolderLock(out).acquire().release()
    (tmp_path / "file").write_text("keep")
    with pytest.raises(RobovaeError, match="cannot write robots there"):
        files.FolderLock(tmp_path / "file" / "out", "robots").acquire()
    assert (tmp_path / "file").read_text() == "keep"


def test_a_lock_beside_the_folder_leaves_the_folder_unmade(tmp_path):
    """``beside``: the lock file is ``.<name>.robovae.lock`` next to ``out``, which stays absent
    (an output renamed into place whole, as ``robovae interpolate``'s); a second holder is
    refused naming that file."""
    out = tmp_path / "runs" / "path"
    with files.FolderLock(out, "the path", beside=True) as lock:
        assert lock.path == tmp_path / "runs" / f".path{files.LOCK}" and lock.path.is_file()
        assert not out.exists()
        with pytest.raises(RobovaeError, match=rf"path: another run is writing there "
                                               rf"\(process {os.getpid()}, \.path\.robovae"):
            files.FolderLock(out, beside=True).acquire()
        files.FolderLock(out).acquire().release()  # a lock inside out is another lock
    assert not lock.path.exists()


def test_a_killed_holder_leaves_no_lock(tmp_path):
    """A run killed outright leaves its lock file but not the lock (the kernel drops a dead
    process's ``flock``): the next run takes the folder."""
    import signal
    import subprocess
    import sys

    code = ("import sys, time\nfrom robovae.files import FolderLock\n"
            "FolderLock(sys.argv[1]).acquire()\nprint('held', flush=True)\ntime.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        with pytest.raises(RobovaeError, match=f"process {proc.pid}"):
            files.FolderLock(tmp_path).acquire()
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert (tmp_path / files.LOCK).exists()  # stale file, no lock
    with files.FolderLock(tmp_path) as lock:
        assert lock.path.read_text().strip() == str(os.getpid())


def test_a_file_system_without_locks_runs_unguarded_with_a_warning(tmp_path, monkeypatch):
    """Some network mounts refuse ``flock`` (ENOLCK): the run goes on, said once, unguarded."""
    import errno

    def no_locks(fd, op):
        raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    monkeypatch.setattr(files.fcntl, "flock", no_locks)
    with pytest.warns(UserWarning, match="no file locks on this file system"), \
            files.FolderLock(tmp_path / "o") as lock:
        assert (tmp_path / "o").is_dir() and not lock.path.exists()


def test_atomic_write_keeps_the_old_file_when_the_disk_is_full(tmp_path):
    """Bytes are written as they are; a write that fails (here past ``RLIMIT_FSIZE``, as on a
    full disk) raises an ``OSError`` naming the file, which keeps its old content, and leaves no
    temporary file."""
    import errno

    from tests.conftest import oserror_past_size_limit

    path = tmp_path / "blob.bin"
    files.atomic_write(path, b"old\x00")
    assert path.read_bytes() == b"old\x00"
    code = "from robovae.files import atomic_write\natomic_write(sys.argv[1], bytes(200_000))"
    assert oserror_past_size_limit(code, path, 100_000) == [str(errno.EFBIG), str(path)]
    assert path.read_bytes() == b"old\x00" and [p.name for p in tmp_path.iterdir()] == [path.name]
