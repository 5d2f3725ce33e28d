"""Run the 2D lid-driven cavity for every (dx, method) of a profile and evaluate the runs.

Each run starts from the Cartesian lattice at rest (sph.cases.ldc: three layers of wall particles,
the top ones moving at the lid speed) and runs to t_end. With `lid_corners: fixed` the wall
particles of the top layers that lie beyond the side walls (x < 0 or x > 1, the corner blocks) are
fixed walls, so the lid spans exactly the cavity width; `moving` keeps sph.cases.ldc's full-width lid
(as JAX-SPH). A moving corner block has diagonal wall normals and a velocity with a component along
them, which the one-sided Riemann wall reads as a wall receding from the fluid: at the downstream
corner it sucks fluid particles into the wall (Riemann SPH at dx = 0.02 blows up at t = 0.79).
Each run writes

  results/<profile>/ldc2d/<method>_dx<dx>/traj.h5        LagrangeBench layout (sph.io), + checkpoint
  results/<profile>/ldc2d/<method>_dx<dx>/metadata.json
  results/<profile>/ldc2d/<method>_dx<dx>/profiles.npz   centreline profiles (analysis.py)
  results/<profile>/ldc2d/metrics.csv                    one row per run (upserted)

A run whose traj.h5 is complete and was made from the same inputs (settings.run_fingerprint) is
skipped (only re-evaluated); one that stopped part-way resumes from its checkpoint; anything else
runs from scratch. With --ignore-code-changes a stored run counts as the same when its solver settings
match, whatever the code (sph/, run.py) was: for long runs that should survive an unrelated edit of
the core (see README). Progress goes to stdout (with --no-progress one line per `--log-every` frames),
so a background run can be followed with `tail -f`.

    python experiments/ldc2d/run.py --profile smoke [--results results/smoke] [--fig fig6]
                                    [--only tvf] [--dx 0.05] [--no-progress] [--ignore-code-changes]
"""
import argparse
import dataclasses
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a script: make the repository root importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import h5py
import numpy as np

import sph
from sph import diagnostics, io, simulate
from sph.cases import ldc
from sph.configtools import to_mapping
from experiments.ldc2d import analysis
from experiments.ldc2d import settings as S


def write_every_for(n_steps: int, frames: int) -> int:
    """Steps per frame so that about `frames` frames follow t = 0."""
    return max(1, int(round(n_steps / frames)))


def scene(exp: "S.Experiment", method: "S.Method", dx: float) -> sph.Scene:
    sc = ldc.scene(dx, exp.material, exp.effects(method), layers=exp.wall_layers, lid_velocity=exp.lid_velocity)
    if exp.lid_corners == "fixed":
        x = sc.r[:, 0] - ldc.offset(dx, exp.wall_layers)
        corner = (sc.tag == sph.MOVING_WALL) & ((x < 0.0) | (x > 1.0))
        sc = dataclasses.replace(sc, tag=np.where(corner, sph.WALL, sc.tag).astype(np.int32),
                                 u=np.where(corner[:, None], 0.0, sc.u))
    return sc


def build(exp: "S.Experiment", method: "S.Method", dx: float) -> sph.Solver:
    return sph.build_solver(scene(exp, method, dx), exp.numerics_of(method))


