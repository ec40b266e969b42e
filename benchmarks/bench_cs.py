"""Steps per second of the CS filter: C core through cffi (batched and one call per step)
and the float64 golden model, with their ratios, measured in one run.

Run: python benchmarks/bench_cs.py [--steps N]
A step is one three-axis predict at 100 Hz; every 20th step also updates (5 Hz GPS).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mcahrs import core
from mcahrs.golden import cs as gcs


def inputs(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    dt = np.full(n, 0.01)
    zp = rng.normal(0.0, 2.5, (n, 3))
    zv = rng.normal(0.0, 0.1, (n, 3))
    rp = np.full((n, 3), 6.25)
    rv = np.full((n, 3), 0.01)
    mask = np.zeros((n, 3), np.uint8)
    mask[19::20, :2] = 3
    mask[19::20, 2] = 1
    return dt, zp, zv, rp, rv, mask


def best_of(fn, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200_000)
    args = ap.parse_args()
    n = args.steps
    dt, zp, zv, rp, rv, mask = inputs(n)

    t_batch = best_of(lambda: core.Cs3().run(dt, zp, zv, rp, rv, mask, want_p=False))

    n_call = min(n, 50_000)

    def per_call() -> None:
        c = core.Cs3()
        for k in range(n_call):
            c.predict(0.01)
            if mask[k].any():
                c.update(zp[k], zv[k], rp[k], rv[k], mask[k])

    t_call = best_of(per_call, 1) * n / n_call

    n_gold = min(n, 10_000)

    def golden() -> None:
        g = gcs.Cs3()
        g.init()
        for k in range(n_gold):
            g.predict(0.01)
            if mask[k].any():
                g.update(zp[k], zv[k], rp[k], rv[k], mask[k])

    t_gold = best_of(golden, 1) * n / n_gold
    rate = {
        name: n / t
        for name, t in (
            ("C batched (one cffi call)", t_batch),
            ("C one cffi call per step", t_call),
            ("golden float64 NumPy", t_gold),
        )
    }
    print(f"CS filter, {n} steps (3 axes, predict at 100 Hz, update at 5 Hz)")
    for name, r in rate.items():
        print(f"  {name:28s} {r:12,.0f} steps/s  ({1e6 / r:8.2f} us/step)")
    print(
        f"  cffi call overhead per step:  {1e6 * (t_call - t_batch) / n:8.2f} us "
        f"(per-call / batched = {t_call / t_batch:.1f}x)"
    )
    print(f"  C batched / golden:           {t_gold / t_batch:8.1f}x")
    print(f"  C per call / golden:          {t_gold / t_call:8.1f}x")


if __name__ == "__main__":
    main()
