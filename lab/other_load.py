"""How busy the machine was with other work while a run was timed.

A run's wall time is the machine's speed only when nothing else ran beside it; on a small shared
machine (2 cores here) a second job makes the same run slower. `OtherLoad` measures the
CPU time every *other* process took during the run: the machine's busy time from /proc/stat (user,
nice, system, irq, softirq and steal) less this process's own CPU time (`os.times`), in cores,
averaged over the wall time measured. 0 on an idle machine; about 1 when another single-threaded job
ran throughout; the run records carry it (`other_load`, lab.record) so that a table of times
can say which were taken beside other work.

Where /proc/stat cannot be read (not Linux) the load is unknown: NaN. In a container whose
/proc/stat shows the host's cores, it counts the host's other work too.
"""
import math
import os
import time
from typing import NamedTuple, Optional

PROC_STAT = "/proc/stat"
BUSY_FIELDS = (0, 1, 2, 5, 6, 7)
"""user, nice, system, irq, softirq, steal of /proc/stat's `cpu` line (guest time is inside user)."""


class Sample(NamedTuple):
    """Machine busy CPU seconds, this process's CPU seconds, monotonic wall seconds, at one instant."""
    busy_s: float
    own_s: float
    wall_s: float


def machine_busy_seconds(path: str = PROC_STAT) -> Optional[float]:
    """Busy CPU seconds of all cores since boot (None when `path` cannot be read or parsed)."""
    try:
        with open(path) as f:
            first = f.readline().split()
        ticks = [int(v) for v in first[1:]]
        if first[0] != "cpu" or len(ticks) < 8:
            return None
        return sum(ticks[i] for i in BUSY_FIELDS) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def sample(path: str = PROC_STAT) -> Optional[Sample]:
    """The machine's and this process's CPU time now (None: the machine's is unknown)."""
    busy = machine_busy_seconds(path)
    if busy is None:
        return None
    t = os.times()
    return Sample(busy, t.user + t.system, time.monotonic())


def other_cpu_seconds(start: Optional[Sample], end: Optional[Sample]) -> tuple:
    """(CPU seconds other processes took, wall seconds) between two samples; (nan, nan) when either is
    unknown. Clipped at 0: the two clocks tick at different instants."""
    if start is None or end is None:
        return math.nan, math.nan
    other = (end.busy_s - start.busy_s) - (end.own_s - start.own_s)
    return max(other, 0.0), max(end.wall_s - start.wall_s, 0.0)


def mean_cores(other_s: float, wall_s: float) -> float:
    """Other work in cores, averaged over `wall_s` (nan when unknown or nothing was measured)."""
    if not (wall_s > 0.0) or math.isnan(other_s):
        return math.nan
    return other_s / wall_s


class OtherLoad:
    """Meter over one stretch of work: `with OtherLoad() as m: ...`, then `m.other_s`, `m.wall_s` and
    `m.cores`. A resumed run is measured over its last session only (other_load_wall_s says how
    long); the sessions before it were killed before they could write theirs."""

    def __init__(self, path: str = PROC_STAT):
        self.path = path
        self.other_s, self.wall_s = math.nan, math.nan
        self._start = None

    def __enter__(self) -> "OtherLoad":
        self._start = sample(self.path)
        return self

    def __exit__(self, *exc) -> None:
        self.other_s, self.wall_s = other_cpu_seconds(self._start, sample(self.path))

    @property
    def cores(self) -> float:
        return mean_cores(self.other_s, self.wall_s)

    def fields(self) -> dict:
        """What a run's metadata keeps: other_load (cores) and the seconds it was measured from (None
        where unknown, so that the JSON stays standard)."""
        f = {"other_load": self.cores, "other_cpu_s": self.other_s, "other_load_wall_s": self.wall_s}
        return {k: None if math.isnan(v) else v for k, v in f.items()}


def cell(cores) -> str:
    """A run's other_load in a table cell: 2 significant digits, 'not measured' for runs made before
    it was recorded (None or NaN)."""
    if cores is None or (isinstance(cores, float) and math.isnan(cores)):
        return "not measured"
    return f"{float(cores):.2g}"
