"""Benchmark: neighbour-list build and update of the sort-based cell list against jax-md's.

For TGV-like lattices (0.05 dx noise) in 2D (unit square) and 3D ((2 pi)^3), periodic, search
radius 3.5 dx (quintic support 3 h, h = dx, skin 0.5 dx), both backends (`sph.neighbors`):
allocate (not jitted, includes compilation), a forced rebuild under `jit` (one particle moved past
skin / 2), the no-rebuild update (the Verlet-skin check, what most steps pay), the slots K and the
memory XLA plans for the rebuild (arguments + outputs + temporaries). Timings: best of `--repeats`,
interleaved between the backends. Prints a table.

    python bench/bench_neighbors.py            # 2D 50^2, 100^2, 200^2; 3D 20^3, 32^3
    python bench/bench_neighbors.py --quick    # 2D 50^2, 3D 16^3
"""
import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import sph
from sph.domain import Domain
from sph.lattice import cartesian, jitter
from sph.neighbors import make_neighbor_search

GB = 1024.0**3


def lattice(dim, side):
    box = 1.0 if dim == 2 else 2.0 * np.pi
    dx = box / side
    r = jitter(cartesian([0.0] * dim, [box] * dim, dx), 0.05 * dx, seed=0, box=(box,) * dim)
    return Domain(box=(box,) * dim, periodic=(True,) * dim), r, dx


def _plan_gb(compiled):
    ma = compiled.memory_analysis()
    return (ma.argument_size_in_bytes + ma.output_size_in_bytes + ma.temp_size_in_bytes
            - ma.alias_size_in_bytes) / GB


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dtype", default="float64", choices=["float64", "float32"])
    args = ap.parse_args()
    sph.precision.enable_x64()
    dtype = jnp.float64 if args.dtype == "float64" else jnp.float32
    sizes = [(2, 50), (3, 16)] if args.quick else [(2, 50), (2, 100), (2, 200), (3, 20), (3, 32)]
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {args.dtype}")
    print(f"{'dim':>3s} {'N':>7s} {'backend':9s} {'K':>4s} {'allocate s':>10s} {'rebuild ms':>10s} "
          f"{'check ms':>9s} {'rebuild GB':>10s}")
    for dim, side in sizes:
        domain, r, dx = lattice(dim, side)
        r = jnp.asarray(r, dtype)
        moved = r.at[0, 0].add(0.3 * dx)  # > skin / 2 = 0.25 dx: forces a rebuild
        res, fns = {}, {}
        for backend in ("cell_sort", "jax_md"):
            search = make_neighbor_search(domain, 3.0 * dx, 0.5 * dx, backend=backend)
            t0 = time.perf_counter()
            nbrs = search.allocate(r)
            jax.block_until_ready(nbrs.idx)
            alloc_s = time.perf_counter() - t0
            update = jax.jit(search.update).lower(r, nbrs).compile()
            fns[backend] = (update, nbrs)
            res[backend] = dict(K=nbrs.max_occupancy, alloc_s=alloc_s, GB=_plan_gb(update),
                                rebuild=np.inf, check=np.inf)
        for _ in range(args.repeats):
            for backend, (update, nbrs) in fns.items():
                for key, pos in (("rebuild", moved), ("check", r)):
                    jax.block_until_ready(update(pos, nbrs).idx)
                    t0 = time.perf_counter()
                    jax.block_until_ready(update(pos, nbrs).idx)
                    res[backend][key] = min(res[backend][key], time.perf_counter() - t0)
        for backend, m in res.items():
            print(f"{dim:3d} {r.shape[0]:7d} {backend:9s} {m['K']:4d} {m['alloc_s']:10.2f} "
                  f"{1e3 * m['rebuild']:10.1f} {1e3 * m['check']:9.2f} {m['GB']:10.3f}", flush=True)
        print(f"    rebuild ratio jax_md / cell_sort: {res['jax_md']['rebuild'] / res['cell_sort']['rebuild']:.1f}")


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
