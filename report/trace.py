"""A number on the report and where it comes from.

A `Trace` names a file (a metrics csv, a run record, docs/paper_values.yaml), the row (`where`:
column = value; `min` / `max` pick the row with the smallest / largest value of that column), the
column (several columns are added up per row), an aggregate over the selected rows (sum, min, max,
count, cells: the non-empty cells; none: exactly one row must match), and how it is shown (absolute value, scale, as a
duration). `value()` reads it; the report writes every number with its trace beside it (HTML: a
`data-src` attribute and a tooltip; markdown: a footnote), and the tests resolve each trace again
and compare it with the number shown.
"""
import json
import math
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Optional, Union

import numpy as np
import pandas as pd
import yaml


class TraceError(LookupError):
    """The traced file, row or column does not exist (or the row is ambiguous)."""


@dataclass(frozen=True)
class Trace:
    file: Path
    column: Union[str, tuple]
    where: dict = field(default_factory=dict)
    agg: Optional[str] = None
    absolute: bool = False
    scale: float = 1.0
    display: str = "number"  # or "duration" (seconds written as s / min / h)

    def value(self) -> float:
        raw = _read_value(Path(self.file), self.column, tuple(sorted(self.where.items(), key=str)), self.agg)
        v = abs(raw) if self.absolute else raw
        return v * self.scale

    def describe(self, base=None) -> str:
        """One line for a tooltip / footnote: file, row, column, aggregate."""
        f = self.rel_file(base)
        row = ", ".join(f"{k}={v}" for k, v in self.where.items())
        col = "+".join(self.column) if isinstance(self.column, tuple) else self.column
        parts = [f, f"row {row}" if row else None, f"column {col}", f"{self.agg} over rows" if self.agg else None,
                 "absolute value" if self.absolute else None, f"x {self.scale:g}" if self.scale != 1 else None]
        return "; ".join(p for p in parts if p)

    def rel_file(self, base=None) -> str:
        return os.path.relpath(self.file, base) if base is not None else str(self.file)

    def to_json(self, base) -> str:
        """The trace as JSON, its file relative to `base` (the report's folder)."""
        col = list(self.column) if isinstance(self.column, tuple) else self.column
        return json.dumps({"file": self.rel_file(base), "column": col, "where": self.where, "agg": self.agg,
                           "absolute": self.absolute, "scale": self.scale, "display": self.display})

    @classmethod
    def from_json(cls, text: str, base) -> "Trace":
        d = json.loads(text)
        col = tuple(d["column"]) if isinstance(d["column"], list) else d["column"]
        return cls(file=(Path(base) / d["file"]).resolve(), column=col, where=d.get("where") or {}, agg=d.get("agg"),
                   absolute=bool(d.get("absolute")), scale=float(d.get("scale", 1.0)), display=d.get("display", "number"))


@lru_cache(maxsize=256)
def _table(path: str, mtime_ns: int) -> pd.DataFrame:
    return pd.read_csv(path)


def read_table(path) -> pd.DataFrame:
    p = Path(path)
    if not p.exists():
        raise TraceError(f"{p}: missing")
    return _table(str(p), p.stat().st_mtime_ns)


def select(table: pd.DataFrame, where: dict) -> pd.DataFrame:
    """The rows matching `where` (numbers compared to 1e-9 relative; `min` / `max`: extreme rows)."""
    t = table
    for key, want in where.items():
        if key not in t:
            raise TraceError(f"no column {key!r}")
        col = t[key]
        if want in ("min", "max"):
            num = pd.to_numeric(col, errors="coerce")
            ext = num.min() if want == "min" else num.max()
            t = t[np.isclose(num, ext, rtol=1e-12, atol=0)]
        elif isinstance(want, (int, float)) and not isinstance(want, bool):
            num = pd.to_numeric(col, errors="coerce")
            t = t[np.isclose(num, float(want), rtol=1e-9, atol=1e-12)]
        else:
            t = t[col.astype(str) == str(want)]
    return t


def _number(v) -> float:
    if isinstance(v, (bool, np.bool_)):
        return float(bool(v))
    if isinstance(v, str):
        if v.strip().lower() in ("true", "false"):
            return float(v.strip().lower() == "true")
        return float(v)
    return float(v)


def _read_value(path: Path, column, where: tuple, agg) -> float:
    where = dict(where)
    if path.suffix == ".csv":
        t = select(read_table(path), where)
        cols = column if isinstance(column, tuple) else (column,)
        missing = [c for c in cols if c not in t]
        if missing:
            raise TraceError(f"{path}: no column {', '.join(missing)}")
        vals = sum(pd.to_numeric(t[c].map(_number), errors="coerce") for c in cols)
        if agg is None:
            if len(t) != 1:
                raise TraceError(f"{path}: {len(t)} rows match {where} (expected 1)")
            return float(vals.iloc[0])
        if agg == "count":
            return float(len(t))
        if agg == "cells":  # the non-empty cells of the columns over the rows (e.g. one row, two trainings)
            return float(sum(int(pd.to_numeric(t[c], errors="coerce").notna().sum()) for c in cols))
        if not len(t):
            raise TraceError(f"{path}: no row matches {where}")
        return float(getattr(vals, agg)())
    if path.suffix in (".json", ".yaml", ".yml"):
        if not path.exists():
            raise TraceError(f"{path}: missing")
        data = json.loads(path.read_text()) if path.suffix == ".json" else yaml.safe_load(path.read_text())
        for part in str(column).split("."):
            if not isinstance(data, dict) or part not in data:
                raise TraceError(f"{path}: no key {column!r}")
            data = data[part]
        return _number(data)
    raise TraceError(f"{path}: cannot trace numbers in a {path.suffix} file")


def safe_value(trace: Optional[Trace]) -> Optional[float]:
    """The traced value, or None when its file / row / column is missing or it is not finite."""
    if trace is None:
        return None
    try:
        v = trace.value()
    except (TraceError, ValueError, TypeError):
        return None
    return v if math.isfinite(v) else None
