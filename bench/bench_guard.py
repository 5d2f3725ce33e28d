"""Benchmark: what the step guard costs (a script, not a test; issue 13 asks for < 3 % of a step).

The guard (`sph.guard.StepGuard`, on by default in every run) refuses a step after which a
fluid particle is outside a non-periodic side of the domain, moves faster than the speed limit or
has a non-finite position or velocity. Here the same compiled chunk of steps is timed with and
without it, interleaved (A, B, A, B, ...) so that a busy machine slows both alike, on a periodic
scene (TGV: the escape test compiles away, only the speed/finiteness test remains) and on a walled
one (tank at rest: the full test). Compare the rows of one run only. "test alone" times the
guard's test by itself against one step (both jitted in a scan, back to back): the share of a
step the guard can cost at most, which machine noise hardly moves.

    python bench/bench_guard.py [--steps 200] [--dx 0.02] [--repeats 7]
"""
import argparse
import time

import jax
import numpy as np

import sph
from sph.rollout import make_chunk

try:
    from . import bench_effects
except ImportError:  # run as a script: its folder comes first on the import path
    import bench_effects


def chunk_timer(solver, steps, guard):
    """A function that times one compiled chunk of `steps` steps (seconds)."""
    state, nbrs = solver.init_fn()
    compiled = jax.jit(make_chunk(solver.step_fn, steps, guard=guard)).lower(state, nbrs, 0, steps).compile()

    def once():
        t0 = time.perf_counter()
        out = jax.block_until_ready(compiled(state, nbrs, 0, steps))
        assert int(out[2]) == steps and not bool(out[3]), "benchmark chunk stopped early or overflowed"
        return time.perf_counter() - t0

    once()
    return once


def reject_share(solver, steps):
    """The guard's test alone against one step, each jitted and run `steps` times in a scan: a ratio
    that machine noise hardly moves (both are timed back to back)."""
    state, nbrs = solver.init_fn()

    def loop(body):
        def run(state):
            return jax.lax.scan(lambda c, _: (body(c), None), state, None, length=steps)[0]
        return jax.jit(run)

    step = loop(lambda s: solver.step_fn(s, nbrs, 0)[0])
    reject = loop(lambda s: s.replace(v=s.v * (1.0 - 1e-12 * solver.guard.reject(s))))  # keeps it live
    best = {}
    for name, f in (("step", step), ("reject", reject)):
        jax.block_until_ready(f(state))
        t = []
        for _ in range(5):
            t0 = time.perf_counter()
            jax.block_until_ready(f(state))
            t.append(time.perf_counter() - t0)
        best[name] = min(t) / steps
    return best["reject"] / best["step"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--dx", type=float, default=0.02)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    print(f"step guard on / off, dx {args.dx}, float64, {args.steps} steps a chunk, interleaved, "
          f"min and median of {args.repeats}")
    print(f"{'scene':14s} {'N':>6s} {'off ms/step':>12s} {'on ms/step':>11s} {'overhead (min)':>15s} "
          f"{'(median)':>9s}")
    picked = [s for s in bench_effects.scenes(args.dx) if s[1] in ("-", "walls")]
    for case, _, scene in picked:
        solver = sph.build_solver(scene, sph.Numerics(dt=1e-4))
        timers = {"off": chunk_timer(solver, args.steps, None), "on": chunk_timer(solver, args.steps, solver.guard)}
        times = {k: [] for k in timers}
        for _ in range(args.repeats):
            for k, f in timers.items():
                times[k].append(f())
        mins = {k: 1e3 * min(v) / args.steps for k, v in times.items()}
        meds = {k: 1e3 * float(np.median(v)) / args.steps for k, v in times.items()}
        print(f"{case:14s} {scene.n:6d} {mins['off']:12.3f} {mins['on']:11.3f} "
              f"{100 * (mins['on'] / mins['off'] - 1):14.1f}% {100 * (meds['on'] / meds['off'] - 1):8.1f}%   "
              f"test alone: {100 * reject_share(solver, args.steps):.2f}% of a step", flush=True)


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
