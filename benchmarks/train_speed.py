"""Benchmark: training throughput of the tree VAE (graphs/s), level-scheduled batches against a
per-tree reference loop, and the encoder against its naive per-edge reference.

Datasets: the 17 Menagerie robots (``--menagerie``, default ``../shared/menagerie``) and
``--procedural`` procedural robots. One training step = forward + backward + AdamW step.

    python benchmarks/train_speed.py --procedural 1000 --steps 5
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import torch
from torch_geometric.data import Batch

from robovae.cli import format_table
from robovae.data.dataset import RobotDataset
from robovae.data.features import Normalizer
from robovae.model.tree import encode_reference
from robovae.model.vae import RoboVAE


def _batches(graphs: list, size: int, count: int) -> list[Batch]:
    out, i = [], 0
    while len(out) < count:
        chunk = [graphs[(i + k) % len(graphs)] for k in range(size)]
        out.append(Batch.from_data_list(chunk))
        i += size
    return out


def _train_rate(model: RoboVAE, batches: list[Batch], per_tree: bool) -> float:
    opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
    graphs, t = 0, time.perf_counter()
    for b in batches:
        opt.zero_grad()
        if per_tree:  # reference: the same batch, one tree at a time
            for d in b.to_data_list():
                (model(Batch.from_data_list([d]))["loss"] / b.num_graphs).backward()
        else:
            model(b)["loss"].backward()
        opt.step()
        graphs += b.num_graphs
    return graphs / (time.perf_counter() - t)


def _encoder_rate(model: RoboVAE, graphs: list, naive: bool) -> float:
    graphs = graphs[:64]
    with torch.no_grad():
        norm = [model.normalized(Batch.from_data_list([g])) for g in graphs]
        t = time.perf_counter()
        if naive:
            for g in norm:
                encode_reference(model.encoder, g)
        else:
            model.encoder(Batch.from_data_list([g.to_data_list()[0] for g in norm]))
    return len(graphs) / (time.perf_counter() - t)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--menagerie", default="../shared/menagerie")
    p.add_argument("--procedural", type=int, default=1000)
    p.add_argument("--steps", type=int, default=5, help="timed steps per measurement")
    p.add_argument("--batch-sizes", default="1,16,64")
    p.add_argument("--hidden", type=int, default=128)
    args = p.parse_args()
    torch.manual_seed(0)
    root = Path(tempfile.mkdtemp(prefix="robovae_speed_"))
    sets = {}
    if Path(args.menagerie).is_dir():
        sets["menagerie17"] = list(RobotDataset(root, [f"dir:{args.menagerie}"], progress=False))
    if args.procedural:
        sets[f"procedural{args.procedural}"] = list(RobotDataset(
            root, [f"procedural:n={args.procedural},seed=0"], progress=False))
    rows = []
    for name, graphs in sets.items():
        model = RoboVAE(hidden_dim=args.hidden)
        x = torch.cat([g.x for g in graphs])
        t = torch.cat([g.node_type for g in graphs])
        model.normalizer.load_state_dict(Normalizer("paper34").fit(x, t).state_dict())
        nodes = sum(g.num_nodes for g in graphs) / len(graphs)
        for bs in (int(s) for s in args.batch_sizes.split(",")):
            batches = _batches(graphs, bs, args.steps)
            _train_rate(model, batches[:1], per_tree=False)  # warm-up
            fast = _train_rate(model, batches, per_tree=False)
            ref = _train_rate(model, batches, per_tree=True) if bs > 1 else fast
            rows.append({"dataset": name, "nodes/graph": f"{nodes:.0f}", "batch": bs,
                         "level-scheduled graphs/s": f"{fast:.1f}",
                         "per-tree loop graphs/s": f"{ref:.1f}",
                         "speed-up": f"{fast / ref:.1f}x"})
        enc_fast = _encoder_rate(model, graphs, naive=False)
        enc_naive = _encoder_rate(model, graphs, naive=True)
        rows.append({"dataset": name, "nodes/graph": f"{nodes:.0f}", "batch": "encoder only",
                     "level-scheduled graphs/s": f"{enc_fast:.1f}",
                     "per-tree loop graphs/s": f"{enc_naive:.1f} (naive per-edge)",
                     "speed-up": f"{enc_fast / enc_naive:.1f}x"})
    print(format_table(rows, ["dataset", "nodes/graph", "batch", "level-scheduled graphs/s",
                              "per-tree loop graphs/s", "speed-up"]))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"threads: {torch.get_num_threads()}, hidden {args.hidden}, peak RSS {peak:.0f} MiB")


if __name__ == "__main__":
    main()
