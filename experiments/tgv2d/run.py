"""Run the 2D Taylor-Green vortex for every (dx, method) of a profile and collect the metrics.

For each spacing the relaxed positions (relax.py, cached) get the analytical TGV velocity; each
method then runs to t_end (lab.tgv2d_runs), writing

  results/<profile>/tgv2d/<method>_dx<dx>/traj.h5        LagrangeBench layout (lab.io), + checkpoint
  results/<profile>/tgv2d/<method>_dx<dx>/metadata.json
  results/<profile>/tgv2d/<method>_dx<dx>/record.json    the run record (lab.record), for `make accuracy`
  results/<profile>/tgv2d/metrics.csv                    one row per run of the current config

Caching and resuming are lab.runs.run_cached's: a run whose traj.h5 is complete and was made
from the same inputs (the profile settings, the relaxation and the code that can change the numbers)
is skipped; one that stopped part-way resumes from its checkpoint; a damaged or stale one is set aside
and run again. metrics.csv is rebuilt from the trajectories every time. The folder name (here tgv2d)
is the experiment's name: a copy of this folder under another name is an experiment of its own.

    python experiments/tgv2d/run.py --profile smoke [--results results/smoke] [--only tvf] [--dx 0.05]
"""
import pandas as pd

from lab import cli, tgv2d_runs

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S


def run_one(exp: "S.Experiment", method: "S.Method", dx: float, results, progress: bool = True,
            callback=None) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row."""
    return tgv2d_runs.run_one(S.STUDY, exp, method, dx, results, progress, callback)


def write_metrics(exp: "S.Experiment", results) -> pd.DataFrame:
    """Rebuild metrics.csv from exactly the current config's finished runs (and their records)."""
    return tgv2d_runs.write_metrics(S.STUDY, exp, results)


options = cli.run_options("--dx", float, "spacings")


def main(args):
    exp = S.load(args.profile)
    methods = cli.select("--only", args.only, [m.name for m in exp.methods])
    dxs = cli.select("--dx", args.dx, list(exp.dx))
    tgv2d_runs.run_all(S.STUDY, exp, args.results, methods, dxs, not args.no_progress)


if __name__ == "__main__":
    cli.profile_main(main, __doc__, options)
