"""Benchmark: what TVF (and Riemann SPH) cost against standard SPH, per step of the 2D TGV (a script,
not a test). Two measures that answer differently to a busy machine:

  XLA's cost analysis of the compiled step (flops, bytes accessed): deterministic, load-free;
  the time per step, the methods interleaved over repeats (best of the repeats), so that a load
  that comes and goes hits them alike.

    python bench/bench_tvf_cost.py [--dx 0.02] [--steps 50] [--repeats 7]
"""
import argparse
import time

import jax

import sph
from sph.cases import tgv
from sph.lattice import cartesian, jitter


def compiled(method: str, dx: float):
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), 0.1 * dx, seed=0, box=(1.0, 1.0))
    solver = sph.build_solver(tgv.scene(dx, sph.Material(eta=0.01), tgv.METHODS[method], r=r), tgv.NUMERICS)
    state, nbrs = solver.init_fn()
    step = jax.jit(solver.step_fn).lower(state, nbrs, 1).compile()
    cost = step.cost_analysis()
    cost = cost[0] if isinstance(cost, list) else cost
    for _ in range(3):
        state, nbrs = step(state, nbrs, 1)
    return step, (state, nbrs), cost


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx", type=float, default=0.02)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    sph.set_cpu_defaults()
    methods = ("sph", "tvf", "riemann")
    runs = {m: compiled(m, args.dx) for m in methods}
    times = {m: [] for m in methods}
    for _ in range(args.repeats):
        for m in methods:
            step, carry, _ = runs[m]
            state, nbrs = carry
            jax.block_until_ready(state)
            t0 = time.perf_counter()
            for _ in range(args.steps):
                state, nbrs = step(state, nbrs, 1)
            jax.block_until_ready(state)
            times[m].append(1e3 * (time.perf_counter() - t0) / args.steps)
    print(f"2D TGV dx {args.dx} ({int(round(1 / args.dx)) ** 2} particles), float64, jax {jax.__version__}, "
          f"{jax.devices()[0].platform}; best of {args.repeats} interleaved repeats of {args.steps} steps")
    print(f"{'method':8s} {'MFLOP':>8s} {'MB accessed':>12s} {'ms/step':>8s} {'x SPH (time)':>13s} {'x SPH (bytes)':>14s}")
    base_t, base_b = min(times["sph"]), runs["sph"][2]["bytes accessed"]
    for m in methods:
        c = runs[m][2]
        t = min(times[m])
        print(f"{m:8s} {c['flops'] / 1e6:8.2f} {c['bytes accessed'] / 1e6:12.2f} {t:8.3f} {t / base_t:13.2f} "
              f"{c['bytes accessed'] / base_b:14.2f}")


if __name__ == "__main__":
    main()
