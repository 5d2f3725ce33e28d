"""bench/bench_suite.py's summary: the per-test rows of its plugin summed per test file, longest
(CPU in the worker + its children) first, and the totals line adding them up."""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))

import bench_suite  # noqa: E402


def _row(test_id, wall, cpu, children, compile_s):
    return {"id": test_id, "wall_s": wall, "cpu_s": cpu, "children_cpu_s": children, "trace_s": 0.5,
            "lower_s": 0.25, "compile_s": compile_s, "cache_saved_s": 0.0}


def test_rows_are_summed_per_file_longest_first(tmp_path):
    log = tmp_path / "suite_cost.jsonl"
    rows = [_row("tests/a.py::t1", 2.0, 1.0, 0.0, 0.5), _row("tests/a.py::t2[x]", 3.0, 2.0, 0.0, 1.0),
            _row("tests/b.py::t", 9.0, 1.0, 7.0, 0.0)]
    log.write_text("".join(json.dumps(r) + "\n" for r in rows))
    table = bench_suite.per_file(log)
    assert list(table.index) == ["tests/b.py", "tests/a.py"]          # 8 CPU-s before 3
    assert table.loc["tests/a.py", "tests"] == 2
    assert table.loc["tests/a.py", "wall_s"] == 5.0 and table.loc["tests/a.py", "compile_s"] == 1.5
    assert table.loc["tests/b.py", "cpu_total_s"] == 8.0
    text = bench_suite.report(table, wall=6.0)
    assert "3 tests in 2 files: test time 14 s; CPU 11 s = 4 s in the workers + 7 s in their child processes" in text
    assert "tracing + lowering 2 s, XLA compilation 2 s" in text
    assert "CPU / wall = 1.83 cores busy" in text
