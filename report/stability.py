"""The stability matrix (`make stability`): one row per hard case, its verdict against its expected
outcome and the numbers behind it, each a trace into results/<profile>/stability/stability.csv."""
from dataclasses import dataclass
from pathlib import Path

from .fmt import truthy
from .trace import Trace, read_table

NUMBERS = (("density_error_max", "max |rho/rho0 - 1|"), ("n_crossed_wall", "crossed a wall"),
           ("n_left_domain", "left the box"), ("energy_drift", "energy drift"), ("wall_s", "wall time"))


@dataclass
class CaseRow:
    case: str
    method: str
    expected: str
    passed: bool
    as_expected: bool
    traces: dict  # column -> Trace


def matrix(csv) -> list:
    csv = Path(csv).resolve()
    t = read_table(csv)
    rows = []
    for _, r in t.iterrows():
        where = {"case": r["case"]}
        traces = {c: Trace(csv, c, where, display="duration" if c == "wall_s" else "number")
                  for c, _ in NUMBERS if c in t and str(r[c]) not in ("", "nan")}
        rows.append(CaseRow(str(r["case"]), str(r.get("method", "")), str(r.get("expected", "")), truthy(r.get("passed")),
                            truthy(r.get("as_expected")), traces))
    return rows
