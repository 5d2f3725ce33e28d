"""Run the 2D dam break for every water column of a profile (Riemann SPH in a closed tank).

For each column (config `columns`: the 2:1 column of Colagrossi & Landrini 2003 for the pressure
history and Fig. 8, the square column of Martin & Moyce 1952 for the surge front) this writes

  results/<profile>/dambreak2d/<column>_dx<dx>/traj.h5        LagrangeBench layout (lab.io), + checkpoint
  results/<profile>/dambreak2d/<column>_dx<dx>/metadata.json

with a frame every `frame_dt` (rounded to whole steps). The metrics are computed from these files by
evaluate.py. Caching is lab.runs.run_cached's: a run whose traj.h5 is complete and was made from the
same inputs (the simulation settings and the code that can change its numbers) is skipped; one that
stopped part-way resumes from its checkpoint; a damaged or stale one is set aside and run again.

    python experiments/dambreak2d/run.py --profile smoke [--results results/smoke] [--only square]
"""
import time

import numpy as np

import sph
from lab import cli, runs
from sph.cases import tank
from lab.configtools import to_mapping
try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S


def build(exp: "S.Experiment", column: "S.Column") -> sph.Solver:
    scene = tank.scene(exp.dx, exp.material(column), exp.effects, width=column.width, height=column.height,
                       tank_length=exp.tank.length, tank_height=exp.tank.height, layers=exp.tank.layers,
                       name=f"dambreak_{column.name}")
    return sph.build_solver(scene, exp.numerics)


def initial_state(exp: "S.Experiment", column: "S.Column", solver: sph.Solver):
    """(state, nbrs) at t = 0: the column at rest, with the hydrostatic pressure
    p = rho_ref g (H - y) and the density of the equation of state at that pressure when
    `hydrostatic_init` (otherwise rho = rho_ref, p = 0 and the column first settles under gravity,
    ringing with acoustic waves). The stored initial acceleration is that of the uniform state; it
    enters only the first step (an error of dt g in the velocity)."""
    state, nbrs = solver.init_fn()
    if not exp.hydrostatic_init:
        return state, nbrs
    return tank.hydrostatic(state, solver.eos, exp.fluid.rho_ref, exp.g, exp.offset + column.height), nbrs


def spec(exp: "S.Experiment", column: "S.Column", results) -> runs.RunSpec:
    """What identifies the run of one column and how it is written."""
    return runs.RunSpec(folder=S.run_dir(results, column.name, exp.dx), case=exp.case,
                        method="riemann" if exp.effects.riemann else "sph", fingerprint=S.run_fingerprint(exp, column),
                        t_end=column.t_end, frame_dt=exp.frame_dt, keep=exp.keep,
                        connectivity_radius_factor=exp.connectivity_radius_factor,
                        metadata={"column": to_mapping(column), "tank": to_mapping(exp.tank), "tank_offset": exp.offset,
                                  "g": exp.g, "hydrostatic_init": exp.hydrostatic_init},
                        u_limit=exp.numerics.c_ref_factor * exp.material(column).u_ref)


def run_one(exp: "S.Experiment", column: "S.Column", results, progress: bool = True, callback=None) -> dict:
    """Run (or skip, or resume) one column; returns {'status', 'wall_s', ...}."""
    out = runs.run_cached(spec(exp, column, results), lambda: build(exp, column),
                          initial_state=lambda solver: initial_state(exp, column, solver),
                          progress=progress, callback=callback)
    if out.result is None:
        return {"status": out.status}
    res = out.result
    print(f"{column.name}: max density error {np.max(res.density_error):.4f}", flush=True)
    return {"status": out.status, "wall_s": res.wall_s_total, "compile_s": res.compile_s, "n_steps": res.step_end,
            "n_reallocations": res.n_reallocations_total}


def run_all(exp: "S.Experiment", results, columns=None, progress: bool = True):
    t0 = time.perf_counter()
    n = 0
    for c in exp.columns:
        if columns is None or c.name in columns:
            run_one(exp, c, results, progress)
            n += 1
    print(f"dambreak2d: {n} runs in {time.perf_counter() - t0:.1f} s -> {S.out_dir(results)}", flush=True)


def options(ap):
    ap.add_argument("--only", nargs="*", default=None, help="column names to run (default: all)")
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    exp = S.load(args.profile)
    columns = cli.select("--only", args.only, [c.name for c in exp.columns])
    run_all(exp, args.results, columns, not args.no_progress)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
