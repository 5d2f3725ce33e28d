"""lab.other_load: the cores other processes kept busy while a run was timed."""
import json
import math
import os
import subprocess
import sys

from lab import other_load as L


def test_other_work_is_the_machines_busy_time_less_this_processs_own():
    """By the definition: 6 s of machine busy time over 2 s of wall, 2 s of it this process's own,
    leaves 4 s of other work: 2 cores."""
    a, b = L.Sample(busy_s=10.0, own_s=2.0, wall_s=100.0), L.Sample(busy_s=16.0, own_s=4.0, wall_s=102.0)
    other, wall = L.other_cpu_seconds(a, b)
    assert (other, wall) == (4.0, 2.0) and L.mean_cores(other, wall) == 2.0
    # the two clocks are read at different instants: a tiny negative difference is no work, not less
    assert L.other_cpu_seconds(a, L.Sample(10.5, 2.6, 101.0))[0] == 0.0


def test_proc_stat_busy_fields_and_unknown_machines(tmp_path):
    """user + nice + system + irq + softirq + steal, not idle or iowait, in seconds of SC_CLK_TCK."""
    f = tmp_path / "stat"
    f.write_text("cpu  100 20 30 400 5 6 7 8 0 0\ncpu0 50 10 15 200 2 3 3 4 0 0\n")
    assert math.isclose(L.machine_busy_seconds(str(f)), (100 + 20 + 30 + 6 + 7 + 8) / os.sysconf("SC_CLK_TCK"))
    f.write_text("intr 1 2 3\n")
    assert L.machine_busy_seconds(str(f)) is None
    with L.OtherLoad(str(tmp_path / "missing")) as m:
        pass
    assert math.isnan(m.cores)
    assert json.loads(json.dumps(m.fields())) == {"other_load": None, "other_cpu_s": None, "other_load_wall_s": None}


def test_a_busy_second_process_is_counted():
    """A child spinning for 1.5 s while this process sleeps is at least ~0.5 cores of other work
    (more when other test workers run too: only the lower bound is certain)."""
    assert L.machine_busy_seconds() is not None, "/proc/stat unreadable: other_load would be unknown here"
    spin = "import time\nt = time.perf_counter()\nwhile time.perf_counter() - t < 1.5: pass\n"
    with L.OtherLoad() as m:
        subprocess.run([sys.executable, "-c", spin], check=True, timeout=60)
    assert m.wall_s >= 1.5 and m.cores >= 0.4, m.fields()
