"""The stability table: every case of the profile judged against its criteria (the `criteria`,
`expected` and `note` of config.yaml, out of the runs' keys: editing them re-judges without
re-running), from what each case measured (study.metrics).

Writes into <out> (make: results/<profile>/stability/):

  stability.csv        one row per case, in config order: metrics + criterion + passed + as_expected
  stability.md         the same as a readable markdown table, with the criteria and failure messages
  stability.png/pdf    per case, the largest density error and the verdict against the criterion

A case that fails is a row of the table, never a failed make (the runs of the suite record a blow-up
or an error as their outcome, lab.experiment FAILURES).

    python experiments/stability/plot_stability.py --profile smoke [--results results/smoke] [--out DIR]
"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402

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
"""Each criterion of `study.Criteria` in words, {v} its value: the criterion column of the table."""


def criterion_text(case, window: float) -> str:
    """The case's criteria in words: those set (not None; `no_crossing` when true), in table order."""
    c = case.criteria
    parts = ["finite and |u| < c_ref to t_end"]
    for name, text in CRITERION_TEXTS:
        v = getattr(c, name)
        if v is not None and v is not False:
            parts.append(text.format(v=v, window=window))
    return "; ".join(parts)


def failed_checks(case, m: dict) -> list:
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


def evaluate(case, metrics: dict, window: float) -> dict:
    """The table row: metrics + criterion, passed, failed_checks, expected, as_expected."""
    bad = failed_checks(case, metrics)
    passed = not bad
    return {**metrics, "criterion": criterion_text(case, window), "passed": passed, "failed_checks": ",".join(bad),
            "expected": case.expected, "note": case.note,
            "as_expected": case.expected == "unknown" or (case.expected == "pass") == passed}


def rows(exp) -> pd.DataFrame:
    """The judged rows of every case of the profile, in config order (refused, naming them, when a
    case has not been run with its current settings)."""
    exp.table()  # every case current, and metrics.csv an input of what this script writes
    table = pd.DataFrame([evaluate(run, exp.metrics(run), exp.study.EKIN_WINDOW) for run in exp.runs])
    return table.reindex(columns=COLUMNS + [c for c in table.columns if c not in COLUMNS])


# -- the table --------------------------------------------------------------------------------------
def _fmt(x, spec=".3g"):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        return str(x)
    return format(int(x) if spec == "d" else x, spec)


def _num(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")


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


def markdown(profile: str, table: pd.DataFrame) -> str:
    lines = [f"# Stability suite, profile `{profile}`", "",
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


def write_table(exp, out) -> pd.DataFrame:
    """stability.csv (every column) and stability.md (readable subset) of every case, in config order."""
    table = rows(exp)
    path = out / "stability.csv"
    tmp = path.with_suffix(".csv.tmp")
    table.to_csv(tmp, index=False)
    tmp.replace(path)
    (out / "stability.md").write_text(markdown(exp.profile, table))
    unexpected = table.loc[~table["as_expected"].astype(bool), "case"].tolist()
    print(f"stability: {int(table['passed'].sum())}/{len(table)} cases pass, {len(unexpected)} not as expected"
          f"{' (' + ', '.join(unexpected) + ')' if unexpected else ''} -> {path}", flush=True)
    return table


def figure(table: pd.DataFrame, exp):
    """Per case, the largest density error (log scale) against its criterion; colour: the verdict."""
    n = len(table)
    fig, ax = plt.subplots(figsize=(9.0, 1.2 + 0.3 * n), layout="constrained")
    y = np.arange(n)[::-1]
    err = pd.to_numeric(table["density_error_max"], errors="coerce").to_numpy(float)
    shown = np.where(np.isfinite(err) & (err > 0), err, np.nan)
    colors = ["C2" if p else ("C1" if a else "C3") for p, a in zip(table["passed"], table["as_expected"])]
    ax.barh(y, shown, color=colors, alpha=0.85)
    for yi, run in zip(y, exp.runs):
        lim = run.criteria.density_error_max
        if lim is not None:
            ax.plot([lim, lim], [yi - 0.4, yi + 0.4], "k-", lw=1)
    for yi, (_, r) in zip(y, table.iterrows()):
        verdict = "pass" if r["passed"] else f"fail: {r['failed_checks']}"
        ax.annotate(f"{verdict}  [{r['method']}]", (1, yi), xycoords=("axes fraction", "data"), xytext=(4, 0),
                    textcoords="offset points", va="center", fontsize=6.5, annotation_clip=False)
    ax.set_yticks(y, list(table["case"]), fontsize=8)
    ax.set_xscale("log")
    ax.set_ylim(-0.6, n - 0.4)
    ax.set_xlabel(r"max over frames and fluid particles of $|\rho/\rho_0 - 1|$ (black: the case's criterion)",
                  fontsize=8)
    ax.set_title(f"Stability suite ({exp.profile}): green pass, orange fail as expected, red not as expected; "
                 "right: verdict [method]", fontsize=8.5, loc="left")
    ax.grid(True, axis="x", which="both", alpha=0.3)
    return fig


def plot(exp, out):
    table = write_table(exp, out)
    return save_figure(figure(table, exp), out, "stability")


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
