"""Run the 2D dam break for every water column of a profile (Riemann SPH in a closed tank).

For each column (config `columns`: the 2:1 column of Colagrossi & Landrini 2003 for the pressure
history and Fig. 8, the square column of Martin & Moyce 1952 for the surge front) this writes

  results/<profile>/dambreak2d/<column>_dx<dx>/traj.h5        LagrangeBench layout (sph.io), + checkpoint
  results/<profile>/dambreak2d/<column>_dx<dx>/metadata.json

with a frame every `frame_dt` (rounded to whole steps). The metrics are computed from these files by
evaluate.py. A run whose traj.h5 is complete and was made from the same inputs (fingerprint of the
simulation settings and the code) is skipped; one that stopped part-way resumes from its checkpoint;
anything else is run from scratch.

    python experiments/dambreak2d/run.py --profile smoke [--results results/smoke] [--only square]
"""
import argparse
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a script: make the repository root importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np

import sph
from sph import io, simulate
from sph.cases import tank
from sph.configtools import to_mapping
from experiments.dambreak2d import settings as S


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


def write_every_for(exp: "S.Experiment", dt: float) -> int:
    """Steps per frame: frame_dt rounded to whole steps."""
    return max(1, int(round(exp.frame_dt / dt)))


def _metadata(exp, column, solver, n_total, write_every, fp, **extra) -> dict:
    n_frames = 1 + -(-n_total // write_every)
    return io.lagrangebench_metadata(
        case=exp.case, solver="riemann" if exp.effects.riemann else "sph", dim=solver.scene.dim, dx=exp.dx,
        dt=solver.dt, t_end=n_total * solver.dt, sequence_length=n_frames, write_every=write_every,
        num_particles_max=solver.scene.n, periodic_boundary_conditions=solver.scene.domain.periodic,
        bounds=[(0.0, b) for b in solver.scene.domain.box],
        default_connectivity_radius=exp.connectivity_radius_factor * exp.dx, dtype=exp.numerics.dtype,
        column=to_mapping(column), tank=to_mapping(exp.tank), tank_offset=exp.offset, g=exp.g,
        effects=exp.effects.names(), material=to_mapping(solver.scene.material), numerics=to_mapping(exp.numerics),
        hydrostatic_init=exp.hydrostatic_init, dt_limits=solver.dt_limits, kept_fields=list(exp.keep),
        n_fluid=int(solver.scene.fluid_mask.sum()), fingerprint=fp, **extra)


def run_one(exp: "S.Experiment", column: "S.Column", results, progress: bool = True, callback=None) -> dict:
    """Run (or skip, or resume) one column; returns {'status', 'wall_s', 'compile_s', 'n_steps'}."""
    folder = S.run_dir(results, column.name, exp.dx)
    traj, meta_path = folder / "traj.h5", folder / "metadata.json"
    fp = S.run_fingerprint(exp, column)
    status = io.trajectory_status(traj)
    same = status["exists"] and status["fingerprint"] == fp
    label = f"{column.name} dx{exp.dx:g}"
    if same and status["complete"] and meta_path.exists():
        print(f"{label}: complete, skipped", flush=True)
        return {"status": "skipped"}

    solver = build(exp, column)
    n_steps = solver.n_steps(column.t_end)
    write_every = write_every_for(exp, solver.dt)
    resume = same and status["checkpoint_step"] is not None
    if resume:
        writer = io.TrajectoryWriter.open(traj)
    else:
        writer = io.TrajectoryWriter.create(traj, solver.scene.tag, solver.scene.dim, dtype=solver.dtype,
                                            keep=exp.keep, attrs={"fingerprint": fp})
    with writer:
        if resume:
            state, nbrs, step0 = simulate.resume(solver, writer)
            print(f"{label}: resuming at step {step0} of {n_steps}", flush=True)
        else:
            state, nbrs = initial_state(exp, column, solver)
            step0 = 0
        if not resume or not meta_path.exists():
            io.write_metadata(meta_path, _metadata(exp, column, solver, n_steps, write_every, fp))
        res = simulate.run(solver, state, nbrs, column.t_end, write_every, writer=writer, progress=progress,
                           step0=step0, desc=label, callback=callback,
                           u_limit=exp.numerics.c_ref_factor * solver.scene.material.u_ref)
        timings = {"wall_s": res.wall_s_total, "compile_s": res.compile_s, "n_steps": res.step_end,
                   "n_reallocations": res.n_reallocations_total}
        writer.mark_complete(**timings)
        position = writer.group["position"][...]
    stats = io.lagrangebench_stats(position, solver.scene.domain.box, solver.scene.domain.periodic)
    io.write_metadata(meta_path, _metadata(exp, column, solver, n_steps, write_every, fp, **stats, **timings))
    print(f"{label}: {res.n_steps} steps of {solver.scene.n} particles ({int(solver.scene.fluid_mask.sum())} "
          f"fluid) in {res.wall_s:.1f} s ({res.ms_per_step:.2f} ms/step), compile {res.compile_s:.1f} s, "
          f"max density error {np.max(res.density_error):.4f}", flush=True)
    return {"status": "resumed" if resume else "run", **timings}


def run_all(exp: "S.Experiment", results, columns=None, progress: bool = True):
    t0 = time.perf_counter()
    n = 0
    for c in exp.columns:
        if columns is None or c.name in columns:
            run_one(exp, c, results, progress)
            n += 1
    print(f"dambreak2d: {n} runs in {time.perf_counter() - t0:.1f} s -> {S.out_dir(results)}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None, help="results folder (default results/<profile>)")
    ap.add_argument("--only", nargs="*", default=None, help="column names to run (default: all)")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)
    exp = S.load(args.profile)
    if args.only:
        names = [c.name for c in exp.columns]
        bad = [n for n in args.only if n not in names]
        if bad:
            ap.error(f"--only: {bad[0]!r} is not one of {names}")
    run_all(exp, args.results or f"results/{args.profile}", args.only, not args.no_progress)


if __name__ == "__main__":
    main()
