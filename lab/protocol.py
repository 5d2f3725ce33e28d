"""What a study module (an experiment folder's study.py, lab.experiment) may declare beyond its
Settings, runs, scene and metrics: a cached `Start` its runs share and the `Table` of its metrics.
Declarations only (the harness acts on them): number-neutral, so a study that imports them keeps its
cache keys when the harness changes.
"""
from dataclasses import dataclass, field
from typing import Callable, Optional

from .configtools import require


@dataclass(frozen=True)
class Start:
    """A cached initial state that runs share (e.g. a relaxed lattice per resolution).

    tag      its file, relaxed_<tag>.npy (+ .json sidecar) in the experiment's results folder
    inputs   every setting the positions depend on (digested with the code of study.py and `modules`)
    compute  compute(progress) -> (positions, info), run only when the cache is missing or stale
    modules  sph modules of the computation besides those study.py imports
    meta     entries the sidecar records and the cache is checked against (e.g. dx), named when they differ
    """

    tag: str
    inputs: dict
    compute: Callable
    modules: tuple = ()
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Table:
    """The metrics table(s): `rows` "records" (each run's record, the default) or "metrics" (the metrics
    dicts as they are), sorted by the columns `sort` (`ascending`: one flag per column), else in the
    runs' order; `file(run)` names the table a run's row goes to when a folder's runs are of several
    kinds (default: metrics.csv for every run)."""

    rows: str = "records"
    sort: tuple = ()
    ascending: tuple = ()
    file: Optional[Callable] = None

    def __post_init__(self):
        require(self.rows in ("records", "metrics"), "TABLE.rows", f"must be 'records' or 'metrics', got {self.rows!r}")
        require(not self.ascending or len(self.ascending) == len(self.sort), "TABLE.ascending",
                f"needs one flag per sort column {list(self.sort)}")
