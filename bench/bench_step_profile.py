"""Benchmark: where the time of one solver step goes (TGV, 3D or 2D, standard SPH by default).

Times, at one resolution, with the same state and list:

  chunk        a jitted `make_chunk` of `--steps` steps with the step guard (what the runs do), per step
  rebuilds     how many of those steps rebuilt the neighbour list (Verlet skin)
  check        the neighbour update that does not rebuild (the skin test + `lax.cond`)
  build        one forced neighbour-list build with the list's capacities
  pairs        the pair geometry (dr, |r|, W, dW/dr / r over the K slots), materialised
  density      the density pass (summation), in blocks as the step evaluates it (its geometry included)
  accel        the force pass's momentum term (or the Riemann one), likewise
  step_nb      one jitted step without a rebuild (`step_fn` with a list whose skin test passes)

and the neighbour statistics: K slots, mean real neighbours within the search radius and within
the kernel support (the padding waste). Min and median over `--repeats` calls each; the machine is
shared, so compare within one run only.

    python bench/bench_step_profile.py --dim 3 --n 20 32 [--method sph|tvf|riemann] [--steps 12]
"""
import argparse
import dataclasses
import time

import jax
import numpy as np

import sph
import sph.blocks
from sph.density import Summation
from sph.momentum import Momentum
from sph.riemann import RiemannMomentum
from sph.rollout import make_chunk

try:
    from bench_scaling import count_rebuilds, tgv2d_scene, tgv3d_scene
except ImportError:  # imported as bench.bench_step_profile
    from bench.bench_scaling import count_rebuilds, tgv2d_scene, tgv3d_scene

METHODS = {"sph": sph.Effects(), "tvf": sph.Effects(tvf=True),
           "riemann": sph.Effects(riemann=True, density_evolution=True)}


def timed(fn, *args, repeats=5):
    """(min, median) seconds of fn(*args) after one warm-up call."""
    jax.block_until_ready(fn(*args))
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        ts.append(time.perf_counter() - t0)
    return min(ts), float(np.median(ts))


def profile(scene, method, steps, repeats, numerics):
    solver = sph.build_solver(scene, numerics)
    state, nbrs = solver.init_fn()
    out = {"n": scene.n, "K": nbrs.max_occupancy, "C": getattr(nbrs, "cell_list_capacity", 0) or 0}
    n = scene.n
    idx = np.asarray(nbrs.idx)
    out["nbrs_search"] = float(np.mean(np.sum(idx < n, axis=1)))
    pairs = jax.jit(solver.pairs_fn)(state.r, nbrs)
    d = np.asarray(pairs.d)
    out["nbrs_support"] = float(np.mean(np.sum(d < solver.kernel.cutoff, axis=1)))

    chunk = jax.jit(make_chunk(solver.step_fn, steps, guard=solver.guard))
    t, tm = timed(chunk, state, nbrs, 0, steps, repeats=max(2, repeats // 2))
    res = chunk(state, nbrs, 0, steps)
    assert int(res[2]) == steps and not bool(res[3])
    out["chunk"] = (t / steps, tm / steps)
    # the same chunk without the step guard, and without the neighbour update (the list is kept)
    nog = jax.jit(make_chunk(solver.step_fn, steps))
    t, tm = timed(nog, state, nbrs, 0, steps, repeats=max(2, repeats // 2))
    out["chunk_noguard"] = (t / steps, tm / steps)
    impl = solver.neighbors.impl

    class Keep:
        def update(self, r, nb):
            return nb

    object.__setattr__(solver.neighbors, "impl", Keep())
    noup = jax.jit(make_chunk(solver.step_fn, steps))
    t, tm = timed(noup, state, nbrs, 0, steps, repeats=max(2, repeats // 2))
    object.__setattr__(solver.neighbors, "impl", impl)
    out["chunk_noupdate"] = (t / steps, tm / steps)
    out["rebuilds"] = count_rebuilds(solver, state, nbrs, steps)

    update = jax.jit(solver.neighbors.update)
    out["check"] = timed(update, state.r, nbrs, repeats=repeats)
    if solver.numerics.neighbor_search == "cell_sort":
        build = jax.jit(lambda r: impl._build(r, nbrs.cell_list_capacity, nbrs.max_occupancy))
        out["build"] = timed(build, state.r, repeats=repeats)
    else:
        moved = state.r.at[0, 0].add(solver.neighbors.skin)
        out["build"] = timed(update, moved, nbrs, repeats=repeats)
    out["pairs"] = timed(jax.jit(solver.pairs_fn), state.r, nbrs, repeats=repeats)
    fields = dict(r=state.r, u=state.u, u_visc=state.u, v_stress=state.v, rho=state.rho, p=state.p,
                  mass=state.mass, vol=state.mass / state.rho)

    def sweep(term):
        return jax.jit(lambda nb, f: solver.sweep_fn(term, nb, **f))

    out["density"] = timed(sweep(Summation(float(solver.kernel.w(0.0)))), nbrs, fields, repeats=repeats)
    eta = scene.material.eta
    if scene.effects.riemann:
        term = RiemannMomentum(eta, solver.c_ref, solver.numerics.eta_limiter)
    else:
        term = Momentum(eta, scene.effects.tvf)
    out["accel"] = timed(sweep(term), nbrs, fields, repeats=repeats)
    # a step that does not rebuild: the list's reference is the position the step moves to
    r_next = solver.step_fn(state, nbrs, 1)[0].r
    nb_next = dataclasses.replace(nbrs, reference_position=r_next)
    out["step_nb"] = timed(jax.jit(solver.step_fn), state, nb_next, 1, repeats=repeats)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dim", type=int, default=3, choices=[2, 3])
    ap.add_argument("--n", type=int, nargs="+", default=[20, 32], help="particles per side")
    ap.add_argument("--method", default="sph", choices=list(METHODS))
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--backend", default="cell_sort")
    ap.add_argument("--dtype", default="float64")
    ap.add_argument("--skin", type=float, default=None, help="numerics.skin_factor (default: Numerics')")
    ap.add_argument("--block", type=int, default=None, help="sph.blocks.BLOCK_PAIRS (0: unblocked)")
    args = ap.parse_args()
    sph.precision.enable_x64()
    kw = dict(dtype=args.dtype, neighbor_search=args.backend)
    if args.skin is not None:
        kw["skin_factor"] = args.skin
    numerics = sph.Numerics(**kw)
    if args.block is not None:
        sph.blocks.BLOCK_PAIRS = args.block or (1 << 62)
    print(f"jax {jax.__version__}, {args.dim}D {args.method}, {args.backend}, {args.dtype}, skin {numerics.skin_factor} dx; "
          "ms: min / median")
    keys = ["chunk", "chunk_noguard", "chunk_noupdate", "check", "build", "pairs", "density", "accel", "step_nb"]
    for side in args.n:
        make = tgv3d_scene if args.dim == 3 else tgv2d_scene
        o = profile(make(side, METHODS[args.method]), args.method, args.steps, args.repeats, numerics)
        print(f"n = {side}^{args.dim} = {o['n']}: K = {o['K']}, C = {o['C']}, neighbours within search radius "
              f"{o['nbrs_search']:.1f}, within support {o['nbrs_support']:.1f} "
              f"(slot use {o['nbrs_support'] / o['K']:.0%}); rebuilds {o['rebuilds']} / {args.steps} steps")
        print("   " + "  ".join(f"{k} {1e3 * o[k][0]:.1f}/{1e3 * o[k][1]:.1f}" for k in keys), flush=True)


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
