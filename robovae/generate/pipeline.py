"""Generation at scale: sample latents → decode → write MJCF → validate → manifest.

``generate(ckpt, n, out)`` writes ``out/robot_<i>/robot.xml`` (+ ``scene.xml``) for robots
``i = 0 … n-1`` and appends one JSON line per robot to ``out/manifest.jsonl``. Robot ``i``'s
latent is drawn from its own generator seeded by ``(seed, i)``, so a robot does not depend on
batch size, on which robots were already done, or on the process that made it: re-running
skips the robots already in the manifest (resume after a crash), and the same checkpoint +
seed give byte-identical files. A folder of another run (``run.json``: model, seed, sampling
settings and the writer, :data:`~robovae.generate.writer.WRITER`) is refused unless
``overwrite``. Manifest lines are flushed and fsync'ed per batch; robot folders are complete
before their manifest line is written.

With worker processes the main process decodes batch ``k + 1`` while the workers write,
validate and measure batch ``k`` (the next batch is queued before the previous one is
collected, so the workers never wait for the decoder, nor the decoder for them); decoding then
uses one torch thread, the workers having the other cores. The workers start before the
first batch is decoded (each imports the writer, MuJoCo and the measures meanwhile), and an
error or Ctrl-C cancels the robots still queued for them.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Executor
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, TextIO

import torch

from robovae.data.graph import RobotData
from robovae.data.tree_arrays import TreeArrays
from robovae.data.workers import WorkerPool, process_pool
from robovae.errors import RobovaeError
from robovae.evaluate.quality.report import summarize as quality_summary
from robovae.evaluate.samples import robot_record, sample_metrics
from robovae.files import FolderLock, atomic_json, writable
from robovae.generate.build import build_robot, warm_up
from robovae.generate.fixes import decoded_fixes
from robovae.generate.writer import WRITER
from robovae.model.checkpoint import own_model
from robovae.model.prior import draw_robots, latent, node_noise  # noqa: F401  (re-exported)
from robovae.model.vae import PRIORS, RoboVAE
from robovae.options import BATCH_SIZE, check_generate

if TYPE_CHECKING:
    from tqdm.auto import tqdm

MANIFEST = "manifest.jsonl"
SUMMARY = "summary.json"
RUN = "run.json"


class HasStateDict(Protocol):
    """A model's weights and buffers by name (a ``torch.nn.Module``, or a view of one)."""

    def state_dict(self) -> Mapping[str, torch.Tensor]:
        """Tensors by name."""
        ...


