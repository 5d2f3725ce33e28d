"""Benchmark: time per step and peak memory against particle count, 2D and 3D TGV (`make scaling`).

Per size: the steady-state time per step of a jitted `lax.scan` chunk (compilation excluded,
neighbour-list updates included at their natural rate), split into the neighbour search (one list
build, times the measured rebuilds per step) and the rest (pair geometry and physics: the chunk
time minus the amortised search), the number of neighbour slots K, and the peak memory of one
chunk as XLA plans it (arguments + outputs + temporaries of the compiled chunk, i.e. what the step
needs beyond the Python process). Fits the exponent b of time ~ N^b per dimension (the goal: b ~ 1).

Writes results/bench/scaling.csv and scaling.png; prints a table.

    python bench/bench_scaling.py                    # 2D 32^2 .. 1000^2, 3D 20^3 .. 63^3
    python bench/bench_scaling.py --quick            # a few small sizes
    python bench/bench_scaling.py --backend jax_md   # the reference search
"""
import argparse
import csv
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

import sph
from sph.domain import Domain
from sph.lattice import cartesian, jitter
from sph.rollout import make_chunk
from sph.scene import Scene
from sph.state import FLUID

GB = 1024.0**3


def tgv2d_scene(n_side, effects=sph.Effects()):
    """2D TGV on the unit square, n_side^2 particles (lattice + 0.05 dx noise)."""
    dx = 1.0 / n_side
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), 0.05 * dx, seed=0, box=(1.0, 1.0))
    x, y = r[:, 0], r[:, 1]
    u = np.stack([-np.cos(2 * np.pi * x) * np.sin(2 * np.pi * y),
                  np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)], axis=1)
    return Scene(name="tgv2d", dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)),
                 material=sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0), effects=effects, r=r, u=u,
                 tag=np.full(len(r), FLUID, np.int32))


def tgv3d_scene(n_side, effects=sph.Effects()):
    """3D TGV in the periodic box (2 pi)^3, n_side^3 particles (lattice + 0.05 dx noise):
    u = sin x cos y cos z, v = -cos x sin y cos z, w = 0, Re = 100."""
    box = 2.0 * np.pi
    dx = box / n_side
    r = jitter(cartesian([0.0] * 3, [box] * 3, dx), 0.05 * dx, seed=0, box=(box,) * 3)
    x, y, z = r.T
    u = np.stack([np.sin(x) * np.cos(y) * np.cos(z), -np.cos(x) * np.sin(y) * np.cos(z), 0.0 * x], axis=1)
    return Scene(name="tgv3d", dx=dx, domain=Domain(box=(box,) * 3, periodic=(True,) * 3),
                 material=sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0), effects=effects, r=r, u=u,
                 tag=np.full(len(r), FLUID, np.int32))


def best_time(fn, *args, repeats: int):
    """(best wall seconds of `repeats` calls of fn(*args), the last output), after one warm-up call
    (caches, allocator); every call waits for its result (block_until_ready)."""
    out = fn(*args)
    jax.block_until_ready(out)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn(*args)
        jax.block_until_ready(out)
        best = min(best, time.perf_counter() - t0)
    return best, out


def time_chunk(solver, state, nbrs, steps: int, repeats: int):
    """(compiled chunk, compile seconds, best seconds of one chunk): `make_chunk` of `steps` steps
    from (state, nbrs), compiled ahead and timed with `best_time`; fails if the list overflowed."""
    chunk = jax.jit(make_chunk(solver.step_fn, steps))
    t0 = time.perf_counter()
    compiled = chunk.lower(state, nbrs, 0, steps).compile()
    compile_s = time.perf_counter() - t0
    chunk_s, out = best_time(compiled, state, nbrs, 0, steps, repeats=repeats)
    assert int(out[2]) == steps and not bool(out[3]), "benchmark run overflowed its neighbour list"
    return compiled, compile_s, chunk_s


def _plan_bytes(compiled):
    ma = compiled.memory_analysis()
    return ma.argument_size_in_bytes + ma.output_size_in_bytes + ma.temp_size_in_bytes - ma.alias_size_in_bytes



def count_rebuilds(solver, state, nbrs, steps: int) -> int:
    """Neighbour-list rebuilds in `steps` steps from (state, nbrs): stepped one at a time, a rebuild
    is a change of the list's reference positions."""
    step = jax.jit(solver.step_fn)
    s, nb, rebuilds = state, nbrs, 0
    for k in range(steps):
        s, nb2 = step(s, nb, k + 1)
        rebuilds += int(not np.array_equal(np.asarray(nb2.reference_position), np.asarray(nb.reference_position)))
        nb = nb2
    return rebuilds

