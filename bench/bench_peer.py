"""Benchmark: JAX-SPH 0.1.0's solver step against this project's, side by side (`make bench-peer`).

Runs in `.venv-lb` (JAX-SPH 0.1.0 installed there; `lbcompat` restores the jax aliases it imports;
same jax as the core environment). Both codes advance the same scene (same positions, velocities,
time step, quintic kernel h = dx, Tait EoS, c_ref = 10 U, periodic box):

* JAX-SPH: its `WCSPH` + `si_euler` + neighbour list exactly as its `simulate.py` builds them
  (Sparse jax-md list, backend "jaxmd_vmap", capacity_multiplier 1.25, no skin: rebuilt every step),
  one jitted `advance` call per step, as its simulation loop does.
* this project: `sph.build_solver` + a jitted `lax.scan` chunk of the same steps (the way every run
  here advances), neighbour search `--backend` (default cell_sort, Verlet skin 0.5 dx).

Timings alternate A, B, A, B, ... (`--repeats` rounds of `--steps` steps each, after one warm-up
round that also compiles); min and median time per step of each and the ratio JAX-SPH / ours.
This machine is shared and noisy: only ratios from the same run mean anything.
Writes results/bench/peer.csv and prints a table.

    .venv-lb/bin/python bench/bench_peer.py                 # TGV 2D dx 0.02 (SPH, TVF, f64/f32), 3D 20^3, 32^3
    .venv-lb/bin/python bench/bench_peer.py --quick         # 2D SPH f64 and 3D 12^3 only
"""
import argparse
import csv
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lbcompat import apply_jax_aliases  # noqa: E402

apply_jax_aliases()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import sph  # noqa: E402
from bench_scaling import tgv2d_scene, tgv3d_scene  # noqa: E402
from sph.rollout import make_chunk  # noqa: E402


# ---------------------------------------------------------------------------------------------------
# the peer: JAX-SPH 0.1.0, assembled as its simulate.py does
# ---------------------------------------------------------------------------------------------------

def peer_advance(scene, dt, tvf: bool, dtype):
    """JAX-SPH's jitted `advance(dt, state, neighbors)`, its initial state and neighbour list."""
    from jax_sph import partition
    from jax_sph.eos import TaitEoS
    from jax_sph.integrator import si_euler
    from jax_sph.jax_md import space
    from jax_sph.jax_md.partition import Sparse
    from jax_sph.solver import WCSPH
    from jax_sph.utils import Tag

    dim, dx, mat = scene.dim, scene.dx, scene.material
    box = np.asarray(scene.domain.box, float)
    c_ref = 10.0 * mat.u_ref
    p_ref = mat.rho_ref * c_ref**2  # gamma = 1
    p_bg = 0.0
    eos = TaitEoS(p_ref, mat.rho_ref, p_bg, 1.0)
    displacement_fn, shift_fn = space.periodic(side=jnp.asarray(box, dtype))
    n = scene.n
    r = jnp.asarray(scene.r, dtype)
    u = jnp.asarray(scene.u, dtype)
    rho = jnp.full(n, mat.rho_ref, dtype)
    state = {"r": r, "tag": jnp.full(n, Tag.FLUID, dtype=int), "u": u, "v": u,
             "dudt": jnp.zeros_like(u), "dvdt": jnp.zeros_like(u), "drhodt": jnp.zeros_like(rho),
             "rho": rho, "p": eos.p_fn(rho), "mass": jnp.full(n, mat.rho_ref * dx**dim, dtype),
             "eta": jnp.full(n, mat.eta, dtype), "dTdt": jnp.zeros_like(rho), "T": jnp.ones_like(rho),
             "kappa": jnp.zeros_like(rho), "Cp": jnp.zeros_like(rho), "nw": jnp.zeros_like(r)}
    solver = WCSPH(displacement_fn, eos, lambda r: jnp.zeros_like(r), dx, dim, dt, c_ref, 3, "SPH", "QSK",
                   False, False, 0.0, False, False, False)
    forward = solver.forward_wrapper()
    neighbor_fn = partition.neighbor_list(displacement_fn, jnp.asarray(box, dtype), r_cutoff=solver._kernel_fn.cutoff,
                                          backend="jaxmd_vmap", capacity_multiplier=1.25, mask_self=False,
                                          format=Sparse, num_particles_max=n, num_partitions=1,
                                          pbc=np.array([True] * dim))
    neighbors = neighbor_fn.allocate(state["r"], num_particles=n)
    advance = jax.jit(si_euler(1.0 if tvf else 0.0, forward, shift_fn, lambda s: s, None))
    state, neighbors = advance(0.0, state, neighbors)  # compile; initial accelerations (as simulate.py)
    jax.block_until_ready(state["v"])

    def run(steps):
        nonlocal state, neighbors
        for _ in range(steps):
            new_state, new_nbrs = advance(dt, state, neighbors)
            if new_nbrs.did_buffer_overflow:
                neighbors = neighbor_fn.allocate(state["r"], num_particles=n)
                continue
            state, neighbors = new_state, new_nbrs
        jax.block_until_ready(state["r"])

    return run, int(neighbors.idx.shape[1])