def model_fingerprint(model: HasStateDict) -> str:
    """SHA-256 of the model's weights and buffers (names, dtypes, values)."""
    h = hashlib.sha256()
    for name, t in sorted(model.state_dict().items()):
        h.update(name.encode())
        h.update(str(t.dtype).encode())
        h.update(t.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def claim(out: Path, run: dict, overwrite: bool = False) -> None:
    """Make ``out`` a generation folder of ``run`` (model fingerprint, seed, temperature).

    A folder that holds robots of another run is refused with one line (resuming it would mix
    two models' robots), unless ``overwrite``: then robovae's own files (``robot_<i>/``,
    manifests, summary) are deleted first — nothing else in the folder is touched.
    """
    writable(out, "robots")
    path = out / RUN
    old = read_run(path) if path.is_file() else None
    has_robots = bool(read_manifest(out))
    if old == run or (old is None and not has_robots):
        if old is None:
            atomic_json(path, run, durable=False)
        return
    if not overwrite:
        if isinstance(old, str):
            raise RobovaeError(f"robovae: {path}: not a generation run's record ({old}); use "
                               "another --out or --overwrite")
        keys = list(run) + [k for k in (old or {}) if k not in run]
        what = ", ".join(k for k in keys if old is None or old.get(k) != run.get(k))
        raise RobovaeError(f"robovae: {out}: holds robots of another run ({what or 'unknown'} "
                           "differ); use another --out or --overwrite")
    for item in out.iterdir():
        if item.is_dir() and re.fullmatch(r"robot_\d{6}", item.name):
            shutil.rmtree(item)
        elif re.fullmatch(r"manifest.*\.jsonl|summary\.json|run\.json", item.name):
            item.unlink()
    atomic_json(path, run, durable=False)


def read_run(path: Path) -> dict | str:
    """A folder's ``run.json``, or why it is not one (damaged, or another program's)."""
    try:
        run = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        return str(e)
    return run if isinstance(run, dict) else "not a JSON object"


def read_manifest(out: Path) -> dict[int, dict]:
    """Manifest records by robot index; a line that is not a record (a torn last line from a
    crash, or damage) is ignored: its robot is made again."""
    records: dict[int, dict] = {}
    for path in sorted(out.glob("manifest*.jsonl")):  # manifest.jsonl + per-rank manifests
        for line in path.read_text(errors="replace").splitlines():
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue
            index = rec.get("index") if isinstance(rec, dict) else None
            if isinstance(index, int) and not isinstance(index, bool) and index >= 0:
                records[index] = rec
    return records


def open_manifest(path: Path) -> TextIO:
    """Open a manifest for appending; a torn last line (crash mid-write) is terminated first
    so that the next record starts on its own line."""
    f = path.open("a+")
    if f.tell() > 0:
        f.seek(f.tell() - 1)
        if f.read(1) != "\n":
            f.write("\n")
    return f


def _chunks(items: list[int], size: int) -> Iterator[list[int]]:
    for k in range(0, len(items), size):
        yield items[k:k + size]


@dataclass
class GenerationReport:
    """What a :func:`generate` run produced (all robots in the manifest, old and new)."""

    out: Path
    total: int
    new: int
    seconds: float
    reasons: dict[str, int] = field(default_factory=dict)
    rules: dict[str, int] = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready dictionary of the report."""
        return {"out": str(self.out), "total": self.total, "new": self.new,
                "seconds": self.seconds, "reasons": self.reasons, "rules": self.rules,
                "metrics": self.metrics}

    def format(self) -> str:
        """The report as printed by ``robovae generate``."""
        m = self.metrics
        lines = [f"{self.total} robots in {self.out} ({self.new} new, {self.seconds:.1f} s)"]
        if "validity" in m:
            lines.append(f"validity {m['validity']:.1%}  uniqueness {m['uniqueness']:.1%}  "
                         f"novelty {m['novelty']:.1%}  distinct topologies "
                         f"{m['distinct_topologies']} (training: {m['training_topologies']})")
        q = m.get("quality")
        if q and q["robots"]:
            lines.append(f"of {q['robots']} valid: all bodies attached {q['all_attached']:.1%}  "
                         f"symmetric {q['symmetric']:.1%}  one limb {q['one_limb']:.1%}  "
                         f"standing {q['standing']:.1%} (of {q['floating']} floating)")
        if "like" in m:
            lines.append(_like_line(m["like"]))
        lines.append("reasons: " + ", ".join(f"{k} {v}" for k, v in sorted(self.reasons.items())))
        if self.rules:
            lines.append("rules fired: " + ", ".join(f"{k} {v}" for k, v in
                                                     sorted(self.rules.items())))
        return "\n".join(lines)


def _like_line(like: dict) -> str:
    """The report's line on variations of one robot (``robovae generate --like``)."""
    return (f"variations at radius {like['radius']:g} (in the prior's standard deviations; "
            f"its draws lie {like['prior_spread']:.2f} from its mean, root mean square): "
            f"the reconstruction's topology kept by {like['same_topology']:.1%}, its limb count "
            f"by {like['same_limbs']:.1%}, nodes changed by {like['nodes_changed']:.1f} on "
            f"average, mass by a factor {like['mass_factor']:.2f} (median)")


def prior_name(model: RoboVAE) -> str:
    """The prior a model samples from, as ``run.json`` records it: ``mixture`` when it has a
    fitted mixture and samples from it, else ``standard``."""
    return "mixture" if model.sampling_mixture() is not None else "standard"


def run_record(model: RoboVAE, fingerprint: str, seed: int, temperature: float,
               node_temperature: float | None, redraws: int, *, floating: bool = True,
               mirror: bool = True, stance: bool = True, validation: str | None = "held",
               self_collision: bool = False) -> dict:
    """The ``run.json`` of a generation folder: what its robots depend on, so that a run is
    resumed only with the same model (``fingerprint``, :func:`model_fingerprint` of its float32
    weights), sampling, graph fixes, writer (:data:`~robovae.generate.writer.WRITER`) and
    validation. ``validation``: the validation's controls (``"held"``, ``"zero"``), ``None``:
    not validated. Keys added since the first folders are left out at their old value
    (``validation`` unless ``"held"``, ``self_collision`` unless true) so that those folders
    resume. ``generate`` and :class:`~robovae.generate.predict.RobotWriter` both build it here:
    either resumes the other's folder."""
    run = {"model": fingerprint, "seed": seed, "temperature": temperature,
           "feature_set": model.feature_set.name, "floating": floating, "mirror": mirror,
           "node_temperature": node_temperature, "redraws": redraws,
           "prior": prior_name(model), "stance": stance, "writer": WRITER}
    if validation is not None and validation != "zero":
        run["validation"] = validation
    if self_collision:
        run["self_collision"] = True
    return run


def generate(
    model: RoboVAE | str | Path,
    n: int,
    out: str | Path,
    seed: int = 0,
    temperature: float = 1.0,
    validate: bool = True,
    batch_size: int = BATCH_SIZE,
    jobs: int = 0,
    progress: bool = True,
    scene: bool = True,
    overwrite: bool = False,
    floating: bool = True,
    mirror: bool = True,
    node_temperature: float | None = None,
    quality: bool = True,
    controls: str = "held",
    redraws: int = 4,
    prior: str | None = None,
    stance: bool = True,
    self_collision: bool = False,
) -> GenerationReport:
    """Generate ``n`` robots into ``out`` (resumable; see the module docstring).

    Raises:
        RobovaeError: ``n`` is not a positive integer, a temperature is negative, ``out``
            cannot be written to, it holds robots of another run, or another run is writing
            there (:class:`~robovae.files.FolderLock`).

    ``out`` is tied to the model and settings that started it (``run.json``): resuming with
    another checkpoint, seed, temperature or validation is refused unless ``overwrite``.
    ``temperature`` scales the robot latent ``z``; ``node_temperature`` (default: the
    checkpoint's ``node_temperature``, else ``temperature``) the node latents' noise (the detail
    of each node). ``mirror``: near-mirror
    limb pairs become exact mirror images (:func:`~robovae.generate.symmetry.mirror_limbs`,
    reported as ``mirror_limbs``), a stray limb beside them gets its mirror image
    (:func:`~robovae.generate.symmetry.complete_pairs`, reported as ``complete_pairs``) and
    near-equal limbs on the sagittal plane become equal
    (:func:`~robovae.generate.symmetry.twin_limbs`, reported as ``twin_limbs``) and the
    near-mirror branches of a link below the trunk (a chest's arms) mirror images
    (:func:`~robovae.generate.symmetry.mirror_branches`, reported as ``mirror_branches``).
    ``quality``: measure every valid robot (attached, symmetric, standing;
    :func:`~robovae.evaluate.quality.measure.robot_quality`). ``controls``: the validation's
    simulation, ``"held"`` (the first second of the standing test) or ``"zero"``
    (:mod:`robovae.generate.validate`). ``redraws``: a robot whose decoding did not finish its
    tree (it reached the decoder's node or depth limit) redraws its ``z`` up to this many times
    (:func:`~robovae.model.prior.draw_robots`; rule ``redraw_unfinished``, ``draw`` in the
    record). ``prior``: ``mixture`` or ``standard`` (:data:`~robovae.model.vae.PRIORS`;
    default: the checkpoint's ``prior``); the prior actually used is recorded in ``run.json``.
    ``stance``: a free-floating robot's hanging wheels are lowered onto the floor, its soles
    laid flat, and a two-footed robot gets ankles strong enough for its soles and a balanced
    ``home`` keyframe (:mod:`robovae.generate.stance` and :mod:`robovae.generate.bipeds`;
    rules ``ground_wheels``, ``level_soles``, ``level_stilts``, ``strong_ankles``,
    ``balance_home``). ``self_collision``: the robot's bodies collide with each other, but for
    the pairs in contact at rest (:mod:`robovae.data.self_collision`; rule
    ``self_collision_excludes``). ``batch_size``: latents decoded at once, and the robots per
    manifest flush (:data:`~robovae.options.BATCH_SIZE`).
    """
    if prior is not None and prior not in PRIORS:
        raise RobovaeError(f"robovae: --prior must be one of {', '.join(PRIORS)}, got {prior!r}")
    check_generate(n, temperature, node_temperature, batch_size, jobs, redraws, seed)
    start = time.perf_counter()
    model = own_model(model)
    if prior is not None:
        model.hparams.prior = prior
    if node_temperature is None:  # the checkpoint's setting, recorded as such
        node_temperature = model.hparams.get("node_temperature")
    out = Path(out)
    run = run_record(model, model_fingerprint(model), seed, temperature, node_temperature,
                     redraws, floating=floating, mirror=mirror, stance=stance,
                     validation=controls if validate else None, self_collision=self_collision)
    with FolderLock(out, "robots"):  # a second run into out is refused while this one writes
        claim(out, run, overwrite)
        # float64 decoding: batched float32 matmuls differ in the last bits with the batch size, and
        # a robot must not depend on which robots it was decoded with (byte-identical files)
        model = model.to(torch.float64)
        done = read_manifest(out)
        todo = [i for i in range(n) if i not in done]
        from tqdm.auto import tqdm

        bar = tqdm(total=n, initial=n - len(todo), desc="robots", unit="robot",
                   disable=not progress)
        jobs = jobs or (os.cpu_count() or 1)
        threads = torch.get_num_threads()
        prepare = partial(prepare_records, seed=seed, temperature=temperature, validate=validate,
                          scene=scene, floating=floating, mirror=mirror, quality=quality,
                          controls=controls, stance=stance, self_collision=self_collision)
        try:
            if jobs > 1:
                torch.set_num_threads(1)  # the workers have the other cores
            # the workers start before the first batch is decoded (each imports the writer, MuJoCo
            # and the measures meanwhile), after the refusals above and only with robots to make;
            # an error or Ctrl-C cancels the robots queued for them (WorkerPool)
            with open_manifest(out / MANIFEST) as manifest, \
                    (worker_pool(jobs, warm=True) if jobs > 1 and todo else nullcontext()) as pool:
                queued = None  # the batch the workers are on: its records and their results
                for chunk in _chunks(todo, batch_size):
                    z, graphs, draws = draw_robots(model, seed, chunk, temperature,
                                                   node_temperature, redraws)
                    records, items = prepare(model, chunk, z, graphs, out, draws=draws)
                    built = pool.map(build_robot, items, chunksize=4) if pool is not None \
                        else [build_robot(item) for item in items]
                    if queued is not None:  # collected only once the next batch is queued
                        _finish(manifest, *queued, bar)
                    queued = records, built
                if queued is not None:
                    _finish(manifest, *queued, bar)
        finally:
            torch.set_num_threads(threads)
            bar.close()  # on Ctrl-C too: its last line before the run's last word
        return summarize(model, out, n, len(todo), validate, time.perf_counter() - start)


def _finish(manifest: TextIO, records: list[dict], built: Iterable[dict],
            bar: tqdm) -> None:
    """Merge a batch's worker results into its records and append them to the manifest."""
    append_records(manifest, merge_built(records, built))
    bar.update(len(records))


def worker_pool(jobs: int, warm: bool = False) -> WorkerPool:
    """Worker processes for writing and validating robots
    (:func:`robovae.data.workers.process_pool`: spawned, not forked). ``warm``: start all
    ``jobs`` workers now, each importing :mod:`robovae.generate.build`
    (:func:`~robovae.generate.build.warm_up`), instead of at the first work item."""
    pool = process_pool(jobs)
    if warm:
        for _ in range(pool.workers):  # at most one per core (process_pool)
            pool.submit(warm_up)
    return pool


def prepare_records(model: RoboVAE, indices: Sequence[int], z: torch.Tensor,
                    graphs: Sequence[RobotData], out: Path, seed: int = 0,
                    temperature: float = 1.0, validate: bool = True, scene: bool = True,
                    floating: bool = True, mirror: bool = True, quality: bool = True,
                    controls: str = "held", draws: Sequence[int] | None = None,
                    stance: bool = True, self_collision: bool = False
                    ) -> tuple[list[dict], list[tuple]]:
    """The first half of :func:`write_records`, in this process: each decoded robot's graph
    given a floating base and mirrored limbs (as asked), its manifest record so far and the
    work item of :func:`~robovae.generate.build.build_robot` (write, validate, measure).
    ``draws``: per robot, the prior draw kept (:func:`~robovae.model.prior.draw_robots`).
    ``stance``: the writer's stance rules (:mod:`robovae.generate.stance`);
    ``self_collision``: bodies that collide with each other
    (:mod:`robovae.data.self_collision`)."""
    records, items = [], []
    fs = model.feature_set
    draws = [0] * len(graphs) if draws is None else draws
    for i, g, zi, k in zip(indices, graphs, z, draws):
        name = f"robovae_s{seed}_{i:06d}"
        g, fixes = decoded_fixes(g, fs, floating=floating, mirror=mirror)
        fixes = (["redraw_unfinished"] if k else []) + fixes
        rec = robot_record(g, model.normalizer)
        rec.update(index=int(i), name=name, seed=seed, temperature=temperature,
                   latent=[round(float(v), 6) for v in zi], draw=int(k), rules=fixes,
                   path=f"robot_{i:06d}/robot.xml")
        records.append(rec)
        items.append((TreeArrays.of(g), out / f"robot_{i:06d}", fs.name, name, scene, validate,
                      quality, controls, stance, self_collision))
    return records, items


def merge_built(records: list[dict], built: Iterable[dict]) -> list[dict]:
    """The second half of :func:`write_records`: each record completed with what
    :func:`~robovae.generate.build.build_robot` returned for it (in order)."""
    for rec, b in zip(records, built):
        rec["rules"] = rec["rules"] + b.pop("rules")
        rec.update(b)
    return records


def write_records(model: RoboVAE, indices: Sequence[int], z: torch.Tensor,
                  graphs: Sequence[RobotData], out: Path, seed: int = 0,
                  temperature: float = 1.0, validate: bool = True, jobs: int = 0,
                  scene: bool = True, floating: bool = True,
                  pool: Executor | None = None, mirror: bool = True,
                  quality: bool = True, controls: str = "held",
                  draws: Sequence[int] | None = None, stance: bool = True,
                  self_collision: bool = False) -> list[dict]:
    """Write the folders of decoded robots ``graphs`` (latents ``z``, indices ``indices``) and
    validate them. Returns one manifest record per robot (the caller appends them).

    Writing and validation run in ``pool`` (or ``jobs`` worker processes, 0: all cores; 1: in
    this process). With ``floating``, a robot whose root is a single joint gets a floating
    base (:func:`~robovae.generate.rules.floating_base`, listed as ``floating_base``); with
    ``mirror``, near-mirror limb pairs are mirrored, stray limbs paired and twins on the plane
    made equal, and near-mirror branches of a link below the trunk (a chest's arms) mirrored
    (:func:`~robovae.generate.symmetry.mirror_limbs`,
    :func:`~robovae.generate.symmetry.complete_pairs`, :func:`~robovae.generate.symmetry.
    twin_limbs`, :func:`~robovae.generate.symmetry.mirror_branches`, listed as
    ``mirror_limbs``, ``complete_pairs``, ``twin_limbs``, ``mirror_branches``); with
    ``quality`` (and ``validate``), every valid robot's quality measures go into its record
    under ``quality``; ``controls``: the validation's simulation
    (:mod:`robovae.generate.validate`); ``stance``: the writer's stance rules
    (:mod:`robovae.generate.stance`); ``self_collision``: bodies that collide with each other
    (:mod:`robovae.data.self_collision`).
    """
    records, items = prepare_records(model, indices, z, graphs, out, seed=seed,
                                     temperature=temperature, validate=validate, scene=scene,
                                     floating=floating, mirror=mirror, quality=quality,
                                     controls=controls, draws=draws, stance=stance,
                                     self_collision=self_collision)
    jobs = jobs or (os.cpu_count() or 1)
    if pool is not None:
        built = list(pool.map(build_robot, items, chunksize=4))
    elif jobs == 1 or len(items) < 4:
        built = [build_robot(item) for item in items]
    else:
        with worker_pool(jobs) as tmp_pool:
            built = list(tmp_pool.map(build_robot, items, chunksize=4))
    return merge_built(records, built)


def append_records(manifest: TextIO, records: Sequence[dict]) -> None:
    """Append manifest lines and make them durable (flush + fsync) before returning. The robot
    folders of the lines, written without a per-file fsync, are first flushed to disk with one
    ``os.sync()``, so that a line never survives a crash that its robot did not."""
    os.sync()
    for rec in records:
        manifest.write(json.dumps(rec) + "\n")
    manifest.flush()
    os.fsync(manifest.fileno())


def summarize(model: RoboVAE, out: Path, n: int, new: int, validate: bool,
              seconds: float, extra: Callable[[list[dict]], dict] | None = None
              ) -> GenerationReport:
    """The report over robots ``0 … n-1`` of the manifests in ``out``; saved as JSON.
    ``extra(records)``, when given, returns more metrics from the robots' records (a dict
    merged into ``metrics``)."""
    everything = [r for i, r in sorted(read_manifest(out).items()) if i < n]
    reasons = Counter(r.get("reason", "unvalidated") for r in everything)
    rules = Counter(rule for r in everything for rule in r.get("rules", []))
    metrics = sample_metrics(everything, model.training_robots) if validate else {}
    if validate:
        metrics["quality"] = quality_summary([r["quality"] for r in everything if "quality" in r])
    if extra is not None:
        metrics.update(extra(everything))
    report = GenerationReport(out, len(everything), new, seconds,
                              dict(reasons), dict(rules), metrics)
    atomic_json(out / SUMMARY, report.to_dict(), durable=False)
    return report
