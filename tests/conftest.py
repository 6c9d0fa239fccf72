"""Shared fixtures: paths to the workspace's Menagerie copy and small datasets."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_MENAGERIE = Path(os.environ.get("ROBOVAE_SHARED_MENAGERIE",
                                       REPO.parent / "shared" / "menagerie"))
CORPUS = REPO / "tests" / "data" / "corpus"

os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture(scope="session")
def menagerie_dir() -> Path:
    """The 17 Menagerie robots of the paper (skips when the folder is absent)."""
    if not SHARED_MENAGERIE.is_dir():
        pytest.skip(f"{SHARED_MENAGERIE} not present")
    return SHARED_MENAGERIE


@pytest.fixture(scope="session")
def cache_root(tmp_path_factory) -> Path:
    """One dataset cache folder for the whole session."""
    return tmp_path_factory.mktemp("data_cache")
