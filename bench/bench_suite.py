"""Benchmark: where the test suite's time goes, per test file.

Runs the suite (or the files named) as `make test` does (`-n WORKERS --dist loadfile`, the
persistent compilation cache of tests/conftest.py, here in a fresh folder so every program is
compiled as on a clean clone) with bench/suite_cost_plugin.py, which records per test its wall
time, the CPU time of the test process and of the child processes it waited for, and JAX's compile
events in the test process. Prints, per file, longest first:

* `wall`: the sum of its tests' wall times (what `--durations` adds up);
* `cpu_own`: CPU seconds in the pytest worker (its tests' JAX programs: tracing, compiling, running);
* `cpu_children`: CPU seconds of the processes it started (make, run scripts, .venv-lb's training);
* `trace+lower`, `xla_compile`: JAX's tracing and lowering, and XLA's backend compilation, in the
  worker (not in children); `cache_saved`: compile time the persistent cache saved;
* the totals. JAX times its compile phases in elapsed seconds: on a busy machine they can exceed
  the CPU seconds they took.

On a machine where the suite keeps every core busy, the wall time of `make test` is about
(sum of cpu_own + cpu_children) / cores; a change that does not lower that sum does not shorten it.

    .venv/bin/python bench/bench_suite.py                      # the whole suite (minutes)
    .venv/bin/python bench/bench_suite.py tests/core/test_gradients.py --workers 1
    .venv/bin/python bench/bench_suite.py --summarise          # the table of the last log again

Writes the per-test log (`--log`, default results/bench/suite_cost.jsonl, replaced) and the per-file
table beside it (suite_cost.csv).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from lab.atomic import write_text

ROOT = Path(__file__).resolve().parents[1]
COLUMNS = ["wall_s", "cpu_s", "children_cpu_s", "trace_s", "lower_s", "compile_s", "cache_saved_s"]


def run_suite(targets, workers: int, log: Path) -> float:
    """Run pytest on `targets` with the plugin, the per-test rows into `log`; its wall seconds."""
    log.parent.mkdir(parents=True, exist_ok=True)
    log.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="suite-jax-cache-") as cache:
        env = dict(os.environ, SUITE_COST_LOG=str(log), JAX_COMPILATION_CACHE_DIR=cache,
                   PYTHONPATH=os.pathsep.join([str(ROOT / "bench"), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "suite_cost_plugin", "-n", str(workers), "--dist", "loadfile",
               *targets]
        t0 = time.time()
        proc = subprocess.run(cmd, cwd=ROOT, env=env)
        wall = time.time() - t0
    if proc.returncode != 0:
        print(f"bench_suite: pytest exited with {proc.returncode} (the table below covers the tests that ran)",
              file=sys.stderr)
    return wall


def per_file(log: Path) -> pd.DataFrame:
    """The per-test rows of `log` summed per test file, longest (own + children CPU) first."""
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    if not rows:
        raise SystemExit(f"bench_suite: {log} has no rows")
    df = pd.DataFrame(rows)
    df["file"] = df["id"].str.split("::").str[0]
    out = df.groupby("file")[COLUMNS].sum()
    out.insert(0, "tests", df.groupby("file").size())
    out["cpu_total_s"] = out["cpu_s"] + out["children_cpu_s"]
    return out.sort_values("cpu_total_s", ascending=False)


def report(table: pd.DataFrame, wall: float = None) -> str:
    tot = table[COLUMNS + ["cpu_total_s"]].sum()
    shown = table.rename(columns={"cpu_s": "cpu_own", "children_cpu_s": "cpu_children", "compile_s": "xla_compile",
                                  "cache_saved_s": "cache_saved"})
    shown["trace+lower"] = table["trace_s"] + table["lower_s"]
    cols = ["tests", "wall_s", "cpu_own", "cpu_children", "trace+lower", "xla_compile", "cache_saved"]
    lines = [shown[cols].round(1).to_string(), ""]
    lines.append(f"{int(table['tests'].sum())} tests in {len(table)} files: test time {tot['wall_s']:.0f} s; "
                 f"CPU {tot['cpu_total_s']:.0f} s = {tot['cpu_s']:.0f} s in the workers + {tot['children_cpu_s']:.0f} s "
                 f"in their child processes")
    lines.append(f"JAX in the workers (elapsed seconds, as JAX times them): tracing + lowering "
                 f"{tot['trace_s'] + tot['lower_s']:.0f} s, XLA compilation {tot['compile_s']:.0f} s, beside "
                 f"{tot['cpu_s']:.0f} CPU-s of the workers; the persistent cache saved {round(tot['cache_saved_s'])} s")
    if wall is not None:
        lines.append(f"pytest wall time {wall:.0f} s on {os.cpu_count()} cores "
                     f"(CPU / wall = {tot['cpu_total_s'] / wall:.2f} cores busy on average)")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("targets", nargs="*", default=["tests"], help="test files or folders (default: tests)")
    ap.add_argument("--workers", type=int, default=2, help="pytest-xdist workers (make test: TEST_WORKERS, 2)")
    ap.add_argument("--log", type=Path, default=ROOT / "results" / "bench" / "suite_cost.jsonl")
    ap.add_argument("--summarise", action="store_true", help="only summarise an existing --log")
    args = ap.parse_args(argv)
    wall = None if args.summarise else run_suite(args.targets, args.workers, args.log)
    table = per_file(args.log)
    write_text(args.log.with_suffix(".csv"), table.to_csv())
    print(report(table, wall))


if __name__ == "__main__":
    main()
