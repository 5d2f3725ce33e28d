"""Run the 3D Taylor-Green vortex for every (resolution, method) of a profile and collect the metrics.

For each resolution n (n^3 particles, dx = 2 pi / n) the start (relaxed positions from relax.py,
cached, or the bare lattice, `start` in config.yaml) gets the analytical TGV velocity; each method
then runs to t_end, writing

  results/<profile>/tgv3d/<method>_n<n>/traj.h5        LagrangeBench layout (lab.io), + checkpoint
  results/<profile>/tgv3d/<method>_n<n>/metadata.json
  results/<profile>/tgv3d/<method>_n<n>/record.json    the run record (lab.runs), for `make accuracy`
  results/<profile>/tgv3d/metrics.csv                  one row per run of the current config

Caching and resuming are lab.runs.run_cached's: a run whose traj.h5 is complete and was made from the
same inputs (the profile settings, the relaxation and the code that can change the numbers) is
skipped; one that stopped part-way resumes from its checkpoint; a damaged or stale one is set aside
and run again. metrics.csv is rebuilt from the trajectories every time (analysis.py, which is not part
of the fingerprint: editing a metric re-evaluates, never re-runs).

    python experiments/tgv3d/run.py --profile smoke [--results results/smoke] [--only tvf] [--n 12]
"""
import pandas as pd

import sph
from sph.cases import tgv3d
from lab import cli, record, runs, tables
from lab.configtools import to_mapping
from lab.study import run_spec, sweep

try:
    from . import analysis, relax, settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import analysis
    import relax
    import settings as S


def build(exp: "S.Experiment", method: "S.Method", n: int, r) -> sph.Solver:
    return sph.build_solver(tgv3d.scene(exp.dx(n), exp.material, method.effects, r=r), exp.numerics)


def spec(exp: "S.Experiment", method: "S.Method", n: int, results) -> runs.RunSpec:
    """What identifies the run of `method` at n^3 particles and how it is written."""
    return run_spec(S.STUDY, exp, method, S.n_tag(n), results, S.run_fingerprint(exp, method, n),
                    {"re": exp.re, "n_side": n, "start": exp.start,
                     "relaxation": to_mapping(exp.relaxation) if exp.start == "relaxed" else None})


def run_one(exp: "S.Experiment", method: "S.Method", n: int, results, progress: bool = True,
            callback=None) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row."""
    sp = spec(exp, method, n, results)
    out = runs.run_cached(sp, lambda: build(exp, method, n, relax.initial_positions(exp, n, results, progress)),
                          progress=progress, callback=callback)
    row = analysis.metrics_row(exp, method.name, n, results)
    if out.status != "skipped":
        print(f"{sp.label}: E_kin RMS deviation {row['e_kin_rms_dev']:.3g} (rel. {row['e_kin_rms_rel']:.3g}), "
              f"-dE/dt RMS deviation {row['dissipation_rms_dev']:.3g}", flush=True)
    write_metrics(exp, results)
    return row


def write_metrics(exp: "S.Experiment", results) -> pd.DataFrame:
    """Rebuild metrics.csv from the trajectories of exactly the current config's finished runs (a run
    of other inputs, or a removed method or resolution, leaves no row behind); also writes each run's
    record."""
    ref = analysis.load_reference(exp)
    rows = []
    for n in exp.n_side:
        for m in exp.methods:
            sp = spec(exp, m, n, results)
            if runs.stored_state(sp) == "current":
                row = analysis.metrics_row(exp, m.name, n, results, ref)
                rows.append(row)
                record.save_record(sp.folder, record.record(
                    sp.folder, experiment=S.NAME, target="fig9", method=m.name,
                    errors={**{k: row[k] for k in ("e_kin_rms_dev", "e_kin_max_dev", "e_kin_rms_rel", "dissipation_rms_dev",
                                                   "dissipation_max_dev", "dissipation_rms_rel")},
                            "peak_t": abs(row["peak_t_err"]), "peak_height": abs(row["peak_dissipation_relerr"]),
                            "early_rate": abs(row["early_rate_relerr"])},
                    n_side=n, start=exp.start))
    return tables.write_table(S.metrics_path(results), rows, sort=["n_side", "method"])


def run_all(exp: "S.Experiment", results, methods=None, ns=None, progress: bool = True) -> pd.DataFrame:
    """Every (resolution, method) of the profile (optionally a subset); returns the metrics rows. Every
    resolution is checked against the available memory first, before anything is relaxed or run."""
    for n in exp.n_side if ns is None else ns:
        runs.check_fits(f"tgv3d at n = {n} ({n ** 3:,} particles)", n ** 3, 3, exp.dx(n), exp.numerics)
    return sweep(S.STUDY, results, exp.n_side if ns is None else ns, exp.methods,
                 lambda m, n: run_one(exp, m, n, results, progress), only=methods)


options = cli.run_options("--n", int, "resolutions, particles per side")


def main(args):
    exp = S.load(args.profile)
    methods = cli.select("--only", args.only, [m.name for m in exp.methods])
    ns = cli.select("--n", args.n, list(exp.n_side))
    run_all(exp, args.results, methods, ns, not args.no_progress)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
