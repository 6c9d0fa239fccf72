"""Benchmark: training throughput of the tree VAE (graphs/s), level-scheduled batches against a
per-tree reference loop, and the encoder against its naive per-edge reference.

Datasets: the 17 Menagerie robots (``--menagerie``, default ``../shared/menagerie``) and
``--procedural`` procedural robots. One training step = forward + backward + AdamW step. The
model is the one of ``--config`` (its ``model:`` block; default ``configs/menagerie17.yaml``).

One epoch is one pass over the dataset: the ``epochs/s`` column is graphs/s over its size.

Also measured: the time of one training step on the 17 Menagerie robots in one batch (the
paper's setting); with ``--lightning-epochs N`` the steady-state epochs/s of ``Trainer.fit`` on
them (one batch of 17 per epoch, progress bar, logger and checkpointing off); and with
``--fit`` the whole 17-robot experiment, ``configs/menagerie17.yaml`` through the Lightning CLI
exactly as ``python -m robovae.evaluate.experiments run menagerie17`` trains it (1500 epochs,
validation, reconstruction metrics and checkpoints included), with its RA and FRE.

    python benchmarks/train_speed.py --procedural 1000 --steps 5
    python benchmarks/train_speed.py --procedural 0 --lightning-epochs 300 --fit --threads 2
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import torch
import yaml
from torch_geometric.data import Batch

from robovae.data.dataset import RobotDataset
from robovae.data.normalizer import Normalizer
from robovae.evaluate.tables import format_table
from robovae.model.encoder import encode_reference
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


def _step_ms(model: RoboVAE, batch: Batch, steps: int = 30) -> tuple[float, float]:
    """(median, min) milliseconds of one training step on ``batch``."""
    opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
    times = []
    for i in range(steps + 5):
        t = time.perf_counter()
        opt.zero_grad()
        model(batch)["loss"].backward()
        opt.step()
        if i >= 5:
            times.append(1000 * (time.perf_counter() - t))
    times.sort()
    return times[len(times) // 2], times[0]


def _lightning_rate(menagerie: str, root: Path, epochs: int, model_kw: dict) -> float:
    """Steady-state epochs/s of ``Trainer.fit`` on the 17 robots (epochs 10.. timed)."""
    import logging
    import warnings

    import lightning as L

    from robovae.data.datamodule import RobotDataModule

    warnings.filterwarnings("ignore", ".*does not have many workers.*")
    warnings.filterwarnings("ignore", ".*smaller than the logging interval.*")
    warnings.filterwarnings("ignore", ".*LeafSpec.*")
    logging.getLogger("lightning.pytorch").setLevel(logging.WARNING)

    class Clock(L.Callback):
        start = 0.0

        def on_train_epoch_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
            if trainer.current_epoch == 10:
                self.start = time.perf_counter()

    L.seed_everything(0, verbose=False)
    dm = RobotDataModule([f"dir:{menagerie}"], root=str(root), val_fraction=0.0,
                         test_fraction=0.0, val_is_train=True, batch_size=17)
    clock = Clock()
    trainer = L.Trainer(max_epochs=epochs, accelerator="cpu", devices=1, logger=False,
                        enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, num_sanity_val_steps=0,
                        check_val_every_n_epoch=epochs + 1, callbacks=[clock])
    trainer.fit(RoboVAE(**model_kw), dm)
    return (epochs - 10) / (time.perf_counter() - clock.start)


def _fit_experiment(config: str, menagerie: str, root: Path, threads: int) -> dict:
    """Train ``config`` through the Lightning CLI as the experiment runner does; its result."""
    from robovae.evaluate.experiments import RunSpec, run_one

    spec = RunSpec("menagerie17", config, 0, root / "fit" / "seed0",
                   [f"--data.root={root}", f'--data.sources=["dir:{menagerie}"]'],
                   threads=threads)
    return run_one(spec)


def _machine_gflops(n: int = 256, reps: int = 200) -> float:
    """Reference speed of this machine: float32 ``n x n`` matmul GFLOP/s on the torch threads."""
    a, b = torch.randn(n, n), torch.randn(n, n)
    for _ in range(10):
        a @ b
    t = time.perf_counter()
    for _ in range(reps):
        a @ b
    return 2 * n ** 3 * reps / (time.perf_counter() - t) / 1e9


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--menagerie", default="../shared/menagerie")
    p.add_argument("--procedural", type=int, default=1000)
    p.add_argument("--steps", type=int, default=5, help="timed steps per measurement")
    p.add_argument("--batch-sizes", default="1,16,64")
    p.add_argument("--config", default="configs/menagerie17.yaml",
                   help="the model settings (its model: block) and the --fit experiment")
    p.add_argument("--threads", type=int, default=0, help="torch threads (0: default)")
    p.add_argument("--lightning-epochs", type=int, default=0,
                   help="also time Trainer.fit on the 17 robots for this many epochs")
    p.add_argument("--fit", action="store_true",
                   help="also train --config through the Lightning CLI and time it")
    args = p.parse_args()
    model_kw = yaml.safe_load(Path(args.config).read_text()).get("model", {})
    if args.threads:
        torch.set_num_threads(args.threads)
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
        model = RoboVAE(**model_kw)
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
                         "speed-up": f"{fast / ref:.1f}x",
                         "epochs/s": f"{fast / len(graphs):.3g}"})
        if name == "menagerie17":
            median, best = _step_ms(model, Batch.from_data_list(graphs))
            rows.append({"dataset": name, "nodes/graph": f"{nodes:.0f}",
                         "batch": f"{len(graphs)} (all)",
                         "level-scheduled graphs/s": f"{1000 * len(graphs) / median:.1f}",
                         "per-tree loop graphs/s": f"step {median:.1f} ms (min {best:.1f})",
                         "speed-up": "", "epochs/s": f"{1000 / median:.1f}"})
        enc_fast = _encoder_rate(model, graphs, naive=False)
        enc_naive = _encoder_rate(model, graphs, naive=True)
        rows.append({"dataset": name, "nodes/graph": f"{nodes:.0f}", "batch": "encoder only",
                     "level-scheduled graphs/s": f"{enc_fast:.1f}",
                     "per-tree loop graphs/s": f"{enc_naive:.1f} (naive per-edge)",
                     "speed-up": f"{enc_fast / enc_naive:.1f}x", "epochs/s": ""})
    print(format_table(rows, ["dataset", "nodes/graph", "batch", "level-scheduled graphs/s",
                              "per-tree loop graphs/s", "speed-up", "epochs/s"]))
    if args.lightning_epochs and "menagerie17" in sets:
        rate = _lightning_rate(args.menagerie, root, max(args.lightning_epochs, 20), model_kw)
        print(f"Trainer.fit, 17 Menagerie robots, batch 17: {rate:.1f} epochs/s "
              f"({1000 / rate:.1f} ms/epoch; 1500 epochs ~ {1500 / rate:.0f} s + start-up)")
    if args.fit and "menagerie17" in sets:
        r = _fit_experiment(args.config, args.menagerie, root, args.threads)
        s = r["summary"]
        print(f"{args.config}: {r['epochs']} epochs, Trainer.fit {r['fit_s']:.1f} s, whole "
              f"command {r['command_s']:.1f} s (start-up, data, scoring); 17 robots: RA "
              f"{s['ra']:.1%}, exact {s['exact']:.0%}, mean FRE {s['fre']:.2g}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"threads: {torch.get_num_threads()}, model of {args.config} (hidden "
          f"{model_kw.get('hidden_dim', 128)}, node latents {model_kw.get('node_latent_dim', 0)})"
          f", peak RSS {peak:.0f} MiB, machine reference {_machine_gflops():.1f} GFLOP/s "
          "(256x256 float32 matmul)")


if __name__ == "__main__":
    main()
