"""README table of the stability matrix (`make stability`), generated from the snapshot's
stability/stability.csv by `make readme-tables` (report/readme_tables.py registers it): per hard
case its expected outcome, the verdict, the density error, wall crossings and the energy check.
Every number is a cell of that file."""
from pathlib import Path

import pandas as pd

from .fmt import truthy
from .readme_cells import find_source, duration, sig


def stability(snapshot: Path) -> list:
    t = pd.read_csv(find_source(snapshot, "stability/stability.csv"))
    lines = ["| case | method | expected | result | as expected | max abs(rho/rho0 - 1) | crossed a wall / left the box | "
             "energy drift | wall |", "|---|---|---|---|---|---|---|---|---|"]
    for _, r in t.iterrows():
        result = "pass" if truthy(r["passed"]) else f"fail ({r['failed_checks']})"
        crossed = "-" if pd.isna(r["n_crossed_wall"]) else f"{int(r['n_crossed_wall'])} / {int(r['n_left_domain'])}"
        lines.append(f"| {r['case']} | {r['method']} | {r['expected']} | {result} | "
                     f"{'yes' if truthy(r['as_expected']) else '**no**'} | {sig(r['density_error_max'], 2)} | {crossed} | "
                     f"{sig(r['energy_drift'], 2)} | {duration(r['wall_s'])} |")
    n_ok = sum(truthy(v) for v in t["as_expected"])
    return lines + ["", f"{n_ok} of {len(t)} cases ended as expected (`stability/stability.md` of the snapshot has "
                        "every column and each case's criterion)."]
