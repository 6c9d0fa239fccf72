"""Benchmark: CPU time and peak memory of the population statistics ``robovae analyze`` runs on
the training corpus (:mod:`robovae.evaluate.population`): MMD² with its permutation test and
coverage on ``--reference`` training descriptor vectors against ``--samples`` sample vectors
(``compare`` caps the reference at :data:`~robovae.evaluate.population.MAX_REFERENCE`), and the
k-NN entropy of ``--latents`` encoded means.

Each statistic runs in a fresh process on seeded Gaussian vectors (the statistics' cost depends
on the sizes, not on the values): CPU seconds (``time.process_time``) and the process's peak
resident memory above its size before the call (``ru_maxrss``).

    PYTHONPATH=. python benchmarks/population.py --reference 10000 --samples 300
"""

from __future__ import annotations

import argparse
import multiprocessing
import resource
import time


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _one(job: tuple[str, int, int, int, int]) -> tuple[float, float]:
    """(CPU s, peak MB above the start) of one statistic in this (fresh) process."""
    import numpy as np

    from robovae.evaluate.population import coverage, knn_entropy, mmd_rbf

    name, n, m, dim, permutations = job
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(n, dim)), rng.normal(size=(m, dim)) + 0.1
    start, t0 = _rss_mb(), time.process_time()
    if name == "mmd":
        mmd_rbf(x, y, permutations=permutations)
    elif name == "coverage":
        coverage(x, y)
    else:
        knn_entropy(x)
    return time.process_time() - t0, _rss_mb() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--reference", type=int, default=10_000, help="training vectors (MMD, coverage)")
    p.add_argument("--samples", type=int, default=300, help="sample vectors")
    p.add_argument("--dim", type=int, default=9, help="descriptor vector width")
    p.add_argument("--permutations", type=int, default=200)
    p.add_argument("--latents", type=int, default=40_000, help="encoded means (k-NN entropy)")
    p.add_argument("--latent-dim", type=int, default=64)
    a = p.parse_args()
    jobs = [("mmd", a.reference, a.samples, a.dim, a.permutations),
            ("coverage", a.reference, a.samples, a.dim, 0),
            ("knn_entropy", a.latents, 1, a.latent_dim, 0)]
    ctx = multiprocessing.get_context("spawn")
    print("| statistic | points | CPU s | peak MB above start |\n|---|---|---|---|")
    for job in jobs:
        with ctx.Pool(1, maxtasksperchild=1) as pool:
            cpu, mb = pool.apply(_one, (job,))
        points = f"{job[1]:,} + {job[2]:,}" if job[0] != "knn_entropy" else f"{job[1]:,}"
        print(f"| {job[0]} | {points} | {cpu:.1f} | {mb:,.0f} |")


if __name__ == "__main__":
    main()
