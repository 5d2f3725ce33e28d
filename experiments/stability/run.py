"""Run the stability suite of a profile and write one table of pass/fail results.

Every case of config.yaml runs to its t_end with `sph.simulate.run` (u_limit = c_ref) and is checked
after every diagnostic frame (`cases.Monitor`: density error, wall crossing, escapes, particle
spacing, energy, accuracy). A case whose fields go non-finite (or faster than c_ref) stops in the
driver; the suite records it as failed with the driver's message (step, time, particle), records
whether the last good state is on disk (the checkpoint of its traj.h5, which must be finite) and
goes on with the next case; any other exception becomes status "error" with its message.

Outputs (results/<profile>/stability/):

  <case>/traj.h5       a few frames (LagrangeBench layout, lab.io) + the checkpoint of the last good state
  <case>/series.csv    the monitor's values at every diagnostic frame
  <case>/result.json   the case's metrics, info (dt limits, relaxation, traceback) and the fingerprint
  stability.csv        one row per case, in config order: metrics + criterion + passed
  stability.md         the same as a readable markdown table, with the criteria and failure messages

Caching: a case whose result.json carries the fingerprint of its current inputs (its simulation
settings and the code of sph/, cases.py and settings.py) is not re-run
(`--force` re-runs). Pass/fail is evaluated from the stored metrics every time the table is written,
so editing `criteria` or `expected` in config.yaml, or this file, re-evaluates without re-running.

    python experiments/stability/run.py --profile smoke [--results results/smoke] [--only ldc_tvf heat_sine]
"""
import json
import time

import numpy as np
import pandas as pd

from sph.errors import ConfigError

try:
    from . import cases as C
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import cases as C
    import settings as S

COLUMNS = ["case", "kind", "method", "setup", "expected", "status", "passed", "as_expected", "failed_checks",
           "criterion", "message", "dx", "n_fluid", "n_particles", "dt", "dt_binding", "t_end", "t_reached",
           "n_steps", "finite_throughout", "checkpoint_step", "checkpoint_t", "checkpoint_finite",
           "density_error_max", "n_crossed_wall", "n_left_domain", "min_spacing_dx", "u_max_max",
           "energy_quantity", "energy_drift", "energy_end", "ekin_rise_max", "T_overshoot", "accuracy_quantity",
           "accuracy",
           "wall_s", "solve_s", "compile_s", "ms_per_step"]


# -- criteria ---------------------------------------------------------------------------------------
CRITERION_TEXTS = (
    ("density_error_max", "max abs(rho/rho0-1) <= {v:g}"),
    ("no_crossing", "no fluid particle beyond a wall face by > dx/2 or outside the box"),
    ("energy_rise_max", "E = E_kin+E_pot never rises above its running minimum by > {v:g} E0"),
    ("ekin_relerr_max", "abs(E_kin/E_exact-1) <= {v:g} while E_exact >= {window:g} E0"),
    ("ekin_rise_max", "E_kin never rises above its running minimum by > {v:g} E0"),
    ("thermal_drift_max", "abs(E_th/E_th0-1) <= {v:g}"),
    ("overshoot_max", "T stays in its initial range within {v:g} of it"),
    ("dt_limit", "the {v} dt limit binds"),
    ("rest_speed_max", "at rest: max abs(u) / sqrt(gH) <= {v:g} over the last quarter"),
)
"""Each criterion of `S.Criteria` in words, {v} its value: the criterion column of the table."""


def criterion_text(case: "S.Case") -> str:
    """The case's criteria in words: those set (not None; `no_crossing` when true), in table order."""
    c = case.criteria
    parts = ["finite and |u| < c_ref to t_end"]
    for name, text in CRITERION_TEXTS:
        v = getattr(c, name)
        if v is not None and v is not False:
            parts.append(text.format(v=v, window=C.EKIN_WINDOW))
    return "; ".join(parts)


def failed_checks(case: "S.Case", m: dict) -> list:
    """Names of the checks of `case.criteria` that the metrics `m` fail (empty: the case passes)."""
    c, kind, bad = case.criteria, case.kind, []
    if m.get("status") != "completed":
        bad.append(m.get("status", "missing"))
    checks = [("density_error", c.density_error_max, m.get("density_error_max")),
              ("energy_rise", c.energy_rise_max, m.get("energy_drift") if kind == "dam_break" else None),
              ("ekin_relerr", c.ekin_relerr_max, m.get("energy_drift") if kind == "tgv" else None),
              ("ekin_rise", c.ekin_rise_max, m.get("ekin_rise_max")),
              ("thermal_drift", c.thermal_drift_max, m.get("energy_drift") if kind == "heat" else None),
              ("overshoot", c.overshoot_max, m.get("T_overshoot")),
              ("rest_speed", c.rest_speed_max, m.get("rest_speed"))]
    for name, limit, value in checks:
        if limit is not None and (value is None or not np.isfinite(value) or value > limit):
            bad.append(name)
    if c.no_crossing and (m.get("n_crossed_wall", 1) > 0 or m.get("n_left_domain", 1) > 0):
        bad.append("crossing")
    if c.dt_limit is not None and m.get("dt_binding") != c.dt_limit:
        bad.append("dt_limit")
    return bad


