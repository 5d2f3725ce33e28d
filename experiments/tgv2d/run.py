"""Run the 2D Taylor-Green vortex for every (dx, method) of a profile and collect the metrics.

For each spacing the relaxed positions (relax.py, cached) get the analytical TGV velocity; each
method then runs to t_end, writing

  results/<profile>/tgv2d/<method>_dx<dx>/traj.h5        LagrangeBench layout (sph.io), + checkpoint
  results/<profile>/tgv2d/<method>_dx<dx>/metadata.json
  results/<profile>/tgv2d/metrics.csv                    one row per run (upserted)

A run whose traj.h5 is complete and was made from the same inputs (fingerprint of the profile
settings, the relaxation and the code) is skipped; one that stopped part-way resumes from its
checkpoint; anything else is run from scratch.

    python experiments/tgv2d/run.py --profile smoke [--results results/smoke] [--only tvf] [--dx 0.05]
"""
import argparse
import json
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # run as a script: make the repository root importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np
import pandas as pd

import sph
from sph import io, simulate
from sph.cases import tgv
from sph.configtools import to_mapping
from experiments.tgv2d import relax
from experiments.tgv2d import settings as S

KEY = ["case", "method", "dx", "dtype"]


def write_every_for(n_steps: int, frames: int) -> int:
    """Steps per frame so that about `frames` frames follow t = 0."""
    return max(1, int(round(n_steps / frames)))


def build(exp: "S.Experiment", method: "S.Method", dx: float, r: np.ndarray) -> sph.Solver:
    return sph.build_solver(tgv.scene(dx, exp.material, method.effects, r=r), exp.numerics)


