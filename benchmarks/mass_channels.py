"""Benchmark: where the samples' total mass leaves the training corpus's, channel by channel.

The total mass of a robot graph is the sum of its links' ``link.mass`` (kg, before the writer:
its rules and mirrored limbs change it a little). For ``--n`` training robots of the checkpoint
(drawn at random, seed 0) it compares, by the 1-D Wasserstein distance W1 to their masses
(:func:`robovae.evaluate.quality.distribution.wasserstein_1d`):

- another ``--n`` training robots (the corpus's own split-half reference);
- their reconstructions through the full channel (``z`` and node latents at the posterior
  means, :meth:`RoboVAE.reconstruct <robovae.model.vae.RoboVAE.reconstruct>`) and from ``z``
  alone (node latents at their conditional prior means);
- ``--n`` prior samples (seed 0) at node temperature 0 (the default's sampling) and 1.

A second table splits the full-channel reconstructions by the true mass's quintile: the median
log ratio of reconstructed to true mass (0: unbiased), what a decoder that pulls every robot
towards the corpus's typical mass shows as positive below and negative above::

    PYTHONPATH=. python benchmarks/mass_channels.py --ckpt runs/default/checkpoints/last.ckpt
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from torch_geometric.data import Batch

from robovae.data.graph import RobotData
from robovae.evaluate.analyze import training_graphs
from robovae.evaluate.quality.distribution import wasserstein_1d
from robovae.evaluate.tables import format_table
from robovae.model.checkpoint import own_model
from robovae.model.prior import draw_robots
from robovae.model.vae import RoboVAE

BATCH = 250


def total_mass(g: RobotData, column: int) -> float:
    """Sum of the link nodes' (node type 0) mass feature, negative masses counted as 0."""
    return float(g.x[g.node_type == 0, column].double().clamp(min=0).sum())


def root_subtreemass(g: RobotData, column: int) -> float:
    """The root link's ``link.subtreemass`` as decoded (the writer recomputes it from the
    links' masses, rule ``subtreemass_consistent``): the model's own estimate of the total."""
    roots = torch.nonzero(g.node_type == 0).view(-1)
    return float(g.x[roots[0], column].double().clamp(min=0)) if len(roots) else 0.0


def reconstructed(model: RoboVAE, graphs: list[RobotData], from_z: bool) -> list[RobotData]:
    """Greedy reconstructions, :data:`BATCH` robots at a time."""
    return [r for k in range(0, len(graphs), BATCH)
            for r in model.reconstruct(Batch.from_data_list(graphs[k:k + BATCH]), from_z=from_z)]


def sampled(model: RoboVAE, n: int, node_temperature: float) -> list[RobotData]:
    """Prior samples ``0 … n-1`` of seed 0, unfinished trees redrawn up to 4 times (as
    ``robovae generate`` draws them)."""
    return [g for k in range(0, n, BATCH) for g in draw_robots(
        model, 0, list(range(k, min(n, k + BATCH))), 1.0, node_temperature, 4)[1]]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--ckpt", required=True, help="checkpoint (e.g. runs/default/...last.ckpt)")
    p.add_argument("--n", type=int, default=2000, help="robots per column")
    args = p.parse_args()
    torch.set_num_threads(1)
    model = own_model(args.ckpt).to(torch.float64)
    column = model.feature_set.slice("link.mass").start
    sub = model.feature_set.slice("link.subtreemass").start
    graphs, what = training_graphs(model, args.ckpt)
    rng = np.random.default_rng(0)
    order = rng.permutation(len(graphs))
    corpus = [graphs[i] for i in order[:args.n]]
    other = [graphs[i] for i in order[args.n:2 * args.n]]
    true = np.array([total_mass(g, column) for g in corpus])
    columns = {"training robots, other half": other,
               "reconstructed, full channel": reconstructed(model, corpus, False),
               "reconstructed, from z": reconstructed(model, corpus, True),
               "samples, node temperature 0": sampled(model, args.n, 0.0),
               "samples, node temperature 1": sampled(model, args.n, 1.0)}
    def row(label: str, m: np.ndarray, w1: str) -> dict:
        qs = [0.05, 0.25, 0.5, 0.75, 0.9, 0.95]
        return {"robots": label, "W1 kg": w1, "mean kg": f"{m.mean():.1f}",
                **{f"q{round(q * 100)}": f"{v:.1f}" for q, v in zip(qs, np.quantile(m, qs))}}

    rows = [row("training robots", true, "-")]
    masses = {label: np.array([total_mass(g, column) for g in gs])
              for label, gs in columns.items()}
    # decoded graphs (not the other half): the root's own estimate of the total
    subs = {label: np.array([root_subtreemass(g, sub) for g in gs])
            for label, gs in list(columns.items())[1:]}
    for label, m in [*masses.items(), *((f"{k}, root subtreemass", v) for k, v in subs.items())]:
        rows.append(row(label, m, f"{wasserstein_1d(m, true):.2f}"))
    print(f"{len(corpus)} of {what}")
    print(format_table(rows, list(rows[0])))
    full = masses["reconstructed, full channel"]
    root = subs["reconstructed, full channel"]
    ranks = np.argsort(true)
    bias = []
    for k, idx in enumerate(np.array_split(ranks, 5)):
        t, f, r = true[idx], full[idx], root[idx]
        ok, ok_root = (t > 0) & (f > 0), (t > 0) & (r > 0)
        bias.append({"true mass quintile": k + 1,
                     "true kg (mean)": f"{t.mean():.1f}",
                     "reconstructed kg (mean)": f"{f.mean():.1f}",
                     "median log(reconstructed / true)":
                         f"{np.median(np.log(f[ok] / t[ok])):+.3f}",
                     "root subtreemass: median log(/ true)":
                         f"{np.median(np.log(r[ok_root] / t[ok_root])):+.3f}"})
    print(format_table(bias, list(bias[0])))


if __name__ == "__main__":
    main()
