"""The 2D Taylor-Green study's runs: for each spacing the relaxed start (cached) gets the analytical
TGV velocity; each method then runs to t_end (cached, resumable: `lab.runs`), and the
metrics table is rebuilt from exactly the current config's finished runs, each with its run record.

Errors against the analytical decay (sph.cases.tgv): |u_max / exact - 1| and |E_kin / exact - 1| at
`eval_times` and time-averaged over the run; the largest density error of any frame.
"""
import dataclasses

import numpy as np
import pandas as pd

from sph.cases import tgv
from sph.lattice import count
from sph.solver import Solver, build_solver
from . import io, runs
from .configtools import to_mapping
from .layout import Study, dx_tag
from .record import record, save_record
from .study import Method, run_spec, sweep
from .tables import write_table
from .tgv2d import Experiment, relax_fingerprint, run_fingerprint

def relaxed_positions(study: Study, exp: Experiment, dx: float, results, progress: bool = True) -> np.ndarray:
    """Cached relaxed positions for spacing `dx` (computed and saved when missing or stale)."""
    def compute():
        return tgv.relax(dx, exp.material, exp.numerics, exp.relaxation, progress, desc=f"relax {dx_tag(dx)}")

    return runs.cached_positions(study.relaxed_path(results, dx_tag(dx)), relax_fingerprint(study, exp, dx), compute,
                                 f"relaxed {dx_tag(dx)}", dx=dx, relaxation=dataclasses.asdict(exp.relaxation))


def build(exp: Experiment, method: Method, dx: float, r: np.ndarray) -> Solver:
    return build_solver(tgv.scene(dx, exp.material, method.effects, r=r), exp.numerics)


def spec(study: Study, exp: Experiment, method: Method, dx: float, results) -> runs.RunSpec:
    """What identifies the run of `method` at `dx` and how it is written."""
    return run_spec(study, exp, method, dx_tag(dx), results, run_fingerprint(study, exp, method, dx),
                    {"re": exp.re, "relaxation": to_mapping(exp.relaxation)})


def run_one(study: Study, exp: Experiment, method: Method, dx: float, results, progress: bool = True,
            callback=None) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row."""
    sp = spec(study, exp, method, dx, results)
    out = runs.run_cached(sp, lambda: build(exp, method, dx, relaxed_positions(study, exp, dx, results, progress)),
                          progress=progress, callback=callback)
    row = metrics_row(study, exp, method.name, dx, results)
    if out.status != "skipped":
        print(f"{sp.label}: E_kin rel. err. (mean) {row['e_kin_relerr_mean']:.3g}", flush=True)
    write_metrics(study, exp, results)
    return row


def metrics_row(study: Study, exp: Experiment, method: str, dx: float, results) -> dict:
    """Metrics of one finished run, from its traj.h5 and metadata.json."""
    folder = study.run_dir(results, method, dx_tag(dx))
    tr = io.read_trajectory(folder / "traj.h5")
    meta = io.read_metadata(folder / "metadata.json")
    attrs = tr["attrs"]
    t, u, e = tr["time"], tr["u_max"], tr["e_kin"]
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
    for name, rel in tgv.decay_errors(t, u, e, exp.re).items():
        row[f"{name}_relerr_mean"] = float(np.trapezoid(rel, t) / (t[-1] - t[0])) if t[-1] > t[0] else float(rel[0])
    row["density_error_max"] = float(np.max(tr["density_error"]))
    return row


def write_metrics(study: Study, exp: Experiment, results) -> pd.DataFrame:
    """Rebuild metrics.csv from the trajectories of exactly the current config's finished runs (a run
    of other inputs, or a removed method or dx, leaves no row behind); also writes each run's record."""
    rows = []
    for dx in exp.dx:
        for m in exp.methods:
            sp = spec(study, exp, m, dx, results)
            if runs.stored_state(sp) == "current":
                row = metrics_row(study, exp, m.name, dx, results)
                rows.append(row)
                save_record(sp.folder, record(
                    sp.folder, experiment=study.name, target="fig5", method=m.name,
                    errors={"u_max_mean": row["u_max_relerr_mean"], "e_kin_mean": row["e_kin_relerr_mean"],
                            **{f"u_max_t{te:g}": row[f"u_max_relerr_t{te:g}"] for te in exp.eval_times}}))
    return write_table(study.metrics_path(results), rows, sort=["dx", "method"], ascending=[False, True])


def run_all(study: Study, exp: Experiment, results, methods=None, dxs=None, progress: bool = True) -> pd.DataFrame:
    """Every (dx, method) of the profile (optionally a subset); returns the metrics rows. Every spacing
    is checked against the available memory first (runs.check_fits), before anything is relaxed or run."""
    for dx in exp.dx if dxs is None else dxs:
        runs.check_fits(f"{study.name} at dx = {dx:g}", count([0.0, 0.0], list(tgv.BOX), dx), 2, dx, exp.numerics)
    return sweep(study, results, exp.dx if dxs is None else dxs, exp.methods,
                 lambda m, dx: run_one(study, exp, m, dx, results, progress), only=methods)
