"""Benchmark: where do bodies that pass through each other come from, the writer or the model?

For ``--n`` procedural robots of each class (seeds from ``--seed``, beyond the default's
training seeds), four versions of every robot are measured for bodies overlapping away from a
joint at rest (:func:`robovae.evaluate.quality.attachment.attachment`'s ``off_joint_pairs``,
the ``penetrating_off_joint`` of ``robovae generate``'s records):

- ``original``: the procedural robot as built;
- ``round trip``: robot file → graph → ``robovae generate``'s fixes and writer, no model;
- ``full channel``: the checkpoint's reconstruction from its latent mean and its nodes' latent
  means, written the same way;
- ``from z``: the reconstruction from the latent mean alone (node latents at their
  conditional prior mean, as samples are decoded at node temperature 0).

A share far above the round trip's is the model's, not the writer's. Prints one table
(shares of robots with at least one such pair; ``limbs kept``: the reconstruction has the
original's number of limbs on the root).

    PYTHONPATH=. python benchmarks/reconstruction_overlaps.py \\
        --ckpt runs/default/checkpoints/last.ckpt --n 16
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import torch
from torch_geometric.data import Batch

from robovae.data.mjcf import model_to_graph
from robovae.data.procedural import procedural_spec
from robovae.data.procedural.robots import CLASSES
from robovae.evaluate.quality.attachment import attachment
from robovae.evaluate.tables import format_table
from robovae.generate.pipeline import write_records
from robovae.model.checkpoint import own_model
from robovae.model.node_transfer import EncodedRobot, decode_near


def _written(model, graphs: list, z: torch.Tensor, out: Path, jobs: int) -> list[dict]:
    """``robovae generate``'s records of ``graphs`` written into ``out``."""
    return write_records(model, list(range(len(graphs))), z, graphs, out, jobs=jobs,
                         scene=False, draws=[0] * len(graphs))


def _share(flags: list[bool]) -> str:
    return f"{sum(flags) / max(len(flags), 1):.0%}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ckpt", required=True)
    p.add_argument("--n", type=int, default=16, help="robots per procedural class")
    p.add_argument("--seed", type=int, default=900_000, help="first procedural seed")
    p.add_argument("--jobs", type=int, default=2)
    args = p.parse_args()
    t = time.perf_counter()
    model = own_model(args.ckpt).to(torch.float64)
    fs = model.feature_set
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in CLASSES:
            models = [procedural_spec(args.seed + i, kind).compile() for i in range(args.n)]
            graphs = [model_to_graph(m, fs, name=f"{kind}_{i}") for i, m in enumerate(models)]
            mu, nodes = model.encode_nodes(Batch.from_data_list(graphs))
            z = mu.double()
            full = [decode_near(model, z[i:i + 1], [EncodedRobot(z[i], nodes[i].double(),
                                                                 (g.parent, g.node_type))])[0]
                    for i, g in enumerate(graphs)]
            versions = {"round trip": graphs, "full channel": full, "from z": model.decode(z)}
            row = {"class": kind, "robots": args.n,
                   "original": _share([attachment(m).off_joint_pairs > 0 for m in models])}
            limbs = None
            for name, decoded in versions.items():
                recs = _written(model, decoded, z, Path(tmp) / kind / name.replace(" ", "_"),
                                args.jobs)
                row[name] = _share([r["valid"] and r["quality"]["penetrating_off_joint"]
                                    for r in recs])
                if name == "round trip":
                    limbs = [r["limbs"] for r in recs]
                else:
                    row[f"limbs kept, {name}"] = _share(
                        [r["limbs"] == k for r, k in zip(recs, limbs)])
            rows.append(row)
            print(f"{kind}: done ({time.perf_counter() - t:.0f} s)", flush=True)
    print(format_table(rows, ["class", "robots", "original", "round trip", "full channel",
                              "from z", "limbs kept, full channel", "limbs kept, from z"]))
    print(f"checkpoint {args.ckpt}, feature set {model.hparams.feature_set}, seeds {args.seed}.., "
          f"{time.perf_counter() - t:.0f} s")


if __name__ == "__main__":
    main()
