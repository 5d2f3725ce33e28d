"""The accuracy atlas's cheapest-setting table (the README's "error you accept" table): for each
error level of the atlas, the cheapest 2D TGV run of the sweep that reaches it (wall time of the
solve, with the cores other work kept busy meanwhile where the record has it:
lab.other_load), or the best run when none does. Read from results/<profile>/accuracy/runs.csv (written by
`make accuracy`); every cell a trace into that file (row: the run's folder)."""
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pandas as pd

from .trace import Trace, read_table

DEFAULT_LEVELS = (0.1, 0.03, 0.01, 0.003)
OTHER_LOAD_NOTE = ("Other work meanwhile: the cores other processes kept busy, on average, while the run was "
                   "timed (lab.other_load). Near 0 the wall time is this machine's speed; above it the "
                   "run shared the cores and took longer than it would alone.")
DEFAULT_ERROR = "u_max_mean"
METHOD_NAMES = {"sph": "standard SPH", "tvf": "TVF", "riemann": "Riemann SPH"}
KERNEL_NAMES = {"quintic": "quintic", "wendland_c2": "Wendland C2", "wendland_c4": "Wendland C4"}


@dataclass
class LevelRow:
    level: float
    reached: bool
    run: Optional[dict]      # the cheapest run reaching the level, or the best run of the sweep
    traces: dict             # dx, n_particles, error, wall_s (other_load where measured) -> Trace


def settings(profile: str) -> tuple:
    """(levels, error name) of the atlas's config for `profile` (defaults if it cannot be read)."""
    try:
        from lab.experiment import load_settings
        a = load_settings(Path(__file__).resolve().parents[1] / "experiments" / "accuracy", profile)
        return tuple(a.levels), a.tgv.error
    except Exception:  # noqa: BLE001 - the table still renders with the documented defaults
        return DEFAULT_LEVELS, DEFAULT_ERROR


def tgv_runs(runs_csv: Path, error: str) -> pd.DataFrame:
    t = read_table(runs_csv)
    col = f"err_{error}"
    if "experiment" not in t or col not in t:
        return t.iloc[0:0]
    t = t[(t["experiment"] == "tgv2d") & t[col].notna() & t["wall_s"].notna()].copy()
    t["error"] = t[col].abs()
    return t


def setting_label(run: dict) -> str:
    """'TVF, quintic, float32' (+ ' at h = 1.5 dx' for another smoothing length); dx and the particle
    count are written beside it as traced numbers."""
    kern = KERNEL_NAMES.get(str(run.get("kernel", "")), str(run.get("kernel", "")))
    h = run.get("h_factor")
    if h is not None and pd.notna(h) and float(h) != 1.0:
        kern += f" at h = {float(h):g} dx"
    return f"{METHOD_NAMES.get(run['method'], run['method'])}, {kern}, {run['dtype']}"


def cheapest(runs_csv, profile: str) -> list:
    runs_csv = Path(runs_csv)
    levels, error = settings(profile)
    t = tgv_runs(runs_csv, error)
    rows = []
    for lv in levels:
        if t.empty:
            rows.append(LevelRow(lv, False, None, {}))
            continue
        ok = t[t["error"] <= lv]
        reached = not ok.empty
        r = (ok.loc[ok["wall_s"].idxmin()] if reached else t.loc[t["error"].idxmin()]).to_dict()
        where = {"folder": r["folder"]}
        traces = {"dx": Trace(runs_csv.resolve(), "dx", where), "n_particles": Trace(runs_csv.resolve(), "n_particles", where),
                  "error": Trace(runs_csv.resolve(), f"err_{error}", where, absolute=True, scale=100.0),
                  "wall_s": Trace(runs_csv.resolve(), "wall_s", where, display="duration")}
        if pd.notna(r.get("other_load", float("nan"))):  # records made before it was measured have none
            traces["other_load"] = Trace(runs_csv.resolve(), "other_load", where)
        rows.append(LevelRow(lv, reached, r, traces))
    return rows
