"""Benchmark: the least end to end can cost, and so the most it can reach of validation-only.

Issue 21 asks end-to-end generation at >= 80 % of the MuJoCo-only validation throughput: on
the same cores, decoding and writing may then cost at most a quarter of the validation's CPU
per robot. This benchmark measures, on N decoded robots of a checkpoint (one process, CPU
time, steps interleaved over ``--passes`` passes, the median pass kept), what no writer can
avoid, beside what the project's code costs:

- ``decoder loop``: :meth:`robovae.model.decoder.TreeDecoder.decode` alone on the robots' latents
  (torch, float64, batches of ``--batch-size``, one thread): the network's own arithmetic,
  without the drawing of latents, de-normalisation and generation fixes;
- ``MjSpec element calls``: every body, joint, geom, actuator and keyframe of the written spec
  created again with its attributes as keyword arguments from plain lists (the least any
  ``MjSpec`` writer calls; the replayed spec's ``to_xml`` is compared with the writer's);
- ``to_xml``: MuJoCo writing that spec (it compiles it first);
- ``one compile``: the writer's stance rules and floor placement read a compiled model;
- ``writer``: :func:`robovae.generate.writer.write_robot` as the workers call it (stance rules,
  no load check, no fsync), and ``decode + fixes``: :func:`robovae.model.prior.draw_robots`
  and :func:`robovae.generate.pipeline.prepare_records` as ``generate`` runs them;
- ``validation``: :func:`robovae.generate.validate.check_robot` of each written file (held),
  the validation-only side of the ratio.

The *floor* is decoder loop + element calls + to_xml (+ one compile): a writer whose own
Python cost nothing. With the validation ``V`` and the floor ``F`` per robot, end to end can
reach at most ``V / (V + F)`` of validation-only throughput (the validation inside end to end
being the same as alone); the project's code reaches about ``V / (V + decode + writer)``.

    PYTHONPATH=. python benchmarks/generate_floor.py --ckpt runs/default/checkpoints/last.ckpt
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from robovae.evaluate.tables import format_table
from robovae.generate.validate import check_robot
from robovae.generate.writer import graph_to_spec, write_robot

_BODY = ("pos", "quat", "mass", "inertia", "ipos", "iquat", "explicitinertial")
_JOINT = ("type", "axis", "pos", "range", "limited", "damping", "armature", "frictionloss",
          "stiffness")
_GEOM = ("type", "size", "pos", "quat", "rgba", "contype", "conaffinity")
_ACT = ("target", "trntype", "gear", "ctrlrange", "ctrllimited", "forcerange", "forcelimited",
        "gaintype", "gainprm", "biastype", "biasprm", "dyntype")


def _plain(x: object) -> object:
    return x.tolist() if isinstance(x, np.ndarray) else x


def _record(spec: mujoco.MjSpec) -> tuple:
    """Every element of ``spec`` with the attributes the writer sets, as plain lists."""
    bodies = [(b.name, b.parent.name, {k: _plain(getattr(b, k)) for k in _BODY},
               [(j.name, {k: _plain(getattr(j, k)) for k in _JOINT}) for j in b.joints],
               [(g.name, {k: _plain(getattr(g, k)) for k in _GEOM}) for g in b.geoms])
              for b in spec.bodies[1:]]
    acts = [(a.name, {k: _plain(getattr(a, k)) for k in _ACT}) for a in spec.actuators]
    keys = [(k.name, _plain(k.qpos)) for k in spec.keys]
    return spec.modelname, bodies, acts, keys


def _replay(rec: tuple) -> mujoco.MjSpec:
    """The spec of :func:`_record`, made with one keyword call per element."""
    name, bodies, acts, keys = rec
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.compiler.degree = False
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    made = {"world": spec.worldbody}
    for bname, parent, attrs, joints, geoms in bodies:
        body = made[parent].add_body(name=bname, **attrs)
        made[bname] = body
        for jname, kw in joints:
            body.add_joint(name=jname, **kw)
        for gname, kw in geoms:
            body.add_geom(name=gname, **kw)
    for aname, kw in acts:
        spec.add_actuator(name=aname, **kw)
    for kname, qpos in keys:
        spec.add_key(name=kname, qpos=qpos)
    return spec


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--ckpt", required=True)
    p.add_argument("--n", type=int, default=512)
    p.add_argument("--batch-size", type=int, default=1024)
    p.add_argument("--passes", type=int, default=3)
    args = p.parse_args()
    import torch

    from robovae.generate.pipeline import prepare_records
    from robovae.model.checkpoint import load_model
    from robovae.model.prior import draw_robots

    torch.set_num_threads(1)
    model = load_model(args.ckpt).to(torch.float64)
    fs, hp, n = model.feature_set, model.hparams, args.n
    index = list(range(n))
    chunks = [index[k:k + args.batch_size] for k in range(0, n, args.batch_size)]

    def decode_and_fix() -> list:
        graphs = []
        for chunk in chunks:
            z, decoded, draws = draw_robots(model, 0, chunk, 1.0, redraws=4)
            graphs += [it[0] for it in prepare_records(model, chunk, z, decoded,
                                                       Path("unused"), draws=draws)[1]]
        return graphs

    graphs = decode_and_fix()
    z, noise = model.sample_prior(0, index, 1.0)
    names = [f"robovae_s0_{i:06d}" for i in index]
    specs = [graph_to_spec(g, fs, name, stance=True)[0] for g, name in zip(graphs, names)]
    xmls = [s.to_xml() for s in specs]
    recs = [_record(s) for s in specs]
    same = sum(_replay(r).to_xml() == x for r, x in zip(recs, xmls))
    root = Path(tempfile.mkdtemp(prefix="robovae_floor_"))
    paths = [write_robot(g, root / name, fs, name=name, check=False, durable=False,
                         stance=True).robot_path for g, name in zip(graphs, names)]

    def decoder_loop() -> None:
        for chunk in chunks:
            model.decoder.decode(z[chunk], max_nodes=hp.max_nodes, max_depth=hp.max_depth,
                                 node_noise=noise[chunk])

    replayed: list[mujoco.MjSpec] = []
    steps: dict[str, Callable[[], object]] = {
        "decoder loop (torch, 1 thread)": decoder_loop,
        "MjSpec element calls (replayed)": lambda: replayed.__setitem__(
            slice(None), [_replay(r) for r in recs]),
        "to_xml (MuJoCo compiles, then writes)": lambda: [s.to_xml() for s in replayed],
        "one compile": lambda: [s.compile() for s in replayed],
        "decode + fixes, as generate (draw_robots, prepare_records)": decode_and_fix,
        "writer, as the workers call it (write_robot, stance)": lambda: [
            write_robot(g, root / name, fs, name=name, check=False, durable=False, stance=True)
            for g, name in zip(graphs, names)],
        "validation of the written file (check_robot, held)": lambda: [
            check_robot(path) for path in paths],
    }
    cpu: dict[str, list[float]] = {k: [] for k in steps}
    for _ in range(args.passes):  # interleaved: the machine's drift reaches every step alike
        for label, fn in steps.items():
            t = time.process_time()
            fn()
            cpu[label].append(1e3 * (time.process_time() - t) / n)
    ms = {k: statistics.median(v) for k, v in cpu.items()}
    labels = list(steps)
    floor = ms[labels[0]] + ms[labels[1]] + ms[labels[2]]
    val = ms[labels[6]]
    rows = [{"step": k, "CPU ms/robot (median pass)": f"{v:.2f}",
             "passes": " ".join(f"{x:.2f}" for x in cpu[k])} for k, v in ms.items()]
    print(f"{n} decoded robots, batches of {args.batch_size}; {same} of {n} replayed specs write "
          "the writer's XML")
    print(format_table(rows, ["step", "CPU ms/robot (median pass)", "passes"]))
    ours = ms[labels[4]] + ms[labels[5]]
    print(f"a quarter of the validation (80 % asked): {0.25 * val:.2f} ms per robot")
    for what, f in (("floor without a compile", floor),
                    ("floor with the writer's compile", floor + ms[labels[3]]),
                    ("the project's decode + writer", ours)):
        print(f"{what}: {f:.2f} ms per robot -> end to end at most {val / (val + f):.0%} of "
              "validation-only throughput")
    shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