def evaluate(case: "S.Case", metrics: dict) -> dict:
    """The table row: metrics + criterion, passed, failed_checks, expected, as_expected."""
    bad = failed_checks(case, metrics)
    passed = not bad
    return {**metrics, "criterion": criterion_text(case), "passed": passed, "failed_checks": ",".join(bad),
            "expected": case.expected, "note": case.note,
            "as_expected": case.expected == "unknown" or (case.expected == "pass") == passed}


# -- one case, cached -------------------------------------------------------------------------------
def cached_metrics(name: str, case: "S.Case", results, ignore_code: bool = False):
    """The stored metrics of a case if its result.json matches the current inputs, else None;
    `ignore_code`: a result made from the same settings counts even if the code changed since."""
    path = S.case_dir(results, name) / "result.json"
    try:
        stored = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if ignore_code:
        same = stored.get("settings_fingerprint") == S.case_fingerprint(name, case, code=False)
    else:
        same = stored.get("fingerprint") == S.case_fingerprint(name, case)
    return stored.get("metrics") if same else None


def run_case(name: str, case: "S.Case", results, progress: bool = True, force: bool = False,
             ignore_code: bool = False) -> dict:
    """Run one case (or reuse its current result) and return its evaluated table row."""
    metrics = None if force else cached_metrics(name, case, results, ignore_code)
    if metrics is not None:
        row = evaluate(case, metrics)
        print(f"{name}: unchanged, reused: {_verdict(row)}", flush=True)
        return row
    folder = S.case_dir(results, name)
    fp = S.case_fingerprint(name, case)
    print(f"{name}: running ({case.kind}, {C.method_name(case.effects)}, dx {case.dx:g}, t_end {case.t_end:g})",
          flush=True)
    metrics, info = C.simulate_case(name, case, folder, fp, progress)
    metrics, info = _plain(metrics), _plain(info)
    path = folder / "result.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps({"fingerprint": fp, "settings_fingerprint": S.case_fingerprint(name, case, code=False),
                               "metrics": metrics, "info": info}, indent=2) + "\n")
    tmp.replace(path)
    row = evaluate(case, metrics)
    print(f"{name}: {_verdict(row)} in {row['wall_s']:.1f} s" + (f": {row['message']}" if row["message"] else ""),
          flush=True)
    return row


def _verdict(row) -> str:
    return "pass" if row["passed"] else f"FAIL ({row['failed_checks']})"


