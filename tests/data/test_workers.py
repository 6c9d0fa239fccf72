"""Worker pools (robovae.data.workers): their workers end with their parent, and a block
ended by an exception cancels its queued work and ends its busy workers."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from concurrent.futures import wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import pytest

from robovae.data.workers import process_pool

PARENT = """
import os, time
from robovae.data.workers import process_pool

if __name__ == "__main__":
    pool = process_pool(1)
    print(pool.submit(os.getpid).result(), flush=True)
    pool.submit(time.sleep, 120)
    time.sleep(120)
"""


def _running(pid: int) -> bool:
    """The process exists and is not a zombie waiting to be reaped."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_pool_runs_work_in_other_processes():
    with process_pool(2) as pool:
        pids = {pool.submit(os.getpid).result() for _ in range(4)}
    assert os.getpid() not in pids and 1 <= len(pids) <= 2


def test_a_pool_has_at_most_one_process_per_core(monkeypatch):
    """``--jobs 1000`` started a thousand interpreters (each with its imports: hundreds of MB)
    on a machine of 2 cores, until 2026-11-29."""
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    with process_pool(64) as pool:
        pids = {f.result() for f in [pool.submit(os.getpid) for _ in range(32)]}
    assert pool.workers == 2 and len(pids) <= 2
    with process_pool(0) as pool:
        assert pool.workers == 1


def test_an_error_in_the_block_cancels_the_queued_work():
    """The with block waits for its work when it ends normally, and cancels what has not
    started when it ends with an exception (instead of running all of it first)."""
    with process_pool(1) as pool:
        done = [pool.submit(time.sleep, 0.01) for _ in range(5)]
    assert all(f.done() and not f.cancelled() for f in done)
    queued = []
    with pytest.raises(RuntimeError, match="stop"), process_pool(1) as pool:
        queued = [pool.submit(time.sleep, 0.5) for _ in range(20)]
        queued[0].result()
        raise RuntimeError("stop")
    wait(queued, timeout=5)  # the pool's manager thread cancels them
    assert all(f.done() for f in queued)
    ran = [f for f in queued if not f.cancelled() and f.exception() is None]
    assert len(ran) <= 3  # the first, and at most those already sent to the worker


def test_an_error_in_the_block_ends_the_busy_workers():
    """Work in hand is not waited for either: its worker is ended and its future fails."""
    with pytest.raises(RuntimeError, match="stop"), process_pool(1) as pool:
        worker = pool.submit(os.getpid).result()
        busy = pool.submit(time.sleep, 120)
        while not busy.running():
            time.sleep(0.01)
        raise RuntimeError("stop")
    with pytest.raises(BrokenProcessPool):
        busy.result(timeout=20)
    deadline = time.monotonic() + 20
    while _running(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _running(worker), "the busy worker outlived its interrupted pool"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_worker_ends_when_its_parent_is_killed(tmp_path, sig):
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(parent.stdout.readline())
        time.sleep(0.5)
        assert _running(worker)  # busy with its two-minute job while the parent lives
        parent.send_signal(sig)
        parent.wait(10)
        deadline = time.monotonic() + 20
        while _running(worker) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _running(worker), "the worker outlived its killed parent"
    finally:
        parent.kill()
        parent.wait()
