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
# so a hit is the same executable. SPH_TEST_JAX_CACHE=0 turns it off. Every program is cached, however
# quickly it compiled: a .venv-lb process (make's train / evaluate of the SitL tests, dozens per run)
# compiles many small programs at start-up, and reading them back instead saved 1.7-2.6 s of its
# 11-15 s of CPU (smoke train.py, evaluate.py, warm cache; 2026-12-06) against a 0.2 s threshold,
# at no measurable cost on a cold cache.
if os.environ.get("SPH_TEST_JAX_CACHE", "1") != "0":
    os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(_ROOT / ".pytest_cache" / "jax-compilation-cache"))
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
# LLVM's expensive passes off for the test session and every process it starts: most of a test's
# time is XLA compiling programs it then runs for a few steps. Measured on this project's 2-core
# machine (2026-12-06, no persistent cache, the same load): test_cell_list's 24 pair-set tests 88 -> 74 s
# (compile-bound), the droplet's Laplace test 31.5 -> 31.9 s (run-bound: no loss), where LLVM -O1
# would cost the run-bound test 15 %. Results agree to round-off, as between any two XLA builds; a test
# that compares two processes bit for bit runs both under the same flags. SPH_TEST_XLA_FAST=0 keeps
# XLA's defaults.
_FAST_FLAG = "--xla_llvm_disable_expensive_passes"
if os.environ.get("SPH_TEST_XLA_FAST", "1") != "0" and _FAST_FLAG not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {_FAST_FLAG}=true".strip()
for _p in (str(_ROOT), str(_TESTS)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import pytest  # noqa: E402

import sph  # noqa: E402,F401
from sph import xla_cpu  # noqa: E402

xla_cpu.set_cpu_defaults()

sph.precision.enable_x64()  # tests compare float64 results; sph itself leaves the flag alone


# The longest test files first (seconds of test time per file in a clean-clone `make test`, 2 workers on the
# 2-core machine, 2026-12-06: 291 s test_sitl_pipeline ... 40 s test_surface_tension): with `--dist
# loadfile` each file goes to the first free worker in this order, so a long file taken last is a long
# tail. Longest first (LPT) keeps both workers busy to the end.
LONGEST_FIRST = ("test_sitl_pipeline.py", "test_cell_list.py", "test_sitl_study.py", "test_gradients.py",
                 "test_faults_make.py", "test_stability_pipeline.py", "test_parallel.py", "test_faults.py",
                 "test_tgv3d_pipeline.py", "test_sitl_model.py", "test_inverse_pipeline.py", "test_gradcheck_pipeline.py",
                 "test_accuracy_atlas.py", "test_sitl_cost.py", "test_report.py", "test_ldc2d_pipeline.py",
                 "test_dambreak2d_pipeline.py", "test_surface_tension.py")


def pytest_configure(config):
    """Keep the order below under xdist: pytest-xdist >= 3.6 re-sorts the files of `--dist loadfile`
    by their number of tests (`--loadscope-reorder`, on by default), which put the long SitL files
    (few tests, minutes each) last and made them the tail of the run."""
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False
    config.addinivalue_line("markers", "compile_bound: the module's programs are compiled with XLA's optimizations "
                                       "off (jax_disable_most_optimizations), see _compile_bound")


@pytest.fixture(scope="module", autouse=True)
def _compile_bound(request):
    """A module marked `pytestmark = pytest.mark.compile_bound` compiles its programs with most of XLA's
    optimizations off (`jax_disable_most_optimizations`: LLVM -O0), in this process and in the processes
    it starts (the environment variable), for the module's duration. Module-scoped and autouse, so its
    module-scoped fixtures compile alike. For modules whose programs run a few steps: compiling them is
    most of their time. Measured on this project's 2-core machine (2026-12-07, cold compilation cache):
    test_cell_list's pair-set and row-blocked tests 168 -> 116 CPU-s. Not for a module that runs a
    program for thousands of steps: the droplet and tank-at-rest tests took 76 -> 386 s at -O0, and the
    smoke pipelines (ldc2d, dambreak2d, tgv3d, stability) 2.2-3.6x longer. Results differ from the
    optimized programs' by round-off only; a program compiled here and reused by a later module in the
    same worker runs unoptimized (correct, slower). SPH_TEST_XLA_FAST=0 turns it off with the other
    speed settings above."""
    if request.node.get_closest_marker("compile_bound") is None or os.environ.get("SPH_TEST_XLA_FAST", "1") == "0":
        yield
        return
    import jax

    before = (jax.config.read("jax_disable_most_optimizations"), os.environ.get("JAX_DISABLE_MOST_OPTIMIZATIONS"))
    jax.config.update("jax_disable_most_optimizations", True)
    os.environ["JAX_DISABLE_MOST_OPTIMIZATIONS"] = "1"
    try:
        yield
    finally:
        jax.config.update("jax_disable_most_optimizations", before[0])
        if before[1] is None:
            os.environ.pop("JAX_DISABLE_MOST_OPTIMIZATIONS", None)
        else:
            os.environ["JAX_DISABLE_MOST_OPTIMIZATIONS"] = before[1]


def pytest_collection_modifyitems(session, config, items):
    """Order the files longest first (LONGEST_FIRST, then the rest as collected); a file's own tests
    keep their order (some build on the one before)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda it: rank.get(it.path.name, len(rank)))  # stable: the order within a file stays


@pytest.fixture(scope="session")
def sitl_smoke_dataset():
    """The smoke RPF dataset folder (`make sitl-data PROFILE=smoke` into the tests' shared folder
    SHARED_SMOKE), made once for every test file and xdist worker of the session: the first to ask
    makes it under a file lock while the others wait, and later ones find it current (make checks
    its recorded digests and fingerprint). Read-only for the tests: a test that changes data copies
    it first (sph_test_helpers.seed_sitl_dataset)."""
    import sph_test_helpers

    return sph_test_helpers.shared_sitl_dataset()
