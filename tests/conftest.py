"""Make `import sph` (repo root) and the shared test helpers (tests/) importable under plain `pytest`,
and set XLA's CPU defaults as every entry point does (sph.harness.xla_cpu), before any JAX computation.

A `tests` package is installed in the core venv's site-packages, so the helpers are a top-level
module (`sph_test_helpers`) found through the tests directory rather than `tests.<name>`.
"""
import sys
from pathlib import Path

_TESTS = Path(__file__).resolve().parent
_ROOT = _TESTS.parent
for _p in (str(_ROOT), str(_TESTS)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import sph  # noqa: E402,F401
from sph.harness import xla_cpu  # noqa: E402

xla_cpu.set_cpu_defaults()

sph.precision.enable_x64()  # tests compare float64 results; sph itself leaves the flag alone
