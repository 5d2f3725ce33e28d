"""Make `import sph` (repo root) and the shared test helpers (tests/) importable under plain `pytest`,
and set XLA's CPU defaults as every entry point does (sph.xla_cpu), before any JAX computation.

A `tests` package is installed in the core venv's site-packages, so the helpers are a top-level
module (`sph_test_helpers`) found through the tests directory rather than `tests.<name>`.
"""
import os
import sys
from pathlib import Path

_TESTS = Path(__file__).resolve().parent
_ROOT = _TESTS.parent

# JAX's persistent compilation cache for the test session and every process it starts (make, the
# run scripts, .venv-lb): many tests run the same smoke programs in fresh processes (a second make
# into another results folder, -j2 against serial, a repaired output made again), and compilation
# is most of a smoke test's time. The cache is keyed on the program, the backend and XLA's flags,
# so a hit is the same executable. SPH_TEST_JAX_CACHE=0 turns it off.
if os.environ.get("SPH_TEST_JAX_CACHE", "1") != "0":
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(_ROOT / ".pytest_cache" / "jax-compilation-cache"))
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.2")
for _p in (str(_ROOT), str(_TESTS)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import sph  # noqa: E402,F401
from sph import xla_cpu  # noqa: E402

xla_cpu.set_cpu_defaults()

sph.precision.enable_x64()  # tests compare float64 results; sph itself leaves the flag alone


# The longest test files first (seconds on the 2-core CI machine, 2026-12-04): with `--dist loadfile`
# each file goes to one worker in collection order, so a long file collected last is a long tail.
LONGEST_FIRST = ("test_sitl_pipeline.py", "test_sitl_study.py", "test_faults_make.py", "test_stability_pipeline.py",
                 "test_report.py", "test_gradcheck_pipeline.py", "test_sitl_cost.py", "test_accuracy_atlas.py")


def pytest_collection_modifyitems(session, config, items):
    """Order the files longest first (LONGEST_FIRST, then the rest as collected); a file's own tests
    keep their order (some build on the one before)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda it: rank.get(it.path.name, len(rank)))  # stable: the order within a file stays