def _metadata(exp, method, dx, solver, n_total, write_every, fp, **extra) -> dict:
    n_frames = 1 + -(-n_total // write_every)
    return io.lagrangebench_metadata(
        case=exp.case, solver=method.name, dim=solver.scene.dim, dx=dx, dt=solver.dt, t_end=n_total * solver.dt,
        sequence_length=n_frames, write_every=write_every, num_particles_max=solver.scene.n,
        periodic_boundary_conditions=solver.scene.domain.periodic,
        bounds=[(0.0, b) for b in solver.scene.domain.box],
        default_connectivity_radius=exp.connectivity_radius_factor * dx, dtype=solver.numerics.dtype,
        effects=exp.effects(method).names(), re=exp.re, lid_velocity=exp.lid_velocity,
        wall_layers=exp.wall_layers, lid_corners=exp.lid_corners, cavity_offset=ldc.offset(dx, exp.wall_layers),
        n_fluid=int(solver.scene.fluid_mask.sum()), material=to_mapping(exp.material),
        numerics=to_mapping(solver.numerics), dt_limits=solver.dt_limits, kept_fields=list(exp.keep),
        fingerprint=fp, **extra)


def _logger(label, n_total, dt, every):
    """Callback printing one progress line every `every` frames (for --no-progress / log files)."""
    t0 = time.perf_counter()
    count = [0]

    def log(step, t, state):
        count[0] += 1
        if count[0] % every == 0 or step >= n_total:
            el = time.perf_counter() - t0
            print(f"{label}: step {step}/{n_total} t={t:.3f} u_max={float(diagnostics.u_max(state)):.4f} "
                  f"[{el:.0f} s this session, {time.strftime('%H:%M:%S')}]", flush=True)
    return log


def _stored_settings(traj) -> str:
    try:
        with h5py.File(traj, "r") as f:
            return str(f["00000"].attrs.get("settings_fingerprint", ""))
    except (OSError, KeyError):
        return ""


def run_one(exp: "S.Experiment", method: "S.Method", dx: float, results, progress: bool = True,
            callback=None, log_every: int = 0, ignore_code_changes: bool = False) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row (also upserted to the csv).
    `ignore_code_changes`: a stored run with the same solver settings counts as the same run even
    when the code (sph/, run.py) has changed since it was made."""
    folder = S.run_dir(results, method.name, dx)
    traj, meta_path = folder / "traj.h5", folder / "metadata.json"
    fp = S.run_fingerprint(exp, method, dx)
    sfp = S.settings_fingerprint(exp, method, dx)
    status = io.trajectory_status(traj)
    same = status["exists"] and status["fingerprint"] == fp
    label = f"{method.name} {S.dx_tag(dx)}"
    if status["exists"] and not same and ignore_code_changes and _stored_settings(traj) == sfp:
        print(f"{label}: code changed since this run was made; reused (--ignore-code-changes)", flush=True)
        same, fp = True, status["fingerprint"]
    if same and status["complete"] and meta_path.exists():
        print(f"{label}: complete, skipped", flush=True)
        return analysis.record(exp, method.name, dx, results)

    solver = build(exp, method, dx)
    n_steps = solver.n_steps(exp.t_end)
    write_every = write_every_for(n_steps, exp.frames)
    resume = same and status["checkpoint_step"] is not None
    if resume:
        writer = io.TrajectoryWriter.open(traj)
    else:
        if status["exists"]:
            print(f"{label}: stored run has other inputs (or no checkpoint), running from scratch", flush=True)
        writer = io.TrajectoryWriter.create(traj, solver.scene.tag, solver.scene.dim, dtype=solver.dtype,
                                            keep=exp.keep, attrs={"fingerprint": fp, "settings_fingerprint": sfp})
    cbs = [c for c in (callback, _logger(label, n_steps, solver.dt, log_every) if log_every else None) if c]

    def cb(step, t, state):
        for c in cbs:
            c(step, t, state)

    with writer:
        if resume:
            state, nbrs, step0 = simulate.resume(solver, writer)
            print(f"{label}: resuming at step {step0} of {n_steps}", flush=True)
        else:
            state, nbrs = solver.init_fn()
            step0 = 0
            print(f"{label}: {solver.scene.n} particles ({int(solver.scene.fluid_mask.sum())} fluid), "
                  f"dt {solver.dt:.4g}, {n_steps} steps, a frame every {write_every}", flush=True)
        if not resume or not meta_path.exists():
            io.write_metadata(meta_path, _metadata(exp, method, dx, solver, n_steps, write_every, fp))
        res = simulate.run(solver, state, nbrs, exp.t_end, write_every, writer=writer, progress=progress,
                           step0=step0, desc=label, callback=cb if cbs else None,
                           u_limit=solver.numerics.c_ref_factor * exp.material.u_ref)
        timings = {"wall_s": res.wall_s_total, "compile_s": res.compile_s, "n_steps": res.step_end,
                   "n_reallocations": res.n_reallocations_total}
        writer.mark_complete(**timings)
        position = writer.group["position"][...]
    stats = io.lagrangebench_stats(position, solver.scene.domain.box, solver.scene.domain.periodic)
    io.write_metadata(meta_path, _metadata(exp, method, dx, solver, n_steps, write_every, fp, **stats, **timings))
    row = analysis.record(exp, method.name, dx, results)
    print(f"{label}: {res.n_steps} steps of {solver.scene.n} particles in {res.wall_s:.1f} s "
          f"({res.ms_per_step:.2f} ms/step), compile {res.compile_s:.1f} s; RMS deviation from Ghia "
          f"u {row['u_rms']:.4f}, v {row['v_rms']:.4f}", flush=True)
    return row


def run_all(exp: "S.Experiment", results, methods=None, dxs=None, progress: bool = True, log_every: int = 0,
            ignore_code_changes: bool = False):
    """Every (dx, method) of the profile (optionally a subset); returns the metrics rows."""
    t0 = time.perf_counter()
    rows = []
    for dx in exp.dx if dxs is None else dxs:
        for m in exp.methods:
            if methods is None or m.name in methods:
                rows.append(run_one(exp, m, dx, results, progress, log_every=log_every,
                                    ignore_code_changes=ignore_code_changes))
    print(f"ldc2d: {len(rows)} runs in {time.perf_counter() - t0:.1f} s -> {S.metrics_path(results)}", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None, help="results folder (default results/<profile>)")
    ap.add_argument("--fig", choices=S.FIGURES, default=None, help="only the runs of this figure (its dx)")
    ap.add_argument("--only", nargs="*", default=None, help="method names to run (default: all)")
    ap.add_argument("--dx", nargs="*", type=float, default=None, help="spacings to run (default: all)")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--log-every", type=int, default=None,
                    help="print a progress line every N frames (default: 10 with --no-progress, else off)")
    ap.add_argument("--ignore-code-changes", action="store_true",
                    help="reuse/resume stored runs whose solver settings match even if sph/ or run.py changed")
    args = ap.parse_args(argv)
    exp = S.load(args.profile)
    if args.only:
        names = [m.name for m in exp.methods]
        bad = [n for n in args.only if n not in names]
        if bad:
            ap.error(f"--only: {bad[0]!r} is not one of {names}")
    dxs = args.dx
    if args.fig:
        if args.fig not in exp.figures:
            ap.error(f"--fig: profile {args.profile!r} has no {args.fig} (figures: {list(exp.figures)})")
        dxs = [float(exp.figures[args.fig])]
    log_every = args.log_every if args.log_every is not None else (10 if args.no_progress else 0)
    run_all(exp, args.results or f"results/{args.profile}", args.only, dxs, not args.no_progress, log_every,
            args.ignore_code_changes)


if __name__ == "__main__":
    main()
