"""Shared fixtures: paths to the workspace's Menagerie copy and small datasets."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path
from typing import Any

import lightning as L
import numpy as np
import pytest
import torch

from robovae.data.datamodule import RobotDataModule
from robovae.data.features import get_feature_set
from robovae.data.graph import RobotData, tree_data
from robovae.model.vae import RoboVAE

REPO = Path(__file__).resolve().parents[1]
SHARED_MENAGERIE = Path(os.environ.get("ROBOVAE_SHARED_MENAGERIE",
                                       REPO.parent / "shared" / "menagerie"))
CORPUS = REPO / "tests" / "data" / "corpus"

#: the libraries a light code path must not import (seconds each)
HEAVY = ("torch", "torch_geometric", "lightning")

os.environ.setdefault("MUJOCO_GL", "egl")
if os.environ.get("PYTEST_XDIST_WORKER"):  # two test processes on two cores: one thread each
    torch.set_num_threads(1)


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


def in_fresh_python(code: str) -> tuple[Any, list[str], str]:
    """Run ``code``, which sets ``result`` (JSON-ready), in a new interpreter; returns
    ``result``, the modules of :data:`HEAVY` it imported, and its stderr."""
    script = (f"{code}\nimport json as _json, sys as _sys\n"
              f"print(_json.dumps([result, [m for m in {HEAVY!r} if m in _sys.modules]]))\n")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True)
    result, loaded = json.loads(run.stdout.strip().splitlines()[-1])
    return result, loaded, run.stderr


def with_file_size_limit(limit: int) -> Any:
    """A ``preexec_fn`` for ``subprocess``: files the child writes cannot grow past ``limit``
    bytes (``RLIMIT_FSIZE``; a write past it fails with ``EFBIG``, as a full disk fails one
    with ``ENOSPC``), and ``SIGXFSZ``, which would kill the child, is ignored."""
    import resource
    import signal

    def limit_files() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE,
                           (limit, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
    return limit_files


def oserror_past_size_limit(code: str, path: Path, limit: int) -> list[str]:
    """Run ``code`` (lines that write ``sys.argv[1]``, which is ``path``) in a new interpreter
    whose files cannot grow past ``limit`` bytes (:func:`with_file_size_limit`); returns the
    errno and file name of the ``OSError`` it raised (empty when it raised none)."""
    body = "".join(f"    {line}\n" for line in code.splitlines())
    script = f"import sys\ntry:\n{body}except OSError as e:\n    print(e.errno, e.filename)\n"
    run = subprocess.run([sys.executable, "-c", script, str(path)], capture_output=True,
                         text=True, preexec_fn=with_file_size_limit(limit), check=True)
    return run.stdout.split()


def random_parent(n: int, rng: random.Random, pop: float = 0.5) -> list[int]:
    """A random pre-order parent vector: ``pop=0`` gives a chain, ``pop=1`` a star."""
    parent, stack = [-1], [0]
    for i in range(1, n):
        while len(stack) > 1 and rng.random() < pop:
            stack.pop()
        parent.append(stack[-1])
        stack.append(i)
    return parent


def random_shape(n: int, rng: random.Random, pop: float = 0.5, fs: str = "full") -> RobotData:
    """A tree of :func:`random_parent`'s shape, random node types (``rng``) and standard
    normal features (torch's global generator): the model tests' trees."""
    f = get_feature_set(fs)
    types = [rng.randrange(f.num_node_types) for _ in range(n)]
    return tree_data(random_parent(n, rng, pop), types, torch.randn(n, f.dim), f)


def random_tree(rng: np.random.Generator, fs_name: str, n: int) -> RobotData:
    """A random pre-order tree with random node types and garbage features (randn·10, NaN, Inf)."""
    fs = get_feature_set(fs_name)
    parent, path = [-1], [0]
    for i in range(1, n):
        path = path[: int(rng.integers(0, len(path))) + 1]
        parent.append(path[-1])
        path.append(i)
    p = [0.5, 0.4, 0.1] if fs.num_node_types == 3 else [0.5, 0.5]
    types = rng.choice(fs.num_node_types, n, p=p) if rng.random() < 0.7 \
        else rng.integers(0, fs.num_node_types, n)
    gen = torch.Generator().manual_seed(int(rng.integers(2**31)))
    x = torch.randn(n, fs.dim, generator=gen) * 10
    x[torch.rand(n, fs.dim, generator=gen) < 0.05] = float("nan")
    x[torch.rand(n, fs.dim, generator=gen) < 0.02] = float("inf")
    return tree_data(parent, types.tolist(), x, fs)


def _train_small(tmp, **model_kw):
    L.seed_everything(0)
    dm = RobotDataModule(["zoo"], root=str(tmp / "cache"),
                         test_names=["gym_half_cheetah", "gym_hopper"], batch_size=8)
    model = RoboVAE(hidden_dim=32, latent_dim=8, max_nodes=64, **model_kw)
    trainer = L.Trainer(max_epochs=2, accelerator="cpu", devices=1, logger=False,
                        enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, default_root_dir=tmp,
                        limit_train_batches=2)
    trainer.fit(model, dm)
    ckpt = tmp / "model.ckpt"
    trainer.save_checkpoint(ckpt)
    return model.eval(), dm, ckpt


@pytest.fixture(scope="session")
def trained(tmp_path_factory):
    """A small model trained a few epochs on the zoo, with its datamodule and checkpoint."""
    return _train_small(tmp_path_factory.mktemp("zoo"))


@pytest.fixture(scope="session")
def trained_nodes(tmp_path_factory):
    """The same with 6-wide node latents."""
    return _train_small(tmp_path_factory.mktemp("zoo_nodes"), node_latent_dim=6)