def measure(scene, steps, backend="cell_sort", dtype="float64", repeats=2):
    """Time per step (chunk of `steps`), search share and planned memory of one scene."""
    solver = sph.build_solver(scene, sph.Numerics(dtype=dtype, neighbor_search=backend))
    state, nbrs = solver.init_fn()
    compiled, compile_s, chunk_s = time_chunk(solver, state, nbrs, steps, repeats)
    rebuilds = count_rebuilds(solver, state, nbrs, steps)
    # one forced build with the list's capacities
    impl = solver.neighbors.impl
    if backend == "cell_sort":
        build = jax.jit(lambda r: impl._build(r, nbrs.cell_list_capacity, nbrs.max_occupancy))
        build_s, _ = best_time(build, state.r, repeats=repeats)
        build_bytes = _plan_bytes(build.lower(state.r).compile())
    else:
        moved = state.r.at[0, 0].add(solver.neighbors.skin)  # one particle past skin / 2: a rebuild
        build_s, _ = best_time(jax.jit(impl.update), moved, nbrs, repeats=repeats)
        build_bytes = _plan_bytes(jax.jit(impl.update).lower(moved, nbrs).compile())
    per_step = chunk_s / steps
    search_per_step = build_s * rebuilds / steps
    return dict(dim=scene.dim, n=scene.n, backend=backend, dtype=dtype, K=nbrs.max_occupancy,
                C=nbrs.cell_list_capacity or 0, steps=steps, rebuilds=rebuilds, compile_s=compile_s,
                ms_per_step=1e3 * per_step, build_ms=1e3 * build_s,
                search_share=min(search_per_step / per_step, 1.0),
                chunk_GB=_plan_bytes(compiled) / GB, build_GB=build_bytes / GB)


FIELDS = ["dim", "n", "backend", "dtype", "K", "C", "steps", "rebuilds", "compile_s", "ms_per_step",
          "build_ms", "search_share", "chunk_GB", "build_GB"]


def fit_exponent(n, t):
    return float(np.polyfit(np.log(n), np.log(t), 1)[0]) if len(n) > 1 else float("nan")


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for dim, marker in ((2, "o"), (3, "s")):
        sel = [r for r in rows if r["dim"] == dim]
        if not sel:
            continue
        n = np.array([r["n"] for r in sel], float)
        t = np.array([r["ms_per_step"] for r in sel])
        m = np.array([r["chunk_GB"] for r in sel])
        b = fit_exponent(n, t)
        axes[0].loglog(n, t, marker + "-", label=f"{dim}D, time ~ N^{b:.2f}")
        axes[0].loglog(n, t * np.array([r["search_share"] for r in sel]), marker + ":",
                       label=f"{dim}D neighbour search (amortised)")
        axes[1].loglog(n, m, marker + "-", label=f"{dim}D, memory ~ N^{fit_exponent(n, m):.2f}")
    axes[0].set(xlabel="particles N", ylabel="ms per step", title="TGV, standard SPH, time per step")
    axes[1].set(xlabel="particles N", ylabel="GB (XLA plan of one chunk)", title="peak memory")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--backend", default="cell_sort", choices=["cell_sort", "jax_md"])
    ap.add_argument("--dtype", default="float64", choices=["float64", "float32"])
    ap.add_argument("--sides2d", default=None, help="comma-separated particles per side, 2D")
    ap.add_argument("--sides3d", default=None, help="comma-separated particles per side, 3D")
    ap.add_argument("--out", default="results/bench")
    args = ap.parse_args()
    sph.precision.enable_x64()
    sides2d = [32, 64] if args.quick else [32, 64, 128, 256, 512, 1000]   # 10^3 ... 10^6 particles
    sides3d = [12, 16] if args.quick else [20, 32, 40, 50, 63]            # 8 10^3 ... 2.5 10^5
    if args.sides2d is not None:
        sides2d = [int(s) for s in args.sides2d.split(",") if s]
    if args.sides3d is not None:
        sides3d = [int(s) for s in args.sides3d.split(",") if s]
    os.makedirs(args.out, exist_ok=True)
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {args.backend}, {args.dtype}")
    print(f"{'dim':>3s} {'N':>8s} {'K':>4s} {'C':>4s} {'rebuilds':>8s} {'compile s':>9s} {'ms/step':>9s} "
          f"{'build ms':>9s} {'search %':>8s} {'chunk GB':>8s} {'build GB':>8s}")
    rows = []
    jobs = [(tgv2d_scene, s, 40) for s in sides2d] + [(tgv3d_scene, s, 12) for s in sides3d]
    for make, side, steps in jobs:
        r = measure(make(side), steps, args.backend, args.dtype)
        rows.append(r)
        print(f"{r['dim']:3d} {r['n']:8d} {r['K']:4d} {r['C']:4d} {r['rebuilds']:8d} {r['compile_s']:9.1f} "
              f"{r['ms_per_step']:9.2f} {r['build_ms']:9.1f} {100 * r['search_share']:8.1f} "
              f"{r['chunk_GB']:8.3f} {r['build_GB']:8.3f}", flush=True)
        with open(os.path.join(args.out, "scaling.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=FIELDS)
            w.writeheader()
            w.writerows(rows)
    for dim in (2, 3):
        sel = [r for r in rows if r["dim"] == dim]
        if len(sel) > 1:
            print(f"{dim}D: time ~ N^{fit_exponent([r['n'] for r in sel], [r['ms_per_step'] for r in sel]):.2f}")
    plot(rows, os.path.join(args.out, "scaling.png"))
    print(f"wrote {args.out}/scaling.csv, scaling.png")


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
