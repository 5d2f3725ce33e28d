"""Benchmark: particle-steps per second of the 2D Taylor-Green vortex (a script, not a test).

Prints, per method, resolution and precision, the compile time and the steady-state time per
step of a jitted `lax.scan` chunk (neighbour-list updates included). Positions are a lattice with
0.1 dx of noise, which exercises the same code as a relaxed start.

    make bench                         # full table
    python bench/bench_tgv.py --quick  # dx = 0.02, float64 only
"""
import argparse

import jax

import sph
from sph.cases import tgv
from sph.lattice import cartesian, jitter

try:
    from bench_scaling import time_chunk
except ImportError:  # imported as bench.bench_tgv
    from bench.bench_scaling import time_chunk

METHODS = {
    "sph": sph.Effects(),
    "tvf": sph.Effects(tvf=True),
    "riemann": sph.Effects(riemann=True, density_evolution=True),
}


def measure(dx, dtype, method, steps):
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), 0.1 * dx, seed=0, box=(1.0, 1.0))
    solver = sph.build_solver(tgv.scene(dx, sph.Material(eta=0.01), METHODS[method], r=r),
                              sph.Numerics(dtype=dtype))
    state, nbrs = solver.init_fn()
    _, compile_s, best = time_chunk(solver, state, nbrs, steps, repeats=5)
    n = state.r.shape[0]
    return dict(method=method, dx=dx, dtype=dtype, n=n, K=nbrs.idx.shape[1], compile_s=compile_s,
                ms_per_step=1e3 * best / steps, mpps=n * steps / best / 1e6)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="dx = 0.02, float64 only")
    ap.add_argument("--steps", type=int, default=200)
    args = ap.parse_args()
    dxs = [0.02] if args.quick else [0.02, 0.01]
    dtypes = ["float64"] if args.quick else ["float64", "float32"]
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {args.steps} steps per timing (best of 5)")
    print(f"{'method':8s} {'dx':>5s} {'dtype':8s} {'N':>6s} {'K':>3s} {'compile s':>9s} {'ms/step':>8s} {'Mpart-steps/s':>13s}")
    for dx in dxs:
        for dtype in dtypes:
            for method in METHODS:
                m = measure(dx, dtype, method, args.steps)
                print(f"{m['method']:8s} {m['dx']:5.2f} {m['dtype']:8s} {m['n']:6d} {m['K']:3d} "
                      f"{m['compile_s']:9.2f} {m['ms_per_step']:8.3f} {m['mpps']:13.2f}", flush=True)


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
