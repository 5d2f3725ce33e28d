"""The cells and sources every README table module shares (report/readme_tables.py and the
readme_<topic> modules): the snapshot file a table reads (`find_source`, with the cpu profile as the
fallback where the paper profile needs a GPU) and how a value is printed. A module of its own so that
the table modules import it, not each other."""
from pathlib import Path

import pandas as pd

METHODS = {"sph": "SPH", "tvf": "SPH + TVF", "riemann": "Riemann SPH"}


class SourceMissing(FileNotFoundError):
    pass


FALLBACK = "cpu"
"""The profile a target is shown from where the paper profile needs a GPU (Table 1, report.paper)."""


def find_source(snapshot: Path, rel: str, fallback: bool = False) -> Path:
    """snapshot/rel, or (fallback) the same file in the sibling snapshot of the `cpu` profile."""
    for base in (snapshot, snapshot.parent / FALLBACK) if fallback else (snapshot,):
        if (base / rel).exists():
            return base / rel
    raise SourceMissing(f"{rel} is not in the {snapshot.name} snapshot")


def snapshot_csv(snapshot: Path, rel: str) -> pd.DataFrame:
    """The table `rel` of the snapshot (SourceMissing when absent)."""
    return pd.read_csv(find_source(snapshot, rel))


def pct(v, digits: int = 3) -> str:
    return "-" if pd.isna(v) else f"{100 * float(v):.{digits}g} %"


def duration(s) -> str:
    """A wall time in seconds: '45 s', '12 min', '1.9 h'."""
    s = float(s)
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.0f} min" if s < 7200 else f"{s / 3600:.2g} h"


def sig(v, digits: int = 3) -> str:
    """`digits` significant digits; '-' for a missing cell (None, NaN or empty)."""
    return "-" if v is None or str(v) == "" or pd.isna(v) else f"{float(v):.{digits}g}"


def sci(v) -> str:
    """7.1e-09 -> 7.1e-9."""
    if v is None or pd.isna(v):
        return "-"
    m, e = f"{float(v):.1e}".split("e")
    return f"{m}e{int(e)}"
