"""Relaxed initial particle positions for the 2D Taylor-Green vortex (JAX-SPH 'rlx' mode).

A Cartesian lattice jittered by Gaussian noise (std noise_factor * dx, fixed seed) is advanced at
rest (zero initial velocity) with the transport-velocity formulation and an EoS background pressure
p_bg_factor * p_ref, until the particles settle into an even, non-lattice distribution. The result is
cached in results/<profile>/tgv2d/relaxed_dx<dx>.npy with a .json sidecar; the cache is reused only
when its fingerprint (relaxation settings, material, numerics, code) matches.

    python experiments/tgv2d/relax.py --profile smoke [--results results/smoke]
"""
import argparse
import dataclasses
import json
import sys
from pathlib import Path

if __package__ in (None, ""):  # run as a script: make the repository root importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import time

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

import sph
from sph import diagnostics, simulate
from sph.cases import tgv
from sph.lattice import cartesian, jitter
from sph.rollout import advance, make_chunk
from experiments.tgv2d import settings as S


def relax(exp: "S.Experiment", dx: float, progress: bool = True):
    """Run the relaxation; returns (positions (N, 2) float64, info dict)."""
    rlx = exp.relaxation
    box = (1.0, 1.0)
    r = jitter(cartesian([0.0, 0.0], list(box), dx), rlx.noise_factor * dx, rlx.seed, box=box)
    r = np.where(r >= 1.0, 0.0, r)  # np.mod can round a tiny negative up to exactly the box side
    scene = tgv.scene(dx, exp.material, sph.Effects(tvf=True), r=r)
    scene = dataclasses.replace(scene, u=np.zeros_like(scene.r))
    solver = sph.build_solver(scene, dataclasses.replace(exp.numerics, p_bg_factor=rlx.p_bg_factor))
    state, nbrs = solver.init_fn()
    rho_err0 = float(diagnostics.density_error(state, exp.material.rho_ref))
    if rlx.steps == 0:
        return np.asarray(state.r, np.float64), {"steps": 0}
    if rlx.quench_every:
        return _relax_quenched(solver, state, nbrs, rlx, exp.material.rho_ref, rho_err0, dx, progress)
    res = simulate.run(solver, state, nbrs, t_end=rlx.steps * solver.dt, write_every=max(1, rlx.steps // 10),
                       n_steps=rlx.steps, progress=progress, desc=f"relax {S.dx_tag(dx)}")
    info = {"steps": rlx.steps, "dt": solver.dt, "n_particles": scene.n, "wall_s": res.wall_s,
            "compile_s": res.compile_s, "density_error_start": rho_err0,
            "density_error_end": float(res.density_error[-1]), "u_max_end": float(res.u_max[-1])}
    return np.asarray(res.state.r, np.float64), info


def _relax_quenched(solver, state, nbrs, rlx, rho_ref, rho_err0, dx, progress):
    """Relaxation with the velocity zeroed every `rlx.quench_every` steps (damped relaxation)."""
    q = rlx.quench_every
    chunk = jax.jit(make_chunk(solver.step_fn, q))
    t0 = time.perf_counter()
    for k in tqdm(range(rlx.steps // q), desc=f"relax {S.dx_tag(dx)} (quench every {q})", disable=not progress):
        state, nbrs, _ = advance(chunk, solver.neighbors, state, nbrs, k * q, q)
        u_max_end = float(diagnostics.u_max(state))
        state = state.replace(u=jnp.zeros_like(state.u))
    wall = time.perf_counter() - t0
    info = {"steps": rlx.steps, "quench_every": q, "dt": solver.dt, "n_particles": state.n, "wall_s": wall,
            "density_error_start": rho_err0,
            "density_error_end": float(diagnostics.density_error(state, rho_ref)), "u_max_end": u_max_end}
    return np.asarray(state.r, np.float64), info


def relaxed_positions(exp: "S.Experiment", dx: float, results, progress: bool = True) -> np.ndarray:
    """Cached relaxed positions for spacing `dx` (computed and saved when missing or stale)."""
    path = S.relaxed_path(results, dx)
    side = path.with_suffix(".json")
    fp = S.relax_fingerprint(exp, dx)
    if path.exists() and side.exists():
        try:
            if json.loads(side.read_text()).get("fingerprint") == fp:
                return np.load(path)
        except (ValueError, OSError):
            pass
    r, info = relax(exp, dx, progress)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.npy")
    np.save(tmp, r)
    tmp.replace(path)
    side.write_text(json.dumps({"fingerprint": fp, "dx": dx, "relaxation": dataclasses.asdict(exp.relaxation),
                                **info}, indent=2) + "\n")
    print(f"relaxed {S.dx_tag(dx)}: {info.get('steps')} steps, max |rho/rho_ref - 1| "
          f"{info.get('density_error_start', float('nan')):.3g} -> {info.get('density_error_end', float('nan')):.3g}, "
          f"u_max {info.get('u_max_end', float('nan')):.3g}", flush=True)
    return r


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None, help="results folder (default results/<profile>)")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)
    exp = S.load(args.profile)
    results = args.results or f"results/{args.profile}"
    for dx in exp.dx:
        relaxed_positions(exp, dx, results, progress=not args.no_progress)


if __name__ == "__main__":
    main()
