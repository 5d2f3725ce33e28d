"""Run the 2D lid-driven cavity for every (dx, method) of a profile and evaluate the runs.

Each run starts from the Cartesian lattice at rest (sph.cases.ldc: three layers of wall particles,
the top ones moving at the lid speed) and runs to t_end. With `lid_corners: fixed` (the validated
set-up) the wall particles of the top layers that lie beyond the side walls (the corner blocks) are
fixed walls, so the lid spans exactly the cavity width; `moving` is the full-width lid of JAX-SPH
(why: sph.cases.ldc.LID_CORNERS). Each run writes

  results/<profile>/ldc2d/<method>_dx<dx>/traj.h5        LagrangeBench layout (lab.io), + checkpoint
  results/<profile>/ldc2d/<method>_dx<dx>/metadata.json
  results/<profile>/ldc2d/<method>_dx<dx>/profiles.npz   centreline profiles (analysis.py)
  results/<profile>/ldc2d/<method>_dx<dx>/record.json    the run record (lab.runs), for `make accuracy`
  results/<profile>/ldc2d/metrics.csv                    one row per run of the current config

Caching is lab.runs.run_cached's: a run whose traj.h5 is complete and was made from the same inputs
(settings.run_fingerprint: the solver settings and only the code that can change the numbers, without
docstrings) is skipped (only re-evaluated, itself cached on the analysis settings and code); one that
stopped part-way resumes from its checkpoint; a damaged or stale one is set aside and run again.
metrics.csv is rebuilt from the current config's runs every time. Progress goes to stdout (with --no-progress one line per `--log-every` frames),
so a background run can be followed with `tail -f`.

    python experiments/ldc2d/run.py --profile smoke [--results results/smoke] [--fig fig6]
                                    [--only tvf] [--dx 0.05] [--no-progress]
"""
import time

import numpy as np

import sph
from sph import diagnostics
from lab import cli, keys, record, runs, tables
from sph.cases import ldc
from lab.configtools import to_mapping
try:
    from . import analysis
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import analysis
    import settings as S


def scene(exp: "S.Experiment", method: "S.Method", dx: float) -> sph.Scene:
    return ldc.scene(dx, exp.material, exp.effects(method), layers=exp.wall_layers, lid_velocity=exp.lid_velocity,
                     lid_corners=exp.lid_corners)


def build(exp: "S.Experiment", method: "S.Method", dx: float) -> sph.Solver:
    return sph.build_solver(scene(exp, method, dx), exp.numerics_of(method))


def _logger(label, t_end, every):
    """Callback printing one progress line every `every` frames (for --no-progress / log files)."""
    t0 = time.perf_counter()
    count = [0]

    def log(step, t, state):
        count[0] += 1
        if count[0] % every == 0 or t >= t_end * (1 - 1e-9):
            el = time.perf_counter() - t0
            print(f"{label}: step {step} t={t:.3f}/{t_end:g} u_max={float(diagnostics.u_max(state)):.4f} "
                  f"[{el:.0f} s this session, {time.strftime('%H:%M:%S')}]", flush=True)
    return log


def spec(exp: "S.Experiment", method: "S.Method", dx: float, results) -> runs.RunSpec:
    """What identifies the run of `method` at `dx` and how it is written."""
    return runs.RunSpec(folder=S.run_dir(results, method.name, dx), case=exp.case, method=method.name,
                        fingerprint=S.run_fingerprint(exp, method, dx), t_end=exp.t_end, frames=exp.frames,
                        keep=exp.keep, connectivity_radius_factor=exp.connectivity_radius_factor,
                        metadata={"re": exp.re, "lid_velocity": exp.lid_velocity, "wall_layers": exp.wall_layers,
                                  "lid_corners": exp.lid_corners, "cavity_offset": ldc.offset(dx, exp.wall_layers)},
                        u_limit=exp.numerics_of(method).c_ref_factor * exp.material.u_ref)


