"""Wall time and ms per step of a target's runs (from its metrics file), and the expected time of a
target for `make all`'s plan: measured where earlier runs left their times, else the documented
estimate (docs/time_estimates.yaml). `cells` writes the wall time (with the most other work any run
ran beside, where every run measured it: lab.other_load) and the ms per step of a target."""
from pathlib import Path
from typing import Optional

import pandas as pd
import yaml

from .paper import ROOT
from .trace import Trace, TraceError, read_table, safe_value, select

ESTIMATES = ROOT / "docs" / "time_estimates.yaml"
DEFAULT_COLUMNS = {"wall": "wall_s", "compile": "compile_s", "ms": "ms_per_step"}


def _cols(c):
    return tuple(c) if isinstance(c, list) else c


def traces(target: dict, results) -> dict:
    """{'wall', 'compile', 'ms_min', 'ms_max', 'n'}: traces into the target's timing file (absent keys:
    the target has no such column); {} when the target names no timing file. `n` counts the rows, or
    with `timing_count: {agg: cells}` the non-empty cells of the wall columns (Table 1: one row, two
    trainings)."""
    if not target.get("timing"):
        return {}
    f = (Path(results) / target["timing"]).resolve()
    cols = {**DEFAULT_COLUMNS, **(target.get("timing_columns") or {})}
    where = dict(target.get("timing_where") or {})
    out = {}
    if cols["wall"]:
        out["wall"] = Trace(f, _cols(cols["wall"]), where, agg="sum", display="duration")
        out["n"] = Trace(f, _cols(cols["wall"]), where, agg=(target.get("timing_count") or {}).get("agg", "count"))
    if cols["compile"]:
        out["compile"] = Trace(f, _cols(cols["compile"]), where, agg="sum", display="duration")
    if cols["ms"]:
        out["ms_min"] = Trace(f, _cols(cols["ms"]), where, agg="min")
        out["ms_max"] = Trace(f, _cols(cols["ms"]), where, agg="max")
    if _all_measured(f, where):
        out["load_max"] = Trace(f, "other_load", where, agg="max")
    return out


def _all_measured(f: Path, where: dict) -> bool:
    """Every timed run of the file measured its other work (runs made before it was recorded did
    not: then the report shows none rather than the maximum of a few)."""
    try:
        t = select(read_table(f), where)
    except TraceError:
        return False
    return "other_load" in t and len(t) > 0 and bool(pd.to_numeric(t["other_load"], errors="coerce").notna().all())


def cells(num, timing: dict) -> tuple:
    """(wall, ms per step) cells of a target's timing, `num(trace)` writing one traced number (the
    HTML page's or report.md's): the wall time with the compilation and, where the runs measured it,
    the most other work any of them ran beside (lab.other_load); ms per step as a range."""
    wall = num(timing["wall"]) if "wall" in timing else "-"
    extra = [f"+ {num(timing['compile'])} compile"] if "compile" in timing else []
    if "load_max" in timing:
        extra.append(f"other work meanwhile: up to {num(timing['load_max'])} cores")
    if extra:
        wall += f" ({'; '.join(extra)})"
    if "ms_min" in timing:
        lo, hi = timing["ms_min"], timing["ms_max"]
        ms = num(lo) if lo.value() == hi.value() else f"{num(lo)} - {num(hi)}"
    else:
        ms = "-"
    return wall, ms


def measured_seconds(target: dict, results) -> Optional[float]:
    """Wall + compile time of the target's runs in `results`, None when no timing is on disk."""
    t = traces(target, results)
    wall = safe_value(t.get("wall"))
    if wall is None:
        return None
    return wall + (safe_value(t.get("compile")) or 0.0)


def estimates(path=ESTIMATES) -> dict:
    return yaml.safe_load(Path(path).read_text())


def estimate_seconds(name: str, profile: str, table: dict) -> Optional[float]:
    """The documented estimate of `name` in `profile` (None: no estimate for that profile)."""
    e = (table.get("targets", {}).get(name) or {}).get(profile)
    if e is None:
        return None
    return float(e["minutes"]) * 60.0 if isinstance(e, dict) else float(e) * 60.0


def overhead_seconds(profile: str, table: dict) -> float:
    """What a target costs besides its timed runs (start-up, compilation outside them, plots)."""
    e = (table.get("overhead") or {}).get(profile)
    return float(e["minutes"]) * 60.0 if e else 0.0
