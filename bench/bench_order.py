"""Benchmark: what particle order costs, measured on the positions of a finished 3D TGV run.

The solver keeps the particles in the scene's order. A run starts from a lattice (or relaxed
lattice) in lattice order, whose neighbours are close in memory; as the vortex moves the particles,
a particle's neighbours drift apart in the arrays and the gathers x[j] of the pair sums miss the
cache more often. Reordering the particles by cell every so often would undo that. This benchmark
says what that could buy, on the positions a run actually reached: it times a jitted chunk of steps
(standard SPH, the run's numerics, compilation excluded, interleaved, min and median of `--rounds`)
from three arrangements of the same particles:

* `start`: the first frame of the run, in its order (the order a run starts with);
* `end`: the last frame (t = t_end), in the same order (what the run pays at its end);
* `end_sorted`: the last frame, particles sorted by cell (x-major cells of side dx: the order a
  periodic reordering would restore).

The velocities are the TGV field at each position (only the positions' order matters for the cost).
Prints the table; `end / end_sorted` is the most a periodic reordering could save at the end of
the run, `end / start` what the run lost over its course.

    python bench/bench_order.py results/paper/tgv3d/sph_n50/traj.h5
"""
import argparse
import dataclasses
import time

import h5py
import jax
import numpy as np

import sph
from sph.rollout import make_chunk

try:
    from bench_scaling import tgv3d_scene
except ImportError:
    from bench.bench_scaling import tgv3d_scene


def cell_order(r, dx, box):
    """Indices that sort positions r (N, 3) by their cell of side dx (x-major, then y, then z)."""
    n = int(round(box / dx))
    c = np.clip(np.floor(np.mod(r, box) / dx).astype(np.int64), 0, n - 1)
    return np.argsort((c[:, 0] * n + c[:, 1]) * n + c[:, 2], kind="stable")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("traj", help="traj.h5 of a tgv3d run (LagrangeBench layout)")
    ap.add_argument("--steps", type=int, default=11)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--dtype", default="float64", choices=["float64", "float32"])
    args = ap.parse_args()
    sph.precision.enable_x64()
    with h5py.File(args.traj, "r") as f:
        g = f["00000"]
        first = np.asarray(g["position"][0], float)
        last = np.asarray(g["position"][-1], float)
        t_last = float(g["time"][-1]) if "time" in g else float("nan")
    n_side = int(round(first.shape[0] ** (1 / 3)))
    base = tgv3d_scene(n_side)
    box = base.domain.box[0]
    arrangements = {"start": first, "end": last, "end_sorted": last[cell_order(last, base.dx, box)]}
    chunks = {}
    for name, r in arrangements.items():
        r = np.mod(r, box)
        x, y, z = r.T
        u = np.stack([np.sin(x) * np.cos(y) * np.cos(z), -np.cos(x) * np.sin(y) * np.cos(z), 0.0 * x], axis=1)
        scene = dataclasses.replace(base, r=r, u=u)
        solver = sph.build_solver(scene, sph.Numerics(dtype=args.dtype, neighbor_search="cell_sort"))
        state, nbrs = solver.init_fn()
        chunk = jax.jit(make_chunk(solver.step_fn, args.steps)).lower(state, nbrs, 0, args.steps).compile()
        out = chunk(state, nbrs, 0, args.steps)
        jax.block_until_ready(out)
        assert int(out[2]) == args.steps and not bool(out[3]), f"{name}: the chunk overflowed its list"
        chunks[name] = (chunk, state, nbrs)
    times = {k: [] for k in chunks}
    for _ in range(args.rounds):
        for name, (chunk, state, nbrs) in chunks.items():
            t0 = time.perf_counter()
            jax.block_until_ready(chunk(state, nbrs, 0, args.steps))
            times[name].append(1e3 * (time.perf_counter() - t0) / args.steps)
    print(f"{args.traj}: {first.shape[0]} particles, last frame t = {t_last:g}; {args.dtype}, "
          f"standard SPH, {args.steps}-step chunks x {args.rounds} rounds")
    print(f"{'arrangement':12s} {'min ms/step':>11s} {'median':>8s}")
    for name, ts in times.items():
        print(f"{name:12s} {min(ts):11.2f} {np.median(ts):8.2f}")
    lo = {k: min(v) for k, v in times.items()}
    print(f"end / start {lo['end'] / lo['start']:.3f}   end / end_sorted {lo['end'] / lo['end_sorted']:.3f}")


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