# ---------------------------------------------------------------------------------------------------
# this project
# ---------------------------------------------------------------------------------------------------

def ours_advance(scene, dtype: str, backend: str):
    solver = sph.build_solver(scene, sph.Numerics(dtype=dtype, neighbor_search=backend))
    state, nbrs = solver.init_fn()
    chunks = {}
    carry = [state, nbrs, 0]

    def run(steps):
        if steps not in chunks:
            chunks[steps] = jax.jit(make_chunk(solver.step_fn, steps))
        state, nbrs, step = carry
        state, nbrs, _ = sph.rollout.advance(chunks[steps], solver.neighbors, state, nbrs, step, steps)
        jax.block_until_ready(state.r)
        carry[:] = [state, nbrs, step + steps]

    return run, solver.dt, int(nbrs.max_occupancy)


CASES = {
    "tgv2d_dx0.02_sph_f64": (lambda: tgv2d_scene(50), "float64", False, 100),
    "tgv2d_dx0.02_tvf_f64": (lambda: tgv2d_scene(50, sph.Effects(tvf=True)), "float64", True, 100),
    "tgv2d_dx0.02_sph_f32": (lambda: tgv2d_scene(50), "float32", False, 100),
    "tgv3d_20_sph_f64": (lambda: tgv3d_scene(20), "float64", False, 6),
    "tgv3d_32_sph_f64": (lambda: tgv3d_scene(32), "float64", False, 3),
}
QUICK = {"tgv2d_dx0.02_sph_f64": CASES["tgv2d_dx0.02_sph_f64"],
         "tgv3d_12_sph_f64": (lambda: tgv3d_scene(12), "float64", False, 6)}


def bench_case(name, make, dtype, tvf, steps, repeats, backend):
    scene = make()
    ours, dt, k_ours = ours_advance(scene, dtype, backend)
    theirs, k_theirs = peer_advance(scene, dt, tvf, jnp.float64 if dtype == "float64" else jnp.float32)
    ours(steps)  # compile and warm up
    theirs(steps)
    times = {"jax_sph": [], "ours": []}
    for _ in range(repeats):
        for who, fn in (("jax_sph", theirs), ("ours", ours)):
            t0 = time.perf_counter()
            fn(steps)
            times[who].append((time.perf_counter() - t0) / steps)
    t_j, t_o = np.array(times["jax_sph"]), np.array(times["ours"])
    return dict(case=name, n=scene.n, dtype=dtype, backend=backend, steps=steps, repeats=repeats,
                K_ours=k_ours, edges_jax_sph=k_theirs,
                jax_sph_min_ms=1e3 * t_j.min(), jax_sph_median_ms=1e3 * np.median(t_j),
                ours_min_ms=1e3 * t_o.min(), ours_median_ms=1e3 * np.median(t_o),
                ratio_min=t_j.min() / t_o.min(), ratio_median=np.median(t_j) / np.median(t_o))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cases", default=None, help="comma-separated subset of " + ",".join(CASES))
    ap.add_argument("--backend", default="cell_sort", choices=["cell_sort", "jax_md"])
    ap.add_argument("--out", default="results/bench")
    args = ap.parse_args()
    sph.precision.enable_x64()
    cases = QUICK if args.quick else CASES
    if args.cases:
        cases = {k: CASES[k] for k in args.cases.split(",")}
    os.makedirs(args.out, exist_ok=True)
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}; interleaved JAX-SPH, ours; ratio = JAX-SPH / ours")
    print(f"{'case':24s} {'N':>7s} {'JAX-SPH min':>11s} {'median':>9s} {'ours min':>9s} {'median':>9s} "
          f"{'ratio min':>9s} {'median':>7s}  (ms per step)")
    rows = []
    for name, (make, dtype, tvf, steps) in cases.items():
        r = bench_case(name, make, dtype, tvf, steps, args.repeats, args.backend)
        rows.append(r)
        print(f"{r['case']:24s} {r['n']:7d} {r['jax_sph_min_ms']:11.2f} {r['jax_sph_median_ms']:9.2f} "
              f"{r['ours_min_ms']:9.2f} {r['ours_median_ms']:9.2f} {r['ratio_min']:9.2f} {r['ratio_median']:7.2f}",
              flush=True)
        with open(os.path.join(args.out, "peer.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    print(f"wrote {args.out}/peer.csv")


if __name__ == "__main__":
    main()
