"""Benchmark: what an effect costs, and that an undeclared effect costs nothing (a script, not a test).

The same scene is timed with and without one extra declared effect that has (almost) nothing to do:
heat with a uniform temperature, or a small artificial viscosity in a tank at rest. The difference
is the price of evaluating the effect; a scene that does not declare it never traces it (see
tests/core/test_effects.py), so it pays nothing. Timings share the machine: compare rows of one run.

    python bench/bench_effects.py [--steps 200]
"""
import argparse
import dataclasses

import numpy as np

import sph
from sph.cases import tank, tgv
from sph.lattice import cartesian, jitter

try:
    from bench_scaling import time_chunk
except ImportError:  # imported as bench.bench_effects
    from bench.bench_scaling import time_chunk

HOT = dict(kappa=0.01, c_p=1.0)


def _heat(scene):
    return dataclasses.replace(scene, material=dataclasses.replace(scene.material, **HOT),
                               effects=dataclasses.replace(scene.effects, heat=True), T=np.ones(scene.n))


def scenes(dx):
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), 0.1 * dx, seed=0, box=(1.0, 1.0))
    tgv_plain = tgv.scene(dx, sph.Material(eta=0.01), sph.Effects(), r=r)
    mat = sph.Material(eta=0.01, u_ref=tank.u_ref(1.0, 1.0))
    fx = sph.Effects(gravity=(0.0, -1.0), walls="no_slip", density_evolution=True)
    tank_plain = tank.scene(dx, mat, fx, width=1.0, height=1.0, tank_length=1.0, tank_height=1.2)
    tank_av = dataclasses.replace(tank_plain, effects=dataclasses.replace(fx, artificial_viscosity=0.02))
    return [("tgv2d", "-", tgv_plain), ("tgv2d", "+heat", _heat(tgv_plain)),
            ("tank at rest", "walls", tank_plain), ("tank at rest", "walls+heat", _heat(tank_plain)),
            ("tank at rest", "walls+art.visc.", tank_av)]


def ms_per_step(scene, steps, dt):
    solver = sph.build_solver(scene, sph.Numerics(dt=dt))
    state, nbrs = solver.init_fn()
    _, _, best = time_chunk(solver, state, nbrs, steps, repeats=5)
    return 1e3 * best / steps


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--dx", type=float, default=0.02)
    args = ap.parse_args()
    print(f"same scene with and without an extra declared effect, dx {args.dx}, float64, best of 5")
    print(f"{'scene':14s} {'effects':16s} {'N':>6s} {'ms/step':>8s}")
    for case, label, scene in scenes(args.dx):
        ms = ms_per_step(scene, args.steps, dt=1e-4)  # one dt for all, so the runs are comparable
        print(f"{case:14s} {label:16s} {scene.n:6d} {ms:8.3f}", flush=True)


if __name__ == "__main__":
    from lab.cli import script_main

    script_main(main)  # sets XLA's CPU defaults first
