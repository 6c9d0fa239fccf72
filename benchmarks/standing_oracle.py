"""Diagnostic: which decoded feature columns keep robots from standing? One table.

Procedural robots at a seed no config trains on are encoded and decoded from ``z`` alone
(``RoboVAE.reconstruct(from_z=True)``); those whose tree and node types come back exactly are
written and tested (:func:`robovae.generate.pipeline.write_records`: rules, floating base,
mirrored limbs, validation, standing test) once as decoded and once per *oracle* group, with
that group's columns replaced by the true values. Rows: the group; columns: robots standing per
procedural class. The true graphs themselves are the ``all`` row.

    PYTHONPATH=. python benchmarks/standing_oracle.py --ckpt runs/default/checkpoints/last.ckpt \\
        --classes biped+humanoid --n 400 --seed 11
"""

from __future__ import annotations

import argparse
import collections
import tempfile
from pathlib import Path

import torch
from torch_geometric.data import Batch

from robovae.data.dataset import RobotDataset
from robovae.evaluate.tables import format_table
from robovae.generate.pipeline import write_records
from robovae.model.checkpoint import load_model

_GEOMETRY = ["link.box_axes", "link.box_half", "link.box_pos", "link.pos", "link.quat",
             "joint.pos", "joint.axis", "joint.range"]
GROUPS = {
    "decoded": [],
    "link.pos": ["link.pos"],
    "collision box": ["link.box_axes", "link.box_half", "link.box_pos"],
    "mass, inertia": ["link.mass", "link.inertia", "link.ipos", "link.iquat"],
    "joint.torque": ["joint.torque"],
    "all geometry": _GEOMETRY,
}


def _same_tree(a, b) -> bool:
    return a.num_nodes == b.num_nodes and torch.equal(a.parent, b.parent) \
        and torch.equal(a.node_type, b.node_type)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ckpt", required=True)
    ap.add_argument("--classes", default="biped+humanoid")
    ap.add_argument("--n", type=int, default=400)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--root", default="data_cache")
    ap.add_argument("--jobs", type=int, default=0)
    args = ap.parse_args()

    model = load_model(args.ckpt)
    fs = model.feature_set
    source = f"procedural:n={args.n},seed={args.seed},classes={args.classes}"
    robots = list(RobotDataset(args.root, [source], fs.name, progress=False))
    decoded = []
    for start in range(0, len(robots), 64):
        decoded += model.reconstruct(Batch.from_data_list(robots[start:start + 64]),
                                     from_z=True)
    keep = [i for i, (t, d) in enumerate(zip(robots, decoded)) if _same_tree(t, d)]
    kinds = {i: str(robots[i].name).split("_")[1] for i in keep}  # proc_<class>_<k>
    groups = dict(GROUPS, all=[f.key for f in fs.features])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, keys in groups.items():
            graphs = []
            for i in keep:
                g = decoded[i].clone()
                for key in keys:
                    g.x[:, fs.slice(key)] = robots[i].x[:, fs.slice(key)]
                graphs.append(g)
            z = torch.zeros(len(graphs), int(model.hparams.latent_dim))
            out = write_records(model, keep, z, graphs, Path(tmp) / name.replace(" ", "_"),
                                jobs=args.jobs)
            count: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
            for i, rec in zip(keep, out):
                q = rec.get("quality") or {}
                if q.get("floating"):
                    count[kinds[i]][0] += 1
                    count[kinds[i]][1] += bool(q.get("stands"))
            total = [sum(v[k] for v in count.values()) for k in (0, 1)]
            row = {"true columns": name, "stand": f"{total[1] / max(total[0], 1):.1%}"}
            row.update({k: f"{count[k][1]} of {count[k][0]}" for k in count})
            rows.append(row)
            print(row, flush=True)
    classes = sorted({kinds[i] for i in keep})
    print(f"\n{len(keep)} of {len(robots)} decoded with the exact tree ({source})")
    print(format_table(rows, ["true columns"] + classes + ["stand"]))


if __name__ == "__main__":
    main()
