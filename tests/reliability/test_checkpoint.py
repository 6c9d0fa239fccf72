"""Safe checkpoints: a checkpoint carrying a pickled payload is refused everywhere robovae reads
checkpoints — ``load_model``, ``robovae generate``, ``robovae fit|validate|test|predict
--ckpt_path`` (a file or ``last``) — with one line, and the payload never runs.

The payload is harmless but detectable: unpickling it runs ``touch <marker>``. The last test
proves it is live (a plain ``torch.load(weights_only=False)`` does create the marker).
"""

from __future__ import annotations

import os
import pickle
import shlex
from pathlib import Path

import lightning as L
import pytest
import torch

from robovae.cli import main
from robovae.errors import RobovaeError
from robovae.model.checkpoint import load_model, read_checkpoint
from tests.conftest import REPO

TINY = str(REPO / "configs" / "tiny.yaml")


class Payload:
    """Unpickling this runs ``touch <marker>`` (through ``os.system``)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {shlex.quote(str(self.marker))}",))


@pytest.fixture
def planted(trained, tmp_path) -> tuple[Path, Path]:
    """A real checkpoint (the trained model) with a payload among its hyperparameters."""
    _, _, ckpt = trained
    marker = tmp_path / "PAYLOAD_RAN"
    data = torch.load(ckpt, weights_only=True)
    data["hyper_parameters"]["note"] = Payload(marker)
    path = tmp_path / "planted.ckpt"
    torch.save(data, path)
    return path, marker


def _one_line(err: str) -> str:
    err = err.strip()
    assert err and "\n" not in err and "Traceback" not in err, err
    return err


def test_load_model_refuses_a_planted_checkpoint(planted):
    path, marker = planted
    for load in (load_model, read_checkpoint):
        with pytest.raises(RobovaeError) as e:
            load(path)
        msg = _one_line(str(e.value))
        assert msg.startswith(f"robovae: {path}: refused to load checkpoint")
        assert "pickled object" in msg and "system" in msg  # names the offending global
        assert not marker.exists()


def test_broken_checkpoints_are_one_line(trained, tmp_path):
    _, _, ckpt = trained
    torn = tmp_path / "torn.ckpt"
    torn.write_bytes(ckpt.read_bytes()[:2000])  # a copy interrupted mid-write
    text = tmp_path / "text.ckpt"
    text.write_text("hello")
    listing = tmp_path / "list.ckpt"
    torch.save([1, 2], listing)
    for path, what in [(torn, "not a checkpoint"), (text, "not a checkpoint"),
                       (listing, "not a Lightning checkpoint"),
                       (tmp_path / "missing.ckpt", "no such checkpoint")]:
        with pytest.raises(RobovaeError, match=what) as e:
            load_model(path)
        _one_line(str(e.value))
    assert "state_dict" in read_checkpoint(ckpt)  # a real checkpoint passes


def test_cli_generate_refuses_a_planted_checkpoint(planted, tmp_path, capsys):
    path, marker = planted
    out = tmp_path / "gen"
    assert main(["generate", "--ckpt", str(path), "-n", "2", "--out", str(out)]) == 2
    err = _one_line(capsys.readouterr().err)
    assert err.startswith(f"robovae: {path}: refused to load checkpoint")
    assert not marker.exists() and not list(out.glob("robot_*"))


@pytest.mark.parametrize("command", ["fit", "validate", "test", "predict"])
def test_lightning_cli_refuses_a_planted_ckpt_path(planted, tmp_path, capsys, monkeypatch,
                                                   command):
    path, marker = planted
    monkeypatch.chdir(tmp_path)
    # even where torch.load would otherwise unpickle everything (its own weights_only default)
    monkeypatch.setenv("TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD", "1")
    code = main([command, "--config", TINY, f"--data.root={tmp_path / 'cache'}",
                 "--trainer.logger=false", f"--ckpt_path={path}"])
    assert code == 2
    err = _one_line(capsys.readouterr().err)
    assert err.startswith(f"robovae: {path}: refused to load checkpoint")
    assert not marker.exists()


def test_lightning_cli_refuses_a_planted_last_checkpoint(planted, tmp_path, capsys,
                                                         monkeypatch):
    """``--ckpt_path last`` is resolved by Lightning's trainer, which reads the file itself: the
    CLI makes that read ``weights_only=True`` and turns the refusal into one line."""
    path, marker = planted
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD", "1")
    ckpt_dir = tmp_path / "ckpt"
    ckpt_dir.mkdir()
    (ckpt_dir / "last.ckpt").write_bytes(path.read_bytes())
    code = main(["fit", "--config", TINY, f"--data.root={tmp_path / 'cache'}",
                 "--trainer.logger=false", f"--checkpoint.dirpath={ckpt_dir}",
                 "--ckpt_path", "last"])
    assert code == 2
    err = capsys.readouterr().err  # after the dataset's progress bar: one line, no traceback
    assert "Traceback" not in err and err.endswith("\n")
    assert err.splitlines()[-1].startswith(
        f"robovae: {ckpt_dir / 'last.ckpt'}: refused to load checkpoint (it holds a pickled "
        "object")
    assert not marker.exists()


def test_a_torn_last_checkpoint_is_one_line(trained, tmp_path, capsys, monkeypatch):
    """A ``last.ckpt`` cut short (a run killed while writing it) given as ``--ckpt_path last``,
    which Lightning resolves and reads itself: one line naming the file (until 2026-11-29
    ``torch.load``'s traceback, ``OSError: [Errno 22] Invalid argument``)."""
    monkeypatch.chdir(tmp_path)
    ckpt_dir = tmp_path / "ckpt"
    ckpt_dir.mkdir()
    (ckpt_dir / "last.ckpt").write_bytes(Path(trained[2]).read_bytes()[:65536])
    code = main(["fit", "--config", TINY, f"--data.root={tmp_path / 'cache'}",
                 "--trainer.logger=false", f"--checkpoint.dirpath={ckpt_dir}",
                 "--ckpt_path", "last"])
    assert code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.splitlines()[-1] == (f"robovae: {ckpt_dir / 'last.ckpt'}: not a checkpoint (not a "
                                    "zip archive: another kind of file, or one cut short)")


def test_checkpoints_are_written_whole(trained, tmp_path):
    """``AtomicCheckpointIO`` writes Lightning's bytes, and a write that fails (a full disk;
    here ``RLIMIT_FSIZE``) names the file and leaves the checkpoint that was there whole: no
    torn ``last.ckpt`` for ``--ckpt_path last`` to fail on."""
    import errno

    from lightning.pytorch.plugins.io import TorchCheckpointIO

    from robovae.model.checkpoint_io import AtomicCheckpointIO
    from tests.conftest import oserror_past_size_limit

    ckpt = torch.load(trained[2], weights_only=True)
    ours, theirs = tmp_path / "ours.ckpt", tmp_path / "theirs.ckpt"
    AtomicCheckpointIO().save_checkpoint(ckpt, ours)
    TorchCheckpointIO().save_checkpoint(ckpt, theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    small = tmp_path / "last.ckpt"
    AtomicCheckpointIO().save_checkpoint({"epoch": 1}, small)
    before = small.read_bytes()
    code = ("import torch\nfrom robovae.model.checkpoint_io import AtomicCheckpointIO\n"
            "AtomicCheckpointIO().save_checkpoint({'w': torch.zeros(100_000)}, sys.argv[1])")
    assert oserror_past_size_limit(code, small, 100_000) == [str(errno.EFBIG), str(small)]
    assert small.read_bytes() == before
    assert AtomicCheckpointIO().load_checkpoint(small) == {"epoch": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["last.ckpt", "ours.ckpt",
                                                          "theirs.ckpt"]


def test_fit_on_a_full_disk_is_one_line(tmp_path):
    """``robovae fit`` whose checkpoint cannot be written (the disk full; here the checkpoint
    grows past ``RLIMIT_FSIZE``, the dataset cache does not): exit status 1, one line naming
    the checkpoint file, no torn file left (until 2026-11-29 Lightning's traceback, naming
    fsspec's temporary file in the system's temporary folder)."""
    import subprocess
    import sys

    from tests.conftest import with_file_size_limit

    folder = tmp_path / "ckpt"
    run = subprocess.run([sys.executable, "-m", "robovae.cli", "fit", "--config", TINY,
                          f"--data.root={tmp_path / 'cache'}", "--trainer.logger=false",
                          "--trainer.max_epochs=1", f"--checkpoint.dirpath={folder}"],
                         capture_output=True, text=True, cwd=tmp_path,
                         preexec_fn=with_file_size_limit(200_000))
    assert run.returncode == 1, run.stderr[-2000:]
    assert "Traceback" not in run.stderr
    assert run.stderr.splitlines()[-1] == (
        f"robovae: {folder / 'epoch=0-step=3.ckpt'}: cannot write there (File too large); what "
        "was written whole is kept")
    assert list(folder.iterdir()) == []


def test_lightning_trainer_default_is_weights_only(trained, planted, tmp_path):
    """Lightning 2.6 passes ``weights_only=None`` to ``torch.load``, whose default (torch >= 2.6)
    is ``True``: the trainer alone refuses the payload too (unless that default is overridden
    by ``TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD``, which the CLI guards against, see above)."""
    model, dm, _ = trained
    path, marker = planted
    trainer = L.Trainer(accelerator="cpu", devices=1, logger=False, enable_progress_bar=False,
                        enable_model_summary=False, default_root_dir=tmp_path)
    with pytest.raises(pickle.UnpicklingError):
        trainer.test(model, dm, ckpt_path=path, verbose=False)
    assert not marker.exists()


def test_the_payload_is_live(planted):
    """Control: without ``weights_only`` the planted file does run its payload."""
    path, marker = planted
    torch.load(path, weights_only=False)
    assert marker.exists()
