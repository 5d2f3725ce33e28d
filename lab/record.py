"""The run record: one schema for every experiment's finished runs, what the accuracy-cost atlas
(`make accuracy`) gathers.

`record(folder, ...)` reads a finished run's metadata.json into `RECORD_COLUMNS`, then the run's
error metrics as ``err_<name>`` columns, then any extra columns; `save_record` writes it as
record.json in the run folder.
"""
from pathlib import Path

import numpy as np

from . import io
from .stamp import note_current

RECORD_COLUMNS = ("experiment", "target", "method", "effects", "kernel", "h_factor", "dx", "dim", "dtype", "n_particles",
                  "n_steps", "dt", "t_end", "wall_s", "compile_s", "ms_per_step", "other_load", "peak_rss_mb",
                  "devices", "processes")
"""The fixed columns of a run record; the run's error metrics follow as err_<name>. other_load: the cores
other processes kept busy, on average, while the run was timed (lab.other_load; NaN: not
measured, as in runs made before it was recorded). devices, processes: what the run's steps ran on
(sph.parallel; 1 and 1 for runs made before multi-device runs were recorded, all of which ran on one
device); the decomposition itself is in metadata.json."""


def record(folder, *, experiment: str, target: str, method: str, errors: dict, **extra) -> dict:
    """The run record of a finished run in `folder` (from its metadata.json and traj.h5 attrs):
    RECORD_COLUMNS, then `errors` as err_<name>, then `extra` columns."""
    folder = Path(folder)
    meta = io.read_metadata(folder / "metadata.json")
    if meta is None:
        raise FileNotFoundError(f"{folder / 'metadata.json'}: missing or damaged; re-run the experiment")
    n_steps = int(meta.get("n_steps", 0))
    rec = {"experiment": experiment, "target": target, "method": method,
           "effects": "+".join(meta.get("effects", [])) or "standard", "kernel": meta.get("kernel", ""),
           "h_factor": float((meta.get("numerics") or {}).get("h_factor", np.nan)), "dx": float(meta["dx"]), "dim": int(meta["dim"]), "dtype": meta["dtype"],
           "n_particles": int(meta["num_particles_max"]), "n_steps": n_steps, "dt": float(meta["dt"]),
           "t_end": float(meta["t_end"]), **timing(meta, n_steps), "peak_rss_mb": float(meta.get("peak_rss_mb", np.nan)),
           "devices": int(meta.get("devices", 1)), "processes": int(meta.get("processes", 1))}
    rec.update({f"err_{k}": float(v) for k, v in errors.items()})
    rec.update(extra)
    return rec


def timing(src, n_steps: int) -> dict:
    """wall_s, compile_s, ms_per_step and other_load of a finished run from its traj.h5 attrs or its
    metadata.json (`src`, a mapping): what an experiment's metrics row says of its cost. other_load
    is NaN for runs made before it was recorded."""
    wall = float(src.get("wall_s", np.nan))
    return {"wall_s": wall, "compile_s": float(src.get("compile_s", np.nan)),
            "ms_per_step": 1e3 * wall / n_steps if n_steps else np.nan, "other_load": _number(src.get("other_load"))}


def _number(v) -> float:
    return np.nan if v is None else float(v)


def save_record(folder, rec: dict) -> None:
    """Write the run record as record.json in the run folder (what `make accuracy` gathers)."""
    io.write_metadata(Path(folder) / "record.json", rec)
    note_current(folder)
