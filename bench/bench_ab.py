"""Benchmark: interleaved A/B timing of solver variants on one TGV scene (this machine is shared and
noisy, so variants are timed in alternation, A, B, C, A, B, C, ..., and compared by min and median).

A variant is a comma-separated list of settings: numerics fields (`skin_factor=0.3`,
`neighbor_search=jax_md`, `dtype=float32`, `capacity_multiplier=1.1`) and `block=<slots>`
(`sph.pairs.BLOCK_PAIRS`, read when the step is traced; `block=0`: unblocked). Each variant runs
jitted chunks of `--steps` steps (`sph.rollout.make_chunk` with the step guard, as the runs do) from
the same start; compilation is excluded.

    python bench/bench_ab.py --dim 3 --n 32 --variants "block=0" "block=65536"
    python bench/bench_ab.py --dim 2 --n 50 --method tvf --variants "neighbor_search=jax_md" "neighbor_search=cell_sort"
"""
import argparse
import time

import jax
import numpy as np

import sph
import sph.pairs
from sph.rollout import make_chunk

try:
    from bench_scaling import tgv2d_scene, tgv3d_scene
except ImportError:
    from bench.bench_scaling import tgv2d_scene, tgv3d_scene

METHODS = {"sph": sph.Effects(), "tvf": sph.Effects(tvf=True),
           "riemann": sph.Effects(riemann=True, density_evolution=True)}


def parse(variant):
    kw, block = {}, sph.pairs.BLOCK_PAIRS
    for item in filter(None, variant.split(",")):
        key, value = item.split("=")
        if key == "block":
            block = int(value) or (1 << 62)
            continue
        field = sph.Numerics.__dataclass_fields__[key]
        kw[key] = value if field.type in (str, "str") else int(value) if field.type in (int, "int") else float(value)
    return kw, block


def prepare(scene, variant, steps):
    kw, block = parse(variant)
    sph.pairs.BLOCK_PAIRS = block
    solver = sph.build_solver(scene, sph.Numerics(**kw))
    state, nbrs = solver.init_fn()
    chunk = jax.jit(make_chunk(solver.step_fn, steps, guard=solver.guard)).lower(state, nbrs, 0, steps).compile()
    out = chunk(state, nbrs, 0, steps)
    jax.block_until_ready(out)
    assert int(out[2]) == steps and not bool(out[3]), f"{variant}: the chunk overflowed or stopped"
    return lambda: jax.block_until_ready(chunk(state, nbrs, 0, steps)), int(nbrs.idx.shape[1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dim", type=int, default=3, choices=[2, 3])
    ap.add_argument("--n", type=int, default=20, help="particles per side")
    ap.add_argument("--method", default="sph", choices=list(METHODS))
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--variants", nargs="+", required=True)
    args = ap.parse_args()
    sph.precision.enable_x64()
    make = tgv3d_scene if args.dim == 3 else tgv2d_scene
    scene = make(args.n, METHODS[args.method])
    runs, slots = {}, {}
    for v in args.variants:
        runs[v], slots[v] = prepare(scene, v, args.steps)
    times = {v: [] for v in args.variants}
    for _ in range(args.rounds):
        for v in args.variants:
            t0 = time.perf_counter()
            runs[v]()
            times[v].append((time.perf_counter() - t0) / args.steps)
    base = args.variants[0]
    print(f"{args.dim}D {args.method} n = {args.n} ({scene.n} particles), {args.steps} steps per chunk, "
          f"{args.rounds} rounds interleaved; ms per step")
    for v in args.variants:
        t = np.array(times[v]) * 1e3
        print(f"  {v or '(default)':45s} K {slots[v]:4d}  min {t.min():9.2f}  median {np.median(t):9.2f}  "
              f"ratio to first: min {t.min() / (1e3 * min(times[base])):.3f}  "
              f"median {np.median(t) / (1e3 * np.median(times[base])):.3f}", flush=True)


if __name__ == "__main__":
    main()
