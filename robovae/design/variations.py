"""Variations of a robot and paths between two robots, from the latent space.

**Variations** (``robovae generate --like ROBOT.xml --radius R -n N``, :func:`generate_like`):
the robot file is encoded to its latent mean ``mu`` and its nodes' latent means ``w_1 … w_m``
(pre-order). Variation ``i`` decodes

    z_i = mu + R · B y_i,    y_i uniform in the unit ball of R^k,

``B = U_k diag(lambda_k)^{1/2}`` the basis of the sampling prior's principal subspace that
holds the share ``variance`` (0.95) of its variance
(:meth:`~robovae.model.sampling.PriorSampling.prior_directions`; ``robovae optimize``
searches such a space). So ``R`` is a
distance in the prior's standard deviations, along the directions the prior varies in: the
prior's own draws lie ``sqrt(k)`` from its mean in these units, root mean square
(:func:`prior_spread`), and the nearly collapsed latent directions, which the decoder hardly
reads, take none of the radius. The tree and its node types come from ``z`` alone
(:mod:`robovae.model.decoder`); every node the variation shares with the robot (at the same
place, reached from the root by the same child ranks, and of the same type,
:func:`~robovae.data.tree_arrays.shared_nodes`) keeps the robot's node latent, the other nodes
take their conditional prior mean, as sampled robots do at node temperature 0
(:mod:`robovae.model.node_transfer`). ``R = 0`` gives the robot's reconstruction ``n`` times.
``y_i`` comes from a generator seeded by ``(seed, i)``, so a variation does not depend on
``n`` or on which variations were already written; a variation whose decoding does not finish
its tree (the decoder's node or depth limit: a chain cut off) draws ``y_i`` again from
``(seed, i, 2, k)``, up to ``redraws`` times, as ``robovae generate`` redraws a prior sample
(``draw`` in its record). The output folder has the layout of
``robovae generate`` (``robot_<i>/robot.xml``, ``manifest.jsonl`` with ``latent``, ``like``
and ``radius`` per robot, ``summary.json``) and resumes the same way. The report adds what the
radius bought (:func:`like_metrics`): against the robot's reconstruction, the share of
variations that keep its topology and limb count, the mean node-count change and the median
mass factor, beside the prior's own scale :func:`prior_spread`.

**Paths** (``robovae interpolate A.xml B.xml --steps K --out DIR``, :func:`interpolate_files`):
:func:`robovae.generate.interpolate.interpolate` decodes ``K`` evenly spaced points of the line
between the two robots' latent means, writes ``step_<k>/robot.xml``, validates each in MuJoCo,
and a contact sheet ``sheet.png`` (one tile per step, labelled with ``t`` and the validity; at
most :data:`SHEET_STEPS` tiles, evenly spaced, for longer paths) and ``path.json`` are added.
The folder is built next to ``DIR`` and renamed into place when complete: a failure leaves no
partial ``DIR``.

Bad input is refused with one line before anything is written: a file that is not a robot
(:class:`~robovae.errors.RobotFileError`), ``R < 0``, ``n < 1``, ``K < 2``, a checkpoint that is
not one, an ``--out`` that holds something else, or one another run is writing (a lock file
``.<name>.robovae.lock`` beside it, :class:`~robovae.files.FolderLock`)
(:class:`~robovae.errors.RobovaeError`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch_geometric.data import Batch

from robovae.data.graph import RobotData
from robovae.data.mjcf import mjcf_to_graph
from robovae.errors import RobovaeError
from robovae.files import FolderLock, writable
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
from robovae.model.node_transfer import EncodedRobot, decode_near
from robovae.model.prior import latent_rng, redraw_unfinished
from robovae.model.vae import RoboVAE
from robovae.options import check_interpolate, check_like

__all__ = ["ball_offsets", "draw_variations", "encode_file", "generate_like",
           "interpolate_files", "like_metrics", "prior_spread", "reconstruction_record",
           "variation_latents"]

#: Share of the sampling prior's variance that the variations' subspace holds (every direction
#: the prior varies in; ``robovae optimize`` searches a narrower one by default, 0.9).
LIKE_VARIANCE = 0.95


def ball_offsets(rng: np.random.Generator, count: int, dim: int, radius: float) -> np.ndarray:
    """``count`` points drawn uniformly from the ``dim``-ball of ``radius`` around 0
    (``[count, dim]``): a Gaussian direction normalised, times ``radius · U^(1/dim)``."""
    if dim == 0 or count == 0:
        return np.zeros((count, dim))
    u = rng.standard_normal((count, dim))
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    return u * (radius * rng.random((count, 1)) ** (1.0 / dim))


@torch.no_grad()
def encode_file(model: RoboVAE, path: str | os.PathLike) -> EncodedRobot:
    """The robot file encoded by ``model`` (:class:`~robovae.model.node_transfer.EncodedRobot`:
    latent mean, node latent means, tree).

    Raises:
        RobotFileError: the file is not a robot (one line).
    """
    graph = mjcf_to_graph(path, model.feature_set)
    mu, nodes = model.encode_nodes(Batch.from_data_list([graph]))
    return EncodedRobot(mu[0], nodes[0], (graph.parent, graph.node_type))


def _check_out(out: Path) -> None:
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RobovaeError(f"robovae: {out}: exists and is not empty; choose another --out")


#: Variations decoded, written and added to the manifest at a time (memory; a killed run
#: resumes after its last whole batch).
LIKE_BATCH = 256


def generate_like(model: RoboVAE | str | Path, robot: str | os.PathLike, radius: float, n: int,
                  out: str | os.PathLike, seed: int = 0, validate: bool = True, jobs: int = 0,
                  scene: bool = True, overwrite: bool = False, floating: bool = True,
                  variance: float = LIKE_VARIANCE, redraws: int = 4, mirror: bool = True,
                  stance: bool = True, quality: bool = True, controls: str = "held",
                  self_collision: bool = False) -> GenerationReport:
    """Write ``n`` variations of ``robot`` within ``radius`` prior standard deviations in the
    prior's principal subspace holding ``variance`` of its variance (module docstring).
    ``mirror``, ``stance``, ``quality``, ``controls`` and ``self_collision`` as in
    :func:`robovae.generate.pipeline.generate` (mirrored limbs, the stance rules, the quality
    measures, the validation's simulation, bodies that collide with each other).

    Raises:
        RobovaeError: ``radius < 0``, ``n < 1``, ``redraws`` or ``jobs`` negative,
            ``variance`` outside ``(0, 1]``, a bad checkpoint, another run writing into ``out``
            (:class:`~robovae.files.FolderLock`), or
            ``out`` holds robots of another run (unless ``overwrite``). RobotFileError:
            ``robot`` is not a robot.
    """
    check_like(radius, n, redraws, seed, variance, jobs)
    start = time.perf_counter()
    model = own_model(model)  # decoded in float64: never the caller's object
    encoded = encode_file(model, robot)  # refuses a bad file before anything is written
    out = Path(out)
    digest = hashlib.sha256(Path(robot).read_bytes()).hexdigest()
    run = {"model": model_fingerprint(model), "like": digest, "radius": radius,
           "radius_space": f"prior standard deviations, principal subspace {variance:g}",
           "seed": seed, "redraws": redraws, "floating": floating, "writer": WRITER}
    # the settings that change the files, recorded when not the defaults (older folders resume)
    run.update({k: v for k, v, default in (
        ("mirror", mirror, True), ("stance", stance, True),
        ("self_collision", self_collision, False),
        ("validation", controls if validate else "held", "held")) if v != default})
    with FolderLock(out, "robots"):  # as robovae generate: one run writes there at a time
        claim(out, run, overwrite)
        model = model.to(torch.float64)  # as robovae generate: a robot never depends on its batch
        encoded = encoded._replace(mu=encoded.mu.double(), nodes=encoded.nodes.double())
        basis = model.prior_directions(variance)[1]
        todo = [i for i in range(n) if i not in read_manifest(out)]
        jobs = jobs or (os.cpu_count() or 1)
        write = {"validate": validate, "jobs": jobs, "scene": scene, "floating": floating,
                 "mirror": mirror, "stance": stance, "quality": quality, "controls": controls,
                 "self_collision": self_collision}
        with worker_pool(jobs, warm=True) if jobs > 1 and len(todo) >= 4 else nullcontext() as pool:
            for k in range(0, len(todo), LIKE_BATCH):
                _like_batch(model, todo[k:k + LIKE_BATCH], encoded, basis, robot, radius, out,
                            seed, redraws, pool, **write)
        reference = reconstruction_record(model, encoded, floating)
        spread = prior_spread(model, variance)
        return summarize(model, out, n, len(todo), validate, time.perf_counter() - start,
                         extra=lambda records: {"like": like_metrics(records, reference, radius,
                                                                     spread)})


def prior_spread(model: RoboVAE, variance: float = LIKE_VARIANCE) -> float:
    """Root-mean-square distance of the sampling prior's draws from its mean in the units of
    ``--radius``: ``sqrt(k)``, ``k`` the dimension of the principal subspace holding
    ``variance`` of the prior's variance (whitened, each draw's coordinates have unit
    variance): the scale a radius compares to."""
    return math.sqrt(model.prior_directions(variance)[1].shape[1])


def variation_latents(encoded: EncodedRobot, basis: np.ndarray, radius: float, seed: int,
                      indices: Sequence[int], draw: int = 0) -> torch.Tensor:
    """``z_i = mu + R · B y_i`` of variations ``indices`` ``[len, latent_dim]``, ``y_i``
    uniform in the unit ``k``-ball from variation ``i``'s generator, draw ``draw``
    (:func:`~robovae.model.prior.latent_rng`: seeded by ``(seed, i)``, a redraw ``k`` by
    ``(seed, i, 2, k)``)."""
    offsets = [basis @ ball_offsets(latent_rng(seed, int(i), draw), 1, basis.shape[1],
                                    radius)[0] for i in indices]
    return encoded.mu + torch.from_numpy(np.stack(offsets)).to(encoded.mu)


def draw_variations(model: RoboVAE, encoded: EncodedRobot, basis: np.ndarray, radius: float,
                    seed: int, indices: Sequence[int], redraws: int = 4
                    ) -> tuple[torch.Tensor, list, list[int]]:
    """``(z, graphs, draws)`` of variations ``indices``: each decoded near the robot
    (:func:`~robovae.model.node_transfer.decode_near`); one whose decoding did not finish its
    tree (:func:`~robovae.model.prior.unfinished`) draws its ``y`` again, up to ``redraws``
    times, as ``robovae generate`` redraws a prior sample (``draws``: the draw kept per
    variation; the last is kept even if unfinished)."""
    z = variation_latents(encoded, basis, radius, seed, indices)

    def redraw(rows: list[int], k: int) -> tuple[torch.Tensor, list]:
        zk = variation_latents(encoded, basis, radius, seed, [indices[b] for b in rows], k)
        return zk, decode_near(model, zk, [encoded])

    return redraw_unfinished(model, z, decode_near(model, z, [encoded]), redraw, redraws)


@torch.no_grad()
def reconstruction_record(model: RoboVAE, encoded: EncodedRobot, floating: bool = True) -> dict:
    """The manifest record (descriptors only: nothing is written) of the robot decoded from
    its latent mean as a variation of radius 0 is."""
    z = encoded.mu[None]
    records, _ = prepare_records(model, [0], z, decode_near(model, z, [encoded]), Path("."),
                                 validate=False, floating=floating)
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


def _like_batch(model: RoboVAE, chunk: list[int], encoded: EncodedRobot, basis: np.ndarray,
                robot: str | os.PathLike, radius: float, out: Path, seed: int, redraws: int,
                pool: Executor | None, **write: Any) -> None:
    """Decode, write and log variations ``chunk`` (:func:`generate_like`; ``write``: the
    keyword arguments of :func:`~robovae.generate.pipeline.write_records`)."""
    z, graphs, draws = draw_variations(model, encoded, basis, radius, seed, chunk, redraws)
    records = write_records(model, chunk, z, graphs, out, seed=seed, pool=pool, draws=draws,
                            **write)
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
                      sheet: bool = True, self_collision: bool = False) -> dict:
    """Interpolate between two robot files and write the path (module docstring); with
    ``self_collision`` the steps' bodies collide with each other but for the pairs in contact
    at rest (:mod:`robovae.data.self_collision`).

    Returns:
        the ``path.json`` content: ``a``, ``b`` (and ``self_collision: true`` when set), and
        per step ``t``, ``path``, ``valid``, ``reason``; plus ``sheet`` (PNG path or None).

    Raises:
        RobovaeError: ``steps < 2``, a bad checkpoint, ``out`` not empty, written by another
            run, or its folder not writable. RobotFileError: ``a`` or ``b`` is not a robot.
    """
    check_interpolate(steps)
    out = Path(out)
    _check_out(out)
    writable(out.parent, "the path")
    with FolderLock(out, "the path", beside=True):  # a second run into out is refused
        _check_out(out)  # again: a run that ended as this one started filled it
        model = own_model(model)  # decoded in float64: never the caller's object
        ga, gb = mjcf_to_graph(a, model.feature_set), mjcf_to_graph(b, model.feature_set)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
        try:
            result = {"a": str(a), "b": str(b),
                      **({"self_collision": True} if self_collision else {}),
                      **_write_path(model, ga, gb, steps, tmp, validate, sheet,
                                    self_collision)}
            if result["sheet"]:
                result["sheet"] = str(out / "sheet.png")
            (tmp / "path.json").write_text(json.dumps(result, indent=1))
            if out.exists():
                out.rmdir()  # empty (checked above)
            os.replace(tmp, out)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    return result


def _write_path(model: RoboVAE, a: RobotData, b: RobotData, steps: int, folder: Path,
                validate: bool, sheet: bool, self_collision: bool = False
                ) -> dict[str, Any]:
    """Write the path's steps and, with ``sheet``, its contact sheet into ``folder``; returns
    the ``path.json`` content without its ends (``steps``, ``sheet``)."""
    from robovae.evaluate.render import contact_sheet
    from robovae.generate.interpolate import interpolate

    rows: list[dict[str, Any]] = []
    for s in interpolate(model, a, b, steps=steps, out=folder, validate=validate,
                         self_collision=self_collision):
        assert s.path is not None  # written: interpolate was given a folder
        rows.append({"t": round(s.t, 6), "path": str(s.path.relative_to(folder)),
                     "valid": s.validation.valid if s.validation else None,
                     "reason": s.validation.reason if s.validation else None})
    result: dict[str, Any] = {"steps": rows, "sheet": None}
    if sheet:
        drawn = [rows[k] for k in sheet_steps(steps)]
        labels = [f"t = {s['t']:.2f}" + (f"  {s['reason']}" if s["reason"] else "")
                  for s in drawn]
        result["sheet"] = contact_sheet([folder / s["path"] for s in drawn],
                                        folder / "sheet.png", columns=min(len(drawn), 6),
                                        labels=labels)
    return result
