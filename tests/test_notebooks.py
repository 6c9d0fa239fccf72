"""The notebooks run top to bottom with small settings (``ROBOVAE_FAST=1``).

``quickstart.ipynb`` gets no checkpoint, so it trains its own tiny model (the "no checkpoint"
path); ``latent_space.ipynb`` uses the session's small zoo model (the ``trained`` fixture),
``design.ipynb`` the one with node latents (``trained_nodes``).
Pictures and robots go to a temporary folder, never into the repository.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

REPO = Path(__file__).resolve().parents[1]
NOTEBOOKS = REPO / "notebooks"


def execute(name: str) -> tuple[object, float]:
    """Run a notebook in a fresh kernel (cwd: notebooks/); returns it and the seconds taken."""
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    start = time.perf_counter()
    client = nbclient.NotebookClient(nb, timeout=240, kernel_name="python3",
                                     resources={"metadata": {"path": str(NOTEBOOKS)}})
    client.execute()
    return nb, time.perf_counter() - start


def outputs(nb) -> str:
    return "\n".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                     for o in c.get("outputs", []) if o.get("output_type") == "stream")


@pytest.fixture
def notebook_env(monkeypatch, tmp_path, cache_root):
    monkeypatch.setenv("ROBOVAE_FAST", "1")
    monkeypatch.setenv("MUJOCO_GL", "egl")
    monkeypatch.setenv("ROBOVAE_OUT", str(tmp_path / "out"))
    monkeypatch.setenv("ROBOVAE_CACHE", str(cache_root / "notebooks"))
    return tmp_path


@pytest.mark.parametrize("name", ["quickstart.ipynb", "latent_space.ipynb", "design.ipynb"])
def test_notebook_is_committed_without_outputs(name):
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(not c.outputs and c.execution_count is None for c in code)


def test_quickstart_runs(notebook_env, monkeypatch):
    monkeypatch.setenv("ROBOVAE_CKPT", str(notebook_env / "missing.ckpt"))  # trains its own
    nb, seconds = execute("quickstart.ipynb")
    text = outputs(nb)
    assert "checkpoint" in text and "missing: will train" in text
    assert "ant: 22 nodes" in text and "RA " in text and "written:" in text
    assert (notebook_env / "out" / "quickstart_robot" / "robot.xml").is_file()
    assert seconds < 150, f"quickstart took {seconds:.0f} s"


def test_latent_space_runs(notebook_env, monkeypatch, trained):
    _, _, ckpt = trained
    monkeypatch.setenv("ROBOVAE_CKPT", str(ckpt))
    nb, seconds = execute("latent_space.ipynb")
    text = outputs(nb)
    assert "robots encoded" in text and "t = 1.00" in text and "nearest in latent" in text
    assert "MMD²" in text
    assert (notebook_env / "out" / "neighbours_of_gym_ant.png").is_file()
    assert (notebook_env / "out" / "nearest.png").is_file()
    assert seconds < 150, f"latent_space took {seconds:.0f} s"


def test_design_runs(notebook_env, monkeypatch, trained_nodes):
    _, _, ckpt = trained_nodes
    monkeypatch.setenv("ROBOVAE_CKPT", str(ckpt))
    nb, seconds = execute("design.ipynb")
    text = outputs(nb)
    assert "best step score" in text and "after 3 evaluations" in text
    assert "could not walk" in text
    # the best robot driven by its gait in Walk-v0 (or, if it scored 0, the one-line refusal)
    assert "its gait replayed in Walk-v0" in text or "no gait" in text
    out = notebook_env / "out"
    assert (out / "design_convergence.png").is_file() and (out / "design_best.png").is_file()
    assert json.loads((out / "design_step" / "log.json").read_text())["settings"]["task"] == "step"
    assert seconds < 150, f"design took {seconds:.0f} s"
