"""A/B of the solver's numbers: every field after N steps of a set of small scenes covering each
pass (summation / continuity / Riemann density, re-initialization, no-slip / free-slip / moving walls,
TVF, artificial viscosity, body force, heat with Dirichlet walls and zones, 3D).

    python scripts/ab_fields.py save DIR      # on the base commit
    python scripts/ab_fields.py compare DIR   # on the new one: max relative difference per field

float64 throughout; `compare` exits 1 when any field differs by more than --tol (relative to its scale).
"""
import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

import sph
from sph import Effects, Material, Numerics
from sph.cases import channel, ldc, tank, tgv, tgv3d
from sph.lattice import cartesian

STEPS = 60


def cases():
    mat = tgv.material(100.0)
    box = cartesian([0.0, 0.0], [1.0, 1.0], 0.05)
    jitter = box + np.random.default_rng(0).normal(scale=0.05 * 0.05, size=box.shape)
    yield "tgv_sph", tgv.scene(0.05, mat, Effects(), r=np.mod(jitter, 1.0)), Numerics(p_bg_factor=0.01)
    yield "tgv_tvf", tgv.scene(0.05, mat, Effects(tvf=True), r=np.mod(jitter, 1.0)), Numerics()
    yield "tgv_riemann", tgv.scene(0.05, mat, Effects(riemann=True, density_evolution=True, density_reinit_every=7),
                                   r=np.mod(jitter, 1.0)), Numerics()
    yield "tgv_av", tgv.scene(0.05, mat, Effects(density_evolution=True, artificial_viscosity=0.1),
                              r=np.mod(jitter, 1.0)), Numerics()
    for m in ("sph", "tvf", "riemann"):
        sc, nm = ldc.setup(0.05, re=100, method=m)
        yield f"ldc_{m}", sc, nm
    fx = tank.DAM_BREAK_EFFECTS
    sc = tank.scene(0.05, Material(eta=tank.DAM_BREAK_ETA, u_ref=tank.u_ref(1.0, 1.0)), fx, width=1.0, height=1.0,
                    tank_length=2.0, tank_height=1.5)
    yield "dambreak", sc, tank.DAM_BREAK_NUMERICS
    sc = tank.scene(0.05, Material(eta=0.01, u_ref=tank.u_ref(1.0, 1.0)), Effects(gravity=(0.0, -1.0), walls="no_slip",
                    tvf=True), width=1.0, height=0.5, tank_length=1.0, tank_height=1.0)
    yield "tank_tvf", sc, Numerics()
    heat_mat = Material(rho_ref=1.0, eta=0.01, u_ref=1.0, kappa=7.313, c_p=305.27)
    sc = channel.scene(0.04, heat_mat, Effects(walls="no_slip", heat=True, gravity=(2.3, 0.0)), noise_factor=0.05)
    yield "channel_heat", sc, Numerics(p_bg_factor=0.05)
    m3 = tgv3d.material(100.0)
    yield "tgv3d_tvf", tgv3d.scene(tgv3d.dx_for(8), m3, Effects(tvf=True)), Numerics()


def run(sc, nm):
    nm = dataclasses.replace(nm, dtype="float64")
    solver = sph.build_solver(sc, nm)
    state, nbrs = solver.init_fn()
    import jax
    step = jax.jit(solver.step_fn)
    out = {f"init_{k}": np.asarray(getattr(state, k)) for k in state.field_names()}
    for s in range(1, STEPS + 1):
        state, nbrs = step(state, nbrs, s)
    out.update({k: np.asarray(getattr(state, k)) for k in state.field_names()})
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=("save", "compare"))
    ap.add_argument("dir", type=Path)
    ap.add_argument("--tol", type=float, default=1e-12)
    a = ap.parse_args()
    a.dir.mkdir(parents=True, exist_ok=True)
    worst = 0.0
    for name, sc, nm in cases():
        got = run(sc, nm)
        path = a.dir / f"{name}.npz"
        if a.mode == "save":
            np.savez(path, **got)
            print(f"{name}: saved {len(got)} fields")
            continue
        ref = dict(np.load(path))
        if set(ref) != set(got):
            print(f"{name}: fields differ: {sorted(set(ref) ^ set(got))}")
            worst = np.inf
            continue
        diffs = {k: float(np.max(np.abs(got[k] - ref[k])) / max(np.max(np.abs(ref[k])), 1e-300)) for k in ref}
        k = max(diffs, key=diffs.get)
        worst = max(worst, diffs[k])
        print(f"{name}: max relative difference {diffs[k]:.2e} ({k})")
    if a.mode == "compare":
        print(f"worst {worst:.2e} (tol {a.tol:g})")
        sys.exit(0 if worst <= a.tol else 1)


if __name__ == "__main__":
    main()