def run_one(exp: "S.Experiment", method: "S.Method", dx: float, results, progress: bool = True,
            callback=None, log_every: int = 0) -> dict:
    """Run (or skip, or resume) one simulation; returns its metrics row."""
    sp = spec(exp, method, dx, results)
    cbs = [c for c in (callback, _logger(sp.label, exp.t_end, log_every) if log_every else None)
           if c]

    def cb(step, t, state):
        for c in cbs:
            c(step, t, state)

    runs.run_cached(sp, lambda: build(exp, method, dx), progress=progress, callback=cb if cbs else None)
    row = evaluate(exp, method.name, dx, results)
    print(f"{sp.label}: RMS deviation from Ghia u {row['u_rms']:.4f}, v {row['v_rms']:.4f}", flush=True)
    return row


def evaluate(exp: "S.Experiment", method: str, dx: float, results) -> dict:
    """The metrics row of a finished run (analysis.evaluate, cached beside the run on the trajectory's
    fingerprint and the analysis settings and code: analysis.py and sph.cases.ldc_reference)."""
    sp = spec(exp, exp.method(method), dx, results)
    runs.require_current(sp, "make the figure (make fig6 / fig7, or experiments/ldc2d/run.py) to run it first")
    key = keys.digest({"run": sp.fingerprint, "analysis": to_mapping(exp.analysis), "ghia_re": exp.ghia_re,
                       "code": analysis.code_key()})
    return runs.cached_row(sp.folder, key, lambda: analysis.evaluate(exp, method, dx, results))


def write_metrics(exp: "S.Experiment", results) -> None:
    """Rebuild metrics.csv from exactly the current config's finished runs; save each run record."""
    rows = []
    for dx in exp.dx:
        for m in exp.methods:
            sp = spec(exp, m, dx, results)
            if runs.stored_state(sp) != "current":
                continue
            row = evaluate(exp, m.name, dx, results)
            rows.append(row)
            fig = next((f for f, d in exp.figures.items() if abs(d - dx) < 1e-12), "ldc2d")
            record.save_record(sp.folder, record.record(
                sp.folder, experiment=S.NAME, target=fig, method=m.name,
                errors={"ghia_u_rms": row["u_rms"], "ghia_v_rms": row["v_rms"],
                        "ghia_rms": float(np.hypot(row["u_rms"], row["v_rms"]) / np.sqrt(2))}))
    order = {m.name: i for i, m in enumerate(exp.methods)}
    rows.sort(key=lambda r: (-r["dx"], order[r["method"]]))
    tables.write_table(S.metrics_path(results), rows)


def run_all(exp: "S.Experiment", results, methods=None, dxs=None, progress: bool = True, log_every: int = 0):
    """Every (dx, method) of the profile (optionally a subset); returns the metrics rows."""
    t0 = time.perf_counter()
    for dx in exp.dx if dxs is None else dxs:  # before anything is built: a dx that cannot fit is refused now
        for m in exp.methods:
            if methods is None or m.name in methods:
                runs.check_fits(f"ldc2d {m.name} at dx = {dx:g}", (round(1.0 / dx) + 2 * exp.wall_layers) ** 2, 2, dx,
                                exp.numerics_of(m))
    rows = []
    for dx in exp.dx if dxs is None else dxs:
        for m in exp.methods:
            if methods is None or m.name in methods:
                rows.append(run_one(exp, m, dx, results, progress, log_every=log_every))
    write_metrics(exp, results)
    print(f"ldc2d: {len(rows)} runs in {time.perf_counter() - t0:.1f} s -> {S.metrics_path(results)}", flush=True)
    return rows


def options(ap):
    ap.add_argument("--fig", choices=S.FIGURES, default=None, help="only the runs of this figure (its dx)")
    ap.add_argument("--only", nargs="*", default=None, help="method names to run (default: all)")
    ap.add_argument("--dx", nargs="*", type=float, default=None, help="spacings to run (default: all)")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--log-every", type=int, default=None,
                    help="print a progress line every N frames (default: 10 with --no-progress, else off)")


def main(args):
    exp = S.load(args.profile)
    methods = cli.select("--only", args.only, [m.name for m in exp.methods])
    dxs = cli.select("--dx", args.dx, list(exp.dx))
    if args.fig:
        if args.fig not in exp.figures:
            raise sph.ConfigError(f"--fig: profile {args.profile!r} has no {args.fig} (figures: {list(exp.figures)})")
        dxs = [float(exp.figures[args.fig])]
    log_every = args.log_every if args.log_every is not None else (10 if args.no_progress else 0)
    run_all(exp, args.results, methods, dxs, not args.no_progress, log_every)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