def _metadata(exp, method, dx, solver, n_total, write_every, fp, **extra) -> dict:
    n_frames = 1 + -(-n_total // write_every)
    return io.lagrangebench_metadata(
        case=exp.case, solver=method.name, dim=solver.scene.dim, dx=dx, dt=solver.dt, t_end=n_total * solver.dt,
        sequence_length=n_frames, write_every=write_every, num_particles_max=solver.scene.n,
        periodic_boundary_conditions=solver.scene.domain.periodic,
        bounds=[(0.0, b) for b in solver.scene.domain.box],
        default_connectivity_radius=exp.connectivity_radius_factor * dx, dtype=exp.numerics.dtype,
        effects=method.effects.names(), re=exp.re, material=to_mapping(exp.material),
        numerics=to_mapping(exp.numerics), relaxation=to_mapping(exp.relaxation), dt_limits=solver.dt_limits,
        kept_fields=list(exp.keep), fingerprint=fp, **extra)


def run_one(exp: "S.Experiment", method: "S.Method", dx: float, results, progress: bool = True,
            callback=None) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row (also upserted to the csv)."""
    folder = S.run_dir(results, method.name, dx)
    traj, meta_path = folder / "traj.h5", folder / "metadata.json"
    fp = S.run_fingerprint(exp, method, dx)
    status = io.trajectory_status(traj)
    same = status["exists"] and status["fingerprint"] == fp
    label = f"{method.name} {S.dx_tag(dx)}"
    if same and status["complete"] and meta_path.exists():
        print(f"{label}: complete, skipped", flush=True)
        return record_metrics(exp, method.name, dx, results)

    r = relax.relaxed_positions(exp, dx, results, progress)
    solver = build(exp, method, dx, r)
    n_steps = solver.n_steps(exp.t_end)
    write_every = write_every_for(n_steps, exp.frames)
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
            state, nbrs = solver.init_fn()
            step0 = 0
        if not resume or not meta_path.exists():
            io.write_metadata(meta_path, _metadata(exp, method, dx, solver, n_steps, write_every, fp))
        res = simulate.run(solver, state, nbrs, exp.t_end, write_every, writer=writer, progress=progress,
                           step0=step0, desc=label, callback=callback,
                           u_limit=exp.numerics.c_ref_factor * exp.material.u_ref)
        timings = {"wall_s": res.wall_s_total, "compile_s": res.compile_s, "n_steps": res.step_end,
                   "n_reallocations": res.n_reallocations_total}
        writer.mark_complete(**timings)
        position = writer.group["position"][...]
    stats = io.lagrangebench_stats(position, solver.scene.domain.box, solver.scene.domain.periodic)
    io.write_metadata(meta_path, _metadata(exp, method, dx, solver, n_steps, write_every, fp, **stats, **timings))
    row = record_metrics(exp, method.name, dx, results)
    print(f"{label}: {res.n_steps} steps of {solver.scene.n} particles in {res.wall_s:.2f} s "
          f"({res.ms_per_step:.2f} ms/step), compile {res.compile_s:.2f} s, "
          f"E_kin rel. err. (mean) {row['e_kin_relerr_mean']:.3g}", flush=True)
    return row


def metrics_row(exp: "S.Experiment", method: str, dx: float, results) -> dict:
    """Metrics of one finished run, from its traj.h5 and metadata.json."""
    folder = S.run_dir(results, method, dx)
    tr = io.read_trajectory(folder / "traj.h5")
    meta = json.loads((folder / "metadata.json").read_text())
    attrs = tr["attrs"]
    t, u, e = tr["time"], tr["u_max"], tr["e_kin"]
    u_ex, e_ex = tgv.u_max_exact(t, exp.re), tgv.e_kin_exact(t, exp.re)
    n_steps = int(attrs["n_steps"])
    row = {"case": exp.case, "method": method, "dx": dx, "dtype": exp.numerics.dtype,
           "n_particles": int(tr["particle_type"].shape[0]), "n_steps": n_steps, "dt": meta["dt"],
           "t_end": float(t[-1]), "write_every": meta["write_every"], "n_frames": int(t.shape[0]),
           "wall_s": float(attrs["wall_s"]), "compile_s": float(attrs["compile_s"]),
           "ms_per_step": 1e3 * float(attrs["wall_s"]) / n_steps if n_steps else np.nan,
           "n_reallocations": int(attrs["n_reallocations"])}
    for name, sim, exact in (("u_max", u, tgv.u_max_exact), ("e_kin", e, tgv.e_kin_exact)):
        for te in exp.eval_times:
            val = np.interp(te, t, sim) if te <= t[-1] * (1 + 1e-9) else np.nan
            row[f"{name}_relerr_t{te:g}"] = abs(val / exact(te, exp.re) - 1.0) if np.isfinite(val) else np.nan
    for name, sim, ex in (("u_max", u, u_ex), ("e_kin", e, e_ex)):
        rel = np.abs(sim / ex - 1.0)
        row[f"{name}_relerr_mean"] = float(np.trapezoid(rel, t) / (t[-1] - t[0])) if t[-1] > t[0] else float(rel[0])
    row["density_error_max"] = float(np.max(tr["density_error"]))
    return row


def record_metrics(exp, method: str, dx: float, results) -> dict:
    """Compute the row of one run and upsert it into metrics.csv (keyed by case, method, dx, dtype)."""
    row = metrics_row(exp, method, dx, results)
    path = S.metrics_path(results)
    new = pd.DataFrame([row])
    if path.exists():
        old = pd.read_csv(path)
        same = np.ones(len(old), bool)
        for k in KEY:
            same &= np.asarray(np.isclose(old[k], row[k]) if k == "dx" else old[k].astype(str) == str(row[k]))
        new = pd.concat([old[~same], new], ignore_index=True)
    new = new.sort_values(["dx", "method"], ascending=[False, True], ignore_index=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".csv.tmp")
    new.to_csv(tmp, index=False)
    tmp.replace(path)
    return row


def run_all(exp: "S.Experiment", results, methods=None, dxs=None, progress: bool = True) -> pd.DataFrame:
    """Every (dx, method) of the profile (optionally a subset); returns the metrics table."""
    t0 = time.perf_counter()
    rows = []
    for dx in exp.dx if dxs is None else dxs:
        for m in exp.methods:
            if methods is None or m.name in methods:
                rows.append(run_one(exp, m, dx, results, progress))
    print(f"tgv2d: {len(rows)} runs in {time.perf_counter() - t0:.1f} s -> {S.metrics_path(results)}", flush=True)
    return pd.DataFrame(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None, help="results folder (default results/<profile>)")
    ap.add_argument("--only", nargs="*", default=None, help="method names to run (default: all)")
    ap.add_argument("--dx", nargs="*", type=float, default=None, help="spacings to run (default: all)")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)
    exp = S.load(args.profile)
    if args.only:
        names = [m.name for m in exp.methods]
        bad = [n for n in args.only if n not in names]
        if bad:
            ap.error(f"--only: {bad[0]!r} is not one of {names}")
    run_all(exp, args.results or f"results/{args.profile}", args.only, args.dx, not args.no_progress)


if __name__ == "__main__":
    main()
