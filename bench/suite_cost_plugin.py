"""pytest plugin of bench/bench_suite.py: one JSON line per test into $SUITE_COST_LOG.

Per test (its setup, call and teardown together): wall seconds; CPU seconds of the test process
(user + system, all its threads); CPU seconds of the child processes it waited for (make, the run
scripts, .venv-lb: `resource.RUSAGE_CHILDREN`, which counts a child once it has been waited for,
with the descendants it waited for); and JAX's own compile events in the test process
(`jax._src.monitoring`): tracing to a jaxpr, lowering to MLIR, XLA's backend compilation, and what
the persistent compilation cache saved. Loaded with `-p suite_cost_plugin` (bench/ on PYTHONPATH);
without $SUITE_COST_LOG it records nothing.
"""
import json
import os
import resource
import time
from collections import Counter

import pytest

_EVENTS = Counter()
_NAMES = {"jaxpr_trace_duration": "trace_s", "jaxpr_to_mlir_module_duration": "lower_s",
          "backend_compile_duration": "compile_s", "compile_time_saved_sec": "cache_saved_s"}


def _on_duration(event: str, duration: float, **_):
    name = _NAMES.get(event.rsplit("/", 1)[-1])
    if name is not None:
        _EVENTS[name] += duration


def pytest_configure(config):
    if os.environ.get("SUITE_COST_LOG"):
        import jax._src.monitoring as monitoring

        monitoring.register_event_duration_secs_listener(_on_duration)


def _cpu(who) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    log = os.environ.get("SUITE_COST_LOG")
    if not log:
        yield
        return
    events, own, children, t0 = dict(_EVENTS), _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN), time.time()
    yield
    row = {"id": item.nodeid, "wall_s": time.time() - t0, "cpu_s": _cpu(resource.RUSAGE_SELF) - own,
           "children_cpu_s": _cpu(resource.RUSAGE_CHILDREN) - children,
           **{k: _EVENTS[k] - events.get(k, 0.0) for k in _NAMES.values()}}
    with open(log, "a") as f:
        f.write(json.dumps(row) + "\n")