def _plain(x):
    """JSON-safe copy (numpy scalars to Python; NaN stays NaN, which json writes as NaN)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.floating):
        return float(x)
    return x


# -- the table --------------------------------------------------------------------------------------
def write_table(suite: "S.Suite", results, rows: dict) -> pd.DataFrame:
    """stability.csv (every column) and stability.md (readable subset) of the cases of `suite` that
    have a row, in config order."""
    table = pd.DataFrame([rows[n] for n in suite.names() if n in rows])
    table = table.reindex(columns=COLUMNS + [c for c in table.columns if c not in COLUMNS])
    path = S.table_path(results)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".csv.tmp")
    table.to_csv(tmp, index=False)
    tmp.replace(path)
    S.markdown_path(results).write_text(markdown(suite, table))
    return table


def _fmt(x, spec=".3g"):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        return str(x)
    return format(int(x) if spec == "d" else x, spec)


ENERGY_LEGEND = {
    "dam_break": "E = E_kin + E_pot (dissipated): largest rise above its running minimum / E0; E(t_end)/E0 - 1",
    "tgv": "abs(E_kin/E_exact - 1), max while E_exact >= 0.2 E0; (E_kin - E_exact)/E0 at t_end; "
           "rise = max (E_kin - running min of E_kin)/E0",
    "heat": "E_th = sum m c_p T (conserved): max abs(E_th/E_th0 - 1); value at t_end",
    "ldc": "driven flow, no energy check",
}
ACCURACY_LEGEND = {
    "tgv": "abs(E_kin/E_exact - 1) at t = min(1, t_end)",
    "heat": "first Fourier mode of T over exp(-alpha (2 pi)^2 t), minus 1, at t_end",
}


def markdown(suite: "S.Suite", table: pd.DataFrame) -> str:
    lines = [f"# Stability suite, profile `{suite.profile}`", "",
             "One row per case (experiments/stability/README.md); `stability.csv` has every column. "
             "crossed: fluid particles ever beyond a wall face by > dx/2 or outside the box; left: outside "
             "the box; min spacing: smallest fluid-particle distance to any particle / dx.", "",
             "| case | method | setup | dx | dt (binding limit) | steps | t reached / t_end | result | expected | "
             "max abs(rho/rho0-1) | crossed / left | min spacing / dx | energy: check; end | accuracy | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, r in table.iterrows():
        result = "pass" if r["passed"] else f"**FAIL** ({r['failed_checks']})"
        energy = "-" if not np.isfinite(_num(r["energy_drift"])) else (
            f"{_fmt(r['energy_drift'])}; {_fmt(r['energy_end'])}"
            + (f"; rise {_fmt(r['ekin_rise_max'])}" if r["kind"] == "tgv" else "")
            + (f"; overshoot {_fmt(r['T_overshoot'])}" if r["kind"] == "heat" else ""))
        lines.append(f"| {r['case']} | {r['method']} | {r['setup']} | {_fmt(r['dx'], 'g')} | "
                     f"{_fmt(r['dt'])} ({r['dt_binding']}) | {_fmt(r['n_steps'], 'd')} | "
                     f"{_fmt(r['t_reached'], '.4g')} / {_fmt(r['t_end'], 'g')} | "
                     f"{result} | {r['expected']} | {_fmt(r['density_error_max'])} | "
                     f"{_fmt(r['n_crossed_wall'], 'd')} / {_fmt(r['n_left_domain'], 'd')} | "
                     f"{_fmt(r['min_spacing_dx'])} | {energy} | {_fmt(r['accuracy'])} | {_fmt(r['wall_s'], '.1f')} |")
    kinds = list(dict.fromkeys(table["kind"]))
    lines += ["", "Energy column: " + "; ".join(f"**{k}**: {ENERGY_LEGEND[k]}" for k in kinds if k in ENERGY_LEGEND),
              "", "Accuracy column: " + "; ".join(f"**{k}**: {ACCURACY_LEGEND[k]}" for k in kinds
                                                  if k in ACCURACY_LEGEND) + "."]
    lines += ["", "## Criteria", ""] + [f"- **{r['case']}**: {r['criterion']}" for _, r in table.iterrows()]
    msgs = [(r["case"], r["message"]) for _, r in table.iterrows() if isinstance(r["message"], str) and r["message"]]
    if msgs:
        lines += ["", "## Messages", ""] + [f"- **{c}**: {m}" for c, m in msgs]
    return "\n".join(lines) + "\n"


def _num(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")


def run_suite(suite: "S.Suite", results, only=None, progress: bool = True, force: bool = False,
              ignore_code: bool = False) -> pd.DataFrame:
    """Run (or reuse) the cases (all, or those in `only`), then write the table of every case of the
    suite that has a current result."""
    t0 = time.perf_counter()
    rows = {}
    for name, case in suite.cases:
        if only and name not in only:
            metrics = cached_metrics(name, case, results, ignore_code)
            if metrics is not None:
                rows[name] = evaluate(case, metrics)
            continue
        rows[name] = run_case(name, case, results, progress, force, ignore_code)
    table = write_table(suite, results, rows)
    unexpected = table.loc[~table["as_expected"].astype(bool), "case"].tolist()
    print(f"stability: {int(table['passed'].sum())}/{len(table)} cases pass, {len(unexpected)} not as expected"
          f"{' (' + ', '.join(unexpected) + ')' if unexpected else ''}; {time.perf_counter() - t0:.1f} s -> "
          f"{S.table_path(results)}", flush=True)
    return table


def options(ap):
    ap.add_argument("--only", nargs="*", default=None, help="case names to run (default: all)")
    ap.add_argument("--force", action="store_true", help="re-run cases even if their result is current")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--ignore-code-changes", action="store_true",
                    help="reuse a case's result made from the same settings even if sph/ or the scripts changed")


def main(args):
    suite = S.load(args.profile)
    if args.only:
        bad = [n for n in args.only if n not in suite.names()]
        if bad:
            raise ConfigError(f"--only: {bad[0]!r} is not one of {suite.names()}")
    run_suite(suite, args.results, args.only, not args.no_progress, args.force,
              args.ignore_code_changes)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
