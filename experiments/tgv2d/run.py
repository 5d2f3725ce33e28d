"""Run the 2D Taylor-Green vortex for every (dx, method) of a profile and collect the metrics.

For each spacing the relaxed positions (relax.py, cached) get the analytical TGV velocity; each
method then runs to t_end, writing

  results/<profile>/tgv2d/<method>_dx<dx>/traj.h5        LagrangeBench layout (sph.harness.io), + checkpoint
  results/<profile>/tgv2d/<method>_dx<dx>/metadata.json
  results/<profile>/tgv2d/<method>_dx<dx>/record.json    the run record (sph.harness.runs), for `make accuracy`
  results/<profile>/tgv2d/metrics.csv                    one row per run of the current config

Caching and resuming are sph.harness.runs.run_cached's: a run whose traj.h5 is complete and was made from the
same inputs (the profile settings, the relaxation and the code that can change the numbers) is
skipped; one that stopped part-way resumes from its checkpoint; a damaged or stale one is set aside
and run again. metrics.csv is rebuilt from the trajectories every time. The folder name (here tgv2d)
is the experiment's name: a copy of this folder under another name is an experiment of its own.

    python experiments/tgv2d/run.py --profile smoke [--results results/smoke] [--only tvf] [--dx 0.05]
"""
import time

import numpy as np
import pandas as pd

import sph
from sph.harness import cli, io, record, runs, tables
from sph.cases import tgv
from sph.harness.configtools import to_mapping

try:
    from . import relax, settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import relax
    import settings as S


def build(exp: "S.Experiment", method: "S.Method", dx: float, r: np.ndarray) -> sph.Solver:
    return sph.build_solver(tgv.scene(dx, exp.material, method.effects, r=r), exp.numerics)


def spec(exp: "S.Experiment", method: "S.Method", dx: float, results) -> runs.RunSpec:
    """What identifies the run of `method` at `dx` and how it is written."""
    return runs.RunSpec(folder=S.run_dir(results, method.name, dx), case=exp.case, method=method.name,
                        fingerprint=S.run_fingerprint(exp, method, dx), t_end=exp.t_end, frames=exp.frames,
                        keep=exp.keep, connectivity_radius_factor=exp.connectivity_radius_factor,
                        metadata={"re": exp.re, "relaxation": to_mapping(exp.relaxation)},
                        u_limit=exp.numerics.c_ref_factor * exp.material.u_ref)


def run_one(exp: "S.Experiment", method: "S.Method", dx: float, results, progress: bool = True,
            callback=None) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row."""
    sp = spec(exp, method, dx, results)
    out = runs.run_cached(sp, lambda: build(exp, method, dx, relax.relaxed_positions(exp, dx, results, progress)),
                          progress=progress, callback=callback)
    row = metrics_row(exp, method.name, dx, results)
    if out.status != "skipped":
        print(f"{sp.label}: E_kin rel. err. (mean) {row['e_kin_relerr_mean']:.3g}", flush=True)
    write_metrics(exp, results)
    return row


def metrics_row(exp: "S.Experiment", method: str, dx: float, results) -> dict:
    """Metrics of one finished run, from its traj.h5 and metadata.json."""
    folder = S.run_dir(results, method, dx)
    tr = io.read_trajectory(folder / "traj.h5")
    meta = io.read_metadata(folder / "metadata.json")
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


def write_metrics(exp: "S.Experiment", results) -> pd.DataFrame:
    """Rebuild metrics.csv from the trajectories of exactly the current config's finished runs (a run
    of other inputs, or a removed method or dx, leaves no row behind); also writes each run's record."""
    rows = []
    for dx in exp.dx:
        for m in exp.methods:
            sp = spec(exp, m, dx, results)
            if runs.stored_state(sp) == "current":
                row = metrics_row(exp, m.name, dx, results)
                rows.append(row)
                record.save_record(sp.folder, record.record(
                    sp.folder, experiment=S.NAME, target="fig5", method=m.name,
                    errors={"u_max_mean": row["u_max_relerr_mean"], "e_kin_mean": row["e_kin_relerr_mean"],
                            **{f"u_max_t{te:g}": row[f"u_max_relerr_t{te:g}"] for te in exp.eval_times}}))
    return tables.write_table(S.metrics_path(results), rows, sort=["dx", "method"], ascending=[False, True])


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


def options(ap):
    ap.add_argument("--only", nargs="*", default=None, help="method names to run (default: all)")
    ap.add_argument("--dx", nargs="*", type=float, default=None,
                    help="run only these of the profile's spacings (default: all)")
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    exp = S.load(args.profile)
    methods = cli.select("--only", args.only, [m.name for m in exp.methods])
    dxs = cli.select("--dx", args.dx, list(exp.dx))
    run_all(exp, args.results, methods, dxs, not args.no_progress)


if __name__ == "__main__":
    from sph.harness.cli import profile_main

    profile_main(main, __doc__, options)
