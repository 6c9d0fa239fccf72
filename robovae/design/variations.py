"""Variations of a robot and paths between two robots, from the latent space.

**Variations** (``robovae generate --like ROBOT.xml --radius R -n N``, :func:`generate_like`):
the robot file is encoded to its latent mean ``mu`` (and, for a model with node latents, its
nodes' latent means ``w_1 … w_m`` in pre-order). Variation ``i`` decodes

    z_i = mu + R · r_i · u_i,    u_i uniform on the unit sphere,  r_i = U_i^(1/d)

a point drawn uniformly from the ball of radius ``R`` around ``mu`` in the ``d``-dimensional
latent space, and with node latents ``w_{i,t} = w_t + R · r_{i,t} · u_{i,t}`` drawn the same way
around each node's mean (ball of radius ``R`` in the node-latent space). ``R = 0`` gives the
robot's reconstruction ``n`` times. Draws come from a generator seeded by ``(seed, i)``, so a
variation does not depend on ``n`` or on which variations were already written. The output
folder has the layout of ``robovae generate`` (``robot_<i>/robot.xml``, ``manifest.jsonl`` with
``latent``, ``like`` and ``radius`` per robot, ``summary.json``) and resumes the same way. The
report adds what the radius bought (:func:`like_metrics`): against the robot's reconstruction,
the share of variations that keep its topology and limb count, the mean node-count change and
the median mass factor, beside the prior's own scale :func:`prior_spread`.

**Paths** (``robovae interpolate A.xml B.xml --steps K --out DIR``, :func:`interpolate_files`):
:func:`robovae.generate.interpolate.interpolate` decodes ``K`` evenly spaced points of the line
between the two robots' latent means, writes ``step_<k>/robot.xml``, validates each in MuJoCo,
and a contact sheet ``sheet.png`` (one tile per step, labelled with ``t`` and the validity; at
most :data:`SHEET_STEPS` tiles, evenly spaced, for longer paths) and ``path.json`` are added.
The folder is built next to ``DIR`` and renamed into place when complete: a failure leaves no
partial ``DIR``.

Bad input is refused with one line before anything is written: a file that is not a robot
(:class:`~robovae.errors.RobotFileError`), ``R < 0``, ``n < 1``, ``K < 2``, a checkpoint that is
not one, or an ``--out`` that holds something else (:class:`~robovae.errors.RobovaeError`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import tempfile
import time
from concurrent.futures import Executor
from contextlib import nullcontext
from pathlib import Path

import numpy as np
import torch
from torch_geometric.data import Batch

from robovae.data.mjcf import mjcf_to_graph
from robovae.errors import RobovaeError
from robovae.generate.pipeline import (
    MANIFEST,
    GenerationReport,
    append_records,
    claim,
    model_fingerprint,
    open_manifest,
    prepare_records,
    read_manifest,
    summarize,
    worker_pool,
    write_records,
)
from robovae.generate.writer import WRITER
from robovae.model.checkpoint import own_model
from robovae.model.vae import RoboVAE

__all__ = ["ball_offsets", "encode_file", "generate_like", "interpolate_files", "like_metrics",
           "prior_spread", "reconstruction_record"]


def ball_offsets(rng: np.random.Generator, count: int, dim: int, radius: float) -> np.ndarray:
    """``count`` points drawn uniformly from the ``dim``-ball of ``radius`` around 0
    (``[count, dim]``): a Gaussian direction normalised, times ``radius · U^(1/dim)``."""
    if dim == 0 or count == 0:
        return np.zeros((count, dim))
    u = rng.standard_normal((count, dim))
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    return u * (radius * rng.random((count, 1)) ** (1.0 / dim))


@torch.no_grad()
def encode_file(model: RoboVAE, path: str | os.PathLike) -> tuple[torch.Tensor, torch.Tensor]:
    """``(mu, w)``: the robot file's latent mean ``[latent_dim]`` and its nodes' latent means
    ``[n_nodes, node_latent_dim]`` (0 columns without node latents).

    Raises:
        RobotFileError: the file is not a robot (one line).
    """
    graph = mjcf_to_graph(path, model.feature_set)
    mu, nodes = model.encode_nodes(Batch.from_data_list([graph]))
    return mu[0], nodes[0]


def _check_out(out: Path) -> None:
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RobovaeError(f"robovae: {out}: exists and is not empty; choose another --out")


#: Variations decoded, written and added to the manifest at a time (memory; a killed run
#: resumes after its last whole batch).
LIKE_BATCH = 256


def generate_like(model: RoboVAE | str | Path, robot: str | os.PathLike, radius: float, n: int,
                  out: str | os.PathLike, seed: int = 0, validate: bool = True, jobs: int = 0,
                  scene: bool = True, overwrite: bool = False,
                  floating: bool = True) -> GenerationReport:
    """Write ``n`` variations of ``robot`` within latent ``radius`` (module docstring).

    Raises:
        RobovaeError: ``radius < 0`` or ``n < 1``, a bad checkpoint, or ``out`` holds robots of
            another run (unless ``overwrite``). RobotFileError: ``robot`` is not a robot.
    """
    if not (math.isfinite(radius) and radius >= 0):
        raise RobovaeError(f"robovae: --radius must be a finite number >= 0, got {radius}")
    if n < 1:
        raise RobovaeError(f"robovae: -n must be >= 1, got {n}")
    start = time.perf_counter()
    model = own_model(model)  # decoded in float64: never the caller's object
    mu, w = encode_file(model, robot)  # refuses a bad file before anything is written
    out = Path(out)
    digest = hashlib.sha256(Path(robot).read_bytes()).hexdigest()
    claim(out, {"model": model_fingerprint(model), "like": digest, "radius": radius,
                "seed": seed, "floating": floating, "writer": WRITER}, overwrite)
    model = model.to(torch.float64)  # as robovae generate: a robot never depends on its batch
    mu, w = mu.to(torch.float64), w.to(torch.float64)
    todo = [i for i in range(n) if i not in read_manifest(out)]
    jobs = jobs or (os.cpu_count() or 1)
    with worker_pool(jobs, warm=True) if jobs > 1 and len(todo) >= 4 else nullcontext() as pool:
        for k in range(0, len(todo), LIKE_BATCH):
            _like_batch(model, todo[k:k + LIKE_BATCH], mu, w, robot, radius, out, seed,
                        validate, jobs, scene, floating, pool)
    reference = reconstruction_record(model, mu, w, floating)
    return summarize(model, out, n, len(todo), validate, time.perf_counter() - start,
                     extra=lambda records: {"like": like_metrics(records, reference, radius,
                                                                 prior_spread(model))})


def prior_spread(model: RoboVAE) -> float:
    """Root-mean-square distance of the sampling prior's draws from its mean,
    ``sqrt(tr C)`` (the fitted mixture's covariance :meth:`~robovae.model.latent_mixture.
    LatentMixture.moments`; ``sqrt(d)`` for ``N(0, I)``): the scale a ``--radius`` compares to."""
    mix = model.sampling_mixture()
    if mix is None:
        return math.sqrt(int(model.hparams.latent_dim))
    return math.sqrt(float(np.trace(mix.moments()[1])))


@torch.no_grad()
def reconstruction_record(model: RoboVAE, mu: torch.Tensor, w: torch.Tensor,
                          floating: bool = True) -> dict:
    """The manifest record (descriptors only: nothing is written) of the robot decoded from
    ``mu`` and node latents ``w`` as a variation of radius 0 is."""
    nodes = [w] if model.hparams.get("node_latent_dim") else None
    graphs = model.decode(mu[None], node_latents=nodes, clamp=nodes is None)
    records, _ = prepare_records(model, [0], mu[None], graphs, Path("."), validate=False,
                                 floating=floating)
    return records[0]


def like_metrics(records: list[dict], reference: dict, radius: float, spread: float) -> dict:
    """What a radius buys: over the variations' ``records``, the share that keep the
    reference's (the reconstruction's) topology and limb count, the mean ``|Δ nodes|``, and
    the median mass factor ``exp(median |ln(m / m_ref)|)``; with the reference's descriptors,
    ``radius`` and the prior's ``spread`` (:func:`prior_spread`)."""
    n = max(len(records), 1)
    masses = [abs(math.log(r["mass"] / reference["mass"])) for r in records
              if r["mass"] > 0 and reference["mass"] > 0]
    return {
        "radius": radius, "prior_spread": spread,
        "reconstruction": {k: reference[k] for k in ("topology", "nodes", "limbs", "mass")},
        "same_topology": sum(r["topology"] == reference["topology"] for r in records) / n,
        "same_limbs": sum(r["limbs"] == reference["limbs"] for r in records) / n,
        "nodes_changed": sum(abs(r["nodes"] - reference["nodes"]) for r in records) / n,
        "mass_factor": math.exp(float(np.median(masses))) if masses else float("nan"),
    }


def _like_batch(model: RoboVAE, chunk: list[int], mu: torch.Tensor, w: torch.Tensor,
                robot: str | os.PathLike, radius: float, out: Path, seed: int, validate: bool,
                jobs: int, scene: bool, floating: bool, pool: Executor | None) -> None:
    """Decode, write and log variations ``chunk`` (:func:`generate_like`)."""
    zs, ws = [], []
    for i in chunk:
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, i])))
        zs.append(mu + torch.from_numpy(ball_offsets(rng, 1, mu.numel(), radius)[0]))
        ws.append(w + torch.from_numpy(ball_offsets(rng, w.shape[0], w.shape[1], radius)))
    z = torch.stack(zs)
    nodes = ws if model.hparams.get("node_latent_dim") else None
    graphs = model.decode(z, node_latents=nodes, clamp=nodes is None)
    records = write_records(model, chunk, z, graphs, out, seed=seed, validate=validate,
                            jobs=jobs, scene=scene, floating=floating, pool=pool)
    for rec in records:
        rec.pop("temperature", None)
        rec.update(like=str(robot), radius=radius)
    with open_manifest(out / MANIFEST) as manifest:
        append_records(manifest, records)


#: Most steps drawn on an interpolation's contact sheet.
SHEET_STEPS = 48


def sheet_steps(steps: int) -> list[int]:
    """The steps a path's contact sheet shows: every one up to :data:`SHEET_STEPS`, else
    that many evenly spaced, both ends included."""
    return sorted({round(k) for k in np.linspace(0, steps - 1, min(steps, SHEET_STEPS))})


def interpolate_files(model: RoboVAE | str | Path, a: str | os.PathLike, b: str | os.PathLike,
                      steps: int, out: str | os.PathLike, validate: bool = True,
                      sheet: bool = True) -> dict:
    """Interpolate between two robot files and write the path (module docstring).

    Returns:
        the ``path.json`` content: ``a``, ``b``, and per step ``t``, ``path``, ``valid``,
        ``reason``; plus ``sheet`` (PNG path or None).

    Raises:
        RobovaeError: ``steps < 2``, a bad checkpoint, ``out`` not empty. RobotFileError: ``a``
            or ``b`` is not a robot.
    """
    from robovae.evaluate.render import contact_sheet
    from robovae.generate.interpolate import interpolate

    if steps < 2:
        raise RobovaeError(f"robovae: --steps must be >= 2 (the two ends), got {steps}")
    out = Path(out)
    _check_out(out)
    model = own_model(model)  # decoded in float64: never the caller's object
    ga, gb = mjcf_to_graph(a, model.feature_set), mjcf_to_graph(b, model.feature_set)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        path = interpolate(model, ga, gb, steps=steps, out=tmp, validate=validate)
        result = {"a": str(a), "b": str(b), "steps": [
            {"t": round(s.t, 6), "path": str(s.path.relative_to(tmp)),
             "valid": s.validation.valid if s.validation else None,
             "reason": s.validation.reason if s.validation else None} for s in path]}
        result["sheet"] = None
        if sheet:
            drawn = [result["steps"][k] for k in sheet_steps(steps)]
            labels = [f"t = {s['t']:.2f}" + (f"  {s['reason']}" if s["reason"] else "")
                      for s in drawn]
            contact_sheet([tmp / s["path"] for s in drawn], tmp / "sheet.png",
                          columns=min(len(drawn), 6), labels=labels)
            result["sheet"] = str(out / "sheet.png")
        (tmp / "path.json").write_text(json.dumps(result, indent=1))
        if out.exists():
            out.rmdir()  # empty (checked above)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return result
